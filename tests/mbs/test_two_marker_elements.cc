// Bushing and user force elements in model files and in the multibody system: the
// loader's keys and errors, the writer's round trip, the user library against the built-in
// spring_damper (values and exact Jacobians), a user function's error at the callback
// edge, and the bushing's generalized forces against its potential.
// (The FD tests of dQ/dq and dQ/dv with bushings are in test_system.cc,
// DerivativesMatchFiniteDifferences.)
#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <random>
#include <string>

#include "mbs/loader.h"
#include "mbs/model_writer.h"
#include "mbs/system.h"
#include "mbs/user_force.h"
#include "tests/support/load_error.h"
#include "tests/support/random_models.h"

namespace mbdae::mbs {
namespace {

using Eigen::MatrixXd;
using Eigen::VectorXd;
using testing::MakeRandomState;
using testing::RandomModel;
using testing::RandomModelOptions;
using testing::RandomState;

const std::string kLibrary = MBDAE_EXAMPLE_USER_FORCE_LIBRARY;

bool Contains(const std::string& s, const std::string& part) { return s.find(part) != std::string::npos; }

using testing::LoadError;

// Two bodies; FORCES is the text of the forces block entries.
std::string TwoBodies(const std::string& forces) {
  return "format: 1\n"
         "parameters: {kr: 30}\n"
         "bodies:\n"
         "  - {name: a, mass: 2, inertia: [0.1, 0.2, 0.3], position: [0.1, 0.2, 0.3],\n"
         "     velocity: [0.3, -0.2, 0.1], angular_velocity: [0.5, 0.2, -0.4],\n"
         "     markers: {m: {position: [0.1, 0, 0.05]}}}\n"
         "  - {name: b, mass: 1, inertia: [0.1, 0.1, 0.1], position: [0.9, -0.1, 0.2],\n"
         "     markers: {m: {position: [-0.1, 0.02, 0]}}}\n"
         "forces:\n" +
         forces;
}

struct Eval {
  VectorXd Q;
  MatrixXd Kq, Kv;
  int code = 0;
};

MatrixXd Dense(const dae::CscPattern& p, const std::vector<double>& val) {
  MatrixXd d = MatrixXd::Zero(p.rows, p.cols);
  for (int c = 0; c < p.cols; ++c)
    for (int k = p.col_start[c]; k < p.col_start[c + 1]; ++k) d(p.row_index[k], c) = val[k];
  return d;
}

Eval Evaluate(MultibodySystem& sys, const std::vector<double>& q, const std::vector<double>& v,
              double t = 0) {
  const int nq = sys.num_coordinates();
  Eval r;
  r.Q.setZero(nq);
  std::vector<double> kq(sys.pattern(dae::Matrix::kForceDq).nnz()), kv(sys.pattern(dae::Matrix::kForceDv).nnz());
  dae::EvalInput in;
  in.q = q.data();
  in.v = v.data();
  in.t = t;
  dae::EvalOutput out;
  out.force = r.Q.data();
  out.matrix[static_cast<int>(dae::Matrix::kForceDq)] = kq.data();
  out.matrix[static_cast<int>(dae::Matrix::kForceDv)] = kv.data();
  r.code = sys.Evaluate(in, out);
  r.Kq = Dense(sys.pattern(dae::Matrix::kForceDq), kq);
  r.Kv = Dense(sys.pattern(dae::Matrix::kForceDv), kv);
  return r;
}

double RelErr(const MatrixXd& a, const MatrixXd& b) {
  return (a - b).lpNorm<Eigen::Infinity>() / std::max(1.0, b.lpNorm<Eigen::Infinity>());
}

// A scratch directory in the build tree's temporary space, removed at the end.
struct ScratchDir {
  std::filesystem::path path;
  explicit ScratchDir(const std::string& name) {
    path = std::filesystem::temp_directory_path() /
           ("mbdae_two_marker_" + name + "_" + std::to_string(::testing::UnitTest::GetInstance()->random_seed()) +
            "_" + std::to_string(reinterpret_cast<uintptr_t>(this)));
    std::filesystem::remove_all(path);
    std::filesystem::create_directories(path);
  }
  ~ScratchDir() {
    std::error_code ec;
    std::filesystem::remove_all(path, ec);
  }
};

TEST(TwoMarkerLoader, BushingKeysDefaultsAndErrors) {
  const Model m = LoadModelFromString(
      TwoBodies("  - {name: bu, type: bushing, i: a.m, j: b.m, stiffness: [100, 200, 300, kr, 2*kr, 50],\n"
                "     damping: [1, 2, 3, 0.1, 0.2, 0.3]}\n"
                "  - {name: bg, type: bushing, i: b.m, stiffness: [1, 1, 1, 1, 1, 1]}\n"),
      "m.yaml");
  ASSERT_EQ(m.forces.size(), 2u);
  const Force& bu = m.forces[0];
  EXPECT_EQ(bu.type, ForceType::kBushing);
  EXPECT_EQ(m.markers[bu.i].name, "a.m");
  EXPECT_EQ(m.markers[bu.j].name, "b.m");
  const std::vector<double> p = m.parameter_values();
  const double ks[6] = {100, 200, 300, 30, 60, 50}, cs[6] = {1, 2, 3, 0.1, 0.2, 0.3};
  for (int c = 0; c < 6; ++c) {
    EXPECT_EQ(bu.bushing_stiffness[c].Evaluate(p.data()), ks[c]);
    EXPECT_EQ(bu.bushing_damping[c].Evaluate(p.data()), cs[c]);
    EXPECT_EQ(m.forces[1].bushing_damping[c].Evaluate(p.data()), 0.0);  // default
  }
  EXPECT_EQ(m.forces[1].j, 0);  // ground.O

  EXPECT_TRUE(Contains(LoadError(TwoBodies("  - {name: bu, type: bushing, i: a.m, stiffness: [1, 1, -1, 1, 1, 1]}\n")),
                       "m.yaml:10:57: force 'bu': 'stiffness' entry 3 is -1"));
  EXPECT_TRUE(Contains(LoadError(TwoBodies("  - {name: bu, type: bushing, i: a.m, stiffness: [1, 1, 1, 1, 1, 1],\n"
                                           "     damping: [1, 1, 1, 1, 1, -kr]}\n")),
                       "'damping' entry 6 is -30"));
  EXPECT_TRUE(Contains(LoadError(TwoBodies("  - {name: bu, type: bushing, i: a.m, stiffness: [1, 1, 1]}\n")),
                       "'stiffness' must be a list of 6 numbers or expressions of the parameters, got 3 entries"));
  EXPECT_TRUE(Contains(LoadError(TwoBodies("  - {name: bu, type: bushing, i: a.m, stiffness: [1, 1, 1, 1, 1, t]}\n")),
                       "force 'bu': 'stiffness'"));
  EXPECT_TRUE(Contains(LoadError(TwoBodies("  - {name: bu, type: bushing, i: a.m, stiffness: [1, 1, 1, 1, 1, 1], frame: j}\n")),
                       "frame"));
}

TEST(TwoMarkerLoader, UserForceLibraryRelativeToTheModelAndShared) {
  ScratchDir dir("relative");
  std::filesystem::create_directories(dir.path / "lib");
  std::filesystem::copy_file(kLibrary, dir.path / "lib" / "libspring.so");
  const std::string text = TwoBodies(
      "  - {name: u1, type: user, library: lib/libspring.so, function: mbdae_spring_damper,\n"
      "     i: a.m, j: b.m, parameters: [50, 2, 0.5, kr/10]}\n"
      "  - {name: u2, type: user, library: ./lib/../lib/libspring.so, function: mbdae_spring_damper_nojac,\n"
      "     i: b.m, parameters: [5, 1, 0.2, 0]}\n");
  const std::string path = (dir.path / "model.yaml").string();
  std::ofstream(path) << text;
  const Model m = LoadModel(path);
  ASSERT_EQ(m.forces.size(), 2u);
  EXPECT_EQ(m.forces[0].type, ForceType::kUser);
  EXPECT_EQ(m.forces[0].library_path, "lib/libspring.so");
  EXPECT_EQ(m.forces[0].function, "mbdae_spring_damper");
  ASSERT_TRUE(m.forces[0].library);
  EXPECT_EQ(m.forces[0].library.get(), m.forces[1].library.get());  // loaded once
  ASSERT_EQ(m.forces[0].user_parameters.size(), 4u);
  EXPECT_EQ(m.forces[0].user_parameters[3].Evaluate(m.parameter_values().data()), 3.0);
  MultibodySystem sys(m);  // init succeeds with 4 parameters
  EXPECT_EQ(m.forces[1].j, 0);

  // Errors name the file, the line and the element.
  const std::string missing = LoadError(TwoBodies(
      "  - {name: u, type: user, library: nowhere/libnothing.so, function: f, i: a.m}\n"), path);
  EXPECT_TRUE(Contains(missing, path + ":10:36: force 'u': cannot use the library")) << missing;
  EXPECT_TRUE(Contains(missing, "libnothing.so")) << missing;
  const std::string symbol = LoadError(TwoBodies(
      "  - {name: u, type: user, library: lib/libspring.so, function: no_such_function, i: a.m}\n"), path);
  EXPECT_TRUE(Contains(symbol, path + ":10:"));
  EXPECT_TRUE(Contains(symbol, "force 'u'"));
  EXPECT_TRUE(Contains(symbol, "no_such_function")) << symbol;
  EXPECT_TRUE(Contains(LoadError(TwoBodies("  - {name: u, type: user, library: " + kLibrary +
                                           ", function: mbdae_spring_damper, i: a.m, parameters: 3}\n")),
                       "'parameters' must be a list"));
}

// The example library's spring-damper equals the built-in one: the same generalized
// forces and the same exact Jacobians (the library's analytic Jacobian to round-off, its
// finite-difference fallback to the FD error).
TEST(TwoMarkerSystem, UserSpringDamperEqualsTheBuiltIn) {
  for (const char* fn : {"mbdae_spring_damper", "mbdae_spring_damper_nojac"}) {
    SCOPED_TRACE(fn);
    const Model user = LoadModelFromString(
        TwoBodies("  - {name: s, type: user, library: " + kLibrary + ", function: " + fn +
                  ", i: a.m, j: b.m, parameters: [50, 2, 0.5, kr/10]}\n"
                  "  - {name: g, type: user, library: " + kLibrary + ", function: " + fn +
                  ", i: a.m, parameters: [20, 1, 0.3, 0]}\n"),
        "m.yaml");
    const Model builtin = LoadModelFromString(
        TwoBodies("  - {name: s, type: spring_damper, i: a.m, j: b.m, stiffness: 50, damping: 2,\n"
                  "     free_length: 0.5, preload: kr/10}\n"
                  "  - {name: g, type: spring_damper, i: a.m, stiffness: 20, damping: 1, free_length: 0.3}\n"),
        "m.yaml");
    MultibodySystem su(user), sb(builtin);
    std::mt19937 rng(7);
    for (int trial = 0; trial < 3; ++trial) {
      const RandomState s = MakeRandomState(rng, user, su.num_constraints());
      const Eval eu = Evaluate(su, s.q, s.v), eb = Evaluate(sb, s.q, s.v);
      ASSERT_EQ(eu.code, 0) << su.last_error();
      ASSERT_EQ(eb.code, 0);
      EXPECT_LT(RelErr(eu.Q, eb.Q), 1e-13);
      const double tol = std::string(fn) == "mbdae_spring_damper" ? 1e-12 : 1e-7;
      EXPECT_LT(RelErr(eu.Kq, eb.Kq), tol);
      EXPECT_LT(RelErr(eu.Kv, eb.Kv), tol);
      double fu[3], tu[3], fb[3], tb[3];
      su.ForceAction(0, 0, s.q.data(), s.v.data(), fu, tu);
      sb.ForceAction(0, 0, s.q.data(), s.v.data(), fb, tb);
      for (int c = 0; c < 3; ++c) {
        EXPECT_NEAR(fu[c], fb[c], 1e-12 * std::max(1.0, std::abs(fb[c])));
        EXPECT_EQ(tu[c], 0.0);
      }
    }
  }
}

// A user function's error does not cross the DAE callback: Evaluate returns a negative
// (fatal) code and last_error names the element and the library's message.
TEST(TwoMarkerSystem, UserFunctionErrorIsFatalWithAMessage) {
  const Model m = LoadModelFromString(
      TwoBodies("  - {name: bad, type: user, library: " + kLibrary +
                ", function: mbdae_spring_damper_nojac, i: a.m, parameters: [1, 2, 3]}\n"),
      "m.yaml");
  MultibodySystem sys(m);
  std::vector<double> q, v;
  sys.InitialState(q, v);
  const Eval e = Evaluate(sys, q, v);
  EXPECT_LT(e.code, 0);
  EXPECT_TRUE(Contains(sys.last_error(), "user force 'bad'")) << sys.last_error();
  EXPECT_TRUE(Contains(sys.last_error(), "expected 4 parameters")) << sys.last_error();
  double f[3], t[3];
  EXPECT_THROW(sys.ForceAction(0, 0, q.data(), v.data(), f, t), std::runtime_error);
  // init failing (mbdae_spring_damper has an init that checks the count): at construction.
  const Model mi = LoadModelFromString(
      TwoBodies("  - {name: bad, type: user, library: " + kLibrary +
                ", function: mbdae_spring_damper, i: a.m, parameters: [1, 2, 3]}\n"),
      "m.yaml");
  try {
    MultibodySystem s2(mi);
    ADD_FAILURE() << "no exception";
  } catch (const std::runtime_error& ex) {
    EXPECT_TRUE(Contains(ex.what(), "user force 'bad'")) << ex.what();
  }
}

// Without damping, gravity and velocity, the bushings' generalized forces are minus the
// gradient of their potential along admissible directions (unit Euler parameters):
// Q . v = -dV/ds along q + s v, by central differences. And the damping dissipates.
TEST(TwoMarkerSystem, BushingForcesDeriveFromThePotential) {
  std::mt19937 rng(41);
  RandomModelOptions opt;
  opt.joints = false;
  opt.forces = false;
  opt.measures = false;
  opt.gravity = false;
  opt.bushings = true;
  Model model = RandomModel(rng, opt);
  // Keep the relative rotations moderate (theta is meant for deflections below pi).
  MultibodySystem sys(model);
  const int nq = sys.num_coordinates();
  for (int trial = 0; trial < 3; ++trial) {
    RandomState s = MakeRandomState(rng, model, sys.num_constraints(), true);
    for (int b = 0; b < static_cast<int>(model.bodies.size()); ++b) {
      // small rotations of every body: e close to (1, 0, 0, 0), rates tangent
      Quat e(1, 0.2 * (rng() % 100) / 100.0, -0.1, 0.15);
      e.normalize();
      Eigen::Map<Quat>(s.q.data() + 7 * b + 3) = e;
      const Quat ed = Eigen::Map<Quat>(s.v.data() + 7 * b + 3);
      Eigen::Map<Quat>(s.v.data() + 7 * b + 3) = ed - e.dot(ed) * e;
    }
    std::vector<double> zero(nq, 0.0);
    // Q at rest (no damping, no quadratic velocity terms).
    const Eval e0 = Evaluate(sys, s.q, zero);
    ASSERT_EQ(e0.code, 0);
    const double h = 1e-6;
    std::vector<double> qp = s.q, qm = s.q;
    for (int k = 0; k < nq; ++k) {
      qp[k] += h * s.v[k];
      qm[k] -= h * s.v[k];
    }
    const double dV = (sys.PotentialEnergy(0, qp.data()) - sys.PotentialEnergy(0, qm.data())) / (2 * h);
    const double Qv = e0.Q.dot(Eigen::Map<const VectorXd>(s.v.data(), nq));
    EXPECT_NEAR(Qv, -dV, 1e-6 * std::max(1.0, std::abs(dV)));
    EXPECT_GT(std::abs(dV), 1e-3);  // the check has something to see
    // Damping: Q(q, v) - Q(q, 0) does negative work minus the quadratic velocity terms,
    // which do none on rigid bodies with tangent rates: (Q(v) - Q(0)) . v < 0.
    const Eval ev = Evaluate(sys, s.q, s.v);
    const double power = (ev.Q - e0.Q).dot(Eigen::Map<const VectorXd>(s.v.data(), nq));
    EXPECT_LT(power, 0.0);
  }
}

// The writer writes bushing and user elements; reading the text back gives the same
// elements, and writing again the same text.
TEST(TwoMarkerWriter, RoundTripOfBushingAndUserElements) {
  const std::string text =
      TwoBodies("  - {name: bu, type: bushing, i: a.m, j: b.m, stiffness: [100, 200, 300, kr, 2*kr, 50],\n"
                "     damping: [1, 2, 3, 0.1, 0.2, 0.3]}\n"
                "  - {name: us, type: user, library: " + kLibrary +
                ", function: mbdae_spring_damper, i: a.m, j: b.m, parameters: [50, 2, 0.5, kr/10]}\n");
  const Model a = LoadModelFromString(text, "m.yaml");
  const std::string written = WriteModelYaml(a);
  Model b;
  try {
    b = LoadModelFromString(written, "m.yaml");
  } catch (const ModelError& e) {
    FAIL() << e.what() << "\n" << written;
  }
  EXPECT_EQ(WriteModelYaml(b), written);
  ASSERT_EQ(b.forces.size(), 2u);
  const std::vector<double> p = a.parameter_values();
  EXPECT_EQ(b.forces[0].type, ForceType::kBushing);
  for (int c = 0; c < 6; ++c) {
    EXPECT_EQ(b.forces[0].bushing_stiffness[c].text(), a.forces[0].bushing_stiffness[c].text());
    EXPECT_EQ(b.forces[0].bushing_damping[c].Evaluate(p.data()), a.forces[0].bushing_damping[c].Evaluate(p.data()));
  }
  EXPECT_EQ(b.forces[1].type, ForceType::kUser);
  EXPECT_EQ(b.forces[1].function, "mbdae_spring_damper");
  EXPECT_EQ(b.forces[1].library->path(), a.forces[1].library->path());
  ASSERT_EQ(b.forces[1].user_parameters.size(), 4u);
  EXPECT_EQ(b.forces[1].user_parameters[3].Evaluate(p.data()), 3.0);
  EXPECT_EQ(b.markers[b.forces[1].j].name, "b.m");
}

}  // namespace
}  // namespace mbdae::mbs
