// Euler parameter kinematics: identities of E, G and A, derivatives, and the
// conversions from a rotation matrix and from an axis and angle.
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "mbs/kinematics.h"

namespace mbdae::mbs {
namespace {

Quat RandomUnitQuat(std::mt19937& rng) {
  std::normal_distribution<double> n(0.0, 1.0);
  Quat e(n(rng), n(rng), n(rng), n(rng));
  return e / e.norm();
}

TEST(Kinematics, SkewIsCrossProduct) {
  const Vec3 a(0.3, -1.2, 2.5), b(-0.7, 0.4, 1.1);
  EXPECT_LT((Skew(a) * b - a.cross(b)).norm(), 1e-15);
  EXPECT_LT((Skew(a) + Skew(a).transpose()).norm(), 1e-15);
}

TEST(Kinematics, RotationMatrixIsEGtAndOrthonormal) {
  std::mt19937 rng(1);
  for (int k = 0; k < 50; ++k) {
    const Quat e = RandomUnitQuat(rng);
    const Mat3 A = RotationMatrix(e);
    EXPECT_LT((A - EMatrix(e) * GMatrix(e).transpose()).norm(), 1e-14);
    EXPECT_LT((A.transpose() * A - Mat3::Identity()).norm(), 1e-14);
    EXPECT_NEAR(A.determinant(), 1.0, 1e-14);
    // E e = G e = 0 and E E^T = G G^T = I for unit e (Nikravesh eq. 6.76)
    EXPECT_LT((EMatrix(e) * e).norm(), 1e-15);
    EXPECT_LT((GMatrix(e) * e).norm(), 1e-15);
    EXPECT_LT((EMatrix(e) * EMatrix(e).transpose() - Mat3::Identity()).norm(), 1e-14);
    EXPECT_LT((GMatrix(e) * GMatrix(e).transpose() - Mat3::Identity()).norm(), 1e-14);
    // A = E G^T holds for any e, not only unit ones.
    const Quat f = 1.7 * e + Quat(0.1, -0.2, 0.3, 0.05);
    EXPECT_LT((RotationMatrix(f) - EMatrix(f) * GMatrix(f).transpose()).norm(), 1e-13);
  }
}

TEST(Kinematics, AxisAngleMatchesRodrigues) {
  const Vec3 axis = Vec3(1, -2, 0.5);
  const double angle = 0.9;
  const Vec3 u = axis.normalized();
  // Rodrigues: A = I + sin(a) [u] + (1 - cos(a)) [u]^2
  const Mat3 R = Mat3::Identity() + std::sin(angle) * Skew(u) +
                 (1 - std::cos(angle)) * Skew(u) * Skew(u);
  const Quat e = QuaternionFromAxisAngle(axis, angle);
  EXPECT_NEAR(e.norm(), 1.0, 1e-15);
  EXPECT_LT((RotationMatrix(e) - R).norm(), 1e-14);
  // Rotation about z by 90 degrees maps x to y.
  const Mat3 Az = RotationMatrix(QuaternionFromAxisAngle(Vec3(0, 0, 1), M_PI / 2));
  EXPECT_LT((Az * Vec3(1, 0, 0) - Vec3(0, 1, 0)).norm(), 1e-15);
  EXPECT_EQ(QuaternionFromAxisAngle(Vec3::Zero(), 0.0), Quat(1, 0, 0, 0));
  EXPECT_THROW(QuaternionFromAxisAngle(Vec3::Zero(), 0.3), std::invalid_argument);
}

TEST(Kinematics, QuaternionFromMatrixRoundTrip) {
  std::mt19937 rng(2);
  for (int k = 0; k < 200; ++k) {
    Quat e = RandomUnitQuat(rng);
    // Also exercise the four branches of Shepperd's method with near-180-degree turns.
    if (k % 4 == 1) e = QuaternionFromAxisAngle(Vec3(1, 0.01 * k, 0), M_PI - 1e-9 * k);
    if (k % 4 == 2) e = QuaternionFromAxisAngle(Vec3(0.01 * k, 1, 0), M_PI);
    if (k % 4 == 3) e = QuaternionFromAxisAngle(Vec3(0, 0.02, 1), M_PI);
    const Quat r = QuaternionFromMatrix(RotationMatrix(e));
    EXPECT_NEAR(r.norm(), 1.0, 1e-15);
    EXPECT_GE(r[0], 0.0);
    const double err = std::min((r - e).norm(), (r + e).norm());
    EXPECT_LT(err, 1e-14) << "k = " << k;
  }
  EXPECT_LT((QuaternionFromMatrix(Mat3::Identity()) - Quat(1, 0, 0, 0)).norm(), 1e-16);
}

// A(e) differentiated along a rate e': dA/dt = E(e') G(e)^T + E(e) G(e')^T, and the
// angular velocities: skew(omega) = A' A^T with omega = 2 E e' (world), A^T A' =
// skew(2 G e') (body), for unit e and e' with e.e' = 0.
TEST(Kinematics, AngularVelocityMatchesFiniteDifferences) {
  std::mt19937 rng(3);
  std::normal_distribution<double> n(0.0, 1.0);
  for (int k = 0; k < 20; ++k) {
    const Quat e = RandomUnitQuat(rng);
    Quat ed(n(rng), n(rng), n(rng), n(rng));
    ed -= e.dot(ed) * e;  // tangent to the unit sphere
    const double h = 1e-6;
    const Mat3 Ad = (RotationMatrix(e + h * ed) - RotationMatrix(e - h * ed)) / (2 * h);
    const Mat3 Ad_exact = EMatrix(ed) * GMatrix(e).transpose() + EMatrix(e) * GMatrix(ed).transpose();
    EXPECT_LT((Ad - Ad_exact).norm() / std::max(1.0, Ad_exact.norm()), 1e-8);
    const Mat3 A = RotationMatrix(e);
    EXPECT_LT((Ad_exact * A.transpose() - Skew(2 * EMatrix(e) * ed)).norm(), 1e-13);
    EXPECT_LT((A.transpose() * Ad_exact - Skew(2 * GMatrix(e) * ed)).norm(), 1e-13);
  }
}

}  // namespace
}  // namespace mbdae::mbs
