// The C API (api/mbdae.h) through the shared library and the C header only: errors,
// names, parameters and splines, options, state get/set and restarts.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <fstream>
#include <string>
#include <vector>

#include "mbdae.h"

namespace {

const std::string kModels = MBDAE_API_TEST_MODELS;
const std::string kPendulum = MBDAE_PENDULUM;

#define ASSERT_MBDAE_OK(expr) ASSERT_EQ((expr), MBDAE_OK) << mbdae_last_error()
#define EXPECT_MBDAE_OK(expr) EXPECT_EQ((expr), MBDAE_OK) << mbdae_last_error()

// A handle freed at the end of the scope.
class Model {
 public:
  explicit Model(const std::string& path) {
    const mbdae_status s = mbdae_model_from_file(path.c_str(), &m_);
    EXPECT_EQ(s, MBDAE_OK) << mbdae_last_error();
  }
  ~Model() { mbdae_model_free(m_); }
  Model(const Model&) = delete;
  Model& operator=(const Model&) = delete;
  operator mbdae_model*() const { return m_; }
  mbdae_model* get() const { return m_; }

 private:
  mbdae_model* m_ = nullptr;
};

int Count(mbdae_model* m, mbdae_kind kind) {
  int n = -1;
  EXPECT_EQ(mbdae_count(m, kind, &n), MBDAE_OK) << mbdae_last_error();
  return n;
}

int Find(mbdae_model* m, mbdae_kind kind, const char* name) {
  int index = -1;
  EXPECT_EQ(mbdae_find(m, kind, name, &index), MBDAE_OK) << mbdae_last_error();
  return index;
}

// Measure `name` over the stored rows (time, value).
std::vector<std::pair<double, double>> MeasureHistory(mbdae_model* m, const char* name) {
  const int k = Find(m, MBDAE_MEASURES, name);
  const int nm = Count(m, MBDAE_MEASURES);
  std::vector<std::pair<double, double>> out;
  std::vector<double> values(nm);
  for (int r = 0; r < Count(m, MBDAE_OUTPUTS); ++r) {
    double t = 0;
    EXPECT_EQ(mbdae_get_output(m, r, MBDAE_OUT_TIME, &t, 1), MBDAE_OK);
    EXPECT_EQ(mbdae_get_output(m, r, MBDAE_OUT_MEASURES, values.data(), nm), MBDAE_OK);
    out.emplace_back(t, values[k]);
  }
  return out;
}

// Times where the value crosses zero downwards or upwards (linear interpolation).
std::vector<double> ZeroCrossings(const std::vector<std::pair<double, double>>& h) {
  std::vector<double> out;
  for (size_t i = 1; i < h.size(); ++i) {
    const double a = h[i - 1].second, b = h[i].second;
    if ((a > 0 && b <= 0) || (a < 0 && b >= 0))
      out.push_back(h[i - 1].first + (h[i].first - h[i - 1].first) * a / (a - b));
  }
  return out;
}

std::string TempPath(const std::string& name) {
  return ::testing::TempDir() + "mbdae_api_test_" + name;
}

// ---- Creating, names, counts ------------------------------------------------------------

TEST(ApiModel, CountsAndNamesOfThePendulum) {
  Model m(kPendulum);
  EXPECT_EQ(Count(m, MBDAE_COORDINATES), 7);
  EXPECT_EQ(Count(m, MBDAE_BODIES), 1);
  EXPECT_EQ(Count(m, MBDAE_JOINTS), 1);
  EXPECT_EQ(Count(m, MBDAE_FORCES), 0);
  EXPECT_EQ(Count(m, MBDAE_MEASURES), 3);
  EXPECT_EQ(Count(m, MBDAE_PARAMETERS), 2);
  EXPECT_EQ(Count(m, MBDAE_SPLINES), 0);
  EXPECT_EQ(Count(m, MBDAE_OUTPUTS), 0);  // nothing solved yet
  // Revolute: 5 equations, plus the Euler-parameter normalisation; none redundant.
  EXPECT_EQ(Count(m, MBDAE_MULTIPLIERS), 6);
  EXPECT_EQ(Count(m, MBDAE_REDUNDANT), 0);
  EXPECT_EQ(Count(m, MBDAE_OUTPUTS), 1);  // counting the multipliers assembled: row 0
  const char* name = nullptr;
  ASSERT_MBDAE_OK(mbdae_name(m, MBDAE_COORDINATES, 3, &name));
  EXPECT_STREQ(name, "bob.e0");
  ASSERT_MBDAE_OK(mbdae_name(m, MBDAE_MEASURES, 2, &name));
  EXPECT_STREQ(name, "angle");
  ASSERT_MBDAE_OK(mbdae_name(m, MBDAE_PARAMETERS, 0, &name));
  EXPECT_STREQ(name, "L");
  EXPECT_EQ(Find(m, MBDAE_COORDINATES, "bob.y"), 1);
  EXPECT_EQ(Find(m, MBDAE_JOINTS, "pivot"), 0);
  EXPECT_EQ(Find(m, MBDAE_PARAMETERS, "m"), 1);
  // Multiplier names: the joint's equations.
  ASSERT_MBDAE_OK(mbdae_name(m, MBDAE_MULTIPLIERS, 0, &name));
  EXPECT_EQ(std::string(name).rfind("pivot", 0), 0u) << name;
  EXPECT_STREQ(mbdae_last_error(), "");
  EXPECT_EQ(mbdae_api_version(), MBDAE_API_VERSION);
  EXPECT_STREQ(mbdae_version(), "0.1.0");
}

TEST(ApiModel, RedundantEquationsOfTheSliderCrank) {
  Model m(kModels + "/slider_crank.yaml");
  // 3 bodies: 21 coordinates; 3 revolute (5 each) + prismatic (5) + 3 normalisations = 23
  // equations, 3 of them redundant.
  EXPECT_EQ(Count(m, MBDAE_COORDINATES), 21);
  EXPECT_EQ(Count(m, MBDAE_REDUNDANT), 3);
  EXPECT_EQ(Count(m, MBDAE_MULTIPLIERS), 20);
  const char* name = nullptr;
  ASSERT_MBDAE_OK(mbdae_name(m, MBDAE_FORCES, 1, &name));
  EXPECT_STREQ(name, "spring");
}

TEST(ApiModel, FromStringAndFreeDynFile) {
  std::ifstream in(kPendulum);
  std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  mbdae_model* m = nullptr;
  ASSERT_MBDAE_OK(mbdae_model_from_string(text.c_str(), "pendulum.yaml", &m));
  EXPECT_EQ(Count(m, MBDAE_BODIES), 1);
  mbdae_model_free(m);

  Model fds(MBDAE_FREEDYN_OSCILLATOR);
  EXPECT_GT(Count(fds, MBDAE_BODIES), 0);
  ASSERT_MBDAE_OK(mbdae_solve(fds));
  EXPECT_GT(Count(fds, MBDAE_OUTPUTS), 10);
}

// ---- Errors -------------------------------------------------------------------------------

TEST(ApiErrors, MissingFileIsAnIoErrorNamingThePath) {
  mbdae_model* m = reinterpret_cast<mbdae_model*>(0x1);
  EXPECT_EQ(mbdae_model_from_file("/nonexistent/model.yaml", &m), MBDAE_ERROR_IO);
  EXPECT_NE(std::string(mbdae_last_error()).find("/nonexistent/model.yaml"), std::string::npos)
      << mbdae_last_error();
  EXPECT_EQ(m, reinterpret_cast<mbdae_model*>(0x1));  // output untouched
  const std::string dir = ::testing::TempDir();
  EXPECT_EQ(mbdae_model_from_file(dir.c_str(), &m), MBDAE_ERROR_IO);
  EXPECT_EQ(std::string(mbdae_last_error()), dir + ": cannot read the file: it is a directory");
}

TEST(ApiErrors, BadModelNamesFileAndLine) {
  const std::string path = TempPath("bad_mass.yaml");
  {
    std::ofstream out(path);
    out << "format: 1\n"
           "name: bad\n"
           "bodies:\n"
           "  - name: link\n"
           "    mass: -1\n"
           "    inertia: [1, 1, 1]\n";
  }
  mbdae_model* m = nullptr;
  EXPECT_EQ(mbdae_model_from_file(path.c_str(), &m), MBDAE_ERROR_INPUT);
  const std::string msg = mbdae_last_error();
  EXPECT_EQ(msg.rfind(path + ":5:", 0), 0u) << msg;  // FILE:LINE:COL, line 5
  EXPECT_NE(msg.find("body 'link'"), std::string::npos) << msg;
  EXPECT_NE(msg.find("mass"), std::string::npos) << msg;
  EXPECT_EQ(m, nullptr);

  // The same from a string: the name given is the file of the message.
  std::ifstream in(path);
  std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  EXPECT_EQ(mbdae_model_from_string(text.c_str(), "inline.yaml", &m), MBDAE_ERROR_INPUT);
  EXPECT_EQ(std::string(mbdae_last_error()).rfind("inline.yaml:5:", 0), 0u) << mbdae_last_error();
  std::remove(path.c_str());
}

TEST(ApiErrors, UnknownNamesAndIndices) {
  Model m(kPendulum);
  int index = 42;
  EXPECT_EQ(mbdae_find(m, MBDAE_BODIES, "wheel", &index), MBDAE_ERROR_ARGUMENT);
  EXPECT_STREQ(mbdae_last_error(), "there is no body called 'wheel'");
  EXPECT_EQ(index, 42);
  const char* name = nullptr;
  EXPECT_EQ(mbdae_name(m, MBDAE_JOINTS, 1, &name), MBDAE_ERROR_ARGUMENT);
  EXPECT_STREQ(mbdae_last_error(), "joint index 1 is out of range: there are 1");
  EXPECT_EQ(mbdae_name(m, MBDAE_OUTPUTS, 0, &name), MBDAE_ERROR_ARGUMENT);
  EXPECT_EQ(mbdae_count(m, static_cast<mbdae_kind>(17), &index), MBDAE_ERROR_ARGUMENT);
  EXPECT_STREQ(mbdae_last_error(), "unknown kind 17");
  double v = 0;
  EXPECT_EQ(mbdae_get_parameter(m, 2, &v), MBDAE_ERROR_ARGUMENT);
  EXPECT_STREQ(mbdae_last_error(), "parameter index 2 is out of range: there are 2");
  EXPECT_EQ(mbdae_set_option(m, "hht.beta", "0.3"), MBDAE_ERROR_ARGUMENT);
  EXPECT_EQ(std::string(mbdae_last_error()).rfind("unknown option 'hht.beta'; the options are", 0),
            0u) << mbdae_last_error();
  int n = 0;
  EXPECT_EQ(mbdae_spline_size(m, 0, &n), MBDAE_ERROR_ARGUMENT);
  EXPECT_STREQ(mbdae_last_error(), "spline index 0 is out of range: there are 0");
  // A successful call clears the message.
  EXPECT_MBDAE_OK(mbdae_count(m, MBDAE_BODIES, &n));
  EXPECT_STREQ(mbdae_last_error(), "");
}

TEST(ApiErrors, WrongSizesSayTheExpectedLength) {
  Model m(kPendulum);
  ASSERT_MBDAE_OK(mbdae_assemble(m));
  std::vector<double> q(8, -5.0), lambda(6);
  EXPECT_EQ(mbdae_get_state(m, nullptr, q.data(), nullptr, nullptr, nullptr, 8, 6),
            MBDAE_ERROR_SIZE);
  EXPECT_STREQ(mbdae_last_error(), "nq (coordinates): the array has 8 values, expected 7");
  EXPECT_EQ(q[0], -5.0);  // untouched
  EXPECT_EQ(mbdae_get_state(m, nullptr, q.data(), nullptr, nullptr, lambda.data(), 7, 5),
            MBDAE_ERROR_SIZE);
  EXPECT_STREQ(mbdae_last_error(), "nm (multipliers): the array has 5 values, expected 6");
  EXPECT_EQ(q[0], -5.0);
  EXPECT_EQ(mbdae_get_output(m, 0, MBDAE_OUT_MEASURES, q.data(), 2), MBDAE_ERROR_SIZE);
  EXPECT_STREQ(mbdae_last_error(), "measures: the array has 2 values, expected 3");
  EXPECT_EQ(mbdae_get_output(m, 0, MBDAE_OUT_BODY_POSES, q.data(), 7), MBDAE_ERROR_SIZE);
  EXPECT_STREQ(mbdae_last_error(), "body poses: the array has 7 values, expected 12");
  EXPECT_EQ(mbdae_set_state(m, 0.0, q.data(), q.data(), nullptr, nullptr, 8, 6),
            MBDAE_ERROR_SIZE);
  char small[3];
  EXPECT_EQ(mbdae_get_option(m, "integrator", small, sizeof small), MBDAE_ERROR_SIZE);
  EXPECT_STREQ(mbdae_last_error(),
               "option integrator: the buffer has 3 bytes, expected at least 4");
  char enough[4];
  ASSERT_MBDAE_OK(mbdae_get_option(m, "integrator", enough, sizeof enough));
  EXPECT_STREQ(enough, "ida");
}

TEST(ApiErrors, CallsOutOfOrder) {
  Model m(kPendulum);
  double t = -1;
  EXPECT_EQ(mbdae_get_output(m, 0, MBDAE_OUT_TIME, &t, 1), MBDAE_ERROR_ORDER);
  EXPECT_STREQ(mbdae_last_error(),
               "there are no stored rows: call mbdae_assemble or mbdae_solve first");
  EXPECT_EQ(t, -1);
  const std::string path = TempPath("order.h5");
  EXPECT_EQ(mbdae_write_results(m, path.c_str()), MBDAE_ERROR_ORDER);
  ASSERT_MBDAE_OK(mbdae_solve_to(m, 0.5));
  // Backwards in time, or not moving, is an argument error.
  EXPECT_EQ(mbdae_solve_to(m, 0.5), MBDAE_ERROR_ARGUMENT);
  EXPECT_STREQ(mbdae_last_error(), "t = 0.5 must be after the current time 0.5");
  EXPECT_EQ(mbdae_solve_to(m, 0.25), MBDAE_ERROR_ARGUMENT);
  EXPECT_EQ(mbdae_get_output(m, 501, MBDAE_OUT_TIME, &t, 1), MBDAE_ERROR_ARGUMENT);
  EXPECT_STREQ(mbdae_last_error(), "output row index 501 is out of range: there are 501");
}

TEST(ApiErrors, NullHandlesAndPointers) {
  int n = 0;
  EXPECT_EQ(mbdae_count(nullptr, MBDAE_BODIES, &n), MBDAE_ERROR_ARGUMENT);
  EXPECT_STREQ(mbdae_last_error(), "model is NULL");
  EXPECT_EQ(mbdae_solve(nullptr), MBDAE_ERROR_ARGUMENT);
  EXPECT_EQ(mbdae_model_from_file(nullptr, nullptr), MBDAE_ERROR_ARGUMENT);
  EXPECT_STREQ(mbdae_last_error(), "path is NULL");
  mbdae_model_free(nullptr);  // allowed
  Model m(kPendulum);
  EXPECT_EQ(mbdae_count(m, MBDAE_BODIES, nullptr), MBDAE_ERROR_ARGUMENT);
  EXPECT_STREQ(mbdae_last_error(), "count is NULL");
  EXPECT_EQ(mbdae_find(m, MBDAE_BODIES, nullptr, &n), MBDAE_ERROR_ARGUMENT);
  EXPECT_STREQ(mbdae_last_error(), "name is NULL");
  EXPECT_EQ(mbdae_set_option(m, "t_end", nullptr), MBDAE_ERROR_ARGUMENT);
  EXPECT_STREQ(mbdae_last_error(), "value is NULL");
  EXPECT_EQ(mbdae_set_state(m, 0, nullptr, nullptr, nullptr, nullptr, 7, 6), MBDAE_ERROR_ARGUMENT);
  EXPECT_STREQ(mbdae_last_error(), "q is NULL");
  EXPECT_EQ(mbdae_write_results(m, nullptr), MBDAE_ERROR_ARGUMENT);
  EXPECT_STREQ(mbdae_last_error(), "path is NULL");
}

TEST(ApiErrors, BadOptionValuesAreInputErrorsAndChangeNothing) {
  Model m(kPendulum);
  char buf[64];
  EXPECT_EQ(mbdae_set_option(m, "t_end", "-1"), MBDAE_ERROR_INPUT);
  EXPECT_STREQ(mbdae_last_error(),
               "option t_end = -1: simulation setting t_end must be > 0, got -1");
  EXPECT_EQ(mbdae_set_option(m, "output_step", "0.01s"), MBDAE_ERROR_INPUT);
  EXPECT_STREQ(mbdae_last_error(), "option output_step: expected a number, got '0.01s'");
  EXPECT_EQ(mbdae_set_option(m, "integrator", "euler"), MBDAE_ERROR_INPUT);
  EXPECT_STREQ(mbdae_last_error(),
               "option integrator: expected hht, ida, kinematic or erk, got 'euler'");
  EXPECT_EQ(mbdae_set_option(m, "hht.adaptive", "yes"), MBDAE_ERROR_INPUT);
  EXPECT_STREQ(mbdae_last_error(), "option hht.adaptive: expected true or false, got 'yes'");
  EXPECT_EQ(mbdae_set_option(m, "hht.alpha", "-0.5"), MBDAE_ERROR_INPUT);
  EXPECT_NE(std::string(mbdae_last_error()).find("alpha"), std::string::npos);
  EXPECT_EQ(mbdae_set_option(m, "hht.form", "classic"), MBDAE_ERROR_INPUT);
  ASSERT_MBDAE_OK(mbdae_get_option(m, "t_end", buf, sizeof buf));
  EXPECT_STREQ(buf, "2");
  ASSERT_MBDAE_OK(mbdae_get_option(m, "hht.alpha", buf, sizeof buf));
  EXPECT_STREQ(buf, "-0.10000000000000001");
  // Good values are read back.
  ASSERT_MBDAE_OK(mbdae_set_option(m, "hht.adaptive", "true"));
  ASSERT_MBDAE_OK(mbdae_get_option(m, "hht.adaptive", buf, sizeof buf));
  EXPECT_STREQ(buf, "true");
  ASSERT_MBDAE_OK(mbdae_set_option(m, "hht.form", "negrut"));
  ASSERT_MBDAE_OK(mbdae_get_option(m, "hht.form", buf, sizeof buf));
  EXPECT_STREQ(buf, "negrut");
  ASSERT_MBDAE_OK(mbdae_get_option(m, "hht.dense_output", buf, sizeof buf));
  EXPECT_STREQ(buf, "false");
  EXPECT_EQ(mbdae_set_option(m, "hht.dense_output", "1"), MBDAE_ERROR_INPUT);
  EXPECT_STREQ(mbdae_last_error(), "option hht.dense_output: expected true or false, got '1'");
  ASSERT_MBDAE_OK(mbdae_set_option(m, "hht.dense_output", "true"));
  ASSERT_MBDAE_OK(mbdae_get_option(m, "hht.dense_output", buf, sizeof buf));
  EXPECT_STREQ(buf, "true");
  ASSERT_MBDAE_OK(mbdae_get_option(m, "hht.newton_tolerance", buf, sizeof buf));
  EXPECT_STREQ(buf, "9.9999999999999998e-13");
  ASSERT_MBDAE_OK(mbdae_set_option(m, "hht.newton_tolerance", "1e-10"));
  ASSERT_MBDAE_OK(mbdae_get_option(m, "hht.newton_tolerance", buf, sizeof buf));
  EXPECT_STREQ(buf, "1e-10");
  EXPECT_EQ(mbdae_set_option(m, "hht.newton_tolerance", "1"), MBDAE_ERROR_INPUT);
  EXPECT_STREQ(mbdae_last_error(),
               "option hht.newton_tolerance = 1: hht settings: HhtOptions: newton_tolerance must be in (0, 1)");
  ASSERT_MBDAE_OK(mbdae_get_option(m, "hht.newton_tolerance", buf, sizeof buf));
  EXPECT_STREQ(buf, "1e-10");
  ASSERT_MBDAE_OK(mbdae_get_option(m, "ida.dense_output", buf, sizeof buf));
  EXPECT_STREQ(buf, "false");
  ASSERT_MBDAE_OK(mbdae_set_option(m, "ida.dense_output", "true"));
  ASSERT_MBDAE_OK(mbdae_get_option(m, "ida.dense_output", buf, sizeof buf));
  EXPECT_STREQ(buf, "true");
  ASSERT_MBDAE_OK(mbdae_set_option(m, "ida.rtol", "1e-6"));
  ASSERT_MBDAE_OK(mbdae_get_option(m, "ida.rtol", buf, sizeof buf));
  EXPECT_EQ(std::atof(buf), 1e-6);
  // IDA's step budget and smallest step (the file's ida: {max_steps, min_step}).
  auto option = [&](const char* key) {
    EXPECT_EQ(mbdae_get_option(m, key, buf, sizeof buf), MBDAE_OK) << key;
    return std::string(buf);
  };
  EXPECT_EQ(option("ida.max_steps"), "100000000");
  EXPECT_EQ(option("ida.min_step"), "0");
  ASSERT_MBDAE_OK(mbdae_set_option(m, "ida.max_steps", "5000"));
  ASSERT_MBDAE_OK(mbdae_set_option(m, "ida.min_step", "1e-12"));
  EXPECT_EQ(option("ida.max_steps"), "5000");
  EXPECT_EQ(std::atof(option("ida.min_step").c_str()), 1e-12);
  const std::pair<const char*, const char*> bad[] = {{"ida.max_steps", "0"}, {"ida.max_steps", "2.5"},
                                                      {"ida.min_step", "-1"}};
  for (const auto& [key, value] : bad) {
    EXPECT_EQ(mbdae_set_option(m, key, value), MBDAE_ERROR_INPUT) << key << " = " << value;
    EXPECT_NE(std::string(mbdae_last_error()).find(key), std::string::npos) << mbdae_last_error();
  }
  EXPECT_EQ(option("ida.max_steps"), "5000");  // the old value stays
  // The erk integrator's settings (the file's erk: {rtol, atol, max_steps, min_step,
  // max_step}).
  EXPECT_EQ(std::atof(option("erk.rtol").c_str()), 1e-8);
  EXPECT_EQ(option("erk.max_steps"), "100000000");
  ASSERT_MBDAE_OK(mbdae_set_option(m, "integrator", "erk"));
  EXPECT_EQ(option("integrator"), "erk");
  ASSERT_MBDAE_OK(mbdae_set_option(m, "erk.rtol", "1e-7"));
  ASSERT_MBDAE_OK(mbdae_set_option(m, "erk.max_step", "0.5"));
  EXPECT_EQ(std::atof(option("erk.rtol").c_str()), 1e-7);
  EXPECT_EQ(std::atof(option("erk.max_step").c_str()), 0.5);
  const std::pair<const char*, const char*> bad_erk[] = {
      {"erk.rtol", "0"}, {"erk.atol", "-1"}, {"erk.max_steps", "2.5"}, {"erk.min_step", "1"}};
  for (const auto& [key, value] : bad_erk) {
    EXPECT_EQ(mbdae_set_option(m, key, value), MBDAE_ERROR_INPUT) << key << " = " << value;
    EXPECT_NE(std::string(mbdae_last_error()).find(key), std::string::npos) << mbdae_last_error();
  }
}

TEST(ApiErrors, SolverFailureKeepsTheRowsSoFar) {
  Model m(kPendulum);
  ASSERT_MBDAE_OK(mbdae_set_option(m, "integrator", "hht"));
  ASSERT_MBDAE_OK(mbdae_set_option(m, "hht.adaptive", "true"));
  ASSERT_MBDAE_OK(mbdae_set_option(m, "hht.tolerance", "1e-30"));
  EXPECT_EQ(mbdae_solve(m), MBDAE_ERROR_SOLVER);
  const std::string msg = mbdae_last_error();
  EXPECT_EQ(msg.rfind("the integrator failed at t = ", 0), 0u) << msg;
  EXPECT_GE(Count(m, MBDAE_OUTPUTS), 1);  // at least the row at t = 0
  const std::string path = TempPath("failed.h5");
  EXPECT_MBDAE_OK(mbdae_write_results(m, path.c_str()));
  std::remove(path.c_str());
}

TEST(ApiErrors, UnwritableResultsFileIsAnIoError) {
  Model m(kPendulum);
  ASSERT_MBDAE_OK(mbdae_assemble(m));
  EXPECT_EQ(mbdae_write_results(m, "/nonexistent/dir/out.h5"), MBDAE_ERROR_IO);
  EXPECT_NE(std::string(mbdae_last_error()).find("/nonexistent/dir/out.h5"), std::string::npos)
      << mbdae_last_error();
}

// ---- Parameters and splines ---------------------------------------------------------------

// The pendulum released from the horizontal: x = 0 at T/4 and 3T/4, T = 4 sqrt(L/g)
// K(sin(pi/4)) = 2.36784 s for L = 1 (docs of examples/pendulum.yaml).
double HalfPeriod(mbdae_model* m) {
  EXPECT_EQ(mbdae_solve(m), MBDAE_OK) << mbdae_last_error();
  const auto crossings = ZeroCrossings(MeasureHistory(m, "x"));
  EXPECT_GE(crossings.size(), 2u);
  return crossings.size() >= 2 ? crossings[1] - crossings[0] : 0;
}

TEST(ApiParameters, PendulumLengthChangesThePeriod) {
  const double t_ref = 4 * std::sqrt(1.0 / 9.81) * 1.854074677301372;  // K(1/sqrt 2)
  Model m(kPendulum);
  ASSERT_MBDAE_OK(mbdae_set_option(m, "t_end", "4"));
  ASSERT_MBDAE_OK(mbdae_set_option(m, "output_step", "1e-3"));
  const double half1 = HalfPeriod(m);
  EXPECT_NEAR(2 * half1, t_ref, 1e-5);  // interpolated between 1 ms rows

  const int L = Find(m, MBDAE_PARAMETERS, "L");
  const int mass = Find(m, MBDAE_PARAMETERS, "m");
  ASSERT_MBDAE_OK(mbdae_set_parameter(m, mass, 3.0));
  ASSERT_MBDAE_OK(mbdae_set_parameter(m, L, 2.0));
  double value = 0;
  ASSERT_MBDAE_OK(mbdae_get_parameter(m, L, &value));
  EXPECT_EQ(value, 2.0);
  // The rebuild kept the other parameter and the options.
  ASSERT_MBDAE_OK(mbdae_get_parameter(m, mass, &value));
  EXPECT_EQ(value, 3.0);
  char buf[32];
  ASSERT_MBDAE_OK(mbdae_get_option(m, "t_end", buf, sizeof buf));
  EXPECT_STREQ(buf, "4");
  // Rows of the old run stay until the next solve, which starts again from t = 0.
  EXPECT_EQ(Count(m, MBDAE_OUTPUTS), 4001);
  const double half2 = HalfPeriod(m);
  EXPECT_EQ(Count(m, MBDAE_OUTPUTS), 4001);
  // The period scales with sqrt(L) (the mass does not matter).
  EXPECT_NEAR(2 * half2, std::sqrt(2.0) * t_ref, 1e-5);
  std::printf("pendulum period: L = 1: %.6f s, L = 2: %.6f s (closed form %.6f, %.6f)\n",
              2 * half1, 2 * half2, t_ref, std::sqrt(2.0) * t_ref);
  // The bob starts at x = L.
  std::vector<double> q(7);
  ASSERT_MBDAE_OK(mbdae_get_output(m, 0, MBDAE_OUT_Q, q.data(), 7));
  EXPECT_EQ(q[0], 2.0);
}

TEST(ApiParameters, InvalidValueKeepsTheOldModel) {
  Model m(kPendulum);
  ASSERT_MBDAE_OK(mbdae_solve_to(m, 0.1));
  const int mass = Find(m, MBDAE_PARAMETERS, "m");
  EXPECT_EQ(mbdae_set_parameter(m, mass, -1.0), MBDAE_ERROR_INPUT);
  const std::string msg = mbdae_last_error();
  EXPECT_EQ(msg.rfind("parameter 'm' = -1 makes the model invalid (the old value stays): ", 0), 0u)
      << msg;
  EXPECT_NE(msg.find("mass must be >= 0"), std::string::npos) << msg;
  double value = 0;
  ASSERT_MBDAE_OK(mbdae_get_parameter(m, mass, &value));
  EXPECT_EQ(value, 1.0);
  EXPECT_EQ(mbdae_set_parameter(m, mass, NAN), MBDAE_ERROR_INPUT);
  // The run was not disturbed: it goes on from t = 0.1.
  ASSERT_MBDAE_OK(mbdae_solve_to(m, 0.2));
  EXPECT_EQ(Count(m, MBDAE_OUTPUTS), 201);
}

TEST(ApiSplines, SplineForceChangesTheMotion) {
  Model m(kModels + "/spline_force.yaml");
  const int push = Find(m, MBDAE_SPLINES, "push");
  int n = 0;
  ASSERT_MBDAE_OK(mbdae_spline_size(m, push, &n));
  ASSERT_EQ(n, 2);
  std::vector<double> x(2), y(2);
  ASSERT_MBDAE_OK(mbdae_get_spline_points(m, push, x.data(), y.data(), 2));
  EXPECT_EQ(x, (std::vector<double>{0, 10}));
  EXPECT_EQ(y, (std::vector<double>{1, 1}));

  auto final_x = [&]() {
    EXPECT_EQ(mbdae_solve(m), MBDAE_OK) << mbdae_last_error();
    const auto h = MeasureHistory(m, "x");
    EXPECT_EQ(h.back().first, 1.0);
    return h.back().second;
  };
  // Constant push F on mass m: x(1) = F / (2 m).
  EXPECT_NEAR(final_x(), 1.0 / 4, 1e-12);
  // A ramp F = 6 t: x(1) = 6 / (6 * 2) = 0.5; three points of a linear spline.
  const double xs[3] = {0, 1, 2}, ys[3] = {0, 6, 12};
  ASSERT_MBDAE_OK(mbdae_set_spline_points(m, push, xs, ys, 3));
  const double ramp = final_x();
  EXPECT_NEAR(ramp, 0.5, 1e-6);  // HHT, h = 1e-3: second order
  // A parameter rebuild keeps the points set here.
  ASSERT_MBDAE_OK(mbdae_set_parameter(m, Find(m, MBDAE_PARAMETERS, "m"), 4.0));
  ASSERT_MBDAE_OK(mbdae_spline_size(m, push, &n));
  EXPECT_EQ(n, 3);
  EXPECT_NEAR(final_x(), 0.25, 1e-6);
  std::printf("spline force: x(1) = %.9f (constant 1 N, 2 kg), %.9f (ramp 6t), then %.9f (4 kg)\n",
              0.25, ramp, 0.25);

  // Bad points: an INPUT error naming the spline, the points stay.
  const double bad_x[3] = {0, 2, 1};
  EXPECT_EQ(mbdae_set_spline_points(m, push, bad_x, ys, 3), MBDAE_ERROR_INPUT);
  EXPECT_EQ(std::string(mbdae_last_error()).rfind("spline 'push': ", 0), 0u) << mbdae_last_error();
  EXPECT_EQ(mbdae_set_spline_points(m, push, xs, ys, 1), MBDAE_ERROR_INPUT);
  EXPECT_EQ(mbdae_get_spline_points(m, push, x.data(), y.data(), 2), MBDAE_ERROR_SIZE);
  EXPECT_STREQ(mbdae_last_error(), "spline points: the array has 2 values, expected 3");
  x.resize(3);
  y.resize(3);
  ASSERT_MBDAE_OK(mbdae_get_spline_points(m, push, x.data(), y.data(), 3));
  EXPECT_EQ(y, (std::vector<double>{0, 6, 12}));
}

// ---- Solving, state ------------------------------------------------------------------------

TEST(ApiSolve, SolveToBetweenOutputTimesStoresNoExtraRow) {
  Model m(kPendulum);
  ASSERT_MBDAE_OK(mbdae_set_option(m, "output_step", "0.1"));
  ASSERT_MBDAE_OK(mbdae_solve_to(m, 0.25));
  EXPECT_EQ(Count(m, MBDAE_OUTPUTS), 3);  // 0, 0.1, 0.2
  double t = 0;
  ASSERT_MBDAE_OK(mbdae_get_state(m, &t, nullptr, nullptr, nullptr, nullptr, 0, 0));
  EXPECT_EQ(t, 0.25);
  ASSERT_MBDAE_OK(mbdae_solve(m));
  EXPECT_EQ(Count(m, MBDAE_OUTPUTS), 21);
  ASSERT_MBDAE_OK(mbdae_get_output(m, 3, MBDAE_OUT_TIME, &t, 1));
  EXPECT_NEAR(t, 0.3, 1e-15);
  // Past t_end: a row every output step after t_end.
  ASSERT_MBDAE_OK(mbdae_solve_to(m, 2.35));
  EXPECT_EQ(Count(m, MBDAE_OUTPUTS), 24);
  ASSERT_MBDAE_OK(mbdae_get_output(m, 23, MBDAE_OUT_TIME, &t, 1));
  EXPECT_NEAR(t, 2.3, 1e-15);
  // Body pose: position and an orthonormal rotation matrix.
  std::vector<double> pose(12), q(7);
  ASSERT_MBDAE_OK(mbdae_get_output(m, 10, MBDAE_OUT_BODY_POSES, pose.data(), 12));
  ASSERT_MBDAE_OK(mbdae_get_output(m, 10, MBDAE_OUT_Q, q.data(), 7));
  EXPECT_EQ(pose[0], q[0]);
  EXPECT_EQ(pose[1], q[1]);
  const double* R = pose.data() + 3;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) {
      double dot = 0;
      for (int k = 0; k < 3; ++k) dot += R[3 * i + k] * R[3 * j + k];
      EXPECT_NEAR(dot, i == j ? 1 : 0, 1e-12);
    }
  // The pivot marker (-L, 0, 0) in body axes is at the origin: p + R (-1, 0, 0) = 0.
  EXPECT_NEAR(q[0] - R[0], 0, 1e-8);
  EXPECT_NEAR(q[1] - R[3], 0, 1e-8);
}

