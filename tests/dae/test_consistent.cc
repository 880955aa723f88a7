// Consistent initial values, redundant constraints and the KeepConstraints view.
#include "dae/consistent.h"

#include <gtest/gtest.h>

#include <cmath>
#include <stdexcept>
#include <vector>

#include "tests/support/nonlinear_system.h"
#include "tests/support/pendulum_system.h"

namespace mbdae::dae {
namespace {

using testing::NonlinearSystem;
using testing::PendulumSystem;

// A point in the plane on several circles: equation i is
//   s_i ((x - cx_i)^2 + (y - cy_i)^2 - r_i^2) = 0.
class PointOnCircles : public MechanicalSystem {
 public:
  struct Circle { double cx, cy, r, s; };
  explicit PointOnCircles(std::vector<Circle> circles) : circles_(std::move(circles)) {
    const int nc = static_cast<int>(circles_.size());
    diag_ = CscPattern::FromEntries(2, 2, {{0, 0}, {1, 1}});
    empty_ = CscPattern::FromEntries(2, 2, {});
    std::vector<std::pair<int, int>> e;
    for (int r = 0; r < nc; ++r) { e.push_back({r, 0}); e.push_back({r, 1}); }
    cq_ = CscPattern::FromEntries(nc, 2, e);
  }
  int num_coordinates() const override { return 2; }
  int num_constraints() const override { return static_cast<int>(circles_.size()); }
  const CscPattern& pattern(Matrix m) const override {
    switch (m) {
      case Matrix::kMass: case Matrix::kConstraintTDq: return diag_;
      case Matrix::kConstraintDq: case Matrix::kConstraintVelDq: return cq_;
      default: return empty_;
    }
  }
  int Evaluate(const EvalInput& in, EvalOutput& out) override {
    const int nc = num_constraints();
    const double* q = in.q;
    if (out.force) { out.force[0] = 0; out.force[1] = -1; }
    double wsum = 0;
    for (int r = 0; r < nc; ++r) {
      const Circle& c = circles_[r];
      const double dx = q[0] - c.cx, dy = q[1] - c.cy;
      if (out.constraint) out.constraint[r] = c.s * (dx * dx + dy * dy - c.r * c.r);
      if (out.constraint_dt) out.constraint_dt[r] = 0;
      if (out.acc_rhs) out.acc_rhs[r] = -c.s * 2 * (in.v[0] * in.v[0] + in.v[1] * in.v[1]);
      if (double* C = out[Matrix::kConstraintDq]) { C[r] = 2 * c.s * dx; C[nc + r] = 2 * c.s * dy; }
      if (double* C = out[Matrix::kConstraintVelDq]) {
        C[r] = 2 * c.s * in.v[0];
        C[nc + r] = 2 * c.s * in.v[1];
      }
      if (out[Matrix::kConstraintTDq]) wsum += 2 * c.s * in.w[r];
    }
    if (double* M = out[Matrix::kMass]) { M[0] = 1; M[1] = 1; }
    if (double* K = out[Matrix::kConstraintTDq]) { K[0] = wsum; K[1] = wsum; }
    return 0;
  }

