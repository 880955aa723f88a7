#!/usr/bin/env python3
"""Writes andrews.yaml (Andrews' squeezer as 7 rigid bodies) from andrews_data.py.

Every body's frame is its own planar frame (andrews_data.py) rotated about world z by
its absolute angle at the consistent initial angles; the markers have the body's axes,
so each rotational measure (about z) is the test set's relative angle.
"""
import math
import os

import andrews_data as ad

HERE = os.path.dirname(os.path.abspath(__file__))


def num(x):
    return repr(float(x))


def vec(v):
    return "[" + ", ".join(num(c) for c in v) + "]"


def main():
    q = ad.Q0
    angles = ad.absolute_angles(q)
    out = []
    w = out.append
    w("# Andrews' squeezer mechanism (Hairer & Wanner, Solving ODEs II, VII.7; Test Set for IVP")
    w("# Solvers, andrews.f). Written by make_model.py from andrews_data.py: edit those, not this.")
    w("# 7 planar bodies in 3-D joined by revolute joints about z; the planar loops closed with")
    w("# spatial revolute joints give redundant equations, which the solver detects.")
    w("# The measures beta ... epsilon are the test set's 7 angles.")
    w("format: 1")
    w("name: andrews squeezer")
    w("gravity: [0, 0, 0]")
    w("parameters: {mom: %s, c0: %s, l0: %s}" % (num(ad.mom), num(ad.c0), num(ad.l0)))
    w("ground:")
    w("  markers:")
    for name, p in ad.GROUND.items():
        if name != "O":
            w("    %s: {position: %s}" % (name, vec([p[0], p[1], 0.0])))
    w("bodies:")
    for k, (name, points, cm) in enumerate(ad.BODIES):
        a = angles[k]
        pos = ad.centre_of_mass(q, k)
        w("  - name: %s" % name)
        w("    mass: %s" % num(ad.m[k]))
        i = ad.inertia[k]
        w("    inertia: %s   # only Izz matters in plane motion" % vec([i, i, i]))
        w("    position: %s" % vec([pos[0], pos[1], 0.0]))
        w("    orientation: %s   # about z by %s" % (
            vec([math.cos(a / 2), 0.0, 0.0, math.sin(a / 2)]), num(a)))
        w("    markers:")
        for pname, p in points.items():
            w("      %s: {position: [%.15g, %.15g, 0]}" % (pname, p[0] - cm[0], p[1] - cm[1]))
    w("measures:")
    for name, i, j in ad.MEASURES:
        w("  - {name: %s, type: rotational, i: %s, j: %s, axis: z}" % (name, i, j))
    w("joints:")
    for name, i, j in ad.JOINTS:
        w("  - {name: %s, type: revolute, i: %s, j: %s}" % (name, i, j))
    w("forces:")
    w("  - {name: spring, type: spring_damper, i: K3.D, j: ground.C, stiffness: c0, damping: 0,"
      " free_length: l0, preload: 0}")
    w("  - {name: drive, type: torque, i: K1.cm, j: ground.O, frame: world, value: [0, 0, mom]}")
    w("simulation:")
    w("  t_end: 0.03")
    w("  output_step: 1.0e-4")
    w("  integrator: ida")
    w("  ida: {rtol: 1.0e-10, atol: 1.0e-10}")
    w("  hht: {alpha: -0.1, step: 1.0e-5, adaptive: false}")
    with open(os.path.join(HERE, "andrews.yaml"), "w") as f:
        f.write("\n".join(out) + "\n")


if __name__ == "__main__":
    main()
