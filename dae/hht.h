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
  // Reuse the factorised Newton matrix across iterations and steps while the
  // convergence rate stays below this value.
  double jacobian_reuse_rate = 0.2;
  int max_steps_same_jacobian = 20;

  bool IsValid(std::string* error) const;
};

std::unique_ptr<Integrator> MakeHhtIntegrator(MechanicalSystem& system, const HhtOptions& options);

}  // namespace mbdae::dae
