#!/usr/bin/env python3
"""Test Set for IVP Solvers (Mazzia, Magherini, Univ. Bari), problem andrews: the
reference at t = 0.03 and the accuracy scd over a tolerance sweep.

Model: verification/andrews/andrews.yaml (7 bodies, 10 revolute joints, spring, torque;
the 7 rotational measures are the test set's angles). Reference: the test set's values
at t = 0.03 (PSIDE, rtol = atol = 1e-14; verification/andrews/andrews_data.py).
scd = -log10(max over the 7 angles of |angle - ref| / |ref|) at t = 0.03, the test set's
"significant correct digits" of the position variables.

1. Reference: IDA at rtol = atol = 1e-12 against the test set's values (table of the
   7 angles); requirement scd >= 9.
2. IDA sweep rtol = atol = 1e-2 ... 1e-10 in half decades (17 runs), HHT (alpha = -0.1)
   with fixed steps 4e-5 ... 6.25e-7 (7 runs): scd, CPU seconds in the integrator
   (solver_cpu_time), steps. Requirements: every run ends (status done); IDA at 1e-10:
   scd >= 7; IDA scd rises with the tolerance, scd(1e-10) - scd(1e-4) >= 4; HHT scd
   rises at every halving of h.
Output rows every 1e-3 s: the measures are unwrapped between rows, and beta turns by
up to ~1.1 rad per 1e-3 s (a coarser output step would leave beta off by 2 pi k).
--quick: the reference, IDA at 1e-4, 1e-7, 1e-10 and HHT at 1e-5, 5e-6.
Writes results.md, summary.json, work_precision.csv, scd_cpu.png, scd_tolerance.png.
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
VERIF = os.path.join(os.path.dirname(os.path.dirname(HERE)), "verification")
sys.path.insert(0, VERIF)
sys.path.insert(0, os.path.join(VERIF, "andrews"))
import andrews_data as ad  # noqa: E402
import mbdae_run as mr  # noqa: E402

MODEL = os.path.join(VERIF, "andrews", "andrews.yaml")
COMMON = ["--t-end", "0.03", "--output-step", "1e-3"]
ALPHA = -0.1


def run_case(runner, integrator, setting, args):
    path, proc = runner.simulate(MODEL, COMMON + ["--integrator", integrator] + args, integrator, check=False)
    c = {"integrator": integrator, "setting": setting}
    if proc.returncode != 0:
        msg = (proc.stderr.strip().splitlines() or ["exit %d" % proc.returncode])[-1]
        c["status"] = "failed"
        c["message"] = msg.split("; the results up to there")[0].replace(runner.dir, "<tmp>")
        try:
            r = mr.Results(path)
            c["cpu"] = r.cpu_time()
            c["steps"] = int(r.attrs.get("steps_accepted", 0))
        except Exception:
            pass
        return c
    r = mr.Results(path)
    q = np.array([r.at("/measures/" + n, ad.T_REF) for n in ad.NAMES])
    rel = np.abs(q - ad.Q_REF) / np.abs(ad.Q_REF)
    c.update(status="done", q=q, rel=rel, err=float(np.max(rel)), scd=-math.log10(max(float(np.max(rel)), 1e-300)),
             cpu=r.cpu_time(), steps=int(r.attrs["steps_accepted"]))
    return c


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    mr.add_mbdae_argument(ap)
    ap.add_argument("--quick", action="store_true", help="a few tolerances and steps only")
    args = ap.parse_args()
    runner = mr.Runner(mr.find_mbdae(args.mbdae), args.keep)
    if args.quick:
        tols = [1e-4, 1e-7, 1e-10]
        steps = [1e-5, 5e-6]
    else:
        tols = [10.0 ** (-2 - 0.5 * k) for k in range(17)]
        steps = [4e-5 / 2**i for i in range(7)]
    checks, md = [], ["# Andrews' squeezer: Test Set for IVP Solvers reference and scd sweep\n",
                      "Produced by `papers/andrews-testset/run.py%s`; model `verification/andrews/andrews.yaml`; "
                      "reference: Test Set for IVP Solvers, andrews, PSIDE at rtol = atol = 1e-14, t = 0.03. "
                      "scd = -log10(max relative error of the 7 angles at t = 0.03).\n"
                      % (" --quick" if args.quick else "")]

    ref = run_case(runner, "ida", "rtol = atol = 1e-12", ["--rtol", "1e-12", "--atol", "1e-12"])
    if ref["status"] != "done":
        checks.append(("reference run IDA 1e-12 ends: %s" % ref.get("message", ""), False))
    else:
        print("reference IDA 1e-12: scd %.2f, CPU %.3f s" % (ref["scd"], ref["cpu"]))
        md.append("## 1. The reference at t = 0.03: IDA, rtol = atol = 1e-12\n")
        md.append(mr.markdown_table(["angle", "mbdae (IDA 1e-12)", "test set (PSIDE 1e-14)", "relative difference"],
                                    [[n, "%.15e" % ref["q"][k], "%.15e" % ad.Q_REF[k], "%.2e" % ref["rel"][k]]
                                     for k, n in enumerate(ad.NAMES)]))
        md.append("\nscd = %.2f (CPU %.3f s, %d steps).\n" % (ref["scd"], ref["cpu"], ref["steps"]))
        checks.append(("IDA at rtol = atol = 1e-12 reproduces the test set's reference at t = 0.03: "
                        "scd = %.2f >= 9" % ref["scd"], ref["scd"] >= 9.0))

    cases = []
    for tol in tols:
        cases.append(run_case(runner, "ida", "rtol = atol = %.3g" % tol, ["--rtol", "%.3g" % tol, "--atol", "%.3g" % tol]))
        cases[-1]["tol"] = tol
    for h in steps:
        cases.append(run_case(runner, "hht", "h = %.4g, alpha = %g" % (h, ALPHA),
                              ["--alpha", repr(ALPHA), "--fixed-step", "--step", repr(h)]))
        cases[-1]["h"] = h
    for c in cases:
        print("%-4s %-26s %s" % (c["integrator"], c["setting"],
                                 "scd %6.2f  CPU %.4f s  steps %d" % (c["scd"], c["cpu"], c["steps"])
                                 if c["status"] == "done" else "FAILED: " + c["message"]))
    failed = [c for c in cases if c["status"] != "done"]
    checks.append(("every run of the sweep ends (%d of %d done%s)" % (
        len(cases) - len(failed), len(cases),
        "; failed: " + "; ".join("%s %s: %s" % (c["integrator"], c["setting"], c["message"]) for c in failed)
        if failed else ""), not failed))
    ida = {c["tol"]: c for c in cases if c["integrator"] == "ida" and c["status"] == "done"}
    hht = [c for c in cases if c["integrator"] == "hht" and c["status"] == "done"]
    t10, t4 = min(tols), 1e-4
    if t10 in ida:
        checks.append(("IDA at rtol = atol = 1e-10: scd = %.2f >= 7" % ida[t10]["scd"], ida[t10]["scd"] >= 7.0))
    if t10 in ida and t4 in ida:
        gain = ida[t10]["scd"] - ida[t4]["scd"]
        checks.append(("IDA: scd(1e-10) - scd(1e-4) = %.2f >= 4 (accuracy follows the tolerance)" % gain, gain >= 4.0))
    hs = sorted(hht, key=lambda c: -c["h"])
    mono = all(hs[i + 1]["scd"] > hs[i]["scd"] for i in range(len(hs) - 1))
    checks.append(("HHT: scd rises at every halving of the step (%s)" % ", ".join("%.2f" % c["scd"] for c in hs),
                   mono and len(hs) == len(steps)))

    wp = "work_precision.csv"
    with open(os.path.join(OUT, wp), "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["problem", "integrator", "setting", "cpu_time", "error", "steps", "status"])
        for c in cases:
            integ = "ida" if c["integrator"] == "ida" else "hht-fixed"
            w.writerow(["andrews", integ, c["setting"], "%.6g" % c["cpu"] if "cpu" in c else "",
                        "%.6e" % c["err"] if "err" in c else "", c.get("steps", ""), c["status"]])
    md.append("\n## 2. scd against tolerance and CPU time\n")
    md.append("CPU time: `solver_cpu_time` (process CPU seconds in the integrator, without output). "
              "Data: `work_precision.csv` (error = max relative angle error = 10^-scd).\n")
    md.append(mr.markdown_table(["integrator", "setting", "scd", "max relative error", "CPU [s]", "steps"],
                                [[c["integrator"], c["setting"], "%.2f" % c["scd"] if "scd" in c else "failed",
                                  "%.3e" % c["err"] if "err" in c else c.get("message", ""),
                                  "%.4f" % c["cpu"] if "cpu" in c else "-", c.get("steps", "-")] for c in cases]))
    md.append("")

    figures = []
    if not args.quick:
        try:
            import matplotlib
            matplotlib.use("Agg")
            import matplotlib.pyplot as plt
            fig, ax = plt.subplots(figsize=(6.4, 4.6))
            it = sorted(ida.values(), key=lambda c: c["cpu"])
            ax.semilogx([c["cpu"] for c in it], [c["scd"] for c in it], "s-", label="IDA, rtol = atol = 1e-2 ... 1e-10")
            ax.semilogx([c["cpu"] for c in hs], [c["scd"] for c in hs], "o-",
                        label="HHT, alpha = %g, h = 4e-5 ... 6.25e-7" % ALPHA)
            ax.set_xlabel("CPU time in the integrator [s]")
            ax.set_ylabel("scd (significant correct digits, t = 0.03)")
            ax.set_title("Andrews' squeezer: accuracy against cost")
            ax.grid(True, which="both", alpha=0.3)
            ax.legend(fontsize=8)
            fig.tight_layout()
            fig.savefig(os.path.join(OUT, "scd_cpu.png"), dpi=100)
            figures.append("scd_cpu.png")
            fig, ax = plt.subplots(figsize=(6.4, 4.6))
            it = sorted(ida.values(), key=lambda c: -c["tol"])
            ax.semilogx([c["tol"] for c in it], [c["scd"] for c in it], "s-", label="IDA")
            xs = np.array([1e-2, 1e-10])
            ax.semilogx(xs, -np.log10(xs), "k:", label="scd = -log10(tol)")
            ax.invert_xaxis()
            ax.set_xlabel("rtol = atol")
            ax.set_ylabel("scd (t = 0.03)")
            ax.set_title("Andrews' squeezer: scd against the tolerance")
            ax.grid(True, which="both", alpha=0.3)
            ax.legend(fontsize=8)
            fig.tight_layout()
            fig.savefig(os.path.join(OUT, "scd_tolerance.png"), dpi=100)
            figures.append("scd_tolerance.png")
        except Exception as exc:
            print("figures not written:", exc)

    head = "reference IDA 1e-12 scd %.2f" % ref["scd"] if ref["status"] == "done" else "reference run failed"
    if t10 in ida and t4 in ida:
        head += "; IDA scd %.2f at 1e-4, %.2f at 1e-10 (CPU %.3f s)" % (ida[t4]["scd"], ida[t10]["scd"], ida[t10]["cpu"])
    if hs:
        head += "; HHT scd %.2f at h = %.3g (CPU %.3f s)" % (hs[-1]["scd"], hs[-1]["h"], hs[-1]["cpu"])
    summary = {"title": "Andrews' squeezer, Test Set for IVP Solvers: reference and scd sweep",
               "headline": head, "figures": figures, "csv": [wp], "work_precision": wp}
    return mr.finish_checks(runner, checks, md, OUT, summary)


if __name__ == "__main__":
    sys.exit(main())
