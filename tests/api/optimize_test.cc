// Optimal control through the C API (api/mbdae.h: mbdae_optimize, mbdae_optimize_string,
// mbdae_optimization_report, mbdae_optimization_history), through the shared library and
// the C header only.
//
// The rotor of tests/optimize/rotor.yaml (inertia J = 0.5, torque a natural cubic spline
// of 21 ordinates) turned rest-to-rest by theta_f = 1 rad in T = 1 s with minimum
// integral tau^2: the optimum is 12 J^2 theta_f^2 / T^3 (tests/optimize/rotor_problem.yaml;
// `mbdae optimize` reaches it to 4.5e-6 relative with the HHT step 1e-3). Also the
// problem file's `start:` and `parameters:` (J fixed to 1: optimum 12), the progress
// callback (once per iteration; stopping), and bad input.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "mbdae.h"

namespace {

const std::string kDir = MBDAE_OPTIMIZE_DIR;  // tests/optimize
const std::string kProblem = kDir + "/rotor_problem.yaml";
constexpr double kJ = 0.5, kThetaF = 1.0, kT = 1.0;
const double kOptimum = 12 * kJ * kJ * kThetaF * kThetaF / (kT * kT * kT);  // 3

#define ASSERT_MBDAE_OK(expr) ASSERT_EQ((expr), MBDAE_OK) << mbdae_last_error()

// Owns a result.
struct Result {
  mbdae_optimization* r = nullptr;
  ~Result() { mbdae_optimization_free(r); }
};

std::string Report(const mbdae_optimization* r, int json) {
  size_t length = 0;
  EXPECT_EQ(mbdae_optimization_report(r, json, nullptr, 0, &length), MBDAE_OK) << mbdae_last_error();
  std::string text(length, '\0');
  EXPECT_EQ(mbdae_optimization_report(r, json, &text[0], length, nullptr), MBDAE_OK) << mbdae_last_error();
  text.resize(std::strlen(text.c_str()));
  return text;
}

// The number after "KEY": in a flat part of the JSON report (the first occurrence).
double JsonNumber(const std::string& json, const std::string& key) {
  const std::string needle = "\"" + key + "\": ";
  const size_t at = json.find(needle);
  if (at == std::string::npos) {
    ADD_FAILURE() << "no " << key << " in " << json;
    return NAN;
  }
  return std::strtod(json.c_str() + at + needle.size(), nullptr);
}

std::string JsonString(const std::string& json, const std::string& key) {
  const std::string needle = "\"" + key + "\": \"";
  const size_t at = json.find(needle);
  if (at == std::string::npos) return "";
  const size_t from = at + needle.size();
  return json.substr(from, json.find('"', from) - from);
}

std::vector<double> History(const mbdae_optimization* r, int* rows) {
  EXPECT_EQ(mbdae_optimization_history(r, nullptr, 0, rows), MBDAE_OK) << mbdae_last_error();
  std::vector<double> h(static_cast<size_t>(*rows) * MBDAE_OPTIMIZATION_HISTORY_COLUMNS);
  EXPECT_EQ(mbdae_optimization_history(r, h.data(), static_cast<int>(h.size()), nullptr), MBDAE_OK)
      << mbdae_last_error();
  return h;
}

std::string ReadFile(const std::string& path) {
  std::ifstream in(path);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

std::string Replace(std::string text, const std::string& from, const std::string& to) {
  const size_t at = text.find(from);
  EXPECT_NE(at, std::string::npos) << from;
  if (at != std::string::npos) text.replace(at, from.size(), to);
  return text;
}

struct Progress {
  std::vector<int> iterations;
  std::vector<double> objectives, violations;
  int stop_at = -1;
};

int OnIteration(int iteration, double objective, double violation, void* user_data) {
  auto* p = static_cast<Progress*>(user_data);
  p->iterations.push_back(iteration);
  p->objectives.push_back(objective);
  p->violations.push_back(violation);
  return iteration == p->stop_at ? 1 : 0;
}

TEST(ApiOptimize, RotorReachesTheKnownOptimumWithOneCallbackPerIteration) {
  const std::string results = ::testing::TempDir() + "api_optimize_rotor.h5";
  std::remove(results.c_str());
  Progress progress;
  Result r;
  ASSERT_MBDAE_OK(mbdae_optimize(kProblem.c_str(), results.c_str(), OnIteration, &progress, &r.r));
  ASSERT_NE(r.r, nullptr);
  const std::string json = Report(r.r, 1);
  EXPECT_EQ(JsonString(json, "status"), "solved") << json;
  EXPECT_EQ(JsonString(json, "ipopt_status"), "Solve_Succeeded") << json;
  // 12 J^2 theta_f^2 / T^3 = 3 (measured 3.0000136: 4.5e-6 relative, the O(h^2) of HHT
  // and the trapezoidal quadrature at the step 1e-3)
  const double objective = JsonNumber(json, "objective");
  EXPECT_LT(std::fabs(objective - kOptimum) / kOptimum, 1e-4) << objective;
  EXPECT_LT(JsonNumber(json, "constraint_violation"), 1e-9);
  EXPECT_NEAR(JsonNumber(json, "final_angle"), kThetaF, 1e-9);
  EXPECT_NEAR(JsonNumber(json, "final_speed"), 0.0, 1e-9);
  // tau linear: 6 J theta_f / T^2 (1 - 2 t / T) at the knots t = 0 and t = T (the
  // CLI test's bound on the knots, measured max deviation 1.8e-4)
  EXPECT_NEAR(JsonNumber(json, "tau[0]"), 6 * kJ * kThetaF / (kT * kT), 1e-3);
  EXPECT_NEAR(JsonNumber(json, "tau[20]"), -6 * kJ * kThetaF / (kT * kT), 1e-3);
  const int iterations = static_cast<int>(JsonNumber(json, "iterations"));
  EXPECT_GT(iterations, 3);
  EXPECT_LT(iterations, 40);

  // One callback per iteration, iteration 0 the start (zero torque: objective 0, not
  // turned: violation theta_f), in order; the same numbers as the history.
  int rows = 0;
  const std::vector<double> h = History(r.r, &rows);
  ASSERT_EQ(rows, iterations + 1);
  ASSERT_EQ(static_cast<int>(progress.iterations.size()), rows);
  const int c = MBDAE_OPTIMIZATION_HISTORY_COLUMNS;
  for (int i = 0; i < rows; ++i) {
    EXPECT_EQ(progress.iterations[i], i);
    EXPECT_EQ(h[i * c + 0], i);
    EXPECT_EQ(h[i * c + 1], progress.objectives[i]);
    EXPECT_EQ(h[i * c + 2], progress.violations[i]);
  }
  EXPECT_EQ(h[1], 0.0);
  EXPECT_NEAR(h[2], kThetaF, 1e-12);
  EXPECT_NEAR(h[(rows - 1) * c + 1], objective, 1e-9 * kOptimum);
  EXPECT_GE(h[(rows - 1) * c + 7], rows - 1);  // at least one evaluation an iteration
  EXPECT_LE(h[(rows - 1) * c + 7], JsonNumber(json, "gradient_evaluations"));

  // The text report and the results file.
  const std::string text = Report(r.r, 0);
  EXPECT_NE(text.find("status: solved"), std::string::npos) << text;
  EXPECT_NE(text.find("objective energy = 3.0000"), std::string::npos) << text;
  EXPECT_TRUE(std::ifstream(results).good());
}

TEST(ApiOptimize, StartAndFixedParametersFromAProblemString) {
  // J fixed to 1 by `parameters:` (optimum 12 J^2 = 12), every ordinate starting at 1:
  // constant torque 1 (the natural cubic through equal values), so the start has the
  // objective integral 1^2 = 1, angle(1) = 1 / (2 J) = 0.5 and speed(1) = 1 / J = 1
  // (HHT exact for a constant acceleration): violation max(|0.5 - 1|, |1 - 0|) = 1.
  std::string text = ReadFile(kProblem);
  text = Replace(text, "{spline: tau, lower: -40, upper: 40}", "{spline: tau, lower: -40, upper: 40, start: 1}");
  text = Replace(text, "model: rotor.yaml", "model: rotor.yaml\nparameters: {J: 1.0}");
  const std::string name = kDir + "/inline_problem.yaml";  // only names the folder
  Progress progress;
  Result r;
  ASSERT_MBDAE_OK(mbdae_optimize_string(text.c_str(), name.c_str(), nullptr, OnIteration, &progress, &r.r));
  const std::string json = Report(r.r, 1);
  EXPECT_EQ(JsonString(json, "status"), "solved") << json;
  const double objective = JsonNumber(json, "objective");
  EXPECT_LT(std::fabs(objective - 12.0) / 12.0, 1e-4) << objective;
  EXPECT_NEAR(JsonNumber(json, "tau[0]"), 6.0, 4e-3);  // 6 J theta_f / T^2
  ASSERT_GE(progress.objectives.size(), 2u);
  EXPECT_NEAR(progress.objectives[0], 1.0, 1e-12);
  EXPECT_NEAR(progress.violations[0], 1.0, 1e-8);  // measured 3.5e-10 off (Newton tolerance)

  // A list start, one value per ordinate: the optimum of J = 0.5 itself; Ipopt starts at
  // the optimum of the continuous problem (objective 3 to 1e-4) and stays there.
  std::string list = "[";
  for (int i = 0; i <= 20; ++i) list += (i ? ", " : "") + std::to_string(3.0 * (1 - 2 * i / 20.0));
  list += "]";
  std::string text2 = Replace(ReadFile(kProblem), "{spline: tau, lower: -40, upper: 40}",
                              "{spline: tau, lower: -40, upper: 40, start: " + list + "}");
  Progress progress2;
  Result r2;
  ASSERT_MBDAE_OK(mbdae_optimize_string(text2.c_str(), name.c_str(), nullptr, OnIteration, &progress2, &r2.r));
  const std::string json2 = Report(r2.r, 1);
  EXPECT_EQ(JsonString(json2, "status"), "solved") << json2;
  EXPECT_LT(std::fabs(progress2.objectives[0] - kOptimum) / kOptimum, 1e-4) << progress2.objectives[0];
  EXPECT_LT(std::fabs(JsonNumber(json2, "objective") - kOptimum) / kOptimum, 1e-4);
}

TEST(ApiOptimize, TheCallbackStopsTheOptimization) {
  Progress progress;
  progress.stop_at = 2;
  Result r;
  ASSERT_MBDAE_OK(mbdae_optimize(kProblem.c_str(), nullptr, OnIteration, &progress, &r.r));
  const std::string json = Report(r.r, 1);
  EXPECT_EQ(JsonString(json, "status"), "failed") << json;
  EXPECT_EQ(JsonString(json, "ipopt_status"), "User_Requested_Stop") << json;
  EXPECT_EQ(progress.iterations, (std::vector<int>{0, 1, 2}));
  int rows = 0;
  History(r.r, &rows);
  EXPECT_EQ(rows, 3);
}

// Each bad problem: the status, and the message naming the problem, line and what.
struct Bad {
  const char* from;
  const char* to;
  int line;
  const char* needle;
};

TEST(ApiOptimize, BadInputIsAnErrorNamingTheFileAndLine) {
  const std::string good = ReadFile(kProblem);
  const std::string name = kDir + "/bad_problem.yaml";
  const Bad cases[] = {
      {"upper: 40}", "upper: 40, start: 41}", 6, "start 41 is outside the bounds [-40, 40]"},
      {"upper: 40}", "upper: 40, start: [1, 2]}", 6, "start has 2 values, the variable 21 ordinates"},
      {"upper: 40}", "upper: 40, start: [0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 50, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0]}", 6,
       "start[10] 50 is outside the bounds"},
      {"model: rotor.yaml", "model: rotor.yaml\nparameters: {g: 2.0}", 5, "unknown parameter 'g'"},
      {"model: rotor.yaml", "model: rotor.yaml\nparameters: {J: many}", 5, "J must be a number"},
      {"{spline: tau, lower: -40, upper: 40}", "{spline: nope}", 6, "unknown spline 'nope'"},
  };
  for (const Bad& b : cases) {
    const std::string text = Replace(good, b.from, b.to);
    mbdae_optimization* r = nullptr;
    EXPECT_EQ(mbdae_optimize_string(text.c_str(), name.c_str(), nullptr, nullptr, nullptr, &r), MBDAE_ERROR_INPUT)
        << b.to;
    EXPECT_EQ(r, nullptr);
    const std::string message = mbdae_last_error();
    EXPECT_EQ(message.rfind(name + ":" + std::to_string(b.line) + ":", 0), 0u) << message;
    EXPECT_NE(message.find(b.needle), std::string::npos) << message;
  }
  // A parameter both fixed and a variable.
  {
    const std::string text = Replace(Replace(good, "model: rotor.yaml", "model: rotor.yaml\nparameters: {J: 1}"),
                                     "  - {spline: tau, lower: -40, upper: 40}",
                                     "  - {spline: tau, lower: -40, upper: 40}\n  - {parameter: J, lower: 0.1}");
    mbdae_optimization* r = nullptr;
    EXPECT_EQ(mbdae_optimize_string(text.c_str(), name.c_str(), nullptr, nullptr, nullptr, &r), MBDAE_ERROR_INPUT);
    EXPECT_NE(std::string(mbdae_last_error()).find(":8:"), std::string::npos) << mbdae_last_error();
    EXPECT_NE(std::string(mbdae_last_error()).find("is fixed in `parameters:` (line 5)"), std::string::npos)
        << mbdae_last_error();
  }
  // Files, paths, pointers.
  mbdae_optimization* r = nullptr;
  EXPECT_EQ(mbdae_optimize((kDir + "/no_such_problem.yaml").c_str(), nullptr, nullptr, nullptr, &r), MBDAE_ERROR_IO);
  EXPECT_NE(std::string(mbdae_last_error()).find("no_such_problem.yaml"), std::string::npos);
  EXPECT_EQ(mbdae_optimize(kProblem.c_str(), (kDir + "/no_such_folder/r.h5").c_str(), nullptr, nullptr, &r),
            MBDAE_ERROR_IO);
  EXPECT_NE(std::string(mbdae_last_error()).find("No such file or directory"), std::string::npos) << mbdae_last_error();
  EXPECT_EQ(mbdae_optimize(nullptr, nullptr, nullptr, nullptr, &r), MBDAE_ERROR_ARGUMENT);
  EXPECT_EQ(mbdae_optimize(kProblem.c_str(), nullptr, nullptr, nullptr, nullptr), MBDAE_ERROR_ARGUMENT);
  EXPECT_EQ(mbdae_optimize_string(nullptr, "", nullptr, nullptr, nullptr, &r), MBDAE_ERROR_ARGUMENT);
  EXPECT_EQ(mbdae_optimize_string("model: [", "", nullptr, nullptr, nullptr, &r), MBDAE_ERROR_INPUT);
  EXPECT_EQ(std::string(mbdae_last_error()).rfind("<string>:1:", 0), 0u) << mbdae_last_error();
  EXPECT_EQ(r, nullptr);
  size_t length = 0;
  EXPECT_EQ(mbdae_optimization_report(nullptr, 1, nullptr, 0, &length), MBDAE_ERROR_ARGUMENT);
  mbdae_optimization_free(nullptr);
}

TEST(ApiOptimize, ReportAndHistoryBuffers) {
  std::string text = Replace(ReadFile(kProblem), "max_iter: 100", "max_iter: 1");
  Result r;
  ASSERT_MBDAE_OK(mbdae_optimize_string(text.c_str(), (kDir + "/p.yaml").c_str(), nullptr, nullptr, nullptr, &r.r));
  EXPECT_EQ(JsonString(Report(r.r, 1), "ipopt_status"), "Maximum_Iterations_Exceeded");
  size_t length = 0;
  ASSERT_MBDAE_OK(mbdae_optimization_report(r.r, 1, nullptr, 0, &length));
  std::vector<char> small(length - 1);
  EXPECT_EQ(mbdae_optimization_report(r.r, 1, small.data(), small.size(), nullptr), MBDAE_ERROR_SIZE);
  EXPECT_EQ(mbdae_optimization_report(r.r, 1, nullptr, 5, &length), MBDAE_ERROR_ARGUMENT);
  int rows = 0;
  ASSERT_MBDAE_OK(mbdae_optimization_history(r.r, nullptr, 0, &rows));
  EXPECT_EQ(rows, 2);
  std::vector<double> h(rows * MBDAE_OPTIMIZATION_HISTORY_COLUMNS - 1);
  EXPECT_EQ(mbdae_optimization_history(r.r, h.data(), static_cast<int>(h.size()), nullptr), MBDAE_ERROR_SIZE);
  EXPECT_NE(std::string(mbdae_last_error()).find("2 rows x 8"), std::string::npos) << mbdae_last_error();
}

}  // namespace
