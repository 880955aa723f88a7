// driver::AnalyseDeterminacy (structural pre-pass, numeric test on the groups of bodies
// without a positive mass and inertia) against driver::DenseDeterminacy (FullPivLU of
// the whole equilibrated [M C_q^T; C_q 0], the method the check used before) on random
// small mechanisms: chains, closed loops (with redundant equations), floating bodies,
// with random masses and inertias of which some are zero. Both must agree on whether
// the matrix is singular and name the same bodies.
#include <gtest/gtest.h>

#include <algorithm>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include "dae/consistent.h"
#include "driver/determinacy.h"
#include "driver/simulation.h"
#include "mbs/loader.h"
#include "mbs/system.h"

namespace {

using namespace mbdae;

struct Mechanism {
  std::string yaml;
  std::string kind;
};

// A body's mass and inertia: regular, a point mass, massless, massless and inertia-free,
// or a thin rod (one zero moment).
std::string MassText(std::mt19937& rng) {
  std::uniform_real_distribution<double> u(0.5, 2.0);
  std::ostringstream s;
  s.precision(17);
  const double m = u(rng), a = u(rng), b = u(rng);
  switch (std::uniform_int_distribution<int>(0, 6)(rng)) {
    case 0: s << "mass: " << m << ", inertia: [0, 0, 0]"; break;
    case 1: s << "mass: 0, inertia: [" << a << ", " << a << ", " << a << "]"; break;
    case 2: s << "mass: 0, inertia: [0, 0, 0]"; break;
    case 3: s << "mass: " << m << ", inertia: [0, " << a << ", " << a << "]"; break;
    default: s << "mass: " << m << ", inertia: [" << a << ", " << b << ", " << (a + b) * 0.75 << "]";
  }
  return s.str();
}

const char* JointType(std::mt19937& rng) {
  static const char* kTypes[] = {"spherical", "revolute", "spherical", "universal"};
  return kTypes[std::uniform_int_distribution<int>(0, 3)(rng)];
}

std::string Body(const std::string& name, const std::string& mass, double x, double y,
                 const std::string& markers) {
  std::ostringstream s;
  s << "  - {name: " << name << ", " << mass << ", position: [" << x << ", " << y
    << ", 0], markers: {" << markers << "}}\n";
  return s.str();
}

// An open chain of n rods along x (0.2 m each), the first to the ground.
Mechanism Chain(std::mt19937& rng, int n) {
  std::ostringstream s;
  s << "format: 1\nname: chain\ngravity: [0, -9.81, 0]\nbodies:\n";
  for (int k = 0; k < n; ++k)
    s << Body("b" + std::to_string(k), MassText(rng), 0.2 * k + 0.1, 0,
              "A: {position: [-0.1, 0, 0]}, B: {position: [0.1, 0, 0]}");
  s << "joints:\n";
  for (int k = 0; k < n; ++k)
    s << "  - {name: j" << k << ", type: " << JointType(rng) << ", i: b" << k << ".A, j: "
      << (k == 0 ? std::string("ground.O") : "b" + std::to_string(k - 1) + ".B") << "}\n";
  return {s.str(), "chain"};
}

// A closed four-bar (a parallelogram of 1 m cranks and coupler) with random joint types:
// revolute loops have redundant equations.
Mechanism Loop(std::mt19937& rng) {
  std::ostringstream s;
  s << "format: 1\nname: loop\ngravity: [0, -9.81, 0]\nbodies:\n";
  s << Body("crank", MassText(rng), 0, 0.5, "A: {position: [0, -0.5, 0]}, B: {position: [0, 0.5, 0]}");
  s << Body("coupler", MassText(rng), 0.5, 1, "A: {position: [-0.5, 0, 0]}, B: {position: [0.5, 0, 0]}");
  s << Body("rocker", MassText(rng), 1, 0.5, "A: {position: [0, 0.5, 0]}, B: {position: [0, -0.5, 0]}");
  s << "  - {name: pivot, mass: 0, inertia: [0, 0, 0], position: [1, 0, 0], markers: {P: {position: [0, 0, 0]}}}\n";
  s << "joints:\n";
  s << "  - {name: j0, type: revolute, i: crank.A, j: ground.O}\n";
  s << "  - {name: j1, type: " << JointType(rng) << ", i: coupler.A, j: crank.B}\n";
  s << "  - {name: j2, type: " << JointType(rng) << ", i: rocker.A, j: coupler.B}\n";
  s << "  - {name: j3, type: revolute, i: rocker.B, j: pivot.P}\n";
  s << "  - {name: j4, type: fixed, i: pivot.P, j: ground.O}\n";
  return {s.str(), "loop"};
}

// A floating body, and a chain of two beside it.
Mechanism Floating(std::mt19937& rng) {
  std::ostringstream s;
  s << "format: 1\nname: floating\ngravity: [0, -9.81, 0]\nbodies:\n";
  s << Body("free", MassText(rng), 3, 3, "C: {position: [0, 0, 0]}");
  s << Body("arm", MassText(rng), 0.1, 0, "A: {position: [-0.1, 0, 0]}, B: {position: [0.1, 0, 0]}");
  s << "joints:\n";
  s << "  - {name: j0, type: " << JointType(rng) << ", i: arm.A, j: ground.O}\n";
  return {s.str(), "floating"};
}

struct Analysed {
  driver::DeterminacyResult fast, dense;
};

// Both methods on the kept system (redundant equations set aside, normalisations first)
// at the model's initial state, which closes exactly.
Analysed OnKeptSystem(const mbs::Model& model, int max_dense_columns = 1400) {
  mbs::MultibodySystem sys(model);
  const int nq = sys.num_coordinates(), nc = sys.num_constraints();
  dae::State x;
  x.Resize(nq, nc);
  sys.InitialState(x.q, x.v);
  std::vector<int> order;
  for (int e = 0; e < nc; ++e)
    if (sys.constraint_joint()[e] < 0) order.push_back(e);
  for (int e = 0; e < nc; ++e)
    if (sys.constraint_joint()[e] >= 0) order.push_back(e);
  const std::vector<int> redundant = dae::FindRedundantConstraints(sys, 0, x.q.data(), 1e-9, order);
  std::vector<int> kept;
  for (int e = 0, k = 0; e < nc; ++e) {
    if (k < static_cast<int>(redundant.size()) && redundant[k] == e) ++k;
    else kept.push_back(e);
  }
  auto view = dae::KeepConstraints(sys, kept);
  x.lambda.assign(kept.size(), 0.0);
  driver::DeterminacyOptions o;
  o.check_constraint_rank = false;
  o.max_dense_columns = max_dense_columns;
  return {driver::AnalyseDeterminacy(model, *view, x, o), driver::DenseDeterminacy(model, *view, x, 1e-10)};
}

TEST(Determinacy, AgreesWithTheDenseLuOnRandomMechanisms) {
  std::mt19937 rng(20261124);
  int singular = 0, regular = 0;
  for (int trial = 0; trial < 120; ++trial) {
    Mechanism m = trial % 3 == 0 ? Chain(rng, 1 + trial % 5) : trial % 3 == 1 ? Loop(rng) : Floating(rng);
    SCOPED_TRACE(m.kind + " (trial " + std::to_string(trial) + "):\n" + m.yaml);
    mbs::Model model = mbs::LoadModelFromString(m.yaml, "random.yaml");
    const Analysed a = OnKeptSystem(model);
    EXPECT_EQ(a.fast.singular, a.dense.singular);
    EXPECT_EQ(a.fast.bodies, a.dense.bodies);
    (a.dense.singular ? singular : regular) += 1;
  }
  // Both kinds occur, so the comparison decides something.
  EXPECT_GT(singular, 20);
  EXPECT_GT(regular, 20);
}

TEST(Determinacy, FullSystemWithRedundantEquationsIsSingularLikeTheDenseLu) {
  // The planar parallelogram with revolute joints only: C_q has dependent rows.
  const std::string yaml =
      "format: 1\nname: loop\ngravity: [0, -9.81, 0]\nbodies:\n" +
      Body("crank", "mass: 1, inertia: [1, 1, 1]", 0, 0.5, "A: {position: [0, -0.5, 0]}, B: {position: [0, 0.5, 0]}") +
      Body("coupler", "mass: 1, inertia: [1, 1, 1]", 0.5, 1, "A: {position: [-0.5, 0, 0]}, B: {position: [0.5, 0, 0]}") +
      Body("rocker", "mass: 1, inertia: [1, 1, 1]", 1, 0.5, "A: {position: [0, 0.5, 0]}, B: {position: [0, -0.5, 0]}") +
      "joints:\n  - {name: j0, type: revolute, i: crank.A, j: ground.O}\n"
      "  - {name: j1, type: revolute, i: coupler.A, j: crank.B}\n"
      "  - {name: j2, type: revolute, i: rocker.A, j: coupler.B}\n"
      "  - {name: j3, type: revolute, i: rocker.B, j: ground.O}\n";
  // j3's ground marker is the origin: move it to (1, 0, 0) with a ground marker.
  std::string text = yaml;
  text.replace(text.find("bodies:"), 7, "ground: {markers: {P: {position: [1, 0, 0]}}}\nbodies:");
  text.replace(text.find("i: rocker.B, j: ground.O"), 24, "i: rocker.B, j: ground.P");
  mbs::Model model;
  try {
    model = mbs::LoadModelFromString(text, "loop.yaml");
  } catch (const std::exception& e) {
    GTEST_SKIP() << "ground markers not in this format: " << e.what();
  }
  mbs::MultibodySystem sys(model);
  dae::State x;
  x.Resize(sys.num_coordinates(), sys.num_constraints());
  sys.InitialState(x.q, x.v);
  const driver::DeterminacyResult fast = driver::AnalyseDeterminacy(model, sys, x);
  const driver::DeterminacyResult dense = driver::DenseDeterminacy(model, sys, x, 1e-10);
  EXPECT_TRUE(dense.singular);
  EXPECT_TRUE(fast.singular);
  EXPECT_TRUE(fast.bodies.empty());
  EXPECT_EQ(fast.irregular_bodies, 0);
}

TEST(Determinacy, SparseRankOfLargeGroupsDecidesLikeTheDenseLu) {
  // Groups above max_dense_columns go to the sparse QR (rank only; it names the
  // group's bodies with zero mass or a singular inertia).
  std::mt19937 rng(7);
  for (int trial = 0; trial < 40; ++trial) {
    Mechanism m = trial % 2 ? Chain(rng, 2 + trial % 4) : Loop(rng);
    SCOPED_TRACE(m.yaml);
    mbs::Model model = mbs::LoadModelFromString(m.yaml, "random.yaml");
    const Analysed a = OnKeptSystem(model, /*max_dense_columns=*/1);
    EXPECT_EQ(a.fast.singular, a.dense.singular);
    for (const std::string& name : a.dense.bodies)
      EXPECT_NE(std::find(a.fast.bodies.begin(), a.fast.bodies.end(), name), a.fast.bodies.end()) << name;
  }
}

TEST(Determinacy, ChainOfRegularBodiesNeedsNoNumericTest) {
  std::ostringstream s;
  s << "format: 1\nname: chain\ngravity: [0, -9.81, 0]\nbodies:\n";
  const int n = 2000;
  for (int k = 0; k < n; ++k)
    s << Body("b" + std::to_string(k), "mass: 1, inertia: [1.0e-5, 8.0e-4, 8.0e-4]", 0.1 * k + 0.05, 0,
              "A: {position: [-0.05, 0, 0]}, B: {position: [0.05, 0, 0]}");
  s << "joints:\n";
  for (int k = 0; k < n; ++k)
    s << "  - {name: j" << k << ", type: spherical, i: b" << k << ".A, j: "
      << (k == 0 ? std::string("ground.O") : "b" + std::to_string(k - 1) + ".B") << "}\n";
  mbs::Model model = mbs::LoadModelFromString(s.str(), "chain.yaml");
  driver::Assembly asmb = driver::Assemble(model);  // with the determinacy check
  const driver::DeterminacyResult r = driver::AnalyseDeterminacy(
      model, *asmb.kept_system, asmb.x0, driver::DeterminacyOptions{1e-10, 1e-6, 1400, false});
  EXPECT_FALSE(r.singular);
  EXPECT_EQ(r.irregular_bodies, 0);
  // One point mass in the middle: its spin about the chain is undetermined, and only it
  // is named.
  std::string text = s.str();
  const std::string point = "b1000, mass: 1, inertia: [1.0e-5, 8.0e-4, 8.0e-4]";
  text.replace(text.find(point), point.size(), "b1000, mass: 1, inertia: [0, 0, 0]");
  mbs::Model with_point = mbs::LoadModelFromString(text, "chain.yaml");
  try {
    driver::Assemble(with_point);
    ADD_FAILURE() << "the point mass's spin is not determined";
  } catch (const driver::InputError& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("not determined by their joints: b1000"), std::string::npos) << what;
    EXPECT_EQ(what.find("b999"), std::string::npos) << what;
  }
}

}  // namespace
