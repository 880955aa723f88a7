"""Shared by the whole-run benchmarks on issue 12's ball chains (bench/newton_tolerance.py,
bench/linear_solver.py, bench/jacobian_cost.py, bench/predictor.py): their command line, the chains'
references, the chain models, `mbdae simulate` runs of a list of settings repeated with the
order shuffled in every repeat (so that the runs of one setting spread over the
invocation), what a run's results file says, a setting's summary over its repeats and the
written results."""
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
import run as peers  # noqa: E402  (tip_of)


def references(ns):
    """The tip at t = 1 s of each chain N (bench/results/peers/reference_chainN.json)."""
    refs = {}
    for n in ns:
        with open(os.path.join(ROOT, "bench", "results", "peers", "reference_chain%d.json" % n)) as f:
            refs[n] = json.load(f)["tip"]
    return refs


def simulate(mbdae, model, n, options, out, attrs=()):
    """`mbdae simulate MODEL -o OUT --quiet OPTIONS` of the chain of n rods: status, tip at
    the last row, solver CPU time, Newton iterations, factorisations, steps (accepted,
    rejected) and the results file's attributes `attrs`; status "failed" with the message
    when the program fails."""
    p = subprocess.run([mbdae, "simulate", model, "-o", out, "--quiet"] + list(options),
                       capture_output=True, text=True)
    if p.returncode != 0:
        return {"status": "failed", "message": p.stderr.strip()[-300:]}
    with h5py.File(out, "r") as f:
        a = f.attrs
        body = f["bodies/rod%d" % n]
        r = {"status": str(a["status"]), "tip": peers.tip_of(body["position"][-1], body["orientation"][-1]),
             "solver_time": float(a["solver_cpu_time"]), "newton": int(a["newton_iterations"]),
             "factorizations": int(a["factorizations"]), "steps": int(a["steps_accepted"]),
             "rejected": int(a["steps_rejected"])}
        for k in attrs:
            v = a[k]
            r[k] = v.item() if hasattr(v, "item") else str(v)
        return r


def run_shuffled(ns, settings, repeats, run_one, describe):
    """run_one(model_of_n, setting, out_path) for every setting (a tuple starting with N)
    `repeats` times, the order shuffled in every repeat; chain models with one row per
    second. Returns {setting: [results]}, and prints every run with describe(setting)."""
    runs = {s: [] for s in settings}
    with tempfile.TemporaryDirectory() as tmp:
        models = {}
        for n in ns:
            models[n] = os.path.join(tmp, "chain%d.yaml" % n)
            subprocess.run([sys.executable, os.path.join(ROOT, "bench", "scenes", "ball_chain.py"), str(n),
                            "-o", models[n], "--output-step", "1"], check=True)
        for rep in range(repeats):
            order = list(settings)
            random.Random(rep).shuffle(order)
            for s in order:
                r = run_one(models[s[0]], s, os.path.join(tmp, "run.h5"))
                runs[s].append(r)
                print("repeat %d: %s: %s" % (rep + 1, describe(s),
                                             "%.3f s" % r["solver_time"] if "solver_time" in r else r["status"]),
                      flush=True)
    return runs


def hht_study(a, settings, options_of, attrs, describe, keys):
    """Fixed-step HHT runs of every setting (n, h, ...) with `--step h` and the options
    options_of(setting), as run_shuffled runs them (a: parse_args's). Returns the rows --
    dict(zip(keys, setting)) with the setting's summary (attrs read from the results file)
    and its done runs' solver times -- and the load average before."""
    refs = references(a.n)
    load_before = os.getloadavg()[0]

    def one(model, s, out):
        return simulate(a.mbdae, model, s[0], ["--integrator", "hht", "--fixed-step", "--step", repr(s[1])] +
                        options_of(s), out, attrs)

    runs = run_shuffled(a.n, settings, a.repeats, one, describe)
    rows = []
    for s in settings:
        row = dict(zip(keys, s))
        row.update(summary(runs[s], refs[s[0]], attrs))
        row["solver_times"] = [r["solver_time"] for r in runs[s] if r["status"] == "done"]
        rows.append(row)
    return rows, load_before


