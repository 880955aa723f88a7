#!/usr/bin/env python3
"""Acceptance 3: a crank driven by a motion constraint on its rotation angle, once with
an expression of t (crank_expression.yaml) and once with a natural cubic spline of t
(crank_spline.yaml), holds the imposed angle to 1e-10, and the motion's multiplier is
the driving torque of inverse dynamics by hand.

The crank turns about the z axis of ground.O; its centre of mass is r = 0.3 m from the
axis, m = 2 kg, Jzz = 0.03 kg m^2 about the centre of mass, gravity 9.81 m/s^2 along -y.
With the imposed angle f(t) the torque about z that drives it is (Euler's equation about
the fixed axis)
    tau = (Jzz + m r^2) f''(t) + m g r cos(f(t)).
The motion equation is C = phi(q) - f(t) = 0, whose virtual work -lambda dC = -lambda dphi
makes its generalised force the torque -lambda about z: lambda_drive = -tau.
Requirements: max |phi - f| <= 1e-10; max |lambda + tau| / max |tau| <= 1e-6.
Writes results.md (here, or in $MBDAE_VERIFICATION_OUT); exits 1 if a requirement fails.
"""
import argparse
import math
import os
import re
import sys

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
OUT = os.environ.get("MBDAE_VERIFICATION_OUT") or HERE
os.makedirs(OUT, exist_ok=True)
sys.path.insert(0, os.path.dirname(HERE))
sys.path.insert(0, HERE)
import mbdae_run as mr  # noqa: E402
from natural_spline import natural_spline  # noqa: E402

M, R, JZZ, G = 2.0, 0.3, 0.03, 9.81


def expression_motion(t):
    return 0.5 * t**2 + 0.3 * np.sin(2 * t), 1.0 - 1.2 * np.sin(2 * t)


def spline_motion():
    with open(os.path.join(HERE, "crank_spline.yaml")) as f:
        text = f.read()
    xs = [float(v) for v in re.search(r"\n    x: \[(.*)\]", text).group(1).split(",")]
    ys = [float(v) for v in re.search(r"\n    y: \[(.*)\]", text).group(1).split(",")]
    s = natural_spline(xs, ys)

    def motion(t):
        v, _, d2 = s(t)
        return v, d2
    return motion


def lambda_of(r, name):
    names = [n.decode() if isinstance(n, bytes) else str(n) for n in r["/lambda_names"]]
    return r["/lambda"][:, names.index(name)]


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    mr.add_mbdae_argument(ap)
    args = ap.parse_args()
    runner = mr.Runner(mr.find_mbdae(args.mbdae), args.keep)
    checks, rows = [], []
    for model, motion in (("crank_expression.yaml", expression_motion), ("crank_spline.yaml", spline_motion())):
        path, _ = runner.simulate(os.path.join(HERE, model), [], "crank")
        r = mr.Results(path)
        t = r.time
        f, f2 = motion(t)
        phi = r["/measures/phi"]
        angle_err = float(np.max(np.abs(phi - f)))
        tau = (JZZ + M * R * R) * f2 + M * G * R * np.cos(f)
        lam = lambda_of(r, "drive.motion")
        torque_err = float(np.max(np.abs(lam + tau))) / float(np.max(np.abs(tau)))
        rows.append("| %s | %d | %.3e | %.3e |" % (model, len(t), angle_err, torque_err))
        checks.append(("%s: max abs(phi - f) = %.3e <= 1e-10" % (model, angle_err), angle_err <= 1e-10))
        checks.append(("%s: max abs(lambda + tau) / max abs(tau) = %.3e <= 1e-6" % (model, torque_err),
                       torque_err <= 1e-6))
    md = ["# Crank driven by a motion constraint: results\n",
          "Produced by `verification/crank_motion/run.py` (IDA, rtol 1e-10, atol 1e-12, 3 s; the "
          "angle turns past pi, the output is unwrapped).\n",
          "| model | rows | max abs angle error (rad) | torque: max abs(lambda + tau) / max abs(tau) |",
          "|---|---|---|---|"] + rows + [""]
    return mr.finish_checks(runner, checks, md, OUT)


if __name__ == "__main__":
    sys.exit(main())
