// The block tree elimination (dae/block_tree_lu.h): solutions against a dense LU on random
// nonsymmetric forests (fixed-size and generic kernels), against KLU on HHT's Newton matrix
// of a chain of rods (with springs between neighbours, which couple bodies directly), its
// refusals, and HHT with HhtOptions::LinearSolver::kTree against KLU (the same steps and
// states to round-off; a loop falls back to KLU with the reason; a pendulum, the
// single-body tree, is covered by tests/app/test_linear_solver.py), and IDA with
// IdaOptions::linear_solver kTree against KLU.
#include "dae/block_tree_lu.h"

#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include "dae/consistent.h"
#include "dae/hht.h"
#include "dae/ida.h"
#include "dae/klu_solver.h"
#include "mbs/loader.h"
#include "mbs/system.h"
#include "tests/support/ball_chain.h"
#include "tests/support/relative_difference.h"

namespace mbdae::dae {
namespace {

using testing::RelativeDifference;

// A random forest of `nn` nodes with sizes in 1..max_size, its unknowns shuffled, and a
// nonsymmetric matrix on it: dense diagonal blocks made diagonally dominant, blocks
// between each node and about half of its parent's unknowns with some entries left out of
// the pattern.
struct RandomForest {
  std::vector<std::vector<int>> nodes;
  std::vector<int> parent;
  Eigen::MatrixXd dense;
  CscPattern pattern;
  std::vector<double> values;
};

RandomForest MakeRandomForest(int nn, int max_size, unsigned seed) {
  std::mt19937 gen(seed);
  std::uniform_int_distribution<int> size(1, max_size);
  std::uniform_real_distribution<double> u(-1, 1), coin(0, 1);
  RandomForest f;
  f.nodes.resize(nn);
  f.parent.resize(nn);
  int n = 0;
  for (int i = 0; i < nn; ++i) {
    const int s = size(gen);
    for (int k = 0; k < s; ++k) f.nodes[i].push_back(n++);
    // Node 0 and about one in five others are roots; the rest hang below an earlier node.
    f.parent[i] = (i == 0 || coin(gen) < 0.2) ? -1 : std::uniform_int_distribution<int>(0, i - 1)(gen);
  }
  std::vector<int> shuffle(n);
  for (int k = 0; k < n; ++k) shuffle[k] = k;
  std::shuffle(shuffle.begin(), shuffle.end(), gen);
  for (auto& node : f.nodes)
    for (int& x : node) x = shuffle[x];
  f.dense = Eigen::MatrixXd::Zero(n, n);
  std::vector<std::pair<int, int>> entries;
  auto put = [&](int r, int c, double v) {
    f.dense(r, c) = v;
    entries.push_back({r, c});
  };
  for (int i = 0; i < nn; ++i) {
    for (int r : f.nodes[i])
      for (int c : f.nodes[i]) put(r, c, r == c ? 0.0 : u(gen));
    if (f.parent[i] < 0) continue;
    // The coupling touches about half of the parent's unknowns (the node's interface).
    for (int c : f.nodes[f.parent[i]]) {
      if (coin(gen) < 0.5) continue;
      for (int r : f.nodes[i]) {
        if (coin(gen) < 0.7) put(r, c, u(gen));
        if (coin(gen) < 0.7) put(c, r, u(gen));
      }
    }
  }
  for (int r = 0; r < n; ++r) f.dense(r, r) = 2.0 + f.dense.row(r).cwiseAbs().sum();
  f.pattern = CscPattern::FromEntries(n, n, entries);
  f.values.assign(f.pattern.nnz(), 0.0);
  for (int c = 0; c < n; ++c)
    for (int k = f.pattern.col_start[c]; k < f.pattern.col_start[c + 1]; ++k)
      f.values[k] = f.dense(f.pattern.row_index[k], c);
  return f;
}

TEST(BlockTreeLu, MatchesDenseLuOnRandomForests) {
  // Node sizes up to 12 (the fixed-size kernels) and up to 16 (the generic ones).
  for (int max_size : {12, 16})
    for (unsigned seed = 1; seed <= 20; ++seed) {
      RandomForest f = MakeRandomForest(25, max_size, seed);
      std::string why;
      auto lu = BlockTreeLu::Analyze(f.pattern, f.nodes, f.parent, 48, &why);
      ASSERT_TRUE(lu) << why;
      ASSERT_TRUE(lu->Factor(f.values.data(), &why)) << why;
      const int n = f.pattern.rows;
      std::vector<double> b(n), x(n), ref(n);
      for (int i = 0; i < n; ++i) b[i] = std::sin(0.3 * i + seed);
      x = b;
      lu->Solve(x.data());
      const Eigen::VectorXd r = f.dense.partialPivLu().solve(Eigen::Map<Eigen::VectorXd>(b.data(), n));
      for (int i = 0; i < n; ++i) ref[i] = r[i];
      EXPECT_LT(RelativeDifference(x, ref), 1e-12) << "max size " << max_size << ", seed " << seed;
      EXPECT_GT(lu->rcond(), 0);
      EXPECT_LT(lu->BackwardError(f.values.data()), 1e-14);
      EXPECT_EQ(lu->num_nodes(), 25);
      // A second factorisation with other values (the pattern's zeros stay zero).
      for (double& v : f.values) v *= 1.5;
      ASSERT_TRUE(lu->Factor(f.values.data(), &why)) << why;
      x = b;
      lu->Solve(x.data());
      for (int i = 0; i < n; ++i) EXPECT_NEAR(x[i], ref[i] / 1.5, 1e-12 * (1 + std::abs(ref[i])));
    }
}

TEST(BlockTreeLu, RefusesWhatIsNoForestAndReportsZeroPivots) {
  // Three nodes {0}, {1}, {2}: 1 and 2 below 0.
  const std::vector<std::vector<int>> nodes = {{0}, {1}, {2}};
  const std::vector<int> parent = {-1, 0, 0};
  std::string why;
  const CscPattern ok = CscPattern::FromEntries(3, 3, {{0, 0}, {1, 1}, {2, 2}, {0, 1}, {2, 0}});
  EXPECT_TRUE(BlockTreeLu::Analyze(ok, nodes, parent, 48, &why)) << why;
  // An entry between the two children.
  const CscPattern siblings = CscPattern::FromEntries(3, 3, {{0, 0}, {1, 1}, {2, 2}, {1, 2}});
  EXPECT_FALSE(BlockTreeLu::Analyze(siblings, nodes, parent, 48, &why));
  EXPECT_NE(why.find("entry (1, 2) couples nodes 1 and 2"), std::string::npos) << why;
  EXPECT_FALSE(BlockTreeLu::Analyze(ok, {{0}, {1, 0}, {2}}, parent, 48, &why));
  EXPECT_NE(why.find("unknown 0 is in nodes 0 and 1"), std::string::npos) << why;
  EXPECT_FALSE(BlockTreeLu::Analyze(ok, {{0}, {1}}, {-1, 0}, 48, &why));
  EXPECT_NE(why.find("unknown 2 is in no node"), std::string::npos) << why;
  EXPECT_FALSE(BlockTreeLu::Analyze(ok, nodes, {1, 2, 0}, 48, &why));
  EXPECT_NE(why.find("cycle"), std::string::npos) << why;
  EXPECT_FALSE(BlockTreeLu::Analyze(ok, {{0, 1, 2}}, {-1}, 2, &why));
  EXPECT_NE(why.find("3 unknowns (more than 2)"), std::string::npos) << why;
  EXPECT_FALSE(BlockTreeLu::Analyze(CscPattern::FromEntries(2, 3, {{0, 0}}), nodes, parent, 48, &why));
  EXPECT_NE(why.find("not square"), std::string::npos) << why;
  // [0 1; 1 0] in one node: partial pivoting within the node handles it; split over two
  // nodes (child {1} eliminated first, its block 0) it is a zero pivot.
  const CscPattern swap = CscPattern::FromEntries(2, 2, {{0, 1}, {1, 0}});
  const double v[] = {1.0, 1.0};
  auto one = BlockTreeLu::Analyze(swap, {{0, 1}}, {-1}, 48, &why);
  ASSERT_TRUE(one) << why;
  EXPECT_TRUE(one->Factor(v, &why)) << why;
  // One 2 x 2 node: the LU's one division and multiply-add (1 + 2), the solve 2 m^2.
  EXPECT_EQ(one->factor_flops(), 3.0);
  EXPECT_EQ(one->solve_flops(), 8.0);
  auto two = BlockTreeLu::Analyze(swap, {{0}, {1}}, {-1, 0}, 48, &why);
  ASSERT_TRUE(two) << why;
  EXPECT_FALSE(two->Factor(v, &why));
  EXPECT_NE(why.find("zero pivot"), std::string::npos) << why;
  EXPECT_EQ(two->rcond(), 0);
}

// A chain of n rods (tests/support/ball_chain.h) with a spring-damper between the middles
// of each pair of neighbours when `springs`: forces that couple two bodies directly.
std::string ChainYaml(int n, bool springs) {
  std::string y = mbdae::testing::BallChainYaml(n, 0.05);
  if (!springs) return y;
  const size_t at = y.find("simulation:");
  std::string f = "forces:\n";
  for (int k = 2; k <= n; ++k)
    f += "  - {name: s" + std::to_string(k) + ", type: spring_damper, i: rod" + std::to_string(k) +
         ".cm, j: rod" + std::to_string(k - 1) +
         ".cm, stiffness: 200, damping: 0.5, free_length: 0.1}\n";
  return y.substr(0, at) + f + y.substr(at);
}

// A model made consistent, its independent constraints kept (all of them unless some are
// redundant): `kept` and its state `x`, as driver::Assemble hands them to an integrator.
struct Consistent {
  mbs::Model model;
  std::unique_ptr<mbs::MultibodySystem> system;
  std::unique_ptr<MechanicalSystem> kept;
  State x;
  size_t redundant = 0;
  explicit Consistent(const std::string& yaml)
      : model(mbs::LoadModelFromString(yaml, "test.yaml")),
        system(std::make_unique<mbs::MultibodySystem>(model)) {
    State full;
    full.Resize(system->num_coordinates(), system->num_constraints());
    system->InitialState(full.q, full.v);
    const ConsistencyReport rep = MakeConsistent(*system, full);
    EXPECT_TRUE(rep.ok) << rep.message;
    redundant = rep.redundant.size();
    std::vector<int> rows;
    for (int r = 0; r < system->num_constraints(); ++r)
      if (std::find(rep.redundant.begin(), rep.redundant.end(), r) == rep.redundant.end())
        rows.push_back(r);
    kept = KeepConstraints(*system, rows);
    x = full;
    x.lambda.resize(rows.size());
    for (size_t k = 0; k < rows.size(); ++k) x.lambda[k] = full.lambda[rows[k]];
  }
};

// HHT with KLU and with the tree on c's kept system from its consistent state to t_end.
// The tree's jacobian_cost is 0 unless given: the same refresh rules as KLU's, so that the
// two runs differ only by the linear solver.
struct KluAndTree {
  std::unique_ptr<Integrator> klu, tree;
  // The tree's defaults (refresh by cost, linear predictor, exact rotation blocks) off
  // unless asked for, so that both take the same iterations.
  KluAndTree(Consistent& c, double t_end, double tree_jacobian_cost = 0,
             HhtOptions::Predictor tree_predictor = HhtOptions::Predictor::kConstant,
             HhtOptions::RotationJacobian tree_rotation = HhtOptions::RotationJacobian::kFirstOrder) {
    HhtOptions klu_opt, tree_opt;
    klu_opt.linear_solver = HhtOptions::LinearSolver::kKlu;
    tree_opt.linear_solver = HhtOptions::LinearSolver::kTree;
    tree_opt.jacobian_cost = tree_jacobian_cost;
    tree_opt.predictor = tree_predictor;
    tree_opt.rotation_jacobian = tree_rotation;
    klu = MakeHhtIntegrator(*c.kept, klu_opt);
    tree = MakeHhtIntegrator(*c.kept, tree_opt);
    klu->Initialize(c.x);
    tree->Initialize(c.x);
    EXPECT_TRUE(klu->AdvanceTo(t_end)) << klu->summary().message;
    EXPECT_TRUE(tree->AdvanceTo(t_end)) << tree->summary().message;
  }
};

// Why ForMechanicalSystem refuses the HHT Newton matrix of this model (empty: it did not).
std::string Refusal(const std::string& yaml) {
  const mbs::Model model = mbs::LoadModelFromString(yaml, "test.yaml");
  mbs::MultibodySystem sys(model);
  HhtNewtonMatrix newton(sys, HhtOptions());
  std::string why;
  if (BlockTreeLu::ForMechanicalSystem(newton.pattern(), sys.pattern(Matrix::kMass),
                                       sys.pattern(Matrix::kConstraintDq), 48, &why))
    return "";
  return why.empty() ? "(no reason)" : why;
}

TEST(BlockTreeLu, MatchesKluOnHhtNewtonMatrices) {
  for (bool springs : {false, true}) {
    Consistent c(ChainYaml(40, springs));
    ASSERT_EQ(c.redundant, 0u);
    MechanicalSystem& sys = *c.kept;
    HhtOptions opt;
    HhtNewtonMatrix newton(sys, opt);
    // A bent, moving chain off the constraints (the matrix exists anywhere).
    std::mt19937 gen(5);
    std::uniform_real_distribution<double> u(-0.05, 0.05);
    std::vector<double> q = c.x.q, v = c.x.v, a = c.x.a, lam = c.x.lambda;
    for (double& x : q) x += u(gen);
    for (double& x : v) x += 20 * u(gen);
    for (double& x : a) x += 100 * u(gen);
    for (double& x : lam) x += 100 * u(gen);
    std::vector<double> values(newton.pattern().nnz());
    ASSERT_EQ(newton.Assemble(0.1, 1e-3, q.data(), v.data(), a.data(), lam.data(), values.data()), 0);
    std::string why;
    auto tree = BlockTreeLu::ForMechanicalSystem(newton.pattern(), sys.pattern(Matrix::kMass),
                                                 sys.pattern(Matrix::kConstraintDq), 48, &why);
    ASSERT_TRUE(tree) << why;
    EXPECT_EQ(tree->num_nodes(), 40);
    EXPECT_EQ(tree->largest_node(), 11);  // 7 coordinates, the normalisation, 3 joint rows
    ASSERT_TRUE(tree->Factor(values.data(), &why)) << why;
    KluSolver klu(newton.pattern());
    ASSERT_TRUE(klu.Factor(values.data(), &why)) << why;
    const int n = newton.pattern().rows;
    std::vector<double> b(n), x(n), ref(n);
    for (int i = 0; i < n; ++i) b[i] = std::cos(1.0 + 0.7 * i);
    x = b;
    ref = b;
    tree->Solve(x.data());
    klu.Solve(ref.data());
    const double d = RelativeDifference(x, ref);
    std::printf("Newton matrix of 40 rods%s: tree against KLU %.1e, pivot ratio %.1e\n",
                springs ? " with springs" : "", d, tree->rcond());
    EXPECT_LT(d, 1e-11);
  }
}

// The parallelogram four-bar of tests/app/models/fourbar.yaml with its two ground pivots
// on a body `base` welded to the ground: the loop base-crank-coupler-rocker is then one of
// bodies (the forest of dae/tree_kkt.h sees it), not one through the ground.
std::string FloatingBaseFourBar() {
  return R"(format: 1
name: four-bar on a welded base
gravity: [0, -9.81, 0]
parameters: {c: 0.5, s: 0.8660254037844386}
ground:
  markers:
    C: {position: [1, 0, 0]}
bodies:
  - {name: base, mass: 5, inertia: [0.1, 0.1, 0.1], position: [1, 0, 0],
     markers: {O: {position: [-1, 0, 0]}, P: {position: [1, 0, 0]}, C: {position: [0, 0, 0]}}}
  - {name: crank, mass: 1, inertia: [0.01, 0.08, 0.08], position: ["c/2", "-s/2", 0],
     markers: {A: {position: ["-c/2", "s/2", 0]}, B: {position: ["c/2", "-s/2", 0]}}}
  - {name: coupler, mass: 2, inertia: [0.01, 0.7, 0.7], position: ["1 + c", "-s", 0],
     markers: {L: {position: [-1, 0, 0]}, R: {position: [1, 0, 0]}}}
  - {name: rocker, mass: 1, inertia: [0.01, 0.08, 0.08], position: ["2 + c/2", "-s/2", 0],
     markers: {A: {position: ["-c/2", "s/2", 0]}, B: {position: ["c/2", "-s/2", 0]}}}
joints:
  - {name: weld, type: fixed, i: base.C, j: ground.C}
  - {name: j_crank, type: revolute, i: crank.A, j: base.O}
  - {name: j_left, type: revolute, i: crank.B, j: coupler.L}
  - {name: j_right, type: revolute, i: coupler.R, j: rocker.B}
  - {name: j_rocker, type: revolute, i: rocker.A, j: base.P}
simulation: {t_end: 0.5, output_step: 0.05}
)";
}

TEST(BlockTreeLu, RefusesLoopsAndForcesBetweenBodiesWithoutAJoint) {
  // A four-bar on a welded base: the body-joint graph has a loop.
  const std::string loop = Refusal(FloatingBaseFourBar());
  EXPECT_NE(loop.find("closed loop"), std::string::npos) << loop;
  // A spring from the first rod to the third: no joint joins them.
  std::string y = mbdae::testing::BallChainYaml(3, 0.05);
  const size_t at = y.find("simulation:");
  y = y.substr(0, at) +
      "forces:\n  - {name: s, type: spring_damper, i: rod1.cm, j: rod3.cm, stiffness: 10, damping: 0, free_length: 0.2}\n" +
      y.substr(at);
  const std::string spring = Refusal(y);
  EXPECT_NE(spring.find("which are not parent and child"), std::string::npos) << spring;
  // The chain itself, with springs between neighbours: accepted.
  EXPECT_EQ(Refusal(ChainYaml(3, true)), "");
}

// HHT with the tree against HHT with KLU: the same number of steps, iterations and
// factorisations, the states equal to round-off; and the four-bar (a loop) on KLU.
TEST(BlockTreeLu, HhtWithTheTreeTakesTheSameStepsAsWithKlu) {
  for (bool springs : {false, true}) {
    Consistent c(ChainYaml(30, springs));
    KluAndTree run(c, 0.2);
    const Summary& sk = run.klu->summary();
    const Summary& st = run.tree->summary();
    EXPECT_EQ(sk.linear_solver, "klu");
    EXPECT_EQ(st.linear_solver, "tree");
    EXPECT_EQ(st.klu_fallbacks, 0);
    EXPECT_EQ(st.steps_accepted, sk.steps_accepted);
    EXPECT_NEAR(st.newton_iterations, sk.newton_iterations, 0.01 * sk.newton_iterations);
    const double dq = RelativeDifference(run.tree->state().q, run.klu->state().q);
    const double dv = RelativeDifference(run.tree->state().v, run.klu->state().v);
    std::printf("HHT, 30 rods%s, 0.2 s: %ld steps, Newton %ld (KLU) and %ld (tree); q differs by %.1e, v by %.1e\n",
                springs ? " with springs" : "", sk.steps_accepted, sk.newton_iterations,
                st.newton_iterations, dq, dv);
    EXPECT_LT(dq, 1e-10);
    EXPECT_LT(dv, 1e-8);
  }
}

// HHT with KLU and the options the tree's run `tree` resolved to (0.2 s): the same counts
// (the refresh rule and the predictor see only iteration counts and states; to round-off,
// which moves a count by one here or there) and q within 1e-10. Returns KLU's summary.
Summary KluLikeTheTree(Consistent& c, const HhtOptions& klu_options, const Integrator& tree) {
  auto klu = MakeHhtIntegrator(*c.kept, klu_options);
  klu->Initialize(c.x);
  EXPECT_TRUE(klu->AdvanceTo(0.2)) << klu->summary().message;
  const Summary& sk = klu->summary();
  const Summary& st = tree.summary();
  EXPECT_EQ(sk.linear_solver, "klu");
  EXPECT_NEAR(sk.newton_iterations, st.newton_iterations, 0.01 * st.newton_iterations);
  EXPECT_NEAR(sk.factorizations, st.factorizations, 0.05 * st.factorizations);
  EXPECT_LT(RelativeDifference(klu->state().q, tree.state().q), 1e-10);
  return sk;
}

// The refresh by cost (HhtOptions::jacobian_cost; its default with the tree is
// kTreeJacobianCost): on the 30-rod chain, fewer Newton iterations for more
// factorisations, the work in iterations (iterations + cost x factorisations) lower than
// with the rate and age rules alone, the same steps and the results within the Newton
// threshold's reach of KLU's. With KLU and the same cost the rule gives the same counts
// (it sees only iteration counts; to round-off, which moves a count by one here or
// there), and with cost 0 the tree keeps KLU's counts.
TEST(BlockTreeLu, HhtRefreshesTheMatrixByCost) {
  Consistent c(ChainYaml(30, false));
  KluAndTree plain(c, 0.2);
  KluAndTree by_cost(c, 0.2, -1);  // auto: kTreeJacobianCost with the tree
  const Summary& sk = plain.klu->summary();
  const Summary& s0 = plain.tree->summary();
  const Summary& st = by_cost.tree->summary();
  const double cost = HhtOptions::kTreeJacobianCost;
  EXPECT_EQ(sk.jacobian_cost, 0.0);
  EXPECT_EQ(s0.jacobian_cost, 0.0);
  EXPECT_EQ(st.jacobian_cost, cost);
  EXPECT_NEAR(s0.newton_iterations, sk.newton_iterations, 0.01 * sk.newton_iterations);
  EXPECT_NEAR(s0.factorizations, sk.factorizations, 0.05 * sk.factorizations);
  EXPECT_EQ(st.steps_accepted, sk.steps_accepted);
  const double work_k = sk.newton_iterations + cost * sk.factorizations;
  const double work_t = st.newton_iterations + cost * st.factorizations;
  const double dq = RelativeDifference(by_cost.tree->state().q, plain.klu->state().q);
  std::printf("HHT, 30 rods, 0.2 s, %ld steps: rate and age rules %ld iterations, %ld "
              "factorisations (work %.0f); by cost %ld, %ld (work %.0f, %.3f of it); q differs "
              "from KLU's by %.1e\n",
              sk.steps_accepted, sk.newton_iterations, sk.factorizations, work_k,
              st.newton_iterations, st.factorizations, work_t, work_t / work_k, dq);
  EXPECT_LT(st.newton_iterations, 0.9 * sk.newton_iterations);
  EXPECT_GT(st.factorizations, sk.factorizations);
  EXPECT_LT(work_t, 0.95 * work_k);
  EXPECT_LT(dq, 1e-9);

  HhtOptions klu_cost;
  klu_cost.jacobian_cost = cost;
  EXPECT_EQ(KluLikeTheTree(c, klu_cost, *by_cost.tree).jacobian_cost, cost);
}

// Two tree runs of the 30-rod chain (0.2 s) that differ in one option, `before` and
// `after`: the same steps and the states within the Newton threshold's reach of each
// other (1e-9 relative); printed with their Newton iterations, factorisations and work
// (iterations + kTreeJacobianCost x factorisations). Returns after's iterations and work
// as fractions of before's.
struct WorkRatio {
  double iterations, work;
};
WorkRatio CompareTreeRuns(const char* before_name, const Integrator& before,
                          const char* after_name, const Integrator& after) {
  const Summary& s0 = before.summary();
  const Summary& s1 = after.summary();
  EXPECT_EQ(s1.steps_accepted, s0.steps_accepted);
  const double cost = HhtOptions::kTreeJacobianCost;
  const double work0 = s0.newton_iterations + cost * s0.factorizations;
  const double work1 = s1.newton_iterations + cost * s1.factorizations;
  const double dq = RelativeDifference(after.state().q, before.state().q);
  std::printf("HHT, 30 rods, 0.2 s, tree, %ld steps: %s %ld iterations, %ld factorisations "
              "(work %.0f); %s %ld, %ld (work %.0f, %.3f of it); q differs by %.1e\n",
              s0.steps_accepted, before_name, s0.newton_iterations, s0.factorizations, work0,
              after_name, s1.newton_iterations, s1.factorizations, work1, work1 / work0, dq);
  EXPECT_LT(dq, 1e-9);
  return {static_cast<double>(s1.newton_iterations) / s0.newton_iterations, work1 / work0};
}

// The linear predictor (HhtOptions::predictor; the tree's default): on the 30-rod chain
// with the tree's refresh by cost, fewer Newton iterations and less work (iterations +
// cost x factorisations) than the constant predictor, the same steps, and the states
// within the Newton threshold's reach of each other. KLU with the linear predictor takes
// the tree's counts (to round-off, which moves a count by one here or there).
TEST(BlockTreeLu, HhtLinearPredictorSavesIterations) {
  Consistent c(ChainYaml(30, false));
  KluAndTree constant(c, 0.2, -1, HhtOptions::Predictor::kConstant);
  KluAndTree linear(c, 0.2, -1, HhtOptions::Predictor::kAuto);  // auto: linear with the tree
  EXPECT_EQ(constant.tree->summary().predictor, "constant");
  EXPECT_EQ(linear.tree->summary().predictor, "linear");
  EXPECT_EQ(constant.klu->summary().predictor, "constant");  // auto with KLU
  const WorkRatio w = CompareTreeRuns("constant predictor", *constant.tree, "linear", *linear.tree);
  EXPECT_LT(w.iterations, 0.9);
  EXPECT_LT(w.work, 0.9);

  HhtOptions klu_linear;
  klu_linear.jacobian_cost = HhtOptions::kTreeJacobianCost;
  klu_linear.predictor = HhtOptions::Predictor::kLinear;
  EXPECT_EQ(KluLikeTheTree(c, klu_linear, *linear.tree).predictor, "linear");
}

// The exact rotation blocks of the Newton matrix (HhtOptions::rotation_jacobian; the
// tree's default): on the 30-rod chain with the tree's other defaults, fewer Newton
// iterations and less work than the first-order matrix, the same steps, and the states
// within the Newton threshold's reach of each other. KLU with the exact blocks takes the
// tree's counts (to round-off); KLU's default stays first-order.
TEST(BlockTreeLu, HhtExactRotationJacobianSavesIterations) {
  Consistent c(ChainYaml(30, false));
  using R = HhtOptions::RotationJacobian;
  KluAndTree first(c, 0.2, -1, HhtOptions::Predictor::kAuto, R::kFirstOrder);
  KluAndTree exact(c, 0.2, -1, HhtOptions::Predictor::kAuto, R::kAuto);  // auto: exact
  EXPECT_EQ(first.tree->summary().rotation_jacobian, "first-order");
  EXPECT_EQ(exact.tree->summary().rotation_jacobian, "exact");
  EXPECT_EQ(first.klu->summary().rotation_jacobian, "first-order");  // auto with KLU
  const WorkRatio w =
      CompareTreeRuns("first-order matrix", *first.tree, "exact rotation blocks", *exact.tree);
  EXPECT_LT(w.iterations, 0.95);
  EXPECT_LT(w.work, 0.97);

  HhtOptions klu_exact;
  klu_exact.jacobian_cost = HhtOptions::kTreeJacobianCost;
  klu_exact.predictor = HhtOptions::Predictor::kLinear;
  klu_exact.rotation_jacobian = R::kExact;
  EXPECT_EQ(KluLikeTheTree(c, klu_exact, *exact.tree).rotation_jacobian, "exact");
}

// The system without EvalOutput::constraint_transpose_w: everything else forwarded.
class WithoutConstraintProduct final : public MechanicalSystem {
 public:
  explicit WithoutConstraintProduct(MechanicalSystem& base) : base_(base) {}
  int num_coordinates() const override { return base_.num_coordinates(); }
  int num_constraints() const override { return base_.num_constraints(); }
  const CscPattern& pattern(Matrix m) const override { return base_.pattern(m); }
  const std::vector<int>& quaternion_offsets() const override { return base_.quaternion_offsets(); }
  int Evaluate(const EvalInput& in, EvalOutput& out) override {
    EXPECT_EQ(out.constraint_transpose_w, nullptr);
    return base_.Evaluate(in, out);
  }
  const char* last_error() const override { return base_.last_error(); }

