// Motion and gear joints and force values over t, measures and splines: loading,
// writing back, the system's equations at hand-computed states. (Their Jacobians against
// finite differences are in test_system.cc, DerivativesMatchFiniteDifferences.)
#include <gtest/gtest.h>

#include <cmath>
#include <string>

#include "mbs/loader.h"
#include "mbs/model_writer.h"
#include "mbs/system.h"

namespace mbdae::mbs {
namespace {

const char* kCrank =
    "format: 1\n"
    "gravity: [0, -9.81, 0]\n"
    "parameters: {w: 2, r: -2.5}\n"
    "splines: {lift: {x: [0, 1, 2], y: [0, 0.5, 0.25], interpolation: cubic}}\n"
    "bodies:\n"
    "  - {name: crank, mass: 2, inertia: [0.01, 0.02, 0.03], position: [0.3, 0, 0],\n"
    "     markers: {P: {position: [-0.3, 0, 0]}}}\n"
    "  - {name: wheel, mass: 1, inertia: [0.01, 0.01, 0.02], position: [1, 0, 0]}\n"
    "ground: {markers: {B: {position: [1, 0, 0]}}}\n"
    "measures:\n"
    "  - {name: phi, type: rotational, i: crank.P, j: ground.O, axis: z}\n"
    "  - {name: psi, type: rotational, i: wheel.cm, j: ground.B, axis: z}\n"
    "  - {name: y, type: translational, i: wheel.cm, j: ground.B, component: y}\n"
    "  - {name: yv, type: translational, i: wheel.cm, j: ground.B, component: y, quantity: velocity}\n"
    "joints:\n"
    "  - {name: hinge, type: revolute, i: crank.P, j: ground.O}\n"
    "  - {name: drive, type: motion, measure: phi, value: \"w*t + 0.1*sin(t) + spline(lift, t)\"}\n"
    "  - {name: mesh, type: gear, measures: [phi, psi], ratio: r}\n"
    "forces:\n"
    "  - {name: push, type: force, i: wheel.cm, frame: world, value: [0, \"-3*y - 0.5*yv + spline(lift, t)\", 0]}\n";

std::string LoadError(const std::string& text) {
  try {
    LoadModelFromString(text, "m.yaml");
  } catch (const ModelError& e) {
    return e.what();
  }
  return "";
}

TEST(MotionGear, LoadsAndWritesBack) {
  const Model m = LoadModelFromString(kCrank, "m.yaml");
  ASSERT_EQ(m.joints.size(), 3u);
  const Joint& drive = m.joints[1];
  EXPECT_EQ(drive.type, JointType::kMotion);
  EXPECT_EQ(drive.measures[0], m.find_measure("phi"));
  EXPECT_EQ(drive.value.text(), "w*t + 0.1*sin(t) + spline(lift, t)");
  EXPECT_TRUE(drive.value.uses_time());
  const Joint& mesh = m.joints[2];
  EXPECT_EQ(mesh.type, JointType::kGear);
  EXPECT_EQ(mesh.measures[0], m.find_measure("phi"));
  EXPECT_EQ(mesh.measures[1], m.find_measure("psi"));
  EXPECT_EQ(mesh.ratio, -2.5);
  EXPECT_TRUE(m.forces[0].value[1].depends_on_state());

  const Model b = LoadModelFromString(WriteModelYaml(m), "w.yaml");
  ASSERT_EQ(b.joints.size(), 3u);
  EXPECT_EQ(b.joints[1].type, JointType::kMotion);
  EXPECT_EQ(b.joints[1].measures[0], drive.measures[0]);
  EXPECT_EQ(b.joints[1].value.text(), drive.value.text());
  EXPECT_EQ(b.joints[2].type, JointType::kGear);
  EXPECT_EQ(b.joints[2].measures, mesh.measures);
  EXPECT_EQ(b.joints[2].ratio, -2.5);
  EXPECT_EQ(b.forces[0].value[1].text(), m.forces[0].value[1].text());
}

TEST(MotionGear, LoaderErrors) {
  const std::string base(kCrank, std::string(kCrank).find("joints:"));
  auto joints = [&](const std::string& j) { return LoadError(base + "joints:\n" + j); };
  std::string e = joints("  - {name: d, type: motion, measure: yv, value: t}\n");
  EXPECT_NE(e.find("joint 'd': 'measure': measure 'yv' is a velocity; a motion constrains position-level measures only"),
            std::string::npos) << e;
  e = joints("  - {name: d, type: motion, measure: phi, value: \"y + t\"}\n");
  EXPECT_NE(e.find("joint 'd': 'value': in expression 'y + t': measure 'y' at column 1 cannot be used here"),
            std::string::npos) << e;
  e = joints("  - {name: d, type: motion, measure: phi, i: crank.P, value: t}\n");
  EXPECT_NE(e.find("a motion joint acts on measures, it has no 'i'"), std::string::npos) << e;
  e = joints("  - {name: g, type: gear, measures: [phi, y], ratio: 2}\n");
  EXPECT_NE(e.find("joint 'g': 'measures': measure 'y' is translational"), std::string::npos) << e;
  e = joints("  - {name: g, type: gear, measures: [phi], ratio: 2}\n");
  EXPECT_NE(e.find("'measures' must be a list of 2 rotational angle measures, got 1 entries"), std::string::npos) << e;
  e = joints("  - {name: g, type: gear, measures: [phi, psi]}\n");
  EXPECT_NE(e.find("missing required key 'ratio'"), std::string::npos) << e;
}

// The equations at a state computed by hand: crank at angle a, wheel at angle b, wheel
// centre displaced by y0 along y (only the motion, gear and force rows are checked).
TEST(MotionGear, EquationsAtAHandState) {
  const Model m = LoadModelFromString(kCrank, "m.yaml");
  MultibodySystem sys(m);
  const auto& names = sys.constraint_names();
  int row_drive = -1, row_mesh = -1;
  for (size_t k = 0; k < names.size(); ++k) {
    if (names[k] == "drive.motion") row_drive = static_cast<int>(k);
    if (names[k] == "mesh.gear") row_mesh = static_cast<int>(k);
  }
  ASSERT_GE(row_drive, 0);
  ASSERT_GE(row_mesh, 0);
  std::vector<double> q, v;
  sys.InitialState(q, v);
  const double a = 0.7, b = -0.4, y0 = 0.05, t = 0.8;
  q[3] = std::cos(a / 2); q[6] = std::sin(a / 2);
  q[7 + 3] = std::cos(b / 2); q[7 + 6] = std::sin(b / 2);
  q[7 + 1] = y0;
  v[7 + 1] = 0.2;  // wheel centre velocity along y
  const int nq = sys.num_coordinates(), nc = sys.num_constraints();
  std::vector<double> c(nc), ct(nc), force(nq);
  dae::EvalInput in;
  in.t = t; in.q = q.data(); in.v = v.data();
  dae::EvalOutput out;
  out.constraint = c.data(); out.constraint_dt = ct.data(); out.force = force.data();
  ASSERT_EQ(sys.Evaluate(in, out), 0);
  const Spline& lift = m.splines[0].spline;
  double s1 = 0, s2 = 0;
  const double s0 = lift.Evaluate(t, &s1, &s2);
  EXPECT_NEAR(c[row_drive], std::remainder(a - (2 * t + 0.1 * std::sin(t) + s0), 2 * M_PI), 1e-14);
  EXPECT_NEAR(ct[row_drive], -(2 + 0.1 * std::cos(t) + s1), 1e-14);
  // gear: initial angles are 0 for both
  EXPECT_NEAR(c[row_mesh], b - (-2.5) * a, 1e-14);
  EXPECT_EQ(ct[row_mesh], 0.0);
  // the force on the wheel centre along y, gravity included
  EXPECT_NEAR(force[7 + 1], -3 * y0 - 0.5 * 0.2 + s0 - 9.81 * 1.0, 1e-13);
}

}  // namespace
}  // namespace mbdae::mbs
