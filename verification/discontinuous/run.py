#!/usr/bin/env python3
"""Discontinuous forcing of a mass on a spring (m x'' = -k x + f(t)), closed-form
reference, three forces:
  kink.yaml       f = linear spline 0 -> F0 over [0, tk], F0 after (slope jumps at tk)
  step.yaml       f = step(t, ts, 0, ts, F0): the hard switch (0 at t = ts, F0 after)
  step_sign.yaml  f = F0 (1 + sign(t - ts))/2: the same step, F0/2 at t = ts
x is continuous in every case; x''' jumps at a kink, x'' at a step.

A. Fixed-step HHT (alpha = -0.1), h = 2^-5 ... 2^-11 (quick: 2^-6 ... 2^-10), with the
   jump on the step grid (0.5) and off it (1/3): error = max over the output rows
   (every 1/32 s, 0 to 2 s) of |x - exact|; observed order per halving.
B. The program's fixed-step HHT against an independent scalar recursion of the same HHT
   formulas (docs/hht.md) at h = 2^-8: the orders of A are the method's.
C. Adaptive HHT and IDA over their tolerances with the jump at 1/3 (not a grid point nor
   an output time), against the same model without the force (F0 = 0): the jump must not
   cost more than a factor 5 in error at the same tolerance; no failure, no NaN.
D. (full run) the accepted-step count N(t) around the jump (runs ending at t), the work-
   precision table work_precision.csv and figure.png.
Writes results.md and summary.json (here or in $MBDAE_VERIFICATION_OUT).
"""
import argparse
import csv
import json
import math
import os
import subprocess
import sys

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
OUT = os.environ.get("MBDAE_VERIFICATION_OUT") or HERE
os.makedirs(OUT, exist_ok=True)
sys.path.insert(0, os.path.dirname(HERE))
import mbdae_run as mr  # noqa: E402

ON_GRID, OFF_GRID = 0.5, 1.0 / 3.0
ALPHA = -0.1
MODELS = {"kink": "kink.yaml", "step": "step.yaml", "step_sign": "step_sign.yaml"}
JUMP = {"kink": "tk", "step": "ts", "step_sign": "ts"}
# expected order of fixed-step HHT (measured; see README): (on grid, off grid)
EXPECTED_ORDER = {"kink": (2, 2), "step": (1, 1), "step_sign": (2, 1)}
ORDER_TOL = 0.2
TOL_CROSS = 1e-10        # program vs scalar HHT recursion, m
FACTOR = 5.0             # adaptive/IDA: error with the jump <= FACTOR x error without it
TOL_IDA_TIGHT = 1e-7     # IDA rtol = atol = 1e-10: max |x - exact| (m), |x| up to 0.5 m
TOL_HHT_TIGHT = 1e-3     # adaptive HHT tolerance 1e-8 (global error ~ sum of local tolerances)


class Problem:
    def __init__(self, par):
        self.m, self.k, self.F0 = par["m"], par["k"], par["F0"]
        self.x0, self.v0 = par["x0"], par["v0"]
        self.w = math.sqrt(self.k / self.m)

    def homogeneous(self, t):
        return self.x0 * np.cos(self.w * t) + self.v0 / self.w * np.sin(self.w * t)

    def exact(self, case, t, tj, F0=None):
        F0 = self.F0 if F0 is None else F0
        t = np.asarray(t, float)
        if case == "kink":
            c = F0 / tj

            def ramp(s):     # response to f = c s for s > 0 from rest
                return np.where(s > 0, c / self.k * (s - np.sin(self.w * s) / self.w), 0.0)
            return self.homogeneous(t) + ramp(t) - ramp(t - tj)
        return self.homogeneous(t) + np.where(t > tj, F0 / self.k * (1 - np.cos(self.w * (t - tj))), 0.0)

    def force(self, case, t, tj):
        """f(t) with the program's conventions at the jump."""
        if case == "kink":
            return self.F0 * min(t / tj, 1.0)
        if case == "step":
            return 0.0 if t <= tj else self.F0
        return self.F0 * (1 + np.sign(t - tj)) / 2

    def hht_recursion(self, case, tj, h, t_end):
        """HHT of docs/hht.md on the scalar equation (M constant): x at t = n h."""
        a_, b_, g_ = ALPHA, (1 - ALPHA) ** 2 / 4, 0.5 - ALPHA
        n = int(round(t_end / h))
        x, v = self.x0, self.v0
        f = self.force(case, 0.0, tj)
        a = (f - self.k * x) / self.m
        xs = [x]
        for i in range(n):
            t1 = (i + 1) * h
            f1 = self.force(case, t1, tj)
            xp = x + h * v + h * h / 2 * (1 - 2 * b_) * a
            Fn = self.k * x - f
            a1 = (f1 - self.k * xp + a_ / (1 + a_) * Fn) / (self.m / (1 + a_) + self.k * b_ * h * h)
            x = xp + b_ * h * h * a1
            v = v + h * ((1 - g_) * a + g_ * a1)
            a, f = a1, f1
            xs.append(x)
        return np.arange(n + 1) * h, np.array(xs)


