// Issue 12, goal 3: one HHT step against one bare KLU refactorisation + solve of the same
// Newton matrix, and that refactorisation + solve against its flop count, on the ball
// chains of bench/scenes/ball_chain.py (bench/README.md, "Peers: mbdae against Simbody").
//
//   bench_step_flops --model N=PATH [--model N=PATH ...] [Google Benchmark flags]
//
// PATH: the chain's model file (bench/scenes/ball_chain.py N). For each N:
//   BM_HhtStep        one fixed step h = 1e-3 s of dae::MakeHhtIntegrator with the
//                     project's default HhtOptions (alpha = -0.1, equilibrium form,
//                     modified for Euler parameters), AdvanceTo(t + h), at Newton
//                     thresholds 10^-k and with KLU (N/k/0) or the block tree
//                     elimination (N/k/1) as the linear solver; every repetition
//                     times the same 200 steps (t = 0.005 .. 0.205 s, after 5 untimed
//                     steps from the consistent initial state; restarted untimed)
//   BM_KluRefactorSolve  bare KLU: klu_refactor + klu_solve (one right side) of the HHT
//                     Newton matrix (dae::HhtNewtonMatrix, the integrator's own assembly)
//                     at the state after the 5 warm-up steps, with the symbolic analysis
//                     (klu_defaults: AMD ordering, BTF, scaling) and the pivots of one
//                     klu_factor done before
//   BM_KluRefactor    klu_refactor alone
//   BM_KluSolve       klu_solve alone
//   BM_KluSolverFactorSolve  what the integrator calls: dae::KluSolver::Factor (the
//                     refactorisation plus its pivot-growth and condition checks) + Solve
//   BM_TreeLu         the same matrix by the block tree elimination (dae/block_tree_lu.h,
//                     HhtOptions::LinearSolver::kTree): N/1 Factor + Solve, N/2 Factor,
//                     N/3 Solve; its flops (BlockTreeLu::factor_flops, solve_flops) and
//                     its solution's difference from KLU's
//   BM_HhtRefresh     the tree's step with the Newton matrix refreshed every step (N/1) and
//                     every second step (N/2): the fit of a refresh's cost in iterations
//   BM_DenseGemm      C = A B of two dense 256 x 256 matrices (Eigen, as this build
//                     compiles it): 2 * 256^3 flops, the rate dense code reaches here
// Counters: flops of the factorisation (klu_flops: the multiply-subtract pairs of the LU
// factorisation counted as 2), of the solve (2 (nnz(L) + nnz(U) + nnz(off-diagonal BTF
// blocks)) - 3 n: L has a unit diagonal, U's diagonal costs one division),
// nnz of the matrix, of L and U, and the rate GFLOP/s = flops / CPU time per iteration.
#include <benchmark/benchmark.h>
#include <klu.h>

#include <Eigen/Dense>
#include <cmath>
#include <cstdlib>
#include <map>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include "dae/block_tree_lu.h"
#include "bench/hht_windows.h"
#include "dae/consistent.h"
#include "dae/hht.h"
#include "dae/klu_solver.h"
#include "dae/sparse.h"
#include "mbs/loader.h"
#include "mbs/model.h"
#include "mbs/system.h"

namespace {

namespace dae = mbdae::dae;
namespace mbs = mbdae::mbs;

constexpr double kStep = 1e-3;
constexpr int kWarmupSteps = 5;
constexpr int kWindowSteps = 200;

std::map<int, std::string> g_models;  // N -> model file

// Bare KLU on one matrix: symbolic analysis and a first factorisation at construction.
struct BareKlu {
  int n = 0;
  std::vector<int> ap, ai;
  std::vector<double> ax;
  klu_common common;
  klu_symbolic* symbolic = nullptr;
  klu_numeric* numeric = nullptr;

