// The simulation pipeline behind the `mbdae` program (and any other front end):
// settings, system, assembly, determinacy check, integration output step by output
// step, and the results file.
//
//   Model model = mbs::LoadModel(path, {overrides});
//   SimulationSettings s = ResolveSettings(model.simulation, cli_overrides);  // validated
//   Assembly asmb = Assemble(model);               // consistent state, redundant equations
//   SimulationSummary summary = Simulate(model, asmb, s, options);  // writes the file
//
// Errors: mistakes of the user (a model that cannot be assembled, bodies whose motion is
// not determined, bad settings) are InputError; a solver failure during the run is not
// an exception: the summary says kFailed, and the rows computed so far stay in the file.
#pragma once

#include <functional>
#include <limits>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "dae/consistent.h"
#include "dae/erk.h"
#include "dae/hht.h"
#include "dae/ida.h"
#include "dae/integrator.h"
#include "io/results_file.h"
#include "mbs/joint_space.h"
#include "mbs/measure_kinematics.h"
#include "mbs/model.h"
#include "mbs/reaction.h"
#include "mbs/system.h"

namespace mbdae::driver {

// A mistake in the input (settings, a model that cannot be assembled or whose motion is
// not determined). what() names the element and what is wrong.
class InputError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// Command-line values that override the model's `simulation:` block; unset ones keep it.
struct SettingsOverrides {
  std::optional<double> t_end, output_step;
  std::optional<mbs::IntegratorKind> integrator;
  std::optional<double> hht_alpha, hht_step, hht_tolerance, hht_newton_tolerance;
  std::optional<bool> hht_adaptive, hht_modified, hht_dense_output;
  std::optional<std::string> hht_form;
  std::optional<std::string> hht_start;             // "perturbed" | "consistent"
  std::optional<std::string> hht_linear_solver;     // "klu" | "tree"
  std::optional<double> hht_jacobian_cost;          // >= 0, or -1: auto
  std::optional<std::string> hht_predictor;         // "auto" | "constant" | "linear"
  std::optional<std::string> hht_rotation_jacobian; // "auto" | "first-order" | "exact"
  std::optional<std::string> output_accelerations;  // "solved" | "integrator"
  std::optional<double> ida_rtol, ida_atol;
  std::optional<long> ida_max_steps;
  std::optional<double> ida_min_step;
  std::optional<bool> ida_dense_output;
  std::optional<std::string> ida_linear_solver;     // "klu" | "tree"
  std::optional<double> erk_rtol, erk_atol;
  std::optional<long> erk_max_steps;
  std::optional<double> erk_min_step, erk_max_step;
  // --output-bodies, --output-joints, --output-forces, --output-measures: given (the
  // outer optional) as all (nullopt) or a list of names (SimulationSettings::output_bodies).
  std::optional<std::optional<std::vector<std::string>>> output_bodies, output_joints, output_forces,
      output_measures;
};

// The model's settings with the overrides applied, validated (t_end > 0, 0 < output_step,
// output_accelerations solved | integrator, hht_start perturbed | consistent, and
// HhtOptions::IsValid / IdaOptions::IsValid of the chosen integrator). Throws
// InputError naming the setting.
mbs::SimulationSettings ResolveSettings(const mbs::SimulationSettings& model_settings,
                                        const SettingsOverrides& overrides);

// Throws InputError when the settings' chosen elements (output_bodies, ...) name an
// element the model lacks (the model file's are checked when it is read; an override's
// are not). DescribeRun checks the same.
void CheckOutputSelection(const mbs::Model& model, const mbs::SimulationSettings& settings);
// The text of a chosen-elements option (--output-bodies V, options["output.bodies"]):
// `all` -> nullopt (every element), `none` -> an empty list, else comma-separated
// names. Throws InputError("empty name in 'V'") for an empty name.
std::optional<std::vector<std::string>> ParseElementChoice(const std::string& value);
// The text of HHT's jacobian_cost option (--jacobian-cost V, options["hht.jacobian_cost"]):
// `auto` -> -1, a finite number >= 0 -> itself; anything else -> nullopt.
std::optional<double> ParseJacobianCost(const std::string& value);

const char* IntegratorName(mbs::IntegratorKind kind);  // "hht" | "ida" | "kinematic" | "erk"

// Degrees of freedom of a system of independent constraint equations (Assembly::
// kept_system): coordinates minus equations.
int DegreesOfFreedom(const dae::MechanicalSystem& kept_system);
// Throws InputError when settings.integrator is kinematic and kept_system has degrees of
// freedom: the message names where the file chose it (file:line:column, or
// `--integrator kinematic` for an override) and the number of degrees of freedom.
void CheckIntegrator(const dae::MechanicalSystem& kept_system, const mbs::SimulationSettings& settings);

// The integrators' options of the settings. HhtOptionsOf throws InputError for an
// unknown form or start.
dae::HhtOptions HhtOptionsOf(const mbs::SimulationSettings& settings);
dae::IdaOptions IdaOptionsOf(const mbs::SimulationSettings& settings);
dae::ErkOptions ErkOptionsOf(const mbs::SimulationSettings& settings);

// The model assembled at t = 0.
struct Assembly {
  std::unique_ptr<mbs::MultibodySystem> system;  // all constraint equations
  std::vector<int> kept;                         // independent equations (sorted)
  std::vector<int> redundant;                    // dependent equations (sorted)
  std::unique_ptr<dae::MechanicalSystem> kept_system;  // view of `system` with `kept`
  dae::State x0;                                 // consistent, of kept_system (lambda: nc kept)
  dae::ConsistencyReport report;                 // of the full system
  std::vector<std::string> moved_bodies;         // bodies moved by more than 1e-9 (q or v)
  std::vector<double> v_raw;                     // the model's initial velocities (before projection)
  double max_position_change = 0;
  double max_velocity_change = 0;

