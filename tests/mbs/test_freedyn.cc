// FreeDyn model files (mbs/freedyn.*) and the model writer (mbs/model_writer.*): every
// block and conversion against hand-computed values, every rejection with its
// FILE:LINE:COLUMN, and round trips through the YAML format.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include "apps/cli.h"
#include "mbs/freedyn.h"
#include "mbs/kinematics.h"
#include "mbs/loader.h"
#include "mbs/model_writer.h"

namespace mbdae::mbs {
namespace {

const std::string kSource = MBDAE_SOURCE_DIR;
const std::string kModels = kSource + "/tests/mbs/models/freedyn/";

// ---- comparing two models field by field ------------------------------------------------

void ExpectNear(const Mat3& a, const Mat3& b, double tol, const std::string& what) {
  EXPECT_LE((a - b).cwiseAbs().maxCoeff(), tol) << what << "\n" << a << "\n" << b;
}
void ExpectNear(const Vec3& a, const Vec3& b, double tol, const std::string& what) {
  EXPECT_LE((a - b).cwiseAbs().maxCoeff(), tol) << what << ": " << a.transpose() << " vs " << b.transpose();
}

// The value of `e` at inputs drawn from `rng` (the same draws for both models).
double EvaluateAt(const Expression& e, const Model& m, const std::vector<double>& measures, double t) {
  std::vector<double> p = m.parameter_values();
  std::vector<const Spline*> splines;
  for (const SplineDef& d : m.splines) splines.push_back(&d.spline);
  ExpressionInputs in;
  in.t = t;
  in.parameters = p.data();
  in.measures = measures.data();
  in.splines = splines.data();
  return e.Evaluate(in);
}

void ExpectSameExpression(const Expression& a, const Model& ma, const Expression& b, const Model& mb,
                          const std::string& what) {
  EXPECT_EQ(a.text(), b.text()) << what;
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(0.1, 2.0);
  for (int trial = 0; trial < 5; ++trial) {
    std::vector<double> measures(ma.measures.size() + 1);
    for (double& x : measures) x = u(rng);
    const double t = u(rng);
    const double va = EvaluateAt(a, ma, measures, t), vb = EvaluateAt(b, mb, measures, t);
    EXPECT_NEAR(va, vb, 1e-14 * std::max(1.0, std::abs(va))) << what << " at t = " << t;
  }
}

// Everything LoadModel reads, compared (markers by name: the writer groups them by body).
void ExpectSameModel(const Model& a, const Model& b) {
  EXPECT_EQ(a.name, b.name);
  ExpectNear(a.gravity, b.gravity, 0, "gravity");
  ASSERT_EQ(a.parameters.size(), b.parameters.size());
  for (size_t k = 0; k < a.parameters.size(); ++k) {
    EXPECT_EQ(a.parameters[k].name, b.parameters[k].name);
    EXPECT_EQ(a.parameters[k].value, b.parameters[k].value) << a.parameters[k].name;
    EXPECT_EQ(a.parameters[k].expression, b.parameters[k].expression);
  }
  ASSERT_EQ(a.splines.size(), b.splines.size());
  for (size_t k = 0; k < a.splines.size(); ++k) {
    EXPECT_EQ(a.splines[k].name, b.splines[k].name);
    EXPECT_EQ(a.splines[k].spline.kind(), b.splines[k].spline.kind());
    EXPECT_EQ(a.splines[k].spline.x(), b.splines[k].spline.x());
    EXPECT_EQ(a.splines[k].spline.y(), b.splines[k].spline.y());
  }
  ASSERT_EQ(a.markers.size(), b.markers.size());
  for (const Marker& m : a.markers) {
    const int k = b.find_marker(m.name);
    ASSERT_GE(k, 0) << m.name;
    EXPECT_EQ(m.body, b.markers[k].body) << m.name;
    ExpectNear(m.position, b.markers[k].position, 0, m.name + " position");
    ExpectNear(m.orientation, b.markers[k].orientation, 4e-16, m.name + " orientation");
  }
  ASSERT_EQ(a.bodies.size(), b.bodies.size());
  for (size_t k = 0; k < a.bodies.size(); ++k) {
    const Body &x = a.bodies[k], &y = b.bodies[k];
    EXPECT_EQ(x.name, y.name);
    EXPECT_EQ(x.mass, y.mass) << x.name;
    ExpectNear(x.inertia, y.inertia, 0, x.name + " inertia");
    ExpectNear(x.position, y.position, 0, x.name + " position");
    EXPECT_LE((x.orientation - y.orientation).cwiseAbs().maxCoeff(), 2.3e-16) << x.name;
    ExpectNear(x.velocity, y.velocity, 0, x.name + " velocity");
    ExpectNear(x.angular_velocity, y.angular_velocity, 0, x.name + " angular velocity");
    EXPECT_EQ(a.markers[x.cm_marker].name, b.markers[y.cm_marker].name);
  }
  ASSERT_EQ(a.measures.size(), b.measures.size());
  for (size_t k = 0; k < a.measures.size(); ++k) {
    const Measure &x = a.measures[k], &y = b.measures[k];
    EXPECT_EQ(x.name, y.name);
    EXPECT_EQ(x.type, y.type) << x.name;
    EXPECT_EQ(a.markers[x.i].name, b.markers[y.i].name) << x.name;
    EXPECT_EQ(a.markers[x.j].name, b.markers[y.j].name) << x.name;
    EXPECT_EQ(x.component, y.component) << x.name;
    if (x.type == MeasureType::kTranslational) EXPECT_EQ(x.frame, y.frame) << x.name;
    EXPECT_EQ(x.quantity, y.quantity) << x.name;
    EXPECT_EQ(x.offset_initial, y.offset_initial) << x.name;
  }
  ASSERT_EQ(a.joints.size(), b.joints.size());
  for (size_t k = 0; k < a.joints.size(); ++k) {
    const Joint &x = a.joints[k], &y = b.joints[k];
    EXPECT_EQ(x.name, y.name);
    EXPECT_EQ(x.type, y.type) << x.name;
    EXPECT_EQ(x.locks, y.locks) << x.name;
    EXPECT_EQ(a.markers[x.i].name, b.markers[y.i].name) << x.name;
    EXPECT_EQ(a.markers[x.j].name, b.markers[y.j].name) << x.name;
  }
  ASSERT_EQ(a.forces.size(), b.forces.size());
  for (size_t k = 0; k < a.forces.size(); ++k) {
    const Force &x = a.forces[k], &y = b.forces[k];
    EXPECT_EQ(x.name, y.name);
    EXPECT_EQ(x.type, y.type) << x.name;
    EXPECT_EQ(a.markers[x.i].name, b.markers[y.i].name) << x.name;
    EXPECT_EQ(a.markers[x.j].name, b.markers[y.j].name) << x.name;
    if (x.type == ForceType::kSpringDamper) {
      ExpectSameExpression(x.stiffness, a, y.stiffness, b, x.name + " stiffness");
      ExpectSameExpression(x.damping, a, y.damping, b, x.name + " damping");
      ExpectSameExpression(x.free_length, a, y.free_length, b, x.name + " free_length");
      ExpectSameExpression(x.preload, a, y.preload, b, x.name + " preload");
    } else {
      EXPECT_EQ(x.frame, y.frame) << x.name;
      for (int c = 0; c < 3; ++c) ExpectSameExpression(x.value[c], a, y.value[c], b, x.name + " value");
    }
  }
  const SimulationSettings &s = a.simulation, &r = b.simulation;
  EXPECT_EQ(s.t_end, r.t_end);
  EXPECT_EQ(s.output_step, r.output_step);
  EXPECT_EQ(s.integrator, r.integrator);
  EXPECT_EQ(s.hht_alpha, r.hht_alpha);
  EXPECT_EQ(s.hht_step, r.hht_step);
  EXPECT_EQ(s.hht_adaptive, r.hht_adaptive);
  EXPECT_EQ(s.hht_tolerance, r.hht_tolerance);
  EXPECT_EQ(s.hht_modified, r.hht_modified);
  EXPECT_EQ(s.ida_rtol, r.ida_rtol);
  EXPECT_EQ(s.ida_atol, r.ida_atol);
  EXPECT_EQ(s.ida_max_steps, r.ida_max_steps);
  EXPECT_EQ(s.ida_min_step, r.ida_min_step);
}

// Whether the YAML loader reads force values over measures and t (the elements work).
bool LoaderReadsStateForces() {
  try {
    LoadModelFromString(
        "format: 1\nbodies: [{name: b, mass: 1, inertia: [1, 1, 1]}]\n"
        "measures: [{name: x, type: translational, i: b.cm, component: x}]\n"
        "forces: [{name: f, type: force, i: b.cm, value: [\"-x*t\", 0, 0]}]\n",
        "probe.yaml");
    return true;
  } catch (const ModelError&) {
    return false;
  }
}

std::string Message(const std::string& text, const std::string& file = "m.fds") {
  try {
    LoadFreeDynModelFromString(text, kModels + file);
  } catch (const ModelError& e) {
    return e.what();
  }
  return "(no error)";
}

// ---- expressions ----------------------------------------------------------------------------

FreeDynNames Names() {
  FreeDynNames n;
  n.parameters = {{"k", "k"}, {"my par", "my_par"}};
  n.measures = {{"x", "x"}, {"v", "v_1"}};
  n.splines = {{"drive", "drive"}};
  return n;
}

TEST(FreeDynExpression, TranslatesEveryForm) {
  const FreeDynNames n = Names();
  EXPECT_EQ(TranslateFreeDynExpression("PARVAL[k]*MEAVAL[x] + PARVAL[my par]*MEAVAL[v]", n), "k*x + my_par*v_1");
  EXPECT_EQ(TranslateFreeDynExpression("SPL[SIMTIME[],drive]", n), "spline(drive, t)");
  EXPECT_EQ(TranslateFreeDynExpression("2*SPL[ PARVAL[k]*(SIMTIME[]+1) , drive ]^2", n),
            "2*spline(drive, k*(t+1))^2");
  EXPECT_EQ(TranslateFreeDynExpression("SPL[SPL[SIMTIME[],drive],drive]", n), "spline(drive, spline(drive, t))");
  EXPECT_EQ(TranslateFreeDynExpression("COS(MEAVAL[x])+Exp(1)", n), "cos(x)+exp(1)");
  EXPECT_EQ(TranslateFreeDynExpression("3.5e-2 - x", n), "3.5e-2 - x");  // other text kept
}

TEST(FreeDynExpression, MistakesNameTheColumn) {
  const FreeDynNames n = Names();
  struct Case {
    const char* text;
    const char* message;
    int column;
  } cases[] = {
      {"1 + PARVAL[q]", "unknown parameter 'q' in PARVAL[]", 5},
      {"MEAVAL[k]", "unknown measure 'k' in MEAVAL[]", 1},
      {"2*SPL[SIMTIME[],road]", "unknown spline 'road' in SPL[]", 3},
      {"FOO[1]", "unknown FreeDyn function 'FOO[...]'", 1},
      {"PARVAL[k", "missing ']'", 1},
      {"SIMTIME[3]", "SIMTIME[] takes no argument", 1},
      {"SPL[SIMTIME[]]", "SPL[x, name] needs two arguments", 1},
      {"x]", "unexpected ']'", 2},
  };
  for (const Case& c : cases) {
    int column = 0;
    try {
      TranslateFreeDynExpression(c.text, n, &column);
      ADD_FAILURE() << c.text << ": no error";
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find(c.message), std::string::npos) << c.text << ": " << e.what();
      EXPECT_EQ(column, c.column) << c.text;
    }
  }
}

// ---- the single-mass oscillator -----------------------------------------------------------------

TEST(FreeDyn, OscillatorEveryField) {
  const Model m = LoadFreeDynModel(kSource + "/examples/freedyn/oscillator.fds");
  EXPECT_EQ(m.name, "oscillator");
  ASSERT_EQ(m.bodies.size(), 1u);
  const Body& b = m.bodies[0];
  EXPECT_EQ(b.name, "block");
  EXPECT_EQ(b.mass, 1.5);
  ExpectNear(b.inertia, Mat3(Vec3(0.01, 0.01, 0.01).asDiagonal()), 0, "inertia");
  ExpectNear(b.position, Vec3(0.2, 0, 0), 0, "position");
  EXPECT_EQ(b.orientation, Quat(1, 0, 0, 0));
  ExpectNear(b.velocity, Vec3(0.5, 0, 0), 0, "velocity");
  EXPECT_EQ(m.markers[0].name, "ground.O");
  EXPECT_EQ(m.markers[b.cm_marker].name, "block.cm");

  ASSERT_EQ(m.parameters.size(), 2u);
  EXPECT_EQ(m.parameters[0].name, "k");
  EXPECT_EQ(m.parameters[0].value, 40);
  EXPECT_EQ(m.parameters[1].value, 0.8);

  ASSERT_EQ(m.measures.size(), 2u);
  const Measure &x = m.measures[0], &v = m.measures[1];
  EXPECT_EQ(x.name, "x");
  EXPECT_EQ(x.quantity, Quantity::kPosition);
  EXPECT_EQ(x.component, Component::kX);
  EXPECT_EQ(x.frame, MeasureFrame::kWorld);
  EXPECT_TRUE(x.offset_initial);
  EXPECT_EQ(m.markers[x.i].name, "block.cm");  // the location is the centre of mass
  EXPECT_EQ(x.j, 0);
  EXPECT_EQ(v.quantity, Quantity::kVelocity);
  EXPECT_FALSE(v.offset_initial);

  ASSERT_EQ(m.joints.size(), 1u);
  const Joint& j = m.joints[0];
  EXPECT_EQ(j.type, JointType::kGeneric);
  EXPECT_EQ(j.locks, kLockY | kLockZ | kLockRx | kLockRy | kLockRz);
  EXPECT_EQ(m.markers[j.i].name, "block.cm");
  EXPECT_EQ(m.markers[j.j].name, "ground.slide_x");
  ExpectNear(m.markers[j.j].position, Vec3(0.2, 0, 0), 0, "joint location");

  ASSERT_EQ(m.forces.size(), 1u);
  const Force& f = m.forces[0];
  EXPECT_EQ(f.type, ForceType::kForce);
  EXPECT_EQ(f.frame, ForceFrame::kWorld);
  EXPECT_EQ(f.value[0].text(), "-(k*x + d*v)");
  // F = -(k x + d v) along x at x = 0.03, v = -0.4: -(1.2 - 0.32) = -0.88.
  const double measures[] = {0.03, -0.4};
  const std::vector<double> p = m.parameter_values();
  ExpressionInputs in;
  in.parameters = p.data();
  in.measures = measures;
  EXPECT_NEAR(f.value[0].Evaluate(in), -0.88, 1e-15);
  EXPECT_EQ(f.value[1].Evaluate(in), 0);
  EXPECT_EQ(f.value[2].Evaluate(in), 0);

  const SimulationSettings& s = m.simulation;
  EXPECT_EQ(s.t_end, 3);
  EXPECT_EQ(s.output_step, 0.01);
  EXPECT_EQ(s.integrator, IntegratorKind::kHht);
  EXPECT_EQ(s.hht_alpha, -0.1);
  EXPECT_TRUE(s.hht_adaptive);
  EXPECT_EQ(s.hht_tolerance, 1e-7);
  EXPECT_EQ(s.hht_step, 1e-3);  // min(SolverMaxTimeStep, OutputTimeStepSize)
  EXPECT_TRUE(s.hht_modified);
}

TEST(FreeDyn, ParameterOverrides) {
  LoadOptions o;
  o.parameter_overrides = {{"k", 12.5}};
  const Model m = LoadFreeDynModel(kSource + "/examples/freedyn/oscillator.fds", o);
  EXPECT_EQ(m.parameters[0].value, 12.5);
  o.parameter_overrides = {{"kk", 1}};
  try {
    LoadFreeDynModel(kSource + "/examples/freedyn/oscillator.fds", o);
    ADD_FAILURE() << "no error";
  } catch (const ModelError& e) {
    EXPECT_NE(std::string(e.what()).find("cannot set 'kk=1': the model has no such parameter"), std::string::npos) << e.what();
  }
}

// ---- orientations, markers and the other force and measure types ------------------------------

TEST(FreeDyn, RowsOfOrientationPAIAreTheBodyAxes) {
  const Model m = LoadFreeDynModel(kModels + "two_bodies.fds");
  ASSERT_EQ(m.bodies.size(), 2u);
  // arm: rows (cos 30, sin 30, 0), (-sin 30, cos 30, 0), (0, 0, 1) -> body x along 30 deg.
  const Mat3 A = RotationMatrix(m.bodies[0].orientation);
  ExpectNear(A.col(0), Vec3(std::cos(M_PI / 6), std::sin(M_PI / 6), 0), 1e-6, "arm x axis");
  ExpectNear(A.col(2), Vec3(0, 0, 1), 1e-15, "arm z axis");
  EXPECT_NEAR(m.bodies[0].orientation.norm(), 1, 1e-15);
  ExpectNear(m.bodies[0].angular_velocity, Vec3(0, 0, 1.5), 0, "omega");
  // slider block (name with a blank -> '_'): rows x, z, -y -> 90 deg about x.
  EXPECT_EQ(m.bodies[1].name, "slider_block");
  const Mat3 B = RotationMatrix(m.bodies[1].orientation);
  ExpectNear(B, (Mat3() << 1, 0, 0, 0, 0, -1, 0, 1, 0).finished(), 1e-15, "slider axes");
  ExpectNear(m.bodies[1].inertia.diagonal(), Vec3(0.01, 0.02, 0.03), 0, "principal inertia");
  ExpectNear(m.bodies[1].velocity, Vec3(0, 0.1, 0), 0, "velocity");
  EXPECT_EQ(m.gravity, Vec3(0, -9.81, 0));
}

TEST(FreeDyn, ConstraintMarkersAtTheWorldLocationWithTheConstraintAxes) {
  const Model m = LoadFreeDynModel(kModels + "two_bodies.fds");
  ASSERT_EQ(m.joints.size(), 2u);
  const Joint& pin = m.joints[1];
  EXPECT_EQ(pin.locks, kLockX | kLockY | kLockRz);
  // Body 1 (slider) is i, body 2 (arm) is j; both markers are at the world Location with
  // the axes of ConstraintOrientation (rows: 45 deg about z) at t = 0.
  const Vec3 location(0.866025, 0.5, 0);
  const Mat3 axes = (Mat3() << std::sqrt(0.5), -std::sqrt(0.5), 0, std::sqrt(0.5), std::sqrt(0.5), 0, 0, 0, 1).finished();
  for (int marker : {pin.i, pin.j}) {
    const Marker& mk = m.markers[marker];
    const Body& body = m.bodies[mk.body];
    const Mat3 A = RotationMatrix(body.orientation);
    ExpectNear(body.position + A * mk.position, location, 1e-15, mk.name + " world position");
    ExpectNear(A * mk.orientation, axes, 1e-6, mk.name + " world axes");
  }
  EXPECT_EQ(m.markers[pin.i].body, 1);
  EXPECT_EQ(m.markers[pin.j].body, 0);
  // The hinge on ground at the origin with world axes is ground.O itself.
  EXPECT_EQ(m.joints[0].j, 0);
  // Ground markers first, then each body's: cm first.
  for (size_t k = 1; k < m.markers.size(); ++k) EXPECT_LE(m.markers[k - 1].body, m.markers[k].body);
  EXPECT_EQ(m.bodies[0].cm_marker, 1);
}

TEST(FreeDyn, LineOfSightForceFromFourMeasures) {
  const Model m = LoadFreeDynModel(kModels + "two_bodies.fds");
  const Force& rope = m.forces[0];
  EXPECT_EQ(rope.name, "rope");
  EXPECT_EQ(rope.frame, ForceFrame::kWorld);
  const int dx = m.find_measure("rope_dx"), len = m.find_measure("rope_length");
  ASSERT_GE(dx, 0);
  ASSERT_GE(len, 0);
  EXPECT_EQ(m.measures[len].component, Component::kDistance);
  EXPECT_EQ(m.measures[dx].i, rope.i);
  EXPECT_EQ(m.measures[dx].j, rope.j);
  // p1 - p2 = (-0.4, 0.2, -0.1) (|d| = 0.458...), gap = 0.6: F = 250 (0.6 - 0.35) = 62.5
  // along (p2 - p1)/|p2 - p1| on body 1.
  std::vector<double> measures(m.measures.size(), 0.0);
  const Vec3 d(-0.4, 0.2, -0.1);
  measures[m.find_measure("gap")] = 0.6;
  measures[dx] = d[0];
  measures[m.find_measure("rope_dy")] = d[1];
  measures[m.find_measure("rope_dz")] = d[2];
  measures[len] = d.norm();
  const std::vector<double> p = m.parameter_values();
  ExpressionInputs in;
  in.parameters = p.data();
  in.measures = measures.data();
  const Vec3 expected = -62.5 * d / d.norm();
  for (int c = 0; c < 3; ++c) EXPECT_NEAR(rope.value[c].Evaluate(in), expected[c], 1e-13) << c;
}

TEST(FreeDyn, SpaceFixedDirectionIsNormalisedAndSplinesAreRead) {
  const Model m = LoadFreeDynModel(kModels + "two_bodies.fds");
  ASSERT_EQ(m.splines.size(), 1u);
  const SplineDef& drive = m.splines[0];
  EXPECT_EQ(drive.spline.kind(), Interpolation::kLinear);
  EXPECT_EQ(drive.spline.x(), (std::vector<double>{0, 1, 2, 4}));
  EXPECT_EQ(drive.spline.y(), (std::vector<double>{0, 2, 1, 3}));  // ColumnYData = 2, 1 header line
  const Force& push = m.forces[1];
  EXPECT_EQ(push.value[2].text(), "spline(drive, t)*c");  // direction (0, 0, 2) -> (0, 0, 1)
  const std::vector<double> p = m.parameter_values();
  const Spline* splines[] = {&drive.spline};
  ExpressionInputs in;
  in.parameters = p.data();
  in.splines = splines;
  in.t = 1.5;
  EXPECT_NEAR(push.value[2].Evaluate(in), 1.5 * 250, 1e-12);
  EXPECT_EQ(push.value[0].Evaluate(in), 0);
}

TEST(FreeDyn, BodyFixedTorqueInBodyOneAxes) {
  const Model m = LoadFreeDynModel(kModels + "two_bodies.fds");
  const Force& motor = m.forces[2];
  EXPECT_EQ(motor.type, ForceType::kTorque);
  EXPECT_EQ(motor.frame, ForceFrame::kI);
  // World y at t = 0 is the slider's -z axis; marker i has the body's axes.
  EXPECT_EQ(m.markers[motor.i].name, "slider_block.cm");
  EXPECT_EQ(motor.value[0].text(), "0");
  EXPECT_EQ(motor.value[1].text(), "0");
  EXPECT_EQ(motor.value[2].text(), "-(l0*sin(t))");
}

TEST(FreeDyn, RotationalMeasure) {
  const Model m = LoadFreeDynModel(kModels + "two_bodies.fds");
  const int k = m.find_measure("arm_angle");  // "arm angle" -> arm_angle
  ASSERT_GE(k, 0);
  const Measure& r = m.measures[k];
  EXPECT_EQ(r.type, MeasureType::kRotational);
  EXPECT_EQ(r.quantity, Quantity::kVelocity);
  EXPECT_EQ(r.component, Component::kZ);
  EXPECT_EQ(r.j, 0);
  // Marker i: world axes at t = 0 on the arm.
  ExpectNear(Mat3(RotationMatrix(m.bodies[0].orientation) * m.markers[r.i].orientation), Mat3::Identity(), 1e-15, "axes");
}

TEST(FreeDyn, SolverStepIsAtMostTheOutputStep) {
  const Model m = LoadFreeDynModel(kModels + "two_bodies.fds");
  EXPECT_EQ(m.simulation.hht_step, 5e-3);  // SolverMaxTimeStep 1e-2 > output step 5e-3
  EXPECT_EQ(m.simulation.hht_alpha, -0.2);
  EXPECT_FALSE(m.simulation.hht_modified);
  EXPECT_EQ(m.simulation.t_end, 0.5);
}

TEST(FreeDyn, ExtensionDispatch) {
  EXPECT_TRUE(IsFreeDynPath("a/b.fds"));
  EXPECT_TRUE(IsFreeDynPath("B.FDS"));
  EXPECT_FALSE(IsFreeDynPath("b.fds.yaml"));
  EXPECT_FALSE(IsFreeDynPath("fds"));
  EXPECT_EQ(LoadAnyModel(kSource + "/examples/freedyn/oscillator.fds").bodies.size(), 1u);
  EXPECT_EQ(LoadAnyModel(kSource + "/examples/pendulum.yaml").bodies.size(), 1u);
}

// ---- mistakes ------------------------------------------------------------------------------------

const char* kBody =
    "Body Rigid_EulerParameter_PAI\n"
    "  ID = b1\n"
    "  Name = m\n"
    "  Mass = 1\n"
    "  LocationCenterMass = 0,0,0\n"
    "  Inertia = 1,1,1\n"
    "EndBody\n";

TEST(FreeDynErrors, EveryMistakeNamesFileLineColumnAndElement) {
  const std::string body = kBody;
  const std::string f = kModels + "m.fds";
  struct Case {
    std::string text, expected;
  } cases[] = {
      {"Header x\nEndHeader\n%\nContact Hertz\nEndContact\n", f + ":4:1: model: unknown block 'Contact Hertz'"},
      {"Body FFRF_Flexible\n  ID = 3\nEndBody\n", f + ":1:1: Body FFRF_Flexible: block type 'Body FFRF_Flexible' is not read"},
      {"Constraint Motion\nEndConstraint\n", f + ":1:1: Constraint Motion: block type 'Constraint Motion' is not read"},
      {body + "%\nBody Rigid_EulerParameter_PAI\n  Name = n\n\tColour = 1\nEndBody\n",
       f + ":11:2: Body 'n': unknown key 'Colour' in a 'Body Rigid_EulerParameter_PAI' block"},
      {"Body Rigid_EulerParameter_PAI\n  ID = 1\n  ID = 2\nEndBody\n", f + ":3:3: Body Rigid_EulerParameter_PAI: key 'ID' is given twice"},
      {"Body Rigid_EulerParameter_PAI\n  ID = 1\n  Name = q\n  Mass = 1\n  Inertia = 1,1,1\nEndBody\n",
       f + ":1:1: Body 'q': missing required key 'LocationCenterMass'"},
      {body + "%\nDataObject Parameter\n  Name = p\n", f + ":9:1: DataObject 'p': the block is not closed: 'EndDataObject' is missing"},
      {"DataObject Parameter\n  Name = p\n  InitialValue = 1\nEndBody\n", f + ":4:1: DataObject 'p': expected 'EndDataObject' to close the block opened at line 1"},
      {"EndBody\n", f + ":1:1: model: 'EndBody' closes no block"},
      {"DataObject Parameter\n  Name = p\n  just text\nEndDataObject\n", f + ":3:3: DataObject 'p': expected 'Key = value'"},
      {"DataObject Parameter\n  Name = p\n  InitialValue = 1.5x\nEndDataObject\n",
       f + ":3:18: DataObject 'p': 'InitialValue': expected a number, got '1.5x'"},
      {body + "Body Rigid_EulerParameter_PAI\n  ID = b2\n  Mass = -1\n  LocationCenterMass = 0,0,0\n  Inertia = 1,1,1\nEndBody\n",
       f + ":10:10: Body Rigid_EulerParameter_PAI: 'Mass': mass must be >= 0, got -1"},
      {"Body Rigid_EulerParameter_PAI\n  ID = 1\n  Mass = 1\n  LocationCenterMass = 0,0\n  Inertia = 1,1,1\nEndBody\n",
       f + ":4:24: Body Rigid_EulerParameter_PAI: 'LocationCenterMass': expected 3 numbers separated by commas, got 2"},
      {"Body Rigid_EulerParameter_PAI\n  ID = 1\n  Mass = 1\n  LocationCenterMass = 0,0,0\n  Inertia = 1,1,1\n"
       "  OrientationPAI = 1,0,0,0,1,0,0,0,2\nEndBody\n",
       f + ":6:20: Body Rigid_EulerParameter_PAI: 'OrientationPAI': the 9 numbers are not an orthonormal matrix"},
      {body + "Constraint Generic\n  Name = c\n  BodyIDs = b1, b9\n  dxFixed = yes\n  Location = 0,0,0\nEndConstraint\n",
       f + ":10:13: Constraint 'c': 'BodyIDs': no body has the ID 'b9' (0 is ground)"},
      {body + "Constraint Generic\n  Name = c\n  BodyIDs = b1, 0\n  Location = 0,0,0\nEndConstraint\n",
       f + ":8:1: Constraint 'c': the constraint fixes nothing"},
      {body + "Constraint Generic\n  Name = c\n  BodyIDs = b1, 0\n  dxFixed = maybe\n  Location = 0,0,0\nEndConstraint\n",
       f + ":11:13: Constraint 'c': 'dxFixed': expected yes or no, got 'maybe'"},
      {body + "Force GenericForce\n  Name = f\n  BodyIDs = b1, 0\n  PointOfApplication_Body1 = 0,0,0\n"
              "  PointOfApplication_Body2 = 0,0,0\n  ForceDirectionType = Follower\n  ForceDirection = 1,0,0\n"
              "  ForceExpression = 1\nEndForce\n",
       f + ":13:24: Force 'f': 'ForceDirectionType': unknown force direction type 'Follower'"},
      {body + "Force GenericForce\n  Name = f\n  BodyIDs = b1, 0\n  PointOfApplication_Body1 = 0,0,0\n"
              "  PointOfApplication_Body2 = 0,0,0\n  ForceDirectionType = SpaceFixed\n  ForceDirection = 1,0,0\n"
              "  ForceExpression = 2*PARVAL[kk]\nEndForce\n",
       f + ":15:23: Force 'f': 'ForceExpression': unknown parameter 'kk' in PARVAL[]"},
      {body + "Force GenericForce\n  Name = f\n  BodyIDs = b1, 0\n  PointOfApplication_Body1 = 0,0,0\n"
              "  PointOfApplication_Body2 = 0,0,0\n  ForceDirectionType = SpaceFixed\n  ForceDirection = 1,0,0\n"
              "  ForceExpression = 2*q\nEndForce\n",
       f + ":15:21: Force 'f': 'ForceExpression': in expression '2*q' (translated from '2*q'): unknown name 'q'"},
      {"Force Gravity\n  GravityAccVector = 0,0,-9.81\n  ActivationTime = 1\nEndForce\n",
       f + ":3:20: Force Gravity: 'ActivationTime': gravity switched on at a later time is not available here"},
      {"DataObject Spline_1D\n  Name = s\n  InterpolationType = zccspl\n  PathToSplineData = drive.txt\nEndDataObject\n",
       f + ":3:23: DataObject 's': 'InterpolationType': interpolation 'zccspl'"},
      {"DataObject Spline_1D\n  Name = s\n  PathToSplineData = none.txt\nEndDataObject\n",
       f + ":3:22: DataObject 's': 'PathToSplineData': data file '"},
      {"Simulation Dynamic\n  SimulationTimeBegin = 1\nEndSimulation\n",
       f + ":2:25: Simulation Dynamic: 'SimulationTimeBegin': a start time other than 0 is not available here"},
      {"Solver HHT\n  Alpha = -0.5\nEndSolver\n", f + ":2:11: Solver HHT: 'Alpha': alpha must be in [-1/3, 0], got -0.5"},
      {body + "Measure Translational\n  Name = x\n  BodyIDs = b1, 0\n  MeasureMode = jerk\n  MeasureCoordinate = X\n"
              "  MeasureLocation_Body1 = 0,0,0\n  MeasureLocation_Body2 = 0,0,0\nEndMeasure\n",
       f + ":11:17: Measure 'x': 'MeasureMode': unknown measure mode 'jerk' (known: disp, vel, acc)"},
  };
  for (const Case& c : cases) {
    const std::string m = Message(c.text);
    EXPECT_EQ(m.substr(0, c.expected.size()), c.expected) << "got: " << m;
  }
}

TEST(FreeDynErrors, GuiOnlyKeysAreAcceptedAndIgnored) {
  const std::string text = std::string(kBody).insert(std::string(kBody).find("EndBody"),
                                                      "  Geometry = Sphere 0.1\n  Geometry Color = 1,2,3,4\n") +
                           "Globals Settings\n  Anything = at all\nEndGlobals\n"
                           "Simulation Dynamic\n  WriteStateResultFile = yes\nEndSimulation\n";
  const Model m = LoadFreeDynModelFromString(text, "g.fds");
  EXPECT_EQ(m.bodies.size(), 1u);
  EXPECT_FALSE(IgnoredFreeDynKeys().empty());
}

TEST(FreeDynErrors, MissingFile) {
  try {
    LoadFreeDynModel(kModels + "does_not_exist.fds");
    ADD_FAILURE();
  } catch (const ModelError& e) {
    EXPECT_NE(std::string(e.what()).find("cannot open the file"), std::string::npos) << e.what();
  }
}

// ---- the writer: round trips ----------------------------------------------------------------------

// YAML model -> write -> load gives the same model, and writing again the same text.
void YamlRoundTrip(const std::string& path) {
  SCOPED_TRACE(path);
  const Model a = LoadModel(path);
  const std::string text = WriteModelYaml(a);
  // Relative data files are not written (splines are inline): the text stands alone.
  const std::string copy = path + ".roundtrip.yaml";
  Model b;
  try {
    b = LoadModelFromString(text, path);
  } catch (const ModelError& e) {
    FAIL() << e.what() << "\n" << text;
  }
  b.file = a.file;
  ExpectSameModel(a, b);
  EXPECT_EQ(WriteModelYaml(b), text);
}

TEST(ModelWriter, RoundTripOfTheRepositoryModels) {
  std::vector<std::string> paths = {kSource + "/tests/mbs/models/every_key.yaml",
                                    kSource + "/tests/mbs/models/splines.yaml",
                                    kSource + "/tests/mbs/models/mesh_body.yaml"};
  for (const char* dir : {"/examples", "/examples/freedyn", "/verification/pendulum", "/verification/free_body",
                          "/verification/bricard", "/verification/andrews", "/verification/malformed"}) {
    for (const auto& entry : std::filesystem::directory_iterator(kSource + dir)) {
      const std::string p = entry.path().string();
      if (entry.path().extension() != ".yaml") continue;
      if (std::string(dir) == "/verification/malformed") {
        if (entry.path().filename() != "correct_base.yaml") continue;  // the others are meant to fail
      }
      paths.push_back(p);
    }
  }
  int loaded = 0;
  for (const std::string& p : paths) {
    try {
      LoadModel(p);
    } catch (const ModelError& e) {
      // A model using elements this build's loader does not read yet is not a writer case.
      continue;
    }
    ++loaded;
    YamlRoundTrip(p);
  }
  EXPECT_GE(loaded, 7);
}

TEST(ModelWriter, SixEntryInertiaAndMarkerOrientations) {
  const Model a = LoadModelFromString(
      "format: 1\nname: \"a \\\"quoted\\\" name\"\ngravity: [0, 0, -9.81]\n"
      "parameters: {L: 2, h: \"L/2\"}\n"
      "splines: {s: {x: [0, L], y: [1, h], interpolation: cubic}}\n"
      "ground: {markers: {P: {position: [1, 2, 3], orientation: {axis: [1, 1, 0], angle: 0.3}}}}\n"
      "bodies:\n"
      "  - {name: b, mass: 1, inertia: [2, 3, 4, 0.1, -0.2, 0.3], position: [0, 1, 0],\n"
      "     orientation: {axis: [0, 0, 1], angle: 1}, velocity: [1, 0, 0], angular_velocity: [0, 0, 2],\n"
      "     markers: {A: {position: [h, 0, 0], orientation: {axis: [0, 1, 0], angle: -2}}}}\n"
      "joints: [{name: j, type: revolute, i: b.A, j: ground.P}]\n"
      "forces: [{name: s, type: spring_damper, i: b.cm, j: ground.P, stiffness: \"10*L\", free_length: h}]\n"
      "simulation: {t_end: 2, integrator: ida, ida: {rtol: 1e-9, atol: 1e-11}}\n",
      "w.yaml");
  const std::string text = WriteModelYaml(a);
  EXPECT_NE(text.find("inertia: [2, 3, 4, 0.1, -0.2, 0.3]"), std::string::npos) << text;
  EXPECT_NE(text.find("h: \"L/2\""), std::string::npos) << text;
  EXPECT_NE(text.find("x: [0, \"L\"]"), std::string::npos) << text;
  const Model b = LoadModelFromString(text, "w.yaml");
  ExpectSameModel(a, b);
}

TEST(ModelWriter, FreeDynToYamlGivesTheSameModel) {
  if (!LoaderReadsStateForces()) GTEST_SKIP() << "the YAML loader does not read forces over measures and t yet";
  for (const std::string path : {kSource + "/examples/freedyn/oscillator.fds", kModels + "two_bodies.fds"}) {
    SCOPED_TRACE(path);
    const Model a = LoadFreeDynModel(path);
    const std::string text = WriteModelYaml(a);
    Model b;
    try {
      b = LoadModelFromString(text, path);
    } catch (const ModelError& e) {
      FAIL() << e.what() << "\n" << text;
    }
    ExpectSameModel(a, b);
  }
}

TEST(ModelWriter, WriteFileFailsWithThePath) {
  const Model a = LoadFreeDynModel(kSource + "/examples/freedyn/oscillator.fds");
  try {
    WriteModelFile(a, kModels + "no_such_dir/x.yaml");
    ADD_FAILURE();
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("no_such_dir/x.yaml: cannot create the file"), std::string::npos);
  }
}

// ---- the program's command line --------------------------------------------------------------------

TEST(FreeDynCommandLine, ConvertAndResultsPath) {
  const app::CommandLine cl = app::ParseCommandLine({"convert", "m.fds", "-o", "m.yaml", "--set", "k=2"});
  EXPECT_EQ(cl.command, app::Command::kConvert);
  EXPECT_EQ(cl.model_path, "m.fds");
  EXPECT_EQ(cl.output_path, "m.yaml");
  EXPECT_EQ(cl.parameter_overrides.at("k"), 2);
  EXPECT_EQ(app::ParseCommandLine({"convert", "m.fds"}).output_path, "");
  EXPECT_THROW(app::ParseCommandLine({"convert", "m.fds", "--t-end", "1"}), app::UsageError);
  EXPECT_THROW(app::ParseCommandLine({"check", "m.fds", "-o", "x"}), app::UsageError);
  EXPECT_EQ(app::DefaultResultsPath("dir/model.fds"), "dir/model.h5");
  EXPECT_EQ(app::DefaultResultsPath("MODEL.FDS"), "MODEL.h5");
}

}  // namespace
}  // namespace mbdae::mbs
