// Euler parameter kinematics; formulas from Nikravesh, Computer-Aided Analysis of
// Mechanical Systems (1988), ch. 6, and Shepperd, "Quaternion from rotation matrix",
// J. Guidance and Control 1(3), 1978.
#include "mbs/kinematics.h"

#include <algorithm>
#include <cmath>
#include <sstream>
#include <stdexcept>

namespace mbdae::mbs {

Mat3 Skew(const Vec3& a) {
  Mat3 s;
  s << 0, -a.z(), a.y(),  //
      a.z(), 0, -a.x(),   //
      -a.y(), a.x(), 0;
  return s;
}

Mat34 EMatrix(const Quat& e) {
  // E = [-e_v, skew(e_v) + e0 I]   (Nikravesh eq. 6.75)
  Mat34 m;
  m << -e[1], e[0], -e[3], e[2],  //
      -e[2], e[3], e[0], -e[1],   //
      -e[3], -e[2], e[1], e[0];
  return m;
}



Quat QuaternionFromMatrix(const Mat3& A) {
  // Shepperd's method: pick the largest of 4 e0^2, 4 e1^2, 4 e2^2, 4 e3^2 (computed from
  // the trace and the diagonal) and derive the other three from off-diagonal sums or
  // differences, which avoids dividing by a small number.
  const double tr = A.trace();
  const double c[4] = {1 + tr, 1 + 2 * A(0, 0) - tr, 1 + 2 * A(1, 1) - tr,
                       1 + 2 * A(2, 2) - tr};  // 4 e_k^2
  int k = 0;
  for (int i = 1; i < 4; ++i)
    if (c[i] > c[k]) k = i;
  Quat e;
  const double s = 2 * std::sqrt(std::max(c[k], 0.0));  // 4 e_k
  switch (k) {
    case 0:
      e << s / 4, (A(2, 1) - A(1, 2)) / s, (A(0, 2) - A(2, 0)) / s, (A(1, 0) - A(0, 1)) / s;
      break;
    case 1:
      e << (A(2, 1) - A(1, 2)) / s, s / 4, (A(0, 1) + A(1, 0)) / s, (A(0, 2) + A(2, 0)) / s;
      break;
    case 2:
      e << (A(0, 2) - A(2, 0)) / s, (A(0, 1) + A(1, 0)) / s, s / 4, (A(1, 2) + A(2, 1)) / s;
      break;
    default:
      e << (A(1, 0) - A(0, 1)) / s, (A(0, 2) + A(2, 0)) / s, (A(1, 2) + A(2, 1)) / s, s / 4;
      break;
  }
  if (e[0] < 0) e = -e;  // canonical sign: e0 >= 0
  return e / e.norm();
}

Quat QuaternionFromAxisAngle(const Vec3& axis, double angle) {
  // The axis is first divided by its largest component, so that its length neither
  // overflows ([1e200, 1e200, 0]) nor underflows ([1e-200, 0, 0]).
  const double scale = axis.cwiseAbs().maxCoeff();
  if (!(scale > 0) || !std::isfinite(scale)) {
    if (scale == 0 && angle == 0) return Quat(1, 0, 0, 0);
    std::ostringstream msg;
    msg << "rotation axis [" << axis.x() << ", " << axis.y() << ", " << axis.z() << "] "
        << (scale == 0 ? "has zero length" : "is not finite");
    throw std::invalid_argument(msg.str());
  }
  const Vec3 unit = (axis / scale).normalized();
  Quat e;
  e[0] = std::cos(angle / 2);
  e.tail<3>() = std::sin(angle / 2) * unit;
  return e;
}

}  // namespace mbdae::mbs
