#!/usr/bin/env python3
"""Redundant constraints: a door held by two hinges on one axis (door.yaml) and a planar
parallelogram linkage with three parallel cranks built of spatial revolute joints
(parallelogram.yaml).

For each model:
1. `mbdae info --json`: the redundant equations and the degrees of freedom, against the
   Grubler count and the true mobility (1 for both).
2. The reference: the one-degree-of-freedom equation of motion in the hinge / crank angle,
   integrated with scipy (DOP853, rtol = atol = 1e-13).
3. Runs with IDA, fixed-step HHT and adaptive HHT; error = max over the output rows of
   |angle - reference| (rad), with a stated tolerance each.
4. Constraint violations: the program's (kept equations) and every joint equation,
   the removed ones included, recomputed here from the bodies' states.
5. Multipliers: the removed equations have no multiplier in /lambda (they are zero); a
   joint all of whose equations were removed reports zero reactions. The resultant of the
   joint reactions on every body (force, and moment about its centre of mass) is unique
   and is checked against Newton-Euler with the reference motion; the door's total hinge
   force and moment about the axis origin against the closed form.
Full run (without --quick): step-size / tolerance sweeps (work_precision.csv) and
figure.png. Writes results.md, summary.json (here or in $MBDAE_VERIFICATION_OUT).
"""
import argparse
import csv
import json
import math
import os
import subprocess
import sys

import numpy as np
from scipy.integrate import solve_ivp

HERE = os.path.dirname(os.path.abspath(__file__))
OUT = os.environ.get("MBDAE_VERIFICATION_OUT") or HERE
os.makedirs(OUT, exist_ok=True)
sys.path.insert(0, os.path.dirname(HERE))
import mbdae_run as mr  # noqa: E402

G = np.array([0.0, -9.81, 0.0])
T_END = 5.0
IDA = ["--integrator", "ida", "--rtol", "1e-10", "--atol", "1e-10"]
HHT_FIXED = ["--integrator", "hht", "--step", "1e-3", "--alpha", "-0.1"]
HHT_ADAPTIVE = ["--integrator", "hht", "--adaptive", "--step", "1e-4", "--tolerance", "1e-8"]
# Tolerances of the angle error (rad): IDA at rtol 1e-10 within 1e-7; fixed-step HHT
# (second order) at h = 1e-3 within 1e-3 (0.06 degrees; the full run also checks the
# order 2 over a step sweep); adaptive HHT at tolerance 1e-8 within 1e-3: its estimate
# does not see the velocity error, and the global error is about the sum of the local
# tolerances over the steps (docs/hht.md), a few thousand steps here.
TOL_ANGLE = {"ida": 1e-7, "hht-fixed": 1e-3, "hht-adaptive": 1e-3}
# Reaction resultants, relative to a scale of the reactions (door: the largest analytic
# value; parallelogram: four times the total weight). IDA 1e-5: the multipliers are left
# out of IDA's error test, so they are less accurate than the coordinates. HHT 1e-2: the
# HHT multipliers satisfy the alpha-shifted residual (docs/hht.md), an O(h) difference.
TOL_REACTION = {"ida": 1e-5, "hht-fixed": 1e-2, "hht-adaptive": 1e-2}
TOL_JOINTS = 1e-9       # every joint equation, recomputed from the bodies' states


# ---------------------------------------------------------------- geometry helpers
def rot_from_euler(e):
    e0, e1, e2, e3 = e
    return np.array([
        [1 - 2 * (e2 * e2 + e3 * e3), 2 * (e1 * e2 - e0 * e3), 2 * (e1 * e3 + e0 * e2)],
        [2 * (e1 * e2 + e0 * e3), 1 - 2 * (e1 * e1 + e3 * e3), 2 * (e2 * e3 - e0 * e1)],
        [2 * (e1 * e3 - e0 * e2), 2 * (e2 * e3 + e0 * e1), 1 - 2 * (e1 * e1 + e2 * e2)]])


def axis_angle(axis, angle):
    a = np.asarray(axis, float) / np.linalg.norm(axis)
    K = np.array([[0, -a[2], a[1]], [a[2], 0, -a[0]], [-a[1], a[0], 0]])
    return np.eye(3) + math.sin(angle) * K + (1 - math.cos(angle)) * K @ K


def box_inertia(m, size):
    a, b, c = size
    return m / 12 * np.diag([b * b + c * c, a * a + c * c, a * a + b * b])