  BareKlu(const dae::CscPattern& p, const std::vector<double>& values)
      : n(p.rows), ap(p.col_start), ai(p.row_index), ax(values) {
    klu_defaults(&common);
    common.halt_if_singular = 1;
    symbolic = klu_analyze(n, ap.data(), ai.data(), &common);
    if (!symbolic) throw std::runtime_error("klu_analyze failed");
    numeric = klu_factor(ap.data(), ai.data(), ax.data(), symbolic, &common);
    if (!numeric || common.status != KLU_OK) throw std::runtime_error("klu_factor failed");
  }
  ~BareKlu() {
    if (numeric) klu_free_numeric(&numeric, &common);
    if (symbolic) klu_free_symbolic(&symbolic, &common);
  }
  bool Refactor() { return klu_refactor(ap.data(), ai.data(), ax.data(), symbolic, numeric, &common); }
  void Solve(double* b) { klu_solve(symbolic, numeric, n, 1, b, &common); }
  double FactorFlops() {
    klu_flops(symbolic, numeric, &common);
    return common.flops;
  }
  long Lnz() const { return numeric->lnz; }
  long Unz() const { return numeric->unz; }
  // Off-diagonal blocks of the BTF form are used by the solve as well.
  long Offnz() const { return numeric->nzoff; }
};

struct Chain {
  mbs::Model model;
  std::unique_ptr<mbs::MultibodySystem> system;
  dae::State x0, xs;  // consistent initial state; the state after the warm-up steps
  dae::HhtOptions hht;
  std::unique_ptr<dae::HhtNewtonMatrix> newton;
  std::vector<double> jac;

