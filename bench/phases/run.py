#!/usr/bin/env python3
"""Seconds per phase against the size of the ball chain, and the fitted exponents.

    /usr/bin/python3 bench/phases/run.py [--build DIR] [--n 10 100 1000 10000]
                                         [--label NAME] [--out FILE.json] [--timeout S]

For every N: writes the chain of bench/scenes/ball_chain.py (into a temporary folder),
runs DIR/bench/bench_phases on it, one process per phase (seconds per phase, see
bench_phases.cc: the median of at least 3 calls, and the first call) and times
`DIR/mbdae check` on it (CPU time of the process, user + system, best of 3 when a run
takes under 10 s of wall time, else one run). Every number is CPU time: on a machine
shared with other work, wall time measures that work too.
Then fits the exponent of every phase by least squares on log t against log N over the
three largest N (of the medians, and of the first calls), and writes the JSON of all
numbers (--out, default bench/phases/results-LABEL.json) and prints two Markdown tables:
medians and first calls. A run that takes longer
than --timeout seconds (default 1800) is stopped and its phases left empty.
"""
import argparse
import json
import math
import os
import subprocess
import sys
import tempfile
import time

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, "..", "scenes"))
import ball_chain  # noqa: E402

# The bench_phases runs, one process each ("write" also times create_file).
RUNS = ["load", "build", "redundancy", "consistent", "determinacy", "assemble", "residual", "jacobian",
        "hht_step", "hht_step_tree", "ida_step", "ida_step_tree", "row", "write"]
PHASES = ["load", "build", "redundancy", "consistent", "determinacy", "assemble", "residual",
          "jacobian", "hht_step", "hht_step_tree", "ida_step", "ida_step_tree", "row", "create_file", "write",
          "check"]


def fit(ns, ts):
    pts = [(math.log(n), math.log(t)) for n, t in zip(ns, ts) if t is not None and t > 0]
    if len(pts) < 2:
        return None
    mx = sum(p[0] for p in pts) / len(pts)
    my = sum(p[1] for p in pts) / len(pts)
    sxx = sum((p[0] - mx) ** 2 for p in pts)
    sxy = sum((p[0] - mx) * (p[1] - my) for p in pts)
    return sxy / sxx


def time_check(mbdae, model, timeout):
    best = None
    for _ in range(3):
        t0 = time.perf_counter()
        try:
            p = subprocess.Popen([mbdae, "check", model], stdout=subprocess.DEVNULL)
            _, status, usage = os.wait4(p.pid, 0)
            p.returncode = os.waitstatus_to_exitcode(status)
        except OSError:
            return None
        if p.returncode != 0:
            raise RuntimeError("mbdae check %s failed (exit %d)" % (model, p.returncode))
        wall = time.perf_counter() - t0
        dt = usage.ru_utime + usage.ru_stime
        best = dt if best is None else min(best, dt)
        if wall > 10:
            break
    return best


def table(result, seconds="seconds", exponents="exponents"):
    ns = result["n"]
    lines = ["| phase | " + " | ".join("N = %d" % n for n in ns) + " | exponent (3 largest N) |",
             "| --- |" + " --- |" * (len(ns) + 1)]
    for p in PHASES:
        row = result[seconds].get(p)
        if row is None or all(t is None for t in row):
            continue
        cells = ["-" if t is None else "%.3g" % t for t in row]
        e = result[exponents].get(p)
        lines.append("| %s | %s | %s |" % (p, " | ".join(cells), "-" if e is None else "%.2f" % e))
    return "\n".join(lines)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--build", default=os.path.join(HERE, "..", "..", "build"))
    ap.add_argument("--n", type=int, nargs="+", default=[10, 100, 1000, 10000])
    ap.add_argument("--label", default="after")
    ap.add_argument("--out")
    ap.add_argument("--timeout", type=float, default=1800)
    ap.add_argument("--skip", default="", help="phases not to run (comma-separated)")
    a = ap.parse_args()
    a.build = os.path.abspath(a.build)
    bench = os.path.join(a.build, "bench", "bench_phases")
    mbdae = os.path.join(a.build, "mbdae")
    skip = set(a.skip.split(",")) if a.skip else set()
    result = {"label": a.label, "n": a.n, "seconds": {p: [] for p in PHASES},
              "first_call": {p: [] for p in PHASES}, "sizes": []}
    with tempfile.TemporaryDirectory() as tmp:
        for n in a.n:
            model = os.path.join(tmp, "chain%d.yaml" % n)
            ball_chain.write_chain(model, n)
            # One process per phase (write with create_file): a phase's repeated calls
            # leave the heap as a run would not have it for the next phase (three loads of
            # the 10^4 chain made the redundancy check after them 6x slower).
            data = {"seconds": {}, "first_call": {}}
            sizes = {}
            for p in RUNS:
                if p in skip:
                    continue
                # In the temporary folder on the file name: the results name no machine path.
                cmd = [bench, os.path.basename(model), "--skip", ",".join(q for q in RUNS if q != p)]
                print("N = %d: %s" % (n, " ".join(cmd)), file=sys.stderr)
                try:
                    out = subprocess.run(cmd, check=True, stdout=subprocess.PIPE, text=True,
                                         timeout=a.timeout, cwd=tmp).stdout
                    one = json.loads(out.strip().splitlines()[-1])
                except subprocess.TimeoutExpired:
                    sizes["timed_out"] = a.timeout
                    continue
                for kind in ("seconds", "first_call"):
                    data[kind].update(one.get(kind, {}))
                for k, v in one.items():
                    if k not in ("seconds", "first_call") and (k not in sizes or v):
                        sizes[k] = v
            result["sizes"].append(sizes)
            check = None if "check" in skip else time_check(mbdae, model, a.timeout)
            data["seconds"]["check"] = check
            for p in PHASES:
                result["seconds"][p].append(data["seconds"].get(p))
                # The process of `check` runs once: its time is its first call.
                result["first_call"][p].append(data.get("first_call", {}).get(p, check if p == "check" else None))
    result["exponents"] = {p: fit(a.n[-3:], result["seconds"][p][-3:]) for p in PHASES}
    result["first_call_exponents"] = {p: fit(a.n[-3:], result["first_call"][p][-3:]) for p in PHASES}
    out = a.out or os.path.join(HERE, "results-%s.json" % a.label)
    with open(out, "w") as f:
        json.dump(result, f, indent=1)
    print("Median of the calls (CPU seconds):\n")
    print(table(result))
    print("\nFirst call (CPU seconds; phases timed per step or row have none):\n")
    print(table(result, "first_call", "first_call_exponents"))


if __name__ == "__main__":
    main()