def info(mbdae, model):
    p = subprocess.run([mbdae, "info", model, "--json"], stdout=subprocess.PIPE,
                       stderr=subprocess.PIPE, text=True, check=True)
    return json.loads(p.stdout)


def simulate(runner, case, tj, args, F0=None, name="run"):
    sets = ["--set", "%s=%r" % (JUMP[case], tj)]
    if F0 is not None:
        sets += ["F0=%r" % F0]
    path, proc = runner.simulate(os.path.join(HERE, MODELS[case]), list(args) + sets, name, check=False)
    if proc.returncode != 0:
        return None, (proc.stderr.strip().splitlines() or ["exit %d" % proc.returncode])[-1]
    r = mr.Results(path)
    return r, None


def finite(r):
    return all(np.all(np.isfinite(v)) for v in r.data.values() if v.dtype.kind == "f")


def fixed_args(h):
    return ["--integrator", "hht", "--step", repr(h), "--alpha", repr(ALPHA)]


def adaptive_args(tol):
    return ["--integrator", "hht", "--adaptive", "--step", "1e-4", "--tolerance", repr(tol)]


def ida_args(tol):
    return ["--integrator", "ida", "--rtol", repr(tol), "--atol", repr(tol)]


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    mr.add_mbdae_argument(ap)
    ap.add_argument("--quick", action="store_true", help="the checks only, a smaller sweep, no figure")
    args = ap.parse_args()
    mbdae = mr.find_mbdae(args.mbdae)
    runner = mr.Runner(mbdae, args.keep)
    pb = Problem(info(mbdae, os.path.join(HERE, "step.yaml"))["parameters"])
    pk = Problem(info(mbdae, os.path.join(HERE, "kink.yaml"))["parameters"])
    probs = {"kink": pk, "step": pb, "step_sign": pb}
    checks, wp_rows = [], []
    md = ["# Discontinuous forcing: results\n",
          "Produced by `verification/discontinuous/run.py%s`. Mass on a spring, m = %g kg, k = %.6g N/m "
          "(period 1 s), F0 = %g N, x(0) = %g, x'(0) = %g m/s; 0 to 2 s, output every 1/32 s. "
          "Error = max over the output rows of |x - exact| (m), the closed form.\n"
          % (" --quick" if args.quick else "", pb.m, pb.k, pb.F0, pb.x0, pb.v0)]

    # ---------------------------------------------------------------- A: fixed-step HHT
    ks = range(6, 11) if args.quick else range(5, 12)
    hs = [2.0 ** -k for k in ks]
    md.append("## A. Fixed-step HHT (alpha = -0.1): error against h\n")
    md.append("Jump on the grid: t = 0.5 (a multiple of every h); off the grid: t = 1/3.\n")
    header = ["force", "jump at"] + ["h = 2^-%d" % k for k in ks] + ["orders per halving", "expected"]
    rows, curves = [], {}
    for case in MODELS:
        for where, tj, exp in (("grid", ON_GRID, EXPECTED_ORDER[case][0]), ("off grid", OFF_GRID, EXPECTED_ORDER[case][1])):
            errs = []
            for h in hs:
                r, err = simulate(runner, case, tj, fixed_args(h), name=case)
                if r is None or not finite(r):
                    errs.append(float("nan"))
                    checks.append(("%s, jump %s, h = %g: run failed or NaN: %s" % (case, where, h, err), False))
                    continue
                errs.append(float(np.max(np.abs(r["/measures/x"] - probs[case].exact(case, r.time, tj)))))
                if tj == OFF_GRID and case != "step_sign":
                    wp_rows.append(["%s-force" % case, "hht-fixed", "h = 2^-%d" % int(round(-math.log2(h))),
                                    "%.6g" % r.cpu_time(), "%.6e" % errs[-1], int(r.attrs["steps_accepted"]), "done"])
            orders = [math.log2(errs[i] / errs[i + 1]) for i in range(len(errs) - 1)]
            curves[(case, where)] = errs
            rows.append([case, "%s (%.4g)" % (where, tj)] + ["%.2e" % e for e in errs]
                        + [" ".join("%.2f" % o for o in orders), str(exp)])
            last = orders[-3:]
            checks.append(("fixed-step HHT, %s, jump %s: orders over the last three halvings %s within %d +- %.1f"
                           % (case, where, ", ".join("%.2f" % o for o in last), exp, ORDER_TOL),
                           len(last) == 3 and all(abs(o - exp) <= ORDER_TOL for o in last)))
    md.append(mr.markdown_table(header, rows))

    # ---------------------------------------------------------------- B: scalar recursion
    md.append("## B. The program's fixed-step HHT against a scalar HHT recursion (h = 2^-8)\n")
    rows = []
    h = 2.0 ** -8
    for case in MODELS:
        for where, tj in (("grid", ON_GRID), ("off grid", OFF_GRID)):
            r, err = simulate(runner, case, tj, fixed_args(h), name="rec")
            if r is None:
                checks.append(("recursion cross-check %s %s: run failed: %s" % (case, where, err), False))
                continue
            tr, xr = probs[case].hht_recursion(case, tj, h, r.time[-1])
            idx = np.rint(r.time / h).astype(int)
            d = float(np.max(np.abs(r["/measures/x"] - xr[idx])))
            rows.append([case, where, "%.1e" % d])
            checks.append(("fixed-step HHT = scalar HHT recursion, %s, jump %s: max abs difference %.1e <= %.0e m"
                           % (case, where, d, TOL_CROSS), d <= TOL_CROSS))
    md.append(mr.markdown_table(["force", "jump", "max abs(x_program - x_recursion) (m)"], rows))

    # ---------------------------------------------------------------- C: adaptive HHT, IDA
    md.append("## C. Adaptive HHT and IDA, jump at t = 1/3, against the same model without the force\n")
    md.append("`none` = F0 = 0 (no jump; a smooth free oscillation of the same model). Check: error with "
              "the jump <= %g x error without it at the same setting.\n" % FACTOR)
    tols_hht = [1e-6, 1e-8] if args.quick else [1e-4, 1e-5, 1e-6, 1e-7, 1e-8]
    tols_ida = [1e-6, 1e-8, 1e-10] if args.quick else [1e-4, 1e-5, 1e-6, 1e-7, 1e-8, 1e-9, 1e-10]
    rows = []
    adapt = {}
    for integ, tols, mk in (("hht-adaptive", tols_hht, adaptive_args), ("ida", tols_ida, ida_args)):
        for tol in tols:
            base, err0 = simulate(runner, "step", OFF_GRID, mk(tol), F0=0.0, name="base")
            e0 = float(np.max(np.abs(base["/measures/x"] - pb.homogeneous(base.time)))) if base else float("nan")
            for case in ("kink", "step"):
                r, err = simulate(runner, case, OFF_GRID, mk(tol), name=case)
                if r is None or not finite(r):
                    checks.append(("%s tol %g, %s: the run failed or wrote NaN: %s" % (integ, tol, case, err), False))
                    wp_rows.append(["%s-force" % case, integ, "tol = %g" % tol, "", "", "", "failed"])
                    continue
                e = float(np.max(np.abs(r["/measures/x"] - probs[case].exact(case, r.time, OFF_GRID))))
                adapt[(integ, tol, case)] = (r, e)
                wp_rows.append(["%s-force" % case, integ, ("tol = %g" if integ == "hht-adaptive" else "rtol = atol = %g")
                                % tol, "%.6g" % r.cpu_time(), "%.6e" % e, int(r.attrs["steps_accepted"]), "done"])
                rows.append([integ, "%g" % tol, case, "%.2e" % e, "%.2e" % e0, "%.2f" % (e / e0),
                             "%d / %d" % (r.attrs["steps_accepted"], r.attrs["steps_rejected"]),
                             "%d / %d" % (base.attrs["steps_accepted"], base.attrs["steps_rejected"]) if base else "-"])
                checks.append(("%s tol %g, %s at 1/3: error %.2e <= %g x error without the jump %.2e; no NaN"
                               % (integ, tol, case, e, FACTOR, e0), e <= FACTOR * e0))
    md.append(mr.markdown_table(["integrator", "tolerance", "force", "error", "error without jump", "ratio",
                                 "steps accepted / rejected", "without jump"], rows))
    for integ, tol, lim in (("ida", 1e-10, TOL_IDA_TIGHT), ("hht-adaptive", 1e-8, TOL_HHT_TIGHT)):
        for case in ("kink", "step"):
            if (integ, tol, case) in adapt:
                e = adapt[(integ, tol, case)][1]
                checks.append(("%s tol %g, %s at 1/3: error %.2e <= %.0e m" % (integ, tol, case, e, lim), e <= lim))

    figures, csvs = [], []
    summary_runs = []
    for (integ, tol, case), (r, e) in sorted(adapt.items()):
        lim = {("ida", 1e-10): TOL_IDA_TIGHT, ("hht-adaptive", 1e-8): TOL_HHT_TIGHT}.get((integ, tol))
        if lim:
            summary_runs.append({"problem": "%s-force" % case, "integrator": integ, "setting": "tol = %g" % tol,
                                 "quantity": "max abs x error (m)", "error": e, "tolerance": lim,
                                 "cpu_time": r.cpu_time(), "passed": bool(e <= lim)})
    if not args.quick:
        # ------------------------------------------------------------ D: steps around the jump
        md.append("## D. Accepted steps around the jump (tolerance 1e-6)\n")
        md.append("N(t) = accepted steps of a run that ends at t (output only at t): its slope is 1/h. "
                  "Steps taken within 0.01 s after the jump at 1/3 (from N(1/3 - 0.001) to N(1/3 + 0.01)), "
                  "with the step force and without it (F0 = 0):\n")
        T = np.concatenate([np.linspace(0.25, 0.32, 8), np.linspace(0.325, 0.36, 36), np.linspace(0.37, 0.45, 5)])
        profiles, rows = {}, []
        for integ, mk in (("hht-adaptive", adaptive_args), ("ida", ida_args)):
            for label, F0 in (("step", None), ("none", 0.0)):
                N = []
                for te in T:
                    r, err = simulate(runner, "step", OFF_GRID, mk(1e-6) + ["--t-end", repr(te), "--output-step",
                                                                                  repr(te)], F0=F0, name="prof")
                    N.append(int(r.attrs["steps_accepted"]) if r else -1)
                profiles[(integ, label)] = np.array(N)
            win = []
            for label in ("step", "none"):
                n_lo = _count_at(runner, integ, mk, OFF_GRID - 0.001, None if label == "step" else 0.0)
                n_hi = _count_at(runner, integ, mk, OFF_GRID + 0.01, None if label == "step" else 0.0)
                win.append(n_hi - n_lo)
            rows.append([integ, str(win[0]), str(win[1])])
            checks.append(("%s tol 1e-6: more steps within 0.01 s after the jump (%d) than without it (%d)"
                           % (integ, win[0], win[1]), win[0] > win[1]))
        md.append(mr.markdown_table(["integrator", "steps, step force", "steps, no force"], rows))
        with open(os.path.join(OUT, "work_precision.csv"), "w", newline="") as f:
            w = csv.writer(f)
            w.writerow(["problem", "integrator", "setting", "cpu_time", "error", "steps", "status"])
            w.writerows(wp_rows)
        csvs.append("work_precision.csv")
        md.append("## Work-precision (work_precision.csv; jump at t = 1/3)\n")
        md.append(mr.markdown_table(["problem", "integrator", "setting", "CPU s", "error (m)", "steps", "status"],
                                    wp_rows))
        figures.append(make_figure(runner, probs, hs, ks, curves, T, profiles))

    summary = {"title": "Discontinuous forcing: kink (linear spline) and step in a force on a spring-mass",
               "headline": "fixed-step HHT: order 2 with a kink (on or off the grid), order 1 with a hard step "
                           "(on the grid too), order 2 with a sign() step on the grid; adaptive HHT and IDA "
                           "keep the error within %g x the smooth case; no failure, no NaN" % FACTOR,
               "figures": figures, "csv": csvs, "runs": summary_runs}
    if csvs:
        summary["work_precision"] = "work_precision.csv"
    return mr.finish_checks(runner, checks, md, OUT, summary)


