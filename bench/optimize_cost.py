#!/usr/bin/python3
"""Cost of `mbdae optimize` against the number of spline ordinates (issue 10, "What it
must show": an optimisation of 100 spline ordinates costs about as many forward runs as
Ipopt iterations, not 100 times more; and the gradient evaluations' share of the time).

Usage:
    /usr/bin/python3 bench/optimize_cost.py [--mbdae PATH] [--results DIR] [--keep DIR]
                                            [--quick] [--no-plot] [--commit TEXT]

--mbdae: the program (default $MBDAE, else build/mbdae). --results: where
optimize_cost.csv, optimize_cost.md and optimize_cost.png go (default bench/results next
to this script). --keep: write the generated model and problem files there and keep
them (default: a temporary directory, removed at the end). --quick: n = 10 and 30 only.

The problems (generated, one model file and one problem file per case):

- rotor: a rotor of inertia J = 0.5 on a revolute joint (no gravity) turned rest-to-rest
  by theta_f = 1 rad in T = 1 s by a torque tau(t), a natural cubic spline of n
  ordinates at uniform knots over [0, T], all zero at the start (the warm start);
  minimise integral tau^2 subject to final angle = theta_f and final speed = 0. Continuous
  optimum 12 J^2 theta_f^2 / T^3 = 3 (tau linear in t). n = 10, 30, 100, 300 with the
  adjoint; n = 10, 30, 100 also with forward sensitivities and central differences (fd).
- rotor_acc: the same rotor with the objective written as integral (J * angular
  acceleration)^2 (the same integral tau^2 for this model) instead of integral
  spline(tau, t)^2: the objective's integrand then does not use the spline, and its
  gradient reaches the ordinates only through the motion. This isolates the cost of
  differentiating an objective that uses the spline directly with respect to every
  ordinate at every step (which, at the program this was written for, rebuilds a tangent
  spline per ordinate and step: O(n^2) per step). Adjoint and forward for every n.
- damped rotor: the same with a viscous damper (torque -c * speed, c = 2, so c T / J =
  4): the optimum torque is a combination of exp(+-c t / J)-type functions, not in the
  spline space, so the optimum over n ordinates lies above the continuous one and
  approaches it as n grows (both computed in this script). Adjoint only.
- pendulum: a point mass m = 1 on a massless link L = 1 under gravity 9.81, hanging at
  rest, swung rest-to-rest by 2 rad in T = 2 s by a torque spline at the pivot
  (nonlinear: the gravity torque is m g L sin(angle)); minimise integral tau^2. No
  closed-form optimum: the table compares the methods and the values over n. Adjoint for
  every n, forward and fd for n = 10, 30.

HHT, fixed step 1e-3 s (1000 steps per run for the rotors, 2000 for the pendulum),
Ipopt tol 1e-10 (pendulum 1e-9), limited-memory Hessian (the driver's only choice).

The optimum over the spline space (the "spline optimum" columns): the torque is
tau = sum_i y_i B_i(t) with B_i the cardinal natural cubic splines of the knots (the
spline through the unit vector e_i, built here in numpy from the same tridiagonal
system mbs/spline.cc solves); the final speed and angle of a rotor are linear in y
(J w(T) = int k_w(t) tau dt, J theta(T) = int k_theta(t) tau dt with the damper's
kernels), and integral tau^2 = y' Q y with Q_ij = int B_i B_j dt. The equality-constrained
QP min y' Q y, A y = b is solved through its KKT system; the integrals by Gauss-Legendre
quadrature per knot interval (8 points: exact for the polynomials, to round-off for the
exponential kernels). The continuous optimum: b' G^-1 b with G the Gram matrix of the two
kernels (closed form). Neither involves the time discretisation: the difference between
mbdae's optimum and the spline optimum is that of the HHT scheme and the trapezoidal
quadrature of the objective (O(h^2)). As an independent check of the discrete side, the
model with the QP's ordinates is run once (`mbdae gradient`): its objective and
constraint values are the discretised ones at the spline optimum.

Each `mbdae optimize --json` gives iterations, runs (forward simulations), gradient
evaluations, gradient_cpu_time, cpu_time and wall_time. Also measured once per model:
one `mbdae gradient --wrt-splines --json` at the starting point with each method, whose
solver_cpu_time (the forward run) and gradient_cpu_time (what follows it) give the cost
of one gradient evaluation in forward runs.
"""
import argparse
import csv
import json
import math
import os
import shutil
import subprocess
import sys
import tempfile
import time

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)

