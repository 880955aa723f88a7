// The C API (api/mbdae.h): handles, errors, names, parameters, splines, options, assembly,
// solving, stored outputs and the results file. The vectors, matrices and measures at the
// current state are in state_matrices.cc; this file has their extern "C" wrappers.
//
// Every extern "C" function runs its body through Call(): an ApiError gives its status, a
// ModelError or InputError MBDAE_ERROR_INPUT, anything else MBDAE_ERROR_INTERNAL; the
// message goes to the thread's last error. Outputs are written only after every check.

// The declarations of the header get default visibility: the library is compiled with
// hidden visibility, and only these functions are exported.
#pragma GCC visibility push(default)
#include "api/mbdae.h"
#pragma GCC visibility pop

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <ctime>
#include <filesystem>
#include <fstream>
#include <initializer_list>
#include <new>
#include <string>
#include <vector>

#include "api/session.h"
#include "apps/cli.h"
#include "dae/format.h"
#include "dae/hht.h"
#include "dae/kinematic.h"
#include "dae/klu_solver.h"
#include "dae/sparse.h"
#include "io/results_file.h"
#include "io/results_geometry.h"
#include "mbs/freedyn.h"
#include "mbs/loader.h"

namespace mbdae::api {
namespace {

thread_local std::string last_error;

mbdae_status Fail(mbdae_status status, const char* message) {
  last_error = message;
  return status;
}

template <typename F>
mbdae_status Call(F&& body) {
  try {
    body();
    last_error.clear();
    return MBDAE_OK;
  } catch (const ApiError& e) {
    return Fail(e.status(), e.what());
  } catch (const mbs::ModelError& e) {
    return Fail(MBDAE_ERROR_INPUT, e.what());
  } catch (const driver::InputError& e) {
    return Fail(MBDAE_ERROR_INPUT, e.what());
  } catch (const std::bad_alloc&) {
    return Fail(MBDAE_ERROR_INTERNAL, "out of memory");
  } catch (const std::exception& e) {
    return Fail(MBDAE_ERROR_INTERNAL, e.what());
  } catch (...) {
    return Fail(MBDAE_ERROR_INTERNAL, "an unknown exception");
  }
}

std::string Num(double x) { return FormatG(x, 17); }

mbdae_model& Handle(mbdae_model* model) {
  if (!model) throw ApiError(MBDAE_ERROR_ARGUMENT, "model is NULL");
  return *model;
}

void NotNull(const void* p, const char* what) {
  if (!p) throw ApiError(MBDAE_ERROR_ARGUMENT, std::string(what) + " is NULL");
}

void CheckSize(int n, int expected, const char* what) {
  if (n != expected)
    throw ApiError(MBDAE_ERROR_SIZE, std::string(what) + ": the array has " + std::to_string(n) +
                                         " values, expected " + std::to_string(expected));
}

const char* KindName(mbdae_kind kind) {
  switch (kind) {
    case MBDAE_COORDINATES: return "coordinate";
    case MBDAE_MULTIPLIERS: return "multiplier";
    case MBDAE_REDUNDANT: return "redundant equation";
    case MBDAE_BODIES: return "body";
    case MBDAE_JOINTS: return "joint";
    case MBDAE_FORCES: return "force";
    case MBDAE_MEASURES: return "measure";
    case MBDAE_PARAMETERS: return "parameter";
    case MBDAE_SPLINES: return "spline";
    case MBDAE_OUTPUTS: return "output row";
    case MBDAE_OBJECTIVES: return "objective";
    case MBDAE_GRADIENT_OBJECTIVES: return "objective of the stored gradient";
    case MBDAE_GRADIENT_WRT: return "wrt entry of the stored gradient";
  }
  return "?";
}

void CheckKind(const mbdae_kind& kind) {
  const int k = EnumInt(kind);
  if (k < 0 || k >= mbdae_model::kNumKinds)
    throw ApiError(MBDAE_ERROR_ARGUMENT, "unknown kind " + std::to_string(k));
}

void CheckIndex(int index, int count, const char* what) {
  if (index < 0 || index >= count)
    throw ApiError(MBDAE_ERROR_ARGUMENT, std::string(what) + " index " + std::to_string(index) +
                                             " is out of range: there are " +
                                             std::to_string(count));
}

}  // namespace

mbdae_status CallApi(const std::function<void()>& body) { return Call(body); }

// ---- Loading -------------------------------------------------------------------------------

// The model from its source with the given parameter overrides and the spline points set
// through the API; the settings resolved with the API's options. Throws (ModelError,
// InputError, ApiError) without touching m.
void Load(const mbdae_model& m, const std::map<std::string, double>& overrides,
          std::unique_ptr<mbs::Model>* model, mbs::SimulationSettings* settings) {
  mbs::LoadOptions options;
  options.parameter_overrides = overrides;
  auto loaded = std::make_unique<mbs::Model>(
      m.path.empty() ? mbs::LoadModelFromString(m.text, m.name, options)
                     : mbs::LoadAnyModel(m.path, options));
  for (const auto& [name, points] : m.spline_points) {
    const int k = loaded->find_spline(name);
    if (k < 0)
      throw ApiError(MBDAE_ERROR_INTERNAL, "spline '" + name + "' is gone after the rebuild");
    try {
      loaded->splines[k].spline.SetPoints(points.first, points.second);
    } catch (const std::invalid_argument& e) {
      throw ApiError(MBDAE_ERROR_INPUT, "spline '" + name + "': " + e.what());
    }
  }
  *settings = driver::ResolveSettings(loaded->simulation, m.option_overrides);
  *model = std::move(loaded);
}

namespace {

// Drops the assembly and what depends on it; the stored rows stay until the next one.
void MarkForAssembly(mbdae_model& m) {
  m.row_builder.reset();
  m.integrator.reset();
  m.assembly.reset();
  m.state = dae::State();
  m.names_valid[MBDAE_MULTIPLIERS] = false;
  m.names_valid[MBDAE_REDUNDANT] = false;
}

// ---- Rows ----------------------------------------------------------------------------------

// The rotation matrix body -> world, row-major, of Euler parameters (normalised first).
void RotationOf(const double* e_in, double* r) {
  const double n = std::sqrt(e_in[0] * e_in[0] + e_in[1] * e_in[1] + e_in[2] * e_in[2] +
                             e_in[3] * e_in[3]);
  const double e0 = e_in[0] / n, e1 = e_in[1] / n, e2 = e_in[2] / n, e3 = e_in[3] / n;
  r[0] = 2 * (e0 * e0 + e1 * e1) - 1;
  r[1] = 2 * (e1 * e2 - e0 * e3);
  r[2] = 2 * (e1 * e3 + e0 * e2);
  r[3] = 2 * (e1 * e2 + e0 * e3);
  r[4] = 2 * (e0 * e0 + e2 * e2) - 1;
  r[5] = 2 * (e2 * e3 - e0 * e1);
  r[6] = 2 * (e1 * e3 - e0 * e2);
  r[7] = 2 * (e2 * e3 + e0 * e1);
  r[8] = 2 * (e0 * e0 + e3 * e3) - 1;
}

// Stores the row of state x (x.t the output time).
void StoreRow(mbdae_model& m, const dae::State& x) {
  const io::ResultsRow& r = m.row_builder->Compute(x);
  const int nb = m.row_builder->num_bodies();
  OutputRow row;
  row.t = x.t;
  row.q = x.q;
  row.v = x.v;
  // a and lambda as the results file has them (the row builder's: solved from (t, q, v)
  // or the integrator's, by the setting output_accelerations).
  row.a.assign(r.a, r.a + x.a.size());
  row.lambda.assign(r.lambda, r.lambda + x.lambda.size());
  row.measures.assign(r.measures, r.measures + m.row_builder->num_measures());
  row.body_data.assign(r.body_data, r.body_data + 13 * nb);
  row.joint_data.assign(r.joint_data, r.joint_data + 6 * m.row_builder->num_joints());
  if (r.joint_coordinate_data)
    row.joint_coordinate_data.assign(r.joint_coordinate_data,
                                     r.joint_coordinate_data + m.row_builder->num_joint_coordinate_values());
  row.force_data.assign(r.force_data, r.force_data + 6 * m.row_builder->num_forces());
  row.body_poses.resize(12 * nb);
  for (int b = 0; b < nb; ++b) {
    std::copy(x.q.data() + 7 * b, x.q.data() + 7 * b + 3, row.body_poses.data() + 12 * b);
    RotationOf(x.q.data() + 7 * b + 3, row.body_poses.data() + 12 * b + 3);
  }
  row.kinetic_energy = r.kinetic_energy;
  row.potential_energy = r.potential_energy;
  row.position_violation = r.position_violation;
  row.velocity_violation = r.velocity_violation;
  m.rows.push_back(std::move(row));
}

// Output time k: driver::OutputTimes up to t_end, then every output_step after t_end (a
// host may step past t_end).
double OutputTime(const mbdae_model& m, int k) {
  const int n = static_cast<int>(m.output_times.size());
  if (k < n) return m.output_times[k];
  return m.settings.t_end + (k - n + 1) * m.settings.output_step;
}

// Whether t is output time k (up to the merging tolerance of driver::OutputTimes).
bool IsOutputTime(const mbdae_model& m, int k, double t) {
  return std::abs(t - OutputTime(m, k)) <= 1e-9 * m.settings.output_step;
}

void Assemble(mbdae_model& m) {
  MarkForAssembly(m);
  auto assembly = std::make_unique<driver::Assembly>();
  try {
    *assembly = driver::Assemble(*m.model);
  } catch (const driver::InputError& e) {
    throw ApiError(MBDAE_ERROR_SOLVER, e.what());
  }
  auto integrator = driver::MakeIntegrator(*assembly->kept_system, m.settings);
  try {
    integrator->Initialize(assembly->x0);
  } catch (const std::exception& e) {
    throw ApiError(MBDAE_ERROR_SOLVER, std::string("the integrator cannot start: ") + e.what());
  }
  m.run = driver::DescribeRun(*m.model, *assembly, m.settings, m.model->file, integrator->name());
  m.output_times = driver::OutputTimes(m.settings.t_end, m.settings.output_step);
  m.rows.clear();
  m.finished_counters = dae::Summary();
  m.solver_cpu_time = 0;
  m.wall_time = 0;
  m.failed = false;
  m.failure_reason.clear();
  m.t_failed = 0;
  m.state = assembly->x0;
  m.assembly = std::move(assembly);
  m.integrator = std::move(integrator);
  m.row_builder = std::make_unique<driver::OutputRowBuilder>(*m.model, *m.assembly, m.settings);
  StoreRow(m, m.state);
  m.next_output = 1;
}

// to += the step and Newton counters of `from`.
void AddCounters(const dae::Summary& from, dae::Summary* to) {
  to->steps_accepted += from.steps_accepted;
  to->steps_rejected += from.steps_rejected;
  to->newton_iterations += from.newton_iterations;
  to->jacobian_evaluations += from.jacobian_evaluations;
  to->factorizations += from.factorizations;
  to->residual_evaluations += from.residual_evaluations;
  to->newton_noise_stops += from.newton_noise_stops;
  to->klu_fallbacks += from.klu_fallbacks;
  if (!from.linear_solver.empty()) to->linear_solver = from.linear_solver;
  if (from.jacobian_cost >= 0) to->jacobian_cost = from.jacobian_cost;
  if (!from.predictor.empty()) to->predictor = from.predictor;
  if (!from.rotation_jacobian.empty()) to->rotation_jacobian = from.rotation_jacobian;
}

// Adds the counters of the current integrator to finished_counters and drops it.
void FinishIntegrator(mbdae_model& m) {
  if (!m.integrator) return;
  AddCounters(m.integrator->summary(), &m.finished_counters);
  m.integrator.reset();
}

dae::Summary Counters(const mbdae_model& m) {
  dae::Summary c = m.finished_counters;
  if (m.integrator) AddCounters(m.integrator->summary(), &c);
  return c;
}

// A new integrator started at `x` (throws ApiError SOLVER); m is not changed.
std::unique_ptr<dae::Integrator> StartIntegrator(mbdae_model& m, const dae::State& x) {
  auto integrator = driver::MakeIntegrator(*m.assembly->kept_system, m.settings);
  try {
    integrator->Initialize(x);
  } catch (const std::exception& e) {
    throw ApiError(MBDAE_ERROR_SOLVER, "the integrator cannot start at t = " + Num(x.t) + ": " +
                                           e.what());
  }
  return integrator;
}

// Integrates to t, storing the rows of the output times passed (see mbdae_solve_to).
void SolveTo(mbdae_model& m, double t) {
  EnsureAssembled(m);
  if (!m.integrator) {
    m.integrator = StartIntegrator(m, m.state);
    m.failed = false;
  }
  const auto start = std::chrono::steady_clock::now();
  auto advance = [&m](double target) {
    bool ok = false;
    std::string reason;
    const std::clock_t cpu_start = std::clock();
    try {
      ok = m.integrator->AdvanceTo(target);
    } catch (const std::exception& e) {
      reason = e.what();
    }
    m.solver_cpu_time += double(std::clock() - cpu_start) / CLOCKS_PER_SEC;
    if (ok) return;
    // The rows so far stay; the next call restarts from the last state reached.
    if (reason.empty())
      reason = m.integrator->summary().message.empty()
                   ? std::string("the integrator stopped without a reason")
                   : m.integrator->summary().message;
    m.state = m.integrator->state();
    m.failed = true;
    m.failure_reason = reason;
    m.t_failed = m.integrator->summary().t_reached;
    FinishIntegrator(m);
    throw ApiError(MBDAE_ERROR_SOLVER, "the integrator failed at t = " + Num(m.t_failed) +
                                           " on the way to " + Num(target) + ": " + reason);
  };
  struct WallClock {  // adds the wall time of the call, also when it throws
    mbdae_model& m;
    std::chrono::steady_clock::time_point start;
    ~WallClock() {
      m.wall_time += std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    }
  } wall{m, start};
  while (OutputTime(m, m.next_output) <= t || IsOutputTime(m, m.next_output, t)) {
    const double target = OutputTime(m, m.next_output);
    advance(target);
    m.state = m.integrator->state();
    m.state.t = target;  // exactly the output time, as the program writes it
    StoreRow(m, m.state);
    ++m.next_output;
  }
  if (m.state.t < t && !(m.next_output > 0 && IsOutputTime(m, m.next_output - 1, t))) {
    advance(t);
    m.state = m.integrator->state();
  }
}

// a and lambda at (t, q, v) of the kept system: [M C_q^T; C_q 0] [a; lambda] = [Q; gamma].
void SolveAccelerations(mbdae_model& m, dae::State* x) {
  dae::MechanicalSystem& sys = *m.assembly->kept_system;
  const int nq = sys.num_coordinates();
  const int nc = sys.num_constraints();
  const dae::CscPattern& pm = sys.pattern(dae::Matrix::kMass);
  const dae::CscPattern& pc = sys.pattern(dae::Matrix::kConstraintDq);
  dae::BlockAssembler kkt;
  const int b_m = kkt.AddBlock(pm, 0, 0);
  const int b_ct = kkt.AddBlock(pc, 0, nq, /*transpose=*/true);
  const int b_c = kkt.AddBlock(pc, nq, 0);
  kkt.Finalize(nq + nc, nq + nc);
  std::vector<double> mass(pm.nnz()), cq(pc.nnz()), values(kkt.pattern().nnz(), 0.0);
  std::vector<double> sol(nq + nc, 0.0), gamma(nc, 0.0);
  dae::EvalInput in;
  in.t = x->t;
  in.q = x->q.data();
  in.v = x->v.data();
  dae::EvalOutput out;
  out.force = sol.data();
  out.acc_rhs = gamma.data();
  out[dae::Matrix::kMass] = mass.data();
  out[dae::Matrix::kConstraintDq] = cq.data();
  if (sys.Evaluate(in, out) != 0)
    throw ApiError(MBDAE_ERROR_SOLVER, "the equations of motion cannot be evaluated at t = " +
                                           Num(x->t) + ": " + sys.last_error());
  std::copy(gamma.begin(), gamma.end(), sol.begin() + nq);
  kkt.Accumulate(b_m, mass.data(), 1.0, values.data());
  kkt.Accumulate(b_ct, cq.data(), 1.0, values.data());
  kkt.Accumulate(b_c, cq.data(), 1.0, values.data());
  dae::KluSolver klu(kkt.pattern());
  std::string error;
  if (!klu.Factor(values.data(), &error))
    throw ApiError(MBDAE_ERROR_SOLVER,
                   "the acceleration-level system [M C_q^T; C_q 0] is singular at t = " +
                       Num(x->t) + ": " + error);
  klu.Solve(sol.data());
  x->a.assign(sol.begin(), sol.begin() + nq);
  x->lambda.assign(sol.begin() + nq, sol.end());
}

// ---- Names and options ------------------------------------------------------------------

const std::vector<std::string>& Names(mbdae_model& m, mbdae_kind kind) {
  CheckKind(kind);
  if (kind == MBDAE_OUTPUTS)
    throw ApiError(MBDAE_ERROR_ARGUMENT, "output rows have no names");
  if (kind == MBDAE_MULTIPLIERS || kind == MBDAE_REDUNDANT) EnsureAssembled(m);
  std::vector<std::string>& names = m.names_cache[kind];
  if (m.names_valid[kind]) return names;
  const mbs::Model& model = *m.model;
  std::vector<std::string> list;
  switch (kind) {
    case MBDAE_COORDINATES: {
      static const char* kCoordinate[7] = {"x", "y", "z", "e0", "e1", "e2", "e3"};
      for (const auto& b : model.bodies)
        for (const char* c : kCoordinate) list.push_back(b.name + "." + c);
      break;
    }
    case MBDAE_MULTIPLIERS: list = m.assembly->kept_names(); break;
    case MBDAE_REDUNDANT: list = m.assembly->redundant_names(); break;
    case MBDAE_BODIES: for (const auto& x : model.bodies) list.push_back(x.name); break;
    case MBDAE_JOINTS: for (const auto& x : model.joints) list.push_back(x.name); break;
    case MBDAE_FORCES: for (const auto& x : model.forces) list.push_back(x.name); break;
    case MBDAE_MEASURES: for (const auto& x : model.measures) list.push_back(x.name); break;
    case MBDAE_PARAMETERS: for (const auto& x : model.parameters) list.push_back(x.name); break;
    case MBDAE_SPLINES: for (const auto& x : model.splines) list.push_back(x.name); break;
    case MBDAE_OUTPUTS: break;
    case MBDAE_OBJECTIVES: for (const auto& x : model.objectives) list.push_back(x.name); break;
    case MBDAE_GRADIENT_OBJECTIVES: if (m.gradient) list = m.gradient->objectives; break;
    case MBDAE_GRADIENT_WRT: if (m.gradient) list = m.gradient->wrt; break;
  }
  names = std::move(list);
  m.names_valid[kind] = true;
  return names;
}

int Count(mbdae_model& m, mbdae_kind kind) {
  CheckKind(kind);
  switch (kind) {
    case MBDAE_COORDINATES: return m.model->num_coordinates();
    case MBDAE_MULTIPLIERS:
      EnsureAssembled(m);
      return static_cast<int>(m.assembly->kept.size());
    case MBDAE_REDUNDANT:
      EnsureAssembled(m);
      return static_cast<int>(m.assembly->redundant.size());
    case MBDAE_BODIES: return static_cast<int>(m.model->bodies.size());
    case MBDAE_JOINTS: return static_cast<int>(m.model->joints.size());
    case MBDAE_FORCES: return static_cast<int>(m.model->forces.size());
    case MBDAE_MEASURES: return static_cast<int>(m.model->measures.size());
    case MBDAE_PARAMETERS: return static_cast<int>(m.model->parameters.size());
    case MBDAE_SPLINES: return static_cast<int>(m.model->splines.size());
    case MBDAE_OUTPUTS: return static_cast<int>(m.rows.size());
    case MBDAE_OBJECTIVES: return static_cast<int>(m.model->objectives.size());
    case MBDAE_GRADIENT_OBJECTIVES:
      return m.gradient ? static_cast<int>(m.gradient->objectives.size()) : 0;
    case MBDAE_GRADIENT_WRT: return m.gradient ? static_cast<int>(m.gradient->wrt.size()) : 0;
  }
  return 0;
}

const char* const kOptionKeys =
    "t_end, output_step, integrator, hht.alpha, hht.step, hht.adaptive, hht.tolerance, "
    "hht.modified, hht.form, hht.dense_output, hht.newton_tolerance, hht.linear_solver, hht.jacobian_cost, hht.predictor, hht.rotation_jacobian, ida.rtol, ida.atol, ida.max_steps, ida.min_step, ida.dense_output, ida.linear_solver, "
    "erk.rtol, erk.atol, erk.max_steps, erk.min_step, erk.max_step, output.bodies, output.joints, output.forces, "
    "output.measures, gradient.fd_step, gradient.newton_factor, "
    "gradient.trajectory_memory, gradient.ida_checkpoint_steps";

}  // namespace

double ParseOptionNumber(const std::string& key, const char* value) {
  char* end = nullptr;
  const double x = std::strtod(value, &end);
  if (*value == '\0' || *end != '\0' || !std::isfinite(x))
    throw ApiError(MBDAE_ERROR_INPUT,
                   "option " + key + ": expected a number, got '" + std::string(value) + "'");
  return x;
}

namespace {

// value if it is one of choices, else an ApiError "option KEY: expected A, B or C, got 'V'".
std::string ParseOptionChoice(const std::string& key, const char* value,
                              const std::vector<std::string>& choices) {
  const std::string v = value;
  if (std::find(choices.begin(), choices.end(), v) != choices.end()) return v;
  throw ApiError(MBDAE_ERROR_INPUT,
                 "option " + key + ": expected " + JoinOr(choices) + ", got '" + v + "'");
}

bool ParseOptionBool(const std::string& key, const char* value) {
  return ParseOptionChoice(key, value, {"true", "false"}) == "true";
}

[[noreturn]] void UnknownOption(const std::string& key) {
  throw ApiError(MBDAE_ERROR_ARGUMENT,
                 "unknown option '" + key + "'; the options are " + kOptionKeys);
}

void SetOption(mbdae_model& m, const std::string& key, const char* value) {
  if (SetGradientOption(m, key, value)) return;  // not a simulation setting: no re-assembly
  driver::SettingsOverrides o = m.option_overrides;
  if (key == "t_end") {
    o.t_end = ParseOptionNumber(key, value);
  } else if (key == "output_step") {
    o.output_step = ParseOptionNumber(key, value);
  } else if (key == "integrator") {
    const std::string v = ParseOptionChoice(key, value, {"hht", "ida", "kinematic", "erk"});
    o.integrator = v == "hht"   ? mbs::IntegratorKind::kHht
                   : v == "ida" ? mbs::IntegratorKind::kIda
                   : v == "erk" ? mbs::IntegratorKind::kErk
                                : mbs::IntegratorKind::kKinematic;
  } else if (key == "hht.alpha") {
    o.hht_alpha = ParseOptionNumber(key, value);
  } else if (key == "hht.step") {
    o.hht_step = ParseOptionNumber(key, value);
  } else if (key == "hht.adaptive") {
    o.hht_adaptive = ParseOptionBool(key, value);
  } else if (key == "hht.tolerance") {
    o.hht_tolerance = ParseOptionNumber(key, value);
  } else if (key == "hht.newton_tolerance") {
    o.hht_newton_tolerance = ParseOptionNumber(key, value);
  } else if (key == "hht.jacobian_cost") {
    o.hht_jacobian_cost = driver::ParseJacobianCost(value);
    if (!o.hht_jacobian_cost)
      throw ApiError(MBDAE_ERROR_INPUT, "option hht.jacobian_cost: expected auto or a number >= 0, got '" +
                                            std::string(value) + "'");
  } else if (key == "hht.modified") {
    o.hht_modified = ParseOptionBool(key, value);
  } else if (key == "hht.dense_output") {
    o.hht_dense_output = ParseOptionBool(key, value);
  } else if (key == "ida.dense_output") {
    o.ida_dense_output = ParseOptionBool(key, value);
  } else if (key == "hht.form") {
    o.hht_form = ParseOptionChoice(key, value, dae::HhtFormNames());
  } else if (key == "hht.predictor") {
    o.hht_predictor = ParseOptionChoice(key, value, dae::HhtPredictorNames());
  } else if (key == "hht.rotation_jacobian") {
    o.hht_rotation_jacobian = ParseOptionChoice(key, value, dae::HhtRotationJacobianNames());
  } else if (key == "hht.linear_solver" || key == "ida.linear_solver") {
    (key == "hht.linear_solver" ? o.hht_linear_solver : o.ida_linear_solver) =
        ParseOptionChoice(key, value, dae::HhtLinearSolverNames());
  } else if (key == "ida.rtol") {
    o.ida_rtol = ParseOptionNumber(key, value);
  } else if (key == "ida.atol") {
    o.ida_atol = ParseOptionNumber(key, value);
  } else if (key == "ida.max_steps") {
    const double x = ParseOptionNumber(key, value);
    if (!(x >= 1 && x == std::floor(x) && x <= 9e18))
      throw ApiError(MBDAE_ERROR_INPUT, "option ida.max_steps: expected a whole number >= 1, got '" +
                                            std::string(value) + "'");
    o.ida_max_steps = static_cast<long>(x);
  } else if (key == "ida.min_step") {
    o.ida_min_step = ParseOptionNumber(key, value);
  } else if (key == "erk.rtol") {
    o.erk_rtol = ParseOptionNumber(key, value);
  } else if (key == "erk.atol") {
    o.erk_atol = ParseOptionNumber(key, value);
  } else if (key == "erk.max_steps") {
    const double x = ParseOptionNumber(key, value);
    if (!(x >= 1 && x == std::floor(x) && x <= 9e18))
      throw ApiError(MBDAE_ERROR_INPUT, "option erk.max_steps: expected a whole number >= 1, got '" +
                                            std::string(value) + "'");
    o.erk_max_steps = static_cast<long>(x);
  } else if (key == "erk.min_step") {
    o.erk_min_step = ParseOptionNumber(key, value);
  } else if (key == "erk.max_step") {
    o.erk_max_step = ParseOptionNumber(key, value);
  } else if (key == "output.bodies" || key == "output.joints" || key == "output.forces" ||
             key == "output.measures") {
    // all, none or comma-separated names (the elements with datasets in the results file).
    std::optional<std::vector<std::string>> chosen;
    try {
      chosen = driver::ParseElementChoice(value);
    } catch (const driver::InputError&) {
      throw ApiError(MBDAE_ERROR_INPUT, "option " + key + ": expected all, none or comma-separated names, got '" +
                                            std::string(value) + "'");
    }
    (key == "output.bodies"   ? o.output_bodies
     : key == "output.joints" ? o.output_joints
     : key == "output.forces" ? o.output_forces
                              : o.output_measures) = chosen;
  } else {
    UnknownOption(key);
  }
  mbs::SimulationSettings settings;
  try {
    settings = driver::ResolveSettings(m.model->simulation, o);
    driver::CheckOutputSelection(*m.model, settings);
  } catch (const driver::InputError& e) {
    throw ApiError(MBDAE_ERROR_INPUT, std::string("option ") + key + " = " + value + ": " + e.what());
  }
  m.option_overrides = o;
  m.settings = settings;
  MarkForAssembly(m);
}

std::string GetOption(const mbdae_model& m, const std::string& key) {
  const mbs::SimulationSettings& s = m.settings;
  auto boolean = [](bool b) { return std::string(b ? "true" : "false"); };
  if (key == "t_end") return Num(s.t_end);
  if (key == "output_step") return Num(s.output_step);
  if (key == "integrator") return driver::IntegratorName(s.integrator);
  if (key == "hht.alpha") return Num(s.hht_alpha);
  if (key == "hht.step") return Num(s.hht_step);
  if (key == "hht.adaptive") return boolean(s.hht_adaptive);
  if (key == "hht.tolerance") return Num(s.hht_tolerance);
  if (key == "hht.newton_tolerance") return Num(s.hht_newton_tolerance);
  if (key == "hht.jacobian_cost") return s.hht_jacobian_cost < 0 ? "auto" : Num(s.hht_jacobian_cost);
  if (key == "hht.modified") return boolean(s.hht_modified);
  if (key == "hht.dense_output") return boolean(s.hht_dense_output);
  if (key == "ida.dense_output") return boolean(s.ida_dense_output);
  if (key == "hht.form") return s.hht_form;
  if (key == "hht.linear_solver") return s.hht_linear_solver;
  if (key == "hht.predictor") return s.hht_predictor;
  if (key == "hht.rotation_jacobian") return s.hht_rotation_jacobian;
  if (key == "ida.linear_solver") return s.ida_linear_solver;
  if (key == "ida.rtol") return Num(s.ida_rtol);
  if (key == "ida.atol") return Num(s.ida_atol);
  if (key == "ida.max_steps") return std::to_string(s.ida_max_steps);
  if (key == "ida.min_step") return Num(s.ida_min_step);
  if (key == "erk.rtol") return Num(s.erk_rtol);
  if (key == "erk.atol") return Num(s.erk_atol);
  if (key == "erk.max_steps") return std::to_string(s.erk_max_steps);
  if (key == "erk.min_step") return Num(s.erk_min_step);
  if (key == "erk.max_step") return Num(s.erk_max_step);
  for (const auto& [name, chosen] : {std::pair{"output.bodies", &s.output_bodies},
                                     std::pair{"output.joints", &s.output_joints},
                                     std::pair{"output.forces", &s.output_forces},
                                     std::pair{"output.measures", &s.output_measures}}) {
    if (key != name) continue;
    if (!*chosen) return "all";
    if ((*chosen)->empty()) return "none";
    std::string joined;
    for (const std::string& n : **chosen) joined += (joined.empty() ? "" : ",") + n;
    return joined;
  }
  std::string gradient_value;
  if (GetGradientOption(m, key, &gradient_value)) return gradient_value;
  UnknownOption(key);
}

// ---- Results file -------------------------------------------------------------------------

void WriteResults(const mbdae_model& m, const std::string& path) {
  if (m.rows.empty())
    throw ApiError(MBDAE_ERROR_ORDER,
                   "there are no stored rows to write: call mbdae_assemble or mbdae_solve first");
  driver::SimulationSummary summary;
  summary.integrator = driver::IntegratorName(m.run.settings.integrator);
  summary.integrator_detail = m.run.integrator_detail;
  summary.t_end = m.run.settings.t_end;
  summary.counters = Counters(m);
  if (const auto* kinematic = dynamic_cast<const dae::KinematicSolver*>(m.integrator.get())) {
    summary.max_newton_iterations = kinematic->statistics().max_newton_iterations;
    summary.singular_points = kinematic->statistics().singular_points;
  }
  summary.wall_time = m.wall_time;
  summary.solver_cpu_time = m.solver_cpu_time;
  summary.rows = static_cast<long>(m.rows.size());
  for (const OutputRow& r : m.rows) {
    if (!std::isnan(r.position_violation))
      summary.max_position_violation = std::max(summary.max_position_violation, r.position_violation);
    if (!std::isnan(r.velocity_violation))
      summary.max_velocity_violation = std::max(summary.max_velocity_violation, r.velocity_violation);
  }
  const bool done = !m.failed && m.rows.back().t >= m.run.settings.t_end;
  summary.status = m.failed ? driver::SimulationSummary::Status::kFailed
                            : driver::SimulationSummary::Status::kDone;
  summary.t_reached = m.failed ? m.t_failed : m.rows.back().t;
  summary.failure_reason = m.failure_reason;

  // Written beside the path and renamed over it at the end (an earlier file stays whole
  // until then; the model file itself is refused).
  ResultsTarget target(path, {{"model file", m.path}});
  std::unique_ptr<io::ResultsFile> file;
  try {
    io::ResultsLayout layout = m.run.layout;
    layout.expected_rows = static_cast<long>(m.rows.size());  // the rows stored: all of them
    file = std::make_unique<io::ResultsFile>(target.CreateTemporary(), layout);
    file->set_flush_interval(1e30);  // one flush at the end
    driver::WriteRunAttributes(*file, m.run);
    io::WriteModelGeometry(*file, *m.model);  // /geometry, as the program writes it
    for (const OutputRow& r : m.rows) {
      io::ResultsRow row;
      row.t = r.t;
      row.q = r.q.data();
      row.v = r.v.data();
      row.a = r.a.data();
      row.lambda = r.lambda.data();
      row.body_data = r.body_data.data();
      row.measures = r.measures.data();
      row.joint_data = r.joint_data.data();
      row.joint_coordinate_data = r.joint_coordinate_data.empty() ? nullptr : r.joint_coordinate_data.data();
      row.force_data = r.force_data.data();
      row.kinetic_energy = r.kinetic_energy;
      row.potential_energy = r.potential_energy;
      row.position_violation = r.position_violation;
      row.velocity_violation = r.velocity_violation;
      file->AppendRow(row);
    }
    driver::WriteSummaryAttributes(*file, summary);
    // A run a host is still stepping (neither done nor failed) is "running", as the
    // program's file is while it runs.
    if (!done && !m.failed) file->SetAttribute("status", "running");
    file->Flush();
    file.reset();  // closed before it is renamed
  } catch (const ApiError&) {
    throw;
  } catch (const std::runtime_error& e) {
    throw ApiError(MBDAE_ERROR_IO, "results file " + path + ": " + e.what());
  }
  target.Commit();
}

}  // namespace

ResultsTarget::ResultsTarget(const std::string& path,
                             const std::vector<std::pair<std::string, std::string>>& inputs)
    : path_(path) {
  if (path.empty()) throw ApiError(MBDAE_ERROR_IO, "the results file's path is empty");
  for (const auto& [what, file] : inputs)
    if (!file.empty() && (path == file || app::SameFile(path, file)))
      throw ApiError(MBDAE_ERROR_IO, "the results file '" + path + "' is the " + what + " '" + file +
                                         "' itself: give the results another name");
  try {
    destination_ = std::make_unique<app::ResultsDestination>(path, "");
  } catch (const app::UsageError& e) {
    throw ApiError(MBDAE_ERROR_IO, e.what());  // "cannot write the results file 'PATH': why"
  }
}

ResultsTarget::~ResultsTarget() = default;  // the destination removes an uncommitted file

const std::string& ResultsTarget::CreateTemporary() {
  try {
    return destination_->CreateTemporary();
  } catch (const app::UsageError& e) {
    throw ApiError(MBDAE_ERROR_IO, e.what());
  }
}

void ResultsTarget::Commit() {
  try {
    destination_->Commit();
  } catch (const std::runtime_error& e) {
    throw ApiError(MBDAE_ERROR_IO, e.what());
  }
}

void EnsureAssembled(mbdae_model& m) {
  if (!m.assembly) Assemble(m);
}

}  // namespace mbdae::api

