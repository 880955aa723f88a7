"""Objectives over an angle that turns several times (sensitivities/model_objectives.h):
the values and every method's gradient count the turns as the results file's rows do.

Model: tests/app/models/turning_rotor.yaml, angle(t) = tau t^2 / (2 J) (16 rad at
t = 2 s with J = 0.5, tau = 4). Closed forms, with a = angle(2) = 16:
  final_angle  = a,               d/dJ = -a / J,        d/dtau = a / tau
  final_square = a^2,             d/dJ = -2 a^2 / J,    d/dtau = 2 a^2 / tau
  mean_square  = int_0^2 (tau t^2 / 2J)^2 dt = tau^2 2^5 / (20 J^2),
                 d/dJ = -2 mean_square / J, d/dtau = 2 mean_square / tau.
Constant acceleration is integrated exactly by HHT's Newmark formulas; the integral by
the trapezoidal rule over 2000 steps (relative error ~ h^2 / ... about 1e-6). Before the
turn count, the terminal values were the angle in (-pi, pi] (-2.85 rad here).
Run by CTest (app.objective_turns) with MBDAE_BIN and MBDAE_APP_MODELS set.
"""
import json
import os
import subprocess

import h5py
import numpy as np
import pytest

MBDAE = os.environ.get("MBDAE_BIN", "build/mbdae")
MODELS = os.environ.get("MBDAE_APP_MODELS", "tests/app/models")
MODEL = os.path.join(MODELS, "turning_rotor.yaml")
J, TAU, A = 0.5, 4.0, 16.0
MEAN = TAU**2 * 2**5 / (20 * J**2)
EXACT = {
    "final_angle": (A, {"J": -A / J, "tau": A / TAU}),
    "final_square": (A**2, {"J": -2 * A**2 / J, "tau": 2 * A**2 / TAU}),
    "mean_square": (MEAN, {"J": -2 * MEAN / J, "tau": 2 * MEAN / TAU}),
}


def gradient(*args):
    p = subprocess.run([MBDAE, "gradient", MODEL, "--json", *args], capture_output=True, text=True)
    assert p.returncode == 0, p.stderr
    return json.loads(p.stdout)


# (method and options, relative tolerance of values and gradients against the closed forms)
CASES = [
    (("--method", "adjoint"), 2e-6),
    (("--method", "forward"), 2e-6),
    (("--method", "fd"), 1e-5),
    (("--method", "adjoint", "--integrator", "ida", "--rtol", "1e-10", "--atol", "1e-10"), 1e-5),
    (("--method", "forward", "--integrator", "ida", "--rtol", "1e-10", "--atol", "1e-10"), 1e-5),
]


@pytest.mark.parametrize("args,tol", CASES, ids=[" ".join(c[0]) for c in CASES])
def test_values_and_gradients_count_turns(args, tol):
    d = gradient(*args)
    for name, (value, grad) in EXACT.items():
        o = d["objectives"][name]
        assert o["value"] == pytest.approx(value, rel=tol), (name, o["value"])
        for p, g in grad.items():
            assert o["gradient"][p] == pytest.approx(g, rel=tol), (name, p, o["gradient"][p])


def test_terminal_value_equals_the_results_files_last_row(tmp_path):
    out = tmp_path / "turns.h5"
    p = subprocess.run([MBDAE, "simulate", MODEL, "-o", str(out), "--quiet"], capture_output=True, text=True)
    assert p.returncode == 0, p.stderr
    with h5py.File(out) as f:
        last = f["/measures/angle"][-1]
        assert last == pytest.approx(A, rel=1e-9)
        assert f["/objectives/final_angle"].attrs["value"] == pytest.approx(last, rel=1e-12)
