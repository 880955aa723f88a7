#include "mbs/loader.h"

#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <sstream>
#include <string>

#include "mbs/geometry.h"
#include "mbs/kinematics.h"

namespace mbdae::mbs {
namespace {

const std::string kSource = MBDAE_SOURCE_DIR;

std::string ModelPath(const std::string& name) { return kSource + "/tests/mbs/models/" + name; }

// The message of the ModelError thrown when loading `text`, "" if none.
std::string LoadError(const std::string& text, const LoadOptions& options = {}) {
  try {
    LoadModelFromString(text, "m.yaml", options);
  } catch (const ModelError& e) {
    return e.what();
  }
  return "";
}

bool Contains(const std::string& s, const std::string& part) { return s.find(part) != std::string::npos; }

TEST(Loader, EveryKey) {
  const Model m = LoadModel(ModelPath("every_key.yaml"));
  EXPECT_EQ(m.name, "every key");
  EXPECT_EQ(m.gravity, Vec3(0, -9.81, 0));

  // Parameters: in file order, `l` uses `half_l` defined after it.
  ASSERT_EQ(m.parameters.size(), 6u);
  EXPECT_EQ(m.parameters[0].name, "l");
  EXPECT_DOUBLE_EQ(m.parameters[0].value, 0.5);
  EXPECT_EQ(m.parameters[0].expression, "2 * half_l");
  EXPECT_EQ(m.parameters[1].expression, "");  // a plain number
  EXPECT_DOUBLE_EQ(m.parameters[m.find_parameter("c")].value, 4.53);
  EXPECT_EQ(m.parameters[0].where.line, 6);
  EXPECT_EQ(m.parameter_values(), (std::vector<double>{0.5, 0.25, 9.81, 4530, 4.53, 7800}));

  // Markers: ground.O first, other ground markers, then each body's cm and markers.
  EXPECT_EQ(m.find_marker("ground.O"), 0);
  EXPECT_EQ(m.find_marker("ground.B"), 1);
  EXPECT_EQ(m.find_marker("ground.C"), 2);
  EXPECT_EQ(m.find_marker("crank.cm"), 3);
  EXPECT_EQ(m.find_marker("crank.A"), 4);
  EXPECT_EQ(m.find_marker("crank.B"), -1);
  EXPECT_EQ(m.markers[0].body, -1);
  EXPECT_TRUE(m.markers[0].position.isZero());
  const Marker& b = m.markers[1];
  EXPECT_EQ(b.position, Vec3(-0.03635, 0.03273, 0));
  const Mat3 rx = Eigen::AngleAxisd(0.5, Vec3::UnitX()).toRotationMatrix();
  EXPECT_LT((b.orientation - rx).cwiseAbs().maxCoeff(), 1e-14);
  Mat3 rz90;
  rz90 << 0, -1, 0, 1, 0, 0, 0, 0, 1;
  EXPECT_LT((m.markers[2].orientation - rz90).cwiseAbs().maxCoeff(), 1e-14);
  const Marker& a = m.markers[4];
  EXPECT_EQ(a.body, 0);
  EXPECT_DOUBLE_EQ(a.position.y(), 0.05);
  EXPECT_EQ(a.name, "crank.A");

  // Bodies.
  ASSERT_EQ(m.bodies.size(), 7u);
  EXPECT_EQ(m.num_coordinates(), 49);
  const Body& crank = m.bodies[0];
  EXPECT_EQ(crank.mass, 0.04325);
  Mat3 inertia;
  inertia << 2.194e-6, 1e-8, -2e-8, 1e-8, 4.410e-7, 3e-8, -2e-8, 3e-8, 2.500e-6;
  EXPECT_EQ(crank.inertia, inertia);
  EXPECT_EQ(crank.position, Vec3(0.1, 0.2, 0.3));
  EXPECT_NEAR(crank.orientation.norm(), 1.0, 1e-15);
  EXPECT_NEAR(crank.orientation[3], 1e-4, 1e-12);
  EXPECT_EQ(crank.velocity, Vec3(1, 2, 3));
  EXPECT_DOUBLE_EQ(crank.angular_velocity.z(), 2 * M_PI);
  EXPECT_EQ(crank.cm_marker, 3);
  EXPECT_EQ(m.markers[crank.cm_marker].name, "crank.cm");

  const Body& ball = m.bodies[1];
  const double ball_mass = 4.0 / 3.0 * M_PI * 1e-3 * 7800;
  EXPECT_NEAR(ball.mass, ball_mass, 1e-12);
  EXPECT_NEAR(ball.inertia(1, 1), 0.4 * ball_mass * 0.01, 1e-14);
  const double s = std::sqrt(0.5);
  EXPECT_LT((ball.orientation - Quat(s, 0, 0, s)).cwiseAbs().maxCoeff(), 1e-15);

  const Body& rod = m.bodies[2];
  EXPECT_EQ(rod.mass, 1.5);  // explicit mass wins
  const MassProperties cylinder = CylinderMass(0.01, 0.5, 7800);
  EXPECT_NEAR(rod.inertia(0, 0), cylinder.inertia(0, 0), 1e-15);  // inertia from the geometry
  Mat3 rxp90;
  rxp90 << 1, 0, 0, 0, 0, -1, 0, 1, 0;
  EXPECT_LT((RotationMatrix(rod.orientation) - rxp90).cwiseAbs().maxCoeff(), 1e-15);
  EXPECT_DOUBLE_EQ(m.markers[m.find_marker("rod.top")].position.z(), 0.25);

  EXPECT_NEAR(m.bodies[3].mass, M_PI * 0.0025 * 0.2 * 1000 / 3, 1e-12);
  EXPECT_NEAR(m.bodies[3].inertia(2, 2), 0.3 * m.bodies[3].mass * 0.0025, 1e-15);
  EXPECT_NEAR(m.bodies[4].mass, 3.0, 1e-12);
  EXPECT_NEAR(m.bodies[4].inertia(0, 0), 3.0 * (0.04 + 0.09) / 12, 1e-14);
  EXPECT_EQ(m.bodies[5].mass, 0.0);
  EXPECT_EQ(m.bodies[6].mass, 0.0);
  EXPECT_TRUE(m.bodies[6].inertia.isZero());

  // Measures.
  ASSERT_EQ(m.measures.size(), 4u);
  EXPECT_EQ(m.find_measure("d"), 1);
  const Measure& x1 = m.measures[0];
  EXPECT_EQ(x1.type, MeasureType::kTranslational);
  EXPECT_EQ(x1.i, 4);
  EXPECT_EQ(x1.j, 0);
  EXPECT_EQ(x1.component, Component::kX);
  EXPECT_EQ(x1.frame, MeasureFrame::kJ);
  EXPECT_EQ(x1.quantity, Quantity::kPosition);
  EXPECT_FALSE(x1.offset_initial);
  const Measure& d = m.measures[1];
  EXPECT_EQ(d.i, m.find_marker("rod.top"));
  EXPECT_EQ(d.j, 1);
  EXPECT_EQ(d.component, Component::kDistance);
  EXPECT_EQ(d.frame, MeasureFrame::kWorld);
  EXPECT_EQ(d.quantity, Quantity::kVelocity);
  EXPECT_TRUE(d.offset_initial);
  EXPECT_EQ(m.measures[2].type, MeasureType::kRotational);
  EXPECT_EQ(m.measures[2].component, Component::kZ);
  EXPECT_EQ(m.measures[2].quantity, Quantity::kAcceleration);
  EXPECT_EQ(m.measures[3].component, Component::kY);
  EXPECT_EQ(m.measures[3].quantity, Quantity::kPosition);
  EXPECT_EQ(m.measures[3].j, 0);

  // Joints and their locks (model format table).
  ASSERT_EQ(m.joints.size(), 8u);
  const unsigned t = kLockX | kLockY | kLockZ, r = kLockRx | kLockRy | kLockRz;
  EXPECT_EQ(m.joints[0].type, JointType::kFixed);
  EXPECT_EQ(m.joints[0].locks, t | r);
  EXPECT_EQ(m.joints[1].type, JointType::kSpherical);
  EXPECT_EQ(m.joints[1].locks, t);
  EXPECT_EQ(m.joints[2].type, JointType::kRevolute);
  EXPECT_EQ(m.joints[2].locks, t | kLockRx | kLockRy);
  EXPECT_EQ(m.joints[2].i, 4);
  EXPECT_EQ(m.joints[2].j, 0);
  EXPECT_EQ(m.joints[3].type, JointType::kPrismatic);
  EXPECT_EQ(m.joints[3].locks, kLockX | kLockY | r);
  EXPECT_EQ(m.joints[4].type, JointType::kCylindrical);
  EXPECT_EQ(m.joints[4].locks, kLockX | kLockY | kLockRx | kLockRy);
  EXPECT_EQ(m.joints[5].type, JointType::kUniversal);
  EXPECT_EQ(m.joints[5].locks, t | kLockRz);
  EXPECT_EQ(m.joints[6].type, JointType::kPlanar);
  EXPECT_EQ(m.joints[6].locks, kLockZ | kLockRx | kLockRy);
  EXPECT_EQ(m.joints[7].type, JointType::kGeneric);
  EXPECT_EQ(m.joints[7].locks, kLockX | kLockY | kLockRz);
  EXPECT_EQ(m.joints[7].where.line, 66);

  // Forces: values are expressions over the parameter vector.
  ASSERT_EQ(m.forces.size(), 5u);
  std::vector<double> p = m.parameter_values();
  const Force& spring = m.forces[0];
  EXPECT_EQ(spring.type, ForceType::kSpringDamper);
  EXPECT_EQ(spring.i, 4);
  EXPECT_EQ(spring.j, m.find_marker("rod.top"));
  EXPECT_EQ(spring.stiffness.Evaluate(p.data()), 4530.0);
  EXPECT_DOUBLE_EQ(spring.damping.Evaluate(p.data()), 4.53);
  EXPECT_DOUBLE_EQ(spring.free_length.Evaluate(p.data()), 0.5);
  EXPECT_DOUBLE_EQ(spring.preload.Evaluate(p.data()), -19.62);
  p[m.find_parameter("k")] = 1000;  // run-time values follow the parameter vector
  EXPECT_DOUBLE_EQ(spring.stiffness.Evaluate(p.data()), 1000.0);
  EXPECT_DOUBLE_EQ(spring.damping.Evaluate(p.data()), 4.53);  // c was evaluated at load
  p = m.parameter_values();
  const Force& soft = m.forces[1];
  EXPECT_EQ(soft.j, 0);
  EXPECT_EQ(soft.damping.Evaluate(p.data()), 0.0);
  EXPECT_EQ(soft.preload.Evaluate(p.data()), 0.0);
  const Force& push = m.forces[2];
  EXPECT_EQ(push.type, ForceType::kForce);
  EXPECT_EQ(push.frame, ForceFrame::kI);
  EXPECT_EQ(push.j, 1);
  EXPECT_DOUBLE_EQ(push.value[0].Evaluate(p.data()), -4530 * 0.5);
  EXPECT_EQ(push.value[1].Evaluate(p.data()), 0.0);
  EXPECT_DOUBLE_EQ(push.value[2].Evaluate(p.data()), std::sqrt(9.81));
  EXPECT_EQ(push.value[0].parameters_used(), (std::vector<int>{3, 0}));
  EXPECT_EQ(m.forces[3].type, ForceType::kTorque);
  EXPECT_EQ(m.forces[3].frame, ForceFrame::kJ);
  EXPECT_EQ(m.forces[3].value[2].Evaluate(p.data()), 1.5);
  EXPECT_EQ(m.forces[4].frame, ForceFrame::kWorld);
  EXPECT_EQ(m.forces[4].j, 0);

  // Simulation.
  const SimulationSettings& sim = m.simulation;
  EXPECT_EQ(sim.t_end, 0.03);
  EXPECT_EQ(sim.output_step, 1e-4);
  EXPECT_EQ(sim.integrator, IntegratorKind::kIda);
  EXPECT_DOUBLE_EQ(sim.hht_alpha, -1.0 / 3.0);
  EXPECT_EQ(sim.hht_step, 1e-5);
  EXPECT_TRUE(sim.hht_adaptive);
  EXPECT_EQ(sim.hht_tolerance, 1e-7);
  EXPECT_FALSE(sim.hht_modified);
  EXPECT_EQ(sim.hht_form, "negrut");
  EXPECT_EQ(sim.ida_rtol, 1e-6);
  EXPECT_EQ(sim.ida_atol, 1e-9);
  EXPECT_EQ(sim.ida_max_steps, 250000);
  EXPECT_EQ(sim.ida_min_step, 1e-14);
  EXPECT_EQ(m.file, ModelPath("every_key.yaml"));
}

// simulation: {ida: {max_steps, min_step}}: IDA's step budget and smallest step; the
// defaults unchanged when absent; bad values refused with the file, line and column.
TEST(Loader, IdaStepBudgetAndSmallestStep) {
  const SimulationSettings defaults;
  EXPECT_EQ(defaults.ida_max_steps, 100000000);
  EXPECT_EQ(defaults.ida_min_step, 0);
  Model m = LoadModelFromString("format: 1\nsimulation: {ida: {rtol: 1e-6}}\n", "m.yaml");
  EXPECT_EQ(m.simulation.ida_max_steps, defaults.ida_max_steps);
  EXPECT_EQ(m.simulation.ida_min_step, defaults.ida_min_step);
  m = LoadModelFromString(
      "format: 1\nparameters: {n: 400}\nsimulation: {ida: {max_steps: 3*n, min_step: 2.5e-9}}\n", "m.yaml");
  EXPECT_EQ(m.simulation.ida_max_steps, 1200);
  EXPECT_EQ(m.simulation.ida_min_step, 2.5e-9);
  m = LoadModelFromString("format: 1\nsimulation: {ida: {max_steps: 1e12}}\n", "m.yaml");
  EXPECT_EQ(m.simulation.ida_max_steps, 1000000000000L);
  const std::vector<std::pair<std::string, std::string>> bad = {
      {"{max_steps: 0}", "m.yaml:3:20: simulation: ida max_steps must be a whole number >= 1, got 0"},
      {"{max_steps: -5}", "m.yaml:3:20: simulation: ida max_steps must be a whole number >= 1, got -5"},
      {"{max_steps: 10.5}", "m.yaml:3:20: simulation: ida max_steps must be a whole number >= 1, got 10.5"},
      {"{max_steps: 1e30}", "m.yaml:3:20: simulation: ida max_steps must be a whole number >= 1, got 1e+30"},
      {"{max_steps: many}", "m.yaml:3:20: simulation: 'ida max_steps': in expression 'many'"},
      {"{max_steps: [1]}", "m.yaml:3:20: simulation:"},
      {"{min_step: 0}", "m.yaml:3:19: simulation: ida min_step must be > 0, got 0"},
      {"{min_step: -1e-9}", "m.yaml:3:19: simulation: ida min_step must be > 0, got -1e-09"},
      {"{min_step: 1/0}", "m.yaml:3:19: simulation: 'ida min_step' evaluates to inf"},
      {"{min_steps: 1e-9}", "m.yaml:3:9: simulation: unknown key 'min_steps'; did you mean 'min_step'?"},
      {"{max_step: 100}", "m.yaml:3:9: simulation: unknown key 'max_step'; did you mean 'max_steps'?"},
  };
  for (const auto& [ida, message] : bad) {
    const std::string error = LoadError("format: 1\nsimulation:\n  ida: " + ida + "\n");
    EXPECT_EQ(error.find(message), 0u) << ida << ": " << error << "\nexpected: " << message;
  }
  EXPECT_TRUE(Contains(LoadError("format: 1\nsimulation: {ida: {max_step: 100}}\n"),
                       "(allowed keys: rtol, atol, max_steps, min_step, dense_output, linear_solver)"));
}

// simulation: {output: {bodies, joints, forces, measures}}: `all` or lists of names of
// the model's elements; absent: all; wrong names and shapes refused where they stand.
TEST(Loader, OutputSelection) {
  const std::string model =
      "format: 1\n"
      "bodies:\n"
      "  - {name: a, mass: 1, inertia: [1, 1, 1], position: [0, 0, 0], orientation: [1, 0, 0, 0]}\n"
      "  - {name: b, mass: 1, inertia: [1, 1, 1], position: [1, 0, 0], orientation: [1, 0, 0, 0]}\n"
      "measures:\n"
      "  - {name: ax, type: translational, i: a.cm, component: x}\n"
      "joints:\n"
      "  - {name: ja, type: spherical, i: a.cm, j: ground.O}\n"
      "forces:\n"
      "  - {name: s, type: spring_damper, i: a.cm, j: b.cm, stiffness: 1, damping: 0, free_length: 1}\n"
      "simulation:\n";
  Model m = LoadModelFromString(model + "  t_end: 1\n", "m.yaml");
  EXPECT_FALSE(m.simulation.output_bodies || m.simulation.output_joints || m.simulation.output_forces ||
               m.simulation.output_measures);
  m = LoadModelFromString(model + "  output: {bodies: [b, a], joints: [], forces: all, measures: [ax]}\n", "m.yaml");
  EXPECT_EQ(m.simulation.output_bodies, (std::vector<std::string>{"b", "a"}));
  EXPECT_EQ(m.simulation.output_joints, std::vector<std::string>{});
  EXPECT_FALSE(m.simulation.output_forces);
  EXPECT_EQ(m.simulation.output_measures, std::vector<std::string>{"ax"});
  const std::vector<std::pair<std::string, std::string>> bad = {
      {"{bodies: [a, c]}", "m.yaml:12:24: simulation: output bodies: no body named 'c'"},
      {"{bodies: [a, a]}", "m.yaml:12:24: simulation: output bodies: body 'a' is named twice"},
      {"{joints: [a]}", "m.yaml:12:21: simulation: output joints: no joint named 'a'"},
      {"{forces: [ja]}", "m.yaml:12:21: simulation: output forces: no force named 'ja'"},
      {"{measures: [s]}", "m.yaml:12:23: simulation: output measures: no measure named 's'"},
      {"{bodies: a}", "m.yaml:12:20: simulation: output bodies must be 'all' or a list of body names, got 'a'"},
      {"{bodies: [[a]]}", "m.yaml:12:21: simulation: 'output bodies' must be a name (text), got a list"},
      {"{body: [a]}", "m.yaml:12:12: simulation: unknown key 'body' (allowed keys: bodies, joints, forces, measures)"},
      {"[a]", "m.yaml:12:11: simulation: 'output' must be a mapping (key: value), got a list"},
  };
  for (const auto& [output, message] : bad) {
    const std::string error = LoadError(model + "  output: " + output + "\n");
    EXPECT_EQ(error.find(message), 0u) << output << ": " << error << "\nexpected: " << message;
  }
}

TEST(Loader, MinimalModelAndDefaults) {
  const Model m = LoadModelFromString("format: 1\n", "min.yaml");
  EXPECT_EQ(m.markers.size(), 1u);
  EXPECT_EQ(m.markers[0].name, "ground.O");
  EXPECT_TRUE(m.bodies.empty());
  EXPECT_TRUE(m.gravity.isZero());
  const SimulationSettings defaults;
  EXPECT_EQ(m.simulation.t_end, defaults.t_end);
  EXPECT_EQ(m.simulation.integrator, IntegratorKind::kHht);
  EXPECT_TRUE(m.simulation.hht_modified);
  EXPECT_EQ(m.simulation.hht_form, "equilibrium");
}

TEST(Loader, ParameterOverrides) {
  const std::string text =
      "format: 1\n"
      "parameters: {a: 2*b, b: 3, c: a + 1}\n"
      "bodies:\n"
      "  - {name: p, mass: c}\n";
  LoadOptions options;
  options.parameter_overrides["b"] = 10;
  Model m = LoadModelFromString(text, "m.yaml", options);
  EXPECT_EQ(m.parameters[0].value, 20.0);
  EXPECT_EQ(m.parameters[1].value, 10.0);
  EXPECT_EQ(m.bodies[0].mass, 21.0);
  options.parameter_overrides = {{"a", 5}};  // an overridden expression takes the value
  m = LoadModelFromString(text, "m.yaml", options);
  EXPECT_EQ(m.parameters[0].value, 5.0);
  EXPECT_EQ(m.bodies[0].mass, 6.0);
  options.parameter_overrides = {{"bb", 1}};
  const std::string error = LoadError(text, options);
  EXPECT_TRUE(Contains(error, "m.yaml:2:13: parameter 'bb':")) << error;
  EXPECT_TRUE(Contains(error, "no such parameter; did you mean 'b'?")) << error;
}

TEST(Loader, ParameterCycle) {
  const std::string error = LoadError("format: 1\nparameters:\n  a: b + 1\n  b: 2 * c\n  c: a\n");
  EXPECT_TRUE(Contains(error, "m.yaml:3:6: parameter 'a': parameters depend on each other in a cycle: a -> b -> c -> a"))
      << error;
  const std::string self = LoadError("format: 1\nparameters: {x: x + 1}\n");
  EXPECT_TRUE(Contains(self, "cycle: x -> x")) << self;
}

TEST(Loader, OrientationTolerances) {
  auto body = [](const std::string& orientation) {
    return "format: 1\nbodies:\n  - name: b\n    orientation: " + orientation + "\n";
  };
  EXPECT_EQ(LoadError(body("[1, 0, 0, 2.0e-3]")).find("m.yaml:4:18: body 'b': 'orientation': Euler parameters must have unit norm"),
            0u);
  EXPECT_EQ(LoadError(body("[1.0000009, 0, 0, 0]")), "");
  EXPECT_TRUE(Contains(LoadError(body("[0, 0, 0, 0]")), "unit norm"));
  EXPECT_TRUE(Contains(LoadError(body("{axis: [0, 0, 0], angle: 1}")), "rotation axis must not be zero"));
  EXPECT_TRUE(Contains(LoadError(body("{matrix: [[1, 0, 0], [0, 1, 0], [0, 0, -1]]}")), "determinant -1"));
  EXPECT_TRUE(Contains(LoadError(body("{matrix: [[1, 0, 0], [0, 1, 1e-8], [0, 0, 1]]}")), "not orthonormal"));
  EXPECT_TRUE(Contains(LoadError(body("{axis: [0, 0, 1], angle: 1, turns: 2}")), "unknown key 'turns'"));
  EXPECT_TRUE(Contains(LoadError(body("{axis: [0, 0, 1]}")), "missing required key 'angle'"));
  const double c = std::cos(0.3), s = std::sin(0.3);
  std::ostringstream matrix;
  matrix.precision(17);
  matrix << "{matrix: [[" << c << ", " << -s << ", 0], [" << s << ", " << c << ", 0], [0, 0, 1]]}";
  const Model m = LoadModelFromString(body(matrix.str()), "m.yaml");
  EXPECT_LT((m.bodies[0].orientation - QuaternionFromAxisAngle(Vec3::UnitZ(), 0.3)).cwiseAbs().maxCoeff(), 1e-15);
}

TEST(Loader, InertiaChecks) {
  auto body = [](const std::string& inertia) {
    return "format: 1\nbodies:\n  - {name: b, mass: 1, inertia: " + inertia + "}\n";
  };
  EXPECT_EQ(LoadError(body("[1, 2, 2.5]")), "");
  EXPECT_EQ(LoadError(body("[0, 0, 0]")), "");  // point mass
  EXPECT_EQ(LoadError(body("[1, 1, 2, -1, 0, 0]")), "");  // singular, semi-definite: a thin rod along (1, 1, 0)
  const std::string neg = LoadError(body("[1, 1, 1, 2, 0, 0]"));  // eigenvalues -1, 1, 3
  EXPECT_TRUE(Contains(neg, "m.yaml:3:33: body 'b': inertia is not positive semi-definite (smallest eigenvalue -1)")) << neg;
  EXPECT_TRUE(Contains(LoadError(body("[1, 1]")), "'inertia' must have 3 or 6 entries, got 2"));
  EXPECT_TRUE(Contains(LoadError(body("5")), "'inertia' must be a list of 3 or 6 numbers"));
}

TEST(Loader, MiscErrors) {
  EXPECT_TRUE(Contains(LoadError(""), "m.yaml:1:1: model: the file is empty"));
  EXPECT_TRUE(Contains(LoadError("format: 2\n"), "m.yaml:1:9: model: unsupported format 2"));
  EXPECT_TRUE(Contains(LoadError("- 1\n- 2\n"), "the top level must be a mapping"));
  EXPECT_TRUE(Contains(LoadError("format: 1\nformat: 1\n"), "m.yaml:2:1: model: key 'format' is given twice"));
  EXPECT_EQ(LoadError("format: 1\nsplines: {}\n"), "");  // an empty splines block loads
  EXPECT_TRUE(Contains(LoadError("format: 1\nbodies:\n  - {name: b, geometry: {shape: mesh, file: a.stl}}\n"),
                       "body 'b': mesh file 'a.stl' not found"));
  EXPECT_TRUE(Contains(LoadError("format: 1\nbodies: [{name: b}]\nforces:\n  - {name: f, type: bushing, i: b.cm}\n"),
                       "m.yaml:4:5: force 'f': missing required key 'stiffness'"));
  EXPECT_TRUE(Contains(LoadError("format: 1\nbodies: [{name: b}]\nforces:\n  - {name: f, type: user, i: b.cm}\n"),
                       "force 'f': missing required key 'library'"));
  EXPECT_TRUE(Contains(LoadError("format: 1\nbodies: [{name: b}]\njoints:\n  - {name: j, type: gear, measures: [a, b], ratio: 2}\n"),
                       "m.yaml:4:38: joint 'j': 'measures': unknown measure 'a'"));
  // Time, measures and splines in force values load; an acceleration measure does not.
  const std::string ms =
      "format: 1\nbodies: [{name: b}]\nsplines: {s: {x: [0, 1], y: [0, 2]}}\n"
      "measures: [{name: x1, type: translational, i: b.cm, component: x},\n"
      "           {name: a1, type: translational, i: b.cm, component: x, quantity: acceleration}]\n";
  EXPECT_EQ(LoadError(ms + "forces: [{name: f, type: force, i: b.cm, value: [\"-3*x1\", \"spline(s, t)\", t]}]\n"), "");
  EXPECT_EQ(LoadError(ms + "forces: [{name: f, type: spring_damper, i: b.cm, stiffness: \"1+x1^2\", damping: t, free_length: 1}]\n"), "");
  const std::string acc = LoadError(ms + "forces: [{name: f, type: force, i: b.cm, value: [\"-3*a1\", 0, 0]}]\n");
  EXPECT_TRUE(Contains(acc, "force 'f': 'value': measure 'a1' is an acceleration")) << acc;
  EXPECT_TRUE(Contains(LoadError("format: 1\nbodies: [{name: b, mass: 1, nmae: c}]\n"),
                       "m.yaml:2:29: body 'b': unknown key 'nmae'; did you mean 'name'?"));
  EXPECT_TRUE(Contains(LoadError("format: 1\nbodies: [{name: b}, {name: c}]\njoints: [{name: j, type: revolute, i: b.cm, j: b.cm}]\n"),
                       "joint 'j': markers i and j are both on body 'b'"));
  EXPECT_TRUE(Contains(LoadError("format: 1\nsimulation: {hht: {alpha: 0.1}}\n"),
                       "m.yaml:2:27: simulation: hht alpha must be in [-1/3, 0], got 0.1"));
  EXPECT_TRUE(Contains(LoadError("format: 1\nsimulation: {t_end: 0}\n"), "simulation: t_end must be > 0, got 0"));
  EXPECT_TRUE(Contains(LoadError("format: 1\nsimulation: {ida: {rtol: -1}}\n"), "ida rtol must be > 0"));
  EXPECT_TRUE(Contains(LoadError("format: 1\nsimulation: {integrator: rk4}\n"),
                       "simulation: unknown integrator 'rk4'; did you mean 'erk'? (allowed: hht, ida, kinematic, erk)"));
  EXPECT_TRUE(Contains(LoadError("format: 1\nsimulation: {hht: {adaptive: maybe}}\n"), "'adaptive' must be true or false"));
  EXPECT_TRUE(Contains(LoadError("format: 1\nsimulation: {hht: {newton_tolerance: 0}}\n"),
                       "m.yaml:2:38: simulation: hht newton_tolerance must be > 0, got 0"));
  EXPECT_TRUE(Contains(LoadError("format: 1\nsimulation: {hht: {newton_tolerance: 2}}\n"),
                       "m.yaml:2:38: simulation: hht newton_tolerance must be below 1, got 2"));
  EXPECT_EQ(LoadModelFromString("format: 1\nsimulation: {hht: {newton_tolerance: 1e-10}}\n", "m.yaml")
                .simulation.hht_newton_tolerance,
            1e-10);
  EXPECT_EQ(LoadModelFromString("format: 1\n", "m.yaml").simulation.hht_newton_tolerance, 1e-12);
  EXPECT_TRUE(Contains(LoadError("format: 1\nbodies: [{name: b}]\nmeasures: [{name: k, type: translational, i: b.cm, component: x}]\nparameters: {k: 1}\n"),
                       "parameter 'k': a measure has the same name"));
  EXPECT_TRUE(Contains(LoadError("format: 1\nparameters: {sin: 1}\n"), "parameter 'sin': 'sin' is reserved"));
  EXPECT_TRUE(Contains(LoadError("format: 1\nbodies: [{name: ground}]\n"), "'ground' is reserved"));
  EXPECT_TRUE(Contains(LoadError("format: 1\nbodies: [{name: b, markers: {cm: {position: [1, 0, 0]}}}]\n"),
                       "body 'b', marker 'cm': marker 'b.cm' is the centre of mass"));
  EXPECT_TRUE(Contains(LoadError("format: 1\nbodies: [{name: b, mass: 1}]\nmeasures: [{name: x, type: translational, i: bb.cm, component: x}]\n"),
                       "measure 'x': 'i': unknown body 'bb' in marker 'bb.cm'; did you mean 'b'?"));
  EXPECT_TRUE(Contains(LoadError("format: 1\nbodies: [{name: b, mass: 1}]\nmeasures: [{name: x, type: translational, i: b, component: x}]\n"),
                       "must be written BODY.MARKER"));
  EXPECT_TRUE(Contains(LoadError("format: 1\nbodies: [{name: a b}]\n"),
                       "m.yaml:2:17: body 'a b': a body name may only use letters, digits, '_' and '-'"));
  EXPECT_TRUE(Contains(LoadError("format: 1\nbodies: [{name: b}]\nforces: [{name: f/1, type: torque, i: b.cm, value: [0, 0, 1]}]\n"),
                       "force 'f/1': a force name may only use"));
  EXPECT_TRUE(Contains(LoadError("format: 1\nbodies: [{name: b}]\njoints:\n  - {name: h, type: revolute, i: b.cm, j: ground.O, lock: [x]}\n"),
                       "m.yaml:4:53: joint 'h': 'lock' is only for joints of type generic"));
  EXPECT_TRUE(Contains(LoadError("format: 1\nbodies: [{name: b}]\njoints:\n  - {name: g, type: generic, i: b.cm, j: ground.O, lock: [x, rq]}\n"),
                       "joint 'g': unknown lock 'rq'"));
  EXPECT_TRUE(Contains(LoadError("format: 1\nbodies: [{name: b}]\njoints:\n  - {name: g, type: generic, i: b.cm, j: ground.O, lock: [x, x]}\n"),
                       "joint 'g': 'x' is locked twice"));
  EXPECT_TRUE(Contains(LoadError("format: 1\nbodies: [{name: b, mass: 1e999}]\n"), "number out of range"));
  EXPECT_TRUE(Contains(LoadError("format: 1\nparameters: {a: sqrt(-1)}\n"),
                       "m.yaml:2:17: parameter 'a': evaluates to nan ('sqrt(-1)')"));
  EXPECT_TRUE(Contains(LoadError("format: 1\nbodies: [{name: b, mass: 1/0}]\n"), "body 'b': 'mass' evaluates to inf"));
  LoadOptions options;
  options.parameter_overrides["k"] = 1;  // no parameters block: no line to point at
  EXPECT_EQ(LoadError("format: 1\n", options).find("m.yaml: parameter 'k': cannot set 'k=1': the model has no such parameter"), 0u);
}

TEST(Loader, UnreadableFile) {
  const std::string path = ModelPath("does_not_exist.yaml");
  try {
    LoadModel(path);
    FAIL() << "no error";
  } catch (const ModelError& e) {
    EXPECT_EQ(std::string(e.what()).find(path + ": model: cannot open the file"), 0u) << e.what();
  }
  try {
    LoadModel(ModelPath(""));  // a directory
    FAIL() << "no error";
  } catch (const ModelError& e) {
    EXPECT_TRUE(Contains(e.what(), "cannot read")) << e.what();
  }
}

// verification/malformed/: one mistake per file, listed with the expected line, element
// and message in expected.txt (FILE|LINE|ELEMENT|MESSAGE PART).
TEST(Loader, MalformedFiles) {
  const std::string dir = kSource + "/verification/malformed/";
  std::ifstream list(dir + "expected.txt");
  ASSERT_TRUE(list) << "cannot open expected.txt";
  std::string line;
  int count = 0;
  while (std::getline(list, line)) {
    if (line.empty() || line[0] == '#') continue;
    std::istringstream fields(line);
    std::string file, line_number, element, message;
    std::getline(fields, file, '|');
    std::getline(fields, line_number, '|');
    std::getline(fields, element, '|');
    std::getline(fields, message);
    ++count;
    SCOPED_TRACE(file);
    try {
      LoadModel(dir + file);
      ADD_FAILURE() << file << " loaded without an error";
    } catch (const ModelError& e) {
      const std::string what = e.what();
      const std::string prefix = dir + file + ":" + line_number + ":";
      EXPECT_EQ(what.compare(0, prefix.size(), prefix), 0) << what;
      EXPECT_EQ(e.where().line, std::stoi(line_number)) << what;
      EXPECT_EQ(e.element(), element) << what;
      EXPECT_TRUE(Contains(what, ": " + element + ": ")) << what;
      EXPECT_TRUE(Contains(what, message)) << what << "\nexpected to contain: " << message;
    }
  }
  EXPECT_GE(count, 12);
  // Without the mistake the model loads: each file fails for its own reason only.
  const Model base = LoadModel(dir + "correct_base.yaml");
  EXPECT_EQ(base.bodies.size(), 2u);
  EXPECT_EQ(base.joints.size(), 2u);
  EXPECT_DOUBLE_EQ(base.markers[base.find_marker("crank.A")].position.y(), 0.05);
}

// ---- splines ------------------------------------------------------------------------------

TEST(LoaderSplines, InlineAndFromFiles) {
  const Model m = LoadModel(ModelPath("splines.yaml"));
  ASSERT_EQ(m.splines.size(), 5u);
  EXPECT_EQ(m.find_spline("drive"), 0);
  EXPECT_EQ(m.find_spline("profile"), 4);
  EXPECT_EQ(m.find_spline("nope"), -1);

  // Inline cubic through (0,0), (1,1), (2,0): 0.6875 at 0.5 (see test_spline.cc).
  const SplineDef& drive = m.splines[0];
  EXPECT_EQ(drive.name, "drive");
  EXPECT_EQ(drive.spline.kind(), Interpolation::kCubic);
  EXPECT_EQ(drive.file, "");
  EXPECT_EQ(drive.where.line, 8);
  EXPECT_NEAR(drive.spline.Evaluate(0.5), 0.6875, 1e-15);

  // Entries may be load-time expressions of the parameters (a = 2, top = 6).
  const Spline& steps = m.splines[1].spline;
  EXPECT_EQ(steps.kind(), Interpolation::kLinear);
  EXPECT_EQ(steps.x(), (std::vector<double>{0, 1, 2, 3}));
  EXPECT_EQ(steps.y(), (std::vector<double>{0, 6, 0, -6}));
  EXPECT_NEAR(steps.Evaluate(0.5), 3, 1e-15);

  // Default interpolation: akima (Akima slopes by hand in test_spline.cc: -0.5 at 0).
  const Spline& smooth = m.splines[2].spline;
  EXPECT_EQ(smooth.kind(), Interpolation::kAkima);
  double d1;
  smooth.Evaluate(0, &d1);
  EXPECT_NEAR(d1, -0.5, 1e-15);

  // CSV, relative to the model file, header line, columns 0 and 2, comment and blank line.
  const SplineDef& road = m.splines[3];
  EXPECT_EQ(road.spline.x(), (std::vector<double>{0, 1, 2.5}));
  EXPECT_EQ(road.spline.y(), (std::vector<double>{0, -0.1, 0.05}));
  EXPECT_TRUE(Contains(road.file, "models/data/road.csv")) << road.file;
  EXPECT_NEAR(road.spline.Evaluate(1.75), -0.025, 1e-15);

  // Whitespace file, default columns 0 and 1, no header lines (the first line is a comment).
  const Spline& profile = m.splines[4].spline;
  EXPECT_EQ(profile.kind(), Interpolation::kAkima);
  EXPECT_EQ(profile.x(), (std::vector<double>{0, 1, 2, 3, 4}));
  EXPECT_NEAR(profile.Evaluate(1.5), 0.5625, 1e-15);  // same data as `smooth`, Akima by hand
  EXPECT_NEAR(profile.Evaluate(1.5), smooth.Evaluate(1.5), 1e-15);
}

TEST(LoaderSplines, ParameterOverridesReachThePoints) {
  LoadOptions options;
  options.parameter_overrides["a"] = 1;  // x = [0, a/2, a, 3], y = [0, 3a, 0, -3a]
  const Model m = LoadModel(ModelPath("splines.yaml"), options);
  EXPECT_EQ(m.splines[1].spline.x(), (std::vector<double>{0, 0.5, 1, 3}));
  EXPECT_EQ(m.splines[1].spline.y(), (std::vector<double>{0, 3, 0, -3}));
  // An override that makes x decrease is reported at the entry.
  options.parameter_overrides["a"] = 4;
  try {
    LoadModel(ModelPath("splines.yaml"), options);
    ADD_FAILURE() << "loaded";
  } catch (const ModelError& e) {
    EXPECT_TRUE(Contains(e.what(), "splines.yaml:10:22: spline 'steps': 'x' must be strictly increasing: x[3] = 3 "
                                   "is not greater than x[2] = 4")) << e.what();
  }
}

TEST(LoaderSplines, PointsCanBeReplacedAfterLoading) {
  Model m = LoadModel(ModelPath("splines.yaml"));
  Spline& drive = m.splines[m.find_spline("drive")].spline;
  drive.SetPoints({0, 1, 2}, {0, 2, 0});
  EXPECT_NEAR(m.splines[0].spline.Evaluate(0.5), 1.375, 1e-15);
}

// Parameters changed after loading: the inline points written as expressions follow.
TEST(LoaderSplines, ReevaluateSplinePointsAfterAParameterChange) {
  Model m = LoadModel(ModelPath("splines.yaml"));
  EXPECT_TRUE(m.splines[m.find_spline("steps")].depends_on_parameters());
  EXPECT_FALSE(m.splines[m.find_spline("drive")].depends_on_parameters());
  EXPECT_FALSE(m.splines[m.find_spline("road")].depends_on_parameters());
  m.splines[m.find_spline("drive")].spline.SetPoints({0, 1, 2}, {0, 2, 0});  // by hand: kept
  m.parameters[m.find_parameter("a")].value = 1;
  m.parameters[m.find_parameter("top")].value = 3;
  ReevaluateSplinePoints(&m);
  const Spline& steps = m.splines[m.find_spline("steps")].spline;
  EXPECT_EQ(steps.x(), (std::vector<double>{0, 0.5, 1, 3}));
  EXPECT_EQ(steps.y(), (std::vector<double>{0, 3, 0, -3}));
  EXPECT_NEAR(steps.Evaluate(0.25), 1.5, 1e-15);
  EXPECT_EQ(m.splines[m.find_spline("drive")].spline.y(), (std::vector<double>{0, 2, 0}));
  // Points that become invalid: an error naming the spline, the old points kept.
  m.parameters[m.find_parameter("a")].value = 4;
  try {
    ReevaluateSplinePoints(&m);
    ADD_FAILURE() << "no error";
  } catch (const std::invalid_argument& e) {
    EXPECT_EQ(std::string(e.what()),
              "spline 'steps': x must be strictly increasing: x[3] = 3 is not greater than x[2] = 4");
  }
  EXPECT_EQ(steps.x(), (std::vector<double>{0, 0.5, 1, 3}));
}

TEST(LoaderSplines, Mistakes) {
  auto err = [](const std::string& splines) { return LoadError("format: 1\nparameters: {p: 1}\nsplines:\n" + splines); };
  std::string e;
  e = err("  s: {x: [0, 1], y: [0, 1], interpolation: cubik}\n");
  EXPECT_TRUE(Contains(e, "m.yaml:4:44: spline 's': unknown interpolation 'cubik'; did you mean 'cubic'?")) << e;
  e = err("  s: {x: [0, 1, 1], y: [0, 1, 2]}\n");
  EXPECT_TRUE(Contains(e, "m.yaml:4:17: spline 's': 'x' must be strictly increasing: x[2] = 1 is not greater than x[1] = 1")) << e;
  e = err("  s: {x: [0, 1, 2], y: [0, 1]}\n");
  EXPECT_TRUE(Contains(e, "m.yaml:4:24: spline 's': 'x' has 3 entries but 'y' has 2")) << e;
  e = err("  s: {x: [0], y: [0]}\n");
  EXPECT_TRUE(Contains(e, "m.yaml:4:10: spline 's': a spline needs at least 2 points, got 1")) << e;
  e = err("  s: {x: [0, q], y: [0, 1]}\n");
  EXPECT_TRUE(Contains(e, "m.yaml:4:14: spline 's': 'x[1]': in expression 'q': unknown name 'q'")) << e;
  e = err("  s: {x: [0, \"1/0\"], y: [0, 1]}\n");
  EXPECT_TRUE(Contains(e, "spline 's': 'x[1]' evaluates to inf")) << e;
  e = err("  s: {x: 3, y: [0, 1]}\n");
  EXPECT_TRUE(Contains(e, "m.yaml:4:10: spline 's': 'x' must be a list of numbers, got '3'")) << e;
  e = err("  s: {x: [0, 1]}\n");
  EXPECT_TRUE(Contains(e, "spline 's': missing required key 'y'")) << e;
  e = err("  s: {interpolation: linear}\n");
  EXPECT_TRUE(Contains(e, "m.yaml:4:6: spline 's': missing the points: give 'x' and 'y' (lists of numbers) or 'file'")) << e;
  e = err("  s: {x: [0, 1], y: [0, 1], colour: red}\n");
  EXPECT_TRUE(Contains(e, "m.yaml:4:29: spline 's': unknown key 'colour'")) << e;
  e = err("  s: {file: a.csv, x: [0, 1], y: [0, 1]}\n");
  EXPECT_TRUE(Contains(e, "spline 's': give either 'file' or the points 'x' and 'y', not both")) << e;
  e = err("  s: {file: a.csv, x_column: 1.5}\n");
  EXPECT_TRUE(Contains(e, "m.yaml:4:30: spline 's': 'x_column' must be a whole number >= 0, got 1.5")) << e;
  e = err("  s: {file: a.csv, header_lines: -1}\n");
  EXPECT_TRUE(Contains(e, "spline 's': 'header_lines' must be a whole number >= 0, got -1")) << e;
  e = err("  s: {file: a.csv, x_column: 1}\n");
  EXPECT_TRUE(Contains(e, "spline 's': x_column and y_column are both 1; they must differ")) << e;
  e = err("  s: {file: no_such_file.csv}\n");
  EXPECT_TRUE(Contains(e, "m.yaml:4:13: spline 's': data file 'no_such_file.csv' not found")) << e;
  e = err("  s: [0, 1]\n");
  EXPECT_TRUE(Contains(e, "m.yaml:4:6: spline 's': a spline must be a mapping")) << e;
  e = err("  2s: {x: [0, 1], y: [0, 1]}\n");
  EXPECT_TRUE(Contains(e, "m.yaml:4:3: spline '2s': a spline name must be letters, digits and '_'")) << e;
  e = err("  s: {x: [0, 1], y: [0, 1]}\n  s: {x: [0, 1], y: [0, 1]}\n");
  EXPECT_TRUE(Contains(e, "m.yaml:5:3: spline 's': duplicate spline name")) << e;
  e = LoadError("format: 1\nsplines: [1, 2]\n");
  EXPECT_TRUE(Contains(e, "m.yaml:2:10: model: 'splines' must be a mapping")) << e;
}

// Data-file mistakes name the model file's line and the data file's line.
TEST(LoaderSplines, DataFileMistakes) {
  const std::string dir = ::testing::TempDir();
  auto write = [&](const std::string& name, const std::string& text) { std::ofstream(dir + name) << text; };
  write("spline_model.yaml", "format: 1\nsplines:\n  road: {file: spline_data.csv, header_lines: 1}\n");
  auto error = [&] {
    try {
      LoadModel(dir + "spline_model.yaml");
    } catch (const ModelError& e) {
      return std::string(e.what());
    }
    return std::string();
  };
  write("spline_data.csv", "x,y\n0,0\n1,1\n");
  EXPECT_EQ(error(), "");
  write("spline_data.csv", "x,y\n0,0\n1,1e\n");
  std::string e = error();
  EXPECT_TRUE(Contains(e, "spline_model.yaml:3:16: spline 'road': in data file: " + dir +
                              "spline_data.csv:3: column 1 is '1e', not a number")) << e;
  write("spline_data.csv", "x,y\n0,0\n2\n");
  e = error();
  EXPECT_TRUE(Contains(e, "spline_data.csv:3: column 1 (0-based) is missing: the line has 1 column")) << e;
  write("spline_data.csv", "x,y\n0,0\n\n# later\n1,0\n1,1\n");
  e = error();
  EXPECT_TRUE(Contains(e, "spline_data.csv:6: x = 1 is not greater than x = 1 on line 5; x must be strictly increasing")) << e;
  write("spline_data.csv", "x,y\n0,0\n");
  e = error();
  EXPECT_TRUE(Contains(e, "spline_data.csv' has 1 point after 1 header line; a spline needs at least 2")) << e;
}

}  // namespace
}  // namespace mbdae::mbs