def parse_args(doc, ns, more=None):
    """The benchmarks' command line (description: doc's first line): --mbdae (default
    build/mbdae), --repeats (3), --n (default ns), --results (bench/results), and the
    arguments more(parser) adds."""
    ap = argparse.ArgumentParser(description=doc.splitlines()[0])
    if more:
        more(ap)
    ap.add_argument("--mbdae", default=os.path.join(ROOT, "build", "mbdae"))
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--n", type=int, nargs="+", default=sorted(ns))
    ap.add_argument("--results", default=os.path.join(ROOT, "bench", "results"))
    return ap.parse_args()


def summary(runs, ref, attrs=()):
    """A setting's runs (simulate's dicts) summarised: runs, done and, if any is done, the
    first done run's tip error against ref, steps, rejected steps, Newton iterations,
    factorisations and `attrs`, the median solver time and whether every done run ended
    on the same tip."""
    ok = [r for r in runs if r["status"] == "done"]
    row = {"runs": len(runs), "done": len(ok)}
    if ok:
        r0 = ok[0]
        row.update(error=math.dist(r0["tip"], ref), steps=r0["steps"], rejected=r0["rejected"],
                   newton=r0["newton"], factorizations=r0["factorizations"],
                   solver_time=statistics.median(r["solver_time"] for r in ok),
                   same_result=all(r["tip"] == r0["tip"] for r in ok))
        row.update({k: r0[k] for k in attrs})
    return row


def option_table(rows, key, baseline, used, work_cost):
    """The table of a study of one HHT option on the chains (rows: hht_study's, each with
    n, h, solver and the option under `key`): per row N, h, the solver used, the attrs
    `used` (pairs of attribute and column title), the tip error, steps, iterations and
    factorisations per step, the work per step (iterations + work_cost[solver] x
    factorisations), its ratio to the row of the same N, h and solver whose option is
    `baseline`, the median solver time and its ratio to that row's."""
    lines = ["| N | h | solver | %s | tip error [m] | steps | iterations / step "
             "| factorisations / step | work / step | work ratio | solver CPU [s] | time ratio |"
             % " | ".join(title for _, title in used),
             "| ---: | ---: | --- | %s | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |"
             % " | ".join("---" for _ in used)]
    base = {(r["n"], r["h"], r["solver"]): r for r in rows if r[key] == baseline and "solver_time" in r}
    for r in rows:
        if "solver_time" not in r:
            cells = [""] * len(used)
            cells[-1] = str(r[key])
            lines.append("| %d | %g | %s | %s | failed | | | | | | | |"
                         % (r["n"], r["h"], r["solver"], " | ".join(cells)))
            continue
        b = base.get((r["n"], r["h"], r["solver"]))
        c = work_cost[r["solver"]]
        it, fa = r["newton"] / r["steps"], r["factorizations"] / r["steps"]
        work = it + c * fa
        work_b = (b["newton"] + c * b["factorizations"]) / b["steps"] if b else None
        lines.append("| %d | %g | %s | %s | %.4g | %d | %.2f | %.3f | %.2f | %s | %.3g | %s |" % (
            r["n"], r["h"], r["linear_solver_used"], " | ".join(str(r[attr]) for attr, _ in used),
            r["error"], r["steps"], it, fa, work, "%.2f" % (work / work_b) if b else "",
            r["solver_time"], "%.2f" % (r["solver_time"] / b["solver_time"]) if b else ""))
    return lines


def write(results, name, load_before, rows, make_lines):
    """results/NAME.json (the command, date, loads and rows) and results/NAME.md, the lines
    make_lines(that json's dict) gives, printed too."""
    out = {"command": " ".join(["bench/%s.py" % name] + sys.argv[1:]),
           "date": time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime()),
           "load_before": load_before, "load_after": os.getloadavg()[0], "rows": rows}
    with open(os.path.join(results, name + ".json"), "w") as f:
        json.dump(out, f, indent=1)
    text = "\n".join(make_lines(out))
    with open(os.path.join(results, name + ".md"), "w") as f:
        f.write(text + "\n")
    print(text)
