#!/usr/bin/python3
"""The motion of the robot arm (arm.yaml) that draws the least mechanical energy, by Ipopt.

    PYTHONPATH=build/python /usr/bin/python3 examples/robot_energy/energy_ipopt.py [--T 1.0] [--sweep 0.7,0.85,1.2]

Minimises energy_reg = energy + rho losses (rho = 0.01; energy = integral of sum
smax(tau_k w_k), smax(P) = (P + sqrt(P^2 + eps^2)) / 2) subject to the rest-to-rest
terminal conditions, by `mbdae.optimize_string` (the solver of `mbdae optimize`) with

- multiple shooting over 5 intervals (problem_energy.yaml has the same problem as a file);
- Ipopt's exact-Hessian mode (`hessian_approximation: exact`: the Lagrangian's Hessian
  from differences of the adjoint gradients). With the limited-memory Hessian the same
  problem stalls (README.md has the measured runs);
- a continuation in the smoothing eps: 2, 1, 0.5, 0.2, 0.1 W, each stage starting from the
  last (ordinates and node states). The kink of max(P, 0) is what the quasi-Newton
  iteration could not resolve; eps = 2 W is smooth enough to converge in a few Newton
  steps, and each halving starts close to its solution;
- the start: the quintic motion of quintic.yaml (its motor torques at the spline knots,
  from `mbdae simulate quintic.yaml`; its angles and rates at the nodes, in closed form).
  --from-loss-optimum starts instead from the loss optimum in summary.json (T = 1 s only;
  the nodes then come from a forward sweep).

At every T the quintic motion is also run (its energy and losses are the comparison).
Writes energy_summary.json, energy_stages.csv, energy_history.csv, energy_optimal.csv,
energy_torques.png, energy_angles.png and energy_sweep.png into this folder (or --out).
"""
import argparse
import json
import os
import subprocess
import tempfile
import time

import h5py
import numpy as np
import scipy.interpolate

import mbdae
from optimize_ipopt import plot_histories, write_csv  # this folder

HERE = os.path.dirname(os.path.abspath(__file__))
SPLINES = ("tau1", "tau2", "tau3")
N = 11           # ordinates per torque spline, at t_k = k T / 10
INTERVALS = 5    # shooting intervals
STATES = (("q1_0", "q1"), ("q2_0", "q2"), ("q3_0", "q3"), ("w1_0", "w1"), ("w2_0", "w2"), ("w3_0", "w3"))
CONSTRAINTS = ("final_q1", "final_q2", "final_q3", "final_w1", "final_w2", "final_w3")
POSE_0 = (0.0, 0.3, -1.2)  # arm.yaml's poses (rad)
POSE_T = (1.5, 0.9, -0.3)
G_EARTH = 9.81
BOUND = 40.0               # N m, every ordinate
EPS_STEPS = (2.0, 1.0, 0.5, 0.2, 0.1)
MAX_ITER = 60              # per stage (measured: 7 to 10 at T = 1 s)


def quintic_nodes(T):
    """Angles and rates of the quintic motion at the nodes t = k T / 5, k = 1..4."""
    s = np.arange(1, INTERVALS) / INTERVALS
    shape, rate = 10 * s**3 - 15 * s**4 + 6 * s**5, (30 * s**2 - 60 * s**3 + 30 * s**4) / T
    nodes = {}
    for k in range(3):
        d = POSE_T[k] - POSE_0[k]
        nodes["q%d_0" % (k + 1)] = (POSE_0[k] + d * shape).tolist()
        nodes["w%d_0" % (k + 1)] = (d * rate).tolist()
    return nodes


def problem_text(T, eps, start, nodes):
    lines = ["format: 1", "model: arm.yaml", "parameters: {g: %r, T: %r, eps: %r}" % (G_EARTH, T, eps), "variables:"]
    for s in SPLINES:
        lines.append("  - {spline: %s, lower: %r, upper: %r, start: [%s]}"
                     % (s, -BOUND, BOUND, ", ".join(repr(float(v)) for v in start[s])))
    lines.append("minimize: energy_reg")
    lines.append("constraints:")
    lines += ["  - {objective: %s, equals: 0}" % c for c in CONSTRAINTS]
    lines.append("simulation: {integrator: hht, hht: {step: 1.0e-3}}")
    lines.append("ipopt: {tol: 1.0e-8, max_iter: %d, hessian_approximation: exact}" % MAX_ITER)
    lines.append("shooting:")
    lines.append("  intervals: %d" % INTERVALS)
    lines.append("  time: t0")
    lines.append("  state:")
    for p, m in STATES:
        extra = "" if nodes is None else ", start: [%s]" % ", ".join(repr(float(v)) for v in nodes[p])
        lines.append("    - {parameter: %s, measure: %s%s}" % (p, m, extra))
    return "\n".join(lines) + "\n"


