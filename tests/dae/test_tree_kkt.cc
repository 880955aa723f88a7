// The tree elimination of [M C_q^T; C_q 0] (dae/tree_kkt.h) against KLU: the same a and
// lambda to 1e-10 (relative, max norm) on the test systems, a chain of 60 rods, and every
// model of tests/app/models that assembles; its refusals (closed loops, rows that touch
// nothing) and the fallback to KLU at a zero pivot (AccelerationSolver).
#include "dae/tree_kkt.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <dirent.h>
#include <random>
#include <string>
#include <vector>

#include "dae/consistent.h"
#include "mbs/loader.h"
#include "mbs/system.h"
#include "tests/support/ball_chain.h"
#include "tests/support/relative_difference.h"
#include "tests/support/free_body_system.h"
#include "tests/support/integrator_cases.h"
#include "tests/support/nonlinear_system.h"
#include "tests/support/pendulum_system.h"

namespace mbdae::dae {
namespace {

using testing::ConsistentState;

using testing::RelativeDifference;

struct Comparison {
  bool tree = false;      // the tree elimination was used
  double da = 0, dl = 0;  // relative differences of a and lambda against KLU
};

// a and lambda at (t, q, v) by KLU and by AccelerationSolver with the tree elimination,
// twice each (a second call must not depend on state left by the first).
Comparison Compare(MechanicalSystem& sys, double t, const std::vector<double>& q,
                   const std::vector<double>& v) {
  const int nq = sys.num_coordinates(), nc = sys.num_constraints();
  AccelerationSolver klu(sys), tree(sys, 1, true);
  std::vector<double> a0(nq), l0(nc), a1(nq), l1(nc);
  Comparison c;
  for (int rep = 0; rep < 2; ++rep) {
    EXPECT_EQ(klu.Solve(t, q.data(), v.data(), a0.data(), l0.data()), 0) << klu.last_error();
    EXPECT_EQ(tree.Solve(t, q.data(), v.data(), a1.data(), l1.data()), 0) << tree.last_error();
    c.tree = tree.used_tree();
    c.da = std::max(c.da, RelativeDifference(a1, a0));
    c.dl = std::max(c.dl, RelativeDifference(l1, l0));
  }
  // SolveAgain with another right side: the factorisation each kept.
  std::vector<double> r0(nq + nc), r1;
  for (int i = 0; i < nq + nc; ++i) r0[i] = std::sin(1.0 + i);
  r1 = r0;
  klu.SolveAgain(r0.data());
  tree.SolveAgain(r1.data());
  c.da = std::max(c.da, RelativeDifference(r1, r0));
  return c;
}

TEST(TreeKkt, MatchesKluOnTheTestSystems) {
  {
    testing::PendulumSystem sys(1.3, 0.8, 9.81);
    const State x = ConsistentState(sys, {0.6, -std::sqrt(0.64 - 0.36)}, {1.0, 0.75});
    const Comparison c = Compare(sys, 0, x.q, x.v);
    EXPECT_TRUE(c.tree);
    EXPECT_LT(c.da, 1e-13);
    EXPECT_LT(c.dl, 1e-13);
  }
  {
    testing::FreeBodySystem sys(2.0, {0.7, 1.3, 2.1}, {0, 0, 0}, {0, 0, 0});
    const double n = std::sqrt(1 + 0.04 + 0.09 + 0.16);
    const State x = ConsistentState(sys, {0.1, 0.2, 0.3, 1 / n, 0.2 / n, 0.3 / n, 0.4 / n},
                                    {0.1, 0, 0.2, 0, 0.15, 1.0, 0.05});
    const Comparison c = Compare(sys, 0, x.q, x.v);
    EXPECT_TRUE(c.tree);
    EXPECT_LT(c.da, 1e-13);
    EXPECT_LT(c.dl, 1e-13);
  }
  {
    testing::NonlinearSystem sys;
    const State x = ConsistentState(sys, {0.5, 0.3, 0.7}, {0.2, -0.4, 0.9});
    const Comparison c = Compare(sys, 0, x.q, x.v);
    EXPECT_LT(c.da, 1e-12);
    EXPECT_LT(c.dl, 1e-12);
    std::printf("nonlinear system: tree %d, differences %.1e %.1e\n", c.tree, c.da, c.dl);
  }
}

std::string ChainYaml(int n) { return mbdae::testing::BallChainYaml(n, 0.1); }

// (q, v) of `model` made consistent, the independent constraints kept; false when it
// does not assemble.
struct Assembled {
  std::unique_ptr<mbs::MultibodySystem> full;
  std::unique_ptr<MechanicalSystem> kept;
  State x;
};
bool Assemble(const mbs::Model& model, Assembled* out) {
  out->full = std::make_unique<mbs::MultibodySystem>(model);
  MechanicalSystem& sys = *out->full;
  out->x.Resize(sys.num_coordinates(), sys.num_constraints());
  out->full->InitialState(out->x.q, out->x.v);
  const ConsistencyReport rep = MakeConsistent(sys, out->x);
  if (!rep.ok) return false;
  std::vector<int> kept;
  for (int r = 0; r < sys.num_constraints(); ++r)
    if (std::find(rep.redundant.begin(), rep.redundant.end(), r) == rep.redundant.end())
      kept.push_back(r);
  out->kept = KeepConstraints(sys, kept);
  return true;
}

// A generic velocity: v + a pseudo-random perturbation (the acceleration-level solve does
// not need v on the velocity constraints).
std::vector<double> Perturbed(std::vector<double> v, unsigned seed) {
  std::mt19937 gen(seed);
  std::uniform_real_distribution<double> u(-1, 1);
  for (double& x : v) x += u(gen);
  return v;
}

TEST(TreeKkt, MatchesKluOnAChainOfSixtyRods) {
  const mbs::Model model = mbs::LoadModelFromString(ChainYaml(60), "chain.yaml");
  Assembled as;
  ASSERT_TRUE(Assemble(model, &as));
  // A bent, moving chain: positions perturbed off the line (KLU and the tree see the same
  // matrix whether or not it is on the constraints).
  std::vector<double> q = as.x.q;
  std::mt19937 gen(3);
  std::uniform_real_distribution<double> u(-0.02, 0.02);
  for (double& x : q) x += u(gen);
  const Comparison c = Compare(*as.kept, 0.3, q, Perturbed(as.x.v, 7));
  std::printf("chain of 60 rods: differences a %.1e, lambda %.1e\n", c.da, c.dl);
  EXPECT_TRUE(c.tree);
  EXPECT_LT(c.da, 1e-10);
  EXPECT_LT(c.dl, 1e-10);
  std::string why;
  auto tree = TreeKktSolver::Analyze(as.kept->pattern(Matrix::kMass),
                                     as.kept->pattern(Matrix::kConstraintDq), 48, &why);
  ASSERT_TRUE(tree) << why;
  EXPECT_EQ(tree->num_nodes(), 60 + 59);  // rods and the joints between them
  EXPECT_EQ(tree->largest_node(), 7 + 1 + 3);  // rod 1: its normalisation and ground joint
}

TEST(TreeKkt, MatchesKluOnEveryTestModel) {
  const std::string dir = MBDAE_TEST_MODELS;
  std::vector<std::string> files;
  if (DIR* d = opendir(dir.c_str())) {
    while (dirent* e = readdir(d)) {
      const std::string name = e->d_name;
      if (name.size() > 5 && name.substr(name.size() - 5) == ".yaml") files.push_back(name);
    }
    closedir(d);
  }
  std::sort(files.begin(), files.end());
  ASSERT_GE(files.size(), 10u);
  int compared = 0, trees = 0;
  for (const std::string& f : files) {
    mbs::Model model;
    try {
      model = mbs::LoadModel(dir + "/" + f);
    } catch (const std::exception&) {
      continue;  // a model that must not load (bad_mass.yaml ...)
    }
    Assembled as;
    try {
      if (!Assemble(model, &as)) continue;  // unassemblable.yaml
    } catch (const std::exception&) {
      continue;
    }
    AccelerationSolver probe(*as.kept, 1, true);
    std::vector<double> a(as.x.q.size()), l(as.kept->num_constraints());
    if (probe.Solve(as.x.t, as.x.q.data(), as.x.v.data(), a.data(), l.data()) != 0)
      continue;  // singular at its initial state (fourbar_singular.yaml at a dead point)
    for (unsigned seed : {1u, 2u}) {
      const Comparison c = Compare(*as.kept, as.x.t, as.x.q, Perturbed(as.x.v, seed));
      EXPECT_LT(c.da, 1e-10) << f;
      EXPECT_LT(c.dl, 1e-10) << f;
      if (seed == 1)
        std::printf("%-28s %s: differences a %.1e, lambda %.1e\n", f.c_str(),
                    c.tree ? "tree" : ("KLU (" + probe.tree_refusal() + ")").c_str(), c.da,
                    c.dl);
      trees += c.tree && seed == 1;
    }
    ++compared;
  }
  EXPECT_GE(compared, 8);
  EXPECT_GE(trees, 5);
}

TEST(TreeKkt, RefusesLoopsAndEmptyRows) {
  // Two particles (x0, x1) and two rows that both touch both: x0 - x1 and x0 + x1 form
  // one joint node, no loop; a third particle tied to both by separate rows closes one.
  const CscPattern m3 = CscPattern::FromEntries(3, 3, {{0, 0}, {1, 1}, {2, 2}});
  std::string why;
  EXPECT_TRUE(TreeKktSolver::Analyze(
      m3, CscPattern::FromEntries(2, 3, {{0, 0}, {0, 1}, {1, 0}, {1, 1}}), 48, &why))
      << why;
  EXPECT_FALSE(TreeKktSolver::Analyze(
      m3, CscPattern::FromEntries(3, 3, {{0, 0}, {0, 1}, {1, 1}, {1, 2}, {2, 2}, {2, 0}}), 48,
      &why));
  EXPECT_NE(why.find("closed loop"), std::string::npos) << why;
  EXPECT_FALSE(TreeKktSolver::Analyze(m3, CscPattern::FromEntries(2, 3, {{0, 0}}), 48, &why));
  EXPECT_NE(why.find("row 1 touches no coordinate"), std::string::npos) << why;
  // A dense 3 x 3 mass with a limit of 2 unknowns per node.
  std::vector<std::pair<int, int>> dense;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) dense.push_back({i, j});
  EXPECT_FALSE(TreeKktSolver::Analyze(CscPattern::FromEntries(3, 3, dense),
                                      CscPattern::FromEntries(0, 3, {}), 2, &why));
  EXPECT_NE(why.find("3 unknowns"), std::string::npos) << why;
}

// x0 (mass 1, tied by row 0) and a body y of two coordinates (mass m(t) I, rows 1 and
// 2: y_k - x0) hanging from it: a tree, root x0. Where m = 0 (0.4 < t < 0.6) eliminating
// the leaf y meets a zero pivot, though [M C^T; C 0] is regular: KLU solves it there.
class MasslessLeaf final : public MechanicalSystem {
 public:
  MasslessLeaf() {
    mass_ = CscPattern::FromEntries(3, 3, {{0, 0}, {1, 1}, {1, 2}, {2, 1}, {2, 2}});
    cq_ = CscPattern::FromEntries(3, 3, {{0, 0}, {1, 0}, {2, 0}, {1, 1}, {2, 2}});
  }
  int num_coordinates() const override { return 3; }
  int num_constraints() const override { return 3; }
  const CscPattern& pattern(Matrix m) const override {
    return m == Matrix::kMass ? mass_ : m == Matrix::kConstraintDq ? cq_ : empty_;
  }
  int Evaluate(const EvalInput& in, EvalOutput& out) override {
    const double m = in.t > 0.4 && in.t < 0.6 ? 0.0 : 2.0;
    if (double* f = out.force) f[0] = -9.81, f[1] = 0.5, f[2] = -0.25;
    if (double* g = out.acc_rhs) g[0] = 0.3, g[1] = 0.1 * std::sin(in.t), g[2] = -0.2;
    // Column order: M (0,0); (1,1) (2,1); (1,2) (2,2). C_q: (0,0) (1,0) (2,0); (1,1); (2,2).
    if (double* M = out[Matrix::kMass]) M[0] = 1, M[1] = m, M[2] = 0, M[3] = 0, M[4] = m;
    if (double* C = out[Matrix::kConstraintDq]) C[0] = 1, C[1] = -1, C[2] = -1, C[3] = 1, C[4] = 1;
    return 0;
  }