  std::vector<std::string> redundant_names() const;
  std::vector<std::string> kept_names() const;
  // "assembly: positions moved by at most ..., velocities by ...; moved: a, b"
  std::string Report() const;
};

struct AssemblyOptions {
  dae::ConsistencyOptions consistency;
  double moved_threshold = 1e-9;  // a body is reported as moved above this change
  // The acceleration-level matrix is declared singular when its rank (relative
  // tolerance on the equilibrated matrix) is below its size.
  double singularity_tolerance = 1e-10;
  bool check_determinacy = true;
  // Parameters to differentiate with respect to (mbs/sensitivity_parameters.h): the
  // system is built with them (MultibodySystem(model, sensitivity, values), which throws
  // std::invalid_argument for a dependence it cannot differentiate; Assemble turns that
  // into an InputError). Empty: a plain system.
  std::vector<mbs::SensitivityParameter> sensitivity;
  bool IsValid(std::string* error) const;
};

// Builds the system, projects the initial state, finds the redundant equations, keeps
// the independent ones and solves for a and lambda. Throws InputError naming the joints
// whose equations cannot be satisfied, or the bodies whose motion is not determined.
Assembly Assemble(const mbs::Model& model, const AssemblyOptions& options = {});

// Determinacy: if [M C_q^T; C_q 0] of `system` at x is singular, returns the names of the
// bodies whose coordinates appear in its null space (or, for a group of more than 200
// connected bodies without positive mass and inertia, the group's bodies with zero mass
// or a singular inertia); empty if regular. Linear in the number of bodies
// (driver/determinacy.h: only bodies without a positive mass and inertia are tested
// numerically). When `system` is a mbs::MultibodySystem (all equations) dependent
// constraint equations make it singular too; a KeepConstraints view has none.
std::vector<std::string> UndeterminedBodies(const mbs::Model& model, dae::MechanicalSystem& system,
                                            const dae::State& x, double tolerance,
                                            bool* singular);

struct SimulationOptions {
  std::string model_path;    // written as the `model` attribute
  std::string results_path;  // the file to create (after everything checked out); "": none
  // Called after every output row with (t, t_end).
  std::function<void(double, double)> progress;
  // Seconds of wall time between flushes of the results file (0: after every row). The
  // file is always flushed at the end and when the run fails.
  double flush_interval = 0;
  // Changes to the HHT options of the settings (e.g. a replayed step sequence, a tighter
  // Newton threshold), applied before the integrator is made.
  std::function<void(dae::HhtOptions&)> adjust_hht;
  // Called with the integrator before it is initialised (e.g. to set a step observer).
  std::function<void(dae::Integrator&)> prepare;
  // Asked before every output time and after every step the integrator reports (through
  // a step observer set before `prepare`, which may replace it): true ends the run there
  // with status kInterrupted, the rows so far kept (e.g. a flag a signal handler sets).
  std::function<bool()> stop;
};

struct SimulationSummary {
  enum class Status { kDone, kFailed, kInterrupted };
  Status status = Status::kFailed;
  std::string integrator;           // "hht" | "ida" | "kinematic"
  std::string integrator_detail;    // Integrator::name()
  std::string failure_reason;
  double t_end = 0;
  double t_reached = 0;
  long rows = 0;
  dae::Summary counters;            // of the integrator
  double wall_time = 0;             // seconds, the integration and output
  // Process CPU seconds spent in the integrator (AdvanceTo), without the output rows:
  // the cost measure of the work-precision studies.
  double solver_cpu_time = 0;
  double max_position_violation = 0;  // max |C| of the kept system over the rows
  double max_velocity_violation = 0;  // max |C_q v + C_t| over the rows
  // Rows whose a and lambda are the integrator's although output_accelerations is
  // "solved" (the acceleration-level system was singular or could not be evaluated).
  long rows_with_integrator_accelerations = 0;
  // Kinematic analysis only: the most Newton iterations at one solved time, and the
  // times solved by the minimum-norm fallback where C_q was singular (dae/kinematic.h).
  int max_newton_iterations = 0;
  long singular_points = 0;
  std::vector<std::string> redundant_constraints;
  std::string results_path;
  // The model's objectives (Model::objectives) of a run that reached t_end: integral by
  // the integrator's quadrature (HHT: trapezoidal rule over the accepted steps), terminal
  // at the final state, value = integral + terminal. Empty when the model has none, the
  // run failed, or the integrator has no quadrature (then objectives_note says so).
  struct ObjectiveValue {
    std::string name;
    double value = 0, integral = 0, terminal = 0;
  };
  std::vector<ObjectiveValue> objectives;
  std::string objectives_note;
  // Where the objectives' count of turns of angle measures ended (sens::ModelObjectives::
  // angle_track after the terminal values): an adjoint sweep starts from there.
  double objectives_angle_t = 0;
  std::vector<double> objectives_angles, objectives_angle_rates;