 private:
  std::vector<Circle> circles_;
  CscPattern diag_, empty_, cq_;
};

State MakeState(std::vector<double> q, std::vector<double> v, double t = 0) {
  State x;
  x.t = t;
  x.q = std::move(q);
  x.v = std::move(v);
  return x;
}

// Max |C|, max |C_q v + C_t| and the residuals of M a + C_q^T lambda = Q, C_q a = gamma.
struct Residuals { double pos = 0, vel = 0, dyn = 0, acc = 0; };
Residuals Check(MechanicalSystem& sys, const State& x) {
  const int nq = sys.num_coordinates(), nc = sys.num_constraints();
  std::vector<double> c(nc), ct(nc), gamma(nc), Q(nq);
  std::vector<double> M(sys.pattern(Matrix::kMass).nnz()), cq(sys.pattern(Matrix::kConstraintDq).nnz());
  EvalInput in;
  in.t = x.t; in.q = x.q.data(); in.v = x.v.data();
  EvalOutput out;
  out.constraint = c.data(); out.constraint_dt = ct.data(); out.acc_rhs = gamma.data();
  out.force = Q.data();
  out[Matrix::kMass] = M.data();
  out[Matrix::kConstraintDq] = cq.data();
  EXPECT_EQ(sys.Evaluate(in, out), 0);
  const CscPattern& pc = sys.pattern(Matrix::kConstraintDq);
  std::vector<double> vel = ct, dyn(nq), acc(nc);
  MultiplyAdd(pc, cq.data(), 1.0, x.v.data(), vel.data());
  for (int i = 0; i < nq; ++i) dyn[i] = -Q[i];
  MultiplyAdd(sys.pattern(Matrix::kMass), M.data(), 1.0, x.a.data(), dyn.data());
  MultiplyTransposeAdd(pc, cq.data(), 1.0, x.lambda.data(), dyn.data());
  for (int r = 0; r < nc; ++r) acc[r] = -gamma[r];
  MultiplyAdd(pc, cq.data(), 1.0, x.a.data(), acc.data());
  Residuals res;
  for (double e : c) res.pos = std::max(res.pos, std::abs(e));
  for (double e : vel) res.vel = std::max(res.vel, std::abs(e));
  for (double e : dyn) res.dyn = std::max(res.dyn, std::abs(e));
  for (double e : acc) res.acc = std::max(res.acc, std::abs(e));
  return res;
}

TEST(MakeConsistent, PendulumProjectionIsRadialAndMultiplierExact) {
  const double m = 2.0, L = 1.5, g = 9.81;
  PendulumSystem sys(m, L, g);
  State x = MakeState({0.9, -1.3}, {0.7, 0.4});
  const double r0 = std::hypot(0.9, -1.3);
  const auto report = MakeConsistent(sys, x);
  ASSERT_TRUE(report.ok) << report.message;
  EXPECT_TRUE(report.redundant.empty());
  EXPECT_TRUE(report.violated.empty());
  EXPECT_GT(report.iterations, 0);
  EXPECT_NEAR(report.initial_position_violation, std::abs(r0 * r0 - L * L), 1e-14);
  EXPECT_NEAR(report.initial_velocity_violation, std::abs(2 * (0.9 * 0.7 - 1.3 * 0.4)), 1e-14);
  // Least change: the projection of q0 onto the circle is q0 L / |q0|.
  EXPECT_NEAR(x.q[0], 0.9 * L / r0, 1e-13);
  EXPECT_NEAR(x.q[1], -1.3 * L / r0, 1e-13);
  EXPECT_NEAR(report.max_position_change, std::abs(1.3 * (1 - L / r0)), 1e-13);
  const Residuals res = Check(sys, x);
  EXPECT_LT(res.pos, 1e-12);
  EXPECT_LT(res.vel, 1e-12);
  // Velocity: the radial part removed, the tangential part kept.
  const double ux = x.q[0] / L, uy = x.q[1] / L;
  const double vt = -0.7 * uy + 0.4 * ux;  // tangential component of v0
  EXPECT_NEAR(x.v[0], -vt * uy, 1e-13);
  EXPECT_NEAR(x.v[1], vt * ux, 1e-13);
  // Exact a and lambda: lambda = m (|v|^2 - g y) / (2 L^2), a = (-2 q lambda + [0, -m g]) / m.
  const double v2 = x.v[0] * x.v[0] + x.v[1] * x.v[1];
  const double lambda = m * (v2 - g * x.q[1]) / (2 * L * L);
  EXPECT_NEAR(x.lambda[0], lambda, 1e-12 * std::abs(lambda));
  EXPECT_NEAR(x.a[0], -2 * x.q[0] * lambda / m, 1e-12);
  EXPECT_NEAR(x.a[1], -2 * x.q[1] * lambda / m - g, 1e-12);
}

TEST(MakeConsistent, ConsistentStateIsLeftUnchangedAndRepeatable) {
  PendulumSystem sys(1.0, 1.0, 9.81);
  State x = MakeState({0.3, -0.8}, {0.1, 0.2});
  ASSERT_TRUE(MakeConsistent(sys, x).ok);
  State y = x;
  const auto again = MakeConsistent(sys, y);
  ASSERT_TRUE(again.ok);
  EXPECT_EQ(again.iterations, 0);
  EXPECT_LE(again.max_position_change, 0.0);
  EXPECT_LT(again.max_velocity_change, 1e-15);
  for (int i = 0; i < 2; ++i) {
    EXPECT_EQ(x.q[i], y.q[i]);
    EXPECT_NEAR(x.a[i], y.a[i], 1e-14);
  }
  EXPECT_NEAR(x.lambda[0], y.lambda[0], 1e-14);
}

TEST(MakeConsistent, NonlinearTimeDependentSystem) {
  NonlinearSystem sys;
  State x = MakeState({0.5, 0.3, 0.7}, {0.2, -0.4, 0.9}, 0.35);
  const auto report = MakeConsistent(sys, x);
  ASSERT_TRUE(report.ok) << report.message;
  EXPECT_TRUE(report.redundant.empty());
  const Residuals res = Check(sys, x);
  EXPECT_LT(res.pos, 1e-12);
  EXPECT_LT(res.vel, 1e-12);
  EXPECT_LT(res.dyn, 1e-12);
  EXPECT_LT(res.acc, 1e-12);
}

// gamma of the test system against a central difference of C_q v + C_t along the motion
// (q + h v + h^2/2 a, v + h a, t + h): d/dt (C_q v + C_t) = C_q a - gamma.
TEST(MakeConsistent, NonlinearSystemGammaMatchesFiniteDifference) {
  NonlinearSystem sys;
  const double t = 0.7, q[3] = {0.4, -0.2, 0.6}, v[3] = {0.3, 0.5, -0.8}, a[3] = {1.1, -0.7, 0.4};
  const CscPattern& pc = sys.pattern(Matrix::kConstraintDq);
  auto velocity_level = [&](double h, double* out2) {
    double qh[3], vh[3], ct[2], cq[5];
    for (int i = 0; i < 3; ++i) { qh[i] = q[i] + h * v[i] + 0.5 * h * h * a[i]; vh[i] = v[i] + h * a[i]; }
    EvalInput in; in.t = t + h; in.q = qh; in.v = vh;
    EvalOutput out; out.constraint_dt = ct; out[Matrix::kConstraintDq] = cq;
    sys.Evaluate(in, out);
    out2[0] = ct[0]; out2[1] = ct[1];
    MultiplyAdd(pc, cq, 1.0, vh, out2);
  };
  const double h = 1e-5;
  double fp[2], fm[2], gamma[2], cq[5], ca[2] = {0, 0};
  velocity_level(h, fp);
  velocity_level(-h, fm);
  EvalInput in; in.t = t; in.q = q; in.v = v;
  EvalOutput out; out.acc_rhs = gamma; out[Matrix::kConstraintDq] = cq;
  sys.Evaluate(in, out);
  MultiplyAdd(pc, cq, 1.0, a, ca);
  for (int r = 0; r < 2; ++r) EXPECT_NEAR((fp[r] - fm[r]) / (2 * h), ca[r] - gamma[r], 1e-8) << r;
}

TEST(FindRedundantConstraints, RedundantPendulumFlagsTheSecondCopy) {
  PendulumSystem sys(1.0, 1.0, 9.81, /*redundant=*/true);
  const double q[2] = {0.6, -0.8};
  EXPECT_EQ(FindRedundantConstraints(sys, 0.0, q, 1e-9), std::vector<int>({1}));
  PendulumSystem plain(1.0, 1.0, 9.81);
  EXPECT_TRUE(FindRedundantConstraints(plain, 0.0, q, 1e-9).empty());
}

TEST(FindRedundantConstraints, EliminationOrderDecidesWhichCopyGoes) {
  PendulumSystem sys(1.0, 1.0, 9.81, /*redundant=*/true);
  const double q[2] = {0.6, -0.8};
  EXPECT_EQ(FindRedundantConstraints(sys, 0.0, q, 1e-9, {1, 0}), std::vector<int>({0}));
  EXPECT_EQ(FindRedundantConstraints(sys, 0.0, q, 1e-9, {0, 1}), std::vector<int>({1}));
  EXPECT_THROW(FindRedundantConstraints(sys, 0.0, q, 1e-9, {0, 0}), std::invalid_argument);
  EXPECT_THROW(FindRedundantConstraints(sys, 0.0, q, 1e-9, {0}), std::invalid_argument);
  // MakeConsistent follows the same order, and keeps the multiplier on the kept copy.
  State x;
  x.Resize(2, 2);
  x.q = {0.6, -0.8};
  x.v = {0.8, 0.6};
  ConsistencyOptions options;
  options.elimination_order = {1, 0};
  const ConsistencyReport report = MakeConsistent(sys, x, options);
  ASSERT_TRUE(report.ok) << report.message;
  EXPECT_EQ(report.redundant, std::vector<int>({0}));
  EXPECT_EQ(x.lambda[0], 0.0);
  EXPECT_NE(x.lambda[1], 0.0);
}

TEST(FindRedundantConstraints, LaterEquationOfADependentPairIsFlagged) {
  // Equations 0 and 1 are the same circle (scaled by 3), equation 2 another circle
  // through the point (0.5, sqrt(0.75)): rank 2, and of the pair 0-1 the later one goes.
  PointOnCircles sys({{0, 0, 1, 1}, {0, 0, 1, 3}, {1, 0, 1, 1}});
  const double q[2] = {0.5, std::sqrt(0.75)};
  EXPECT_EQ(FindRedundantConstraints(sys, 0.0, q, 1e-9), std::vector<int>({1}));
  // Independent circles first: the third equation depends on the first two (2 unknowns).
  PointOnCircles three({{0, 0, 1, 1}, {1, 0, 1, 1}, {0.5, -1, 1 + std::sqrt(0.75), 1}});
  EXPECT_EQ(FindRedundantConstraints(three, 0.0, q, 1e-9), std::vector<int>({2}));
  // Nearly parallel rows: dependent or not by the relative tolerance on |R_ii|.
  PointOnCircles near({{0, 0, 1, 1}, {1e-7, 0, 1, 1}});
  const double p[2] = {0.0, 1.0};
  EXPECT_EQ(FindRedundantConstraints(near, 0.0, p, 1e-6), std::vector<int>({1}));
  EXPECT_TRUE(FindRedundantConstraints(near, 0.0, p, 1e-9).empty());
}

TEST(MakeConsistent, RedundantPendulumGivesTheMultiplierToTheFirstEquation) {
  const double m = 1.0, L = 1.0, g = 9.81;
  PendulumSystem red(m, L, g, true), plain(m, L, g);
  State xr = MakeState({1.1, -0.2}, {0.3, 0.5});
  State xp = xr;
  const auto rr = MakeConsistent(red, xr);
  const auto rp = MakeConsistent(plain, xp);
  ASSERT_TRUE(rr.ok) << rr.message;
  ASSERT_TRUE(rp.ok) << rp.message;
  EXPECT_EQ(rr.redundant, std::vector<int>({1}));
  for (int i = 0; i < 2; ++i) {
    EXPECT_NEAR(xr.q[i], xp.q[i], 1e-14);
    EXPECT_NEAR(xr.v[i], xp.v[i], 1e-14);
    EXPECT_NEAR(xr.a[i], xp.a[i], 1e-12);
  }
  EXPECT_NEAR(xr.lambda[0], xp.lambda[0], 1e-12);
  EXPECT_EQ(xr.lambda[1], 0.0);
  const Residuals res = Check(red, xr);
  EXPECT_LT(res.pos, 1e-12);
  EXPECT_LT(res.dyn, 1e-12);
  EXPECT_LT(res.acc, 1e-12);
}

TEST(MakeConsistent, DependentEquationBetweenIndependentOnes) {
  // Equation 1 repeats equation 0; the solution is the intersection (0.5, sqrt(0.75)).
  PointOnCircles sys({{0, 0, 1, 1}, {0, 0, 1, 3}, {1, 0, 1, 1}});
  State x = MakeState({0.62, 0.71}, {0.4, -0.3});
  const auto report = MakeConsistent(sys, x);
  ASSERT_TRUE(report.ok) << report.message;
  EXPECT_EQ(report.redundant, std::vector<int>({1}));
  EXPECT_NEAR(x.q[0], 0.5, 1e-13);
  EXPECT_NEAR(x.q[1], std::sqrt(0.75), 1e-13);
  // Two independent constraints on two coordinates: no motion is left.
  EXPECT_NEAR(x.v[0], 0.0, 1e-13);
  EXPECT_NEAR(x.v[1], 0.0, 1e-13);
  EXPECT_EQ(x.lambda[1], 0.0);
  const Residuals res = Check(sys, x);
  EXPECT_LT(res.pos, 1e-12);
  EXPECT_LT(res.vel, 1e-12);
  EXPECT_LT(res.dyn, 1e-12);
  EXPECT_LT(res.acc, 1e-12);
}

// A planar chain of n unit point masses in Cartesian coordinates: equation k keeps
// point b_k at distance r_k from point a_k (a_k = -1: the fixed origin).
class DistanceChain : public MechanicalSystem {
 public:
  struct Link { int a, b; double r; };
  DistanceChain(int points, std::vector<Link> links) : n_(points), links_(std::move(links)) {
    std::vector<std::pair<int, int>> d, e;
    for (int i = 0; i < 2 * n_; ++i) d.push_back({i, i});
    for (int k = 0; k < num_constraints(); ++k)
      for (int p : {links_[k].a, links_[k].b})
        if (p >= 0) { e.push_back({k, 2 * p}); e.push_back({k, 2 * p + 1}); }
    diag_ = CscPattern::FromEntries(2 * n_, 2 * n_, d);
    empty_ = CscPattern::FromEntries(2 * n_, 2 * n_, {});
    cq_ = CscPattern::FromEntries(num_constraints(), 2 * n_, e);
  }
  int num_coordinates() const override { return 2 * n_; }
  int num_constraints() const override { return static_cast<int>(links_.size()); }
  const CscPattern& pattern(Matrix m) const override {
    if (m == Matrix::kMass) return diag_;
    if (m == Matrix::kConstraintDq) return cq_;
    return empty_;  // the other matrices are not needed by MakeConsistent
  }
  int Evaluate(const EvalInput& in, EvalOutput& out) override {
    if (out.force)
      for (int i = 0; i < n_; ++i) { out.force[2 * i] = 0; out.force[2 * i + 1] = -9.81; }
    if (double* M = out[Matrix::kMass]) std::fill(M, M + 2 * n_, 1.0);
    for (int k = 0; k < num_constraints(); ++k) {
      const Link& l = links_[k];
      double d[2], dv[2];
      for (int j = 0; j < 2; ++j) {
        d[j] = in.q[2 * l.b + j] - (l.a >= 0 ? in.q[2 * l.a + j] : 0.0);
        dv[j] = in.v ? in.v[2 * l.b + j] - (l.a >= 0 ? in.v[2 * l.a + j] : 0.0) : 0.0;
      }
      if (out.constraint) out.constraint[k] = d[0] * d[0] + d[1] * d[1] - l.r * l.r;
      if (out.constraint_dt) out.constraint_dt[k] = 0;
      if (out.acc_rhs) out.acc_rhs[k] = -2 * (dv[0] * dv[0] + dv[1] * dv[1]);
      if (double* C = out[Matrix::kConstraintDq])
        for (int j = 0; j < 2; ++j) {
          C[cq_.find(k, 2 * l.b + j)] = 2 * d[j];
          if (l.a >= 0) C[cq_.find(k, 2 * l.a + j)] = -2 * d[j];
        }
    }
    return 0;
  }

