"""Speed-up of mbdae.sweep with 1 and 2 Dask worker processes (docs/sweeps.md).

    PYTHONPATH=build/python /usr/bin/python3 bench/sweep_speedup.py [--runs N] [--repeat R] [--batch B]

The study: a Monte Carlo of the slider-crank (verification/slider_crank) in k and c,
N runs (default 100) of t_end = 2 s with HHT at h = 1e-3 (2000 steps a run), outputs
the final slider position and the largest crank speed. Three ways, each timed from the
submission of the first run to the arrival of the last (the clusters are started
beforehand and each has run the study once untimed, so every worker has its model
loaded): "serial" (this process, no Dask), a LocalCluster of 1 worker process, one of 2
(one thread each). The R repetitions interleave the three (serial, 1, 2, serial, 1, 2,
...), so that a busy spell of a shared machine does not hit one of them only; the table
gives the median and the fastest of the repetitions, and the speed-ups are ratios of
medians. Writes bench/results/sweep_speedup.md and .json.
"""

import argparse
import importlib
import json
import os
import platform
import statistics
import sys
import time

import numpy as np

import mbdae

sw = importlib.import_module("mbdae.sweep")

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
MODEL = os.path.join(ROOT, "verification", "slider_crank", "slider_crank.yaml")
OPTIONS = {"t_end": 2.0, "integrator": "hht", "hht.step": 1e-3, "output_step": 0.01}
OUTPUTS = ["final:xs", "max:wc"]


def samples(n):
    rng = np.random.default_rng(1)
    return [{"k": float(k), "c": float(c)}
            for k, c in zip(rng.normal(1, 0.1, n), rng.uniform(0.5, 1.5, n))]


def cpu_seconds(client):
    """CPU time used so far by this process (serial) or the workers of `client`."""
    if client == "serial":
        return time.process_time()
    return sum(client.run(time.process_time).values())


def timed(study, client, batch=1):
    cpu = cpu_seconds(client)
    start = time.perf_counter()
    frame = mbdae.sweep(MODEL, study, OUTPUTS, client, options=OPTIONS, batch=batch)
    elapsed = time.perf_counter() - start
    cpu = cpu_seconds(client) - cpu
    assert (frame["status"] == "done").all(), frame["message"].unique()
    return elapsed, cpu, frame


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--runs", type=int, default=100)
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--batch", type=int, default=1, help="runs per Dask task")
    ap.add_argument("--out", default=os.path.join(ROOT, "bench", "results"))
    args = ap.parse_args()
    from distributed import Client, LocalCluster

    study = samples(args.runs)
    load_before = os.getloadavg()
    clusters = {}
    for n in (1, 2):
        cluster = LocalCluster(n_workers=n, processes=True, threads_per_worker=1,
                               dashboard_address=None)
        clusters[n] = (cluster, Client(cluster))
    reference = None
    for n in (1, 2):  # warm-up: every worker loads the model
        _, _, frame = timed(study, clusters[n][1], args.batch)
        reference = frame if reference is None else reference
    times = {"serial": [], "1 worker": [], "2 workers": []}
    cpus = {k: [] for k in times}
    for r in range(args.repeat):
        for name, client in (("serial", "serial"), ("1 worker", clusters[1][1]),
                             ("2 workers", clusters[2][1])):
            t, cpu, frame = timed(study, client, args.batch)
            assert np.array_equal(frame["final:xs"], reference["final:xs"])  # bitwise
            times[name].append(t)
            cpus[name].append(cpu)
            print("repetition %d: %-9s %.3f s, %.3f CPU s" % (r + 1, name, t, cpu),
                  file=sys.stderr)
    load_after = os.getloadavg()
    for cluster, client in clusters.values():
        client.close()
        cluster.close()
    med = {k: statistics.median(v) for k, v in times.items()}
    med_cpu = {k: statistics.median(v) for k, v in cpus.items()}
    per_run = statistics.median(reference["wall_time"])
    result = {
        "command": "PYTHONPATH=build/python /usr/bin/python3 bench/sweep_speedup.py --runs %d "
                   "--repeat %d --batch %d" % (args.runs, args.repeat, args.batch),
        "runs": args.runs, "repeat": args.repeat, "options": OPTIONS,
        "cpus": sw._cpu_count(), "machine": platform.machine(),
        "load_average_before": load_before, "load_average_after": load_after,
        "batch": args.batch, "seconds": times, "median": med, "cpu_seconds": cpus,
        "median_cpu_seconds": med_cpu,
        "median_run_wall_time_on_a_worker": per_run,
        "speedup_2_over_1": med["1 worker"] / med["2 workers"],
        "speedup_2_over_serial": med["serial"] / med["2 workers"],
        "overhead_1_over_serial": med["1 worker"] / med["serial"],
    }
    os.makedirs(args.out, exist_ok=True)
    with open(os.path.join(args.out, "sweep_speedup.json"), "w") as f:
        json.dump(result, f, indent=1)
    lines = [
        "# mbdae.sweep: 1 and 2 worker processes",
        "",
        "Produced by `%s` (bench/sweep_speedup.py: %d Monte Carlo runs of the slider-crank, "
        "t_end = 2 s, HHT h = 1e-3, outputs final:xs and max:wc, %d run(s) per task; "
        "repetitions interleaved; clusters started and warmed up beforehand). CPU s: the "
        "CPU time this process (serial) or the workers (summed) used during the study; "
        "CPU s / wall s is how many cores the study got." % (result["command"], args.runs,
                                                            args.batch),
        "",
        "| way | median wall s | fastest wall s | wall s per run | CPU s of the runs | CPU s / wall s |",
        "| --- | --- | --- | --- | --- | --- |",
    ]
    for k, v in times.items():
        lines.append("| %s | %.3f | %.3f | %.4f | %.3f | %.2f |"
                     % (k, med[k], min(v), med[k] / args.runs, med_cpu[k],
                        med_cpu[k] / med[k]))
    lines += [
        "",
        "Speed-up 2 workers over 1: **%.2f**; 2 workers over serial: %.2f; 1 worker against "
        "serial (the cost of Dask: task submission, scheduling, results back): %.2f."
        % (result["speedup_2_over_1"], result["speedup_2_over_serial"],
           result["overhead_1_over_serial"]),
        "Median time of one run on a worker: %.4f s." % per_run,
        "",
        "The machine: %d cores (%s), **shared** with other jobs while this was measured: "
        "load average %.1f before and %.1f after (1-minute values). On a shared machine the "
        "second worker competes with the other jobs for the second core, so the speed-up "
        "measured here is a lower bound of what 2 free cores give; the ratios of the "
        "interleaved medians are the result, not the absolute times."
        % (result["cpus"], result["machine"], load_before[0], load_after[0]),
        "",
    ]
    with open(os.path.join(args.out, "sweep_speedup.md"), "w") as f:
        f.write("\n".join(lines))
    print("\n".join(lines))


if __name__ == "__main__":
    main()
