"""The kinematic analysis (`integrator: kinematic`) through the program and the Python package.

- models/crank_slider_driven.yaml (a slider-crank, the crank driven at 2 rad/s, no degree
  of freedom): the results file's rows against the closed form of the slider, and its
  attributes (integrator, Newton iterations in total and at most per time);
- a model with degrees of freedom and `integrator: kinematic`: exit 2, the file, line and
  the number of degrees of freedom, nothing written; the same through --integrator;
- models/slider_lockup.yaml (the slider driven through the dead centre at t = 0.417 s): exit 3,
  status failed, the rows up to there kept, a message naming t and the residual;
- the Python package: options["integrator"] = "kinematic".
"""
import os
import subprocess

import h5py
import numpy as np

MBDAE = os.environ["MBDAE_BIN"]
MODELS = os.environ["MBDAE_APP_MODELS"]

R, L, W = 0.3, 1.0, 2.0


def slider(t):
    """x, x', x'' of the slider of crank_slider_driven.yaml at the times t."""
    phi = W * t
    s = np.sqrt(L**2 - (R * np.sin(phi))**2)
    u = R**2 * np.sin(phi) * np.cos(phi)
    ud = W * R**2 * np.cos(2 * phi)
    sd = -W * u / s
    sdd = -W * (ud * s - u * sd) / s**2
    return (R * np.cos(phi) + s, -R * W * np.sin(phi) + sd, -R * W**2 * np.cos(phi) + sdd)


def run(args, cwd):
    return subprocess.run([MBDAE] + args, cwd=cwd, capture_output=True, text=True, timeout=100)


def test_slider_crank_rows_follow_the_closed_form(tmp_path):
    out = str(tmp_path / "crank.h5")
    p = run(["simulate", os.path.join(MODELS, "crank_slider_driven.yaml"), "-o", out], tmp_path)
    assert p.returncode == 0, p.stderr
    assert "integrator:            kinematic" in p.stdout
    assert "solved times:          200" in p.stdout
    with h5py.File(out, "r") as f:
        assert f.attrs["integrator"] == "kinematic"
        assert f.attrs["status"] == "done"
        assert f.attrs["kinematic_tolerance"] == 1e-12
        assert 1 <= f.attrs["newton_iterations_max"] <= 3
        assert f.attrs["newton_iterations_max"] <= f.attrs["newton_iterations"] <= 3 * 200
        assert f.attrs["steps_accepted"] == 200
        assert f.attrs["singular_points"] == 0
        t = f["/time"][:]
        assert len(t) == 201
        x, xd, xdd = slider(t)
        q, v, a = f["/q"][:], f["/v"][:], f["/a"][:]
        # The slider is the third body: its x is coordinate 14.
        # Measured: 4.4e-16 m, 1.6e-13 m/s, 7.4e-13 m/s^2.
        assert np.max(np.abs(q[:, 14] - x)) < 1e-14
        assert np.max(np.abs(v[:, 14] - xd)) < 2e-12
        assert np.max(np.abs(a[:, 14] - xdd)) < 1e-11
        # Below the Newton tolerance 1e-12 max(1, max |q|) (measured 4.4e-16, 1.4e-13).
        assert f.attrs["max_position_violation"] <= 1e-14
        assert f.attrs["max_velocity_violation"] < 2e-12


def test_a_model_with_degrees_of_freedom_is_refused(tmp_path):
    text = open(os.path.join(MODELS, "pendulum.yaml")).read()
    assert "  integrator: hht\n" in text
    text = text.replace("  integrator: hht\n", "  integrator: kinematic\n")
    line = text[:text.index("integrator: kinematic")].count("\n") + 1
    (tmp_path / "pendulum_kin.yaml").write_text(text)
    p = run(["simulate", "pendulum_kin.yaml"], tmp_path)
    assert p.returncode == 2, p.stderr
    assert "pendulum_kin.yaml:%d:15: simulation: " % line in p.stderr, p.stderr
    assert "this one has 1 degree of freedom" in p.stderr, p.stderr
    assert not (tmp_path / "pendulum_kin.h5").exists()
    assert [f for f in os.listdir(tmp_path) if f.endswith(".tmp")] == []
    p = run(["check", "pendulum_kin.yaml"], tmp_path)
    assert p.returncode == 2 and "1 degree of freedom" in p.stderr, p.stderr
    # Chosen on the command line.
    (tmp_path / "pendulum.yaml").write_text(open(os.path.join(MODELS, "pendulum.yaml")).read())
    p = run(["simulate", "pendulum.yaml", "--integrator", "kinematic"], tmp_path)
    assert p.returncode == 2, p.stderr
    assert "--integrator kinematic: " in p.stderr and "1 degree of freedom" in p.stderr, p.stderr
    assert not (tmp_path / "pendulum.h5").exists()
    # Gradients are refused for the kinematic analysis.
    quintic = os.path.join(MODELS, "..", "..", "..", "examples", "robot_energy", "quintic.yaml")
    p = run(["gradient", quintic, "--integrator", "kinematic"], tmp_path)
    assert p.returncode == 2 and "kinematic analysis has no sensitivities" in p.stderr, p.stderr


