#!/usr/bin/env python3
"""IFToMM A01 simple pendulum (examples/pendulum.yaml): period against the closed form,
and the convergence order of the HHT integrator.

(a) IDA at rtol = atol = 1e-11 over two periods; the period is measured from the zero
    crossings of x (x(t) = 0 at T/4, 3T/4, 5T/4, 7T/4), each located on the cubic Hermite
    interpolant of x and x' between the two output samples that bracket it, and compared
    with the closed form T = 4 sqrt(L/g) K(k), k = sin(theta0/2), theta0 = pi/2.
    Requirement: relative error < 1e-8.
(b) HHT (alpha = -0.1, fixed steps h = 1e-2 / 2^i, i = 0..5) against IDA at
    rtol = atol = 1e-12: the error in x at t = 1 and the largest error over [0, 1]
    (at the output times, every 0.01 s). Requirement: at least four halvings with an
    error ratio of 4 +- 0.4 (second order), both for x(1) and for the maximum.
(c) IFToMM A01 (Gonzalez et al. 2006): x and y of the mass over 10 s, 4000 output
    steps (every 2.5e-3 s), against the exact solution in closed form (Jacobi elliptic
    functions: sin(theta/2) = k sn(K(k) - w0 t; k), k = sin(theta0/2), w0 = sqrt(g/L), so
    x = 2 k sn dn, y = 2 k^2 sn^2 - 1). The closed form is checked against IDA at
    rtol = atol = 1e-12 (max difference <= 1e-8 m). Error of a run (our reading of the
    benchmark's "maximum error, threshold 1e-3"): max over x, y of
    max_t |q(t) - q_ref(t)| / max(max_t |q_ref|, 1e-3). HHT (alpha = -0.1, h = 5e-4) and
    IDA (rtol = atol = 1e-6): error <= 1e-3 (high precision). Rows in summary.json
    ("iftomm").

Writes results.md and summary.json (and, without --quick, iftomm_a01.png) in
verification/pendulum or $MBDAE_VERIFICATION_OUT; exits 1 if a requirement fails.
--quick: everything but the figure (the checks are the same).
"""
import argparse
import math
import os
import sys

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
# Where the tables and figures go: this folder, or $MBDAE_VERIFICATION_OUT (the tests).
OUT = os.environ.get("MBDAE_VERIFICATION_OUT") or HERE
os.makedirs(OUT, exist_ok=True)
sys.path.insert(0, os.path.dirname(HERE))
import mbdae_run as mr  # noqa: E402

MODEL = os.path.join(mr.REPO, "examples", "pendulum.yaml")
L, G = 1.0, 9.81


def ellipk_agm(k):
    """Complete elliptic integral of the first kind K(k), modulus k, by the arithmetic-
    geometric mean: K(k) = pi / (2 AGM(1, sqrt(1 - k^2))) (Abramowitz & Stegun 17.6.1)."""
    a, b = 1.0, math.sqrt(1.0 - k * k)
    for _ in range(60):
        a, b = 0.5 * (a + b), math.sqrt(a * b)
        if abs(a - b) <= 1e-17 * a:
            break
    return math.pi / (2.0 * a)


def exact_period(theta0=math.pi / 2):
    # Large-amplitude pendulum: T = 4 sqrt(L/g) K(sin(theta0/2)).
    return 4.0 * math.sqrt(L / G) * ellipk_agm(math.sin(theta0 / 2))


def hermite_root(t0, t1, x0, x1, v0, v1):
    """Root in [t0, t1] of the cubic Hermite interpolant of (x, x')."""
    h = t1 - t0

    def p(s):  # s in [0, 1]
        h00 = 2 * s**3 - 3 * s**2 + 1
        h10 = s**3 - 2 * s**2 + s
        h01 = -2 * s**3 + 3 * s**2
        h11 = s**3 - s**2
        return h00 * x0 + h10 * h * v0 + h01 * x1 + h11 * h * v1

    def dp(s):
        return ((6 * s**2 - 6 * s) * x0 + (3 * s**2 - 4 * s + 1) * h * v0
                + (-6 * s**2 + 6 * s) * x1 + (3 * s**2 - 2 * s) * h * v1)

    s = x0 / (x0 - x1)  # secant start
    for _ in range(50):
        ds = p(s) / dp(s)
        s -= ds
        if abs(ds) < 1e-16:
            break
    assert 0.0 <= s <= 1.0, s
    return t0 + s * h


