"""The mbdae program end to end: runs it on the test models and opens the results file
with h5py, checking every dataset and attribute of the command-line contract; runs every
malformed model of verification/malformed and checks that it is refused (exit code 2, a
message naming the file, no results file).

Environment: MBDAE_BIN (the program), MBDAE_APP_MODELS (tests/app/models),
MBDAE_MALFORMED (verification/malformed).
"""
import glob
import json
import math
import os
import shutil
import subprocess

import h5py
import numpy as np
import pytest

MBDAE = os.environ.get("MBDAE_BIN", "mbdae")
MODELS = os.environ.get("MBDAE_APP_MODELS", os.path.join(os.path.dirname(__file__), "models"))
MALFORMED = os.environ.get("MBDAE_MALFORMED", "")


def run(args, cwd):
    return subprocess.run([MBDAE] + args, cwd=cwd, capture_output=True, text=True, timeout=60)


def copy_model(name, tmp_path):
    shutil.copy(os.path.join(MODELS, name), tmp_path / name)
    return name


def as_str(x):
    return x.decode() if isinstance(x, bytes) else str(x)


def names(dataset):
    return [as_str(s) for s in dataset[()]]


@pytest.fixture(scope="module")
def pendulum(tmp_path_factory):
    """The pendulum run with IDA; returns (open h5 file, completed process)."""
    tmp = tmp_path_factory.mktemp("pendulum")
    model = copy_model("pendulum.yaml", tmp)
    p = run(["simulate", model, "--integrator", "ida", "--t-end", "1.0", "--output-step",
             "0.01"], tmp)
    assert p.returncode == 0, p.stderr
    path = tmp / "pendulum.h5"  # the default: next to the model
    assert path.exists()
    f = h5py.File(path, "r")
    yield f, p
    f.close()


def test_datasets_have_the_contract_shapes(pendulum):
    f, _ = pendulum
    n = 101
    nq, nc = 7, 6
    time = f["time"][()]
    assert time.shape == (n,)
    assert time[0] == 0.0 and time[-1] == 1.0
    assert np.all(np.diff(time) > 0)
    np.testing.assert_allclose(np.diff(time), 0.01, rtol=1e-9)
    for name in ("q", "v", "a"):
        assert f[name].shape == (n, nq), name
    assert names(f["q_names"]) == ["bob.x", "bob.y", "bob.z", "bob.e0", "bob.e1", "bob.e2",
                                   "bob.e3"]
    assert f["lambda"].shape == (n, nc)
    assert names(f["lambda_names"]) == ["pivot.x", "pivot.y", "pivot.z", "pivot.rx", "pivot.ry",
                                        "bob.euler_norm"]
    assert f["q_names"].asstr()[0] == "bob.x"  # readable as str
    for d, cols in (("position", 3), ("orientation", 4), ("velocity", 3),
                    ("angular_velocity", 3)):
        assert f["bodies/bob/" + d].shape == (n, cols), d
    assert sorted(f["measures"].keys()) == ["angle", "drop", "rate", "x"]
    for m in f["measures"].values():
        assert m.shape == (n,)
    for d in ("force", "torque"):
        assert f["joints/pivot/" + d].shape == (n, 3)
        assert f["forces/push/" + d].shape == (n, 3)
    assert f["energy/kinetic"].shape == (n,)
    assert f["energy/potential"].shape == (n,)
    assert f["violation/position"].shape == (n,)


def test_attributes(pendulum):
    f, _ = pendulum
    a = f.attrs
    assert a["format"] == 1
    assert as_str(a["model"]) == "pendulum.yaml"
    assert as_str(a["integrator"]) == "ida"
    assert a["ida_rtol"] == 1e-8 and a["ida_atol"] == 1e-10
    assert a["ida_max_steps"] == 100000000 and a["ida_min_step"] == 0  # the defaults
    assert as_str(a["status"]) == "done"
    assert a["t_reached"] == 1.0
    assert "failure_reason" not in a
    for key in ("steps_accepted", "newton_iterations", "jacobian_evaluations", "factorizations"):
        assert a[key] > 0, key
    assert a["steps_rejected"] >= 0
    assert a["wall_time"] > 0
    assert 0 <= a["max_position_violation"] < 1e-8
    assert 0 <= a["max_velocity_violation"] < 1e-6
    assert a["redundant_constraints"] == 0
    assert len(a["redundant_constraint_names"]) == 0


