// Reading a model file (format 1, YAML; see the model format contract).
#pragma once

#include <map>
#include <stdexcept>
#include <string>

#include "mbs/model.h"

namespace mbdae::mbs {

// A mistake in a model file. what() is the full message:
//   "FILE:LINE:COLUMN: ELEMENT: what is wrong"
// e.g. "pendulum.yaml:12:7: body 'link': mass must be >= 0, got -1".
class ModelError : public std::runtime_error {
 public:
  ModelError(const SourceLocation& where, const std::string& element, const std::string& what);
  const SourceLocation& where() const { return where_; }
  const std::string& element() const { return element_; }
 private:
  SourceLocation where_;
  std::string element_;
};

struct LoadOptions {
  // Parameter overrides (--set NAME=VALUE), applied before any expression is evaluated.
  // An override of an unknown parameter is a ModelError.
  std::map<std::string, double> parameter_overrides;
  // URDF files (mbs/urdf.h): the root link is a free body instead of the ground.
  bool urdf_floating_base = false;
};

// Throws ModelError for any mistake; nothing is partially returned.
Model LoadModel(const std::string& path, const LoadOptions& options = {});
// Same from text; `file` is used in messages and for relative paths.
Model LoadModelFromString(const std::string& text, const std::string& file,
                          const LoadOptions& options = {});

}  // namespace mbdae::mbs
