"""HHT's linear solver (`hht: {linear_solver}`, `--linear-solver`,
options["hht.linear_solver"]; docs/hht.md, "Linear solver") through the program and the
Python package.

- models/pendulum.yaml (a tree of one body): `tree` takes the same 500 steps as `klu`
  and, with `--jacobian-cost 0 --predictor constant --rotation-jacobian first-order`
  (KLU's refresh rules, predictor and Newton matrix, so that only the linear solver
  differs; test_jacobian_cost.py, test_predictor.py and test_rotation_jacobian.py have
  the tree's own), its rows agree to round-off
  (measured 0 to 1e-15 rad); the attributes hht_linear_solver and linear_solver_used say
  `tree`;
- models/fourbar.yaml (a loop closed through the ground, which the forest of bodies and
  joints does not see): the first tree factorisation meets a zero pivot, KLU takes over
  for the run, linear_solver_used gives the reason and the run is bitwise KLU's;
- the model file's key: read, overridden by the command line, checked with file and line
  (exit 2, nothing written), written back by `convert` only when not the default;
- IDA (`--integrator ida`; `ida: {linear_solver}`, options["ida.linear_solver"]): the
  tree on the pendulum, rows within 1e-7 rad of KLU's (IDA adapts its steps to what the
  solves give, so not bitwise), and on the four-bar the first factorisation's check sends
  it to KLU (bitwise KLU's run);
- the Python package takes options["hht.linear_solver"] and options["ida.linear_solver"].
"""
import os
import sys

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(__file__), "..", "support"))
from pendulum_app import assert_hht_key_error, pendulum_with_hht, run, run_ok, simulate  # noqa: E402

MODELS = os.environ["MBDAE_APP_MODELS"]
PENDULUM = os.path.join(MODELS, "pendulum.yaml")
FOURBAR = os.path.join(MODELS, "fourbar.yaml")


def test_tree_takes_the_same_steps_on_a_tree(tmp_path):
    with simulate(tmp_path, PENDULUM, "k.h5") as k, \
            simulate(tmp_path, PENDULUM, "t.h5", ["--linear-solver", "tree", "--jacobian-cost", "0", "--predictor", "constant",
                                                     "--rotation-jacobian", "first-order"]) as t:
        assert k.attrs["hht_linear_solver"] == "klu"
        assert k.attrs["linear_solver_used"] == "klu"
        assert t.attrs["hht_linear_solver"] == "tree"
        assert t.attrs["linear_solver_used"] == "tree"
        assert t.attrs["klu_fallbacks"] == 0
        assert t.attrs["steps_accepted"] == k.attrs["steps_accepted"] == 500
        diff = np.max(np.abs(t["/measures/angle"][:] - k["/measures/angle"][:]))
        print("pendulum: rows of tree and klu apart by %.1e rad" % diff)
        assert diff < 1e-12


def test_a_loop_through_the_ground_falls_back_to_klu(tmp_path):
    extra = ["--integrator", "hht", "--t-end", "0.2"]
    with simulate(tmp_path, FOURBAR, "k.h5", extra) as k, \
            simulate(tmp_path, FOURBAR, "t.h5", extra + ["--linear-solver", "tree"]) as t:
        used = t.attrs["linear_solver_used"]
        assert used.startswith("klu (no tree: ") and "pivots" in used, used
        assert t.attrs["klu_fallbacks"] == 1
        assert np.array_equal(t["/q"][:], k["/q"][:])


def test_model_file_key_override_errors_and_convert(tmp_path):
    good = pendulum_with_hht(PENDULUM, "linear_solver: tree")
    (tmp_path / "p.yaml").write_text(good)
    with simulate(tmp_path, "p.yaml", "p.h5") as f:
        assert f.attrs["hht_linear_solver"] == "tree"
        assert f.attrs["linear_solver_used"] == "tree"
    with simulate(tmp_path, "p.yaml", "o.h5", ["--linear-solver", "klu"]) as f, \
            simulate(tmp_path, PENDULUM, "d.h5") as d:
        assert f.attrs["linear_solver_used"] == "klu"
        assert np.array_equal(f["/q"][:], d["/q"][:])
    run_ok(["convert", "p.yaml", "-o", "q.yaml"], tmp_path)
    assert "linear_solver: tree}" in (tmp_path / "q.yaml").read_text()
    run_ok(["convert", PENDULUM, "-o", "r.yaml"], tmp_path)
    assert "linear_solver" not in (tmp_path / "r.yaml").read_text()
    assert_hht_key_error(tmp_path, good.replace("linear_solver: tree", "linear_solver: lu"),
                         "linear_solver")
    p = run(["simulate", PENDULUM, "-o", "bad.h5", "--linear-solver", "lu"], tmp_path)
    assert p.returncode == 2 and "--linear-solver" in p.stderr, p.stderr
    assert not (tmp_path / "bad.h5").exists()