  std::string FullReport() const;  // the multi-line summary the program prints
};

// What a results file says about its run before the first row: the layout (names) and
// the attributes written when the file is created (docs/results-file.md). Kept apart from
// the model and the assembly so that a front end can write a file later (the C API).
struct RunDescription {
  io::ResultsLayout layout;
  std::string model;  // the `model` attribute: the path as given
  std::string model_name;
  mbs::SimulationSettings settings;
  std::string integrator_detail;  // Integrator::name()
  std::vector<std::string> redundant_constraints;
  double assembly_max_position_change = 0;
  double assembly_max_velocity_change = 0;
  std::vector<std::string> assembly_moved_bodies;
  std::vector<std::pair<std::string, double>> parameters;  // name, value
};

// model_path: the `model` attribute ("" gives model.file).
RunDescription DescribeRun(const mbs::Model& model, const Assembly& asmb,
                           const mbs::SimulationSettings& settings, const std::string& model_path,
                           const std::string& integrator_detail);
// The attributes known before the run (status "running", t_reached 0).
void WriteRunAttributes(io::ResultsFile& file, const RunDescription& run);
// The attributes of the end of the run: status, t_reached, failure_reason (when failed),
// counters, times, violations.
void WriteSummaryAttributes(io::ResultsFile& file, const SimulationSummary& summary);

// The integrator of the settings (HHT, IDA, erk or the kinematic analysis) on `system`,
// not yet initialised. Throws InputError for settings that cannot be used
// (CheckIntegrator). dense_stop_time: the stop time of HHT's and IDA's dense output
// (hht.dense_output, ida.dense_output; infinity: none, for a host that steps past t_end).
std::unique_ptr<dae::Integrator> MakeIntegrator(
    dae::MechanicalSystem& system, const mbs::SimulationSettings& settings,
    const std::function<void(dae::HhtOptions&)>& adjust_hht = {},
    double dense_stop_time = std::numeric_limits<double>::infinity());

// The quantities of one output row beyond the state: body data, measures (angles
// unwrapped across the rows: the turn is chosen nearest to the angle predicted from the
// previous row by the trapezoidal rule on the angle's rate at both rows, so that rows
// more than half a turn apart stay continuous while the rate varies slowly between
// them; offset_initial taken from the first row), joint reactions,
// force element actions, energies and constraint violations. Workspaces are allocated
// once; Compute does not allocate. References `model` and `asmb`, which must outlive it.
//
// a and lambda of the row (settings.output_accelerations): "solved" solves the
// acceleration-level equations [M C_q^T; C_q 0] [a; lambda] = [Q; gamma] of the kept
// equations at the row's (t, q, v) (one KLU factorisation per row), so that they, the
// joint reactions, efforts, reaction measures and acceleration measures of the row are
// functions of (t, q, v) alone, free of the integrator's error in a and lambda (IDA
// leaves lambda out of its error test; HHT's lambda of the index-3 form); where that
// system cannot be solved the integrator's values are used and the row is counted
// (fallbacks()). "integrator": the integrator's own a and lambda.
//
// Joint reactions: JointReaction for joints with markers, ReactionMeasures::JointWrench
// (the constraint force of the equation on the body of the driven measure's marker i)
// for motion and gear joints. Efforts (effort_joints()): for each motion joint
// -lambda of its equation, the generalised force along the driven measure (a torque
// about the axis of an angle, a force along a translation).
class OutputRowBuilder {
 public:
  // The row settings of model.simulation.
  OutputRowBuilder(const mbs::Model& model, Assembly& asmb);
  OutputRowBuilder(const mbs::Model& model, Assembly& asmb, const mbs::SimulationSettings& settings);

