// Joint reactions and actuator efforts of motion joints, against an independent
// recursive Newton-Euler computation of the 3-axis arm of tests/app/models/arm_motion.yaml
// (the arm of examples/robot_energy driven by three motion joints); the output rows whose
// a and lambda are solved from (t, q, v) (output_accelerations: solved) against the
// integrators' own multipliers; and the perturbed start of HHT against the consistent one.
//
// The Newton-Euler computation below knows only the arm's geometry and inertias (as the
// model file's comments state them) and the joint angles, rates and accelerations; it
// shares no code with the multibody system.
#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <Eigen/Geometry>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <random>
#include <string>
#include <vector>

#include "driver/simulation.h"
#include "mbs/loader.h"

namespace mbdae::driver {
namespace {

using Eigen::Matrix3d;
using Eigen::Vector3d;

std::string ModelPath(const std::string& name) { return std::string(MBDAE_TEST_MODELS) + "/" + name; }

// ---- The arm, independently ---------------------------------------------------------

struct Arm {
  double g = 9.81, L1 = 0.4, L2 = 0.3, L3 = 0.2, m1 = 3, m2 = 2, m3 = 1, mp = 0.5, rr = 0.02,
         rp = 0.03;
};

// Joint angles, rates and accelerations.
struct JointMotion {
  Vector3d q, qd, qdd;
};

// A wrench on the outer body of a joint about the joint point, world axes.
struct Wrench {
  Vector3d f = Vector3d::Zero(), n = Vector3d::Zero();
};

Matrix3d Rz(double a) { return Eigen::AngleAxisd(a, Vector3d::UnitZ()).toRotationMatrix(); }
Matrix3d Ry(double a) { return Eigen::AngleAxisd(a, Vector3d::UnitY()).toRotationMatrix(); }

// World kinematics of the four bodies (column, upper, fore, payload): rotation, centre of
// mass, its velocity and acceleration, angular velocity and acceleration.
struct Kinematics {
  std::array<Matrix3d, 4> R;
  std::array<Vector3d, 4> c, v, a, w, dw;
  std::array<Vector3d, 3> axis, point;  // joint axes (world) and points
  std::array<Matrix3d, 4> J;            // body-axes inertias
  std::array<double, 4> m;
};

Kinematics ArmKinematics(const Arm& arm, const JointMotion& x) {
  Kinematics k;
  const Vector3d ez = Vector3d::UnitZ();
  k.R[0] = Rz(x.q[0]);
  k.R[1] = Rz(x.q[0]) * Ry(-x.q[1]);
  k.R[2] = Rz(x.q[0]) * Ry(-(x.q[1] + x.q[2]));
  k.R[3] = k.R[2];
  // Axes: base about world z; shoulder and elbow about -y of the column (= -y of the
  // upper arm), the sense in which the angles grow.
  k.axis[0] = ez;
  k.axis[1] = k.R[0] * Vector3d(0, -1, 0);
  k.axis[2] = k.axis[1];
  const Vector3d w1 = x.qd[0] * k.axis[0], w2 = w1 + x.qd[1] * k.axis[1], w3 = w2 + x.qd[2] * k.axis[2];
  const Vector3d dw1 = x.qdd[0] * k.axis[0];
  // d(axis_2)/dt = w1 x axis_2.
  const Vector3d dw2 = dw1 + x.qdd[1] * k.axis[1] + w1.cross(x.qd[1] * k.axis[1]);
  const Vector3d dw3 = dw2 + x.qdd[2] * k.axis[2] + w1.cross(x.qd[2] * k.axis[2]);
  k.w = {w1, w2, w3, w3};
  k.dw = {dw1, dw2, dw3, dw3};
  const Vector3d S(0, 0, arm.L1);
  const Vector3d E = S + k.R[1] * Vector3d(arm.L2, 0, 0);
  k.point = {Vector3d::Zero(), S, E};
  // Point B of a body whose point A moves with (vA, aA): vB = vA + w x r, aB = aA + dw x r
  // + w x (w x r).
  auto carry = [](const Vector3d& vA, const Vector3d& aA, const Vector3d& w, const Vector3d& dw,
                  const Vector3d& r, Vector3d* vB, Vector3d* aB) {
    *vB = vA + w.cross(r);
    *aB = aA + dw.cross(r) + w.cross(w.cross(r));
  };
  const Vector3d zero = Vector3d::Zero();
  k.c[0] = Vector3d(0, 0, arm.L1 / 2);
  carry(zero, zero, w1, dw1, k.c[0], &k.v[0], &k.a[0]);
  k.c[1] = S + k.R[1] * Vector3d(arm.L2 / 2, 0, 0);
  carry(zero, zero, w2, dw2, k.c[1] - S, &k.v[1], &k.a[1]);  // S is on the base axis: at rest
  Vector3d vE, aE;
  carry(zero, zero, w2, dw2, E - S, &vE, &aE);
  k.c[2] = E + k.R[2] * Vector3d(arm.L3 / 2, 0, 0);
  carry(vE, aE, w3, dw3, k.c[2] - E, &k.v[2], &k.a[2]);
  k.c[3] = E + k.R[2] * Vector3d(arm.L3, 0, 0);
  carry(vE, aE, w3, dw3, k.c[3] - E, &k.v[3], &k.a[3]);
  const double r2 = arm.rr * arm.rr;
  k.J[0] = Vector3d(arm.m1 * (3 * r2 + arm.L1 * arm.L1) / 12, arm.m1 * (3 * r2 + arm.L1 * arm.L1) / 12,
                    arm.m1 * r2 / 2).asDiagonal();
  k.J[1] = Vector3d(arm.m2 * r2 / 2, arm.m2 * (3 * r2 + arm.L2 * arm.L2) / 12,
                    arm.m2 * (3 * r2 + arm.L2 * arm.L2) / 12).asDiagonal();
  k.J[2] = Vector3d(arm.m3 * r2 / 2, arm.m3 * (3 * r2 + arm.L3 * arm.L3) / 12,
                    arm.m3 * (3 * r2 + arm.L3 * arm.L3) / 12).asDiagonal();
  k.J[3] = (0.4 * arm.mp * arm.rp * arm.rp) * Matrix3d::Identity();
  k.m = {arm.m1, arm.m2, arm.m3, arm.mp};
  return k;
}

struct NewtonEulerResult {
  std::array<Wrench, 3> joint;  // base, shoulder, elbow: on the outer body about the joint point
  Wrench grip;                  // on the payload about its centre
  Vector3d tau;                 // actuator torques about the joint axes
};

// Newton-Euler, backward over the subtrees: the wrench a joint transmits to its outer
// subtree is the sum over the subtree's bodies of m (a_c - g) and, about the joint point
// P, (c - P) x m (a_c - g) + I dw + w x I w (I = R J R^T).
NewtonEulerResult NewtonEuler(const Arm& arm, const JointMotion& x) {
  const Kinematics k = ArmKinematics(arm, x);
  const Vector3d g(0, 0, -arm.g);
  auto body_wrench = [&](int b, const Vector3d& P) {
    Wrench w;
    const Matrix3d I = k.R[b] * k.J[b] * k.R[b].transpose();
    w.f = k.m[b] * (k.a[b] - g);
    w.n = (k.c[b] - P).cross(w.f) + I * k.dw[b] + k.w[b].cross(I * k.w[b]);
    return w;
  };
  NewtonEulerResult r;
  for (int j = 0; j < 3; ++j) {
    for (int b = j; b < 4; ++b) {
      const Wrench w = body_wrench(b, k.point[j]);
      r.joint[j].f += w.f;
      r.joint[j].n += w.n;
    }
    r.tau[j] = k.axis[j].dot(r.joint[j].n);
  }
  r.grip = body_wrench(3, k.c[3]);
  return r;
}

// The joint angles of arm_motion.yaml: quintic rest-to-rest plus b sin(w t).
struct MotionParameters {
  Vector3d q0{0, 0, 0}, qT{1.5, 0.9, -0.3}, b{0, 0, 0}, w{3, 5, 7};
  double T = 1;
};

JointMotion Angles(const MotionParameters& p, double t) {
  const double s = t / p.T;
  const double P = 10 * s * s * s - 15 * s * s * s * s + 6 * s * s * s * s * s;
  const double dP = (30 * s * s - 60 * s * s * s + 30 * s * s * s * s) / p.T;
  const double ddP = (60 * s - 180 * s * s + 120 * s * s * s) / (p.T * p.T);
  JointMotion x;
  for (int k = 0; k < 3; ++k) {
    const double d = p.qT[k] - p.q0[k];
    x.q[k] = p.q0[k] + d * P + p.b[k] * std::sin(p.w[k] * t);
    x.qd[k] = d * dP + p.b[k] * p.w[k] * std::cos(p.w[k] * t);
    x.qdd[k] = d * ddP - p.b[k] * p.w[k] * p.w[k] * std::sin(p.w[k] * t);
  }
  return x;
}

// The multibody state (centre of mass, Euler parameters and their rates per body) of the
// arm at joint motion x; Euler parameters with the sign of `like` (a state of the model).
void ArmState(const Arm& arm, const JointMotion& x, const std::vector<double>& like, double t,
              dae::State* s) {
  const Kinematics k = ArmKinematics(arm, x);
  s->t = t;
  s->q.assign(28, 0.0);
  s->v.assign(28, 0.0);
  for (int b = 0; b < 4; ++b) {
    double* q = s->q.data() + 7 * b;
    double* v = s->v.data() + 7 * b;
    for (int i = 0; i < 3; ++i) {
      q[i] = k.c[b][i];
      v[i] = k.v[b][i];
    }
    Eigen::Quaterniond e(k.R[b]);
    double sign = e.w() * like[7 * b + 3] + e.x() * like[7 * b + 4] + e.y() * like[7 * b + 5] +
                  e.z() * like[7 * b + 6] < 0 ? -1 : 1;
    const double e0 = sign * e.w(), e1 = sign * e.x(), e2 = sign * e.y(), e3 = sign * e.z();
    q[3] = e0, q[4] = e1, q[5] = e2, q[6] = e3;
    // e' = 1/2 E(e)^T omega (world), E = [-e1 e0 -e3 e2; -e2 e3 e0 -e1; -e3 -e2 e1 e0].
    Eigen::Matrix<double, 3, 4> E;
    E << -e1, e0, -e3, e2, -e2, e3, e0, -e1, -e3, -e2, e1, e0;
    const Eigen::Vector4d ed = 0.5 * E.transpose() * k.w[b];
    for (int i = 0; i < 4; ++i) v[3 + i] = ed[i];
  }
}

mbs::Model LoadArm(const MotionParameters& p) {
  mbs::LoadOptions lo;
  const char* names[3] = {"1", "2", "3"};
  for (int k = 0; k < 3; ++k) {
    lo.parameter_overrides[std::string("q") + names[k] + "_0"] = p.q0[k];
    lo.parameter_overrides[std::string("q") + names[k] + "_T"] = p.qT[k];
    lo.parameter_overrides[std::string("b") + names[k]] = p.b[k];
    lo.parameter_overrides[std::string("w") + names[k]] = p.w[k];
  }
  lo.parameter_overrides["T"] = p.T;
  return mbs::LoadModel(ModelPath("arm_motion.yaml"), lo);
}

int JointIndex(const mbs::Model& model, const std::string& name) {
  for (size_t j = 0; j < model.joints.size(); ++j)
    if (model.joints[j].name == name) return static_cast<int>(j);
  ADD_FAILURE() << "no joint " << name;
  return -1;
}

Vector3d Force(const io::ResultsRow& row, int joint) { return Vector3d(row.joint_data + 6 * joint); }
Vector3d Torque(const io::ResultsRow& row, int joint) { return Vector3d(row.joint_data + 6 * joint + 3); }

// ---- t = 0: at rest, arm horizontal -----------------------------------------------------

TEST(MotionJointReactions, StaticHorizontalArmMatchesNewtonEuler) {
  const MotionParameters p;
  mbs::Model model = LoadArm(p);
  Assembly asmb = Assemble(model);
  OutputRowBuilder rows(model, asmb);
  ASSERT_EQ(rows.effort_joints().size(), 3u);
  const io::ResultsRow& row = rows.Compute(asmb.x0);
  // The numbers of the issue: shoulder 9.3195 N m = 9.81 (2 0.15 + 1 0.4 + 0.5 0.5),
  // elbow 1.962 N m = 9.81 (1 0.1 + 0.5 0.2), base 0.
  EXPECT_NEAR(row.effort_data[0], 0.0, 1e-10);
  EXPECT_NEAR(row.effort_data[1], 9.3195, 1e-10);
  EXPECT_NEAR(row.effort_data[2], 1.962, 1e-10);
  const NewtonEulerResult ne = NewtonEuler(Arm(), Angles(p, 0.0));
  EXPECT_NEAR(ne.tau[1], 9.3195, 1e-12);
  EXPECT_NEAR(ne.tau[2], 1.962, 1e-12);
  // What the motion joints exert: a pure torque about the joint axis (world: shoulder
  // and elbow axes along -y), on the outer link.
  const int drive2 = JointIndex(model, "drive2"), drive3 = JointIndex(model, "drive3");
  EXPECT_LT((Force(row, drive2)).norm(), 1e-10);
  EXPECT_LT((Torque(row, drive2) - Vector3d(0, -9.3195, 0)).norm(), 1e-10);
  EXPECT_LT((Torque(row, drive3) - Vector3d(0, -1.962, 0)).norm(), 1e-10);
  // The reaction measure of drive2 (rz in the axes of column.S) is the same effort.
  int tau2 = -1;
  for (size_t m = 0; m < model.measures.size(); ++m)
    if (model.measures[m].name == "tau2") tau2 = static_cast<int>(m);
  EXPECT_NEAR(row.measures[tau2], 9.3195, 1e-10);
  // Revolute + motion joint together transmit the whole Newton-Euler wrench.
  const char* joints[3][2] = {{"base", "drive1"}, {"shoulder", "drive2"}, {"elbow", "drive3"}};
  for (int j = 0; j < 3; ++j) {
    const int rj = JointIndex(model, joints[j][0]), mj = JointIndex(model, joints[j][1]);
    EXPECT_LT((Force(row, rj) + Force(row, mj) - ne.joint[j].f).norm(), 1e-9) << joints[j][0];
    EXPECT_LT((Torque(row, rj) + Torque(row, mj) - ne.joint[j].n).norm(), 1e-9) << joints[j][0];
  }
  EXPECT_NEAR(ne.joint[1].f.z(), 3.5 * 9.81, 1e-12);  // the shoulder carries 3.5 kg
}

// ---- Random states along random motions ---------------------------------------------------

TEST(MotionJointReactions, RandomStatesMatchNewtonEuler) {
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> u(-1, 1);
  int checked = 0;
  for (int trial = 0; trial < 4; ++trial) {
    MotionParameters p;
    p.q0 = Vector3d(u(rng), 0.6 * u(rng), 1.2 * u(rng));
    p.qT = p.q0 + Vector3d(u(rng), u(rng), u(rng));
    p.b = 0.3 * Vector3d(u(rng), u(rng), u(rng));
    p.T = 1.3;
    mbs::Model model = LoadArm(p);
    Assembly asmb = Assemble(model);
    OutputRowBuilder rows(model, asmb);  // output_accelerations: solved (the default)
    for (int k = 0; k < 5; ++k) {
      const double t = 1.3 * (0.5 + 0.5 * u(rng));
      const JointMotion x = Angles(p, t);
      dae::State s = asmb.x0;
      ArmState(Arm(), x, asmb.x0.q, t, &s);
      const NewtonEulerResult ne = NewtonEuler(Arm(), x);
      // Twice: nothing left over from the first call.
      for (int again = 0; again < 2; ++again) {
        const io::ResultsRow& row = rows.Compute(s);
        const double scale = 1 + ne.tau.cwiseAbs().maxCoeff();
        for (int j = 0; j < 3; ++j)
          EXPECT_NEAR(row.effort_data[j], ne.tau[j], 1e-9 * scale) << "trial " << trial << " t " << t;
        const char* joints[3][2] = {{"base", "drive1"}, {"shoulder", "drive2"}, {"elbow", "drive3"}};
        for (int j = 0; j < 3; ++j) {
          const int rj = JointIndex(model, joints[j][0]), mj = JointIndex(model, joints[j][1]);
          EXPECT_LT((Force(row, rj) + Force(row, mj) - ne.joint[j].f).norm(), 1e-9 * (1 + ne.joint[j].f.norm()));
          EXPECT_LT((Torque(row, rj) + Torque(row, mj) - ne.joint[j].n).norm(), 1e-9 * scale);
          // The revolute joint takes no torque about its axis; the motion joint takes all.
          const Vector3d axis = Torque(row, mj).normalized();
          EXPECT_NEAR(std::abs(Torque(row, mj).dot(axis)), std::abs(ne.tau[j]), 1e-9 * scale);
          EXPECT_LT(Force(row, mj).norm(), 1e-9 * scale);
        }
        const int grip = JointIndex(model, "grip");
        EXPECT_LT((Force(row, grip) - ne.grip.f).norm(), 1e-9 * (1 + ne.grip.f.norm()));
        EXPECT_LT((Torque(row, grip) - ne.grip.n).norm(), 1e-9 * scale);
        ++checked;
      }
    }
  }
  EXPECT_EQ(checked, 40);
}

// ---- Integrated runs: rows solved from (t, q, v) against the integrator's lambda -----------

struct RunErrors {
  double max_integrator = 0, max_solved = 0, median_integrator = 0;
  std::vector<double> integrator, solved;  // per row, max over the three efforts
};

RunErrors EffortErrors(mbs::Model& model, mbs::SimulationSettings settings, const MotionParameters& p) {
  Assembly asmb = Assemble(model);
  settings.output_accelerations = "integrator";
  OutputRowBuilder raw(model, asmb, settings);
  settings.output_accelerations = "solved";
  OutputRowBuilder solved(model, asmb, settings);
  auto integrator = MakeIntegrator(*asmb.kept_system, settings);
  integrator->Initialize(asmb.x0);
  RunErrors e;
  const std::vector<double> times = OutputTimes(settings.t_end, settings.output_step);
  for (size_t k = 0; k < times.size(); ++k) {
    if (k > 0) EXPECT_TRUE(integrator->AdvanceTo(times[k])) << integrator->summary().message;
    dae::State x = integrator->state();
    x.t = times[k];
    const NewtonEulerResult ne = NewtonEuler(Arm(), Angles(p, x.t));
    double ei = 0, es = 0;
    const io::ResultsRow& ri = raw.Compute(x);
    for (int j = 0; j < 3; ++j) ei = std::max(ei, std::abs(ri.effort_data[j] - ne.tau[j]));
    const io::ResultsRow& rs = solved.Compute(x);
    for (int j = 0; j < 3; ++j) es = std::max(es, std::abs(rs.effort_data[j] - ne.tau[j]));
    e.integrator.push_back(ei);
    e.solved.push_back(es);
  }
  EXPECT_EQ(solved.fallbacks(), 0);
  e.max_integrator = *std::max_element(e.integrator.begin(), e.integrator.end());
  e.max_solved = *std::max_element(e.solved.begin(), e.solved.end());
  std::vector<double> sorted = e.integrator;
  std::sort(sorted.begin(), sorted.end());
  e.median_integrator = sorted[sorted.size() / 2];
  return e;
}

TEST(SolvedOutputRows, IdaEffortsWithoutSpikes) {
  // The quintic motion of examples/robot_energy/quintic.yaml (poses (0, 0.3, -1.2) to
  // (1.5, 0.9, -0.3) in 1 s), IDA at its default tolerances, rows every 0.01 s.
  MotionParameters p;
  p.q0 = Vector3d(0, 0.3, -1.2);
  mbs::Model model = LoadArm(p);
  mbs::SimulationSettings s = model.simulation;
  s.integrator = mbs::IntegratorKind::kIda;
  const RunErrors e = EffortErrors(model, s, p);
  std::printf("IDA efforts against Newton-Euler: integrator lambda max %.3g median %.3g; solved max %.3g\n",
              e.max_integrator, e.median_integrator, e.max_solved);
  EXPECT_LT(e.max_solved, 1e-6);
  EXPECT_LT(e.max_solved, 0.1 * e.max_integrator);
}

TEST(SolvedOutputRows, HhtEffortsSecondOrder) {
  MotionParameters p;
  p.q0 = Vector3d(0, 0.3, -1.2);
  mbs::Model model = LoadArm(p);
  mbs::SimulationSettings s = model.simulation;
  s.integrator = mbs::IntegratorKind::kHht;
  s.hht_step = 1e-3;
  const RunErrors e = EffortErrors(model, s, p);
  std::printf("HHT h = 1e-3 efforts against Newton-Euler: integrator lambda max %.3g; solved max %.3g\n",
              e.max_integrator, e.max_solved);
  EXPECT_LT(e.max_solved, 1e-3);
}

// ---- HHT start -------------------------------------------------------------------------

// Efforts from the integrator's own lambda over the first 0.05 s, every step (h = 1e-3):
// error against Newton-Euler at each step.
std::vector<double> HhtStartErrors(const std::string& start, std::vector<double>* signed_error) {
  MotionParameters p;
  p.q0 = Vector3d(0, 0.3, -1.2);
  mbs::Model model = LoadArm(p);
  mbs::SimulationSettings s = model.simulation;
  s.integrator = mbs::IntegratorKind::kHht;
  s.hht_step = 1e-3;
  s.hht_start = start;
  s.t_end = 0.05;
  s.output_step = 1e-3;
  s.output_accelerations = "integrator";
  Assembly asmb = Assemble(model);
  OutputRowBuilder rows(model, asmb, s);
  auto integrator = MakeIntegrator(*asmb.kept_system, s);
  integrator->Initialize(asmb.x0);
  std::vector<double> err;
  for (double t : OutputTimes(s.t_end, s.output_step)) {
    if (t > 0) EXPECT_TRUE(integrator->AdvanceTo(t));
    dae::State x = integrator->state();
    x.t = t;
    const io::ResultsRow& row = rows.Compute(x);
    const NewtonEulerResult ne = NewtonEuler(Arm(), Angles(p, t));
    err.push_back(std::abs(row.effort_data[1] - ne.tau[1]) + std::abs(row.effort_data[2] - ne.tau[2]));
    if (signed_error) signed_error->push_back(row.effort_data[1] - ne.tau[1]);
  }
  return err;
}

TEST(HhtStart, PerturbedStartHasNoAlternatingMultipliers) {
  std::vector<double> sc, sp;
  const std::vector<double> consistent = HhtStartErrors("consistent", &sc);
  const std::vector<double> perturbed = HhtStartErrors("perturbed", &sp);
  ASSERT_EQ(consistent.size(), 51u);
  auto sign_changes = [](const std::vector<double>& e) {
    int n = 0;
    for (size_t k = 2; k < e.size(); ++k) n += (e[k] > 0) != (e[k - 1] > 0);
    return n;
  };
  const double max_c = *std::max_element(consistent.begin() + 1, consistent.end());
  const double max_p = *std::max_element(perturbed.begin() + 1, perturbed.end());
  std::printf("HHT start: effort error at t = 0.005 consistent %.3g perturbed %.3g; max over "
              "0.05 s %.3g / %.3g; sign changes of the shoulder error %d / %d\n",
              consistent[5], perturbed[5], max_c, max_p, sign_changes(sc), sign_changes(sp));
  // Measured: 1.31e-2 / 1.9e-5 at t = 0.005, 1.31e-2 / 6.1e-5 over the first 0.05 s.
  EXPECT_GT(consistent[5], 5e-3);
  EXPECT_LT(perturbed[5], 1e-4);
  EXPECT_LT(max_p, 2e-4);
}


// ---- A gear joint: what it exerts on the driven wheel ------------------------------------

// verification/gear/gear.yaml: wheel 1 (J1 = 0.02 about z) driven by 0.05 sin t, wheel 2
// (J2 = 0.005) geared to it with phi2 - phi2_0 = r (phi1 - phi1_0), r = -2. The gear's
// torque on wheel 2 is T2 = J2 phi2'' = r J2 tau / (J1 + r^2 J2) = -0.25 tau, about z,
// whatever the angles and rates.
TEST(GearJointReactions, TorqueOnTheDrivenWheel) {
  const char* text = R"yaml(format: 1
bodies:
  - {name: wheel1, mass: 1, inertia: [0.01, 0.01, 0.02], position: [0, 0, 0]}
  - {name: wheel2, mass: 0.5, inertia: [0.004, 0.004, 0.005], position: [0.3, 0, 0],
     orientation: {axis: [0, 0, 1], angle: 0.4}}
measures:
  - {name: phi1, type: rotational, i: wheel1.cm, j: ground.O, axis: z}
  - {name: phi2, type: rotational, i: wheel2.cm, j: ground.B, axis: z}
ground:
  markers:
    B: {position: [0.3, 0, 0]}
joints:
  - {name: hinge1, type: revolute, i: wheel1.cm, j: ground.O}
  - {name: hinge2, type: revolute, i: wheel2.cm, j: ground.B}
  - {name: mesh, type: gear, measures: [phi1, phi2], ratio: -2}
forces:
  - {name: drive, type: torque, i: wheel1.cm, frame: world, value: [0, 0, "0.05*sin(t)"]}
)yaml";
  mbs::Model model = mbs::LoadModelFromString(text, "gear.yaml");
  Assembly asmb = Assemble(model);
  OutputRowBuilder rows(model, asmb);
  EXPECT_TRUE(rows.effort_joints().empty());
  const int mesh = JointIndex(model, "mesh");
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> u(-1, 1);
  for (int k = 0; k < 6; ++k) {
    const double t = 3 * std::abs(u(rng)) + 0.1, phi1 = 2 * u(rng), w1 = 5 * u(rng);
    const double phi2 = 0.4 - 2 * phi1, w2 = -2 * w1;
    dae::State s = asmb.x0;
    s.t = t;
    const double angle[2] = {phi1, phi2}, rate[2] = {w1, w2};
    for (int b = 0; b < 2; ++b) {
      double* q = s.q.data() + 7 * b;
      double* v = s.v.data() + 7 * b;
      q[3] = std::cos(angle[b] / 2);
      q[6] = std::sin(angle[b] / 2);
      q[4] = q[5] = 0;
      // e' = 1/2 E^T omega with omega = (0, 0, w): (-e3, -e2, e1, e0) w / 2.
      v[3] = -0.5 * q[6] * rate[b];
      v[4] = v[5] = 0;
      v[6] = 0.5 * q[3] * rate[b];
    }
    const io::ResultsRow& row = rows.Compute(s);
    const Vector3d expected(0, 0, -0.25 * 0.05 * std::sin(t));
    EXPECT_LT((Torque(row, mesh) - expected).norm(), 1e-12) << "t " << t;
    EXPECT_LT(Force(row, mesh).norm(), 1e-12);
  }
}

}  // namespace
}  // namespace mbdae::driver
