#include "mbs/force_law.h"

#include <algorithm>
#include <cassert>
#include <cmath>

namespace mbdae::mbs {
namespace {

// exp(skew(phi)) by Rodrigues' formula.
Eigen::Matrix3d RotationExp(const Eigen::Vector3d& phi) {
  const double a = phi.norm();
  Eigen::Matrix3d s;
  s << 0, -phi.z(), phi.y(), phi.z(), 0, -phi.x(), -phi.y(), phi.x(), 0;
  if (a < 1e-300) return Eigen::Matrix3d::Identity();
  return Eigen::Matrix3d::Identity() + std::sin(a) / a * s +
         (1 - std::cos(a)) / (a * a) * s * s;
}

}  // namespace

MarkerPairKinematics PerturbInput(const MarkerPairKinematics& k, int c, double h) {
  assert(c >= 0 && c < 24);
  MarkerPairKinematics out = k;
  const int block = c / 3, comp = c % 3;
  Eigen::Vector3d phi = Eigen::Vector3d::Zero();
  phi[comp] = h;
  switch (block) {
    case 0: out.p_i[comp] += h; break;
    case 1: out.R_i = RotationExp(phi) * k.R_i; break;
    case 2: out.p_j[comp] += h; break;
    case 3: out.R_j = RotationExp(phi) * k.R_j; break;
    case 4: out.v_i[comp] += h; break;
    case 5: out.w_i[comp] += h; break;
    case 6: out.v_j[comp] += h; break;
    case 7: out.w_j[comp] += h; break;
  }
  return out;
}

ForceJacobian FiniteDifferenceJacobian(
    const std::function<ForceTorque(const MarkerPairKinematics&)>& f,
    const MarkerPairKinematics& k, double relative_step) {
  ForceJacobian J;
  for (int c = 0; c < 24; ++c) {
    const int block = c / 3, comp = c % 3;
    double x = 0;  // the input's current value (rotations: 0)
    switch (block) {
      case 0: x = k.p_i[comp]; break;
      case 2: x = k.p_j[comp]; break;
      case 4: x = k.v_i[comp]; break;
      case 5: x = k.w_i[comp]; break;
      case 6: x = k.v_j[comp]; break;
      case 7: x = k.w_j[comp]; break;
      default: break;
    }
    const double h = relative_step * std::max(1.0, std::abs(x));
    const ForceTorque plus = f(PerturbInput(k, c, h));
    const ForceTorque minus = f(PerturbInput(k, c, -h));
    J.block<3, 1>(0, c) = (plus.force - minus.force) / (2 * h);
    J.block<3, 1>(3, c) = (plus.torque - minus.torque) / (2 * h);
  }
  return J;
}

}  // namespace mbdae::mbs
