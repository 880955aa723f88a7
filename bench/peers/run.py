#!/usr/bin/env python3
"""mbdae against Simbody at equal error (issue 12): work-precision runs of both solvers,
interleaved and repeated, on the ball chains and the parallelogram four-bar, and the
cost of an HHT step against a bare KLU refactorisation + solve (bench/README.md, "Peers:
mbdae against Simbody").

    /usr/bin/python3 bench/peers/run.py [--build DIR] [--quick] [--repeats K]
        [--scenes chain10 chain100 chain1000 fourbar] [--no-step-flops] [--report-only]
        [--new-reference] [--results DIR]

Each scene's runs go to RESULTS/runs_SCENE.json (with the command, the date and the load
average); the report (RESULTS/results.md, work_precision.csv, work_precision.png) is
built from every runs_*.json there, so scenes may be run by separate invocations.
mbdae runs are `mbdae simulate` processes (solver time: the results file's
solver_cpu_time; also the process' wall and CPU time); Simbody runs are processes of
bench/peers/simbody_peers (solver time: the CPU time of its integration; also the
process' wall and CPU time). Per repeat, each scene's mbdae and Simbody settings are
shuffled and spread evenly over the repeat, so that the two solvers' runs alternate.
"""
import argparse
import datetime
import json
import math
import os
import random
import resource
import shutil
import statistics
import subprocess
import sys
import tempfile
import time

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(os.path.dirname(HERE))
sys.path.insert(0, os.path.join(ROOT, "bench", "scenes"))
sys.path.insert(0, os.path.join(ROOT, "verification", "singular"))

import ball_chain  # noqa: E402  (bench/scenes/ball_chain.py)

FOURBAR = os.path.join(ROOT, "verification", "singular", "fourbar.yaml")
# mbdae settings whose results file holds the tip body's datasets only (`--output-bodies
# rodN --output-joints none`; /q, /v, /a and /lambda stay whole).
TIP_ONLY = ("erk_tip",)
TOL_EQUAL = 1e-6      # the error at which the solvers are compared (issue 12)
BRANCH_LIMIT = 1e-2   # rad: largest crank gap / coupler rotation still on the branch


def geometric(a, b, n):
    """n values from a to b, equal ratios."""
    return [a * (b / a) ** (k / (n - 1)) for k in range(n)]


def chain_settings(n):
    """(solver, integrator, value) of every run of the chain of n rods."""
    sim, mb = [], []
    if n <= 100:
        sim += [("rkmerson", a) for a in (1e-3, 1e-4, 1e-5, 1e-6, 1e-7, 1e-8)]
        sim += [("rkfehlberg", a) for a in (1e-3, 1e-4, 1e-5, 1e-6, 1e-7, 1e-8)]
        if n <= 10:
            sim += [("rk3", a) for a in (1e-3, 1e-4, 1e-5, 1e-6, 1e-7)]
            sim += [("cpodes", a) for a in (1e-3, 1e-4, 1e-5, 1e-6, 1e-7, 1e-8)]
        else:  # the slow ones over a shorter range (CPodes: 11 s of CPU at 1e-6)
            sim += [("rk3", a) for a in (1e-3, 1e-4, 1e-5, 1e-6)]
            sim += [("cpodes", a) for a in (1e-4, 1e-6)]
        sim += [("verlet", a) for a in (1e-2, 1e-3, 1e-4, 1e-5)]
        if n <= 10:  # first order: sensible only on the small chain
            sim += [("euler", a) for a in (1e-3, 1e-4)]
        mb += [("ida", r) for r in (1e-4, 1e-5, 1e-6, 1e-7, 1e-8, 1e-9)]
        mb += [("hht", h) for h in (1e-3, 5e-4, 2.5e-4, 1.25e-4)]
        mb += [("hht_adaptive", t) for t in (1e-4, 1e-5, 1e-6, 1e-7)]
        mb += [("erk", r) for r in (1e-3, 1e-4, 1e-5, 1e-6, 1e-7, 1e-8)]
        mb += [("erk_tip", r) for r in (1e-4, 1e-5, 1e-6)]
    else:  # N = 1000: a few settings near the compared error (each mbdae run's set-up
        # takes minutes, issue 12's goal 1)
        sim += [("rkmerson", a) for a in (3e-4, 1e-4, 1e-5, 1e-6)]
        mb += [("hht", 1e-3), ("hht", 5e-4)]
        mb += [("erk", r) for r in (1e-4, 3e-5, 1e-5, 1e-6)]
        mb += [("erk_tip", r) for r in (1e-4, 3e-5, 1e-5)]
    return [("simbody",) + s for s in sim], [("mbdae",) + s for s in mb]


def fourbar_settings():
    sim = [("rkmerson", a) for a in (1e-4, 1e-6, 1e-8, 1e-10)]
    sim += [("rkfehlberg", a) for a in (1e-4, 1e-6, 1e-8, 1e-10)]
    sim += [("rk3", a) for a in (1e-4, 1e-6, 1e-8)]
    sim += [("cpodes", a) for a in (1e-4, 1e-6)]  # at 1e-8 it stalled (README)
    sim += [("verlet", a) for a in (1e-3, 1e-4, 1e-5)]
    mb = [("ida", r) for r in (1e-4, 1e-6, 1e-8, 1e-10)]
    mb += [("hht_adaptive", t) for t in (1e-4, 1e-6, 1e-8)]
    mb += [("hht", h) for h in (1e-3, 1e-4)]
    # erk cannot pass the singular positions (docs/erk.md): run to show it.
    mb += [("erk", r) for r in (1e-6, 1e-8)]
    return [("simbody",) + s for s in sim], [("mbdae",) + s for s in mb]


