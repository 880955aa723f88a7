// The gradient pipeline behind `mbdae gradient`, the C API's mbdae_gradient and
// Python's Model.gradient (shared/spec/sensitivities.md): gradients dG/dp of the model's
// objectives with respect to parameters and spline ordinates, by
//   - adjoint:  HHT: the discrete adjoint of the run (sensitivities/hht_sensitivity.h);
//               IDA: IDAS adjoint sensitivity analysis (sensitivities/idas_sensitivity.h);
//   - forward:  HHT: direct differentiation; IDA: IDAS forward sensitivities;
//   - fd:       central differences of whole runs (the reference; the step is reported).
//
//   Model model = mbs::LoadModel(path, {overrides});
//   SimulationSettings s = ResolveSettings(model.simulation, cli_overrides);
//   GradientRequest request;  request.method = GradientMethod::kAdjoint; ...
//   GradientResult r = ComputeGradient(model, s, request, options);   // throws InputError
//
// What is checked before anything runs or is written (InputError, exit 2 in the
// program): an objective or a wrt name that does not exist, a model without objectives,
// a parameter whose derivative the exact methods cannot take (the element and line are
// named: mbs::MultibodySystem's refusals), a method the integrator cannot provide for
// these objectives (the IDAS adjoint with objectives over accelerations or reactions),
// fd over parameters without a way to reload the model. A run that fails (the forward
// run, a perturbed run of fd, a sweep) gives status kFailed and no gradient.
//
// The forward run is the simulation of the settings, with two differences: every HHT
// run of a gradient (fd's too, so that fd differentiates the same discrete runs) has its
// adaptive Newton threshold lowered to GradientRequest::newton_factor * tolerance (the
// exact gradient is exact to the Newton tolerance); and for IDA the values and
// gradients come from the IDAS run with sensitivities (forward) or with checkpoints
// (adjoint; it stops only at t_end), while the results file (-o) and solver_cpu_time
// are those of a plain IDA run of the same settings (one more run).
// fd of an adaptive HHT run replays the forward run's accepted step sequence in every
// perturbed run (the derivative of the discrete objective of that sequence).
#pragma once

#include <functional>
#include <map>
#include <string>
#include <vector>

#include "driver/simulation.h"
#include "mbs/model.h"

namespace mbdae::driver {

enum class GradientMethod { kAdjoint, kForward, kFd };
const char* GradientMethodName(GradientMethod method);  // "adjoint" | "forward" | "fd"
bool ParseGradientMethod(const std::string& name, GradientMethod* method);

struct GradientRequest {
  // Objective names (Model::objectives); empty: every objective of the model.
  std::vector<std::string> objectives;
  // Parameter names and spline ordinates "SPLINE[i]"; empty: every parameter.
  std::vector<std::string> wrt;
  // Adds every ordinate of every spline (after `wrt`, or after every parameter when
  // `wrt` is empty), skipping ones already listed.
  bool wrt_splines = false;
  GradientMethod method = GradientMethod::kAdjoint;
  // fd: the step of parameter p is fd_step * max(|p|, 1) (central differences, error
  // O(step^2) plus the runs' own error / step).
  double fd_step = 1e-5;
  // HHT, exact methods: the adaptive Newton threshold of the forward run,
  // max(newton_tolerance, newton_factor * tolerance) (dae::HhtOptions).
  double newton_factor = 1e-6;
  // HHT adjoint: bytes the stored trajectory may take before it keeps checkpoints only
  // (sensitivities/hht_sensitivity.h); 0: store every step.
  double trajectory_memory = 512.0 * 1024 * 1024;
  // IDA adjoint: forward steps between two IDAS checkpoints.
  long ida_checkpoint_steps = 200;
  AssemblyOptions assembly;

  bool IsValid(std::string* error) const;
};

struct GradientOptions {
  std::string model_path;    // the results file's `model` attribute
  std::string results_path;  // "" : no results file
  // Called with (t, t_end) after every output row of the forward run.
  std::function<void(double, double)> progress;
  // fd over model parameters: the model loaded again with these parameter values set
  // (as --set does, on top of whatever the base model was loaded with). Without it a
  // request of fd with respect to a parameter is an InputError; spline ordinates need
  // no reload.
  std::function<mbs::Model(const std::map<std::string, double>& overrides)> reload;
};

struct GradientResult {
  enum class Status { kDone, kFailed };
  Status status = Status::kFailed;
  std::string failure_reason;
  std::string method;             // "adjoint" | "forward" | "fd"
  std::string integrator;         // "hht" | "ida"
  std::string integrator_detail;  // Integrator::name() of the forward run
  std::vector<std::string> objectives;  // names, in the model's order
  std::vector<std::string> wrt;         // names, in the request's order
  std::vector<double> values;     // G_i of the forward run
  std::vector<double> gradient;   // dG_i/dp_k at [i * wrt.size() + k]
  std::vector<double> fd_steps;   // fd: the absolute step of each wrt entry
  double solver_cpu_time = 0;     // process CPU seconds of the forward run
  double gradient_cpu_time = 0;   // process CPU seconds of the gradient beyond it
                                  // (fd: every perturbed run and its assembly)
  double wall_time = 0;           // seconds, everything
  long forward_steps = 0;         // accepted steps of the forward run
  long linear_solves = 0;         // of the sweep (HHT), 0 otherwise
  double trajectory_bytes = 0;    // HHT exact methods: memory of the stored run
  long runs = 1;                  // whole runs done (fd: 1 + 2 per wrt entry)
  SimulationSummary forward;      // of the forward run (the results file's run)

  double Gradient(int objective, int wrt_index) const {
    return gradient[static_cast<size_t>(objective) * wrt.size() + wrt_index];
  }
  // One line per objective with its value, then a table of dG/dp (one row per wrt
  // entry, one column per objective), then the method, the times and (fd) the steps.
  std::string Report() const;
  // Exactly one JSON object (shared/spec/sensitivities.md), plus "status",
  // "failure_reason" (failed), "fd_steps" (fd), "forward_steps", "runs".
  // Non-finite numbers are written as null.
  std::string Json() const;
};

// Throws InputError (nothing run, nothing written) for the mistakes listed above.
// results_path: the results file of the forward run plus, per objective, the group
// /objectives/NAME with attributes value, integral, terminal (HHT: the run's
// quadrature), gradient_names and the dataset gradient (the values of a failed
// gradient are not written; the file's status says what happened).
GradientResult ComputeGradient(const mbs::Model& model, const mbs::SimulationSettings& settings,
                               const GradientRequest& request, const GradientOptions& options);

// The settings whose runs a gradient differentiates (ComputeGradient's runs, optimize's
// final run): a fixed-step HHT Newton threshold no looser than the default 1e-12 (a
// model's looser hht.newton_tolerance would leave the runs, and so the gradient, off by
// about that much).
mbs::SimulationSettings GradientRunSettings(const mbs::SimulationSettings& settings);

}  // namespace mbdae::driver
