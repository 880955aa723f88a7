// The multibody model as loaded from a file: what the system is, immutable during a
// simulation. Everything a computation needs beyond it lives in a workspace.
#pragma once

#include <Eigen/Dense>
#include <array>
#include <limits>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "mbs/expression.h"
#include "mbs/spline.h"

namespace mbdae::mbs {

class UserForceLibrary;  // mbs/user_force.h

using Vec3 = Eigen::Vector3d;
using Mat3 = Eigen::Matrix3d;
using Quat = Eigen::Vector4d;  // Euler parameters e0 (scalar), e1, e2, e3

// Where an element was defined, for messages.
struct SourceLocation {
  std::string file;
  int line = 0;    // 1-based, 0 if unknown
  int column = 0;  // 1-based
};

struct Parameter {
  std::string name;
  double value = 0;         // evaluated (after --set overrides)
  std::string expression;   // as written, if it was an expression
  // The value as parsed (over the other parameters), for parameter derivatives
  // (ParameterChain, mbs/sensitivity_parameters.h); `overridden`: set with --set
  // (LoadOptions::parameter_overrides), then a fixed number whatever `formula` says.
  Expression formula;
  bool overridden = false;
  SourceLocation where;
};

// A value the loader computed once from the parameters (a load-time expression that
// uses at least one parameter), recorded for parameter derivatives: `kept` values are
// also stored as expressions where they are used (BodyExpressions, Model::
// gravity_expressions, SplineDef::y_expressions) and their derivatives are exact; every
// other one (marker geometry, geometry, gear ratio, spline x points, settings, ...) makes
// a MultibodySystem refuse a sensitivity parameter it depends on.
struct LoadTimeValue {
  Expression expression;
  std::string element;  // e.g. "body 'arm'"
  std::string key;      // e.g. "mass", "geometry density"
  bool kept = false;
  SourceLocation where;
};

// How a body's initial orientation was written.
enum class OrientationForm { kNone, kEulerParameters, kAxisAngle, kMatrix };

// A body's values as written (expressions of the parameters), for exact parameter
// derivatives; an empty list: not given in the file (the value is a default, or comes
// from the geometry).
struct BodyExpressions {
  std::vector<Expression> mass;     // 0 or 1
  std::vector<Expression> inertia;  // 0, 3 (Ixx Iyy Izz) or 6 (+ Ixy Ixz Iyz)
  std::vector<Expression> position, velocity, angular_velocity;  // 0 or 3
  OrientationForm orientation_form = OrientationForm::kNone;
  // Euler parameters [e0 e1 e2 e3] (as written, before normalisation), or axis x y z and
  // angle; empty for a matrix.
  std::vector<Expression> orientation;
};

// A marker: a frame fixed on a body (or on ground, body = -1).
struct Marker {
  std::string name;          // full name, "body.marker" or "ground.O"
  int body = -1;             // index into Model::bodies, -1 for ground
  Vec3 position = Vec3::Zero();        // body axes, from the centre of mass (ground: world)
  Mat3 orientation = Mat3::Identity(); // marker axes to body axes (ground: to world)
  SourceLocation where;
};

// A shape drawn for a body or for ground (`visual:` in the model file; docs/model-format.md,
// "Visual geometry"). Drawing only: no mass, no effect on the motion. How to fill one
// (the YAML loader, the FreeDyn reader and importers such as URDF do the same):
//   - kind and its sizes: box: `size` (edge lengths along the shape's x, y, z); sphere:
//     `radius`; cylinder: `radius`, `length` along the shape's z; capsule: `radius`,
//     `length` (the cylinder part along z, between the centres of the end spheres);
//     cone: `radius` (base), `length` along z, apex towards +z, origin at its centre of
//     mass (length/4 above the base, as `geometry: {shape: cone}`); mesh: `mesh_file`
//     (STL or OBJ, path as resolved for reading) scaled by `mesh_scale`, vertices in the
//     shape's axes. Box, sphere, cylinder and capsule are centred on the shape origin.
//   - pose: `position` of the shape origin in body axes from the body's centre of mass
//     and `orientation` (shape axes to body axes); for ground, world coordinates and axes.
//   - `color`: red, green, blue, opacity in [0, 1].
// A body with no shapes is drawn by default from what it has (mbs/visual.h).
enum class VisualKind { kBox, kSphere, kCylinder, kCapsule, kCone, kMesh };
struct VisualShape {
  VisualKind kind = VisualKind::kBox;
  Vec3 size = Vec3::Zero();  // box
  double radius = 0;         // sphere, cylinder, capsule, cone
  double length = 0;         // cylinder, capsule, cone
  std::string mesh_file;     // mesh
  double mesh_scale = 1;     // mesh
  Vec3 position = Vec3::Zero();
  Mat3 orientation = Mat3::Identity();
  std::array<double, 4> color = {0.62, 0.66, 0.72, 1.0};
  SourceLocation where;
};

struct Body {
  std::string name;
  double mass = 0;
  Mat3 inertia = Mat3::Zero();  // about the centre of mass, body axes
  Vec3 position = Vec3::Zero(); // initial centre of mass, world
  Quat orientation = Quat(1, 0, 0, 0);  // initial Euler parameters, normalised
  Vec3 velocity = Vec3::Zero();          // initial, world
  Vec3 angular_velocity = Vec3::Zero();  // initial, world axes
  int cm_marker = -1;           // index of the marker `cm`
  std::vector<VisualShape> visuals;  // drawing only; `visual:` (or `geometry:`) in the file
  BodyExpressions expressions;  // the values as written, for parameter derivatives
  SourceLocation where;
};

// kReaction: the force or torque a joint exerts on the body of its marker i (a function of
// the multipliers; mbs/reaction.h, docs/measures.md).
enum class MeasureType { kTranslational, kRotational, kReaction };
enum class Quantity { kPosition, kVelocity, kAcceleration };  // rotational: angle, angular_velocity, angular_acceleration
enum class Component { kX, kY, kZ, kDistance };
enum class MeasureFrame { kJ, kWorld };

struct Measure {
  std::string name;
  MeasureType type = MeasureType::kTranslational;
  int i = -1, j = -1;                  // marker indices; j defaults to ground.O
  Component component = Component::kX; // translational; rotational uses kX/kY/kZ as the axis
  MeasureFrame frame = MeasureFrame::kJ;
  Quantity quantity = Quantity::kPosition;
  bool offset_initial = false;
  // Reaction measures: the joint (Model::joints index); torque (rx ry rz) or force
  // (x y z), the axis in `component` (kX/kY/kZ), in `frame` axes. i and j are the
  // joint's markers (motion joints: those of the driven measure; gear joints: those of
  // the second, driven measure); reactions have no quantity and no offset_initial.
  int joint = -1;
  bool torque = false;
  // Angle measures (IsAngleMeasure): the objectives count turns from the branch of the
  // initial angle nearest to this value (NaN: the principal value in (-pi, pi]). Set by
  // programs, not by the model file: `mbdae optimize` with `shooting:` sets it to the
  // node's angle so that an interval's angles continue those of the previous one.
  double turn_reference = std::numeric_limits<double>::quiet_NaN();
  SourceLocation where;
};

// Lock bits, in marker j's axes.
enum Lock : unsigned { kLockX = 1, kLockY = 2, kLockZ = 4, kLockRx = 8, kLockRy = 16, kLockRz = 32 };
enum class JointType {
  kFixed, kSpherical, kRevolute, kPrismatic, kCylindrical, kUniversal, kPlanar, kGeneric,
  kMotion,  // one equation m(q) - f(t) = 0 on a position-level measure, named NAME.motion
  kGear     // one equation (m2 - m2_0) - ratio (m1 - m1_0) = 0 on two angles, NAME.gear
};

struct Joint {
  std::string name;
  JointType type = JointType::kGeneric;
  int i = -1, j = -1;  // marker indices (-1 for motion and gear joints)
  unsigned locks = 0;  // Lock bits; equations are emitted in the order x y z rx ry rz
  // Motion: measures[0] is the driven measure (position level) and `value` f(t), an
  // expression over t, parameters and spline(NAME, t) (not measures).
  // Gear: measures[0], measures[1] are two rotational angle measures and `ratio` r;
  // m1_0, m2_0 are their values at the initial state of the model file (before assembly).
  std::array<int, 2> measures = {-1, -1};  // Model::measures indices
  Expression value;
  double ratio = 1;
  // Limits of the joint's coordinate (URDF <limit>, the model file's `limits:`): recorded
  // and written, not enforced. has_position: lower and upper were given.
  struct Limits {
    double lower = 0, upper = 0, effort = 0, velocity = 0;
    bool has_position = false;
  };
  std::optional<Limits> limits;
  SourceLocation where;
};

enum class ForceType {
  kSpringDamper, kForce, kTorque,
  kBushing,  // mbs/bushing.h: 6-axis linear spring-damper in marker j's axes
  kUser      // api/mbdae_user_force.h: a function of a shared library
};
enum class ForceFrame { kWorld, kI, kJ };

struct Force {
  std::string name;
  ForceType type = ForceType::kForce;
  int i = -1, j = -1;  // marker indices; j defaults to ground.O
  ForceFrame frame = ForceFrame::kWorld;
  // spring_damper
  Expression stiffness, damping, free_length, preload;
  // force / torque: components in `frame` axes
  std::array<Expression, 3> value;
  // bushing: kx ky kz krx kry krz and cx .. crz, expressions of the parameters only
  // (evaluated at every Evaluate with the system's parameter values; >= 0).
  std::array<Expression, 6> bushing_stiffness, bushing_damping;
  // user: the library (loaded once per path and shared by the elements naming it), the
  // path as written in the file (for the writer), the function and its parameters
  // (expressions of the parameters, evaluated when the system is constructed).
  std::shared_ptr<const UserForceLibrary> library;
  std::string library_path;
  std::string function;
  std::vector<Expression> user_parameters;
  SourceLocation where;
};

// A spline of the model file (`splines:`), by name; expressions call it as
// spline(NAME, x). Its points may be replaced between runs (spline.SetPoints) without
// reloading the model.
struct SplineDef {
  std::string name;
  Spline spline;
  std::string file;  // the data file as read (resolved against the model file), "" if inline
  // Inline points as written (numbers or expressions of the parameters), for
  // ReevaluateSplinePoints; empty for a spline read from a file.
  std::vector<Expression> x_expressions, y_expressions;
  SourceLocation where;
  // Whether some inline point depends on a parameter.
  bool depends_on_parameters() const;
};

// An objective of the model file (`objectives:`): G = integral_0^T integral dt + terminal
// at T. Expressions over parameters, every measure (any quantity, reactions too), t and
// spline(NAME, x) (sensitivities/model_objectives.h evaluates them).
struct Objective {
  std::string name;
  Expression integral, terminal;  // over parameters, every measure (any quantity, reactions too), t, spline(NAME, x)
  bool has_integral = false, has_terminal = false;
  SourceLocation where;
};

// kKinematic: kinematic analysis of a model without degrees of freedom (dae/kinematic.h).
// kErk: explicit Runge-Kutta (Dormand-Prince 5(4)) on the index-1 form with projection
// (dae/erk.h).
enum class IntegratorKind { kHht, kIda, kKinematic, kErk };

// The most output rows a run may have (t_end / output_step); the loaders refuse more
// with the file and line, the driver (driver/simulation.h) settings from the command line.
constexpr double kMaxOutputRows = 1e8;

struct SimulationSettings {
  double t_end = 1.0;
  double output_step = 1e-2;
  IntegratorKind integrator = IntegratorKind::kHht;
  // Whether the integrator was chosen (in the file or by an override) rather than left
  // at its default, and where the file chose it (line 0: not in the file).
  bool integrator_named = false;
  SourceLocation integrator_where;
  double hht_alpha = -0.1;
  double hht_step = 1e-3;
  bool hht_adaptive = false;
  double hht_tolerance = 1e-6;
  bool hht_modified = true;
  // The residual of the step: "equilibrium" (generalized-alpha with HHT's parameters) or
  // "negrut" (Negrut et al. 2007); see docs/hht.md.
  std::string hht_form = "equilibrium";
  // The start of the equilibrium form: "consistent" (abar_0 = a_0, the start the
  // gradient runs differentiate) or "perturbed" (the smooth solution's abar_0 and v_0: no
  // start-up oscillation of the multipliers); dae/hht.h HhtOptions::Start.
  std::string hht_start = "consistent";
  // Dense output (dae/hht.h HhtOptions::dense_output): the steps do not land on the output
  // times, the rows are interpolated (docs/hht.md, "Dense output"). Not with gradients.
  bool hht_dense_output = false;
  // Newton threshold of fixed steps (dae/hht.h HhtOptions::newton_tolerance; adaptive
  // steps use max(this, 1e-3 tolerance)): the file's `hht: {newton_tolerance}`. The
  // default 1e-12 makes a run's result independent of the iteration to round-off; a
  // looser one trades that for fewer iterations (docs/hht.md, "Newton threshold").
  double hht_newton_tolerance = 1e-12;
  // The linear solver of HHT's Newton matrix (dae/hht.h HhtOptions::linear_solver):
  // "klu" (sparse LU) or "tree" (block elimination along a tree of bodies, KLU where the
  // system is no tree); the file's `hht: {linear_solver}` (docs/hht.md, "Linear solver").
  std::string hht_linear_solver = "klu";
  // The cost of a fresh Newton matrix in Newton iterations (dae/hht.h
  // HhtOptions::jacobian_cost; docs/hht.md, "Newton matrix"): the file's
  // `hht: {jacobian_cost}`, a number >= 0 or `auto` (-1 here: 3 with the tree elimination,
  // 0 with KLU).
  double hht_jacobian_cost = -1;
  // The first iterate of HHT's Newton iteration (dae/hht.h HhtOptions::predictor;
  // docs/hht.md, "Newton iteration"): the file's `hht: {predictor}`, "auto" (linear with
  // the tree elimination, constant with KLU), "constant" or "linear".
  std::string hht_predictor = "auto";
  // The Newton matrix's columns of the Euler-parameter groups in HHT's modified scheme
  // (dae/hht.h HhtOptions::rotation_jacobian; docs/hht.md, "Rotation blocks"): the file's
  // `hht: {rotation_jacobian}`, "auto" (exact with the tree elimination, first-order with
  // KLU), "first-order" (the classical scheme's mix beta h^2 I and mix gamma h I) or
  // "exact" (each group's exact 4 x 4 blocks). Unused by the classical scheme.
  std::string hht_rotation_jacobian = "auto";
  double ida_rtol = 1e-8;
  double ida_atol = 1e-10;
  // IDA's step budget (total steps of the run; dae/ida.h IdaOptions::max_steps) and its
  // smallest step (IdaOptions::min_step; 0: no limit). The file's `ida: {max_steps,
  // min_step}` take a positive integer and a positive number.
  long ida_max_steps = 100000000;
  double ida_min_step = 0;
  // IDA's dense output (dae/ida.h IdaOptions::dense_output): the file's `ida:
  // {dense_output}`; not with gradients.
  bool ida_dense_output = false;
  // The linear solver of IDA's iteration matrix (dae/ida.h IdaOptions::linear_solver):
  // "klu" or "tree", as hht_linear_solver; the file's `ida: {linear_solver}`.
  std::string ida_linear_solver = "klu";
  // The explicit Runge-Kutta integrator (dae/erk.h ErkOptions): its local error
  // tolerances, step budget (total steps), smallest step (0: 1e-14 max(1, |t|)) and
  // largest step (0: no limit); the file's `erk: {rtol, atol, max_steps, min_step,
  // max_step}`.
  double erk_rtol = 1e-8;
  double erk_atol = 1e-10;
  long erk_max_steps = 100000000;
  double erk_min_step = 0;
  double erk_max_step = 0;
  // a and lambda of the output rows: "solved" (the acceleration-level equations
  // [M C_q^T; C_q 0] [a; lambda] = [Q; gamma] at the row's (t, q, v)) or "integrator"
  // (the integrator's own values); docs/model-format.md, "Simulation".
  std::string output_accelerations = "solved";
  // The elements given datasets in the results file (/bodies/NAME, /joints/NAME,
  // /forces/NAME, /measures/NAME): every one (nullopt, the default) or the named ones
  // (an empty list: none). The file's `output: {bodies, joints, forces, measures}`, each
  // `all` or a list of names; /q, /v, /a and /lambda always hold every coordinate and
  // multiplier (docs/model-format.md, "Simulation").
  std::optional<std::vector<std::string>> output_bodies, output_joints, output_forces, output_measures;
};

struct Model {
  std::string file;        // path as given
  std::string name;
  Vec3 gravity = Vec3::Zero();
  std::vector<Expression> gravity_expressions;  // 0 or 3, as written
  // Every load-time value that uses a parameter, in load order (see LoadTimeValue).
  std::vector<LoadTimeValue> load_time_values;
  std::vector<Parameter> parameters;
  std::vector<SplineDef> splines;  // in file order
  std::vector<Marker> markers;   // ground markers first (ground.O is index 0), then bodies'
  std::vector<Body> bodies;
  std::vector<VisualShape> ground_visuals;  // `ground: {visual: ...}`, world coordinates
  std::vector<Measure> measures;
  std::vector<Joint> joints;
  std::vector<Force> forces;
  std::vector<Objective> objectives;
  SimulationSettings simulation;
  // What an import from another format (URDF: mbs/urdf.h) changed or left out, one
  // sentence each (links merged, visuals not represented, ...); `mbdae info` prints them.
  std::vector<std::string> notes;

