// Cost of the model's expressions against the same force written by hand in C++.
//
// 1000 force elements, element i with the value "-k_i*x_i - d_i*v_i + F_i*sin(2*pi*f_i*t)"
// over its own measures x_i, v_i and parameters k_i, d_i, F_i, f_i (7 arguments with t),
// as a model with 1000 force elements has them. Each benchmark iteration evaluates all
// 1000: the value alone, or the value with its first derivatives with respect to every
// argument (what a force Jacobian needs), by mbs::Expression and by a hand-written
// function computing the same numbers. Heap allocations during the timed loops are
// counted (operator new is replaced in this program) and reported as a counter.
//
// Run by hand (see bench/README.md):
//   build/bench/bench_expression --benchmark_repetitions=5 --benchmark_report_aggregates_only=true \
//       --benchmark_enable_random_interleaving=true
#include <benchmark/benchmark.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <new>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

#include "mbs/expression.h"

namespace {
long g_allocations = 0;
}  // namespace

void* operator new(std::size_t size) {
  ++g_allocations;
  if (void* p = std::malloc(size == 0 ? 1 : size)) return p;
  throw std::bad_alloc();
}
void operator delete(void* p) noexcept { std::free(p); }
void operator delete(void* p, std::size_t) noexcept { std::free(p); }

