#!/usr/bin/env python3
"""The parallelogram four-bar through its singular positions (issue 11, part 1): IDA and
adaptive HHT over their tolerances against the closed-form-equation reference of
reference.py, with the crank-angle error at 10 s, the cost, the branch kept and the
passages counted; and the IDA rows of the A02 study (verification/nfourbar) after the
change.

--quick (CTest): the reference's self-check, IDA at rtol = atol = 1e-8 and adaptive HHT at
tol = 1e-6, each through all 10 passages, on the parallelogram branch, with the error at
10 s below the bound of the full study.
"""
import argparse
import csv
import math
import os
import sys

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
OUT = os.environ.get("MBDAE_VERIFICATION_OUT") or HERE
os.makedirs(OUT, exist_ok=True)
sys.path.insert(0, HERE)
sys.path.insert(0, os.path.dirname(HERE))
import mbdae_run as mr  # noqa: E402
import reference as ref  # noqa: E402

MODEL = os.path.join(HERE, "fourbar.yaml")
T_END = ref.T_END
CSV = "work_precision.csv"
IDA_TOLS = [1e-4, 1e-5, 1e-6, 1e-7, 1e-8, 1e-9, 1e-10]
HHT_TOLS = [1e-4, 1e-5, 1e-6, 1e-7, 1e-8, 1e-9]
# Adaptive HHT with rows every 0.1 s: with rows every 0.01 s the output step caps HHT's
# step at tolerances 1e-4 and 1e-5 (README, "Adaptive HHT and the output step").
HHT_COARSE_TOLS = [1e-4, 1e-5, 1e-6, 1e-7, 1e-8, 1e-9]
COARSE_OUTPUT_STEP = 0.1
# Adaptive HHT with dense output (rows every 0.01 s interpolated; the steps do not land on
# them): README, "Dense output".
HHT_DENSE_TOLS = [1e-4, 1e-5, 1e-6, 1e-7, 1e-8, 1e-9]
# IDA with dense output likewise (rows interpolated by IDAGetDky; the steps land only on
# t_end).
IDA_DENSE_TOLS = IDA_TOLS
HHT_STEPS = [1e-3, 1e-4]
# The error at 10 s each setting must stay below (rad): a bound of the measured error
# with a margin for the chaotic dependence of a run's steps on rounding (README).
ERROR_BOUND = {("ida", 1e-8): 1e-3, ("ida", 1e-10): 1e-5, ("hht-adaptive", 1e-6): 5e-2,
               ("hht-adaptive", 1e-9): 1e-3, ("hht-adaptive-dense", 1e-6): 5e-2,
               ("hht-adaptive-dense", 1e-9): 1e-3, ("ida-dense", 1e-8): 1e-3, ("ida-dense", 1e-10): 1e-5}
# Branch kept: coupler rotation and crank-angle difference at most max(1e-6, tolerance)
# rad (the antiparallelogram branch turns the coupler by order 1 rad).
BRANCH_FLOOR = 1e-6


def angle_of(quat):
    """Rotation angle about world z of Euler parameters (rows of [e0, e1, e2, e3])."""
    return 2.0 * np.arctan2(quat[:, 3], quat[:, 0])


def wrap(a):
    return (a + np.pi) % (2.0 * np.pi) - np.pi


def args_for(integ, val):
    if integ == "ida":
        return ["--integrator", "ida", "--rtol", repr(val), "--atol", repr(val)]
    if integ == "hht-adaptive":
        return ["--integrator", "hht", "--adaptive", "--alpha", "-0.1", "--step", "1e-3",
                "--tolerance", repr(val)]
    if integ == "hht-adaptive-rows-0.1":
        return args_for("hht-adaptive", val) + ["--output-step", repr(COARSE_OUTPUT_STEP)]
    if integ == "hht-adaptive-dense":
        return args_for("hht-adaptive", val) + ["--dense-output"]
    if integ == "ida-dense":
        return args_for("ida", val) + ["--dense-output"]
    return ["--integrator", "hht", "--fixed-step", "--alpha", "-0.1", "--step", repr(val)]


