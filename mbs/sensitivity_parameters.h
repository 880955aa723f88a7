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

// The chain of dependent parameters: chain[k][j] = d(value of model parameter j)/d(the
// sensitivity parameter params[k]), for every model parameter j (Model::parameters
// order). A parameter may be an expression of others (Parameter::formula): the
// derivative with respect to `a` is the total one, through every parameter computed
// from `a` (depth-first over the formulas, exact: Expression::EvaluateGradient). The
// parameter `a` itself is independent (chain 1 for j = a, whatever its own formula says);
// a parameter overridden with --set (Parameter::overridden) is a fixed number (0). A
// spline ordinate's column is zero (no parameter depends on one).
// Use: the total derivative of an expression E over the parameters is
//   sum_u E.d_parameters[u] * chain[k][E.parameters_used()[u]],
// or EvaluateDirectional with ParameterDirection::parameters = chain[k].data().
std::vector<std::vector<double>> ParameterChain(const Model& model,
                                                const std::vector<SensitivityParameter>& params);

// d(y_i)/d(params[k]) of every point i of spline `spline`, given chain[k]: for the
// ordinate spline[i] itself the unit vector; for a model parameter the derivative of the
// inline y expressions (zero for a spline read from a file). Inline x points that depend
// on the parameter are not differentiated (MultibodySystem refuses them).
std::vector<double> SplineOrdinateDirection(const Model& model, const SensitivityParameter& param,
                                            const std::vector<double>& chain_column, int spline);

}  // namespace mbdae::mbs
