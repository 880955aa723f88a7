// Common inputs and outputs of the two-marker force laws (user forces, bushings): the
// absolute kinematics of markers i and j in world axes, the force and torque on marker i
// (world axes; the reaction on j is force_j = -force, torque_j = -torque - (p_i - p_j) x
// force), and their 6 x 24 Jacobian with respect to
//     x = (p_i, phi_i, p_j, phi_j, v_i, w_i, v_j, w_j)
// (offsets kPi ... kWj), phi a small rotation in world axes, R -> exp(skew(phi)) R, all
// 24 inputs independent. This is the layout of api/mbdae_user_force.h, so the system
// chains both force laws into dQ/dq and dQ/dv the same way:
//   dp/dq = d(r_b + A_b s)/dq,  dphi = 2 E(e) de (unit e),  v = r_b' + w x (A_b s), ...
#pragma once

#include <Eigen/Dense>
#include <functional>

namespace mbdae::mbs {

struct MarkerPairKinematics {
  Eigen::Vector3d p_i = Eigen::Vector3d::Zero(), p_j = Eigen::Vector3d::Zero();
  Eigen::Matrix3d R_i = Eigen::Matrix3d::Identity(), R_j = Eigen::Matrix3d::Identity();
  Eigen::Vector3d v_i = Eigen::Vector3d::Zero(), v_j = Eigen::Vector3d::Zero();
  Eigen::Vector3d w_i = Eigen::Vector3d::Zero(), w_j = Eigen::Vector3d::Zero();
};

struct ForceTorque {
  Eigen::Vector3d force = Eigen::Vector3d::Zero();   // on marker i, world axes
  Eigen::Vector3d torque = Eigen::Vector3d::Zero();  // on marker i, world axes
};

// Rows: force x,y,z then torque x,y,z. Columns: the offsets below.
using ForceJacobian = Eigen::Matrix<double, 6, 24>;

enum ForceInput : int { kPi = 0, kPhiI = 3, kPj = 6, kPhiJ = 9, kVi = 12, kWi = 15, kVj = 18, kWj = 21 };

// The kinematics with input c (0..23) moved by h: positions and velocities by adding h to
// the component, rotations by R -> exp(skew(h e_k)) R (Rodrigues' formula, exact).
MarkerPairKinematics PerturbInput(const MarkerPairKinematics& k, int c, double h);

// Central finite-difference Jacobian of f at k. Step for input c:
//   h = relative_step * max(1, |x_c|)  for positions and velocities,
//   h = relative_step                  for rotations (phi = 0 at the evaluation point);
// the default relative_step = cbrt(machine epsilon) ~ 6.06e-6 balances the O(h^2)
// truncation error of central differences against the O(eps/h) rounding error.
// Costs 48 evaluations of f.
inline constexpr double kDefaultFdRelativeStep = 6.0554544523933395e-06;
ForceJacobian FiniteDifferenceJacobian(
    const std::function<ForceTorque(const MarkerPairKinematics&)>& f,
    const MarkerPairKinematics& k, double relative_step = kDefaultFdRelativeStep);

}  // namespace mbdae::mbs
