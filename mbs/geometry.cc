// Mass properties of homogeneous primitive shapes, closed forms (e.g. Meriam & Kraige,
// Engineering Mechanics: Dynamics, table D/4, "Properties of homogeneous solids").
#include "mbs/geometry.h"

#include <cmath>
#include <stdexcept>
#include <string>

namespace mbdae::mbs {

namespace {

void Require(bool ok, const char* what, double value) {
  if (!ok) throw std::invalid_argument(std::string(what) + ", got " + std::to_string(value));
}

void CheckDensity(double density) {
  Require(std::isfinite(density) && density >= 0, "density must be >= 0", density);
}

}  // namespace

MassProperties SphereMass(double radius, double density) {
  Require(std::isfinite(radius) && radius > 0, "sphere radius must be > 0", radius);
  CheckDensity(density);
  MassProperties p;
  p.mass = 4.0 / 3.0 * M_PI * radius * radius * radius * density;
  p.inertia = Mat3::Identity() * (0.4 * p.mass * radius * radius);
  return p;
}

MassProperties CylinderMass(double radius, double length, double density) {
  Require(std::isfinite(radius) && radius > 0, "cylinder radius must be > 0", radius);
  Require(std::isfinite(length) && length > 0, "cylinder length must be > 0", length);
  CheckDensity(density);
  MassProperties p;
  p.mass = M_PI * radius * radius * length * density;
  const double transverse = p.mass * (3.0 * radius * radius + length * length) / 12.0;
  p.inertia.diagonal() << transverse, transverse, 0.5 * p.mass * radius * radius;
  return p;
}

MassProperties ConeMass(double radius, double length, double density) {
  Require(std::isfinite(radius) && radius > 0, "cone radius must be > 0", radius);
  Require(std::isfinite(length) && length > 0, "cone length must be > 0", length);
  CheckDensity(density);
  MassProperties p;
  p.mass = M_PI * radius * radius * length * density / 3.0;
  // About the centre of mass (h/4 above the base): Izz = 3/10 m r^2,
  // Ixx = Iyy = 3/20 m r^2 + 3/80 m h^2.
  const double transverse = p.mass * (3.0 / 20.0 * radius * radius + 3.0 / 80.0 * length * length);
  p.inertia.diagonal() << transverse, transverse, 0.3 * p.mass * radius * radius;
  return p;
}

MassProperties BoxMass(const Vec3& size, double density) {
  for (int k = 0; k < 3; ++k) {
    Require(std::isfinite(size[k]) && size[k] > 0, "box size must be > 0 along each axis", size[k]);
  }
  CheckDensity(density);
  MassProperties p;
  p.mass = size.prod() * density;
  const Vec3 s2 = size.cwiseProduct(size);
  p.inertia.diagonal() << p.mass * (s2[1] + s2[2]) / 12.0, p.mass * (s2[0] + s2[2]) / 12.0,
      p.mass * (s2[0] + s2[1]) / 12.0;
  return p;
}

}  // namespace mbdae::mbs