def test_physics_of_the_rows(pendulum):
    """Values, not only shapes: the pendulum released from the horizontal."""
    f, _ = pendulum
    q, v = f["q"][()], f["v"][()]
    pos = f["bodies/bob/position"][()]
    np.testing.assert_array_equal(pos, q[:, 0:3])
    np.testing.assert_array_equal(f["bodies/bob/velocity"][()], v[:, 0:3])
    np.testing.assert_array_equal(f["bodies/bob/orientation"][()], q[:, 3:7])
    # On the unit circle, energy conserved (IDA, rtol 1e-8).
    np.testing.assert_allclose(np.hypot(pos[:, 0], pos[:, 1]), 1.0, atol=1e-8)
    e = f["energy/kinetic"][()] + f["energy/potential"][()]
    np.testing.assert_allclose(e, e[0], atol=1e-5)
    np.testing.assert_allclose(f["energy/kinetic"][()], 0.5 * np.sum(v[:, 0:3] ** 2, axis=1),
                               rtol=1e-9, atol=1e-12)
    # Measures: x, the drop from the start (offset_initial), the angle and its rate.
    np.testing.assert_allclose(f["measures/x"][()], pos[:, 0], atol=1e-12)
    drop = f["measures/drop"][()]
    assert drop[0] == 0.0
    np.testing.assert_allclose(drop, pos[:, 1] - pos[0, 1], atol=1e-12)
    angle = f["measures/angle"][()]
    np.testing.assert_allclose(np.cos(angle), pos[:, 0], atol=1e-8)
    np.testing.assert_allclose(np.sin(angle), pos[:, 1], atol=1e-8)
    w = f["bodies/bob/angular_velocity"][()]
    np.testing.assert_allclose(w[:, 0:2], 0, atol=1e-9)
    np.testing.assert_allclose(w[:, 2], f["measures/rate"][()], atol=1e-7)
    # Joint reaction: zero at release (at rest, horizontal); the link tension is
    # m g (3 sin(-angle)) along the link (energy: v^2 = 2 g L sin(-angle)).
    jf = f["joints/pivot/force"][()]
    np.testing.assert_allclose(jf[0], 0, atol=1e-8)
    radial = -(jf[:, 0] * pos[:, 0] + jf[:, 1] * pos[:, 1])  # reaction on the bob, inwards
    tension = 9.81 * 3 * np.sin(-angle)
    # lambda is algebraic, outside IDA's error test: it is accurate to ~1e-4 relative.
    np.testing.assert_allclose(np.abs(radial), np.abs(tension), rtol=1e-4, atol=1e-6)
    np.testing.assert_allclose(f["forces/push/force"][()], 0, atol=0)


def test_summary_and_progress(pendulum):
    _, p = pendulum
    for word in ("integrator:", "steps:", "accepted", "rejected", "Newton iterations:",
                 "Jacobian evaluations:", "factorizations:", "wall time:", "max violation:",
                 "redundant constraints:"):
        assert word in p.stdout, word
    # stderr is not a terminal here: one plain line per tenth of the run.
    lines = [l for l in p.stderr.splitlines() if " of 1 " in l]
    assert len(lines) == 10, p.stderr


