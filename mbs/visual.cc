#include "mbs/visual.h"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>

#include "mbs/kinematics.h"

namespace mbdae::mbs {

const char* VisualKindName(VisualKind kind) {
  switch (kind) {
    case VisualKind::kBox: return "box";
    case VisualKind::kSphere: return "sphere";
    case VisualKind::kCylinder: return "cylinder";
    case VisualKind::kCapsule: return "capsule";
    case VisualKind::kCone: return "cone";
    case VisualKind::kMesh: return "mesh";
  }
  return "box";
}

double ModelLengthScale(const Model& model) {
  Vec3 lo = Vec3::Constant(HUGE_VAL), hi = Vec3::Constant(-HUGE_VAL);
  auto add = [&](const Vec3& p) {
    lo = lo.cwiseMin(p);
    hi = hi.cwiseMax(p);
  };
  for (const Marker& m : model.markers) {
    if (m.body < 0) {
      add(m.position);
    } else {
      const Body& b = model.bodies[m.body];
      add(b.position + RotationMatrix(b.orientation) * m.position);
    }
  }
  for (const VisualShape& v : model.ground_visuals) add(v.position);
  for (const Body& b : model.bodies)
    for (const VisualShape& v : b.visuals) add(b.position + RotationMatrix(b.orientation) * v.position);
  const double d = (hi - lo).norm();
  return std::isfinite(d) && d > 0 ? d : 1.0;
}

namespace {

// Distinct colours for default bodies (RGB in [0, 1]).
constexpr double kPalette[][3] = {{0.85, 0.33, 0.10}, {0.00, 0.45, 0.74}, {0.47, 0.67, 0.19},
                                  {0.49, 0.18, 0.56}, {0.93, 0.69, 0.13}, {0.30, 0.75, 0.93},
                                  {0.64, 0.08, 0.18}};

DrawnShape FromVisual(const VisualShape& v, int body) {
  DrawnShape d;
  d.kind = VisualKindName(v.kind);
  d.body = body;
  switch (v.kind) {
    case VisualKind::kBox: d.size = v.size; break;
    case VisualKind::kSphere: d.size = Vec3(v.radius, 0, 0); break;
    case VisualKind::kMesh: d.size = Vec3(v.mesh_scale, 0, 0); break;
    default: d.size = Vec3(v.radius, v.length, 0); break;
  }
  d.position = v.position;
  d.orientation = v.orientation;
  d.color = v.color;
  d.mesh_file = v.mesh_file;
  return d;
}

}  // namespace

std::vector<DrawnShape> DefaultShapes(const Model& model, int b, double length_scale) {
  const Body& body = model.bodies[b];
  const double* rgb = kPalette[b % (sizeof kPalette / sizeof kPalette[0])];
  const std::array<double, 4> color = {rgb[0], rgb[1], rgb[2], 1.0};
  // Sizes follow the body's own reach (its farthest marker) where it has markers, so
  // that a long chain of small bodies is not drawn with the chain's scale.
  double reach = 0;
  for (const Marker& m : model.markers)
    if (m.body == b) reach = std::max(reach, m.position.norm());
  const double smallest = reach > 0 ? std::min(length_scale / 20, reach / 10) : length_scale / 20;
  std::vector<DrawnShape> out;

  DrawnShape e;
  e.kind = "ellipsoid";
  e.body = b;
  e.color = color;
  e.source = "default";
  const Eigen::SelfAdjointEigenSolver<Mat3> eig(0.5 * (body.inertia + body.inertia.transpose()));
  const Vec3 I = eig.eigenvalues();
  const double trace = I.sum();
  // Capped at half the distance to the farthest marker: a cue of the inertia that does
  // not hide the rods (planar models often give every body the same moment about each axis).
  const double largest = reach > 0 ? std::max(smallest, 0.5 * reach) : HUGE_VAL;
  bool point = true;
  for (int k = 0; k < 3; ++k) {
    const double a2 = body.mass > 0 ? 5 * (trace - 2 * I[k]) / (2 * body.mass) : 0;
    const double a = std::sqrt(std::max(0.0, a2));
    point = point && !(a > smallest);
    e.size[k] = std::min(largest, std::max(smallest, a));
  }
  // A point mass is an opaque sphere; a larger ellipsoid is see-through.
  if (!point) e.color[3] = 0.35;
  Mat3 axes = eig.eigenvectors();
  if (axes.determinant() < 0) axes.col(2) = -axes.col(2);
  e.orientation = axes;
  if (!(e.size.allFinite())) e.size = Vec3::Constant(smallest);
  out.push_back(e);

  for (const Marker& m : model.markers) {
    if (m.body != b) continue;
    const double len = m.position.norm();
    if (!(len > 1e-12 * length_scale)) continue;
    DrawnShape rod;
    rod.kind = "cylinder";
    rod.body = b;
    rod.color = color;
    rod.source = "default";
    rod.size = Vec3(std::min(length_scale / 120, len / 25), len, 0);
    rod.position = 0.5 * m.position;
    // Shape z along the rod: any rotation taking e_z to the rod's direction.
    const Vec3 z = m.position / len;
    const Vec3 helper = std::abs(z.x()) < 0.9 ? Vec3::UnitX() : Vec3::UnitY();
    const Vec3 x = helper.cross(z).normalized();
    rod.orientation.col(0) = x;
    rod.orientation.col(1) = z.cross(x);
    rod.orientation.col(2) = z;
    out.push_back(rod);
  }
  return out;
}

std::vector<DrawnShape> DrawnShapes(const Model& model) {
  std::vector<DrawnShape> out;
  for (const VisualShape& v : model.ground_visuals) out.push_back(FromVisual(v, -1));
  const double scale = ModelLengthScale(model);
  for (int b = 0; b < static_cast<int>(model.bodies.size()); ++b) {
    const Body& body = model.bodies[b];
    if (body.visuals.empty()) {
      for (DrawnShape& d : DefaultShapes(model, b, scale)) out.push_back(std::move(d));
    } else {
      for (const VisualShape& v : body.visuals) out.push_back(FromVisual(v, b));
    }
  }
  return out;
}

}  // namespace mbdae::mbs
