#!/usr/bin/env python3
"""Writes flyball.yaml: IFToMM benchmark A05, the stiff flyball governor.

Geometry (see README.md for the sources and the assumptions):
  world z up along the shaft, gravity 9.81 m/s^2 in -z;
  shaft: box 0.01 x 0.01 x 1 m (along z) from z = 0 to z = 1, revolute joint to ground
    at its lower end (z = 0) about world z, turned at the imposed speed omega (motion
    joint on its angle);
  slider: 0.1 m cube on the shaft (prismatic joint along the shaft), centre at z = s,
    s0 = 0.5 m; it turns with the shaft;
  rods: boxes 1 x 0.01 x 0.01 m, hinged at the top of the shaft at x = +-0.05 m
    (points A, B) about the tangential axis, pointing outwards and downwards at
    alpha0 = 30 deg below the horizontal; rod B is rod A turned by pi about the shaft;
  two 5 kg point masses at the outer ends of the rods (bodies of zero inertia welded
    to the rods);
  two spring-dampers (K, C, rest length 0.5 m) from the slider's side points
    (+-0.05, 0, 0) to the rods' midpoints; at t = 0 the hinge, the slider point and
    the rod midpoint form an equilateral triangle of side 0.5 m, so the springs are at
    their rest length;
  initial velocities: the rigid rotation at omega about z (everything else at rest).
Density 3000 kg/m^3 for shaft, rods and slider (masses 0.3, 0.3, 3 kg).
"""
import math
import os

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))

P = dict(K=8.0e5, C=4.0e4, l0=0.5, s0=0.5, alpha0=30.0, omega=2 * math.pi, rho=3000.0,
         m_ball=5.0, L_rod=1.0, L_shaft=1.0, w=0.01, a_slider=0.1, e=0.05, g=9.81)


def Ry(a):
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])


def Rz(a):
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])


def Rx(a):
    c, s = math.cos(a), math.sin(a)
    return np.array([[1, 0, 0], [0, c, -s], [0, s, c]])


def num(x):
    """A float as text, rounding-level values (below 1e-14) written as 0."""
    x = float(x)
    return "0" if abs(x) < 1e-14 else repr(x)


def mat(R):
    return "{matrix: [%s]}" % ", ".join("[%s]" % ", ".join(num(x) for x in row) for row in R)


def vec(v):
    return "[%s]" % ", ".join(num(x) for x in v)


def geometry(p=P):
    """Initial positions/orientations of every body (world), used here and by run.py."""
    a = math.radians(p["alpha0"])
    top = np.array([0.0, 0.0, p["L_shaft"]])
    bodies = {}
    bodies["shaft"] = (np.array([0.0, 0.0, p["L_shaft"] / 2]), np.eye(3))
    bodies["slider"] = (np.array([0.0, 0.0, p["s0"]]), np.eye(3))
    for name, turn in (("rodA", 0.0), ("rodB", math.pi)):
        R = Rz(turn) @ Ry(a)             # body x along the rod, outwards and down
        hinge = top + Rz(turn) @ np.array([p["e"], 0.0, 0.0])
        bodies[name] = (hinge + R @ np.array([p["L_rod"] / 2, 0, 0]), R)
        bodies["ball" + name[-1]] = (hinge + R @ np.array([p["L_rod"], 0, 0]), R)
    return bodies


