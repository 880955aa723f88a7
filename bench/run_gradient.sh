#!/usr/bin/env bash
# Builds and runs the gradient cost benchmark, then writes bench/results/gradient.json and
# bench/results/gradient.md (bench/README.md, "Gradients: cost"). Usage (from anywhere):
#   bash bench/run_gradient.sh [BUILD_DIR]        (default BUILD_DIR: build, in the repo)
# Environment: REPETITIONS (default 3): rounds of the repeated measurements;
#   ONCE=0: leave out the measurements made once (forward sensitivities for 100
#   parameters, finite differences for 10, the evaluation costs): a quick run;
#   IDA=1: add, once, IDAS on the same model (the IDA simulation, IDAS forward
#   sensitivities and the IDAS adjoint for 10 parameters; about 5 more minutes of CPU).
#
# Every measurement is one invocation of bench_gradient (its own process, so that its
# peak resident memory is its own). Each round runs the repeated measurements once, in
# an order shuffled per round (a busy spell of the machine then hits the compared
# measurements alike); the expensive ones (forward sensitivities for 100 parameters,
# finite differences for 10, the evaluation costs) run once, in the middle round.
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
build="${1:-$root/build}"
reps="${REPETITIONS:-3}"

# The commit the program is built from (and the tracked files changed in the working tree,
# if any), recorded in the results.
commit="$(git -C "$root" rev-parse --short HEAD 2>/dev/null || echo unknown)"
dirty="$(git -C "$root" status --porcelain --untracked-files=no 2>/dev/null | awk '{print $2}' | tr '\n' ' ')"
cmake -S "$root" -B "$build" -DCMAKE_BUILD_TYPE=Release >/dev/null
cmake --build "$build" --target bench_gradient -j 2

model="$root/bench/bench_gradient_chain.yaml"
# The committed model must be what the generator writes.
tmp_model="$(mktemp --suffix=.yaml)"
trap 'rm -f "$tmp_model"' EXIT
/usr/bin/python3 "$root/bench/bench_gradient_model.py" "$tmp_model" >/dev/null
if ! cmp -s "$tmp_model" "$model"; then
  echo "bench/bench_gradient_chain.yaml differs from what bench/bench_gradient_model.py writes;" \
       "run the script and commit the model" >&2
  exit 1
fi

exe="$build/bench/bench_gradient"
out_dir="$root/bench/results"
mkdir -p "$out_dir"
lines="$(mktemp)"
trap 'rm -f "$tmp_model" "$lines"' EXIT

# The trajectory budget of the checkpointed adjoint (GradientRequest::trajectory_memory;
# the full record of this run is about 21 MiB, and the default budget, 512 MiB, keeps
# it all).
budget_mib="${BUDGET_MIB:-2}"

repeated=("simulate" "simulate-file" "adjoint 1" "adjoint 10" "adjoint 100" "adjoint 1000"
          "adjoint 1 --trajectory-mib $budget_mib" "adjoint 1000 --trajectory-mib $budget_mib"
          "forward 1" "forward 10" "fd 1")
once=("adjoint-direct 1" "adjoint-direct 1000" "adjoint-direct 1000 --trajectory-mib $budget_mib"
      "forward 100" "fd 10" "fd 4 --fd-step 1e-6"
      "parts 1" "parts 10" "parts 100" "parts 1000"
      "simulate --step 2.5e-4" "adjoint 1 --step 2.5e-4 --trajectory-mib 0"
      "adjoint 1 --step 2.5e-4 --trajectory-mib $budget_mib")
if [ "${IDA:-0}" = "1" ]; then
  once+=("simulate --integrator ida" "forward 10 --integrator ida" "adjoint 10 --integrator ida")
fi
if [ "${ONCE:-1}" = "0" ]; then once=(); fi

run_case() {  # round, case words...
  local round="$1"
  shift
  local args=("$@")
  if [ "${args[0]}" = "simulate-file" ]; then
    args+=("$(mktemp -u --suffix=.h5)")
  fi
  local load
  load="$(cut -d' ' -f1 /proc/loadavg)"
  echo "round $round: ${args[*]} (load average $load)" >&2
  local json err
  err="$(mktemp)"
  if json="$("$exe" "$model" "${args[@]}" 2>"$err")"; then
    # Tag the line with the round, the case as given and the load average before it.
    echo "{\"round\": $round, \"label\": \"$*\", \"loadavg_before\": $load, ${json:1}" >>"$lines"
  else
    # A failed measurement is recorded with its message (and reported as failed).
    local msg
    msg="$(tr -d '"\\' <"$err" | tr '\n' ' ')"
    echo "  failed: $msg" >&2
    echo "{\"round\": $round, \"label\": \"$*\", \"loadavg_before\": $load, \"failed\": \"$msg\"}" >>"$lines"
  fi
  rm -f "$err"
}

start="$(date +%s)"
uptime_before="$(uptime)"
for ((r = 0; r < reps; ++r)); do
  cases=("${repeated[@]}")
  if [ "$r" -eq $((reps / 2)) ] && [ "${#once[@]}" -gt 0 ]; then cases+=("${once[@]}"); fi
  # Shuffled per round with a fixed seed per round (reproducible order).
  mapfile -t cases < <(printf '%s\n' "${cases[@]}" | shuf --random-source=<(yes "$r"))
  for c in "${cases[@]}"; do
    read -r -a words <<<"$c"
    run_case "$r" "${words[@]}"
  done
done
end="$(date +%s)"

/usr/bin/python3 "$root/bench/report_gradient.py" "$lines" "$out_dir/gradient.json" \
  "$out_dir/gradient.md" --seconds "$((end - start))" --uptime-before "$uptime_before" \
  --uptime-after "$(uptime)" --nproc "$(nproc)" \
  --commit "$commit" --dirty "$dirty"
echo "wrote bench/results/gradient.json and bench/results/gradient.md"
