"""The explicit Runge-Kutta integrator (`integrator: erk`, docs/erk.md) through the program
and the Python package.

- models/pendulum.yaml with --integrator erk: the angle at every row against scipy's DOP853
  solution of theta'' = -(g/L) cos theta at rtol 1e-13, the constraints and the energy of
  every row, the attributes, and a and lambda of the rows equal to the `solved` ones;
- the model file's `erk:` block: read, checked with file and line, written back by
  `mbdae convert`;
- a stiff spring (k = 1e30) ends with exit 3 and a message naming hht or ida, the file kept;
- gradients refuse erk; the Python package takes options["integrator"] = "erk".
"""
import os
import sys

import h5py
import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(__file__), "..", "support"))
from pendulum_app import reference_angle, run, run_ok  # noqa: E402

MODELS = os.environ["MBDAE_APP_MODELS"]


def test_pendulum_rows_against_the_reference(tmp_path):
    out = str(tmp_path / "erk.h5")
    p = run(["simulate", os.path.join(MODELS, "pendulum.yaml"), "--integrator", "erk",
             "--rtol", "1e-10", "--atol", "1e-10", "-o", out], tmp_path)
    assert p.returncode == 0, p.stderr
    assert "integrator:            erk (explicit Runge-Kutta Dormand-Prince 5(4)" in p.stdout
    with h5py.File(out, "r") as f:
        a = f.attrs
        assert a["integrator"] == "erk" and a["status"] == "done"
        assert a["erk_rtol"] == 1e-10 and a["erk_atol"] == 1e-10
        assert a["erk_max_steps"] == 100000000 and a["erk_min_step"] == 0
        assert a["steps_accepted"] >= 50  # at least one step per row
        # 6 factorisations per step (the last stage is the next step's first), one per
        # output row after the first (a and lambda at the projected state) and one for
        # the initial step size.
        assert a["factorizations"] == 6 * (a["steps_accepted"] + a["steps_rejected"]) + 50 + 1
        t = f["/time"][:]
        angle = np.unwrap(f["/measures/angle"][:])
        # Measured 4.4e-12 rad over the 51 rows (51 steps: one per row).
        err = np.max(np.abs(angle - reference_angle(t)))
        assert err < 1e-9, err
        # Projection: both constraint levels at every row (measured 2.2e-16, 2.0e-13).
        assert a["max_position_violation"] < 1e-13
        assert a["max_velocity_violation"] < 1e-12
        E = f["/energy/kinetic"][:] + f["/energy/potential"][:]
        assert np.max(np.abs(E - E[0])) < 1e-8  # measured 1.5e-10 J
        lam_erk, acc_erk = f["/lambda"][:], f["/a"][:]
    # a and lambda of the rows are the acceleration-level solution at the rows' states:
    # the same as the `solved` rows of the same run.
    out2 = str(tmp_path / "erk_solved.h5")
    p = run(["simulate", os.path.join(MODELS, "pendulum.yaml"), "--integrator", "erk",
             "--rtol", "1e-10", "--atol", "1e-10", "--output-accelerations", "solved", "-o",
             out2], tmp_path)
    assert p.returncode == 0, p.stderr
    with h5py.File(out2, "r") as f:
        assert np.array_equal(f["/lambda"][:], lam_erk)
        assert np.array_equal(f["/a"][:], acc_erk)


def test_erk_block_of_the_model_file(tmp_path):
    text = open(os.path.join(MODELS, "pendulum.yaml")).read()
    assert "  integrator: hht\n" in text
    good = text.replace("  integrator: hht\n",
                        "  integrator: erk\n  erk: {rtol: 1.0e-9, atol: 1.0e-11, max_steps: 1000, "
                        "max_step: 0.02}\n")
    (tmp_path / "p.yaml").write_text(good)
    p = run_ok(["simulate", "p.yaml", "-o", "p.h5", "--quiet"], tmp_path)
    with h5py.File(tmp_path / "p.h5", "r") as f:
        assert f.attrs["integrator"] == "erk"
        assert f.attrs["erk_rtol"] == 1e-9 and f.attrs["erk_atol"] == 1e-11
        assert f.attrs["erk_max_steps"] == 1000 and f.attrs["erk_max_step"] == 0.02
    # Written back by convert and read again with the same settings.
    run_ok(["convert", "p.yaml", "-o", "q.yaml"], tmp_path)
    written = (tmp_path / "q.yaml").read_text()
    assert "integrator: erk" in written and "erk: {rtol: 1e-09, atol: 1e-11, max_steps: 1000, " \
        "max_step: 0.02}" in written, written
    p = run_ok(["simulate", "q.yaml", "-o", "q.h5", "--quiet"], tmp_path)
    with h5py.File(tmp_path / "q.h5", "r") as f, h5py.File(tmp_path / "p.h5", "r") as g:
        assert np.array_equal(f["/q"][:], g["/q"][:])
    # Bad values: exit 2 with the file and line of the value, nothing written.
    line = good[:good.index("  erk:")].count("\n") + 1
    for bad, what in (("rtol: 1.0e-9", "rtol: -1"), ("max_steps: 1000", "max_steps: 2.5"),
                      ("max_step: 0.02", "max_stp: 0.02")):
        (tmp_path / "bad.yaml").write_text(good.replace(bad, what))
        p = run(["simulate", "bad.yaml", "-o", "bad.h5"], tmp_path)
        assert p.returncode == 2, p.stderr
        assert "bad.yaml:%d:" % line in p.stderr, p.stderr
        assert not (tmp_path / "bad.h5").exists()
    p = run(["simulate", "p.yaml", "--integrator", "erk", "--rtol", "0"], tmp_path)
    assert p.returncode == 2 and "rtol" in p.stderr, p.stderr


def test_a_stiff_spring_ends_with_a_message(tmp_path):
    out = str(tmp_path / "spring.h5")
    p = run(["simulate", os.path.join(MODELS, "spring_1e30.yaml"), "--integrator", "erk",
             "-o", out], tmp_path)
    assert p.returncode == 3, p.stderr
    assert "use hht or ida" in p.stderr, p.stderr
    with h5py.File(out, "r") as f:
        assert f.attrs["status"] == "failed"
        assert len(f["/time"]) >= 1  # the t = 0 row is kept


def test_gradients_refuse_erk_and_python_takes_it(tmp_path):
    quintic = os.path.join(MODELS, "..", "..", "..", "examples", "robot_energy", "quintic.yaml")
    text = open(quintic).read()
    p = run(["gradient", quintic, "--integrator", "erk"], tmp_path)
    assert p.returncode == 2 and "erk integrator has no sensitivities" in p.stderr, p.stderr
    import mbdae
    with mbdae.Model(os.path.join(MODELS, "pendulum.yaml")) as m:
        m.options["integrator"] = "erk"
        m.options["erk.rtol"] = "1e-10"
        m.options["erk.atol"] = "1e-10"
        assert m.options["integrator"] == "erk" and float(m.options["erk.rtol"]) == 1e-10
        m.solve()
        t = m.outputs.time
        angle = np.unwrap(m.outputs.measure("angle"))
        assert np.max(np.abs(angle - reference_angle(t))) < 1e-9
    assert text  # the example exists