  int num_coordinates() const { return 7 * static_cast<int>(bodies.size()); }
  static int coordinate_offset(int body) { return 7 * body; }

  // Lookups; -1 if absent.
  int find_parameter(const std::string& name) const;
  int find_marker(const std::string& full_name) const;
  int find_body(const std::string& name) const;
  int find_measure(const std::string& name) const;
  int find_spline(const std::string& name) const;
  int find_objective(const std::string& name) const;

  std::vector<double> parameter_values() const;
};

// Whether J (symmetric, kg m^2) can be the inertia tensor of a rigid body about its centre
// of mass; if not, *error (if not null) gets the reason with the numbers. The rules
// (docs/model-format.md, "Inertia"), on the eigenvalues I1 <= I2 <= I3 (the principal
// moments):
//   - positive semi-definite: I1 >= -1e-12 max(1, |I3|);
//   - the triangle inequality I3 <= I1 + I2, which every mass distribution satisfies
//     (I1 + I2 - I3 = 2 * integral of the squared distance along the third axis), with
//     the tolerance I3 - (I1 + I2) <= kInertiaTriangleRelativeTolerance I3 +
//     kInertiaTriangleAbsoluteTolerance: slender rods (I1 = 0, I2 = I3) and flat plates
//     (I3 = I1 + I2) written with rounded values, and point masses whose moments are
//     round-off, pass.
constexpr double kInertiaTriangleRelativeTolerance = 1e-3;
constexpr double kInertiaTriangleAbsoluteTolerance = 1e-12;  // kg m^2
bool IsPhysicalInertia(const Mat3& J, std::string* error);

// After parameter values changed (Model::parameters[k].value): re-evaluates the points of
// every inline spline that depends on a parameter and sets them (Spline::SetPoints);
// other splines, including points set by hand with SetPoints, are left alone. Throws
// std::invalid_argument "spline 'NAME': what" if the new points are not valid (x no
// longer increasing, a value not finite); that spline then keeps its previous points,
// the ones before it in Model::splines have been updated.
void ReevaluateSplinePoints(Model* model);

}  // namespace mbdae::mbs
