// max_i |x_i - y_i| / max_i |y_i| (the absolute difference when y is zero): how far a
// solution is from a reference, relative to the reference's size. Shared by
// tests/dae/test_tree_kkt.cc and tests/dae/test_block_tree_lu.cc.
#pragma once

#include <algorithm>
#include <cmath>
#include <vector>

namespace mbdae::testing {

inline double RelativeDifference(const std::vector<double>& x, const std::vector<double>& y) {
  double d = 0, s = 0;
  for (size_t i = 0; i < y.size(); ++i) {
    d = std::max(d, std::abs(x[i] - y[i]));
    s = std::max(s, std::abs(y[i]));
  }
  return s > 0 ? d / s : d;
}

}  // namespace mbdae::testing