def info(mbdae, model):
    p = subprocess.run([mbdae, "info", model, "--json"], stdout=subprocess.PIPE,
                       stderr=subprocess.PIPE, text=True, check=True)
    return json.loads(p.stdout)


def reference(rhs, theta0, t):
    sol = solve_ivp(lambda _, y: [y[1], rhs(y[0])], (0.0, t[-1]), [theta0, 0.0],
                    method="DOP853", rtol=1e-13, atol=1e-13, dense_output=True)
    th, om = sol.sol(t)
    return th, om, rhs(th)


def lambda_names(r):
    return [n.decode() if isinstance(n, bytes) else str(n) for n in r["/lambda_names"]]


def redundant_attr(r):
    v = r.attrs.get("redundant_constraint_names", [])
    return [str(x) for x in np.atleast_1d(v)] if len(np.atleast_1d(v)) else []


# ---------------------------------------------------------------- the door
class Door:
    name = "door"
    model = os.path.join(HERE, "door.yaml")
    expected_redundant = 5
    grubler = "6*1 - 5*2 = -4"

    def __init__(self, par):
        self.b, self.H, self.th = par["b"], par["H"], par["th"]
        self.beta, self.ys = par["beta"], (par["y1"], par["y2"])
        self.m = par["rho"] * self.b * self.H * self.th
        self.Jb = box_inertia(self.m, (self.b, self.H, self.th))
        self.u = np.array([0.0, math.cos(self.beta), math.sin(self.beta)])
        self.Iu = self.m * (self.b ** 2 + self.th ** 2) / 12 + self.m * self.b ** 2 / 4
        self.R0 = axis_angle([1, 0, 0], self.beta)
        self.theta0 = 0.0

    def rhs(self, th):
        # V = m g sin(beta) (b/2) sin(theta): the centre of mass, b/2 from the axis, starts
        # at 90 degrees from the lowest point (theta = -pi/2)
        return -self.m * 9.81 * math.sin(self.beta) * (self.b / 2) * np.cos(th) / self.Iu

    def joint_error(self, r):
        """max over rows and hinges of |p_i - p_j| and |z_i x z_j|, all ten equations."""
        x, e = r["/bodies/door/position"], r["/bodies/door/orientation"]
        worst = 0.0
        for n in range(len(r.time)):
            A = rot_from_euler(e[n])
            for y in self.ys:
                pi_ = x[n] + A @ np.array([-self.b / 2, y, 0.0])
                worst = max(worst, np.linalg.norm(pi_ - y * self.u),
                            np.linalg.norm(np.cross(A[:, 1], self.u)))
        return worst

    def resultants(self, r, th, om, al):
        """Program's and analytic total hinge force and moment about the origin (on the
        axis), relative errors, and the per-hinge data."""
        F = r["/joints/hinge1/force"] + r["/joints/hinge2/force"]
        x, e = r["/bodies/door/position"], r["/bodies/door/orientation"]
        M = np.zeros_like(F)
        for n in range(len(r.time)):
            A = rot_from_euler(e[n])
            for k, y in enumerate(self.ys):
                p = x[n] + A @ np.array([-self.b / 2, y, 0.0])
                M[n] += np.cross(p, r["/joints/hinge%d/force" % (k + 1)][n]) + r["/joints/hinge%d/torque" % (k + 1)][n]
        Fa, Ma = np.zeros_like(F), np.zeros_like(F)
        for n in range(len(r.time)):
            Ru = axis_angle(self.u, th[n])
            R = Ru @ self.R0
            rc = Ru @ np.array([self.b / 2, 0.0, 0.0])
            w, a = om[n] * self.u, al[n] * self.u
            acc = np.cross(a, rc) + np.cross(w, np.cross(w, rc))
            Fa[n] = self.m * acc - self.m * G
            JO = R @ self.Jb @ R.T + self.m * (rc @ rc * np.eye(3) - np.outer(rc, rc))
            Ma[n] = JO @ a + np.cross(w, JO @ w) - np.cross(rc, self.m * G)
        ef = float(np.max(np.linalg.norm(F - Fa, axis=1)) / np.max(np.linalg.norm(Fa, axis=1)))
        em = float(np.max(np.linalg.norm(M - Ma, axis=1)) / np.max(np.linalg.norm(Ma, axis=1)))
        return {"force": ef, "moment": em, "F": F, "Fa": Fa, "M": M, "Ma": Ma}