namespace mbdae::mbs {
namespace {

TEST(LoaderMesh, MassAndInertiaFromTheMesh) {
  const Model m = LoadModel(kSource + "/tests/mbs/models/mesh_body.yaml");
  ASSERT_EQ(m.bodies.size(), 2u);
  // The box 2 x 1 x 0.5 scaled by 0.1 with density 1000: the closed form of a box.
  const MassProperties box = BoxMass(Vec3(0.2, 0.1, 0.05), 1000);
  EXPECT_NEAR(m.bodies[0].mass, 1.0, 1e-12);
  EXPECT_NEAR(m.bodies[0].mass, box.mass, 1e-12);
  EXPECT_LT((m.bodies[0].inertia - box.inertia).norm(), 1e-12 * box.inertia.norm());
  // A mesh without a density only shows the body: the explicit values stay.
  EXPECT_EQ(m.bodies[1].mass, 2.0);
  EXPECT_EQ(m.bodies[1].inertia, Mat3::Identity());
}

TEST(LoaderMesh, Errors) {
  // A missing file names the file; a bad scale names the key.
  const std::string base = "format: 1\nbodies:\n  - name: b\n    geometry: {shape: mesh, ";
  std::string e = LoadError(base + "file: nowhere.stl, density: 1}\n");
  EXPECT_TRUE(Contains(e, "m.yaml:4:")) << e;
  EXPECT_TRUE(Contains(e, "body 'b'")) << e;
  EXPECT_TRUE(Contains(e, "mesh file 'nowhere.stl' not found")) << e;
  e = LoadError(base + "file: nowhere.stl, scale: -1}\n");
  EXPECT_TRUE(Contains(e, "geometry scale must be > 0")) << e;
  e = LoadError(base + "file: x.stl, radius: 1}\n");
  EXPECT_TRUE(Contains(e, "unknown key 'radius'")) << e;
}

}  // namespace
}  // namespace mbdae::mbs
