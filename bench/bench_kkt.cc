// Factorise + solve of the acceleration-level matrix K = [M C_q^T; C_q 0] (one erk stage)
// on the ball chain of bench/peers (N rods of 0.1 m, 1 kg, box inertia 0.1 x 0.01 x
// 0.01 m, spherical joints, the first to the ground; bench/scenes/ball_chain.py), at a
// bent, moving state. Side by side in one run (bench/README.md, "KKT factorisations"):
//
//   BM_Klu/N            KluSolver::Factor (a refactorisation, klu_refactor, with its
//                       condition estimate, the pivot growth at every 6th) + Solve, as
//                       erk's AccelerationSolver calls them
//   BM_KluOption/N/k    raw KLU with one option changed: k = 0 the defaults (AMD, BTF)
//                       with klu_refactor, 1 BTF off, 2 COLAMD ordering, 3 klu_factor
//                       (fresh pivoting) at every call, 4 tol 1e-3 with klu_factor
//   BM_Tree/N           TreeKktSolver::Factor + Solve (dae/tree_kkt.h)
//   BM_AssembleKkt/N    the block assembly of K's values that KLU needs and the tree not
//   BM_StageKlu/N       AccelerationSolver::Solve (evaluation of M, C_q, Q, gamma, then
//   BM_StageTree/N      the factorisation and solve): one erk stage, KLU or the tree
//   BM_Evaluate/N       the evaluation alone
//
// Every benchmark first checks that the tree's a and lambda equal KLU's to 1e-10.
#include <benchmark/benchmark.h>
#include <klu.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <memory>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

#include "dae/consistent.h"
#include "dae/klu_solver.h"
#include "dae/sparse.h"
#include "dae/tree_kkt.h"
#include "mbs/loader.h"
#include "mbs/system.h"
#include "tests/support/ball_chain.h"

namespace {

namespace dae = mbdae::dae;
namespace mbs = mbdae::mbs;
using dae::Matrix;

std::string ChainYaml(int n) { return mbdae::testing::BallChainYaml(n, 1); }

struct Chain {
  mbs::Model model;
  std::unique_ptr<mbs::MultibodySystem> system;
  int nq = 0, nc = 0;
  std::vector<double> q, v, mass, cq, force, gamma, values;
  dae::BlockAssembler kkt;
  int b_m = 0, b_ct = 0, b_c = 0;

