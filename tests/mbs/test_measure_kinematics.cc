// Measures with exact derivatives (mbs/measure_kinematics.h): values against
// MultibodySystem::EvaluateMeasures, gradients and Hessians against central finite
// differences on random bodies, markers and states for every measure kind and every
// marker placement (body-body, body-ground, ground-body, both on one body), velocity
// measures and their state derivatives, acceleration consistency along a path, and the
// angle across its wrap at +-pi.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdlib>
#include <iostream>
#include <memory>
#include <new>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

#include "mbs/kinematics.h"
#include "mbs/measure_kinematics.h"
#include "mbs/system.h"
#include "tests/support/random_models.h"

#include "tests/support/count_allocations.h"

namespace mbdae::mbs {
namespace {

using Eigen::MatrixXd;
using Eigen::VectorXd;
using testing::RandomUnitQuaternion;
using testing::RandomVector;

constexpr double kFdTolerance = 1e-7;  // relative, for central differences

// Bodies b0..b2 with two markers each (random pose), ground markers O and G (random
// pose), and for each marker pair (body-body, body-ground, ground-body, same body)
// every measure: translational x|y|z in j and world axes and distance, rotational about
// x|y|z; each at position, velocity and acceleration level.
Model MeasureModel(std::mt19937& rng) {
  Model m;
  m.name = "measures";
  m.markers.push_back(Marker{"ground.O", -1, Vec3::Zero(), Mat3::Identity(), {}});
  m.markers.push_back(Marker{"ground.G", -1, RandomVector(rng, 1.0),
                             RotationMatrix(RandomUnitQuaternion(rng)), {}});
  for (int b = 0; b < 3; ++b) {
    Body body;
    body.name = "b" + std::to_string(b);
    body.mass = 1.0;
    body.inertia = Mat3::Identity();
    body.position = RandomVector(rng, 2.0);
    body.orientation = RandomUnitQuaternion(rng);
    body.cm_marker = static_cast<int>(m.markers.size());
    m.markers.push_back(Marker{body.name + ".cm", b, Vec3::Zero(), Mat3::Identity(), {}});
    for (int k = 0; k < 2; ++k)
      m.markers.push_back(Marker{body.name + ".M" + std::to_string(k), b,
                                 RandomVector(rng, 0.5), RotationMatrix(RandomUnitQuaternion(rng)),
                                 {}});
    m.bodies.push_back(body);
  }
  // marker indices: ground.O 0, ground.G 1, b0: 2 3 4, b1: 5 6 7, b2: 8 9 10
  const int pairs[][2] = {{3, 7}, {4, 1}, {1, 9}, {6, 7}, {10, 0}};
  int n = 0;
  for (const auto& pr : pairs)
    for (Quantity qt : {Quantity::kPosition, Quantity::kVelocity, Quantity::kAcceleration}) {
      auto add = [&](MeasureType type, Component c, MeasureFrame f) {
        Measure me;
        me.name = "m" + std::to_string(n++);
        me.type = type;
        me.i = pr[0];
        me.j = pr[1];
        me.component = c;
        me.frame = f;
        me.quantity = qt;
        m.measures.push_back(me);
      };
      for (MeasureFrame f : {MeasureFrame::kJ, MeasureFrame::kWorld})
        for (Component c : {Component::kX, Component::kY, Component::kZ})
          add(MeasureType::kTranslational, c, f);
      add(MeasureType::kTranslational, Component::kDistance, MeasureFrame::kJ);
      for (Component c : {Component::kX, Component::kY, Component::kZ})
        add(MeasureType::kRotational, c, MeasureFrame::kJ);
    }
  return m;
}

// Random state: positions, Euler parameters of norm near (not exactly) 1 (the
// functions are defined for every e), velocities and accelerations.
void RandomState(std::mt19937& rng, int nb, VectorXd* q, VectorXd* v, VectorXd* a) {
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  q->resize(7 * nb);
  v->resize(7 * nb);
  a->resize(7 * nb);
  for (int b = 0; b < nb; ++b) {
    q->segment<3>(7 * b) = RandomVector(rng, 2.0);
    q->segment<4>(7 * b + 3) = RandomUnitQuaternion(rng) * (1.0 + 0.05 * u(rng));
  }
  for (int k = 0; k < 7 * nb; ++k) {
    (*v)[k] = u(rng);
    (*a)[k] = 2 * u(rng);
  }
}

// Scatters a local gradient / Hessian into the global coordinates.
VectorXd Scatter(const int offset[2], const Vec14& g, int nq) {
  VectorXd x = VectorXd::Zero(nq);
  for (int s = 0; s < 2; ++s)
    if (offset[s] >= 0) x.segment<7>(offset[s]) += g.segment<7>(7 * s);
  return x;
}
MatrixXd Scatter(const int offset[2], const Mat14& h, int nq) {
  MatrixXd x = MatrixXd::Zero(nq, nq);
  for (int s = 0; s < 2; ++s)
    for (int t = 0; t < 2; ++t)
      if (offset[s] >= 0 && offset[t] >= 0)
        x.block<7, 7>(offset[s], offset[t]) += h.block<7, 7>(7 * s, 7 * t);
  return x;
}

double RelError(const MatrixXd& a, const MatrixXd& ref) {
  return (a - ref).cwiseAbs().maxCoeff() / std::max(1.0, ref.cwiseAbs().maxCoeff());
}

// Difference of two values of the measure; angles modulo 2 pi (the wrap).
double Diff(const MeasureDef& def, double a, double b) {
  const double d = a - b;
  return def.type == MeasureType::kRotational ? std::remainder(d, 2 * M_PI) : d;
}

MeasureDef AsPosition(MeasureDef d) {
  d.quantity = Quantity::kPosition;
  return d;
}

class MeasureKinematicsTest : public ::testing::Test {
 protected:
  void SetUp() override {
    std::mt19937 rng(20240611);
    model_ = MeasureModel(rng);
    system_ = std::make_unique<MultibodySystem>(model_);
    nq_ = system_->num_coordinates();
    for (int s = 0; s < 4; ++s) {
      VectorXd q, v, a;
      RandomState(rng, static_cast<int>(model_.bodies.size()), &q, &v, &a);
      qs_.push_back(q);
      vs_.push_back(v);
      as_.push_back(a);
    }
  }
  Model model_;
  std::unique_ptr<MultibodySystem> system_;
  int nq_ = 0;
  std::vector<VectorXd> qs_, vs_, as_;
};

TEST_F(MeasureKinematicsTest, ResolvesSlotsAndFoldsOneBody) {
  // pair (6, 7): both on b1 -> slot 0 only
  const int k = 3 * 3 * 11;  // first measure of the fourth pair
  ASSERT_EQ(model_.measures[k].i, 6);
  const MeasureDef d = ResolveMeasure(model_, k);
  EXPECT_EQ(d.offset[0], 7);
  EXPECT_EQ(d.offset[1], -1);
  EXPECT_EQ(d.slot_i, 0);
  EXPECT_EQ(d.slot_j, 0);
  // pair (1, 9): ground - b2
  const MeasureDef g = ResolveMeasure(model_, 2 * 3 * 11);
  EXPECT_EQ(g.offset[0], -1);
  EXPECT_EQ(g.offset[1], 14);
  EXPECT_EQ(g.slot_i, -1);
  EXPECT_EQ(g.slot_j, 1);
  EXPECT_THROW(ResolveMeasure(model_, static_cast<int>(model_.measures.size())),
               std::invalid_argument);
}

TEST_F(MeasureKinematicsTest, ValuesEqualEvaluateMeasures) {
  const int nm = static_cast<int>(model_.measures.size());
  std::vector<double> ref(nm);
  double worst[3] = {0, 0, 0};
  for (size_t s = 0; s < qs_.size(); ++s) {
    system_->EvaluateMeasures(0.0, qs_[s].data(), vs_[s].data(), as_[s].data(), ref.data());
    for (int k = 0; k < nm; ++k) {
      const MeasureDef d = ResolveMeasure(model_, k);
      const double x = EvaluateMeasureValue(d, qs_[s].data(), vs_[s].data(), as_[s].data());
      const double err = std::abs(x - ref[k]) / std::max(1.0, std::abs(ref[k]));
      const int lvl = static_cast<int>(d.quantity);
      worst[lvl] = std::max(worst[lvl], err);
      // position and velocity: the same sums in another order; acceleration: g.a + v^T H v
      // against the system's product-rule form.
      EXPECT_LT(err, d.quantity == Quantity::kAcceleration ? 1e-13 : 1e-14)
          << model_.measures[k].name << " state " << s;
    }
  }
  std::cout << "value vs EvaluateMeasures, max relative error: position " << worst[0]
            << ", velocity " << worst[1] << ", acceleration " << worst[2] << "\n";
  // null v and a are zeros
  system_->EvaluateMeasures(0.0, qs_[0].data(), nullptr, nullptr, ref.data());
  for (int k = 0; k < nm; ++k)
    EXPECT_NEAR(EvaluateMeasureValue(ResolveMeasure(model_, k), qs_[0].data(), nullptr, nullptr),
                ref[k], 1e-14);
}

TEST_F(MeasureKinematicsTest, GradientAndHessianMatchFiniteDifferences) {
  const double h = 1e-6;
  double worst_g = 0, worst_h = 0, worst_sym = 0;
  for (size_t s = 0; s < qs_.size(); ++s) {
    for (size_t k = 0; k < model_.measures.size(); ++k) {
      const MeasureDef d = AsPosition(ResolveMeasure(model_, static_cast<int>(k)));
      if (model_.measures[k].quantity != Quantity::kPosition) continue;
      MeasureJacobian j;
      EvaluateMeasurePosition(d, qs_[s].data(), true, &j);
      // the gradient alone gives the same numbers
      MeasureJacobian j2;
      EvaluateMeasurePosition(d, qs_[s].data(), false, &j2);
      EXPECT_EQ(j.value, j2.value);
      EXPECT_EQ((j.gradient - j2.gradient).norm(), 0.0);
      const VectorXd g = Scatter(j.offset, j.gradient, nq_);
      const MatrixXd H = Scatter(j.offset, j.hessian, nq_);
      VectorXd g_fd(nq_);
      MatrixXd H_fd(nq_, nq_);
      for (int c = 0; c < nq_; ++c) {
        VectorXd qp = qs_[s], qm = qs_[s];
        qp[c] += h;
        qm[c] -= h;
        MeasureJacobian jp, jm;
        EvaluateMeasurePosition(d, qp.data(), false, &jp);
        EvaluateMeasurePosition(d, qm.data(), false, &jm);
        g_fd[c] = Diff(d, jp.value, jm.value) / (2 * h);
        H_fd.col(c) = (Scatter(jp.offset, jp.gradient, nq_) -
                       Scatter(jm.offset, jm.gradient, nq_)) / (2 * h);
      }
      const double eg = RelError(g, g_fd), eh = RelError(H, H_fd);
      const double es = (H - H.transpose()).cwiseAbs().maxCoeff();
      worst_g = std::max(worst_g, eg);
      worst_h = std::max(worst_h, eh);
      worst_sym = std::max(worst_sym, es);
      EXPECT_LT(eg, kFdTolerance) << model_.measures[k].name;
      EXPECT_LT(eh, kFdTolerance) << model_.measures[k].name;
      EXPECT_LT(es, 1e-13) << model_.measures[k].name;
      // zero outside the slots: nothing leaks into other bodies' columns
      for (int c = 0; c < nq_; ++c)
        if (c / 7 * 7 != j.offset[0] && c / 7 * 7 != j.offset[1]) {
          EXPECT_EQ(g_fd[c], 0.0);
        }
    }
  }
  std::cout << "position measures vs central differences (h = 1e-6): gradient " << worst_g
            << ", Hessian " << worst_h << "; Hessian asymmetry " << worst_sym << "\n";
}

TEST_F(MeasureKinematicsTest, VelocityMeasureStateDerivatives) {
  const double h = 1e-6;
  double worst_v = 0, worst_dq = 0;
  for (size_t s = 0; s < qs_.size(); ++s) {
    for (size_t k = 0; k < model_.measures.size(); ++k) {
      const Measure& me = model_.measures[k];
      if (me.quantity != Quantity::kVelocity) continue;
      const MeasureDef d = ResolveMeasure(model_, static_cast<int>(k));
      MeasureStateJacobian sj;
      EvaluateMeasureState(d, qs_[s].data(), vs_[s].data(), &sj);
      MeasureJacobian pj;
      EvaluateMeasurePosition(AsPosition(d), qs_[s].data(), false, &pj);
      // velocity measure = gradient . v, d/dv = gradient
      const double gv = Scatter(pj.offset, pj.gradient, nq_).dot(vs_[s]);
      const double ev = std::abs(sj.value - gv) / std::max(1.0, std::abs(gv));
      worst_v = std::max(worst_v, ev);
      EXPECT_LT(ev, 1e-14) << me.name;
      EXPECT_EQ((sj.dv - pj.gradient).norm(), 0.0) << me.name;
      // d/dq against central differences of the value (v fixed)
      VectorXd fd(nq_);
      for (int c = 0; c < nq_; ++c) {
        VectorXd qp = qs_[s], qm = qs_[s];
        qp[c] += h;
        qm[c] -= h;
        fd[c] = (EvaluateMeasureValue(d, qp.data(), vs_[s].data(), nullptr) -
                 EvaluateMeasureValue(d, qm.data(), vs_[s].data(), nullptr)) / (2 * h);
      }
      const double e = RelError(Scatter(sj.offset, sj.dq, nq_), fd);
      worst_dq = std::max(worst_dq, e);
      EXPECT_LT(e, kFdTolerance) << me.name;
      // d/dv against differences too (the value is linear in v: exact up to rounding)
      VectorXd fdv(nq_);
      for (int c = 0; c < nq_; ++c) {
        VectorXd vp = vs_[s], vm = vs_[s];
        vp[c] += h;
        vm[c] -= h;
        fdv[c] = (EvaluateMeasureValue(d, qs_[s].data(), vp.data(), nullptr) -
                  EvaluateMeasureValue(d, qs_[s].data(), vm.data(), nullptr)) / (2 * h);
      }
      EXPECT_LT(RelError(Scatter(sj.offset, sj.dv, nq_), fdv), kFdTolerance) << me.name;
    }
  }
  std::cout << "velocity measures: value vs g.v " << worst_v << ", d/dq vs differences "
            << worst_dq << "\n";
}

TEST_F(MeasureKinematicsTest, PositionMeasureStateIsTheGradient) {
  for (size_t k = 0; k < model_.measures.size(); ++k) {
    if (model_.measures[k].quantity != Quantity::kPosition) continue;
    const MeasureDef d = ResolveMeasure(model_, static_cast<int>(k));
    MeasureStateJacobian sj;
    EvaluateMeasureState(d, qs_[1].data(), vs_[1].data(), &sj);
    MeasureJacobian pj;
    EvaluateMeasurePosition(d, qs_[1].data(), false, &pj);
    EXPECT_EQ(sj.value, pj.value);
    EXPECT_EQ((sj.dq - pj.gradient).norm(), 0.0);
    EXPECT_EQ(sj.dv.norm(), 0.0);
  }
  const int acc = 2 * 11;  // first pair, acceleration level
  ASSERT_EQ(model_.measures[acc].quantity, Quantity::kAcceleration);
  MeasureStateJacobian sj;
  EXPECT_THROW(EvaluateMeasureState(ResolveMeasure(model_, acc), qs_[0].data(), vs_[0].data(), &sj),
               std::invalid_argument);
}

TEST_F(MeasureKinematicsTest, EvaluationsDoNotAllocate) {
  std::vector<MeasureDef> defs;
  for (size_t k = 0; k < model_.measures.size(); ++k)
    defs.push_back(ResolveMeasure(model_, static_cast<int>(k)));
  MeasureJacobian j;
  MeasureStateJacobian sj;
  double sum = 0;
  const long before = g_allocations;
  for (const MeasureDef& d : defs) {
    EvaluateMeasurePosition(d, qs_[0].data(), true, &j);
    sum += j.value + j.hessian(3, 3);
    if (d.quantity != Quantity::kAcceleration) {
      EvaluateMeasureState(d, qs_[0].data(), vs_[0].data(), &sj);
      sum += sj.dq[3];
    }
    sum += EvaluateMeasureValue(d, qs_[0].data(), vs_[0].data(), as_[0].data());
  }
  EXPECT_EQ(g_allocations - before, 0);
  EXPECT_TRUE(std::isfinite(sum));
}

// The system's acceleration measure is d/dt of the velocity measure along
// (q + s v + s^2/2 a, v + s a); and v^T H v is d/ds of g(q + s v) . v (gamma of a motion
// constraint).
TEST_F(MeasureKinematicsTest, AccelerationConsistentAlongPath) {
  const int nm = static_cast<int>(model_.measures.size());
  std::vector<double> acc(nm);
  const double h = 1e-5;
  double worst_a = 0, worst_g = 0;
  for (size_t s = 0; s < qs_.size(); ++s) {
    const VectorXd &q = qs_[s], &v = vs_[s], &a = as_[s];
    system_->EvaluateMeasures(0.0, q.data(), v.data(), a.data(), acc.data());
    for (int k = 0; k < nm; ++k) {
      const Measure& me = model_.measures[k];
      if (me.quantity != Quantity::kAcceleration) continue;
      MeasureDef dv = ResolveMeasure(model_, k);
      dv.quantity = Quantity::kVelocity;
      auto vel = [&](double t) {
        const VectorXd qt = q + t * v + 0.5 * t * t * a, vt = v + t * a;
        return EvaluateMeasureValue(dv, qt.data(), vt.data(), nullptr);
      };
      const double fd = (vel(h) - vel(-h)) / (2 * h);
      const double e = std::abs(acc[k] - fd) / std::max(1.0, std::abs(fd));
      worst_a = std::max(worst_a, e);
      EXPECT_LT(e, kFdTolerance) << me.name;
      // v^T H v (gamma of a motion constraint) against d/ds of g(q + s v) . v
      const MeasureDef dp = AsPosition(dv);
      MeasureJacobian j;
      EvaluateMeasurePosition(dp, q.data(), true, &j);
      const Vec14 vl = GatherLocal(j.offset, v.data());
      const double vhv = vl.dot(j.hessian * vl);
      auto gv = [&](double t) {
        const VectorXd qt = q + t * v;
        MeasureJacobian jt;
        EvaluateMeasurePosition(dp, qt.data(), false, &jt);
        return jt.gradient.dot(vl);
      };
      const double fd2 = (gv(h) - gv(-h)) / (2 * h);
      const double e2 = std::abs(vhv - fd2) / std::max(1.0, std::abs(fd2));
      worst_g = std::max(worst_g, e2);
      EXPECT_LT(e2, kFdTolerance) << me.name;
    }
  }
  std::cout << "acceleration vs d/dt of velocity measure " << worst_a
            << "; v^T H v vs d/ds of g(q + s v).v " << worst_g << "\n";
}

// Body b0 turned by theta about the world z axis, marker i = b0.cm (identity axes),
// marker j = ground.O: the rotational z measure is theta wrapped to (-pi, pi]. Across
// theta = pi the value jumps by 2 pi but the gradient and Hessian are continuous, and
// they match differences (taken modulo 2 pi) right at the wrap.
TEST(MeasureAngleWrap, DerivativesSmoothAcrossPi) {
  Model m;
  m.markers.push_back(Marker{"ground.O", -1, Vec3::Zero(), Mat3::Identity(), {}});
  Body b;
  b.name = "b0";
  b.cm_marker = 1;
  m.bodies.push_back(b);
  m.markers.push_back(Marker{"b0.cm", 0, Vec3::Zero(), Mat3::Identity(), {}});
  Measure me;
  me.name = "angle";
  me.type = MeasureType::kRotational;
  me.component = Component::kZ;
  me.i = 1;
  me.j = 0;
  m.measures.push_back(me);
  const MeasureDef d = ResolveMeasure(m, 0);
  auto state = [](double theta) {
    VectorXd q(7);
    q << 0.3, -0.2, 0.1, std::cos(theta / 2), 0, 0, std::sin(theta / 2);
    return q;
  };
  const double delta = 1e-9;
  MeasureJacobian below, above, at;
  EvaluateMeasurePosition(d, state(M_PI - delta).data(), true, &below);
  EvaluateMeasurePosition(d, state(M_PI + delta).data(), true, &above);
  EvaluateMeasurePosition(d, state(M_PI).data(), true, &at);
  EXPECT_NEAR(below.value, M_PI - delta, 1e-14);
  EXPECT_NEAR(above.value, -M_PI + delta, 1e-14);
  EXPECT_NEAR(at.value, M_PI, 1e-15);
  EXPECT_LT((below.gradient - above.gradient).cwiseAbs().maxCoeff(), 1e-8);
  EXPECT_LT((below.hessian - above.hessian).cwiseAbs().maxCoeff(), 1e-8);
  // theta = 2 atan2(e3, e0) for a rotation about z: d theta / d e0 = -2 e3 / |e|^2 = -2
  // and d theta / d e3 = 2 e0 / |e|^2 = 0 at theta = pi (e0 = 0, e3 = 1; local 3 and 6).
  EXPECT_NEAR(at.gradient[3], -2.0, 1e-14);
  EXPECT_NEAR(at.gradient[6], 0.0, 1e-14);
  EXPECT_EQ(at.gradient.tail<7>().norm(), 0.0);  // marker j on ground: slot 1 unused
  // differences modulo 2 pi at the wrap, random perturbation directions too
  const double h = 1e-6;
  const VectorXd q0 = state(M_PI);
  Vec14 g_fd = Vec14::Zero();
  Mat14 H_fd = Mat14::Zero();
  for (int c = 0; c < 7; ++c) {
    VectorXd qp = q0, qm = q0;
    qp[c] += h;
    qm[c] -= h;
    MeasureJacobian jp, jm;
    EvaluateMeasurePosition(d, qp.data(), false, &jp);
    EvaluateMeasurePosition(d, qm.data(), false, &jm);
    g_fd[c] = std::remainder(jp.value - jm.value, 2 * M_PI) / (2 * h);
    H_fd.col(c) = (jp.gradient - jm.gradient) / (2 * h);
  }
  EXPECT_LT((at.gradient - g_fd).cwiseAbs().maxCoeff(), kFdTolerance);
  EXPECT_LT((at.hessian - H_fd).cwiseAbs().maxCoeff(), kFdTolerance);
  // the system agrees on the value at the wrap
  MultibodySystem sys(m);
  double x;
  sys.EvaluateMeasures(0.0, q0.data(), nullptr, nullptr, &x);
  EXPECT_EQ(x, at.value);
}

// Both markers at one point: the distance is 0 with zero derivatives (as the system's
// rates), not NaN.
TEST(MeasureSingular, ZeroDistanceHasZeroDerivatives) {
  Model m;
  m.markers.push_back(Marker{"ground.O", -1, Vec3::Zero(), Mat3::Identity(), {}});
  Body b;
  b.name = "b0";
  b.cm_marker = 1;
  m.bodies.push_back(b);
  m.markers.push_back(Marker{"b0.cm", 0, Vec3::Zero(), Mat3::Identity(), {}});
  Measure me;
  me.name = "len";
  me.component = Component::kDistance;
  me.i = 1;
  me.j = 0;
  m.measures.push_back(me);
  VectorXd q(7);
  q << 0, 0, 0, 1, 0, 0, 0;
  MeasureJacobian j;
  EvaluateMeasurePosition(ResolveMeasure(m, 0), q.data(), true, &j);
  EXPECT_EQ(j.value, 0.0);
  EXPECT_EQ(j.gradient.norm(), 0.0);
  EXPECT_EQ(j.hessian.norm(), 0.0);
}

}  // namespace
}  // namespace mbdae::mbs
