// The C API's optimal control and identification (api/mbdae.h: mbdae_optimize,
// mbdae_optimize_string, mbdae_optimization_report, mbdae_optimization_history,
// mbdae_optimization_free): driver::LoadOptimizationProblem and driver::Optimize, the
// pipeline of `mbdae optimize`, with the result kept in its own handle. The extern "C"
// functions run through CallApi (api/mbdae_api.cc), so errors reach mbdae_last_error()
// as for every other call.

// The declarations of the header get default visibility (the library is compiled with
// hidden visibility, and only these functions are exported).
#pragma GCC visibility push(default)
#include "api/mbdae.h"
#pragma GCC visibility pop

#include <cstring>
#include <filesystem>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include "api/session.h"
#include "apps/cli.h"
#include "driver/optimize.h"
#include "mbs/loader.h"

// The handle: the driver's result (the report, the JSON and the history come from it).
struct mbdae_optimization {
  mbdae::driver::OptimizationResult result;
};

namespace mbdae::api {
namespace {

static_assert(MBDAE_OPTIMIZATION_HISTORY_COLUMNS == 8, "the history rows below have 8 columns");

// Loads (a file when `text` is null, else the text named `name`) and solves; the result
// into *out only when everything went through.
void Optimize(const char* path, const char* text, const char* name, const char* results_path,
              mbdae_progress_callback progress, void* user_data, mbdae_optimization** out) {
  if (!out) throw ApiError(MBDAE_ERROR_ARGUMENT, "result is NULL");
  driver::OptimizationProblem problem;
  if (text) {
    problem = driver::LoadOptimizationProblemFromString(text, name ? name : "");
  } else {
    if (!path) throw ApiError(MBDAE_ERROR_ARGUMENT, "problem_path is NULL");
    std::error_code ec;
    if (!std::filesystem::exists(path, ec))
      throw ApiError(MBDAE_ERROR_IO, std::string(path) + ": cannot open the problem file (it does not exist)");
    try {
      problem = driver::LoadOptimizationProblem(path);
    } catch (const driver::InputError& e) {
      // A file that exists but cannot be read is an I/O error, the rest bad input.
      if (std::strstr(e.what(), ": cannot open the problem file")) throw ApiError(MBDAE_ERROR_IO, e.what());
      throw;
    }
  }
  driver::OptimizeOptions options;
  // The results file as `mbdae optimize -o` writes it: checked before anything runs
  // (neither the problem file nor its model), written beside its path (the final run,
  // then /optimization) and renamed over it at the end; a call that fails before that,
  // or whose final run could not start, leaves an earlier file as it was.
  const std::string results = results_path ? results_path : "";
  std::unique_ptr<ResultsTarget> target;
  if (!results.empty()) {
    target = std::make_unique<ResultsTarget>(
        results, std::vector<std::pair<std::string, std::string>>{
                     {"problem file", text ? std::string() : std::string(path)},
                     {"model file of the problem", problem.model_path}});
    options.results_path = target->CreateTemporary();
  }
  bool abandoned = false;  // the callback returned a negative value: nothing is written
  if (progress) {
    options.stop = [progress, user_data, &abandoned](const driver::OptimizationIteration& it) {
      const int answer = progress(it.iteration, it.objective, it.constraint_violation, user_data);
      if (answer < 0) abandoned = true;
      return answer != 0;
    };
  }
  auto handle = std::make_unique<mbdae_optimization>();
  try {
    handle->result = driver::Optimize(problem, options);
  } catch (const driver::InputError&) {
    throw;
  } catch (const mbs::ModelError&) {
    throw;
  } catch (const std::runtime_error& e) {
    // The driver's other runtime errors come from the results file (created, written).
    if (target) throw ApiError(MBDAE_ERROR_IO, "results file " + results + ": " + e.what());
    throw;
  }
  if (abandoned) {
    handle->result.final_run.results_path.clear();  // the temporary file goes with target
  } else if (target && !handle->result.final_run.results_path.empty()) {
    target->Commit();
    handle->result.final_run.results_path = results;
  }
  *out = handle.release();
}

const mbdae_optimization& Result(const mbdae_optimization* r) {
  if (!r) throw ApiError(MBDAE_ERROR_ARGUMENT, "result is NULL");
  return *r;
}

void Report(const mbdae_optimization& r, bool json, char* buf, size_t size, size_t* length) {
  const std::string text = json ? r.result.Json() : r.result.Report();
  const size_t needed = text.size() + 1;
  if (!buf) {
    if (size != 0) throw ApiError(MBDAE_ERROR_ARGUMENT, "buf is NULL but size is " + std::to_string(size));
    if (!length) throw ApiError(MBDAE_ERROR_ARGUMENT, "buf and length are both NULL");
    *length = needed;
    return;
  }
  if (size < needed)
    throw ApiError(MBDAE_ERROR_SIZE, "optimization report: the buffer has " + std::to_string(size) +
                                         " bytes, expected at least " + std::to_string(needed));
  std::memcpy(buf, text.c_str(), needed);
  if (length) *length = needed;
}

void History(const mbdae_optimization& r, double* out, int n, int* rows) {
  const auto& h = r.result.history;
  const int count = static_cast<int>(h.size());
  if (!out) {
    if (n != 0) throw ApiError(MBDAE_ERROR_ARGUMENT, "out is NULL but n is " + std::to_string(n));
    if (!rows) throw ApiError(MBDAE_ERROR_ARGUMENT, "out and rows are both NULL");
    *rows = count;
    return;
  }
  const long expected = static_cast<long>(count) * MBDAE_OPTIMIZATION_HISTORY_COLUMNS;
  if (n != expected)
    throw ApiError(MBDAE_ERROR_SIZE, "optimization history: the array has " + std::to_string(n) +
                                         " values, expected " + std::to_string(expected) + " (" +
                                         std::to_string(count) + " rows x " +
                                         std::to_string(MBDAE_OPTIMIZATION_HISTORY_COLUMNS) + ")");
  for (int i = 0; i < count; ++i) {
    const driver::OptimizationIteration& it = h[i];
    const double row[MBDAE_OPTIMIZATION_HISTORY_COLUMNS] = {
        static_cast<double>(it.iteration), it.objective, it.constraint_violation,
        it.dual_infeasibility, it.mu, it.step, static_cast<double>(it.line_search_trials),
        static_cast<double>(it.gradient_evaluations)};
    std::memcpy(out + static_cast<size_t>(i) * MBDAE_OPTIMIZATION_HISTORY_COLUMNS, row, sizeof row);
  }
  if (rows) *rows = count;
}

}  // namespace
}  // namespace mbdae::api