def fmt_setting(integ, val):
    return {"ida": "rtol = atol = %g", "hht-adaptive": "tol = %g", "hht-fixed": "h = %g",
            "hht-adaptive-rows-0.1": "tol = %g, rows every 0.1 s",
            "hht-adaptive-dense": "tol = %g, dense output",
            "ida-dense": "rtol = atol = %g, dense output"}[integ] % val


def run_case(runner, integ, val):
    path, proc = runner.simulate(MODEL, args_for(integ, val), integ, check=False)
    if proc.returncode not in (0, 3):
        raise mr.RunError("mbdae exited with %d: %s" % (proc.returncode, proc.stderr.strip()))
    r = mr.Results(path)
    t = r.time
    phi = 0.5 * math.pi - np.unwrap(r["/measures/phi0"])
    phi_ref = ref.phi(t)
    c = {"integrator": integ, "value": val, "setting": fmt_setting(integ, val),
         "status": r.attrs["status"], "t_reached": float(r.attrs["t_reached"]),
         "cpu": r.cpu_time(), "steps": int(r.attrs["steps_accepted"]),
         "rejected": int(r.attrs["steps_rejected"]),
         "reason": str(r.attrs.get("failure_reason", ""))}
    c["error_max"] = float(np.max(np.abs(phi - phi_ref)))
    c["error"] = float(abs(phi[-1] - phi_ref[-1])) if c["status"] == "done" else float("nan")
    # passages: crossings of phi = pi/2 + j pi by the run's own crank angle
    j = np.floor((phi - 0.5 * math.pi) / math.pi)
    c["passages"] = int(j[-1] - j[0])
    c["coupler_rotation"] = float(np.max(np.abs(wrap(angle_of(r["/bodies/coupler0/orientation"])))))
    c["crank_spread"] = float(np.max(np.abs(wrap(angle_of(r["/bodies/crank1/orientation"])
                                                 - angle_of(r["/bodies/crank0/orientation"])))))
    return c


