#!/usr/bin/env python3
"""Two builds' bench_phases side by side, alternated, on the ball chains.

    /usr/bin/python3 bench/phases/compare.py --base DIR --new DIR
        [--n 100 1000 10000] [--rounds 3] [--phases load,build,consistent]

For every round, every N and each build in turn (base, then new): runs
DIR/bench/bench_phases on the chain of bench/scenes/ball_chain.py with only the named
phases (the others skipped), and keeps its medians and first calls. Prints, per phase and
build, the median over the rounds of each (CPU seconds) and the exponent fitted by least
squares on log t against log N, the ratio base / new, and the single values of the
rounds, so that the noise of a shared machine shows. Both builds must have a
bench_phases that prints "first_call" (this folder's since it was added).
"""
import argparse
import json
import math
import os
import statistics
import subprocess
import sys
import tempfile

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
sys.path.insert(0, os.path.join(HERE, "..", "scenes"))
import ball_chain  # noqa: E402
from run import PHASES, fit  # noqa: E402


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--base", required=True)
    ap.add_argument("--new", required=True)
    ap.add_argument("--n", type=int, nargs="+", default=[100, 1000, 10000])
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--phases", default="load,build,consistent")
    a = ap.parse_args()
    phases = a.phases.split(",")
    skip = ",".join(p for p in PHASES if p not in phases and p != "check")
    builds = {"base": os.path.abspath(a.base), "new": os.path.abspath(a.new)}
    runs = {}  # (kind, phase, build, n) -> [seconds of each round]
    with tempfile.TemporaryDirectory() as tmp:
        for n in a.n:
            ball_chain.write_chain(os.path.join(tmp, "chain%d.yaml" % n), n)
        for r in range(a.rounds):
            for n in a.n:
                for name, build in builds.items():
                    cmd = [os.path.join(build, "bench", "bench_phases"), "chain%d.yaml" % n, "--skip", skip]
                    out = subprocess.run(cmd, check=True, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL,
                                         text=True, cwd=tmp).stdout
                    data = json.loads(out.strip().splitlines()[-1])
                    for kind in ("seconds", "first_call"):
                        for p in phases:
                            runs.setdefault((kind, p, name, n), []).append(data[kind][p])
                    print("round %d N = %d %s done" % (r + 1, n, name), file=sys.stderr)
    for kind, title in (("seconds", "median of the calls"), ("first_call", "first call")):
        print("\n%s (CPU seconds, median over %d rounds; exponent over N = %s)\n" %
              (title, a.rounds, ", ".join(str(n) for n in a.n)))
        print("| phase | build | " + " | ".join("N = %d" % n for n in a.n) + " | exponent |")
        print("| --- | --- |" + " --- |" * (len(a.n) + 1))
        for p in phases:
            med = {}
            for name in builds:
                med[name] = [statistics.median(runs[(kind, p, name, n)]) for n in a.n]
                e = fit(a.n, med[name])
                print("| %s | %s | %s | %s |" % (p, name, " | ".join("%.3g" % t for t in med[name]),
                                                  "-" if e is None else "%.2f" % e))
            print("| %s | base / new | %s | |" % (p, " | ".join("%.2f" % (b / m) for b, m in
                                                              zip(med["base"], med["new"]))))
        print("\nsingle rounds:")
        for p in phases:
            for name in builds:
                print("  %s %s: %s" % (p, name, "; ".join(
                    "N = %d: %s" % (n, ", ".join("%.3g" % t for t in runs[(kind, p, name, n)])) for n in a.n)))


if __name__ == "__main__":
    main()
