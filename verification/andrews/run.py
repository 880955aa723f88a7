#!/usr/bin/env python3
"""Andrews' squeezer (andrews.yaml) against the Test Set for IVP Solvers reference.

(a) IDA at rtol = atol = 1e-10: the 7 angles (rotational measures) at t = 0 must equal
    the consistent initial angles to 1e-12, and at t = 0.03 the accuracy
    scd = -log10(max relative error over the 7 angles) against the PSIDE reference must
    be >= 7.
(b) HHT, alpha = -0.1, fixed steps 1e-5, 5e-6, 2.5e-6, 1.25e-6, 6.25e-7: observed order
    log2(err(h) / err(h/2)) of the max relative angle error at t = 0.03; requirement:
    every observed order within 2 +- 0.3.
(c) Work-precision: HHT (fixed steps 4e-5 ... 6.25e-7) and IDA (rtol = atol = 1e-3 ...
    1e-10 in half decades): max relative angle error at t = 0.03 against the CPU time in
    the integrator (the results file's solver_cpu_time). Writes work_precision.csv
    (columns problem,integrator,setting,cpu_time,error,steps,status), work_precision.png
    and the tables in results.md.
(d) IFToMM A03 (Gonzalez et al. 2006): beta over 0.03 s (output every 1e-4 s) against
    IDA at rtol = atol = 1e-12, which is checked against the test set's value at 0.03
    (scd >= 9). Error: max_t |beta - beta_ref| / max(max_t |beta_ref|, 1e-3). HHT
    (alpha = -0.1, h = 1e-5) and IDA (rtol = atol = 1e-5): error <= 1e-3. Rows in
    summary.json ("iftomm").

Tables and figures go to this folder or $MBDAE_VERIFICATION_OUT (results.md,
summary.json). Exits 1 if a requirement fails. --quick skips (c).
"""
import argparse
import csv
import math
import os
import sys
import time

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
# Where the tables and figures go: this folder, or $MBDAE_VERIFICATION_OUT (the tests).
OUT = os.environ.get("MBDAE_VERIFICATION_OUT") or HERE
os.makedirs(OUT, exist_ok=True)
sys.path.insert(0, HERE)
sys.path.insert(0, os.path.dirname(HERE))
import andrews_data as ad  # noqa: E402
import mbdae_run as mr  # noqa: E402

MODEL = os.path.join(HERE, "andrews.yaml")
COMMON = ["--t-end", "0.03", "--output-step", "1e-3"]


def run_case(runner, args, name):
    """Returns dict with angles at 0.03, errors, wall time, stats; or a failure note."""
    t0 = time.perf_counter()
    path, proc = runner.simulate(MODEL, COMMON + args, name, check=False)
    elapsed = time.perf_counter() - t0
    out = {"args": " ".join(args), "exit": proc.returncode, "elapsed": elapsed}
    if proc.returncode != 0:
        msg = (proc.stderr.strip().splitlines() or ["exit %d" % proc.returncode])[-1]
        out["error"] = msg.split("; the results up to there")[0].replace(runner.dir, "<tmp>")
        try:  # the rows before the failure are kept in the file
            r = mr.Results(path)
            out["q_start"] = np.array([r["/measures/" + n][0] for n in ad.NAMES])
        except Exception:
            pass
        return out
    r = mr.Results(path)
    q_end = np.array([r.at("/measures/" + n, ad.T_REF) for n in ad.NAMES])
    q_start = np.array([r["/measures/" + n][0] for n in ad.NAMES])
    rel = np.abs(q_end - ad.Q_REF) / np.abs(ad.Q_REF)
    out.update(q_end=q_end, q_start=q_start, rel=rel, err=float(np.max(rel)),
               scd=-math.log10(max(float(np.max(rel)), 1e-300)))
    out["cpu"] = r.cpu_time()
    out["steps"] = int(r.attrs["steps_accepted"])
    out["attrs"] = r.attrs
    return out


IFTOMM_TOL, IFTOMM_THRESHOLD = 1e-3, 1e-3
IFTOMM_COMMON = ["--t-end", "0.03", "--output-step", "1e-4"]
IFTOMM_SETTINGS = [("hht-fixed", "alpha = -0.1, h = 1e-5", ["--integrator", "hht", "--alpha", "-0.1", "--fixed-step",
                                                            "--step", "1e-5"]),
                   ("ida", "rtol = atol = 1e-5", ["--integrator", "ida", "--rtol", "1e-5", "--atol", "1e-5"])]


