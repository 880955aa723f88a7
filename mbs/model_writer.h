// Writing an mbs::Model as a model file of this project (YAML, format 1), e.g. a model
// read from a FreeDyn .fds file (`mbdae convert`).
//
// The text is such that LoadModelFromString(WriteModelYaml(model), ...) gives the same
// model: the same elements in the same order, numbers written with enough digits to read
// back exactly (orientations as Euler parameters, which the loader normalises: equal to
// round-off), expressions as their text. What is written:
//
//   name, gravity, parameters (the expression when there is one, else the value),
//   splines (inline points x, y, with the parameter expressions of inline points when
//   there are some, and the interpolation; a spline read from a data file is written
//   with its points, so the converted file stands alone), ground markers, bodies (mass,
//   inertia as [Ixx, Iyy, Izz] or with the products [.., Ixy, Ixz, Iyz] when one is
//   non-zero, position, orientation, velocity, angular velocity, markers), measures,
//   joints (generic ones with their locks), forces (expression texts) and the
//   simulation block.
//
// A body's geometry is not part of the Model (its mass and inertia are): the written
// body has explicit mass and inertia.
#pragma once

#include <string>

#include "mbs/model.h"

namespace mbdae::mbs {

struct ModelWriterOptions {
  // A first comment line "# written by mbdae from FILE" when `source` is not empty.
  std::string source;
};

std::string WriteModelYaml(const Model& model, const ModelWriterOptions& options = {});

// `s` as a double-quoted string, escaped as JSON does; valid as a YAML double-quoted
// scalar and as a JSON string alike.
std::string DoubleQuoted(const std::string& s);

// Writes WriteModelYaml(model) to `path`; throws std::runtime_error "PATH: what" when the
// file cannot be written.
void WriteModelFile(const Model& model, const std::string& path, const ModelWriterOptions& options = {});

}  // namespace mbdae::mbs