TIMEOUT = 600.0  # s of wall time per run (--timeout); a run killed then counts as failed


def run_process(cmd):
    """Runs cmd; returns (returncode, stdout, stderr, wall seconds); returncode None when
    the run was stopped after TIMEOUT seconds."""
    t0 = time.perf_counter()
    p = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        out, err = p.communicate(timeout=TIMEOUT)
        rc = p.returncode
    except subprocess.TimeoutExpired:
        p.kill()
        out, err = p.communicate()
        rc, err = None, "stopped after %g s of wall time (--timeout)" % TIMEOUT
    wall = time.perf_counter() - t0
    # communicate() reaped the child: its CPU time is in the children's totals.
    return rc, out, err, wall


class ChildCpu:
    """CPU seconds (user + system) of the child processes reaped inside the block."""

    @staticmethod
    def _now():
        r = resource.getrusage(resource.RUSAGE_CHILDREN)
        return r.ru_utime + r.ru_stime

    def __enter__(self):
        self.t0 = self._now()
        return self

    def __exit__(self, *exc):
        self.seconds = self._now() - self.t0


def tip_of(q_last, e_last, half=ball_chain.LENGTH / 2):
    """Far end of the last rod: centre + half * (first column of R(e)), e scalar first."""
    e0, e1, e2, e3 = e_last
    col = (e0 * e0 + e1 * e1 - e2 * e2 - e3 * e3, 2 * (e1 * e2 + e0 * e3), 2 * (e1 * e3 - e0 * e2))
    return [q_last[k] + half * col[k] for k in range(3)]


def rotation_angle(e):
    """Rotation angle (rad, 0..pi) of the Euler parameters e (scalar first)."""
    v = math.sqrt(e[1] ** 2 + e[2] ** 2 + e[3] ** 2)
    return 2 * math.atan2(v, abs(e[0]))


def relative(a, b):
    """Euler parameters of conj(a) * b (the rotation from a to b), scalar first."""
    a0, a1, a2, a3 = a[0], -a[1], -a[2], -a[3]
    b0, b1, b2, b3 = b
    return (a0 * b0 - a1 * b1 - a2 * b2 - a3 * b3,
            a0 * b1 + a1 * b0 + a2 * b3 - a3 * b2,
            a0 * b2 - a1 * b3 + a2 * b0 + a3 * b1,
            a0 * b3 + a1 * b2 - a2 * b1 + a3 * b0)


def mbdae_command(mbdae, model, integrator, value, out, extra=()):
    cmd = [mbdae, "simulate", model, "-o", out, "--quiet"]
    if integrator == "ida":
        cmd += ["--integrator", "ida", "--rtol", repr(value), "--atol", repr(value)]
    elif integrator == "hht":
        cmd += ["--integrator", "hht", "--fixed-step", "--step", repr(value)]
    elif integrator == "hht_adaptive":
        cmd += ["--integrator", "hht", "--adaptive", "--tolerance", repr(value)]
    elif integrator in ("erk", "erk_tip"):
        cmd += ["--integrator", "erk", "--rtol", repr(value), "--atol", repr(value)]
    else:
        raise ValueError(integrator)
    return cmd + list(extra)


def run_mbdae(mbdae, scene, model, integrator, value, tmp):
    import h5py
    out = os.path.join(tmp, "run.h5")
    extra = ["--output-step", "0.01"] if scene == "fourbar" else []
    if integrator in TIP_ONLY:
        # The results file with the datasets of the tip's body only (every coordinate
        # stays in /q): what the run is asked for, as Simbody's runs report the tip alone.
        extra += ["--output-bodies", "rod%d" % int(scene[5:]), "--output-joints", "none"]
    cmd = mbdae_command(mbdae, model, integrator, value, out, extra)
    with ChildCpu() as cpu:
        rc, stdout, stderr, wall = run_process(cmd)
    rec = {"solver": "mbdae", "scene": scene, "integrator": integrator, "value": value,
           "returncode": rc, "process_wall": wall, "process_cpu": cpu.seconds}
    if rc is None or not os.path.exists(out):
        rec.update(status="failed", message=stderr.strip()[-300:])
        if os.path.exists(out):
            os.remove(out)
        return rec
    with h5py.File(out, "r") as f:
        a = f.attrs
        rec["status"] = str(a.get("status"))
        rec["solver_time"] = float(a["solver_cpu_time"]) if "solver_cpu_time" in a else None
        rec["steps"] = int(a["steps_accepted"]) if "steps_accepted" in a else None
        rec["t_reached"] = float(a.get("t_reached", float("nan")))
        if rec["status"] != "done":
            rec["message"] = str(a.get("failure_reason", stderr.strip()[-300:]))
        elif scene.startswith("chain"):
            n = int(scene[5:])
            body = f["bodies/rod%d" % n]
            rec["tip"] = tip_of(body["position"][-1], body["orientation"][-1])
        else:
            rec["phi"] = math.pi / 2 - float(f["measures/phi0"][-1])
            rec["phi_0_5"] = math.pi / 2 - float(f["measures/phi0"][50])
            turn = max(rotation_angle(e) for e in f["bodies/coupler0/orientation"][:])
            e0 = f["bodies/crank0/orientation"][:]
            e1 = f["bodies/crank1/orientation"][:]
            gap = max(rotation_angle(relative(a0, a1)) for a0, a1 in zip(e0, e1))
            rec["max_coupler_turn"], rec["max_crank_gap"] = turn, gap
            rec["branch"] = ("parallelogram" if turn < BRANCH_LIMIT and gap < BRANCH_LIMIT
                             else "left")
    os.remove(out)
    return rec


