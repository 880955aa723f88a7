#!/usr/bin/env bash
# Builds and runs the chain benchmark, then writes bench/results/chain.json and
# bench/results/chain.md. Usage (from anywhere):
#   bash bench/run_chain.sh [BUILD_DIR]        (default BUILD_DIR: build, in the repo)
# Environment: REPETITIONS (default 5; 1 gives single runs without aggregates).
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
build="${1:-$root/build}"
reps="${REPETITIONS:-5}"

cmake -S "$root" -B "$build" -DCMAKE_BUILD_TYPE=Release >/dev/null
cmake --build "$build" --target bench_chain -j 2

mkdir -p "$root/bench/results"
args=(--benchmark_out="$root/bench/results/chain.json" --benchmark_out_format=json)
if [ "$reps" -gt 1 ]; then
  # Repetitions of all benchmarks in random order: a busy spell of the machine then
  # hits the step and the factorisation alike instead of one of them.
  args+=(--benchmark_repetitions="$reps" --benchmark_report_aggregates_only=true
         --benchmark_enable_random_interleaving=true)
fi
# Run from the build directory so that the recorded executable name is relative.
(cd "$build" && ./bench/bench_chain "${args[@]}")
/usr/bin/python3 "$root/bench/report_chain.py" "$root/bench/results/chain.json" \
  "$root/bench/results/chain.md"
echo "wrote bench/results/chain.json and bench/results/chain.md"
