// Shared by the HHT sensitivity tests (test_hht_sensitivity.cc, test_hht_checkpoint.cc):
// test objectives, a pendulum and a heavy top with their initial-state derivatives, and a
// recorded HHT run with its objective values.
#pragma once

#include <gtest/gtest.h>

#include <cmath>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "dae/consistent.h"
#include "dae/hht.h"
#include "mbs/loader.h"
#include "mbs/system.h"
#include "sensitivities/hht_sensitivity.h"
#include "sensitivities/initial_state.h"
#include "tests/support/parametric_pendulum.h"

namespace mbdae::hht_test {

using sens::HhtSensitivityResult;
using sens::HhtTrajectory;
using sens::InitialStateDerivatives;

// Two objectives of the pendulum: G0 = int 1/2 m |v|^2 + 0.3 lambda + 0.1 a_y dt + x(T),
// G1 = int y dt + 0.5 v_y(T). Depends on every part of the state and on m directly.
class PendulumObjectives : public sens::ObjectiveFunction {
 public:
  explicit PendulumObjectives(testing::ParametricPendulum& sys) : sys_(sys) {}
  int num_objectives() const override { return 2; }
  const std::vector<std::string>& names() const override { return names_; }
  bool has_integral(int) const override { return true; }
  bool has_terminal(int) const override { return true; }
  bool depends_on_acceleration() const override { return true; }
  bool depends_on_multipliers() const override { return true; }
  int Integrand(const sens::ObjectivePoint& x, double* g) override {
    const double m = sys_.parameter(0);
    g[0] = 0.5 * m * (x.v[0] * x.v[0] + x.v[1] * x.v[1]) + 0.3 * x.lambda[0] + 0.1 * x.a[1];
    g[1] = x.q[1];
    return 0;
  }
  int Terminal(const sens::ObjectivePoint& x, double* phi) override {
    phi[0] = x.q[0];
    phi[1] = 0.5 * x.v[1];
    return 0;
  }
  int IntegrandGradient(const sens::ObjectivePoint& x, const double* w,
                        sens::ObjectiveGradient* out) override {
    const double m = sys_.parameter(0);
    if (out->dv) {
      out->dv[0] += w[0] * m * x.v[0];
      out->dv[1] += w[0] * m * x.v[1];
    }
    if (out->dlambda) out->dlambda[0] += w[0] * 0.3;
    if (out->da) out->da[1] += w[0] * 0.1;
    if (out->dq) out->dq[1] += w[1];
    if (out->dp) out->dp[0] += w[0] * 0.5 * (x.v[0] * x.v[0] + x.v[1] * x.v[1]);
    return 0;
  }
  int TerminalGradient(const sens::ObjectivePoint&, const double* w,
                       sens::ObjectiveGradient* out) override {
    if (out->dq) out->dq[0] += w[0];
    if (out->dv) out->dv[1] += 0.5 * w[1];
    return 0;
  }