ROTOR = dict(J=0.5, theta_f=1.0, T=1.0, c=0.0)
DAMPED = dict(J=0.5, theta_f=1.0, T=1.0, c=2.0)
PENDULUM = dict(m=1.0, L=1.0, g=9.81, theta_f=2.0, T=2.0)
STEP = 1.0e-3


# ---------------------------------------------------------------- model and problem files

def knots(n, T):
    return [T * i / (n - 1) for i in range(n)]


def fmt_list(values):
    return "[" + ", ".join(repr(float(v)) for v in values) + "]"


def rotor_model(n, p, acc_objective=False):
    """acc_objective: the energy objective written as integral (J * angular acceleration)^2
    (equal to integral tau^2 for the undamped rotor) instead of integral spline(tau, t)^2."""
    damper = ""
    if p["c"] > 0:
        damper = ('  - {name: damper, type: torque, i: rotor.cm, j: ground.O, frame: world, '
                  'value: [0, 0, "-%r*speed"]}\n' % p["c"])
    energy = "(%r*acc)^2" % p["J"] if acc_objective else "spline(tau, t)^2"
    return f"""# Generated by bench/optimize_cost.py: a rotor of inertia J = {p['J']} about z on a
# revolute joint, turned by a natural cubic torque spline of {n} ordinates over [0, {p['T']}]
# (all zero: the warm start){'' if p['c'] == 0 else ', against a viscous damper c = %r' % p['c']}.
format: 1
name: rotor{n}
gravity: [0, 0, 0]
splines:
  tau:
    x: {fmt_list(knots(n, p['T']))}
    y: {fmt_list([0.0] * n)}
    interpolation: cubic
bodies:
  - name: rotor
    mass: 1
    inertia: [1, 1, {p['J']!r}]
    position: [0, 0, 0]
measures:
  - {{name: angle, type: rotational, i: rotor.cm, j: ground.O, axis: z}}
  - {{name: speed, type: rotational, i: rotor.cm, j: ground.O, axis: z, quantity: angular_velocity}}
  - {{name: acc, type: rotational, i: rotor.cm, j: ground.O, axis: z, quantity: angular_acceleration}}
joints:
  - {{name: axle, type: revolute, i: rotor.cm, j: ground.O}}
forces:
  - {{name: motor, type: torque, i: rotor.cm, j: ground.O, frame: world, value: [0, 0, "spline(tau, t)"]}}
{damper}objectives:
  - {{name: energy, integral: "{energy}"}}
  - {{name: final_angle, terminal: "angle"}}
  - {{name: final_speed, terminal: "speed"}}
simulation: {{t_end: {p['T']!r}, output_step: 0.01, integrator: hht, hht: {{step: {STEP!r}}}}}
"""