def _count_at(runner, integ, mk, te, F0):
    r, _ = simulate(runner, "step", OFF_GRID, mk(1e-6) + ["--t-end", repr(te), "--output-step", repr(te)],
                    F0=F0, name="win")
    return int(r.attrs["steps_accepted"]) if r else -1


def make_figure(runner, probs, hs, ks, curves, T, profiles):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(2, 2, figsize=(11, 8))
    a = ax[0, 0]
    styles = {"kink": "o", "step": "s", "step_sign": "^"}
    for (case, where), errs in curves.items():
        a.loglog(hs, errs, styles[case], ls="-" if where == "grid" else "--", label="%s, %s" % (case, where), ms=4)
    a.loglog(hs, [0.5 * h for h in hs], "k:", lw=1, label="slope 1")
    a.loglog(hs, [2 * h * h for h in hs], "k-.", lw=1, label="slope 2")
    a.set_xlabel("h (s)")
    a.set_ylabel("max |x - exact| (m)")
    a.set_title("A. fixed-step HHT", fontsize="medium")
    a.legend(fontsize="x-small", ncol=2)
    # solution and error of the step force
    a = ax[0, 1]
    h = 2.0 ** -7
    for where, tj in (("grid", ON_GRID), ("off grid", OFF_GRID)):
        r, _ = simulate(runner, "step", tj, fixed_args(h) + ["--output-step", repr(h)], name="fig")
        a.plot(r.time, r["/measures/x"] - probs["step"].exact("step", r.time, tj),
               label="HHT h = 2^-7, step at %s (%.3g)" % (where, tj))
    r, _ = simulate(runner, "step", OFF_GRID, ida_args(1e-8) + ["--output-step", repr(h)], name="fig")
    a.plot(r.time, r["/measures/x"] - probs["step"].exact("step", r.time, OFF_GRID), label="IDA 1e-8, step at 1/3")
    a.set_xlabel("t (s)")
    a.set_ylabel("x - exact (m)")
    a.set_title("step force: error along the run", fontsize="medium")
    a.legend(fontsize="x-small")
    a = ax[1, 0]
    t = np.linspace(0, 2, 801)
    for case, tj in (("kink", OFF_GRID), ("step", OFF_GRID)):
        a.plot(t, probs[case].exact(case, t, tj), label="exact x, %s at 1/3" % case)
        a.plot(t, [probs[case].force(case, s, tj) / probs[case].k for s in t], ":", label="f(t)/k, %s" % case)
    a.set_xlabel("t (s)")
    a.set_ylabel("m")
    a.set_title("the closed-form solutions", fontsize="medium")
    a.legend(fontsize="x-small")
    a = ax[1, 1]
    for (integ, label), N in profiles.items():
        a.plot(T, N, ".-" if label == "step" else ":", label="%s, %s" % (integ, "step force" if label == "step" else "no force"))
    a.axvline(OFF_GRID, color="gray", lw=0.8)
    a.set_xlabel("t_end (s)")
    a.set_ylabel("accepted steps N(t)")
    a.set_title("D. steps around the jump (tol 1e-6)", fontsize="medium")
    a.legend(fontsize="x-small")
    fig.tight_layout()
    fig.savefig(os.path.join(OUT, "figure.png"), dpi=100)
    plt.close(fig)
    return "figure.png"


if __name__ == "__main__":
    sys.exit(main())
