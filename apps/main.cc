// mbdae: the command-line program (see the command-line contract).
//
//   mbdae simulate MODEL.yaml [options]   integrate and write the HDF5 results file
//   mbdae info MODEL.yaml [--json]        counts and names
//   mbdae check MODEL.yaml                load, assemble, check determinacy
//   mbdae convert MODEL.fds [-o OUT.yaml] the model in this project's format
//   mbdae gradient MODEL.yaml [options]   dG/dp of the model's objectives
//   mbdae optimize PROBLEM.yaml [options] optimal control / identification with Ipopt
//   mbdae sweep STUDY.yaml [options]      parameter study / Monte Carlo on Dask (Python)
//
// MODEL may be a FreeDyn model file (.fds, any letter case) for every command.
// Output: progress on stderr, the summary and `info`/`check` reports on stdout, errors
// on stderr prefixed "mbdae: error: ". Exit codes: 0 done, 2 bad input (nothing
// written), 3 solver failed (file kept, status failed), 128 + N a simulation stopped by
// signal N (SIGINT: 130, SIGTERM: 143; file kept, status interrupted), 1 anything else.
#include <signal.h>
#include <unistd.h>

#include <cerrno>
#include <climits>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <iostream>
#include <map>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include "apps/cli.h"
#include "apps/view.h"
#include "driver/gradient.h"
#include "driver/optimize.h"
#include "driver/simulation.h"
#include "mbs/freedyn.h"
#include "mbs/loader.h"
#include "mbs/model_writer.h"

