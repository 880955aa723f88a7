// The explicit Runge-Kutta integrator on the index-1 form with projection (dae/erk.h):
// its order (5) with fixed steps, the pendulum period against the closed form, error
// proportional to the tolerance, the constraints after projection, a free body with
// Euler parameters, quadratures, failures and options.
#include "dae/erk.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <vector>

#include "dae/consistent.h"
#include "tests/support/free_body_system.h"
#include "tests/support/integrator_cases.h"
#include "tests/support/pendulum_reference.h"
#include "tests/support/nonlinear_system.h"
#include "tests/support/pendulum_system.h"

namespace mbdae::dae {
namespace {

using testing::ConsistentState;
using testing::EllipticK;
using testing::FailingPendulum;
using testing::FreeBodySystem;
using testing::NonlinearSystem;
using testing::PendulumSystem;

constexpr double kPi = 3.14159265358979323846;

// The RK4 reference with 20000 steps per second (a step 200 times below the finest of
// the order test).
double PendulumAngle(double theta0, double omega0, double g_over_L, double t_end) {
  return testing::PendulumAngleRk4(theta0, omega0, g_over_L, t_end,
                                   static_cast<int>(std::ceil(t_end * 20000)));
}

// Fixed steps: every step accepted (the tolerances far above the local errors) and the
// step held at max_step from the first one.
ErkOptions FixedStep(double h) {
  ErkOptions o;
  o.rtol = o.atol = 1e6;
  o.initial_step = h;
  o.max_step = h;
  return o;
}

TEST(ErkIntegrator, FifthOrderWithFixedSteps) {
  const double m = 1.0, L = 1.0, g = 9.81;
  PendulumSystem sys(m, L, g);
  const double theta0 = 1.2, t_end = 1.0;
  const double ref = PendulumAngle(theta0, 0.0, g / L, t_end);
  std::vector<double> err;
  const double steps[3] = {0.04, 0.02, 0.01};
  for (double h : steps) {
    auto erk = MakeErkIntegrator(sys, FixedStep(h));
    erk->Initialize(ConsistentState(sys, {L * std::sin(theta0), -L * std::cos(theta0)}, {0, 0}));
    ASSERT_TRUE(erk->AdvanceTo(t_end)) << erk->summary().message;
    const State& s = erk->state();
    EXPECT_EQ(erk->summary().steps_accepted, std::lround(t_end / h));
    EXPECT_EQ(erk->summary().steps_rejected, 0);
    // The projection keeps both constraint levels at every step.
    EXPECT_NEAR(s.q[0] * s.q[0] + s.q[1] * s.q[1], L * L, 1e-13);
    EXPECT_NEAR(s.q[0] * s.v[0] + s.q[1] * s.v[1], 0.0, 1e-12);
    err.push_back(std::abs(std::atan2(s.q[0], -s.q[1]) - ref));
  }
  const double p1 = std::log2(err[0] / err[1]), p2 = std::log2(err[1] / err[2]);
  std::printf("angle errors at h = 0.04, 0.02, 0.01: %.3e %.3e %.3e; orders %.2f %.2f\n",
              err[0], err[1], err[2], p1, p2);
  EXPECT_GT(p1, 4.5);
  EXPECT_LT(p1, 5.6);
  EXPECT_GT(p2, 4.5);
  EXPECT_LT(p2, 5.6);
  EXPECT_LT(err[2], 1e-9);
}

TEST(ErkIntegrator, PendulumPeriodMatchesEllipticIntegral) {
  const double m = 1.0, L = 1.0, g = 9.81;
  PendulumSystem sys(m, L, g);
  const double T = 4 * std::sqrt(L / g) * EllipticK(std::sin(kPi / 4));
  ErkOptions options;
  options.rtol = 1e-11;
  options.atol = 1e-11;
  auto erk = MakeErkIntegrator(sys, options);
  erk->Initialize(ConsistentState(sys, {L, 0.0}, {0.0, 0.0}));
  std::vector<double> crossings;
  for (int j = 0; j < 3; ++j) {
    const double guess = (2 * j + 1) * T / 4;
    ASSERT_TRUE(erk->AdvanceTo(guess)) << erk->summary().message;
    const State& s = erk->state();
    EXPECT_EQ(s.t, guess);
    crossings.push_back(s.t - s.q[0] / s.v[0]);
    EXPECT_NEAR(s.q[0] * s.q[0] + s.q[1] * s.q[1], L * L, 1e-13);
    EXPECT_NEAR(s.q[0] * s.v[0] + s.q[1] * s.v[1], 0.0, 1e-12);
    // lambda at the bottom: m (v^2 + g L) / (2 L^2) with v^2 = 2 g L; here a and lambda
    // are solved from the acceleration-level equations at the state.
    EXPECT_NEAR(s.lambda[0], 3 * m * g / (2 * L), 1e-8);
  }
  const double period = crossings[2] - crossings[0];
  EXPECT_NEAR(period / T, 1.0, 1e-9) << "measured " << period << ", closed form " << T;
  const Summary& sum = erk->summary();
  EXPECT_EQ(sum.status, Summary::Status::kDone);
  EXPECT_GT(sum.steps_accepted, 20);
  // 6 factorisations per step, accepted or rejected (the last stage is the next step's
  // first), one per AdvanceTo (a and lambda at the projected state) and the initial step
  // size's one.
  EXPECT_EQ(sum.factorizations, 6 * (sum.steps_accepted + sum.steps_rejected) + 3 + 1);
  EXPECT_EQ(sum.t_reached, erk->state().t);
  std::printf("period error %.2e with %ld steps (%ld rejected)\n", period / T - 1,
              sum.steps_accepted, sum.steps_rejected);
}

// Global error against a tight reference falls with the tolerance on a system whose
// matrices all depend on the state and whose constraint depends on time.
TEST(ErkIntegrator, ErrorFallsWithTheTolerance) {
  NonlinearSystem sys;
  const State x0 = ConsistentState(sys, {0.5, 0.3, 0.7}, {0.2, -0.4, 0.9});
  auto run = [&](double tol, long* steps) {
    ErkOptions options;
    options.rtol = options.atol = tol;
    auto erk = MakeErkIntegrator(sys, options);
    erk->Initialize(x0);
    for (int k = 1; k <= 10; ++k) {
      EXPECT_TRUE(erk->AdvanceTo(0.1 * k)) << erk->summary().message;
      const State& s = erk->state();
      const double c0 = s.q[0] * s.q[0] + s.q[1] * s.q[1] + s.q[2] * s.q[2] - 1;
      const double c1 = s.q[0] - s.q[2] * std::cos(s.t) - 0.1 * s.t;
      EXPECT_LT(std::abs(c0) + std::abs(c1), 1e-12);
    }
    if (steps) *steps = erk->summary().steps_accepted;
    return erk->state();
  };
  const State ref = run(1e-13, nullptr);
  double err[3];
  long steps[3];
  const double tols[3] = {1e-5, 1e-7, 1e-9};
  for (int i = 0; i < 3; ++i) {
    const State s = run(tols[i], &steps[i]);
    err[i] = 0;
    for (int j = 0; j < 3; ++j)
      err[i] = std::max({err[i], std::abs(s.q[j] - ref.q[j]), std::abs(s.v[j] - ref.v[j])});
  }
  std::printf("errors at tol 1e-5, 1e-7, 1e-9: %.2e %.2e %.2e (steps %ld %ld %ld)\n", err[0],
              err[1], err[2], steps[0], steps[1], steps[2]);
  for (int i = 0; i < 3; ++i) EXPECT_LT(err[i], 100 * tols[i]);
  EXPECT_LT(err[1], 0.1 * err[0]);
  EXPECT_LT(err[2], 0.1 * err[1]);
  EXPECT_LT(steps[0], steps[1]);
  EXPECT_LT(steps[1], steps[2]);
}

// A torque-free asymmetric body (Euler parameters, gyroscopic forces): the angular
// momentum in world axes and the kinetic energy are invariants, |e| = 1 by projection.
TEST(ErkIntegrator, FreeBodyKeepsItsInvariants) {
  const std::array<double, 3> J = {0.7, 1.3, 2.1};
  FreeBodySystem sys(2.0, J, {0, 0, 0}, {0, 0, 0});
  // e = (1, 0, 0, 0); body angular velocity w0: e' = 1/2 G^T w.
  const double w0[3] = {0.3, 2.0, 0.1};  // near the unstable middle axis: a tumbling motion
  std::vector<double> q = {0, 0, 0, 1, 0, 0, 0};
  std::vector<double> v = {0.1, 0, 0, 0, 0.5 * w0[0], 0.5 * w0[1], 0.5 * w0[2]};
  auto erk_options = ErkOptions{};
  erk_options.rtol = erk_options.atol = 1e-10;
  auto erk = MakeErkIntegrator(sys, erk_options);
  erk->Initialize(ConsistentState(sys, q, v));
  // World angular momentum H = R(e) J w, w = 2 G(e) e'.
  auto invariants = [&](const State& s, double H[3], double* T) {
    const double* e = &s.q[3];
    const double* ed = &s.v[3];
    const double w[3] = {2 * (-e[1] * ed[0] + e[0] * ed[1] + e[3] * ed[2] - e[2] * ed[3]),
                         2 * (-e[2] * ed[0] - e[3] * ed[1] + e[0] * ed[2] + e[1] * ed[3]),
                         2 * (-e[3] * ed[0] + e[2] * ed[1] - e[1] * ed[2] + e[0] * ed[3])};
    const double Jw[3] = {J[0] * w[0], J[1] * w[1], J[2] * w[2]};
    const double e0 = e[0], e1 = e[1], e2 = e[2], e3 = e[3];
    const double R[3][3] = {
        {1 - 2 * (e2 * e2 + e3 * e3), 2 * (e1 * e2 - e0 * e3), 2 * (e1 * e3 + e0 * e2)},
        {2 * (e1 * e2 + e0 * e3), 1 - 2 * (e1 * e1 + e3 * e3), 2 * (e2 * e3 - e0 * e1)},
        {2 * (e1 * e3 - e0 * e2), 2 * (e2 * e3 + e0 * e1), 1 - 2 * (e1 * e1 + e2 * e2)}};
    for (int i = 0; i < 3; ++i) H[i] = R[i][0] * Jw[0] + R[i][1] * Jw[1] + R[i][2] * Jw[2];
    *T = 0.5 * (Jw[0] * w[0] + Jw[1] * w[1] + Jw[2] * w[2]);
  };
  double H0[3], T0;
  invariants(erk->state(), H0, &T0);
  double dH = 0, dT = 0, de = 0;
  for (int k = 1; k <= 50; ++k) {
    ASSERT_TRUE(erk->AdvanceTo(0.2 * k)) << erk->summary().message;
    const State& s = erk->state();
    double H[3], T;
    invariants(s, H, &T);
    for (int i = 0; i < 3; ++i) dH = std::max(dH, std::abs(H[i] - H0[i]));
    dT = std::max(dT, std::abs(T - T0));
    const double n2 = s.q[3] * s.q[3] + s.q[4] * s.q[4] + s.q[5] * s.q[5] + s.q[6] * s.q[6];
    de = std::max(de, std::abs(n2 - 1));
    EXPECT_NEAR(s.q[0], 0.1 * s.t, 1e-12);  // uniform translation
  }
  std::printf("10 s tumbling: max |dH| %.2e, |dT| %.2e, | |e|^2 - 1 | %.2e, %ld steps\n", dH,
              dT, de, erk->summary().steps_accepted);
  EXPECT_LT(dH, 1e-7);
  EXPECT_LT(dT, 1e-7);
  EXPECT_LT(de, 1e-14);
}

TEST(ErkIntegrator, QuadratureMatchesClosedForms) {
  const double m = 1.3, L = 0.8, g = 9.81;
  PendulumSystem sys(m, L, g);
  ErkOptions options;
  options.rtol = 1e-10;
  options.atol = 1e-12;
  auto erk = MakeErkIntegrator(sys, options);
  Quadrature quad;
  quad.size = 4;
  quad.integrand = [&](double, const double* q, const double* v, const double* a,
                       const double* lambda, double* out) {
    out[0] = 0.5 * m * (v[0] * v[0] + v[1] * v[1]) + m * g * q[1];
    out[1] = v[0];
    out[2] = a[0];
    out[3] = 2 * q[0] * lambda[0];
    return 0;
  };
  erk->SetQuadrature(quad);
  const State x0 = ConsistentState(sys, {0.6, -std::sqrt(L * L - 0.36)}, {1.0, 0.75});
  const double E0 = 0.5 * m * (x0.v[0] * x0.v[0] + x0.v[1] * x0.v[1]) + m * g * x0.q[1];
  erk->Initialize(x0);
  ASSERT_EQ(erk->quadrature().size(), 4u);
  double max_err = 0;
  for (int k = 1; k <= 20; ++k) {
    const double t = 0.1 * k;
    ASSERT_TRUE(erk->AdvanceTo(t)) << erk->summary().message;
    const State& x = erk->state();
    const std::vector<double>& I = erk->quadrature();
    const double expected[4] = {E0 * t, x.q[0] - x0.q[0], x.v[0] - x0.v[0],
                                -m * (x.v[0] - x0.v[0])};
    for (int i = 0; i < 4; ++i) {
      const double err = std::abs(I[i] - expected[i]) / (1 + std::abs(expected[i]));
      max_err = std::max(max_err, err);
      EXPECT_LT(err, 1e-9) << "integral " << i << " at t = " << t;
    }
  }
  std::printf("quadrature: max relative error against the closed forms %.2e\n", max_err);
}

TEST(ErkIntegrator, FailuresAreReported) {
  for (int code : {-1, 1}) {
    FailingPendulum sys(0.3, code);
    auto erk = MakeErkIntegrator(sys, ErkOptions{});
    erk->Initialize(ConsistentState(sys, {0.6, -0.8}, {0, 0}));
    EXPECT_FALSE(erk->AdvanceTo(1.0));
    const Summary& s = erk->summary();
    EXPECT_EQ(s.status, Summary::Status::kFailed);
    EXPECT_NE(s.message.find("joint 7 broke"), std::string::npos) << s.message;
    if (code > 0) EXPECT_NE(s.message.find("smallest step"), std::string::npos) << s.message;
    EXPECT_LE(erk->state().t, 0.3);
    EXPECT_GT(erk->state().t, 0.2);
    EXPECT_EQ(s.t_reached, erk->state().t);
  }
  // The step budget.
  PendulumSystem sys(1, 1, 9.81);
  ErkOptions options;
  options.max_steps = 5;
  auto erk = MakeErkIntegrator(sys, options);
  erk->Initialize(ConsistentState(sys, {0.6, -0.8}, {0, 0}));
  EXPECT_FALSE(erk->AdvanceTo(10.0));
  EXPECT_NE(erk->summary().message.find("max_steps = 5"), std::string::npos)
      << erk->summary().message;
  EXPECT_EQ(erk->summary().steps_accepted + erk->summary().steps_rejected, 5);
  EXPECT_GT(erk->state().t, 0.0);
}

TEST(ErkOptions, Validation) {
  std::string why;
  EXPECT_TRUE(ErkOptions{}.IsValid(&why)) << why;
  auto bad = [](auto change) {
    ErkOptions o;
    change(o);
    std::string reason;
    EXPECT_FALSE(o.IsValid(&reason));
    EXPECT_NE(reason.find("ErkOptions"), std::string::npos);
    return reason;
  };
  EXPECT_NE(bad([](ErkOptions& o) { o.rtol = 0; }).find("rtol"), std::string::npos);
  EXPECT_NE(bad([](ErkOptions& o) { o.atol = -1; }).find("atol"), std::string::npos);
  EXPECT_NE(bad([](ErkOptions& o) { o.rtol = NAN; }).find("rtol"), std::string::npos);
  EXPECT_NE(bad([](ErkOptions& o) { o.max_steps = 0; }).find("max_steps"), std::string::npos);
  EXPECT_NE(bad([](ErkOptions& o) { o.min_step = 1; o.max_step = 0.1; }).find("min_step"),
            std::string::npos);
  PendulumSystem sys(1, 1, 9.81);
  ErkOptions o;
  o.rtol = 0;
  EXPECT_THROW(MakeErkIntegrator(sys, o), std::invalid_argument);
  auto erk = MakeErkIntegrator(sys, ErkOptions{});
  EXPECT_FALSE(erk->AdvanceTo(1.0));  // before Initialize
  State wrong;
  wrong.Resize(3, 1);
  EXPECT_THROW(erk->Initialize(wrong), std::invalid_argument);
  IntegratorSnapshot snap;
  EXPECT_THROW(erk->SaveSnapshot(&snap), std::logic_error);
}

}  // namespace
}  // namespace mbdae::dae
