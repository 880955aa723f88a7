#include "mbs/geometry.h"

#include <gtest/gtest.h>

#include <cmath>
#include <stdexcept>

namespace mbdae::mbs {
namespace {

TEST(Geometry, SphereKnownValues) {
  // r = 0.1 m steel sphere: m = 4/3 pi r^3 rho = 32.6725635973 kg, I = 2/5 m r^2.
  const MassProperties p = SphereMass(0.1, 7800);
  EXPECT_NEAR(p.mass, 32.67256359733385, 1e-10);
  EXPECT_NEAR(p.inertia(0, 0), 0.4 * 32.67256359733385 * 0.01, 1e-12);
  EXPECT_TRUE(p.inertia.isDiagonal());
  EXPECT_EQ(p.inertia(0, 0), p.inertia(2, 2));
}

TEST(Geometry, CylinderKnownValues) {
  // r = 0.05, L = 0.4, rho = 1000: m = pi r^2 L rho = 3.14159265 kg;
  // Izz = m r^2 / 2, Ixx = Iyy = m (3 r^2 + L^2) / 12.
  const MassProperties p = CylinderMass(0.05, 0.4, 1000);
  const double m = M_PI;
  EXPECT_NEAR(p.mass, m, 1e-12);
  EXPECT_NEAR(p.inertia(2, 2), m * 0.0025 / 2, 1e-14);
  EXPECT_NEAR(p.inertia(0, 0), m * (3 * 0.0025 + 0.16) / 12, 1e-14);
  EXPECT_EQ(p.inertia(0, 0), p.inertia(1, 1));
  EXPECT_TRUE(p.inertia.isDiagonal());
}

TEST(Geometry, BoxKnownValues) {
  // 0.1 x 0.01 x 0.02 steel bar (the crank-like link of many examples).
  const MassProperties p = BoxMass(Vec3(0.1, 0.01, 0.02), 7800);
  const double m = 0.1 * 0.01 * 0.02 * 7800;  // 0.156 kg
  EXPECT_NEAR(p.mass, 0.156, 1e-14);
  EXPECT_NEAR(p.inertia(0, 0), m * (1e-4 + 4e-4) / 12, 1e-16);
  EXPECT_NEAR(p.inertia(1, 1), m * (1e-2 + 4e-4) / 12, 1e-16);
  EXPECT_NEAR(p.inertia(2, 2), m * (1e-2 + 1e-4) / 12, 1e-16);
  // A cube: I = m a^2 / 6 about every axis.
  const MassProperties cube = BoxMass(Vec3(2, 2, 2), 0.5);
  EXPECT_DOUBLE_EQ(cube.mass, 4.0);
  EXPECT_DOUBLE_EQ(cube.inertia(1, 1), 4.0 * 4.0 / 6.0);
}

TEST(Geometry, ConeKnownValues) {
  // r = 0.3, h = 1.2, rho = 2: m = pi r^2 h rho / 3; Izz = 3/10 m r^2;
  // Ixx = 3/20 m r^2 + 3/80 m h^2 about the centre of mass.
  const MassProperties p = ConeMass(0.3, 1.2, 2);
  const double m = M_PI * 0.09 * 1.2 * 2 / 3;
  EXPECT_NEAR(p.mass, m, 1e-14);
  EXPECT_NEAR(p.inertia(2, 2), 0.3 * m * 0.09, 1e-14);
  EXPECT_NEAR(p.inertia(0, 0), m * (0.15 * 0.09 + 0.0375 * 1.44), 1e-14);
}

// Independent check of the cone by quadrature: slice the cone into discs along z (axis
// z, base at z = 0, apex at z = h, radius r (1 - z/h)). A disc of radius a and
// thickness dz has dm = rho pi a^2 dz, dIzz = dm a^2 / 2 and dIxx = dm (a^2/4 + z^2)
// about the base centre; midpoint rule on a fine grid, then shift to the centre of mass.
TEST(Geometry, ConeAgainstQuadrature) {
  const double r = 0.25, h = 0.8, rho = 1300;
  const int n = 200000;
  const double dz = h / n;
  double m = 0, mz = 0, izz = 0, ixx_base = 0;
  for (int k = 0; k < n; ++k) {
    const double z = (k + 0.5) * dz;
    const double a = r * (1 - z / h);
    const double dm = rho * M_PI * a * a * dz;
    m += dm;
    mz += dm * z;
    izz += dm * a * a / 2;
    ixx_base += dm * (a * a / 4 + z * z);
  }
  const double zc = mz / m;
  const double ixx = ixx_base - m * zc * zc;  // parallel-axis theorem
  const MassProperties p = ConeMass(r, h, rho);
  EXPECT_NEAR(zc, h / 4, 1e-9);  // the centre of mass is h/4 above the base
  EXPECT_NEAR(p.mass, m, 1e-8 * m);
  EXPECT_NEAR(p.inertia(2, 2), izz, 1e-8 * izz);
  EXPECT_NEAR(p.inertia(0, 0), ixx, 1e-8 * ixx);
  EXPECT_NEAR(p.inertia(1, 1), ixx, 1e-8 * ixx);
}

TEST(Geometry, RejectsBadSizes) {
  EXPECT_THROW(SphereMass(0, 1), std::invalid_argument);
  EXPECT_THROW(CylinderMass(1, -1, 1), std::invalid_argument);
  EXPECT_THROW(ConeMass(1, 1, -2), std::invalid_argument);
  EXPECT_THROW(BoxMass(Vec3(1, 0, 1), 1), std::invalid_argument);
  EXPECT_EQ(SphereMass(1, 0).mass, 0.0);  // zero density: a massless shape is legal
}

}  // namespace
}  // namespace mbdae::mbs
