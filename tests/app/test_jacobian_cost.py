"""HHT's refresh of the Newton matrix by cost (`hht: {jacobian_cost}`, `--jacobian-cost`,
options["hht.jacobian_cost"]; docs/hht.md, "Newton matrix") through the program and the
Python package.

- models/pendulum.yaml: with the tree the default (auto) is a cost of 3 iterations, with
  KLU 0 (the rule off: the run is bitwise the run before the rule, the default); the
  attribute jacobian_cost_used says which ran, hht_jacobian_cost records a value given;
- on the tree the rule takes fewer Newton iterations for more factorisations than the
  rate and age rules alone (cost 0) and the rows stay within the Newton threshold's
  reach of them (measured 6.4e-11 rad over 500 steps);
- the same cost with KLU gives the tree's iteration counts (the rule sees only counts);
- the model file's key: read, overridden by the command line, checked with file and line
  (exit 2, nothing written), written back by `convert` only when given;
- the Python package takes options["hht.jacobian_cost"] (a number or "auto").
"""
import os
import sys

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(__file__), "..", "support"))
from pendulum_app import assert_hht_key_error, pendulum_with_hht, run, run_ok, simulate  # noqa: E402

MODELS = os.environ["MBDAE_APP_MODELS"]
PENDULUM = os.path.join(MODELS, "pendulum.yaml")
# The tree with the constant predictor and the first-order Newton matrix (its defaults
# are linear and exact: test_predictor.py, test_rotation_jacobian.py), so that the cost
# rule alone differs from KLU's runs.
TREE = ["--linear-solver", "tree", "--predictor", "constant", "--rotation-jacobian", "first-order"]


def test_default_by_linear_solver(tmp_path):
    with simulate(tmp_path, PENDULUM, "k.h5") as k, \
            simulate(tmp_path, PENDULUM, "k0.h5", ["--jacobian-cost", "0"]) as k0, \
            simulate(tmp_path, PENDULUM, "t.h5", TREE) as t, \
            simulate(tmp_path, PENDULUM, "t0.h5", TREE + ["--jacobian-cost", "0"]) as t0, \
            simulate(tmp_path, PENDULUM, "k3.h5", ["--jacobian-cost", "3"]) as k3:
        assert k.attrs["jacobian_cost_used"] == 0 and "hht_jacobian_cost" not in k.attrs
        assert np.array_equal(k["/q"][:], k0["/q"][:]) and np.array_equal(k["/lambda"][:], k0["/lambda"][:])
        assert k0.attrs["hht_jacobian_cost"] == 0
        assert t.attrs["jacobian_cost_used"] == 3 and t0.attrs["jacobian_cost_used"] == 0
        assert k3.attrs["jacobian_cost_used"] == 3
        steps = t.attrs["steps_accepted"]
        assert steps == t0.attrs["steps_accepted"] == 500
        it, it0 = t.attrs["newton_iterations"], t0.attrs["newton_iterations"]
        f, f0 = t.attrs["factorizations"], t0.attrs["factorizations"]
        diff = np.max(np.abs(t["/measures/angle"][:] - t0["/measures/angle"][:]))
        print("pendulum, tree: by cost %d iterations, %d factorisations; rate and age rules "
              "%d, %d; rows apart by %.1e rad" % (it, f, it0, f0, diff))
        assert it < 0.9 * it0 and f > f0
        assert it + 3 * f < it0 + 3 * f0
        assert 0 < diff < 1e-9
        assert abs(k3.attrs["newton_iterations"] - it) <= 0.01 * it
        assert abs(k3.attrs["factorizations"] - f) <= 0.05 * f


def test_model_file_key_override_errors_and_convert(tmp_path):
    good = pendulum_with_hht(PENDULUM, "jacobian_cost: 2.5")
    (tmp_path / "p.yaml").write_text(good)
    with simulate(tmp_path, "p.yaml", "p.h5") as f:
        assert f.attrs["hht_jacobian_cost"] == 2.5 and f.attrs["jacobian_cost_used"] == 2.5
    with simulate(tmp_path, "p.yaml", "o.h5", ["--jacobian-cost", "auto"]) as f, \
            simulate(tmp_path, PENDULUM, "d.h5") as d:
        assert "hht_jacobian_cost" not in f.attrs and f.attrs["jacobian_cost_used"] == 0
        assert np.array_equal(f["/q"][:], d["/q"][:])
    auto = pendulum_with_hht(PENDULUM, "jacobian_cost: auto")
    (tmp_path / "a.yaml").write_text(auto)
    with simulate(tmp_path, "a.yaml", "a.h5", TREE) as f:
        assert f.attrs["jacobian_cost_used"] == 3
    run_ok(["convert", "p.yaml", "-o", "q.yaml"], tmp_path)
    assert "jacobian_cost: 2.5}" in (tmp_path / "q.yaml").read_text()
    run_ok(["convert", "a.yaml", "-o", "r.yaml"], tmp_path)
    assert "jacobian_cost" not in (tmp_path / "r.yaml").read_text()
    for bad, what in (("-1", "jacobian_cost must be auto or a number >= 0"),
                      ("sometimes", "jacobian_cost")):
        assert_hht_key_error(tmp_path, good.replace("jacobian_cost: 2.5", "jacobian_cost: " + bad), what)
    for bad in ("-2", "often"):
        p = run(["simulate", PENDULUM, "-o", "bad.h5", "--jacobian-cost", bad], tmp_path)
        assert p.returncode == 2 and "--jacobian-cost" in p.stderr, p.stderr
        assert not (tmp_path / "bad.h5").exists()


def test_python_option():
    import mbdae
    with mbdae.Model(PENDULUM) as m:
        assert m.options["hht.jacobian_cost"] == "auto"
        m.options["hht.jacobian_cost"] = 4
        assert m.options["hht.jacobian_cost"] == 4.0
        m.options["hht.jacobian_cost"] = "auto"
        assert m.options["hht.jacobian_cost"] == "auto"
        for bad in (-1, "often"):
            try:
                m.options["hht.jacobian_cost"] = bad
                raise AssertionError("accepted %r" % (bad,))
            except mbdae.Error as e:
                assert "hht.jacobian_cost" in str(e)
