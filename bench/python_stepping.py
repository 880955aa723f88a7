#!/usr/bin/env python3
"""Overhead of stepping a model from Python (issue 5, acceptance 5): the same run once as
one ``solve()`` and once as one ``solve_to(t)`` call per output time, side by side.

    PYTHONPATH=build/python /usr/bin/python3 bench/python_stepping.py [--repeat 15]

For each model the two ways alternate (stepped, whole, stepped, whole, ...) so that a busy
spell of the machine hits both; the result is the ratio of the median times (process CPU
time; wall time also shown), which must be <= 1.5. The stepped run is also checked to give
bitwise the rows of the whole run. Writes bench/results/python_stepping.md (or --out).
"""

import argparse
import os
import platform
import statistics
import sys
import time

import numpy as np

import mbdae

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)

# (label, model file, options)
CASES = [
    ("pendulum, IDA (rtol 1e-8), 2 s, output every 1 ms",
     "examples/pendulum.yaml", {}),
    ("pendulum, HHT (h = 1e-3), 2 s, output every 1 ms",
     "examples/pendulum.yaml", {"integrator": "hht", "hht.step": 1e-3}),
    ("oscillator, HHT (h = 1e-3), 10 s, output every 10 ms",
     "examples/virtual_iteration/oscillator.yaml", {}),
]


def run(path, options, stepped):
    """One run; returns (cpu seconds, wall seconds, q rows)."""
    with mbdae.Model(path) as m:
        for k, v in options.items():
            m.options[k] = v
        t_end = m.options["t_end"]
        dt = m.options["output_step"]
        steps = int(round(t_end / dt))
        c0, w0 = time.process_time(), time.perf_counter()
        if stepped:
            m.assemble()
            solve_to = m.solve_to
            for k in range(1, steps + 1):
                solve_to(k * dt)
        else:
            m.solve()
        cpu, wall = time.process_time() - c0, time.perf_counter() - w0
        return cpu, wall, m.outputs.q


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--repeat", type=int, default=15)
    p.add_argument("--out", default=os.path.join(HERE, "results", "python_stepping.md"))
    args = p.parse_args()

    rows = []
    worst = 0.0
    for label, rel, options in CASES:
        path = os.path.join(ROOT, rel)
        run(path, options, True)  # warm up (page cache, library)
        times = {True: [], False: []}
        q = {}
        for _ in range(args.repeat):
            for stepped in (True, False):
                cpu, wall, q[stepped] = run(path, options, stepped)
                times[stepped].append((cpu, wall))
        bitwise = np.array_equal(q[True], q[False])
        med = {s: (statistics.median(c for c, _ in times[s]),
                   statistics.median(w for _, w in times[s])) for s in times}
        ratio_cpu = med[True][0] / med[False][0]
        ratio_wall = med[True][1] / med[False][1]
        worst = max(worst, ratio_cpu)
        calls = q[True].shape[0] - 1
        per_call = (med[True][0] - med[False][0]) / calls * 1e6
        rows.append((label, calls, med[False], med[True], ratio_cpu, ratio_wall, per_call,
                     bitwise))
        print("%s: one solve %.1f ms, %d solve_to calls %.1f ms: ratio %.3f (wall %.3f), "
              "%.2f us per call, rows bitwise equal: %s"
              % (label, 1e3 * med[False][0], calls, 1e3 * med[True][0], ratio_cpu, ratio_wall,
                 per_call, bitwise))

    lines = [
        "# Python stepping overhead (issue 5, acceptance 5)",
        "",
        "`PYTHONPATH=build/python /usr/bin/python3 bench/python_stepping.py --repeat %d`"
        % args.repeat,
        "",
        "Each model run from Python through the `mbdae` package, once as one `solve()` and once",
        "as one `solve_to(t)` per output time (`assemble()` first), alternating, %d times each;"
        % args.repeat,
        "medians of the process CPU time (wall time in brackets). Requirement: stepped / whole",
        "<= 1.5. The stepped rows are compared with the whole run's bitwise.",
        "",
        "| model | solve_to calls | one solve (ms) | stepped (ms) | ratio | extra per call (us) "
        "| rows bitwise equal |",
        "| --- | ---: | ---: | ---: | ---: | ---: | --- |",
    ]
    for label, calls, whole, stepped, rc, rw, per_call, bitwise in rows:
        lines.append("| %s | %d | %.1f (%.1f) | %.1f (%.1f) | **%.3f** (%.3f) | %.1f | %s |"
                     % (label, calls, 1e3 * whole[0], 1e3 * whole[1], 1e3 * stepped[0],
                        1e3 * stepped[1], rc, rw, per_call, "yes" if bitwise else "NO"))
    lines += ["", "Largest ratio: **%.3f** (%s)." % (worst, "<= 1.5: met" if worst <= 1.5
                                                       else "> 1.5: NOT met"),
              "", "Machine: %s, Python %s, numpy %s; absolute times depend on the machine "
              "and its load, the ratio is the result." % (platform.machine(),
                                                          platform.python_version(),
                                                          np.__version__), ""]
    os.makedirs(os.path.dirname(args.out), exist_ok=True)
    with open(args.out, "w") as f:
        f.write("\n".join(lines))
    print("wrote", args.out)
    return 0 if worst <= 1.5 and all(r[-1] for r in rows) else 1


if __name__ == "__main__":
    sys.exit(main())
