// Objective values of a simulate run (driver::Simulate): /objectives/NAME in the results
// file and the summary.
#include <gtest/gtest.h>
#include <hdf5.h>
#include <unistd.h>

#include <cmath>
#include <string>
#include <vector>

#include "driver/simulation.h"
#include "mbs/loader.h"

namespace mbdae::driver {
namespace {

// A pendulum with output at every HHT step, so that the trapezoidal rule over the rows
// is the integrator's own quadrature.
const std::string kModel = R"Y(format: 1
gravity: [0, -9.81, 0]
bodies:
  - name: bob
    mass: 1
    inertia: [0, 0, 0]
    position: [1, 0, 0]
    markers:
      pivot: {position: [-1, 0, 0]}
measures:
  - {name: x, type: translational, i: bob.cm, component: x}
  - {name: tension, type: reaction, joint: pivot, component: x, frame: world}
joints:
  - {name: pivot, type: revolute, i: bob.pivot, j: ground.O}
objectives:
  - {name: T, integral: "t"}
  - {name: X, integral: "x^2", terminal: "x"}
  - {name: R, integral: "tension"}
simulation: {t_end: 0.3, output_step: 1.0e-3, integrator: hht, hht: {step: 1.0e-3}}
)Y";

double ReadAttribute(hid_t file, const std::string& group, const std::string& name) {
  const hid_t g = H5Gopen2(file, group.c_str(), H5P_DEFAULT);
  EXPECT_GE(g, 0) << group;
  const hid_t a = H5Aopen(g, name.c_str(), H5P_DEFAULT);
  double v = std::nan("");
  H5Aread(a, H5T_NATIVE_DOUBLE, &v);
  H5Aclose(a);
  H5Gclose(g);
  return v;
}

std::vector<double> ReadRows(hid_t file, const std::string& path) {
  const hid_t d = H5Dopen2(file, path.c_str(), H5P_DEFAULT);
  const hid_t s = H5Dget_space(d);
  hsize_t n = 0;
  H5Sget_simple_extent_dims(s, &n, nullptr);
  std::vector<double> v(n);
  H5Dread(d, H5T_NATIVE_DOUBLE, H5S_ALL, H5S_ALL, H5P_DEFAULT, v.data());
  H5Sclose(s);
  H5Dclose(d);
  return v;
}

TEST(SimulateObjectives, PendulumValuesInTheResultsFileMatchTheRows) {
  const mbs::Model model = mbs::LoadModelFromString(kModel, "pendulum.yaml");
  Assembly asmb = Assemble(model);
  const std::string path = "objectives_test_" + std::to_string(getpid()) + ".h5";
  SimulationOptions options;
  options.results_path = path;
  // Rows with the integrator's own a and lambda: the quadrature integrates those (the
  // default rows solve a and lambda from (t, q, v) and differ by the integrator's error
  // in lambda, here 1.5e-5 in the reaction's integral).
  SettingsOverrides overrides;
  overrides.output_accelerations = "integrator";
  const mbs::SimulationSettings settings = ResolveSettings(model.simulation, overrides);
  const SimulationSummary summary = Simulate(model, asmb, settings, options);
  ASSERT_EQ(summary.status, SimulationSummary::Status::kDone) << summary.failure_reason;
  ASSERT_EQ(summary.objectives.size(), 3u) << summary.objectives_note;
  EXPECT_NE(summary.FullReport().find("objective X:"), std::string::npos) << summary.FullReport();

  const hid_t f = H5Fopen(path.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
  ASSERT_GE(f, 0);
  const std::vector<double> t = ReadRows(f, "/time");
  const std::vector<double> x = ReadRows(f, "/measures/x");
  const std::vector<double> tension = ReadRows(f, "/measures/tension");
  ASSERT_EQ(t.size(), 301u);
  double ix2 = 0, it = 0;
  for (size_t k = 1; k < t.size(); ++k) {
    const double h = t[k] - t[k - 1];
    ix2 += 0.5 * h * (x[k] * x[k] + x[k - 1] * x[k - 1]);
    it += 0.5 * h * (tension[k] + tension[k - 1]);
  }
  // integral of t: exact under the trapezoidal rule.
  EXPECT_NEAR(ReadAttribute(f, "/objectives/T", "value"), 0.5 * 0.3 * 0.3, 1e-12);
  EXPECT_NEAR(ReadAttribute(f, "/objectives/T", "terminal"), 0.0, 0.0);
  // integral of x^2 and terminal x: the trapezoid of the rows (same points) and the last row.
  EXPECT_NEAR(ReadAttribute(f, "/objectives/X", "integral"), ix2, 1e-12);
  EXPECT_NEAR(ReadAttribute(f, "/objectives/X", "terminal"), x.back(), 1e-12);
  EXPECT_NEAR(ReadAttribute(f, "/objectives/X", "value"), ix2 + x.back(), 1e-12);
  // the reaction measure: its rows are the joint's /joints/pivot/force x (world).
  EXPECT_NEAR(ReadAttribute(f, "/objectives/R", "integral"), it, 1e-10);
  EXPECT_NE(tension.back(), 0.0);
  H5Fclose(f);
  std::remove(path.c_str());
}

}  // namespace
}  // namespace mbdae::driver