def test_redundant_loop_and_turns(tmp_path):
    model = copy_model("fourbar.yaml", tmp_path)
    p = run(["simulate", model, "-o", "out.h5", "--integrator", "hht", "--quiet"], tmp_path)
    assert p.returncode == 0, p.stderr
    assert p.stdout == "" and p.stderr == ""
    with h5py.File(tmp_path / "out.h5", "r") as f:
        assert f.attrs["redundant_constraints"] == 3
        red = [as_str(s) for s in f.attrs["redundant_constraint_names"]]
        assert len(red) == 3
        kept = names(f["lambda_names"])
        assert len(kept) == 20 and not set(red) & set(kept)
        assert f["lambda"].shape == (11, 20)
        assert as_str(f.attrs["integrator"]) == "hht"
        for k in ("hht_alpha", "hht_step", "hht_adaptive", "hht_tolerance", "hht_modified"):
            assert k in f.attrs, k
        assert f.attrs["max_position_violation"] < 1e-8
        # Parallelogram: crank and rocker turn alike.
        np.testing.assert_allclose(f["measures/crank_angle"][()], f["measures/rocker_angle"][()],
                                   atol=1e-6)
        for j in ("j_crank", "j_left", "j_right", "j_rocker"):
            assert f["joints/%s/force" % j].shape == (11, 3)


def test_set_overrides_a_parameter(tmp_path):
    model = copy_model("pendulum.yaml", tmp_path)
    p = run(["simulate", model, "-o", "long.h5", "--set", "L=2", "--t-end", "0.1", "--quiet"],
            tmp_path)
    assert p.returncode == 0, p.stderr
    with h5py.File(tmp_path / "long.h5", "r") as f:
        np.testing.assert_allclose(f["bodies/bob/position"][0], [2, 0, 0])
        assert f["time"][-1] == 0.1


def test_solver_failure_keeps_the_file(tmp_path):
    model = copy_model("pendulum.yaml", tmp_path)
    p = run(["simulate", model, "--adaptive", "--tolerance", "1e-30", "--quiet"], tmp_path)
    assert p.returncode == 3, p.stderr
    assert "mbdae: error: " in p.stderr
    with h5py.File(tmp_path / "pendulum.h5", "r") as f:
        assert as_str(f.attrs["status"]) == "failed"
        assert f.attrs["t_reached"] < 0.5
        assert len(as_str(f.attrs["failure_reason"])) > 0
        assert f["time"].shape[0] >= 1 and f["time"][0] == 0.0


@pytest.mark.parametrize("flags,attrs", [
    ([], {"output_accelerations": "solved", "hht_start": "consistent"}),
    (["--output-accelerations", "integrator"], {"output_accelerations": "integrator"}),
    (["--output-accelerations=solved"], {"output_accelerations": "solved"}),
    (["--hht-start", "perturbed"], {"hht_start": "perturbed"}),
    (["--hht-start", "consistent", "--output-accelerations", "integrator"],
     {"hht_start": "consistent", "output_accelerations": "integrator"}),
], ids=["defaults", "accelerations-integrator", "accelerations-solved", "start-perturbed",
        "both"])
def test_output_accelerations_and_hht_start_flags(tmp_path, flags, attrs):
    # The flags override the model's simulation.output_accelerations and simulation.hht.start;
    # the results file's attributes give the values used.
    model = copy_model("pendulum.yaml", tmp_path)
    p = run(["simulate", model, "--t-end", "0.05", "--quiet"] + flags, tmp_path)
    assert p.returncode == 0, p.stderr
    with h5py.File(tmp_path / "pendulum.h5", "r") as f:
        assert as_str(f.attrs["integrator"]) == "hht"
        for key, value in attrs.items():
            assert as_str(f.attrs[key]) == value, key
    # The model's own value is overridden: the file says `integrator`, the flag `solved`.
    text = (tmp_path / model).read_text().replace(
        "hht: {alpha: -0.1, step: 1.0e-3}",
        "hht: {alpha: -0.1, step: 1.0e-3, start: perturbed}\n  output_accelerations: integrator")
    (tmp_path / "own.yaml").write_text(text)
    p = run(["simulate", "own.yaml", "--t-end", "0.05", "--quiet"] + flags, tmp_path)
    assert p.returncode == 0, p.stderr
    with h5py.File(tmp_path / "own.h5", "r") as f:
        expected = {"output_accelerations": "integrator", "hht_start": "perturbed"}
        expected.update(attrs if flags else {})
        for key, value in expected.items():
            assert as_str(f.attrs[key]) == value, key


