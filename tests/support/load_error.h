// The message of a model text that does not load (tests of the loader's checks).
#pragma once

#include <string>

#include "mbs/loader.h"

namespace mbdae::testing {

// The ModelError's message of loading `text` as the file `file`; "" when it loads.
inline std::string LoadError(const std::string& text, const std::string& file = "m.yaml") {
  try {
    mbs::LoadModelFromString(text, file);
  } catch (const mbs::ModelError& e) {
    return e.what();
  }
  return "";
}

}  // namespace mbdae::testing
