"""Shared by the app tests on tests/app/models/pendulum.yaml (test_dense_output,
test_erk, test_newton_tolerance, test_linear_solver): the program's runner, a simulate
that opens its results file, and the pendulum's reference.

models/pendulum.yaml: a 1 kg point mass on a massless 1 m link, pivot at the origin,
revolute about z, released at rest from the horizontal under gravity -9.81 y.
"""
import os
import subprocess

import h5py
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


def simulate(tmp_path, model, name, extra=()):
    """`mbdae simulate MODEL -o NAME --quiet EXTRA` in tmp_path, asserting exit 0; the
    results file opened for reading."""
    run_ok(["simulate", model, "-o", name, "--quiet", *extra], tmp_path)
    return h5py.File(tmp_path / name, "r")


PENDULUM_HHT = "  hht: {alpha: -0.1, step: 1.0e-3}\n"


def pendulum_with_hht(path, more):
    """The text of models/pendulum.yaml (at path) with `, MORE` added to its hht block."""
    text = open(path).read()
    assert PENDULUM_HHT in text
    return text.replace(PENDULUM_HHT, PENDULUM_HHT[:-2] + ", " + more + "}\n")


def assert_hht_key_error(tmp_path, text, what):
    """`mbdae simulate` of text (a pendulum_with_hht text with a bad value) exits 2 with
    the file and the hht block's line and `what` on stderr, and writes nothing."""
    line = text[:text.index("  hht:")].count("\n") + 1
    (tmp_path / "bad.yaml").write_text(text)
    p = run(["simulate", "bad.yaml", "-o", "bad.h5"], tmp_path)
    assert p.returncode == 2, p.stderr
    assert "bad.yaml:%d:" % line in p.stderr and what in p.stderr, p.stderr
    assert not (tmp_path / "bad.h5").exists()


def reference_angle(t):
    """The link's angle from +x (about z) at the times t (increasing, from 0):
    theta'' = -(g/L) cos theta from rest, by scipy's DOP853 at rtol 1e-13."""
    sol = solve_ivp(lambda _, y: [y[1], -G / L * np.cos(y[0])], (0, t[-1]), [0.0, 0.0],
                    method="DOP853", rtol=1e-13, atol=1e-14, dense_output=True)
    assert sol.success
    return sol.sol(t)[0]