@pytest.mark.parametrize("flag,value,allowed", [
    ("--output-accelerations", "exact", "expected solved or integrator, got 'exact'"),
    ("--hht-start", "smooth", "expected consistent or perturbed, got 'smooth'"),
])
def test_output_accelerations_and_hht_start_bad_values_exit_2(tmp_path, flag, value, allowed):
    model = copy_model("pendulum.yaml", tmp_path)
    for args in ([flag, value], [flag + "=" + value]):
        p = run(["simulate", model, "--quiet"] + args, tmp_path)
        assert p.returncode == 2, p.stderr
        assert p.stderr.startswith("mbdae: error: " + flag + ": " + allowed), p.stderr
    p = run(["simulate", model, "--quiet", flag], tmp_path)  # the value is missing
    assert p.returncode == 2 and flag + ": missing value" in p.stderr, p.stderr
    p = run(["check", model, flag, value], tmp_path)  # only for simulate and gradient
    assert p.returncode == 2 and "option " + flag + " is only for" in p.stderr, p.stderr
    assert not list(tmp_path.glob("*.h5"))


def test_info_json_counts(tmp_path):
    model = copy_model("fourbar.yaml", tmp_path)
    p = run(["info", model, "--json"], tmp_path)
    assert p.returncode == 0, p.stderr
    info = json.loads(p.stdout)
    c = info["counts"]
    assert (c["bodies"], c["coordinates"], c["constraint_equations"]) == (3, 21, 23)
    assert (c["redundant_equations"], c["degrees_of_freedom"], c["joints"]) == (3, 1, 4)
    assert info["bodies"] == ["crank", "coupler", "rocker"]
    assert info["parameters"]["c"] == 0.5
    assert not list(tmp_path.glob("*.h5"))


@pytest.mark.parametrize("args", [
    ["simulate", "missing.yaml"],
    ["simulate", "pendulum.yaml", "--t-end", "-1"],
    ["simulate", "pendulum.yaml", "--integrator", "rk4"],
    ["simulate", "pendulum.yaml", "--bogus"],
    ["simulate", "pendulum.yaml", "--set", "nosuchparameter=1"],
    ["simulate", "pendulum.yaml", "--alpha", "0.5"],
])
def test_bad_input_exit_2_and_nothing_written(tmp_path, args):
    copy_model("pendulum.yaml", tmp_path)
    p = run(args, tmp_path)
    assert p.returncode == 2, p.stderr
    assert p.stderr.startswith("mbdae: error: "), p.stderr
    assert not list(tmp_path.glob("*.h5"))


def malformed_files():
    if not MALFORMED or not os.path.isdir(MALFORMED):
        return []
    return sorted(f for f in glob.glob(os.path.join(MALFORMED, "*.yaml"))
                  if os.path.basename(f) != "correct_base.yaml")


def test_malformed_folder_is_there():
    files = malformed_files()
    if not MALFORMED:
        pytest.skip("MBDAE_MALFORMED not set")
    assert len(files) >= 5, MALFORMED


@pytest.mark.parametrize("path", malformed_files(), ids=os.path.basename)
def test_malformed_model_is_refused(tmp_path, path):
    name = os.path.basename(path)
    shutil.copy(path, tmp_path / name)
    p = run(["simulate", name], tmp_path)
    assert p.returncode == 2, (p.returncode, p.stderr)
    assert p.stderr.startswith("mbdae: error: "), p.stderr
    assert name in p.stderr, p.stderr
    assert not list(tmp_path.glob("*.h5"))
