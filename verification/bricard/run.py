#!/usr/bin/env python3
"""IFToMM A04, Bricard's mechanism (bricard.yaml): redundancy and energy conservation.

1. Without the program: the two markers of each joint coincide at t = 0, their z axes
   are the joint axes of the benchmark, and the mechanism has exactly one free motion
   (rank of the joints' velocity equations 29 of 30, i.e. one redundant equation).
2. Runs IDA (rtol = atol = 1e-10 from the model) for 10 s and reports the redundant
   constraints the program found (summary on stdout and the file's attributes).
3. Total energy E = /energy/kinetic + /energy/potential. Requirement:
   max_t |E(t) - E(0)| / max_t E_kin(t) <= 1e-6. The scale is the largest kinetic energy,
   i.e. the energy the mechanism actually exchanges (independent of the potential's
   datum); the drift relative to |E(0)| is reported as well.
   Cross-check: the program's energies equal the ones computed here from the bodies'
   velocities, angular velocities and positions (relative 1e-9 of the scale).
4. IFToMM A04 (Gonzalez et al. 2006): the moving point (joint J3, measures P3x/y/z) over
   10 s (output every 0.01 s) against IDA at rtol = atol = 1e-12, whose energy drift must
   be <= 1e-9 of the largest kinetic energy (how the reference is checked); error:
   max over x, y, z of max_t |p - p_ref| / max(max_t |p_ref|, 1e-3); and the energy:
   max_t |E(t) - E(0)| / max_t E_kin. HHT (alpha = -0.1, h = 2e-3) and IDA
   (rtol = atol = 1e-6): each error <= 1e-3. Rows in summary.json ("iftomm").
Writes results.md, summary.json and (without --quick) energy.png in verification/bricard
or $MBDAE_VERIFICATION_OUT; exits 1 if a requirement fails. --quick: no figure.
"""
import argparse
import math
import os
import sys

import numpy as np
import yaml

HERE = os.path.dirname(os.path.abspath(__file__))
# Where the tables and figures go: this folder, or $MBDAE_VERIFICATION_OUT (the tests).
OUT = os.environ.get("MBDAE_VERIFICATION_OUT") or HERE
os.makedirs(OUT, exist_ok=True)
sys.path.insert(0, os.path.dirname(HERE))
import mbdae_run as mr  # noqa: E402

MODEL = os.path.join(HERE, "bricard.yaml")
JOINT_POINTS = [(0, 0, 0), (1, 0, 0), (1, -1, 0), (1, -1, 1), (0, -1, 1), (0, 0, 1)]
JOINT_AXES = [(0, 1, 0), (0, 0, 1), (1, 0, 0), (0, 1, 0), (0, 0, 1), (1, 0, 0)]


def axis_angle(axis, angle):
    a = np.array(axis, float) / np.linalg.norm(axis)
    K = np.array([[0, -a[2], a[1]], [a[2], 0, -a[0]], [-a[1], a[0], 0]])
    return np.eye(3) + math.sin(angle) * K + (1 - math.cos(angle)) * K @ K


