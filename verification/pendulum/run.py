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

Writes verification/pendulum/results.md; exits 1 if a requirement fails.
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


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    mr.add_mbdae_argument(ap)
    args = ap.parse_args()
    runner = mr.Runner(mr.find_mbdae(args.mbdae), args.keep)
    ok = True
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
        print("FAIL: found %d zero crossings of x, expected 4" % len(tz))
        return 1
    periods = [tz[2] - tz[0], tz[3] - tz[1]]
    errs = [abs(p - T) / T for p in periods]
    pass_a = max(errs) < 1e-8
    ok &= pass_a
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
            print("FAIL: output times of HHT and reference differ")
            return 1
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
    ok &= pass_b
    md.append("\n## (b) HHT order (alpha = -0.1, fixed steps) against IDA at rtol = atol = 1e-12\n")
    md.append(mr.markdown_table(["h [s]", "error x(1) [m]", "ratio", "max error over [0,1] [m]",
                                 "ratio"], rows))
    md.append("\nRequirement: at least four halvings with ratio 4 +- 0.4 (found %d for x(1), %d for "
              "the maximum). **%s**\n" % (good_end, good_max, "PASS" if pass_b else "FAIL"))

    with open(os.path.join(OUT, "results.md"), "w") as f:
        f.write("\n".join(md))
    runner.cleanup()
    print("pendulum:", "PASS" if ok else "FAIL")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