namespace mbdae::app {
namespace {

const char* kUsage =
    "usage:\n"
    "  mbdae simulate MODEL.yaml [-o RESULTS.h5] [--integrator hht|ida|kinematic|erk]\n"
    "                 [--t-end T] [--output-step H] [--step H] [--alpha A] [--adaptive]\n"
    "                 [--tolerance TOL] [--newton-tolerance TAU] [--linear-solver klu|tree]\n"
    "                 [--jacobian-cost C|auto] [--predictor auto|constant|linear]\n"
    "                 [--rotation-jacobian auto|first-order|exact]\n"
    "                 [--modified | --no-modified] [--hht-form equilibrium|negrut]\n"
    "                 [--hht-start consistent|perturbed]\n"
    "                 [--output-accelerations solved|integrator] [--rtol R] [--atol A]\n"
    "                 [--output-bodies|--output-joints|--output-forces|--output-measures all|none|N,N,...]\n"
    "                 [--set NAME=VALUE ...] [--quiet]\n"
    "  mbdae info MODEL.yaml [--json]\n"
    "  mbdae check MODEL.yaml\n"
    "  mbdae convert MODEL.fds|MODEL.yaml [-o OUT.yaml] [--set NAME=VALUE ...]\n"
    "  mbdae gradient MODEL.yaml [--objective NAME ...] [--wrt NAME,NAME,...] [--wrt-splines]\n"
    "                 [--method adjoint|forward|fd] [--fd-step S] [--trajectory-memory MIB]\n"
    "                 [every simulate option] [--json] [-o RESULTS.h5]\n"
    "  mbdae optimize PROBLEM.yaml [-o RESULTS.h5] [--json] [--quiet]\n"
    "  mbdae sweep STUDY.yaml [-o STUDY.h5] [--scheduler ADDRESS] [--workers N]\n"
    "                 [--retry-failed] [--flush-interval S] [--quiet]\n"
    "  mbdae view RESULTS.h5 [-o FILE.html]\n"
    "  mbdae --help | --version\n";

const char* kHelp =
    "\n"
    "simulate: integrates the model from t = 0 to t_end and writes one row per output\n"
    "time to RESULTS.h5 (default: the model's path with .h5 instead of .yaml/.yml/.json).\n"
    "Command-line values override the model's `simulation:` block:\n"
    "  -o, --output FILE     results file\n"
    "  --integrator hht|ida|kinematic|erk\n"
    "                        integrator; kinematic: kinematic analysis of a model\n"
    "                        without degrees of freedom (every motion driven); erk:\n"
    "                        explicit Runge-Kutta 5(4) on the index-1 form (smooth,\n"
    "                        non-stiff scenes at tight tolerances)\n"
    "  --t-end T             end time\n"
    "  --output-step H       time between output rows\n"
    "  --step H              HHT step (initial step when adaptive)\n"
    "  --alpha A             HHT alpha, in [-1/3, 0]\n"
    "  --adaptive            HHT with step size control (--fixed-step: without)\n"
    "  --tolerance TOL       HHT local error tolerance when adaptive\n"
    "  --newton-tolerance TAU\n"
    "                        HHT Newton threshold of fixed steps (default 1e-12)\n"
    "  --linear-solver S     HHT's and IDA's Newton matrix by klu (default) or tree\n"
    "                        (block elimination along a tree of bodies; klu where none)\n"
    "  --jacobian-cost C     HHT: a fresh Newton matrix costs C iterations; refresh it\n"
    "                        once it no longer pays (auto: 3 with tree, 0 = off with klu)\n"
    "  --predictor P         HHT: the Newton iteration's first iterate, constant (a_n,\n"
    "                        lambda_n) or linear (extrapolated from the last two steps);\n"
    "                        auto (default): linear with tree, constant with klu\n"
    "  --rotation-jacobian R HHT (modified scheme): the Newton matrix's Euler-parameter\n"
    "                        columns, first-order (the classical scheme's) or exact\n"
    "                        (the rotation update's 4 x 4 blocks; fewer iterations);\n"
    "                        auto (default): exact with tree, first-order with klu\n"
    "  --modified            HHT scheme modified for Euler parameters (default)\n"
    "  --no-modified         classical HHT\n"
    "  --hht-form F          HHT residual: equilibrium (default; generalized-alpha\n"
    "                        form, second order) or negrut (Negrut et al. 2007)\n"
    "  --hht-start S         start of the equilibrium form: consistent (default) or\n"
    "                        perturbed (no start-up oscillation of the multipliers)\n"
    "  --output-accelerations A\n"
    "                        a and lambda of the rows: solved (default: the\n"
    "                        acceleration-level equations at each row) or integrator\n"
    "                        (the integrator's own values)\n"
    "  --output-bodies L, --output-joints L, --output-forces L, --output-measures L\n"
    "                        the elements with datasets in the results file (/bodies/NAME,\n"
    "                        ...): all (default), none or comma-separated names; /q, /v,\n"
    "                        /a and /lambda always hold every coordinate and multiplier\n"
    "  --rtol R, --atol A    IDA and erk tolerances\n"
    "  --set NAME=VALUE ...  override a parameter of the model (repeatable)\n"
    "  --quiet               no progress, no summary\n"
    "Progress goes to stderr (a bar on a terminal, a line every 10 % otherwise); the\n"
    "summary goes to stdout.\n"
    "\n"
    "info: counts (bodies, coordinates, constraint equations, redundant ones, degrees of\n"
    "freedom, joints, measures, forces, parameters) and names; --json prints JSON.\n"
    "check: loads and assembles the model and checks that its motion is determined.\n"
    "convert: writes the model in this project's YAML format (format 1) to OUT.yaml, or\n"
    "to stdout without -o; a FreeDyn file (.fds) is translated, a YAML file normalised.\n"
    "\n"
    "gradient: values of the model's objectives (`objectives:`) and their gradients with\n"
    "respect to parameters and spline ordinates (docs/sensitivities.md):\n"
    "  --objective NAME      an objective (repeatable; default: every objective)\n"
    "  --wrt NAME,NAME       parameters and spline ordinates SPLINE[i] (default: every\n"
    "                        parameter)\n"
    "  --wrt-splines         also every ordinate of every spline\n"
    "  --method M            adjoint (default: HHT's discrete adjoint, IDAS adjoint),\n"
    "                        forward (HHT direct differentiation, IDAS forward\n"
    "                        sensitivities) or fd (central differences of whole runs)\n"
    "  --fd-step S           fd: relative step, h = S max(|p|, 1) (default 1e-5)\n"
    "  --trajectory-memory M HHT adjoint: MiB the stored run may take before only\n"
    "                        checkpoints are kept (default 512; 0: store every step)\n"
    "  --json                one JSON object on stdout\n"
    "  -o FILE               the forward run's results file plus /objectives/NAME with\n"
    "                        the value and the gradient (default: no file)\n"
    "The simulate options set the forward run.\n"
    "\n"
    "optimize: single shooting over model parameters and spline ordinates with Ipopt\n"
    "(exact gradients, limited-memory Hessian). PROBLEM.yaml names the model (relative\n"
    "to the problem file), the variables with bounds, the objective to minimise, the\n"
    "constraints (objectives of the model with bounds), simulation overrides, Ipopt\n"
    "options and the gradient method (docs/sensitivities.md, docs/cli.md):\n"
    "  -o FILE               the final run plus /optimization (default: the problem's\n"
    "                        path with .h5)\n"
    "  --json                one JSON object on stdout (status, objective, iterations,\n"
    "                        variables, constraint_violation, ...)\n"
    "  --quiet               no progress lines, no report\n"
    "One progress line per Ipopt iteration goes to stderr. Exit 0 when Ipopt solved the\n"
    "problem (or to an acceptable level), 3 otherwise (the final point and the history\n"
    "are still written).\n"
    "\n"
    "sweep: a parameter study or Monte Carlo study (STUDY.yaml: the model, parameters with\n"
    "values or distributions, outputs), each run a task on a Dask cluster (a local one, or\n"
    "--scheduler ADDRESS), the results in one HDF5 file; a rerun skips the runs done\n"
    "(docs/sweeps.md; `mbdae sweep --help`). Runs in Python: needs python3 with numpy,\n"
    "pandas, dask and distributed, and the package mbdae (built next to this program).\n"
    "\n"
    "view: writes one self-contained HTML file (default RESULTS.html) that plays the run in a\n"
    "browser (three.js inlined; at most 2000 rows drawn); docs/viewer.md. Exit 2 for a file\n"
    "that is not a results file.\n"
    "\n"
    "Every command also reads FreeDyn model files (MODEL.fds, see docs/freedyn.md) and\n"
    "URDF robot descriptions (MODEL.urdf, docs/urdf.md: the root link fixed to the world,\n"
    "or a free body with --floating-base).\n"
    "\n"
    "The results file is written as RESULTS.PID.tmp beside it and renamed when the run\n"
    "ends; an earlier file of that name stays whole until then. SIGTERM or SIGINT stops\n"
    "the run after the current step (status 'interrupted', the rows kept); gradient and\n"
    "optimize instead remove the temporary file and end at once (no file written).\n"
    "\n"
    "exit codes: 0 done; 2 bad input (nothing written); 3 the solver failed (the rows up\n"
    "to the failure are kept, status 'failed'); 130 / 143 (128 + signal) simulate stopped\n"
    "by SIGINT / SIGTERM; 1 anything else.\n";

void PrintError(const std::string& message) {
  std::fprintf(stderr, "mbdae: error: %s\n", message.c_str());
}

// The signal that asked a simulation to stop (0: none). The handler only sets it and
// restores the default action, so that a second signal ends the process at once.
volatile std::sig_atomic_t stop_signal = 0;

extern "C" void OnStopSignal(int signal_number) { stop_signal = signal_number; }

void CatchStopSignals() {
  struct sigaction action {};
  action.sa_handler = OnStopSignal;
  sigemptyset(&action.sa_mask);
  action.sa_flags = SA_RESETHAND;
  sigaction(SIGINT, &action, nullptr);
  sigaction(SIGTERM, &action, nullptr);
}

// gradient and optimize: a SIGINT or SIGTERM removes the temporary results file (the
// earlier results file stays as it was) and ends the process by the signal's default
// action. unlink and raise are async-signal-safe; the name is set once the file exists.
const char* volatile temporary_to_remove = nullptr;

extern "C" void OnSignalRemoveTemporary(int signal_number) {
  if (const char* name = temporary_to_remove) unlink(name);
  raise(signal_number);  // delivered on return: SA_RESETHAND restored the default action
}

void RemoveTemporaryOnSignal(const ResultsDestination& destination) {
  struct sigaction action {};
  action.sa_handler = OnSignalRemoveTemporary;
  sigemptyset(&action.sa_mask);
  sigaddset(&action.sa_mask, SIGINT);
  sigaddset(&action.sa_mask, SIGTERM);
  action.sa_flags = SA_RESETHAND;
  static std::string name;  // outlives the destination
  name = destination.temporary();
  temporary_to_remove = name.c_str();
  sigaction(SIGINT, &action, nullptr);
  sigaction(SIGTERM, &action, nullptr);
}

std::string TimeText(double t) {
  char text[32];
  std::snprintf(text, sizeof text, "%.12g", t);
  return text;
}

void RequireReadable(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw UsageError(path + ": cannot open the model file");
}

mbs::Model Load(const CommandLine& cl) {
  RequireReadable(cl.model_path);
  mbs::LoadOptions lo;
  lo.parameter_overrides = cl.parameter_overrides;
  lo.urdf_floating_base = cl.floating_base;
  return mbs::LoadAnyModel(cl.model_path, lo);
}

// Prefixes messages that do not name the model file yet.
std::string NameFile(const std::string& path, const std::string& message) {
  if (message.find(path) != std::string::npos) return message;
  return path + ": " + message;
}

int RunInfo(const CommandLine& cl) {
  mbs::Model model = Load(cl);
  // A model whose motion is not determined is reported like `check` does (naming the
  // bodies), rather than with the singular solve it would run into.
  driver::Assembly asmb = driver::Assemble(model);
  ModelInfo info = Describe(model, asmb);
  std::cout << (cl.json ? info.Json() : info.Text());
  return 0;
}

int RunCheck(const CommandLine& cl) {
  mbs::Model model = Load(cl);
  const mbs::SimulationSettings settings = driver::ResolveSettings(model.simulation, cl.overrides);
  driver::Assembly asmb = driver::Assemble(model);
  driver::CheckIntegrator(*asmb.kept_system, settings);
  ModelInfo info = Describe(model, asmb);
  std::cout << cl.model_path << ": ok: " << info.bodies.size() << " bodies, "
            << info.degrees_of_freedom << " degrees of freedom, " << info.redundant.size()
            << " redundant constraint equations\n"
            << asmb.Report() << "\n";
  return 0;
}

int RunConvert(const CommandLine& cl) {
  if (!cl.output_path.empty() && (cl.output_path == cl.model_path || SameFile(cl.output_path, cl.model_path)))
    throw UsageError("convert: the output file is the model file itself ('" + cl.model_path + "')");
  const mbs::Model model = Load(cl);
  mbs::ModelWriterOptions wo;
  wo.source = cl.model_path;
  if (cl.output_path.empty()) {
    std::cout << mbs::WriteModelYaml(model, wo) << std::flush;
  } else {
    mbs::WriteModelFile(model, cl.output_path, wo);
    if (!cl.quiet) std::cerr << "mbdae: wrote " << cl.output_path << "\n";
  }
  return 0;
}

int RunSimulate(const CommandLine& cl) {
  // Before anything else: the results file can be written (and is not the model).
  RequireReadable(cl.model_path);
  ResultsDestination destination(cl.output_path.empty() ? DefaultResultsPath(cl.model_path) : cl.output_path,
                                 cl.model_path);
  mbs::Model model = Load(cl);
  mbs::SimulationSettings settings = driver::ResolveSettings(model.simulation, cl.overrides);
  driver::CheckOutputSelection(model, settings);  // before the assembly's work
  driver::Assembly asmb = driver::Assemble(model);
  driver::CheckIntegrator(*asmb.kept_system, settings);
  if (!cl.quiet) {
    std::fprintf(stderr, "mbdae: %s\n", asmb.Report().c_str());
    if (driver::DegreesOfFreedom(*asmb.kept_system) == 0 && !settings.integrator_named)
      std::fprintf(stderr,
                   "mbdae: note: the model has no degrees of freedom (every motion driven): "
                   "`integrator: kinematic` (or --integrator kinematic) solves it by kinematic "
                   "analysis, to the Newton tolerance at each output time and faster\n");
    if (!asmb.redundant.empty()) {
      std::string names;
      for (const auto& n : asmb.redundant_names()) names += (names.empty() ? "" : ", ") + n;
      std::fprintf(stderr, "mbdae: %zu redundant constraint equations removed: %s\n",
                   asmb.redundant.size(), names.c_str());
    }
  }
  driver::SimulationOptions so;
  so.model_path = cl.model_path;
  CatchStopSignals();
  so.results_path = destination.CreateTemporary();
  so.stop = [] { return stop_signal != 0; };
  // Flushing costs about 0.3 ms a row: at most five times a second, so a killed run
  // loses at most the last 0.2 s of computing; failures and the end always flush.
  so.flush_interval = 0.2;
  ProgressReporter progress(cl.quiet ? ProgressReporter::Mode::kNone
                            : isatty(STDERR_FILENO) ? ProgressReporter::Mode::kBar
                                                    : ProgressReporter::Mode::kLines);
  so.progress = [&progress](double t, double t_end) { progress.Update(t, t_end); };
  driver::SimulationSummary summary = driver::Simulate(model, asmb, settings, so);
  progress.Finish();
  destination.Commit();
  summary.results_path = destination.path();
  if (!cl.quiet) std::cout << summary.FullReport() << std::flush;
  if (summary.status == driver::SimulationSummary::Status::kInterrupted) {
    const int signal_number = stop_signal;
    PrintError(std::string("interrupted by ") + (signal_number == SIGINT ? "SIGINT" : "SIGTERM") +
               " at t = " + TimeText(summary.t_reached) + "; the results up to there are in " +
               destination.path());
    return 128 + signal_number;
  }
  if (summary.status != driver::SimulationSummary::Status::kDone) {
    PrintError("the solver failed at t = " + TimeText(summary.t_reached) + ": " + summary.failure_reason +
               "; the results up to there are in " + destination.path());
    return 3;
  }
  return 0;
}

int RunGradient(const CommandLine& cl) {
  // As simulate: the results file can be written and is not the model, before loading.
  std::optional<ResultsDestination> destination;
  if (!cl.output_path.empty()) {
    RequireReadable(cl.model_path);
    destination.emplace(cl.output_path, cl.model_path);
  }
  mbs::Model model = Load(cl);
  mbs::SimulationSettings settings = driver::ResolveSettings(model.simulation, cl.overrides);
  driver::CheckOutputSelection(model, settings);
  driver::GradientRequest request;
  request.objectives = cl.objectives;
  request.wrt = cl.wrt;
  request.wrt_splines = cl.wrt_splines;
  if (!driver::ParseGradientMethod(cl.method, &request.method))
    throw UsageError("--method: expected adjoint, forward or fd, got '" + cl.method + "'");
  if (cl.fd_step) request.fd_step = *cl.fd_step;
  if (cl.trajectory_memory_mib) request.trajectory_memory = *cl.trajectory_memory_mib * 1024.0 * 1024.0;
  driver::GradientOptions go;
  go.model_path = cl.model_path;
  go.reload = [&cl](const std::map<std::string, double>& values) {
    mbs::LoadOptions lo;
    lo.parameter_overrides = cl.parameter_overrides;
    lo.urdf_floating_base = cl.floating_base;
    for (const auto& [name, value] : values) lo.parameter_overrides[name] = value;
    return mbs::LoadAnyModel(cl.model_path, lo);
  };
  ProgressReporter progress(cl.quiet || cl.json ? ProgressReporter::Mode::kNone
                            : isatty(STDERR_FILENO) ? ProgressReporter::Mode::kBar
                                                    : ProgressReporter::Mode::kLines);
  go.progress = [&progress](double t, double t_end) { progress.Update(t, t_end); };
  if (destination) {
    // The temporary file is created only once the input checked out (ComputeGradient's
    // InputErrors come before it writes), and renamed when everything is in it.
    go.results_path = destination->CreateTemporary();
    RemoveTemporaryOnSignal(*destination);
  }
  driver::GradientResult r = driver::ComputeGradient(model, settings, request, go);
  progress.Finish();
  if (destination) {
    destination->Commit();
    r.forward.results_path = destination->path();
  }
  if (cl.json)
    std::cout << r.Json() << "\n" << std::flush;
  else if (!cl.quiet && r.status == driver::GradientResult::Status::kDone)
    std::cout << r.Report() << std::flush;
  if (r.status != driver::GradientResult::Status::kDone) {
    PrintError("no gradient: " + r.failure_reason +
               (cl.output_path.empty() ? std::string() : "; the forward run is in " + cl.output_path));
    return 3;
  }
  return 0;
}

int RunOptimize(const CommandLine& cl) {
  // Every mistake of the problem file (and of its model) before anything runs.
  const driver::OptimizationProblem problem = driver::LoadOptimizationProblem(cl.model_path);
  // The results file can be written and is neither the problem file nor its model.
  ResultsDestination destination(cl.output_path.empty() ? DefaultResultsPath(cl.model_path) : cl.output_path,
                                 cl.model_path);
  if (SameFile(destination.path(), problem.model_path))
    throw UsageError("the results file '" + destination.path() + "' is the model file '" + problem.model_path +
                     "' of the problem: give another name with -o");
  driver::OptimizeOptions oo;
  // The final run and then /optimization go to the temporary file, renamed at the end.
  oo.results_path = destination.CreateTemporary();
  RemoveTemporaryOnSignal(destination);
  if (!cl.quiet)
    oo.iteration = [](const driver::OptimizationIteration& it) {
      if (it.iteration % 20 == 0)
        std::fprintf(stderr, "mbdae: %4s  %-22s  %-10s  %-10s  %-9s  %s\n", "iter", "objective", "violation",
                     "dual inf", "step", "gradients");
      std::fprintf(stderr, "mbdae: %4d  %22.14e  %10.3e  %10.3e  %9.2e  %ld\n", it.iteration, it.objective,
                   it.constraint_violation, it.dual_infeasibility, it.step, it.gradient_evaluations);
      std::fflush(stderr);
    };
  driver::OptimizationResult r = driver::Optimize(problem, oo);
  // A final run that could not start wrote nothing: the temporary file is removed (by
  // the destructor) and an earlier results file stays.
  if (!r.final_run.results_path.empty()) {
    destination.Commit();
    r.final_run.results_path = destination.path();
  }
  if (cl.json)
    std::cout << r.Json() << "\n" << std::flush;
  else if (!cl.quiet)
    std::cout << r.Report() << std::flush;
  if (!r.solved) {
    PrintError("not solved (Ipopt: " + r.ipopt_status + ")" +
               (r.failure_reason.empty() ? std::string() : ": " + r.failure_reason) +
               (r.final_run.results_path.empty() ? std::string()
                                                 : "; the final point and the history are in " + destination.path()));
    return 3;
  }
  return 0;
}

// sweep runs the Python implementation (python/mbdae/sweep.py) with the package found
// beside this program: <build>/python in the build tree, <prefix>/lib/mbdae/python when
// installed (python/CMakeLists.txt). The interpreter is MBDAE_PYTHON from the environment,
// else the one the build was configured with. Only returns when it cannot start Python.
const char* kSweepBootstrap =
    "import sys\n"
    "try:\n"
    "    from mbdae.sweep import main\n"
    "except ImportError as e:\n"
    "    sys.stderr.write('mbdae: error: sweep runs in Python (%s) with the package mbdae; "
    "importing it failed: %s\\n' % (sys.executable, e))\n"
    "    sys.exit(1)\n"
    "sys.exit(main(sys.argv[1:]))\n";

std::string ProgramFolder(const char* argv0) {
  char path[PATH_MAX];
  const ssize_t n = readlink("/proc/self/exe", path, sizeof path - 1);
  std::string exe = n > 0 ? std::string(path, static_cast<size_t>(n)) : std::string(argv0);
  const size_t slash = exe.rfind('/');
  return slash == std::string::npos ? std::string(".") : exe.substr(0, slash);
}

int RunSweep(int argc, char** argv) {
  const std::string folder = ProgramFolder(argv[0]);
  const std::vector<std::string> places = {folder + "/python", folder + "/../lib/mbdae/python"};
  std::string package;
  for (const auto& place : places)
    if (std::ifstream(place + "/mbdae/sweep.py")) {
      package = place;
      break;
    }
  if (package.empty()) {
    PrintError("sweep runs in Python and needs the package mbdae, which is neither in " + places[0] +
               " (the build tree: build the target mbdae_python) nor in " + places[1] +
               " (an installed mbdae: cmake --install)");
    return 1;
  }
  const char* from_env = std::getenv("MBDAE_PYTHON");
  const std::string python = from_env && *from_env ? from_env : MBDAE_PYTHON_EXECUTABLE;
  const char* old_path = std::getenv("PYTHONPATH");
  const std::string path = package + (old_path && *old_path ? ":" + std::string(old_path) : "");
  setenv("PYTHONPATH", path.c_str(), 1);
  std::vector<char*> args = {const_cast<char*>(python.c_str()), const_cast<char*>("-c"),
                             const_cast<char*>(kSweepBootstrap)};
  for (int k = 2; k < argc; ++k) args.push_back(argv[k]);
  args.push_back(nullptr);
  std::fflush(nullptr);
  execv(python.c_str(), args.data());
  PrintError("sweep runs in Python: cannot run " + python + " (" + std::strerror(errno) +
             "); install python3 (Debian: apt-get install python3 python3-numpy python3-pandas "
             "python3-dask python3-distributed) or name an interpreter in MBDAE_PYTHON");
  return 1;
}

int Run(int argc, char** argv) {
  CommandLine cl = ParseCommandLine(std::vector<std::string>(argv + 1, argv + argc));
  if (cl.help) {
    std::cout << kUsage << kHelp;
    return 0;
  }
  if (cl.version) {
    std::cout << "mbdae " << MBDAE_VERSION << "\n";
    return 0;
  }
  try {
    switch (cl.command) {
      case Command::kSimulate: return RunSimulate(cl);
      case Command::kInfo: return RunInfo(cl);
      case Command::kCheck: return RunCheck(cl);
      case Command::kConvert: return RunConvert(cl);
      case Command::kGradient: return RunGradient(cl);
      case Command::kOptimize: return RunOptimize(cl);
    }
  } catch (const driver::InputError& e) {
    throw driver::InputError(NameFile(cl.model_path, e.what()));
  }
  return 1;
}

}  // namespace
}  // namespace mbdae::app

int main(int argc, char** argv) {
  using namespace mbdae;
  // sweep is a Python program; its command line is its own (mbdae sweep --help).
  if (argc >= 2 && std::strcmp(argv[1], "sweep") == 0) return app::RunSweep(argc, argv);
  // view writes an HTML page from a results file (apps/view.h).
  if (argc >= 2 && std::strcmp(argv[1], "view") == 0) return app::RunView(argc, argv);
  try {
    return app::Run(argc, argv);
  } catch (const app::UsageError& e) {
    app::PrintError(e.what());
    if (e.show_usage()) std::fputs(app::kUsage, stderr);
    return 2;
  } catch (const mbs::ModelError& e) {
    app::PrintError(e.what());
    return 2;
  } catch (const driver::InputError& e) {
    app::PrintError(e.what());
    return 2;
  } catch (const std::exception& e) {
    app::PrintError(e.what());
    return 1;
  } catch (...) {
    app::PrintError("unknown exception");
    return 1;
  }
}
