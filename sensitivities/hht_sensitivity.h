// Exact gradients of the discrete objective of an HHT run (dae/hht.h, docs/hht.md):
// the discrete adjoint (a backward sweep over the stored steps with the transposed
// Newton matrices) and direct differentiation (a forward sweep), both of the very step
// sequence the run took (fixed or adaptive step: the accepted steps frozen), for the
// classical and the modified scheme and both residual forms. Equations:
// docs/sensitivities.md.
//
// The objective's integral is the HHT quadrature: the trapezoidal rule over the
// accepted steps (dae::Quadrature), the terminal part is taken at the last state.
#pragma once

#include <string>
#include <vector>

#include "dae/hht.h"
#include "dae/integrator.h"
#include "dae/mechanical_system.h"
#include "sensitivities/objective.h"

namespace mbdae::sens {

// Derivatives of the consistent initial state with respect to the system's parameters:
// dense, column-major (column k: d/dp_k), nq x np for q, v, a and nc x np for lambda.
struct InitialStateDerivatives {
  int np = 0;
  std::vector<double> dq, dv, da, dlambda;
};

// The accepted states of a run, in order (the initial state first), with the step that
// produced each (h[0] = 0): what the sweeps replay. Fill it with Recorder() as the
// integrator's step observer.
class HhtTrajectory {
 public:
  HhtTrajectory(int nq, int nc) : nq_(nq), nc_(nc) {}
  dae::StepObserver Recorder();
  void Clear();

  int nq() const { return nq_; }
  int nc() const { return nc_; }
  int size() const { return static_cast<int>(t_.size()); }
  double t(int n) const { return t_[n]; }
  double h(int n) const { return h_[n]; }
  const double* q(int n) const { return &q_[static_cast<size_t>(n) * nq_]; }
  const double* v(int n) const { return &v_[static_cast<size_t>(n) * nq_]; }
  const double* a(int n) const { return &a_[static_cast<size_t>(n) * nq_]; }
  const double* lambda(int n) const { return &lambda_[static_cast<size_t>(n) * nc_]; }
  // Bytes held.
  size_t memory() const;

 private:
  int nq_, nc_;
  std::vector<double> t_, h_, q_, v_, a_, lambda_;
};

struct HhtSensitivityResult {
  std::vector<double> values;    // G_i of the discrete run (n objectives)
  std::vector<double> gradient;  // dG_i/dp_k at [i * np + k]
  long linear_solves = 0;        // transposed (adjoint) or plain (forward) solves
  long factorizations = 0;
};

// The discrete adjoint. Returns false with *error set when an evaluation fails or a
// transposed step system cannot be solved.
bool HhtAdjointGradient(dae::MechanicalSystem& system, const dae::HhtOptions& options,
                        ObjectiveFunction& objective, const HhtTrajectory& trajectory,
                        const InitialStateDerivatives& dx0, HhtSensitivityResult* result,
                        std::string* error);

// Direct differentiation (forward sensitivities, np directions at once); the same
// numbers as the adjoint up to round-off.
bool HhtForwardGradient(dae::MechanicalSystem& system, const dae::HhtOptions& options,
                        ObjectiveFunction& objective, const HhtTrajectory& trajectory,
                        const InitialStateDerivatives& dx0, HhtSensitivityResult* result,
                        std::string* error);

}  // namespace mbdae::sens
