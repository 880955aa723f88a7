"""HHT's Newton threshold (`hht: {newton_tolerance}`, `--newton-tolerance`,
options["hht.newton_tolerance"]; docs/hht.md, "Newton threshold") through the program
and the Python package.

- models/pendulum.yaml, fixed steps h = 1e-3: 1e-10 takes fewer Newton iterations than
  the default 1e-12 (measured 1741 against 2216) and its rows stay within 1e-7 rad of the
  default run's (measured 3.6e-9 rad; the run's own error against scipy's DOP853 solution
  is 5.9e-6 rad); the attribute hht_newton_tolerance records the threshold;
- the model file's key: read, overridden by the command line, checked with file and line
  (exit 2, nothing written), written back by `convert` only when not the default;
- `gradient` ignores a looser threshold (its runs keep 1e-12, and its results file says
  so): the same gradient;
- the Python package takes options["hht.newton_tolerance"].
"""
import json
import os
import sys

import h5py
import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(__file__), "..", "support"))
from pendulum_app import (assert_hht_key_error, pendulum_with_hht, reference_angle, run,  # noqa: E402
                          run_ok, simulate)

MODELS = os.environ["MBDAE_APP_MODELS"]
PENDULUM = os.path.join(MODELS, "pendulum.yaml")


def test_looser_threshold_fewer_iterations_same_rows(tmp_path):
    default = simulate(tmp_path, PENDULUM, "d.h5")
    loose = simulate(tmp_path, PENDULUM, "l.h5", ["--newton-tolerance", "1e-10"])
    with default, loose:
        assert default.attrs["hht_newton_tolerance"] == 1e-12
        assert loose.attrs["hht_newton_tolerance"] == 1e-10
        assert loose.attrs["steps_accepted"] == default.attrs["steps_accepted"] == 500
        nd, nl = default.attrs["newton_iterations"], loose.attrs["newton_iterations"]
        t = default["/time"][:]
        ref = reference_angle(t)
        ad = np.unwrap(default["/measures/angle"][:])
        al = np.unwrap(loose["/measures/angle"][:])
        err = np.max(np.abs(ad - ref))
        diff = np.max(np.abs(al - ad))
        print("Newton iterations %d (1e-12) and %d (1e-10); largest angle error %.2e rad, "
              "rows apart by %.2e rad" % (nd, nl, err, diff))
        assert nl < 0.85 * nd
        assert err > 3e-6
        assert diff < 1e-7


def test_model_file_key_override_errors_and_convert(tmp_path):
    good = pendulum_with_hht(PENDULUM, "newton_tolerance: 1.0e-10")
    (tmp_path / "p.yaml").write_text(good)
    with simulate(tmp_path, "p.yaml", "p.h5") as f, \
            simulate(tmp_path, PENDULUM, "c.h5", ["--newton-tolerance", "1e-10"]) as c:
        assert f.attrs["hht_newton_tolerance"] == 1e-10
        assert np.array_equal(f["/q"][:], c["/q"][:])
    with simulate(tmp_path, "p.yaml", "o.h5", ["--newton-tolerance", "1e-12"]) as f, \
            simulate(tmp_path, PENDULUM, "d.h5") as d:
        assert f.attrs["hht_newton_tolerance"] == 1e-12
        assert np.array_equal(f["/q"][:], d["/q"][:])
    run_ok(["convert", "p.yaml", "-o", "q.yaml"], tmp_path)
    assert "newton_tolerance: 1e-10}" in (tmp_path / "q.yaml").read_text()
    run_ok(["convert", PENDULUM, "-o", "r.yaml"], tmp_path)
    assert "newton_tolerance" not in (tmp_path / "r.yaml").read_text()
    for bad_value, what in (("0", "must be > 0"), ("1.5", "must be below 1"), ("abc", "newton_tolerance")):
        assert_hht_key_error(tmp_path, good.replace("newton_tolerance: 1.0e-10",
                                                    "newton_tolerance: " + bad_value), what)
    p = run(["simulate", PENDULUM, "-o", "bad.h5", "--newton-tolerance", "0"], tmp_path)
    assert p.returncode == 2 and "newton_tolerance must be in (0, 1)" in p.stderr, p.stderr
    assert not (tmp_path / "bad.h5").exists()


def test_gradient_keeps_the_default_threshold(tmp_path):
    demo = os.path.join(MODELS, "gradient_demo.yaml")
    text = open(demo).read()
    old = "hht: {step: 1.0e-3}"
    assert old in text
    (tmp_path / "g.yaml").write_text(text.replace(old, "hht: {step: 1.0e-3, newton_tolerance: 1.0e-4}"))

    def gradient(model, out):
        p = run_ok(["gradient", model, "--json", "--wrt", "k,c", "-o", out], tmp_path)
        return json.loads(p.stdout)["objectives"]

    assert gradient("g.yaml", "g.h5") == gradient(demo, "d.h5")
    # The forward run's file records the threshold the run used.
    with h5py.File(tmp_path / "g.h5", "r") as f:
        assert f.attrs["hht_newton_tolerance"] == 1e-12


def test_python_option(tmp_path):
    import mbdae
    with mbdae.Model(PENDULUM) as m:
        assert m.options["hht.newton_tolerance"] == 1e-12
        m.options["hht.newton_tolerance"] = 1e-10
        assert m.options["hht.newton_tolerance"] == 1e-10
        m.solve()
        t = m.outputs.time
        angle = np.unwrap(m.outputs.measure("angle"))
        assert len(t) == 51 and np.max(np.abs(angle - reference_angle(t))) < 1e-3
