// The pendulum's angle by classical RK4 (tests/dae/test_hht.cc, test_erk.cc).
#pragma once

#include <cmath>

namespace mbdae::testing {

// The pendulum's angle from the downward vertical, theta'' = -(g/L) sin theta, from
// (theta0, omega0) to t_end by the classical 4th-order Runge-Kutta method with `steps`
// equal steps: a reference independent of the integrators under test and of the DAE form.
inline double PendulumAngleRk4(double theta0, double omega0, double g_over_L, double t_end,
                               int steps) {
  const double h = t_end / steps;
  double th = theta0, om = omega0;
  auto f = [&](double x) { return -g_over_L * std::sin(x); };
  for (int i = 0; i < steps; ++i) {
    const double k1t = om, k1o = f(th);
    const double k2t = om + 0.5 * h * k1o, k2o = f(th + 0.5 * h * k1t);
    const double k3t = om + 0.5 * h * k2o, k3o = f(th + 0.5 * h * k2t);
    const double k4t = om + h * k3o, k4o = f(th + h * k3t);
    th += h / 6 * (k1t + 2 * k2t + 2 * k3t + k4t);
    om += h / 6 * (k1o + 2 * k2o + 2 * k3o + k4o);
  }
  return th;
}

}  // namespace mbdae::testing
