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
  double atol = 1e-10;
  double max_step = 0;      // 0: no limit
  double initial_step = 0;  // 0: IDA chooses
  int max_order = 5;
  long max_num_steps = 100000000;  // per AdvanceTo call

  bool IsValid(std::string* error) const;
};

std::unique_ptr<Integrator> MakeIdaIntegrator(MechanicalSystem& system, const IdaOptions& options);

}  // namespace mbdae::dae