def zero_crossings(t, x, v):
    out = []
    for k in range(len(t) - 1):
        if x[k] == 0.0 or x[k] * x[k + 1] < 0.0:
            out.append(hermite_root(t[k], t[k + 1], x[k], x[k + 1], v[k], v[k + 1]))
    return out


def exact_xy(t, theta0=math.pi / 2):
    """Closed-form motion of the pendulum released from rest at theta0 (from the downward
    vertical, towards +x): sin(theta/2) = k sn(K - w0 t; k), k = sin(theta0/2)."""
    from scipy.special import ellipj
    k = math.sin(theta0 / 2)
    K = ellipk_agm(k)
    sn, _, dn, _ = ellipj(K - math.sqrt(G / L) * np.asarray(t), k * k)
    return L * 2 * k * sn * dn, L * (2 * k * k * sn * sn - 1)


IFTOMM_TOL, IFTOMM_THRESHOLD = 1e-3, 1e-3
IFTOMM_T_END, IFTOMM_OUTPUT = 10.0, 2.5e-3
IFTOMM_SETTINGS = [("hht-fixed", "alpha = -0.1, h = 5e-4", ["--integrator", "hht", "--alpha", "-0.1", "--fixed-step",
                                                            "--step", "5e-4"]),
                   ("ida", "rtol = atol = 1e-6", ["--integrator", "ida", "--rtol", "1e-6", "--atol", "1e-6"])]


def iftomm_error(values, refs, threshold=IFTOMM_THRESHOLD):
    """max over the components of max_t |q - q_ref| / max(max_t |q_ref|, threshold)."""
    return max(float(np.max(np.abs(v - r))) / max(float(np.max(np.abs(r))), threshold)
               for v, r in zip(values, refs))


