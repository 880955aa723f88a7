"""Dense output (`hht: {dense_output: true}`, `ida: {dense_output: true}`, `--dense-output`;
docs/dense-output.md) through the program and the Python package.

- models/pendulum.yaml, adaptive HHT: with dense output the rows every 0.01 s and every
  0.1 s come from the same steps (the rows at the common times are the same numbers), the
  last row is t_end, and the angle of every row is within the run's accuracy of scipy's
  DOP853 solution; without dense output the steps land on the rows (more steps);
- the model file's key: read, checked with file and line, written back by `convert`;
- gradients refuse it with exit 2; the Python package takes options["hht.dense_output"];
- IDA likewise: the same steps for both row spacings, the key, the attribute, gradients.
"""
import os
import sys

import h5py
import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(__file__), "..", "support"))
from pendulum_app import (assert_hht_key_error, pendulum_with_hht, reference_angle, run,  # noqa: E402
                          run_ok)

MODELS = os.environ["MBDAE_APP_MODELS"]
ADAPTIVE = ["--adaptive", "--tolerance", "1e-6", "--step", "1e-3"]


def simulate(tmp_path, name, extra):
    out = str(tmp_path / name)
    p = run(["simulate", os.path.join(MODELS, "pendulum.yaml"), "-o", out, "--quiet"] + extra,
            tmp_path)
    assert p.returncode == 0, p.stderr
    f = h5py.File(out, "r")
    return f


def test_rows_do_not_change_the_steps(tmp_path):
    fine = simulate(tmp_path, "fine.h5", ADAPTIVE + ["--dense-output"])
    coarse = simulate(tmp_path, "coarse.h5", ADAPTIVE + ["--dense-output", "--output-step", "0.1"])
    hit = simulate(tmp_path, "hit.h5", ADAPTIVE)
    with fine, coarse, hit:
        assert fine.attrs["hht_dense_output"] == 1 and hit.attrs["hht_dense_output"] == 0
        assert fine.attrs["status"] == "done" and fine["/time"][-1] == 0.5
        assert fine.attrs["steps_accepted"] == coarse.attrs["steps_accepted"]
        assert hit.attrs["steps_accepted"] > fine.attrs["steps_accepted"]
        t = fine["/time"][:]
        assert len(t) == 51 and len(coarse["/time"]) == 6
        common = [int(round(x / 0.01)) for x in coarse["/time"][:]]
        # The same steps; the row times k * 0.01 and k * 0.1 may differ in the last bit.
        assert np.max(np.abs(fine["/time"][:][common] - coarse["/time"][:])) <= 1e-15
        assert np.max(np.abs(fine["/q"][:][common] - coarse["/q"][:])) < 1e-13
        assert np.max(np.abs(fine["/v"][:][common] - coarse["/v"][:])) < 1e-12
        # The interpolated rows are about as accurate as step ends: measured 2.5e-4 rad
        # (dense, 74 steps) and 1.5e-4 rad (the steps landing on the rows, 101 steps).
        err = np.max(np.abs(np.unwrap(fine["/measures/angle"][:]) - reference_angle(t)))
        err_hit = np.max(np.abs(np.unwrap(hit["/measures/angle"][:]) - reference_angle(t)))
        print("largest angle error: dense %.2e (%d steps), steps on the rows %.2e (%d steps)" % (
            err, fine.attrs["steps_accepted"], err_hit, hit.attrs["steps_accepted"]))
        assert err < 5e-4, err
        # The rows' constraints: interpolated positions are off the circle by O(h^4).
        assert fine.attrs["max_position_violation"] < 1e-6


def test_dense_output_key_of_the_model_file(tmp_path):
    good = pendulum_with_hht(os.path.join(MODELS, "pendulum.yaml"),
                             "adaptive: true, tolerance: 1.0e-6, dense_output: true")
    (tmp_path / "p.yaml").write_text(good)
    p = run_ok(["simulate", "p.yaml", "-o", "p.h5", "--quiet"], tmp_path)
    with h5py.File(tmp_path / "p.h5", "r") as f:
        assert f.attrs["hht_dense_output"] == 1
    # The command line overrides it.
    run_ok(["simulate", "p.yaml", "-o", "n.h5", "--quiet", "--no-dense-output"], tmp_path)
    with h5py.File(tmp_path / "n.h5", "r") as f:
        assert f.attrs["hht_dense_output"] == 0
    run_ok(["convert", "p.yaml", "-o", "q.yaml"], tmp_path)
    assert "dense_output: true}" in (tmp_path / "q.yaml").read_text()
    p = run_ok(["simulate", "q.yaml", "-o", "q.h5", "--quiet"], tmp_path)
    with h5py.File(tmp_path / "q.h5", "r") as f, h5py.File(tmp_path / "p.h5", "r") as g:
        assert np.array_equal(f["/q"][:], g["/q"][:])
    # A value that is not a boolean: exit 2 with the file and line, nothing written.
    assert_hht_key_error(tmp_path, good.replace("dense_output: true", "dense_output: 3"),
                         "dense_output")