 private:
  testing::ParametricPendulum& sys_;
  std::vector<std::string> names_{"G0", "G1"};
};

constexpr double kTheta0 = 0.7;

// The consistent initial state of the pendulum released at rest from kTheta0.
inline dae::State PendulumStart(testing::ParametricPendulum& sys) {
  dae::State x;
  x.Resize(2, 1);
  const double L = sys.parameter(testing::ParametricPendulum::kLength);
  x.q = {L * std::sin(kTheta0), -L * std::cos(kTheta0)};
  const dae::ConsistencyReport rep = dae::MakeConsistent(sys, x);
  EXPECT_TRUE(rep.ok) << rep.message;
  return x;
}

struct RecordedRun {
  HhtTrajectory traj{0, 0};
  std::vector<double> values;  // quadrature + terminal
};

// A whole run recorded into run.traj (every state, or checkpoints under a memory
// budget of `budget` bytes).
inline RecordedRun RunHht(dae::MechanicalSystem& sys, sens::ObjectiveFunction& obj,
                  const dae::HhtOptions& opt, const dae::State& x0, double t_end,
                  double output_step, size_t budget = 0) {
  RecordedRun run;
  run.traj = HhtTrajectory(sys.num_coordinates(), sys.num_constraints());
  run.traj.set_memory_budget(budget);
  auto integ = dae::MakeHhtIntegrator(sys, opt);
  dae::Quadrature quad;
  quad.size = obj.num_objectives();
  quad.integrand = [&](double t, const double* q, const double* v, const double* a,
                       const double* l, double* g) {
    sens::ObjectivePoint p{t, q, v, a, l};
    return obj.Integrand(p, g);
  };
  integ->SetQuadrature(quad);
  run.traj.Attach(*integ);
  integ->Initialize(x0);
  const int n_out = static_cast<int>(std::round(t_end / output_step));
  for (int i = 1; i <= n_out; ++i)
    EXPECT_TRUE(integ->AdvanceTo(i * output_step)) << integ->summary().BriefReport();
  const dae::State& x = integ->state();
  std::vector<double> phi(obj.num_objectives());
  sens::ObjectivePoint p{x.t, x.q.data(), x.v.data(), x.a.data(), x.lambda.data()};
  obj.Terminal(p, phi.data());
  run.values = integ->quadrature();
  for (size_t j = 0; j < phi.size(); ++j) run.values[j] += phi[j];
  return run;
}

// Fourth-order central difference of f at p with step d.
inline double Richardson(const std::function<double(double)>& f, double p, double d) {
  return (8 * (f(p + d) - f(p - d)) - (f(p + 2 * d) - f(p - 2 * d))) / (12 * d);
}

// The pendulum's initial-state derivatives: q = L (sin, -cos) moves with L, v = 0.
inline InitialStateDerivatives PendulumInitialDerivatives(testing::ParametricPendulum& sys,
                                                          const dae::State& x0) {
  std::vector<double> dq_raw(2 * 4, 0.0), dv_raw(2 * 4, 0.0);
  dq_raw[2 * testing::ParametricPendulum::kLength + 0] = std::sin(kTheta0);
  dq_raw[2 * testing::ParametricPendulum::kLength + 1] = -std::cos(kTheta0);
  InitialStateDerivatives dx0;
  std::string err;
  EXPECT_TRUE(sens::ConsistentInitialStateDerivatives(sys, x0, {0.0, 0.0}, dq_raw, dv_raw, &dx0, &err)) << err;
  return dx0;
}

// A system with np pseudo-parameters on which nothing depends: the gradient is then the
// derivative with respect to the initial state along given directions (dx0).
class PseudoParameters : public dae::MechanicalSystem {
 public:
  PseudoParameters(dae::MechanicalSystem& base, int np) : base_(base), np_(np) {
    for (int m = 0; m < dae::kNumParameterMatrices; ++m) {
      const bool rows_c = m >= static_cast<int>(dae::ParameterMatrix::kConstraintDp);
      empty_[m] = dae::CscPattern::FromEntries(rows_c ? base.num_constraints() : base.num_coordinates(),
                                               np, {});
    }
  }
  int num_coordinates() const override { return base_.num_coordinates(); }
  int num_constraints() const override { return base_.num_constraints(); }
  const dae::CscPattern& pattern(dae::Matrix m) const override { return base_.pattern(m); }
  const std::vector<int>& quaternion_offsets() const override { return base_.quaternion_offsets(); }
  int Evaluate(const dae::EvalInput& in, dae::EvalOutput& out) override {
    dae::EvalOutput o = out;
    for (double*& p : o.parameter_matrix) p = nullptr;
    return base_.Evaluate(in, o);
  }
  int num_parameters() const override { return np_; }
  const dae::CscPattern& parameter_pattern(dae::ParameterMatrix m) const override {
    return empty_[static_cast<int>(m)];
  }
  const char* last_error() const override { return base_.last_error(); }