 private:
  int n_;
  std::vector<Link> links_;
  CscPattern diag_, empty_, cq_;
};

TEST(MakeConsistent, SparseChainWithADuplicatedLinkInTheMiddle) {
  // Eight links; equation 4 repeats link 2 -> 3 (reversed, with the same length).
  const int n = 8;
  std::vector<DistanceChain::Link> links = {{-1, 0, 1.0}, {0, 1, 0.5}, {1, 2, 0.7}, {2, 3, 0.4}};
  links.push_back({3, 2, 0.4});
  for (int i = 4; i < n; ++i) links.push_back({i - 1, i, 0.3 + 0.1 * i});
  DistanceChain sys(n, links);
  State x;
  x.q.resize(2 * n);
  x.v.resize(2 * n);
  for (int i = 0; i < n; ++i) {
    x.q[2 * i] = 0.4 * (i + 1) + 0.05 * std::sin(3.0 * i);
    x.q[2 * i + 1] = -0.2 * i + 0.05 * std::cos(5.0 * i);
    x.v[2 * i] = 0.3 * std::cos(1.0 * i);
    x.v[2 * i + 1] = 0.2 * std::sin(2.0 * i);
  }
  const auto report = MakeConsistent(sys, x);
  ASSERT_TRUE(report.ok) << report.message;
  EXPECT_EQ(report.redundant, std::vector<int>({4}));
  EXPECT_EQ(x.lambda[4], 0.0);
  EXPECT_EQ(FindRedundantConstraints(sys, 0.0, x.q.data(), 1e-9), std::vector<int>({4}));
  const Residuals res = Check(sys, x);
  EXPECT_LT(res.pos, 1e-12);
  EXPECT_LT(res.vel, 1e-12);
  EXPECT_LT(res.dyn, 1e-11);
  EXPECT_LT(res.acc, 1e-11);
  EXPECT_GT(report.initial_position_violation, 1e-2);  // there was something to correct
  EXPECT_GT(report.max_position_change, 1e-3);
}

TEST(MakeConsistent, InconsistentRedundantConstraintIsReported) {
  // Concentric circles of radii 1 and 2: C_q has rank 1 and equation 1 cannot hold.
  PointOnCircles sys({{0, 0, 1, 1}, {0, 0, 2, 1}});
  State x = MakeState({0.3, 0.9}, {0, 0});
  const auto report = MakeConsistent(sys, x);
  EXPECT_FALSE(report.ok);
  EXPECT_EQ(report.violated, std::vector<int>({1}));
  EXPECT_NE(report.message.find("equation(s) 1"), std::string::npos) << report.message;
  EXPECT_LT(report.iterations, 50);  // stops when the steps vanish
  // The independent equation does hold.
  EXPECT_NEAR(std::hypot(x.q[0], x.q[1]), 1.0, 1e-12);
}

TEST(MakeConsistent, DisjointCirclesFailAfterTheIterationLimit) {
  PointOnCircles sys({{0, 0, 1, 1}, {3, 0, 1, 1}});
  State x = MakeState({0.5, 0.5}, {0, 0});
  ConsistencyOptions options;
  options.max_iterations = 20;
  const auto report = MakeConsistent(sys, x, options);
  EXPECT_FALSE(report.ok);
  EXPECT_FALSE(report.violated.empty());
  EXPECT_FALSE(report.message.empty());
  EXPECT_LE(report.iterations, 20);
  std::vector<double> c(2);
  EvalInput in; in.q = x.q.data();
  EvalOutput out; out.constraint = c.data();
  sys.Evaluate(in, out);
  for (int r : report.violated) EXPECT_GT(std::abs(c[r]), options.position_tolerance);
}

TEST(KeepConstraints, ViewMatchesTheKeptRowsOfTheBase) {
  NonlinearSystem base;
  const double q[3] = {0.4, -0.2, 0.6}, v[3] = {0.3, 0.5, -0.8}, a[3] = {1, 2, 3};
  for (int keep : {0, 1}) {
    auto view = KeepConstraints(base, {keep});
    ASSERT_EQ(view->num_constraints(), 1);
    ASSERT_EQ(view->num_coordinates(), 3);
    const double w1 = 0.37;
    double wfull[2] = {0, 0};
    wfull[keep] = w1;
    EvalInput in; in.t = 0.4; in.q = q; in.v = v; in.a = a;
    // Full evaluation of base and view.
    std::vector<double> bc(2), bct(2), bg(2), vc(1), vct(1), vg(1);
    std::vector<std::vector<double>> bm(kNumMatrices), vm(kNumMatrices);
    EvalOutput bout, vout;
    bout.constraint = bc.data(); bout.constraint_dt = bct.data(); bout.acc_rhs = bg.data();
    vout.constraint = vc.data(); vout.constraint_dt = vct.data(); vout.acc_rhs = vg.data();
    for (int m = 0; m < kNumMatrices; ++m) {
      bm[m].assign(base.pattern(static_cast<Matrix>(m)).nnz(), 0.0);
      vm[m].assign(view->pattern(static_cast<Matrix>(m)).nnz(), 0.0);
      bout.matrix[m] = bm[m].data();
      vout.matrix[m] = vm[m].data();
    }
    in.w = wfull;
    ASSERT_EQ(base.Evaluate(in, bout), 0);
    in.w = &w1;
    ASSERT_EQ(view->Evaluate(in, vout), 0);
    EXPECT_EQ(vc[0], bc[keep]);
    EXPECT_EQ(vct[0], bct[keep]);
    EXPECT_EQ(vg[0], bg[keep]);
    for (int m = 0; m < kNumMatrices; ++m) {
      const Matrix mm = static_cast<Matrix>(m);
      const CscPattern& pb = base.pattern(mm);
      const CscPattern& pv = view->pattern(mm);
      std::string why;
      ASSERT_TRUE(pv.IsValid(&why)) << why;
      const bool filtered = mm == Matrix::kConstraintDq || mm == Matrix::kConstraintVelDq;
      ASSERT_EQ(pv.rows, filtered ? 1 : pb.rows);
      ASSERT_EQ(pv.cols, pb.cols);
      int count = 0;
      for (int c = 0; c < pb.cols; ++c)
        for (int k = pb.col_start[c]; k < pb.col_start[c + 1]; ++k) {
          const int r = pb.row_index[k];
          if (filtered && r != keep) continue;
          const int kv = pv.find(filtered ? 0 : r, c);
          ASSERT_GE(kv, 0);
          EXPECT_EQ(vm[m][kv], bm[m][k]) << "matrix " << m;
          ++count;
        }
      EXPECT_EQ(count, pv.nnz());
    }
  }
  EXPECT_THROW(KeepConstraints(base, {1, 0}), std::invalid_argument);
  EXPECT_THROW(KeepConstraints(base, {2}), std::invalid_argument);
}

// With no equation set aside the view hands the evaluation to the base system unchanged
// (no copies): the same patterns and bitwise the same outputs, weights included.
TEST(KeepConstraints, ViewOfEveryEquationIsTheBase) {
  NonlinearSystem base;
  auto view = KeepConstraints(base, {0, 1});
  ASSERT_EQ(view->num_constraints(), 2);
  const double q[3] = {0.4, -0.2, 0.6}, v[3] = {0.3, 0.5, -0.8}, a[3] = {1, 2, 3};
  const double w[2] = {0.37, -1.3};
  EvalInput in; in.t = 0.4; in.q = q; in.v = v; in.a = a; in.w = w;
  std::vector<double> out_b[3], out_v[3];
  std::vector<std::vector<double>> bm(kNumMatrices), vm(kNumMatrices);
  EvalOutput bout, vout;
  for (int k = 0; k < 3; ++k) {
    out_b[k].assign(2, -7.0);
    out_v[k].assign(2, 7.0);
  }
  bout.constraint = out_b[0].data(); bout.constraint_dt = out_b[1].data(); bout.acc_rhs = out_b[2].data();
  vout.constraint = out_v[0].data(); vout.constraint_dt = out_v[1].data(); vout.acc_rhs = out_v[2].data();
  for (int m = 0; m < kNumMatrices; ++m) {
    const Matrix mm = static_cast<Matrix>(m);
    const CscPattern& pb = base.pattern(mm);
    const CscPattern& pv = view->pattern(mm);
    ASSERT_EQ(pv.rows, pb.rows);
    ASSERT_EQ(pv.cols, pb.cols);
    ASSERT_EQ(pv.col_start, pb.col_start) << "matrix " << m;
    ASSERT_EQ(pv.row_index, pb.row_index) << "matrix " << m;
    bm[m].assign(pb.nnz(), -7.0);
    vm[m].assign(pv.nnz(), 7.0);
    bout.matrix[m] = bm[m].data();
    vout.matrix[m] = vm[m].data();
  }
  ASSERT_EQ(base.Evaluate(in, bout), 0);
  ASSERT_EQ(view->Evaluate(in, vout), 0);
  for (int k = 0; k < 3; ++k) EXPECT_EQ(out_v[k], out_b[k]) << "output " << k;
  for (int m = 0; m < kNumMatrices; ++m) EXPECT_EQ(vm[m], bm[m]) << "matrix " << m;
  // Not all zero: the comparison sees real values.
  EXPECT_NE(out_b[0][0], 0.0);
  EXPECT_NE(bm[static_cast<int>(Matrix::kConstraintDq)][0], 0.0);
}

TEST(ConsistencyOptions, Validation) {
  std::string why;
  EXPECT_TRUE(ConsistencyOptions{}.IsValid(&why));
  ConsistencyOptions o;
  o.position_tolerance = 0;
  EXPECT_FALSE(o.IsValid(&why));
  EXPECT_NE(why.find("position_tolerance"), std::string::npos);
  o = {};
  o.rank_tolerance = 1.5;
  EXPECT_FALSE(o.IsValid(&why));
  PendulumSystem sys(1, 1, 1);
  State x = MakeState({1, 0}, {0, 0});
  EXPECT_THROW(MakeConsistent(sys, x, o), std::invalid_argument);
  State bad = MakeState({1, 0, 0}, {0, 0});
  EXPECT_THROW(MakeConsistent(sys, bad), std::invalid_argument);
}

}  // namespace
}  // namespace mbdae::dae