def quintic_run(T, workdir):
    """The quintic motion at T: its costs, its torques at the knots, its results file."""
    out = os.path.join(workdir, "quintic_%g.h5" % T)
    subprocess.run([MBDAE_BIN, "simulate", os.path.join(HERE, "quintic.yaml"), "--set", "T=%r" % T,
                    "-o", out, "--quiet"], check=True)
    with h5py.File(out) as f:
        t = f["/time"][()]
        knots = np.linspace(0, T, N)
        torques = {s: np.interp(knots, t, f["/measures/" + s][()]) for s in SPLINES}
        costs = {k: float(f["/objectives/" + k].attrs["value"]) for k in ("losses", "energy")}
    return costs, torques, out


def trapz(y, t):
    return float(np.sum(0.5 * (y[1:] + y[:-1]) * np.diff(t)))


class Runner:
    def __init__(self, workdir):
        self.workdir, self.stages, self.history, self.count = workdir, [], [], 0

    def solve(self, T, eps, start, nodes, what):
        self.count += 1
        results = os.path.join(self.workdir, "energy%03d.h5" % self.count)
        t0 = time.time()
        r = mbdae.optimize_string(problem_text(T, eps, start, nodes), name=os.path.join(HERE, "energy-stage.yaml"),
                                  results=results)
        wall = time.time() - t0
        with h5py.File(results) as f:
            costs = {k: float(f["/objectives/" + k].attrs["value"]) for k in ("energy", "losses", "energy_reg")}
        row = {"stage": self.count, "what": what, "T": T, "eps": eps, "status": r.status,
               "energy_reg": r.objective, "energy": costs["energy"], "losses": costs["losses"],
               "violation": r.constraint_violation, "shooting_defect": r.shooting_defect,
               "iterations": r.iterations, "gradient_evaluations": r.gradient_evaluations,
               "hessian_evaluations": r.hessian_evaluations, "gradient_cpu_time": r.gradient_cpu_time,
               "cpu_time": r.cpu_time, "wall_time": wall}
        self.stages.append(row)
        for h in r.history:
            self.history.append([self.count] + [float(v) for v in h])
        print("stage %2d %-22s T = %-5.3g eps = %-4.3g %-7s energy_reg = %-11.7g energy %.5f J, losses %.4f, "
              "violation %.1e, defect %.1e, %2d iterations, %5.1f s"
              % (self.count, what, T, eps, r.status, r.objective, costs["energy"], costs["losses"],
                 r.constraint_violation, r.shooting_defect, r.iterations, wall), flush=True)
        x = {s: np.array([r.variables["%s[%d]" % (s, k)] for k in range(N)]) for s in SPLINES}
        nodes = {p: [r.variables["%s@%d" % (p, k)] for k in range(1, INTERVALS)] for p, _ in STATES}
        return r, x, nodes, results


def energy_optimum(runner, T, start, nodes, what):
    """The continuation in eps from (start, nodes); the last stage's result."""
    for eps in EPS_STEPS:
        r, start, nodes, results = runner.solve(T, eps, start, nodes, what)
        if not r.solved:
            return r, start, results, eps
    return r, start, results, None