# ---------------------------------------------------------------- the parallelogram
class Parallelogram:
    name = "parallelogram"
    model = os.path.join(HERE, "parallelogram.yaml")
    expected_redundant = 7
    grubler = "spatial 6*4 - 5*6 = -6, planar 3*4 - 2*6 = 0"

    def __init__(self, par):
        self.L, self.ds = par["L"], (0.0, par["d1"], par["d2"])
        self.theta0, self.xc = par["theta0"], par["xc"]
        rho, wc, tc, lc, hc = par["rho"], par["wc"], par["tc"], par["lc"], par["hc"]
        self.mk = rho * self.L * wc * tc
        self.mc = rho * lc * hc * tc
        self.Jk = box_inertia(self.mk, (self.L, wc, tc))
        self.Ieff = 3 * (self.Jk[2, 2] + self.mk * self.L ** 2 / 4) + self.mc * self.L ** 2
        self.Gm = 3 * self.mk * self.L / 2 + self.mc * self.L

    def rhs(self, th):
        return -9.81 * np.cos(th) * self.Gm / self.Ieff

    def markers(self, r, n):
        """World points and z axes of the joints' markers (i, j) at row n."""
        out = {}
        pos = {b: r["/bodies/%s/position" % b][n] for b in ("crank1", "crank2", "crank3", "coupler")}
        A = {b: rot_from_euler(r["/bodies/%s/orientation" % b][n]) for b in pos}
        for k in range(3):
            c = "crank%d" % (k + 1)
            O = (pos[c] + A[c] @ [-self.L / 2, 0, 0], A[c][:, 2])
            P = (pos[c] + A[c] @ [self.L / 2, 0, 0], A[c][:, 2])
            out["ABC"[k]] = (O, (np.array([self.ds[k], 0, 0]), np.array([0.0, 0, 1])))
            Q = (pos["coupler"] + A["coupler"] @ [self.ds[k] - self.xc, 0, 0], A["coupler"][:, 2])
            out["P%d" % (k + 1)] = (Q, P)
        return out, pos, A

    def joint_error(self, r):
        worst = 0.0
        for n in range(len(r.time)):
            for (pi_, zi), (pj, zj) in self.markers(r, n)[0].values():
                worst = max(worst, np.linalg.norm(pi_ - pj), np.linalg.norm(np.cross(zi, zj)))
        return worst

    def resultants(self, r, th, om, al):
        """Resultant of the joint reactions on each body against Newton-Euler with the
        reference motion: force, and moment about the body's centre of mass."""
        ef, em = 0.0, 0.0
        scale_f = 9.81 * (3 * self.mk + self.mc) * 4
        scale_m = scale_f * self.L
        Fg_tot, Fg_ana = np.zeros((len(r.time), 3)), np.zeros((len(r.time), 3))
        for n in range(len(r.time)):
            mk, pos, A = self.markers(r, n)
            c, s = math.cos(th[n]), math.sin(th[n])
            tang, rad = np.array([-s, c, 0]), np.array([c, s, 0])
            acc1 = al[n] * tang - om[n] ** 2 * rad          # acceleration of a point at distance 1
            for k in range(3):
                body = "crank%d" % (k + 1)
                J, P = "ABC"[k], "P%d" % (k + 1)
                F = r["/joints/%s/force" % J][n] - r["/joints/%s/force" % P][n]
                M = (np.cross(mk[J][0][0] - pos[body], r["/joints/%s/force" % J][n]) + r["/joints/%s/torque" % J][n]
                     - np.cross(mk[P][0][0] - pos[body], r["/joints/%s/force" % P][n]) - r["/joints/%s/torque" % P][n])
                Fa = self.mk * (self.L / 2) * acc1 - self.mk * G
                Ma = np.array([0, 0, self.Jk[2, 2] * al[n]])
                ef, em = max(ef, np.linalg.norm(F - Fa)), max(em, np.linalg.norm(M - Ma))
                Fg_tot[n] += r["/joints/%s/force" % J][n]
            F = sum(r["/joints/P%d/force" % (k + 1)][n] for k in range(3))
            M = sum(np.cross(mk["P%d" % (k + 1)][0][0] - pos["coupler"], r["/joints/P%d/force" % (k + 1)][n])
                    + r["/joints/P%d/torque" % (k + 1)][n] for k in range(3))
            Fa = self.mc * self.L * acc1 - self.mc * G
            ef, em = max(ef, np.linalg.norm(F - Fa)), max(em, np.linalg.norm(M))
            Fg_ana[n] = 3 * self.mk * (self.L / 2) * acc1 + self.mc * self.L * acc1 - (3 * self.mk + self.mc) * G
        return {"force": float(ef / scale_f), "moment": float(em / scale_m), "Fg": Fg_tot, "Fg_ana": Fg_ana,
                "scale_f": scale_f}