extern "C" {

mbdae_status mbdae_optimize(const char* problem_path, const char* results_path,
                            mbdae_progress_callback progress, void* user_data,
                            mbdae_optimization** result) {
  return mbdae::api::CallApi([&] {
    mbdae::api::Optimize(problem_path, nullptr, nullptr, results_path, progress, user_data, result);
  });
}

mbdae_status mbdae_optimize_string(const char* text, const char* name, const char* results_path,
                                   mbdae_progress_callback progress, void* user_data,
                                   mbdae_optimization** result) {
  return mbdae::api::CallApi([&] {
    if (!text) throw mbdae::api::ApiError(MBDAE_ERROR_ARGUMENT, "text is NULL");
    mbdae::api::Optimize(nullptr, text, name, results_path, progress, user_data, result);
  });
}

void mbdae_optimization_free(mbdae_optimization* result) { delete result; }

mbdae_status mbdae_optimization_report(const mbdae_optimization* result, int json, char* buf,
                                       size_t size, size_t* length) {
  return mbdae::api::CallApi(
      [&] { mbdae::api::Report(mbdae::api::Result(result), json != 0, buf, size, length); });
}

mbdae_status mbdae_optimization_history(const mbdae_optimization* result, double* out, int n,
                                        int* rows) {
  return mbdae::api::CallApi(
      [&] { mbdae::api::History(mbdae::api::Result(result), out, n, rows); });
}

}  // extern "C"
