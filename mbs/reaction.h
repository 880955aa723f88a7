// Reaction measures (MeasureType::kReaction, docs/measures.md): the force (x, y, z) or
// torque (rx, ry, rz) that a joint exerts on the body of its marker i, at marker i's
// origin, in marker j's axes (frame: j) or world axes (frame: world), as a function of
// (t, q, lambda) with lambda the multipliers of the FULL constraint set of a
// MultibodySystem (joint equations, then the normalisations).
//
// Definition: the joint's generalised constraint force is -C_q^T w, w = lambda on the
// joint's equations and zero elsewhere. On the body B of marker i (centre of mass C,
// Euler parameters e, marker origin P = r + A(e) s_i):
//   force  f = the translational part of -C_q^T w on B,
//   torque n = A(e) (1/2 G(e) g_e) - (A(e) s_i) x f   (g_e: the Euler parameter part),
// the moment about P. If marker i is on ground and marker j on a body B_j, the reaction
// on ground is minus that on B_j: f = -f_j, n = -n_j - (r_j - P) x f_j. These are the
// rows /joints/NAME/{force,torque} of the results file (MultibodySystem::JointReaction)
// for joints with markers. Motion and gear joints have no markers of their own: i and j
// are those of the driven measure (motion: its measure; gear: the second measure, m2),
// and the reaction is the whole constraint force of the joint's single equation on the
// body of that marker i (for a rotational motion about an axis: the driving torque, in
// the units of the joint's multiplier times the angle's gradient). JointReaction gives
// zeros for these joints; a reaction measure and JointWrench give this definition (the
// rows /joints/NAME/{force,torque} of motion and gear joints).
// frame j: components along marker j's axes R_j = A(e_j) O_j (O_j for a ground marker).
//
// Derivatives: the value is linear in lambda (d/dlambda exact, from C_q); the q-
// derivative is exact too: d(C_q^T w)/dq from the system's kConstraintTDq matrix chained
// with the (forward-mode automatic) derivative of the wrench map with respect to the
// coordinates of the bodies of markers i and j.
//
// ReactionMeasures keeps a MultibodySystem of its own (for C_q and d(C_q^T w)/dq), so it
// does not disturb the state of the system being integrated (gear unwrapping).
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "mbs/model.h"

namespace mbdae::mbs {

class ReactionMeasures {
 public:
  // parameters: values by Model::parameters index (default: the model's). Throws
  // std::invalid_argument if a reaction measure names no valid joint.
  explicit ReactionMeasures(const Model& model, std::vector<double> parameters = {});
  ~ReactionMeasures();
  ReactionMeasures(const ReactionMeasures&) = delete;
  ReactionMeasures& operator=(const ReactionMeasures&) = delete;

  // Model::measures indices of the reaction measures, in model order.
  const std::vector<int>& measures() const;
  int num_coordinates() const;
  int num_constraints() const;  // of the full set

  // Values of every reaction measure at (t, q, lambda): values[m] for m in measures()
  // (other entries untouched). Returns 0, or nonzero if the system's evaluation failed
  // (reason in last_error()).
  int Evaluate(double t, const double* q, const double* lambda, double* values);

  // One reaction measure (Model::measures index): its value, and its derivatives ADDED
  // into dq (nq, scaled by `weight`) and dlambda (nc full, scaled by `weight`); either
  // may be null.
  int Derivatives(int measure, double t, const double* q, const double* lambda, double weight,
                  double* value, double* dq, double* dlambda);

  // The force and torque (world axes, 3 + 3) that joint `joint` (Model::joints index)
  // exerts on the body of its marker i, about marker i's origin, at (t, q, lambda): the
  // definition above, with the joint's own markers or, for motion and gear joints, those
  // of the driven measure. For joints with markers it equals
  // MultibodySystem::JointReaction. Returns 0, or nonzero if the system's evaluation
  // failed (reason in last_error()).
  int JointWrench(int joint, double t, const double* q, const double* lambda, double* force,
                  double* torque);

  // The parameter values the private system uses (change them between evaluations like
  // MultibodySystem::parameters()).
  std::vector<double>& parameters();
  const char* last_error() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace mbdae::mbs
