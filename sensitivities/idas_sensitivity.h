// Gradients dG/dp of objectives (sensitivities/objective.h) of an IDA run
// (dae/ida.h: BDF on the stabilised index-2 GGL form y = (q, v, lambda, mu)) by IDAS:
//
// - IdasForwardGradient: forward sensitivity analysis. The np sensitivity systems
//     F_y s_k + F_y' s_k' + dF/dp_k = 0
//   (staggered corrector, sensitivities of q and v in the error test), with the initial
//   sensitivities of the consistent initial state (InitialStateDerivatives; mu and its
//   sensitivity are 0); the integral parts by quadrature sensitivities, the terminal
//   parts from the final sensitivities (s_v' from IDAS's interpolant). Objectives may
//   depend on t, q, v, a and lambda.
//
// - IdasAdjointGradient: adjoint sensitivity analysis (checkpointed forward run, one
//   backward problem per objective). The adjoint of the GGL form,
//     (F_y'^T chi)' - F_y^T chi = -g_y^T,     chi = (chi1, chi2, chi3, chi4),
//   is again a Hessenberg index-2 system (chi1, chi2 differential; chi3, chi4
//   algebraic; constraints C_q chi1 = 0 and C_q chi2 = g_lambda^T). Following Cao, Li,
//   Petzold, Serban (SIAM J. Sci. Comput. 24 (2003) 1076-1089), its terminal values
//   must satisfy those constraints, which the terminal part phi(q, v) of an objective
//   cannot in general; they are made so with multipliers alpha, beta:
//     M chi2(T) + C_q^T beta = phi_v^T,               C_q chi2(T) = 0,
//     chi1(T) = phi_q^T - C_q^T alpha - V_q^T beta,  C_q chi1(T) = 0   (V_q = d(C_q v + C_t)/dq),
//   which is exact because the sensitivities satisfy C_q s_q = -C_p and
//   V_q s_q + C_q s_v = -V_p at T:
//     dG/dp = int (g_p - chi^T F_p) dt + phi_p - alpha^T C_p - beta^T V_p
//             + chi1(t0)^T dq0/dp + chi2(t0)^T M dv0/dp.
//   chi3(T), chi4(T) and chi'(T) are computed consistently (the derivatives of the two
//   constraints). M alone is singular for bodies with Euler parameters (4 G^T J G e = 0)
//   and massless bodies: every M^-1 of these formulas is a solve with the saddle-point
//   matrix [M C_q^T; C_q 0], which must be regular (refused with a message otherwise). Supported: g(t, q, v, p) and phi(T, q, v, p). Refused with a message:
//   objectives that depend on a or lambda (ObjectiveFunction::depends_on_acceleration /
//   depends_on_multipliers): g_lambda makes C_q chi2(T) = g_lambda, so chi2(T) != 0 and
//   the boundary term chi2^T M s_v(T) would need the forward sensitivities the adjoint
//   avoids; a dependence on a would need the time derivative of g_a. Use the forward
//   method for those. The backward Jacobian includes dM/dt (by d(M a)/dq v over a
//   colouring of the columns of M). The backward residual evaluates the GGL Jacobian (F_y^T chi) at every call: simple,
//   not cheap for large systems. C_q must have full row rank (independent constraints,
//   as the IDA integrator needs anyway). The adjoint's forward run factorises every
//   Jacobian afresh (no KLU refactorisation): IDAS's replay of a checkpoint interval must
//   repeat the run's steps bit for bit, or it writes past its storage of the interval.
//
// Both methods run with the IDA integrator's settings (IdaOptions). The forward method
// stops at each requested output time like a simulation does; the adjoint ignores the
// output times and goes straight to t_end (IDAS replays checkpoint intervals with the
// last stop time only, and intermediate interpolated returns of IDASolveF corrupted the
// quadratures), which changes the run by the integration error, not the gradient's
// meaning. Errors are returned as messages; nothing escapes into SUNDIALS callbacks.
#pragma once

#include <string>
#include <vector>

#include "dae/ida.h"
#include "dae/integrator.h"
#include "dae/mechanical_system.h"
#include "sensitivities/hht_sensitivity.h"
#include "sensitivities/objective.h"

namespace mbdae::sens {

struct IdasSensitivityOptions {
  dae::IdaOptions ida;  // the forward run (and the tolerances of every IDAS problem)
  double t_end = 0;     // end of the run (> x0.t): T of the objectives
  // Intermediate output times, strictly increasing in (x0.t, t_end); the run stops at
  // each exactly (IDASetStopTime) as a simulation writing rows does. Empty: straight to
  // t_end.
  std::vector<double> output_times;
  // Adjoint: forward steps between two checkpoints (IDAAdjInit). IDAS stores the
  // forward solution at every step of one interval at a time (n doubles per step) and
  // refreshes the Jacobian at every checkpoint, which changes the forward step sequence
  // (on the pendulum at rtol 1e-10: 449 steps with an interval of 10, 822 with 200,
  // 941 with none), not the gradient beyond the tolerances.
  long checkpoint_steps = 200;
  // Adjoint: interpolation of the forward solution between its steps. Polynomial (the
  // BDF interpolant, IDA_POLYNOMIAL) by default; Hermite (IDA_HERMITE) uses y' of the
  // algebraic variables lambda, mu, which the index-2 form leaves rough, and has made
  // the backward error test fail on the pendulum.
  bool hermite_interpolation = false;

  bool IsValid(std::string* error) const;
};

struct IdasSensitivityResult {
  std::vector<double> values;    // G_i (n objectives)
  std::vector<double> gradient;  // dG_i/dp_k at [i * np + k]
  long steps = 0;                // forward steps
  long backward_steps = 0;       // adjoint: backward steps summed over the objectives
  long checkpoints = 0;          // adjoint
  long error_test_failures = 0;  // forward (state and sensitivities)
  double wall_time = 0;          // seconds, the whole computation
  double cpu_time = 0;           // seconds of process CPU time
};

// Both return false with *error set (and *result partly filled) on failure: invalid
// options or sizes, a failed IDAS run, a failed system or objective evaluation, and
// for the adjoint an objective it does not support.
bool IdasForwardGradient(dae::MechanicalSystem& system, const IdasSensitivityOptions& options,
                         ObjectiveFunction& objective, const dae::State& x0,
                         const InitialStateDerivatives& dx0, IdasSensitivityResult* result,
                         std::string* error);

bool IdasAdjointGradient(dae::MechanicalSystem& system, const IdasSensitivityOptions& options,
                         ObjectiveFunction& objective, const dae::State& x0,
                         const InitialStateDerivatives& dx0, IdasSensitivityResult* result,
                         std::string* error);

}  // namespace mbdae::sens
