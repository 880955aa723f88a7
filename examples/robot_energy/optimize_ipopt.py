#!/usr/bin/python3
"""Energy-optimal rest-to-rest motion of the robot arm (arm.yaml) with Ipopt, from zero torque.

    PYTHONPATH=build/python /usr/bin/python3 examples/robot_energy/optimize_ipopt.py [--quick]

Every optimisation is `mbdae.optimize_string` (the same solver as `mbdae optimize`:
Ipopt, limited-memory Hessian, exact gradients from the HHT discrete adjoint) on a problem
like problem.yaml with `parameters:` (g, T) and `start:` values written by this script.

Why a continuation: with gravity, single shooting from zero torque fails (the arm falls
and its forearm swings as a double pendulum; README.md has the measured failures). The
script therefore

1. solves the problem without gravity (g = 0) from zero torque;
2. raises g to 9.81 in steps, each stage starting from a *predictor*: the last stage's
   torques plus the change of the gravity torques along its motion,
       tau_k += (g_new - g_old) G_k(q(t_k)),  G_2 = a cos q2 + b cos(q2 + q3),
       G_3 = b cos(q2 + q3), a = (m2/2 + m3 + mp) L2, b = (m3/2 + mp) L3, G_1 = 0,
   which, were the torques continuous functions, would keep the last motion exactly
   (gravity enters the equations linearly); a failed stage halves the step;
3. tries to minimise the mechanical energy drawn (objective `energy_reg` = energy + 0.01
   losses) from the loss optimum by single shooting, 100 Ipopt iterations at most (it
   does not converge: README.md; energy_ipopt.py solves that problem);
4. sweeps the duration T: at each T steps 1 and 2 again, and the quintic motion's costs
   (`mbdae simulate quintic.yaml --set T=...`).

Writes into this folder (or --out): summary.json, stages.csv (one row per optimisation),
history.csv (every Ipopt iteration of every stage), optimal.csv (the optimal torques and
angles at T = 1 s against the quintic motion), sweep.csv, torques.png, angles.png,
sweep.png. --quick stops after step 2 (the test).
"""
import argparse
import csv
import json
import os
import subprocess
import tempfile
import time

import h5py
import numpy as np
import scipy.interpolate

import mbdae

HERE = os.path.dirname(os.path.abspath(__file__))
SPLINES = ("tau1", "tau2", "tau3")
N = 11  # ordinates per torque spline, at t_k = k T / 10
CONSTRAINTS = ("final_q1", "final_q2", "final_q3", "final_w1", "final_w2", "final_w3")
# arm.yaml's masses and lengths (for the gravity torques of the predictor only)
M2, M3, MP, L2, L3 = 2.0, 1.0, 0.5, 0.3, 0.2
A_COEF = (M2 / 2 + M3 + MP) * L2
B_COEF = (M3 / 2 + MP) * L3
G_EARTH = 9.81
BOUND = 40.0  # N m, every ordinate


def gravity_torques(q2, q3):
    """Joint torques that hold the arm against unit gravity at (q2, q3): (G1, G2, G3)."""
    c23 = np.cos(q2 + q3)
    return np.zeros_like(q2), A_COEF * np.cos(q2) + B_COEF * c23, B_COEF * c23


def problem_text(g, T, start, minimize, tol, max_iter):
    lines = ["format: 1", "model: arm.yaml", "parameters: {g: %r, T: %r}" % (g, T), "variables:"]
    for s in SPLINES:
        values = ", ".join(repr(float(v)) for v in start[s])
        lines.append("  - {spline: %s, lower: %r, upper: %r, start: [%s]}" % (s, -BOUND, BOUND, values))
    lines.append("minimize: %s" % minimize)
    lines.append("constraints:")
    lines += ["  - {objective: %s, equals: 0}" % c for c in CONSTRAINTS]
    lines.append("simulation: {integrator: hht, hht: {step: 1.0e-3}}")
    lines.append("ipopt: {tol: %r, max_iter: %d}" % (tol, max_iter))
    return "\n".join(lines) + "\n"


