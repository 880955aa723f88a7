// Reaction measures (mbs/reaction.h) and objectives in the model file (loader, writer).
#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <string>
#include <vector>

#include "driver/simulation.h"
#include "mbs/loader.h"
#include "mbs/model_writer.h"
#include "mbs/reaction.h"
#include "mbs/system.h"

namespace mbdae::mbs {
namespace {

// Every component of a reaction in both frames, for joint `joint`.
std::string ReactionMeasures6(const std::string& joint) {
  std::string s;
  for (const char* f : {"j", "world"})
    for (const char* c : {"x", "y", "z", "rx", "ry", "rz"})
      s += "  - {name: " + joint + "_" + c + "_" + f + ", type: reaction, joint: " + joint +
           ", component: " + c + ", frame: " + f + "}\n";
  return s;
}

// Two bodies: a link hinged to ground (marker i on ground, so the ground branch is
// used) and a second body on a spherical joint with rotated markers.
const std::string kTwoBodies = R"(format: 1
gravity: [0, -9.81, 0]
bodies:
  - name: a
    mass: 2
    inertia: [0.1, 0.2, 0.3]
    position: [0.5, 0, 0]
    markers:
      p: {position: [-0.5, 0, 0], orientation: {axis: [1, 1, 0], angle: 0.4}}
      q: {position: [0.5, 0, 0], orientation: {axis: [0, 0.2, 1], angle: 0.7}}
  - name: b
    mass: 1
    inertia: [0.05, 0.06, 0.07]
    position: [1.3, 0.1, 0]
    orientation: {axis: [0, 0, 1], angle: 0.3}
    markers:
      s: {position: [-0.3, -0.1, 0.05], orientation: {axis: [1, 0, 0.3], angle: 1.1}}
ground:
  markers:
    h: {position: [0, 0, 0], orientation: {axis: [1, 1, 0], angle: 0.4}}
measures:
)" + ReactionMeasures6("hinge") + ReactionMeasures6("ball") + R"(joints:
  - {name: hinge, type: revolute, i: ground.h, j: a.p}
  - {name: ball, type: spherical, i: b.s, j: a.q}
)";

// A rotor driven by a motion joint about z (angle 0.5 alpha t^2), and a pendulum.
const std::string kMotion = R"(format: 1
gravity: [0, -9.81, 0]
parameters: {alpha: 3.0}
bodies:
  - name: rotor
    mass: 2
    inertia: [0.2, 0.2, 0.4]
    markers:
      o: {position: [0, 0, 0]}
measures:
  - {name: angle, type: rotational, i: rotor.o, j: ground.O, axis: z}
  - {name: drive, type: reaction, joint: spin, component: rz, frame: world}
  - {name: drive_j, type: reaction, joint: spin, component: rz, frame: j}
  - {name: hold_y, type: reaction, joint: axle, component: y, frame: world}
joints:
  - {name: axle, type: revolute, i: rotor.o, j: ground.O}
  - {name: spin, type: motion, measure: angle, value: "0.5*alpha*t^2"}
)";

void RandomState(const Model& model, std::mt19937& rng, std::vector<double>* q, std::vector<double>* lambda,
                 int nc) {
  std::uniform_real_distribution<double> u(-1, 1);
  q->assign(model.num_coordinates(), 0.0);
  for (double& x : *q) x = u(rng);
  for (size_t b = 0; b < model.bodies.size(); ++b) (*q)[7 * b + 3] += 1.5;  // away from e = 0
  lambda->assign(nc, 0.0);
  for (double& x : *lambda) x = 10 * u(rng);
}

TEST(ReactionMeasure, AgreesWithJointReactionForOrdinaryJoints) {
  const Model model = LoadModelFromString(kTwoBodies, "two.yaml");
  MultibodySystem sys(model);
  ReactionMeasures r(model);
  ASSERT_EQ(r.measures().size(), 24u);
  std::mt19937 rng(7);
  std::vector<double> q, lambda;
  for (int trial = 0; trial < 3; ++trial) {
    RandomState(model, rng, &q, &lambda, sys.num_constraints());
    std::vector<double> values(model.measures.size(), -1.0);
    ASSERT_EQ(r.Evaluate(0.0, q.data(), lambda.data(), values.data()), 0);
    for (int j = 0; j < 2; ++j) {
      double f[3], n[3];
      sys.JointReaction(j, 0.0, q.data(), lambda.data(), f, n);
      const std::string name = model.joints[j].name;
      for (int c = 0; c < 3; ++c) {
        const char* axis[] = {"x", "y", "z"};
        EXPECT_NEAR(values[model.find_measure(name + "_" + axis[c] + "_world")], f[c], 1e-12);
        EXPECT_NEAR(values[model.find_measure(name + "_r" + axis[c] + "_world")], n[c], 1e-12);
      }
      // frame j: the same vectors along marker j's axes.
      const Marker& mj = model.markers[model.joints[j].j];
      const int o = 7 * mj.body;
      const Quat e(q[o + 3], q[o + 4], q[o + 5], q[o + 6]);
      const double e0 = e[0], e1 = e[1], e2 = e[2], e3 = e[3];
      Mat3 A;
      A << e0 * e0 + e1 * e1 - e2 * e2 - e3 * e3, 2 * (e1 * e2 - e0 * e3), 2 * (e1 * e3 + e0 * e2),
          2 * (e1 * e2 + e0 * e3), e0 * e0 - e1 * e1 + e2 * e2 - e3 * e3, 2 * (e2 * e3 - e0 * e1),
          2 * (e1 * e3 - e0 * e2), 2 * (e2 * e3 + e0 * e1), e0 * e0 - e1 * e1 - e2 * e2 + e3 * e3;
      const Mat3 R = A * mj.orientation;
      const Vec3 fj = R.transpose() * Vec3(f[0], f[1], f[2]);
      const Vec3 nj = R.transpose() * Vec3(n[0], n[1], n[2]);
      for (int c = 0; c < 3; ++c) {
        const char* axis[] = {"x", "y", "z"};
        EXPECT_NEAR(values[model.find_measure(name + "_" + axis[c] + "_j")], fj[c], 1e-12);
        EXPECT_NEAR(values[model.find_measure(name + "_r" + axis[c] + "_j")], nj[c], 1e-12);
      }
    }
  }
}