def pendulum_model(n, p):
    return f"""# Generated by bench/optimize_cost.py: a point mass m = {p['m']} on a massless link
# L = {p['L']} (pivot at the origin, hanging in -y at rest), gravity {p['g']}, driven by a
# natural cubic torque spline of {n} ordinates over [0, {p['T']}] (all zero: the warm start).
format: 1
name: pendulum{n}
gravity: [0, {-p['g']!r}, 0]
splines:
  tau:
    x: {fmt_list(knots(n, p['T']))}
    y: {fmt_list([0.0] * n)}
    interpolation: cubic
bodies:
  - name: bob
    mass: {p['m']!r}
    inertia: [0, 0, 0]
    position: [0, {-p['L']!r}, 0]
    markers:
      pivot: {{position: [0, {p['L']!r}, 0]}}
measures:
  - {{name: angle, type: rotational, i: bob.pivot, j: ground.O, axis: z}}
  - {{name: speed, type: rotational, i: bob.pivot, j: ground.O, axis: z, quantity: angular_velocity}}
joints:
  - {{name: pivot, type: revolute, i: bob.pivot, j: ground.O}}
forces:
  - {{name: motor, type: torque, i: bob.cm, j: ground.O, frame: world, value: [0, 0, "spline(tau, t)"]}}
objectives:
  - {{name: energy, integral: "spline(tau, t)^2"}}
  - {{name: final_angle, terminal: "angle"}}
  - {{name: final_speed, terminal: "speed"}}
simulation: {{t_end: {p['T']!r}, output_step: 0.01, integrator: hht, hht: {{step: {STEP!r}}}}}
"""


def problem_file(model_name, theta_f, method, tol):
    return f"""# Generated by bench/optimize_cost.py: rest-to-rest turn by {theta_f} rad, minimum integral tau^2.
format: 1
model: {model_name}
variables:
  - {{spline: tau, lower: -100, upper: 100}}
minimize: energy
constraints:
  - {{objective: final_angle, equals: {theta_f!r}}}
  - {{objective: final_speed, equals: 0.0}}
ipopt: {{tol: {tol!r}, max_iter: 300}}
method: {method}
"""


# ---------------------------------------------------------------- the spline-space optimum

def natural_cubic_coefficients(x, y):
    """Per interval (y_i, b_i, c_i, d_i) of y_i + b s + c s^2 + d s^3, s = t - x_i:
    the natural cubic spline (second derivatives M from the tridiagonal system
    h_{i-1} M_{i-1} + 2 (h_{i-1} + h_i) M_i + h_i M_{i+1} = 6 (m_i - m_{i-1}), M_0 = M_n = 0)."""
    x = np.asarray(x, float)
    y = np.asarray(y, float)
    n = len(x) - 1
    h = np.diff(x)
    m = np.diff(y) / h
    M = np.zeros(n + 1)
    if n > 1:
        A = np.zeros((n - 1, n - 1))
        r = 6 * (m[1:] - m[:-1])
        for i in range(n - 1):
            A[i, i] = 2 * (h[i] + h[i + 1])
            if i > 0:
                A[i, i - 1] = h[i]
            if i < n - 2:
                A[i, i + 1] = h[i + 1]
        M[1:n] = np.linalg.solve(A, r)
    b = m - h * (2 * M[:-1] + M[1:]) / 6
    c = M[:-1] / 2
    d = (M[1:] - M[:-1]) / (6 * h)
    return y[:-1], b, c, d


def spline_basis_at(x, t_nodes_per_interval, s_nodes):
    """B[i, k, q]: cardinal spline i on interval k at local offset s_nodes[k, q]."""
    n = len(x)
    B = np.zeros((n, n - 1, s_nodes.shape[1]))
    for i in range(n):
        e = np.zeros(n)
        e[i] = 1
        a, b, c, d = natural_cubic_coefficients(x, e)
        s = s_nodes
        B[i] = a[:, None] + b[:, None] * s + c[:, None] * s**2 + d[:, None] * s**3
    return B


def rotor_kernels(t, p):
    """Kernels of J w(T) and J theta(T) over tau: J w' + c w = tau (w(0) = theta(0) = 0)."""
    J, c, T = p["J"], p["c"], p["T"]
    if c == 0:
        return np.ones_like(t), (T - t)
    a = c / J
    e = np.exp(-a * (T - t))
    return e, (1 - e) / a


