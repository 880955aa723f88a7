"""The Newton matrix's columns of the Euler-parameter groups in HHT's modified scheme
(`hht: {rotation_jacobian}`, `--rotation-jacobian`, options["hht.rotation_jacobian"];
docs/hht.md, "Rotation blocks") through the program and the Python package.

- models/pendulum.yaml: the default (auto) is `exact` with the tree elimination and
  `first-order` with KLU (whose run is then bitwise the run with `--rotation-jacobian
  first-order`); `exact` asked for runs with KLU too; the classical scheme
  (`--no-modified`), whose matrix is exact anyway, runs `first-order` whatever the
  setting; the attribute rotation_jacobian_used says which ran, hht_rotation_jacobian
  records the setting;
- a 10-rod ball chain (bench/scenes/ball_chain.py), tree: the exact blocks take no more
  Newton iterations than the first-order ones, and the final q agree to 1e-8 (the
  converged steps are the same to the Newton threshold);
- the model file's key: read, overridden by the command line, checked with file and line
  (exit 2, nothing written), written back by `convert` only when not `auto`; a bad value
  on the command line: exit 2, nothing written;
- the Python package takes options["hht.rotation_jacobian"] (a bad value is an error
  naming the option) and its results file records the value used.
"""
import os
import sys

import h5py
import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(__file__), "..", "support"))
from pendulum_app import assert_hht_key_error, pendulum_with_hht, run, run_ok, simulate  # noqa: E402

MODELS = os.environ["MBDAE_APP_MODELS"]
PENDULUM = os.path.join(MODELS, "pendulum.yaml")
TREE = ["--linear-solver", "tree"]
ROT = "--rotation-jacobian"


def test_default_by_linear_solver_and_scheme(tmp_path):
    with simulate(tmp_path, PENDULUM, "k.h5") as k, \
            simulate(tmp_path, PENDULUM, "kf.h5", [ROT, "first-order"]) as kf, \
            simulate(tmp_path, PENDULUM, "ke.h5", [ROT, "exact"]) as ke, \
            simulate(tmp_path, PENDULUM, "t.h5", TREE) as t, \
            simulate(tmp_path, PENDULUM, "tf.h5", TREE + [ROT, "first-order"]) as tf, \
            simulate(tmp_path, PENDULUM, "c.h5", TREE + ["--no-modified"]) as c, \
            simulate(tmp_path, PENDULUM, "ce.h5", ["--no-modified", ROT, "exact"]) as ce:
        assert k.attrs["hht_rotation_jacobian"] == "auto"
        assert k.attrs["rotation_jacobian_used"] == "first-order"
        assert kf.attrs["hht_rotation_jacobian"] == "first-order"
        assert kf.attrs["rotation_jacobian_used"] == "first-order"
        assert ke.attrs["hht_rotation_jacobian"] == "exact"
        assert ke.attrs["rotation_jacobian_used"] == "exact"
        assert ke.attrs["linear_solver_used"] == "klu"
        assert t.attrs["hht_rotation_jacobian"] == "auto"
        assert t.attrs["rotation_jacobian_used"] == "exact"
        assert t.attrs["linear_solver_used"] == "tree"
        assert tf.attrs["rotation_jacobian_used"] == "first-order"
        assert c.attrs["hht_modified"] == 0
        assert c.attrs["hht_rotation_jacobian"] == "auto"
        assert c.attrs["rotation_jacobian_used"] == "first-order"
        assert ce.attrs["hht_rotation_jacobian"] == "exact"
        assert ce.attrs["rotation_jacobian_used"] == "first-order"
        for name in ("/q", "/v", "/lambda"):
            assert np.array_equal(k[name][:], kf[name][:]), name
        for exact, first, solver in ((ke, kf, "klu"), (t, tf, "tree")):
            assert exact.attrs["steps_accepted"] == first.attrs["steps_accepted"] == 500
            diff = np.max(np.abs(exact["/measures/angle"][:] - first["/measures/angle"][:]))
            print("pendulum, %s: exact blocks %d iterations, first-order %d; rows apart by "
                  "%.1e rad" % (solver, exact.attrs["newton_iterations"],
                                first.attrs["newton_iterations"], diff))
            assert diff < 1e-9