def static_checks():
    with open(MODEL) as f:
        model = yaml.safe_load(f)
    env = {"pi": math.pi}
    env.update({k: float(v) for k, v in model["parameters"].items()})

    def val(x):
        return float(eval(str(x), {"__builtins__": {}}, env)) if isinstance(x, str) else float(x)

    def orient(o):
        return np.eye(3) if o is None else axis_angle([val(c) for c in o["axis"]], val(o["angle"]))

    frames = {"ground.O": (np.zeros(3), np.eye(3))}
    for n, mk in model["ground"]["markers"].items():
        frames["ground." + n] = (np.array([val(c) for c in mk["position"]]), orient(mk.get("orientation")))
    bodies = []
    for b in model["bodies"]:
        r = np.array([val(c) for c in b["position"]])
        size = [val(c) for c in b["geometry"]["size"]]
        mass = val(b["geometry"]["density"]) * size[0] * size[1] * size[2]
        J = mass / 12 * np.diag([size[1]**2 + size[2]**2, size[0]**2 + size[2]**2, size[0]**2 + size[1]**2])
        bodies.append((b["name"], r, mass, J))
        for n, mk in b["markers"].items():
            frames[b["name"] + "." + n] = (r + np.array([val(c) for c in mk["position"]]), orient(mk.get("orientation")))
    worst = 0.0
    for k, j in enumerate(model["joints"]):
        (pi_, Ri), (pj, Rj) = frames[j["i"]], frames[j["j"]]
        worst = max(worst, np.max(np.abs(pi_ - pj)), np.max(np.abs(pi_ - JOINT_POINTS[k])),
                    np.max(np.abs(Ri[:, 2] - JOINT_AXES[k])), np.max(np.abs(Rj[:, 2] - JOINT_AXES[k])))
    # velocity equations of the 6 revolute joints in the 30 body twists
    def skew(v):
        return np.array([[0, -v[2], v[1]], [v[2], 0, -v[0]], [-v[1], v[0], 0]])
    rows = []
    for k in range(6):
        a = np.array(JOINT_AXES[k], float)
        perp = np.linalg.svd(a.reshape(1, 3))[2][1:]
        R = np.zeros((5, 30))
        for b, s in ((k - 1, 1.0), (k, -1.0)):
            if 0 <= b < 5:
                R[0:3, 6 * b:6 * b + 3] += s * np.eye(3)
                R[0:3, 6 * b + 3:6 * b + 6] += -s * skew(np.array(JOINT_POINTS[k], float) - bodies[b][1])
                R[3:5, 6 * b + 3:6 * b + 6] += s * perp
        rows.append(R)
    C = np.vstack(rows)
    sv = np.linalg.svd(C, compute_uv=False)
    rank = int(np.sum(sv > 1e-10 * sv[0]))
    return worst, rank, bodies, [b[2] for b in bodies]


IFTOMM_TOL, IFTOMM_THRESHOLD = 1e-3, 1e-3
IFTOMM_COMMON = ["--t-end", "10", "--output-step", "0.01"]
IFTOMM_SETTINGS = [("hht-fixed", "alpha = -0.1, h = 2e-3", ["--integrator", "hht", "--alpha", "-0.1", "--fixed-step",
                                                            "--step", "2e-3"]),
                   ("ida", "rtol = atol = 1e-6", ["--integrator", "ida", "--rtol", "1e-6", "--atol", "1e-6"])]


def point_and_energy(r):
    p = np.stack([r["/measures/P3" + c] for c in "xyz"], axis=1)
    e = r["/energy/kinetic"] + r["/energy/potential"]
    return p, float(np.max(np.abs(e - e[0]))) / float(np.max(r["/energy/kinetic"]))


