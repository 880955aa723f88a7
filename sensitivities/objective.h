// Objectives of a run, as the sensitivity solvers see them: n functionals
//
//   G_i = integral_{t0}^{T} g_i(t, q, v, a, lambda, p) dt + phi_i(T, q, v, a, lambda, p)
//
// of the trajectory of a dae::MechanicalSystem (lambda: the multipliers of that system's
// constraint equations) and of its parameters p (MechanicalSystem::num_parameters()).
// The integral is discretised by the integrator that computes the run (dae::Quadrature);
// the solvers differentiate that discretisation. Like the system, an objective knows
// nothing of the multibody model: mbs-side implementations map measures and reactions
// onto it (sensitivities/model_objectives.h).
#pragma once

#include <string>
#include <vector>

namespace mbdae::sens {

// Where to evaluate: the time and the state; lambda has the system's nc entries.
struct ObjectivePoint {
  double t = 0;
  const double* q = nullptr;
  const double* v = nullptr;
  const double* a = nullptr;
  const double* lambda = nullptr;
};

// First derivatives of sum_i w_i f_i (f = g or phi) at a point: dense vectors, each
// ADDED to (so callers may accumulate); a null pointer is not computed.
struct ObjectiveGradient {
  double* dq = nullptr;       // nq
  double* dv = nullptr;       // nq
  double* da = nullptr;       // nq
  double* dlambda = nullptr;  // nc
  double* dp = nullptr;       // np
};

// Return codes as dae::MechanicalSystem::Evaluate: 0 success, nonzero failure (the
// reason in last_error()).
class ObjectiveFunction {
 public:
  virtual ~ObjectiveFunction() = default;

  virtual int num_objectives() const = 0;
  virtual const std::vector<std::string>& names() const = 0;
  // Whether objective i has an integral part / a terminal part (zero otherwise).
  virtual bool has_integral(int i) const = 0;
  virtual bool has_terminal(int i) const = 0;
  // Whether any integrand or terminal value depends on a (accelerations) or on lambda
  // (reactions): solvers that cannot treat such a dependence refuse the objective.
  virtual bool depends_on_acceleration() const = 0;
  virtual bool depends_on_multipliers() const = 0;

  // g (n values) or phi (n values) at a point.
  virtual int Integrand(const ObjectivePoint& x, double* g) = 0;
  virtual int Terminal(const ObjectivePoint& x, double* phi) = 0;
  // The gradient of sum_i weights[i] g_i (or phi_i) at x, added into *out.
  virtual int IntegrandGradient(const ObjectivePoint& x, const double* weights,
                                ObjectiveGradient* out) = 0;
  virtual int TerminalGradient(const ObjectivePoint& x, const double* weights,
                               ObjectiveGradient* out) = 0;

  virtual const char* last_error() const { return ""; }
};

}  // namespace mbdae::sens