def spline_optimum(n, p):
    """min int tau^2 over the natural cubic splines of n ordinates with J w(T) = 0,
    theta(T) = theta_f: (value, ordinates)."""
    x = np.array(knots(n, p["T"]))
    g, w = np.polynomial.legendre.leggauss(8)
    h = np.diff(x)
    s = (g[None, :] + 1) / 2 * h[:, None]            # local offsets, (n-1) x 8
    wt = w[None, :] / 2 * h[:, None]                 # weights
    t = x[:-1, None] + s
    B = spline_basis_at(x, None, s)                  # n x (n-1) x 8
    Q = np.einsum("ikq,jkq,kq->ij", B, B, wt)
    kw, kth = rotor_kernels(t, p)
    A = np.vstack([np.einsum("ikq,kq,kq->i", B, kw, wt),
                   np.einsum("ikq,kq,kq->i", B, kth, wt)]) / p["J"]
    b = np.array([0.0, p["theta_f"]])
    K = np.block([[2 * Q, A.T], [A, np.zeros((2, 2))]])
    sol = np.linalg.solve(K, np.concatenate([np.zeros(n), b]))
    y = sol[:n]
    return float(y @ Q @ y), y


def continuous_optimum(p):
    """b' G^-1 b, G the Gram matrix of the kernels of w(T) and theta(T) (closed form)."""
    J, c, T, th = p["J"], p["c"], p["T"], p["theta_f"]
    if c == 0:
        return 12 * J**2 * th**2 / T**3
    a = c / J
    # kernels over J: k1 = e(t) = exp(-a (T - t)), k2 = (1 - e) / a; u = T - t in [0, T]
    I_e = (1 - math.exp(-a * T)) / a                 # int e
    I_ee = (1 - math.exp(-2 * a * T)) / (2 * a)      # int e^2
    G11 = I_ee
    G12 = (I_e - I_ee) / a
    G22 = (T - 2 * I_e + I_ee) / a**2
    G = np.array([[G11, G12], [G12, G22]]) / J**2
    b = np.array([0.0, th])
    return float(b @ np.linalg.solve(G, b))


# ---------------------------------------------------------------- running mbdae

def loadavg():
    try:
        return os.getloadavg()[0]
    except OSError:
        return float("nan")


def run_json(cmd, cwd):
    load = loadavg()
    t0 = time.time()
    p = subprocess.run(cmd, cwd=cwd, capture_output=True, text=True)
    wall = time.time() - t0
    out = p.stdout.strip().splitlines()
    data = None
    for line in reversed(out):
        if line.startswith("{"):
            data = json.loads(line)
            break
    if data is None:
        sys.stderr.write(f"command failed (exit {p.returncode}): {' '.join(cmd)}\n{p.stderr[-2000:]}\n")
    return data, p.returncode, wall, load


def write_case(work, family, n, method):
    d = os.path.join(work, f"{family}_{n}")
    os.makedirs(d, exist_ok=True)
    model = os.path.join(d, "model.yaml")
    if not os.path.exists(model):
        if family == "pendulum":
            text = pendulum_model(n, PENDULUM)
        else:
            text = rotor_model(n, DAMPED if family == "damped" else ROTOR, family == "rotor_acc")
        with open(model, "w") as f:
            f.write(text)
    params = PENDULUM if family == "pendulum" else (DAMPED if family == "damped" else ROTOR)
    tol = 1e-9 if family == "pendulum" else 1e-10
    problem = os.path.join(d, f"problem_{method}.yaml")
    with open(problem, "w") as f:
        f.write(problem_file("model.yaml", params["theta_f"], method, tol))
    return d, model, problem


def model_with_ordinates(src, dst, y):
    lines = open(src).read().splitlines()
    out = []
    for line in lines:
        if line.startswith("    y: ["):
            line = "    y: " + fmt_list(y)
        out.append(line)
    with open(dst, "w") as f:
        f.write("\n".join(out) + "\n")