def part_iftomm(runner, md, checks):
    path, _ = runner.simulate(MODEL, ["--integrator", "ida", "--rtol", "1e-12", "--atol", "1e-12"] + IFTOMM_COMMON,
                              "a04ref")
    ref = mr.Results(path)
    p_ref, drift_ref = point_and_energy(ref)
    checks.append(("A04 reference: IDA at rtol = atol = 1e-12 conserves the energy to %.1e of the largest kinetic "
                   "energy (<= 1e-9)" % drift_ref, drift_ref <= 1e-9))
    rows = []
    for integ, setting, args in IFTOMM_SETTINGS:
        path, _ = runner.simulate(MODEL, args + IFTOMM_COMMON, "a04")
        r = mr.Results(path)
        if len(r.time) != len(ref.time) or np.max(np.abs(r.time - ref.time)) > 1e-9:
            raise mr.RunError("A04: output times differ from the reference's")
        p, drift = point_and_energy(r)
        err_p = max(float(np.max(np.abs(p[:, i] - p_ref[:, i]))) / max(float(np.max(np.abs(p_ref[:, i]))),
                                                                      IFTOMM_THRESHOLD) for i in range(3))
        for quantity, err in (("position of the moving point J3", err_p), ("energy", drift)):
            passed = err <= IFTOMM_TOL
            rows.append({"problem": "A04", "integrator": integ, "setting": setting, "quantity": quantity,
                         "error": err, "tolerance": IFTOMM_TOL, "cpu_time": r.cpu_time(), "passed": bool(passed)})
            checks.append(("IFToMM A04, %s (%s): error of the %s over 10 s = %.2e <= 1e-3" % (
                integ, setting, quantity, err), passed))
        print("A04 %-9s %-22s point %.3e energy %.3e (tolerance 1e-3) CPU %.3f s" % (integ, setting, err_p, drift,
                                                                                    r.cpu_time()))
    md.append("\n## IFToMM A04: the moving point and the energy over 10 s\n")
    md.append("Reference: IDA at rtol = atol = 1e-12, output every 0.01 s; its energy drift is %.1e of the largest "
              "kinetic energy. Error of the point: max over x, y, z of max_t |p - p_ref| / max(max_t |p_ref|, 1e-3); "
              "of the energy: max_t |E(t) - E(0)| / max_t E_kin. CPU: solver_cpu_time.\n" % drift_ref)
    md.append(mr.markdown_table(["integrator", "setting", "quantity", "error", "tolerance", "CPU [s]", "passed"],
                                [[r["integrator"], r["setting"], r["quantity"], "%.3e" % r["error"], "1e-3",
                                  "%.4f" % r["cpu_time"], "yes" if r["passed"] else "NO"] for r in rows]))
    return rows


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    mr.add_mbdae_argument(ap)
    ap.add_argument("--set", action="append", default=[], metavar="OPTION",
                    help="extra mbdae simulate settings, e.g. --set=--integrator --set=hht (default: the model's)")
    ap.add_argument("--quick", action="store_true", help="no figure (the checks are the same)")
    args = ap.parse_args()
    checks = []
    worst, rank, bodies, masses = static_checks()
    pass_static = worst < 1e-15 and rank == 29 and all(abs(m - 1.0) < 1e-12 for m in masses)
    checks.append(("model geometry: joint markers coincide and point along the benchmark's axes (%.1e), joint "
                   "velocity equations of rank %d of 30, rod masses 1 kg" % (worst, rank), pass_static))
    print("static: joint mismatch %.1e, rank %d of 30, masses %s -> %s" % (
        worst, rank, masses, "ok" if pass_static else "FAIL"))

    runner = mr.Runner(mr.find_mbdae(args.mbdae), args.keep)
    path, proc = runner.simulate(MODEL, args.set, "bricard", check=False)
    if proc.returncode != 0:
        msg = (proc.stderr.strip().splitlines() or ["exit %d" % proc.returncode])[-1]
        msg = msg.split("; the results up to there")[0].replace(runner.dir, "<tmp>")
        print("FAIL: the run failed: %s" % msg)
        checks.append(("run (`mbdae simulate bricard.yaml %s`) ends: %s" % (" ".join(args.set), msg), False))
        md = ["# Bricard's mechanism (IFToMM A04): verification results\n",
              "Produced by `verification/bricard/run.py`; model `verification/bricard/bricard.yaml`.\n"]
        return mr.finish_checks(runner, checks, md, OUT, {"title": "Bricard's mechanism (IFToMM A04)"})
    r = mr.Results(path)
    summary = [l for l in (proc.stdout + proc.stderr).splitlines() if "redundan" in l.lower()]
    red_attrs = {k: v for k, v in r.attrs.items() if "redundan" in k.lower()}
    print("redundancy: summary %s; attributes %s" % (summary or "-", red_attrs or "-"))

    ek, ep = r["/energy/kinetic"], r["/energy/potential"]
    E = ek + ep
    scale = float(np.max(ek))
    drift = float(np.max(np.abs(E - E[0])))
    rel_scale, rel_e0 = drift / scale, drift / abs(E[0])
    pass_energy = rel_scale <= 1e-6
    checks.append(("energy drift %.2e of the largest kinetic energy <= 1e-6 (run: %s)" % (
        rel_scale, " ".join(args.set) or "the model's IDA 1e-10"), pass_energy))
    print("energy: E(0) = %.12f J, max E_kin = %.6f J, max |E - E(0)| = %.3e J -> %.3e of max E_kin, "
          "%.3e of |E(0)| (%s)" % (E[0], scale, drift, rel_scale, rel_e0, "ok" if pass_energy else "FAIL"))

    # own energies from the bodies' states
    g = np.array([0.0, -9.81, 0.0])
    ek_own = np.zeros_like(ek)
    ep_own = np.zeros_like(ep)
    for name, _, mass, J in bodies:
        v = r["/bodies/%s/velocity" % name]
        w = r["/bodies/%s/angular_velocity" % name]
        x = r["/bodies/%s/position" % name]
        e = r["/bodies/%s/orientation" % name]
        for n in range(len(r.time)):
            e0, e1, e2, e3 = e[n]
            A = np.array([
                [1 - 2 * (e2 * e2 + e3 * e3), 2 * (e1 * e2 - e0 * e3), 2 * (e1 * e3 + e0 * e2)],
                [2 * (e1 * e2 + e0 * e3), 1 - 2 * (e1 * e1 + e3 * e3), 2 * (e2 * e3 - e0 * e1)],
                [2 * (e1 * e3 - e0 * e2), 2 * (e2 * e3 + e0 * e1), 1 - 2 * (e1 * e1 + e2 * e2)]])
            wb = A.T @ w[n]
            ek_own[n] += 0.5 * mass * v[n] @ v[n] + 0.5 * wb @ J @ wb
            ep_own[n] += -mass * g @ x[n]
    dk = float(np.max(np.abs(ek_own - ek))) / scale
    # the potential's datum may differ: compare the variation
    dp = float(np.max(np.abs((ep_own - ep_own[0]) - (ep - ep[0])))) / scale
    pass_own = dk <= 1e-9 and dp <= 1e-9
    checks.append(("the program's energies equal those computed from the bodies' states (kinetic %.1e, potential "
                   "variation %.1e of the scale, <= 1e-9)" % (dk, dp), pass_own))
    print("energy cross-check: kinetic %.2e, potential variation %.2e (of max E_kin) (%s)" % (
        dk, dp, "ok" if pass_own else "FAIL"))

    p3 = np.stack([r["/measures/P3" + c] for c in "xyz"], axis=1)
    md = ["# Bricard's mechanism (IFToMM A04): verification results\n",
          "Produced by `verification/bricard/run.py`; model `verification/bricard/bricard.yaml`; "
          "IDA, rtol = atol = 1e-10, 10 s, output every 0.01 s.\n",
          "- Model geometry (before running): joint markers coincide to %.1e m, marker z axes are the "
          "benchmark's joint axes; the 30 joint velocity equations have rank %d (one redundant, "
          "one degree of freedom): **%s**" % (worst, rank, "PASS" if pass_static else "FAIL"),
          "- Redundant constraints reported by the program: %s" % (
              "; ".join(s.strip() for s in summary) or "(summary: none printed)")
          + ("; attributes: " + ", ".join("%s = %s" % kv for kv in red_attrs.items()) if red_attrs else ""),
          "- Energy: E(0) = %.12f J (potential datum y = 0), largest kinetic energy %.6f J, "
          "max |E(t) - E(0)| = %.3e J, i.e. **%.3e of the largest kinetic energy** (requirement <= 1e-6: "
          "**%s**), %.3e of |E(0)|." % (E[0], scale, drift, rel_scale, "PASS" if pass_energy else "FAIL", rel_e0),
          "- The program's energies against energies computed from the bodies' states in the file: "
          "kinetic %.1e, potential variation %.1e of the largest kinetic energy (requirement <= 1e-9: **%s**)"
          % (dk, dp, "PASS" if pass_own else "FAIL"),
          "- Moving joint point J3 at t = 10 s: (%.9f, %.9f, %.9f) m" % tuple(p3[-1]), ""]
    iftomm = part_iftomm(runner, md, checks)
    md.append("")
    figures = []
    if not args.quick:
        try:
            import matplotlib
            matplotlib.use("Agg")
            import matplotlib.pyplot as plt
            fig, (a1, a2) = plt.subplots(2, 1, figsize=(6.4, 6), sharex=True)
            for k, c in enumerate("xyz"):
                a1.plot(r.time, p3[:, k], label=c)
            a1.set_ylabel("joint point J3 [m]")
            a1.legend()
            a2.plot(r.time, E - E[0])
            a2.set_ylabel("E(t) - E(0) [J]")
            a2.set_xlabel("t [s]")
            fig.tight_layout()
            fig.savefig(os.path.join(OUT, "energy.png"), dpi=100)
            figures.append("energy.png")
        except Exception as exc:
            print("plot not written:", exc)
    summary = {"title": "Bricard's mechanism (IFToMM A04)",
               "headline": "%s redundant equation(s) found; energy drift %.1e of the largest kinetic energy (IDA 1e-10); "
                           "IFToMM A04 errors: %s" % (red_attrs.get("redundant_constraints", "no"), rel_scale, ", ".join(
                               "%s %s %.1e" % (r_["integrator"], "point" if r_["quantity"] != "energy" else "energy",
                                               r_["error"]) for r_ in iftomm)),
               "figures": figures, "csv": [], "iftomm": iftomm}
    return mr.finish_checks(runner, checks, md, OUT, summary)


if __name__ == "__main__":
    sys.exit(main())
