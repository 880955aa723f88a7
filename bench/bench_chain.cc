// Cost of one HHT step against the cost of one KLU refactorisation + solve of its Newton
// matrix, for a chain of N uniform rods joined by spherical joints (see README.md).
//
// The chain: N rods of length 1 m and mass 1 kg (a solid cylinder of radius 1 cm:
// Iyy = Izz = m (3 r^2 + L^2) / 12, Ixx = m r^2 / 2 about the rod axis x), the first
// attached to the world origin by a spherical joint, each further rod to the end of
// the previous one; gravity 9.81 m/s^2 in -y. Initially at rest, nearly horizontal:
// rod k points along (cos phi_k, 0, sin phi_k) with phi_k = 0.05 sin(1.3 k + 0.4), so
// the chain is slightly out of the x-y plane and its motion is three-dimensional.
// Coordinates: 7 per rod; constraints: 3 per joint + 1 Euler-parameter normalisation
// per rod (no redundancy).
//
// Benchmarks, each for N = 10, 100, 1000:
//   BM_HhtStep           one fixed step of the HHT integrator (h = 1e-3, alpha = -0.1);
//                        the system is wrapped to time its Evaluate calls inside the step
//   BM_KluRefactorSolve  dae::KluSolver::Factor (a refactorisation: the solver has
//                        factorised the same pattern before) + one Solve of the Newton
//                        matrix assembled as dae/hht.cc does, at a state reached by the
//                        integrator
//   BM_KluSolve          the Solve alone (one per Newton iteration)
//   BM_EvalResidual      MultibodySystem::Evaluate of what one Newton iteration of HHT
//                        asks for (Q, C, M, C_q)
//   BM_EvalJacobian      MultibodySystem::Evaluate of the six matrices of the Newton
//                        matrix (as the integrator's Jacobian update)
//   BM_AssembleNewton    the block assembly of the Newton matrix from those matrices
// bench/report_chain.py turns the JSON output into the table of bench/results/chain.md.
#include <benchmark/benchmark.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <map>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include "bench/hht_windows.h"
#include "dae/consistent.h"
#include "dae/hht.h"
#include "dae/klu_solver.h"
#include "dae/sparse.h"
#include "mbs/kinematics.h"
#include "mbs/model.h"
#include "mbs/system.h"

