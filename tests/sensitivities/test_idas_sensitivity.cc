// IDAS forward and adjoint sensitivities (sensitivities/idas_sensitivity.h) on the
// parametric pendulum: against central differences of whole IDA runs with the same
// settings, forward against adjoint, and the adjoint's refusal of objectives in a or
// lambda.
#include "sensitivities/idas_sensitivity.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <functional>
#include <string>
#include <vector>

#include "dae/consistent.h"
#include "dae/ida.h"
#include "sensitivities/initial_state.h"
#include "tests/support/parametric_pendulum.h"

namespace mbdae {
namespace {

using testing::ParametricPendulum;

// Objectives of the pendulum. State-only set (what the adjoint supports):
//   G0 = int 1/2 m |v|^2 dt               (kinetic energy; depends on m directly)
//   G1 = x(T)
//   G2 = int x y dt + L v_x(T)            (terminal in v and in L directly)
// With `full`, a and lambda enter as well (forward only):
//   G0 += int 0.3 lambda + 0.1 a_y dt,    G1 += 0.2 a_x(T) + 0.05 lambda(T).
class PendulumObjectives : public sens::ObjectiveFunction {
 public:
  PendulumObjectives(ParametricPendulum& sys, bool full) : sys_(sys), full_(full) {}
  int num_objectives() const override { return 3; }
  const std::vector<std::string>& names() const override { return names_; }
  bool has_integral(int i) const override { return i != 1; }
  bool has_terminal(int i) const override { return i != 0; }
  bool depends_on_acceleration() const override { return full_; }
  bool depends_on_multipliers() const override { return full_; }
  int Integrand(const sens::ObjectivePoint& x, double* g) override {
    const double m = sys_.parameter(ParametricPendulum::kMass);
    g[0] = 0.5 * m * (x.v[0] * x.v[0] + x.v[1] * x.v[1]);
    if (full_) g[0] += 0.3 * x.lambda[0] + 0.1 * x.a[1];
    g[1] = 0;
    g[2] = x.q[0] * x.q[1];
    return 0;
  }
  int Terminal(const sens::ObjectivePoint& x, double* phi) override {
    const double L = sys_.parameter(ParametricPendulum::kLength);
    phi[0] = 0;
    phi[1] = x.q[0];
    if (full_) phi[1] += 0.2 * x.a[0] + 0.05 * x.lambda[0];
    phi[2] = L * x.v[0];
    return 0;
  }
  int IntegrandGradient(const sens::ObjectivePoint& x, const double* w,
                        sens::ObjectiveGradient* out) override {
    const double m = sys_.parameter(ParametricPendulum::kMass);
    if (out->dv) {
      out->dv[0] += w[0] * m * x.v[0];
      out->dv[1] += w[0] * m * x.v[1];
    }
    if (out->dp) out->dp[ParametricPendulum::kMass] += w[0] * 0.5 * (x.v[0] * x.v[0] + x.v[1] * x.v[1]);
    if (out->dq) {
      out->dq[0] += w[2] * x.q[1];
      out->dq[1] += w[2] * x.q[0];
    }
    if (full_) {
      if (out->dlambda) out->dlambda[0] += w[0] * 0.3;
      if (out->da) out->da[1] += w[0] * 0.1;
    }
    return 0;
  }
  int TerminalGradient(const sens::ObjectivePoint& x, const double* w,
                       sens::ObjectiveGradient* out) override {
    const double L = sys_.parameter(ParametricPendulum::kLength);
    if (out->dq) out->dq[0] += w[1];
    if (out->dv) out->dv[0] += w[2] * L;
    if (out->dp) out->dp[ParametricPendulum::kLength] += w[2] * x.v[0];
    if (full_) {
      if (out->da) out->da[0] += w[1] * 0.2;
      if (out->dlambda) out->dlambda[0] += w[1] * 0.05;
    }
    return 0;
  }

