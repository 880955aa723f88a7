// Hilber-Hughes-Taylor integrator for the index-3 form, after Negrut, Rampalli,
// Ottarsson, Sajdak, J. Comput. Nonlinear Dynam. 2 (2007) 73-85, with the
// modification for Euler parameters of Sherif, Nachbagauer, Steiner, Lauss,
// Multibody Syst. Dyn. 46 (2019) 181-202.
#pragma once

#include <memory>
#include <string>

#include "dae/integrator.h"

namespace mbdae::dae {

struct HhtOptions {
  // Which residual the step solves (docs/hht.md, "Forms"):
  //  kEquilibrium (default): the equations of motion hold exactly at t_{n+1},
  //    M(q_{n+1}) a_{n+1} + F_{n+1} = 0, and Newmark's formulas use the acceleration-like
  //    variable abar_{n+1} = (1 + alpha) a_{n+1} - alpha a_n: the generalized-alpha scheme
  //    of Arnold & Bruls, Multibody Syst. Dyn. 18 (2007) 185-202, with alpha_m = 0,
  //    alpha_f = -alpha (HHT's parameters). Second order in q and v also when M depends
  //    on q.
  //  kNegrut: the residual of Negrut et al. 2007, (M a)_{n+1}/(1+alpha) + F_{n+1}
  //    - alpha/(1+alpha) F_n = 0 (forces mixed at t_n and t_{n+1}); identical to the above
  //    for a constant M and linear forces, first order for alpha < 0 when M depends on q.
  enum class Form { kEquilibrium, kNegrut };
  Form form = Form::kEquilibrium;
  // Numerical damping, in [-1/3, 0]; beta = (1 - alpha)^2 / 4, gamma = 1/2 - alpha.
  double alpha = -0.1;
  // Step size: the fixed step, or the initial step when adaptive.
  double step = 1e-3;
  // Adaptive step size control on the local error estimate.
  bool adaptive = false;
  // Tolerance of the local error estimate (weighted RMS norm, relative and absolute
  // parts both equal to this value) when adaptive.
  double tolerance = 1e-6;
  double min_step = 1e-12;
  double max_step = 0;  // 0: no limit
  // true: the modified scheme for Euler parameters (Sherif et al. 2019); false: classical.
  bool modified = true;
  // Newton: stop when the weighted norm of the correction is below this fraction of the
  // tolerance (adaptive) or below newton_tolerance (fixed step).
  double newton_tolerance = 1e-12;
  // An iteration whose correction stops contracting (rate > 0.5) while its norm is below
  // newton_noise_factor * the Newton threshold has reached the round-off floor of the
  // linear solve and is accepted as converged (counted in Summary::newton_noise_stops).
  double newton_noise_factor = 1e4;
  int max_newton_iterations = 10;
  // One AdvanceTo call fails (with a message) after this many step attempts beyond the
  // number the nominal step needs to reach its target: the step size has collapsed
  // (as SUNDIALS' mxstep). 0: no limit.
  int max_steps_per_call = 100000;
  // Reuse the factorised Newton matrix across iterations and steps while the
  // convergence rate stays below this value.
  double jacobian_reuse_rate = 0.2;
  int max_steps_same_jacobian = 20;

  bool IsValid(std::string* error) const;
};

// "equilibrium" | "negrut"; and the inverse (false for an unknown name).
const char* HhtFormName(HhtOptions::Form form);
bool ParseHhtForm(const std::string& name, HhtOptions::Form* form);

std::unique_ptr<Integrator> MakeHhtIntegrator(MechanicalSystem& system, const HhtOptions& options);

}  // namespace mbdae::dae