namespace {

using mbdae::dae::Matrix;
namespace dae = mbdae::dae;
namespace mbs = mbdae::mbs;

constexpr double kLength = 1.0;
constexpr double kMass = 1.0;
constexpr double kRadius = 0.01;
constexpr double kStep = 1e-3;
constexpr double kAlpha = -0.1;
// Steps taken (untimed) after every (re)start of the integrator before timing.
constexpr int kWarmupSteps = 5;
// Timed steps between restarts from the initial state: every timed step lies in the
// first 0.5 s of the motion, so the sizes compare at the same phase of the motion.
constexpr int kWindowSteps = 500;

// Euler parameters (scalar first) of the rotation taking the x axis onto the unit
// vector d: half-way quaternion (1 + x.d, x cross d), normalised.
mbs::Quat RotationFromX(const mbs::Vec3& d) {
  mbs::Quat e(1 + d.x(), 0.0, -d.z(), d.y());
  return e / e.norm();
}

mbs::Model BuildChain(int n) {
  mbs::Model m;
  m.name = "chain" + std::to_string(n);
  m.gravity = mbs::Vec3(0, -9.81, 0);
  m.markers.push_back(mbs::Marker{"ground.O", -1, mbs::Vec3::Zero(), mbs::Mat3::Identity(), {}});
  const double transverse = kMass * (3 * kRadius * kRadius + kLength * kLength) / 12;
  const double polar = kMass * kRadius * kRadius / 2;
  mbs::Vec3 start = mbs::Vec3::Zero();  // world position of the rod's end A
  for (int k = 0; k < n; ++k) {
    const double phi = 0.05 * std::sin(1.3 * k + 0.4);
    const mbs::Vec3 d(std::cos(phi), 0.0, std::sin(phi));
    mbs::Body b;
    b.name = "rod" + std::to_string(k);
    b.mass = kMass;
    b.inertia = mbs::Vec3(polar, transverse, transverse).asDiagonal();
    b.position = start + 0.5 * kLength * d;
    b.orientation = RotationFromX(d);
    b.cm_marker = static_cast<int>(m.markers.size());
    m.markers.push_back(mbs::Marker{b.name + ".cm", k, mbs::Vec3::Zero(), mbs::Mat3::Identity(), {}});
    m.markers.push_back(
        mbs::Marker{b.name + ".A", k, mbs::Vec3(-0.5 * kLength, 0, 0), mbs::Mat3::Identity(), {}});
    m.markers.push_back(
        mbs::Marker{b.name + ".B", k, mbs::Vec3(0.5 * kLength, 0, 0), mbs::Mat3::Identity(), {}});
    m.bodies.push_back(b);
    mbs::Joint j;
    j.name = "s" + std::to_string(k);
    j.type = mbs::JointType::kSpherical;
    j.locks = mbs::kLockX | mbs::kLockY | mbs::kLockZ;
    j.i = m.find_marker(b.name + ".A");
    j.j = k == 0 ? 0 : m.find_marker("rod" + std::to_string(k - 1) + ".B");
    m.joints.push_back(j);
    start += kLength * d;
  }
  return m;
}

// Forwards to a system and adds up the wall time spent in its Evaluate, separately for
// the Jacobian updates (calls that ask for d(Ma)/dq) and for the residual-type calls.
// Costs two clock readings per call (tens of ns against tens of us per call).
class TimedSystem final : public dae::MechanicalSystem {
 public:
  explicit TimedSystem(dae::MechanicalSystem& base) : base_(base) {}
  int num_coordinates() const override { return base_.num_coordinates(); }
  int num_constraints() const override { return base_.num_constraints(); }
  const dae::CscPattern& pattern(Matrix m) const override { return base_.pattern(m); }
  const std::vector<int>& quaternion_offsets() const override {
    return base_.quaternion_offsets();
  }
  const char* last_error() const override { return base_.last_error(); }
  int Evaluate(const dae::EvalInput& in, dae::EvalOutput& out) override {
    const auto start = std::chrono::steady_clock::now();
    const int rc = base_.Evaluate(in, out);
    const double dt =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    (out[Matrix::kMassTimesAccDq] ? jacobian_seconds : residual_seconds) += dt;
    return rc;
  }
  double residual_seconds = 0, jacobian_seconds = 0;

 private:
  dae::MechanicalSystem& base_;
};

// Everything the benchmarks of one size share, built once per size.
struct Chain {
  mbs::Model model;
  std::unique_ptr<mbs::MultibodySystem> system;
  dae::State x0;  // consistent initial state
  dae::HhtOptions hht;
  // A state reached by the integrator (after kWarmupSteps steps from x0) and the Newton
  // matrix of HHT assembled there.
  dae::State xs;
  std::vector<double> mat[dae::kNumMatrices];
  dae::BlockAssembler assembler;
  int b_mass = 0, b_kma = 0, b_kc = 0, b_qq = 0, b_qv = 0, b_cqt = 0, b_cq = 0;
  std::vector<double> jac;