def run_simbody(simbody, scene, integrator, value):
    if scene.startswith("chain"):
        cmd = [simbody, "chain", scene[5:], integrator, repr(value)]
    else:
        cmd = [simbody, "fourbar", integrator, repr(value)]
    with ChildCpu() as cpu:
        rc, stdout, stderr, wall = run_process(cmd)
    rec = {"solver": "simbody", "scene": scene, "integrator": integrator, "value": value,
           "returncode": rc, "process_wall": wall, "process_cpu": cpu.seconds}
    line = stdout.strip().splitlines()[-1] if stdout.strip() else ""
    try:
        d = json.loads(line)
    except ValueError:
        rec.update(status="failed", message=(stderr.strip() or "no output")[-300:])
        return rec
    rec["status"] = d["status"]
    rec["solver_time"] = d["solve_cpu"]
    rec["steps"] = d["steps"]
    rec["t_reached"] = d["t"]
    for k in ("tip", "phi", "phi_0_5", "max_coupler_turn", "max_crank_gap", "branch"):
        if k in d:
            rec[k] = d[k]
    if d["status"] != "done":
        rec["message"] = (d.get("message", "") + " " + stderr.strip()[-300:]).strip()
    return rec


def load_avg():
    try:
        return os.getloadavg()
    except OSError:
        return None


def write_chain_model(n, tmp):
    path = os.path.join(tmp, "chain%d.yaml" % n)
    ball_chain.write_chain(path, n, t_end=1.0, output_step=1.0)
    return path


# Accuracy of the chains' references: Simbody RK-Merson at REF_ACCURACY[n], checked
# against Simbody RK-Feldberg at the same accuracy and mbdae IDA at rtol = atol
# REF_IDA[n] (None: no IDA check; N = 1000 would spend most of the benchmark's time on it).
REF_ACCURACY = {10: 1e-12, 100: 1e-11, 1000: 1e-9}
REF_IDA = {10: 1e-11, 100: 1e-10, 1000: None}