using mbdae::api::ApiError;
using mbdae::api::Call;
using mbdae::api::CheckEnum;
using mbdae::api::CheckIndex;
using mbdae::api::CheckSize;
using mbdae::api::Handle;
using mbdae::api::NotNull;

extern "C" {

const char* mbdae_last_error(void) { return mbdae::api::last_error.c_str(); }
const char* mbdae_version(void) { return MBDAE_VERSION; }
int mbdae_api_version(void) { return MBDAE_API_VERSION; }

// ---- Creating and freeing ------------------------------------------------------------------

mbdae_status mbdae_model_from_file(const char* path, mbdae_model** model) {
  return Call([&] {
    NotNull(path, "path");
    NotNull(model, "model");
    {
      std::error_code ignored;
      if (std::filesystem::is_directory(path, ignored))
        throw ApiError(MBDAE_ERROR_IO, std::string(path) + ": cannot read the file: it is a directory");
      std::ifstream in(path);
      if (!in)
        throw ApiError(MBDAE_ERROR_IO, std::string(path) + ": cannot open the file: " +
                                           std::strerror(errno));
    }
    auto m = std::make_unique<mbdae_model>();
    m->path = path;
    m->name = path;
    mbdae::api::Load(*m, {}, &m->model, &m->settings);
    *model = m.release();
  });
}

mbdae_status mbdae_model_from_string(const char* text, const char* name, mbdae_model** model) {
  return Call([&] {
    NotNull(text, "text");
    NotNull(name, "name");
    NotNull(model, "model");
    auto m = std::make_unique<mbdae_model>();
    m->text = text;
    m->name = *name ? name : "<string>";
    mbdae::api::Load(*m, {}, &m->model, &m->settings);
    *model = m.release();
  });
}

void mbdae_model_free(mbdae_model* model) { delete model; }

// ---- Sizes and names -------------------------------------------------------------------

mbdae_status mbdae_count(mbdae_model* model, mbdae_kind kind, int* count) {
  return Call([&] {
    mbdae::api::CheckKind(kind);
    mbdae_model& m = Handle(model);
    NotNull(count, "count");
    *count = mbdae::api::Count(m, kind);
  });
}

mbdae_status mbdae_name(mbdae_model* model, mbdae_kind kind, int index, const char** name) {
  return Call([&] {
    mbdae::api::CheckKind(kind);
    mbdae_model& m = Handle(model);
    NotNull(name, "name");
    const auto& names = mbdae::api::Names(m, kind);
    CheckIndex(index, static_cast<int>(names.size()), mbdae::api::KindName(kind));
    *name = names[index].c_str();
  });
}

mbdae_status mbdae_find(mbdae_model* model, mbdae_kind kind, const char* name, int* index) {
  return Call([&] {
    mbdae::api::CheckKind(kind);
    mbdae_model& m = Handle(model);
    NotNull(name, "name");
    NotNull(index, "index");
    const auto& names = mbdae::api::Names(m, kind);
    const auto it = std::find(names.begin(), names.end(), name);
    if (it == names.end())
      throw ApiError(MBDAE_ERROR_ARGUMENT, std::string("there is no ") +
                                               mbdae::api::KindName(kind) + " called '" + name +
                                               "'");
    *index = static_cast<int>(it - names.begin());
  });
}

// ---- Parameters, splines and options ----------------------------------------------------

mbdae_status mbdae_get_parameter(mbdae_model* model, int index, double* value) {
  return Call([&] {
    mbdae_model& m = Handle(model);
    NotNull(value, "value");
    CheckIndex(index, static_cast<int>(m.model->parameters.size()), "parameter");
    *value = m.model->parameters[index].value;
  });
}

mbdae_status mbdae_set_parameter(mbdae_model* model, int index, double value) {
  return Call([&] {
    mbdae_model& m = Handle(model);
    CheckIndex(index, static_cast<int>(m.model->parameters.size()), "parameter");
    const std::string& name = m.model->parameters[index].name;
    if (!std::isfinite(value))
      throw ApiError(MBDAE_ERROR_INPUT,
                     "parameter '" + name + "': the value must be finite, got " +
                         mbdae::api::Num(value));
    std::map<std::string, double> overrides = m.parameter_overrides;
    overrides[name] = value;
    std::unique_ptr<mbdae::mbs::Model> rebuilt;
    mbdae::mbs::SimulationSettings settings;
    try {
      mbdae::api::Load(m, overrides, &rebuilt, &settings);
    } catch (const std::exception& e) {
      throw ApiError(MBDAE_ERROR_INPUT, "parameter '" + name + "' = " + mbdae::api::Num(value) +
                                            " makes the model invalid (the old value stays): " +
                                            e.what());
    }
    mbdae::api::MarkForAssembly(m);  // before the model the assembly refers to goes
    m.model = std::move(rebuilt);
    m.settings = settings;
    m.parameter_overrides = std::move(overrides);
    for (bool& valid : m.names_valid) valid = false;
  });
}

mbdae_status mbdae_spline_size(mbdae_model* model, int index, int* num_points) {
  return Call([&] {
    mbdae_model& m = Handle(model);
    NotNull(num_points, "num_points");
    CheckIndex(index, static_cast<int>(m.model->splines.size()), "spline");
    *num_points = static_cast<int>(m.model->splines[index].spline.x().size());
  });
}

mbdae_status mbdae_get_spline_points(mbdae_model* model, int index, double* x, double* y, int n) {
  return Call([&] {
    mbdae_model& m = Handle(model);
    NotNull(x, "x");
    NotNull(y, "y");
    CheckIndex(index, static_cast<int>(m.model->splines.size()), "spline");
    const mbdae::mbs::Spline& s = m.model->splines[index].spline;
    CheckSize(n, static_cast<int>(s.x().size()), "spline points");
    std::copy(s.x().begin(), s.x().end(), x);
    std::copy(s.y().begin(), s.y().end(), y);
  });
}

mbdae_status mbdae_set_spline_points(mbdae_model* model, int index, const double* x,
                                     const double* y, int n) {
  return Call([&] {
    mbdae_model& m = Handle(model);
    NotNull(x, "x");
    NotNull(y, "y");
    CheckIndex(index, static_cast<int>(m.model->splines.size()), "spline");
    if (n < 0) throw ApiError(MBDAE_ERROR_SIZE, "spline points: n = " + std::to_string(n) + " < 0");
    mbdae::mbs::SplineDef& def = m.model->splines[index];
    std::vector<double> xs(x, x + n), ys(y, y + n);
    try {
      mbdae::mbs::Spline::Validate(xs, ys);
    } catch (const std::invalid_argument& e) {
      throw ApiError(MBDAE_ERROR_INPUT, "spline '" + def.name + "': " + e.what());
    }
    mbdae::api::MarkForAssembly(m);
    def.spline.SetPoints(xs, ys);
    m.spline_points[def.name] = {std::move(xs), std::move(ys)};
  });
}

mbdae_status mbdae_set_option(mbdae_model* model, const char* key, const char* value) {
  return Call([&] {
    mbdae_model& m = Handle(model);
    NotNull(key, "key");
    NotNull(value, "value");
    mbdae::api::SetOption(m, key, value);
  });
}

mbdae_status mbdae_get_option(mbdae_model* model, const char* key, char* buf, size_t size) {
  return Call([&] {
    mbdae_model& m = Handle(model);
    NotNull(key, "key");
    NotNull(buf, "buf");
    const std::string value = mbdae::api::GetOption(m, key);
    if (value.size() + 1 > size)
      throw ApiError(MBDAE_ERROR_SIZE, std::string("option ") + key + ": the buffer has " +
                                           std::to_string(size) + " bytes, expected at least " +
                                           std::to_string(value.size() + 1));
    std::memcpy(buf, value.c_str(), value.size() + 1);
  });
}

// ---- Solving -----------------------------------------------------------------------------

mbdae_status mbdae_assemble(mbdae_model* model) {
  return Call([&] { mbdae::api::Assemble(Handle(model)); });
}

mbdae_status mbdae_solve(mbdae_model* model) {
  return Call([&] {
    mbdae_model& m = Handle(model);
    mbdae::api::EnsureAssembled(m);
    if (m.state.t < m.settings.t_end) mbdae::api::SolveTo(m, m.settings.t_end);
  });
}

mbdae_status mbdae_solve_to(mbdae_model* model, double t) {
  return Call([&] {
    mbdae_model& m = Handle(model);
    if (!std::isfinite(t)) throw ApiError(MBDAE_ERROR_ARGUMENT, "t must be finite");
    mbdae::api::EnsureAssembled(m);
    if (!(t > m.state.t))
      throw ApiError(MBDAE_ERROR_ARGUMENT, "t = " + mbdae::api::Num(t) +
                                               " must be after the current time " +
                                               mbdae::api::Num(m.state.t));
    mbdae::api::SolveTo(m, t);
  });
}

mbdae_status mbdae_get_state(mbdae_model* model, double* t, double* q, double* v, double* a,
                             double* lambda, int nq, int nm) {
  return Call([&] {
    mbdae_model& m = Handle(model);
    mbdae::api::EnsureAssembled(m);
    const mbdae::dae::State& x = m.state;
    if (q || v || a) CheckSize(nq, static_cast<int>(x.q.size()), "nq (coordinates)");
    if (lambda) CheckSize(nm, static_cast<int>(x.lambda.size()), "nm (multipliers)");
    if (t) *t = x.t;
    if (q) std::copy(x.q.begin(), x.q.end(), q);
    if (v) std::copy(x.v.begin(), x.v.end(), v);
    if (a) std::copy(x.a.begin(), x.a.end(), a);
    if (lambda) std::copy(x.lambda.begin(), x.lambda.end(), lambda);
  });
}

mbdae_status mbdae_set_state(mbdae_model* model, double t, const double* q, const double* v,
                             const double* a, const double* lambda, int nq, int nm) {
  return Call([&] {
    mbdae_model& m = Handle(model);
    NotNull(q, "q");
    NotNull(v, "v");
    if (!std::isfinite(t)) throw ApiError(MBDAE_ERROR_ARGUMENT, "t must be finite");
    mbdae::api::EnsureAssembled(m);
    const int nq_model = static_cast<int>(m.state.q.size());
    const int nm_model = static_cast<int>(m.state.lambda.size());
    CheckSize(nq, nq_model, "nq (coordinates)");
    CheckSize(nm, nm_model, "nm (multipliers)");
    mbdae::dae::State x;
    x.t = t;
    x.q.assign(q, q + nq);
    x.v.assign(v, v + nq);
    for (int i = 0; i < nq; ++i)
      if (!std::isfinite(x.q[i]) || !std::isfinite(x.v[i]))
        throw ApiError(MBDAE_ERROR_ARGUMENT, "q and v must be finite (coordinate " +
                                                 std::to_string(i) + ")");
    if (!a || !lambda) mbdae::api::SolveAccelerations(m, &x);
    if (a) x.a.assign(a, a + nq);
    if (lambda) x.lambda.assign(lambda, lambda + nm);
    auto integrator = mbdae::api::StartIntegrator(m, x);

    // Rows after t belong to the history being replaced.
    const double tol = 1e-9 * m.settings.output_step;
    while (!m.rows.empty() && m.rows.back().t > t + tol) m.rows.pop_back();
    int next = 0;
    while (mbdae::api::OutputTime(m, next) <= t + tol) ++next;
    mbdae::api::FinishIntegrator(m);
    m.integrator = std::move(integrator);
    m.state = std::move(x);
    m.next_output = next;
    m.failed = false;
    m.failure_reason.clear();
    if (m.rows.empty())
      m.row_builder->Restart();
    else
      m.row_builder->ContinueAfter(m.rows.back().measures.data());
  });
}

// ---- Stored outputs ------------------------------------------------------------------------

mbdae_status mbdae_get_output(mbdae_model* model, int row, mbdae_output what, double* out, int n) {
  return Call([&] {
    CheckEnum(what, MBDAE_OUT_BODY_POSES + 1, "mbdae_get_output", "mbdae_output");
    mbdae_model& m = Handle(model);
    NotNull(out, "out");
    if (m.rows.empty())
      throw ApiError(MBDAE_ERROR_ORDER,
                     "there are no stored rows: call mbdae_assemble or mbdae_solve first");
    CheckIndex(row, static_cast<int>(m.rows.size()), "output row");
    const mbdae::api::OutputRow& r = m.rows[row];
    const std::vector<double>* values = nullptr;
    const char* name = "";
    switch (what) {
      case MBDAE_OUT_TIME:
        CheckSize(n, 1, "time");
        out[0] = r.t;
        return;
      case MBDAE_OUT_Q: values = &r.q; name = "q"; break;
      case MBDAE_OUT_V: values = &r.v; name = "v"; break;
      case MBDAE_OUT_A: values = &r.a; name = "a"; break;
      case MBDAE_OUT_LAMBDA: values = &r.lambda; name = "lambda"; break;
      case MBDAE_OUT_MEASURES: values = &r.measures; name = "measures"; break;
      case MBDAE_OUT_BODY_POSES: values = &r.body_poses; name = "body poses"; break;
      default:
        throw ApiError(MBDAE_ERROR_ARGUMENT,
                       "unknown output quantity " + std::to_string(static_cast<int>(what)));
    }
    CheckSize(n, static_cast<int>(values->size()), name);
    std::copy(values->begin(), values->end(), out);
  });
}

mbdae_status mbdae_write_results(mbdae_model* model, const char* path) {
  return Call([&] {
    mbdae_model& m = Handle(model);
    NotNull(path, "path");
    mbdae::api::WriteResults(m, path);
  });
}

// ---- Measures, vectors, matrices at the current state (state_matrices.cc) ------------------

mbdae_status mbdae_measure_values(mbdae_model* model, double* values, int n) {
  return Call([&] {
    mbdae_model& m = Handle(model);
    NotNull(values, "values");
    mbdae::api::MeasureValues(m, values, n);
  });
}

mbdae_status mbdae_measure_gradient(mbdae_model* model, int measure, double* dq, int n) {
  return Call([&] {
    mbdae_model& m = Handle(model);
    NotNull(dq, "dq");
    mbdae::api::MeasureGradient(m, measure, dq, n);
  });
}

mbdae_status mbdae_get_vector(mbdae_model* model, mbdae_vector which, double* out, int n) {
  return Call([&] {
    CheckEnum(which, MBDAE_VEC_CONSTRAINTS_DTT + 1, "mbdae_get_vector", "mbdae_vector");
    mbdae_model& m = Handle(model);
    NotNull(out, "out");
    mbdae::api::GetVector(m, which, out, n);
  });
}

mbdae_status mbdae_set_newton_step(mbdae_model* model, double h) {
  return Call([&] {
    mbdae_model& m = Handle(model);
    if (!(h > 0) || !std::isfinite(h))
      throw ApiError(MBDAE_ERROR_ARGUMENT,
                     "the Newton step h must be > 0 and finite, got " + mbdae::api::Num(h));
    m.newton_step = h;
  });
}

mbdae_status mbdae_get_matrix(mbdae_model* model, const mbdae_block* blocks, int num_blocks,
                              int rows, int cols, mbdae_sparse_format format, int* nnz,
                              int* ptr, int* idx, double* val) {
  return Call([&] {
    CheckEnum(format, MBDAE_CSR + 1, "mbdae_get_matrix: format", "mbdae_sparse_format (MBDAE_CSC, MBDAE_CSR)");
    mbdae_model& m = Handle(model);
    NotNull(nnz, "nnz");
    if (num_blocks > 0) NotNull(blocks, "blocks");
    mbdae::api::GetMatrix(m, blocks, num_blocks, rows, cols, format, nnz, ptr, idx, val);
  });
}

// ---- Objectives and their gradients (gradient.cc) ------------------------------------------

mbdae_status mbdae_gradient(mbdae_model* model, const char* method,
                            const char* const* objectives, int num_objectives,
                            const char* const* wrt, int num_wrt, int wrt_splines,
                            const char* results_path) {
  return Call([&] {
    mbdae_model& m = Handle(model);
    mbdae::api::ComputeGradient(m, method, objectives, num_objectives, wrt, num_wrt,
                                wrt_splines != 0, results_path);
  });
}

mbdae_status mbdae_get_gradient(mbdae_model* model, mbdae_gradient_output what, double* out,
                                int n) {
  return Call([&] {
    CheckEnum(what, MBDAE_GRAD_COUNTERS + 1, "mbdae_get_gradient", "mbdae_gradient_output");
    const mbdae_model& m = Handle(model);
    NotNull(out, "out");
    mbdae::api::GetGradient(m, what, out, n);
  });
}

mbdae_status mbdae_gradient_report(mbdae_model* model, int json, char* buf, size_t size,
                                   size_t* length) {
  return Call([&] {
    const mbdae_model& m = Handle(model);
    mbdae::api::GradientReport(m, json != 0, buf, size, length);
  });
}

}  // extern "C"
