// Tests of mbs/bushing: exact Jacobian against central finite differences, zero force at
// zero deflection and under rigid motion, small-deflection stiffness and damping equal
// to K and D, the spring part derived from its potential for both markers, deflection
// rates as time derivatives, the damper's dissipation, the rotation measure.
#include "mbs/bushing.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

namespace mbdae::mbs {
namespace {

using Vec3 = Eigen::Vector3d;
using Mat3 = Eigen::Matrix3d;

Mat3 Exp(const Vec3& phi) {
  const double a = phi.norm();
  if (a == 0) return Mat3::Identity();
  return Eigen::AngleAxisd(a, phi / a).toRotationMatrix();
}

// Markers with relative rotation angle below max_angle (< pi).
MarkerPairKinematics RandomKinematics(std::mt19937& rng, double max_angle = 2.0) {
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  auto vec = [&] { return Vec3(u(rng), u(rng), u(rng)); };
  MarkerPairKinematics k;
  k.p_i = vec();
  k.p_j = vec();
  k.R_j = Eigen::Quaterniond(Eigen::Vector4d(u(rng), u(rng), u(rng), u(rng)).normalized())
              .toRotationMatrix();
  const Vec3 axis = vec().normalized();
  k.R_i = Exp(max_angle * std::abs(u(rng)) * axis) * k.R_j;
  k.v_i = 2 * vec();
  k.v_j = 2 * vec();
  k.w_i = 3 * vec();
  k.w_j = 3 * vec();
  return k;
}

BushingParameters RandomParameters(std::mt19937& rng) {
  std::uniform_real_distribution<double> u(0.5, 2.0);
  BushingParameters p;
  for (int c = 0; c < 6; ++c) {
    p.stiffness[c] = (c < 3 ? 1e5 : 1e3) * u(rng);
    p.damping[c] = (c < 3 ? 1e2 : 1.0) * u(rng);
  }
  return p;
}

TEST(Bushing, JacobianMatchesCentralFiniteDifferences) {
  std::mt19937 rng(21);
  double worst = 0;
  for (int trial = 0; trial < 40; ++trial) {
    const BushingParameters p = RandomParameters(rng);
    const MarkerPairKinematics k = RandomKinematics(rng);
    ForceJacobian J;
    const ForceTorque y = EvaluateBushing(p, k, &J);
    const ForceTorque y2 = EvaluateBushing(p, k);  // same value without the Jacobian
    EXPECT_EQ(y.force, y2.force);
    EXPECT_EQ(y.torque, y2.torque);
    const ForceJacobian fd = FiniteDifferenceJacobian(
        [&](const MarkerPairKinematics& m) { return EvaluateBushing(p, m); }, k);
    // Relative per row block (forces and torques have different scales).
    for (int b = 0; b < 2; ++b) {
      const double scale = J.middleRows<3>(3 * b).cwiseAbs().maxCoeff();
      const double err = (J - fd).middleRows<3>(3 * b).cwiseAbs().maxCoeff() / scale;
      worst = std::max(worst, err);
      EXPECT_LT(err, 1e-7) << "trial " << trial << " block " << b;
    }
  }
  std::printf("bushing Jacobian vs central FD: worst relative difference %.3g\n", worst);
}

TEST(Bushing, ZeroForceAtZeroDeflectionAndUnderRigidMotion) {
  std::mt19937 rng(22);
  const BushingParameters p = RandomParameters(rng);
  MarkerPairKinematics k = RandomKinematics(rng);
  k.p_i = k.p_j;
  k.R_i = k.R_j;
  k.v_i = k.v_j;
  k.w_i = k.w_j;
  ForceTorque y = EvaluateBushing(p, k);
  EXPECT_EQ(y.force.norm(), 0.0);
  EXPECT_LT(y.torque.norm(), 1e-12);
  // A damper-only bushing with a deflection, both markers moving as one rigid body:
  // the rates vanish, so does the force.
  BushingParameters damper = p;
  damper.stiffness.setZero();
  k = RandomKinematics(rng);
  k.w_i = k.w_j;
  k.v_i = k.v_j + k.w_j.cross(k.p_i - k.p_j);
  const BushingDeflection b = ComputeBushingDeflection(k);
  EXPECT_LT(b.d_dot.norm(), 1e-14);
  EXPECT_LT(b.theta_dot.norm(), 1e-14);
  y = EvaluateBushing(damper, k);
  EXPECT_LT(y.force.norm(), 1e-11);
  EXPECT_LT(y.torque.norm(), 1e-13);
}

TEST(Bushing, SmallDeflectionStiffnessAndDampingAreKAndD) {
  std::mt19937 rng(23);
  const BushingParameters p = RandomParameters(rng);
  MarkerPairKinematics k = RandomKinematics(rng);
  k.p_i = k.p_j;
  k.R_i = k.R_j;
  // At rest (with w_j != 0, d' depends on p_i through w_j x r: a damping term in dF/dp_i).
  k.v_i = k.v_j = k.w_i = k.w_j = Vec3::Zero();
  ForceJacobian J;
  EvaluateBushing(p, k, &J);
  const Mat3& A = k.R_j;
  const Mat3 Kt = A.transpose() * J.block<3, 3>(0, kPi) * A;
  const Mat3 Kr = A.transpose() * J.block<3, 3>(3, kPhiI) * A;
  const Mat3 Dt = A.transpose() * J.block<3, 3>(0, kVi) * A;
  const Mat3 Dr = A.transpose() * J.block<3, 3>(3, kWi) * A;
  EXPECT_LT((Kt + Mat3(p.stiffness.head<3>().asDiagonal())).norm(), 1e-9 * 1e5);
  EXPECT_LT((Kr + Mat3(p.stiffness.tail<3>().asDiagonal())).norm(), 1e-12 * 1e3);
  EXPECT_LT((Dt + Mat3(p.damping.head<3>().asDiagonal())).norm(), 1e-12 * 1e2);
  EXPECT_LT((Dr + Mat3(p.damping.tail<3>().asDiagonal())).norm(), 1e-12);
  // A small deflection along one j axis at a time: force/torque = -K * deflection.
  for (int c = 0; c < 3; ++c) {
    const double eps = 1e-6;
    MarkerPairKinematics m = k;
    m.v_i = m.v_j = m.w_i = m.w_j = Vec3::Zero();
    m.p_i = m.p_j + eps * A.col(c);
    ForceTorque y = EvaluateBushing(p, m);
    EXPECT_NEAR((A.transpose() * y.force)[c], -p.stiffness[c] * eps, 1e-12 * p.stiffness[c]);
    m.p_i = m.p_j;
    m.R_i = Exp(eps * A.col(c)) * m.R_j;
    y = EvaluateBushing(p, m);
    // 2 sin(eps/2) = eps (1 - eps^2/24): relative 4e-14
    // (theta comes from the rotation matrix entries: absolute rounding ~1e-16 rad)
    EXPECT_NEAR((A.transpose() * y.torque)[c], -p.stiffness[3 + c] * eps,
                1e-9 * p.stiffness[3 + c] * eps);
  }
}

TEST(Bushing, SpringIsMinusGradientOfPotentialForBothMarkers) {
  std::mt19937 rng(24);
  double worst = 0;
  for (int trial = 0; trial < 20; ++trial) {
    BushingParameters p = RandomParameters(rng);
    p.damping.setZero();
    const MarkerPairKinematics k = RandomKinematics(rng);
    const ForceTorque y = EvaluateBushing(p, k);
    const Vec3 r = k.p_i - k.p_j;
    const Vec3 force_j = -y.force, torque_j = -y.torque - r.cross(y.force);
    Eigen::Matrix<double, 12, 1> expected, gradient;
    expected << y.force, y.torque, force_j, torque_j;
    for (int c = 0; c < 12; ++c) {  // p_i, phi_i, p_j, phi_j
      const double h = 1e-4;  // truncation ~1e-8 relative, rounding of V ~1e-11
      gradient[c] = (BushingPotential(p, PerturbInput(k, c, h)) -
                     BushingPotential(p, PerturbInput(k, c, -h))) / (2 * h);
    }
    for (int b = 0; b < 4; ++b) {
      const double err = (expected.segment<3>(3 * b) + gradient.segment<3>(3 * b)).norm() /
                         expected.segment<3>(3 * b).norm();
      worst = std::max(worst, err);
      EXPECT_LT(err, 1e-7) << "trial " << trial << " block " << b;
    }
  }
  std::printf("bushing spring vs -dV/dx: worst relative difference %.3g\n", worst);
}

TEST(Bushing, RatesAreTimeDerivativesAndDamperDissipates) {
  std::mt19937 rng(25);
  for (int trial = 0; trial < 10; ++trial) {
    BushingParameters p = RandomParameters(rng);
    const MarkerPairKinematics k = RandomKinematics(rng);
    // Motion with constant velocities: p(t) = p + v t, R(t) = exp(skew(w) t) R.
    auto at = [&](double t) {
      MarkerPairKinematics m = k;
      m.p_i += t * k.v_i;
      m.p_j += t * k.v_j;
      m.R_i = Exp(t * k.w_i) * k.R_i;
      m.R_j = Exp(t * k.w_j) * k.R_j;
      return ComputeBushingDeflection(m);
    };
    const double h = 1e-5;
    const BushingDeflection b = ComputeBushingDeflection(k), bp = at(h), bm = at(-h);
    EXPECT_LT(((bp.d - bm.d) / (2 * h) - b.d_dot).norm(), 1e-8 * (1 + b.d_dot.norm()));
    EXPECT_LT(((bp.theta - bm.theta) / (2 * h) - b.theta_dot).norm(),
              1e-8 * (1 + b.theta_dot.norm()));
    // Power of the damper-only pair (i and j) = -(d'^T D_t d' + theta'^T D_r theta').
    p.stiffness.setZero();
    const ForceTorque y = EvaluateBushing(p, k);
    const Vec3 r = k.p_i - k.p_j;
    const double power = y.force.dot(k.v_i) + y.torque.dot(k.w_i) - y.force.dot(k.v_j) +
                         (-y.torque - r.cross(y.force)).dot(k.w_j);
    const double dissipation = b.d_dot.dot(p.damping.head<3>().cwiseProduct(b.d_dot)) +
                               b.theta_dot.dot(p.damping.tail<3>().cwiseProduct(b.theta_dot));
    EXPECT_GT(dissipation, 0);
    EXPECT_NEAR(power, -dissipation, 1e-12 * dissipation);
  }
}

TEST(Bushing, RotationMeasureIsTwiceSineOfHalfAngle) {
  std::mt19937 rng(26);
  MarkerPairKinematics k = RandomKinematics(rng);
  const Vec3 axis_j = Vec3(0.3, -0.5, 0.8).normalized();  // in j's axes
  for (double angle : {1e-3, 0.5, 1.5, 3.0, -2.0}) {
    k.R_i = k.R_j * Exp(angle * axis_j);
    const BushingDeflection b = ComputeBushingDeflection(k);
    EXPECT_LT((b.theta - 2 * std::sin(angle / 2) * axis_j).norm(), 1e-14) << angle;
    EXPECT_GE(b.e[0], 0.0);
  }
}

TEST(Bushing, ParameterValidation) {
  BushingParameters p;
  std::string error;
  EXPECT_TRUE(p.IsValid(&error));
  p.damping[4] = -1;
  EXPECT_FALSE(p.IsValid(&error));
  EXPECT_EQ(error, "bushing: damping[4] must be finite and >= 0");
  p.damping[4] = 0;
  p.stiffness[0] = std::nan("");
  EXPECT_FALSE(p.IsValid(&error));
  EXPECT_EQ(error, "bushing: stiffness[0] must be finite and >= 0");
}

}  // namespace
}  // namespace mbdae::mbs
