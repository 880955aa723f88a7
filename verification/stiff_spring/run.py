#!/usr/bin/env python3
"""A very stiff spring (stiffness ratio 1e8): stiff_spring.yaml against its exact solution.

Two 1 kg masses on a rail, a soft spring (1 N/m) to the wall and a stiff one (1e8 N/m)
between them, both linear, no damping, 20 s. Modes: slow 0.7071 rad/s (period 8.89 s),
fast 14142 rad/s (period T_f = 4.44e-4 s); the initial state gives both about the same
energy. Exact solution by modal superposition (M = I, K = [[k1 + k2, -k2], [-k2, k2]]).

Measured for every run (output every 0.1 s, or every h when h > 0.1):
- e_slow: max_t |q_s(t) - q_s,exact(t)| / |q_s(0)|, q_s = phi_s^T M u the slow modal
  coordinate of the computed motion (u the displacements from equilibrium);
- E_f(t) / E_f(0), the energy of the fast mode, 1/2 (qdot_f^2 + w_f^2 q_f^2): the exact
  solution keeps it at 1 (no physical damping); a method with numerical damping removes it;
- the stiff spring's force error against the force of the exact slow motion.
What a good result is (the requirements): with steps far above the stiff period, the run
ends (no NaN), the stiff mode is damped out (E_f/E_f(0) <= 1e-6 at every row from t = 5 s
on) and the slow motion is tracked: e_slow <= 2e-2 with h = 0.1 s = 225 T_f and
e_slow <= 2e-4 with h = 0.01 s = 22.5 T_f (HHT alpha = -0.3), observed order
log10(e(0.1)/e(0.01)) within 2 +- 0.2.
Also required (it is what the method is): HHT with alpha = 0 (no numerical damping) keeps
the stiff mode's energy (|E_f(20)/E_f(0) - 1| <= 1e-6 at h = 0.01), i.e. does not damp it.
Full run: sweeps (HHT alpha = -0.3 and 0, fixed and adaptive; IDA from loose to tight
tolerances), work_precision.csv, stiff_spring.png, and the distance-spring trap
(stiff_spring_distance.yaml, spring_damper elements: at h = 0.1 the Newton iteration
lands on the mirrored configuration, the masses pass through each other; reported, not
a requirement).
"""
import argparse
import csv
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

MODEL = os.path.join(HERE, "stiff_spring.yaml")
MODEL_DISTANCE = os.path.join(HERE, "stiff_spring_distance.yaml")
K1, K2, M, U0, D0 = 1.0, 1.0e8, 1.0, 0.1, 1.0e-5
T_END = 20.0
T_LATE = 5.0                   # the stiff mode must be gone from here on

# exact modal data: M = m I, so phi = eigenvectors / sqrt(m) are M-orthonormal
W2, PHI = np.linalg.eigh(np.array([[K1 + K2, -K2], [-K2, K2]]) / M)
PHI = PHI / math.sqrt(M)
W = np.sqrt(W2)
T_FAST = 2 * math.pi / W[1]
U_START = np.array([U0 - D0 / 2, U0 + D0 / 2])
Q0 = PHI.T @ (M * U_START)                 # initial modal coordinates (at rest)
EF0 = 0.5 * W2[1] * Q0[1] ** 2


def exact(t):
    """Exact displacements u (2 x N), velocities, and the slow part of u."""
    q = Q0[:, None] * np.cos(W[:, None] * t[None, :])
    qd = -Q0[:, None] * W[:, None] * np.sin(W[:, None] * t[None, :])
    return PHI @ q, PHI @ qd, np.outer(PHI[:, 0], q[0])


def hht(alpha, h, adaptive=False, tol=None):
    if adaptive:
        return ("hht-adaptive", "tolerance = %g, alpha = %g" % (tol, alpha),
                ["--integrator", "hht", "--adaptive", "--alpha", repr(alpha), "--tolerance", repr(tol),
                 "--step", "1e-3"])
    return ("hht-fixed", "h = %g, alpha = %g" % (h, alpha),
            ["--integrator", "hht", "--alpha", repr(alpha), "--step", repr(h),
             "--output-step", repr(max(0.1, h))])


