// Internal to the C API (api/mbdae.h): what one mbdae_model handle holds, and the
// functions the API's source files share. Not installed; not part of the C ABI.
//
// Files: api/mbdae_api.cc (the extern "C" functions: handles, errors, names, parameters,
// splines, options, assembly, solving, stored outputs, results file); api/state_matrices.cc
// (vectors, matrices, measures at the current state); api/gradient.cc (objectives and
// their gradients: driver::ComputeGradient on the handle's model); api/optimize.cc
// (mbdae_optimize: driver::Optimize, with its own extern "C" functions run through
// CallApi). Every extern "C" function catches
// everything: ApiError gives its status, mbs::ModelError / driver::InputError
// MBDAE_ERROR_INPUT, std::bad_alloc and anything else MBDAE_ERROR_INTERNAL.
#pragma once

#include <cstring>
#include <functional>
#include <map>
#include <memory>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "api/mbdae.h"
#include "dae/integrator.h"
#include "driver/gradient.h"
#include "driver/simulation.h"
#include "mbs/model.h"

namespace mbdae::api {

// An error with its status; what() is the message mbdae_last_error() returns.
class ApiError : public std::runtime_error {
 public:
  ApiError(mbdae_status status, const std::string& message)
      : std::runtime_error(message), status_(status) {}
  mbdae_status status() const { return status_; }

 private:
  mbdae_status status_;
};

// The integer a C caller passed for an enum of the API, read without loading it as the
// enum type: a value outside the enumeration's range is undefined behaviour when loaded
// as the enum (UBSan: "load of value ... which is not a valid value"), so every
// function checks the int first and uses the enum only once it is one of the
// enumerators.
template <typename Enum>
int EnumInt(const Enum& value) {
  static_assert(sizeof(Enum) == sizeof(int), "the API's enums are ints");
  int i;
  std::memcpy(&i, &value, sizeof i);
  return i;
}

// Throws ApiError(MBDAE_ERROR_ARGUMENT) "WHAT: V is not an ENUM_NAME (0 .. count - 1)".
template <typename Enum>
void CheckEnum(const Enum& value, int count, const char* what, const char* enum_name) {
  const int i = EnumInt(value);
  if (i < 0 || i >= count)
    throw ApiError(MBDAE_ERROR_ARGUMENT, std::string(what) + ": " + std::to_string(i) + " is not an " +
                                             enum_name + " (0 .. " + std::to_string(count - 1) + ")");
}

// One stored output row: the state, and everything the results file holds of it (so
// that mbdae_write_results needs neither the model nor the assembly of the run).
struct OutputRow {
  double t = 0;
  std::vector<double> q, v, a, lambda;  // nq, nq, nq, nm (kept equations)
  std::vector<double> measures;         // unwrapped as in the results file
  std::vector<double> body_poses;       // 12 per body: position, rotation row-major
  std::vector<double> body_data;        // 13 per body: position, Euler parameters, v, omega
  std::vector<double> joint_data;       // 6 per joint: reaction force, torque
  std::vector<double> joint_coordinate_data;  // 4 per joint coordinate of a tree (mbs/joint_space.h)
  std::vector<double> force_data;       // 6 per force element: force, torque
  double kinetic_energy = 0, potential_energy = 0;
  double position_violation = 0, velocity_violation = 0;
};

}  // namespace mbdae::api

// The handle. Invariants: `model` is always valid (the last successful load with the
// current parameter values and spline points); `assembly` is null until assembled and
// is reset (with `integrator`, `state`, `row_builder`) whenever the model or the settings
// change. `rows` and `run` (what the results file says of the run) stay until the next
// assembly, which clears them and stores the row at t = 0.
struct mbdae_model {
  // Where the model came from, to rebuild it when a parameter changes.
  std::string path;  // file path (from_file), or "" (from_string)
  std::string text;  // the model text (from_string)
  std::string name;  // for messages
  std::map<std::string, double> parameter_overrides;  // every parameter set through the API
  // Spline points set through the API, by spline name (re-applied after a rebuild).
  std::map<std::string, std::pair<std::vector<double>, std::vector<double>>> spline_points;

  std::unique_ptr<mbdae::mbs::Model> model;
  mbdae::driver::SettingsOverrides option_overrides;  // every option set through the API
  mbdae::mbs::SimulationSettings settings;  // the model's, with set_option applied

  std::unique_ptr<mbdae::driver::Assembly> assembly;  // null: not assembled
  std::unique_ptr<mbdae::dae::Integrator> integrator;  // null: restart from `state`
  mbdae::dae::State state;  // the current state, of assembly->kept_system
  double newton_step = 0;   // 0: settings.hht_step

  std::vector<mbdae::api::OutputRow> rows;
  int next_output = 0;  // index (in driver::OutputTimes) of the next output time to store
  std::vector<double> output_times;  // driver::OutputTimes of the settings