def cases(quick):
    c = []
    big = [10, 30] if quick else [10, 30, 100, 300]
    mid = [10, 30] if quick else [10, 30, 100]
    for n in big:
        c.append(("rotor", n, "adjoint"))
    for n in mid:
        c.append(("rotor", n, "forward"))
        c.append(("rotor", n, "fd"))
    for n in big:
        c.append(("rotor_acc", n, "adjoint"))
        c.append(("rotor_acc", n, "forward"))
    for n in mid:
        c.append(("damped", n, "adjoint"))
    for n in mid:
        c.append(("pendulum", n, "adjoint"))
    for n in [10, 30]:
        c.append(("pendulum", n, "forward"))
        c.append(("pendulum", n, "fd"))
    return c


FIELDS = ["problem", "n", "method", "status", "iterations", "gradient_evaluations", "runs",
          "runs_per_iteration", "failed_evaluations", "cpu_time", "gradient_cpu_time",
          "gradient_share", "gradient_cpu_per_evaluation", "wall_time", "objective", "constraint_violation",
          "continuous_optimum", "spline_optimum", "spline_optimum_discrete", "spline_optimum_miss",
          "rel_error_continuous", "rel_error_spline", "gradient_forward_runs", "loadavg"]


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--mbdae", default=os.environ.get("MBDAE", "build/mbdae"))
    ap.add_argument("--results", default=os.path.join(HERE, "results"))
    ap.add_argument("--keep", default=None)
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--no-plot", action="store_true")
    ap.add_argument("--commit", default=None,
                    help="the commit the program was built from, for the table's header "
                         "(default: HEAD of this checkout when the run starts)")
    a = ap.parse_args()
    commit = a.commit or (git_commit() + " (HEAD when the run started)")
    mbdae = os.path.abspath(a.mbdae)
    if not os.path.exists(mbdae):
        sys.exit(f"no program at {a.mbdae} (build it, or give --mbdae PATH or $MBDAE)")
    work = os.path.abspath(a.keep) if a.keep else tempfile.mkdtemp(prefix="optimize_cost_")
    os.makedirs(work, exist_ok=True)
    started = time.time()
    load_start = loadavg()
    rows = []
    spline_cache = {}
    try:
        for family, n, method in cases(a.quick):
            d, model, problem = write_case(work, family, n, method)
            # one gradient at the starting point: its cost in forward runs
            g, rc, _, _ = run_json([mbdae, "gradient", model, "--wrt-splines", "--method", method, "--json"], d)
            gfr = float("nan")
            if g and g.get("solver_cpu_time"):
                gfr = (g["solver_cpu_time"] + g["gradient_cpu_time"]) / g["solver_cpu_time"]
            r, rc, wall, load = run_json([mbdae, "optimize", problem, "--json", "-o",
                                          os.path.join(d, f"result_{method}.h5")], d)
            row = dict(problem=family, n=n, method=method, loadavg=round(load, 2),
                       gradient_forward_runs=gfr)
            if r is None:
                row["status"] = f"error (exit {rc})"
                rows.append(row)
                continue
            for k in ["status", "iterations", "gradient_evaluations", "runs", "failed_evaluations",
                      "cpu_time", "gradient_cpu_time", "wall_time", "objective", "constraint_violation"]:
                row[k] = r.get(k)
            row["runs_per_iteration"] = r["runs"] / max(r["iterations"], 1)
            row["gradient_cpu_per_evaluation"] = r["gradient_cpu_time"] / max(r["gradient_evaluations"], 1)
            row["gradient_share"] = r["gradient_cpu_time"] / r["cpu_time"] if r["cpu_time"] else float("nan")
            if family != "pendulum":
                p = DAMPED if family == "damped" else ROTOR
                if (family, n) not in spline_cache:
                    so, y = spline_optimum(n, p)
                    # the discretised objective at the spline optimum: one run of the model
                    qp_model = os.path.join(d, "model_spline_optimum.yaml")
                    model_with_ordinates(model, qp_model, y)
                    gq, _, _, _ = run_json([mbdae, "gradient", qp_model, "--wrt", "tau[0]", "--json"], d)
                    sd = miss = float("nan")
                    if gq:
                        o = gq["objectives"]
                        sd = o["energy"]["value"]
                        miss = max(abs(o["final_angle"]["value"] - p["theta_f"]), abs(o["final_speed"]["value"]))
                    spline_cache[(family, n)] = (so, sd, miss)
                so, sd, miss = spline_cache[(family, n)]
                row["spline_optimum_miss"] = miss
                co = continuous_optimum(p)
                row.update(continuous_optimum=co, spline_optimum=so, spline_optimum_discrete=sd,
                           rel_error_continuous=(r["objective"] - co) / co,
                           rel_error_spline=(r["objective"] - so) / so)
            rows.append(row)
            print(f"{family:9s} n={n:4d} {method:8s} {row['status']:7s} it={row['iterations']:4d} "
                  f"runs={row['runs']:6d} grads={row['gradient_evaluations']:4d} "
                  f"cpu={row['cpu_time']:8.2f}s share={100 * row['gradient_share']:5.1f}% "
                  f"f={row['objective']:.10g} load={load:.2f}", flush=True)
    finally:
        if not a.keep:
            shutil.rmtree(work, ignore_errors=True)
    elapsed = time.time() - started
    load_end = loadavg()
    os.makedirs(a.results, exist_ok=True)
    write_csv(os.path.join(a.results, "optimize_cost.csv"), rows)
    write_md(os.path.join(a.results, "optimize_cost.md"), rows, commit, elapsed, load_start, load_end,
             a.quick)
    if not a.no_plot:
        plot(os.path.join(a.results, "optimize_cost.png"), rows)
    print(f"wrote {a.results}/optimize_cost.csv, .md" + ("" if a.no_plot else ", .png") +
          f" ({elapsed:.0f} s)")