namespace {

using mbdae::mbs::Expression;
using mbdae::mbs::ExpressionGradient;
using mbdae::mbs::ExpressionInputs;
using mbdae::mbs::SymbolTable;

constexpr int kElements = 1000;

// Indices of one element's arguments in the measure and parameter arrays.
struct Element {
  int x, v;         // measures
  int k, d, F, f;   // parameters
};

struct Model {
  std::vector<Element> elements;
  std::vector<Expression> expressions;
  std::vector<double> measures, parameters;
};

const Model& TheModel() {
  static const Model model = [] {
    Model m;
    SymbolTable symbols;
    symbols.allow_time = true;
    std::mt19937 rng(1);
    std::uniform_real_distribution<double> u(0.5, 1.5);
    for (int i = 0; i < kElements; ++i) {
      const std::string s = std::to_string(i);
      Element e;
      e.x = static_cast<int>(symbols.measures.size());
      symbols.measures.push_back("x" + s);
      e.v = static_cast<int>(symbols.measures.size());
      symbols.measures.push_back("v" + s);
      e.k = static_cast<int>(symbols.parameters.size());
      for (const char* name : {"k", "d", "F", "f"}) symbols.parameters.push_back(name + s);
      e.d = e.k + 1;
      e.F = e.k + 2;
      e.f = e.k + 3;
      m.elements.push_back(e);
      for (int k = 0; k < 2; ++k) m.measures.push_back(u(rng) - 1.0);
      m.parameters.push_back(1000 * u(rng));  // k
      m.parameters.push_back(10 * u(rng));    // d
      m.parameters.push_back(50 * u(rng));    // F
      m.parameters.push_back(2 * u(rng));     // f
    }
    for (int i = 0; i < kElements; ++i) {
      const std::string s = std::to_string(i);
      m.expressions.push_back(
          Expression::Parse("-k" + s + "*x" + s + " - d" + s + "*v" + s + " + F" + s + "*sin(2*pi*f" + s + "*t)",
                            symbols));
    }
    return m;
  }();
  return model;
}

// The same force by hand.
double HandValue(const Element& e, double t, const double* q, const double* p) {
  return -p[e.k] * q[e.x] - p[e.d] * q[e.v] + p[e.F] * std::sin(2 * M_PI * p[e.f] * t);
}

// Value and the derivatives in the order Expression uses for this text: t, then the
// measures (x, v), then the parameters in order of first use (k, d, F, f).
double HandGradient(const Element& e, double t, const double* q, const double* p, ExpressionGradient* g) {
  const double k = p[e.k], d = p[e.d], F = p[e.F], f = p[e.f];
  const double x = q[e.x], v = q[e.v];
  const double w = 2 * M_PI * f;
  const double s = std::sin(w * t), c = std::cos(w * t);
  g->d_t = F * c * w;
  g->d_measures[0] = -k;
  g->d_measures[1] = -d;
  g->d_parameters[0] = -x;
  g->d_parameters[1] = -v;
  g->d_parameters[2] = s;
  g->d_parameters[3] = F * c * 2 * M_PI * t;
  return -k * x - d * v + F * s;
}

void Finish(benchmark::State& state, long allocations) {
  state.SetItemsProcessed(state.iterations() * kElements);
  // CPU time per expression in ns: time / (iterations * kElements) * 1e9.
  state.counters["ns_per_expression"] = benchmark::Counter(
      kElements * 1e-9, benchmark::Counter::kIsIterationInvariantRate | benchmark::Counter::kInvert);
  state.counters["allocations"] = static_cast<double>(allocations);
}

void BM_ExpressionValue(benchmark::State& state) {
  const Model& m = TheModel();
  double t = 0.1;
  const long before = g_allocations;
  for (auto _ : state) {
    ExpressionInputs in{t, m.parameters.data(), m.measures.data(), nullptr};
    double sum = 0;
    for (const Expression& e : m.expressions) sum += e.Evaluate(in);
    benchmark::DoNotOptimize(sum);
    t += 1e-6;
  }
  Finish(state, g_allocations - before);
}

void BM_HandValue(benchmark::State& state) {
  const Model& m = TheModel();
  double t = 0.1;
  const long before = g_allocations;
  for (auto _ : state) {
    double sum = 0;
    for (const Element& e : m.elements) sum += HandValue(e, t, m.measures.data(), m.parameters.data());
    benchmark::DoNotOptimize(sum);
    t += 1e-6;
  }
  Finish(state, g_allocations - before);
}

void BM_ExpressionGradient(benchmark::State& state) {
  const Model& m = TheModel();
  double t = 0.1;
  ExpressionGradient g;
  const long before = g_allocations;
  for (auto _ : state) {
    ExpressionInputs in{t, m.parameters.data(), m.measures.data(), nullptr};
    double sum = 0;
    for (const Expression& e : m.expressions) {
      sum += e.EvaluateGradient(in, &g);
      sum += g.d_t + g.d_measures[0] + g.d_measures[1] + g.d_parameters[3];
    }
    benchmark::DoNotOptimize(sum);
    t += 1e-6;
  }
  Finish(state, g_allocations - before);
}

void BM_HandGradient(benchmark::State& state) {
  const Model& m = TheModel();
  double t = 0.1;
  ExpressionGradient g;
  const long before = g_allocations;
  for (auto _ : state) {
    double sum = 0;
    for (const Element& e : m.elements) {
      sum += HandGradient(e, t, m.measures.data(), m.parameters.data(), &g);
      sum += g.d_t + g.d_measures[0] + g.d_measures[1] + g.d_parameters[3];
      benchmark::DoNotOptimize(g);
    }
    benchmark::DoNotOptimize(sum);
    t += 1e-6;
  }
  Finish(state, g_allocations - before);
}

// Before timing: the expressions and the hand-written force agree (values and every
// derivative to 1e-12 relative), so that the two sides compute the same thing.
void CheckAgreement() {
  const Model& m = TheModel();
  const double t = 0.37;
  ExpressionInputs in{t, m.parameters.data(), m.measures.data(), nullptr};
  for (int i = 0; i < kElements; ++i) {
    ExpressionGradient a, b;
    const double va = m.expressions[i].EvaluateGradient(in, &a);
    const double vb = HandGradient(m.elements[i], t, m.measures.data(), m.parameters.data(), &b);
    const double pairs[][2] = {{va, vb},
                               {m.expressions[i].Evaluate(in), HandValue(m.elements[i], t, m.measures.data(), m.parameters.data())},
                               {a.d_t, b.d_t},
                               {a.d_measures[0], b.d_measures[0]},
                               {a.d_measures[1], b.d_measures[1]},
                               {a.d_parameters[0], b.d_parameters[0]},
                               {a.d_parameters[1], b.d_parameters[1]},
                               {a.d_parameters[2], b.d_parameters[2]},
                               {a.d_parameters[3], b.d_parameters[3]}};
    for (const auto& p : pairs) {
      if (std::abs(p[0] - p[1]) > 1e-12 * std::max(1.0, std::abs(p[1]))) {
        throw std::runtime_error("expression " + std::to_string(i) + " disagrees with the hand-written force");
      }
    }
  }
}

BENCHMARK(BM_ExpressionValue);
BENCHMARK(BM_HandValue);
BENCHMARK(BM_ExpressionGradient);
BENCHMARK(BM_HandGradient);

}  // namespace

int main(int argc, char** argv) {
  CheckAgreement();
  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  return 0;
}
