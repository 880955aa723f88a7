// IDA on the stabilised index-2 form: Jacobian against finite differences, the
// pendulum period against the closed form, redundant constraints, failures, repeatability.
#include "dae/ida.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <random>
#include <stdexcept>
#include <vector>

#include "dae/consistent.h"
#include "dae/ida_internal.h"
#include "tests/support/integrator_cases.h"
#include "tests/support/nonlinear_system.h"
#include "tests/support/parametric_pendulum.h"
#include "tests/support/pendulum_system.h"

namespace mbdae::dae {
namespace {

using testing::ConsistentState;
using testing::EllipticK;
using testing::FailingPendulum;
using testing::NonlinearSystem;
using testing::PendulumSystem;

constexpr double kPi = 3.14159265358979323846;

// dF/dy + cj dF/dy' of the GGL residual against central differences at random points.
void CheckJacobian(MechanicalSystem& sys, unsigned seed) {
  internal::GglResidual ggl(sys);
  const int n = ggl.size();
  const CscPattern& p = ggl.jacobian_pattern();
  std::string why;
  ASSERT_TRUE(p.IsValid(&why)) << why;
  ASSERT_EQ(p.rows, n);
  ASSERT_EQ(p.cols, n);
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> U(-1.0, 1.0);
  for (int trial = 0; trial < 3; ++trial) {
    std::vector<double> y(n), yp(n), J(p.nnz()), Fp(n), Fm(n);
    for (double& e : y) e = U(rng);
    for (double& e : yp) e = U(rng);
    const double t = 0.5 + U(rng), cj = 10 * (1.5 + U(rng));
    ASSERT_EQ(ggl.Jacobian(t, cj, y.data(), yp.data(), J.data()), 0);
    const double h = 1e-6;
    double max_err = 0, max_entry = 0;
    for (int c = 0; c < n; ++c) {
      // Column c of dF/dy + cj dF/dy': perturb y_c by h and y'_c by cj h together.
      std::vector<double> y1 = y, yp1 = yp, y2 = y, yp2 = yp;
      y1[c] += h; yp1[c] += cj * h;
      y2[c] -= h; yp2[c] -= cj * h;
      ASSERT_EQ(ggl.Residual(t, y1.data(), yp1.data(), Fp.data()), 0);
      ASSERT_EQ(ggl.Residual(t, y2.data(), yp2.data(), Fm.data()), 0);
      for (int r = 0; r < n; ++r) {
        const double fd = (Fp[r] - Fm[r]) / (2 * h);
        const int k = p.find(r, c);
        const double an = k >= 0 ? J[k] : 0.0;
        if (k < 0) {
          EXPECT_EQ(fd, 0.0) << "entry (" << r << ", " << c << ") not in the pattern";
        }
        max_err = std::max(max_err, std::abs(fd - an));
        max_entry = std::max(max_entry, std::abs(an));
        EXPECT_NEAR(an, fd, 1e-7 * (1 + std::abs(an))) << "entry (" << r << ", " << c << ")";
      }
    }
    EXPECT_GT(max_entry, 1.0);  // the test sees real numbers
  }
}

TEST(GglResidual, JacobianMatchesFiniteDifferences) {
  NonlinearSystem nonlinear;
  CheckJacobian(nonlinear, 1);
  PendulumSystem pendulum(1.3, 0.8, 9.81);
  CheckJacobian(pendulum, 2);
  PendulumSystem redundant(1.3, 0.8, 9.81, true);
  CheckJacobian(redundant, 3);
}

TEST(GglResidual, VanishesAtAConsistentState) {
  NonlinearSystem sys;
  State x = ConsistentState(sys, {0.5, 0.3, 0.7}, {0.2, -0.4, 0.9}, 0.35);
  internal::GglResidual ggl(sys);
  const int nq = 3, nc = 2, n = ggl.size();
  std::vector<double> y(n, 0.0), yp(n, 0.0), F(n);
  for (int i = 0; i < nq; ++i) {
    y[i] = x.q[i]; y[nq + i] = x.v[i];
    yp[i] = x.v[i]; yp[nq + i] = x.a[i];
  }
  for (int r = 0; r < nc; ++r) y[2 * nq + r] = x.lambda[r];
  ASSERT_EQ(ggl.Residual(x.t, y.data(), yp.data(), F.data()), 0);
  for (int i = 0; i < n; ++i) EXPECT_NEAR(F[i], 0.0, 1e-12) << i;
}

// Released at rest from the horizontal (theta0 = pi/2): x crosses 0 at (2j + 1) T / 4
// with T = 4 sqrt(L/g) K(sin(theta0/2)).
TEST(IdaIntegrator, PendulumPeriodMatchesEllipticIntegral) {
  const double m = 1.0, L = 1.0, g = 9.81;
  PendulumSystem sys(m, L, g);
  const double T = 4 * std::sqrt(L / g) * EllipticK(std::sin(kPi / 4));
  IdaOptions options;
  options.rtol = 1e-11;
  options.atol = 1e-11;
  auto ida = MakeIdaIntegrator(sys, options);
  ida->Initialize(ConsistentState(sys, {L, 0.0}, {0.0, 0.0}));
  std::vector<double> crossings;
  for (int j = 0; j < 3; ++j) {
    const double guess = (2 * j + 1) * T / 4;
    ASSERT_TRUE(ida->AdvanceTo(guess)) << ida->summary().message;
    const State& s = ida->state();
    EXPECT_EQ(s.t, guess);
    // At the bottom x'' = 0, so one Newton step in time is accurate to O(x^3).
    crossings.push_back(s.t - s.q[0] / s.v[0]);
    // The index-2 form keeps both constraint levels.
    EXPECT_NEAR(s.q[0] * s.q[0] + s.q[1] * s.q[1], L * L, 1e-10);
    EXPECT_NEAR(s.q[0] * s.v[0] + s.q[1] * s.v[1], 0.0, 1e-9);
    // lambda at the bottom: m (v^2 + g L) / (2 L^2) with v^2 = 2 g L.
    EXPECT_NEAR(s.lambda[0], 3 * m * g / (2 * L), 1e-6);
  }
  const double period = crossings[2] - crossings[0];
  EXPECT_NEAR(period / T, 1.0, 1e-8) << "measured " << period << ", closed form " << T;
  for (int j = 0; j < 3; ++j) EXPECT_NEAR(crossings[j] / ((2 * j + 1) * T / 4), 1.0, 1e-8);
  const Summary& sum = ida->summary();
  EXPECT_EQ(sum.status, Summary::Status::kRunning);
  EXPECT_GT(sum.steps_accepted, 100);
  EXPECT_GT(sum.newton_iterations, sum.steps_accepted);
  EXPECT_GT(sum.jacobian_evaluations, 0);
  EXPECT_GE(sum.factorizations, sum.jacobian_evaluations);
  EXPECT_GT(sum.residual_evaluations, sum.steps_accepted);
  EXPECT_GT(sum.h_last, 0.0);
  EXPECT_EQ(sum.t_reached, ida->state().t);
}

// Global error against a tight reference shrinks with the tolerance, and the
// constraints of the time-dependent system hold at every output.
TEST(IdaIntegrator, NonlinearSystemConvergesWithTolerance) {
  NonlinearSystem sys;
  const State x0 = ConsistentState(sys, {0.5, 0.3, 0.7}, {0.2, -0.4, 0.9});
  auto run = [&](double tol) {
    IdaOptions options;
    options.rtol = options.atol = tol;
    auto ida = MakeIdaIntegrator(sys, options);
    ida->Initialize(x0);
    for (int k = 1; k <= 10; ++k) {
      EXPECT_TRUE(ida->AdvanceTo(0.1 * k)) << ida->summary().message;
      const State& s = ida->state();
      const double c0 = s.q[0] * s.q[0] + s.q[1] * s.q[1] + s.q[2] * s.q[2] - 1;
      const double c1 = s.q[0] - s.q[2] * std::cos(s.t) - 0.1 * s.t;
      EXPECT_LT(std::abs(c0) + std::abs(c1), 100 * tol);
    }
    return ida->state();
  };
  const State ref = run(1e-12);
  double err[2];
  const double tols[2] = {1e-5, 1e-8};
  for (int i = 0; i < 2; ++i) {
    const State s = run(tols[i]);
    err[i] = 0;
    for (int j = 0; j < 3; ++j) err[i] = std::max(err[i], std::abs(s.q[j] - ref.q[j]));
  }
  EXPECT_LT(err[0], 1e-3);
  EXPECT_LT(err[1], 1e-6);
  EXPECT_LT(err[1], 1e-2 * err[0]);  // three orders of tolerance: at least two of error
}

TEST(IdaIntegrator, RedundantPendulumWithKeptConstraintsMovesLikeThePlainOne) {
  const double m = 1.0, L = 1.0, g = 9.81;
  PendulumSystem plain(m, L, g), redundant(m, L, g, true);
  IdaOptions options;
  options.rtol = options.atol = 1e-10;

  State xp;
  xp.q = {0.8, -0.6};
  xp.v = {0.5, 0.2};
  State xr = xp;
  ASSERT_TRUE(MakeConsistent(plain, xp).ok);
  const auto report = MakeConsistent(redundant, xr);
  ASSERT_TRUE(report.ok) << report.message;
  ASSERT_EQ(report.redundant, std::vector<int>({1}));

  auto ida_plain = MakeIdaIntegrator(plain, options);
  ida_plain->Initialize(xp);
  ASSERT_TRUE(ida_plain->AdvanceTo(1.5)) << ida_plain->summary().message;

  // Keeping equation 0 is the plain pendulum; keeping only the scaled copy (equation 1)
  // is the same motion with half the multiplier.
  for (int keep : {0, 1}) {
    auto view = KeepConstraints(redundant, {keep});
    State x0 = xr;
    x0.lambda = {keep == 0 ? xr.lambda[0] : 0.5 * xr.lambda[0]};
    auto ida = MakeIdaIntegrator(*view, options);
    ida->Initialize(x0);
    ASSERT_TRUE(ida->AdvanceTo(1.5)) << ida->summary().message;
    const State& a = ida_plain->state();
    const State& b = ida->state();
    const double scale = keep == 0 ? 1.0 : 0.5;
    for (int i = 0; i < 2; ++i) {
      EXPECT_NEAR(b.q[i], a.q[i], 1e-8) << keep;
      EXPECT_NEAR(b.v[i], a.v[i], 1e-7) << keep;
    }
    EXPECT_NEAR(b.lambda[0], scale * a.lambda[0], 1e-6 * std::abs(a.lambda[0])) << keep;
  }
}

TEST(IdaIntegrator, SameRunTwiceGivesIdenticalResults) {
  NonlinearSystem sys;
  const State x0 = ConsistentState(sys, {0.5, 0.3, 0.7}, {0.2, -0.4, 0.9});
  IdaOptions options;
  options.rtol = options.atol = 1e-8;
  auto ida = MakeIdaIntegrator(sys, options);
  std::vector<State> first;
  Summary first_summary;
  for (int run = 0; run < 2; ++run) {
    ida->Initialize(x0);  // the same integrator object, re-initialised
    for (int k = 1; k <= 5; ++k) {
      ASSERT_TRUE(ida->AdvanceTo(0.2 * k)) << ida->summary().message;
      if (run == 0) {
        first.push_back(ida->state());
        continue;
      }
      const State& s = ida->state();
      const State& f = first[k - 1];
      EXPECT_EQ(s.t, f.t);
      for (int i = 0; i < 3; ++i) {
        EXPECT_EQ(s.q[i], f.q[i]);
        EXPECT_EQ(s.v[i], f.v[i]);
        EXPECT_EQ(s.a[i], f.a[i]);
      }
      for (int r = 0; r < 2; ++r) EXPECT_EQ(s.lambda[r], f.lambda[r]);
    }
    if (run == 0) first_summary = ida->summary();
  }
  EXPECT_EQ(ida->summary().steps_accepted, first_summary.steps_accepted);
  EXPECT_EQ(ida->summary().newton_iterations, first_summary.newton_iterations);
  EXPECT_EQ(ida->summary().residual_evaluations, first_summary.residual_evaluations);
  // A second integrator object with the same output times gives the same numbers too.
  auto other = MakeIdaIntegrator(sys, options);
  other->Initialize(x0);
  for (int k = 1; k <= 5; ++k) ASSERT_TRUE(other->AdvanceTo(0.2 * k));
  for (int i = 0; i < 3; ++i) EXPECT_EQ(other->state().q[i], first.back().q[i]);
}

TEST(IdaIntegrator, SystemFailureIsReported) {
  for (int code : {-1, 1}) {
    FailingPendulum sys(0.3, code);
    IdaOptions options;
    options.min_step = 1e-10;
    auto ida = MakeIdaIntegrator(sys, options);
    ida->Initialize(ConsistentState(sys, {0.6, -0.8}, {0, 0}));
    EXPECT_FALSE(ida->AdvanceTo(1.0));
    const Summary& s = ida->summary();
    EXPECT_EQ(s.status, Summary::Status::kFailed);
    EXPECT_NE(s.message.find("joint 7 broke"), std::string::npos) << s.message;
    EXPECT_NE(s.message.find(code < 0 ? "unrecoverable" : "recoverable"), std::string::npos)
        << s.message;
    EXPECT_NE(s.message.find("IDA_"), std::string::npos) << s.message;  // the flag's name
    EXPECT_LE(ida->state().t, 0.3);
    EXPECT_GT(ida->state().t, 0.2);
    EXPECT_EQ(s.t_reached, ida->state().t);
    EXPECT_FALSE(ida->AdvanceTo(2.0));  // stays failed
  }
}

TEST(IdaIntegrator, TooFewStepsIsReported) {
  PendulumSystem sys(1, 1, 9.81);
  IdaOptions options;
  options.max_num_steps = 5;
  auto ida = MakeIdaIntegrator(sys, options);
  ida->Initialize(ConsistentState(sys, {0.6, -0.8}, {0, 0}));
  EXPECT_FALSE(ida->AdvanceTo(10.0));
  EXPECT_NE(ida->summary().message.find("IDA_TOO_MUCH_WORK"), std::string::npos)
      << ida->summary().message;
  EXPECT_GT(ida->state().t, 0.0);
  EXPECT_LT(ida->state().t, 10.0);
}

TEST(IdaOptions, ValidationAndMisuse) {
  std::string why;
  EXPECT_TRUE(IdaOptions{}.IsValid(&why));
  IdaOptions o;
  o.rtol = -1;
  EXPECT_FALSE(o.IsValid(&why));
  EXPECT_NE(why.find("rtol"), std::string::npos);
  o = {};
  o.max_order = 6;
  EXPECT_FALSE(o.IsValid(&why));
  IdaOptions steps;
  steps.max_step = 1e-3;
  steps.min_step = 1e-2;
  EXPECT_FALSE(steps.IsValid(&why));
  EXPECT_NE(why.find("min_step"), std::string::npos);
  PendulumSystem sys(1, 1, 9.81);
  EXPECT_THROW(MakeIdaIntegrator(sys, o), std::invalid_argument);
  auto ida = MakeIdaIntegrator(sys, IdaOptions{});
  EXPECT_FALSE(ida->AdvanceTo(1.0));  // not initialised
  State bad;
  bad.Resize(3, 1);
  EXPECT_THROW(ida->Initialize(bad), std::invalid_argument);
  ida->Initialize(ConsistentState(sys, {0.6, -0.8}, {0, 0}));
  ASSERT_TRUE(ida->AdvanceTo(0.1)) << ida->summary().message;
  EXPECT_FALSE(ida->AdvanceTo(0.05));  // backwards
  EXPECT_EQ(ida->name().rfind("IDA", 0), 0u) << ida->name();
}


// Quadratures on the undamped pendulum against closed forms, integrated together with
// the run and read after every output time:
//   int E dt = E0 t (energy is conserved), int v_x dt = x(t) - x0, int a_x dt = v_x(t) - v_x0,
//   int 2 x lambda dt = -m (v_x(t) - v_x0) (the x equation m a_x + 2 x lambda = 0).
// The last two check that a is read from v' and lambda from y.
TEST(IdaIntegrator, QuadratureMatchesClosedForms) {
  const double m = 1.3, L = 0.8, g = 9.81;
  PendulumSystem sys(m, L, g);
  IdaOptions options;
  options.rtol = 1e-10;
  options.atol = 1e-12;
  auto ida = MakeIdaIntegrator(sys, options);
  Quadrature quad;
  quad.size = 4;
  int calls = 0;
  quad.integrand = [&](double, const double* q, const double* v, const double* a,
                       const double* lambda, double* out) {
    ++calls;
    out[0] = 0.5 * m * (v[0] * v[0] + v[1] * v[1]) + m * g * q[1];
    out[1] = v[0];
    out[2] = a[0];
    out[3] = 2 * q[0] * lambda[0];
    return 0;
  };
  ida->SetQuadrature(quad);
  const State x0 = ConsistentState(sys, {0.6, -std::sqrt(L * L - 0.36)}, {1.0, 0.75});
  const double E0 = 0.5 * m * (x0.v[0] * x0.v[0] + x0.v[1] * x0.v[1]) + m * g * x0.q[1];
  ida->Initialize(x0);
  ASSERT_EQ(ida->quadrature().size(), 4u);
  for (double e : ida->quadrature()) EXPECT_EQ(e, 0.0);
  double max_err = 0;
  for (int k = 1; k <= 20; ++k) {
    const double t = 0.1 * k;
    ASSERT_TRUE(ida->AdvanceTo(t)) << ida->summary().message;
    const State& x = ida->state();
    const std::vector<double>& I = ida->quadrature();
    const double expected[4] = {E0 * t, x.q[0] - x0.q[0], x.v[0] - x0.v[0],
                                -m * (x.v[0] - x0.v[0])};
    for (int i = 0; i < 4; ++i) {
      const double err = std::abs(I[i] - expected[i]) / (1 + std::abs(expected[i]));
      max_err = std::max(max_err, err);
      // lambda is out of the error test: its integral is the least accurate (7e-9 at
      // rtol 1e-10; the others 3e-9 and below).
      EXPECT_LT(err, i == 3 ? 3e-8 : 1e-8) << "integral " << i << " at t = " << t;
    }
  }
  EXPECT_GT(calls, 0);
  // The same run again (Initialize resets the integrals) gives the same numbers.
  const std::vector<double> first = ida->quadrature();
  ida->Initialize(x0);
  for (int k = 1; k <= 20; ++k) ASSERT_TRUE(ida->AdvanceTo(0.1 * k));
  EXPECT_EQ(ida->quadrature(), first);
  std::printf("quadrature: max relative error against the closed forms %.2e\n", max_err);
}

// Dense output (IdaOptions::dense_output): the steps do not depend on the targets (rows
// every 0.01 s and every 0.1 s: the same steps, the same rows at the common times to the
// interpolation's rounding), the rows keep the pendulum's invariants to the tolerance,
// the quadrature of the rows matches its closed form, the last step lands on the stop
// time, and a target beyond it fails.
TEST(IdaIntegrator, DenseOutputStepsDoNotDependOnTheTargets) {
  const double m = 1.3, L = 0.8, g = 9.81;
  PendulumSystem sys(m, L, g);
  const State x0 = ConsistentState(sys, {0.6, -std::sqrt(L * L - 0.36)}, {1.0, 0.75});
  const double E0 = 0.5 * m * (x0.v[0] * x0.v[0] + x0.v[1] * x0.v[1]) + m * g * x0.q[1];
  // The energy (constant) and t.
  Quadrature quad;
  quad.size = 2;
  quad.integrand = [&](double t, const double* q, const double* v, const double*, const double*,
                       double* out) {
    out[0] = 0.5 * m * (v[0] * v[0] + v[1] * v[1]) + m * g * q[1];
    out[1] = t;
    return 0;
  };
  std::vector<State> rows[2];
  long steps[2];
  for (int run = 0; run < 2; ++run) {
    IdaOptions options;
    options.rtol = 1e-8;
    options.atol = 1e-10;
    options.dense_output = true;
    options.stop_time = 1.0;
    auto ida = MakeIdaIntegrator(sys, options);
    ida->SetQuadrature(quad);
    ida->Initialize(x0);
    const int n = run == 0 ? 100 : 10;
    for (int k = 1; k <= n; ++k) {
      const double t = static_cast<double>(k) / n;
      ASSERT_TRUE(ida->AdvanceTo(t)) << ida->summary().message;
      const State& x = ida->state();
      EXPECT_EQ(x.t, t);
      // Invariants of the interpolated rows, to the tolerance (measured below 1e-9).
      EXPECT_NEAR(x.q[0] * x.q[0] + x.q[1] * x.q[1], L * L, 1e-7) << "t = " << t;
      const double E = 0.5 * m * (x.v[0] * x.v[0] + x.v[1] * x.v[1]) + m * g * x.q[1];
      EXPECT_NEAR(E, E0, 1e-6) << "t = " << t;
      EXPECT_NEAR(ida->quadrature()[0], E0 * t, 1e-6) << "t = " << t;
      EXPECT_NEAR(ida->quadrature()[1], 0.5 * t * t, 1e-9) << "t = " << t;
      rows[run].push_back(x);
    }
    steps[run] = ida->summary().steps_accepted;
    EXPECT_EQ(ida->summary().t_reached, 1.0);  // the last step landed on the stop time
    EXPECT_FALSE(ida->AdvanceTo(1.5));
    EXPECT_NE(ida->summary().message.find("beyond the stop time"), std::string::npos)
        << ida->summary().message;
  }
  EXPECT_EQ(steps[0], steps[1]);
  for (int k = 0; k < 10; ++k) {
    const State& a = rows[0][10 * k + 9];
    const State& b = rows[1][k];
    for (int i = 0; i < 2; ++i) {
      EXPECT_NEAR(a.q[i], b.q[i], 1e-14) << "t = " << b.t;
      EXPECT_NEAR(a.v[i], b.v[i], 1e-13) << "t = " << b.t;
    }
  }
  // Without dense output (the same quadrature, which is in the error test) the steps
  // land on the 100 targets: more steps.
  IdaOptions options;
  options.rtol = 1e-8;
  options.atol = 1e-10;
  auto ida = MakeIdaIntegrator(sys, options);
  ida->SetQuadrature(quad);
  ida->Initialize(x0);
  for (int k = 1; k <= 100; ++k) ASSERT_TRUE(ida->AdvanceTo(k / 100.0));
  std::printf("dense output: %ld steps for 100 or 10 rows; landing on 100 rows: %ld steps\n", steps[0],
              ida->summary().steps_accepted);
  EXPECT_GT(ida->summary().steps_accepted, steps[0]);
}

TEST(IdaIntegrator, QuadratureFailureIsReported) {
  PendulumSystem sys(1, 1, 9.81);
  auto ida = MakeIdaIntegrator(sys, IdaOptions{});
  EXPECT_THROW(ida->SetQuadrature(Quadrature{2, nullptr}), std::invalid_argument);
  Quadrature quad;
  quad.size = 1;
  quad.integrand = [](double t, const double*, const double*, const double*, const double*,
                      double* g) {
    g[0] = 1;
    return t > 0.5 ? 1 : 0;
  };
  ida->SetQuadrature(quad);
  ida->Initialize(ConsistentState(sys, {0.6, -0.8}, {0, 0}));
  ASSERT_TRUE(ida->AdvanceTo(0.4)) << ida->summary().message;
  EXPECT_NEAR(ida->quadrature()[0], 0.4, 1e-10);
  EXPECT_FALSE(ida->AdvanceTo(1.0));
  EXPECT_NE(ida->summary().message.find("quadrature integrand failed"), std::string::npos)
      << ida->summary().message;
}


// dF/dp of the GGL residual against central differences in the parameters, at a random
// point with mu != 0 (so every block is seen).
TEST(GglResidual, ParameterJacobianMatchesFiniteDifferences) {
  testing::ParametricPendulum sys(1.3, 0.8, 9.81, 0.2);
  internal::GglResidual ggl(sys);
  const int n = ggl.size(), np = sys.num_parameters();
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> U(-1.0, 1.0);
  std::vector<double> y(n), yp(n), dense(static_cast<size_t>(n) * np), Fp(n), Fm(n);
  for (double& e : y) e = U(rng);
  for (double& e : yp) e = U(rng);
  ASSERT_EQ(ggl.ParameterJacobian(0.3, y.data(), yp.data(), dense.data()), 0);
  double max_entry = 0;
  for (int k = 0; k < np; ++k) {
    const double p0 = sys.parameter(k), h = 1e-6 * (1 + std::abs(p0));
    sys.parameter(k) = p0 + h;
    ASSERT_EQ(ggl.Residual(0.3, y.data(), yp.data(), Fp.data()), 0);
    sys.parameter(k) = p0 - h;
    ASSERT_EQ(ggl.Residual(0.3, y.data(), yp.data(), Fm.data()), 0);
    sys.parameter(k) = p0;
    for (int r = 0; r < n; ++r) {
      const double fd = (Fp[r] - Fm[r]) / (2 * h), an = dense[static_cast<size_t>(k) * n + r];
      max_entry = std::max(max_entry, std::abs(an));
      EXPECT_NEAR(an, fd, 1e-8 * (1 + std::abs(an))) << "row " << r << ", parameter " << k;
    }
  }
  EXPECT_GT(max_entry, 1.0);
}

}  // namespace
}  // namespace mbdae::dae