def main():
    p = P
    b = geometry()
    omega = p["omega"]
    hinge_axis = Rx(-math.pi / 2)                # marker z along world y (axis of rod A)
    lines = [
        "# IFToMM benchmark A05: stiff flyball governor. Written by make_model.py; edit that.",
        "# Shaft along world z (turned at the imposed speed omega), slider on the shaft,",
        "# two rods hinged at the shaft top, 5 kg point masses at the rod ends, spring-dampers",
        "# from the slider's sides to the rod midpoints. Gravity -z. See README.md.",
        "format: 1",
        "name: stiff flyball governor (IFToMM A05)",
        "gravity: [0, 0, -9.81]",
        "parameters:",
        "  K: 8.0e5          # spring stiffness, N/m",
        "  C: 4.0e4          # spring damping, N s/m",
        "  l0: 0.5           # spring rest length, m",
        "  omega: 2*pi       # imposed shaft speed, rad/s",
        "  rho: 3000         # density of shaft, rods and slider, kg/m^3",
        "  m_ball: 5         # point masses, kg",
        "bodies:",
        "  - name: shaft",
        "    geometry: {shape: box, size: [0.01, 0.01, 1.0], density: rho}",
        "    position: %s" % vec(b["shaft"][0]),
        "    angular_velocity: [0, 0, omega]",
        "    markers:",
        "      base: {position: [0, 0, -0.5]}",
        "      A: {position: [0.05, 0, 0.5], orientation: %s}" % mat(hinge_axis),
        "      B: {position: [-0.05, 0, 0.5], orientation: %s}" % mat(Rz(math.pi) @ hinge_axis),
        "  - name: slider",
        "    geometry: {shape: box, size: [0.1, 0.1, 0.1], density: rho}",
        "    position: %s" % vec(b["slider"][0]),
        "    angular_velocity: [0, 0, omega]",
        "    markers:",
        "      E: {position: [0.05, 0, 0]}",
        "      F: {position: [-0.05, 0, 0]}",
    ]
    for side in "AB":
        r, R = b["rod" + side]
        rb, _ = b["ball" + side]
        v = np.cross([0, 0, omega], r)
        vb = np.cross([0, 0, omega], rb)
        # hinge marker: in rod axes, the orientation whose world axes equal the shaft marker's
        shaft_marker = (Rz(math.pi) if side == "B" else np.eye(3)) @ hinge_axis
        lines += [
            "  - name: rod%s" % side,
            "    geometry: {shape: box, size: [1.0, 0.01, 0.01], density: rho}",
            "    position: %s" % vec(r),
            "    orientation: %s" % mat(R),
            "    velocity: %s" % vec(v),
            "    angular_velocity: [0, 0, omega]",
            "    markers:",
            "      hinge: {position: [-0.5, 0, 0], orientation: %s}" % mat(R.T @ shaft_marker),
            "      tip: {position: [0.5, 0, 0]}",
            "  - name: ball%s" % side,
            "    mass: m_ball",
            "    inertia: [0, 0, 0]",
            "    position: %s" % vec(rb),
            "    orientation: %s" % mat(R),
            "    velocity: %s" % vec(vb),
            "    angular_velocity: [0, 0, omega]",
        ]
    lines += [
        "measures:",
        "  - {name: s, type: translational, i: slider.cm, j: ground.O, component: z, frame: world}",
        "  - {name: s_dot, type: translational, i: slider.cm, j: ground.O, component: z, frame: world, quantity: velocity}",
        "  - {name: shaft_angle, type: rotational, i: shaft.cm, j: ground.O, axis: z}",
        "  - {name: zA, type: translational, i: ballA.cm, j: ground.O, component: z, frame: world}",
        "  - {name: zB, type: translational, i: ballB.cm, j: ground.O, component: z, frame: world}",
        "  - {name: springA, type: translational, i: rodA.cm, j: slider.E, component: distance}",
        "joints:",
        "  - {name: bearing, type: revolute, i: shaft.base, j: ground.O}",
        "  - {name: drive, type: motion, measure: shaft_angle, value: omega*t}",
        "  - {name: guide, type: prismatic, i: slider.cm, j: shaft.cm}",
        "  - {name: hingeA, type: revolute, i: rodA.hinge, j: shaft.A}",
        "  - {name: hingeB, type: revolute, i: rodB.hinge, j: shaft.B}",
        "  - {name: weldA, type: fixed, i: ballA.cm, j: rodA.tip}",
        "  - {name: weldB, type: fixed, i: ballB.cm, j: rodB.tip}",
        "forces:",
        "  - {name: spring_A, type: spring_damper, i: rodA.cm, j: slider.E, stiffness: K, damping: C, free_length: l0}",
        "  - {name: spring_B, type: spring_damper, i: rodB.cm, j: slider.F, stiffness: K, damping: C, free_length: l0}",
        "simulation:",
        "  t_end: 10.0",
        "  output_step: 0.01",
        "  integrator: ida",
        "  ida: {rtol: 1.0e-10, atol: 1.0e-10}",
        "  hht: {alpha: -0.3, step: 1.0e-3}",
    ]
    with open(os.path.join(HERE, "flyball.yaml"), "w") as f:
        f.write("\n".join(lines) + "\n")
    print("wrote flyball.yaml")


if __name__ == "__main__":
    main()