def part_d(runner, md, checks):
    """IFToMM A03: beta over 0.03 s against IDA 1e-12 (checked by the test set's value)."""
    path, _ = runner.simulate(MODEL, ["--integrator", "ida", "--rtol", "1e-12", "--atol", "1e-12"] + IFTOMM_COMMON,
                              "a03ref")
    ref = mr.Results(path)
    q_end = np.array([ref.at("/measures/" + n, ad.T_REF) for n in ad.NAMES])
    scd_ref = -math.log10(float(np.max(np.abs(q_end - ad.Q_REF) / np.abs(ad.Q_REF))))
    checks.append(("A03 reference: IDA at rtol = atol = 1e-12 against the test set's angles at t = 0.03, "
                   "scd = %.2f >= 9" % scd_ref, scd_ref >= 9.0))
    beta_ref = ref["/measures/beta"]
    rows = []
    for integ, setting, args in IFTOMM_SETTINGS:
        path, _ = runner.simulate(MODEL, args + IFTOMM_COMMON, "a03")
        r = mr.Results(path)
        if len(r.time) != len(ref.time) or np.max(np.abs(r.time - ref.time)) > 1e-12:
            raise mr.RunError("A03: output times differ from the reference's")
        err = float(np.max(np.abs(r["/measures/beta"] - beta_ref))) / max(float(np.max(np.abs(beta_ref))),
                                                                         IFTOMM_THRESHOLD)
        passed = err <= IFTOMM_TOL
        rows.append({"problem": "A03", "integrator": integ, "setting": setting, "quantity": "beta",
                     "error": err, "tolerance": IFTOMM_TOL, "cpu_time": r.cpu_time(), "passed": bool(passed)})
        print("(d) A03 %-9s %-22s error %.3e (tolerance 1e-3) CPU %.3f s" % (integ, setting, err, r.cpu_time()))
        checks.append(("IFToMM A03, %s (%s): error of beta over 0.03 s = %.2e <= 1e-3" % (integ, setting, err),
                       passed))
    md.append("\n## (d) IFToMM A03: beta over 0.03 s\n")
    md.append("Reference: IDA at rtol = atol = 1e-12, output every 1e-4 s; at t = 0.03 it agrees with the test set's "
              "PSIDE values to scd = %.2f. Error: max_t |beta - beta_ref| / max(max_t |beta_ref|, 1e-3) "
              "(max |beta_ref| = %.4f rad). CPU: solver_cpu_time.\n" % (scd_ref, float(np.max(np.abs(beta_ref)))))
    md.append(mr.markdown_table(["integrator", "setting", "error", "tolerance", "CPU [s]", "passed"],
                                [[r["integrator"], r["setting"], "%.3e" % r["error"], "1e-3", "%.4f" % r["cpu_time"],
                                  "yes" if r["passed"] else "NO"] for r in rows]))
    return rows


