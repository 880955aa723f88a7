#!/usr/bin/env python3
"""The ball chain of issue 12 as an mbdae model file.

An open chain of N rods, each 0.1 m long, 1 kg, with the inertia of a solid box
0.1 x 0.01 x 0.01 m (Ixx = m (b^2 + c^2) / 12 about the rod axis x, Iyy = Izz =
m (a^2 + c^2) / 12), joined by spherical joints: rod 1 to the ground at the origin,
rod k to the far end of rod k - 1. Released at rest straight along +x (rod k's
centre at x = (k - 1/2) 0.1 m), gravity 9.81 m/s^2 in -y, 1 s.

    /usr/bin/python3 bench/scenes/ball_chain.py N [-o FILE] [--t-end T] [--output-step H]

writes the model to FILE (default: standard output). The same scene is meant for
every benchmark that uses the chain (the phase timings in bench/phases/, the side-by-side
benchmark in bench/peers/): import `write_chain` or `chain_yaml` from here rather than
writing another generator.
"""
import argparse
import sys

LENGTH = 0.1      # m
MASS = 1.0        # kg
WIDTH = 0.01      # m, the box's two short sides
GRAVITY = 9.81    # m/s^2, along -y


def inertia():
    """Principal moments of the box about its centre, body axes (x along the rod)."""
    ixx = MASS * (WIDTH ** 2 + WIDTH ** 2) / 12
    iyy = MASS * (LENGTH ** 2 + WIDTH ** 2) / 12
    return ixx, iyy, iyy


def chain_yaml(n, t_end=1.0, output_step=None, integrator=None, extra_simulation=""):
    """The model file text of the chain of n rods."""
    if n < 1:
        raise ValueError("the chain needs at least one rod, got %d" % n)
    if output_step is None:
        output_step = t_end / 100
    ixx, iyy, izz = inertia()
    half = LENGTH / 2
    out = []
    w = out.append
    w("# Ball chain of %d rods (bench/scenes/ball_chain.py): %g m, %g kg, box %g x %g x %g m,\n"
      % (n, LENGTH, MASS, LENGTH, WIDTH, WIDTH))
    w("# spherical joints, the first to the ground; at rest along +x; gravity -%g y.\n" % GRAVITY)
    w("format: 1\n")
    w("name: ball_chain_%d\n" % n)
    w("gravity: [0, %r, 0]\n" % -GRAVITY)
    w("bodies:\n")
    for k in range(1, n + 1):
        x = (k - 0.5) * LENGTH
        w("  - {name: rod%d, mass: %r, inertia: [%r, %r, %r], position: [%.12g, 0, 0], "
          "orientation: [1, 0, 0, 0], markers: {A: {position: [%r, 0, 0]}, B: {position: [%r, 0, 0]}}}\n"
          % (k, MASS, ixx, iyy, izz, x, -half, half))
    w("joints:\n")
    w("  - {name: ball1, type: spherical, i: rod1.A, j: ground.O}\n")
    for k in range(2, n + 1):
        w("  - {name: ball%d, type: spherical, i: rod%d.A, j: rod%d.B}\n" % (k, k, k - 1))
    w("simulation:\n")
    w("  t_end: %r\n" % t_end)
    w("  output_step: %r\n" % output_step)
    if integrator:
        w("  integrator: %s\n" % integrator)
    if extra_simulation:
        w(extra_simulation)
    return "".join(out)


def write_chain(path, n, **kwargs):
    with open(path, "w") as f:
        f.write(chain_yaml(n, **kwargs))


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("n", type=int, help="number of rods (>= 1)")
    p.add_argument("-o", "--output", help="model file to write (default: standard output)")
    p.add_argument("--t-end", type=float, default=1.0)
    p.add_argument("--output-step", type=float, default=None, help="default t_end / 100")
    a = p.parse_args(argv)
    if a.n < 1:
        p.error("n must be >= 1")
    text = chain_yaml(a.n, t_end=a.t_end, output_step=a.output_step)
    if a.output:
        with open(a.output, "w") as f:
            f.write(text)
    else:
        sys.stdout.write(text)


if __name__ == "__main__":
    main()
