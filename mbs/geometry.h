// Mass properties of the primitive shapes (homogeneous, density given).
#pragma once

#include "mbs/model.h"

namespace mbdae::mbs {

struct MassProperties {
  double mass = 0;
  Mat3 inertia = Mat3::Zero();  // about the centre of mass, shape axes
};

// Sphere of radius r.
MassProperties SphereMass(double radius, double density);
// Solid cylinder along z, centred at its centre of mass.
MassProperties CylinderMass(double radius, double length, double density);
// Solid cone along z (apex towards +z), about its centre of mass (length/4 above the base).
MassProperties ConeMass(double radius, double length, double density);
// Box with edge lengths (a, b, c) along x, y, z.
MassProperties BoxMass(const Vec3& size, double density);

}  // namespace mbdae::mbs