class Runner:
    """Runs the stages, keeps their rows and the Ipopt histories."""

    def __init__(self, workdir):
        self.workdir = workdir
        self.stages = []
        self.history = []
        self.count = 0

    # A stage that converges takes 20-40 Ipopt iterations here; one that has not after
    # 50 is abandoned (and the continuation step halved) rather than run to 200.
    def solve(self, what, g, T, start, minimize="losses", tol=1e-8, max_iter=50):
        self.count += 1
        results = os.path.join(self.workdir, "stage%03d.h5" % self.count)
        text = problem_text(g, T, start, minimize, tol, max_iter)
        t0 = time.time()
        r = mbdae.optimize_string(text, name=os.path.join(HERE, "continuation-stage.yaml"), results=results)
        wall = time.time() - t0
        row = {"stage": self.count, "what": what, "g": g, "T": T, "minimize": minimize,
               "status": r.status, "objective": r.objective, "violation": r.constraint_violation,
               "iterations": r.iterations, "runs": r.runs, "gradient_evaluations": r.gradient_evaluations,
               "gradient_cpu_time": r.gradient_cpu_time, "cpu_time": r.cpu_time, "wall_time": wall}
        self.stages.append(row)
        for h in r.history:
            self.history.append([self.count] + [float(v) for v in h])
        print("stage %3d %-26s g = %-6.4g T = %-5.3g %-7s %s = %-12.7g violation %.1e, %3d iterations, %4d runs, %5.1f s"
              % (self.count, what, g, T, r.status, minimize, r.objective, r.constraint_violation,
                 r.iterations, r.runs, wall), flush=True)
        x = {s: np.array([r.variables["%s[%d]" % (s, k)] for k in range(N)]) for s in SPLINES}
        return r, x, results


def knot_angles(results, T):
    """q2, q3 of a results file at the spline knots t_k = k T / 10."""
    with h5py.File(results) as f:
        t = f["/time"][()]
        knots = np.linspace(0, T, N)
        return np.interp(knots, t, f["/measures/q2"][()]), np.interp(knots, t, f["/measures/q3"][()])


def predict_gravity(x, results, T, g_old, g_new):
    q2, q3 = knot_angles(results, T)
    G = gravity_torques(q2, q3)
    return {s: x[s] + (g_new - g_old) * G[i] for i, s in enumerate(SPLINES)}


def continuation(runner, what, value, target, step, solve_at, predict, x, results, min_step=1e-3, max_failures=20):
    """Moves a parameter from value to target in steps of at most `step`, halved after a
    failed stage (which is retried from the last solved one) and grown again by 1.5 after
    a success, up to `step`; gives up (SystemExit) after `max_failures` failed stages."""
    max_step = step
    failures = 0
    sign = 1.0 if target >= value else -1.0
    while value != target:
        nxt = target if abs(target - value) <= step * (1 + 1e-12) else value + sign * step
        r, xn, rn = solve_at(nxt, predict(x, results, value, nxt), what)
        if r.solved:
            value, x, results, last = nxt, xn, rn, r
            step = min(1.5 * step, max_step)
        else:
            step /= 2
            failures += 1
            if step < min_step or failures > max_failures:
                raise SystemExit("continuation in %s stopped at %g after %d failed stages" % (what, value, failures))
    return x, results, last


def quintic_costs(T, workdir):
    out = os.path.join(workdir, "quintic_%g.h5" % T)
    subprocess.run([MBDAE_BIN, "simulate", os.path.join(HERE, "quintic.yaml"), "--set", "T=%r" % T,
                    "-o", out, "--quiet"], check=True)
    with h5py.File(out) as f:
        return {k: float(f["/objectives/" + k].attrs["value"]) for k in ("losses", "energy")}, out


def costs_of(results):
    with h5py.File(results) as f:
        return {k: float(f["/objectives/" + k].attrs["value"]) for k in ("losses", "energy")}


