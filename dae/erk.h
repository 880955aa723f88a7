// Explicit Runge-Kutta integration of the index-1 form with coordinate projection.
//
// The index-3 system M(q) a + C_q^T lambda = Q, C(q, t) = 0 is integrated as the ODE
// q' = v, v' = a(t, q, v), with a and lambda the solution of the acceleration-level
// equations [M C_q^T; C_q 0] [a; lambda] = [Q; gamma] (one sparse KLU factorisation per
// stage, dae/consistent.h AccelerationSolver), by the embedded pair of Dormand and Prince,
// 5th order with a 4th-order error estimate (J. R. Dormand, P. J. Prince, J. Comput.
// Appl. Math. 6 (1980) 19-26; coefficients and step-size control as in Hairer, Norsett,
// Wanner, Solving Ordinary Differential Equations I, 2nd ed., Springer 1993, II.4-II.5,
// Table 5.2). After every accepted step the positions are projected onto C(q, t) = 0
// and the velocities onto C_q v + C_t = 0 along the mass metric (the least change in
// kinetic-energy norm), with the matrix of the step's last stage:
//   [M C_q^T; C_q 0] [dq; mu] = [0; -C(q)],   [M C_q^T; C_q 0] [dv; mu] = [0; -(C_q v + C_t)]
// (coordinate projection, Hairer, Lubich, Wanner, Geometric Numerical Integration,
// 2nd ed., Springer 2006, IV.4; Hairer & Wanner, Solving ODEs II, VII.2). A step costs 6
// factorisations: the next step's first stage is the last stage (first same as last), at
// the 5th-order solution before its projection. At the end of AdvanceTo a and lambda are
// solved afresh at the projected state (one more factorisation per call): the state() a
// successful AdvanceTo leaves is consistent at all three levels and its a and lambda are
// those the acceleration-level equations give. After a failed AdvanceTo, state() is the
// last accepted step's, with the a and lambda of its last stage (O(local error) away).
//
// For smooth non-stiff scenes (open chains, free bodies, mechanisms away from singular
// positions) it takes far fewer steps than the second-order HHT or a BDF at tight
// tolerances. It is explicit: stiff forces make its steps as small as their time
// scale (the step budget ends such a run with a message), and at a singular position
// (the acceleration-level matrix loses rank) its stages fail; use hht or ida there.
#pragma once

#include <memory>
#include <string>

#include "dae/integrator.h"

namespace mbdae::dae {

struct ErkOptions {
  // Local error per step: weighted RMS over q and v of the difference of the 5th- and
  // 4th-order solutions, weights atol + rtol max(|y_n|, |y_n+1|) (Hairer et al. II.4).
  double rtol = 1e-6;
  double atol = 1e-8;
  // First step; 0: chosen from the initial state (Hairer et al. II.4, "Starting step size").
  double initial_step = 0;
  double max_step = 0;  // 0: no limit
  // Smallest step: a run whose step control asks for less fails with a message.
  double min_step = 0;  // 0: 1e-14 max(1, |t|)
  // Total accepted and rejected steps of the run; more fail it with a message.
  long max_steps = 100000000;
  // Coordinate projection after every step (see above). false: none (the constraints then
  // drift with the local errors; for studies of the projection only).
  bool project = true;
  // Newton iterations of the position projection (simplified: the matrix of the last
  // stage); it stops earlier when the correction is below 1e-3 of the error weights.
  int max_projection_iterations = 3;

  bool IsValid(std::string* error) const;
};

// `system`: independent constraints (a KeepConstraints view when some are redundant).
// Initialize needs a consistent state (MakeConsistent). No snapshots, step observer or
// sensitivities (the gradient runs use hht or ida). Quadratures are integrated with the
// method's 5th-order weights over the stages.
std::unique_ptr<Integrator> MakeErkIntegrator(MechanicalSystem& system, const ErkOptions& options);

}  // namespace mbdae::dae
