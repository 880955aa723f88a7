// SUNDIALS IDA on the stabilised index-2 (Gear-Gupta-Leimkuhler) form of a
// mechanical system:
//   q' = v - C_q^T mu,   M v' + C_q^T lambda = Q,   C(q, t) = 0,   C_q v + C_t = 0,
// with the analytic sparse Jacobian and KLU; lambda and mu are algebraic and left out
// of the error test.
#pragma once

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

  bool IsValid(std::string* error) const;
};

std::unique_ptr<Integrator> MakeIdaIntegrator(MechanicalSystem& system, const IdaOptions& options);

}  // namespace mbdae::dae
