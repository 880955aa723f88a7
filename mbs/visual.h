// What is drawn for a model: every body's shapes in body axes (its `visual:` shapes, the
// shape of its `geometry:`, or a default made from what the body has) and ground's.
// Drawing only; nothing here affects the motion. The results file stores the outcome
// (io/results_geometry.h) and `mbdae view` draws it (docs/viewer.md).
#pragma once

#include <string>
#include <vector>

#include "mbs/model.h"

namespace mbdae::mbs {

// One drawn shape. `kind` is a VisualKind's name (box, sphere, cylinder, capsule, cone,
// mesh) or "ellipsoid" (defaults only). `size`: box: the edge lengths; sphere: radius, 0,
// 0; cylinder, capsule, cone: radius, length, 0; ellipsoid: the three semi-axes along the
// shape's axes; mesh: the scale, 0, 0. `position`, `orientation`: the shape's origin and
// axes in body axes from the centre of mass (ground: world).
struct DrawnShape {
  std::string kind;
  int body = -1;  // index into Model::bodies, -1 for ground
  Vec3 size = Vec3::Zero();
  Vec3 position = Vec3::Zero();
  Mat3 orientation = Mat3::Identity();
  std::array<double, 4> color = {0.62, 0.66, 0.72, 1.0};
  std::string mesh_file;  // mesh
  // Where it comes from: "visual" (the model's shapes, `geometry:` included) or "default".
  std::string source = "visual";
};

const char* VisualKindName(VisualKind kind);

// A length that sets the size of default shapes: the diagonal of the box around the
// initial centres of mass, markers and shape origins (1 when they all coincide).
double ModelLengthScale(const Model& model);

// The default drawing of body b (used when it has no shapes): an ellipsoid with its mass
// and inertia (the homogeneous ellipsoid of semi-axes a_k = sqrt(5 (I_1 + I_2 + I_3 -
// 2 I_k) / (2 m)) in the principal axes, every semi-axis at least min(length_scale / 20,
// reach / 10) with reach the distance to the farthest marker (length_scale / 20 without
// markers), so that a point mass is a small opaque sphere, and at most reach / 2;
// see-through unless a point mass) and a rod from the centre of mass to each of its
// markers (radius min(length_scale / 120, its length / 25)), in one colour per body.
std::vector<DrawnShape> DefaultShapes(const Model& model, int b, double length_scale);

// Every shape drawn: ground's shapes, then per body its shapes or DefaultShapes.
std::vector<DrawnShape> DrawnShapes(const Model& model);

}  // namespace mbdae::mbs
