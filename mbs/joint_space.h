// Joint space of a tree: the coordinates of the revolute and prismatic joints of a model
// whose joints form a tree from the ground (a URDF import, a serial arm), and its
// dynamics in those coordinates computed exactly from the redundant-coordinate equations
// M(x) x'' + C_x^T lambda = Q(x, x', t) of the MultibodySystem (docs/urdf.md, "Joint
// space"):
//
//   1. forward kinematics sets the absolute coordinates x (per body the centre of mass and
//      the Euler parameters) from the joint positions q, and their rates x' = J(q) q' and
//      x'' = J(q) q'' + J'(q, q') q' by a recursion from the ground (Euler parameter rates
//      e' = 1/2 E(e)^T omega, e'' = 1/2 E(e)^T alpha - |e'|^2 e);
//   2. J spans the motions the constraints allow (C_x J = 0), so the multipliers drop out
//      of J^T (M x'' - Q) and
//        mass matrix       M_q(q)       = J^T M J,
//        inverse dynamics  tau(q, q', q'') = J^T (M x'' - Q(x, x', t)),
//        bias              b(q, q')     = tau(q, q', 0)   (C(q, q') q' + g(q)),
//        gravity           g(q)         = tau(q, 0, 0).
//      Q holds every force of the model (gravity and the force elements), so tau is the
//      generalized force each joint has to transmit about (along) its axis on top of
//      them; for a URDF import Q is gravity alone.
//
// The joint coordinate of a revolute joint is the angle of marker i about marker j's z
// axis (the rotational measure's atan2(x_i . y_j, x_i . x_j), not wrapped: any real
// number), of a prismatic joint the displacement z_j . (p_i - p_j); q' and q'' are their
// rates. Fixed joints have none. Model style: a JointSpace is built once from a Model
// (immutable); the functions take the system and a workspace-free state.
#pragma once

#include <string>
#include <vector>

#include "mbs/model.h"

namespace mbdae::mbs {

class MultibodySystem;

class JointSpace {
 public:
  // Throws std::invalid_argument naming the element when the joints do not form a tree of
  // revolute, prismatic and fixed joints from the ground with one joint per body (a
  // motion or gear joint, a loop, a free body, another joint type).
  explicit JointSpace(const Model& model);

  int size() const { return static_cast<int>(coordinate_joint_.size()); }  // n
  // Model::joints index of each joint coordinate (the model's joint order).
  const std::vector<int>& coordinate_joints() const { return coordinate_joint_; }
  const std::vector<std::string>& names() const { return names_; }
  // Whether coordinate k is an angle (revolute) rather than a displacement (prismatic).
  bool is_angle(int k) const { return is_angle_[k]; }

  // Absolute coordinates (7 per body) from the joint state: x, x' (= J q') and x''
  // (= J q'' + J' q'); any output may be null, qd and qdd may be null (zero). J: 7 nb x n,
  // column-major, if not null.
  void Absolute(const double* q, const double* qd, const double* qdd, double* x, double* xd, double* xdd,
                double* J) const;

  // The joint state of absolute coordinates that satisfy the joints (a row of a run): q
  // (within pi of `previous` when given, for unwrapping), q', q''. xd, xdd, qd, qdd may be
  // null.
  void JointState(const double* x, const double* xd, const double* xdd, const double* previous, double* q, double* qd,
             double* qdd) const;

  // Dynamics at time t (forces over t), with `system` built on the same model: n x n
  // column-major mass matrix; n-vectors bias, gravity and tau. Throws std::runtime_error
  // when the system cannot be evaluated (its last_error()).
  void MassMatrix(MultibodySystem& system, const double* q, double* M) const;
  void InverseDynamics(MultibodySystem& system, double t, const double* q, const double* qd, const double* qdd,
                       double* tau) const;
  void Bias(MultibodySystem& system, double t, const double* q, const double* qd, double* b) const;
  void Gravity(MultibodySystem& system, double t, const double* q, double* g) const;

  // The joint coordinates of a row of a run (absolute x, x', x'' that satisfy the joints;
  // the results file's /joints/NAME/{position,rate,acceleration,generalized_force}): per
  // joint from its markers (O(1) each; angles continued from `previous` when not null), and
  // tau = J^T (M x'' - Q(x, x', t)) by one pass from the leaves (O(bodies)): what each
  // joint transmits about (along) its axis. Outputs n each.
  void RowValues(MultibodySystem& system, double t, const double* x, const double* xd, const double* xdd,
                 const double* previous, double* q, double* qd, double* qdd, double* tau) const;

 private:
  struct Link {
    int body = -1;    // the child body
    int parent = -1;  // parent body (-1: ground)
    int joint = -1;   // Model::joints index
    int coordinate = -1;  // joint coordinate, -1 for a fixed joint
    bool prismatic = false;
    bool child_is_i = true;  // the child holds marker i
    // Marker frames on their bodies (position from the centre of mass, axes to body axes).
    Vec3 s_i, s_j;
    Mat3 O_i, O_j;
    // Marker i relative to marker j: p = d0 + q z (prismatic, z component of d0 zero),
    // R = Rz(q) D (revolute; prismatic and fixed: R = D, q = 0).
    Vec3 d0;
    Mat3 D;
  };
  const Model& model_;
  std::vector<Link> links_;  // parents before children
  std::vector<int> coordinate_joint_;
  std::vector<std::string> names_;
  std::vector<bool> is_angle_;
};

}  // namespace mbdae::mbs
