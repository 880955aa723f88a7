#include "mbs/bushing.h"

#include <cmath>
#include <string>

namespace mbdae::mbs {
namespace {

using Vec3 = Eigen::Vector3d;
using Mat3 = Eigen::Matrix3d;
using Mat3x24 = Eigen::Matrix<double, 3, 24>;

Mat3 Skew(const Vec3& a) {
  Mat3 s;
  s << 0, -a.z(), a.y(), a.z(), 0, -a.x(), -a.y(), a.x(), 0;
  return s;
}

// Unit quaternion (e0, e1, e2, e3), e0 >= 0, of a rotation matrix; Shepperd's method
// (S. W. Shepperd, J. Guidance and Control 1(3), 1978): take the largest of
// 4 e0^2 = 1 + tr R and 4 e_k^2 = 1 + 2 R_kk - tr R for the square root.
Eigen::Vector4d QuaternionOf(const Mat3& R) {
  const double tr = R.trace();
  Eigen::Vector4d e;
  const double c[4] = {1 + tr, 1 + 2 * R(0, 0) - tr, 1 + 2 * R(1, 1) - tr, 1 + 2 * R(2, 2) - tr};
  int m = 0;
  for (int k = 1; k < 4; ++k)
    if (c[k] > c[m]) m = k;
  const double s = 0.5 * std::sqrt(c[m]);  // |e_m|
  const double q = 0.25 / s;
  switch (m) {
    case 0:
      e << s, (R(2, 1) - R(1, 2)) * q, (R(0, 2) - R(2, 0)) * q, (R(1, 0) - R(0, 1)) * q;
      break;
    case 1:
      e << (R(2, 1) - R(1, 2)) * q, s, (R(0, 1) + R(1, 0)) * q, (R(0, 2) + R(2, 0)) * q;
      break;
    case 2:
      e << (R(0, 2) - R(2, 0)) * q, (R(0, 1) + R(1, 0)) * q, s, (R(1, 2) + R(2, 1)) * q;
      break;
    default:
      e << (R(1, 0) - R(0, 1)) * q, (R(0, 2) + R(2, 0)) * q, (R(1, 2) + R(2, 1)) * q, s;
      break;
  }
  if (e[0] < 0) e = -e;
  return e.normalized();
}

}  // namespace

bool BushingParameters::IsValid(std::string* error) const {
  for (int k = 0; k < 6; ++k) {
    if (!(std::isfinite(stiffness[k]) && stiffness[k] >= 0)) {
      if (error) *error = "bushing: stiffness[" + std::to_string(k) + "] must be finite and >= 0";
      return false;
    }
    if (!(std::isfinite(damping[k]) && damping[k] >= 0)) {
      if (error) *error = "bushing: damping[" + std::to_string(k) + "] must be finite and >= 0";
      return false;
    }
  }
  return true;
}

BushingDeflection ComputeBushingDeflection(const MarkerPairKinematics& k) {
  BushingDeflection b;
  const Mat3 AjT = k.R_j.transpose();
  const Vec3 r = k.p_i - k.p_j;
  b.d = AjT * r;
  b.d_dot = AjT * (k.v_i - k.v_j - k.w_j.cross(r));
  b.e = QuaternionOf(AjT * k.R_i);
  const double e0 = b.e[0];
  const Vec3 ev = b.e.tail<3>();
  b.theta = 2 * ev;
  const Vec3 omega = AjT * (k.w_i - k.w_j);
  b.theta_dot = e0 * omega - ev.cross(omega);  // L Omega
  return b;
}

double BushingPotential(const BushingParameters& p, const MarkerPairKinematics& k) {
  const BushingDeflection b = ComputeBushingDeflection(k);
  return 0.5 * (b.d.cwiseProduct(p.stiffness.head<3>()).dot(b.d) +
                b.theta.cwiseProduct(p.stiffness.tail<3>()).dot(b.theta));
}

ForceTorque EvaluateBushing(const BushingParameters& p, const MarkerPairKinematics& k,
                            ForceJacobian* jacobian) {
  const BushingDeflection b = ComputeBushingDeflection(k);
  const Vec3 kt = p.stiffness.head<3>(), kr = p.stiffness.tail<3>();
  const Vec3 ct = p.damping.head<3>(), cr = p.damping.tail<3>();
  const double e0 = b.e[0];
  const Vec3 ev = b.e.tail<3>();
  const Mat3 L = e0 * Mat3::Identity() - Skew(ev);
  // Generalized forces conjugate to d and theta.
  const Vec3 f = -(kt.cwiseProduct(b.d) + ct.cwiseProduct(b.d_dot));
  const Vec3 g = -(kr.cwiseProduct(b.theta) + cr.cwiseProduct(b.theta_dot));
  const Vec3 h = L.transpose() * g;
  ForceTorque y;
  y.force = k.R_j * f;
  y.torque = k.R_j * h;
  if (!jacobian) return y;

  // Jacobians of the intermediate quantities with respect to the 24 inputs.
  const Mat3& Aj = k.R_j;
  const Mat3 AjT = Aj.transpose();
  const Vec3 r = k.p_i - k.p_j;
  const Vec3 u = k.v_i - k.v_j - k.w_j.cross(r);
  const Vec3 wr = k.w_i - k.w_j;
  const Vec3 omega = AjT * wr;
  // delta(A_j^T x) = A_j^T skew(x) dphi_j for a world rotation dphi_j of A_j.
  Mat3x24 Jd = Mat3x24::Zero(), Jdd = Mat3x24::Zero(), Jdelta = Mat3x24::Zero(),
          Jomega = Mat3x24::Zero();
  Jd.block<3, 3>(0, kPi) = AjT;
  Jd.block<3, 3>(0, kPj) = -AjT;
  Jd.block<3, 3>(0, kPhiJ) = AjT * Skew(r);
  Jdd.block<3, 3>(0, kPi) = -AjT * Skew(k.w_j);
  Jdd.block<3, 3>(0, kPj) = AjT * Skew(k.w_j);
  Jdd.block<3, 3>(0, kVi) = AjT;
  Jdd.block<3, 3>(0, kVj) = -AjT;
  Jdd.block<3, 3>(0, kWj) = AjT * Skew(r);
  Jdd.block<3, 3>(0, kPhiJ) = AjT * Skew(u);
  // R = A_j^T A_i moves by the left rotation delta = A_j^T (dphi_i - dphi_j) (j's axes);
  // e -> (1, delta/2) (x) e: de0 = -1/2 e_v^T delta, de_v = 1/2 L delta.
  Jdelta.block<3, 3>(0, kPhiI) = AjT;
  Jdelta.block<3, 3>(0, kPhiJ) = -AjT;
  Jomega.block<3, 3>(0, kWi) = AjT;
  Jomega.block<3, 3>(0, kWj) = -AjT;
  Jomega.block<3, 3>(0, kPhiJ) = AjT * Skew(wr);
  const Mat3x24 Jtheta = L * Jdelta;
  // theta' = e0 Omega + Omega x e_v
  const Mat3 M = -0.5 * omega * ev.transpose() + 0.5 * Skew(omega) * L;
  const Mat3x24 Jtheta_dot = L * Jomega + M * Jdelta;
  const Mat3x24 Jf = -(kt.asDiagonal() * Jd + ct.asDiagonal() * Jdd);
  const Mat3x24 Jg = -(kr.asDiagonal() * Jtheta + cr.asDiagonal() * Jtheta_dot);
  // h = L^T g = e0 g + e_v x g
  const Mat3 N = -0.5 * g * ev.transpose() - 0.5 * Skew(g) * L;
  const Mat3x24 Jh = L.transpose() * Jg + N * Jdelta;
  jacobian->topRows<3>() = Aj * Jf;
  jacobian->bottomRows<3>() = Aj * Jh;
  // delta(A_j x) = -skew(A_j x) dphi_j
  jacobian->block<3, 3>(0, kPhiJ) -= Skew(y.force);
  jacobian->block<3, 3>(3, kPhiJ) -= Skew(y.torque);
  return y;
}

}  // namespace mbdae::mbs