  explicit Chain(int n) : model(mbs::LoadModelFromString(ChainYaml(n), "chain.yaml")) {
    system = std::make_unique<mbs::MultibodySystem>(model);
    nq = system->num_coordinates();
    nc = system->num_constraints();
    q.resize(nq);
    v.resize(nq);
    system->InitialState(q, v);
    // Bent and moving: the factorisation's cost does not depend on consistency.
    std::mt19937 gen(5);
    std::uniform_real_distribution<double> u(-1, 1);
    for (double& x : q) x += 0.02 * u(gen);
    for (double& x : v) x += u(gen);
    const dae::CscPattern& pm = system->pattern(Matrix::kMass);
    const dae::CscPattern& pc = system->pattern(Matrix::kConstraintDq);
    mass.resize(pm.nnz());
    cq.resize(pc.nnz());
    force.resize(nq);
    gamma.resize(nc);
    Evaluate();
    b_m = kkt.AddBlock(pm, 0, 0);
    b_ct = kkt.AddBlock(pc, 0, nq, true);
    b_c = kkt.AddBlock(pc, nq, 0);
    kkt.Finalize(nq + nc, nq + nc);
    values.resize(kkt.pattern().nnz());
    Assemble();
  }
  void Evaluate() {
    dae::EvalInput in;
    in.t = 0.2;
    in.q = q.data();
    in.v = v.data();
    dae::EvalOutput out;
    out.force = force.data();
    out.acc_rhs = gamma.data();
    out[Matrix::kMass] = mass.data();
    out[Matrix::kConstraintDq] = cq.data();
    if (system->Evaluate(in, out) != 0) throw std::runtime_error(system->last_error());
  }
  void Assemble() {
    std::fill(values.begin(), values.end(), 0.0);
    kkt.Accumulate(b_m, mass.data(), 1.0, values.data());
    kkt.Accumulate(b_ct, cq.data(), 1.0, values.data());
    kkt.Accumulate(b_c, cq.data(), 1.0, values.data());
  }
  std::vector<double> Rhs() const {
    std::vector<double> b(force);
    b.insert(b.end(), gamma.begin(), gamma.end());
    return b;
  }
};

Chain& GetChain(int n) {
  static std::map<int, std::unique_ptr<Chain>> chains;
  auto& c = chains[n];
  if (!c) {
    c = std::make_unique<Chain>(n);
    // The tree's solution against KLU's.
    dae::KluSolver klu(c->kkt.pattern());
    std::string why;
    auto tree = dae::TreeKktSolver::Analyze(c->system->pattern(Matrix::kMass),
                                            c->system->pattern(Matrix::kConstraintDq), 48, &why);
    if (!tree) throw std::runtime_error("no tree: " + why);
    std::vector<double> x0 = c->Rhs(), x1 = c->Rhs();
    if (!klu.Factor(c->values.data(), &why)) throw std::runtime_error(why);
    klu.Solve(x0.data());
    if (!tree->Factor(c->mass.data(), c->cq.data(), &why)) throw std::runtime_error(why);
    tree->Solve(x1.data());
    double d = 0, s = 0;
    for (size_t i = 0; i < x0.size(); ++i) {
      d = std::max(d, std::abs(x1[i] - x0[i]));
      s = std::max(s, std::abs(x0[i]));
    }
    if (!(d <= 1e-10 * s))
      throw std::runtime_error("tree and KLU differ by " + std::to_string(d / s));
  }
  return *c;
}

void BM_Klu(benchmark::State& st) {
  Chain& c = GetChain(static_cast<int>(st.range(0)));
  dae::KluSolver klu(c.kkt.pattern(), 6);  // the pivot growth every 6th call, as erk
  std::vector<double> b = c.Rhs();
  klu.Factor(c.values.data());
  for (auto _ : st) {
    klu.Factor(c.values.data());
    b = c.Rhs();
    klu.Solve(b.data());
    benchmark::DoNotOptimize(b.data());
  }
}

void BM_KluOption(benchmark::State& st) {
  Chain& c = GetChain(static_cast<int>(st.range(0)));
  const int option = static_cast<int>(st.range(1));
  const dae::CscPattern& p = c.kkt.pattern();
  std::vector<int> ap = p.col_start, ai = p.row_index;
  klu_common common;
  klu_defaults(&common);
  if (option == 1) common.btf = 0;
  if (option == 2) common.ordering = 1;  // COLAMD
  if (option == 4) common.tol = 1e-3;
  const int n = c.nq + c.nc;
  klu_symbolic* sym = klu_analyze(n, ap.data(), ai.data(), &common);
  klu_numeric* num = klu_factor(ap.data(), ai.data(), c.values.data(), sym, &common);
  if (!num) throw std::runtime_error("klu_factor failed");
  st.counters["lu_nnz"] = num->lnz + num->unz;
  std::vector<double> b = c.Rhs();
  for (auto _ : st) {
    if (option >= 3) {
      klu_free_numeric(&num, &common);
      num = klu_factor(ap.data(), ai.data(), c.values.data(), sym, &common);
    } else {
      klu_refactor(ap.data(), ai.data(), c.values.data(), sym, num, &common);
    }
    b = c.Rhs();
    klu_solve(sym, num, n, 1, b.data(), &common);
    benchmark::DoNotOptimize(b.data());
  }
  klu_free_numeric(&num, &common);
  klu_free_symbolic(&sym, &common);
}

void BM_Tree(benchmark::State& st) {
  Chain& c = GetChain(static_cast<int>(st.range(0)));
  std::string why;
  auto tree = dae::TreeKktSolver::Analyze(c.system->pattern(Matrix::kMass),
                                          c.system->pattern(Matrix::kConstraintDq), 48, &why);
  std::vector<double> b = c.Rhs();
  for (auto _ : st) {
    tree->Factor(c.mass.data(), c.cq.data());
    b = c.Rhs();
    tree->Solve(b.data());
    benchmark::DoNotOptimize(b.data());
  }
}

void BM_AssembleKkt(benchmark::State& st) {
  Chain& c = GetChain(static_cast<int>(st.range(0)));
  for (auto _ : st) {
    c.Assemble();
    benchmark::DoNotOptimize(c.values.data());
  }
}

void Stage(benchmark::State& st, bool tree) {
  Chain& c = GetChain(static_cast<int>(st.range(0)));
  dae::AccelerationSolver solver(*c.system, 6, tree);
  std::vector<double> a(c.nq), lambda(c.nc);
  for (auto _ : st) {
    if (solver.Solve(0.2, c.q.data(), c.v.data(), a.data(), lambda.data()) != 0)
      throw std::runtime_error(solver.last_error());
    benchmark::DoNotOptimize(a.data());
  }
  if (solver.used_tree() != tree) throw std::runtime_error("the stage used the other route");
}
void BM_StageKlu(benchmark::State& st) { Stage(st, false); }
void BM_StageTree(benchmark::State& st) { Stage(st, true); }

void BM_Evaluate(benchmark::State& st) {
  Chain& c = GetChain(static_cast<int>(st.range(0)));
  for (auto _ : st) {
    c.Evaluate();
    benchmark::DoNotOptimize(c.mass.data());
  }
}

// Interleaved per size: every route at N before the next N.
void Sizes(benchmark::internal::Benchmark* b) { b->Unit(benchmark::kMicrosecond); }

}  // namespace

BENCHMARK(BM_Klu)->Arg(10)->Arg(100)->Arg(1000)->Apply(Sizes);
BENCHMARK(BM_Tree)->Arg(10)->Arg(100)->Arg(1000)->Apply(Sizes);
BENCHMARK(BM_KluOption)
    ->ArgsProduct({{1000}, {0, 1, 2, 3, 4}})
    ->Apply(Sizes);
BENCHMARK(BM_AssembleKkt)->Arg(1000)->Apply(Sizes);
BENCHMARK(BM_Evaluate)->Arg(1000)->Apply(Sizes);
BENCHMARK(BM_StageKlu)->Arg(1000)->Apply(Sizes);
BENCHMARK(BM_StageTree)->Arg(1000)->Apply(Sizes);

BENCHMARK_MAIN();
