#!/usr/bin/python3
"""Loss-optimal rest-to-rest motion of the robot arm (arm.yaml) with scipy.optimize.

    PYTHONPATH=build/python /usr/bin/python3 examples/robot_energy/optimize_scipy.py

Minimises the electrical losses (integral of tau1^2 + tau2^2 + tau3^2) over the 33
ordinates of the three joint-torque splines of arm.yaml, subject to the six equality
constraints final_q1..final_q3 (angle errors at T) and final_w1..final_w3 (angular
velocities at T), starting from zero torque. Values and exact gradients come from the
model through mbdae's Python package (Model.objective_function: one HHT run plus the
discrete adjoint per new point, shared by the cost and every constraint). Then it runs
quintic.yaml (the naive quintic-polynomial motion between the same poses, torques from
the reactions of its motion joints) and reports the saving.

Writes into the folder scipy/ (or --out): torques.png and angles.png (optimal against quintic),
optimal_torques.csv (t and the optimal ordinates), history_scipy.csv (one row per
optimiser iteration) and summary_scipy.json (the numbers of README.md).
"""
import argparse
import json
import os
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
SPLINES = ("tau1", "tau2", "tau3")
CONSTRAINTS = ("final_q1", "final_q2", "final_q3", "final_w1", "final_w2", "final_w3")
# The costs motor by motor (arm.yaml): their sums are `losses` and `energy`. The program
# of this release crashes on the ordinate gradient of an objective that calls several
# splines (README.md, "Problems found"), so the script sums per-motor objectives.
PARTS = {"losses": ("loss1", "loss2", "loss3"), "energy": ("energy1", "energy2", "energy3")}


class Sum:
    """The sum of objective functions sharing one model's runs (fun and jac)."""

    def __init__(self, functions):
        self.functions = functions

    def __call__(self, x):
        return sum(f(x) for f in self.functions)

    def jac(self, x):
        return sum(f.jac(x) for f in self.functions)


