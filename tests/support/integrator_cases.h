// Pieces the integrator tests share (tests/dae/test_ida.cc, test_erk.cc): a consistent
// initial state, the closed form of the pendulum's period, and a pendulum whose
// evaluation fails after a given time.
#pragma once

#include <gtest/gtest.h>

#include <cmath>
#include <utility>
#include <vector>

#include "dae/consistent.h"
#include "dae/integrator.h"
#include "tests/support/pendulum_system.h"

namespace mbdae::testing {

// x0 at (t, q, v) made consistent (MakeConsistent: a and lambda solved); a failure is a
// test failure.
inline dae::State ConsistentState(dae::MechanicalSystem& sys, std::vector<double> q,
                                  std::vector<double> v, double t = 0) {
  dae::State x;
  x.t = t;
  x.q = std::move(q);
  x.v = std::move(v);
  const auto report = dae::MakeConsistent(sys, x);
  EXPECT_TRUE(report.ok) << report.message;
  return x;
}

// Complete elliptic integral of the first kind by the arithmetic-geometric mean:
// K(k) = pi / (2 AGM(1, sqrt(1 - k^2))) (Abramowitz & Stegun 17.6).
inline double EllipticK(double k) {
  double a = 1.0, b = std::sqrt(1.0 - k * k);
  for (int i = 0; i < 50 && std::abs(a - b) > 1e-16 * a; ++i) {
    const double an = 0.5 * (a + b);
    b = std::sqrt(a * b);
    a = an;
  }
  return 3.14159265358979323846 / (2 * a);
}

// A pendulum (1 kg, 1 m) whose evaluation returns `code` beyond t_fail, with the reason
// "joint 7 broke".
class FailingPendulum : public PendulumSystem {
 public:
  FailingPendulum(double t_fail, int code) : PendulumSystem(1, 1, 9.81), t_fail_(t_fail), code_(code) {}
  int Evaluate(const dae::EvalInput& in, dae::EvalOutput& out) override {
    if (in.t > t_fail_) return code_;
    return PendulumSystem::Evaluate(in, out);
  }
  const char* last_error() const override { return "joint 7 broke"; }

 private:
  double t_fail_;
  int code_;
};

}  // namespace mbdae::testing
