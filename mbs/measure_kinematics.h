// Measures (Model::measures) as functions of the coordinates, with exact first and
// second derivatives: the groundwork for force values, motion constraints and gear
// constraints that depend on measures (their Jacobians are the chain rule into these).
//
// The definitions are those of MultibodySystem::EvaluateMeasures (docs/measures.md):
// - translational: d = x_i - x_j (marker origins, world); the x|y|z component of d in
//   marker j's axes (u = A_j c_k, c_k the k-th column of j's orientation) or in world
//   axes, or the distance |d|;
// - rotational about axis k of marker j (p = k+1, n = k+2 cyclic): the angle
//   atan2(p_i . n_j, p_i . p_j) in (-pi, pi];
// - velocity and acceleration: the exact first and second time derivatives of these
//   scalars with v = q', a = q''.
//
// Coordinates: a measure depends on the (up to) two bodies of its markers. Slot 0 holds
// the body of marker i, slot 1 the body of marker j; the 14 local coordinates are
// (r_0, e_0, r_1, e_1) and offset[s] is the slot's first index in q (7 * body), -1 if the
// slot is unused (ground, or marker j on the same body as marker i: then everything is
// folded into slot 0 and slot 1 is unused). Local vectors are therefore scattered into
// q without duplicates: for (s, k): q[offset[s] + k] <-> local[7 s + k].
//
// What each consumer needs (m(q) the position-level function of the measure,
// g = dm/dq, H = d2m/dq2, both here):
// - a force whose value depends on a position measure: m, dm/dq = g (dm/dv = 0);
//   on a velocity measure m_v = g(q) v: dm_v/dq = H v, dm_v/dv = g
//   (EvaluateMeasureState). Second derivatives of a velocity measure are not needed.
// - a motion constraint C = m(q) - f(t): C_q = g, d(C_q v)/dq = H v,
//   gamma = C_q q'' = -v^T H v + f''(t), d(C_q^T w)/dq = w H (EvaluateMeasurePosition
//   with the Hessian); a gear constraint is a linear combination of two such measures.
// - acceleration-level measures are for output only (EvaluateMeasureValue); forces and
//   constraints must reject them.
//
// Everything is fixed-size: no allocation per evaluation.
#pragma once

#include <Eigen/Dense>

#include "mbs/model.h"

namespace mbdae::mbs {

using Vec14 = Eigen::Matrix<double, 14, 1>;
using Mat14 = Eigen::Matrix<double, 14, 14>;

// One measure resolved against its model once (indices and marker vectors copied), so
// that evaluations do no lookups. Built by ResolveMeasure.
struct MeasureDef {
  MeasureType type = MeasureType::kTranslational;
  Quantity quantity = Quantity::kPosition;
  Component component = Component::kX;
  MeasureFrame frame = MeasureFrame::kJ;
  int offset[2] = {-1, -1};  // coordinate offsets of the slots (see above)
  // Slot of marker i's and marker j's body in the local coordinates, -1 for ground.
  int slot_i = -1, slot_j = -1;
  Vec3 s_i = Vec3::Zero(), s_j = Vec3::Zero();  // marker origins (body axes, ground: world)
  Mat3 axes_i = Mat3::Identity(), axes_j = Mat3::Identity();  // marker axes (body or world)
};

// Resolves Model::measures[measure]. Throws std::invalid_argument naming the measure if
// the index or one of its marker indices is out of range.
MeasureDef ResolveMeasure(const Model& model, int measure);

// The position-level function m(q) of a measure (whatever its quantity) and its
// derivatives with respect to the 14 local coordinates.
struct MeasureJacobian {
  int offset[2] = {-1, -1};
  double value = 0;                 // m(q); angles in (-pi, pi]
  Vec14 gradient = Vec14::Zero();   // dm/dq_local (zero in unused slots)
  Mat14 hessian = Mat14::Zero();    // d2m/dq_local2, symmetric; set only if requested
};

// Fills *out for m(q). with_hessian = false leaves out->hessian untouched. At a
// singular point (distance with d = 0, angle with p_i normal to both p_j and n_j) the
// value is that of EvaluateMeasures (0) and the derivatives are set to zero.
void EvaluateMeasurePosition(const MeasureDef& def, const double* q, bool with_hessian,
                             MeasureJacobian* out);

// The measure at its own quantity as a function of the state, for forces:
// position: value m(q), dq = g, dv = 0; velocity: value g.v, dq = H v, dv = g.
struct MeasureStateJacobian {
  int offset[2] = {-1, -1};
  double value = 0;
  Vec14 dq = Vec14::Zero();
  Vec14 dv = Vec14::Zero();
};

// Fills *out. An acceleration-level measure has no state derivative: throws
// std::invalid_argument (callers reject such measures when the model is loaded).
void EvaluateMeasureState(const MeasureDef& def, const double* q, const double* v,
                          MeasureStateJacobian* out);

// The value at the measure's quantity, for output: position m(q), velocity g.v,
// acceleration g.a + v^T H v. v and a may be null (zero).
// The angle `value` plus the multiple of 2 pi that brings it nearest to `reference` (the
// turn counting of angle measures: the results file's rows, the objectives).
double UnwrapAngle(double value, double reference);
// The same with the reference predicted from the previous angle by the trapezoidal rule
// on the rate: previous + dt (previous_rate + rate) / 2 (dt may be negative: a backward
// sweep).
double UnwrapAngle(double value, double previous, double previous_rate, double rate, double dt);
// Whether measure m is an angle (rotational, position level), and its rate: the same
// measure at velocity level.
bool IsAngleMeasure(const Measure& measure);
MeasureDef AngleRate(MeasureDef angle);

double EvaluateMeasureValue(const MeasureDef& def, const double* q, const double* v,
                            const double* a);

// The 14 local entries of a global vector x (zeros in unused slots).
Vec14 GatherLocal(const int offset[2], const double* x);

}  // namespace mbdae::mbs