// Every derivative against central differences: lambda enters linearly (exact to
// round-off); the q-derivative is exact, checked to 1e-7 relative (step 1e-6).
void CheckDerivatives(const std::string& yaml) {
  const Model model = LoadModelFromString(yaml, "m.yaml");
  ReactionMeasures r(model);
  const int nq = r.num_coordinates(), nc = r.num_constraints();
  std::mt19937 rng(11);
  std::vector<double> q, lambda;
  RandomState(model, rng, &q, &lambda, nc);
  for (int m : r.measures()) {
    SCOPED_TRACE(model.measures[m].name);
    double value = 0, again = 0;
    std::vector<double> dq(nq, 0.0), dl(nc, 0.0);
    ASSERT_EQ(r.Derivatives(m, 0.3, q.data(), lambda.data(), 1.0, &value, dq.data(), dl.data()), 0);
    // A second call gives the same (no state left over), and weights scale.
    std::vector<double> dq2(nq, 0.0), dl2(nc, 0.0);
    ASSERT_EQ(r.Derivatives(m, 0.3, q.data(), lambda.data(), 2.0, &again, dq2.data(), dl2.data()), 0);
    EXPECT_EQ(value, again);
    double scale = 1e-3;
    for (double x : dq) scale = std::max(scale, std::abs(x));
    for (int k = 0; k < nq; ++k) {
      EXPECT_NEAR(dq2[k], 2 * dq[k], 1e-12 * scale);
      const double h = 1e-6;
      std::vector<double> qp = q, qm = q;
      qp[k] += h;
      qm[k] -= h;
      double vp, vm;
      r.Derivatives(m, 0.3, qp.data(), lambda.data(), 1.0, &vp, nullptr, nullptr);
      r.Derivatives(m, 0.3, qm.data(), lambda.data(), 1.0, &vm, nullptr, nullptr);
      EXPECT_NEAR(dq[k], (vp - vm) / (2 * h), 1e-7 * scale) << "q " << k;
    }
    for (int k = 0; k < nc; ++k) {
      std::vector<double> lp = lambda;
      lp[k] += 1.0;
      double vp;
      r.Derivatives(m, 0.3, q.data(), lp.data(), 1.0, &vp, nullptr, nullptr);
      EXPECT_NEAR(dl[k], vp - value, 1e-10 * (1 + std::abs(value))) << "lambda " << k;
    }
  }
}

TEST(ReactionMeasure, DerivativesMatchCentralDifferencesTwoBodies) { CheckDerivatives(kTwoBodies); }
TEST(ReactionMeasure, DerivativesMatchCentralDifferencesMotion) { CheckDerivatives(kMotion); }

// The drive torque of a rotor with angle 0.5 alpha t^2 about z: Izz alpha (world and j
// frame agree, j is ground.O); the axle carries the weight m g upwards.
TEST(ReactionMeasure, MotionDriveTorqueIsInertiaTimesAngularAcceleration) {
  const Model model = LoadModelFromString(kMotion, "m.yaml");
  driver::Assembly a = driver::Assemble(model);
  std::vector<double> lambda(a.system->num_constraints(), 0.0);
  for (size_t k = 0; k < a.kept.size(); ++k) lambda[a.kept[k]] = a.x0.lambda[k];
  ReactionMeasures r(model);
  std::vector<double> values(model.measures.size(), 0.0);
  ASSERT_EQ(r.Evaluate(0.0, a.x0.q.data(), lambda.data(), values.data()), 0);
  EXPECT_NEAR(values[1], 0.4 * 3.0, 1e-9);
  EXPECT_NEAR(values[2], 0.4 * 3.0, 1e-9);
  EXPECT_NEAR(values[3], 2 * 9.81, 1e-9);
  // EvaluateMeasures leaves reactions at 0 and still evaluates the others.
  std::vector<double> raw(model.measures.size(), 5.0);
  a.system->EvaluateMeasures(0.0, a.x0.q.data(), a.x0.v.data(), a.x0.a.data(), raw.data());
  EXPECT_EQ(raw[1], 0.0);
  EXPECT_NEAR(raw[0], 0.0, 1e-12);
}

