#!/usr/bin/env python3
"""Convergence orders of the HHT integrator in positions, velocities, accelerations and
multipliers, for alpha = 0, -0.1, -0.3, the classical and the modified (Euler-parameter)
scheme, and both residual forms (equilibrium, the default, and negrut).

Problems (each with a tight reference: IDA at rtol = atol = 1e-12, whose own error is
estimated by the difference to IDA at 1e-11 and checked by energy conservation):
  - `pendulum`: IFToMM A01 (examples/pendulum.yaml), planar, 1 s;
  - `tumbling`: a heavy asymmetric top on a spherical joint (tumbling_pendulum.yaml),
    spatial, Euler parameters, orientation-dependent mass matrix, 1 s.

Errors at the output times t = 0.1, 0.2, ..., 1 (max over the times and the components):
q and v absolute (positions in m, Euler parameters), a and lambda relative to the
largest |a|, |lambda| of the reference. Steps h = h0 / 2^k, k = 0..5; the observed order
is the least-squares slope of log(error) against log(h) over the four finest steps, and
each halving's log2(ratio) is listed.

Requirement (issue: HHT orders within 0.2 of the theory): for the default form
(equilibrium), |order - 2| <= 0.2 in q and v for every alpha, classical and modified, on
both problems. The negrut form and the orders in a and lambda are reported (the README
explains what is found and why).

--quick: the tumbling problem, equilibrium form only, four steps (the fit over all four).
"""
import argparse
import math
import os
import sys

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
OUT = os.environ.get("MBDAE_VERIFICATION_OUT") or HERE
os.makedirs(OUT, exist_ok=True)
sys.path.insert(0, os.path.dirname(HERE))
import mbdae_run as mr  # noqa: E402

PROBLEMS = {
    "pendulum": {"model": os.path.join(mr.REPO, "examples", "pendulum.yaml"), "h0": 0.02,
                 "title": "IFToMM A01 pendulum (planar)"},
    "tumbling": {"model": os.path.join(HERE, "tumbling_pendulum.yaml"), "h0": 0.02,
                 "title": "heavy asymmetric top on a spherical joint (spatial, Euler parameters)"},
}
T_END, OUT_STEP = 1.0, 0.1
ALPHAS = [0.0, -0.1, -0.3]
QUANTITIES = ["q", "v", "a", "lambda"]


def read(path):
    r = mr.Results(path)
    rows = r.time > 0.5 * OUT_STEP  # the output times after t = 0
    return {k: r[k][rows] for k in QUANTITIES}, r


def errors(x, ref):
    e = {}
    for k in ("q", "v"):
        e[k] = float(np.max(np.abs(x[k] - ref[k])))
    for k in ("a", "lambda"):
        e[k] = float(np.max(np.abs(x[k] - ref[k])) / np.max(np.abs(ref[k])))
    return e


def fit_order(hs, errs):
    hs, errs = np.asarray(hs), np.asarray(errs)
    return float(np.polyfit(np.log(hs), np.log(errs), 1)[0])


def reference(runner, prob):
    base = ["--t-end", T_END, "--output-step", OUT_STEP, "--integrator", "ida"]
    p12, _ = runner.simulate(prob["model"], base + ["--rtol", "1e-12", "--atol", "1e-12"], "ref12")
    p11, _ = runner.simulate(prob["model"], base + ["--rtol", "1e-11", "--atol", "1e-11"], "ref11")
    ref, r12 = read(p12)
    ref11, _ = read(p11)
    est = errors(ref11, ref)  # the 1e-11 run's distance to the 1e-12 one
    energy = r12["/energy/kinetic"] + r12["/energy/potential"]
    drift = float(np.max(np.abs(energy - energy[0])) / max(np.max(r12["/energy/kinetic"]), 1e-300))
    return ref, est, drift