def chain_reference(n, tools, tmp, results, new):
    """The chain's tip at 1 s (REF_ACCURACY, REF_IDA), cached in reference_chainN.json."""
    path = os.path.join(results, "reference_chain%d.json" % n)
    if os.path.exists(path) and not new:
        with open(path) as f:
            return json.load(f)
    scene = "chain%d" % n
    acc = REF_ACCURACY[n]
    print("reference for %s ..." % scene, flush=True)
    runs = [run_simbody(tools["simbody"], scene, "rkmerson", acc),
            run_simbody(tools["simbody"], scene, "rkfehlberg", acc)]
    if REF_IDA[n]:
        runs.append(run_mbdae(tools["mbdae"], scene, tools["models"][scene], "ida", REF_IDA[n],
                              tmp))
    ref = runs[0]
    if ref.get("status") != "done":
        raise RuntimeError("reference run failed: %s" % ref)
    checks = []
    for r in runs[1:]:
        d = (math.dist(r["tip"], ref["tip"]) if r.get("status") == "done" else None)
        checks.append({"solver": r["solver"], "integrator": r["integrator"], "value": r["value"],
                       "status": r.get("status"), "tip": r.get("tip"), "difference": d,
                       "solver_time": r.get("solver_time"), "process_wall": r["process_wall"]})
    out = {"scene": scene, "tip": ref["tip"], "how": "Simbody RK-Merson at accuracy %g" % acc,
           "solver_time": ref["solver_time"], "checks": checks,
           "bound": max([c["difference"] for c in checks if c["difference"] is not None],
                        default=None),
           "date": datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds")}
    with open(path, "w") as f:
        json.dump(out, f, indent=1)
    return out


def fourbar_reference():
    import numpy as np
    import reference  # verification/singular/reference.py
    p = reference.phi(np.array([0.5, reference.T_END]))
    return {"phi": float(p[1]), "phi_0_5": float(p[0]),
            "how": "verification/singular/reference.py (DOP853 at rtol 1e-13)"}


def run_scene(scene, tools, tmp, results, repeats, seed, new_reference):
    if scene == "fourbar":
        sim, mb = fourbar_settings()
        ref = fourbar_reference()
    else:
        n = int(scene[5:])
        sim, mb = chain_settings(n)
        ref = chain_reference(n, tools, tmp, results, new_reference)
    rng = random.Random(seed)
    runs = []
    started = datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds")
    load_before = load_avg()
    def save(done_repeats):
        out = {"scene": scene, "reference": ref, "repeats": done_repeats, "started": started,
               "ended": datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds"),
               "load_before": load_before, "load_after": load_avg(), "cpus": os.cpu_count(),
               "command": " ".join(["bench/peers/run.py"] + sys.argv[1:]), "runs": runs}
        with open(os.path.join(results, "runs_%s.json" % scene), "w") as f:
            json.dump(out, f, indent=1)

    for rep in range(repeats):
        a, b = list(mb), list(sim)
        rng.shuffle(a)
        rng.shuffle(b)
        # Spread both lists evenly over the repeat: item k of a list of length m sits at
        # (k + 1/2) / m, so mbdae and Simbody runs alternate through the whole repeat.
        keyed = [((k + 0.5) / len(a), 0, x) for k, x in enumerate(a)]
        keyed += [((k + 0.5) / len(b), 1, x) for k, x in enumerate(b)]
        order = [x for _, _, x in sorted(keyed)]
        for solver, integ, value in order:
            if solver == "mbdae":
                rec = run_mbdae(tools["mbdae"], scene, tools["models"][scene], integ, value, tmp)
            else:
                rec = run_simbody(tools["simbody"], scene, integ, value)
            rec["repeat"] = rep
            runs.append(rec)
            print("  %s %d %-7s %-12s %-8g %-6s solver %.3g s, process %.3g s" % (
                scene, rep, solver, integ, value, rec.get("status"),
                rec.get("solver_time") or float("nan"), rec["process_wall"]), flush=True)
        save(rep + 1)  # after every repeat, so that a stopped invocation keeps its repeats


def run_step_flops(tools, tmp, results, repeats):
    exe = tools["step_flops"]
    args = [exe]
    for n in (100, 1000):
        args += ["--model", "%d=%s" % (n, write_chain_model(n, tmp))]
    out = os.path.join(results, "step_flops.json")
    args += ["--benchmark_out=" + out, "--benchmark_out_format=json",
             "--benchmark_repetitions=%d" % repeats, "--benchmark_display_aggregates_only=true",
             "--benchmark_enable_random_interleaving=true"]
    print("step against refactor + solve (bench_step_flops) ...", flush=True)
    load = load_avg()
    subprocess.run(args, check=True)
    with open(out) as f:
        d = json.load(f)
    d["load_before"] = load
    d["command"] = " ".join(["bench/peers/run.py"] + sys.argv[1:])
    with open(out, "w") as f:
        json.dump(d, f, indent=1)


# ---- report -----------------------------------------------------------------------------


def summarise(data):
    """Per setting: median times over the repeats, the error, the status."""
    ref = data["reference"]
    groups = {}
    for r in data["runs"]:
        groups.setdefault((r["solver"], r["integrator"], r["value"]), []).append(r)
    rows = []
    for (solver, integ, value), rs in groups.items():
        done = [r for r in rs if r.get("status") == "done"]
        row = {"scene": data["scene"], "solver": solver, "integrator": integ, "value": value,
               "runs": len(rs), "done": len(done)}
        if done:
            row["solver_time"] = statistics.median(r["solver_time"] for r in done)
            row["process_wall"] = statistics.median(r["process_wall"] for r in done)
            row["process_cpu"] = statistics.median(r["process_cpu"] for r in done)
            row["steps"] = done[0].get("steps")
            if data["scene"] == "fourbar":
                row["error"] = abs(done[0]["phi"] - ref["phi"])
                row["error_0_5"] = abs(done[0]["phi_0_5"] - ref["phi_0_5"])
                row["branch"] = done[0]["branch"]
                row["max_coupler_turn"] = done[0]["max_coupler_turn"]
                row["max_crank_gap"] = done[0]["max_crank_gap"]
            else:
                row["error"] = math.dist(done[0]["tip"], ref["tip"])
            row["status"] = "done" if len(done) == len(rs) else "failed %d of %d" % (
                len(rs) - len(done), len(rs))
        else:
            row["status"] = "failed"
            row["message"] = rs[0].get("message", "")
        rows.append(row)
    order = {"simbody": 1, "mbdae": 0}
    rows.sort(key=lambda r: (order[r["solver"]], r["integrator"], -r["value"]))
    return rows


LABEL = {"ida": "IDA rtol", "hht": "HHT h", "hht_adaptive": "HHT adaptive tol",
         "erk": "ERK rtol", "erk_tip": "ERK (tip body's datasets only) rtol", "rkmerson": "RK-Merson acc", "rkfehlberg": "RK-Feldberg acc", "rk3": "RK3 acc",
         "cpodes": "CPodes acc", "verlet": "Verlet acc", "euler": "explicit Euler acc",
         "semieuler2": "semi-explicit Euler 2 acc"}


def setting_name(r):
    return "%s %g" % (LABEL[r["integrator"]], r["value"])


def best(rows, solver, key, limit, fourbar, kinds=None):
    """The fastest done run of `solver` within `limit` (of the integrators `kinds`: all if None)."""
    ok = [r for r in rows if r["solver"] == solver and r.get("status") == "done"
          and (kinds is None or (r["integrator"] in TIP_ONLY) == (kinds == "tip"))
          and r.get("error") is not None and r["error"] <= limit
          and (not fourbar or r.get("branch") == "parallelogram")]
    return min(ok, key=lambda r: r[key]) if ok else None


def fmt(x, spec="%.3g"):
    return "-" if x is None else spec % x


def write_report(results):
    # runs_SCENE.json, and runs_SCENE_*.json of earlier invocations kept beside it: the
    # runs of one scene are pooled (each invocation's command is listed).
    import glob
    scenes = []
    for name in ("chain10", "chain100", "chain1000", "fourbar"):
        parts = []
        for p in sorted(glob.glob(os.path.join(results, "runs_%s.json" % name)) +
                        glob.glob(os.path.join(results, "runs_%s_*.json" % name))):
            with open(p) as f:
                parts.append(json.load(f))
        if not parts:
            continue
        data = dict(parts[0])
        data["runs"] = [r for d in parts for r in d["runs"]]
        data["parts"] = parts
        scenes.append(data)
    allrows = []
    md = ["# mbdae against Simbody at equal error (issue 12)", "",
          "Generated by `bench/peers/run.py` (bench/README.md, \"Peers: mbdae against "
          "Simbody\") from the `runs_*.json` of this folder. Times: **solver** = CPU seconds "
          "of the integration alone (mbdae: the results file's `solver_cpu_time`; Simbody: "
          "the CPU time of `Integrator::stepTo` calls in `simbody_peers`), **process** = wall "
          "seconds of the whole process (loading or building the model, set-up, "
          "integration, output), both the median over the repeats. Error: chains, the "
          "distance of the tip (far end of the last rod) at t = 1 s from the reference; "
          "four-bar, |phi(10 s) - phi_ref(10 s)| of the crank angle (rad), and whether the "
          "run stayed on the parallelogram branch (crank angles equal and coupler "
          "translating to %g rad at every row, rows every 0.01 s)." % BRANCH_LIMIT, "",
          "The machine (2 cores) was shared with other jobs during every run: absolute "
          "times are slow and noisy; each ratio comes from runs interleaved in one "
          "invocation (mbdae, Simbody, mbdae, ... in shuffled order, each setting repeated).",
          ""]
    summary = ["## Ratios at equal error", "",
               "Best time of each solver among its settings with error <= %g (four-bar: "
               "among the runs on the parallelogram branch), ratio = mbdae / Simbody (below "
               "1: mbdae ahead). Process: mbdae's runs writing the whole results file (every "
               "body's and joint's datasets), and its runs writing the tip body's datasets "
               "only (`--output-bodies rodN --output-joints none`; /q, /v, /a, /lambda "
               "whole; Simbody's runs write nothing but the tip)." % TOL_EQUAL, "",
               "| scene | Simbody best (solver s) | mbdae best (solver s) | ratio solver | "
               "Simbody best (process s) | mbdae best (process s), whole results file | ratio process | "
               "mbdae best (process s), tip body's datasets | ratio process |",
               "| --- | --- | --- | ---: | --- | --- | ---: | --- | ---: |"]
    details = []
    for data in scenes:
        rows = summarise(data)
        allrows += rows
        fb = data["scene"] == "fourbar"
        cells = []
        for key, kinds in (("solver_time", None), ("process_wall", "whole"), ("process_wall", "tip")):
            s = best(rows, "simbody", key, TOL_EQUAL, fb)
            m = best(rows, "mbdae", key, TOL_EQUAL, fb, kinds)
            cells.append((s, m, key, kinds))
        line = "| %s |" % data["scene"]
        for s, m, key, kinds in cells:
            if kinds != "tip":
                line += " %s |" % ("%s: %.3g (%.1e)" % (setting_name(s), s[key], s["error"]) if s else "none")
            line += " %s | %s |" % (
                "%s: %.3g (%.1e)" % (setting_name(m), m[key], m["error"]) if m else "none",
                "%.2f" % (m[key] / s[key]) if s and m else "-")
        summary.append(line)
        ref = data["reference"]
        details += ["## %s" % data["scene"], ""]
        for part in data["parts"]:
            la, lb = part.get("load_before"), part.get("load_after")
            details.append("Command: `/usr/bin/python3 %s`; %s .. %s UTC; %d repeat(s); %s "
                           "CPUs; load average before %s, after %s; %d runs." % (
                               part["command"], part["started"], part["ended"],
                               part["repeats"], part.get("cpus"), fmt_load(la), fmt_load(lb),
                               len(part["runs"])))
            details.append("")
        details.append("")
        if fb:
            details.append("Reference: %s, phi(10 s) = %.12f rad (phi(0.5 s) = %.12f, before "
                           "the first singular position; the column err 0.5 s checks each "
                           "model's motion there)." % (ref["how"], ref["phi"], ref["phi_0_5"]))
        else:
            chk = "; ".join("%s %s %g: %s" % (c["solver"], c["integrator"], c["value"],
                                               "differs by %.1e m" % c["difference"]
                                               if c["difference"] is not None else c["status"])
                            for c in ref["checks"])
            details.append("Reference tip: %s = (%.12f, %.12f, %.12f) m; checks: %s; the "
                           "reference's stated accuracy: %s m." % (
                               ref["how"], *ref["tip"], chk, fmt(ref.get("bound"), "%.1e")))
        details.append("")
        head = "| solver | setting | error | solver s | process s | process CPU s | steps |"
        sep = "| --- | --- | ---: | ---: | ---: | ---: | ---: |"
        if fb:
            head += " branch | err 0.5 s |"
            sep += " --- | ---: |"
        head += " status |"
        sep += " --- |"
        details += [head, sep]
        for r in rows:
            line = "| %s | %s | %s | %s | %s | %s | %s |" % (
                r["solver"], setting_name(r), fmt(r.get("error"), "%.2e"),
                fmt(r.get("solver_time")), fmt(r.get("process_wall")),
                fmt(r.get("process_cpu")), fmt(r.get("steps"), "%d"))
            if fb:
                line += " %s | %s |" % (r.get("branch", "-"), fmt(r.get("error_0_5"), "%.1e"))
            msg = " ".join(r.get("message", "").split())  # one line for the table
            status = r["status"] + (" (%s)" % msg[:160].replace("|", "/") if msg else "")
            details.append(line + " %s |" % status)
        details.append("")
    fb_rows = [r for r in allrows if r["scene"] == "fourbar"]
    kept = [r for r in fb_rows if r["solver"] == "simbody" and r.get("branch") == "parallelogram"
            and r.get("status") == "done"]
    if fb_rows:
        summary += ["", "Four-bar, against every Simbody run that kept the parallelogram branch "
                    "(any error): mbdae's fastest run on the branch with no larger error "
                    "(solver time).", ""]
        if not kept:
            summary.append("No Simbody run kept the branch.")
        for s in kept:
            m = best(fb_rows, "mbdae", "solver_time", s["error"], True)
            summary.append("- Simbody %s: %.3g s, error %.1e; mbdae %s" % (
                setting_name(s), s["solver_time"], s["error"],
                "%s: %.3g s, error %.1e, ratio %.2f" % (
                    setting_name(m), m["solver_time"], m["error"],
                    m["solver_time"] / s["solver_time"]) if m else "none"))
    md += summary + [""] + details
    sf = step_flops_section(results)
    md += sf
    with open(os.path.join(results, "results.md"), "w") as f:
        f.write("\n".join(md) + "\n")
    with open(os.path.join(results, "work_precision.csv"), "w") as f:
        cols = ["scene", "solver", "integrator", "value", "error", "solver_time",
                "process_wall", "process_cpu", "steps", "runs", "done", "status", "branch",
                "error_0_5"]
        f.write(",".join(cols) + "\n")
        for r in allrows:
            f.write(",".join("" if r.get(c) is None else str(r.get(c)) for c in cols) + "\n")
    plot(scenes, allrows, results)


def fmt_load(la):
    return "-" if not la else ", ".join("%.1f" % x for x in la)


def plot(scenes, rows, results):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    names = [d["scene"] for d in scenes]
    if not names:
        return
    fig, axes = plt.subplots(1, len(names), figsize=(4.2 * len(names), 4.2), squeeze=False)
    marks = {"rkmerson": "o", "rkfehlberg": "s", "rk3": "^", "cpodes": "D", "verlet": "v",
             "euler": "x", "ida": "o", "hht": "s", "hht_adaptive": "^", "erk": "*", "erk_tip": "P"}
    for ax, name in zip(axes[0], names):
        for solver, color in (("simbody", "tab:blue"), ("mbdae", "tab:red")):
            for integ in sorted({r["integrator"] for r in rows if r["solver"] == solver}):
                pts = sorted((r["error"], r["solver_time"], r.get("branch")) for r in rows
                             if r["scene"] == name and r["solver"] == solver
                             and r["integrator"] == integ and r.get("error") is not None)
                if not pts:
                    continue
                e = [max(p[0], 1e-16) for p in pts]
                t = [p[1] for p in pts]
                ax.plot(e, t, marker=marks.get(integ, "o"), color=color, lw=1,
                        mfc="none" if solver == "simbody" else color,
                        label="%s %s" % (solver, integ))
                off = [(ee, tt) for ee, tt, p in zip(e, t, pts) if p[2] == "left"]
                if off:
                    ax.plot([o[0] for o in off], [o[1] for o in off], "k+", ms=10, lw=0)
        ax.axvline(TOL_EQUAL, color="gray", ls=":", lw=1)
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel("error (%s)" % ("crank angle at 10 s, rad; +: left the branch"
                                      if name == "fourbar" else "tip at 1 s, m"))
        ax.set_ylabel("solver CPU time, s (median)")
        ax.set_title(name)
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=6)
    fig.tight_layout()
    fig.savefig(os.path.join(results, "work_precision.png"), dpi=110)


