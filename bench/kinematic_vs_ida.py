#!/usr/bin/env python3
"""Kinematic analysis against IDA on a model without degrees of freedom, side by side.

The 3-axis arm of tests/app/models/arm_motion.yaml (three motion joints, quintic
rest-to-rest motions) over T = t_end = 2 s, 201 output rows:

- `--integrator kinematic`;
- `--integrator ida` at rtol = atol = 1e-6, 1e-8 (the model's setting and the issue's
  run), 1e-10, 1e-12;
- `--integrator hht` at its default step 1e-3 (alpha = -0.1, the consistent start).

Every run is `mbdae simulate ... --quiet` (the same results file, output_accelerations:
solved), repeated REPEATS times in turn; the table gives the median wall time of the
process, the median CPU time of the process (user + system, from getrusage of the
child) and the solver CPU time the results file records (`solver_cpu_time`: the
integrator's AdvanceTo calls alone). Errors, every row, against references independent
of the solver:

- the payload's position, velocity and acceleration in closed form from the joint
  angles (forward kinematics of the quintics and their first two derivatives);
- the three motor efforts (/joints/driveK/effort) against the Newton-Euler computation of
  tests/app/test_motion_effort.py.

Writes bench/results/kinematic_vs_ida.md and .csv (or --out DIR).

    python3 bench/kinematic_vs_ida.py [--mbdae build/mbdae] [--repeats 5] [--out DIR]
"""
import argparse
import csv
import os
import resource
import statistics
import subprocess
import sys
import tempfile
import time

import h5py
import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
MODEL = os.path.join(ROOT, "tests", "app", "models", "arm_motion.yaml")
T = 2.0

L1, L2, L3 = 0.4, 0.3, 0.2
QT = np.array([1.5, 0.9, -0.3])  # from q = 0 (arm_motion.yaml's defaults)


def joint_angles(t):
    s = t / T
    p = 10 * s**3 - 15 * s**4 + 6 * s**5
    dp = (30 * s**2 - 60 * s**3 + 30 * s**4) / T
    ddp = (60 * s - 180 * s**2 + 120 * s**3) / T**2
    return QT * p, QT * dp, QT * ddp


def payload(t):
    """Position, velocity and acceleration of the payload (the tip) in world axes."""
    (q1, q2, q3), (d1, d2, d3), (e1, e2, e3) = joint_angles(t)
    a, b = q2, q2 + q3
    da, db, ea, eb = d2, d2 + d3, e2, e2 + e3
    rho = L2 * np.cos(a) + L3 * np.cos(b)
    rho_d = -L2 * np.sin(a) * da - L3 * np.sin(b) * db
    rho_dd = (-L2 * (np.cos(a) * da**2 + np.sin(a) * ea)
              - L3 * (np.cos(b) * db**2 + np.sin(b) * eb))
    h = L2 * np.sin(a) + L3 * np.sin(b)
    h_d = L2 * np.cos(a) * da + L3 * np.cos(b) * db
    h_dd = (L2 * (-np.sin(a) * da**2 + np.cos(a) * ea)
            + L3 * (-np.sin(b) * db**2 + np.cos(b) * eb))
    c, s = np.cos(q1), np.sin(q1)
    p = np.array([rho * c, rho * s, L1 + h])
    v = np.array([rho_d * c - rho * s * d1, rho_d * s + rho * c * d1, h_d])
    acc = np.array([rho_dd * c - 2 * rho_d * s * d1 - rho * (c * d1**2 + s * e1),
                    rho_dd * s + 2 * rho_d * c * d1 + rho * (-s * d1**2 + c * e1),
                    h_dd])
    return p, v, acc


def newton_euler_module():
    os.environ.setdefault("MBDAE_BIN", "")
    os.environ.setdefault("MBDAE_APP_MODELS", os.path.dirname(MODEL))
    sys.path.insert(0, os.path.join(ROOT, "tests", "app"))
    import test_motion_effort  # noqa: E402  (the independent Newton-Euler computation)
    return test_motion_effort


def run(mbdae, args, out):
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    start = time.perf_counter()
    subprocess.run([mbdae, "simulate", MODEL, "-o", out, "--quiet", "--set", "T=%g" % T] + args,
                   check=True)
    wall = time.perf_counter() - start
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return wall, cpu


