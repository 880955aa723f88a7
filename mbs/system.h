// The multibody model as a mechanical DAE: coordinates are per body the centre-of-mass
// position and the Euler parameters (7), constraints the joints' equations followed by
// one normalisation per body (e^T e - 1 = 0, named BODY.euler_norm).
//
// Function style: the Model is immutable; a MultibodySystem holds the model reference,
// the parameter values, the fixed sparsity patterns and a workspace.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "dae/mechanical_system.h"
#include "mbs/model.h"
#include "mbs/sensitivity_parameters.h"

namespace mbdae::mbs {

class MultibodySystem final : public dae::MechanicalSystem {
 public:
  // parameters: values by Model::parameters index (default: the model's values).
  explicit MultibodySystem(const Model& model, std::vector<double> parameters = {});
  // With parameter derivatives (dae::MechanicalSystem::num_parameters() =
  // sensitivity.size(), in that order): Evaluate fills the requested parameter_matrix
  // outputs exactly, as total derivatives through the chain of dependent parameters
  // (ParameterChain). Supported dependencies: spring_damper stiffness, damping,
  // free_length, preload; force/torque values; bushing stiffness and damping; motion
  // values (C, C_t, gamma); body mass and inertia (M, Q's gravity and velocity-quadratic
  // terms) and gravity; spline ordinates (inline y points that use a parameter too).
  // Anything else a selected parameter reaches (a load-time value that is not kept:
  // marker geometry, geometry, gear ratio, inline spline x, settings; user force
  // parameters; forces over offset_initial measures and gear joints when the initial
  // state depends on it) throws std::invalid_argument naming the parameter, the element
  // and its file:line. The derivatives are evaluated at the system's parameter values
  // with the chain at the model's values; parameters() must keep the values of
  // dependent parameters consistent with their formulas.
  MultibodySystem(const Model& model, std::vector<SensitivityParameter> sensitivity,
                  std::vector<double> parameters);

  int num_coordinates() const override;
  int num_constraints() const override;
  const dae::CscPattern& pattern(dae::Matrix m) const override;
  const std::vector<int>& quaternion_offsets() const override;
  int Evaluate(const dae::EvalInput& in, dae::EvalOutput& out) override;
  // Yes where the model's equations add each entry of C_q once and each column's entries
  // in increasing rows (checked on the recorded adds; e.g. no gear on two measures of one
  // body, no motion or gear joint before a joint whose rows share its columns).
  bool provides_constraint_transpose_w() const override;
  const char* last_error() const override;
  int num_parameters() const override;
  const dae::CscPattern& parameter_pattern(dae::ParameterMatrix m) const override;
  const std::vector<SensitivityParameter>& sensitivity_parameters() const;

  // Derivatives of the raw initial state (InitialState, before assembly) with respect to
  // the sensitivity parameters: dq, dv, nq x num_parameters(), column-major. Positions,
  // Euler parameters (as written: normalised Euler parameters, or axis and angle),
  // velocities, and the Euler parameter rates e' = 1/2 E(e)^T omega (through e and
  // omega). An orientation written as a matrix that uses a selected parameter is refused
  // at construction.
  void InitialStateParameterDerivatives(std::vector<double>& dq, std::vector<double>& dv) const;

  const Model& model() const;
  // Names: coordinates "body.x" .. "body.e3"; constraints "joint.x" .. "joint.rz",
  // "joint.motion" / "joint.gear" (one equation each), "body.euler_norm". Joint equations
  // in the joints' order, then the normalisations.
  // Force values over t, measures and splines are evaluated at every Evaluate (measures
  // with offset_initial minus their value at the file's initial state); motion joints
  // give C = m(q) - f(t) (angles modulo 2 pi) with C_t = -f'(t), C_tt = -f''(t),
  // gamma = -v^T H v + f''(t); gear joints (m2 - m2_0) - r (m1 - m1_0), angles continued
  // across +-pi from the previous evaluation (so Evaluate keeps that much state). No
  // equation has a mixed term (C_qt = 0), so d(C_q)/dt q' = -gamma - C_tt. Evaluate fills
  // the optional outputs force_quadratic_velocity (per body Q_v = 8 G(e')^T J G(e') e in
  // the Euler parameters, zero in the positions) and constraint_dtt. JointReaction gives
  // zeros for motion and gear joints (their multiplier is the driving effort).
  // Bushing and user elements (mbs/bushing.h, mbs/user_force.h) get the marker
  // kinematics of i and j (p = r + A s, R = A(e/|e|) O, v, w) and their 6x24 Jacobian is
  // chained into dQ/dq and dQ/dv; bushing values are evaluated from the parameters at
  // every call, user parameters when the system is built (NAME_init is called then; its
  // error is a std::runtime_error "user force 'NAME': ..."). An error returned by a user
  // function is caught in Evaluate: last_error() "user force 'NAME': ..." and a negative
  // (fatal) code.
  const std::vector<std::string>& coordinate_names() const;
  const std::vector<std::string>& constraint_names() const;
  // For each constraint equation: the joint index, or -1 for a normalisation.
  const std::vector<int>& constraint_joint() const;

  std::vector<double>& parameters();
  const std::vector<double>& parameters() const;

  // Initial state from the model (positions, Euler parameters, velocities; the Euler
  // parameter rates from the angular velocities); a and lambda zero.
  void InitialState(std::vector<double>& q, std::vector<double>& v) const;

  // Outputs at a solved state (lambda of the full constraint set).
  // Measure values, in Model::measures order (without offset_initial applied); reaction
  // measures are functions of lambda and are set to 0 here (mbs/reaction.h gives them).
  // Translational: the x|y|z component (marker j's axes or world axes) of
  // d = x_i - x_j, or |d|; velocity/acceleration are its exact time derivatives.
  // Rotational about axis k of marker j (p = k+1, n = k+2 cyclic): the angle
  // atan2(p_i . n_j, p_i . p_j) in (-pi, pi] (the caller unwraps turns);
  // angular_velocity/angular_acceleration are the exact first/second time derivatives
  // of that angle, which equal the components along j's k-axis of the relative angular
  // velocity/acceleration of marker i's frame whenever the k-axes stay parallel (a
  // revolute joint). v and a may be null (taken as zero).
  void EvaluateMeasures(double t, const double* q, const double* v, const double* a,
                        double* values) const;
  // Reaction of joint k on body i at marker i, world axes: force and torque (3 + 3).
  void JointReaction(int joint, double t, const double* q, const double* lambda,
                     double* force, double* torque) const;
  // Kinetic energy, and potential energy of gravity, of the spring_damper springs
  // (k/2 (l - l0)^2 - preload (l - l0)) and of the bushings' springs (BushingPotential);
  // forces of type force/torque/user have none.
  double KineticEnergy(const double* q, const double* v) const;
  double PotentialEnergy(double t, const double* q) const;
  // Action of force element `element` on marker i, world axes: force and torque (3 + 3).
  // Throws std::runtime_error if a user function returns an error.
  void ForceAction(int element, double t, const double* q, const double* v, double* force,
                   double* torque) const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
 public:
  ~MultibodySystem() override;
};

}  // namespace mbdae::mbs