def git_commit():
    try:
        return subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=ROOT, capture_output=True,
                              text=True).stdout.strip() or "unknown"
    except OSError:
        return "unknown"


def write_csv(path, rows):
    with open(path, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=FIELDS)
        w.writeheader()
        for r in rows:
            w.writerow({k: r.get(k, "") for k in FIELDS})


def g(v, spec):
    if v is None or v == "" or (isinstance(v, float) and math.isnan(v)):
        return "-"
    return format(v, spec)


def per_eval_ms(r):
    if not r.get("gradient_evaluations"):
        return None
    return 1000 * r["gradient_cpu_time"] / r["gradient_evaluations"]


def write_md(path, rows, commit, elapsed, load_start, load_end, quick):
    L = []
    L.append("# mbdae optimize: cost against the number of spline ordinates")
    L.append("")
    L.append(f"Written by `bench/optimize_cost.py` (program built at {commit}; {elapsed:.0f} s in all; "
             f"{os.cpu_count()} cores, load average {load_start:.1f} at the start, {load_end:.1f} "
             "at the end, the machine shared: CPU times are noisy, the counts are not)."
             + (" Quick run (n = 10, 30 only)." if quick else ""))
    L.append("")
    L.append("Problems, method, what is measured: the script's docstring and `bench/README.md`. "
             "runs = forward simulations (a central-difference gradient runs 1 + 2n); "
             "runs/it = runs per Ipopt iteration; grad share = gradient_cpu_time / cpu_time; "
             "grad CPU per eval. = gradient_cpu_time / gradient evaluations; "
             "grad cost = one gradient evaluation (forward run and what follows it, "
             "`mbdae gradient --wrt-splines` at the starting point) in forward runs.")
    L.append("")
    L.append("| problem | n | method | status | iterations | gradient evaluations | runs | runs/it "
             "| grad cost (runs) | CPU s | grad CPU per eval. ms | grad share | wall s | objective | violation |")
    L.append("| --- | ---: | --- | --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |")
    for r in rows:
        L.append(f"| {r['problem']} | {r['n']} | {r['method']} | {r.get('status', '-')} | "
                 f"{r.get('iterations', '-')} | {r.get('gradient_evaluations', '-')} | {r.get('runs', '-')} | "
                 f"{g(r.get('runs_per_iteration'), '.2f')} | {g(r.get('gradient_forward_runs'), '.2f')} | "
                 f"{g(r.get('cpu_time'), '.2f')} | {g(per_eval_ms(r), '.1f')} | {g(100 * r['gradient_share'] if r.get('gradient_share') is not None else None, '.1f')} % | "
                 f"{g(r.get('wall_time'), '.2f')} | {g(r.get('objective'), '.10g')} | "
                 f"{g(r.get('constraint_violation'), '.1e')} |")
    L.append("")
    L.append("Optimum against the known values (rotors): continuous = the continuous problem's "
             "minimum (12 J^2 theta_f^2 / T^3 = 3 undamped; b' G^-1 b damped); spline = the minimum "
             "over the natural cubic splines of n ordinates (QP in numpy, no time discretisation); "
             "spline run = the objective mbdae computes for the spline optimum's ordinates (one run, "
             "HHT step 1e-3).")
    L.append("")
    L.append("| problem | n | method | objective | continuous | spline | rel. error vs continuous "
             "| rel. error vs spline | spline run | spline run's constraint miss |")
    L.append("| --- | ---: | --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: |")
    for r in rows:
        if r["problem"] == "pendulum" or r.get("objective") is None:
            continue
        L.append(f"| {r['problem']} | {r['n']} | {r['method']} | {g(r['objective'], '.10g')} | "
                 f"{g(r['continuous_optimum'], '.10g')} | {g(r['spline_optimum'], '.10g')} | "
                 f"{g(r['rel_error_continuous'], '.2e')} | {g(r['rel_error_spline'], '.2e')} | "
                 f"{g(r['spline_optimum_discrete'], '.10g')} | {g(r['spline_optimum_miss'], '.1e')} |")
    L.append("")
    with open(path, "w") as f:
        f.write("\n".join(L))


