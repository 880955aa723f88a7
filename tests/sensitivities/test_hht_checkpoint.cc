// Checkpointing of the HHT sweeps (docs/sensitivities.md, "Memory and checkpoints"):
//  - an HHT integrator restored from a snapshot taken mid-run and replaying the run's
//    steps continues as the uninterrupted run (to the Newton tolerance), and without the
//    snapshot's history (Initialize from the same state) it does not;
//  - gradients over a trajectory kept under a small memory budget (several rounds of
//    thinning, every state recomputed from checkpoints) equal those over the trajectory
//    of every state, for the adjoint and direct differentiation, on the pendulum (both
//    forms, fixed and adaptive step) and the heavy top (modified and classical scheme);
//    the record stays under its budget and the sweep adds at most one segment;
//  - budgets and snapshots that cannot work are refused with a reason.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <stdexcept>

#include "dae/ida.h"
#include "tests/sensitivities/hht_test_support.h"

namespace mbdae::hht_test {
namespace {

// max |x - y| / (1 + |y|) over n entries.
double RelDiff(const double* x, const double* y, size_t n) {
  double d = 0;
  for (size_t i = 0; i < n; ++i) d = std::max(d, std::abs(x[i] - y[i]) / (1 + std::abs(y[i])));
  return d;
}

struct StateDiff {
  double qv = 0, a = 0, lambda = 0;
};
StateDiff Diff(const dae::State& x, const dae::State& y) {
  StateDiff d;
  d.qv = std::max(RelDiff(x.q.data(), y.q.data(), y.q.size()), RelDiff(x.v.data(), y.v.data(), y.v.size()));
  d.a = RelDiff(x.a.data(), y.a.data(), y.a.size());
  d.lambda = RelDiff(x.lambda.data(), y.lambda.data(), y.lambda.size());
  return d;
}

// Runs to t_end recording every state and step; takes a snapshot after step `at`.
struct Recorded {
  std::vector<dae::State> states;
  std::vector<double> steps;  // h_1 .. h_N
  dae::IntegratorSnapshot snapshot;
};
Recorded RecordRun(dae::MechanicalSystem& sys, const dae::HhtOptions& opt, const dae::State& x0,
                   double t_end, int at) {
  Recorded rec;
  auto integ = dae::MakeHhtIntegrator(sys, opt);
  integ->SetStepObserver([&](const dae::State& x, double h) {
    rec.states.push_back(x);
    if (h > 0) rec.steps.push_back(h);
    if (static_cast<int>(rec.states.size()) == at + 1) integ->SaveSnapshot(&rec.snapshot);
  });
  integ->Initialize(x0);
  for (int i = 1; i <= 4; ++i) EXPECT_TRUE(integ->AdvanceTo(t_end * i / 4)) << integ->summary().message;
  return rec;
}

// Continues from snapshot (or, restore = false, Initialize from its state) replaying the
// recorded steps; returns the largest differences from the recorded states.
StateDiff Continue(dae::MechanicalSystem& sys, dae::HhtOptions opt, const Recorded& rec, int at,
                   bool restore) {
  opt.replay_steps = rec.steps;
  if (!restore) opt.replay_steps.erase(opt.replay_steps.begin(), opt.replay_steps.begin() + at);
  auto integ = dae::MakeHhtIntegrator(sys, opt);
  if (restore)
    integ->RestoreSnapshot(rec.snapshot);
  else
    integ->Initialize(rec.snapshot.state);
  StateDiff worst;
  for (size_t n = at + 1; n < rec.states.size(); ++n) {
    EXPECT_TRUE(integ->AdvanceTo(rec.states[n].t)) << integ->summary().message;
    EXPECT_EQ(integ->state().t, rec.states[n].t);
    const StateDiff d = Diff(integ->state(), rec.states[n]);
    worst.qv = std::max(worst.qv, d.qv);
    worst.a = std::max(worst.a, d.a);
    worst.lambda = std::max(worst.lambda, d.lambda);
  }
  return worst;
}

// Restored: q, v within 1e-12 (relative, 1 + |x|) of the uninterrupted run, every step
// after the snapshot. a and lambda follow from the Newton iteration, whose stopping test
// weighs the correction of a by gamma h and beta h^2: within 1e-12 / (gamma h) and
// 1e-12 / (beta h^2) (h the smallest step). Without the history (Initialize from the
// same state) an equilibrium-form run departs by more than 1e-9: the test sees abar.
void RestoreCase(dae::MechanicalSystem& sys, const dae::HhtOptions& opt, const dae::State& x0,
                 double t_end, int at) {
  const Recorded rec = RecordRun(sys, opt, x0, t_end, at);
  ASSERT_GT(static_cast<int>(rec.states.size()), at + 20);
  ASSERT_EQ(rec.snapshot.state.t, rec.states[at].t);
  const StateDiff restored = Continue(sys, opt, rec, at, true);
  const double h = *std::min_element(rec.steps.begin(), rec.steps.end());
  const double beta = (1 - opt.alpha) * (1 - opt.alpha) / 4, gamma = 0.5 - opt.alpha;
  EXPECT_LE(restored.qv, 1e-12);
  EXPECT_LE(restored.a, 1e-12 / (gamma * h));
  EXPECT_LE(restored.lambda, 1e-12 / (beta * h * h));
  // The negrut form carries F_n, a function of the state: Initialize rebuilds it.
  const StateDiff fresh = Continue(sys, opt, rec, at, false);
  if (opt.form == dae::HhtOptions::Form::kEquilibrium)
    EXPECT_GT(fresh.qv, 1e-9) << "Initialize from the snapshot's state should differ";
  std::printf("restored: q, v %.2e  a %.2e  lambda %.2e; initialized instead: q, v %.2e\n",
              restored.qv, restored.a, restored.lambda, fresh.qv);
}

TEST(HhtRestore, HeavyTopModifiedEquilibriumAdaptive) {
  HeavyTop top;
  RestoreCase(*top.sys, HeavyTop::Options(true, true), top.x0, 0.3, 60);
}

TEST(HhtRestore, HeavyTopClassicalNegrutFixedStep) {
  HeavyTop top;
  dae::HhtOptions opt = HeavyTop::Options(false, false);
  opt.form = dae::HhtOptions::Form::kNegrut;
  RestoreCase(*top.sys, opt, top.x0, 0.2, 37);
}

TEST(HhtRestore, PendulumNegrutAdaptive) {
  testing::ParametricPendulum sys(1.3, 0.9, 9.81, 0.4);
  dae::HhtOptions opt;
  opt.form = dae::HhtOptions::Form::kNegrut;
  opt.modified = false;
  opt.alpha = -0.2;
  opt.adaptive = true;
  opt.tolerance = 1e-7;
  opt.newton_tolerance = 1e-14;
  opt.adaptive_newton_factor = 1e-7;
  RestoreCase(sys, opt, PendulumStart(sys), 1.0, 25);
}

// The linear predictor extrapolates from a_{n-1} and lambda_{n-1}: the snapshot carries
// them (the recorded state before the snapshot's), and a restored run continues within
// the Newton threshold's reach as with the constant predictor.
TEST(HhtRestore, HeavyTopLinearPredictorCarriesThePreviousStep) {
  HeavyTop top;
  dae::HhtOptions opt = HeavyTop::Options(true, true);
  opt.predictor = dae::HhtOptions::Predictor::kLinear;
  const int at = 60;
  const Recorded rec = RecordRun(*top.sys, opt, top.x0, 0.3, at);
  ASSERT_GT(static_cast<int>(rec.states.size()), at + 20);
  const int ng = 1;
  const double* prev = rec.snapshot.history.data() + dae::HhtHistory::kVectors + top.nq + 3 * ng;
  const dae::State& before = rec.states[at - 1];
  for (int i = 0; i < top.nq; ++i) EXPECT_EQ(prev[i], before.a[i]) << i;
  for (int j = 0; j < top.nc; ++j) EXPECT_EQ(prev[top.nq + j], before.lambda[j]) << j;
  RestoreCase(*top.sys, opt, top.x0, 0.3, at);
}

// The exact rotation blocks of the Newton matrix (HhtOptions::rotation_jacobian) need no
// history of their own. Fixed-step in the negrut form with KLU the restored run is the
// recorded one. Adaptive with the tree elimination's defaults it refreshes its Newton
// matrix at the first step where the recorded run reused an older one, so the iterates
// differ within the Newton threshold (1e-14 here), which the fast top carries to 1e-11 in
// q and v by the end of the run: within 1e-9, as the checkpointed gradients need (they
// accept 1e-6, sensitivities/hht_checkpoint.cc).
TEST(HhtRestore, HeavyTopExactRotationBlocks) {
  HeavyTop top;
  dae::HhtOptions negrut = HeavyTop::Options(true, false);
  negrut.form = dae::HhtOptions::Form::kNegrut;
  negrut.rotation_jacobian = dae::HhtOptions::RotationJacobian::kExact;
  RestoreCase(*top.sys, negrut, top.x0, 0.2, 37);

  dae::HhtOptions opt = HeavyTop::Options(true, true);
  opt.linear_solver = dae::HhtOptions::LinearSolver::kTree;  // auto: exact
  const int at = 60;
  const Recorded rec = RecordRun(*top.sys, opt, top.x0, 0.3, at);
  ASSERT_GT(static_cast<int>(rec.states.size()), at + 20);
  const StateDiff restored = Continue(*top.sys, opt, rec, at, true);
  const StateDiff fresh = Continue(*top.sys, opt, rec, at, false);
  std::printf("tree, exact blocks: restored: q, v %.2e  a %.2e  lambda %.2e; initialized "
              "instead: q, v %.2e\n", restored.qv, restored.a, restored.lambda, fresh.qv);
  EXPECT_LE(restored.qv, 1e-9);
  EXPECT_GT(fresh.qv, 1e3 * restored.qv);  // the history matters
}

TEST(HhtRestore, RefusesSnapshotsOfAnotherKind) {
  HeavyTop top;
  dae::HhtOptions opt = HeavyTop::Options(true, false);
  auto eq = dae::MakeHhtIntegrator(*top.sys, opt);
  eq->Initialize(top.x0);
  dae::IntegratorSnapshot snap;
  eq->SaveSnapshot(&snap);
  EXPECT_EQ(snap.history.size(), size_t(dae::HhtHistory::Size(top.nq, top.nc, 1)));
  EXPECT_EQ(snap.bytes(), 8 * (1 + 3 * size_t(top.nq) + top.nc + snap.history.size()));
  for (int change = 0; change < 3; ++change) {
    dae::HhtOptions other = opt;
    if (change == 0) other.form = dae::HhtOptions::Form::kNegrut;
    if (change == 1) other.modified = false;
    if (change == 2) other.alpha = -0.2;
    auto integ = dae::MakeHhtIntegrator(*top.sys, other);
    EXPECT_THROW(integ->RestoreSnapshot(snap), std::invalid_argument) << "change " << change;
  }
  dae::IntegratorSnapshot short_history = snap;
  short_history.history.pop_back();
  EXPECT_THROW(eq->RestoreSnapshot(short_history), std::invalid_argument);
  dae::IntegratorSnapshot bad_step = snap;
  bad_step.history[dae::HhtHistory::kHNext] = 0;
  EXPECT_THROW(eq->RestoreSnapshot(bad_step), std::invalid_argument);
  testing::ParametricPendulum pendulum;
  auto other = dae::MakeHhtIntegrator(pendulum, HeavyTop::Options(true, false));
  EXPECT_THROW(other->RestoreSnapshot(snap), std::invalid_argument);
}

// ---- Gradients over checkpointed trajectories

// Every state against a budget of `fraction` of what every state takes: the adjoint and
// forward gradients agree to 1e-10 (relative to the largest entry of the objective's
// gradient), the values to 1e-12; the record never held more than its budget; the sweep
// added at most one segment of states and the step list.
void CheckpointCase(dae::MechanicalSystem& sys, sens::ObjectiveFunction& obj,
                    const dae::HhtOptions& opt, const dae::State& x0,
                    const InitialStateDerivatives& dx0, double t_end, double out,
                    double fraction, double tol) {
  const RecordedRun dense = RunHht(sys, obj, opt, x0, t_end, out);
  ASSERT_TRUE(dense.traj.stores_every_step());
  const size_t every_state = dense.traj.size() * (dense.traj.state_bytes() + 16);
  const size_t budget = static_cast<size_t>(fraction * every_state);
  const RecordedRun ckpt = RunHht(sys, obj, opt, x0, t_end, out, budget);
  const HhtTrajectory& tr = ckpt.traj;
  const int N = tr.size() - 1;
  ASSERT_EQ(tr.size(), dense.traj.size());
  EXPECT_FALSE(tr.stores_every_step());
  EXPECT_FALSE(tr.exceeded_budget());
  EXPECT_GE(tr.thinning_rounds(), 2);
  EXPECT_EQ(tr.num_checkpoints(), N / tr.checkpoint_interval() + 1);
  EXPECT_LE(tr.peak_memory(), budget);
  EXPECT_LE(tr.memory(), budget);
  for (int n = 0; n <= N; ++n) EXPECT_EQ(tr.h(n), dense.traj.h(n));
  std::printf("budget %zu of %zu bytes: %d checkpoints every %d steps, %d thinning rounds, peak %zu\n",
              budget, every_state, tr.num_checkpoints(), tr.checkpoint_interval(),
              tr.thinning_rounds(), tr.peak_memory());

  std::string err;
  const int no = obj.num_objectives(), np = sys.num_parameters();
  HhtSensitivityResult adj0, fwd0, adj, fwd;
  ASSERT_TRUE(sens::HhtAdjointGradient(sys, opt, obj, dense.traj, dx0, &adj0, &err)) << err;
  ASSERT_TRUE(sens::HhtForwardGradient(sys, opt, obj, dense.traj, dx0, &fwd0, &err)) << err;
  ASSERT_TRUE(sens::HhtAdjointGradient(sys, opt, obj, tr, dx0, &adj, &err)) << err;
  ASSERT_TRUE(sens::HhtForwardGradient(sys, opt, obj, tr, dx0, &fwd, &err)) << err;
  EXPECT_EQ(adj0.recomputed_steps, 0);
  // Every step of the run is recomputed once (those on checkpoints are replaced by the
  // stored states): one extra forward run.
  EXPECT_EQ(adj.recomputed_steps, N);
  EXPECT_EQ(fwd.recomputed_steps, N);
  EXPECT_LE(adj.recompute_deviation, 1e-11);
  const size_t segment = (tr.checkpoint_interval() + 1) * tr.state_bytes() + sizeof(double) * N;
  EXPECT_LE(adj.peak_trajectory_bytes, budget + segment);
  EXPECT_GT(adj.peak_trajectory_bytes, tr.memory());
  double worst = 0;
  for (int j = 0; j < no; ++j) {
    EXPECT_NEAR(adj.values[j], adj0.values[j], 0.1 * tol * (1 + std::abs(adj0.values[j])));
    EXPECT_NEAR(fwd.values[j], adj0.values[j], 0.1 * tol * (1 + std::abs(adj0.values[j])));
    double scale = 0;
    for (int k = 0; k < np; ++k) scale = std::max(scale, std::abs(adj0.gradient[j * np + k]));
    for (int k = 0; k < np; ++k) {
      const double g0 = adj0.gradient[j * np + k];
      EXPECT_NEAR(adj.gradient[j * np + k], g0, tol * scale) << "objective " << j << " parameter " << k;
      EXPECT_NEAR(fwd.gradient[j * np + k], fwd0.gradient[j * np + k], tol * scale)
          << "objective " << j << " parameter " << k;
      worst = std::max(worst, std::abs(adj.gradient[j * np + k] - g0) / scale);
    }
  }
  std::printf("adjoint with checkpoints vs every state: %.2e relative; recompute deviation %.2e; "
              "sweep peak %zu bytes\n", worst, adj.recompute_deviation, adj.peak_trajectory_bytes);
}

void PendulumCheckpoints(dae::HhtOptions::Form form, bool adaptive) {
  dae::HhtOptions opt;
  opt.form = form;
  opt.modified = false;
  opt.alpha = -0.2;
  opt.step = 2e-3;
  opt.adaptive = adaptive;
  opt.tolerance = 1e-7;
  opt.newton_tolerance = 1e-14;
  opt.adaptive_newton_factor = 1e-7;
  testing::ParametricPendulum sys(1.3, 0.9, 9.81, 0.4);
  PendulumObjectives obj(sys);
  const dae::State x0 = PendulumStart(sys);
  CheckpointCase(sys, obj, opt, x0, PendulumInitialDerivatives(sys, x0), 1.2, 0.05, 0.35, 1e-10);
}

TEST(HhtCheckpoint, PendulumEquilibriumFixedStep) {
  PendulumCheckpoints(dae::HhtOptions::Form::kEquilibrium, false);
}
TEST(HhtCheckpoint, PendulumNegrutFixedStep) { PendulumCheckpoints(dae::HhtOptions::Form::kNegrut, false); }
TEST(HhtCheckpoint, PendulumEquilibriumAdaptive) {
  PendulumCheckpoints(dae::HhtOptions::Form::kEquilibrium, true);
}

void HeavyTopCheckpoints(bool modified, bool adaptive) {
  HeavyTop top;
  StateObjectives obj(top.nq, top.nc);
  CheckpointCase(*top.sys, obj, HeavyTop::Options(modified, adaptive), top.x0, top.dx0,
                 adaptive ? 0.3 : 0.15, 0.05, 0.2, 1e-9);
}

TEST(HhtCheckpoint, HeavyTopModifiedFixedStep) { HeavyTopCheckpoints(true, false); }
TEST(HhtCheckpoint, HeavyTopModifiedAdaptive) { HeavyTopCheckpoints(true, true); }
TEST(HhtCheckpoint, HeavyTopClassicalAdaptive) { HeavyTopCheckpoints(false, true); }

// The pendulum with a fixed-step classical run's options.
struct PendulumSetup {
  testing::ParametricPendulum sys{1.3, 0.9, 9.81, 0.4};
  PendulumObjectives obj{sys};
  dae::HhtOptions opt;
  dae::State x0;
  InitialStateDerivatives dx0;
  PendulumSetup() {
    opt.modified = false;
    opt.step = 2e-3;
    opt.newton_tolerance = 1e-14;
    x0 = PendulumStart(sys);
    dx0 = PendulumInitialDerivatives(sys, x0);
  }
};

// A budget that cannot hold even the step times: the record says so and still gives
// the gradient (its checkpoints then recur ever more rarely).
TEST(HhtCheckpoint, BudgetBelowTheStepTimesIsReported) {
  PendulumSetup p;
  HhtTrajectory probe(2, 1);
  const size_t least = probe.minimum_budget();
  const RecordedRun dense = RunHht(p.sys, p.obj, p.opt, p.x0, 0.6, 0.05);
  const RecordedRun tight = RunHht(p.sys, p.obj, p.opt, p.x0, 0.6, 0.05, least);
  EXPECT_TRUE(tight.traj.exceeded_budget());
  EXPECT_GT(tight.traj.memory(), least);
  EXPECT_LE(tight.traj.num_checkpoints(), 2);
  std::string err;
  HhtSensitivityResult a0, a1;
  ASSERT_TRUE(sens::HhtAdjointGradient(p.sys, p.opt, p.obj, dense.traj, p.dx0, &a0, &err)) << err;
  ASSERT_TRUE(sens::HhtAdjointGradient(p.sys, p.opt, p.obj, tight.traj, p.dx0, &a1, &err)) << err;
  for (size_t i = 0; i < a0.gradient.size(); ++i)
    EXPECT_NEAR(a1.gradient[i], a0.gradient[i], 1e-10 * (1 + std::abs(a0.gradient[i])));
}

TEST(HhtCheckpoint, BadBudgetsAreRefused) {
  HeavyTop top;
  HhtTrajectory tr(top.nq, top.nc);
  const size_t least = tr.minimum_budget();
  EXPECT_EQ(least, 16 * 8 * (3 * size_t(top.nq) + top.nc + dae::HhtHistory::Size(top.nq, top.nc, 1)));
  EXPECT_THROW(tr.set_memory_budget(least - 1), std::invalid_argument);
  EXPECT_THROW(tr.set_memory_budget(1), std::invalid_argument);
  EXPECT_NO_THROW(tr.set_memory_budget(0));
  tr.set_memory_budget(least);
  EXPECT_THROW(tr.Recorder(), std::logic_error);  // checkpoints need the integrator
  auto integ = dae::MakeHhtIntegrator(*top.sys, HeavyTop::Options(true, false));
  EXPECT_NO_THROW(tr.Attach(*integ));
  // IDA cannot save its state.
  tr.set_memory_budget(0);
  auto ida = dae::MakeIdaIntegrator(*top.sys, dae::IdaOptions());
  EXPECT_THROW(tr.Attach(*ida), std::logic_error);
  // A budget once the run is being recorded.
  tr.set_memory_budget(2 * least);
  tr.Attach(*integ);
  integ->Initialize(top.x0);
  EXPECT_THROW(tr.set_memory_budget(0), std::logic_error);
  EXPECT_EQ(tr.size(), 1);
  EXPECT_EQ(tr.checkpoint_bytes(), tr.state_bytes() + 8 * size_t(dae::HhtHistory::Size(top.nq, top.nc, 1)));
}

// A checkpointed trajectory recomputed with options other than the run's: refused with
// a reason (the checkpoints name the scheme they belong to).
TEST(HhtCheckpoint, OtherOptionsThanTheRunsAreRefused) {
  PendulumSetup p;
  const RecordedRun dense = RunHht(p.sys, p.obj, p.opt, p.x0, 0.6, 0.05);
  const RecordedRun ckpt =
      RunHht(p.sys, p.obj, p.opt, p.x0, 0.6, 0.05, dense.traj.size() * dense.traj.state_bytes() / 3);
  ASSERT_FALSE(ckpt.traj.stores_every_step());
  dae::HhtOptions other = p.opt;
  other.alpha = -0.3;
  std::string err;
  HhtSensitivityResult r;
  EXPECT_FALSE(sens::HhtAdjointGradient(p.sys, other, p.obj, ckpt.traj, p.dx0, &r, &err));
  EXPECT_NE(err.find("options"), std::string::npos) << err;
  err.clear();
  EXPECT_FALSE(sens::HhtForwardGradient(p.sys, other, p.obj, ckpt.traj, p.dx0, &r, &err));
  EXPECT_NE(err.find("options"), std::string::npos) << err;
}

}  // namespace
}  // namespace mbdae::hht_test
