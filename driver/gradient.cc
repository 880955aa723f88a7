#include "driver/gradient.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <ctime>
#include <set>
#include <sstream>
#include <stdexcept>

#include "mbs/model_writer.h"
#include "mbs/sensitivity_parameters.h"
#include "sensitivities/hht_sensitivity.h"
#include "sensitivities/idas_sensitivity.h"
#include "sensitivities/initial_state.h"
#include "sensitivities/model_objectives.h"

namespace mbdae::driver {
namespace {

double CpuSeconds() { return double(std::clock()) / CLOCKS_PER_SEC; }

std::string Prefix(const mbs::Model& model) { return model.file.empty() ? "" : model.file + ": "; }

std::string Join(const std::vector<std::string>& names) {
  std::string out;
  for (size_t i = 0; i < names.size(); ++i) out += (i ? ", " : "") + names[i];
  return out;
}

// JSON strings: quoted and escaped as the model writer does.
std::string JsonString(const std::string& s) { return mbs::DoubleQuoted(s); }

std::string JsonNumber(double x) {
  if (!std::isfinite(x)) return "null";
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.17g", x);
  return buf;
}

std::string Fixed(double x, const char* format = "%.10g") {
  char buf[40];
  std::snprintf(buf, sizeof buf, format, x);
  return buf;
}

// The model with only the selected objectives (in the model's order). Throws
// InputError for an unknown name or a model without objectives.
mbs::Model SelectObjectives(const mbs::Model& model, const std::vector<std::string>& wanted) {
  if (model.objectives.empty())
    throw InputError(Prefix(model) +
                     "the model has no objectives: add an `objectives:` list to the model file "
                     "(docs/model-format.md)");
  std::vector<std::string> known;
  for (const auto& o : model.objectives) known.push_back(o.name);
  std::set<std::string> selected;
  for (const std::string& name : wanted) {
    if (std::find(known.begin(), known.end(), name) == known.end())
      throw InputError(Prefix(model) + "objective '" + name + "' does not exist; the model's objectives: " +
                       Join(known));
    selected.insert(name);
  }
  mbs::Model m = model;
  if (!wanted.empty()) {
    m.objectives.clear();
    for (const auto& o : model.objectives)
      if (selected.count(o.name)) m.objectives.push_back(o);
  }
  return m;
}

// The names of the request: `wrt` (or every parameter), then every spline ordinate
// with wrt_splines. Throws InputError for duplicates or an empty list.
std::vector<std::string> WrtNames(const mbs::Model& model, const GradientRequest& request) {
  std::vector<std::string> names = request.wrt;
  if (names.empty())
    for (const auto& p : model.parameters) names.push_back(p.name);
  std::set<std::string> seen;
  for (const std::string& n : names)
    if (!seen.insert(n).second) throw InputError("--wrt lists '" + n + "' twice");
  if (request.wrt_splines)
    for (const auto& s : model.splines)
      for (size_t i = 0; i < s.spline.x().size(); ++i) {
        const std::string n = s.name + "[" + std::to_string(i) + "]";
        if (seen.insert(n).second) names.push_back(n);
      }
  if (names.empty())
    throw InputError(Prefix(model) +
                     "nothing to differentiate with respect to: the model has no parameters "
                     "(name some with --wrt, or add spline ordinates with --wrt-splines)");
  return names;
}

// Whether some objective uses an acceleration or a reaction measure (what the IDAS
// adjoint refuses); the first such objective and measure are named in *what.
bool UsesAccelerationOrReaction(const mbs::Model& model, std::string* what) {
  for (const auto& o : model.objectives)
    for (const mbs::Expression* e : {&o.integral, &o.terminal})
      for (int u : e->measures_used()) {
        const mbs::Measure& me = model.measures[u];
        if (me.type == mbs::MeasureType::kReaction || me.quantity == mbs::Quantity::kAcceleration) {
          *what = "objective '" + o.name + "' uses " +
                  (me.type == mbs::MeasureType::kReaction ? "the reaction measure '"
                                                          : "the acceleration measure '") +
                  me.name + "'";
          return true;
        }
      }
  return false;
}

double ParameterValue(const mbs::Model& model, const mbs::SensitivityParameter& p) {
  if (p.parameter >= 0) return model.parameters[p.parameter].value;
  return model.splines[p.spline].spline.y()[p.point];
}

// What every HHT run of a gradient changes in the options of its settings
// (GradientRunSettings): the tighter adaptive Newton threshold and the start the
// sensitivities differentiate.
void TightenForGradient(dae::HhtOptions& o, double newton_factor) {
  o.adaptive_newton_factor = std::min(o.adaptive_newton_factor, newton_factor);
  o.start = dae::HhtOptions::Start::kConsistent;
}

// The HHT options of a gradient's forward run.
dae::HhtOptions GradientHhtOptions(const mbs::SimulationSettings& settings, double newton_factor) {
  dae::HhtOptions o = HhtOptionsOf(settings);
  TightenForGradient(o, newton_factor);
  return o;
}

void Fail(GradientResult* r, const std::string& reason) {
  r->status = GradientResult::Status::kFailed;
  r->failure_reason = reason;
  r->values.clear();
  r->gradient.clear();
}

// Adds the gradient to the results file of the forward run.
void WriteGradient(const std::string& path, const GradientResult& r) {
  std::vector<io::ResultsGroup> groups;
  const bool ok = r.status == GradientResult::Status::kDone;
  for (size_t i = 0; i < r.objectives.size() && ok; ++i) {
    io::ResultsGroup g;
    g.path = "objectives/" + r.objectives[i];
    g.numbers.emplace_back("value", r.values[i]);
    g.strings.emplace_back("gradient_names", r.wrt);
    g.datasets.emplace_back("gradient", std::vector<double>(r.gradient.begin() + i * r.wrt.size(),
                                                            r.gradient.begin() + (i + 1) * r.wrt.size()));
    groups.push_back(std::move(g));
  }
  std::vector<std::pair<std::string, std::string>> root{
      {"gradient_method", r.method}, {"gradient_status", ok ? "done" : "failed"}};
  if (!ok) root.emplace_back("gradient_failure_reason", r.failure_reason);
  io::AddToResultsFile(path, groups, root);
}

}  // namespace

const char* GradientMethodName(GradientMethod method) {
  switch (method) {
    case GradientMethod::kAdjoint: return "adjoint";
    case GradientMethod::kForward: return "forward";
    case GradientMethod::kFd: return "fd";
  }
  return "?";
}

bool ParseGradientMethod(const std::string& name, GradientMethod* method) {
  for (GradientMethod m : {GradientMethod::kAdjoint, GradientMethod::kForward, GradientMethod::kFd})
    if (name == GradientMethodName(m)) {
      *method = m;
      return true;
    }
  return false;
}

bool GradientRequest::IsValid(std::string* error) const {
  auto fail = [error](const std::string& m) {
    if (error) *error = m;
    return false;
  };
  if (!(fd_step > 0) || !(fd_step < 1)) return fail("fd_step must be in (0, 1), got " + Fixed(fd_step));
  if (!(newton_factor > 0) || !std::isfinite(newton_factor))
    return fail("newton_factor must be > 0, got " + Fixed(newton_factor));
  if (!(trajectory_memory >= 0) || !std::isfinite(trajectory_memory))
    return fail("trajectory_memory must be >= 0 bytes, got " + Fixed(trajectory_memory));
  if (ida_checkpoint_steps < 1)
    return fail("ida_checkpoint_steps must be >= 1, got " + std::to_string(ida_checkpoint_steps));
  return assembly.IsValid(error);
}

mbs::SimulationSettings GradientRunSettings(const mbs::SimulationSettings& settings) {
  mbs::SimulationSettings s = settings;
  s.hht_newton_tolerance = std::min(s.hht_newton_tolerance, dae::HhtOptions().newton_tolerance);
  return s;
}

GradientResult ComputeGradient(const mbs::Model& model, const mbs::SimulationSettings& requested,
                               const GradientRequest& request, const GradientOptions& options) {
  const auto wall_start = std::chrono::steady_clock::now();
  // The settings the runs use, as their results file records them.
  const mbs::SimulationSettings settings = GradientRunSettings(requested);
  std::string error;
  if (!request.IsValid(&error)) throw InputError("gradient options: " + error);

  // ---- Everything the user can get wrong, before anything runs or is written.
  const mbs::Model m = SelectObjectives(model, request.objectives);
  const std::vector<std::string> wrt_names = WrtNames(m, request);
  std::vector<mbs::SensitivityParameter> params;
  try {
    params = mbs::ResolveSensitivityParameters(m, wrt_names);
  } catch (const std::invalid_argument& e) {
    throw InputError(Prefix(m) + "--wrt: " + e.what());
  }
  if (settings.integrator == mbs::IntegratorKind::kErk)
    throw InputError(Prefix(m) + "gradients are taken of hht or ida runs; the erk integrator has no "
                     "sensitivities (use --integrator hht or ida)");
  if (settings.integrator == mbs::IntegratorKind::kKinematic)
    throw InputError(Prefix(m) + "gradients are taken of hht or ida runs; the kinematic analysis has no "
                     "sensitivities (use --integrator hht or ida)");
  if (settings.integrator == mbs::IntegratorKind::kHht && settings.hht_dense_output)
    throw InputError(Prefix(m) + "gradients of hht runs follow steps that land on the output times; "
                     "hht dense_output is not supported (set hht: {dense_output: false})");
  if (settings.integrator == mbs::IntegratorKind::kIda && settings.ida_dense_output)
    throw InputError(Prefix(m) + "gradients of ida runs follow steps that land on the output times; "
                     "ida dense_output is not supported (set ida: {dense_output: false})");
  const bool hht = settings.integrator == mbs::IntegratorKind::kHht;
  const bool exact = request.method != GradientMethod::kFd;
  if (request.method == GradientMethod::kAdjoint && !hht) {
    std::string what;
    if (UsesAccelerationOrReaction(m, &what))
      throw InputError(Prefix(m) + "the adjoint of the ida integrator (IDAS) cannot take gradients of objectives "
                       "over accelerations or reactions (" + what +
                       "); use --method forward, or the hht integrator");
  }
  if (!exact && !options.reload)
    for (const auto& p : params)
      if (p.parameter >= 0)
        throw InputError("fd with respect to parameter '" + p.name +
                         "' needs the model to be loaded again with new values, which this caller "
                         "does not offer");

  GradientResult r;
  r.method = GradientMethodName(request.method);
  r.integrator = IntegratorName(settings.integrator);
  for (const auto& o : m.objectives) r.objectives.push_back(o.name);
  r.wrt = wrt_names;
  const int no = static_cast<int>(r.objectives.size());
  const int np = static_cast<int>(params.size());

  // The assembly (with parameter derivatives for the exact methods: refusals of
  // dependencies that cannot be differentiated come out here as InputError).
  AssemblyOptions assembly_options = request.assembly;
  if (exact) assembly_options.sensitivity = params;
  Assembly asmb = Assemble(m, assembly_options);
  const int nq = asmb.kept_system->num_coordinates();
  const int nc = asmb.kept_system->num_constraints();

  // ---- The forward run (the results file's).
  SimulationOptions so;
  so.model_path = options.model_path;
  so.results_path = options.results_path;
  so.progress = options.progress;
  sens::HhtTrajectory trajectory(nq, nc);
  std::vector<double> steps;  // fd of adaptive HHT: the accepted step sizes, replayed
  const double newton_factor = request.newton_factor;
  // Every HHT run of a gradient (the exact methods' and fd's) uses the tighter Newton
  // threshold, so that fd differentiates the same discrete runs.
  if (hht)
    so.adjust_hht = [newton_factor](dae::HhtOptions& o) { TightenForGradient(o, newton_factor); };
  if (hht && exact) {
    // The record of the run under the memory budget (checkpoints beyond it:
    // docs/sensitivities.md, "Memory and checkpoints"); a budget too small is bad input.
    try {
      trajectory.set_memory_budget(static_cast<size_t>(request.trajectory_memory));
    } catch (const std::invalid_argument& e) {
      throw InputError(std::string("trajectory_memory: ") + e.what());
    }
    so.prepare = [&trajectory](dae::Integrator& integrator) { trajectory.Attach(integrator); };
  } else if (hht && settings.hht_adaptive) {
    so.prepare = [&steps](dae::Integrator& integrator) {
      integrator.SetStepObserver([&steps](const dae::State&, double h) {
        if (h > 0) steps.push_back(h);
      });
    };
  }
  r.forward = Simulate(m, asmb, settings, so);
  r.integrator_detail = r.forward.integrator_detail;
  r.solver_cpu_time = r.forward.solver_cpu_time;
  r.forward_steps = r.forward.counters.steps_accepted;
  const double cpu_start = CpuSeconds();
  auto finish = [&]() {
    r.gradient_cpu_time = CpuSeconds() - cpu_start;
    r.wall_time = std::chrono::duration<double>(std::chrono::steady_clock::now() - wall_start).count();
    if (!options.results_path.empty() && r.forward.status == SimulationSummary::Status::kDone)
      WriteGradient(options.results_path, r);
    return r;
  };
  if (r.forward.status != SimulationSummary::Status::kDone) {
    Fail(&r, "the forward run failed at t = " + Fixed(r.forward.t_reached, "%.6g") + ": " +
                 r.forward.failure_reason);
    return finish();
  }
  if (static_cast<int>(r.forward.objectives.size()) != no) {
    Fail(&r, "the objective values of the forward run are missing: " + r.forward.objectives_note);
    return finish();
  }
  r.status = GradientResult::Status::kDone;  // until something below fails
  r.values.resize(no);
  for (int i = 0; i < no; ++i) r.values[i] = r.forward.objectives[i].value;
  r.gradient.assign(static_cast<size_t>(no) * np, 0.0);

  if (exact) {
    // ---- Derivatives of the consistent initial state, then the sweep or IDAS.
    sens::InitialStateDerivatives dx0;
    std::vector<double> dq_raw, dv_raw;
    asmb.system->InitialStateParameterDerivatives(dq_raw, dv_raw);
    if (!sens::ConsistentInitialStateDerivatives(*asmb.kept_system, asmb.x0, asmb.v_raw, dq_raw, dv_raw,
                                                 &dx0, &error)) {
      Fail(&r, "derivatives of the initial state: " + error);
      return finish();
    }
    sens::ModelObjectives objectives(m, *asmb.system, asmb.kept, params);
    if (hht && request.method == GradientMethod::kAdjoint) {
      // The backward sweep starts at t_end: count the angles' turns on from there.
      sens::ModelObjectives::AngleTrack track;
      track.t = r.forward.objectives_angle_t;
      track.angles = r.forward.objectives_angles;
      track.rates = r.forward.objectives_angle_rates;
      objectives.set_angle_track(track);
    }
    if (hht) {
      const dae::HhtOptions ho = GradientHhtOptions(settings, newton_factor);
      sens::HhtSensitivityResult sr;
      const bool ok = request.method == GradientMethod::kAdjoint
                          ? sens::HhtAdjointGradient(*asmb.kept_system, ho, objectives, trajectory, dx0, &sr, &error)
                          : sens::HhtForwardGradient(*asmb.kept_system, ho, objectives, trajectory, dx0, &sr, &error);
      r.trajectory_bytes = static_cast<double>(trajectory.memory());
      if (!ok) {
        Fail(&r, std::string("the ") + r.method + " sweep failed: " + error);
        return finish();
      }
      r.values = sr.values;
      r.gradient = sr.gradient;
      r.linear_solves = sr.linear_solves;
    } else {
      sens::IdasSensitivityOptions io;
      io.ida = IdaOptionsOf(settings);
      io.t_end = settings.t_end;
      const std::vector<double> times = OutputTimes(settings.t_end, settings.output_step);
      if (times.size() > 2) io.output_times.assign(times.begin() + 1, times.end() - 1);
      io.checkpoint_steps = request.ida_checkpoint_steps;
      sens::IdasSensitivityResult sr;
      const bool ok = request.method == GradientMethod::kAdjoint
                          ? sens::IdasAdjointGradient(*asmb.kept_system, io, objectives, asmb.x0, dx0, &sr, &error)
                          : sens::IdasForwardGradient(*asmb.kept_system, io, objectives, asmb.x0, dx0, &sr, &error);
      if (!ok) {
        Fail(&r, std::string("IDAS ") + r.method + " sensitivities failed: " + error);
        return finish();
      }
      r.values = sr.values;
      r.gradient = sr.gradient;
      r.runs = 2;
    }
    return finish();
  }

  // ---- Central differences of whole runs.
  SimulationOptions po;  // no file, no progress
  po.adjust_hht = so.adjust_hht;
  if (hht && settings.hht_adaptive) {
    po.adjust_hht = [&steps, newton_factor](dae::HhtOptions& o) {
      TightenForGradient(o, newton_factor);
      o.replay_steps = steps;
    };
  }
  r.fd_steps.resize(np);
  for (int k = 0; k < np; ++k) {
    const mbs::SensitivityParameter& p = params[k];
    const double value = ParameterValue(m, p);
    const double h = request.fd_step * std::max(std::abs(value), 1.0);
    r.fd_steps[k] = h;
    std::vector<double> plus(no), minus(no);
    for (int side = 0; side < 2; ++side) {
      const double pv = side == 0 ? value + h : value - h;
      std::vector<double>& out = side == 0 ? plus : minus;
      try {
        mbs::Model pm;
        if (p.parameter >= 0) {
          pm = SelectObjectives(options.reload({{p.name, pv}}), r.objectives);
        } else {
          pm = m;
          mbs::Spline& s = pm.splines[p.spline].spline;
          std::vector<double> y = s.y();
          y[p.point] = pv;
          s.SetPoints(s.x(), y);
        }
        // The perturbed model has the base model's structure, whose motion the base
        // assembly found determined: the dense determinacy check is not repeated.
        AssemblyOptions pao = request.assembly;
        pao.check_determinacy = false;
        Assembly pa = Assemble(pm, pao);
        const SimulationSummary ps = Simulate(pm, pa, settings, po);
        ++r.runs;
        if (ps.status != SimulationSummary::Status::kDone) {
          Fail(&r, "the run with " + p.name + " = " + Fixed(pv, "%.17g") + " failed at t = " +
                       Fixed(ps.t_reached, "%.6g") + ": " + ps.failure_reason);
          return finish();
        }
        if (static_cast<int>(ps.objectives.size()) != no) {
          Fail(&r, "the run with " + p.name + " = " + Fixed(pv, "%.17g") +
                       " gave no objective values: " + ps.objectives_note);
          return finish();
        }
        for (int i = 0; i < no; ++i) out[i] = ps.objectives[i].value;
      } catch (const std::exception& e) {
        Fail(&r, "the run with " + p.name + " = " + Fixed(pv, "%.17g") + " failed: " + e.what());
        return finish();
      }
    }
    for (int i = 0; i < no; ++i) r.gradient[static_cast<size_t>(i) * np + k] = (plus[i] - minus[i]) / (2 * h);
  }
  return finish();
}

std::string GradientResult::Report() const {
  std::ostringstream s;
  const bool ok = status == Status::kDone;
  if (!ok) {
    s << "gradient failed: " << failure_reason << "\n";
    return s.str();
  }
  size_t width = 8;
  for (const auto& n : objectives) width = std::max(width, n.size());
  for (const auto& n : wrt) width = std::max(width, n.size() + 2);
  for (size_t i = 0; i < objectives.size(); ++i)
    s << "objective " << objectives[i] << std::string(width - objectives[i].size() + 1, ' ')
      << Fixed(values[i], "%.12g") << "\n";
  s << "\n" << std::string(width + 2, ' ');
  for (const auto& o : objectives) {
    const std::string head = "d" + o + "/dp";
    s << " " << std::string(head.size() < 22 ? 22 - head.size() : 0, ' ') << head;
  }
  s << "\n";
  for (size_t k = 0; k < wrt.size(); ++k) {
    s << "  " << wrt[k] << std::string(width - wrt[k].size(), ' ');
    for (size_t i = 0; i < objectives.size(); ++i) s << " " << Fixed(Gradient(static_cast<int>(i), static_cast<int>(k)), "%22.14e");
    s << "\n";
  }
  s << "\nmethod: " << method << ", integrator " << integrator;
  if (!integrator_detail.empty()) s << " (" << integrator_detail << ")";
  s << "\nforward run: " << forward_steps << " steps, solver CPU time " << Fixed(solver_cpu_time, "%.4g")
    << " s; gradient CPU time " << Fixed(gradient_cpu_time, "%.4g") << " s";
  if (runs > 1) s << " (" << runs << " runs)";
  s << "\n";
  if (!fd_steps.empty()) {
    s << "fd steps (central differences, absolute):";
    for (size_t k = 0; k < wrt.size(); ++k) s << (k ? ", " : " ") << wrt[k] << " " << Fixed(fd_steps[k], "%.3g");
    s << "\n";
  }
  if (!forward.results_path.empty()) s << "results: " << forward.results_path << "\n";
  return s.str();
}

std::string GradientResult::Json() const {
  std::ostringstream s;
  const bool ok = status == Status::kDone;
  s << "{\"method\": " << JsonString(method) << ", \"integrator\": " << JsonString(integrator)
    << ", \"status\": " << JsonString(ok ? "done" : "failed");
  if (!ok) s << ", \"failure_reason\": " << JsonString(failure_reason);
  s << ", \"objectives\": {";
  for (size_t i = 0; i < objectives.size() && ok; ++i) {
    s << (i ? ", " : "") << JsonString(objectives[i]) << ": {\"value\": " << JsonNumber(values[i])
      << ", \"gradient\": {";
    for (size_t k = 0; k < wrt.size(); ++k)
      s << (k ? ", " : "") << JsonString(wrt[k]) << ": "
        << JsonNumber(Gradient(static_cast<int>(i), static_cast<int>(k)));
    s << "}}";
  }
  s << "}";
  if (!fd_steps.empty()) {
    s << ", \"fd_steps\": {";
    for (size_t k = 0; k < wrt.size(); ++k) s << (k ? ", " : "") << JsonString(wrt[k]) << ": " << JsonNumber(fd_steps[k]);
    s << "}";
  }
  s << ", \"solver_cpu_time\": " << JsonNumber(solver_cpu_time)
    << ", \"gradient_cpu_time\": " << JsonNumber(gradient_cpu_time)
    << ", \"forward_steps\": " << forward_steps << ", \"runs\": " << runs << "}";
  return s.str();
}

}  // namespace mbdae::driver