TEST(ApiState, GetSetRoundTrip) {
  Model m(kPendulum);
  ASSERT_MBDAE_OK(mbdae_assemble(m));
  const int nq = Count(m, MBDAE_COORDINATES), nm = Count(m, MBDAE_MULTIPLIERS);
  std::vector<double> q(nq), v(nq), a(nq), lambda(nm);
  double t = -1;
  ASSERT_MBDAE_OK(mbdae_get_state(m, &t, q.data(), v.data(), a.data(), lambda.data(), nq, nm));
  EXPECT_EQ(t, 0.0);
  // At the consistent initial state, a and lambda computed by set_state from (t, q, v)
  // are those of the assembly.
  ASSERT_MBDAE_OK(mbdae_set_state(m, 0.0, q.data(), v.data(), nullptr, nullptr, nq, nm));
  std::vector<double> q2(nq), v2(nq), a2(nq), lambda2(nm);
  ASSERT_MBDAE_OK(
      mbdae_get_state(m, &t, q2.data(), v2.data(), a2.data(), lambda2.data(), nq, nm));
  EXPECT_EQ(q2, q);
  EXPECT_EQ(v2, v);
  double da = 0, dl = 0;
  for (int i = 0; i < nq; ++i) da = std::max(da, std::abs(a2[i] - a[i]));
  for (int i = 0; i < nm; ++i) dl = std::max(dl, std::abs(lambda2[i] - lambda[i]));
  EXPECT_LT(da, 1e-12);
  EXPECT_LT(dl, 1e-12);
  // The released pendulum: a = (0, -g) at the bob, lambda carries no load yet.
  EXPECT_NEAR(a[1], -9.81, 1e-12);
  std::printf("set_state a, lambda from (t, q, v) vs the assembly: %.3g, %.3g\n", da, dl);
  // Given a and lambda are taken as they are.
  for (double& x : a2) x += 1;
  ASSERT_MBDAE_OK(mbdae_set_state(m, 0.0, q.data(), v.data(), a2.data(), lambda.data(), nq, nm));
  std::vector<double> a3(nq);
  ASSERT_MBDAE_OK(mbdae_get_state(m, nullptr, nullptr, nullptr, a3.data(), nullptr, nq, nm));
  EXPECT_EQ(a3, a2);

  // Mid-run (IDA, rtol 1e-8): a and lambda from the equations of motion at IDA's (q, v)
  // agree with IDA's own to its accuracy. The bob then moves at 4.2 m/s, lambda is ~20 N.
  ASSERT_MBDAE_OK(mbdae_solve_to(m, 0.5));
  ASSERT_MBDAE_OK(mbdae_get_state(m, &t, q.data(), v.data(), a.data(), lambda.data(), nq, nm));
  ASSERT_MBDAE_OK(mbdae_set_state(m, t, q.data(), v.data(), nullptr, nullptr, nq, nm));
  ASSERT_MBDAE_OK(
      mbdae_get_state(m, nullptr, nullptr, nullptr, a2.data(), lambda2.data(), nq, nm));
  da = dl = 0;
  double amax = 0, lmax = 0;
  for (int i = 0; i < nq; ++i) da = std::max(da, std::abs(a2[i] - a[i]));
  for (int i = 0; i < nq; ++i) amax = std::max(amax, std::abs(a[i]));
  for (int i = 0; i < nm; ++i) dl = std::max(dl, std::abs(lambda2[i] - lambda[i]));
  for (int i = 0; i < nm; ++i) lmax = std::max(lmax, std::abs(lambda[i]));
  EXPECT_GT(amax, 5.0);
  EXPECT_LT(da, 1e-5 * amax);
  EXPECT_LT(dl, 1e-5 * lmax);
  std::printf("at t = 0.5: a, lambda from (t, q, v) vs IDA's: %.3g (of %.3g), %.3g (of %.3g)\n",
              da, amax, dl, lmax);
}

