// Objectives and gradients through the C API (api/mbdae.h: mbdae_gradient,
// mbdae_get_gradient, mbdae_gradient_report, MBDAE_OBJECTIVES, the gradient.* options),
// through the shared library and the C header only.
//
// The references are computed through the API itself: the objective values from the
// stored rows of mbdae_solve (output at every HHT step, so the trapezoidal rule over the
// rows is the run's own quadrature), and the gradients by central differences of such
// solves with mbdae_set_parameter / mbdae_set_spline_points.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

#include "mbdae.h"

namespace {

const std::string kModel = std::string(MBDAE_API_TEST_MODELS) + "/gradient_oscillator.yaml";

#define ASSERT_MBDAE_OK(expr) ASSERT_EQ((expr), MBDAE_OK) << mbdae_last_error()
#define EXPECT_MBDAE_OK(expr) EXPECT_EQ((expr), MBDAE_OK) << mbdae_last_error()

class Model {
 public:
  explicit Model(const std::string& path) {
    EXPECT_EQ(mbdae_model_from_file(path.c_str(), &m_), MBDAE_OK) << mbdae_last_error();
  }
  Model(const std::string& text, const char* name) {
    EXPECT_EQ(mbdae_model_from_string(text.c_str(), name, &m_), MBDAE_OK) << mbdae_last_error();
  }
  ~Model() { mbdae_model_free(m_); }
  Model(const Model&) = delete;
  Model& operator=(const Model&) = delete;
  operator mbdae_model*() const { return m_; }

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

std::vector<std::string> Names(mbdae_model* m, mbdae_kind kind) {
  std::vector<std::string> out;
  for (int i = 0; i < Count(m, kind); ++i) {
    const char* name = nullptr;
    EXPECT_EQ(mbdae_name(m, kind, i, &name), MBDAE_OK) << mbdae_last_error();
    out.emplace_back(name ? name : "");
  }
  return out;
}

double Parameter(mbdae_model* m, const char* name) {
  double value = 0;
  EXPECT_EQ(mbdae_get_parameter(m, Find(m, MBDAE_PARAMETERS, name), &value), MBDAE_OK);
  return value;
}

void SetParameter(mbdae_model* m, const char* name, double value) {
  EXPECT_EQ(mbdae_set_parameter(m, Find(m, MBDAE_PARAMETERS, name), value), MBDAE_OK)
      << mbdae_last_error();
}

// The objectives G = int 0.5 x^2 + v(T), E = int c v^2, fit = int (x - ref(t))^2 with
// ref = 0 (its points as in the file), by the trapezoidal rule over the stored rows.
std::vector<double> SolvedObjectives(mbdae_model* m) {
  EXPECT_EQ(mbdae_solve(m), MBDAE_OK) << mbdae_last_error();
  const int nmeas = Count(m, MBDAE_MEASURES);
  const int ix = Find(m, MBDAE_MEASURES, "x"), iv = Find(m, MBDAE_MEASURES, "v");
  const double c = Parameter(m, "c");
  std::vector<double> values(nmeas);
  double G = 0, E = 0, fit = 0, t_prev = 0, x_prev = 0, v_prev = 0;
  const int rows = Count(m, MBDAE_OUTPUTS);
  for (int r = 0; r < rows; ++r) {
    double t = 0;
    EXPECT_EQ(mbdae_get_output(m, r, MBDAE_OUT_TIME, &t, 1), MBDAE_OK);
    EXPECT_EQ(mbdae_get_output(m, r, MBDAE_OUT_MEASURES, values.data(), nmeas), MBDAE_OK);
    const double x = values[ix], v = values[iv];
    if (r > 0) {
      const double h = t - t_prev;
      G += 0.5 * h * (0.5 * x * x + 0.5 * x_prev * x_prev);
      E += 0.5 * h * (c * v * v + c * v_prev * v_prev);
      fit += 0.5 * h * (x * x + x_prev * x_prev);
    }
    t_prev = t;
    x_prev = x;
    v_prev = v;
  }
  G += v_prev;
  return {G, E, fit};
}

// Central differences of SolvedObjectives with respect to `name` (a parameter or
// "u[i]"), step h.
std::vector<double> CentralDifference(mbdae_model* m, const std::string& name, double h) {
  std::vector<double> plus, minus;
  if (name.rfind("u[", 0) == 0) {
    const int s = Find(m, MBDAE_SPLINES, "u");
    const int i = std::stoi(name.substr(2));
    int n = 0;
    EXPECT_EQ(mbdae_spline_size(m, s, &n), MBDAE_OK);
    std::vector<double> x(n), y(n);
    EXPECT_EQ(mbdae_get_spline_points(m, s, x.data(), y.data(), n), MBDAE_OK);
    const double y0 = y[i];
    y[i] = y0 + h;
    EXPECT_EQ(mbdae_set_spline_points(m, s, x.data(), y.data(), n), MBDAE_OK);
    plus = SolvedObjectives(m);
    y[i] = y0 - h;
    EXPECT_EQ(mbdae_set_spline_points(m, s, x.data(), y.data(), n), MBDAE_OK);
    minus = SolvedObjectives(m);
    y[i] = y0;
    EXPECT_EQ(mbdae_set_spline_points(m, s, x.data(), y.data(), n), MBDAE_OK);
  } else {
    const double p0 = Parameter(m, name.c_str());
    SetParameter(m, name.c_str(), p0 + h);
    plus = SolvedObjectives(m);
    SetParameter(m, name.c_str(), p0 - h);
    minus = SolvedObjectives(m);
    SetParameter(m, name.c_str(), p0);
  }
  std::vector<double> d(plus.size());
  for (size_t i = 0; i < d.size(); ++i) d[i] = (plus[i] - minus[i]) / (2 * h);
  return d;
}

struct Stored {
  std::vector<std::string> objectives, wrt;
  std::vector<double> values, gradient;
  double at(int i, int k) const { return gradient[i * wrt.size() + k]; }
};

Stored ReadGradient(mbdae_model* m) {
  Stored s;
  s.objectives = Names(m, MBDAE_GRADIENT_OBJECTIVES);
  s.wrt = Names(m, MBDAE_GRADIENT_WRT);
  s.values.assign(s.objectives.size(), NAN);
  s.gradient.assign(s.objectives.size() * s.wrt.size(), NAN);
  EXPECT_EQ(mbdae_get_gradient(m, MBDAE_GRAD_VALUES, s.values.data(),
                               static_cast<int>(s.values.size())),
            MBDAE_OK)
      << mbdae_last_error();
  EXPECT_EQ(mbdae_get_gradient(m, MBDAE_GRAD_GRADIENT, s.gradient.data(),
                               static_cast<int>(s.gradient.size())),
            MBDAE_OK)
      << mbdae_last_error();
  return s;
}

Stored Gradient(mbdae_model* m, const char* method, std::vector<const char*> wrt,
                std::vector<const char*> objectives = {}, int wrt_splines = 0) {
  EXPECT_EQ(mbdae_gradient(m, method, objectives.empty() ? nullptr : objectives.data(),
                           static_cast<int>(objectives.size()), wrt.empty() ? nullptr : wrt.data(),
                           static_cast<int>(wrt.size()), wrt_splines, nullptr),
            MBDAE_OK)
      << mbdae_last_error();
  return ReadGradient(m);
}

bool Contains(const std::string& text, const std::string& part) {
  return text.find(part) != std::string::npos;
}

// ---- Names ------------------------------------------------------------------------------

TEST(ApiGradient, ObjectiveNamesAndNoGradientYet) {
  Model m(kModel);
  EXPECT_EQ(Names(m, MBDAE_OBJECTIVES), (std::vector<std::string>{"G", "E", "fit"}));
  EXPECT_EQ(Find(m, MBDAE_OBJECTIVES, "fit"), 2);
  int index = -1;
  EXPECT_EQ(mbdae_find(m, MBDAE_OBJECTIVES, "H", &index), MBDAE_ERROR_ARGUMENT);
  EXPECT_TRUE(Contains(mbdae_last_error(), "no objective called 'H'")) << mbdae_last_error();
  // Nothing stored before the first gradient: no names, and reading is an order error.
  EXPECT_EQ(Count(m, MBDAE_GRADIENT_OBJECTIVES), 0);
  EXPECT_EQ(Count(m, MBDAE_GRADIENT_WRT), 0);
  double v[3];
  EXPECT_EQ(mbdae_get_gradient(m, MBDAE_GRAD_VALUES, v, 3), MBDAE_ERROR_ORDER);
  EXPECT_TRUE(Contains(mbdae_last_error(), "mbdae_gradient first")) << mbdae_last_error();
  size_t length = 0;
  EXPECT_EQ(mbdae_gradient_report(m, 0, nullptr, 0, &length), MBDAE_ERROR_ORDER);
  // A model without objectives has none (the pendulum of the examples).
  Model p(MBDAE_PENDULUM);
  EXPECT_EQ(Count(p, MBDAE_OBJECTIVES), 0);
  EXPECT_EQ(mbdae_gradient(p, "adjoint", nullptr, 0, nullptr, 0, 0, nullptr), MBDAE_ERROR_INPUT);
  EXPECT_TRUE(Contains(mbdae_last_error(), "no objectives")) << mbdae_last_error();
}

// ---- Values and gradients against the API's own solves ------------------------------------

TEST(ApiGradient, AdjointAndForwardAgainstCentralDifferencesOfSolves) {
  Model m(kModel);
  const std::vector<const char*> wrt = {"mass", "k", "c", "x0", "v0", "u[1]", "u[3]"};
  const Stored adjoint = Gradient(m, "adjoint", wrt);
  ASSERT_EQ(adjoint.objectives, (std::vector<std::string>{"G", "E", "fit"}));
  ASSERT_EQ(adjoint.wrt, (std::vector<std::string>{"mass", "k", "c", "x0", "v0", "u[1]", "u[3]"}));

  // Values: the trapezoidal rule over the rows of a plain solve (the same HHT steps).
  const std::vector<double> solved = SolvedObjectives(m);
  for (int i = 0; i < 3; ++i)
    EXPECT_NEAR(adjoint.values[i], solved[i], 1e-12 * std::max(1.0, std::abs(solved[i])))
        << adjoint.objectives[i];

  // Gradients: central differences of solves, step 1e-4 * max(|p|, 1) (truncation
  // ~ h^2 G''' / 6, about 1e-9 here).
  const Stored forward = Gradient(m, "forward", wrt);
  double worst = 0, worst_forward = 0;
  for (size_t k = 0; k < wrt.size(); ++k) {
    const std::string name = wrt[k];
    const double p = name[0] == 'u' ? 1.0 : Parameter(m, name.c_str());
    const std::vector<double> fd = CentralDifference(m, name, 1e-4 * std::max(std::abs(p), 1.0));
    for (int i = 0; i < 3; ++i) {
      const double scale = std::max(1.0, std::abs(fd[i]));
      const double err = std::abs(adjoint.at(i, k) - fd[i]) / scale;
      worst = std::max(worst, err);
      EXPECT_LT(err, 1e-7) << adjoint.objectives[i] << " wrt " << name << ": adjoint "
                           << adjoint.at(i, k) << ", central difference " << fd[i];
      worst_forward =
          std::max(worst_forward, std::abs(forward.at(i, k) - adjoint.at(i, k)) / scale);
    }
  }
  // Both exact methods give the gradient of the same discrete objective.
  EXPECT_LT(worst_forward, 1e-10);
  std::printf("adjoint vs central differences of solves: worst %.2e (relative to max(1, |dG/dp|));"
              " forward vs adjoint %.2e\n", worst, worst_forward);
  // Something to find: the gradients are not small.
  EXPECT_GT(std::abs(adjoint.at(0, 1)), 1e-3);
  EXPECT_GT(std::abs(adjoint.at(1, 2)), 1e-2);
}

TEST(ApiGradient, FdMethodUsesTheParametersAndSplinePointsSetThroughTheApi) {
  Model m(kModel);
  // The model moved away from its file: a parameter and spline points set through the
  // API. fd over k reloads the model: these must be there again in every perturbed run.
  SetParameter(m, "c", 0.7);
  const int s = Find(m, MBDAE_SPLINES, "u");
  const double ux[5] = {0, 0.5, 1, 1.5, 2}, uy[5] = {0.3, -1, 2, 0.5, 0};
  ASSERT_MBDAE_OK(mbdae_set_spline_points(m, s, ux, uy, 5));
  ASSERT_MBDAE_OK(mbdae_set_option(m, "gradient.fd_step", "1e-4"));
  const std::vector<const char*> wrt = {"k", "c", "u[2]"};
  const Stored adjoint = Gradient(m, "adjoint", wrt);
  const Stored fd = Gradient(m, "fd", wrt);
  double steps[3] = {0, 0, 0};
  ASSERT_MBDAE_OK(mbdae_get_gradient(m, MBDAE_GRAD_FD_STEPS, steps, 3));
  EXPECT_DOUBLE_EQ(steps[0], 1e-4 * 4.0);  // k = 4
  EXPECT_DOUBLE_EQ(steps[1], 1e-4 * 1.0);  // c = 0.7: max(|c|, 1)
  EXPECT_DOUBLE_EQ(steps[2], 1e-4 * 2.0);  // u[2] = 2
  double counters[4];
  ASSERT_MBDAE_OK(mbdae_get_gradient(m, MBDAE_GRAD_COUNTERS, counters, 4));
  EXPECT_EQ(counters[0], 2000);   // forward steps: 2 s at 1e-3
  EXPECT_EQ(counters[1], 1 + 6);  // runs: 1 + 2 per wrt entry
  for (int i = 0; i < 3; ++i) {
    // The same forward run up to the Newton threshold (lowered for the exact methods).
    EXPECT_NEAR(fd.values[i], adjoint.values[i], 1e-12 * std::abs(adjoint.values[i]));
    for (int k = 0; k < 3; ++k)
      EXPECT_NEAR(fd.at(i, k), adjoint.at(i, k), 1e-7 * std::max(1.0, std::abs(adjoint.at(i, k))))
          << fd.objectives[i] << " wrt " << fd.wrt[k];
  }
  // The values are those of the model with c = 0.7 and the new points (not the file's).
  const std::vector<double> solved = SolvedObjectives(m);
  EXPECT_NEAR(adjoint.values[0], solved[0], 1e-12);
  EXPECT_NEAR(adjoint.values[1], solved[1], 1e-12);
  // fd steps exist for fd only.
  ASSERT_MBDAE_OK(mbdae_gradient(m, "forward", nullptr, 0, wrt.data(), 3, 0, nullptr));
  EXPECT_EQ(mbdae_get_gradient(m, MBDAE_GRAD_FD_STEPS, steps, 3), MBDAE_ERROR_ARGUMENT);
  EXPECT_TRUE(Contains(mbdae_last_error(), "fd only")) << mbdae_last_error();
}

TEST(ApiGradient, DefaultsOrderAndWrtSplines) {
  Model m(kModel);
  // Every objective and every parameter by default, in the model's order.
  const Stored all = Gradient(m, "adjoint", {});
  EXPECT_EQ(all.objectives, (std::vector<std::string>{"G", "E", "fit"}));
  EXPECT_EQ(all.wrt, (std::vector<std::string>{"mass", "k", "c", "x0", "v0", "w"}));
  // Objectives asked for in another order come in the model's order; wrt in the given
  // order; wrt_splines appends every ordinate not listed.
  const Stored some = Gradient(m, "adjoint", {"u[4]", "k"}, {"fit", "G"}, 1);
  EXPECT_EQ(some.objectives, (std::vector<std::string>{"G", "fit"}));
  EXPECT_EQ(some.wrt, (std::vector<std::string>{"u[4]", "k", "u[0]", "u[1]", "u[2]", "u[3]",
                                                "ref[0]", "ref[1]"}));
  // The same numbers as the full request.
  EXPECT_NEAR(some.values[1], all.values[2], 1e-15);
  EXPECT_NEAR(some.at(0, 1), all.at(0, 1), 1e-12 * std::abs(all.at(0, 1)));
  EXPECT_NEAR(some.at(1, 1), all.at(2, 1), 1e-12 * std::abs(all.at(2, 1)));
  // w = 2 c is computed from c: dG/dc is the total derivative, through w as well. The
  // damping is 0.5 w = c, so d/dw (w independent) is half of the part through the
  // damping: dE/dc = int v^2 + c dE/d(damping) = int v^2 + 2 (dE/dw).
  const double int_v2 = all.values[1] / 0.4;
  EXPECT_NEAR(all.at(1, 2), int_v2 + 2 * all.at(1, 5), 1e-10);
  // An objective that does not use a spline has zero derivative to its ordinates.
  EXPECT_EQ(some.at(0, 6), 0.0);
  EXPECT_EQ(some.at(0, 7), 0.0);
}

TEST(ApiGradient, LeavesTheStoredOutputsAndTheStateAlone) {
  Model m(kModel);
  ASSERT_MBDAE_OK(mbdae_solve_to(m, 0.5));
  const int rows = Count(m, MBDAE_OUTPUTS);
  double t0 = 0, q0[7], v0[7];
  ASSERT_MBDAE_OK(mbdae_get_state(m, &t0, q0, v0, nullptr, nullptr, 7, 0));
  Gradient(m, "adjoint", {"k"});
  Gradient(m, "fd", {"k"});
  EXPECT_EQ(Count(m, MBDAE_OUTPUTS), rows);
  double t1 = 0, q1[7], v1[7];
  ASSERT_MBDAE_OK(mbdae_get_state(m, &t1, q1, v1, nullptr, nullptr, 7, 0));
  EXPECT_EQ(t1, t0);
  for (int i = 0; i < 7; ++i) EXPECT_EQ(q1[i], q0[i]) << i;
  // The stepping goes on where it was, and ends where one solve ends.
  ASSERT_MBDAE_OK(mbdae_solve(m));
  Model fresh(kModel);
  ASSERT_MBDAE_OK(mbdae_solve(fresh));
  const int n = Count(m, MBDAE_OUTPUTS);
  ASSERT_EQ(n, Count(fresh, MBDAE_OUTPUTS));
  double qa[7], qb[7];
  ASSERT_MBDAE_OK(mbdae_get_output(m, n - 1, MBDAE_OUT_Q, qa, 7));
  ASSERT_MBDAE_OK(mbdae_get_output(fresh, n - 1, MBDAE_OUT_Q, qb, 7));
  for (int i = 0; i < 7; ++i) EXPECT_EQ(qa[i], qb[i]) << i;
}

// ---- IDA ----------------------------------------------------------------------------------

Stored IdaGradient(mbdae_model* m, const char* method, const std::vector<const char*>& wrt) {
  EXPECT_EQ(mbdae_set_option(m, "integrator", "ida"), MBDAE_OK);
  EXPECT_EQ(mbdae_set_option(m, "ida.rtol", "1e-10"), MBDAE_OK);
  EXPECT_EQ(mbdae_set_option(m, "ida.atol", "1e-12"), MBDAE_OK);
  EXPECT_EQ(mbdae_set_option(m, "gradient.fd_step", "1e-4"), MBDAE_OK);
  return Gradient(m, method, wrt);
}

TEST(ApiGradient, IdaAdjointForwardAndFd) {
  Model m(kModel);
  const std::vector<const char*> wrt = {"k", "c", "x0", "u[1]"};
  const Stored adjoint = IdaGradient(m, "adjoint", wrt);
  const Stored forward = IdaGradient(m, "forward", wrt);
  const Stored fd = IdaGradient(m, "fd", wrt);
  // The values: IDA at rtol 1e-10 against the HHT run (h = 1e-3, second order) of the
  // same model, 2.8e-6 relative apart at most.
  Model hht(kModel);
  const std::vector<double> solved = SolvedObjectives(hht);
  for (int i = 0; i < 3; ++i) {
    EXPECT_NEAR(forward.values[i], solved[i], 1e-5 * std::abs(solved[i]));
    // fd's forward run is a plain IDA run, forward's has the sensitivities in the error
    // test: other steps, the same tolerance (1.5e-9 apart).
    EXPECT_NEAR(fd.values[i], forward.values[i], 1e-8 * std::abs(solved[i]));
    // The gradients: the fd steps' error is about rtol / step = 1e-6.
    for (size_t k = 0; k < wrt.size(); ++k) {
      const double scale = std::max(1.0, std::abs(fd.at(i, k)));
      EXPECT_NEAR(adjoint.at(i, k), fd.at(i, k), 1e-6 * scale)
          << adjoint.objectives[i] << " wrt " << wrt[k];
      EXPECT_NEAR(forward.at(i, k), fd.at(i, k), 1e-6 * scale)
          << forward.objectives[i] << " wrt " << wrt[k];
    }
  }
  char buf[4096];
  ASSERT_MBDAE_OK(mbdae_gradient_report(m, 1, buf, sizeof buf, nullptr));
  EXPECT_TRUE(Contains(buf, "\"integrator\": \"ida\"")) << buf;
}

// The values the IDAS adjoint reports are those of its own forward run (with
// checkpoints): the same objectives at the same tolerances as the forward method's run.
TEST(ApiGradient, IdaAdjointValuesAreTheForwardRunsValues) {
  Model m(kModel);
  const std::vector<const char*> wrt = {"k"};
  const Stored adjoint = IdaGradient(m, "adjoint", wrt);
  const Stored forward = IdaGradient(m, "forward", wrt);
  for (int i = 0; i < 3; ++i)
    EXPECT_NEAR(adjoint.values[i], forward.values[i], 1e-8 * std::abs(forward.values[i]))
        << adjoint.objectives[i];
}

// ---- Errors ---------------------------------------------------------------------------------

TEST(ApiGradient, MistakesAreReportedAndKeepThePreviousResult) {
  Model m(kModel);
  const Stored before = Gradient(m, "adjoint", {"k", "c"});
  auto expect_error = [&](mbdae_status status, mbdae_status expected, const char* part) {
    EXPECT_EQ(status, expected) << mbdae_last_error();
    EXPECT_TRUE(Contains(mbdae_last_error(), part)) << "'" << mbdae_last_error() << "' lacks '"
                                                    << part << "'";
  };
  const char* k[] = {"k"};
  const char* bad_objective[] = {"G", "energy"};
  expect_error(mbdae_gradient(m, "backward", nullptr, 0, k, 1, 0, nullptr), MBDAE_ERROR_ARGUMENT,
               "unknown gradient method 'backward'");
  expect_error(mbdae_gradient(m, "adjoint", bad_objective, 2, k, 1, 0, nullptr),
               MBDAE_ERROR_ARGUMENT, "no objective called 'energy'");
  EXPECT_TRUE(Contains(mbdae_last_error(), "G, E, fit")) << mbdae_last_error();
  const char* bad_wrt[] = {"k", "stiffness"};
  expect_error(mbdae_gradient(m, "adjoint", nullptr, 0, bad_wrt, 2, 0, nullptr),
               MBDAE_ERROR_ARGUMENT, "stiffness");
  const char* bad_point[] = {"u[9]"};
  expect_error(mbdae_gradient(m, "adjoint", nullptr, 0, bad_point, 1, 0, nullptr),
               MBDAE_ERROR_ARGUMENT, "u[9]");
  const char* twice[] = {"k", "k"};
  expect_error(mbdae_gradient(m, "adjoint", nullptr, 0, twice, 2, 0, nullptr),
               MBDAE_ERROR_ARGUMENT, "'k' twice");
  expect_error(mbdae_gradient(m, "adjoint", nullptr, 2, k, 1, 0, nullptr), MBDAE_ERROR_ARGUMENT,
               "objectives is NULL");
  const char* null_entry[] = {"k", nullptr};
  expect_error(mbdae_gradient(m, "adjoint", nullptr, 0, null_entry, 2, 0, nullptr),
               MBDAE_ERROR_ARGUMENT, "wrt[1] is NULL");
  expect_error(mbdae_gradient(nullptr, "adjoint", nullptr, 0, k, 1, 0, nullptr),
               MBDAE_ERROR_ARGUMENT, "model is NULL");
  expect_error(mbdae_set_option(m, "gradient.fd_step", "2"), MBDAE_ERROR_INPUT, "fd_step");
  expect_error(mbdae_set_option(m, "gradient.ida_checkpoint_steps", "2.5"), MBDAE_ERROR_INPUT,
               "integer");
  expect_error(mbdae_set_option(m, "gradient.step", "1"), MBDAE_ERROR_ARGUMENT,
               "unknown option 'gradient.step'");
  // Sizes of the reads.
  double values[3], gradient[6];
  expect_error(mbdae_get_gradient(m, MBDAE_GRAD_VALUES, values, 2), MBDAE_ERROR_SIZE, "expected 3");
  expect_error(mbdae_get_gradient(m, MBDAE_GRAD_GRADIENT, gradient, 3), MBDAE_ERROR_SIZE,
               "expected 6");
  char small[8];
  expect_error(mbdae_gradient_report(m, 0, small, sizeof small, nullptr), MBDAE_ERROR_SIZE,
               "at least");
  // The result of before is still there, unchanged.
  const Stored after = ReadGradient(m);
  EXPECT_EQ(after.wrt, before.wrt);
  EXPECT_EQ(after.values, before.values);
  EXPECT_EQ(after.gradient, before.gradient);
  char option[32];
  ASSERT_MBDAE_OK(mbdae_get_option(m, "gradient.fd_step", option, sizeof option));
  EXPECT_STREQ(option, "1.0000000000000001e-05");
}

// A parameter the exact methods cannot differentiate: the wall's position (a ground
// marker, computed once at load time) is refused with the element named; fd can.
TEST(ApiGradient, AParameterTheExactMethodsRefuseIsAnInputError) {
  std::ifstream in(kModel);
  std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  const std::string from = "wall: {position: [-1, 0, 0]}";
  ASSERT_NE(text.find(from), std::string::npos);
  text.replace(text.find(from), from.size(), "wall: {position: [-L, 0, 0]}");
  text.replace(text.find("  mass: 1.5"), 0, "  L: 1\n");
  Model m(text, "wall_parameter.yaml");
  const char* wrt[] = {"L"};
  EXPECT_EQ(mbdae_gradient(m, "adjoint", nullptr, 0, wrt, 1, 0, nullptr), MBDAE_ERROR_INPUT);
  EXPECT_TRUE(Contains(mbdae_last_error(), "'L'") && Contains(mbdae_last_error(), "wall"))
      << mbdae_last_error();
  // fd can. The spring's stretch is y = x + L - 1, with m y'' + c y' + k y = u and
  // y(0) = x0 + L - 1: the velocity does not see L, and moving the wall is moving the
  // initial position, so dE/dL = dE/dx0 (E = int c v^2).
  ASSERT_MBDAE_OK(mbdae_set_option(m, "gradient.fd_step", "1e-4"));
  ASSERT_MBDAE_OK(mbdae_gradient(m, "fd", nullptr, 0, wrt, 1, 0, nullptr));
  const Stored fd = ReadGradient(m);
  const Stored exact = Gradient(m, "adjoint", {"x0"});
  ASSERT_EQ(fd.objectives[1], "E");
  EXPECT_NEAR(fd.at(1, 0), exact.at(1, 0), 1e-7 * std::abs(exact.at(1, 0)));
  EXPECT_GT(std::abs(exact.at(1, 0)), 1e-3);
}

// A run that fails is MBDAE_ERROR_SOLVER with the reason; nothing is stored.
TEST(ApiGradient, AFailedRunIsASolverError) {
  std::ifstream in(kModel);
  std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  const std::string from = "\"spline(u, t)\"";
  ASSERT_NE(text.find(from), std::string::npos);
  text.replace(text.find(from), from.size(), "\"spline(u, t) + 0.01*log(tf - t)\"");
  text.replace(text.find("  mass: 1.5"), 0, "  tf: 5\n");
  Model m(text, "failing.yaml");
  const Stored good = Gradient(m, "adjoint", {"k"});
  ASSERT_EQ(good.values.size(), 3u);
  SetParameter(m, "tf", 1.0);  // log of a negative number after t = 1
  const char* wrt[] = {"k"};
  for (const char* method : {"adjoint", "forward", "fd"}) {
    EXPECT_EQ(mbdae_gradient(m, method, nullptr, 0, wrt, 1, 0, nullptr), MBDAE_ERROR_SOLVER)
        << method << ": " << mbdae_last_error();
    EXPECT_TRUE(Contains(mbdae_last_error(), "the gradient failed: the forward run failed at t = "))
        << mbdae_last_error();
  }
  const Stored after = ReadGradient(m);
  EXPECT_EQ(after.values, good.values);
  EXPECT_EQ(after.gradient, good.gradient);
}

// ---- Report, times, results file ------------------------------------------------------------

TEST(ApiGradient, ReportTimesAndResultsFile) {
  Model m(kModel);
  const std::string path = ::testing::TempDir() + "mbdae_api_gradient.h5";
  std::remove(path.c_str());
  const char* wrt[] = {"k", "c"};
  ASSERT_MBDAE_OK(mbdae_gradient(m, "adjoint", nullptr, 0, wrt, 2, 0, path.c_str()));
  std::ifstream file(path, std::ios::binary);
  char magic[8] = {};
  file.read(magic, 8);
  EXPECT_EQ(std::string(magic + 1, 3), "HDF") << "an HDF5 file at " << path;
  size_t length = 0;
  ASSERT_MBDAE_OK(mbdae_gradient_report(m, 1, nullptr, 0, &length));
  std::string json(length, '\0');
  ASSERT_MBDAE_OK(mbdae_gradient_report(m, 1, &json[0], length, nullptr));
  EXPECT_EQ(json.size(), length);
  EXPECT_EQ(json[length - 1], '\0');
  EXPECT_EQ(std::strlen(json.c_str()) + 1, length);
  EXPECT_EQ(json.rfind("{\"method\": \"adjoint\", \"integrator\": \"hht\"", 0), 0u) << json;
  EXPECT_TRUE(Contains(json, "\"fit\": {\"value\": ")) << json;
  ASSERT_MBDAE_OK(mbdae_gradient_report(m, 0, nullptr, 0, &length));
  std::string text(length, '\0');
  ASSERT_MBDAE_OK(mbdae_gradient_report(m, 0, &text[0], length, nullptr));
  EXPECT_TRUE(Contains(text, "objective G")) << text;
  EXPECT_TRUE(Contains(text, "dG/dp")) << text;
  double times[3];
  ASSERT_MBDAE_OK(mbdae_get_gradient(m, MBDAE_GRAD_TIMES, times, 3));
  EXPECT_GT(times[0], 0);                      // solver CPU of 2000 steps
  EXPECT_GE(times[1], 0);                      // the sweep
  EXPECT_GE(times[2], 0.5 * (times[0] + times[1]));  // wall time covers both (2 cores)
  // A results file that cannot be written.
  EXPECT_EQ(mbdae_gradient(m, "adjoint", nullptr, 0, wrt, 2, 0, "/nonexistent/dir/g.h5"),
            MBDAE_ERROR_IO)
      << mbdae_last_error();
}

}  // namespace