# ---------------------------------------------------------------- runs
def run_case(runner, problem, label, args):
    path, proc = runner.simulate(problem.model, ["--t-end", T_END, "--output-step", "0.01"] + args,
                                 problem.name, check=False)
    if proc.returncode != 0:
        return None, (proc.stderr.strip().splitlines() or ["exit %d" % proc.returncode])[-1]
    return mr.Results(path), None


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    mr.add_mbdae_argument(ap)
    ap.add_argument("--quick", action="store_true", help="the checks only (no sweep, no figure)")
    args = ap.parse_args()
    mbdae = mr.find_mbdae(args.mbdae)
    runner = mr.Runner(mbdae, args.keep)
    checks, md = [], ["# Redundant constraints: results\n",
                      "Produced by `verification/redundant/run.py%s`. Error = max over the output rows "
                      "(every 0.01 s, 0 to %g s) of |angle - reference| in rad; reference: the "
                      "one-degree-of-freedom equation of motion, scipy DOP853 at rtol = atol = 1e-13.\n"
                      % (" --quick" if args.quick else "", T_END)]
    iftomm, wp_rows, keep = [], [], {}
    settings = [("ida", IDA, "rtol = atol = 1e-10"), ("hht-fixed", HHT_FIXED, "h = 1e-3, alpha = -0.1"),
                ("hht-adaptive", HHT_ADAPTIVE, "tol = 1e-8")]
    for cls in (Door, Parallelogram):
        inf = info(mbdae, cls.model)
        pb = cls(inf["parameters"])
        cnt = inf["counts"]
        red = inf["redundant_equations"]
        md.append("## %s (`%s`)\n" % (cls.name, os.path.basename(cls.model)))
        md.append("`mbdae info --json`: %d coordinates, %d constraint equations, **%d redundant** (%s), "
                  "**%d degrees of freedom**. Grubler: %s; true mobility 1.\n"
                  % (cnt["coordinates"], cnt["constraint_equations"], cnt["redundant_equations"],
                     ", ".join(red), cnt["degrees_of_freedom"], cls.grubler))
        checks.append(("%s: info reports %d redundant equations (expected %d = equations - coordinates + "
                       "mobility) and %d degree(s) of freedom (true mobility 1)"
                       % (cls.name, cnt["redundant_equations"], pb.expected_redundant, cnt["degrees_of_freedom"]),
                       cnt["redundant_equations"] == pb.expected_redundant and cnt["degrees_of_freedom"] == 1
                       and cnt["constraint_equations"] - cnt["redundant_equations"] == cnt["coordinates"] - 1))
        rows = []
        for integ, sargs, setting in settings:
            r, err = run_case(runner, pb, integ, sargs)
            if r is None:
                checks.append(("%s %s (%s): the run failed: %s" % (cls.name, integ, setting, err), False))
                continue
            th_ref, om_ref, al_ref = reference(pb.rhs, pb.theta0, r.time)
            e_ang = float(np.max(np.abs(r["/measures/theta"] - th_ref)))
            ok_nan = all(np.all(np.isfinite(v)) for v in r.data.values() if v.dtype.kind == "f")
            jerr = pb.joint_error(r)
            res = pb.resultants(r, th_ref, om_ref, al_ref)
            lam = lambda_names(r)
            absent = not (set(red) & set(lam)) and len(lam) == cnt["constraint_equations"] - len(red)
            attr_red = redundant_attr(r)
            keep[(cls.name, integ)] = (r, th_ref, res)
            rows.append("| %s | %s | %.3e | %.2e | %.2e | %.2e | %.2e | %.2e | %.3f |" % (
                integ, setting, e_ang, r.attrs["max_position_violation"], r.attrs["max_velocity_violation"],
                jerr, res["force"], res["moment"], r.cpu_time()))
            ok_ang = e_ang <= TOL_ANGLE[integ]
            iftomm.append({"problem": cls.name, "integrator": integ, "setting": setting,
                           "quantity": "max abs angle error (rad)", "error": e_ang,
                           "tolerance": TOL_ANGLE[integ], "cpu_time": r.cpu_time(), "passed": bool(ok_ang)})
            checks.append(("%s %s (%s): angle error %.2e <= %.0e rad" % (cls.name, integ, setting, e_ang,
                                                                       TOL_ANGLE[integ]), ok_ang))
            checks.append(("%s %s: all %d joint equations (removed ones included) hold from the bodies' states: "
                           "%.1e <= %.0e; no NaN" % (cls.name, integ, 5 * len(inf["joints"]), jerr, TOL_JOINTS),
                           jerr <= TOL_JOINTS and ok_nan))
            checks.append(("%s %s: /lambda has the %d kept equations and none of the removed ones; the file's "
                           "redundant_constraint_names = info's" % (cls.name, integ, len(lam)),
                           absent and sorted(attr_red) == sorted(red)))
            what = ("total hinge force / moment about the origin vs closed form" if cls is Door else
                    "resultant reaction force / moment on each body vs Newton-Euler")
            checks.append(("%s %s: %s: %.1e / %.1e <= %.0e (relative)" % (
                cls.name, integ, what, res["force"], res["moment"], TOL_REACTION[integ]),
                max(res["force"], res["moment"]) <= TOL_REACTION[integ]))
            if cls is Door:
                z = float(np.max(np.abs(r["/joints/hinge2/force"])) + np.max(np.abs(r["/joints/hinge2/torque"])))
                checks.append(("door %s: hinge2 (all 5 equations removed) reports zero force and torque: %.1e == 0"
                               % (integ, z), z == 0.0))
        md.append("| integrator | setting | angle error (rad) | position violation (kept eqs) | velocity "
                  "violation (kept eqs) | all joint eqs (ours) | resultant force error (rel) | resultant "
                  "moment error (rel) | CPU s |")
        md.append("|---|---|---|---|---|---|---|---|---|")
        md += rows + [""]

    # what the program returns for the split (IDA runs)
    if ("door", "ida") in keep:
        r, _, res = keep[("door", "ida")]
        f1 = r["/joints/hinge1/force"]
        md.append("Door, IDA: the program removes every equation of `hinge2` (it is listed second), so "
                  "`/joints/hinge2` is zero and `hinge1` carries the whole load: largest |force| %.1f N, "
                  "largest |torque| %.1f N m (the moment that two real hinges share as a couple). The "
                  "total matches the closed form (table above).\n" % (
                      np.max(np.linalg.norm(f1, axis=1)), np.max(np.linalg.norm(r["/joints/hinge1/torque"], axis=1))))
    if ("parallelogram", "ida") in keep:
        r, _, res = keep[("parallelogram", "ida")]
        mx = {j: float(np.max(np.linalg.norm(r["/joints/%s/force" % j], axis=1))) for j in ("A", "B", "C", "P1", "P2", "P3")}
        oop = {j: float(np.max(np.abs(r["/joints/%s/force" % j][:, 2])) + np.max(np.abs(r["/joints/%s/torque" % j][:, :2])))
               for j in ("A", "B", "C", "P1", "P2", "P3")}
        md.append("Parallelogram, IDA: largest |force| per joint (N): %s. Out-of-plane force and torque "
                  "(|F_z| + |T_x|, |T_y|) per joint: %s. The split of the in-plane load among the three "
                  "cranks is one of infinitely many; each body's resultant is unique and checked.\n" % (
                      ", ".join("%s %.2f" % kv for kv in mx.items()),
                      ", ".join("%s %.1e" % kv for kv in oop.items())))

    csv_files, figures = [], []
    if not args.quick:
        for cls in (Door, Parallelogram):
            pb = cls(info(mbdae, cls.model)["parameters"])
            sweep = [("hht-fixed", ["--integrator", "hht", "--step", h], "h = %s" % h)
                     for h in ("4e-3", "2e-3", "1e-3", "5e-4", "2.5e-4")]
            sweep += [("hht-adaptive", ["--integrator", "hht", "--adaptive", "--step", "1e-4", "--tolerance", tol],
                       "tol = %s" % tol) for tol in ("1e-5", "1e-6", "1e-7", "1e-8")]
            sweep += [("ida", ["--integrator", "ida", "--rtol", tol, "--atol", tol], "rtol = atol = %s" % tol)
                      for tol in ("1e-6", "1e-8", "1e-10", "1e-12")]
            for integ, sargs, setting in sweep:
                r, err = run_case(runner, pb, integ, sargs)
                if r is None:
                    wp_rows.append([cls.name, integ, setting, "", "", "", "failed"])
                    continue
                th_ref = reference(pb.rhs, pb.theta0, r.time)[0]
                e_ang = float(np.max(np.abs(r["/measures/theta"] - th_ref)))
                wp_rows.append([cls.name, integ, setting, "%.6g" % r.cpu_time(), "%.6e" % e_ang,
                                int(r.attrs["steps_accepted"]), "done"])
        with open(os.path.join(OUT, "work_precision.csv"), "w", newline="") as f:
            w = csv.writer(f)
            w.writerow(["problem", "integrator", "setting", "cpu_time", "error", "steps", "status"])
            w.writerows(wp_rows)
        csv_files.append("work_precision.csv")
        md.append("## Work-precision (work_precision.csv)\n")
        md.append(mr.markdown_table(["problem", "integrator", "setting", "CPU s", "angle error (rad)", "steps",
                                     "status"], wp_rows))
        fixed = {p: [(float(s.split("=")[1]), float(e)) for (pp, i, s, c, e, n, st) in wp_rows
                     if pp == p and i == "hht-fixed" and st == "done"] for p in ("door", "parallelogram")}
        for p, pts in fixed.items():
            if len(pts) >= 2:
                orders = [math.log(pts[k][1] / pts[k + 1][1]) / math.log(pts[k][0] / pts[k + 1][0])
                          for k in range(len(pts) - 1)]
                md.append("Fixed-step HHT, %s: observed order per halving %s.\n" % (
                    p, ", ".join("%.2f" % o for o in orders)))
                checks.append(("%s fixed-step HHT: observed order of the angle error over the last three "
                               "halvings of h (%s) within 2 +- 0.2" % (p, ", ".join("%.2f" % o for o in orders[-3:])),
                               all(abs(o - 2) <= 0.2 for o in orders[-3:])))
        figures.append(make_figure(keep, wp_rows))

    headline = "; ".join("%s: %s" % (it["problem"] + " " + it["integrator"], "%.1e rad" % it["error"])
                         for it in iftomm)
    summary = {"title": "Redundant constraints: door with two hinges, double parallelogram",
               "headline": "info finds 5 (door) and 7 (parallelogram) redundant equations, 1 degree of "
                           "freedom each; angle errors " + headline,
               "figures": figures, "csv": csv_files}
    if wp_rows:
        summary["work_precision"] = "work_precision.csv"
    summary["runs"] = iftomm
    return mr.finish_checks(runner, checks, md, OUT, summary)