std::string LoadError(const std::string& yaml) {
  try {
    LoadModelFromString(yaml, "bad.yaml");
  } catch (const ModelError& e) {
    return e.what();
  }
  return "";
}

TEST(ReactionMeasure, LoaderRefusesReactionsInForcesMotionsAndUnknownJoints) {
  const std::string base = kMotion;
  const std::string force = base + "forces:\n  - {name: f, type: torque, i: rotor.o, value: [0, 0, \"-drive\"]}\n";
  const std::string e1 = LoadError(force);
  EXPECT_NE(e1.find("force 'f'"), std::string::npos) << e1;
  EXPECT_NE(e1.find("joint reaction"), std::string::npos) << e1;
  EXPECT_NE(e1.find("bad.yaml:"), std::string::npos) << e1;
  std::string motion = base;
  motion.replace(motion.find("measure: angle"), 14, "measure: drive");
  const std::string e2 = LoadError(motion);
  EXPECT_NE(e2.find("joint 'spin'"), std::string::npos) << e2;
  EXPECT_NE(e2.find("joint reaction"), std::string::npos) << e2;
  std::string unknown = base;
  unknown.replace(unknown.find("joint: axle"), 11, "joint: axel");
  const std::string e3 = LoadError(unknown);
  EXPECT_NE(e3.find("measure 'hold_y'"), std::string::npos) << e3;
  EXPECT_NE(e3.find("did you mean 'axle'"), std::string::npos) << e3;
  std::string offset = base;
  offset.replace(offset.find("component: y, frame: world}"), 27, "component: y, offset_initial: true}");
  EXPECT_NE(LoadError(offset).find("unknown key 'offset_initial'"), std::string::npos);
  std::string comp = base;
  comp.replace(comp.find("component: rz, frame: j"), 23, "component: q, frame: j");
  EXPECT_NE(LoadError(comp).find("component"), std::string::npos);
}

TEST(Objectives, LoadedWrittenAndRefusedWithReasons) {
  const std::string yaml = kMotion + R"(objectives:
  - {name: energy, integral: "drive^2 + alpha*angle"}
  - {name: final, terminal: "angle"}
  - {name: both, integral: "t", terminal: "spline_free + 1"}
)";
  // spline_free is not a name: the error names the objective, the key and the file.
  const std::string e = LoadError(yaml);
  EXPECT_NE(e.find("objective 'both'"), std::string::npos) << e;
  EXPECT_NE(e.find("'terminal'"), std::string::npos) << e;
  std::string good = yaml;
  good.replace(good.find("spline_free + 1"), 15, "2*hold_y");
  const Model model = LoadModelFromString(good, "ok.yaml");
  ASSERT_EQ(model.objectives.size(), 3u);
  EXPECT_EQ(model.find_objective("final"), 1);
  EXPECT_TRUE(model.objectives[0].has_integral);
  EXPECT_FALSE(model.objectives[0].has_terminal);
  EXPECT_TRUE(model.objectives[2].has_integral && model.objectives[2].has_terminal);
  EXPECT_EQ(model.measures[1].joint, 1);
  EXPECT_TRUE(model.measures[1].torque);
  EXPECT_EQ(model.measures[1].component, Component::kZ);
  // Written back and read again: the same objectives and reaction measures.
  const Model again = LoadModelFromString(WriteModelYaml(model), "again.yaml");
  ASSERT_EQ(again.objectives.size(), 3u);
  EXPECT_EQ(again.objectives[0].integral.text(), "drive^2 + alpha*angle");
  EXPECT_EQ(again.objectives[2].terminal.text(), "2*hold_y");
  EXPECT_EQ(again.measures[2].type, MeasureType::kReaction);
  EXPECT_EQ(again.measures[2].frame, MeasureFrame::kJ);
  EXPECT_EQ(again.measures[3].torque, false);
  EXPECT_EQ(again.measures[3].component, Component::kY);

  EXPECT_NE(LoadError(kMotion + "objectives:\n  - {name: g}\n").find("needs 'integral', 'terminal' or both"),
            std::string::npos);
  EXPECT_NE(LoadError(kMotion + "objectives:\n  - {name: g, terminal: t}\n  - {name: g, terminal: t}\n")
                .find("duplicate objective name"),
            std::string::npos);
  EXPECT_NE(LoadError(kMotion + "objectives:\n  - {name: g-1, terminal: t}\n").find("objective 'g-1'"),
            std::string::npos);
  EXPECT_NE(LoadError(kMotion + "objectives:\n  - {name: g, final: t}\n").find("unknown key 'final'"),
            std::string::npos);
  EXPECT_NE(LoadError(kMotion + "objectives: 3\n").find("'objectives' must be a list"), std::string::npos);
}

}  // namespace
}  // namespace mbdae::mbs