// Solve to the end, then restart from the state saved half-way: the continuation is
// reproduced within the integrator's accuracy (the restart resets its history: IDA's
// order and step, HHT's acceleration-like variables).
void RestartReproducesContinuation(const char* integrator, double tolerance) {
  Model m(kPendulum);
  ASSERT_MBDAE_OK(mbdae_set_option(m, "integrator", integrator));
  ASSERT_MBDAE_OK(mbdae_set_option(m, "output_step", "0.01"));
  ASSERT_MBDAE_OK(mbdae_solve_to(m, 1.0));
  const int nq = Count(m, MBDAE_COORDINATES), nm = Count(m, MBDAE_MULTIPLIERS);
  std::vector<double> q(nq), v(nq), a(nq), lambda(nm);
  double t = 0;
  ASSERT_MBDAE_OK(mbdae_get_state(m, &t, q.data(), v.data(), a.data(), lambda.data(), nq, nm));
  ASSERT_EQ(t, 1.0);
  ASSERT_MBDAE_OK(mbdae_solve(m));
  ASSERT_EQ(Count(m, MBDAE_OUTPUTS), 201);
  std::vector<std::vector<double>> first;
  for (int r = 0; r < 201; ++r) {
    std::vector<double> row(nq);
    ASSERT_MBDAE_OK(mbdae_get_output(m, r, MBDAE_OUT_Q, row.data(), nq));
    first.push_back(row);
  }
  // Restart: the rows after t = 1 are dropped and computed again.
  ASSERT_MBDAE_OK(mbdae_set_state(m, t, q.data(), v.data(), a.data(), lambda.data(), nq, nm));
  EXPECT_EQ(Count(m, MBDAE_OUTPUTS), 101);
  ASSERT_MBDAE_OK(mbdae_solve(m));
  ASSERT_EQ(Count(m, MBDAE_OUTPUTS), 201);
  double max_diff = 0;
  for (int r = 0; r < 201; ++r) {
    std::vector<double> row(nq);
    ASSERT_MBDAE_OK(mbdae_get_output(m, r, MBDAE_OUT_Q, row.data(), nq));
    for (int i = 0; i < nq; ++i) {
      if (r <= 100) EXPECT_EQ(row[i], first[r][i]);  // the kept rows
      max_diff = std::max(max_diff, std::abs(row[i] - first[r][i]));
    }
  }
  EXPECT_LT(max_diff, tolerance);
  EXPECT_GT(max_diff, 0.0);  // a restart, not a replay
  std::printf("%s: restart at t = 1 from the saved state: max |q - q_continuous| = %.3g over 1 s\n",
              integrator, max_diff);
  // The measures continue unwrapped across the restart (the angle passes +-pi... no jump).
  const auto angle = MeasureHistory(m, "angle");
  for (size_t i = 1; i < angle.size(); ++i)
    EXPECT_LT(std::abs(angle[i].second - angle[i - 1].second), 0.2) << "row " << i;
}

TEST(ApiState, RestartReproducesTheContinuationIda) { RestartReproducesContinuation("ida", 1e-6); }
TEST(ApiState, RestartReproducesTheContinuationHht) { RestartReproducesContinuation("hht", 1e-4); }

TEST(ApiState, TwoHandlesAreIndependent) {
  Model a(kPendulum), b(kPendulum);
  ASSERT_MBDAE_OK(mbdae_set_parameter(b, Find(b, MBDAE_PARAMETERS, "L"), 2.0));
  ASSERT_MBDAE_OK(mbdae_solve_to(a, 0.5));
  ASSERT_MBDAE_OK(mbdae_solve_to(b, 0.5));
  double qa[7], qb[7];
  ASSERT_MBDAE_OK(mbdae_get_output(a, 0, MBDAE_OUT_Q, qa, 7));
  ASSERT_MBDAE_OK(mbdae_get_output(b, 0, MBDAE_OUT_Q, qb, 7));
  EXPECT_EQ(qa[0], 1.0);
  EXPECT_EQ(qb[0], 2.0);
}

}  // namespace