 private:
  dae::MechanicalSystem& base_;
  int np_;
  dae::CscPattern empty_[dae::kNumParameterMatrices];
};

// Objectives over the whole state: G0 = int sum_i c_i q_i^2 + d_i v_i + 0.01 a_i dt,
// G1 = int lambda . 1 dt + sum_i q_i v_i (T).
class StateObjectives : public sens::ObjectiveFunction {
 public:
  StateObjectives(int nq, int nc) : nq_(nq), nc_(nc) {}
  int num_objectives() const override { return 2; }
  const std::vector<std::string>& names() const override { return names_; }
  bool has_integral(int) const override { return true; }
  bool has_terminal(int j) const override { return j == 1; }
  bool depends_on_acceleration() const override { return true; }
  bool depends_on_multipliers() const override { return true; }
  static double C(int i) { return 0.3 + 0.1 * (i % 5); }
  static double D(int i) { return 0.05 * ((i % 3) - 1); }
  int Integrand(const sens::ObjectivePoint& x, double* g) override {
    g[0] = g[1] = 0;
    for (int i = 0; i < nq_; ++i) g[0] += C(i) * x.q[i] * x.q[i] + D(i) * x.v[i] + 0.01 * x.a[i];
    for (int c = 0; c < nc_; ++c) g[1] += x.lambda[c];
    return 0;
  }
  int Terminal(const sens::ObjectivePoint& x, double* phi) override {
    phi[0] = phi[1] = 0;
    for (int i = 0; i < nq_; ++i) phi[1] += x.q[i] * x.v[i];
    return 0;
  }
  int IntegrandGradient(const sens::ObjectivePoint& x, const double* w,
                        sens::ObjectiveGradient* out) override {
    for (int i = 0; i < nq_; ++i) {
      if (out->dq) out->dq[i] += w[0] * 2 * C(i) * x.q[i];
      if (out->dv) out->dv[i] += w[0] * D(i);
      if (out->da) out->da[i] += w[0] * 0.01;
    }
    if (out->dlambda)
      for (int c = 0; c < nc_; ++c) out->dlambda[c] += w[1];
    return 0;
  }
  int TerminalGradient(const sens::ObjectivePoint& x, const double* w,
                       sens::ObjectiveGradient* out) override {
    for (int i = 0; i < nq_; ++i) {
      if (out->dq) out->dq[i] += w[1] * x.v[i];
      if (out->dv) out->dv[i] += w[1] * x.q[i];
    }
    return 0;
  }

 private:
  int nq_, nc_;
  std::vector<std::string> names_{"G0", "G1"};
};
// The heavy top (verification/heavy_top): a spherical joint, gravity, Euler parameters,
// with np = 3 pseudo-parameters: directions of the initial velocity (dirs, nq x 3).
struct HeavyTop {
  static constexpr int np = 3;
  mbs::Model model;
  std::unique_ptr<mbs::MultibodySystem> base;
  std::unique_ptr<PseudoParameters> sys;
  int nq = 0, nc = 0;
  dae::State x0;
  std::vector<double> dirs;
  InitialStateDerivatives dx0;

  HeavyTop() {
    model = mbs::LoadModel(std::string(MBDAE_SOURCE_DIR) + "/verification/heavy_top/heavy_top.yaml");
    base = std::make_unique<mbs::MultibodySystem>(model);
    nq = base->num_coordinates();
    nc = base->num_constraints();
    sys = std::make_unique<PseudoParameters>(*base, np);
    x0.t = 0;
    base->InitialState(x0.q, x0.v);
    EXPECT_TRUE(dae::MakeConsistent(*sys, x0).ok);
    dirs.assign(size_t(nq) * np, 0.0);
    for (int k = 0; k < np; ++k)
      for (int i = 0; i < nq; ++i) dirs[size_t(k) * nq + i] = std::sin(1.0 + 3.1 * k + 0.7 * i);
    std::vector<double> dq_raw(size_t(nq) * np, 0.0);
    std::string err;
    EXPECT_TRUE(sens::ConsistentInitialStateDerivatives(*sys, x0, x0.v, dq_raw, dirs, &dx0, &err)) << err;
  }

  // The options of the heavy top's tests: converged runs (gradients exact to this).
  static dae::HhtOptions Options(bool modified, bool adaptive) {
    dae::HhtOptions opt;
    opt.modified = modified;
    opt.alpha = -0.1;
    opt.step = modified ? 2.5e-4 : (adaptive ? 1e-3 : 2e-3);
    opt.max_newton_iterations = 50;
    opt.adaptive = adaptive;
    opt.tolerance = 1e-5;
    opt.newton_tolerance = 1e-14;
    opt.adaptive_newton_factor = 1e-10;
    opt.newton_noise_factor = 100;
    return opt;
  }
};

}  // namespace mbdae::hht_test
