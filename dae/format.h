// Numbers in messages and written files, shared by every layer (dae, mbs, driver, api,
// apps, sensitivities): header-only.
#pragma once

#include <cstdio>
#include <cstdlib>
#include <string>
#include <vector>

namespace mbdae {

// x with `digits` significant digits, as printf's %.*g (and an ostream's default format
// with that precision) writes it.
inline std::string FormatG(double x, int digits) {
  char buf[48];
  std::snprintf(buf, sizeof buf, "%.*g", digits, x);
  return buf;
}

// x with 15 significant digits if they read back as x, else 17 (which always do).
inline std::string FormatRoundTrip(double x) {
  const std::string s = FormatG(x, 15);
  return std::strtod(s.c_str(), nullptr) == x ? s : FormatG(x, 17);
}

// The names as a message lists them: "a", "a or b", "a, b or c".
inline std::string JoinOr(const std::vector<std::string>& names) {
  std::string s;
  for (size_t i = 0; i < names.size(); ++i)
    s += (i == 0 ? "" : i + 1 == names.size() ? " or " : ", ") + names[i];
  return s;
}

}  // namespace mbdae
