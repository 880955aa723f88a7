// Optimal control and identification behind `mbdae optimize` (shared/spec/
// sensitivities.md, "Optimal control and identification"): single shooting over model
// parameters and spline ordinates with bounds, the objective and the constraints being
// objectives of the model, solved by Ipopt with exact first derivatives from
// ComputeGradient (driver/gradient.h) and a limited-memory Hessian.
//
//   OptimizationProblem p = LoadOptimizationProblem("rotor_problem.yaml");  // throws InputError
//   OptimizeOptions o;  o.results_path = "rotor_problem.h5";
//   OptimizationResult r = Optimize(p, o);
//   r.solved, r.objective, r.variables, r.history ...
//
// The problem file (YAML; every key but `model`, `variables` and `minimize` optional):
//
//   format: 1
//   model: rotor.yaml                 # relative to the problem file
//   parameters: {g: 2.0}              # fixed overrides of model parameters (not variables)
//   variables:                        # each with optional bounds (default unbounded)
//     - {parameter: J, lower: 0.1, upper: 2, start: 1.5}
//     - {spline: tau, lower: -40, upper: 40, start: 0}    # every ordinate of the spline
//     - {spline: u, points: [1, 2], lower: -1, upper: 1, start: [0.5, -0.5]}  # u[1], u[2]
//   minimize: energy                  # an objective of the model
//   constraints:                      # objectives of the model with bounds
//     - {objective: final_angle, equals: 1.0}
//     - {objective: final_speed, lower: -1.0e-6, upper: 1.0e-6}
//   simulation: {hht: {step: 1.0e-3}} # overrides of the model's `simulation:` block
//   ipopt: {tol: 1.0e-10, max_iter: 200}  # Ipopt options, typed by Ipopt's registry
//   method: adjoint                   # adjoint (default) | forward | fd
//
// `parameters:` fixes model parameters that are not variables (e.g. a continuation in
// gravity): the model is loaded with these overrides (as `--set NAME=VALUE`) for every
// run; a name that is not a parameter of the model, or one that is also a variable, is an
// error. `start:` is the variable's starting value instead of the model's (with the
// overrides): one number, or for a spline a list with one value per selected ordinate
// (`points`, else every ordinate); it must lie within the variable's bounds.
//
// Every mistake (unknown keys, variable, parameter or objective names, lower > upper, a
// start outside the bounds or of the wrong length, a missing model file, a bad Ipopt
// option, a `parameters:` value the model refuses) is an InputError "FILE:LINE:COLUMN:
// ELEMENT: what is wrong" naming the problem file, thrown before anything runs; mistakes
// inside the model file are mbs::ModelError naming the model file.
//
// Optimize evaluates f, grad f, g and the (dense) Jacobian of g at a point x with one
// ComputeGradient call of every objective needed (minimize first, then the constraints'
// objectives), cached for as long as Ipopt asks about the same x. The model for x is the
// model file reloaded with the `parameters:` and the parameter variables as overrides
// (when there are parameter variables; else the model as loaded with `parameters:`),
// with the spline ordinates set by Spline::SetPoints. A failed run (or gradient) at a
// trial point makes eval_* return false: Ipopt then cuts the step. The variables start
// at their `start:`, else at the model's values (warm start). At the end the model with the final variables is
// simulated into the results file, and the optimisation is added to it (docs/
// sensitivities.md, "Optimal control: mbdae optimize").
#pragma once

#include <functional>
#include <limits>
#include <map>
#include <string>
#include <vector>

#include "driver/gradient.h"
#include "driver/simulation.h"
#include "mbs/model.h"

