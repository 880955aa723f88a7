// Euler parameter kinematics (Nikravesh, Computer-Aided Analysis of Mechanical
// Systems, 1988, ch. 6): e = (e0, e1, e2, e3), A = E G^T, omega (world) = 2 E e',
// omega' (body) = 2 G e'.
#pragma once

#include "mbs/model.h"

namespace mbdae::mbs {

using Mat34 = Eigen::Matrix<double, 3, 4>;

Mat3 Skew(const Vec3& a);
Mat34 EMatrix(const Quat& e);  // [-e_v, skew(e_v) + e0 I]
inline Mat34 GMatrix(const Quat& e);  // [-e_v, -skew(e_v) + e0 I]
inline Mat3 RotationMatrix(const Quat& e);  // body to world
Quat QuaternionFromMatrix(const Mat3& A);
// Rotation by `angle` about `axis` (any non-zero finite length: it is divided by its
// largest component before it is normalised, so [1e200, 1e200, 0] and [1e-200, 0, 0] are
// valid axes). A zero axis with angle 0 gives the identity; a zero axis with another
// angle, or a non-finite one, throws std::invalid_argument.
Quat QuaternionFromAxisAngle(const Vec3& axis, double angle);

// Inline: evaluated per body and per joint in every system evaluation.
inline Mat34 GMatrix(const Quat& e) {
  // G = [-e_v, -skew(e_v) + e0 I]   (Nikravesh eq. 6.75)
  Mat34 m;
  m << -e[1], e[0], e[3], -e[2],  //
      -e[2], -e[3], e[0], e[1],   //
      -e[3], e[2], -e[1], e[0];
  return m;
}

inline Mat3 RotationMatrix(const Quat& e) {
  // A = E G^T written out: (e0^2 - e_v.e_v) I + 2 e_v e_v^T + 2 e0 skew(e_v). This is
  // the product for any e (not only unit ones), so derivatives of A are those of E G^T.
  const double e0 = e[0], e1 = e[1], e2 = e[2], e3 = e[3];
  Mat3 A;
  A(0, 0) = e0 * e0 + e1 * e1 - e2 * e2 - e3 * e3;
  A(1, 1) = e0 * e0 - e1 * e1 + e2 * e2 - e3 * e3;
  A(2, 2) = e0 * e0 - e1 * e1 - e2 * e2 + e3 * e3;
  A(0, 1) = 2 * (e1 * e2 - e0 * e3);
  A(1, 0) = 2 * (e1 * e2 + e0 * e3);
  A(0, 2) = 2 * (e1 * e3 + e0 * e2);
  A(2, 0) = 2 * (e1 * e3 - e0 * e2);
  A(1, 2) = 2 * (e2 * e3 - e0 * e1);
  A(2, 1) = 2 * (e2 * e3 + e0 * e1);
  return A;
}

}  // namespace mbdae::mbs