def a02_rows():
    """The IDA and adaptive-HHT rows of verification/nfourbar's last full run."""
    path = os.path.join(os.path.dirname(HERE), "nfourbar", CSV)
    if not os.path.isfile(path):
        return []
    with open(path) as f:
        return [r for r in csv.DictReader(f) if r["integrator"] in ("ida", "hht-adaptive")]


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    mr.add_mbdae_argument(ap)
    ap.add_argument("--quick", action="store_true", help="the CTest subset (a few seconds)")
    args = ap.parse_args()
    runner = mr.Runner(mr.find_mbdae(args.mbdae), args.keep)
    checks = []
    md = ["# Parallelogram four-bar through its singular positions: results\n",
          "Produced by `verification/singular/run.py%s`; model `fourbar.yaml` (10 s, output "
          "every 0.01 s); reference: `reference.py`. Error: the crank angle phi at 10 s "
          "against the reference (rad); also the largest error over the output rows.\n"
          % (" --quick" if args.quick else "")]

    d, e = ref.self_check()
    checks.append(("reference: DOP853 vs Radau (rtol 1e-13) max abs(dphi) = %.1e rad <= 1e-9" % d, d <= 1e-9))
    ts = ref.singular_times()
    md.append("Reference: phi'' = k sin phi, k = %.4f 1/s^2, phi(0) = 0, phi'(0) = 1 rad/s; "
              "DOP853 vs Radau (rtol 1e-13) max |dphi| = %.1e rad, energy-integral residual "
              "%.1e. phi(10) = %.12f rad. Singular passages (all links horizontal) at t = %s s "
              "(%d in 10 s).\n" % (ref.k_constant(), d, e, ref.phi(np.array([T_END]))[0],
                                  ", ".join("%.4f" % x for x in ts), len(ts)))
    n_pass = len(ts)

    if args.quick:
        cases = [("ida", 1e-8), ("hht-adaptive", 1e-6), ("hht-adaptive-dense", 1e-6), ("ida-dense", 1e-8)]
    else:
        cases = ([("ida", v) for v in IDA_TOLS] + [("hht-adaptive", v) for v in HHT_TOLS]
                 + [("hht-fixed", v) for v in HHT_STEPS]
                 + [("hht-adaptive-rows-0.1", v) for v in HHT_COARSE_TOLS]
                 + [("hht-adaptive-dense", v) for v in HHT_DENSE_TOLS]
                 + [("ida-dense", v) for v in IDA_DENSE_TOLS])
    runs = []
    for integ, val in cases:
        c = run_case(runner, integ, val)
        runs.append(c)
        print("%-13s %-18s %-6s error %.2e  max %.2e  %d steps  %.2f s" % (
            integ, c["setting"], c["status"], c["error"], c["error_max"], c["steps"], c["cpu"]))

    rows = []
    for c in runs:
        rows.append([c["integrator"], c["setting"], c["status"] if c["status"] == "done" else
                     "failed at t = %.6g: %s" % (c["t_reached"], c["reason"][:160]),
                     "%.2e" % c["error"] if c["status"] == "done" else "-", "%.2e" % c["error_max"],
                     "%d (%d)" % (c["steps"], c["rejected"]), "%.3f" % c["cpu"], c["passages"],
                     "%.1e / %.1e" % (c["coupler_rotation"], c["crank_spread"])])
    md.append("## Work-precision sweep\n")
    md.append("Cost: the results file's `solver_cpu_time`. Branch: the largest coupler rotation "
              "and difference of the two crank angles over the rows (rad; 0 on the "
              "parallelogram branch).\n")
    md.append(mr.markdown_table(["integrator", "setting", "status", "error at 10 s [rad]",
                                 "max error [rad]", "steps (rejected)", "CPU [s]", "passages",
                                 "branch"], rows))

    for c in runs:
        tag = "%s %s" % (c["integrator"], c["setting"])
        checks.append(("%s: runs to 10 s (%s)" % (tag, c["status"] if c["status"] == "done" else
                                                   "failed at t = %.6g" % c["t_reached"]),
                       c["status"] == "done"))
        checks.append(("%s: passes all %d singular positions (the run's own phi crosses %d)"
                       % (tag, n_pass, c["passages"]), c["passages"] == n_pass))
        branch = max(BRANCH_FLOOR, c["value"] if c["integrator"] != "hht-fixed" else 0.0)
        checks.append(("%s: parallelogram branch kept (coupler rotation %.1e, crank spread %.1e "
                       "<= %g rad)" % (tag, c["coupler_rotation"], c["crank_spread"], branch),
                       c["coupler_rotation"] <= branch and c["crank_spread"] <= branch))
        bound = ERROR_BOUND.get((c["integrator"], c["value"]))
        if bound is not None:
            checks.append(("%s: crank-angle error at 10 s %.2e <= %g rad" % (tag, c["error"], bound),
                           c["error"] <= bound))
    if not args.quick:
        # The error falls with the tolerance: over every two decades the largest error over
        # the rows is smaller (the error at 10 s alone can be small by a phase crossing).
        for integ, tols in (("ida", IDA_TOLS), ("hht-adaptive", HHT_TOLS)):
            err = {c["value"]: c["error_max"] for c in runs if c["integrator"] == integ}
            for a, b in zip(tols, tols[2:]):
                checks.append(("%s: largest error at tolerance %g (%.2e) below that at %g (%.2e)" % (
                    integ, b, err[b], a, err[a]), err[b] < err[a]))
        # Adaptive HHT whose step the output step does not cap: the error falls at every
        # decade of the tolerance.
        err = {c["value"]: c["error_max"] for c in runs if c["integrator"] == "hht-adaptive-rows-0.1"}
        for a, b in zip(HHT_COARSE_TOLS, HHT_COARSE_TOLS[1:]):
            checks.append(("hht-adaptive, rows every 0.1 s: largest error at tolerance %g (%.2e) "
                           "below that at %g (%.2e)" % (b, err[b], a, err[a]), err[b] < err[a]))
        # Dense output: the steps do not depend on the rows (every 0.01 s); the error falls
        # at every decade of the tolerance.
        for integ, tols in (("hht-adaptive-dense", HHT_DENSE_TOLS), ("ida-dense", IDA_DENSE_TOLS)):
            err = {c["value"]: c["error_max"] for c in runs if c["integrator"] == integ}
            for a, b in zip(tols, tols[1:]):
                checks.append(("%s: largest error at tolerance %g (%.2e) below that at %g (%.2e)"
                               % (integ, b, err[b], a, err[a]), err[b] < err[a]))
        # With rows every 0.01 s, tolerance 1e-4 takes one step per output interval: the
        # step is the output step, and the run is the fixed-step run h = 0.01 (README).
        pinned = [c for c in runs if c["integrator"] == "hht-adaptive" and c["value"] == 1e-4]
        if pinned:
            c = pinned[0]
            md.append("Adaptive HHT at tol = 1e-4 with rows every 0.01 s: %d steps (%d rejected) "
                      "for %d output intervals: the output step caps the step everywhere (README, "
                      "\"Adaptive HHT and the output step\"); with rows every 0.1 s it takes %s.\n" % (
                          c["steps"], c["rejected"], round(T_END / 0.01),
                          ", ".join("%d steps at tol %g" % (d["steps"], d["value"]) for d in runs
                                    if d["integrator"] == "hht-adaptive-rows-0.1" and d["value"] in (1e-4, 1e-5))))
        with open(os.path.join(OUT, CSV), "w", newline="") as f:
            w = csv.writer(f)
            w.writerow(["problem", "integrator", "setting", "cpu_time", "error", "error_10s", "steps",
                        "rejected", "status"])
            for c in runs:
                done = c["status"] == "done"
                w.writerow(["parallelogram four-bar", c["integrator"], c["setting"], "%.6g" % c["cpu"],
                            "%.6g" % c["error_max"] if done else "", "%.6g" % c["error"] if done else "",
                            c["steps"], c["rejected"], c["status"]])
        plot(runs)
        a02 = a02_rows()
        if a02:
            md.append("## A02 (N = 40, 20 s, 20 passages): IDA and adaptive HHT\n")
            md.append("From the last full run of `verification/nfourbar/run.py` "
                      "(`verification/nfourbar/work_precision.csv`; error e of that study, "
                      "relative to the ranges of x and v of B0).\n")
            md.append(mr.markdown_table(["integrator", "setting", "status", "e", "CPU [s]", "steps"],
                                        [[r["integrator"], r["setting"], r["status"], r["error"] or "-",
                                          r["cpu_time"], r["steps"]] for r in a02]))

    ida = [c for c in runs if c["integrator"] == "ida"]
    done = sum(1 for c in ida if c["status"] == "done")
    headline = ("10 singular passages in 10 s: IDA completes %d of %d tolerances (error at 10 s "
                "%s), adaptive HHT %d of %d" % (
                    done, len(ida), ", ".join("%.0e" % c["error"] for c in ida if c["status"] == "done"),
                    sum(1 for c in runs if c["integrator"] == "hht-adaptive" and c["status"] == "done"),
                    sum(1 for c in runs if c["integrator"] == "hht-adaptive")))
    summary = {"title": "Parallelogram four-bar through its singular positions", "headline": headline}
    if not args.quick:
        summary.update({"figures": ["work_precision.png"], "csv": [CSV], "work_precision": CSV})
    return mr.finish_checks(runner, checks, md, OUT, summary)