 private:
  ParametricPendulum& sys_;
  bool full_;
  std::vector<std::string> names_{"kinetic", "x_end", "mixed"};
};

constexpr double kTheta0 = 0.7, kOmega0 = 1.5;
constexpr double kP[4] = {1.3, 0.9, 9.81, 0.4};  // m, L, g, c
constexpr double kTEnd = 1.0;

// Raw start: q = L (sin, -cos), v = omega0 L (cos, sin), both moving with L.
std::vector<double> RawV(double L) { return {kOmega0 * L * std::cos(kTheta0), kOmega0 * L * std::sin(kTheta0)}; }

dae::State Start(ParametricPendulum& sys) {
  const double L = sys.parameter(ParametricPendulum::kLength);
  dae::State x;
  x.Resize(2, 1);
  x.q = {L * std::sin(kTheta0), -L * std::cos(kTheta0)};
  x.v = RawV(L);
  const dae::ConsistencyReport rep = dae::MakeConsistent(sys, x);
  EXPECT_TRUE(rep.ok) << rep.message;
  return x;
}

sens::InitialStateDerivatives StartDerivatives(ParametricPendulum& sys, const dae::State& x0) {
  std::vector<double> dq_raw(2 * 4, 0.0), dv_raw(2 * 4, 0.0);
  const int k = ParametricPendulum::kLength;
  dq_raw[2 * k + 0] = std::sin(kTheta0);
  dq_raw[2 * k + 1] = -std::cos(kTheta0);
  dv_raw[2 * k + 0] = kOmega0 * std::cos(kTheta0);
  dv_raw[2 * k + 1] = kOmega0 * std::sin(kTheta0);
  sens::InitialStateDerivatives dx0;
  std::string err;
  EXPECT_TRUE(sens::ConsistentInitialStateDerivatives(
      sys, x0, RawV(sys.parameter(ParametricPendulum::kLength)), dq_raw, dv_raw, &dx0, &err))
      << err;
  return dx0;
}

sens::IdasSensitivityOptions Options(double rtol) {
  sens::IdasSensitivityOptions opt;
  opt.ida.rtol = rtol;
  opt.ida.atol = rtol * 1e-2;
  opt.t_end = kTEnd;
  for (int i = 1; i < 10; ++i) opt.output_times.push_back(0.1 * i);
  return opt;
}

// The objective values of a plain IDA run (the integrator's quadrature) with the same
// settings and output times.
// The pendulum with a configuration-dependent mass matrix M = m (1 + kappa x^2) I, so
// that d(M a)/dq and dM/dt enter (the adjoint's dM/dt chi2 term). Not a physical
// system, a DAE with the same structure.
class VariableMassPendulum : public ParametricPendulum {
 public:
  static constexpr double kKappa = 0.8;
  using ParametricPendulum::ParametricPendulum;
  const dae::CscPattern& pattern(dae::Matrix m) const override {
    if (m == dae::Matrix::kMassTimesAccDq) return madq_;
    return ParametricPendulum::pattern(m);
  }
  int Evaluate(const dae::EvalInput& in, dae::EvalOutput& out) override {
    const int code = ParametricPendulum::Evaluate(in, out);
    if (code != 0) return code;
    const double m = parameter(kMass), x = in.q[0], s = 1 + kKappa * x * x;
    const double zero[2] = {0, 0};
    const double* a = in.a ? in.a : zero;
    if (double* M = out[dae::Matrix::kMass]) { M[0] = m * s; M[1] = m * s; }
    if (double* K = out[dae::Matrix::kMassTimesAccDq]) {
      K[0] = m * 2 * kKappa * x * a[0];
      K[1] = m * 2 * kKappa * x * a[1];
    }
    if (double* P = out[dae::ParameterMatrix::kMassTimesAccDp]) { P[0] = s * a[0]; P[1] = s * a[1]; }
    return 0;
  }

