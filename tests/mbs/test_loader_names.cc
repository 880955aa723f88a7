// Names the loader looks up through its indices (joints, forces, the joints of reaction
// measures): duplicates refused where they are written, every name found at its index,
// also after `extends:` and on a long chain.
#include <gtest/gtest.h>

#include <fstream>
#include <string>

#include "mbs/loader.h"
#include "tests/support/load_error.h"

namespace mbdae::mbs {
namespace {

using testing::LoadError;

// A chain of n bodies b1..bn joined by spherical joints j1..jn (j1 to the ground), a
// force f1..fn on every body and a reaction measure r1..rn of every joint.
std::string Chain(int n) {
  std::string s = "format: 1\nbodies:\n";
  for (int k = 1; k <= n; ++k)
    s += "  - {name: b" + std::to_string(k) + ", mass: 1, inertia: [1, 1, 1], position: [" + std::to_string(k) +
         ", 0, 0], markers: {A: {position: [-0.5, 0, 0]}, B: {position: [0.5, 0, 0]}}}\n";
  s += "measures:\n";
  for (int k = 1; k <= n; ++k)
    s += "  - {name: r" + std::to_string(k) + ", type: reaction, joint: j" + std::to_string(k) +
         ", component: x, frame: world}\n";
  s += "joints:\n";
  for (int k = 1; k <= n; ++k)
    s += "  - {name: j" + std::to_string(k) + ", type: spherical, i: b" + std::to_string(k) + ".A, j: " +
         (k == 1 ? std::string("ground.O") : "b" + std::to_string(k - 1) + ".B") + "}\n";
  s += "forces:\n";
  for (int k = 1; k <= n; ++k)
    s += "  - {name: f" + std::to_string(k) + ", type: force, i: b" + std::to_string(k) + ".cm, value: [0, 1, 0]}\n";
  return s;
}

TEST(LoaderNames, ChainResolvesEveryName) {
  const int n = 300;
  const Model m = LoadModelFromString(Chain(n), "m.yaml");
  ASSERT_EQ(static_cast<int>(m.joints.size()), n);
  ASSERT_EQ(static_cast<int>(m.forces.size()), n);
  ASSERT_EQ(static_cast<int>(m.measures.size()), n);
  for (int k = 0; k < n; ++k) {
    EXPECT_EQ(m.joints[k].name, "j" + std::to_string(k + 1));
    EXPECT_EQ(m.forces[k].name, "f" + std::to_string(k + 1));
    // The reaction measure r(k+1) names joint j(k+1), the k-th, with its markers.
    EXPECT_EQ(m.measures[k].joint, k) << m.measures[k].name;
    EXPECT_EQ(m.measures[k].i, m.joints[k].i);
    EXPECT_EQ(m.measures[k].j, m.joints[k].j);
  }
}

TEST(LoaderNames, DuplicatesAreRefusedWhereWritten) {
  // The last joint repeats the name of the first, the last force that of the seventh.
  const int n = 50;
  std::string dup_joint = Chain(n);
  const std::string last_joint = "  - {name: j" + std::to_string(n) + ", type: spherical";
  const size_t at = dup_joint.find(last_joint);
  ASSERT_NE(at, std::string::npos);
  dup_joint.replace(at, last_joint.size(), "  - {name: j1, type: spherical");
  // Lines of Chain(n): bodies 3 .. n + 2, measures n + 4 .. 2n + 3, joints 2n + 5 .. 3n + 4,
  // forces 3n + 6 .. 4n + 5; the name's value starts in column 12.
  std::string e = LoadError(dup_joint);
  EXPECT_NE(e.find("m.yaml:" + std::to_string(3 * n + 4) + ":12: joint 'j1': duplicate joint name"), std::string::npos)
      << e;

  std::string dup_force = Chain(n);
  const std::string last_force = "  - {name: f" + std::to_string(n) + ", type: force";
  const size_t fat = dup_force.find(last_force);
  ASSERT_NE(fat, std::string::npos);
  dup_force.replace(fat, last_force.size(), "  - {name: f7, type: force");
  e = LoadError(dup_force);
  EXPECT_NE(e.find("m.yaml:" + std::to_string(4 * n + 5) + ":12: force 'f7': duplicate force name"), std::string::npos)
      << e;

  // A reaction measure of a joint that does not exist: the names offered.
  std::string unknown = Chain(3);
  unknown.replace(unknown.find("joint: j2,"), 10, "joint: j22,");
  e = LoadError(unknown);
  EXPECT_NE(e.find("measure 'r2': 'joint': unknown joint 'j22'; did you mean 'j2'? (joints: j1, j2, j3)"),
            std::string::npos)
      << e;
}

// The indices restart from the extended model: its joints and forces count as written.
TEST(LoaderNames, ExtendsKeepsTheBaseNames) {
  const std::string dir = ::testing::TempDir();
  std::ofstream(dir + "names_base.yaml") << Chain(4);
  const std::string head = "format: 1\nextends: names_base.yaml\n";
  const std::string body = "bodies:\n  - {name: c1, mass: 1, inertia: [1, 1, 1], markers: {A: {position: [0, 0, 0]}}}\n";
  const std::string file = dir + "names_extending.yaml";
  std::string e = LoadError(head + body + "joints:\n  - {name: j3, type: spherical, i: c1.A, j: b4.B}\n", file);
  EXPECT_NE(e.find("joint 'j3': duplicate joint name"), std::string::npos) << e;
  e = LoadError(head + body + "forces:\n  - {name: f2, type: force, i: c1.cm, value: [0, 1, 0]}\n", file);
  EXPECT_NE(e.find("force 'f2': duplicate force name"), std::string::npos) << e;
  const Model m = LoadModelFromString(
      head + body + "measures:\n  - {name: r9, type: reaction, joint: j5, component: y, frame: world}\n" +
          "joints:\n  - {name: j5, type: spherical, i: c1.A, j: b4.B}\n",
      file);
  ASSERT_EQ(m.joints.size(), 5u);
  EXPECT_EQ(m.joints[4].name, "j5");
  EXPECT_EQ(m.measures[m.find_measure("r9")].joint, 4);
  EXPECT_EQ(m.measures[m.find_measure("r2")].joint, 1);
}

}  // namespace
}  // namespace mbdae::mbs