  explicit Chain(int n) : model(BuildChain(n)) {
    system = std::make_unique<mbs::MultibodySystem>(model);
    const int nq = system->num_coordinates(), nc = system->num_constraints();
    x0.Resize(nq, nc);
    system->InitialState(x0.q, x0.v);
    const dae::ConsistencyReport rep = dae::MakeConsistent(*system, x0);
    if (!rep.ok) throw std::runtime_error("chain " + std::to_string(n) + ": " + rep.message);
    if (!rep.redundant.empty())
      throw std::runtime_error("chain " + std::to_string(n) + ": unexpected redundant constraints");
    hht.alpha = kAlpha;
    hht.step = kStep;

    auto integ = dae::MakeHhtIntegrator(*system, hht);
    integ->Initialize(x0);
    if (!integ->AdvanceTo(kWarmupSteps * kStep))
      throw std::runtime_error("chain " + std::to_string(n) + ": " + integ->summary().message);
    xs = integ->state();
    // The integrator must have kept the chain together: positions on the constraints.
    {
      std::vector<double> con(nc);
      dae::EvalInput in;
      in.t = xs.t;
      in.q = xs.q.data();
      dae::EvalOutput out;
      out.constraint = con.data();
      if (system->Evaluate(in, out) != 0) throw std::runtime_error(system->last_error());
      double worst = 0;
      for (double c : con) worst = std::max(worst, std::abs(c));
      if (!(worst < 1e-9))
        throw std::runtime_error("chain " + std::to_string(n) + ": |C| = " +
                                 std::to_string(worst) + " after the warm-up steps");
    }

    // The Newton matrix pattern, as dae/hht.cc builds it.
    for (int m = 0; m < dae::kNumMatrices; ++m)
      mat[m].assign(system->pattern(static_cast<Matrix>(m)).nnz(), 0.0);
    b_mass = assembler.AddBlock(system->pattern(Matrix::kMass), 0, 0);
    b_kma = assembler.AddBlock(system->pattern(Matrix::kMassTimesAccDq), 0, 0);
    b_kc = assembler.AddBlock(system->pattern(Matrix::kConstraintTDq), 0, 0);
    b_qq = assembler.AddBlock(system->pattern(Matrix::kForceDq), 0, 0);
    b_qv = assembler.AddBlock(system->pattern(Matrix::kForceDv), 0, 0);
    b_cqt = assembler.AddBlock(system->pattern(Matrix::kConstraintDq), 0, nq, /*transpose=*/true);
    b_cq = assembler.AddBlock(system->pattern(Matrix::kConstraintDq), nq, 0);
    std::vector<std::pair<int, int>> diag;
    for (int i = 0; i < nq + nc; ++i) diag.push_back({i, i});
    assembler.AddEntries(diag);
    assembler.Finalize(nq + nc, nq + nc);
    jac.assign(assembler.pattern().nnz(), 0.0);
    if (EvaluateJacobian() != 0)
      throw std::runtime_error("chain: Jacobian evaluation failed: " +
                               std::string(system->last_error()));
    Assemble();
  }

  int nq() const { return system->num_coordinates(); }
  int nc() const { return system->num_constraints(); }
  double* M(Matrix m) { return mat[static_cast<int>(m)].data(); }

  // What HHT's Jacobian update evaluates (every matrix but d(C_q v + C_t)/dq), at xs.
  int EvaluateJacobian() {
    dae::EvalInput in;
    in.t = xs.t;
    in.q = xs.q.data();
    in.v = xs.v.data();
    in.a = xs.a.data();
    in.w = xs.lambda.data();
    dae::EvalOutput out;
    for (int m = 0; m < dae::kNumMatrices; ++m)
      if (m != static_cast<int>(Matrix::kConstraintVelDq)) out.matrix[m] = mat[m].data();
    return system->Evaluate(in, out);
  }

  // What one Newton iteration of HHT evaluates (Q, C, M, C_q), at xs.
  int EvaluateResidual(std::vector<double>& force, std::vector<double>& con) {
    dae::EvalInput in;
    in.t = xs.t;
    in.q = xs.q.data();
    in.v = xs.v.data();
    dae::EvalOutput out;
    out.force = force.data();
    out.constraint = con.data();
    out[Matrix::kMass] = M(Matrix::kMass);
    out[Matrix::kConstraintDq] = M(Matrix::kConstraintDq);
    return system->Evaluate(in, out);
  }