def errors(path, ne):
    with h5py.File(path, "r") as f:
        t = f["/time"][:]
        p = f["/bodies/payload/position"][:]
        v = f["/bodies/payload/velocity"][:]
        names = list(f["/q_names"].asstr()[:])
        a = f["/a"][:, names.index("payload.x"):names.index("payload.x") + 3]
        effort = np.column_stack([f["/joints/drive%d/effort" % k][:] for k in (1, 2, 3)])
        attrs = dict(f.attrs)
    ref = [payload(tk) for tk in t]
    ep = max(np.abs(p[k] - ref[k][0]).max() for k in range(len(t)))
    ev = max(np.abs(v[k] - ref[k][1]).max() for k in range(len(t)))
    ea = max(np.abs(a[k] - ref[k][2]).max() for k in range(len(t)))
    tau = np.array([ne.newton_euler(*joint_angles(tk)) for tk in t])
    ee = np.abs(effort - tau).max()
    return {"rows": len(t), "pos": ep, "vel": ev, "acc": ea, "effort": ee,
            "effort_max": np.abs(tau).max(), "attrs": attrs, "effort_rows": effort}


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--mbdae", default=os.path.join(ROOT, "build", "mbdae"))
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--out", default=os.path.join(HERE, "results"))
    ap.add_argument("--note", default="", help="a line for the report (e.g. which build ran)")
    args = ap.parse_args()
    ne = newton_euler_module()
    cases = [("kinematic", "-", ["--integrator", "kinematic"])]
    for tol in ("1e-6", "1e-8", "1e-10", "1e-12"):
        cases.append(("ida", "rtol = atol = " + tol, ["--integrator", "ida", "--rtol", tol, "--atol", tol]))
    cases.append(("hht", "h = 1e-3 (the default)", ["--integrator", "hht", "--step", "1e-3"]))
    tmp = tempfile.mkdtemp(prefix="kinematic_vs_ida.")
    walls = {i: [] for i in range(len(cases))}
    cpus = {i: [] for i in range(len(cases))}
    solver = {i: [] for i in range(len(cases))}
    inner = {i: [] for i in range(len(cases))}
    result = {}
    for r in range(args.repeats):
        for i, (_, _, extra) in enumerate(cases):  # in turn: the machine's load shared
            out = os.path.join(tmp, "case%d.h5" % i)
            wall, cpu = run(args.mbdae, extra, out)
            walls[i].append(wall)
            cpus[i].append(cpu)
            e = errors(out, ne) if r == 0 else None
            if e:
                result[i] = e
            with h5py.File(out, "r") as f:
                solver[i].append(float(f.attrs["solver_cpu_time"]))
                inner[i].append(float(f.attrs["wall_time"]))
    kin_effort = result[0]["effort_rows"]
    rows = []
    for i, (name, tol, _) in enumerate(cases):
        e = result[i]
        at = e["attrs"]
        rows.append({
            "integrator": name, "setting": tol,
            "status": at["status"].decode() if isinstance(at["status"], bytes) else at["status"],
            "rows": e["rows"],
            "steps": int(at["steps_accepted"]), "newton_iterations": int(at["newton_iterations"]),
            "wall_s": statistics.median(walls[i]), "cpu_s": statistics.median(cpus[i]),
            "run_wall_s": statistics.median(inner[i]),
            "solver_cpu_s": statistics.median(solver[i]),
            "err_position_m": e["pos"], "err_velocity_m_s": e["vel"], "err_acceleration_m_s2": e["acc"],
            "err_effort_Nm": e["effort"],
            "diff_effort_vs_kinematic_Nm": np.abs(e["effort_rows"] - kin_effort).max(),
        })
    os.makedirs(args.out, exist_ok=True)
    csv_path = os.path.join(args.out, "kinematic_vs_ida.csv")
    with open(csv_path, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0].keys()))
        w.writeheader()
        for row in rows:
            w.writerow({k: ("%.6g" % v if isinstance(v, float) else v) for k, v in row.items()})
    kin = rows[0]
    lines = [
        "# Kinematic analysis against IDA and HHT: the driven arm over 2 s",
        "",
        "`python3 bench/kinematic_vs_ida.py --mbdae %s --repeats %d` (written by the script;"
        % (os.path.relpath(args.mbdae, ROOT) if os.path.abspath(args.mbdae).startswith(ROOT + os.sep)
           else args.mbdae, args.repeats),
        "data in `kinematic_vs_ida.csv`). Model: `tests/app/models/arm_motion.yaml` with `--set T=2`",
        "(three motion joints, quintic rest-to-rest motions, t_end = 2 s, %d output rows, 0 degrees"
        % kin["rows"],
        "of freedom). Times: medians of %d runs of `mbdae simulate --quiet` taken in turn on a" % args.repeats,
        "shared 2-core machine: the process's wall and CPU time (loading, assembly, run, results file),",
        "the results file's `wall_time` (the run: solving and writing the rows) and `solver_cpu_time`",
        "(the integrator's AdvanceTo calls alone). Errors: max over every row and component, the payload's",
        "position, velocity and acceleration against the closed form from the joint angles, the three",
        "motor efforts against the Newton-Euler computation of `tests/app/test_motion_effort.py`",
        "(efforts up to %.3g N m)." % result[0]["effort_max"],
        "",
    ] + ([args.note, ""] if args.note else []) + [
        "| integrator | setting | steps | Newton it. | process wall s | process CPU s | run wall s | solver CPU s | position m | velocity m/s | acceleration m/s^2 | effort N m |",
        "| --- | --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |",
    ]
    for row in rows:
        lines.append("| %s | %s | %d | %d | %.4f | %.4f | %.4f | %.5f | %.2e | %.2e | %.2e | %.2e |" % (
            row["integrator"], row["setting"], row["steps"], row["newton_iterations"], row["wall_s"],
            row["cpu_s"], row["run_wall_s"], row["solver_cpu_s"], row["err_position_m"], row["err_velocity_m_s"],
            row["err_acceleration_m_s2"], row["err_effort_Nm"]))
    lines += ["", "Ratios (integrated / kinematic):", "",
              "| integrator | process wall | process CPU | run wall | solver CPU |",
              "| --- | ---: | ---: | ---: | ---: |"]
    for row in rows[1:]:
        lines.append("| %s %s | %.2f | %.2f | %.2f | %.1f |" % (
            row["integrator"], row["setting"], row["wall_s"] / kin["wall_s"], row["cpu_s"] / kin["cpu_s"],
            row["run_wall_s"] / kin["run_wall_s"], row["solver_cpu_s"] / kin["solver_cpu_s"]))
    lines.append("")
    md_path = os.path.join(args.out, "kinematic_vs_ida.md")
    with open(md_path, "w") as f:
        f.write("\n".join(lines))
    print("\n".join(lines))
    print("wrote", md_path, "and", csv_path)


if __name__ == "__main__":
    main()
