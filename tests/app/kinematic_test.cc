// The kinematic analysis (dae/kinematic.h, `integrator: kinematic`) of models without
// degrees of freedom: a slider-crank driven at a constant crank rate against its closed
// form; the 3-axis arm driven by three motion joints (tests/app/models/arm_motion.yaml)
// against IDA at rtol = atol = 1e-10, row by row, in q, v, a, lambda and the joint
// reactions and efforts; objectives (Simpson's rule) against IDA's quadrature; the refusal
// of a model with degrees of freedom (file and line, their number).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <memory>
#include <string>
#include <vector>

#include "dae/kinematic.h"
#include "driver/simulation.h"
#include "mbs/loader.h"

namespace mbdae::driver {
namespace {

std::string ModelPath(const std::string& name) { return std::string(MBDAE_TEST_MODELS) + "/" + name; }

double MaxAbsDiff(const double* x, const double* y, size_t n) {
  double m = 0;
  for (size_t i = 0; i < n; ++i) m = std::max(m, std::abs(x[i] - y[i]));
  return m;
}

double MaxAbs(const double* x, size_t n) {
  double m = 0;
  for (size_t i = 0; i < n; ++i) m = std::max(m, std::abs(x[i]));
  return m;
}

// Slider position, velocity and acceleration of crank_slider_driven.yaml (r = 0.3, l = 1,
// phi = w t with w = 2): x = r cos(phi) + s, s = sqrt(l^2 - r^2 sin(phi)^2).
void SliderClosedForm(double t, double* x, double* xd, double* xdd) {
  const double r = 0.3, l = 1.0, w = 2.0, phi = w * t;
  const double s = std::sqrt(l * l - r * r * std::sin(phi) * std::sin(phi));
  const double u = r * r * std::sin(phi) * std::cos(phi);  // -s s' / w
  const double ud = w * r * r * std::cos(2 * phi);
  const double sd = -w * u / s;
  const double sdd = -w * (ud * s - u * sd) / (s * s);
  *x = r * std::cos(phi) + s;
  *xd = -r * w * std::sin(phi) + sd;
  *xdd = -r * w * w * std::cos(phi) + sdd;
}

TEST(KinematicAnalysis, SliderCrankFollowsTheClosedForm) {
  const mbs::Model model = mbs::LoadModel(ModelPath("crank_slider_driven.yaml"));
  ASSERT_EQ(model.simulation.integrator, mbs::IntegratorKind::kKinematic);
  Assembly asmb = Assemble(model);
  EXPECT_EQ(DegreesOfFreedom(*asmb.kept_system), 0);
  EXPECT_FALSE(asmb.redundant.empty());  // the planar joints' out-of-plane equations
  const int slider_x = 7 * 2;            // third body, x of its centre of mass
  // Twice, with two solvers: the second run must repeat the first bit for bit.
  std::vector<double> first;
  for (int run = 0; run < 2; ++run) {
    auto solver = MakeIntegrator(*asmb.kept_system, model.simulation);
    solver->Initialize(asmb.x0);
    double worst_x = 0, worst_v = 0, worst_a = 0;
    const std::vector<double> times = OutputTimes(model.simulation.t_end, model.simulation.output_step);
    ASSERT_EQ(times.size(), 201u);
    for (size_t k = 1; k < times.size(); ++k) {
      ASSERT_TRUE(solver->AdvanceTo(times[k])) << solver->summary().message;
      const dae::State& x = solver->state();
      double xs, vs, as;
      SliderClosedForm(times[k], &xs, &vs, &as);
      worst_x = std::max(worst_x, std::abs(x.q[slider_x] - xs));
      worst_v = std::max(worst_v, std::abs(x.v[slider_x] - vs));
      worst_a = std::max(worst_a, std::abs(x.a[slider_x] - as));
      if (run == 0) first.push_back(x.q[slider_x]);
      else EXPECT_EQ(x.q[slider_x], first[k - 1]);
    }
    // |x| <= 1.3 m, |x'| <= 0.66 m/s, |x''| <= 1.6 m/s^2; measured 4.4e-16, 1.6e-13, 7.4e-13
    // (the positions to the rounding level after the last Newton correction).
    EXPECT_LT(worst_x, 1e-14);
    EXPECT_LT(worst_v, 2e-12);
    EXPECT_LT(worst_a, 1e-11);
    const dae::Summary& s = solver->summary();
    EXPECT_EQ(s.steps_accepted, 200);
    const auto* kinematic = dynamic_cast<const dae::KinematicSolver*>(solver.get());
    ASSERT_NE(kinematic, nullptr);
    // Started from q + h v + h^2/2 a (error O(h^3) = 1e-6 m): Newton needs 1 to 3 iterations
    // (measured: 1 at every time).
    EXPECT_GE(kinematic->statistics().max_newton_iterations, 1);
    EXPECT_LE(kinematic->statistics().max_newton_iterations, 3);
    EXPECT_LE(s.newton_iterations, 3 * 200);
    EXPECT_EQ(kinematic->statistics().singular_points, 0);
  }
}

// The rows of a run of `model` with `settings` (output_accelerations: solved): state and
// row data per output time.
struct Rows {
  std::vector<std::vector<double>> q, v, a, lambda, joints, efforts;
  std::vector<double> objectives;
  dae::Summary counters;
};

Rows RunRows(const mbs::Model& model, const mbs::SimulationSettings& settings) {
  Assembly asmb = Assemble(model);
  Rows rows;
  auto integrator = MakeIntegrator(*asmb.kept_system, settings);
  integrator->Initialize(asmb.x0);
  OutputRowBuilder builder(model, asmb, settings);
  const size_t nq = asmb.x0.q.size(), nc = asmb.x0.lambda.size();
  auto store = [&](const dae::State& x) {
    const io::ResultsRow& row = builder.Compute(x);
    rows.q.emplace_back(row.q, row.q + nq);
    rows.v.emplace_back(row.v, row.v + nq);
    rows.a.emplace_back(row.a, row.a + nq);
    rows.lambda.emplace_back(row.lambda, row.lambda + nc);
    rows.joints.emplace_back(row.joint_data, row.joint_data + 6 * model.joints.size());
    rows.efforts.emplace_back(row.effort_data, row.effort_data + builder.effort_joints().size());
  };
  store(asmb.x0);
  const std::vector<double> times = OutputTimes(settings.t_end, settings.output_step);
  for (size_t k = 1; k < times.size(); ++k) {
    EXPECT_TRUE(integrator->AdvanceTo(times[k])) << integrator->summary().message;
    dae::State x = integrator->state();
    x.t = times[k];
    store(x);
  }
  rows.counters = integrator->summary();
  return rows;
}

// The arm, moved by the quintics over T = 2 s with sine terms added to each joint.
mbs::Model ArmModel() {
  mbs::LoadOptions lo;
  lo.parameter_overrides = {{"T", 2.0}, {"b1", 0.2}, {"b2", 0.3}, {"b3", 0.4}};
  return mbs::LoadModel(ModelPath("arm_motion.yaml"), lo);
}

TEST(KinematicAnalysis, ArmAgreesWithIdaAtEveryRow) {
  const mbs::Model model = ArmModel();
  mbs::SimulationSettings ida = model.simulation;
  ida.integrator = mbs::IntegratorKind::kIda;
  ida.ida_rtol = 1e-10;
  ida.ida_atol = 1e-10;
  ida.t_end = 2.0;
  mbs::SimulationSettings kin = ida;
  kin.integrator = mbs::IntegratorKind::kKinematic;
  const Rows a = RunRows(model, kin), b = RunRows(model, ida);
  ASSERT_EQ(a.q.size(), 201u);
  ASSERT_EQ(b.q.size(), 201u);
  double dq = 0, dv = 0, da = 0, dl = 0, dj = 0, de = 0, amax = 0, lmax = 0, jmax = 0;
  for (size_t k = 0; k < a.q.size(); ++k) {
    const size_t nq = a.q[k].size(), nc = a.lambda[k].size();
    dq = std::max(dq, MaxAbsDiff(a.q[k].data(), b.q[k].data(), nq));
    dv = std::max(dv, MaxAbsDiff(a.v[k].data(), b.v[k].data(), nq));
    da = std::max(da, MaxAbsDiff(a.a[k].data(), b.a[k].data(), nq));
    dl = std::max(dl, MaxAbsDiff(a.lambda[k].data(), b.lambda[k].data(), nc));
    dj = std::max(dj, MaxAbsDiff(a.joints[k].data(), b.joints[k].data(), a.joints[k].size()));
    de = std::max(de, MaxAbsDiff(a.efforts[k].data(), b.efforts[k].data(), a.efforts[k].size()));
    amax = std::max(amax, MaxAbs(a.a[k].data(), nq));
    lmax = std::max(lmax, MaxAbs(a.lambda[k].data(), nc));
    jmax = std::max(jmax, MaxAbs(a.joints[k].data(), a.joints[k].size()));
  }
  // Measured (IDA of commit cca3377): q 1.0e-11, v 8.6e-11, a 5.5e-10, lambda 3.2e-10,
  // reactions 2.8e-10, efforts 1.6e-10: IDA's error at rtol = atol = 1e-10 (the
  // kinematic rows hold the constraints to 1e-12). Scales: |q| <= 1, |v| <= 1.5,
  // |a| <= 12.2, |lambda| and reactions <= 72.2. Bounds with a margin of 20 to 200 for
  // changes of IDA's step sequence.
  std::printf("kinematic - ida: q %.2e, v %.2e, a %.2e (of %.3g), lambda %.2e (of %.3g), "
              "reactions %.2e (of %.3g), efforts %.2e; Newton iterations %ld, IDA steps %ld\n",
              dq, dv, da, amax, dl, lmax, dj, jmax, de, a.counters.newton_iterations,
              b.counters.steps_accepted);
  EXPECT_LT(dq, 1e-9);
  EXPECT_LT(dv, 1e-8);
  EXPECT_LT(da, 1e-7);
  EXPECT_LT(dl, 1e-7);
  EXPECT_LT(dj, 1e-7);
  EXPECT_LT(de, 1e-7);
  EXPECT_EQ(a.counters.steps_accepted, 200);
}

TEST(KinematicAnalysis, ObjectivesAgreeWithIda) {
  // examples/robot_energy/quintic.yaml: integrals of the squared and smoothed-positive
  // motor powers and terminal values, over 1 s.
  const mbs::Model model = mbs::LoadModel(std::string(MBDAE_SOURCE_DIR) + "/examples/robot_energy/quintic.yaml");
  Assembly asmb = Assemble(model);
  ASSERT_EQ(DegreesOfFreedom(*asmb.kept_system), 0);
  mbs::SimulationSettings ida = model.simulation;
  ida.integrator = mbs::IntegratorKind::kIda;
  ida.ida_rtol = 1e-10;
  ida.ida_atol = 1e-10;
  mbs::SimulationSettings kin = ida;
  kin.integrator = mbs::IntegratorKind::kKinematic;
  SimulationOptions so;
  const SimulationSummary a = Simulate(model, asmb, kin, so);
  Assembly asmb2 = Assemble(model);
  const SimulationSummary b = Simulate(model, asmb2, ida, so);
  ASSERT_EQ(a.status, SimulationSummary::Status::kDone) << a.failure_reason;
  ASSERT_EQ(b.status, SimulationSummary::Status::kDone) << b.failure_reason;
  EXPECT_EQ(a.integrator, "kinematic");
  ASSERT_EQ(a.objectives.size(), 8u);
  ASSERT_EQ(b.objectives.size(), 8u);
  for (size_t i = 0; i < a.objectives.size(); ++i) {
    const double x = a.objectives[i].value, y = b.objectives[i].value;
    // Adaptive Simpson between the rows (h = 0.01 s) against IDA's quadrature at rtol
    // 1e-10: losses (71.07 N^2 m^2 s) and energy (7.561 J) agree to 1.0e-9 and 2.3e-9
    // relative (measured), the terminal values (zero) to 5e-16.
    EXPECT_NEAR(x, y, 1e-7 * std::max(1.0, std::abs(y))) << a.objectives[i].name;
  }
  EXPECT_GT(a.max_newton_iterations, 0);
  // Measured: max |C| 4e-16 (the positions corrected once more after convergence),
  // max |C_q v + C_t| 2.0e-12 (v solved with C_q before that correction).
  EXPECT_LT(a.max_position_violation, 1e-14);
  EXPECT_LT(a.max_velocity_violation, 1e-11);
}

TEST(KinematicAnalysis, RefusesAModelWithDegreesOfFreedom) {
  // The pendulum (1 degree of freedom) with `integrator: kinematic` on line 4.
  const std::string text =
      "format: 1\n"
      "gravity: [0, -9.81, 0]\n"
      "simulation:\n"
      "  integrator: kinematic\n"
      "bodies:\n"
      "  - {name: bob, mass: 1, inertia: [0.1, 0.1, 0.1], position: [1, 0, 0],\n"
      "     markers: {pivot: {position: [-1, 0, 0]}}}\n"
      "joints:\n"
      "  - {name: pivot, type: revolute, i: bob.pivot, j: ground.O}\n";
  const mbs::Model model = mbs::LoadModelFromString(text, "pendulum_kin.yaml");
  Assembly asmb = Assemble(model);
  EXPECT_EQ(DegreesOfFreedom(*asmb.kept_system), 1);
  try {
    CheckIntegrator(*asmb.kept_system, model.simulation);
    FAIL() << "not refused";
  } catch (const InputError& e) {
    const std::string m = e.what();
    EXPECT_NE(m.find("pendulum_kin.yaml:4:15: simulation:"), std::string::npos) << m;
    EXPECT_NE(m.find("has 1 degree of freedom"), std::string::npos) << m;
  }
  EXPECT_THROW(MakeIntegrator(*asmb.kept_system, model.simulation), InputError);
  // Chosen by an override: named as the option.
  SettingsOverrides o;
  o.integrator = mbs::IntegratorKind::kKinematic;
  mbs::SimulationSettings s = model.simulation;
  s.integrator = mbs::IntegratorKind::kHht;
  s = ResolveSettings(s, o);
  try {
    CheckIntegrator(*asmb.kept_system, s);
    FAIL() << "not refused";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("--integrator kinematic: "), std::string::npos) << e.what();
  }
  // The solver itself refuses a system with more coordinates than equations.
  EXPECT_THROW(dae::MakeKinematicSolver(*asmb.kept_system), std::invalid_argument);
}

}  // namespace
}  // namespace mbdae::driver
