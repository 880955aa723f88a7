"""IDA through the singular positions of the parallelogram four-bar (issue 11, part 1):
verification/singular/fourbar.yaml (1 m links of 1 kg, the crank tops at 1 m/s at t = 0,
under gravity; all links horizontal, the loop's Jacobian singular, 10 times in 10 s).

At rtol = atol = 1e-8 IDA used to stop at the first passage (IDA_CONV_FAIL at t = 0.708
with h = 4e-21, output every 0.2 s); at 1e-10 likewise. Each run must now reach 10 s
through all 10 passages, stay on the parallelogram branch (the coupler does not turn,
the cranks keep equal angles) and meet the crank angle of an independent reference:
phi'' = 6 g / (5 L) sin phi (the one-degree-of-freedom equation of the branch),
integrated here by scipy's DOP853 at rtol = 1e-13.

Environment: MBDAE_BIN (the program), MBDAE_SINGULAR_MODEL (the model file).
"""
import math
import os
import subprocess

import h5py
import numpy as np
import pytest
from scipy import integrate

MBDAE = os.environ.get("MBDAE_BIN", "mbdae")
MODEL = os.environ.get("MBDAE_SINGULAR_MODEL", os.path.join(
    os.path.dirname(__file__), "..", "..", "verification", "singular", "fourbar.yaml"))
K = 6.0 * 9.81 / 5.0  # phi'' = K sin phi, L = 1 m


def reference_phi(t):
    sol = integrate.solve_ivp(lambda _, s: [s[1], K * math.sin(s[0])], (0.0, 10.0), [0.0, 1.0],
                              method="DOP853", rtol=1e-13, atol=1e-14, dense_output=True)
    return sol.sol(t)[0]


def angle_about_z(quat):
    return 2.0 * np.arctan2(quat[:, 3], quat[:, 0])


def wrap(a):
    return (a + np.pi) % (2.0 * np.pi) - np.pi


# tolerance, output step, bound of the crank-angle error at 10 s (rad): measured 9.7e-5
# (1e-8, rows every 0.01 s), 6.2e-5 (1e-8, every 0.2 s), 5.9e-8 and 2.4e-7 (1e-10).
CASES = [(1e-8, 0.01, 1e-3), (1e-8, 0.2, 1e-3), (1e-10, 0.01, 1e-5), (1e-10, 0.2, 1e-5)]


@pytest.mark.parametrize("tol,output_step,bound", CASES,
                         ids=["rtol%g-rows%g" % (c[0], c[1]) for c in CASES])
def test_ida_passes_every_singular_position_on_the_parallelogram_branch(tmp_path, tol, output_step,
                                                                         bound):
    out = tmp_path / "fourbar.h5"
    p = subprocess.run([MBDAE, "simulate", MODEL, "-o", str(out), "--quiet", "--integrator", "ida",
                        "--rtol", repr(tol), "--atol", repr(tol), "--output-step", repr(output_step)],
                       capture_output=True, text=True, timeout=300)
    assert p.returncode == 0, p.stderr
    with h5py.File(out, "r") as f:
        status = f.attrs["status"]
        assert (status.decode() if isinstance(status, bytes) else status) == "done"
        t = f["time"][()]
        phi = 0.5 * math.pi - np.unwrap(f["measures/phi0"][()])
        coupler = angle_about_z(f["bodies/coupler0/orientation"][()])
        spread = angle_about_z(f["bodies/crank1/orientation"][()]) - angle_about_z(
            f["bodies/crank0/orientation"][()])
    assert t[-1] == pytest.approx(10.0, abs=1e-12)
    # The 10 passages: phi = pi/2 + j pi for j = 0..9, by the run's own crank angle.
    passages = np.floor((phi - 0.5 * math.pi) / math.pi)
    assert passages[0] == -1 and passages[-1] == 9
    assert np.all(np.diff(passages) >= 0)
    # The parallelogram branch: the coupler keeps its orientation, the cranks their relation.
    assert np.max(np.abs(wrap(coupler))) < 1e-6
    assert np.max(np.abs(wrap(spread))) < 1e-6
    err = abs(phi[-1] - reference_phi(np.array([10.0]))[0])
    assert err < bound, "crank-angle error at 10 s: %.3e rad" % err
