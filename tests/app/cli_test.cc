// The command line parser, the default results path, the progress display and the
// small numerical helpers of the driver (output times, angle unwrapping, angular velocity).
#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <cmath>
#include <cstdio>
#include <random>
#include <string>

#include "apps/cli.h"
#include "driver/simulation.h"
#include "mbs/loader.h"

namespace mbdae {
namespace {

using app::Command;
using app::CommandLine;
using app::ParseCommandLine;
using app::UsageError;

TEST(CommandLine, SimulateWithEveryOption) {
  CommandLine cl = ParseCommandLine(
      {"simulate", "--t-end", "2.5", "m.yaml", "-o", "out.h5", "--integrator=ida", "--output-step",
       "1e-3", "--step", "1e-4", "--alpha", "-0.2", "--adaptive", "--tolerance", "1e-7",
       "--no-modified", "--hht-form", "negrut", "--rtol", "1e-6", "--atol", "1e-9", "--hht-start", "perturbed",
       "--output-accelerations=integrator", "--set", "k=3", "l0=0.5", "--set", "m=-2e-1", "--quiet"});
  EXPECT_EQ(cl.command, Command::kSimulate);
  EXPECT_EQ(cl.model_path, "m.yaml");
  EXPECT_EQ(cl.output_path, "out.h5");
  EXPECT_EQ(*cl.overrides.integrator, mbs::IntegratorKind::kIda);
  EXPECT_EQ(*cl.overrides.t_end, 2.5);
  EXPECT_EQ(*cl.overrides.output_step, 1e-3);
  EXPECT_EQ(*cl.overrides.hht_step, 1e-4);
  EXPECT_EQ(*cl.overrides.hht_alpha, -0.2);
  EXPECT_TRUE(*cl.overrides.hht_adaptive);
  EXPECT_EQ(*cl.overrides.hht_tolerance, 1e-7);
  EXPECT_FALSE(*cl.overrides.hht_modified);
  EXPECT_EQ(*cl.overrides.hht_form, "negrut");
  EXPECT_EQ(*cl.overrides.ida_rtol, 1e-6);
  EXPECT_EQ(*cl.overrides.ida_atol, 1e-9);
  EXPECT_EQ(*cl.overrides.hht_start, "perturbed");
  EXPECT_EQ(*cl.overrides.output_accelerations, "integrator");
  ASSERT_EQ(cl.parameter_overrides.size(), 3u);
  EXPECT_EQ(cl.parameter_overrides.at("k"), 3.0);
  EXPECT_EQ(cl.parameter_overrides.at("l0"), 0.5);
  EXPECT_EQ(cl.parameter_overrides.at("m"), -0.2);
  EXPECT_TRUE(cl.quiet);
}

TEST(CommandLine, DefaultsLeaveTheModelSettings) {
  CommandLine cl = ParseCommandLine({"simulate", "m.yaml"});
  EXPECT_FALSE(cl.overrides.t_end.has_value());
  EXPECT_FALSE(cl.overrides.integrator.has_value());
  EXPECT_FALSE(cl.overrides.hht_modified.has_value());
  EXPECT_FALSE(cl.overrides.hht_start.has_value());
  EXPECT_FALSE(cl.overrides.output_accelerations.has_value());
  EXPECT_TRUE(cl.output_path.empty());
  EXPECT_FALSE(cl.quiet);
  CommandLine info = ParseCommandLine({"info", "m.yaml", "--json"});
  EXPECT_EQ(info.command, Command::kInfo);
  EXPECT_TRUE(info.json);
  EXPECT_EQ(ParseCommandLine({"check", "m.yaml"}).command, Command::kCheck);
  EXPECT_TRUE(ParseCommandLine({"--help"}).help);
  EXPECT_TRUE(ParseCommandLine({"--version"}).version);
  EXPECT_TRUE(ParseCommandLine({"simulate", "--help"}).help);
}

TEST(CommandLine, MistakesAreUsageErrors) {
  const std::vector<std::vector<std::string>> bad = {
      {},
      {"run", "m.yaml"},
      {"simulate"},
      {"simulate", "m.yaml", "--bogus"},
      {"simulate", "m.yaml", "--t-end"},
      {"simulate", "m.yaml", "--t-end", "abc"},
      {"simulate", "m.yaml", "--t-end", "1s"},
      {"simulate", "m.yaml", "--step", "nan"},
      {"simulate", "m.yaml", "--integrator", "rk4"},
      {"simulate", "m.yaml", "--hht-form", "newmark"},
      {"simulate", "m.yaml", "--hht-start", "smooth"},
      {"simulate", "m.yaml", "--hht-start"},
      {"simulate", "m.yaml", "--output-accelerations", "exact"},
      {"simulate", "m.yaml", "--output-accelerations=Solved"},
      {"check", "m.yaml", "--hht-start", "perturbed"},
      {"info", "m.yaml", "--output-accelerations", "solved"},
      {"simulate", "m.yaml", "--set", "k"},
      {"simulate", "m.yaml", "--set", "k=x"},
      {"simulate", "m.yaml", "--adaptive=1"},
      {"simulate", "a.yaml", "b.yaml"},
      {"info", "m.yaml", "--t-end", "1"},
      {"check", "m.yaml", "--json"},
  };
  for (const auto& args : bad) {
    std::string joined;
    for (const auto& a : args) joined += a + " ";
    EXPECT_THROW(ParseCommandLine(args), UsageError) << joined;
  }
  try {
    ParseCommandLine({"simulate", "m.yaml", "--t-end", "abc"});
  } catch (const UsageError& e) {
    EXPECT_NE(std::string(e.what()).find("--t-end"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("abc"), std::string::npos) << e.what();
  }
}

TEST(CommandLine, OutputAccelerationsAndHhtStartNameTheFlagAndTheValues) {
  const std::vector<std::pair<std::vector<std::string>, std::string>> bad = {
      {{"simulate", "m.yaml", "--hht-start", "smooth"}, "--hht-start: expected consistent or perturbed, got 'smooth'"},
      {{"gradient", "m.yaml", "--hht-start=x"}, "--hht-start: expected consistent or perturbed, got 'x'"},
      {{"simulate", "m.yaml", "--output-accelerations", "exact"},
       "--output-accelerations: expected solved or integrator, got 'exact'"},
  };
  for (const auto& [args, message] : bad) {
    try {
      ParseCommandLine(args);
      ADD_FAILURE() << "no error for " << message;
    } catch (const UsageError& e) {
      EXPECT_EQ(std::string(e.what()), message);
    }
  }
  // gradient takes every simulate option.
  const CommandLine g = ParseCommandLine({"gradient", "m.yaml", "--hht-start", "consistent",
                                          "--output-accelerations", "solved"});
  EXPECT_EQ(*g.overrides.hht_start, "consistent");
  EXPECT_EQ(*g.overrides.output_accelerations, "solved");
}

TEST(CommandLine, DefaultResultsPath) {
  EXPECT_EQ(app::DefaultResultsPath("models/pendulum.yaml"), "models/pendulum.h5");
  EXPECT_EQ(app::DefaultResultsPath("a.yml"), "a.h5");
  EXPECT_EQ(app::DefaultResultsPath("a.JSON"), "a.h5");
  EXPECT_EQ(app::DefaultResultsPath("dir.v2/model"), "dir.v2/model.h5");
  EXPECT_EQ(app::DefaultResultsPath("model.txt"), "model.txt.h5");
}

TEST(CommandLine, JsonStringEscapes) {
  EXPECT_EQ(app::JsonString("a\"b\\c\nd\x01"), "\"a\\\"b\\\\c\\nd\\u0001\"");
}

std::string Capture(app::ProgressReporter::Mode mode, int updates) {
  std::FILE* f = std::tmpfile();
  {
    app::ProgressReporter p(mode, f);
    for (int k = 0; k <= updates; ++k) p.Update(2.0 * k / updates, 2.0);
    p.Finish();
  }
  std::rewind(f);
  std::string out;
  for (int c; (c = std::fgetc(f)) != EOF;) out += static_cast<char>(c);
  std::fclose(f);
  return out;
}

TEST(Progress, LinesEveryTenthBarOnTerminalNothingWhenQuiet) {
  const std::string lines = Capture(app::ProgressReporter::Mode::kLines, 1000);
  int newlines = 0;
  for (char c : lines) newlines += c == '\n';
  EXPECT_EQ(newlines, 10) << lines;
  EXPECT_NE(lines.find("100 %"), std::string::npos) << lines;
  EXPECT_TRUE(Capture(app::ProgressReporter::Mode::kNone, 100).empty());
  const std::string bar = Capture(app::ProgressReporter::Mode::kBar, 100);
  EXPECT_EQ(bar.front(), '\r');
  EXPECT_EQ(bar.back(), '\n');
  EXPECT_NE(bar.find("[==============================] 100 %"), std::string::npos) << bar;
}

TEST(Progress, BarShowsTheTimeLeft) {
  // A clock that advances 2 s per update: at t = 0.5 of 2 (25 %) 2 s have passed since
  // the first update, so 6 s are left; at the end 8 s in all.
  std::FILE* f = std::tmpfile();
  double clock = 0;
  {
    app::ProgressReporter p(app::ProgressReporter::Mode::kBar, f);
    p.set_clock([&clock] { return clock; });
    for (double t : {0.0, 0.5, 1.0, 1.5, 2.0}) {
      p.Update(t, 2.0);
      clock += 2;
    }
    p.Finish();
  }
  std::rewind(f);
  std::string out;
  for (int c; (c = std::fgetc(f)) != EOF;) out += static_cast<char>(c);
  std::fclose(f);
  EXPECT_NE(out.find(" 25 %  t = 0.5        of 2  6 s left"), std::string::npos) << out;
  EXPECT_NE(out.find(" 75 %  t = 1.5        of 2  2 s left"), std::string::npos) << out;
  EXPECT_NE(out.find("100 %  t = 2          of 2  8 s in all"), std::string::npos) << out;
  EXPECT_EQ(app::ProgressReporter::Duration(200), "3 min 20 s");
  EXPECT_EQ(app::ProgressReporter::Duration(7500), "2 h 05 min");
}

TEST(Driver, OutputTimesEndExactlyAtTEnd) {
  auto t = driver::OutputTimes(1.0, 0.1);
  ASSERT_EQ(t.size(), 11u);
  EXPECT_EQ(t.front(), 0.0);
  EXPECT_EQ(t.back(), 1.0);
  for (size_t k = 1; k < t.size(); ++k) EXPECT_GT(t[k], t[k - 1]);
  auto u = driver::OutputTimes(1.0, 0.3);  // 0, .3, .6, .9, 1
  ASSERT_EQ(u.size(), 5u);
  EXPECT_DOUBLE_EQ(u[3], 0.9);
  EXPECT_EQ(u[4], 1.0);
  auto w = driver::OutputTimes(0.5, 2.0);  // longer than the run: start and end
  ASSERT_EQ(w.size(), 2u);
  EXPECT_EQ(w[1], 0.5);
}

TEST(Driver, UnwrapAngleCountsTurns) {
  const double pi = std::acos(-1.0);
  // A steadily turning angle, wrapped into (-pi, pi], unwrapped back.
  double previous = 0;
  for (int k = 1; k <= 100; ++k) {
    const double true_angle = 0.3 * k;
    const double wrapped = std::atan2(std::sin(true_angle), std::cos(true_angle));
    previous = driver::UnwrapAngle(wrapped, previous);
    EXPECT_NEAR(previous, true_angle, 1e-12);
  }
  EXPECT_NEAR(driver::UnwrapAngle(-pi + 0.01, pi - 0.01), pi + 0.01, 1e-12);
  EXPECT_NEAR(driver::UnwrapAngle(0.5, 0.4), 0.5, 0);
}

// omega = 2 E(e) e' checked against the finite-difference rate of the rotation matrix:
// A' A^T = skew(omega) (world axes).
TEST(Driver, AngularVelocityMatchesFiniteDifferenceOfRotation) {
  std::mt19937 rng(7);
  std::normal_distribution<double> n(0, 1);
  auto rotation = [](const Eigen::Vector4d& e) {
    Eigen::Quaterniond qt(e[0], e[1], e[2], e[3]);
    return qt.normalized().toRotationMatrix();
  };
  for (int trial = 0; trial < 20; ++trial) {
    Eigen::Vector4d e(n(rng), n(rng), n(rng), n(rng));
    e.normalize();
    Eigen::Vector4d r(n(rng), n(rng), n(rng), n(rng));
    const Eigen::Vector4d ed = r - e * e.dot(r);  // tangent: e^T e' = 0
    double w[3];
    driver::AngularVelocityWorld(e.data(), ed.data(), w);
    const double h = 1e-6;
    const Eigen::Matrix3d Ad = (rotation(e + h * ed) - rotation(e - h * ed)) / (2 * h);
    const Eigen::Matrix3d W = Ad * rotation(e).transpose();
    EXPECT_NEAR(w[0], W(2, 1), 1e-7);
    EXPECT_NEAR(w[1], W(0, 2), 1e-7);
    EXPECT_NEAR(w[2], W(1, 0), 1e-7);
  }
}

TEST(Driver, ResolveSettingsOverridesAndValidates) {
  mbs::SimulationSettings model;
  driver::SettingsOverrides o;
  o.t_end = 3.0;
  o.hht_alpha = -0.3;
  o.integrator = mbs::IntegratorKind::kHht;
  auto s = driver::ResolveSettings(model, o);
  EXPECT_EQ(s.t_end, 3.0);
  EXPECT_EQ(s.hht_alpha, -0.3);
  EXPECT_EQ(s.output_step, model.output_step);
  auto expect_error = [&](driver::SettingsOverrides bad, const std::string& word) {
    try {
      driver::ResolveSettings(model, bad);
      ADD_FAILURE() << "no error for " << word;
    } catch (const driver::InputError& e) {
      EXPECT_NE(std::string(e.what()).find(word), std::string::npos) << e.what();
    }
  };
  driver::SettingsOverrides bad;
  bad.t_end = -1;
  expect_error(bad, "t_end");
  bad = {};
  bad.output_step = 0;
  expect_error(bad, "output_step");
  bad = {};
  bad.hht_alpha = 0.5;  // outside [-1/3, 0]
  expect_error(bad, "hht");
  bad = {};
  bad.integrator = mbs::IntegratorKind::kIda;
  bad.ida_rtol = -1;
  expect_error(bad, "ida");
  bad = {};
  bad.ida_max_steps = 0;
  expect_error(bad, "ida settings: max_steps must be a whole number >= 1, got 0");
  bad = {};
  bad.ida_min_step = -1e-9;
  expect_error(bad, "ida settings: ");
  driver::SettingsOverrides both;
  both.hht_start = "perturbed";
  both.output_accelerations = "integrator";
  both.ida_max_steps = 77;
  both.ida_min_step = 1e-11;
  s = driver::ResolveSettings(model, both);
  EXPECT_EQ(s.hht_start, "perturbed");
  EXPECT_EQ(s.output_accelerations, "integrator");
  EXPECT_EQ(driver::HhtOptionsOf(s).start, dae::HhtOptions::Start::kPerturbed);
  EXPECT_EQ(driver::IdaOptionsOf(s).max_steps, 77);
  EXPECT_EQ(driver::IdaOptionsOf(s).min_step, 1e-11);
}

// simulation: {ida: {max_steps, min_step}} of the model file reach IdaOptions; without
// them IdaOptions keeps its defaults.
TEST(Driver, IdaStepSettingsOfTheModelFileReachIdaOptions) {
  const dae::IdaOptions defaults;
  mbs::Model m = mbs::LoadModelFromString("format: 1\nsimulation: {integrator: ida}\n", "m.yaml");
  dae::IdaOptions o = driver::IdaOptionsOf(driver::ResolveSettings(m.simulation, {}));
  EXPECT_EQ(o.max_steps, defaults.max_steps);
  EXPECT_EQ(o.min_step, defaults.min_step);
  EXPECT_EQ(o.min_relative_step, defaults.min_relative_step);
  m = mbs::LoadModelFromString(
      "format: 1\nsimulation: {integrator: ida, ida: {rtol: 1e-7, max_steps: 5000, min_step: 1e-10}}\n", "m.yaml");
  o = driver::IdaOptionsOf(driver::ResolveSettings(m.simulation, {}));
  EXPECT_EQ(o.rtol, 1e-7);
  EXPECT_EQ(o.max_steps, 5000);
  EXPECT_EQ(o.min_step, 1e-10);
  std::string error;
  EXPECT_TRUE(o.IsValid(&error)) << error;
  // The command line and the API override them through SettingsOverrides.
  driver::SettingsOverrides over;
  over.ida_max_steps = 10;
  o = driver::IdaOptionsOf(driver::ResolveSettings(m.simulation, over));
  EXPECT_EQ(o.max_steps, 10);
  EXPECT_EQ(o.min_step, 1e-10);
}

}  // namespace
}  // namespace mbdae