def test_gradients_refuse_dense_output_and_python_takes_it(tmp_path):
    quintic = os.path.join(MODELS, "..", "..", "..", "examples", "robot_energy", "quintic.yaml")
    text = open(quintic).read()
    assert "  hht: {" in text
    (tmp_path / "g.yaml").write_text(text.replace("  hht: {", "  hht: {dense_output: true, "))
    p = run(["gradient", "g.yaml"], tmp_path)
    assert p.returncode == 2 and "dense_output is not supported" in p.stderr, p.stderr
    import mbdae
    with mbdae.Model(os.path.join(MODELS, "pendulum.yaml")) as m:
        m.options["hht.adaptive"] = "true"
        m.options["hht.tolerance"] = "1e-6"
        m.options["hht.dense_output"] = "true"
        assert m.options["hht.dense_output"] is True
        m.solve()
        t = m.outputs.time
        assert len(t) == 51 and t[-1] == 0.5
        angle = np.unwrap(m.outputs.measure("angle"))
        assert np.max(np.abs(angle - reference_angle(t))) < 5e-4


def test_ida_dense_output(tmp_path):
    ida = ["--integrator", "ida", "--rtol", "1e-8", "--atol", "1e-10", "--dense-output"]
    fine = simulate(tmp_path, "fine.h5", ida)
    coarse = simulate(tmp_path, "coarse.h5", ida + ["--output-step", "0.1"])
    hit = simulate(tmp_path, "hit.h5", ida[:-1])
    with fine, coarse, hit:
        assert fine.attrs["ida_dense_output"] == 1 and hit.attrs["ida_dense_output"] == 0
        assert fine.attrs["status"] == "done" and fine["/time"][-1] == 0.5
        assert fine.attrs["steps_accepted"] == coarse.attrs["steps_accepted"]
        assert hit.attrs["steps_accepted"] > fine.attrs["steps_accepted"]
        common = [int(round(x / 0.01)) for x in coarse["/time"][:]]
        assert np.max(np.abs(fine["/q"][:][common] - coarse["/q"][:])) < 1e-13
        t = fine["/time"][:]
        err = np.max(np.abs(np.unwrap(fine["/measures/angle"][:]) - reference_angle(t)))
        err_hit = np.max(np.abs(np.unwrap(hit["/measures/angle"][:]) - reference_angle(t)))
        print("IDA largest angle error: dense %.2e (%d steps), steps on the rows %.2e (%d steps)" % (
            err, fine.attrs["steps_accepted"], err_hit, hit.attrs["steps_accepted"]))
        assert err < 1e-6, err
    text = open(os.path.join(MODELS, "pendulum.yaml")).read()
    old = "  ida: {rtol: 1.0e-8, atol: 1.0e-10}\n"
    assert old in text
    good = text.replace(old, "  ida: {rtol: 1.0e-8, atol: 1.0e-10, dense_output: true}\n").replace(
        "  integrator: hht\n", "  integrator: ida\n")
    (tmp_path / "p.yaml").write_text(good)
    p = run_ok(["simulate", "p.yaml", "-o", "p.h5", "--quiet"], tmp_path)
    with h5py.File(tmp_path / "p.h5", "r") as f:
        assert f.attrs["ida_dense_output"] == 1
    run_ok(["convert", "p.yaml", "-o", "q.yaml"], tmp_path)
    assert "dense_output: true}" in (tmp_path / "q.yaml").read_text()
    quintic = os.path.join(MODELS, "..", "..", "..", "examples", "robot_energy", "quintic.yaml")
    qt = open(quintic).read()
    assert "  integrator: hht\n" in qt
    (tmp_path / "g.yaml").write_text(qt.replace("  integrator: hht\n",
                                                "  integrator: ida\n  ida: {dense_output: true}\n"))
    p = run(["gradient", "g.yaml"], tmp_path)
    assert p.returncode == 2 and "ida dense_output is not supported" in p.stderr, p.stderr