 private:
  dae::CscPattern madq_ = dae::CscPattern::FromEntries(2, 2, {{0, 0}, {1, 0}});
};

template <typename System>
std::vector<double> RunValues(const double* p, bool full, const sens::IdasSensitivityOptions& opt) {
  System sys(p[0], p[1], p[2], p[3]);
  PendulumObjectives obj(sys, full);
  auto ida = dae::MakeIdaIntegrator(sys, opt.ida);
  dae::Quadrature quad;
  quad.size = obj.num_objectives();
  quad.integrand = [&](double t, const double* q, const double* v, const double* a,
                       const double* l, double* g) { return obj.Integrand({t, q, v, a, l}, g); };
  ida->SetQuadrature(quad);
  ida->Initialize(Start(sys));
  std::vector<double> times = opt.output_times;
  times.push_back(opt.t_end);
  for (double t : times) EXPECT_TRUE(ida->AdvanceTo(t)) << ida->summary().message;
  const dae::State& x = ida->state();
  std::vector<double> phi(obj.num_objectives());
  obj.Terminal({x.t, x.q.data(), x.v.data(), x.a.data(), x.lambda.data()}, phi.data());
  std::vector<double> values = ida->quadrature();
  for (size_t i = 0; i < values.size(); ++i) values[i] += phi[i];
  return values;
}

// Fourth-order central differences of whole runs, step 1e-3 |p_k|.
template <typename System = ParametricPendulum>
std::vector<double> FiniteDifferences(bool full, const sens::IdasSensitivityOptions& opt) {
  std::vector<double> grad(3 * 4);
  for (int k = 0; k < 4; ++k) {
    const double d = 1e-3 * std::abs(kP[k]);
    auto at = [&](double step) {
      double p[4] = {kP[0], kP[1], kP[2], kP[3]};
      p[k] += step;
      return RunValues<System>(p, full, opt);
    };
    const auto p1 = at(d), m1 = at(-d), p2 = at(2 * d), m2 = at(-2 * d);
    for (int i = 0; i < 3; ++i)
      grad[i * 4 + k] = (8 * (p1[i] - m1[i]) - (p2[i] - m2[i])) / (12 * d);
  }
  return grad;
}

double Scale(const std::vector<double>& g, int i) {
  double s = 0;
  for (int k = 0; k < 4; ++k) s = std::max(s, std::abs(g[i * 4 + k]));
  return s;
}

// Largest |a - b| / (largest |b| of the objective), over all entries.
double MaxRelative(const std::vector<double>& a, const std::vector<double>& b, const char* what) {
  double worst = 0;
  for (int i = 0; i < 3; ++i)
    for (int k = 0; k < 4; ++k) {
      const double e = std::abs(a[i * 4 + k] - b[i * 4 + k]) / Scale(b, i);
      std::printf("%s G%d p%d %.12g vs %.12g  rel %.2e\n", what, i, k, a[i * 4 + k], b[i * 4 + k], e);
      worst = std::max(worst, e);
    }
  return worst;
}

TEST(IdasSensitivity, ForwardAndAdjointAgreeWithFiniteDifferences) {
  const auto opt = Options(1e-10);
  ParametricPendulum sys(kP[0], kP[1], kP[2], kP[3]);
  PendulumObjectives obj(sys, false);
  const dae::State x0 = Start(sys);
  const sens::InitialStateDerivatives dx0 = StartDerivatives(sys, x0);
  sens::IdasSensitivityResult fwd, adj;
  std::string err;
  ASSERT_TRUE(sens::IdasForwardGradient(sys, opt, obj, x0, dx0, &fwd, &err)) << err;
  ASSERT_TRUE(sens::IdasAdjointGradient(sys, opt, obj, x0, dx0, &adj, &err)) << err;
  const std::vector<double> values = RunValues<ParametricPendulum>(kP, false, opt);
  for (int i = 0; i < 3; ++i) {
    EXPECT_NEAR(fwd.values[i], values[i], 1e-8 * (1 + std::abs(values[i])));
    EXPECT_NEAR(adj.values[i], values[i], 1e-8 * (1 + std::abs(values[i])));
  }
  // The reference runs at rtol 1e-12: at 1e-10 the differences of whole runs carry
  // the runs' error (up to 1e-5 relative here), not the derivative's.
  const std::vector<double> fd = FiniteDifferences(false, Options(1e-12));
  const double e_fwd = MaxRelative(fwd.gradient, fd, "forward/fd");
  const double e_adj = MaxRelative(adj.gradient, fd, "adjoint/fd");
  const double e_fa = MaxRelative(adj.gradient, fwd.gradient, "adjoint/forward");
  std::printf("max relative differences: forward-fd %.2e, adjoint-fd %.2e, adjoint-forward %.2e\n",
              e_fwd, e_adj, e_fa);
  std::printf("forward: %ld steps, %.3f s; adjoint: %ld forward + %ld backward steps, %ld checkpoints, %.3f s\n",
              fwd.steps, fwd.wall_time, adj.steps, adj.backward_steps, adj.checkpoints, adj.wall_time);
  // Measured: 6.9e-8, 6.9e-8 and 1.9e-8.
  EXPECT_LT(e_fwd, 1e-6);
  EXPECT_LT(e_adj, 1e-6);
  EXPECT_LT(e_fa, 1e-7);
  EXPECT_GT(fwd.steps, 0);
  EXPECT_GT(adj.backward_steps, 0);
}


// Objectives in a and lambda: the forward method takes them, the adjoint refuses them.
TEST(IdasSensitivity, ObjectivesInAccelerationsAndMultipliers) {
  const auto opt = Options(1e-10);
  ParametricPendulum sys(kP[0], kP[1], kP[2], kP[3]);
  PendulumObjectives obj(sys, true);
  const dae::State x0 = Start(sys);
  const sens::InitialStateDerivatives dx0 = StartDerivatives(sys, x0);
  sens::IdasSensitivityResult fwd, adj;
  std::string err;
  ASSERT_TRUE(sens::IdasForwardGradient(sys, opt, obj, x0, dx0, &fwd, &err)) << err;
  const std::vector<double> fd = FiniteDifferences(true, Options(1e-12));
  const double e = MaxRelative(fwd.gradient, fd, "forward(a, lambda)/fd");
  std::printf("objectives in a and lambda: max relative difference forward-fd %.2e\n", e);
  EXPECT_LT(e, 1e-6);
  EXPECT_FALSE(sens::IdasAdjointGradient(sys, opt, obj, x0, dx0, &adj, &err));
  EXPECT_NE(err.find("accelerations or multipliers"), std::string::npos) << err;
}

// The checkpoint interval changes the work, not the gradient; a second call gives the
// same numbers (no state left over).
TEST(IdasSensitivity, AdjointIndependentOfCheckpointsAndRepeatable) {
  ParametricPendulum sys(kP[0], kP[1], kP[2], kP[3]);
  PendulumObjectives obj(sys, false);
  const dae::State x0 = Start(sys);
  const sens::InitialStateDerivatives dx0 = StartDerivatives(sys, x0);
  std::string err;
  auto opt = Options(1e-10);
  sens::IdasSensitivityResult fwd, first, again;
  ASSERT_TRUE(sens::IdasForwardGradient(sys, opt, obj, x0, dx0, &fwd, &err)) << err;
  for (long steps : {10L, 100L, 100000L}) {
    opt.checkpoint_steps = steps;
    sens::IdasSensitivityResult adj;
    ASSERT_TRUE(sens::IdasAdjointGradient(sys, opt, obj, x0, dx0, &adj, &err)) << err;
    const double e = MaxRelative(adj.gradient, fwd.gradient, "adjoint/forward");
    std::printf("checkpoint interval %ld: %ld checkpoints, adjoint-forward %.2e\n", steps,
                adj.checkpoints, e);
    EXPECT_LT(e, 1e-7);
  }
  opt.checkpoint_steps = 50;
  ASSERT_TRUE(sens::IdasAdjointGradient(sys, opt, obj, x0, dx0, &first, &err)) << err;
  ASSERT_TRUE(sens::IdasAdjointGradient(sys, opt, obj, x0, dx0, &again, &err)) << err;
  EXPECT_EQ(first.gradient, again.gradient);
  EXPECT_EQ(first.values, again.values);
  EXPECT_GT(first.checkpoints, 1);
}

TEST(IdasSensitivity, BadInputIsReported) {
  ParametricPendulum sys(kP[0], kP[1], kP[2], kP[3]);
  PendulumObjectives obj(sys, false);
  const dae::State x0 = Start(sys);
  sens::InitialStateDerivatives dx0 = StartDerivatives(sys, x0);
  sens::IdasSensitivityResult r;
  std::string err;
  auto opt = Options(1e-8);
  opt.t_end = 0;
  EXPECT_FALSE(sens::IdasForwardGradient(sys, opt, obj, x0, dx0, &r, &err));
  EXPECT_NE(err.find("t_end"), std::string::npos) << err;
  opt = Options(1e-8);
  opt.output_times = {0.5, 0.2};
  EXPECT_FALSE(sens::IdasAdjointGradient(sys, opt, obj, x0, dx0, &r, &err));
  EXPECT_NE(err.find("increasing"), std::string::npos) << err;
  opt = Options(1e-8);
  dx0.dq.pop_back();
  EXPECT_FALSE(sens::IdasForwardGradient(sys, opt, obj, x0, dx0, &r, &err));
  EXPECT_NE(err.find("nq x np"), std::string::npos) << err;
}


// A configuration-dependent mass matrix: d(M a)/dq in the sensitivity and adjoint
// equations, dM/dt chi2 in the adjoint residual and its terminal values.
TEST(IdasSensitivity, VariableMassMatrix) {
  const auto opt = Options(1e-10);
  VariableMassPendulum sys(kP[0], kP[1], kP[2], kP[3]);
  PendulumObjectives obj(sys, false);
  const dae::State x0 = Start(sys);
  const sens::InitialStateDerivatives dx0 = StartDerivatives(sys, x0);
  sens::IdasSensitivityResult fwd, adj;
  std::string err;
  ASSERT_TRUE(sens::IdasForwardGradient(sys, opt, obj, x0, dx0, &fwd, &err)) << err;
  ASSERT_TRUE(sens::IdasAdjointGradient(sys, opt, obj, x0, dx0, &adj, &err)) << err;
  const std::vector<double> fd = FiniteDifferences<VariableMassPendulum>(false, Options(1e-12));
  const double e_fwd = MaxRelative(fwd.gradient, fd, "variable mass forward/fd");
  const double e_adj = MaxRelative(adj.gradient, fd, "variable mass adjoint/fd");
  std::printf("variable mass: max relative differences forward-fd %.2e, adjoint-fd %.2e\n", e_fwd, e_adj);
  EXPECT_LT(e_fwd, 1e-6);
  EXPECT_LT(e_adj, 1e-6);
}

}  // namespace
}  // namespace mbdae
