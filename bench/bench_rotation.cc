// The cost of the modified HHT scheme's rotation blocks per Euler-parameter group
// (bench/README.md, "The Newton matrix's rotation blocks"): the rotation update itself
// (HhtRotationMap, once per group and Newton iteration) and its derivative with respect
// to a_{n+1} at the fixed point (HhtRotationDerivative, once per group and refresh), on
// 1000 random groups.
#include <benchmark/benchmark.h>

#include <random>
#include <vector>

#include "dae/hht_rotation.h"

namespace {

using mbdae::dae::HhtRotationLayout;
using mbdae::dae::HhtRotationScheme;

std::vector<double> Inputs(int groups) {
  std::mt19937 rng(1);
  std::uniform_real_distribution<double> u(-1, 1);
  std::vector<double> x(size_t(HhtRotationLayout::kInputs) * groups);
  for (double& v : x) v = u(rng);
  return x;
}

void BM_HhtRotationMap(benchmark::State& state) {
  const int groups = 1000;
  const std::vector<double> x = Inputs(groups);
  const HhtRotationScheme sc = HhtRotationScheme::Of(-0.1, true);
  double y[HhtRotationLayout::kOutputs];
  for (auto _ : state)
    for (int i = 0; i < groups; ++i) {
      mbdae::dae::HhtRotationMap(sc, 1e-3, 1.0, &x[size_t(HhtRotationLayout::kInputs) * i], y);
      benchmark::DoNotOptimize(y);
    }
  state.SetItemsProcessed(state.iterations() * groups);  // items/s: groups per second
}
BENCHMARK(BM_HhtRotationMap);

void BM_HhtRotationDerivative(benchmark::State& state) {
  const int groups = 1000;
  const std::vector<double> x = Inputs(groups);
  const HhtRotationScheme sc = HhtRotationScheme::Of(-0.1, true);
  double de[16], ded[16], block[32];
  for (auto _ : state)
    for (int i = 0; i < groups; ++i) {
      mbdae::dae::HhtRotationDerivative(sc, 1e-3, 1.0,
                                        &x[size_t(HhtRotationLayout::kInputs) * i], de, ded);
      mbdae::dae::HhtRotationBlock(sc, 1e-3, de, ded, block);
      benchmark::DoNotOptimize(block);
    }
  state.SetItemsProcessed(state.iterations() * groups);
}
BENCHMARK(BM_HhtRotationDerivative);

}  // namespace

BENCHMARK_MAIN();
