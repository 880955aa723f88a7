#!/usr/bin/python3
"""Identify the slider-crank's spring stiffness k and damping c from a noisy measurement.

    PYTHONPATH=build/python /usr/bin/python3 examples/identification/identify_scipy.py
        [--quick] [--seeds N] [--out DIR]

model.yaml holds the objective misfit = 1/2 integral over [0, 10] s of
(xs - s_meas(t))^2, s_meas the linear spline through the noisy samples of
measurement.csv (make_measurement.py, which also records the truth k = 1, c = 1), and
the wrong starting values (k = 2, c = 0.5: twice and half the truth). The script
starts there and minimises the misfit over (k, c) with scipy.optimize.minimize
(L-BFGS-B, bounds), its value and exact gradient from Model.objective_function (one HHT
run plus the discrete adjoint per new point).

Then it explains the remaining error:
- linearised (Gauss-Newton): with S(t) = d xs / d(k, c) at the truth (central
  differences of two solves per parameter, relative step 1e-4) and phi_i the hat
  functions of the linear spline's knots, the minimiser moves by
  dp = H^-1 W e, H = integral S S^T dt, W_i = integral S phi_i dt, e the sample noise:
  the covariance sigma^2 H^-1 W W^T H^-1 gives the expected error (standard deviation),
  and dp with this file's noise (known: measurement.csv also has the noise-free
  samples) the error this realisation should have; the same map on the noise of seeds
  1 .. 2000 (no runs) checks the standard deviation;
- noise-free (not with --quick): the identification from the noise-free samples gives
  the bias of the linear interpolation between the samples alone;
- repeated (--seeds N, default 6; none with --quick): N more noise realisations of the
  same sigma (seeds 2 .. N+1) set as the spline's points from Python, each identified
  from the same wrong start; the spread of their errors against the predicted one.

Writes into --out (default this folder): fit.png (measured, true, start and fitted
signals; residuals), convergence.png (parameter errors and misfit per iteration),
history_scipy.csv (one row per iteration) and summary_scipy.json (the numbers of
README.md). --quick (the test's): no noise-free run, no repetitions. Exit code 1 if
the optimiser did not converge.
"""
import argparse
import csv
import json
import os
import re
import sys
import time

import numpy as np
import scipy
import scipy.optimize

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

import mbdae  # noqa: E402

HERE = os.path.dirname(os.path.abspath(__file__))
NAMES = ["k", "c"]
BOUNDS = [(0.1, 10.0), (0.05, 5.0)]                   # k in N/m, c in N s/m


def read_measurement(path):
    """(t, s_meas, s_true, sigma, seed, truth) of a file written by make_measurement.py."""
    with open(path) as f:
        text = f.read()
    noise = re.search(r"^# noise: sigma = ([0-9.eE+-]+) m, seed = (\d+)$", text, re.M)
    truth = re.search(r"^# truth: k = ([0-9.eE+-]+), c = ([0-9.eE+-]+)$", text, re.M)
    if not noise or not truth:
        sys.exit(f"identify_scipy: {path} lacks the '# noise: sigma = S m, seed = N' or"
                 " the '# truth: k = K, c = C' line (write it with make_measurement.py)")
    data = np.loadtxt(path, delimiter=",", comments="#", skiprows=1)
    return (data[:, 0], data[:, 1], data[:, 2], float(noise.group(1)), int(noise.group(2)),
            np.array([float(truth.group(1)), float(truth.group(2))]))


def identify(model, start, scale, ftol, gtol, maxiter):
    """Minimises the misfit from `start` with L-BFGS-B. Returns (result, history, runs,
    wall time): history is one (x, f, |projected gradient|) per iterate, iterate 0 the
    start, read from the evaluations made (no extra runs)."""
    for name, value in zip(NAMES, start):
        model.parameters[name] = float(value)
    f = model.objective_function("misfit", NAMES, scale=scale)
    evaluated = []                                    # (x, f, gradient) of every run

    def fun(x):
        value = f(x)
        evaluated.append((np.array(x, dtype=float), value, f.jac(x)))
        return value

    def projected_gradient(x, g):
        lo = np.array([b[0] for b in BOUNDS])
        hi = np.array([b[1] for b in BOUNDS])
        return np.max(np.abs(np.clip(x - g, lo, hi) - x))

    iterates = [np.array(start, dtype=float)]
    t0 = time.perf_counter()
    result = scipy.optimize.minimize(
        fun, np.array(start, dtype=float), jac=f.jac, method="L-BFGS-B", bounds=BOUNDS,
        callback=lambda xk: iterates.append(np.array(xk, dtype=float)),
        options={"ftol": ftol, "gtol": gtol, "maxiter": maxiter})
    wall = time.perf_counter() - t0
    history = []
    for x in iterates:
        match = [e for e in evaluated if np.array_equal(e[0], x)]
        if not match:
            raise RuntimeError(f"identify_scipy: iterate {x} was never evaluated")
        _, value, g = match[-1]
        history.append((x, value / scale, projected_gradient(x, g) / scale))
    f.set(result.x)                                   # the model holds the optimum
    return result, history, f.runs, wall