  explicit Chain(const std::string& path) : model(mbs::LoadModel(path)) {
    system = std::make_unique<mbs::MultibodySystem>(model);
    const int nq = system->num_coordinates(), nc = system->num_constraints();
    x0.Resize(nq, nc);
    system->InitialState(x0.q, x0.v);
    // Normalisations first, as driver::Assemble: the natural order makes SPQR's factor
    // of a chain fill in (minutes and gigabytes at N = 10^4).
    dae::ConsistencyOptions consistency;
    for (int e = 0; e < nc; ++e)
      if (system->constraint_joint()[e] < 0) consistency.elimination_order.push_back(e);
    for (int e = 0; e < nc; ++e)
      if (system->constraint_joint()[e] >= 0) consistency.elimination_order.push_back(e);
    const dae::ConsistencyReport rep = dae::MakeConsistent(*system, x0, consistency);
    if (!rep.ok) throw std::runtime_error(path + ": " + rep.message);
    if (!rep.redundant.empty()) throw std::runtime_error(path + ": redundant constraints");
    hht.step = kStep;
    auto integ = dae::MakeHhtIntegrator(*system, hht);
    integ->Initialize(x0);
    if (!integ->AdvanceTo(kWarmupSteps * kStep))
      throw std::runtime_error(path + ": " + integ->summary().message);
    xs = integ->state();
    newton = std::make_unique<dae::HhtNewtonMatrix>(*system, hht);
    jac.assign(newton->pattern().nnz(), 0.0);
    if (newton->Assemble(xs.t, kStep, xs.q.data(), xs.v.data(), xs.a.data(), xs.lambda.data(),
                         jac.data()) != 0)
      throw std::runtime_error(path + ": Newton matrix: " + system->last_error());
  }
  int n() const { return static_cast<int>(model.bodies.size()); }
};

Chain& GetChain(int n) {
  static std::map<int, std::unique_ptr<Chain>> chains;
  auto it = chains.find(n);
  if (it == chains.end()) it = chains.emplace(n, std::make_unique<Chain>(g_models.at(n))).first;
  return *it->second;
}

void SizeCounters(benchmark::State& state, Chain& c) {
  state.counters["N"] = c.n();
  state.counters["nq"] = c.system->num_coordinates();
  state.counters["nc"] = c.system->num_constraints();
  state.counters["nnz"] = c.newton->pattern().nnz();
}

void FlopCounters(benchmark::State& state, BareKlu& klu, bool factor, bool solve) {
  const double ff = klu.FactorFlops();
  // Off-diagonal entries of L (unit diagonal) and U and of the BTF off-diagonal blocks:
  // a multiply and a subtract each; a division per diagonal entry of U.
  const double sf = 2.0 * (klu.Lnz() + klu.Unz() + klu.Offnz()) - 3.0 * klu.n;
  state.counters["factor_flops"] = ff;
  state.counters["solve_flops"] = sf;
  state.counters["lnz"] = klu.Lnz();
  state.counters["unz"] = klu.Unz();
  state.counters["offnz"] = klu.Offnz();
  const double flops = (factor ? ff : 0) + (solve ? sf : 0);
  // flops per second of CPU time: kIsIterationInvariantRate divides by the CPU time.
  state.counters["GFLOPs"] =
      benchmark::Counter(flops * 1e-9, benchmark::Counter::kIsIterationInvariantRate);
}

// Arguments: N, k, s; the Newton threshold is 10^-k (12: the default HhtOptions), the
// linear solver KLU (s = 0, the default) or the block tree elimination (s = 1,
// HhtOptions::LinearSolver::kTree).
// Times fixed steps of HHT with the options hht on chain c (BM_HhtStep, BM_HhtRefresh).
void TimeHhtSteps(benchmark::State& state, Chain& c, const dae::HhtOptions& hht) {
  auto integ = dae::MakeHhtIntegrator(*c.system, hht);
  dae::Summary base;
  double newton = 0, factor = 0, jacobian = 0, rejected = 0;
  auto close_window = [&]() {
    const dae::Summary& s = integ->summary();
    newton += s.newton_iterations - base.newton_iterations;
    factor += s.factorizations - base.factorizations;
    jacobian += s.jacobian_evaluations - base.jacobian_evaluations;
    rejected += s.steps_rejected - base.steps_rejected;
  };
  if (!mbdae::bench::TimeHhtWindows(state, *integ, c.x0, kStep, kWarmupSteps, kWindowSteps,
                                    [&]() { base = integ->summary(); }, close_window))
    return;
  if (integ->summary().klu_fallbacks > 0) state.SkipWithError("the tree fell back to KLU");
  SizeCounters(state, c);
  using benchmark::Counter;
  state.counters["newton_per_step"] = Counter(newton, Counter::kAvgIterations);
  state.counters["factor_per_step"] = Counter(factor, Counter::kAvgIterations);
  state.counters["jacobian_per_step"] = Counter(jacobian, Counter::kAvgIterations);
  state.counters["rejected_per_step"] = Counter(rejected, Counter::kAvgIterations);
}

void BM_HhtStep(benchmark::State& state) {
  Chain& c = GetChain(static_cast<int>(state.range(0)));
  dae::HhtOptions hht = c.hht;
  hht.newton_tolerance = std::pow(10.0, -static_cast<double>(state.range(1)));
  if (state.range(2) == 1) hht.linear_solver = dae::HhtOptions::LinearSolver::kTree;
  TimeHhtSteps(state, c, hht);
}

// The tree's step with the Newton matrix refreshed every k-th step (N/k; the rate rule
// and the refresh by cost off): two k give two equations t = n_it c_it + n_f c_f in the
// cost of an iteration and of a refresh (run.py fits them; HhtOptions::kTreeJacobianCost).
void BM_HhtRefresh(benchmark::State& state) {
  Chain& c = GetChain(static_cast<int>(state.range(0)));
  dae::HhtOptions hht = c.hht;
  hht.linear_solver = dae::HhtOptions::LinearSolver::kTree;
  hht.jacobian_cost = 0;
  hht.jacobian_reuse_rate = 0.999;
  hht.max_steps_same_jacobian = static_cast<int>(state.range(1));
  TimeHhtSteps(state, c, hht);
}

std::vector<double> RightSide(int n) {
  std::vector<double> rhs(n);
  for (int i = 0; i < n; ++i) rhs[i] = std::sin(0.37 * i + 0.1);
  return rhs;
}

void BM_KluRefactorSolve(benchmark::State& state) {
  Chain& c = GetChain(static_cast<int>(state.range(0)));
  BareKlu klu(c.newton->pattern(), c.jac);
  const std::vector<double> rhs = RightSide(klu.n);
  std::vector<double> x(klu.n);
  for (auto _ : state) {
    if (!klu.Refactor()) {
      state.SkipWithError("klu_refactor failed");
      break;
    }
    x = rhs;
    klu.Solve(x.data());
    benchmark::DoNotOptimize(x.data());
    benchmark::ClobberMemory();
  }
  SizeCounters(state, c);
  FlopCounters(state, klu, true, true);
}

void BM_KluRefactor(benchmark::State& state) {
  Chain& c = GetChain(static_cast<int>(state.range(0)));
  BareKlu klu(c.newton->pattern(), c.jac);
  for (auto _ : state) {
    if (!klu.Refactor()) {
      state.SkipWithError("klu_refactor failed");
      break;
    }
    benchmark::ClobberMemory();
  }
  SizeCounters(state, c);
  FlopCounters(state, klu, true, false);
}

void BM_KluSolve(benchmark::State& state) {
  Chain& c = GetChain(static_cast<int>(state.range(0)));
  BareKlu klu(c.newton->pattern(), c.jac);
  const std::vector<double> rhs = RightSide(klu.n);
  std::vector<double> x(klu.n);
  for (auto _ : state) {
    x = rhs;
    klu.Solve(x.data());
    benchmark::DoNotOptimize(x.data());
    benchmark::ClobberMemory();
  }
  SizeCounters(state, c);
  FlopCounters(state, klu, false, true);
}

void BM_KluSolverFactorSolve(benchmark::State& state) {
  Chain& c = GetChain(static_cast<int>(state.range(0)));
  dae::KluSolver klu(c.newton->pattern());
  std::string err;
  if (!klu.Factor(c.jac.data(), &err)) {
    state.SkipWithError(err.c_str());
    return;
  }
  const std::vector<double> rhs = RightSide(c.newton->pattern().rows);
  std::vector<double> x(rhs.size());
  const long full_before = klu.factorizations();
  for (auto _ : state) {
    if (!klu.Factor(c.jac.data(), &err)) {
      state.SkipWithError(err.c_str());
      break;
    }
    x = rhs;
    klu.Solve(x.data());
    benchmark::DoNotOptimize(x.data());
    benchmark::ClobberMemory();
  }
  SizeCounters(state, c);
  state.counters["factor_per_iter"] = benchmark::Counter(
      static_cast<double>(klu.factorizations() - full_before), benchmark::Counter::kAvgIterations);
}

// The block tree elimination of the same matrix (dae/block_tree_lu.h): arg 1 = factor and
// solve, 2 = factor alone, 3 = solve alone; the relative difference of its solution from
// KLU's (max norm) as a counter.
void BM_TreeLu(benchmark::State& state) {
  Chain& c = GetChain(static_cast<int>(state.range(0)));
  const int what = static_cast<int>(state.range(1));
  std::string why;
  auto tree = dae::BlockTreeLu::ForMechanicalSystem(
      c.newton->pattern(), c.system->pattern(dae::Matrix::kMass),
      c.system->pattern(dae::Matrix::kConstraintDq), 48, &why);
  if (!tree || !tree->Factor(c.jac.data(), &why)) {
    state.SkipWithError(why.c_str());
    return;
  }
  const std::vector<double> rhs = RightSide(c.newton->pattern().rows);
  std::vector<double> x = rhs, xk = rhs;
  for (auto _ : state) {
    if (what != 3 && !tree->Factor(c.jac.data(), &why)) {
      state.SkipWithError(why.c_str());
      break;
    }
    if (what != 2) {
      x = rhs;
      tree->Solve(x.data());
      benchmark::DoNotOptimize(x.data());
    }
    benchmark::ClobberMemory();
  }
  SizeCounters(state, c);
  x = rhs;
  tree->Solve(x.data());
  BareKlu klu(c.newton->pattern(), c.jac);
  klu.Solve(xk.data());
  double diff = 0, scale = 0;
  for (size_t i = 0; i < x.size(); ++i) {
    diff = std::max(diff, std::abs(x[i] - xk[i]));
    scale = std::max(scale, std::abs(xk[i]));
  }
  state.counters["diff_vs_klu"] = diff / scale;
  state.counters["rcond"] = tree->rcond();
  state.counters["factor_flops"] = tree->factor_flops();
  state.counters["solve_flops"] = tree->solve_flops();
  const double flops =
      (what != 3 ? tree->factor_flops() : 0) + (what != 2 ? tree->solve_flops() : 0);
  state.counters["GFLOPs"] =
      benchmark::Counter(flops * 1e-9, benchmark::Counter::kIsIterationInvariantRate);
}

void BM_DenseGemm(benchmark::State& state) {
  const int n = static_cast<int>(state.range(0));
  Eigen::MatrixXd a = Eigen::MatrixXd::Random(n, n), b = Eigen::MatrixXd::Random(n, n), r(n, n);
  for (auto _ : state) {
    r.noalias() = a * b;
    benchmark::DoNotOptimize(r.data());
    benchmark::ClobberMemory();
  }
  state.counters["GFLOPs"] = benchmark::Counter(2.0 * n * n * n * 1e-9,
                                                benchmark::Counter::kIsIterationInvariantRate);
}

}  // namespace