def main():
    global MBDAE_BIN
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--mbdae", default=os.environ.get("MBDAE", "build/mbdae"), help="the mbdae program (quintic runs)")
    ap.add_argument("--out", default=HERE, help="where the tables and figures go")
    ap.add_argument("--T", type=float, default=1.0, help="the duration of the main result (s)")
    ap.add_argument("--sweep", default="0.7,0.85,1.2", help="further durations T ('' for none)")
    ap.add_argument("--from-loss-optimum", action="store_true",
                    help="also start at T = 1 s from the loss optimum of summary.json")
    args = ap.parse_args()
    MBDAE_BIN = args.mbdae
    os.makedirs(args.out, exist_ok=True)
    work = tempfile.mkdtemp(prefix="robot_energy_")
    runner = Runner(work)
    t_start = time.time()

    results_at, sweep = {}, {}
    Ts = [args.T] + sorted(float(v) for v in args.sweep.split(",") if v.strip())
    for T in Ts:
        quintic, q_torques, q_h5 = quintic_run(T, work)
        t1 = time.time()
        r, x, res, failed_eps = energy_optimum(runner, T, q_torques, quintic_nodes(T), "from the quintic motion")
        with h5py.File(res) as f:
            costs = {k: float(f["/objectives/" + k].attrs["value"]) for k in ("energy", "losses", "energy_reg")}
        mine = [s for s in runner.stages if s["T"] == T]
        sweep[T] = {"status": "solved" if failed_eps is None else "failed at eps = %g" % failed_eps,
                    "energy": costs["energy"], "losses": costs["losses"], "energy_reg": costs["energy_reg"],
                    "violation": r.constraint_violation, "shooting_defect": r.shooting_defect,
                    "quintic_energy": quintic["energy"], "quintic_losses": quintic["losses"],
                    "saving": 1 - costs["energy"] / quintic["energy"],
                    "iterations": sum(s["iterations"] for s in mine), "wall_time": time.time() - t1,
                    "cpu_time": sum(s["cpu_time"] for s in mine),
                    "gradient_cpu_time": sum(s["gradient_cpu_time"] for s in mine)}
        results_at[T] = (x, res, q_h5)

    summary = {"model": "arm.yaml", "g": G_EARTH, "rho": 0.01, "eps_steps": list(EPS_STEPS),
               "intervals": INTERVALS, "sweep": {("%g" % T): sweep[T] for T in sorted(sweep)}}
    if args.from_loss_optimum:
        with open(os.path.join(HERE, "summary.json")) as f:
            loss = json.load(f)["losses_optimum"]["torques"]
        r, x, res, failed_eps = energy_optimum(runner, 1.0, {s: np.array(loss[s]) for s in SPLINES}, None,
                                               "from the loss optimum")
        with h5py.File(res) as f:
            costs = {k: float(f["/objectives/" + k].attrs["value"]) for k in ("energy", "losses", "energy_reg")}
        summary["from_loss_optimum"] = {"status": "solved" if failed_eps is None else "failed at eps = %g" % failed_eps,
                                        **costs, "violation": r.constraint_violation,
                                        "shooting_defect": r.shooting_defect}

    # The main result's time histories: energy-optimal against quintic, and the unsmoothed
    # energy drawn, integral of sum max(tau w, 0), from the rows.
    x, res, q_h5 = results_at[args.T]
    series = {}
    for key, path in (("energy_optimum", res), ("quintic", q_h5)):
        with h5py.File(path) as f:
            t = f["/time"][()]
            series[key] = {"t": t, **{m: f["/measures/" + m][()] for m in ("q1", "q2", "q3", "w1", "w2", "w3")}}
            if key == "quintic":
                for k in (1, 2, 3):
                    series[key]["tau%d" % k] = f["/measures/tau%d" % k][()]
    for k, s in enumerate(SPLINES, 1):
        spline = scipy.interpolate.CubicSpline(np.linspace(0, args.T, N), x[s], bc_type="natural")
        series["energy_optimum"]["tau%d" % k] = spline(series["energy_optimum"]["t"])
    for key, s in series.items():
        power = [s["tau%d" % k] * s["w%d" % k] for k in (1, 2, 3)]
        s["drawn"] = trapz(sum(np.maximum(p, 0) for p in power), s["t"])
        s["net"] = trapz(sum(power), s["t"])
    summary["main"] = {"T": args.T, "energy_optimum_torques": {s: x[s].tolist() for s in SPLINES},
                       "unsmoothed_energy_drawn_rows": {k: series[k]["drawn"] for k in series},
                       "net_work_rows": {k: series[k]["net"] for k in series}}
    summary["stages"] = runner.stages
    summary["totals"] = {"optimisations": len(runner.stages), "iterations": sum(s["iterations"] for s in runner.stages),
                         "gradient_evaluations": sum(s["gradient_evaluations"] for s in runner.stages),
                         "gradient_cpu_time": sum(s["gradient_cpu_time"] for s in runner.stages),
                         "cpu_time": sum(s["cpu_time"] for s in runner.stages), "wall_time": time.time() - t_start}

    with open(os.path.join(args.out, "energy_summary.json"), "w") as f:
        json.dump(summary, f, indent=1)
    keys = list(runner.stages[0])
    write_csv(os.path.join(args.out, "energy_stages.csv"), keys, [[s[k] for k in keys] for s in runner.stages])
    write_csv(os.path.join(args.out, "energy_history.csv"), ["stage"] + list(mbdae.HISTORY_COLUMNS), runner.history)
    cols = ["t"] + ["%s_%s" % (k, m) for k in series for m in ("q1", "q2", "q3", "tau1", "tau2", "tau3")]
    t = series["quintic"]["t"]
    write_csv(os.path.join(args.out, "energy_optimal.csv"), cols,
              [[t[i]] + [series[k][m][i] for k in series for m in ("q1", "q2", "q3", "tau1", "tau2", "tau3")]
               for i in range(len(t))])
    plot(series, sweep, args.out)
    print(json.dumps({k: summary[k] for k in ("sweep", "main", "totals") + (("from_loss_optimum",) if
                                                                            args.from_loss_optimum else ())},
                     indent=1, default=str))


def plot(series, sweep, out):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    plot_histories(series, {"energy_optimum": ("energy-optimal", "C2", "-"), "quintic": ("quintic", "C1", "--")}, out,
                   ("energy_torques.png", "energy_angles.png"), "robot arm, least mechanical energy drawn, g = 9.81 m/s^2")
    Ts = sorted(T for T in sweep if sweep[T]["status"] == "solved")
    fig, ax = plt.subplots(figsize=(6, 4))
    ax.plot(Ts, [sweep[T]["energy"] for T in Ts], "o-", color="C2", label="energy-optimal (eps = 0.1 W)")
    ax.plot(sorted(sweep), [sweep[T]["quintic_energy"] for T in sorted(sweep)], "s--", color="C1", label="quintic")
    ax.axhline(6.2338, color="k", lw=0.8, ls=":", label="rise of potential energy (lower bound)")
    ax.set_xlabel("duration T (s)")
    ax.set_ylabel("mechanical energy drawn (J)")
    ax.grid(alpha=0.3)
    ax.legend()
    fig.tight_layout()
    fig.savefig(os.path.join(out, "energy_sweep.png"), dpi=110)
    plt.close(fig)


MBDAE_BIN = "build/mbdae"

if __name__ == "__main__":
    main()
