"""Shared by the app tests on tests/app/models/pendulum.yaml (test_dense_output,
test_erk, test_newton_tolerance): the program's runner and the pendulum's reference.

models/pendulum.yaml: a 1 kg point mass on a massless 1 m link, pivot at the origin,
revolute about z, released at rest from the horizontal under gravity -9.81 y.
"""
import os
import subprocess

import numpy as np
from scipy.integrate import solve_ivp

G, L = 9.81, 1.0


def run(args, cwd):
    """`mbdae ARGS` (the program of $MBDAE_BIN) in cwd, output captured."""
    return subprocess.run([os.environ["MBDAE_BIN"]] + args, cwd=cwd, capture_output=True,
                          text=True, timeout=100)


def run_ok(args, cwd):
    """run(args, cwd), asserting that it exits 0 (its stderr otherwise)."""
    p = run(args, cwd)
    assert p.returncode == 0, p.stderr
    return p


def reference_angle(t):
    """The link's angle from +x (about z) at the times t (increasing, from 0):
    theta'' = -(g/L) cos theta from rest, by scipy's DOP853 at rtol 1e-13."""
    sol = solve_ivp(lambda _, y: [y[1], -G / L * np.cos(y[0])], (0, t[-1]), [0.0, 0.0],
                    method="DOP853", rtol=1e-13, atol=1e-14, dense_output=True)
    assert sol.success
    return sol.sol(t)[0]