def study(runner, name, prob, forms, mods, ksteps, md, checks, csv_rows):
    ref, est, drift = reference(runner, prob)
    md.append("## %s: %s\n" % (name, prob["title"]))
    md.append("Reference: IDA rtol = atol = 1e-12. Its distance to IDA at 1e-11: q %.1e, v %.1e, "
              "a %.1e, lambda %.1e (relative); energy drift %.1e of the largest kinetic energy.\n"
              % (est["q"], est["v"], est["a"], est["lambda"], drift))
    checks.append(("%s: reference energy drift %.1e <= 1e-8 (relative to max kinetic energy)"
                   % (name, drift), drift <= 1e-8))
    hs = [prob["h0"] / 2 ** k for k in ksteps]
    table = []
    results = {}
    for form in forms:
        for modified in mods:
            for alpha in ALPHAS:
                errs = {k: [] for k in QUANTITIES}
                for h in hs:
                    args = ["--t-end", T_END, "--output-step", OUT_STEP, "--integrator", "hht",
                            "--alpha", alpha, "--step", repr(h), "--hht-form", form,
                            "--modified" if modified else "--no-modified"]
                    path, _ = runner.simulate(prob["model"], args, "hht")
                    x, _ = read(path)
                    os.remove(path)
                    e = errors(x, ref)
                    for k in QUANTITIES:
                        errs[k].append(e[k])
                    csv_rows.append([name, form, "modified" if modified else "classical", alpha, h]
                                    + [e[k] for k in QUANTITIES])
                fit = {k: fit_order(hs[-4:], errs[k][-4:]) for k in QUANTITIES}
                halvings = {k: [math.log2(errs[k][i - 1] / errs[k][i]) for i in range(1, len(hs))]
                            for k in QUANTITIES}
                results[(form, modified, alpha)] = (errs, fit, halvings)
                scheme = "modified" if modified else "classical"
                table.append([form, scheme, "%g" % alpha]
                             + ["%.2f" % fit[k] for k in QUANTITIES]
                             + ["%.1e" % errs[k][-1] for k in ("q", "v")])
                if form == "equilibrium":
                    for k in ("q", "v"):
                        ok = abs(fit[k] - 2.0) <= 0.2
                        checks.append(("%s, %s, %s, alpha = %g: order in %s = %.2f (2 +- 0.2)"
                                       % (name, form, scheme, alpha, k, fit[k]), ok))
                print("%-9s %-11s %-9s alpha %5.2f  orders q %.2f v %.2f a %.2f lambda %.2f"
                      % (name, form, scheme, alpha, fit["q"], fit["v"], fit["a"], fit["lambda"]))
    md.append("Steps h = %s s. Observed order: least-squares slope over the four finest steps.\n"
              % ", ".join("%.4g" % h for h in hs))
    md.append(mr.markdown_table(["form", "scheme", "alpha", "order q", "order v", "order a",
                                 "order lambda", "error q, finest h", "error v, finest h"], table))
    # Per-halving orders of the default scheme.
    rows = []
    for alpha in ALPHAS:
        key = ("equilibrium", True, alpha) if ("equilibrium", True, alpha) in results else None
        if key is None:
            continue
        errs, fit, halv = results[key]
        for k in QUANTITIES:
            rows.append(["%g" % alpha, k] + ["%.2e" % e for e in errs[k]]
                        + [" ".join("%.2f" % p for p in halv[k])])
    if rows:
        md.append("\nErrors of the default scheme (equilibrium, modified) per step size, and "
                  "log2 of each halving's ratio:\n")
        md.append(mr.markdown_table(["alpha", "quantity"] + ["h = %.3g" % h for h in hs]
                                    + ["orders per halving"], rows))
    return results, hs


def plot(all_results, path):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    names = list(all_results)
    fig, axes = plt.subplots(len(names), 4, figsize=(14, 3.3 * len(names)), squeeze=False)
    colors = {0.0: "C0", -0.1: "C1", -0.3: "C2"}
    for row, name in enumerate(names):
        results, hs = all_results[name]
        for col, k in enumerate(QUANTITIES):
            ax = axes[row][col]
            for (form, modified, alpha), (errs, fit, _) in results.items():
                if not modified:
                    continue
                ls = "-o" if form == "equilibrium" else "--x"
                ax.loglog(hs, errs[k], ls, color=colors[alpha], ms=3,
                          label="%s, alpha %g (%.2f)" % (form, alpha, fit[k]))
            ref = np.array(hs) ** 2
            ax.loglog(hs, ref * errs[k][-1] / ref[-1] * 0.3, "k:", lw=0.8, label="slope 2")
            ax.set_title("%s: %s" % (name, k), fontsize=9)
            ax.set_xlabel("h [s]", fontsize=8)
            ax.tick_params(labelsize=7)
            ax.legend(fontsize=6)
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    mr.add_mbdae_argument(parser)
    parser.add_argument("--quick", action="store_true", help="the CTest subset")
    args = parser.parse_args()
    runner = mr.Runner(mr.find_mbdae(args.mbdae), keep=args.keep)
    md = ["# HHT convergence orders\n",
          "Produced by `verification/orders/run.py`%s. See README.md for the problems, the "
          "reference and what the orders mean.\n" % (" --quick" if args.quick else "")]
    checks, csv_rows, all_results = [], [], {}
    if args.quick:
        plan = [("tumbling", ["equilibrium"], [True, False], [1, 2, 3, 4])]
    else:
        plan = [(n, ["equilibrium", "negrut"], [True, False], list(range(6))) for n in PROBLEMS]
    for name, forms, mods, ks in plan:
        all_results[name] = study(runner, name, PROBLEMS[name], forms, mods, ks, md, checks,
                                  csv_rows)
    csv = "orders.csv"
    with open(os.path.join(OUT, csv), "w") as f:
        f.write("problem,form,scheme,alpha,h,error_q,error_v,error_a_rel,error_lambda_rel\n")
        for r in csv_rows:
            f.write(",".join(str(c) if isinstance(c, str) else "%.6g" % c for c in r) + "\n")
    figures = []
    if not args.quick:
        plot(all_results, os.path.join(OUT, "orders.png"))
        figures.append("orders.png")
        md.append("\n![orders](orders.png)\n")
    eq = [fit for res, _ in all_results.values()
          for (form, _, _), (_, fit, _) in res.items() if form == "equilibrium"]
    lo = min(f[k] for f in eq for k in ("q", "v"))
    hi = max(f[k] for f in eq for k in ("q", "v"))
    summary = {"title": "HHT convergence orders",
               "headline": "equilibrium form: observed orders in q and v between %.2f and %.2f "
                           "(alpha = 0, -0.1, -0.3, classical and modified)" % (lo, hi),
               "figures": figures, "csv": [csv]}
    return mr.finish_checks(runner, checks, md, OUT, summary)


if __name__ == "__main__":
    sys.exit(main())