def plot(path, rows):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(1, 2, figsize=(11.5, 4.5))
    series = [("rotor", "adjoint", "o-", "C0", "rotor, adjoint"),
              ("rotor", "forward", "s--", "C1", "rotor, forward sens."),
              ("rotor", "fd", "^:", "C3", "rotor, central differences"),
              ("rotor_acc", "adjoint", "o-", "C2", "rotor (acc. objective), adjoint"),
              ("rotor_acc", "forward", "s--", "C4", "rotor (acc. objective), forward sens.")]
    for problem, method, st, col, label in series:
        sel = [r for r in rows if r["problem"] == problem and r["method"] == method and r.get("runs")]
        if not sel:
            continue
        n = [r["n"] for r in sel]
        ax[0].loglog(n, [r["runs"] for r in sel], st, color=col, label=label + ": runs")
        ax[1].loglog(n, [r["cpu_time"] for r in sel], st, color=col, label=label)
    sel = [r for r in rows if r["problem"] == "rotor" and r["method"] == "adjoint" and r.get("runs")]
    if sel:
        ax[0].loglog([r["n"] for r in sel], [r["iterations"] for r in sel], "x-", color="k", alpha=0.6,
                     label="rotor, adjoint: Ipopt iterations")
    ax[0].set_xlabel("spline ordinates n")
    ax[0].set_ylabel("forward runs in the whole optimisation")
    ax[0].set_title("forward runs (counts)")
    ax[1].set_xlabel("spline ordinates n")
    ax[1].set_ylabel("CPU time of mbdae optimize [s]")
    ax[1].set_title("CPU time (shared 2-core machine)")
    for a_ in ax:
        a_.grid(True, which="both", alpha=0.3)
        a_.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=110)


if __name__ == "__main__":
    main()
