// Kinematic analysis of a mechanical system without degrees of freedom: every
// coordinate is fixed by the constraints (and the constraints' time dependence, i.e.
// the driven motions), so the state at a time t follows from t alone:
//
//   C(q, t) = 0                            Newton on the positions (KLU on C_q; once
//                                          converged, one more correction with the
//                                          factorisation the velocities use),
//   C_q v = -C_t                           the velocities,
//   [M C_q^T; C_q 0] [a; lambda] = [Q; gamma]   accelerations and multipliers
//                                          (the AccelerationSolver of dae/consistent.h;
//                                          with a square C_q: C_q a = gamma, then
//                                          C_q^T lambda = Q - M a).
//
// This is the inverse-dynamics analysis of Adams (SIMULATE/KINEMATIC) and MBDyn's
// inverse dynamics problem. The solver offers the Integrator interface, so the driver,
// the C API and the results file treat it like HHT and IDA: AdvanceTo(t) solves at t
// (the Newton iteration started from the previous solution extrapolated with its
// velocity and acceleration, q + h v + h^2/2 a); there is no time step and no
// integration error, only the Newton tolerance.
//
// The system must have as many independent constraint equations as coordinates
// (num_constraints() == num_coordinates(): a KeepConstraints view without the redundant
// equations); MakeKinematicSolver throws std::invalid_argument otherwise, naming the
// number of degrees of freedom. Where C_q is (numerically) singular, e.g. at a dead
// centre the drive passes, the point is solved as the consistent initial values are
// (dae::MakeConsistent: minimum-norm Gauss-Newton steps, redundant equations found at
// that point, their multipliers 0); if that fails too (the driven motion cannot be
// followed: a lock-up, a position out of reach) AdvanceTo fails with a message naming t
// and the residual.
//
// Quadratures (the integral parts of objectives) use adaptive Simpson on every interval
// between two AdvanceTo targets: Simpson's rule on the interval and on its halves (four
// more solves), the interval halved until the two agree to quadrature_tolerance; without
// a quadrature nothing but the targets is solved.
#pragma once

#include <memory>
#include <string>

#include "dae/integrator.h"

namespace mbdae::dae {

struct KinematicOptions {
  // Newton converges when max |C(q, t)| <= tolerance * max(1, max |q|).
  double tolerance = 1e-12;
  // Newton iterations allowed at one time before the solve fails.
  int max_iterations = 25;
  // KLU's reciprocal condition estimate of C_q below which C_q is treated as singular
  // (the point is then solved by dae::MakeConsistent).
  double singular_rcond = 1e-14;
  // Adaptive Simpson: an interval's Simpson value S and the sum S2 of its halves' are
  // accepted (as S2 + (S2 - S) / 15) when |S2 - S| <= 15 quadrature_tolerance (integral
  // of |g| over the interval + its length), per integrand; else each half is treated
  // the same way, at most max_quadrature_depth times halved.
  double quadrature_tolerance = 1e-10;
  int max_quadrature_depth = 20;
  bool IsValid(std::string* error) const;
};

// The counters beyond dae::Summary: Summary::newton_iterations is the total over all
// solved times (midpoints of quadratures included), steps_accepted the number of solved
// times; these add the largest count at one time and the number of times solved by the
// minimum-norm fallback.
struct KinematicStatistics {
  int max_newton_iterations = 0;  // the most Newton iterations at one solved time
  long singular_points = 0;       // times where C_q was singular (solved by MakeConsistent)
  int max_quadrature_depth = 0;   // the most halvings of an output interval (quadrature)
};

class KinematicSolver : public Integrator {
 public:
  virtual const KinematicStatistics& statistics() const = 0;
};

// Throws std::invalid_argument for invalid options or a system whose number of
// constraint equations is not its number of coordinates.
std::unique_ptr<KinematicSolver> MakeKinematicSolver(MechanicalSystem& system,
                                                     const KinematicOptions& options = {});

}  // namespace mbdae::dae