def write_csv(path, header, rows):
    with open(path, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(header)
        w.writerows(rows)


def main():
    global MBDAE_BIN
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--mbdae", default=os.environ.get("MBDAE", "build/mbdae"), help="the mbdae program (quintic runs)")
    ap.add_argument("--out", default=HERE, help="where the tables and figures go")
    ap.add_argument("--quick", action="store_true", help="only the gravity continuation (no energy, no sweep, no figures)")
    ap.add_argument("--sweep", default="0.7,0.85,1.2", help="durations T besides 1 s")
    args = ap.parse_args()
    MBDAE_BIN = args.mbdae
    os.makedirs(args.out, exist_ok=True)
    work = tempfile.mkdtemp(prefix="robot_energy_")
    runner = Runner(work)
    t_start, cpu_start = time.time(), time.process_time()

    zero = {s: np.zeros(N) for s in SPLINES}
    # 1. Without gravity, from zero torque.
    r0, x, res = runner.solve("g = 0 from zero torque", 0.0, 1.0, zero)
    if not r0.solved:
        raise SystemExit("the problem without gravity did not converge")
    # 2. Gravity continuation with the gravity-torque predictor.
    x, res, r_loss = continuation(
        runner, "gravity", 0.0, G_EARTH, 1.0,
        lambda g, start, what: runner.solve(what, g, 1.0, start), lambda xx, rr, a, b: predict_gravity(xx, rr, 1.0, a, b),
        x, res)
    x_loss, res_loss = x, res
    loss_costs = costs_of(res_loss)
    quintic, quintic_h5 = quintic_costs(1.0, work)
    summary = {
        "model": "arm.yaml", "T": 1.0, "g": G_EARTH,
        "losses_optimum": {"losses": loss_costs["losses"], "energy": loss_costs["energy"],
                           "violation": r_loss.constraint_violation, "torques": {s: x_loss[s].tolist() for s in SPLINES}},
        "quintic": quintic,
        "loss_saving": 1 - loss_costs["losses"] / quintic["losses"],
    }
    if args.quick:
        summary["stages"] = runner.stages
        print(json.dumps({k: summary[k] for k in ("losses_optimum", "quintic", "loss_saving")}, indent=1))
        return
    # 3. The mechanical energy drawn, from the loss optimum.
    r_en, x_en, res_en = runner.solve("energy from loss optimum", G_EARTH, 1.0, x_loss, minimize="energy_reg",
                                      max_iter=100)
    en_costs = costs_of(res_en)
    summary["energy_stage"] = {"status": r_en.status, "objective": "energy_reg (rho = 0.01)", "losses": en_costs["losses"], "energy": en_costs["energy"],
                                 "violation": r_en.constraint_violation, "iterations": r_en.iterations,
                                 "torques": {s: x_en[s].tolist() for s in SPLINES}}
    # (a saving only for a solved energy stage: an infeasible iterate's energy says nothing)
    summary["energy_saving"] = 1 - en_costs["energy"] / quintic["energy"] if r_en.solved else None

    # The time histories at T = 1 s: optimal (losses, energy) against quintic.
    series = {}
    for key, path in (("losses_optimum", res_loss), ("energy_stage", res_en), ("quintic", quintic_h5)):
        with h5py.File(path) as f:
            t = f["/time"][()]
            series[key] = {"t": t, **{m: f["/measures/" + m][()] for m in ("q1", "q2", "q3")}}
            if key == "quintic":
                for k in (1, 2, 3):
                    series[key]["tau%d" % k] = f["/measures/tau%d" % k][()]
    # arm.yaml's torques: natural cubic splines through the ordinates at t_k = k T / 10
    for key, xx in (("losses_optimum", x_loss), ("energy_stage", x_en)):
        for k, s in enumerate(SPLINES, 1):
            spline = scipy.interpolate.CubicSpline(np.linspace(0, 1.0, N), xx[s], bc_type="natural")
            series[key]["tau%d" % k] = spline(series[key]["t"])

    # 4. Sweep over T: at each T the same procedure as at T = 1 s (g = 0 from zero torque,
    # then the gravity continuation). (A continuation in T from the T = 1 s optimum with
    # the time-scaling predictor tau = g G + (T_old/T_new)^2 (tau_old - g G) was tried:
    # its starting points miss the target by 2 rad/s already at T = 1.1 s, and the
    # stages failed.)
    sweep = {1.0: {"losses": loss_costs["losses"], "energy_of_loss_optimum": loss_costs["energy"],
                   "status_losses": "solved", "quintic_losses": quintic["losses"], "quintic_energy": quintic["energy"]}}
    for T in sorted(float(v) for v in args.sweep.split(",") if v.strip()):
        rT0, xT, resT = runner.solve("g = 0 from zero torque", 0.0, T, zero)
        if not rT0.solved:
            sweep[T] = {"status_losses": "failed at g = 0"}
            continue
        try:
            xT, resT, rT = continuation(
                runner, "gravity", 0.0, G_EARTH, 1.0,
                lambda g, start, what, TT=T: runner.solve(what, g, TT, start),
                lambda xx, rr, a, b, TT=T: predict_gravity(xx, rr, TT, a, b), xT, resT)
        except SystemExit as e:
            sweep[T] = {"status_losses": str(e)}
            continue
        cT = costs_of(resT)
        qT, _ = quintic_costs(T, work)
        sweep[T] = {"losses": cT["losses"], "energy_of_loss_optimum": cT["energy"],
                    "status_losses": rT.status, "quintic_losses": qT["losses"], "quintic_energy": qT["energy"]}
    summary["sweep"] = {("%g" % T): sweep[T] for T in sorted(sweep)}
    summary["stages"] = runner.stages
    summary["totals"] = {"optimisations": len(runner.stages), "runs": sum(s["runs"] for s in runner.stages),
                         "iterations": sum(s["iterations"] for s in runner.stages),
                         "gradient_cpu_time": sum(s["gradient_cpu_time"] for s in runner.stages),
                         "optimiser_cpu_time": sum(s["cpu_time"] for s in runner.stages),
                         "wall_time": time.time() - t_start, "script_cpu_time": time.process_time() - cpu_start}
    to_T1 = [s for s in runner.stages if s["T"] == 1.0 and s["minimize"] == "losses"]
    summary["to_loss_optimum"] = {"optimisations": len(to_T1), "runs": sum(s["runs"] for s in to_T1),
                                  "iterations": sum(s["iterations"] for s in to_T1),
                                  "wall_time": sum(s["wall_time"] for s in to_T1),
                                  "cpu_time": sum(s["cpu_time"] for s in to_T1),
                                  "gradient_cpu_time": sum(s["gradient_cpu_time"] for s in to_T1),
                                  "failed_stages": sum(s["status"] != "solved" for s in to_T1)}

    with open(os.path.join(args.out, "summary.json"), "w") as f:
        json.dump(summary, f, indent=1)
    keys = list(runner.stages[0])
    write_csv(os.path.join(args.out, "stages.csv"), keys, [[s[k] for k in keys] for s in runner.stages])
    write_csv(os.path.join(args.out, "history.csv"), ["stage"] + list(mbdae.HISTORY_COLUMNS), runner.history)
    keys = list(sweep[1.0])
    write_csv(os.path.join(args.out, "sweep.csv"), ["T"] + keys,
              [[T] + [sweep[T].get(k, "") for k in keys] for T in sorted(sweep)])
    cols = ["t"] + ["%s_%s" % (k, m) for k in series for m in ("q1", "q2", "q3", "tau1", "tau2", "tau3")]
    t = series["quintic"]["t"]
    write_csv(os.path.join(args.out, "optimal.csv"), cols,
              [[t[i]] + [series[k][m][i] for k in series for m in ("q1", "q2", "q3", "tau1", "tau2", "tau3")]
               for i in range(len(t))])
    plot(series, sweep, args.out)
    print(json.dumps({k: summary[k] for k in ("losses_optimum", "energy_stage", "quintic", "loss_saving",
                                              "energy_saving", "to_loss_optimum", "totals")}, indent=1, default=str))


def plot_histories(series, styles, out, files, title):
    """Torques and angles against time, one panel per joint: files = (torques, angles)."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    for what, fname, unit in (("tau", files[0], "torque (N m)"), ("q", files[1], "angle (rad)")):
        fig, axes = plt.subplots(3, 1, figsize=(7, 7.5), sharex=True)
        for k, ax in enumerate(axes, 1):
            for key, (label, color, ls) in styles.items():
                s = series[key]
                ax.plot(s["t"], s["%s%d" % (what, k)], color=color, ls=ls, label=label)
            ax.set_ylabel("%s%d, %s" % (what, k, unit))
            ax.grid(alpha=0.3)
        axes[0].legend()
        axes[-1].set_xlabel("t (s)")
        axes[0].set_title(title)
        fig.tight_layout()
        fig.savefig(os.path.join(out, fname), dpi=110)
        plt.close(fig)


def plot(series, sweep, out):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    plot_histories(series, {"losses_optimum": ("loss-optimal", "C0", "-"), "quintic": ("quintic", "C1", "--")}, out,
                   ("torques.png", "angles.png"), "robot arm, rest to rest in T = 1 s, g = 9.81 m/s^2")
    Ts = sorted(T for T in sweep if "losses" in sweep[T])
    fig, axes = plt.subplots(1, 2, figsize=(10, 4))
    axes[0].plot(Ts, [sweep[T]["losses"] for T in Ts], "o-", label="loss-optimal")
    axes[0].plot(Ts, [sweep[T]["quintic_losses"] for T in Ts], "s--", label="quintic")
    axes[0].set_ylabel("losses, integral of sum tau^2 (N^2 m^2 s)")
    axes[1].plot(Ts, [sweep[T]["energy_of_loss_optimum"] for T in Ts], "o-", color="C0", label="loss-optimal")
    axes[1].plot(Ts, [sweep[T]["quintic_energy"] for T in Ts], "s--", color="C1", label="quintic")
    axes[1].set_ylabel("mechanical energy drawn (J)")
    for ax in axes:
        ax.set_xlabel("duration T (s)")
        ax.grid(alpha=0.3)
        ax.legend()
    fig.suptitle("optimal costs against the duration of the motion (g = 9.81 m/s^2)")
    fig.tight_layout()
    fig.savefig(os.path.join(out, "sweep.png"), dpi=110)
    plt.close(fig)


MBDAE_BIN = "build/mbdae"

if __name__ == "__main__":
    main()