def step_flops_section(results):
    p = os.path.join(results, "step_flops.json")
    if not os.path.exists(p):
        return []
    with open(p) as f:
        d = json.load(f)
    # The medians (a file without repetitions: its single runs); the smallest CPU time
    # over the repetitions where the file keeps them (since 2026-11-25 16:23 UTC).
    med, single, least = {}, {}, {}
    for b in d["benchmarks"]:
        name = b["run_name"] if "run_name" in b else b["name"]
        if b.get("run_type") == "aggregate":
            if b.get("aggregate_name") == "median":
                med[name] = b
        else:
            single[name] = b
            least[name] = min(least.get(name, float("inf")), b["cpu_time"])
    for name, b in single.items():
        med.setdefault(name, b)
    if not any(b.get("run_type") == "aggregate" for b in d["benchmarks"]):
        least = {}  # one run each: no minimum over repetitions
    ctx = d["context"]
    out = ["## Goal 3: one HHT step against one bare KLU refactorisation + solve", "",
           "Program `bench/peers/bench_step_flops.cc` (Google Benchmark), run by the same "
           "command; %s, %d CPUs at %s MHz, load average before %s; CPU times, median of %s "
           "repetitions in random interleaving. HHT: fixed step 1e-3 s, the project's default "
           "HhtOptions (alpha = -0.1, equilibrium form, modified); the step is timed over the "
           "same 200 steps from t = 0.005 s in every repetition. KLU: klu_refactor + "
           "klu_solve of that Newton matrix (dae::HhtNewtonMatrix) at t = 0.005 s, with "
           "klu_defaults (AMD, BTF, scaling). Flops: klu_flops for the refactorisation, "
           "2 (nnz L + nnz U + nnz off-diagonal blocks) - 3 n for the solve." % (
               ctx.get("date", ""), ctx.get("num_cpus", 0), ctx.get("mhz_per_cpu", "?"),
               fmt_load(d.get("load_before")), d["benchmarks"][0].get("repetitions", "?")), "",
           "| N | nnz | nnz L + U | HHT step [us] | Newton it. / step | factorisations / step | "
           "bare refactor + solve [us] | ratio step / (refactor + solve) | "
           "KluSolver Factor + Solve [us] | refactor [us] | solve [us] | refactor flops | "
           "refactor GFLOP/s | refactor + solve GFLOP/s |",
           "| ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |"]

    def get(name, n):
        # run_name "BM_X/N" or "BM_X/N/iterations:K" (fixed iteration counts)
        for key, b in med.items():
            if key == "%s/%d" % (name, n) or key.startswith("%s/%d/" % (name, n)):
                return b
        return None

    def step(n, k, solver=0):
        # "BM_HhtStep/N/k/s/iterations:K": Newton threshold 10^-k, linear solver s (0 KLU,
        # 1 the block tree); older files have no s (KLU) or no k (the default, k = 12).
        for key, b in med.items():
            parts = key.split("/")
            if parts[0] != "BM_HhtStep" or parts[1] != str(n):
                continue
            kk = int(parts[2]) if len(parts) > 2 and parts[2].isdigit() else 12
            ss = int(parts[3]) if len(parts) > 3 and parts[3].isdigit() else 0
            if kk == k and ss == solver:
                return b
        return None

    def tree(n, what):
        return med.get("BM_TreeLu/%d/%d" % (n, what))
    for n in (100, 1000):
        st, rs = step(n, 12), get("BM_KluRefactorSolve", n)
        rf, ks = get("BM_KluRefactor", n), get("BM_KluSolverFactorSolve", n)
        so = get("BM_KluSolve", n)
        if not (st and rs and rf and ks and so):
            continue
        out.append("| %d | %d | %d | %.0f | %.2f | %.3f | %.0f | %.2f | %.0f | %.0f | %.0f | %.3g | %.2f | %.2f |"
                   % (n, rs["nnz"], rs["lnz"] + rs["unz"], st["cpu_time"], st["newton_per_step"],
                      st["factor_per_step"], rs["cpu_time"], st["cpu_time"] / rs["cpu_time"],
                      ks["cpu_time"], rf["cpu_time"], so["cpu_time"], rf["factor_flops"],
                      rf["GFLOPs"], rs["GFLOPs"]))
    loose = []
    for n in (100, 1000):
        rs = get("BM_KluRefactorSolve", n)
        for k in (12, 10, 8, 6):
            st = step(n, k)
            if st and rs and any(step(n, x) for x in (10, 8, 6)):
                loose.append("| %d | 1e-%d | %.0f | %.2f | %.3f | %.2f |" % (
                    n, k, st["cpu_time"], st["newton_per_step"], st["factor_per_step"],
                    st["cpu_time"] / rs["cpu_time"]))
    if loose:
        out += ["", "The same step with looser Newton thresholds (`HhtOptions::newton_tolerance`, "
                "`hht: {newton_tolerance}`; what they cost in accuracy: "
                "`bench/results/newton_tolerance.md`):", "",
                "| N | threshold | HHT step [us] | Newton it. / step | factorisations / step | "
                "ratio step / (refactor + solve) |", "| ---: | ---: | ---: | ---: | ---: | ---: |"] + loose
    rows = []
    for n in (100, 1000):
        rs = get("BM_KluRefactorSolve", n)
        t1, t2, t3 = tree(n, 1), tree(n, 2), tree(n, 3)
        if not (rs and t1 and t2 and t3):
            continue
        for k in (12, 10, 8, 6):
            sk, st = step(n, k, 0), step(n, k, 1)
            if not (sk and st):
                continue
            rows.append("| %d | 1e-%d | %.0f | %.0f | %.2f | %.2f | %.3f | %.0f | %.0f | %.0f | %.2f | %.2f | %.2f | %.2f | %.1e |" % (
                n, k, sk["cpu_time"], st["cpu_time"], st["cpu_time"] / sk["cpu_time"],
                st["newton_per_step"], st["factor_per_step"],
                t1["cpu_time"], t2["cpu_time"], t3["cpu_time"], rs["cpu_time"] / t1["cpu_time"],
                t2["GFLOPs"], st["cpu_time"] / t1["cpu_time"], st["cpu_time"] / rs["cpu_time"],
                t1["diff_vs_klu"]))
    if rows:
        out += ["", "The block tree elimination (`hht: {linear_solver: tree}`, "
                "`dae/block_tree_lu.h`) of the same Newton matrix, and the HHT step with it "
                "(with the tree's defaults: the refresh of the Newton matrix by cost, "
                "`hht: {jacobian_cost: auto}` = 3 iterations, `docs/hht.md` \"Newton matrix\", "
                "and the linear predictor, `hht: {predictor: auto}`, \"Newton iteration\": "
                "its own iterations and factorisations per step, given here; with "
                "`jacobian_cost: 0` and `predictor: constant` they are KLU's and the states "
                "equal to round-off). Its "
                "flops are counted from the blocks "
                "(`BlockTreeLu::factor_flops`: per node of m unknowns and an interface of k "
                "to its parent, the LU of the m x m block, 2 m^2 k for W and 2 m k^2 for the "
                "parent's update):", "",
                "| N | threshold | step, KLU [us] | step, tree [us] | tree / KLU | tree: Newton it. / "
                "step | tree: factorisations / step | tree refactor + "
                "solve [us] | tree refactor [us] | tree solve [us] | KLU (refactor + solve) / "
                "tree's | tree refactor GFLOP/s | step, tree / tree refactor + solve | "
                "step, tree / KLU refactor + solve | solution vs KLU (rel.) |",
                "| ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |"] + rows
    # Goal 3 by the minima: on a machine shared with other jobs, interference only adds
    # time, so the smallest of the interleaved repetitions is the steadier estimate.
    mins = []
    for n in (100, 1000):
        rs, rf, so = (get(x, n) for x in ("BM_KluRefactorSolve", "BM_KluRefactor", "BM_KluSolve"))
        if not (rs and rf and so):
            continue
        lrs, lrf, lso = (least.get(b["run_name"]) for b in (rs, rf, so))
        for k in (12, 10):
            st = step(n, k, 1)
            lst = least.get(st["run_name"]) if st else None
            if not (lst and lrs and lrf and lso):
                continue
            mins.append("| %d | 1e-%d | %.0f | %.0f | %.2f | %.0f + %.0f | %.2f |" % (
                n, k, lst, lrs, lst / lrs, lrf, lso, lst / (lrf + lso)))
    if mins:
        out += ["", "Goal 3 by the smallest of the %s repetitions of each benchmark (interference "
                "from other jobs only adds time; the medians above move with it): the tree's step "
                "against the bare KLU refactorisation + solve, and against the sum of the "
                "refactorisation and the solve timed apart:" % d["benchmarks"][0].get("repetitions", "?"), "",
                "| N | threshold | step, tree [us] | KLU refactor + solve [us] | ratio | KLU refactor "
                "+ solve apart [us] | ratio |", "| ---: | ---: | ---: | ---: | ---: | ---: | ---: |"] + mins
    fits = []
    for n in (100, 1000):
        r1, r2 = get("BM_HhtRefresh/%d" % n, 1), get("BM_HhtRefresh/%d" % n, 2)
        if not (r1 and r2):
            continue
        # t = it * c_it + f * c_f for the two refresh intervals.
        a, b, e = r1["newton_per_step"], r1["factor_per_step"], r1["cpu_time"]
        c, d, f = r2["newton_per_step"], r2["factor_per_step"], r2["cpu_time"]
        det = a * d - b * c
        if det == 0:
            continue
        c_it, c_f = (e * d - b * f) / det, (a * f - e * c) / det
        fits.append("| %d | %.2f + %.3f: %.0f | %.2f + %.3f: %.0f | %.1f | %.0f | %.2f |" % (
            n, a, b, e, c, d, f, c_it, c_f, c_f / c_it))
    if fits:
        out += ["", "The cost of a refresh of the Newton matrix with the tree (`BM_HhtRefresh`: the "
                "tree's step at 1e-12 with the matrix refreshed every step and every second step, "
                "the rate rule and the refresh by cost off), fitted from the two as t = iterations x "
                "c_it + refreshes x c_f per step; `HhtOptions::kTreeJacobianCost` = 3 rests on it "
                "(`docs/hht.md`, \"Newton matrix\"):", "",
                "| N | every step: it. + refr. per step: us | every second step | c_it [us] | "
                "c_f [us] | c_f / c_it |", "| ---: | ---: | ---: | ---: | ---: | ---: |"] + fits
    g = get("BM_DenseGemm", 256)
    if g:
        rate = g["GFLOPs"]
        out += ["", "Dense reference on the same core: C = A B, 256 x 256 (Eigen as this "
                "build compiles it, %.0f us): %.2f GFLOP/s. The core's peak, estimated from "
                "`lscpu` (AMD EPYC, CPU family 26 = Zen 5, 2.1 GHz nominal, AVX-512 and FMA) "
                "and that core's four floating-point pipes (two multiply/FMA, two add): "
                "2.1e9 x 2 FMA x 8 doubles x 2 = 67 GFLOP/s with AVX-512 FMA; 2.1e9 x "
                "(2 multiplies + 2 adds) x 2 doubles = 16.8 GFLOP/s for SSE2 code without "
                "FMA, which is what Debian's KLU and this build (-march=x86-64) are "
                "compiled for (the dense product reaches %.0f %% of that; above 100 %% "
                "the core runs faster than its nominal clock, so these peaks are estimates "
                "at 2.1 GHz, not limits)."
                % (g["cpu_time"], rate, 100 * rate / 16.8)]
    return out + [""]


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--build", default=os.path.join(ROOT, "build"), help="build directory")
    ap.add_argument("--quick", action="store_true", help="chains N = 10, 100 and the four-bar")
    ap.add_argument("--repeats", type=int, default=3, help="runs of every setting (median)")
    ap.add_argument("--scenes", nargs="+", help="chain10 chain100 chain1000 fourbar")
    ap.add_argument("--no-step-flops", action="store_true", help="skip goal 3's benchmark")
    ap.add_argument("--step-flops-only", action="store_true")
    ap.add_argument("--report-only", action="store_true", help="only rebuild the report")
    ap.add_argument("--new-reference", action="store_true",
                    help="recompute the chains' references (else reference_*.json is reused)")
    ap.add_argument("--results", default=os.path.join(ROOT, "bench", "results", "peers"))
    ap.add_argument("--seed", type=int, default=12)
    ap.add_argument("--timeout", type=float, default=TIMEOUT,
                    help="wall seconds after which a run is stopped and counted as failed")
    a = ap.parse_args()
    globals()["TIMEOUT"] = a.timeout
    os.makedirs(a.results, exist_ok=True)
    if not a.report_only:
        tools = {"mbdae": os.path.join(a.build, "mbdae"),
                 "simbody": os.path.join(a.build, "bench", "peers", "simbody_peers"),
                 "step_flops": os.path.join(a.build, "bench", "peers", "bench_step_flops")}
        scenes = a.scenes or (["chain10", "chain100", "fourbar"] if a.quick
                              else ["chain10", "chain100", "chain1000", "fourbar"])
        if a.step_flops_only:
            scenes = []
        if scenes and not os.path.exists(tools["simbody"]):
            sys.exit("bench/peers: %s is missing: Simbody was not found when %s was "
                     "configured (apt-get install -y libsimbody-dev, then configure again)"
                     % (tools["simbody"], a.build))
        tmp = tempfile.mkdtemp(prefix="mbdae_peers_")
        try:
            tools["models"] = {s: write_chain_model(int(s[5:]), tmp)
                               for s in scenes if s.startswith("chain")}
            tools["models"]["fourbar"] = FOURBAR
            for s in scenes:
                run_scene(s, tools, tmp, a.results, a.repeats, a.seed, a.new_reference)
            if not a.no_step_flops and not a.quick:
                run_step_flops(tools, tmp, a.results, a.repeats)
        finally:
            shutil.rmtree(tmp, ignore_errors=True)
    write_report(a.results)
    print("wrote %s/results.md, work_precision.csv, work_precision.png" %
          os.path.relpath(a.results, ROOT))


if __name__ == "__main__":
    main()
