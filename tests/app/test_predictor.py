"""The first iterate of HHT's Newton iteration (`hht: {predictor}`, `--predictor`,
options["hht.predictor"]; docs/hht.md, "Newton iteration") through the program and the
Python package.

- models/pendulum.yaml: the default (auto) is `linear` with the tree elimination and
  `constant` with KLU (whose run is then bitwise the run with `--predictor constant`);
  the attribute predictor_used says which ran, hht_predictor records the setting;
- the linear predictor takes fewer Newton iterations than the constant one, with KLU and
  with the tree, and the rows stay within the Newton threshold's reach of the constant
  predictor's (the converged steps are the same to the threshold);
- the model file's key: read, overridden by the command line, checked with file and line
  (exit 2, nothing written), written back by `convert` only when not `auto`;
- the Python package takes options["hht.predictor"].
"""
import os
import sys

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(__file__), "..", "support"))
from pendulum_app import assert_hht_key_error, pendulum_with_hht, run, run_ok, simulate  # noqa: E402

MODELS = os.environ["MBDAE_APP_MODELS"]
PENDULUM = os.path.join(MODELS, "pendulum.yaml")
TREE = ["--linear-solver", "tree"]


def test_default_by_linear_solver_and_fewer_iterations(tmp_path):
    with simulate(tmp_path, PENDULUM, "k.h5") as k, \
            simulate(tmp_path, PENDULUM, "kc.h5", ["--predictor", "constant"]) as kc, \
            simulate(tmp_path, PENDULUM, "kl.h5", ["--predictor", "linear"]) as kl, \
            simulate(tmp_path, PENDULUM, "t.h5", TREE) as t, \
            simulate(tmp_path, PENDULUM, "tc.h5", TREE + ["--predictor", "constant"]) as tc:
        assert k.attrs["hht_predictor"] == "auto" and k.attrs["predictor_used"] == "constant"
        assert kc.attrs["hht_predictor"] == "constant" and kc.attrs["predictor_used"] == "constant"
        assert kl.attrs["predictor_used"] == "linear"
        assert t.attrs["hht_predictor"] == "auto" and t.attrs["predictor_used"] == "linear"
        assert tc.attrs["predictor_used"] == "constant"
        for name in ("/q", "/v", "/lambda"):
            assert np.array_equal(k[name][:], kc[name][:]), name
        for lin, const, solver in ((kl, kc, "klu"), (t, tc, "tree")):
            assert lin.attrs["steps_accepted"] == const.attrs["steps_accepted"] == 500
            it, it0 = lin.attrs["newton_iterations"], const.attrs["newton_iterations"]
            diff = np.max(np.abs(lin["/measures/angle"][:] - const["/measures/angle"][:]))
            print("pendulum, %s: linear predictor %d iterations, constant %d; rows apart by "
                  "%.1e rad" % (solver, it, it0, diff))
            assert it < 0.9 * it0
            assert diff < 1e-9


def test_model_file_key_override_errors_and_convert(tmp_path):
    good = pendulum_with_hht(PENDULUM, "predictor: linear")
    (tmp_path / "p.yaml").write_text(good)
    with simulate(tmp_path, "p.yaml", "p.h5") as f:
        assert f.attrs["hht_predictor"] == "linear" and f.attrs["predictor_used"] == "linear"
    with simulate(tmp_path, "p.yaml", "o.h5", ["--predictor", "auto"]) as f, \
            simulate(tmp_path, PENDULUM, "d.h5") as d:
        assert f.attrs["hht_predictor"] == "auto" and f.attrs["predictor_used"] == "constant"
        assert np.array_equal(f["/q"][:], d["/q"][:])
    run_ok(["convert", "p.yaml", "-o", "q.yaml"], tmp_path)
    assert "predictor: linear}" in (tmp_path / "q.yaml").read_text()
    with simulate(tmp_path, "q.yaml", "q.h5") as f:
        assert f.attrs["predictor_used"] == "linear"
    run_ok(["convert", PENDULUM, "-o", "r.yaml"], tmp_path)
    assert "predictor" not in (tmp_path / "r.yaml").read_text()
    assert_hht_key_error(tmp_path, good.replace("predictor: linear", "predictor: quadratic"),
                         "predictor")
    p = run(["simulate", PENDULUM, "-o", "bad.h5", "--predictor", "cubic"], tmp_path)
    assert p.returncode == 2 and "--predictor" in p.stderr, p.stderr
    assert not (tmp_path / "bad.h5").exists()


def test_python_option():
    import mbdae
    with mbdae.Model(PENDULUM) as m:
        assert m.options["hht.predictor"] == "auto"
        m.options["hht.predictor"] = "linear"
        assert m.options["hht.predictor"] == "linear"
        try:
            m.options["hht.predictor"] = "often"
            raise AssertionError("accepted 'often'")
        except mbdae.Error as e:
            assert "hht.predictor" in str(e)
        assert m.options["hht.predictor"] == "linear"