  // The run whose rows are stored: its description, the counters of the integrators
  // finished since the assembly (a restart by set_state or after a failure starts a new
  // integrator), times, and how the last solve call ended.
  mbdae::driver::RunDescription run;
  mbdae::dae::Summary finished_counters;
  double solver_cpu_time = 0;
  double wall_time = 0;
  bool failed = false;
  std::string failure_reason;
  double t_failed = 0;  // the time the failed integrator reached

  // The settings of mbdae_gradient ("gradient.*" options: fd_step, newton_factor,
  // trajectory_memory, ida_checkpoint_steps; the names and the method are per call).
  mbdae::driver::GradientRequest gradient_settings;
  // The result of the last successful mbdae_gradient (null before the first); kept
  // whatever happens to the model until the next one.
  std::unique_ptr<mbdae::driver::GradientResult> gradient;

  // Name lists (stable pointers for mbdae_name), filled on demand; names_valid[kind] is
  // false until filled and after the model is rebuilt (or re-assembled, for the
  // multipliers and the redundant equations; or a new gradient, for its names).
  static constexpr int kNumKinds = MBDAE_GRADIENT_WRT + 1;
  std::vector<std::string> names_cache[kNumKinds];
  bool names_valid[kNumKinds] = {};

  // Measures of the rows (unwrapping, offsets), of `model` and `assembly`: declared last,
  // so destroyed before them.
  std::unique_ptr<mbdae::driver::OutputRowBuilder> row_builder;
};

namespace mbdae::app {
class ResultsDestination;
}  // namespace mbdae::app

namespace mbdae::api {

// Runs the body of an extern "C" function as every call of the API does (Call in
// api/mbdae_api.cc): MBDAE_OK, or the status of what it throws with the message as the
// thread's last error. For the extern "C" functions of the other files (api/optimize.cc).
mbdae_status CallApi(const std::function<void()>& body);

// Assembles if needed (throws ApiError MBDAE_ERROR_SOLVER or INPUT with the reason).
void EnsureAssembled(mbdae_model& m);

// The model from its source (path or text) with the given parameter overrides and the
// spline points set through the API; the settings resolved with the API's options.
// Throws (ModelError, InputError, ApiError) without touching m. In api/mbdae_api.cc.
void Load(const mbdae_model& m, const std::map<std::string, double>& overrides,
          std::unique_ptr<mbs::Model>* model, mbs::SimulationSettings* settings);

// The results file of mbdae_write_results, mbdae_gradient and mbdae_optimize, written
// as `mbdae simulate -o` writes its own (app::ResultsDestination, apps/cli.h): the path is
// checked before anything runs, the file is written as PATH.PID.tmp beside it and renamed
// over PATH only by Commit(), so that an earlier file stays whole until then; the
// destructor removes the temporary file of a call that failed before. A path that is one
// of `inputs` ({what, file}: the model file, the problem file; by any spelling or link),
// an empty path, and a path the system would not let us write (its reason) are refused
// with ApiError(MBDAE_ERROR_IO) naming it; so is a temporary file that cannot be made.
// In api/mbdae_api.cc.
class ResultsTarget {
 public:
  ResultsTarget(const std::string& path, const std::vector<std::pair<std::string, std::string>>& inputs);
  ~ResultsTarget();
  ResultsTarget(const ResultsTarget&) = delete;
  ResultsTarget& operator=(const ResultsTarget&) = delete;
  const std::string& path() const { return path_; }
  // Creates the empty temporary file and returns its name (the file to write).
  const std::string& CreateTemporary();
  // Renames the temporary file over the path.
  void Commit();

 private:
  std::string path_;
  std::unique_ptr<app::ResultsDestination> destination_;
};

// Implemented in api/gradient.cc. All throw ApiError (or the driver's InputError).
void ComputeGradient(mbdae_model& m, const char* method, const char* const* objectives,
                     int num_objectives, const char* const* wrt, int num_wrt, bool wrt_splines,
                     const char* results_path);
void GetGradient(const mbdae_model& m, mbdae_gradient_output what, double* out, int n);
void GradientReport(const mbdae_model& m, bool json, char* buf, size_t size, size_t* length);
// "gradient.*" options (SetGradientOption returns false for a key that is not one).
bool SetGradientOption(mbdae_model& m, const std::string& key, const char* value);
// The value of option `key` as a finite number; ApiError (MBDAE_ERROR_INPUT) otherwise.
double ParseOptionNumber(const std::string& key, const char* value);
bool GetGradientOption(const mbdae_model& m, const std::string& key, std::string* value);

// Implemented in api/state_matrices.cc. All throw ApiError.
void MeasureValues(mbdae_model& m, double* values, int n);
void MeasureGradient(mbdae_model& m, int measure, double* dq, int n);
void GetVector(mbdae_model& m, mbdae_vector which, double* out, int n);
void GetMatrix(mbdae_model& m, const mbdae_block* blocks, int num_blocks, int rows, int cols,
               mbdae_sparse_format format, int* nnz, int* ptr, int* idx, double* val);

}  // namespace mbdae::api
