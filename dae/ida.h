// SUNDIALS IDA on the stabilised index-2 (Gear-Gupta-Leimkuhler) form of a
// mechanical system:
//   q' = v - C_q^T mu,   M v' + C_q^T lambda = Q,   C(q, t) = 0,   C_q v + C_t = 0,
// with the analytic sparse Jacobian and KLU; lambda and mu are algebraic and left out
// of the error test. Near singular positions (C_q losing rank) the Newton iteration
// stops at the rounding level of the residual and the error weights allow for the
// resolution of the nearly singular iteration matrix (IdaOptions::roundoff_factor,
// internal::GglRounding), and a failed run starts again from an earlier step
// (IdaOptions::max_restarts), so that IDA passes them. IDA is called one step at a time (IDA_ONE_STEP with the output time
// as stop time): the step observer (Integrator::SetStepObserver) sees every step, and a
// run ends with a message naming t and h when it exceeds its step budget or its steps
// collapse (IdaOptions::max_steps, min_relative_step).
#pragma once

#include <limits>
#include <memory>
#include <string>

#include "dae/integrator.h"

namespace mbdae::dae {

struct IdaOptions {
  double rtol = 1e-8;
  double atol = 1e-10;        // absolute tolerance of q and v
  // Absolute tolerance of lambda and mu. They are left out of the error test, so it
  // only enters IDA's Newton convergence test; 0: left out of that test as well (the
  // index-2 iteration matrix is ill-conditioned at small steps and their round-off
  // would stall the Newton iteration when tolerances are tight).
  double algebraic_atol = 0;
  double max_step = 0;      // 0: no limit
  // 0: no limit. A recoverable system error that persists beyond some time otherwise
  // lets IDA creep towards that time with ever smaller steps until max_num_steps.
  double min_step = 0;
  double initial_step = 0;  // 0: IDA chooses
  int max_order = 5;
  long max_num_steps = 100000000;  // per AdvanceTo call
  // Total steps from Initialize; the run fails when a further step would be needed
  // (0: no limit). A run that creeps with ever smaller steps (a singular configuration
  // the corrector cannot pass, a stiffness beyond what the tolerances resolve) ends here
  // instead of running for hours.
  long max_steps = 100000000;  // 1e8: a 1310 s pendulum at rtol 1e-10 takes over 1e6
  // The run fails after 20 steps in a row with h < min_relative_step * max(1, |t|): at
  // such steps the time barely advances (1e-14 at t = 1 is 45 units in the last place
  // of t). 20, because IDA's first step may be that small and doubles from there. 0: no
  // such rule.
  double min_relative_step = 1e-14;
  // Two rules for singular positions, with this factor (internal::GglRounding), that
  // apply where the resolution r of the Newton solution (the response of the matrix of
  // the last setup to residuals at roundoff_factor times their rounding level) exceeds
  // 10 times rtol |y| + atol for some q or v: a Newton iterate whose residual is, in
  // every row, within roundoff_factor times its rounding level gets a zero correction
  // (converged: near a singular position the correction computed from such a residual
  // is rounding error amplified by the nearly singular iteration matrix); and the error
  // weights are 1 / (rtol |y| + atol + r), so that neither the error test nor the
  // convergence test asks for accuracy below r. 0: neither rule.
  double roundoff_factor = 8;
  // A run that fails (IDA's error, or min_relative_step) starts again from the oldest of
  // its last 10 accepted steps (IDAReInit: order 1, a new sequence of steps), at most
  // this many times in a row; the step observer then sees steps again from that earlier
  // time. Not with quadratures. 0: no restarts.
  int max_restarts = 3;
  // Dense output (docs/dense-output.md): false (default): every AdvanceTo target
  // is a stop time of IDA (IDASetStopTime: the steps land on it). true: IDA's steps do
  // not depend on the targets; AdvanceTo steps until it reaches or passes the target and
  // state() is IDA's interpolating polynomial there (IDAGetDky: q, v, lambda from y, a
  // from y'; the quadrature from IDAGetQuadDky). The steps land on stop_time instead
  // (infinity: no stop time; AdvanceTo beyond it fails).
  bool dense_output = false;
  // The linear solver of the iteration matrix: kKlu (default) or kTree, the block
  // elimination along the tree of bodies (dae/block_tree_lu.h; each node a body's q, v
  // and the lambda, mu of its own rows and of the joint to its parent), KLU where the
  // system is no tree and from the first factorisation on whose solve's backward error
  // exceeds 1e-12 (Summary::linear_solver, klu_fallbacks; see TreeSetup in ida.cc).
  LinearSolverKind linear_solver = LinearSolverKind::kKlu;
  double stop_time = std::numeric_limits<double>::infinity();

  bool IsValid(std::string* error) const;
};

std::unique_ptr<Integrator> MakeIdaIntegrator(MechanicalSystem& system, const IdaOptions& options);

}  // namespace mbdae::dae
