// What a gradient is taken with respect to (shared/spec/sensitivities.md): model
// parameters by name ("k") and spline ordinates as "SPLINE[i]" (0-based point index).
// A MultibodySystem built with a list of these offers their partial derivatives
// (dae::MechanicalSystem::num_parameters, parameter_pattern, parameter_matrix), in the
// order of the list.
#pragma once

#include <string>
#include <vector>

#include "mbs/model.h"

namespace mbdae::mbs {

struct SensitivityParameter {
  std::string name;    // as written: "k" or "u1[3]"
  int parameter = -1;  // Model::parameters index, or -1 for a spline ordinate
  int spline = -1;     // Model::splines index of a spline ordinate
  int point = -1;      // its 0-based point index
};

// Resolves names against the model. Throws std::invalid_argument with a message that
// names the unknown name (and suggests close ones), a malformed "SPLINE[i]", or an index
// outside the spline's points.
std::vector<SensitivityParameter> ResolveSensitivityParameters(const Model& model,
                                                               const std::vector<std::string>& names);

// Every parameter of the model in file order; with_splines adds every ordinate of every
// spline (spline by spline, point by point).
std::vector<SensitivityParameter> AllSensitivityParameters(const Model& model, bool with_splines);

}  // namespace mbdae::mbs
