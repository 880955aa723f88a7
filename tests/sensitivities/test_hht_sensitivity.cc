// The HHT discrete adjoint and direct differentiation give the exact gradient of the
// discrete objective: they agree with central differences (Richardson-extrapolated) of
// whole runs with the same step sequence, and with each other to round-off. Classical
// scheme on a parametric pendulum (parameters in the mass matrix, the forces, the
// constraint and the initial position), both residual forms; the modified scheme on a
// heavy top (Euler parameters, gyroscopic terms) through its initial velocity.
#include <gtest/gtest.h>

#include <cmath>

#include "tests/sensitivities/hht_test_support.h"

namespace mbdae::hht_test {
namespace {

void PendulumCase(dae::HhtOptions::Form form) {
  dae::HhtOptions opt;
  opt.form = form;
  opt.alpha = -0.2;
  opt.step = 2e-3;
  opt.newton_tolerance = 1e-14;
  const double t_end = 0.6, out = 0.05;
  testing::ParametricPendulum sys(1.3, 0.9, 9.81, 0.4);
  PendulumObjectives obj(sys);
  const dae::State x0 = PendulumStart(sys);
  RecordedRun run = RunHht(sys, obj, opt, x0, t_end, out);

  // Raw initial derivatives: q = L (sin, -cos) moves with L, v = 0.
  const InitialStateDerivatives dx0 = PendulumInitialDerivatives(sys, x0);
  std::string err;

  HhtSensitivityResult adj, fwd;
  ASSERT_TRUE(sens::HhtAdjointGradient(sys, opt, obj, run.traj, dx0, &adj, &err)) << err;
  ASSERT_TRUE(sens::HhtForwardGradient(sys, opt, obj, run.traj, dx0, &fwd, &err)) << err;
  for (int j = 0; j < 2; ++j) {
    EXPECT_NEAR(adj.values[j], run.values[j], 1e-12 * (1 + std::abs(run.values[j])));
    EXPECT_NEAR(fwd.values[j], run.values[j], 1e-12 * (1 + std::abs(run.values[j])));
  }
  for (int k = 0; k < 4; ++k) {
    for (int j = 0; j < 2; ++j) {
      auto G = [&](double p) {
        testing::ParametricPendulum s2(1.3, 0.9, 9.81, 0.4);
        s2.parameter(k) = p;
        PendulumObjectives o2(s2);
        return RunHht(s2, o2, opt, PendulumStart(s2), t_end, out).values[j];
      };
      const double p0 = sys.parameter(k);
      const double fd = Richardson(G, p0, 1e-3 * std::abs(p0));
      const double a = adj.gradient[j * 4 + k], f = fwd.gradient[j * 4 + k];
      const double scale = std::max(std::abs(fd), 1e-3 * std::abs(run.values[j]));
      EXPECT_NEAR(a, fd, 1e-7 * scale) << "objective " << j << " parameter " << k;
      EXPECT_NEAR(a, f, 1e-11 * scale) << "objective " << j << " parameter " << k;
    }
  }
}

TEST(HhtSensitivity, PendulumEquilibriumFormAgreesWithFiniteDifferences) {
  PendulumCase(dae::HhtOptions::Form::kEquilibrium);
}

TEST(HhtSensitivity, PendulumNegrutFormAgreesWithFiniteDifferences) {
  PendulumCase(dae::HhtOptions::Form::kNegrut);
}

// Gradients with respect to the initial velocity along three directions, for the
// modified scheme (fixed and adaptive step) and the classical one.
void HeavyTopCase(bool modified, bool adaptive) {
  HeavyTop top;
  const int nq = top.nq, nc = top.nc, np = HeavyTop::np;
  PseudoParameters& sys = *top.sys;
  const dae::State& x0 = top.x0;
  const std::vector<double>& dirs = top.dirs;
  const InitialStateDerivatives& dx0 = top.dx0;
  std::string err;
  const dae::HhtOptions opt = HeavyTop::Options(modified, adaptive);
  const double t_end = adaptive ? 0.3 : 0.1, out = 0.05;
  StateObjectives obj(nq, nc);
  RecordedRun run = RunHht(sys, obj, opt, x0, t_end, out);
  ASSERT_GT(run.traj.size(), 10);
  HhtSensitivityResult adj, fwd;
  ASSERT_TRUE(sens::HhtAdjointGradient(sys, opt, obj, run.traj, dx0, &adj, &err)) << err;
  ASSERT_TRUE(sens::HhtForwardGradient(sys, opt, obj, run.traj, dx0, &fwd, &err)) << err;

  // The reference: the same step sequence replayed from perturbed initial velocities.
  dae::HhtOptions replay = opt;
  replay.adaptive = false;
  for (int n = 1; n < run.traj.size(); ++n) replay.replay_steps.push_back(run.traj.h(n));
  // The replay reproduces the run (to the Newton tolerance).
  const RecordedRun rep = RunHht(sys, obj, replay, x0, t_end, out);
  for (int j = 0; j < 2; ++j) EXPECT_NEAR(rep.values[j], run.values[j], 1e-10 * std::abs(run.values[j]));
  for (int j = 0; j < 2; ++j) {
    EXPECT_NEAR(adj.values[j], run.values[j], 1e-11 * (1 + std::abs(run.values[j])));
    for (int k = 0; k < np; ++k) {
      auto G = [&](double eps) {
        dae::State x = x0;
        for (int i = 0; i < nq; ++i) x.v[i] += eps * dirs[size_t(k) * nq + i];
        EXPECT_TRUE(dae::MakeConsistent(sys, x).ok);
        return RunHht(sys, obj, replay, x, t_end, out).values[j];
      };
      const double fd = Richardson(G, 0.0, 1e-3);
      const double a = adj.gradient[j * np + k], f = fwd.gradient[j * np + k];
      const double scale = std::max(std::abs(fd), 1e-3 * std::abs(run.values[j]));
      // The reference itself scatters by a few 1e-7 here: G1 integrates the large
      // multipliers of the spinning top, and whole runs carry the Newton iterations'
      // round-off floor (about 1e-10), which the differences amplify by 1/eps.
      EXPECT_NEAR(a, fd, 5e-7 * scale) << "objective " << j << " direction " << k;
      EXPECT_NEAR(a, f, 1e-9 * scale) << "objective " << j << " direction " << k;
    }
  }
}

TEST(HhtSensitivity, HeavyTopModifiedFixedStep) { HeavyTopCase(true, false); }
TEST(HhtSensitivity, HeavyTopModifiedAdaptiveStep) { HeavyTopCase(true, true); }
TEST(HhtSensitivity, HeavyTopClassicalAdaptiveStep) { HeavyTopCase(false, true); }

}  // namespace
}  // namespace mbdae::hht_test
