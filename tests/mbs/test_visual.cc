// Visual geometry (mbs/visual.h, `visual:` of the model file): the loader's shapes, keys
// and errors, the writer's round trip, FreeDyn's `Geometry = Box`, and the default
// drawing (inertia ellipsoid and rods to the markers) against hand-computed values.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <string>

#include "mbs/freedyn.h"
#include "mbs/kinematics.h"
#include "mbs/loader.h"
#include "mbs/model_writer.h"
#include "mbs/visual.h"

namespace mbdae::mbs {
namespace {

const std::string kModel = R"(format: 1
ground:
  visual: {shape: box, size: [2, 0.1, 0.1], position: [0, -0.5, 0], color: [0.2, 0.2, 0.2]}
bodies:
  - name: arm
    mass: 2
    inertia: [0.01, 0.2, 0.2]
    position: [0.5, 0, 0]
    markers: {A: {position: [-0.5, 0, 0]}}
    visual:
      - {shape: cylinder, radius: 0.02, length: 1, orientation: {axis: [0, 1, 0], angle: pi/2}, color: [1, 0, 0, 0.5]}
      - {shape: sphere, radius: 0.05, position: [0.5, 0, 0]}
      - {shape: capsule, radius: 0.01, length: 0.3}
      - {shape: cone, radius: 0.03, length: 0.1}
  - name: block
    geometry: {shape: box, size: [0.2, 0.1, 0.05], density: 1000}
  - name: rod
    mass: 3
    inertia: [0, 0.25, 0.25]
    markers: {tip: {position: [0.5, 0, 0]}, end: {position: [-0.5, 0, 0]}}
  - name: ball
    mass: 1
    inertia: [0.004, 0.004, 0.004]
)";

TEST(Visual, LoaderReadsShapesPosesAndColours) {
  const Model m = LoadModelFromString(kModel, "visual.yaml");
  ASSERT_EQ(m.ground_visuals.size(), 1u);
  EXPECT_EQ(m.ground_visuals[0].kind, VisualKind::kBox);
  EXPECT_EQ(m.ground_visuals[0].size, Vec3(2, 0.1, 0.1));
  EXPECT_EQ(m.ground_visuals[0].position, Vec3(0, -0.5, 0));
  EXPECT_DOUBLE_EQ(m.ground_visuals[0].color[3], 1.0);  // opacity defaults to 1
  const Body& arm = m.bodies[0];
  ASSERT_EQ(arm.visuals.size(), 4u);
  EXPECT_EQ(arm.visuals[0].kind, VisualKind::kCylinder);
  EXPECT_DOUBLE_EQ(arm.visuals[0].radius, 0.02);
  EXPECT_DOUBLE_EQ(arm.visuals[0].length, 1.0);
  // Shape z along the body x axis: rotation by 90 degrees about y.
  EXPECT_LE((arm.visuals[0].orientation * Vec3::UnitZ() - Vec3::UnitX()).norm(), 1e-15);
  EXPECT_DOUBLE_EQ(arm.visuals[0].color[3], 0.5);
  EXPECT_EQ(arm.visuals[1].kind, VisualKind::kSphere);
  EXPECT_EQ(arm.visuals[1].position, Vec3(0.5, 0, 0));
  EXPECT_EQ(arm.visuals[2].kind, VisualKind::kCapsule);
  EXPECT_EQ(arm.visuals[3].kind, VisualKind::kCone);
  // `geometry:` is drawn when there is no `visual:`, and still gives the mass.
  const Body& block = m.bodies[1];
  ASSERT_EQ(block.visuals.size(), 1u);
  EXPECT_EQ(block.visuals[0].kind, VisualKind::kBox);
  EXPECT_EQ(block.visuals[0].size, Vec3(0.2, 0.1, 0.05));
  EXPECT_NEAR(block.mass, 0.2 * 0.1 * 0.05 * 1000, 1e-12);
  EXPECT_TRUE(m.bodies[2].visuals.empty());
  // Drawing only: no parameter use is recorded for visual values.
  EXPECT_TRUE(m.load_time_values.empty());
}

TEST(Visual, WriterRoundTrip) {
  const Model a = LoadModelFromString(kModel, "visual.yaml");
  const Model b = LoadModelFromString(WriteModelYaml(a), "written.yaml");
  ASSERT_EQ(b.ground_visuals.size(), a.ground_visuals.size());
  for (size_t k = 0; k < a.bodies.size(); ++k) {
    ASSERT_EQ(a.bodies[k].visuals.size(), b.bodies[k].visuals.size()) << k;
    for (size_t s = 0; s < a.bodies[k].visuals.size(); ++s) {
      const VisualShape& x = a.bodies[k].visuals[s];
      const VisualShape& y = b.bodies[k].visuals[s];
      EXPECT_EQ(x.kind, y.kind);
      EXPECT_EQ(x.size, y.size);
      EXPECT_EQ(x.radius, y.radius);
      EXPECT_EQ(x.length, y.length);
      EXPECT_EQ(x.position, y.position);
      EXPECT_LE((x.orientation - y.orientation).cwiseAbs().maxCoeff(), 1e-15);
      EXPECT_EQ(x.color, y.color);
    }
  }
}

TEST(Visual, LoaderErrorsNameLineAndKey) {
  auto message = [](const std::string& visual) {
    try {
      LoadModelFromString("format: 1\nbodies:\n  - name: b\n    mass: 1\n    visual: " + visual + "\n", "bad.yaml");
    } catch (const std::exception& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  EXPECT_NE(message("{shape: box, size: [1, 0, 1]}").find("bad.yaml:5:"), std::string::npos);
  EXPECT_NE(message("{shape: box, size: [1, 0, 1]}").find("visual size must be > 0"), std::string::npos);
  EXPECT_NE(message("{shape: sphere, radius: 1, size: [1, 1, 1]}").find("unknown key 'size'"), std::string::npos);
  EXPECT_NE(message("{shape: torus, radius: 1}").find("torus"), std::string::npos);
  EXPECT_NE(message("{shape: sphere, radius: 1, color: [1, 2, 0]}").find("must be in [0, 1]"), std::string::npos);
  EXPECT_NE(message("{shape: cylinder, radius: 1}").find("missing required key 'length'"), std::string::npos);
  EXPECT_NE(message("{shape: mesh, file: nowhere.stl}").find("not found"), std::string::npos);
  EXPECT_NE(message("3").find("'visual' must be a shape"), std::string::npos);
}

TEST(Visual, DefaultDrawingIsInertiaEllipsoidAndRods) {
  const Model m = LoadModelFromString(kModel, "visual.yaml");
  const double L = ModelLengthScale(m);
  // Markers and centres of mass span x in [-0.5, 1] (rod.end at -0.5, arm.cm at 0.5 + ...,
  // the ground box at y = -0.5): the diagonal of that box.
  EXPECT_GT(L, 1.0);
  const std::vector<DrawnShape> rod = DefaultShapes(m, 2, L);
  ASSERT_EQ(rod.size(), 3u);  // ellipsoid + two rods
  EXPECT_EQ(rod[0].kind, "ellipsoid");
  // Homogeneous ellipsoid with I = diag(0, 0.25, 0.25), m = 3: a_k^2 = 5 (tr I - 2 I_k) / (2 m);
  // along x: 5 * 0.5 / 6 -> a = 0.6455, capped at half the farthest marker's distance
  // (0.25); across: 5 * 0 / 6 -> raised to min(L / 20, reach / 10). See-through.
  Vec3 semi = rod[0].size;
  std::sort(semi.data(), semi.data() + 3);
  EXPECT_NEAR(semi[2], 0.25, 1e-15);
  EXPECT_DOUBLE_EQ(rod[0].color[3], 0.35);
  EXPECT_NEAR(semi[0], std::min(L / 20, 0.05), 1e-12);  // at least min(L / 20, reach / 10)
  EXPECT_NEAR(semi[1], std::min(L / 20, 0.05), 1e-12);
  // The long semi-axis lies along body x.
  for (int k = 0; k < 3; ++k)
    if (rod[0].size[k] == semi[2]) EXPECT_NEAR(std::abs(rod[0].orientation.col(k).x()), 1.0, 1e-12);
  for (int r = 1; r <= 2; ++r) {
    EXPECT_EQ(rod[r].kind, "cylinder");
    EXPECT_NEAR(rod[r].size[1], 0.5, 1e-15);  // centre of mass to the marker
    EXPECT_NEAR(std::abs(rod[r].position.x()), 0.25, 1e-15);
    EXPECT_LE((rod[r].orientation * Vec3::UnitZ()).cross(Vec3::UnitX()).norm(), 1e-15);
    EXPECT_NEAR(rod[r].orientation.determinant(), 1.0, 1e-14);
  }
  // A homogeneous ball of radius 0.1 (I = 2/5 m r^2 = 0.004, no markers: no cap) is
  // drawn as itself: semi-axes sqrt(5 (0.012 - 0.008) / 2) = 0.1.
  const std::vector<DrawnShape> ball = DefaultShapes(m, 3, L);
  ASSERT_EQ(ball.size(), 1u);
  for (int k = 0; k < 3; ++k) EXPECT_NEAR(ball[0].size[k], 0.1, 1e-12);
  // A point mass (the pendulum's bob) is an opaque sphere of L / 20.
  Model point = LoadModelFromString("format: 1\nbodies:\n  - {name: bob, mass: 1, position: [1, 0, 0], markers: {p: {position: [-1, 0, 0]}}}\n", "p.yaml");
  const std::vector<DrawnShape> bob = DefaultShapes(point, 0, ModelLengthScale(point));
  EXPECT_DOUBLE_EQ(ModelLengthScale(point), 1.0);
  for (int k = 0; k < 3; ++k) EXPECT_DOUBLE_EQ(bob[0].size[k], 0.05);
  EXPECT_DOUBLE_EQ(bob[0].color[3], 1.0);
  // Every shape of the model: ground 1, arm 4, block 1 (geometry), rod 3 and ball 1 (default).
  EXPECT_EQ(DrawnShapes(m).size(), 10u);
}

TEST(Visual, FreeDynGeometryBox) {
  // A body at (1, 2, 0) turned by 90 degrees about z (rows: body x = world y, y = -world x);
  // the box 0.5 further along world y, with the world's axes.
  const std::string text = R"(Body Rigid_EulerParameter_PAI
	ID = 1
	Name = link
	Mass = 1
	LocationCenterMass = 1,2,0
	Inertia = 0.1,0.1,0.1
	OrientationPAI = 0,1,0,-1,0,0,0,0,1
	Geometry = Box 1.0 0.05 0.02
	Geometry Position = 1,2.5,0
	Geometry Orientation = 1,0,0,0,1,0,0,0,1
	Geometry Color = 255,0,51,255
	Geometry Transparency = 0
EndBody
)";
  const Model m = LoadFreeDynModelFromString(text, "link.fds");
  ASSERT_EQ(m.bodies[0].visuals.size(), 1u);
  const VisualShape& v = m.bodies[0].visuals[0];
  EXPECT_EQ(v.kind, VisualKind::kBox);
  EXPECT_EQ(v.size, Vec3(1.0, 0.05, 0.02));
  // World offset (0, 0.5, 0) is body x.
  EXPECT_LE((v.position - Vec3(0.5, 0, 0)).norm(), 1e-12);
  // Box axes = world axes: in body axes, box x = world x = -body y.
  EXPECT_LE((v.orientation * Vec3::UnitX() - Vec3(0, -1, 0)).norm(), 1e-12);
  EXPECT_DOUBLE_EQ(v.color[0], 1.0);
  EXPECT_DOUBLE_EQ(v.color[2], 0.2);
  // A malformed box is an error at its line.
  std::string bad = text;
  bad.replace(bad.find("Box 1.0 0.05 0.02"), 17, "Box 1.0 0.05");
  try {
    LoadFreeDynModelFromString(bad, "link.fds");
    ADD_FAILURE() << "no error";
  } catch (const std::exception& e) {
    EXPECT_NE(std::string(e.what()).find("link.fds:8:"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("three edge lengths"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace mbdae::mbs