  // The row at x (a state of asmb.kept_system, lambda of the kept equations). The pointers
  // of the returned row point into x and into this object: valid until the next call.
  const io::ResultsRow& Compute(const dae::State& x);

  // The next row is a first row again (no unwrapping, initial measure values taken).
  void Restart() { first_ = true; }
  // Continue after a row whose measures (as returned, offsets applied) were `measures`:
  // the unwrapping references are taken from them (the initial values are kept).
  void ContinueAfter(const double* measures);

  int num_bodies() const { return nb_; }
  int num_measures() const { return nm_; }
  int num_joints() const { return nj_; }
  int num_forces() const { return nf_; }
  // The joints with an effort (motion joints, Model::joints indices), in row order.
  const std::vector<int>& effort_joints() const { return effort_joints_; }
  // Values in ResultsRow::joint_coordinate_data (4 per joint coordinate; 0 if not a tree).
  int num_joint_coordinate_values() const { return static_cast<int>(joint_coordinates_.size()); }
  long fallbacks() const { return fallbacks_; }

 private:
  const mbs::Model& model_;
  Assembly& asmb_;
  int nq_, nc_full_, nc_, nb_, nm_, nj_, nf_;
  std::vector<double> lambda_full_, body_, measures_, raw_, previous_, initial_, joints_,
      forces_, c_, cdt_, cv_, cq_;
  // Rotational position measures: index, the definition of the angle's time derivative,
  // its value at the previous row.
  std::vector<int> angle_measures_;
  std::vector<mbs::MeasureDef> rate_defs_;
  std::vector<double> previous_rate_;
  double previous_t_ = 0;
  bool have_rates_ = false;  // previous_rate_ and previous_t_ belong to the previous row
  bool first_ = true;
  io::ResultsRow row_;
  // Reaction measures (mbs/reaction.h), if the model has any reaction measure or a
  // motion or gear joint.
  std::shared_ptr<mbs::ReactionMeasures> reactions_;
  bool has_reaction_measures_ = false;
  // Solved a and lambda (output_accelerations "solved"), the row's a and lambda.
  std::unique_ptr<dae::AccelerationSolver> acceleration_;
  std::vector<double> a_, lambda_;
  long fallbacks_ = 0;
  std::vector<int> effort_joints_, effort_rows_;  // joint, its equation in the full set
  std::vector<double> efforts_;
  // Joint coordinates of a tree (null if the joints are not one): position, rate,
  // acceleration, generalized force per coordinate, in row order; the previous positions.
  std::shared_ptr<mbs::JointSpace> joint_space_;
  // joint_q_ and joint_qd_ hold the last row's values until the next row: with its time
  // they predict the next row's angles (joint_predicted_, a buffer) for unwrapping.
  std::vector<double> joint_coordinates_, joint_q_, joint_qd_, joint_qdd_, joint_tau_, joint_predicted_;
  double joint_previous_t_ = 0;
};

// Names of the joints that have an effort dataset (motion joints), in model order.
std::vector<std::string> EffortJointNames(const mbs::Model& model);

// Integrates from asmb.x0 to settings.t_end, writing one row per output time to a new
// results file (created here; throws std::runtime_error if it cannot be). Integrator
// failure: status kFailed with the reason, the file keeps its rows.
SimulationSummary Simulate(const mbs::Model& model, Assembly& asmb,
                           const mbs::SimulationSettings& settings,
                           const SimulationOptions& options);

// Output times: 0, h, 2h, ..., t_end (the last one exactly t_end; a last interval
// shorter than 1e-9 h is merged into it).
std::vector<double> OutputTimes(double t_end, double output_step);

// Unwraps an angle to be continuous with `previous` (adds multiples of 2 pi).
double UnwrapAngle(double value, double previous);

// Angular velocity in world axes from Euler parameters and their rates: 2 E(e) e'
// (Nikravesh, Computer-Aided Analysis of Mechanical Systems, 1988, eq. 6.101).
void AngularVelocityWorld(const double* e, const double* e_dot, double* omega);

}  // namespace mbdae::driver