def test_exact_blocks_on_a_chain(tmp_path):
    sys.path.insert(0, os.path.join(os.path.dirname(__file__), "..", "..", "bench", "scenes"))
    import ball_chain
    ball_chain.write_chain(str(tmp_path / "chain.yaml"), 10, t_end=0.2, output_step=0.02)
    extra = ["--integrator", "hht"] + TREE
    with simulate(tmp_path, "chain.yaml", "e.h5", extra + [ROT, "exact"]) as e, \
            simulate(tmp_path, "chain.yaml", "f.h5", extra + [ROT, "first-order"]) as f, \
            simulate(tmp_path, "chain.yaml", "d.h5", extra) as d:
        assert e.attrs["rotation_jacobian_used"] == "exact"
        assert f.attrs["rotation_jacobian_used"] == "first-order"
        assert d.attrs["rotation_jacobian_used"] == "exact"
        for r in (e, f, d):
            assert r.attrs["linear_solver_used"] == "tree"
        assert np.array_equal(d["/q"][:], e["/q"][:])
        steps = e.attrs["steps_accepted"]
        assert f.attrs["steps_accepted"] == steps
        it_e, it_f = e.attrs["newton_iterations"], f.attrs["newton_iterations"]
        diff = np.max(np.abs(e["/q"][-1] - f["/q"][-1]))
        print("10-rod chain, tree, %d steps: exact blocks %d iterations, first-order %d; "
              "final q apart by %.1e" % (steps, it_e, it_f, diff))
        assert it_f >= it_e
        assert diff < 1e-8


def test_model_file_key_override_errors_and_convert(tmp_path):
    good = pendulum_with_hht(PENDULUM, "rotation_jacobian: exact")
    (tmp_path / "p.yaml").write_text(good)
    with simulate(tmp_path, "p.yaml", "p.h5") as f:
        assert f.attrs["hht_rotation_jacobian"] == "exact"
        assert f.attrs["rotation_jacobian_used"] == "exact"
    with simulate(tmp_path, "p.yaml", "o.h5", [ROT, "auto"]) as f, \
            simulate(tmp_path, PENDULUM, "d.h5") as d:
        assert f.attrs["hht_rotation_jacobian"] == "auto"
        assert f.attrs["rotation_jacobian_used"] == "first-order"
        assert np.array_equal(f["/q"][:], d["/q"][:])
    run_ok(["convert", "p.yaml", "-o", "q.yaml"], tmp_path)
    assert "rotation_jacobian: exact}" in (tmp_path / "q.yaml").read_text()
    with simulate(tmp_path, "q.yaml", "q.h5") as f:
        assert f.attrs["rotation_jacobian_used"] == "exact"
    run_ok(["convert", PENDULUM, "-o", "r.yaml"], tmp_path)
    assert "rotation_jacobian" not in (tmp_path / "r.yaml").read_text()
    assert_hht_key_error(tmp_path, good.replace("rotation_jacobian: exact",
                                                "rotation_jacobian: second-order"),
                         "rotation_jacobian")
    p = run(["simulate", PENDULUM, "-o", "bad.h5", ROT, "second-order"], tmp_path)
    assert p.returncode == 2 and ROT in p.stderr, p.stderr
    assert not (tmp_path / "bad.h5").exists()


def test_python_option(tmp_path):
    import mbdae
    with mbdae.Model(PENDULUM) as m:
        assert m.options["hht.rotation_jacobian"] == "auto"
        m.options["hht.rotation_jacobian"] = "exact"
        assert m.options["hht.rotation_jacobian"] == "exact"
        try:
            m.options["hht.rotation_jacobian"] = "second-order"
            raise AssertionError("accepted 'second-order'")
        except mbdae.Error as e:
            assert "hht.rotation_jacobian" in str(e)
            assert "expected auto, first-order or exact" in str(e), str(e)
        assert m.options["hht.rotation_jacobian"] == "exact"
        m.solve()
        m.write_results(str(tmp_path / "py.h5"))
    with h5py.File(tmp_path / "py.h5", "r") as f:
        assert f.attrs["hht_rotation_jacobian"] == "exact"
        assert f.attrs["rotation_jacobian_used"] == "exact"
