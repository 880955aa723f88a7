// IDA's runs end: the total step budget (IdaOptions::max_steps), the smallest relative
// step (min_relative_step) against a system that lets IDA creep towards a time it cannot
// pass, and the step observer that sees every step.
#include "dae/ida.h"

#include <gtest/gtest.h>

#include <cmath>
#include <string>
#include <vector>

#include "dae/consistent.h"
#include "tests/support/pendulum_system.h"

namespace mbdae::dae {
namespace {

using testing::PendulumSystem;

State ConsistentState(MechanicalSystem& sys, std::vector<double> q, std::vector<double> v) {
  State x;
  x.q = std::move(q);
  x.v = std::move(v);
  const auto report = MakeConsistent(sys, x);
  EXPECT_TRUE(report.ok) << report.message;
  return x;
}

bool Contains(const std::string& text, const std::string& part) {
  return text.find(part) != std::string::npos;
}

// A pendulum whose evaluation fails recoverably beyond t_stop: IDA cuts the step, steps
// again up to nearly t_stop, and so creeps towards it with ever smaller steps.
class WallPendulum : public PendulumSystem {
 public:
  explicit WallPendulum(double t_stop) : PendulumSystem(1, 1, 9.81), t_stop_(t_stop) {}
  int Evaluate(const EvalInput& in, EvalOutput& out) override {
    if (in.t > t_stop_) return 1;
    return PendulumSystem::Evaluate(in, out);
  }
  const char* last_error() const override { return "beyond the wall"; }

 private:
  double t_stop_;
};

TEST(IdaLimits, StepBudgetIsTotalAndEndsTheRun) {
  PendulumSystem sys(1, 1, 9.81);
  IdaOptions options;
  options.max_steps = 200;
  auto ida = MakeIdaIntegrator(sys, options);
  ida->Initialize(ConsistentState(sys, {0.6, -0.8}, {0, 0}));
  // Output times 0.1 apart: each call takes far fewer than 200 steps, the run more.
  int k = 1;
  while (k <= 1000 && ida->AdvanceTo(0.1 * k)) ++k;
  ASSERT_LE(k, 1000) << "the budget did not end the run";
  const Summary& s = ida->summary();
  EXPECT_EQ(s.status, Summary::Status::kFailed);
  EXPECT_EQ(s.steps_accepted, 200);
  EXPECT_TRUE(Contains(s.message, "step budget of 200 steps")) << s.message;
  EXPECT_TRUE(Contains(s.message, "t = ")) << s.message;
  EXPECT_TRUE(Contains(s.message, "h = ")) << s.message;
  EXPECT_GT(ida->state().t, 0.1 * (k - 1) - 1e-12);  // the steps of the failed call are kept
  EXPECT_LT(ida->state().t, 0.1 * k);
  EXPECT_EQ(s.t_reached, ida->state().t);
  EXPECT_FALSE(ida->AdvanceTo(0.1 * k + 1));  // stays failed
  // Initialize starts a new budget.
  ida->Initialize(ConsistentState(sys, {0.6, -0.8}, {0, 0}));
  EXPECT_TRUE(ida->AdvanceTo(0.1)) << ida->summary().message;
}

TEST(IdaLimits, CollapsingStepsEndTheRunNamingTAndH) {
  WallPendulum sys(0.3);
  auto ida = MakeIdaIntegrator(sys, IdaOptions{});
  ida->Initialize(ConsistentState(sys, {0.6, -0.8}, {0, 0}));
  EXPECT_FALSE(ida->AdvanceTo(1.0));
  const Summary& s = ida->summary();
  EXPECT_EQ(s.status, Summary::Status::kFailed);
  EXPECT_TRUE(Contains(s.message, "step size fell to h = ")) << s.message;
  EXPECT_TRUE(Contains(s.message, "below 1e-14 max(1, |t|)")) << s.message;
  EXPECT_TRUE(Contains(s.message, "20 steps in a row")) << s.message;
  // Stopped just before the wall, with steps below 1e-14 (|t| < 1).
  EXPECT_LE(ida->state().t, 0.3);
  EXPECT_GT(ida->state().t, 0.3 - 1e-9);
  EXPECT_LT(std::abs(s.h_last), 1e-14);
  // Far from the default budget: the collapse ends the run, not the step count.
  EXPECT_LT(s.steps_accepted, 100000);
}

TEST(IdaLimits, WithoutTheSmallestStepTheBudgetEndsACreepingRun) {
  WallPendulum sys(0.3);
  IdaOptions options;
  options.min_relative_step = 0;
  options.max_steps = 3000;
  auto ida = MakeIdaIntegrator(sys, options);
  ida->Initialize(ConsistentState(sys, {0.6, -0.8}, {0, 0}));
  EXPECT_FALSE(ida->AdvanceTo(1.0));
  EXPECT_TRUE(Contains(ida->summary().message, "step budget of 3000 steps")) << ida->summary().message;
  EXPECT_EQ(ida->summary().steps_accepted, 3000);
  EXPECT_LE(ida->state().t, 0.3);
}

TEST(IdaLimits, ObserverSeesEveryStep) {
  PendulumSystem sys(1, 1, 9.81);
  auto ida = MakeIdaIntegrator(sys, IdaOptions{});
  std::vector<double> times, steps;
  ida->SetStepObserver([&](const State& x, double h) {
    times.push_back(x.t);
    steps.push_back(h);
  });
  ida->Initialize(ConsistentState(sys, {0.6, -0.8}, {0, 0}));
  ASSERT_EQ(times.size(), 1u);
  EXPECT_EQ(steps[0], 0.0);  // the initial state
  for (int k = 1; k <= 5; ++k) ASSERT_TRUE(ida->AdvanceTo(0.2 * k)) << ida->summary().message;
  ASSERT_EQ(static_cast<long>(times.size()), ida->summary().steps_accepted + 1);
  for (size_t i = 1; i < times.size(); ++i) {
    EXPECT_GT(steps[i], 0.0);
    EXPECT_NEAR(times[i] - times[i - 1], steps[i], 1e-12) << i;
  }
  EXPECT_EQ(times.back(), 1.0);  // the last step ends at the output time
}

TEST(IdaLimits, OptionsAreValidated) {
  std::string why;
  IdaOptions o;
  o.max_steps = -1;
  EXPECT_FALSE(o.IsValid(&why));
  EXPECT_TRUE(Contains(why, "max_steps")) << why;
  o = {};
  o.min_relative_step = -1e-14;
  EXPECT_FALSE(o.IsValid(&why));
  EXPECT_TRUE(Contains(why, "min_relative_step")) << why;
  o.min_relative_step = std::nan("");
  EXPECT_FALSE(o.IsValid(&why));
  o = {};
  o.max_steps = 0;  // no limit
  o.min_relative_step = 0;
  EXPECT_TRUE(o.IsValid(&why)) << why;
}

}  // namespace
}  // namespace mbdae::dae
