// The objectives of a model file (Model::objectives, `objectives:`) as an
// ObjectiveFunction (sensitivities/objective.h) over the trajectory of a MultibodySystem
// integrated through a KeepConstraints view.
//
// Values: each integrand / terminal expression is evaluated over t, the parameter
// values of the system (MultibodySystem::parameters(), read at every call), the splines
// of the model and the measures it uses:
//   - position measures m(q) as forces see them: angles in (-pi, pi] (no unwrapping
//     across turns, unlike the results file's rows), distances, components;
//   - velocity measures g(q).v, acceleration measures g(q).a + v^T H(q) v
//     (mbs/measure_kinematics.h), the same values as MultibodySystem::EvaluateMeasures;
//   - reaction measures from the multipliers (mbs/reaction.h);
//   - offset_initial: minus the measure's value at the initial state of the model file
//     (before assembly; acceleration-level measures with a = 0 there), as
//     MultibodySystem subtracts its measure_offsets for forces.
// The lambda an objective receives holds the kept equations only (`kept`, sorted, as
// driver::Assembly::kept); the dropped ones are taken as zero and their dlambda is not
// reported.
//
// Gradients: Expression::EvaluateGradient chained with the measures' derivatives:
//   position: dm/dq = g;  velocity: d/dq = H v, d/dv = g;
//   acceleration: d/da = g, d/dv = 2 H v, d/dq = H a + d(v^T H v)/dq, the last by
//     central differences of the exact Hessian on the 14 local coordinates (step
//     1e-5 (1 + |q_k|); error ~1e-9 relative in the tests);
//   reaction: exact (ReactionMeasures::Derivatives), d/dlambda mapped to the kept rows.
// dp: for a sensitivity parameter that is a model parameter, the total derivative of
// the expression through the parameters computed from it (mbs::ParameterChain) and
// through the inline points of splines that use it (mbs::SplineOrdinateDirection). For a
// spline ordinate, Expression::EvaluateSplineOrdinateGradient (exact; it allocates).
// Not included: the dependence of offset_initial offsets on the parameters (the
// offsets are the values at the model file's initial state, taken as constants).
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "mbs/model.h"
#include "mbs/sensitivity_parameters.h"
#include "mbs/system.h"
#include "sensitivities/objective.h"

namespace mbdae::sens {

class ModelObjectives final : public ObjectiveFunction {
 public:
  // model and system must outlive this object. kept: the kept constraint equations of
  // the integrated view (indices into the system's full set). parameters: what dp is
  // taken with respect to (may be empty). Throws std::invalid_argument for an index out
  // of range.
  ModelObjectives(const mbs::Model& model, const mbs::MultibodySystem& system, std::vector<int> kept,
                  std::vector<mbs::SensitivityParameter> parameters = {});
  ~ModelObjectives() override;

  int num_objectives() const override;
  const std::vector<std::string>& names() const override;
  bool has_integral(int i) const override;
  bool has_terminal(int i) const override;
  bool depends_on_acceleration() const override;
  bool depends_on_multipliers() const override;

  int Integrand(const ObjectivePoint& x, double* g) override;
  int Terminal(const ObjectivePoint& x, double* phi) override;
  int IntegrandGradient(const ObjectivePoint& x, const double* weights, ObjectiveGradient* out) override;
  int TerminalGradient(const ObjectivePoint& x, const double* weights, ObjectiveGradient* out) override;
  const char* last_error() const override;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace mbdae::sens