 private:
  CscPattern mass_, cq_, empty_;
};

TEST(TreeKkt, ZeroPivotFallsBackToKlu) {
  MasslessLeaf sys;
  AccelerationSolver solver(sys, 1, true), klu(sys);
  EXPECT_EQ(solver.tree_refusal(), "");
  EXPECT_EQ(klu.tree_refusal(), "not requested");
  std::vector<double> q(3, 0), v(3, 0), a(3), l(3), a0(3), l0(3);
  for (double t : {0.0, 0.5, 1.0}) {
    ASSERT_EQ(solver.Solve(t, q.data(), v.data(), a.data(), l.data()), 0) << solver.last_error();
    ASSERT_EQ(klu.Solve(t, q.data(), v.data(), a0.data(), l0.data()), 0) << klu.last_error();
    EXPECT_EQ(solver.used_tree(), t != 0.5) << t;
    // a0 = 0.3, a_k = gamma_k + a0; lambda_k = Q_k - m a_k; lambda_0 = Q_0 - a0 + sum.
    const double m = t == 0.5 ? 0 : 2;
    const double ex[3] = {0.3, 0.3 + 0.1 * std::sin(t), 0.1};
    const double lk[2] = {0.5 - m * ex[1], -0.25 - m * ex[2]};
    const double el[3] = {-9.81 - 0.3 + lk[0] + lk[1], lk[0], lk[1]};
    for (int i = 0; i < 3; ++i) {
      EXPECT_NEAR(a[i], ex[i], 1e-14) << t;
      EXPECT_NEAR(l[i], el[i], 1e-14) << t;
      EXPECT_NEAR(a0[i], ex[i], 1e-14) << t;
      EXPECT_NEAR(l0[i], el[i], 1e-14) << t;
    }
  }
  EXPECT_EQ(solver.klu_fallbacks(), 1);
  EXPECT_EQ(solver.tree_refusal(), "");
  // A first factorisation that fails turns the tree off for good.
  AccelerationSolver late(sys, 1, true);
  ASSERT_EQ(late.Solve(0.5, q.data(), v.data(), a.data(), l.data()), 0) << late.last_error();
  ASSERT_EQ(late.Solve(1.0, q.data(), v.data(), a.data(), l.data()), 0) << late.last_error();
  EXPECT_FALSE(late.used_tree());
  EXPECT_EQ(late.klu_fallbacks(), 1);
  EXPECT_NE(late.tree_refusal().find("first state"), std::string::npos) << late.tree_refusal();
}

}  // namespace
}  // namespace mbdae::dae
