#!/usr/bin/env python3
"""HHT's Newton threshold against accuracy and time on issue 12's ball chains.

    /usr/bin/python3 bench/newton_tolerance.py --mbdae BUILD/mbdae [--repeats 3]

For every chain (N = 10, 100, 1000; `bench/scenes/ball_chain.py`, 1 s), fixed step h and
threshold (`--newton-tolerance`, 1e-12 the default ... 1e-8) one `mbdae simulate` run,
repeated `--repeats` times with the settings shuffled in every repeat (the runs of one
setting spread over the invocation); the tip error at t = 1 s against the peers
benchmark's reference (`bench/results/peers/reference_chainN.json`, Simbody RK-Merson at
accuracy 1e-12, 1e-11, 1e-9, checked there against RK-Feldberg and IDA), the Newton
iterations, factorisations and the solver CPU time (median over the repeats). Writes
`bench/results/newton_tolerance.md` and `.json`. The tests do not run it.
"""
import argparse
import json
import math
import os
import random
import statistics
import subprocess
import sys
import tempfile
import time

import h5py

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(ROOT, "bench", "peers"))
sys.path.insert(0, os.path.join(ROOT, "bench", "scenes"))
import run as peers  # noqa: E402  (tip_of, the references' location)

TOLERANCES = (1e-12, 1e-11, 1e-10, 1e-9, 1e-8)
STEPS = {10: (1e-3, 2.5e-4), 100: (1e-3, 2.5e-4), 1000: (1e-3,)}


def simulate(mbdae, model, n, h, tol, out):
    cmd = [mbdae, "simulate", model, "-o", out, "--quiet", "--integrator", "hht", "--fixed-step",
           "--step", repr(h), "--newton-tolerance", repr(tol)]
    p = subprocess.run(cmd, capture_output=True, text=True)
    if p.returncode != 0:
        return {"status": "failed", "message": p.stderr.strip()[-300:]}
    with h5py.File(out, "r") as f:
        a = f.attrs
        body = f["bodies/rod%d" % n]
        return {"status": str(a["status"]), "tip": peers.tip_of(body["position"][-1], body["orientation"][-1]),
                "solver_time": float(a["solver_cpu_time"]), "newton": int(a["newton_iterations"]),
                "factorizations": int(a["factorizations"]), "steps": int(a["steps_accepted"]),
                "rejected": int(a["steps_rejected"])}


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--mbdae", default=os.path.join(ROOT, "build", "mbdae"))
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--n", type=int, nargs="+", default=sorted(STEPS))
    ap.add_argument("--results", default=os.path.join(ROOT, "bench", "results"))
    a = ap.parse_args()
    refs = {}
    for n in a.n:
        with open(os.path.join(ROOT, "bench", "results", "peers", "reference_chain%d.json" % n)) as f:
            refs[n] = json.load(f)["tip"]
    settings = [(n, h, tol) for n in a.n for h in STEPS[n] for tol in TOLERANCES]
    runs = {s: [] for s in settings}
    load_before = os.getloadavg()[0]
    with tempfile.TemporaryDirectory() as tmp:
        models = {}
        for n in a.n:
            models[n] = os.path.join(tmp, "chain%d.yaml" % n)
            subprocess.run([sys.executable, os.path.join(ROOT, "bench", "scenes", "ball_chain.py"), str(n),
                            "-o", models[n], "--output-step", "1"], check=True)
        for rep in range(a.repeats):
            order = list(settings)
            random.Random(rep).shuffle(order)
            for s in order:
                n, h, tol = s
                r = simulate(a.mbdae, models[n], n, h, tol, os.path.join(tmp, "run.h5"))
                runs[s].append(r)
                print("repeat %d: N = %d, h = %g, newton_tolerance = %g: %s" % (
                    rep + 1, n, h, tol, "%.3f s" % r["solver_time"] if "solver_time" in r else r["status"]),
                    flush=True)
    rows = []
    for s in settings:
        n, h, tol = s
        rs = runs[s]
        ok = [r for r in rs if r["status"] == "done"]
        row = {"n": n, "h": h, "newton_tolerance": tol, "runs": len(rs), "done": len(ok)}
        if ok:
            r0 = ok[0]
            row.update(error=math.dist(r0["tip"], refs[n]), newton=r0["newton"],
                       factorizations=r0["factorizations"], steps=r0["steps"], rejected=r0["rejected"],
                       solver_time=statistics.median(r["solver_time"] for r in ok),
                       same_result=all(r["tip"] == r0["tip"] for r in ok))
        rows.append(row)
    out = {"command": " ".join(["bench/newton_tolerance.py"] + [x for x in sys.argv[1:]]),
           "date": time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime()),
           "load_before": load_before, "load_after": os.getloadavg()[0], "rows": rows}
    with open(os.path.join(a.results, "newton_tolerance.json"), "w") as f:
        json.dump(out, f, indent=1)
    lines = ["# HHT's Newton threshold on the ball chains", "",
             "`/usr/bin/python3 bench/newton_tolerance.py --mbdae BUILD/mbdae --repeats %d` on %s, load "
             "average %.1f before and %.1f after. Fixed-step HHT (alpha = -0.1, equilibrium form, "
             "modified), 1 s; error: the tip at t = 1 s against `bench/results/peers/reference_chainN.json`; "
             "time: the solver's CPU time, median of the repeats (the other numbers are the same in "
             "every repeat); time ratio: against the default threshold 1e-12 of the same N and h."
             % (a.repeats, out["date"], load_before, out["load_after"]), "",
             "| N | h | newton_tolerance | tip error [m] | error / default's | Newton iterations / step "
             "| factorisations / step | solver CPU [s] | time / default's |",
             "| ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |"]
    base = {(r["n"], r["h"]): r for r in rows if r["newton_tolerance"] == 1e-12 and "error" in r}
    for r in rows:
        if "error" not in r:
            lines.append("| %d | %g | %g | failed | | | | | |" % (r["n"], r["h"], r["newton_tolerance"]))
            continue
        b = base.get((r["n"], r["h"]))
        lines.append("| %d | %g | %g | %.4g | %.3f | %.2f | %.3f | %.3g | %.2f |" % (
            r["n"], r["h"], r["newton_tolerance"], r["error"], r["error"] / b["error"] if b else float("nan"),
            r["newton"] / r["steps"], r["factorizations"] / r["steps"], r["solver_time"],
            r["solver_time"] / b["solver_time"] if b else float("nan")))
    with open(os.path.join(a.results, "newton_tolerance.md"), "w") as f:
        f.write("\n".join(lines) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    main()