namespace mbdae::driver {

struct OptimizationVariable {
  std::string name;  // "J" (a parameter) or "tau[3]" (an ordinate): the gradient's wrt names
  int parameter = -1;           // Model::parameters index, or -1
  int spline = -1, point = -1;  // Model::splines index and 0-based point of an ordinate
  double lower = -std::numeric_limits<double>::infinity();
  double upper = std::numeric_limits<double>::infinity();
  double start = 0;  // the problem's `start:`, else the model's value
  bool start_given = false;  // `start:` in the problem file
  // Multiple shooting: a node variable, state `state` (Shooting::states index) at the
  // start of interval `node` (1 .. intervals - 1), named PARAMETER@NODE; its start is the
  // state's `start:` or the state reached by the runs from the starting point (a forward sweep).
  int node = 0, state = -1;
};

// Multiple shooting (`shooting:` in the problem file): [0, t_end] in `intervals` equal
// intervals, each its own run from t = 0 to t_end / intervals of the model reloaded with
// `time` = the interval's start time and, from the second interval on, every state's
// `parameter` = a node variable; constraints: each state's `measure` at an interval's end
// equals the next interval's node variable. The model must write its time-dependent
// values with t + time and set its initial state from the states' parameters.
struct ShootingState {
  std::string parameter;  // sets the state at an interval's start (the node variable)
  std::string measure;    // the state at an interval's end (continuity)
  int measure_index = -1;
  bool angle = false;     // an angle measure: its turns continue from the node's value
  double lower = -std::numeric_limits<double>::infinity();  // bounds of the node variables
  double upper = std::numeric_limits<double>::infinity();
  std::vector<double> start;  // `start:` of the node variables (nodes 1 .. intervals - 1), or empty
};

struct Shooting {
  int intervals = 1;  // 1: single shooting (no `shooting:`)
  std::string time;   // the parameter that holds the interval's start time
  std::vector<ShootingState> states;
};

struct OptimizationConstraint {
  std::string objective;  // an objective of the model
  double lower = -std::numeric_limits<double>::infinity();  // `equals`: lower == upper
  double upper = std::numeric_limits<double>::infinity();
};

// An Ipopt option of the problem file, with the type Ipopt registers for it.
struct IpoptOption {
  enum class Kind { kNumber, kInteger, kString };
  std::string name;
  Kind kind = Kind::kNumber;
  double number = 0;
  int integer = 0;
  std::string text;
};

struct OptimizationProblem {
  std::string file;        // the problem file as given
  std::string model_path;  // the model file, resolved against the problem file's folder
  // `parameters:`: fixed overrides of model parameters, applied to every load of the model.
  std::map<std::string, double> parameters;
  mbs::Model model;        // as loaded with `parameters:` (the starting values)
  mbs::SimulationSettings settings;  // the model's, with the problem's overrides, validated
  std::vector<OptimizationVariable> variables;
  std::string objective;
  std::vector<OptimizationConstraint> constraints;
  GradientMethod method = GradientMethod::kAdjoint;
  Shooting shooting;
  // Applied after mbdae's defaults (hessian_approximation limited-memory, print_level 0):
  // any registered Ipopt option. hessian_approximation exact: mbdae gives the Hessian of the
  // Lagrangian by forward differences of the exact gradients (one gradient evaluation per
  // variable and Ipopt iteration).
  std::vector<IpoptOption> ipopt;
};

// Throws InputError (problem file mistakes, with FILE:LINE:COLUMN) or mbs::ModelError
// (model file mistakes).
OptimizationProblem LoadOptimizationProblem(const std::string& path);
// The same from YAML text: `name` names it in messages ("" = "<string>") and `model:` is
// resolved against the folder of `name` ("" or a bare file name: the working folder).
OptimizationProblem LoadOptimizationProblemFromString(const std::string& text, const std::string& name);

// One Ipopt iteration (intermediate_callback): iteration 0 is the starting point.
struct OptimizationIteration {
  int iteration = 0;
  double objective = 0;
  // Ipopt's inf_pr: the max-norm of the constraint violation of the iterate (of Ipopt's
  // internal problem, in which inequality constraints have slacks).
  double constraint_violation = 0;
  double dual_infeasibility = 0;  // Ipopt's inf_du
  double mu = 0;                  // barrier parameter
  double step = 0;                // Ipopt's alpha_pr
  int line_search_trials = 0;
  long gradient_evaluations = 0;  // ComputeGradient calls so far
};

struct OptimizeOptions {
  std::string results_path;  // the final run plus /optimization; "": no file
  // Called after every iteration (the program prints a progress line).
  std::function<void(const OptimizationIteration&)> iteration;
  // Called after `iteration`; returning true stops Ipopt (ipopt_status
  // User_Requested_Stop, status "failed"; the final point is still run and written).
  std::function<bool(const OptimizationIteration&)> stop;
};

struct OptimizationResult {
  bool solved = false;       // Ipopt: Solve_Succeeded or Solved_To_Acceptable_Level
  std::string status;        // "solved" | "failed"
  std::string ipopt_status;  // Ipopt's ApplicationReturnStatus, e.g. "Solve_Succeeded"
  std::vector<std::string> variable_names;
  std::vector<double> variables;  // the final point (Ipopt's last iterate when not solved)
  std::vector<double> lower, upper;
  std::string objective_name;
  double objective = std::numeric_limits<double>::quiet_NaN();  // of the final run
  std::vector<std::string> constraint_names;  // objective names of the constraints
  std::vector<double> constraint_values;      // of the final run
  // max over the constraints of the distance of the final run's value to [lower, upper].
  double constraint_violation = std::numeric_limits<double>::quiet_NaN();
  int iterations = 0;
  std::vector<OptimizationIteration> history;
  // Multiple shooting: the largest |continuity defect| at the final point, and the
  // intervals (the final run is one run over [0, t_end] from the final variables).
  int shooting_intervals = 1;
  double shooting_defect = 0;
  long gradient_evaluations = 0;  // ComputeGradient calls (each: a run and its gradient)
  long failed_evaluations = 0;    // of those, failed runs (Ipopt cut its step)
  // Hessians of the Lagrangian by differences of the gradients (`hessian_approximation:
  // exact`; their gradient evaluations are counted above)
  long hessian_evaluations = 0;
  long runs = 0;                  // whole simulation runs, the final run included
  double gradient_cpu_time = 0;   // CPU seconds inside ComputeGradient (runs + gradients)
  double cpu_time = 0;            // CPU seconds of Optimize
  double wall_time = 0;           // seconds of Optimize
  SimulationSummary final_run;    // of the final point (the results file's run)
  std::string failure_reason;     // the final run's, when it failed

  // The optimum, the constraints, iterations, status and the cost.
  std::string Report() const;
  // {"status": "solved", "objective": ..., "iterations": ..., "variables": {...},
  //  "constraint_violation": ..., "ipopt_status": ..., "constraints": {...},
  //  "gradient_evaluations": ..., "failed_evaluations": ..., "runs": ...,
  //  "gradient_cpu_time": ..., "cpu_time": ..., "wall_time": ...}; non-finite as null.
  std::string Json() const;
};

// Throws InputError for what the problem file cannot show before a run (a variable the
// exact methods cannot differentiate, named by ComputeGradient); everything after the
// first run is reported in the result.
OptimizationResult Optimize(const OptimizationProblem& problem, const OptimizeOptions& options);

}  // namespace mbdae::driver
