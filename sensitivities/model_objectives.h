// The objectives of a model file (Model::objectives, `objectives:`) as an
// ObjectiveFunction (sensitivities/objective.h) over the trajectory of a MultibodySystem
// integrated through a KeepConstraints view.
//
// Values: each integrand / terminal expression is evaluated over t, the parameter
// values of the system (MultibodySystem::parameters(), read at every call), the splines
// of the model and the measures it uses:
//   - position measures m(q): distances, components, and angles counted across turns
//     as in the results file's rows: each angle is taken at the turn nearest to the
//     value predicted from the previous evaluation (trapezoidal rule on its rate), so
//     a joint that turns by 2 pi ends at its start angle + 2 pi, not at its start
//     angle. The count starts at the model file's initial state (angles in (-pi, pi])
//     and follows the evaluations in the order they come, forward or backward in time;
//     a backward sweep starts from where the forward run ended (angle_track /
//     set_angle_track). Consecutive evaluations must be less than pi apart in every
//     angle (as the results file's rows must);
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

  // The turn count of the angle measures the objectives use (model order): the time,
  // unwrapped angles and rates of the last evaluation (t is NaN before the first one).
  struct AngleTrack {
    double t = 0;
    std::vector<double> angles, rates;
  };
  const AngleTrack& angle_track() const;
  // Continues the count from a track of the same model (e.g. a forward run's end for the
  // adjoint sweep that starts there). Throws std::invalid_argument on a size mismatch.
  void set_angle_track(const AngleTrack& track);

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