def test_ida(tmp_path):
    ida = ["--integrator", "ida"]
    with simulate(tmp_path, PENDULUM, "k.h5", ida) as k, \
            simulate(tmp_path, PENDULUM, "t.h5", ida + ["--linear-solver", "tree"]) as t:
        assert k.attrs["ida_linear_solver"] == "klu" and k.attrs["linear_solver_used"] == "klu"
        assert t.attrs["ida_linear_solver"] == "tree" and t.attrs["linear_solver_used"] == "tree"
        diff = np.max(np.abs(t["/measures/angle"][:] - k["/measures/angle"][:]))
        print("pendulum, IDA: rows of tree and klu apart by %.1e rad" % diff)
        assert diff < 1e-7
    extra = ida + ["--t-end", "0.2"]
    with simulate(tmp_path, FOURBAR, "fk.h5", extra) as k, \
            simulate(tmp_path, FOURBAR, "ft.h5", extra + ["--linear-solver", "tree"]) as t:
        used = t.attrs["linear_solver_used"]
        assert used == "klu (no tree: a factorisation failed its check at t = 0)", used
        assert np.array_equal(t["/q"][:], k["/q"][:])
    text = open(PENDULUM).read()
    old = "  ida: {rtol: 1.0e-8, atol: 1.0e-10}\n"
    assert old in text
    good = text.replace(old, "  ida: {rtol: 1.0e-8, atol: 1.0e-10, linear_solver: tree}\n")
    (tmp_path / "i.yaml").write_text(good)
    with simulate(tmp_path, "i.yaml", "i.h5", ida) as f:
        assert f.attrs["ida_linear_solver"] == "tree"
    run_ok(["convert", "i.yaml", "-o", "j.yaml"], tmp_path)
    assert "linear_solver: tree}" in (tmp_path / "j.yaml").read_text()
    (tmp_path / "bad.yaml").write_text(good.replace("linear_solver: tree", "linear_solver: lu"))
    p = run(["simulate", "bad.yaml", "-o", "bad.h5"], tmp_path)
    assert p.returncode == 2 and "linear_solver" in p.stderr, p.stderr
    assert not (tmp_path / "bad.h5").exists()


def test_python_option():
    import mbdae
    angles = {}
    for solver in ("klu", "tree"):
        with mbdae.Model(PENDULUM) as m:
            assert m.options["hht.linear_solver"] == "klu"
            m.options["hht.linear_solver"] = solver
            m.options["hht.jacobian_cost"] = 0
            m.options["hht.predictor"] = "constant"
            m.options["hht.rotation_jacobian"] = "first-order"
            assert m.options["hht.linear_solver"] == solver
            m.solve()
            angles[solver] = np.array(m.outputs.measure("angle"))
    assert len(angles["tree"]) == 51
    assert np.max(np.abs(angles["tree"] - angles["klu"])) < 1e-12
    with mbdae.Model(PENDULUM) as m:
        assert m.options["ida.linear_solver"] == "klu"
        m.options["ida.linear_solver"] = "tree"
        assert m.options["ida.linear_solver"] == "tree"
        for key in ("hht.linear_solver", "ida.linear_solver"):
            try:
                m.options[key] = "lu"
                raise AssertionError("accepted 'lu'")
            except mbdae.Error as e:
                assert "expected klu or tree" in str(e)


def test_rows_solved_by_the_tree_with_the_tree(tmp_path):
    """With --linear-solver tree the rows' acceleration-level solve (output_accelerations:
    solved) is the tree elimination too: on a 10-rod ball chain (bench/scenes/
    ball_chain.py) the rows' lambda, a and joint forces agree with KLU's to round-off
    (within 1e-9 of the largest), and the first row's lambda, from the same assembled
    state in both runs, differs at round-off; `--linear-solver klu` gives the default's
    rows bitwise. The tree runs with KLU's first-order Newton matrix: its default, the
    exact rotation blocks (test_rotation_jacobian.py), moves the steps within the Newton
    threshold, and the rows' a with them (measured 1.2e-9 of the largest)."""
    sys.path.insert(0, os.path.join(os.path.dirname(__file__), "..", "..", "bench", "scenes"))
    import ball_chain
    ball_chain.write_chain(str(tmp_path / "chain.yaml"), 10, t_end=0.2, output_step=0.02)
    extra = ["--integrator", "hht"]
    with simulate(tmp_path, "chain.yaml", "k.h5", extra) as k, \
            simulate(tmp_path, "chain.yaml", "t.h5",
                     extra + ["--linear-solver", "tree", "--rotation-jacobian", "first-order"]) as t, \
            simulate(tmp_path, "chain.yaml", "d.h5", extra + ["--linear-solver", "klu"]) as d:
        assert t.attrs["linear_solver_used"] == "tree"
        assert np.max(np.abs(t["/q"][:] - k["/q"][:])) < 1e-10  # measured 3.3e-11 m
        for name in ("/lambda", "/a", "/joints/ball10/force"):
            scale = np.max(np.abs(k[name][:]))
            diff = np.max(np.abs(t[name][:] - k[name][:]))
            assert diff <= 1e-9 * scale, (name, diff, scale)
        # Row 0 is the assembled state, the same in every run: its lambda differs only
        # by the row's solver.
        assert np.array_equal(t["/q"][0], k["/q"][0]) and np.array_equal(t["/v"][0], k["/v"][0])
        assert not np.array_equal(t["/lambda"][0], k["/lambda"][0])
        assert np.array_equal(d["/lambda"][:], k["/lambda"][:])
