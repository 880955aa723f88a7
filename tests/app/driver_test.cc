// The simulation pipeline on the small test models: assembly, redundant constraints,
// input errors naming what is wrong, and a full run to a results file.
#include "driver/simulation.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <cstdio>
#include <string>

#include "mbs/loader.h"

namespace mbdae::driver {
namespace {

std::string ModelPath(const std::string& name) {
  return std::string(MBDAE_TEST_MODELS) + "/" + name;
}

void ExpectInputError(const std::string& model_file, const std::vector<std::string>& words) {
  mbs::Model model = mbs::LoadModel(ModelPath(model_file));
  try {
    Assemble(model);
    ADD_FAILURE() << model_file << ": no error";
  } catch (const InputError& e) {
    for (const auto& w : words)
      EXPECT_NE(std::string(e.what()).find(w), std::string::npos) << e.what();
  }
}

TEST(Assemble, FourBarHasThreeRedundantOutOfPlaneEquations) {
  mbs::Model model = mbs::LoadModel(ModelPath("fourbar.yaml"));
  Assembly a = Assemble(model);
  EXPECT_EQ(a.system->num_constraints(), 23);
  ASSERT_EQ(a.redundant.size(), 3u);
  EXPECT_EQ(a.kept.size(), 20u);
  EXPECT_EQ(a.kept_system->num_constraints(), 20);
  // The planar loop leaves only out-of-plane equations (z, rx, ry) dependent.
  for (const auto& name : a.redundant_names()) {
    const std::string axis = name.substr(name.find('.') + 1);
    EXPECT_TRUE(axis == "z" || axis == "rx" || axis == "ry") << name;
  }
  EXPECT_EQ(a.x0.lambda.size(), 20u);
  EXPECT_LT(a.max_position_change, 1e-9);  // the model is written assembled
  EXPECT_TRUE(a.moved_bodies.empty());
}

TEST(Assemble, ZeroMassBodyIsNamed) {
  ExpectInputError("zero_mass.yaml", {"zero_mass.yaml", "ghost", "not determined"});
}

TEST(Assemble, UnassemblableModelNamesTheJoint) {
  ExpectInputError("unassemblable.yaml", {"unassemblable.yaml", "cannot be assembled", "right"});
}

TEST(Assemble, MovedBodiesAreReported) {
  // The bob 1 cm off its circle: assembly moves it back and says so.
  mbs::LoadOptions lo;
  mbs::Model model = mbs::LoadModel(ModelPath("pendulum.yaml"));
  model.bodies[0].position.x() += 0.01;
  Assembly a = Assemble(model);
  ASSERT_EQ(a.moved_bodies.size(), 1u);
  EXPECT_EQ(a.moved_bodies[0], "bob");
  EXPECT_GT(a.max_position_change, 1e-3);
  EXPECT_LT(a.max_position_change, 0.02);
  EXPECT_NE(a.Report().find("bob"), std::string::npos);
}

TEST(Simulate, PendulumRunsToTheEndWithSmallViolations) {
  mbs::Model model = mbs::LoadModel(ModelPath("pendulum.yaml"));
  SettingsOverrides o;
  o.integrator = mbs::IntegratorKind::kIda;
  mbs::SimulationSettings s = ResolveSettings(model.simulation, o);
  Assembly a = Assemble(model);
  SimulationOptions so;
  so.results_path = ::testing::TempDir() + "/mbdae_driver_" + std::to_string(getpid()) + ".h5";
  int calls = 0;
  double last_t = -1;
  so.progress = [&](double t, double t_end) {
    ++calls;
    EXPECT_GT(t, last_t);
    EXPECT_EQ(t_end, 0.5);
    last_t = t;
  };
  SimulationSummary r = Simulate(model, a, s, so);
  EXPECT_EQ(r.status, SimulationSummary::Status::kDone) << r.failure_reason;
  EXPECT_EQ(r.rows, 51);
  EXPECT_EQ(calls, 51);
  EXPECT_EQ(last_t, 0.5);
  EXPECT_EQ(r.t_reached, 0.5);
  EXPECT_GT(r.counters.steps_accepted, 10);
  EXPECT_LT(r.max_position_violation, 1e-8);
  EXPECT_LT(r.max_velocity_violation, 1e-6);
  EXPECT_NE(r.FullReport().find("redundant constraints: 0"), std::string::npos) << r.FullReport();
  std::remove(so.results_path.c_str());
}

// A body spinning at 10 rad/s about z, output rows 0.5 s apart (5 rad, more than half a
// turn): the angle is continued with the rate (trapezoidal prediction), so it reads
// omega t; unwrapping to the nearest turn alone would read 5 - 2 pi, 10 - 4 pi, ...
TEST(OutputRowBuilder, AnglesStayContinuousWhenRowsAreMoreThanHalfATurnApart) {
  const mbs::Model model = mbs::LoadModelFromString(
      "format: 1\n"
      "bodies:\n"
      "  - {name: rotor, mass: 1, inertia: [1, 1, 1], position: [0, 0, 0],\n"
      "     orientation: [1, 0, 0, 0], angular_velocity: [0, 0, 10]}\n"
      "measures:\n"
      "  - {name: angle, type: rotational, i: rotor.cm, j: ground.O, axis: z}\n",
      "spin.yaml");
  Assembly a = Assemble(model);
  OutputRowBuilder rows(model, a);
  const double omega = 10;
  dae::State x = a.x0;
  for (int k = 0; k <= 8; ++k) {
    const double t = 0.5 * k, c = std::cos(omega * t / 2), s = std::sin(omega * t / 2);
    x.t = t;
    x.q[3] = c, x.q[4] = 0, x.q[5] = 0, x.q[6] = s;
    x.v[3] = -omega / 2 * s, x.v[4] = 0, x.v[5] = 0, x.v[6] = omega / 2 * c;
    for (int i = 3; i < 7; ++i) x.a[i] = -omega * omega / 4 * x.q[i];
    const io::ResultsRow& row = rows.Compute(x);
    EXPECT_NEAR(row.measures[0], omega * t, 1e-9) << "t = " << t;
  }
}

TEST(Simulate, FailureKeepsRowsAndSaysWhy) {
  mbs::Model model = mbs::LoadModel(ModelPath("pendulum.yaml"));
  SettingsOverrides o;
  o.integrator = mbs::IntegratorKind::kHht;
  o.hht_adaptive = true;
  o.hht_tolerance = 1e-30;  // unreachable: the step falls below its minimum
  mbs::SimulationSettings s = ResolveSettings(model.simulation, o);
  Assembly a = Assemble(model);
  SimulationOptions so;
  so.results_path = ::testing::TempDir() + "/mbdae_driver_fail_" + std::to_string(getpid()) + ".h5";
  SimulationSummary r = Simulate(model, a, s, so);
  EXPECT_EQ(r.status, SimulationSummary::Status::kFailed);
  EXPECT_FALSE(r.failure_reason.empty());
  EXPECT_LT(r.t_reached, 0.5);
  EXPECT_GE(r.rows, 1);
  std::remove(so.results_path.c_str());
}

}  // namespace
}  // namespace mbdae::driver