def part_c(runner, md, checks, quick):
    common = ["--t-end", repr(IFTOMM_T_END), "--output-step", repr(IFTOMM_OUTPUT)]
    path, _ = runner.simulate(MODEL, ["--integrator", "ida", "--rtol", "1e-12", "--atol", "1e-12"] + common, "a01ref")
    ref = mr.Results(path)
    xe, ye = exact_xy(ref.time)
    dref = max(float(np.max(np.abs(ref["/measures/x"] - xe))), float(np.max(np.abs(ref["/measures/y"] - ye))))
    print("A01: closed form against IDA 1e-12 over 10 s: max difference %.2e m" % dref)
    checks.append(("A01 reference: closed form (elliptic functions) and IDA at rtol = atol = 1e-12 agree over "
                   "10 s to %.1e m <= 1e-8" % dref, dref <= 1e-8))
    rows, hist = [], {}
    for integ, setting, args in IFTOMM_SETTINGS:
        path, _ = runner.simulate(MODEL, args + common, "a01")
        r = mr.Results(path)
        if len(r.time) != len(ref.time) or np.max(np.abs(r.time - ref.time)) > 1e-9:
            raise mr.RunError("A01: output times differ from the reference's")
        xe, ye = exact_xy(r.time)
        err = iftomm_error([r["/measures/x"], r["/measures/y"]], [xe, ye])
        passed = err <= IFTOMM_TOL
        rows.append({"problem": "A01", "integrator": integ, "setting": setting, "quantity": "x, y of the mass",
                     "error": err, "tolerance": IFTOMM_TOL, "cpu_time": r.cpu_time(), "passed": bool(passed)})
        hist[integ] = (r.time, np.maximum(np.abs(r["/measures/x"] - xe), np.abs(r["/measures/y"] - ye)))
        print("A01 %-9s %-24s error %.3e (tolerance 1e-3) CPU %.3f s" % (integ, setting, err, r.cpu_time()))
        checks.append(("IFToMM A01, %s (%s): error of x, y over 10 s = %.2e <= 1e-3" % (integ, setting, err), passed))
    md.append("\n## (c) IFToMM A01: x, y of the mass over 10 s against the closed form\n")
    md.append("Closed form: sin(theta/2) = k sn(K(k) - sqrt(g/L) t; k), k = sin(pi/4); x = 2 k sn dn, "
              "y = 2 k^2 sn^2 - 1 (scipy's Jacobi elliptic functions). Against IDA at rtol = atol = 1e-12 it differs "
              "by at most %.1e m over 10 s. 4000 output steps (every 2.5e-3 s). Error: max over x, y of "
              "max_t |q - q_ref| / max(max_t |q_ref|, 1e-3) (here max |x_ref| = max |y_ref| = 1 m). "
              "CPU: the results file's solver_cpu_time.\n" % dref)
    md.append(mr.markdown_table(["integrator", "setting", "error", "tolerance", "CPU [s]", "passed"],
                                [[r["integrator"], r["setting"], "%.3e" % r["error"], "1e-3", "%.4f" % r["cpu_time"],
                                  "yes" if r["passed"] else "NO"] for r in rows]))
    figures = []
    if not quick:
        try:
            import matplotlib
            matplotlib.use("Agg")
            import matplotlib.pyplot as plt
            fig, ax = plt.subplots(figsize=(6.4, 4))
            for (integ, setting, _), c in zip(IFTOMM_SETTINGS, ("C0", "C1")):
                t, e = hist[integ]
                ax.semilogy(t[1:], np.maximum(e[1:], 1e-16), color=c, lw=0.8, label="%s, %s" % (integ, setting))
            ax.axhline(IFTOMM_TOL, color="k", ls=":", label="IFToMM high precision 1e-3")
            ax.set_xlabel("t [s]")
            ax.set_ylabel("max(|x - x_exact|, |y - y_exact|) [m]")
            ax.set_title("IFToMM A01 pendulum: error against the closed form")
            ax.grid(True, which="both", alpha=0.3)
            ax.legend(fontsize=8)
            fig.tight_layout()
            fig.savefig(os.path.join(OUT, "iftomm_a01.png"), dpi=100)
            figures.append("iftomm_a01.png")
        except Exception as exc:
            print("figure not written:", exc)
    return rows, figures


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    mr.add_mbdae_argument(ap)
    ap.add_argument("--quick", action="store_true", help="no figure (the checks are the same)")
    args = ap.parse_args()
    runner = mr.Runner(mr.find_mbdae(args.mbdae), args.keep)
    checks = []
    md = ["# Pendulum (IFToMM A01): verification results\n",
          "Produced by `verification/pendulum/run.py`; model `examples/pendulum.yaml`.\n"]

    # (a) period with IDA
    T = exact_period()
    path, _ = runner.simulate(MODEL, ["--integrator", "ida", "--rtol", "1e-11", "--atol", "1e-11",
                                      "--t-end", "5.0", "--output-step", "1e-3"], "period")
    r = mr.Results(path)
    x = r["/measures/x"]
    vx = r["/bodies/bob/velocity"][:, 0]
    tz = zero_crossings(r.time, x, vx)
    if len(tz) < 4:
        checks.append(("period: 4 zero crossings of x found (found %d)" % len(tz), False))
        return mr.finish_checks(runner, checks, md, OUT, {"title": "Pendulum (IFToMM A01)"})
    periods = [tz[2] - tz[0], tz[3] - tz[1]]
    errs = [abs(p - T) / T for p in periods]
    pass_a = max(errs) < 1e-8
    checks.append(("(a) period from IDA 1e-11 within 1e-8 relative of the closed form (worst %.2e)" % max(errs),
                   pass_a))
    print("period: exact %.15f s" % T)
    for p, e in zip(periods, errs):
        print("  measured %.15f s, relative error %.2e" % (p, e))
    md.append("## (a) Period, IDA (rtol = atol = 1e-11, output step 1e-3)\n")
    md.append("Closed form T = 4 sqrt(L/g) K(sin(pi/4)), K by the arithmetic-geometric mean: "
              "T = %.15f s.\n" % T)
    md.append(mr.markdown_table(
        ["estimate", "crossings used", "period [s]", "relative error"],
        [["1", "t1 = %.12f, t3 = %.12f" % (tz[0], tz[2]), "%.15f" % periods[0], "%.2e" % errs[0]],
         ["2", "t2 = %.12f, t4 = %.12f" % (tz[1], tz[3]), "%.15f" % periods[1], "%.2e" % errs[1]]]))
    md.append("\nRequirement: relative error < 1e-8. **%s**\n" % ("PASS" if pass_a else "FAIL"))

    # (b) HHT order
    ref_path, _ = runner.simulate(MODEL, ["--integrator", "ida", "--rtol", "1e-12", "--atol", "1e-12",
                                          "--t-end", "1.0", "--output-step", "1e-2"], "reference")
    ref = mr.Results(ref_path)
    xref = ref["/measures/x"]
    steps = [1e-2 / 2**i for i in range(6)]
    rows, e_end, e_max = [], [], []
    for h in steps:
        p, _ = runner.simulate(MODEL, ["--integrator", "hht", "--alpha", "-0.1", "--step", repr(h),
                                       "--t-end", "1.0", "--output-step", "1e-2"], "hht")
        res = mr.Results(p)
        xs = res["/measures/x"]
        if len(xs) != len(xref) or np.max(np.abs(res.time - ref.time)) > 1e-9:
            checks.append(("(b) output times of HHT and reference agree", False))
            return mr.finish_checks(runner, checks, md, OUT, {"title": "Pendulum (IFToMM A01)"})
        e_end.append(abs(res.at("/measures/x", 1.0) - ref.at("/measures/x", 1.0)))
        e_max.append(float(np.max(np.abs(xs - xref))))
    ratios_end = [e_end[i] / e_end[i + 1] for i in range(len(steps) - 1)]
    ratios_max = [e_max[i] / e_max[i + 1] for i in range(len(steps) - 1)]
    for i, h in enumerate(steps):
        rows.append(["%.6g" % h, "%.3e" % e_end[i], "%.3f" % ratios_end[i - 1] if i else "",
                     "%.3e" % e_max[i], "%.3f" % ratios_max[i - 1] if i else ""])
        print("HHT h = %-10.4g err x(1) %.3e  max err %.3e%s" % (
            h, e_end[i], e_max[i],
            "  ratios %.3f %.3f" % (ratios_end[i - 1], ratios_max[i - 1]) if i else ""))
    good_end = sum(1 for q in ratios_end if abs(q - 4.0) <= 0.4)
    good_max = sum(1 for q in ratios_max if abs(q - 4.0) <= 0.4)
    pass_b = good_end >= 4 and good_max >= 4
    checks.append(("(b) HHT alpha = -0.1: at least four halvings with error ratio 4 +- 0.4 for x(1) (%d) and for "
                   "the maximum over [0, 1] (%d)" % (good_end, good_max), pass_b))
    md.append("\n## (b) HHT order (alpha = -0.1, fixed steps) against IDA at rtol = atol = 1e-12\n")
    md.append(mr.markdown_table(["h [s]", "error x(1) [m]", "ratio", "max error over [0,1] [m]",
                                 "ratio"], rows))
    md.append("\nRequirement: at least four halvings with ratio 4 +- 0.4 (found %d for x(1), %d for "
              "the maximum). **%s**\n" % (good_end, good_max, "PASS" if pass_b else "FAIL"))

    # (c) IFToMM A01
    rows, figures = part_c(runner, md, checks, args.quick)
    md.append("")
    summary = {"title": "Pendulum (IFToMM A01)",
               "headline": "period from IDA within %.1e of the closed form; HHT order %.2f per halving; IFToMM A01 "
                           "errors over 10 s: %s" % (max(errs), ratios_end[-1], ", ".join(
                               "%s %.1e (CPU %.3f s)" % (r["integrator"], r["error"], r["cpu_time"]) for r in rows)),
               "figures": figures, "csv": [], "iftomm": rows}
    return mr.finish_checks(runner, checks, md, OUT, summary)


if __name__ == "__main__":
    sys.exit(main())