def ida(tol):
    return ("ida", "rtol = atol = %g" % tol, ["--integrator", "ida", "--rtol", repr(tol), "--atol", repr(tol)])


def damped_from(t, ef, level=1e-6):
    """The first output time from which E_f/E_f(0) stays <= level (NaN: not by the end)."""
    above = np.nonzero(ef > level)[0]
    if len(above) == 0:
        return 0.0
    return float(t[above[-1] + 1]) if above[-1] + 1 < len(t) else float("nan")


def run_case(runner, case, model=MODEL):
    integ, setting, args = case
    path, proc = runner.simulate(model, ["--t-end", repr(T_END), "--output-step", "0.1"] + args, integ, check=False)
    out = {"integrator": integ, "setting": setting, "exit": proc.returncode}
    if proc.returncode not in (0, 3):
        raise mr.RunError("%s %s: %s" % (integ, setting, proc.stderr.strip()))
    r = mr.Results(path)
    t = r.time
    u = np.stack([r["/measures/x1"] - 1.0, r["/measures/x2"] - 2.0])
    v = np.stack([r["/measures/v1"], r["/measures/v2"]])
    q, qd = PHI.T @ (M * u), PHI.T @ (M * v)
    q_s_exact = Q0[0] * np.cos(W[0] * t)
    ef = 0.5 * (qd[1] ** 2 + W2[1] * q[1] ** 2) / EF0
    _, _, u_slow = exact(t)
    f_slow = -K2 * (u_slow[1] - u_slow[0])           # stiff spring force of the exact slow motion
    f = r["/forces/stiff/force"][:, 0]
    late = t >= T_LATE - 1e-9
    out.update(
        status=r.attrs["status"], message=r.attrs.get("failure_reason", ""), t=t, u=u, ef=ef, f=f, f_slow=f_slow,
        nan=bool(np.isnan(r["/q"]).any() or np.isnan(r["/v"]).any()),
        e_slow=float(np.max(np.abs(q[0] - q_s_exact))) / abs(Q0[0]),
        q_s_err=np.abs(q[0] - q_s_exact) / abs(Q0[0]),
        ef_end=float(ef[-1]), ef_max=float(np.max(ef)), t_ef_max=float(t[np.argmax(ef)]),
        ef_late_max=float(np.max(ef[late])),
        force_err=float(np.max(np.abs(f - f_slow)[late])),
        t_damped=damped_from(t, ef),
        cpu=r.cpu_time(), steps=int(r.attrs["steps_accepted"]), rejected=int(r.attrs["steps_rejected"]))
    return out


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    mr.add_mbdae_argument(ap)
    ap.add_argument("--quick", action="store_true", help="the required cases only (no sweep, no figure)")
    args = ap.parse_args()
    runner = mr.Runner(mr.find_mbdae(args.mbdae), args.keep)
    checks = []
    print("modes: %.9f rad/s (period %.4f s), %.4f rad/s (period %.4e s); E_f(0) = %.3e J, E_s(0) = %.3e J" % (
        W[0], 2 * math.pi / W[0], W[1], T_FAST, EF0, 0.5 * W2[0] * Q0[0] ** 2))

    ours = {h: run_case(runner, hht(-0.3, h)) for h in (0.1, 0.01)}
    undamped = run_case(runner, hht(0.0, 0.01))
    for h, lim in ((0.1, 2e-2), (0.01, 2e-4)):
        c = ours[h]
        checks.append(("HHT alpha = -0.3, h = %g = %.0f stiff periods: done, no NaN; stiff mode damped out "
                       "(max E_f/E_f(0) from t = 5 s on %.1e, tolerance 1e-6; below 1e-6 for good from t = %.1f s); slow-motion error %.2e "
                       "(tolerance %g)" % (h, h / T_FAST, c["ef_late_max"], c["t_damped"], c["e_slow"], lim),
                       c["status"] == "done" and not c["nan"] and c["ef_late_max"] <= 1e-6 and c["e_slow"] <= lim))
    order = math.log10(ours[0.1]["e_slow"] / ours[0.01]["e_slow"])
    checks.append(("HHT alpha = -0.3: observed order of the slow-motion error from h = 0.1 to 0.01: %.3f "
                   "(2 +- 0.2)" % order, abs(order - 2) <= 0.2))
    checks.append(("HHT alpha = 0, h = 0.01 (no numerical damping): the stiff mode keeps its energy, "
                   "E_f(20)/E_f(0) - 1 = %.1e (tolerance 1e-6); slow-motion error %.2e" % (undamped["ef_end"] - 1, undamped["e_slow"]),
                   undamped["status"] == "done" and not undamped["nan"] and abs(undamped["ef_end"] - 1) <= 1e-6))

    cases = [ours[0.1], ours[0.01], undamped]
    trap = None
    if not args.quick:
        for c in ([hht(-0.3, h) for h in (0.5, 0.2, 0.05, 0.02, 0.005, 0.002, 0.001)]
                  + [hht(-0.1, 0.1), hht(-0.1, 0.01), hht(0.0, 0.1), hht(0.0, 5e-5)]
                  + [hht(-0.3, None, True, tol) for tol in (1e-3, 1e-4, 1e-6)]
                  + [hht(0.0, None, True, 1e-4)]
                  + [ida(tol) for tol in (1e-3, 1e-4, 1e-5, 1e-6, 1e-7)]):
            cases.append(run_case(runner, c))
        trap = run_case(runner, hht(-0.3, 0.1), MODEL_DISTANCE)
    for c in cases:
        print("%-13s %-28s %-6s e_slow %.2e  E_f end %.1e  E_f max %.1e (t = %.1f)  force err %.1e N  cpu %.3f  steps %d" % (
            c["integrator"], c["setting"], c["status"], c["e_slow"], c["ef_end"], c["ef_max"], c["t_ef_max"],
            c["force_err"], c["cpu"], c["steps"]))

    md = ["# A very stiff spring (stiffness ratio 1e8): verification results\n",
          "Produced by `verification/stiff_spring/run.py%s`; model `verification/stiff_spring/stiff_spring.yaml`; "
          "20 s; exact solution by modal superposition.\n" % (" --quick" if args.quick else ""),
          "Modes: slow %.9f rad/s (period %.4f s), fast %.4f rad/s (period T_f = %.4e s). Initial energies: slow "
          "%.3e J, fast %.3e J.\n" % (W[0], 2 * math.pi / W[0], W[1], T_FAST, 0.5 * W2[0] * Q0[0] ** 2, EF0),
          "Columns: e_slow = max_t |q_s - q_s,exact| / |q_s(0)| (slow modal coordinate); E_f = energy of the "
          "stiff mode relative to its initial value (exact: 1 at all times), at the end, its largest value (and "
          "when), its largest value from t = 5 s on, and the time from which it stays below 1e-6; force error = max from t = 5 s on of |F_stiff - F_slow| "
          "(F_slow = the stiff spring's force in the exact slow motion, at most %.3f N; the undamped stiff mode "
          "alone gives about k_stiff d0 = %.0f N); CPU = `solver_cpu_time`.\n" % (
              float(np.max(np.abs(ours[0.01]["f_slow"]))), K2 * D0),
          mr.markdown_table(
              ["integrator", "setting", "h / T_f", "status", "e_slow", "E_f(20)/E_f(0)", "max E_f/E_f(0) (t)",
               "max E_f/E_f(0), t >= 5", "E_f < 1e-6 from t =", "force error [N]", "CPU [s]", "steps (rejected)"],
              [[c["integrator"], c["setting"],
                ("%.3g" % (float(c["setting"].split()[2].rstrip(",")) / T_FAST)) if c["integrator"] == "hht-fixed" else "-",
                c["status"], "%.2e" % c["e_slow"], "%.2e" % c["ef_end"], "%.1e (%.1f s)" % (c["ef_max"], c["t_ef_max"]),
                "%.1e" % c["ef_late_max"], "%.1f" % c["t_damped"] if c["t_damped"] == c["t_damped"] else "never",
                "%.2e" % c["force_err"], "%.3f" % c["cpu"],
                "%d (%d)" % (c["steps"], c["rejected"])] for c in cases])]
    if trap is not None:
        x1, x2 = trap["u"][0] + 1.0, trap["u"][1] + 2.0
        k = 1
        md.append("\n## A trap: distance springs and huge steps\n")
        md.append("`stiff_spring_distance.yaml` (the same springs as `spring_damper` elements, which act on the "
                  "distance |x2 - x1|), HHT alpha = -0.3, h = 0.1: status %s, e_slow = %.2e; after the first step "
                  "x1 = %.4f m, x2 = %.4f m: the masses have passed through each other and the stiff spring sits at "
                  "its free length the other way round (x2 - x1 = %.4f m). The discrete equations of that step have "
                  "this second solution and Newton's method, started from a predictor %.0f m away, finds it. The "
                  "linear force of `stiff_spring.yaml` has no such second solution.\n" % (
                      trap["status"], trap["e_slow"], x1[k], x2[k], x2[k] - x1[k],
                      0.5 * 0.1 ** 2 * K2 * D0 / M))
    figures, csvs = [], []
    if not args.quick:
        with open(os.path.join(OUT, "work_precision.csv"), "w", newline="") as fh:
            w = csv.writer(fh)
            w.writerow(["problem", "integrator", "setting", "cpu_time", "error", "steps", "status"])
            for c in cases:
                w.writerow(["stiff spring", c["integrator"], c["setting"], "%.6g" % c["cpu"], "%.6e" % c["e_slow"],
                            c["steps"], "done" if c["status"] == "done" else "failed"])
        csvs.append("work_precision.csv")
        try:
            import matplotlib
            matplotlib.use("Agg")
            import matplotlib.pyplot as plt
            fig, axs = plt.subplots(3, 1, figsize=(7, 8.5), sharex=True)
            show = [("hht-fixed", "h = 0.1, alpha = -0.3"), ("hht-fixed", "h = 0.01, alpha = -0.3"),
                    ("hht-fixed", "h = 0.1, alpha = 0"), ("hht-fixed", "h = 0.01, alpha = 0"),
                    ("ida", "rtol = atol = 0.001"), ("ida", "rtol = atol = 1e-06")]
            for integ, setting in show:
                c = next((x for x in cases if x["integrator"] == integ and x["setting"] == setting), None)
                if c is None:
                    continue
                lab = "%s %s" % (integ, setting)
                axs[0].semilogy(c["t"], np.maximum(c["q_s_err"], 1e-12), lw=1, label=lab)
                axs[1].semilogy(c["t"], np.maximum(c["ef"], 1e-30), lw=1, label=lab)
                axs[2].plot(c["t"], c["f"], lw=1, label=lab)
            axs[2].plot(ours[0.01]["t"], ours[0.01]["f_slow"], "k--", lw=1.5, label="exact slow motion")
            axs[0].set_ylabel("slow-mode error / |q_s(0)|")
            axs[0].set_title("stiff spring, k_stiff / k_soft = 1e8, stiff period %.2e s" % T_FAST)
            axs[1].set_ylabel("E_f(t) / E_f(0)")
            axs[1].axhline(1e-6, color="r", ls="--", lw=1)
            axs[2].set_ylabel("stiff spring force [N]")
            axs[2].set_yscale("symlog", linthresh=0.1)
            axs[2].set_xlabel("t [s]")
            axs[1].legend(fontsize=7, loc="lower left", ncol=2)
            fig.tight_layout()
            fig.savefig(os.path.join(OUT, "stiff_spring.png"), dpi=100)
            plt.close(fig)
            figures.append("stiff_spring.png")
        except Exception as exc:  # the figure is a by-product; the numbers are in the tables
            print("figure not written:", exc)
    summary = {"title": "Very stiff spring (stiffness ratio 1e8)",
               "headline": "HHT alpha = -0.3 with h = 0.1 s (225 stiff periods): stiff mode damped out "
                           "(E_f/E_f0 %.0e at 20 s), slow-motion error %.1e, %.4f s CPU; alpha = 0 keeps the stiff "
                           "mode (E_f/E_f0 = %.6f, spring force off by %.0f N)" % (
                               ours[0.1]["ef_end"], ours[0.1]["e_slow"], ours[0.1]["cpu"], undamped["ef_end"],
                               undamped["force_err"]),
               "figures": figures, "csv": csvs}
    if csvs:
        summary["work_precision"] = "work_precision.csv"
    return mr.finish_checks(runner, checks, md, OUT, summary)


if __name__ == "__main__":
    sys.exit(main())
