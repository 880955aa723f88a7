#include "driver/simulation.h"

#include "dae/format.h"
#include "sensitivities/model_objectives.h"
#include "driver/determinacy.h"

#include <Eigen/Dense>
#include <Eigen/SparseCore>

#include <algorithm>
#include <cassert>
#include <chrono>
#include <ctime>
#include <cmath>
#include <cstdlib>
#include <limits>
#include <map>
#include <set>
#include <sstream>

#include "dae/hht.h"
#include "dae/ida.h"
#include "dae/kinematic.h"
#include "io/results_geometry.h"

namespace mbdae::driver {
namespace {

constexpr double kPi = 3.14159265358979323846;

std::string Num(double x) { return FormatG(x, 6); }

std::string Join(const std::vector<std::string>& names, const char* sep = ", ") {
  std::string out;
  for (size_t i = 0; i < names.size(); ++i) out += (i ? sep : "") + names[i];
  return out;
}

// Thrown by the stop check (SimulationOptions::stop) out of the integrator's step
// observer; not a std::exception, so that nothing between takes it for a failure.
struct StopRequest {};

}  // namespace

dae::HhtOptions HhtOptionsOf(const mbs::SimulationSettings& s) {
  dae::HhtOptions o;
  o.alpha = s.hht_alpha;
  o.step = s.hht_step;
  o.adaptive = s.hht_adaptive;
  o.tolerance = s.hht_tolerance;
  o.modified = s.hht_modified;
  o.dense_output = s.hht_dense_output;
  o.newton_tolerance = s.hht_newton_tolerance;
  o.jacobian_cost = s.hht_jacobian_cost;
  auto fail = [](const char* key, const std::vector<std::string>& names, const std::string& v) {
    return InputError(std::string("hht settings: ") + key + " must be " + JoinOr(names) +
                      ", got '" + v + "'");
  };
  if (!dae::ParseHhtForm(s.hht_form, &o.form)) throw fail("form", dae::HhtFormNames(), s.hht_form);
  if (!dae::ParseHhtStart(s.hht_start, &o.start))
    throw fail("start", dae::HhtStartNames(), s.hht_start);
  if (!dae::ParseHhtPredictor(s.hht_predictor, &o.predictor))
    throw fail("predictor", dae::HhtPredictorNames(), s.hht_predictor);
  if (!dae::ParseHhtRotationJacobian(s.hht_rotation_jacobian, &o.rotation_jacobian))
    throw fail("rotation_jacobian", dae::HhtRotationJacobianNames(), s.hht_rotation_jacobian);
  if (!dae::ParseHhtLinearSolver(s.hht_linear_solver, &o.linear_solver))
    throw fail("linear_solver", dae::HhtLinearSolverNames(), s.hht_linear_solver);
  return o;
}

dae::ErkOptions ErkOptionsOf(const mbs::SimulationSettings& s) {
  dae::ErkOptions o;
  o.rtol = s.erk_rtol;
  o.atol = s.erk_atol;
  o.max_steps = s.erk_max_steps;
  o.min_step = s.erk_min_step;
  o.max_step = s.erk_max_step;
  return o;
}

dae::IdaOptions IdaOptionsOf(const mbs::SimulationSettings& s) {
  dae::IdaOptions o;
  o.rtol = s.ida_rtol;
  o.atol = s.ida_atol;
  o.max_steps = s.ida_max_steps;
  o.min_step = s.ida_min_step;
  o.dense_output = s.ida_dense_output;
  if (!dae::ParseHhtLinearSolver(s.ida_linear_solver, &o.linear_solver))
    throw InputError("ida settings: linear_solver must be klu or tree, got '" +
                     s.ida_linear_solver + "'");
  return o;
}

namespace {

// Names of the joints (or normalisations) owning the listed constraint equations.
std::vector<std::string> OwnersOf(const mbs::MultibodySystem& system, const std::vector<int>& eqs) {
  std::vector<std::string> owners;
  std::set<std::string> seen;
  const auto& joint = system.constraint_joint();
  const auto& names = system.constraint_names();
  for (int e : eqs) {
    if (e < 0 || e >= static_cast<int>(joint.size())) continue;
    std::string owner = joint[e] >= 0 ? system.model().joints[joint[e]].name : names[e];
    if (seen.insert(owner).second) owners.push_back(owner);
  }
  return owners;
}

std::string Prefix(const mbs::Model& model) { return model.file.empty() ? "" : model.file + ": "; }

}  // namespace

const char* IntegratorName(mbs::IntegratorKind kind) {
  switch (kind) {
    case mbs::IntegratorKind::kIda: return "ida";
    case mbs::IntegratorKind::kKinematic: return "kinematic";
    case mbs::IntegratorKind::kErk: return "erk";
    case mbs::IntegratorKind::kHht: break;
  }
  return "hht";
}

int DegreesOfFreedom(const dae::MechanicalSystem& kept_system) {
  return kept_system.num_coordinates() - kept_system.num_constraints();
}

void CheckIntegrator(const dae::MechanicalSystem& kept_system, const mbs::SimulationSettings& settings) {
  if (settings.integrator != mbs::IntegratorKind::kKinematic) return;
  const int dof = DegreesOfFreedom(kept_system);
  if (dof == 0) return;
  const mbs::SourceLocation& at = settings.integrator_where;
  std::string where;
  if (!at.file.empty()) {
    where = at.file + ":";
    if (at.line > 0) where += std::to_string(at.line) + ":" + std::to_string(at.column) + ":";
    where += " simulation: ";
  } else {
    where = "--integrator kinematic: ";
  }
  throw InputError(where + "the kinematic analysis needs a model without degrees of freedom (every "
                   "motion driven); this one has " + std::to_string(dof) + " degree" +
                   (dof == 1 ? "" : "s") + " of freedom (" +
                   std::to_string(kept_system.num_coordinates()) + " coordinates, " +
                   std::to_string(kept_system.num_constraints()) +
                   " independent constraint equations): use hht or ida");
}

mbs::SimulationSettings ResolveSettings(const mbs::SimulationSettings& model_settings,
                                        const SettingsOverrides& o) {
  mbs::SimulationSettings s = model_settings;
  if (o.t_end) s.t_end = *o.t_end;
  if (o.output_step) s.output_step = *o.output_step;
  if (o.integrator) {
    s.integrator = *o.integrator;
    s.integrator_named = true;
    s.integrator_where = mbs::SourceLocation();  // chosen on the command line
  }
  if (o.hht_alpha) s.hht_alpha = *o.hht_alpha;
  if (o.hht_step) s.hht_step = *o.hht_step;
  if (o.hht_tolerance) s.hht_tolerance = *o.hht_tolerance;
  if (o.hht_newton_tolerance) s.hht_newton_tolerance = *o.hht_newton_tolerance;
  if (o.hht_adaptive) s.hht_adaptive = *o.hht_adaptive;
  if (o.hht_modified) s.hht_modified = *o.hht_modified;
  if (o.hht_dense_output) s.hht_dense_output = *o.hht_dense_output;
  if (o.ida_dense_output) s.ida_dense_output = *o.ida_dense_output;
  if (o.ida_linear_solver) s.ida_linear_solver = *o.ida_linear_solver;
  if (o.hht_form) s.hht_form = *o.hht_form;
  if (o.hht_start) s.hht_start = *o.hht_start;
  if (o.hht_linear_solver) s.hht_linear_solver = *o.hht_linear_solver;
  if (o.hht_jacobian_cost) s.hht_jacobian_cost = *o.hht_jacobian_cost;
  if (o.hht_predictor) s.hht_predictor = *o.hht_predictor;
  if (o.hht_rotation_jacobian) s.hht_rotation_jacobian = *o.hht_rotation_jacobian;
  if (o.output_accelerations) s.output_accelerations = *o.output_accelerations;
  if (o.ida_rtol) s.ida_rtol = *o.ida_rtol;
  if (o.ida_atol) s.ida_atol = *o.ida_atol;
  if (o.ida_max_steps) s.ida_max_steps = *o.ida_max_steps;
  if (o.ida_min_step) s.ida_min_step = *o.ida_min_step;
  if (o.erk_rtol) s.erk_rtol = *o.erk_rtol;
  if (o.erk_atol) s.erk_atol = *o.erk_atol;
  if (o.erk_max_steps) s.erk_max_steps = *o.erk_max_steps;
  if (o.erk_min_step) s.erk_min_step = *o.erk_min_step;
  if (o.erk_max_step) s.erk_max_step = *o.erk_max_step;
  if (o.output_bodies) s.output_bodies = *o.output_bodies;
  if (o.output_joints) s.output_joints = *o.output_joints;
  if (o.output_forces) s.output_forces = *o.output_forces;
  if (o.output_measures) s.output_measures = *o.output_measures;
  if (!(s.t_end > 0) || !std::isfinite(s.t_end))
    throw InputError("simulation setting t_end must be > 0, got " + Num(s.t_end));
  if (!(s.output_step > 0) || !std::isfinite(s.output_step))
    throw InputError("simulation setting output_step must be > 0, got " + Num(s.output_step));
  if (s.t_end / s.output_step > 1e8)
    throw InputError("simulation settings t_end / output_step give more than 1e8 output rows");
  if (s.output_accelerations != "solved" && s.output_accelerations != "integrator")
    throw InputError("simulation setting output_accelerations must be solved or integrator, got '" +
                     s.output_accelerations + "'");
  if (s.ida_max_steps < 1)
    throw InputError("ida settings: max_steps must be a whole number >= 1, got " + std::to_string(s.ida_max_steps));
  std::string error;
  // Both integrators' settings are checked, the unused one too: a bad value given on
  // the command line is a mistake whichever integrator runs.
  if (!HhtOptionsOf(s).IsValid(&error)) throw InputError("hht settings: " + error);
  if (!IdaOptionsOf(s).IsValid(&error)) throw InputError("ida settings: " + error);
  if (!ErkOptionsOf(s).IsValid(&error)) throw InputError("erk settings: " + error);
  return s;
}

bool AssemblyOptions::IsValid(std::string* error) const {
  auto fail = [error](const std::string& m) {
    if (error) *error = m;
    return false;
  };
  if (!consistency.IsValid(error)) return false;
  if (!(moved_threshold >= 0)) return fail("moved_threshold must be >= 0");
  if (!(singularity_tolerance > 0 && singularity_tolerance < 1))
    return fail("singularity_tolerance must be in (0, 1)");
  return true;
}

std::vector<std::string> Assembly::redundant_names() const {
  std::vector<std::string> out;
  for (int e : redundant) out.push_back(system->constraint_names()[e]);
  return out;
}

std::vector<std::string> Assembly::kept_names() const {
  std::vector<std::string> out;
  for (int e : kept) out.push_back(system->constraint_names()[e]);
  return out;
}

std::string Assembly::Report() const {
  std::ostringstream s;
  s << "assembly: positions moved by at most " << Num(max_position_change)
    << ", velocities by at most " << Num(max_velocity_change);
  if (moved_bodies.empty())
    s << "; no body moved";
  else
    s << "; moved: " << Join(moved_bodies);
  return s.str();
}

std::vector<std::string> UndeterminedBodies(const mbs::Model& model, dae::MechanicalSystem& system,
                                            const dae::State& x, double tolerance,
                                            bool* singular) {
  DeterminacyOptions options;
  options.tolerance = tolerance;
  // The full system may hold dependent equations (which make the matrix singular too);
  // a KeepConstraints view holds the independent ones only.
  options.check_constraint_rank = dynamic_cast<mbs::MultibodySystem*>(&system) != nullptr;
  try {
    DeterminacyResult r = AnalyseDeterminacy(model, system, x, options);
    *singular = r.singular;
    return r.bodies;
  } catch (const std::runtime_error& e) {
    throw InputError(e.what());
  }
}

namespace {

[[noreturn]] void ThrowUndetermined(const mbs::Model& model, const std::vector<std::string>& bodies) {
  throw InputError(Prefix(model) +
                   "the motion of bodies with zero mass or inertia is not determined by their "
                   "joints: " +
                   (bodies.empty() ? std::string("(could not tell which)") : Join(bodies)));
}

}  // namespace

Assembly Assemble(const mbs::Model& model, const AssemblyOptions& options) {
  std::string error;
  if (!options.IsValid(&error)) throw InputError("assembly options: " + error);
  if (model.bodies.empty())
    throw InputError(Prefix(model) + "the model has no bodies: there is nothing to simulate");
  Assembly r;
  if (options.sensitivity.empty()) {
    r.system = std::make_unique<mbs::MultibodySystem>(model);
  } else {
    std::vector<double> values;
    for (const auto& p : model.parameters) values.push_back(p.value);
    try {
      r.system = std::make_unique<mbs::MultibodySystem>(model, options.sensitivity, std::move(values));
    } catch (const std::invalid_argument& e) {
      throw InputError(e.what());
    }
  }
  mbs::MultibodySystem& sys = *r.system;
  const int nq = sys.num_coordinates();
  const int nc = sys.num_constraints();
  dae::State x;
  x.Resize(nq, nc);
  x.t = 0;
  sys.InitialState(x.q, x.v);
  const std::vector<double> q0 = x.q, v0 = x.v;
  r.v_raw = v0;

  // Rank decision: the Euler-parameter normalisations first, so that a redundancy is
  // always resolved by setting aside joint equations, never a normalisation (without
  // it a body's Euler parameters would keep their unit norm only through its joints).
  dae::ConsistencyOptions consistency = options.consistency;
  if (consistency.elimination_order.empty()) {
    for (int e = 0; e < nc; ++e)
      if (sys.constraint_joint()[e] < 0) consistency.elimination_order.push_back(e);
    for (int e = 0; e < nc; ++e)
      if (sys.constraint_joint()[e] >= 0) consistency.elimination_order.push_back(e);
  }
  r.report = dae::MakeConsistent(sys, x, consistency);
  if (!r.report.ok) {
    if (r.report.violated.empty() && options.check_determinacy) {
      // Positions could be satisfied: the failure may be an undetermined acceleration.
      bool singular = false;
      auto bodies = UndeterminedBodies(model, sys, x, options.singularity_tolerance, &singular);
      if (singular) ThrowUndetermined(model, bodies);
    }
    std::string msg = Prefix(model) + "the model cannot be assembled";
    // Name the joints whose equations are violated at the initial state (where the
    // user put the bodies), then those still violated where the projection stopped.
    std::vector<int> violated;
    {
      std::vector<double> c(nc, 0.0);
      dae::EvalInput in;
      in.t = 0;
      in.q = q0.data();
      in.v = v0.data();
      dae::EvalOutput out;
      out.constraint = c.data();
      if (sys.Evaluate(in, out) == 0)
        for (int e = 0; e < nc; ++e)
          if (std::abs(c[e]) > 1e-6 && sys.constraint_joint()[e] >= 0) violated.push_back(e);
    }
    violated.insert(violated.end(), r.report.violated.begin(), r.report.violated.end());
    auto joints = OwnersOf(sys, violated);
    if (!joints.empty()) msg += ": the equations of " + Join(joints) + " cannot be satisfied";
    if (!r.report.message.empty()) msg += " (" + r.report.message + ")";
    throw InputError(msg);
  }
  r.redundant = r.report.redundant;
  std::sort(r.redundant.begin(), r.redundant.end());
  for (int e = 0, k = 0; e < nc; ++e) {
    if (k < static_cast<int>(r.redundant.size()) && r.redundant[k] == e)
      ++k;
    else
      r.kept.push_back(e);
  }
  r.kept_system = dae::KeepConstraints(sys, r.kept);

  r.x0.t = x.t;
  r.x0.q = x.q;
  r.x0.v = x.v;
  r.x0.a.assign(nq, 0.0);
  r.x0.lambda.assign(r.kept.size(), 0.0);
  if (options.check_determinacy) {
    bool singular = false;
    auto bodies =
        UndeterminedBodies(model, *r.kept_system, r.x0, options.singularity_tolerance, &singular);
    if (singular) ThrowUndetermined(model, bodies);
  }
  // The kept equations are independent: the order decides no redundancy here, only the
  // fill of the QR (normalisations first, as above, keeps a chain's factor linear).
  {
    std::vector<int> position(nc, -1);
    for (size_t k = 0; k < r.kept.size(); ++k) position[r.kept[k]] = static_cast<int>(k);
    std::vector<int> order;
    for (int e : consistency.elimination_order)
      if (position[e] >= 0) order.push_back(position[e]);
    consistency.elimination_order = std::move(order);
  }
  dae::ConsistencyReport second = dae::MakeConsistent(*r.kept_system, r.x0, consistency);
  if (!second.ok)
    throw InputError(Prefix(model) + "the model cannot be assembled: " + second.message);

  // What moved, per body.
  for (size_t b = 0; b < model.bodies.size(); ++b) {
    double dq = 0, dv = 0;
    for (int i = 7 * static_cast<int>(b); i < 7 * static_cast<int>(b) + 7 && i < nq; ++i) {
      dq = std::max(dq, std::abs(r.x0.q[i] - q0[i]));
      dv = std::max(dv, std::abs(r.x0.v[i] - v0[i]));
    }
    r.max_position_change = std::max(r.max_position_change, dq);
    r.max_velocity_change = std::max(r.max_velocity_change, dv);
    if (dq > options.moved_threshold || dv > options.moved_threshold)
      r.moved_bodies.push_back(model.bodies[b].name);
  }
  return r;
}

std::vector<double> OutputTimes(double t_end, double output_step) {
  std::vector<double> times{0.0};
  for (long k = 1;; ++k) {
    const double t = k * output_step;
    if (t >= t_end - 1e-9 * output_step) break;
    times.push_back(t);
  }
  times.push_back(t_end);
  return times;
}

double UnwrapAngle(double value, double previous) { return mbs::UnwrapAngle(value, previous); }

void AngularVelocityWorld(const double* e, const double* ed, double* w) {
  // E(e) = [-e1  e0 -e3  e2; -e2  e3  e0 -e1; -e3 -e2  e1  e0], omega = 2 E e'.
  w[0] = 2 * (-e[1] * ed[0] + e[0] * ed[1] - e[3] * ed[2] + e[2] * ed[3]);
  w[1] = 2 * (-e[2] * ed[0] + e[3] * ed[1] + e[0] * ed[2] - e[1] * ed[3]);
  w[2] = 2 * (-e[3] * ed[0] - e[2] * ed[1] + e[1] * ed[2] + e[0] * ed[3]);
}

std::string SimulationSummary::FullReport() const {
  std::ostringstream s;
  s << "integrator:            " << integrator;
  if (!integrator_detail.empty()) s << " (" << integrator_detail << ")";
  s << "\nstatus:                "
    << (status == Status::kDone          ? std::string("done")
        : status == Status::kInterrupted ? std::string("interrupted")
                                         : "failed: " + failure_reason)
    << ", t = "
    << Num(t_reached) << " of " << Num(t_end) << "\n";
  if (integrator == "kinematic") {
    s << "solved times:          " << counters.steps_accepted << "\n";
    s << "Newton iterations:     " << counters.newton_iterations << " (at most "
      << max_newton_iterations << " at one time)\n";
    if (singular_points > 0)
      s << "singular points:       " << singular_points << " (C_q singular: minimum-norm solves)\n";
  } else {
    s << "steps:                 " << counters.steps_accepted << " accepted, "
      << counters.steps_rejected << " rejected\n";
    s << "Newton iterations:     " << counters.newton_iterations << "\n";
  }
  s << "Jacobian evaluations:  " << counters.jacobian_evaluations << "\n";
  s << "factorizations:        " << counters.factorizations << "\n";
  s << "wall time:             " << Num(wall_time) << " s\n";
  s << "solver CPU time:       " << Num(solver_cpu_time) << " s\n";
  s << "max violation:         position " << Num(max_position_violation) << ", velocity "
    << Num(max_velocity_violation) << "\n";
  if (rows_with_integrator_accelerations > 0)
    s << "rows with the integrator's a, lambda (acceleration-level system not solved): "
      << rows_with_integrator_accelerations << "\n";
  s << "redundant constraints: " << redundant_constraints.size();
  if (!redundant_constraints.empty()) s << " (" << Join(redundant_constraints) << ")";
  s << "\n";
  for (const auto& o : objectives)
    s << "objective " << o.name << ":" << std::string(o.name.size() < 12 ? 12 - o.name.size() : 1, ' ')
      << Num(o.value) << " (integral " << Num(o.integral) << ", terminal " << Num(o.terminal) << ")\n";
  if (!objectives_note.empty()) s << "objectives:            " << objectives_note << "\n";
  if (!results_path.empty()) s << "results:               " << results_path << " (" << rows << " rows)\n";
  return s.str();
}

namespace {

// The layout's write_* flags of the settings' chosen elements (none: every element);
// throws InputError for a name the layout's lists lack (an override may name one).
void SetOutputFlags(const mbs::SimulationSettings& settings, io::ResultsLayout* layout) {
  auto flags = [](const std::optional<std::vector<std::string>>& chosen, const std::vector<std::string>& names,
                  const char* option, const char* kind) {
    std::vector<bool> out;
    if (!chosen) return out;
    out.assign(names.size(), false);
    std::map<std::string, size_t> index;
    for (size_t i = 0; i < names.size(); ++i) index.emplace(names[i], i);
    for (const std::string& name : *chosen) {
      const auto it = index.find(name);
      if (it == index.end())
        throw InputError(std::string("output ") + option + ": the model has no " + kind + " named '" + name + "'");
      out[it->second] = true;
    }
    return out;
  };
  layout->write_bodies = flags(settings.output_bodies, layout->bodies, "bodies", "body");
  layout->write_joints = flags(settings.output_joints, layout->joints, "joints", "joint");
  layout->write_forces = flags(settings.output_forces, layout->forces, "forces", "force");
  layout->write_measures = flags(settings.output_measures, layout->measures, "measures", "measure");
}

}  // namespace

std::optional<std::vector<std::string>> ParseElementChoice(const std::string& value) {
  if (value == "all") return std::nullopt;
  std::vector<std::string> names;
  if (value == "none") return names;
  size_t start = 0;
  while (true) {
    const size_t comma = value.find(',', start);
    std::string name = value.substr(start, comma == std::string::npos ? std::string::npos : comma - start);
    if (name.empty()) throw InputError("empty name in '" + value + "'");
    names.push_back(std::move(name));
    if (comma == std::string::npos) return names;
    start = comma + 1;
  }
}

std::optional<double> ParseJacobianCost(const std::string& value) {
  if (value == "auto") return -1.0;
  char* end = nullptr;
  const double c = std::strtod(value.c_str(), &end);
  if (value.empty() || *end != '\0' || !(c >= 0) || !std::isfinite(c)) return std::nullopt;
  return c;
}

void CheckOutputSelection(const mbs::Model& model, const mbs::SimulationSettings& settings) {
  io::ResultsLayout layout;
  for (const auto& b : model.bodies) layout.bodies.push_back(b.name);
  for (const auto& m : model.measures) layout.measures.push_back(m.name);
  for (const auto& j : model.joints) layout.joints.push_back(j.name);
  for (const auto& f : model.forces) layout.forces.push_back(f.name);
  SetOutputFlags(settings, &layout);
}

RunDescription DescribeRun(const mbs::Model& model, const Assembly& asmb,
                           const mbs::SimulationSettings& settings, const std::string& model_path,
                           const std::string& integrator_detail) {
  RunDescription r;
  r.layout.q_names = asmb.system->coordinate_names();
  r.layout.lambda_names = asmb.kept_names();
  for (const auto& b : model.bodies) r.layout.bodies.push_back(b.name);
  for (const auto& m : model.measures) r.layout.measures.push_back(m.name);
  for (const auto& j : model.joints) r.layout.joints.push_back(j.name);
  try {  // /joints/NAME/{position,rate,acceleration,generalized_force} of a tree's joints
    r.layout.joint_coordinates = mbs::JointSpace(model).names();
  } catch (const std::invalid_argument&) {
  }
  for (const auto& f : model.forces) r.layout.forces.push_back(f.name);
  SetOutputFlags(settings, &r.layout);
  // The rows of a complete run (t = 0, then every output_step up to t_end): the chunk size.
  const double intervals = std::ceil(settings.t_end / settings.output_step - 1e-9);
  r.layout.expected_rows =
      intervals >= 0 && intervals < 1e15 ? static_cast<long>(intervals) + 1 : 0;
  r.model = model_path.empty() ? model.file : model_path;
  r.model_name = model.name;
  r.settings = settings;
  r.integrator_detail = integrator_detail;
  r.redundant_constraints = asmb.redundant_names();
  r.assembly_max_position_change = asmb.max_position_change;
  r.assembly_max_velocity_change = asmb.max_velocity_change;
  r.assembly_moved_bodies = asmb.moved_bodies;
  for (const auto& p : model.parameters) r.parameters.emplace_back(p.name, p.value);
  return r;
}

void WriteRunAttributes(io::ResultsFile& file, const RunDescription& run) {
  const mbs::SimulationSettings& settings = run.settings;
  file.SetAttribute("format", 1);
  file.SetAttribute("model", run.model);
  file.SetAttribute("model_name", run.model_name);
  file.SetAttribute("integrator", IntegratorName(settings.integrator));
  file.SetAttribute("integrator_detail", run.integrator_detail);
  file.SetAttribute("t_end", settings.t_end);
  file.SetAttribute("output_step", settings.output_step);
  file.SetAttribute("output_accelerations", settings.output_accelerations);
  // The elements chosen for datasets, where the settings choose (absent: every one).
  for (const auto& [key, chosen] : {std::pair{"output_bodies", &settings.output_bodies},
                                    std::pair{"output_joints", &settings.output_joints},
                                    std::pair{"output_forces", &settings.output_forces},
                                    std::pair{"output_measures", &settings.output_measures}})
    if (*chosen) file.SetAttribute(key, **chosen);
  if (settings.integrator == mbs::IntegratorKind::kHht) {
    file.SetAttribute("hht_alpha", settings.hht_alpha);
    file.SetAttribute("hht_step", settings.hht_step);
    file.SetAttribute("hht_adaptive", settings.hht_adaptive ? 1 : 0);
    file.SetAttribute("hht_tolerance", settings.hht_tolerance);
    file.SetAttribute("hht_modified", settings.hht_modified ? 1 : 0);
    file.SetAttribute("hht_form", settings.hht_form);
    file.SetAttribute("hht_start", settings.hht_start);
    file.SetAttribute("hht_dense_output", settings.hht_dense_output ? 1 : 0);
    file.SetAttribute("hht_newton_tolerance", settings.hht_newton_tolerance);
    file.SetAttribute("hht_linear_solver", settings.hht_linear_solver);
    if (settings.hht_jacobian_cost >= 0) file.SetAttribute("hht_jacobian_cost", settings.hht_jacobian_cost);
    file.SetAttribute("hht_predictor", settings.hht_predictor);
    file.SetAttribute("hht_rotation_jacobian", settings.hht_rotation_jacobian);
  } else if (settings.integrator == mbs::IntegratorKind::kIda) {
    file.SetAttribute("ida_rtol", settings.ida_rtol);
    file.SetAttribute("ida_atol", settings.ida_atol);
    file.SetAttribute("ida_max_steps", settings.ida_max_steps);
    file.SetAttribute("ida_min_step", settings.ida_min_step);
    file.SetAttribute("ida_dense_output", settings.ida_dense_output ? 1 : 0);
    file.SetAttribute("ida_linear_solver", settings.ida_linear_solver);
  } else if (settings.integrator == mbs::IntegratorKind::kErk) {
    file.SetAttribute("erk_rtol", settings.erk_rtol);
    file.SetAttribute("erk_atol", settings.erk_atol);
    file.SetAttribute("erk_max_steps", settings.erk_max_steps);
    file.SetAttribute("erk_min_step", settings.erk_min_step);
    file.SetAttribute("erk_max_step", settings.erk_max_step);
  } else {
    const dae::KinematicOptions kinematic;
    file.SetAttribute("kinematic_tolerance", kinematic.tolerance);
    file.SetAttribute("kinematic_max_iterations", static_cast<long>(kinematic.max_iterations));
  }
  file.SetAttribute("status", "running");
  file.SetAttribute("t_reached", 0.0);
  file.SetAttribute("redundant_constraints", static_cast<long>(run.redundant_constraints.size()));
  file.SetAttribute("redundant_constraint_names", run.redundant_constraints);
  file.SetAttribute("assembly_max_position_change", run.assembly_max_position_change);
  file.SetAttribute("assembly_max_velocity_change", run.assembly_max_velocity_change);
  file.SetAttribute("assembly_moved_bodies", run.assembly_moved_bodies);
  for (const auto& p : run.parameters) file.SetAttribute("parameter." + p.first, p.second);
}

void WriteSummaryAttributes(io::ResultsFile& file, const SimulationSummary& summary) {
  const bool ok = summary.status == SimulationSummary::Status::kDone;
  const bool interrupted = summary.status == SimulationSummary::Status::kInterrupted;
  file.SetAttribute("status", ok ? "done" : interrupted ? "interrupted" : "failed");
  file.SetAttribute("t_reached", summary.t_reached);
  if (!ok && !interrupted) file.SetAttribute("failure_reason", summary.failure_reason);
  file.SetAttribute("steps_accepted", summary.counters.steps_accepted);
  file.SetAttribute("steps_rejected", summary.counters.steps_rejected);
  file.SetAttribute("newton_iterations", summary.counters.newton_iterations);
  file.SetAttribute("jacobian_evaluations", summary.counters.jacobian_evaluations);
  file.SetAttribute("factorizations", summary.counters.factorizations);
  file.SetAttribute("residual_evaluations", summary.counters.residual_evaluations);
  if (!summary.counters.linear_solver.empty()) {
    file.SetAttribute("linear_solver_used", summary.counters.linear_solver);
    file.SetAttribute("klu_fallbacks", summary.counters.klu_fallbacks);
  }
  if (summary.counters.jacobian_cost >= 0)
    file.SetAttribute("jacobian_cost_used", summary.counters.jacobian_cost);
  if (!summary.counters.predictor.empty())
    file.SetAttribute("predictor_used", summary.counters.predictor);
  if (!summary.counters.rotation_jacobian.empty())
    file.SetAttribute("rotation_jacobian_used", summary.counters.rotation_jacobian);
  file.SetAttribute("wall_time", summary.wall_time);
  file.SetAttribute("solver_cpu_time", summary.solver_cpu_time);
  file.SetAttribute("max_position_violation", summary.max_position_violation);
  file.SetAttribute("max_velocity_violation", summary.max_velocity_violation);
  file.SetAttribute("rows_with_integrator_accelerations", summary.rows_with_integrator_accelerations);
  if (summary.integrator == "kinematic") {
    file.SetAttribute("newton_iterations_max", static_cast<long>(summary.max_newton_iterations));
    file.SetAttribute("singular_points", summary.singular_points);
  }
}

std::unique_ptr<dae::Integrator> MakeIntegrator(dae::MechanicalSystem& system,
                                                const mbs::SimulationSettings& settings,
                                                const std::function<void(dae::HhtOptions&)>& adjust_hht,
                                                double dense_stop_time) {
  if (settings.integrator == mbs::IntegratorKind::kHht) {
    dae::HhtOptions o = HhtOptionsOf(settings);
    o.stop_time = dense_stop_time;
    if (adjust_hht) adjust_hht(o);
    std::string error;
    if (!o.IsValid(&error)) throw InputError("hht settings: " + error);
    return dae::MakeHhtIntegrator(system, o);
  }
  if (settings.integrator == mbs::IntegratorKind::kKinematic) {
    CheckIntegrator(system, settings);
    return dae::MakeKinematicSolver(system);
  }
  if (settings.integrator == mbs::IntegratorKind::kErk) {
    const dae::ErkOptions o = ErkOptionsOf(settings);
    std::string error;
    if (!o.IsValid(&error)) throw InputError("erk settings: " + error);
    return dae::MakeErkIntegrator(system, o);
  }
  dae::IdaOptions o = IdaOptionsOf(settings);
  o.stop_time = dense_stop_time;
  return dae::MakeIdaIntegrator(system, o);
}

std::vector<std::string> EffortJointNames(const mbs::Model& model) {
  std::vector<std::string> names;
  for (const mbs::Joint& j : model.joints)
    if (j.type == mbs::JointType::kMotion) names.push_back(j.name);
  return names;
}

OutputRowBuilder::OutputRowBuilder(const mbs::Model& model, Assembly& asmb)
    : OutputRowBuilder(model, asmb, model.simulation) {}

OutputRowBuilder::OutputRowBuilder(const mbs::Model& model, Assembly& asmb,
                                   const mbs::SimulationSettings& settings)
    : model_(model), asmb_(asmb) {
  assert(asmb.system && asmb.kept_system);
  nq_ = asmb.system->num_coordinates();
  nc_full_ = asmb.system->num_constraints();
  nc_ = asmb.kept_system->num_constraints();
  nb_ = static_cast<int>(model.bodies.size());
  nm_ = static_cast<int>(model.measures.size());
  nj_ = static_cast<int>(model.joints.size());
  nf_ = static_cast<int>(model.forces.size());
  lambda_full_.assign(nc_full_, 0.0);
  body_.assign(13 * nb_, 0.0);
  measures_.assign(nm_, 0.0);
  raw_.assign(nm_, 0.0);
  previous_.assign(nm_, 0.0);
  initial_.assign(nm_, 0.0);
  joints_.assign(6 * nj_, 0.0);
  forces_.assign(6 * nf_, 0.0);
  c_.assign(nc_, 0.0);
  cdt_.assign(nc_, 0.0);
  cv_.assign(nc_, 0.0);
  cq_.assign(asmb.kept_system->pattern(dae::Matrix::kConstraintDq).nnz(), 0.0);
  for (int m = 0; m < nm_; ++m) {
    if (!mbs::IsAngleMeasure(model.measures[m])) continue;
    angle_measures_.push_back(m);
    rate_defs_.push_back(mbs::AngleRate(mbs::ResolveMeasure(model, m)));
  }
  previous_rate_.assign(angle_measures_.size(), 0.0);
  for (const mbs::Measure& meas : model.measures)
    if (meas.type == mbs::MeasureType::kReaction) has_reaction_measures_ = true;
  bool driven = false;
  for (const mbs::Joint& j : model.joints)
    if (j.type == mbs::JointType::kMotion || j.type == mbs::JointType::kGear) driven = true;
  if (has_reaction_measures_ || driven)
    reactions_ = std::make_shared<mbs::ReactionMeasures>(model, asmb.system->parameters());
  for (int j = 0; j < nj_; ++j) {
    if (model.joints[j].type != mbs::JointType::kMotion) continue;
    effort_joints_.push_back(j);
    int row = -1;
    for (int e = 0; e < nc_full_; ++e)
      if (asmb.system->constraint_joint()[e] == j) row = e;
    effort_rows_.push_back(row);
  }
  efforts_.assign(effort_joints_.size(), 0.0);
  try {  // joint coordinates in the rows when the joints form a tree (mbs/joint_space.h)
    joint_space_ = std::make_shared<mbs::JointSpace>(model);
    const size_t n = joint_space_->size();
    joint_coordinates_.assign(4 * n, 0.0);
    for (auto* v : {&joint_q_, &joint_qd_, &joint_qdd_, &joint_tau_, &joint_predicted_}) v->assign(n, 0.0);
  } catch (const std::invalid_argument&) {
    joint_space_.reset();
  }
  a_.assign(nq_, 0.0);
  lambda_.assign(nc_, 0.0);
  // The rows' acceleration-level solve: by the block elimination along the body-joint
  // tree when the run's integrator was asked for the tree (hht or ida linear_solver:
  // tree; KLU where the system is no tree or a factorisation's pivots are poor:
  // dae/consistent.h), else by KLU. The same a and lambda to round-off; KLU by default
  // keeps every default result bitwise.
  const bool tree = (settings.integrator == mbs::IntegratorKind::kHht && settings.hht_linear_solver == "tree") ||
                    (settings.integrator == mbs::IntegratorKind::kIda && settings.ida_linear_solver == "tree");
  if (settings.output_accelerations == "solved")
    acceleration_ = std::make_unique<dae::AccelerationSolver>(*asmb.kept_system, 1, tree);
}

void OutputRowBuilder::ContinueAfter(const double* measures) {
  for (int m = 0; m < nm_; ++m)
    previous_[m] = model_.measures[m].offset_initial ? measures[m] + initial_[m] : measures[m];
  first_ = false;
  have_rates_ = false;  // the rates of that row are not known: nearest-turn unwrapping
}

const io::ResultsRow& OutputRowBuilder::Compute(const dae::State& x) {
  mbs::MultibodySystem& sys = *asmb_.system;
  dae::MechanicalSystem& kept = *asmb_.kept_system;
  const double t = x.t;
  // The row's a and lambda: solved from (t, q, v), or the integrator's.
  if (!acceleration_ || acceleration_->Solve(t, x.q.data(), x.v.data(), a_.data(), lambda_.data()) != 0) {
    if (acceleration_) ++fallbacks_;
    std::copy(x.a.begin(), x.a.end(), a_.begin());
    std::copy(x.lambda.begin(), x.lambda.end(), lambda_.begin());
  }
  std::fill(lambda_full_.begin(), lambda_full_.end(), 0.0);
  for (int k = 0; k < nc_; ++k) lambda_full_[asmb_.kept[k]] = lambda_[k];
  for (int b = 0; b < nb_; ++b) {
    const double* q = x.q.data() + 7 * b;
    const double* v = x.v.data() + 7 * b;
    double* out = body_.data() + 13 * b;
    std::copy(q, q + 3, out);
    std::copy(q + 3, q + 7, out + 3);
    std::copy(v, v + 3, out + 7);
    AngularVelocityWorld(q + 3, v + 3, out + 10);
  }
  if (nm_ > 0) sys.EvaluateMeasures(t, x.q.data(), x.v.data(), a_.data(), raw_.data());
  if (has_reaction_measures_) {
    reactions_->parameters() = sys.parameters();
    if (reactions_->Evaluate(t, x.q.data(), lambda_full_.data(), raw_.data()) != 0)
      for (int m : reactions_->measures()) raw_[m] = std::numeric_limits<double>::quiet_NaN();
  }
  // Angles: the turn nearest to the angle predicted from the previous row by the
  // trapezoidal rule on the rate r: phi_1 = phi_0 + dt (r_0 + r_1) / 2. (A cubic Hermite
  // prediction with the rates' derivatives did worse on Andrews' squeezer, whose rates
  // change by 1e3 rad/s within a millisecond.)
  for (size_t k = 0; k < angle_measures_.size(); ++k) {
    const int m = angle_measures_[k];
    const double rate = mbs::EvaluateMeasureValue(rate_defs_[k], x.q.data(), x.v.data(), nullptr);
    if (!first_) {
      raw_[m] = have_rates_ ? mbs::UnwrapAngle(raw_[m], previous_[m], previous_rate_[k], rate, t - previous_t_)
                            : mbs::UnwrapAngle(raw_[m], previous_[m]);
    }
    previous_rate_[k] = rate;
  }
  for (int m = 0; m < nm_; ++m) {
    const auto& meas = model_.measures[m];
    const double value = raw_[m];
    previous_[m] = value;
    if (first_) initial_[m] = value;
    measures_[m] = meas.offset_initial ? value - initial_[m] : value;
  }
  previous_t_ = t;
  have_rates_ = true;
  for (int j = 0; j < nj_; ++j) {
    double* f = joints_.data() + 6 * j;
    const mbs::JointType type = model_.joints[j].type;
    if (type == mbs::JointType::kMotion || type == mbs::JointType::kGear) {
      if (reactions_->JointWrench(j, t, x.q.data(), lambda_full_.data(), f, f + 3) != 0)
        std::fill(f, f + 6, std::numeric_limits<double>::quiet_NaN());
    } else {
      sys.JointReaction(j, t, x.q.data(), lambda_full_.data(), f, f + 3);
    }
  }
  for (size_t k = 0; k < effort_joints_.size(); ++k)
    efforts_[k] = effort_rows_[k] >= 0 ? -lambda_full_[effort_rows_[k]] : 0.0;
  if (joint_space_) {
    // Angles continued from the previous row's (the turn nearest to it moved by its rate).
    const size_t n = joint_q_.size();
    for (size_t k = 0; k < n; ++k) joint_predicted_[k] = joint_q_[k] + (t - joint_previous_t_) * joint_qd_[k];
    try {
      joint_space_->RowValues(sys, t, x.q.data(), x.v.data(), a_.data(), first_ ? nullptr : joint_predicted_.data(),
                              joint_q_.data(), joint_qd_.data(), joint_qdd_.data(), joint_tau_.data());
    } catch (const std::runtime_error&) {
      std::fill(joint_tau_.begin(), joint_tau_.end(), std::numeric_limits<double>::quiet_NaN());
    }
    for (size_t k = 0; k < n; ++k) {
      joint_coordinates_[4 * k] = joint_q_[k];
      joint_coordinates_[4 * k + 1] = joint_qd_[k];
      joint_coordinates_[4 * k + 2] = joint_qdd_[k];
      joint_coordinates_[4 * k + 3] = joint_tau_[k];
    }
    joint_previous_t_ = t;
  }
  for (int f = 0; f < nf_; ++f)
    sys.ForceAction(f, t, x.q.data(), x.v.data(), forces_.data() + 6 * f,
                    forces_.data() + 6 * f + 3);
  double pos_violation = 0, vel_violation = 0;
  if (nc_ > 0) {
    dae::EvalInput in;
    in.t = t;
    in.q = x.q.data();
    in.v = x.v.data();
    in.a = a_.data();
    dae::EvalOutput out;
    out.constraint = c_.data();
    out.constraint_dt = cdt_.data();
    out[dae::Matrix::kConstraintDq] = cq_.data();
    if (kept.Evaluate(in, out) == 0) {
      cv_ = cdt_;
      dae::MultiplyAdd(kept.pattern(dae::Matrix::kConstraintDq), cq_.data(), 1.0, x.v.data(),
                       cv_.data());
      for (int k = 0; k < nc_; ++k) {
        pos_violation = std::max(pos_violation, std::abs(c_[k]));
        vel_violation = std::max(vel_violation, std::abs(cv_[k]));
      }
    } else {
      pos_violation = vel_violation = std::numeric_limits<double>::quiet_NaN();
    }
  }

  row_ = io::ResultsRow();
  row_.t = t;
  row_.q = x.q.data();
  row_.v = x.v.data();
  row_.a = a_.data();
  row_.lambda = lambda_.data();
  row_.body_data = body_.data();
  row_.measures = measures_.data();
  row_.joint_data = joints_.data();
  row_.effort_data = efforts_.data();
  row_.joint_coordinate_data = joint_space_ ? joint_coordinates_.data() : nullptr;
  row_.force_data = forces_.data();
  row_.kinetic_energy = sys.KineticEnergy(x.q.data(), x.v.data());
  row_.potential_energy = sys.PotentialEnergy(t, x.q.data());
  row_.position_violation = pos_violation;
  row_.velocity_violation = vel_violation;
  first_ = false;
  return row_;
}

SimulationSummary Simulate(const mbs::Model& model, Assembly& asmb,
                           const mbs::SimulationSettings& settings,
                           const SimulationOptions& options) {
  assert(asmb.system && asmb.kept_system);
  const auto start = std::chrono::steady_clock::now();
  dae::MechanicalSystem& kept = *asmb.kept_system;

  SimulationSummary summary;
  summary.integrator = IntegratorName(settings.integrator);
  summary.t_end = settings.t_end;
  summary.redundant_constraints = asmb.redundant_names();
  summary.results_path = options.results_path;

  // Dense output: the last step lands on t_end (a C API host may step past it; the
  // program's run ends there).
  std::unique_ptr<dae::Integrator> integrator =
      MakeIntegrator(kept, settings, options.adjust_hht, settings.t_end);
  summary.integrator_detail = integrator->name();
  // The model's objectives: integrands as the integrator's quadrature, terminal values
  // at the end (sensitivities/model_objectives.h).
  std::unique_ptr<sens::ModelObjectives> objectives;
  bool have_quadrature = false;
  if (!model.objectives.empty()) {
    objectives = std::make_unique<sens::ModelObjectives>(model, *asmb.system, asmb.kept);
    dae::Quadrature quad;
    quad.size = objectives->num_objectives();
    sens::ModelObjectives* obj = objectives.get();
    quad.integrand = [obj](double t, const double* q, const double* v, const double* a,
                           const double* lambda, double* g) {
      return obj->Integrand(sens::ObjectivePoint{t, q, v, a, lambda}, g);
    };
    try {
      integrator->SetQuadrature(std::move(quad));
      have_quadrature = true;
    } catch (const std::logic_error& e) {
      summary.objectives_note = std::string("not computed: the integrator has no quadrature (") + e.what() + ")";
    }
  }
  if (options.stop) {
    try {
      integrator->SetStepObserver([&options](const dae::State&, double h) {
        if (h > 0 && options.stop()) throw StopRequest{};
      });
    } catch (const std::logic_error&) {
      // An integrator that does not report its steps stops at the next output time.
    }
  }
  if (options.prepare) options.prepare(*integrator);
  integrator->Initialize(asmb.x0);

  RunDescription run =
      DescribeRun(model, asmb, settings, options.model_path, summary.integrator_detail);
  run.layout.efforts = EffortJointNames(model);
  // Without a results path the rows are computed (violations, progress) but not stored.
  std::unique_ptr<io::ResultsFile> results;
  if (!options.results_path.empty()) {
    results = std::make_unique<io::ResultsFile>(options.results_path, run.layout);
    results->set_flush_interval(options.flush_interval);
    WriteRunAttributes(*results, run);
    io::WriteModelGeometry(*results, model);  // /geometry: what to draw (io/results_geometry.h)
  }

  // The kinematic analysis's and the erk integrator's a and lambda are the solved ones
  // already (the same acceleration-level solve at the same (t, q, v)): the rows take them
  // as they are.
  mbs::SimulationSettings row_settings = settings;
  if (settings.integrator == mbs::IntegratorKind::kKinematic ||
      settings.integrator == mbs::IntegratorKind::kErk)
    row_settings.output_accelerations = "integrator";
  OutputRowBuilder rows(model, asmb, row_settings);
  long rows_computed = 0;
  auto write_row = [&](const dae::State& x) {
    const io::ResultsRow& row = rows.Compute(x);
    if (!std::isnan(row.position_violation))
      summary.max_position_violation = std::max(summary.max_position_violation, row.position_violation);
    if (!std::isnan(row.velocity_violation))
      summary.max_velocity_violation = std::max(summary.max_velocity_violation, row.velocity_violation);
    if (results) results->AppendRow(row);
    ++rows_computed;
    summary.t_reached = x.t;
    if (options.progress) options.progress(x.t, settings.t_end);
  };

  const std::vector<double> times = OutputTimes(settings.t_end, settings.output_step);
  bool ok = true, interrupted = false;
  std::string exception_reason;
  try {
    // The assembled state (the perturbed start of HHT moves its v_0 by O(h^2)).
    write_row(asmb.x0);
    for (size_t k = 1; k < times.size(); ++k) {
      if (options.stop && options.stop()) throw StopRequest{};
      const std::clock_t cpu_start = std::clock();
      const bool advanced = integrator->AdvanceTo(times[k]);
      summary.solver_cpu_time += double(std::clock() - cpu_start) / CLOCKS_PER_SEC;
      if (!advanced) {
        ok = false;
        break;
      }
      dae::State x = integrator->state();
      x.t = times[k];  // exactly the output time (guards against round-off in the integrator)
      write_row(x);
    }
  } catch (const StopRequest&) {
    ok = false;
    interrupted = true;
  } catch (const std::exception& e) {
    // An exception from the integration (e.g. a linear solver error) is a failure of
    // the solver like any other: the rows written so far stay, with the reason.
    ok = false;
    exception_reason = e.what();
  }

  summary.counters = integrator->summary();
  if (const auto* kinematic = dynamic_cast<const dae::KinematicSolver*>(integrator.get())) {
    summary.max_newton_iterations = kinematic->statistics().max_newton_iterations;
    summary.singular_points = kinematic->statistics().singular_points;
  }
  summary.rows_with_integrator_accelerations = rows.fallbacks();
  summary.rows = results ? results->rows() : rows_computed;
  summary.status = ok ? SimulationSummary::Status::kDone : SimulationSummary::Status::kFailed;
  if (interrupted) {
    summary.status = SimulationSummary::Status::kInterrupted;
    summary.t_reached = integrator->state().t;
    summary.failure_reason = "interrupted";
  } else if (!ok) {
    summary.t_reached = integrator->summary().t_reached;
    summary.failure_reason = !exception_reason.empty() ? exception_reason
                             : integrator->summary().message.empty()
                                 ? std::string("the integrator stopped without a reason")
                                 : integrator->summary().message;
  }
  if (objectives && have_quadrature) {
    if (!ok) {
      summary.objectives_note = "not computed: the run did not reach t_end";
    } else {
      dae::State x = integrator->state();
      x.t = settings.t_end;
      std::vector<double> phi(objectives->num_objectives(), 0.0);
      const std::vector<double>& integrals = integrator->quadrature();
      if (objectives->Terminal(sens::ObjectivePoint{x.t, x.q.data(), x.v.data(), x.a.data(), x.lambda.data()},
                               phi.data()) != 0) {
        summary.objectives_note = std::string("terminal values failed: ") + objectives->last_error();
      } else {
        const sens::ModelObjectives::AngleTrack& track = objectives->angle_track();
        summary.objectives_angle_t = track.t;
        summary.objectives_angles = track.angles;
        summary.objectives_angle_rates = track.rates;
        for (int i = 0; i < objectives->num_objectives(); ++i) {
          SimulationSummary::ObjectiveValue o;
          o.name = objectives->names()[i];
          o.integral = i < static_cast<int>(integrals.size()) ? integrals[i] : 0.0;
          o.terminal = phi[i];
          o.value = o.integral + o.terminal;
          summary.objectives.push_back(o);
          if (results)
            results->SetGroupAttributes("objectives/" + o.name,
                                  {{"value", o.value}, {"integral", o.integral}, {"terminal", o.terminal}});
        }
      }
    }
  }
  summary.wall_time =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();

  if (results) {
    WriteSummaryAttributes(*results, summary);
    results->Flush();
  }
  return summary;
}

}  // namespace mbdae::driver
