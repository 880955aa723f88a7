// Parameter derivatives of the consistent initial state (what the assembly computes,
// driver::Assemble and dae::MakeConsistent): positions projected onto C(q, t0) = 0,
// velocities onto C_q v + C_t = 0 with least change, then a, lambda from
//   [M  C_q^T; C_q  0] [a; lambda] = [Q; gamma].
// Given the derivatives of the raw initial guess (the model file's positions and
// velocities) with respect to the parameters, the consistent state's derivatives follow
// from differentiating these three steps (docs/sensitivities.md, "Initial state"):
//   positions   [I C_q^T; C_q 0] [dq; y] = [dq_raw; -C_p]
//               (the first-order change of the minimum-norm projection; exact when the
//               raw positions are consistent, i.e. the assembly did not move them)
//   velocities  [I C_q^T; C_q 0] [dv; dnu] = [dv_raw - d(C_q^T nu)/dq dq - d(C_q^T nu)/dp;
//                                             -d(C_q v + C_t)/dq dq - d(C_q v + C_t)/dp]
//               with nu the multiplier of the velocity projection, v_raw - v = C_q^T nu
//   a, lambda   [M C_q^T; C_q 0] [da; dlambda] = [dQ - d(M a) - d(C_q^T lambda);
//                                                 dgamma - d(C_q a)]   (total derivatives)
// The one derivative the system does not emit, d(gamma)/dq along dq (third derivatives
// of the constraints), is a central difference with Richardson extrapolation (error
// O(eps^4); exact for the polynomial joint equations, whose gamma is quadratic in q).
#pragma once

#include <string>
#include <vector>

#include "dae/integrator.h"
#include "dae/mechanical_system.h"
#include "sensitivities/hht_sensitivity.h"

namespace mbdae::sens {

// x0: the consistent initial state of `system` (the integrated one, independent
// equations only); v_raw: the raw velocities the projection started from; dq_raw, dv_raw:
// nq x np column-major derivatives of the raw initial guess. Returns false with *error
// when an evaluation fails or a matrix is singular.
bool ConsistentInitialStateDerivatives(dae::MechanicalSystem& system, const dae::State& x0,
                                       const std::vector<double>& v_raw,
                                       const std::vector<double>& dq_raw,
                                       const std::vector<double>& dv_raw,
                                       InitialStateDerivatives* out, std::string* error);

}  // namespace mbdae::sens