def signal(model, values):
    """(t, xs) of a solve of the model at parameter values `values` (k, c)."""
    for name, value in zip(NAMES, values):
        model.parameters[name] = float(value)
    model.solve()
    return np.array(model.outputs.time), np.array(model.outputs.measure("xs"))


def gauss_newton(model, truth, t_s, rel_step=1e-4):
    """The linearised map from the sample noise to the parameter error, A (2 x samples):
    dp = A e. Also the sensitivities S (rows x 2) and the row times."""
    columns = []
    for j in range(len(NAMES)):
        h = rel_step * truth[j]
        up, down = truth.copy(), truth.copy()
        up[j] += h
        down[j] -= h
        t_r, s_up = signal(model, up)
        _, s_down = signal(model, down)
        columns.append((s_up - s_down) / (2 * h))
    S = np.column_stack(columns)
    phi = np.column_stack([np.interp(t_r, t_s, np.eye(t_s.size)[i]) for i in range(t_s.size)])
    H = np.trapz(S[:, :, None] * S[:, None, :], t_r, axis=0)
    W = np.trapz(S[:, :, None] * phi[:, None, :], t_r, axis=0)          # 2 x samples
    return np.linalg.solve(H, W), S, t_r


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--quick", action="store_true", help="only the identification of the file's samples")
    ap.add_argument("--seeds", type=int, default=6,
                    help="noise realisations identified besides the file's (default 6)")
    ap.add_argument("--model", default=os.path.join(HERE, "model.yaml"))
    ap.add_argument("--measurement", default=os.path.join(HERE, "measurement.csv"))
    # The misfit is smooth only to about 5e-11 of its value (the Newton tolerance of the
    # HHT steps; measured: values at points 1e-8 apart scatter by that much): a decrease
    # below that, or a gradient below about 1e-4 on the scaled misfit, is noise, and
    # tighter tolerances end in line-search failures (ABNORMAL_TERMINATION_IN_LNSRCH).
    ap.add_argument("--ftol", type=float, default=1e-10, help="L-BFGS-B ftol (default 1e-10)")
    ap.add_argument("--gtol", type=float, default=1e-4,
                    help="L-BFGS-B gtol on the scaled misfit (default 1e-4)")
    ap.add_argument("--maxiter", type=int, default=100)
    ap.add_argument("--out", default=HERE, help="folder of the figures and files")
    args = ap.parse_args()
    seeds = 0 if args.quick else args.seeds
    os.makedirs(args.out, exist_ok=True)

    t_s, s_meas, s_true, sigma, seed, truth = read_measurement(args.measurement)
    noise = s_meas - s_true
    with mbdae.Model(args.model) as m:
        start = np.array([m.parameters[n] for n in NAMES])     # the model's: wrong
        t_end = float(m.options["t_end"])
        # The misfit in units of its expected value at the truth, 1/2 t_end (2/3) sigma^2
        # (the mean square of a linear interpolation of independent noise is 2/3 sigma^2):
        # values of order 1, so that L-BFGS-B's ftol (relative to max(|f|, 1)) means what
        # it says.
        scale = 1.0 / (0.5 * t_end * (2.0 / 3.0) * sigma ** 2)
        f_truth = m.objective_function("misfit", NAMES)(truth)

        result, history, runs, wall = identify(m, start, scale, args.ftol, args.gtol,
                                               args.maxiter)
        found = np.array(result.x)
        rel_err = (found - truth) / truth
        f_found = result.fun / scale
        print(f"truth      k = {truth[0]:.6g}, c = {truth[1]:.6g}; misfit there "
              f"{f_truth:.6e}")
        print(f"start      k = {start[0]:.6g}, c = {start[1]:.6g}; misfit "
              f"{history[0][1]:.6e}")
        print(f"identified k = {found[0]:.8f} ({rel_err[0]:+.3%}), c = {found[1]:.8f} "
              f"({rel_err[1]:+.3%}); misfit {f_found:.6e}")
        print(f"L-BFGS-B: {result.message}; {result.nit} iterations, {result.nfev} function"
              f" and {result.njev} gradient evaluations, {runs} model runs (HHT + adjoint),"
              f" {wall:.2f} s wall time")

        # The error the noise explains (linearised at the truth).
        t0 = time.perf_counter()
        A, S, t_r = gauss_newton(m, truth.copy(), t_s)
        cov = sigma ** 2 * A @ A.T
        std_rel = np.sqrt(np.diag(cov)) / truth
        corr = cov[0, 1] / np.sqrt(cov[0, 0] * cov[1, 1])
        predicted_rel = (A @ noise) / truth
        print(f"Gauss-Newton at the truth ({time.perf_counter() - t0:.2f} s): expected "
              f"error (1 std) k {std_rel[0]:.3%}, c {std_rel[1]:.3%} (correlation "
              f"{corr:+.2f}); this noise sample predicts k {predicted_rel[0]:+.3%}, "
              f"c {predicted_rel[1]:+.3%}")
        # The same linear map applied to the noise of seeds 1 .. 2000 (no runs): the
        # spread the repetitions below sample only a few points of.
        draws = np.array([np.random.default_rng(s).standard_normal(t_s.size)
                          for s in range(1, 2001)])
        linear_draws = sigma * draws @ A.T / truth
        linear_std = linear_draws.std(axis=0, ddof=1)
        print(f"linearised errors of seeds 1..2000: std k {linear_std[0]:.3%}, "
              f"c {linear_std[1]:.3%}")

        t_fit = np.array(t_r)
        _, s_fit = signal(m, found)
        _, s_start = signal(m, start)
        _, s_truth = signal(m, truth)

        # The identification from the noise-free samples (not with --quick): what the
        # linear interpolation of the samples alone does to the estimate (a bias).
        bias = None
        if seeds:
            m.splines["s_meas"] = (t_s, s_true)
            r, _, n_runs, w = identify(m, start, scale, args.ftol, args.gtol, args.maxiter)
            bias = (np.array(r.x) - truth) / truth
            print(f"noise-free samples: k {bias[0]:+.4%}, c {bias[1]:+.4%} (the linear "
                  f"spline's interpolation error); {r.nit} iterations, {n_runs} runs, "
                  f"{w:.1f} s")
        repeats = []
        for extra in range(2, 2 + seeds):
            e = sigma * np.random.default_rng(extra).standard_normal(t_s.size)
            m.splines["s_meas"] = (t_s, s_true + e)
            r, h, n_runs, w = identify(m, start, scale, args.ftol, args.gtol, args.maxiter)
            err = (np.array(r.x) - truth) / truth
            pred = (A @ e) / truth
            repeats.append({"seed": extra, "k": float(r.x[0]), "c": float(r.x[1]),
                            "rel_error": err.tolist(), "predicted_rel_error": pred.tolist(),
                            "iterations": int(r.nit), "runs": int(n_runs), "wall_time": w,
                            "success": bool(r.success), "message": str(r.message)})
            print(f"seed {extra}: k {err[0]:+.3%} (linearised {pred[0]:+.3%}), c "
                  f"{err[1]:+.3%} ({pred[1]:+.3%}); {r.nit} iterations, {n_runs} runs, "
                  f"{w:.1f} s{'' if r.success else '; ' + str(r.message)}")
        if repeats:
            errs = np.array([r["rel_error"] for r in repeats] + [rel_err.tolist()])
            rms = np.sqrt(np.mean(errs ** 2, axis=0))
            gap = np.max(np.abs(np.array([r["rel_error"] for r in repeats])
                                - np.array([r["predicted_rel_error"] for r in repeats])),
                         axis=0)
            print(f"{len(errs)} realisations (seeds 1..{1 + seeds}): rms relative error k "
                  f"{rms[0]:.3%}, c {rms[1]:.3%} (expected {std_rel[0]:.3%}, "
                  f"{std_rel[1]:.3%}); identified - linearised at most k {gap[0]:.3%}, "
                  f"c {gap[1]:.3%}")
            offset = np.array([np.array(r["rel_error"]) - np.array(r["predicted_rel_error"])
                               for r in repeats])
            print(f"identified - linearised - noise-free bias: k within "
                  f"[{(offset[:, 0] - bias[0]).min():+.4%}, {(offset[:, 0] - bias[0]).max():+.4%}],"
                  f" c within [{(offset[:, 1] - bias[1]).min():+.4%}, "
                  f"{(offset[:, 1] - bias[1]).max():+.4%}]")
            m.splines["s_meas"] = (t_s, s_meas)

    summary = {
        "truth": dict(zip(NAMES, truth.tolist())), "start": dict(zip(NAMES, start.tolist())),
        "bounds": dict(zip(NAMES, BOUNDS)), "identified": dict(zip(NAMES, found.tolist())),
        "relative_error": dict(zip(NAMES, rel_err.tolist())),
        "misfit": {"start": history[0][1], "identified": f_found, "truth": f_truth},
        "optimizer": {"method": "L-BFGS-B", "scipy": scipy.__version__,
                      "ftol": args.ftol, "gtol": args.gtol, "scale": scale,
                      "success": bool(result.success), "message": str(result.message),
                      "iterations": int(result.nit), "function_evaluations": int(result.nfev),
                      "gradient_evaluations": int(result.njev), "model_runs": int(runs),
                      "wall_time": wall, "final_projected_gradient": history[-1][2]},
        "noise": {"sigma": sigma, "seed": seed, "samples": int(t_s.size),
                  "sample_std": float(noise.std(ddof=1))},
        "gauss_newton": {"expected_relative_std": dict(zip(NAMES, std_rel.tolist())),
                         "correlation": corr,
                         "predicted_relative_error": dict(zip(NAMES, predicted_rel.tolist())),
                         "linearised_std_seeds_1_2000": dict(zip(NAMES, linear_std.tolist()))},
        "noise_free_relative_error": None if bias is None else dict(zip(NAMES, bias.tolist())),
        "repeats": repeats,
    }
    with open(os.path.join(args.out, "summary_scipy.json"), "w") as f:
        json.dump(summary, f, indent=1)
    with open(os.path.join(args.out, "history_scipy.csv"), "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["iteration", "k", "c", "misfit", "projected_gradient",
                    "rel_error_k", "rel_error_c"])
        for i, (x, value, pg) in enumerate(history):
            e = (x - truth) / truth
            w.writerow([i, repr(x[0]), repr(x[1]), repr(value), repr(pg), repr(e[0]), repr(e[1])])

    # Figures.
    fig, (ax1, ax2) = plt.subplots(2, 1, figsize=(8, 6.5), sharex=True,
                                   gridspec_kw={"height_ratios": [2, 1]})
    ax1.plot(t_s, s_meas, ".", ms=4, color="0.5", label=f"measured (noise sigma {sigma:g} m)")
    ax1.plot(t_fit, s_start, "--", color="tab:red",
             label=f"start k = {start[0]:g}, c = {start[1]:g}")
    ax1.plot(t_fit, s_truth, "-", lw=3, color="tab:green", alpha=0.5,
             label=f"truth k = {truth[0]:g}, c = {truth[1]:g}")
    ax1.plot(t_fit, s_fit, "-", color="tab:blue",
             label=f"identified k = {found[0]:.4f}, c = {found[1]:.4f}")
    ax1.set_ylabel("slider position xs, m")
    ax1.legend(fontsize=8, loc="upper left")
    ax1.set_title("slider-crank: k and c identified from the slider position")
    ax2.plot(t_s, 1e3 * (s_meas - np.interp(t_s, t_fit, s_fit)), ".", ms=4, color="0.5",
             label="measured - identified")
    ax2.plot(t_fit, 1e3 * (s_truth - s_fit), "-", color="tab:blue",
             label="truth - identified")
    ax2.set_ylabel("mm")
    ax2.set_xlabel("t, s")
    ax2.legend(fontsize=8, loc="upper left")
    fig.tight_layout()
    fig.savefig(os.path.join(args.out, "fit.png"), dpi=110)
    plt.close(fig)

    it = np.arange(len(history))
    errs = np.array([np.abs((x - truth) / truth) for x, _, _ in history])
    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(10, 4))
    for j, (name, color) in enumerate(zip(NAMES, ("tab:blue", "tab:orange"))):
        ax1.semilogy(it, errs[:, j], "o-", ms=3, color=color, label=f"|{name} - truth| / truth")
        ax1.axhline(std_rel[j], ls=":", color=color,
                    label=f"expected from the noise (1 std), {name}")
    ax1.set_xlabel("L-BFGS-B iteration")
    ax1.legend(fontsize=8)
    ax1.set_title("parameter error")
    values = np.array([v for _, v, _ in history])
    pgs = np.array([g for _, _, g in history])
    gap = values - values.min()
    ax2.semilogy(it[gap > 0], gap[gap > 0], "o-", ms=3, label="misfit - final misfit")
    ax2.semilogy(it, pgs, "s-", ms=3, label="projected gradient (max abs)")
    ax2.set_xlabel("L-BFGS-B iteration")
    ax2.legend(fontsize=8)
    ax2.set_title(f"misfit (final {f_found:.4e})")
    fig.tight_layout()
    fig.savefig(os.path.join(args.out, "convergence.png"), dpi=110)
    plt.close(fig)

    if not result.success:
        sys.exit(f"identify_scipy: L-BFGS-B did not converge: {result.message}")


if __name__ == "__main__":
    main()
