"""Finding the library, FreeDyn files, and models driven from several threads at once."""

import os
import subprocess
import sys
import threading

import numpy as np
import pytest

import mbdae
from conftest import OSCILLATOR, ROOT


def run_python(code, **env):
    e = dict(os.environ)
    e.update(env)
    return subprocess.run([sys.executable, "-c", code], env=e, capture_output=True, text=True)


def test_library_from_the_environment_variable():
    r = run_python("import mbdae; print(mbdae.library_path)", MBDAE_LIBRARY=mbdae.library_path)
    assert r.returncode == 0, r.stderr
    assert r.stdout.strip() == mbdae.library_path


def test_a_wrong_environment_variable_is_an_error():
    r = run_python("import mbdae", MBDAE_LIBRARY="/nonexistent/libmbdae.so")
    assert r.returncode != 0
    assert "ImportError" in r.stderr and "MBDAE_LIBRARY" in r.stderr
    assert "/nonexistent/libmbdae.so" in r.stderr


def test_freedyn_file():
    path = os.path.join(ROOT, "examples", "freedyn", "oscillator.fds")
    with mbdae.Model(path) as m:
        assert m.bodies == ["block"]
        assert m.joints == ["slide_x"]
        assert "x" in m.measures
        assert m.parameters["k"] == 40.0 and m.parameters["d"] == 0.8
        m.solve()
        assert len(m.outputs) > 1
        # released at its rest position x = 0.2 with v = 0.5: a damped oscillation
        t, x = m.outputs.time, m.outputs.q[:, 0]
        mass, k, d = 1.5, 40.0, 0.8
        wn = np.sqrt(k / mass)
        zeta = d / (2 * np.sqrt(k * mass))
        wd = wn * np.sqrt(1 - zeta ** 2)
        exact = 0.2 + 0.5 / wd * np.exp(-zeta * wn * t) * np.sin(wd * t)
        assert t[-1] == pytest.approx(3.0, abs=1e-12)
        assert np.max(np.abs(x - exact)) < 1e-4
        np.testing.assert_allclose(m.outputs.measure("x"), x - 0.2, atol=1e-14)


def run_oscillator(amplitude, results, key):
    with mbdae.Model(OSCILLATOR) as m:
        t = np.linspace(0, 10, 101)
        m.splines["drive"] = (t, amplitude * np.sin(3 * t))
        m.options["t_end"] = 3.0
        m.solve()
        # an error in this thread does not disturb the others' messages
        try:
            m.parameters["nothere"]
        except mbdae.ArgumentError as e:
            results[key + "_error"] = str(e)
        results[key] = m.outputs.q.copy()


def test_models_in_threads_at_once():
    serial = {}
    for k, a in enumerate((1.0, 2.0, 3.0)):
        run_oscillator(a, serial, str(k))
    parallel = {}
    threads = [threading.Thread(target=run_oscillator, args=(a, parallel, str(k)))
               for k, a in enumerate((1.0, 2.0, 3.0))]
    for th in threads:
        th.start()
    for th in threads:
        th.join()
    for k in range(3):
        np.testing.assert_array_equal(parallel[str(k)], serial[str(k)])
        assert "nothere" in parallel["%d_error" % k]
    # the response is linear in the force (k3 = 0)
    np.testing.assert_allclose(serial["1"], np.where(np.arange(7) == 0, 2 * serial["0"],
                                                     serial["0"]), rtol=0, atol=1e-12)
