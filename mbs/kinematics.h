// Euler parameter kinematics (Nikravesh, Computer-Aided Analysis of Mechanical
// Systems, 1988, ch. 6): e = (e0, e1, e2, e3), A = E G^T, omega (world) = 2 E e',
// omega' (body) = 2 G e'.
#pragma once

#include "mbs/model.h"

namespace mbdae::mbs {

using Mat34 = Eigen::Matrix<double, 3, 4>;

Mat3 Skew(const Vec3& a);
Mat34 EMatrix(const Quat& e);  // [-e_v, skew(e_v) + e0 I]
Mat34 GMatrix(const Quat& e);  // [-e_v, -skew(e_v) + e0 I]
Mat3 RotationMatrix(const Quat& e);  // body to world
Quat QuaternionFromMatrix(const Mat3& A);
Quat QuaternionFromAxisAngle(const Vec3& axis, double angle);

}  // namespace mbdae::mbs
