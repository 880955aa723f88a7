#!/usr/bin/env python3
"""Checks of the Andrews model without the program:

1. the test set's 6 loop constraints vanish at the consistent initial angles;
2. in andrews.yaml, the two markers of every joint coincide at t = 0 (world positions
   from the bodies' positions, Euler parameters and marker offsets), and point E computed
   through the bodies equals the test set's;
3. the 7 rotational measures (angle of marker i's frame relative to marker j's about z),
   evaluated on andrews.yaml, equal the consistent initial angles to 1e-12;
4. the kinetic energy of the 7 bodies, with the centres of mass of andrews_data.py,
   gives the test set's mass matrix M(q) (at random angles, by central differences);
5. the spring's generalised force on gamma equals the test set's.
Exits 1 if a check fails.
"""
import math
import os
import sys

import numpy as np
import yaml

import andrews_data as ad

HERE = os.path.dirname(os.path.abspath(__file__))


def quat_to_matrix(p):
    e0, e1, e2, e3 = np.array(p, float) / np.linalg.norm(p)
    return np.array([
        [1 - 2 * (e2 * e2 + e3 * e3), 2 * (e1 * e2 - e0 * e3), 2 * (e1 * e3 + e0 * e2)],
        [2 * (e1 * e2 + e0 * e3), 1 - 2 * (e1 * e1 + e3 * e3), 2 * (e2 * e3 - e0 * e1)],
        [2 * (e1 * e3 - e0 * e2), 2 * (e2 * e3 + e0 * e1), 1 - 2 * (e1 * e1 + e2 * e2)]])


def load_frames(path):
    """World position and orientation of every marker of the model at t = 0."""
    with open(path) as f:
        model = yaml.safe_load(f)
    frames = {"ground.O": (np.zeros(3), np.eye(3))}
    for name, mk in model.get("ground", {}).get("markers", {}).items():
        frames["ground." + name] = (np.array(mk["position"], float), np.eye(3))
    for b in model["bodies"]:
        r = np.array(b["position"], float)
        R = quat_to_matrix(b["orientation"])
        frames[b["name"] + ".cm"] = (r, R)
        for name, mk in b["markers"].items():
            assert "orientation" not in mk
            frames[b["name"] + "." + name] = (r + R @ np.array(mk["position"], float), R)
    return model, frames


def main():
    ok = True

    def report(what, value, tol):
        nonlocal ok
        good = value <= tol
        ok &= good
        print("%-62s %.2e (<= %.0e) %s" % (what, value, tol, "ok" if good else "FAIL"))

    q0 = ad.Q0
    report("1. test-set constraints at the initial angles, max |g|", np.max(np.abs(ad.test_set_constraints(q0))), 1e-15)

    model, frames = load_frames(os.path.join(HERE, "andrews.yaml"))
    worst = 0.0
    for j in model["joints"]:
        (pi, Ri), (pj, Rj) = frames[j["i"]], frames[j["j"]]
        worst = max(worst, np.max(np.abs(pi - pj)), np.max(np.abs(Ri[:, 2] - Rj[:, 2])))
    report("2. joints of andrews.yaml: max marker mismatch [m]", worst, 1e-15)
    b, T = q0[0], q0[1]
    E = np.array([ad.rr * math.cos(b) - ad.d * math.cos(b + T), ad.rr * math.sin(b) - ad.d * math.sin(b + T), 0])
    worst = max(np.max(np.abs(frames[n][0] - E)) for n in ("K2.E", "K3.E", "K4.E", "K6.E"))
    report("   point E through bodies 2, 3, 4, 6 vs the test set's [m]", worst, 1e-15)

    worst = 0.0
    for k, meas in enumerate(model["measures"]):
        Ri, Rj = frames[meas["i"]][1], frames[meas["j"]][1]
        Rrel = Rj.T @ Ri
        angle = math.atan2(Rrel[1, 0], Rrel[0, 0])
        assert meas["name"] == ad.NAMES[k]
        worst = max(worst, abs(angle - q0[k]))
    report("3. measures at t = 0 vs the initial angles [rad]", worst, 1e-12)

    rng = np.random.default_rng(1)
    worst = 0.0
    for _ in range(5):
        q = rng.uniform(-math.pi, math.pi, 7)
        h = 1e-6
        M = np.zeros((7, 7))
        for k in range(7):
            Jr = np.zeros((2, 7))
            Ja = np.zeros(7)
            for c in range(7):
                dq = np.zeros(7)
                dq[c] = h
                Jr[:, c] = (ad.centre_of_mass(q + dq, k) - ad.centre_of_mass(q - dq, k)) / (2 * h)
                Ja[c] = (ad.absolute_angles(q + dq)[k] - ad.absolute_angles(q - dq)[k]) / (2 * h)
            M += ad.m[k] * Jr.T @ Jr + ad.inertia[k] * np.outer(Ja, Ja)
        Mt = ad.test_set_mass_matrix(q)
        worst = max(worst, np.max(np.abs(M - Mt)) / np.max(np.abs(Mt)))
    report("4. mass matrix from the bodies vs the test set's (relative)", worst, 1e-8)

    worst = 0.0
    for _ in range(5):
        q = rng.uniform(-math.pi, math.pi, 7)
        g = q[2]
        D = ad.world_point(q, 2, "D")
        dv = D - np.array([ad.xc, ad.yc])
        lang = np.linalg.norm(dv)
        F = -ad.c0 * (lang - ad.l0) / lang * dv
        # test set: fx (sc cos g - sd sin g) + fy (sd cos g + sc sin g)
        ref = F[0] * (ad.sc * math.cos(g) - ad.sd * math.sin(g)) + F[1] * (ad.sd * math.cos(g) + ad.sc * math.sin(g))
        h = 1e-7
        qp, qm = q.copy(), q.copy()
        qp[2] += h
        qm[2] -= h
        dD = (ad.world_point(qp, 2, "D") - ad.world_point(qm, 2, "D")) / (2 * h)
        worst = max(worst, abs(F @ dD - ref) / max(1.0, abs(ref)))
    report("5. spring force on gamma vs the test set's (relative)", worst, 1e-7)
    print("geometry:", "PASS" if ok else "FAIL")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
