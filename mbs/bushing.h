// Bushing: a linear 6-axis spring-damper between markers i and j, in marker j's axes
// (model format: `type: bushing`, `stiffness: [kx, ky, kz, krx, kry, krz]`,
// `damping: [cx, cy, cz, crx, cry, crz]`). Full derivation and conventions:
// docs/bushing.md.
//
// Deflections (j's axes; A_i, A_j marker axes -> world; r = p_i - p_j):
//   d     = A_j^T r                                      translational
//   theta = 2 e_v,  e = (e0, e_v) the unit quaternion of R = A_j^T A_i with e0 >= 0
//           (= 2 sin(phi/2) a for a rotation by phi about the unit axis a, |phi| < pi;
//           equal to the rotation vector phi a to third order)
// Rates, their exact time derivatives:
//   d'     = A_j^T (v_i - v_j - w_j x r)
//   theta' = L Omega,  Omega = A_j^T (w_i - w_j),  L = e0 I - skew(e_v)
// Generalized forces (conjugate to d and theta): f = -(K_t d + D_t d'),
// g = -(K_r theta + D_r theta') (diagonal K, D). Virtual work f.dd + g.dtheta gives the
// force and torque on marker i, world axes:
//   force = A_j f,   torque = A_j L^T g,
// and the reaction on j as in force_law.h. The spring part derives from the potential
//   V = 1/2 d^T K_t d + 1/2 theta^T K_r theta   (force = -dV/dp_i, torque = -dV/dphi_i);
// the damper dissipates d'^T D_t d' + theta'^T D_r theta' >= 0.
// theta is smooth for relative rotations below pi; at pi (e0 = 0) it jumps (a bushing
// is meant for small deflections).
#pragma once

#include <Eigen/Dense>
#include <string>

#include "mbs/force_law.h"

namespace mbdae::mbs {

using Vec6 = Eigen::Matrix<double, 6, 1>;

struct BushingParameters {
  Vec6 stiffness = Vec6::Zero();  // kx, ky, kz (N/m), krx, kry, krz (N m/rad)
  Vec6 damping = Vec6::Zero();    // cx, cy, cz (N s/m), crx, cry, crz (N m s/rad)
  // Every entry finite and >= 0.
  bool IsValid(std::string* error) const;
};

struct BushingDeflection {
  Eigen::Vector3d d, theta;            // translational, rotational (j's axes)
  Eigen::Vector3d d_dot, theta_dot;    // their time derivatives
  Eigen::Vector4d e;                   // relative quaternion (e0 >= 0)
};

BushingDeflection ComputeBushingDeflection(const MarkerPairKinematics& k);

// Force and torque on marker i (world axes) and, if jacobian is not null, their exact
// 6 x 24 Jacobian (force_law.h layout).
ForceTorque EvaluateBushing(const BushingParameters& p, const MarkerPairKinematics& k,
                            ForceJacobian* jacobian = nullptr);

// The spring potential V = 1/2 d^T K_t d + 1/2 theta^T K_r theta.
double BushingPotential(const BushingParameters& p, const MarkerPairKinematics& k);

}  // namespace mbdae::mbs