def run_objectives(model):
    """The model's objective values at its current point and the measures of a solve."""
    # The values of a gradient run with respect to the payload mass (a cheap gradient;
    # Model.solve() gives no objective values, the results file of Model.gradient does).
    values = model.gradient(wrt=["mp"]).values
    model.solve()
    out = model.outputs
    series = {"t": np.array(out.time)}
    for name in model.measures:
        series[name] = np.array(out.measure(name))
    return values, series


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--method", default="SLSQP", choices=["SLSQP", "trust-constr"])
    ap.add_argument("--cost", default="losses", choices=sorted(PARTS),
                    help="the objective to minimise (default losses)")
    ap.add_argument("--maxiter", type=int, default=200)
    ap.add_argument("--bound", type=float, default=40.0,
                    help="bounds -B <= ordinate <= B in N m (default 40, as problem.yaml)")
    ap.add_argument("--tol", type=float, default=1e-8,
                    help="SLSQP ftol / trust-constr gtol and xtol (default 1e-8)")
    ap.add_argument("--gravity", type=float, default=None,
                    help="set the model's parameter g (m/s^2; default: the file's 9.81)")
    ap.add_argument("--out", default=os.path.join(HERE, "scipy"), help="folder of the figures and files")
    args = ap.parse_args()
    os.makedirs(args.out, exist_ok=True)

    print("mbdae library: %s; scipy %s; numpy %s" % (mbdae.library_path, scipy.__version__,
                                                     np.__version__))
    try:
        load = os.getloadavg()
        print("load average at start: %.2f %.2f %.2f (%d cores)" % (load + (os.cpu_count(),)))
    except OSError:
        load = None

    # --- the naive motion: quintic polynomials, torques from the motion joints' reactions
    with mbdae.Model(os.path.join(HERE, "quintic.yaml")) as q:
        if args.gravity is not None:
            q.parameters["g"] = args.gravity
        quintic, quintic_series = run_objectives(q)
    print("quintic motion: losses %.6g N^2 m^2 s, energy %.6g J" % (quintic["losses"],
                                                                      quintic["energy"]))

    with mbdae.Model(os.path.join(HERE, "arm.yaml")) as m:
        if args.gravity is not None:
            m.parameters["g"] = args.gravity
        wrt = [w for s in SPLINES for w in m.spline_ordinates(s)]
        t_knots = np.array(m.splines[SPLINES[0]][0])
        first = m.objective_function(PARTS[args.cost][0], wrt)
        cost = Sum([first] + [first.for_objective(n) for n in PARTS[args.cost][1:]])
        cons = [first.for_objective(n) for n in CONSTRAINTS]
        x0 = np.zeros(len(wrt))  # zero torque (arm.yaml's ordinates)
        bounds = scipy.optimize.Bounds(-args.bound * np.ones(len(wrt)), args.bound * np.ones(len(wrt)))

        history = []  # one row per iteration: cost, largest constraint violation

        def record(x, *unused):
            history.append((len(history) + 1, cost(x), max(abs(c(x)) for c in cons),
                            first.runs))
            k, fx, viol, runs = history[-1]
            print("  iteration %3d  %s %.8g  max|constraint| %.3e  runs %d"
                  % (k, args.cost, fx, viol, runs), flush=True)

        start = time.perf_counter()
        cpu_start = time.process_time()
        if args.method == "SLSQP":
            constraints = [{"type": "eq", "fun": c, "jac": c.jac} for c in cons]
            r = scipy.optimize.minimize(cost, x0, jac=cost.jac, method="SLSQP",
                                        bounds=bounds, constraints=constraints, callback=record,
                                        options={"maxiter": args.maxiter, "ftol": args.tol})
        else:
            def cfun(x):
                return np.array([c(x) for c in cons])

            def cjac(x):
                return np.array([c.jac(x) for c in cons])

            constraint = scipy.optimize.NonlinearConstraint(cfun, 0.0, 0.0, jac=cjac,
                                                            hess=scipy.optimize.BFGS())
            r = scipy.optimize.minimize(cost, x0, jac=cost.jac, method="trust-constr",
                                        hess=scipy.optimize.BFGS(), constraints=[constraint],
                                        bounds=bounds,
                                        callback=lambda x, state: record(x),
                                        options={"maxiter": args.maxiter, "gtol": args.tol,
                                                 "xtol": args.tol})
        wall = time.perf_counter() - start
        cpu = time.process_time() - cpu_start
        runs = first.runs
        njev = getattr(r, "njev", None)
        print(r)

        # --- the optimum: one more run for the values and the curves
        first.set(r.x)
        optimum, series = run_objectives(m)
        violation = max(abs(optimum[n]) for n in CONSTRAINTS)
        tau = {s: np.array(m.splines[s][1]) for s in SPLINES}
        t_fine = series["t"]

    saving = {k: 1 - optimum[k] / quintic[k] for k in ("losses", "energy")}
    # the last point when the optimiser did not converge: not an optimum, no saving
    label = "optimal" if r.success else "last iterate (NOT converged, infeasible)"
    print()
    print("method %s: %s (success %s)" % (args.method, r.message, r.success))
    print("iterations %d, function evaluations %d, gradient evaluations %s, model runs %d"
          % (r.nit, r.nfev, njev, runs))
    print("wall time %.1f s (CPU %.1f s)" % (wall, cpu))
    print("%s: losses %.6g, energy %.6g, max |constraint| %.2e"
          % (label, optimum["losses"], optimum["energy"], violation))
    print("quintic: losses %.6g, energy %.6g" % (quintic["losses"], quintic["energy"]))
    if r.success:
        print("saving against the quintic motion: losses %.1f %%, energy %.1f %%"
              % (100 * saving["losses"], 100 * saving["energy"]))

    os.makedirs(args.out, exist_ok=True)
    # --- files
    with open(os.path.join(args.out, "optimal_torques.csv"), "w") as f:
        f.write("# optimal torque ordinates (N m) of arm.yaml's splines, minimising %s with %s\n"
                % (args.cost, args.method))
        f.write("t,tau1,tau2,tau3\n")
        for i, t in enumerate(t_knots):
            f.write("%.6g,%.12g,%.12g,%.12g\n" % (t, tau["tau1"][i], tau["tau2"][i], tau["tau3"][i]))
    with open(os.path.join(args.out, "history_scipy.csv"), "w") as f:
        f.write("iteration,%s,max_abs_constraint,runs\n" % args.cost)
        for row in history:
            f.write("%d,%.12g,%.6e,%d\n" % row)
    summary = {
        "method": args.method, "cost": args.cost, "success": bool(r.success),
        "message": str(r.message), "iterations": int(r.nit), "function_evaluations": int(r.nfev),
        "gradient_evaluations": None if njev is None else int(njev), "model_runs": int(runs),
        "wall_time_s": wall, "cpu_time_s": cpu,
        "load_average_at_start": None if load is None else list(load),
        "optimal": {k: optimum[k] for k in ("losses", "energy")},
        "max_abs_constraint": violation,
        "quintic": {k: quintic[k] for k in ("losses", "energy")},
        "saving": saving if r.success else None, "scipy": scipy.__version__,
        "gravity": args.gravity if args.gravity is not None else 9.81,
    }
    with open(os.path.join(args.out, "summary_scipy.json"), "w") as f:
        json.dump(summary, f, indent=2)
        f.write("\n")

    # --- figures
    fig, axes = plt.subplots(3, 1, figsize=(7, 7.5), sharex=True)
    for k, ax in enumerate(axes):
        name = SPLINES[k]
        ax.plot(t_fine, _spline_values(t_knots, tau[name], t_fine), "C0",
                label="%s (%s, %s)" % (label, args.cost, args.method))
        ax.plot(t_knots, tau[name], "C0o", ms=4)
        ax.plot(quintic_series["t"], quintic_series[name], "C1--", label="quintic motion")
        ax.set_ylabel("%s (N m)" % name)
        ax.grid(True, alpha=0.3)
    axes[0].legend(loc="best", fontsize=8)
    axes[0].set_title("joint torques: %s %.4g (%s) vs %.4g (quintic)"
                      % (args.cost, optimum[args.cost], label.split(" (")[0], quintic[args.cost]))
    axes[-1].set_xlabel("t (s)")
    fig.tight_layout()
    fig.savefig(os.path.join(args.out, "torques.png"), dpi=110)
    plt.close(fig)

    fig, axes = plt.subplots(3, 1, figsize=(7, 7.5), sharex=True)
    for k, ax in enumerate(axes):
        name = "q%d" % (k + 1)
        ax.plot(t_fine, series[name], "C0", label=label)
        ax.plot(quintic_series["t"], quintic_series[name], "C1--", label="quintic motion")
        ax.set_ylabel("%s (rad)" % name)
        ax.grid(True, alpha=0.3)
    axes[0].legend(loc="best", fontsize=8)
    axes[0].set_title("joint angles, rest to rest in T = %.3g s" % t_knots[-1])
    axes[-1].set_xlabel("t (s)")
    fig.tight_layout()
    fig.savefig(os.path.join(args.out, "angles.png"), dpi=110)
    plt.close(fig)
    return 0 if r.success else 1


def _spline_values(x, y, t):
    """The natural cubic spline through (x, y) at t (as arm.yaml's `interpolation: cubic`)."""
    from scipy.interpolate import CubicSpline
    return CubicSpline(x, y, bc_type="natural")(t)


if __name__ == "__main__":
    sys.exit(main())