  // Newton matrix of HHT (dae/hht.cc, Negrut et al. 2007):
  //   [ M/(1+alpha) + beta h^2 (K_Ma/(1+alpha) + K_C - Q_q) - gamma h Q_v ,  C_q^T ]
  //   [ C_q                                                              ,  0     ]
  void Assemble() {
    const double h = kStep, alpha = kAlpha;
    const double beta = (1 - alpha) * (1 - alpha) / 4, gamma = 0.5 - alpha;
    const double s = 1 / (1 + alpha), bh2 = beta * h * h;
    assembler.SetZero(jac.data());
    assembler.Accumulate(b_mass, M(Matrix::kMass), s, jac.data());
    assembler.Accumulate(b_kma, M(Matrix::kMassTimesAccDq), bh2 * s, jac.data());
    assembler.Accumulate(b_kc, M(Matrix::kConstraintTDq), bh2, jac.data());
    assembler.Accumulate(b_qq, M(Matrix::kForceDq), -bh2, jac.data());
    assembler.Accumulate(b_qv, M(Matrix::kForceDv), -gamma * h, jac.data());
    assembler.Accumulate(b_cqt, M(Matrix::kConstraintDq), 1.0, jac.data());
    assembler.Accumulate(b_cq, M(Matrix::kConstraintDq), 1.0, jac.data());
  }
};

Chain& GetChain(int n) {
  static std::map<int, std::unique_ptr<Chain>> chains;
  auto it = chains.find(n);
  if (it == chains.end()) it = chains.emplace(n, std::make_unique<Chain>(n)).first;
  return *it->second;
}

void SizeCounters(benchmark::State& state, Chain& c) {
  state.counters["N"] = static_cast<double>(c.model.bodies.size());
  state.counters["nq"] = c.nq();
  state.counters["nc"] = c.nc();
  state.counters["nnz"] = c.assembler.pattern().nnz();
}

void BM_HhtStep(benchmark::State& state) {
  Chain& c = GetChain(static_cast<int>(state.range(0)));
  TimedSystem timed(*c.system);
  auto integ = dae::MakeHhtIntegrator(timed, c.hht);
  dae::Summary sum_base;  // counters at the start of the current timed window
  double newton = 0, factor = 0, residual = 0, jacobian = 0, rejected = 0, noise = 0;
  double res_base = 0, jac_base = 0, res_seconds = 0, jac_seconds = 0;
  auto close_window = [&]() {
    res_seconds += timed.residual_seconds - res_base;
    jac_seconds += timed.jacobian_seconds - jac_base;
    const dae::Summary& s = integ->summary();
    newton += s.newton_iterations - sum_base.newton_iterations;
    factor += s.factorizations - sum_base.factorizations;
    residual += s.residual_evaluations - sum_base.residual_evaluations;
    jacobian += s.jacobian_evaluations - sum_base.jacobian_evaluations;
    rejected += s.steps_rejected - sum_base.steps_rejected;
    noise += s.newton_noise_stops - sum_base.newton_noise_stops;
  };
  auto start = [&]() {
    sum_base = integ->summary();
    res_base = timed.residual_seconds;
    jac_base = timed.jacobian_seconds;
  };
  if (!mbdae::bench::TimeHhtWindows(state, *integ, c.x0, kStep, kWarmupSteps, kWindowSteps,
                                    start, close_window))
    return;
  SizeCounters(state, c);
  using benchmark::Counter;
  state.counters["newton_per_step"] = Counter(newton, Counter::kAvgIterations);
  state.counters["factor_per_step"] = Counter(factor, Counter::kAvgIterations);
  state.counters["residual_per_step"] = Counter(residual, Counter::kAvgIterations);
  state.counters["jacobian_per_step"] = Counter(jacobian, Counter::kAvgIterations);
  state.counters["rejected_per_step"] = Counter(rejected, Counter::kAvgIterations);
  state.counters["noise_stops_per_step"] = Counter(noise, Counter::kAvgIterations);
  // Wall time per step inside MultibodySystem::Evaluate, in us (compare with real_time).
  state.counters["eval_residual_us_per_step"] = Counter(1e6 * res_seconds, Counter::kAvgIterations);
  state.counters["eval_jacobian_us_per_step"] = Counter(1e6 * jac_seconds, Counter::kAvgIterations);
}

void BM_KluRefactorSolve(benchmark::State& state) {
  Chain& c = GetChain(static_cast<int>(state.range(0)));
  dae::KluSolver klu(c.assembler.pattern());
  std::string err;
  // The first Factor is a full factorisation; every timed one is a refactorisation.
  if (!klu.Factor(c.jac.data(), &err)) {
    state.SkipWithError(err.c_str());
    return;
  }
  const int n = c.nq() + c.nc();
  std::vector<double> rhs(n), x(n);
  for (int i = 0; i < n; ++i) rhs[i] = std::sin(0.37 * i + 0.1);
  const long full_before = klu.factorizations();
  for (auto _ : state) {
    if (!klu.Factor(c.jac.data(), &err)) {
      state.SkipWithError(err.c_str());
      break;
    }
    x = rhs;  // no allocation: same size
    klu.Solve(x.data());
    benchmark::DoNotOptimize(x.data());
    benchmark::ClobberMemory();
  }
  SizeCounters(state, c);
  state.counters["factor_per_iter"] =
      benchmark::Counter(static_cast<double>(klu.factorizations() - full_before),
                         benchmark::Counter::kAvgIterations);
  state.counters["rcond"] = klu.rcond();
}

// Solve only, with the factorisation of the Newton matrix (one per Newton iteration).
void BM_KluSolve(benchmark::State& state) {
  Chain& c = GetChain(static_cast<int>(state.range(0)));
  dae::KluSolver klu(c.assembler.pattern());
  std::string err;
  if (!klu.Factor(c.jac.data(), &err)) {
    state.SkipWithError(err.c_str());
    return;
  }
  const int n = c.nq() + c.nc();
  std::vector<double> rhs(n), x(n);
  for (int i = 0; i < n; ++i) rhs[i] = std::sin(0.37 * i + 0.1);
  for (auto _ : state) {
    x = rhs;
    klu.Solve(x.data());
    benchmark::DoNotOptimize(x.data());
    benchmark::ClobberMemory();
  }
  SizeCounters(state, c);
}

void BM_EvalResidual(benchmark::State& state) {
  Chain& c = GetChain(static_cast<int>(state.range(0)));
  std::vector<double> force(c.nq()), con(c.nc());
  for (auto _ : state) {
    if (c.EvaluateResidual(force, con) != 0) {
      state.SkipWithError(c.system->last_error());
      break;
    }
    benchmark::ClobberMemory();
  }
  SizeCounters(state, c);
}

void BM_EvalJacobian(benchmark::State& state) {
  Chain& c = GetChain(static_cast<int>(state.range(0)));
  for (auto _ : state) {
    if (c.EvaluateJacobian() != 0) {
      state.SkipWithError(c.system->last_error());
      break;
    }
    benchmark::ClobberMemory();
  }
  SizeCounters(state, c);
}

void BM_AssembleNewton(benchmark::State& state) {
  Chain& c = GetChain(static_cast<int>(state.range(0)));
  for (auto _ : state) {
    c.Assemble();
    benchmark::ClobberMemory();
  }
  SizeCounters(state, c);
}

}  // namespace

// Registered size by size, so that the measurements that are compared (step against
// refactor + solve) run close together in time.
int main(int argc, char** argv) {
  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
  struct Entry {
    const char* name;
    void (*fn)(benchmark::State&);
  };
  const Entry entries[] = {{"BM_HhtStep", BM_HhtStep},
                           {"BM_KluRefactorSolve", BM_KluRefactorSolve},
                           {"BM_KluSolve", BM_KluSolve},
                           {"BM_EvalResidual", BM_EvalResidual},
                           {"BM_EvalJacobian", BM_EvalJacobian},
                           {"BM_AssembleNewton", BM_AssembleNewton}};
  for (int n : {10, 100, 1000})
    for (const Entry& e : entries) {
      auto* b = benchmark::RegisterBenchmark(e.name, e.fn)->Arg(n)->Unit(benchmark::kMicrosecond);
      // The step benchmark runs whole windows, so that every size and every repetition
      // times the same steps (t = 0.005 .. 0.505 s) and the counters per step are
      // deterministic; the small chain runs the window five times.
      if (e.fn == BM_HhtStep) b->Iterations(n <= 10 ? 5 * kWindowSteps : kWindowSteps);
    }
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  return 0;
}