def plot(runs):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(figsize=(6.4, 4.6))
    styles = {"ida": ("^-", "IDA, rtol = atol = 1e-4 ... 1e-10"),
              "hht-adaptive": ("s-", "HHT adaptive, tol = 1e-4 ... 1e-9"),
              "hht-fixed": ("o-", "HHT fixed step, h = 1e-3, 1e-4"),
              "hht-adaptive-rows-0.1": ("s--", "HHT adaptive, tol = 1e-4 ... 1e-9, rows every 0.1 s"),
              "hht-adaptive-dense": ("d-", "HHT adaptive, tol = 1e-4 ... 1e-9, dense output"),
              "ida-dense": ("v-", "IDA, rtol = atol = 1e-4 ... 1e-10, dense output")}
    for integ, (mark, label) in styles.items():
        pts = [(c["cpu"], c["error_max"]) for c in runs if c["integrator"] == integ and c["status"] == "done"]
        if pts:
            x, y = zip(*pts)
            ax.loglog(x, y, mark, label=label)
    ax.set_xlabel("solver CPU time [s]")
    ax.set_ylabel("largest crank-angle error over 0..10 s [rad]")
    ax.set_title("Parallelogram four-bar, 10 singular passages")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend()
    fig.tight_layout()
    fig.savefig(os.path.join(OUT, "work_precision.png"), dpi=110)
    plt.close(fig)


if __name__ == "__main__":
    sys.exit(main())
