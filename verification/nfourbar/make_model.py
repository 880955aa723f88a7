#!/usr/bin/env python3
"""Writes the N-four-bar mechanism (IFToMM benchmark A02) in the model format.

    python3 make_model.py            # nfourbar.yaml (N = 40) and nfourbar_n4.yaml (N = 4)
    python3 make_model.py --n 10 -o other.yaml

N four-bar loops in a row: N + 1 cranks pinned to ground at x = 0, L, ..., N L (vertical,
pointing up at t = 0) and N couplers joining the tops of neighbouring cranks (horizontal).
Every link is a uniform slender rod of length L and mass m along its body x axis
(inertia 0 about the rod's axis, m L^2 / 12 about the two others). Crank k has the markers
O (the ground pin, at -L/2) and B (the top, at +L/2); coupler k has A (on crank k's top)
and C (on crank k + 1's top). All joints are revolute about the world z axis, so each
loop, closed with spatial joints, has 3 redundant equations (3 N in all) that the program
detects and sets aside.

The number of bodies is fixed in the file, so N is a parameter of this script, not of the
model; L, m, g and the initial horizontal velocity v0 of B0 are model parameters
(`--set` changes them). Measures: xB0, yB0 (position of B0 = crank0.B), vB0, vyB0 (its
velocity), phi0 (angle of crank 0's axis from the world x axis, pi/2 at t = 0).
"""
import argparse
import os

HERE = os.path.dirname(os.path.abspath(__file__))


def model_text(n, t_end=20.0, output_step=0.05):
    lines = []
    w = lines.append
    w("# IFToMM benchmark A02, the N-four-bar mechanism, N = %d (%d links)." % (n, 2 * n + 1))
    w("# Written by make_model.py; do not edit by hand.")
    w("format: 1")
    w("name: N-four-bar mechanism, N = %d" % n)
    w("gravity: [0, -g, 0]")
    w("parameters:")
    w("  L: 1.0        # link length, m")
    w("  m: 1.0        # link mass, kg")
    w("  g: 9.81       # gravity, m/s^2")
    w("  v0: 1.0       # initial horizontal velocity of B0 (top of crank 0), m/s")
    w("ground:")
    w("  markers:")
    for k in range(n + 1):
        w("    P%d: {position: [%d*L, 0, 0]}" % (k, k))
    w("bodies:")
    for k in range(n + 1):
        w("  - name: crank%d" % k)
        w("    mass: m")
        w("    inertia: [0, m*L^2/12, m*L^2/12]")
        w("    position: [%d*L, L/2, 0]" % k)
        w("    orientation: {axis: [0, 0, 1], angle: pi/2}   # body x along world y")
        w("    velocity: [v0/2, 0, 0]")
        w("    angular_velocity: [0, 0, -v0/L]")
        w("    markers:")
        w("      O: {position: [-L/2, 0, 0]}")
        w("      B: {position: [L/2, 0, 0]}")
    for k in range(n):
        w("  - name: coupler%d" % k)
        w("    mass: m")
        w("    inertia: [0, m*L^2/12, m*L^2/12]")
        w("    position: [%d*L + L/2, L, 0]" % k)
        w("    velocity: [v0, 0, 0]")
        w("    markers:")
        w("      A: {position: [-L/2, 0, 0]}")
        w("      C: {position: [L/2, 0, 0]}")
    w("measures:")
    w("  - {name: xB0, type: translational, i: crank0.B, component: x, frame: world}")
    w("  - {name: yB0, type: translational, i: crank0.B, component: y, frame: world}")
    w("  - {name: vB0, type: translational, i: crank0.B, component: x, frame: world, quantity: velocity}")
    w("  - {name: vyB0, type: translational, i: crank0.B, component: y, frame: world, quantity: velocity}")
    w("  - {name: phi0, type: rotational, i: crank0.O, j: ground.O, axis: z}")
    w("joints:")
    for k in range(n + 1):
        w("  - {name: G%d, type: revolute, i: crank%d.O, j: ground.P%d}" % (k, k, k))
    for k in range(n):
        w("  - {name: A%d, type: revolute, i: coupler%d.A, j: crank%d.B}" % (k, k, k))
        w("  - {name: C%d, type: revolute, i: coupler%d.C, j: crank%d.B}" % (k, k, k + 1))
    w("simulation:")
    w("  t_end: %g" % t_end)
    w("  output_step: %g" % output_step)
    w("  integrator: hht")
    w("  hht: {alpha: -0.1, step: 1.0e-3}")
    w("  ida: {rtol: 1.0e-8, atol: 1.0e-8}")
    return "\n".join(lines) + "\n"


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=None, help="number of loops (default: write N = 40 and N = 4)")
    ap.add_argument("-o", "--output", default=None, help="output file (with --n)")
    args = ap.parse_args()
    if args.n is None:
        jobs = [(40, os.path.join(HERE, "nfourbar.yaml")), (4, os.path.join(HERE, "nfourbar_n4.yaml"))]
    else:
        jobs = [(args.n, args.output or os.path.join(HERE, "nfourbar_n%d.yaml" % args.n))]
    for n, path in jobs:
        with open(path, "w") as f:
            f.write(model_text(n))
        print("wrote", os.path.relpath(path))


if __name__ == "__main__":
    main()
