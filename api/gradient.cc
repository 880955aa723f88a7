// The C API's objectives and gradients (api/mbdae.h: mbdae_gradient, mbdae_get_gradient,
// mbdae_gradient_report, the "gradient.*" options): driver::ComputeGradient on the
// handle's model, settings and spline points, with a reload that rebuilds the model the
// way mbdae_set_parameter does (for fd over parameters). The handle's assembly, state
// and stored rows are not touched; the result is stored in the handle.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <map>
#include <memory>
#include <set>
#include <stdexcept>
#include <string>
#include <vector>

#include "api/session.h"
#include "apps/cli.h"
#include "driver/gradient.h"
#include "mbs/loader.h"
#include "mbs/sensitivity_parameters.h"

namespace mbdae::api {
namespace {

std::string Number(double x) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.17g", x);
  return buf;
}

std::string Join(const std::vector<std::string>& names) {
  if (names.empty()) return "none";
  std::string out;
  for (size_t i = 0; i < names.size(); ++i) out += (i ? ", " : "") + names[i];
  return out;
}

// The names of a (pointer, count) pair of C strings; null entries are an error.
std::vector<std::string> NameList(const char* const* names, int n, const char* what) {
  if (n < 0)
    throw ApiError(MBDAE_ERROR_SIZE, std::string(what) + ": the count is " + std::to_string(n) +
                                         " < 0");
  std::vector<std::string> out;
  if (n == 0) return out;
  if (!names)
    throw ApiError(MBDAE_ERROR_ARGUMENT, std::string(what) + " is NULL but its count is " +
                                             std::to_string(n));
  std::set<std::string> seen;
  for (int i = 0; i < n; ++i) {
    if (!names[i])
      throw ApiError(MBDAE_ERROR_ARGUMENT, std::string(what) + "[" + std::to_string(i) +
                                               "] is NULL");
    if (!seen.insert(names[i]).second)
      throw ApiError(MBDAE_ERROR_ARGUMENT, std::string(what) + " lists '" + names[i] + "' twice");
    out.emplace_back(names[i]);
  }
  return out;
}

const driver::GradientResult& Stored(const mbdae_model& m) {
  if (!m.gradient)
    throw ApiError(MBDAE_ERROR_ORDER, "there is no stored gradient: call mbdae_gradient first");
  return *m.gradient;
}


}  // namespace

bool SetGradientOption(mbdae_model& m, const std::string& key, const char* value) {
  if (key.rfind("gradient.", 0) != 0) return false;
  driver::GradientRequest r = m.gradient_settings;
  if (key == "gradient.fd_step") {
    r.fd_step = ParseOptionNumber(key, value);
  } else if (key == "gradient.newton_factor") {
    r.newton_factor = ParseOptionNumber(key, value);
  } else if (key == "gradient.trajectory_memory") {
    r.trajectory_memory = ParseOptionNumber(key, value);
  } else if (key == "gradient.ida_checkpoint_steps") {
    const double x = ParseOptionNumber(key, value);
    if (x != std::floor(x) || x < 1 || x > 1e15)
      throw ApiError(MBDAE_ERROR_INPUT, "option " + key + ": expected an integer >= 1, got '" +
                                            std::string(value) + "'");
    r.ida_checkpoint_steps = static_cast<long>(x);
  } else {
    return false;  // the caller reports the unknown key with the list of options
  }
  std::string error;
  if (!r.IsValid(&error))
    throw ApiError(MBDAE_ERROR_INPUT, "option " + key + " = " + value + ": " + error);
  m.gradient_settings = r;
  return true;
}

bool GetGradientOption(const mbdae_model& m, const std::string& key, std::string* value) {
  const driver::GradientRequest& r = m.gradient_settings;
  if (key == "gradient.fd_step") *value = Number(r.fd_step);
  else if (key == "gradient.newton_factor") *value = Number(r.newton_factor);
  else if (key == "gradient.trajectory_memory") *value = Number(r.trajectory_memory);
  else if (key == "gradient.ida_checkpoint_steps") *value = std::to_string(r.ida_checkpoint_steps);
  else return false;
  return true;
}