int main(int argc, char** argv) {
  // Take out --model N=PATH before Google Benchmark sees the arguments.
  std::vector<char*> rest;
  for (int i = 0; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--model" && i + 1 < argc) {
      const std::string spec = argv[++i];
      const auto eq = spec.find('=');
      if (eq == std::string::npos) {
        std::fprintf(stderr, "bench_step_flops: --model takes N=PATH, got '%s'\n", spec.c_str());
        return 2;
      }
      g_models[std::atoi(spec.substr(0, eq).c_str())] = spec.substr(eq + 1);
    } else {
      rest.push_back(argv[i]);
    }
  }
  int rest_argc = static_cast<int>(rest.size());
  benchmark::Initialize(&rest_argc, rest.data());
  if (benchmark::ReportUnrecognizedArguments(rest_argc, rest.data())) return 1;
  if (g_models.empty()) {
    std::fprintf(stderr, "usage: bench_step_flops --model N=PATH [...] [benchmark flags]\n");
    return 2;
  }
  struct Entry {
    const char* name;
    void (*fn)(benchmark::State&);
  };
  const Entry entries[] = {{"BM_HhtStep", BM_HhtStep},
                           {"BM_KluRefactorSolve", BM_KluRefactorSolve},
                           {"BM_KluRefactor", BM_KluRefactor},
                           {"BM_KluSolve", BM_KluSolve},
                           {"BM_KluSolverFactorSolve", BM_KluSolverFactorSolve}};
  for (const auto& m : g_models)
    for (const Entry& e : entries) {
      if (e.fn == BM_HhtStep) {
        // The default threshold 1e-12, and looser ones (HhtOptions::newton_tolerance).
        for (int solver : {0, 1})
          for (int k : {12, 10, 8, 6})
            benchmark::RegisterBenchmark(e.name, e.fn)
                ->Args({m.first, k, solver})
                ->Unit(benchmark::kMicrosecond)
                ->Iterations(m.first <= 100 ? 5 * kWindowSteps : kWindowSteps);
      } else {
        benchmark::RegisterBenchmark(e.name, e.fn)->Arg(m.first)->Unit(benchmark::kMicrosecond);
      }
    }
  for (const auto& m : g_models)
    for (int every : {1, 2})
      benchmark::RegisterBenchmark("BM_HhtRefresh", BM_HhtRefresh)
          ->Args({m.first, every})
          ->Unit(benchmark::kMicrosecond)
          ->Iterations(m.first <= 100 ? 5 * kWindowSteps : kWindowSteps);
  for (const auto& m : g_models)
    for (int what : {1, 2, 3})
      benchmark::RegisterBenchmark("BM_TreeLu", BM_TreeLu)
          ->Args({m.first, what})
          ->Unit(benchmark::kMicrosecond);
  benchmark::RegisterBenchmark("BM_DenseGemm", BM_DenseGemm)->Arg(256)->Unit(benchmark::kMicrosecond);
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  return 0;
}