def test_zero_dof_model_without_a_named_integrator_gets_a_note(tmp_path):
    text = open(os.path.join(MODELS, "crank_slider_driven.yaml")).read()
    text = text.replace("  integrator: kinematic\n", "")
    (tmp_path / "crank.yaml").write_text(text)
    p = run(["simulate", "crank.yaml", "--t-end", "0.05"], tmp_path)
    assert p.returncode == 0, p.stderr
    assert "integrator:            hht" in p.stdout  # the default is unchanged
    assert "note: the model has no degrees of freedom" in p.stderr, p.stderr
    p = run(["info", "crank.yaml"], tmp_path)
    assert p.returncode == 0
    assert "degrees of freedom:    0 (every motion driven: `integrator: kinematic`" in p.stdout


def test_the_dead_centre_ends_the_run_with_exit_3(tmp_path):
    out = str(tmp_path / "lockup.h5")
    p = run(["simulate", os.path.join(MODELS, "slider_lockup.yaml"), "-o", out], tmp_path)
    assert p.returncode == 3, p.stderr
    assert "mbdae: error: the solver failed at t = " in p.stderr
    with h5py.File(out, "r") as f:
        assert f.attrs["status"] == "failed"
        reason = f.attrs["failure_reason"]
        reason = reason.decode() if isinstance(reason, bytes) else reason
        assert "kinematic analysis" in reason and "max |C| = " in reason, reason
        t = f["/time"][:]
        # The dead centre is at t = 0.41667: the rows up to 0.41 are kept, the run fails
        # at the next output time.
        assert abs(t[-1] - 0.41) < 1e-12, t[-1]
        assert abs(f.attrs["t_reached"] - 0.41) < 1e-12
        assert "at t = 0.42" in reason, reason
        # The rows before it are exact: x = x0 + u t.
        xs = f["/q"][:, 14]
        assert np.max(np.abs(xs - (1.1 + 0.48 * t))) < 1e-11
        # The Newton tolerance: 1e-12 max(1, max |q|), |q| <= 1.3 m.
        assert f.attrs["max_position_violation"] <= 1.3e-12


def test_python_package_takes_the_kinematic_integrator():
    import mbdae
    with mbdae.Model(os.path.join(MODELS, "pendulum.yaml")) as m:
        m.options["integrator"] = "kinematic"
        assert m.options["integrator"] == "kinematic"
        try:
            m.solve()
            raise AssertionError("a pendulum solved kinematically")
        except mbdae.InputError as e:
            assert "1 degree of freedom" in str(e)
    with mbdae.Model(os.path.join(MODELS, "crank_slider_driven.yaml")) as m:
        m.options["integrator"] = "hht"
        m.options["integrator"] = "kinematic"
        m.solve()
        t = np.asarray(m.outputs.time)
        q = np.asarray(m.outputs.q)
        x, _, _ = slider(t)
        assert len(t) == 201
        assert np.max(np.abs(q[:, 14] - x)) < 1e-12


def parallelogram(tmp_path, step):
    out = str(tmp_path / ("pd%s.h5" % step))
    p = run(["simulate", os.path.join(MODELS, "parallelogram_driven.yaml"), "-o", out,
             "--output-step", step, "--quiet"], tmp_path)
    with h5py.File(out, "r") as f:
        t = f["/time"][:]
        gap = np.abs(f["/measures/phi0"][:] - f["/measures/phi1"][:]).max()
    return p, t, gap


def test_singular_positions_the_motion_passes(tmp_path):
    """docs/model-format.md, "Kinematic analysis": the parallelogram driven at its crank,
    flat at t = 1 s and 3 s (measured: the cranks parallel to 2.5e-14, 1.8e-14, 9.4e-7)."""
    p, t, gap = parallelogram(tmp_path, "0.007")  # no output time on a singular instant
    assert p.returncode == 0, p.stderr
    assert t[-1] == 4.0 and gap < 1e-12, gap
    p, t, gap = parallelogram(tmp_path, "0.01")   # a row at t = 1: not determined there
    assert p.returncode == 3, p.stderr
    assert "singular at t = 1 " in p.stderr, p.stderr
    assert abs(t[-1] - 0.99) < 1e-12 and gap < 1e-12, gap
    p, t, gap = parallelogram(tmp_path, "0.03")   # passes t = 1 less accurately, ends after t = 3
    assert p.returncode == 3, p.stderr
    assert abs(t[-1] - 3.0) < 1e-12 and gap < 1e-5, gap