def make_figure(keep, wp_rows):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(2, 2, figsize=(11, 7.5))
    for col, p in enumerate(("door", "parallelogram")):
        a = ax[0, col]
        for integ in ("ida", "hht-fixed", "hht-adaptive"):
            if (p, integ) in keep:
                r, th_ref, _ = keep[(p, integ)]
                a.semilogy(r.time[1:], np.abs(r["/measures/theta"] - th_ref)[1:] + 1e-16, label=integ)
        a.set_title("%s: |angle - reference|" % p, fontsize="medium")
        a.set_xlabel("t (s)")
        a.set_ylabel("rad")
        a.legend(fontsize="small")
    if ("door", "ida") in keep:
        r, _, res = keep[("door", "ida")]
        a = ax[1, 0]
        for k, c in enumerate("xyz"):
            a.plot(r.time, r["/joints/hinge1/force"][:, k], label="hinge1 F%s" % c)
            a.plot(r.time, r["/joints/hinge2/force"][:, k], ":", label="hinge2 F%s" % c)
            a.plot(r.time[::10], res["Fa"][::10, k], "k.", ms=3)
        a.set_title("door (IDA): hinge forces; dots: closed-form total", fontsize="medium")
        a.set_xlabel("t (s)")
        a.set_ylabel("N")
        a.legend(fontsize="x-small", ncol=2)
    if ("parallelogram", "ida") in keep:
        r, _, res = keep[("parallelogram", "ida")]
        a = ax[1, 1]
        for j in ("A", "B", "C"):
            a.plot(r.time, r["/joints/%s/force" % j][:, 1], label="%s: F_y on crank" % j)
        a.plot(r.time, res["Fg"][:, 1], "k-", lw=2, label="sum A+B+C")
        a.plot(r.time[::10], res["Fg_ana"][::10, 1], "r.", ms=4, label="Newton-Euler total")
        a.set_title("parallelogram (IDA): ground pivots, y force", fontsize="medium")
        a.set_xlabel("t (s)")
        a.set_ylabel("N")
        a.legend(fontsize="x-small")
    fig.tight_layout()
    fig.savefig(os.path.join(OUT, "figure.png"), dpi=100)
    plt.close(fig)
    return "figure.png"


if __name__ == "__main__":
    sys.exit(main())