def part_a(a, md):
    start_err = float(np.max(np.abs(a["q_start"] - ad.Q0)))
    pass_start = start_err <= 1e-12
    pass_a = a["scd"] >= 7.0
    redundant = {k: v for k, v in a["attrs"].items() if "redundan" in k}
    print("(a) measures at t = 0: max |measure - initial angle| = %.2e rad (%s)" % (
        start_err, "ok" if pass_start else "FAIL"))
    print("(a) IDA 1e-10: scd = %.2f (%s); redundant constraints: %s" % (
        a["scd"], "ok" if pass_a else "FAIL", redundant or "not reported"))
    md.append("## (a) IDA, rtol = atol = 1e-10\n")
    md.append("Measures at t = 0 against the consistent initial angles: max difference %.2e rad "
              "(requirement <= 1e-12: **%s**).\n" % (start_err, "PASS" if pass_start else "FAIL"))
    md.append("Redundant constraints reported by the program: %s.\n" % (
        ", ".join("%s = %s" % kv for kv in redundant.items()) or "not reported"))
    md.append(mr.markdown_table(
        ["angle", "mbdae, t = 0.03", "reference", "relative error"],
        [[n, "%.15e" % a["q_end"][k], "%.15e" % ad.Q_REF[k], "%.2e" % a["rel"][k]]
         for k, n in enumerate(ad.NAMES)]))
    md.append("\nscd = -log10(max relative error) = %.2f; requirement >= 7: **%s**\n" % (
        a["scd"], "PASS" if pass_a else "FAIL"))

    return pass_start, pass_a


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    mr.add_mbdae_argument(ap)
    ap.add_argument("--quick", action="store_true", help="skip the work-precision sweep (c)")
    args = ap.parse_args()
    runner = mr.Runner(mr.find_mbdae(args.mbdae), args.keep)
    checks = []
    md = ["# Andrews' squeezer: verification results\n",
          "Produced by `verification/andrews/run.py`; model `verification/andrews/andrews.yaml`; "
          "reference: Test Set for IVP Solvers (andrews.f), PSIDE at rtol = atol = 1e-14, t = 0.03.\n"]

    # (a)
    a = run_case(runner, ["--integrator", "ida", "--rtol", "1e-10", "--atol", "1e-10"], "ida")
    if "error" in a:
        checks.append(("(a) IDA run at rtol = atol = 1e-10 ends: %s" % a["error"], False))
        print("FAIL (a): IDA run failed:", a["error"])
        md.append("## (a) IDA, rtol = atol = 1e-10\n")
        md.append("The run failed: `%s`. **FAIL**\n" % a["error"])
        if "q_start" in a:
            start_err = float(np.max(np.abs(a["q_start"] - ad.Q0)))
            print("(a) measures at t = 0: max |measure - initial angle| = %.2e rad" % start_err)
            md.append("Measures at t = 0 (first row of the failed run) against the consistent initial "
                      "angles: max difference %.2e rad (requirement <= 1e-12: **%s**).\n" % (
                          start_err, "PASS" if start_err <= 1e-12 else "FAIL"))
    else:
        start_ok, scd_ok = part_a(a, md)
        checks.append(("(a) measures at t = 0 equal the consistent initial angles to 1e-12", start_ok))
        checks.append(("(a) IDA 1e-10: scd = %.2f >= 7" % a["scd"], scd_ok))

    # (b)
    steps_b = [1e-5 / 2**i for i in range(5)]
    hht = {}
    for h in steps_b:
        hht[h] = run_case(runner, ["--integrator", "hht", "--alpha", "-0.1", "--step", repr(h)], "hht")
    rows, orders = [], []
    for i, h in enumerate(steps_b):
        c = hht[h]
        if "error" in c:
            rows.append(["%.4g" % h, "failed: " + c["error"], ""])
            orders.append(float("nan"))
            print("(b) HHT h = %-9.4g FAILED: %s" % (h, c["error"]))
            continue
        order = ""
        if i > 0 and "err" in hht[steps_b[i - 1]]:
            p = math.log2(hht[steps_b[i - 1]]["err"] / c["err"])
            orders.append(p)
            order = "%.3f" % p
        rows.append(["%.4g" % h, "%.3e" % c["err"], order])
        print("(b) HHT h = %-9.4g max rel err %s  order %s" % (h, rows[-1][1], order))
    pass_b = len(orders) == len(steps_b) - 1 and all(abs(p - 2.0) <= 0.3 for p in orders)
    checks.append(("(b) HHT alpha = -0.1: every observed order within 2 +- 0.3 (%s)" % ", ".join(
        "%.3f" % p for p in orders), pass_b))
    md.append("\n## (b) HHT order, alpha = -0.1, fixed steps\n")
    md.append(mr.markdown_table(["h [s]", "max relative angle error, t = 0.03", "observed order"], rows))
    md.append("\nRequirement: every observed order within 2 +- 0.3: **%s**\n" % ("PASS" if pass_b else "FAIL"))

    # (c)
    figures = []
    if not args.quick:
        for h in [4e-5, 2e-5]:
            hht[h] = run_case(runner, ["--integrator", "hht", "--alpha", "-0.1", "--step", repr(h)], "hht")
        ida = {}
        for k in range(15):
            tol = 10.0 ** (-3 - 0.5 * k)
            if k == 14:
                ida[tol] = a
            else:
                ida[tol] = run_case(runner, ["--integrator", "ida", "--rtol", "%.3g" % tol,
                                             "--atol", "%.3g" % tol], "ida")
        # Adaptive HHT (alpha = -0.1, first step 1e-5) over the local error tolerance.
        adaptive = {}
        for k in range(11):
            tol = 10.0 ** (-3 - 0.5 * k)
            adaptive[tol] = run_case(runner, ["--integrator", "hht", "--alpha", "-0.1", "--adaptive",
                                              "--tolerance", "%.3g" % tol, "--step", "1e-5"], "hht-adaptive")
        table = []
        for h in sorted(hht, reverse=True):
            table.append(("hht", "step %.4g" % h, hht[h]))
        for tol in sorted(adaptive, reverse=True):
            table.append(("hht-adaptive", "tolerance %.3g" % tol, adaptive[tol]))
        for tol in sorted(ida, reverse=True):
            table.append(("ida", "rtol = atol = %.3g" % tol, ida[tol]))
        with open(os.path.join(OUT, "work_precision.csv"), "w", newline="") as f:
            wcsv = csv.writer(f)
            wcsv.writerow(["problem", "integrator", "setting", "cpu_time", "error", "steps", "status"])
            for integ, setting, c in table:
                wcsv.writerow(["andrews", {"hht": "hht-fixed"}.get(integ, integ), setting,
                               "%.6g" % c["cpu"] if "cpu" in c else "", "%.6e" % c["err"] if "err" in c else "",
                               c.get("steps", ""), "failed" if "error" in c else "done"])
        md.append("\n## (c) Work-precision at t = 0.03\n")
        md.append("Cost: the results file's `solver_cpu_time` (process CPU seconds in the integrator, without "
                  "output). Error: max relative error of the 7 angles. Data: `work_precision.csv`; plot: "
                  "`work_precision.png`.\n")
        md.append(mr.markdown_table(
            ["integrator", "setting", "CPU [s]", "max relative error", "scd", "steps"],
            [[integ, setting, "%.4f" % c["cpu"] if "cpu" in c else "-",
              "%.3e" % c["err"] if "err" in c else "failed: " + c.get("error", ""),
              "%.2f" % c["scd"] if "scd" in c else "", c.get("steps", "")] for integ, setting, c in table]))
        try:
            import matplotlib
            matplotlib.use("Agg")
            import matplotlib.pyplot as plt
            fig, ax = plt.subplots(figsize=(6.4, 4.8))
            for integ, style, label in (("hht", "o-", "HHT, alpha = -0.1 (fixed steps)"),
                                        ("hht-adaptive", "^-", "HHT adaptive (tolerance 1e-3 ... 1e-8)"),
                                        ("ida", "s-", "IDA (rtol = atol = 1e-3 ... 1e-10)")):
                pts = sorted((c["cpu"], c["err"]) for i, _, c in table if i == integ and "err" in c)
                if pts:
                    ax.loglog([p[0] for p in pts], [p[1] for p in pts], style, label=label)
            ax.set_xlabel("CPU time in the integrator [s]")
            ax.set_ylabel("max relative error of the 7 angles at t = 0.03")
            ax.set_title("Andrews' squeezer: work-precision")
            ax.grid(True, which="both", alpha=0.3)
            ax.legend()
            fig.tight_layout()
            fig.savefig(os.path.join(OUT, "work_precision.png"), dpi=100)
            figures.append("work_precision.png")
        except Exception as exc:  # the plot is a by-product; the numbers are in the CSV
            print("plot not written:", exc)

    # (d)
    iftomm = part_d(runner, md, checks)
    md.append("")
    summary = {"title": "Andrews' squeezer (IFToMM A03, Test Set for IVP Solvers)",
               "headline": "IDA 1e-10: scd %s; HHT order %s; IFToMM A03 beta errors: %s" % (
                   "%.2f" % a["scd"] if "scd" in a else "failed",
                   ", ".join("%.2f" % p for p in orders),
                   ", ".join("%s %.1e (CPU %.3f s)" % (r["integrator"], r["error"], r["cpu_time"]) for r in iftomm)),
               "figures": figures, "csv": ["work_precision.csv"] if not args.quick else [],
               "iftomm": iftomm}
    if not args.quick:
        summary["work_precision"] = "work_precision.csv"
    return mr.finish_checks(runner, checks, md, OUT, summary)


if __name__ == "__main__":
    sys.exit(main())