 private:
  MechanicalSystem& base_;
};

// HHT's residual takes C_q^T lambda from the system's product (EvalOutput::
// constraint_transpose_w) where the system gives it, and the runs are the same to the
// last bit as with C_q and its pattern's product: KLU and the tree, the equilibrium and
// the negrut form (whose F_{n+1} at each converged step is one more evaluation), on the
// 30-rod chain.
TEST(BlockTreeLu, HhtConstraintProductGivesTheSameRuns) {
  Consistent c(ChainYaml(30, false));
  ASSERT_TRUE(c.kept->provides_constraint_transpose_w());
  WithoutConstraintProduct plain(*c.kept);
  for (auto solver : {HhtOptions::LinearSolver::kKlu, HhtOptions::LinearSolver::kTree})
    for (auto form : {HhtOptions::Form::kEquilibrium, HhtOptions::Form::kNegrut}) {
      HhtOptions opt;
      opt.linear_solver = solver;
      opt.form = form;
      auto with = MakeHhtIntegrator(*c.kept, opt), without = MakeHhtIntegrator(plain, opt);
      with->Initialize(c.x);
      without->Initialize(c.x);
      ASSERT_TRUE(with->AdvanceTo(0.1)) << with->summary().message;
      ASSERT_TRUE(without->AdvanceTo(0.1)) << without->summary().message;
      const char* name = solver == HhtOptions::LinearSolver::kKlu ? "klu" : "tree";
      EXPECT_EQ(with->summary().newton_iterations, without->summary().newton_iterations) << name;
      EXPECT_EQ(with->summary().residual_evaluations, without->summary().residual_evaluations);
      EXPECT_EQ(with->state().q, without->state().q) << name;
      EXPECT_EQ(with->state().v, without->state().v) << name;
      EXPECT_EQ(with->state().a, without->state().a) << name;
      EXPECT_EQ(with->state().lambda, without->state().lambda) << name;
    }
}

// A loop of bodies: KLU, and the reason; a loop closed through the ground (the four-bar of
// tests/app/models, which the forest does not see): KLU after the first factorisation.
TEST(BlockTreeLu, HhtOnALoopUsesKluAndSaysWhy) {
  Consistent c(FloatingBaseFourBar());
  EXPECT_EQ(c.redundant, 3u);  // the out-of-plane equations of the loop
  KluAndTree run(c, 0.05);
  const std::string used = run.tree->summary().linear_solver;
  EXPECT_EQ(used.rfind("klu (no tree: ", 0), 0u) << used;
  EXPECT_NE(used.find("closed loop"), std::string::npos) << used;
  // KLU either way: bitwise the same run.
  EXPECT_EQ(run.tree->state().q, run.klu->state().q);
  EXPECT_EQ(run.tree->state().lambda, run.klu->state().lambda);

  std::ifstream in(std::string(MBDAE_TEST_MODELS) + "/fourbar.yaml");
  std::stringstream text;
  text << in.rdbuf();
  Consistent g(text.str());
  KluAndTree through_ground(g, 0.05);
  const Summary& st = through_ground.tree->summary();
  EXPECT_EQ(st.linear_solver, "klu (no tree: the first factorisation's pivots were unusable)");
  EXPECT_EQ(st.klu_fallbacks, 1);
  EXPECT_EQ(through_ground.tree->state().q, through_ground.klu->state().q);
}

// IDA (the stabilised index-2 form: each node a body's q and v with the lambda and mu of
// its rows) with the tree against KLU: adaptive, so not the same steps, but the same
// solution within its tolerance; the loops fall back to KLU (a loop closed through the
// ground by the backward-error check of the first factorisation, after which the run is
// KLU's).
std::unique_ptr<Integrator> RunIda(Consistent& c, LinearSolverKind solver, double t_end) {
  IdaOptions opt;
  opt.rtol = opt.atol = 1e-8;
  opt.linear_solver = solver;
  auto ida = MakeIdaIntegrator(*c.kept, opt);
  ida->Initialize(c.x);
  EXPECT_TRUE(ida->AdvanceTo(t_end)) << ida->summary().message;
  return ida;
}

TEST(BlockTreeLu, IdaWithTheTreeAgreesWithKlu) {
  for (bool springs : {false, true}) {
    Consistent c(ChainYaml(30, springs));
    auto klu = RunIda(c, LinearSolverKind::kKlu, 0.2);
    auto tree = RunIda(c, LinearSolverKind::kTree, 0.2);
    const Summary& sk = klu->summary();
    const Summary& st = tree->summary();
    EXPECT_EQ(sk.linear_solver, "klu");
    EXPECT_EQ(st.linear_solver, "tree");
    EXPECT_EQ(st.klu_fallbacks, 0);
    const double dq = RelativeDifference(tree->state().q, klu->state().q);
    std::printf("IDA rtol 1e-8, 30 rods%s, 0.2 s: %ld and %ld steps (KLU, tree); q differs by %.1e\n",
                springs ? " with springs" : "", sk.steps_accepted, st.steps_accepted, dq);
    EXPECT_LT(dq, 1e-6);
    EXPECT_NEAR(st.steps_accepted, sk.steps_accepted, 0.2 * sk.steps_accepted);
  }
  {
    Consistent c(FloatingBaseFourBar());
    auto tree = RunIda(c, LinearSolverKind::kTree, 0.05);
    EXPECT_NE(tree->summary().linear_solver.find("closed loop"), std::string::npos)
        << tree->summary().linear_solver;
  }
  std::ifstream in(std::string(MBDAE_TEST_MODELS) + "/fourbar.yaml");
  std::stringstream text;
  text << in.rdbuf();
  Consistent g(text.str());
  auto klu = RunIda(g, LinearSolverKind::kKlu, 0.05);
  auto tree = RunIda(g, LinearSolverKind::kTree, 0.05);
  EXPECT_EQ(tree->summary().linear_solver,
            "klu (no tree: a factorisation failed its check at t = 0)");
  EXPECT_EQ(tree->summary().klu_fallbacks, 1);
  EXPECT_EQ(tree->state().q, klu->state().q);
}

}  // namespace
}  // namespace mbdae::dae