void ComputeGradient(mbdae_model& m, const char* method, const char* const* objectives,
                     int num_objectives, const char* const* wrt, int num_wrt, bool wrt_splines,
                     const char* results_path) {
  const mbs::Model& model = *m.model;
  driver::GradientRequest request = m.gradient_settings;
  const std::string method_name = method ? method : "adjoint";
  if (!driver::ParseGradientMethod(method_name, &request.method))
    throw ApiError(MBDAE_ERROR_ARGUMENT,
                   "unknown gradient method '" + method_name + "'; the methods are adjoint, forward, fd");

  // Names that do not exist are the caller's argument mistakes (MBDAE_ERROR_ARGUMENT),
  // found here before the driver runs anything.
  request.objectives = NameList(objectives, num_objectives, "objectives");
  std::vector<std::string> known;
  for (const auto& o : model.objectives) known.push_back(o.name);
  for (const std::string& name : request.objectives)
    if (model.find_objective(name) < 0)
      throw ApiError(MBDAE_ERROR_ARGUMENT, "there is no objective called '" + name +
                                               "' (the model's objectives: " + Join(known) + ")");
  request.wrt = NameList(wrt, num_wrt, "wrt");
  try {
    mbs::ResolveSensitivityParameters(model, request.wrt);
  } catch (const std::invalid_argument& e) {
    throw ApiError(MBDAE_ERROR_ARGUMENT, std::string("wrt: ") + e.what());
  }
  request.wrt_splines = wrt_splines;

  driver::GradientOptions options;
  options.model_path = m.path.empty() ? m.name : m.path;
  // The results file as `mbdae gradient -o` writes it: checked now (not the model file),
  // written beside its path (the forward run, then /objectives) and renamed over it once
  // the driver is through; an exception before that removes the temporary file.
  const std::string path = results_path ? results_path : "";
  std::unique_ptr<ResultsTarget> target;
  if (!path.empty()) {
    target = std::make_unique<ResultsTarget>(path, std::vector<std::pair<std::string, std::string>>{
                                                       {"model file", m.path}});
    options.results_path = target->CreateTemporary();
  }
  // fd over a parameter: the model rebuilt as mbdae_set_parameter rebuilds it (the
  // parameters set so far, then the new values; spline points set through the API
  // applied again).
  const mbdae_model& handle = m;
  options.reload = [&handle](const std::map<std::string, double>& values) {
    std::map<std::string, double> overrides = handle.parameter_overrides;
    for (const auto& [name, value] : values) overrides[name] = value;
    std::unique_ptr<mbs::Model> rebuilt;
    mbs::SimulationSettings ignored;
    Load(handle, overrides, &rebuilt, &ignored);
    return std::move(*rebuilt);
  };

  driver::GradientResult result;
  try {
    result = driver::ComputeGradient(model, m.settings, request, options);
  } catch (const driver::InputError& e) {
    throw ApiError(MBDAE_ERROR_INPUT, e.what());
  } catch (const mbs::ModelError& e) {
    throw ApiError(MBDAE_ERROR_INPUT, e.what());
  } catch (const std::invalid_argument& e) {
    throw ApiError(MBDAE_ERROR_INPUT, e.what());
  } catch (const std::bad_alloc&) {
    throw;
  } catch (const ApiError&) {
    throw;
  } catch (const std::runtime_error& e) {
    // The driver's other runtime errors come from the results file (created, written).
    if (target) throw ApiError(MBDAE_ERROR_IO, "results file " + path + ": " + e.what());
    throw;
  }
  // A forward run that failed is in the file too (status "failed"), as with the program.
  if (target && !result.forward.results_path.empty()) {
    target->Commit();
    result.forward.results_path = path;
  }
  if (result.status != driver::GradientResult::Status::kDone)
    throw ApiError(MBDAE_ERROR_SOLVER, "the gradient failed: " + result.failure_reason);
  m.gradient = std::make_unique<driver::GradientResult>(std::move(result));
  m.names_valid[MBDAE_GRADIENT_OBJECTIVES] = false;
  m.names_valid[MBDAE_GRADIENT_WRT] = false;
}

void GetGradient(const mbdae_model& m, mbdae_gradient_output what, double* out, int n) {
  const driver::GradientResult& r = Stored(m);
  const int no = static_cast<int>(r.objectives.size());
  const int nw = static_cast<int>(r.wrt.size());
  std::vector<double> values;
  size_t expected = 0;
  const char* name = "";
  switch (what) {
    case MBDAE_GRAD_VALUES:
      values = r.values;
      expected = no;
      name = "gradient values (num_objectives)";
      break;
    case MBDAE_GRAD_GRADIENT:
      values = r.gradient;
      expected = static_cast<size_t>(no) * nw;
      name = "gradient (num_objectives * num_wrt)";
      break;
    case MBDAE_GRAD_FD_STEPS:
      if (r.fd_steps.empty())
        throw ApiError(MBDAE_ERROR_ARGUMENT, "the stored gradient was computed by the " +
                                                 r.method + " method: fd steps exist for fd only");
      values = r.fd_steps;
      expected = nw;
      name = "fd steps (num_wrt)";
      break;
    case MBDAE_GRAD_TIMES:
      values = {r.solver_cpu_time, r.gradient_cpu_time, r.wall_time};
      expected = 3;
      name = "gradient times";
      break;
    case MBDAE_GRAD_COUNTERS:
      values = {static_cast<double>(r.forward_steps), static_cast<double>(r.runs),
                static_cast<double>(r.linear_solves), r.trajectory_bytes};
      expected = 4;
      name = "gradient counters";
      break;
    default:
      throw ApiError(MBDAE_ERROR_ARGUMENT,
                     "unknown gradient quantity " + std::to_string(static_cast<int>(what)));
  }
  if (values.size() != expected)
    throw ApiError(MBDAE_ERROR_INTERNAL, std::string("the stored ") + name + " has " +
                                             std::to_string(values.size()) + " values, not " +
                                             std::to_string(expected));
  if (n != static_cast<int>(expected))
    throw ApiError(MBDAE_ERROR_SIZE, std::string(name) + ": the array has " + std::to_string(n) +
                                         " values, expected " + std::to_string(expected));
  std::copy(values.begin(), values.end(), out);
}

void GradientReport(const mbdae_model& m, bool json, char* buf, size_t size, size_t* length) {
  const driver::GradientResult& r = Stored(m);
  const std::string text = json ? r.Json() : r.Report();
  const size_t needed = text.size() + 1;
  if (!buf) {
    if (size != 0)
      throw ApiError(MBDAE_ERROR_ARGUMENT, "buf is NULL but size is " + std::to_string(size));
    if (!length) throw ApiError(MBDAE_ERROR_ARGUMENT, "buf and length are both NULL");
    *length = needed;
    return;
  }
  if (size < needed)
    throw ApiError(MBDAE_ERROR_SIZE, "gradient report: the buffer has " + std::to_string(size) +
                                         " bytes, expected at least " + std::to_string(needed));
  std::memcpy(buf, text.c_str(), needed);
  if (length) *length = needed;
}

}  // namespace mbdae::api
