"""How `mbdae simulate` runs end and what they leave behind (docs/cli.md, "Exit codes" and
"The results file while a run goes on"):

- runs that used to go on without end (a stiffness of 1e30, a stiffness with a pole in
  time) stop with exit 3, a message naming t and h, and the rows up to the stop (the
  four-bar through its singular positions, the first such case, now runs to its end:
  test_fourbar_through_its_singular_positions_runs_to_the_end);
- the results file is written under a temporary name and renamed at the end: an earlier
  file stays whole while a run goes on, a refused run leaves nothing;
- the model is never overwritten (-o naming it, through ./, a symbolic or a hard link);
- an unwritable -o says why (the system's reason);
- SIGTERM and SIGINT stop the run at the next step: status `interrupted`, the time
  reached, exit 128 + the signal's number.

Environment: MBDAE_BIN (the program), MBDAE_APP_MODELS (tests/app/models).
"""
import os
import shutil
import signal
import subprocess
import sys
import time

import h5py
import numpy as np
import pytest

sys.path.insert(0, os.path.join(os.path.dirname(__file__), "..", "support"))
from running import start_until_temporary, temporary_files  # noqa: E402

MBDAE = os.environ.get("MBDAE_BIN", "mbdae")
MODELS = os.environ.get("MBDAE_APP_MODELS", os.path.join(os.path.dirname(__file__), "models"))


def run(args, cwd):
    return subprocess.run([MBDAE] + args, cwd=cwd, capture_output=True, text=True, timeout=120)


def copy_model(name, tmp_path):
    shutil.copy(os.path.join(MODELS, name), tmp_path / name)
    return name


def as_str(x):
    return x.decode() if isinstance(x, bytes) else str(x)


leftovers = temporary_files


# model, time of the stop, output times kept
RUNAWAYS = [
    ("spring_1e30.yaml", 0.0, [0.0]),
    ("pole_spring.yaml", 0.5, [0.0, 0.1, 0.2, 0.3, 0.4]),
]


@pytest.mark.parametrize("name,t_stop,times", RUNAWAYS, ids=[r[0] for r in RUNAWAYS])
def test_runaway_ida_run_ends_with_exit_3_and_keeps_the_rows(tmp_path, name, t_stop, times):
    model = copy_model(name, tmp_path)
    p = run(["simulate", model, "--quiet"], tmp_path)
    assert p.returncode == 3, p.stderr
    err = p.stderr
    assert err.startswith("mbdae: error: the solver failed at t = "), err
    assert "the step size fell to h = " in err and "below 1e-14 max(1, |t|) for 20 steps" in err, err
    stem = name[: -len(".yaml")]
    assert "the results up to there are in %s.h5" % stem in err, err
    with h5py.File(tmp_path / (stem + ".h5"), "r") as f:
        assert as_str(f.attrs["status"]) == "failed"
        reason = as_str(f.attrs["failure_reason"])
        assert "step size fell to h = " in reason and " at t = " in reason, reason
        t_reached = float(f.attrs["t_reached"])
        assert t_reached == pytest.approx(t_stop, abs=1e-6)
        np.testing.assert_allclose(f["time"][()], times, atol=1e-12)
        assert f.attrs["steps_accepted"] < 100000
    assert leftovers(tmp_path) == []


def pendulum_with_ida(tmp_path, ida, name="budget.yaml"):
    """The pendulum model with `integrator: ida` and the given `ida:` block text."""
    text = open(os.path.join(MODELS, "pendulum.yaml")).read()
    text = text.replace("integrator: hht", "integrator: ida")
    text = text.replace("ida: {rtol: 1.0e-8, atol: 1.0e-10}", "ida: " + ida)
    (tmp_path / name).write_text(text)
    return name, text.splitlines().index("  ida: " + ida) + 1


def test_step_budget_from_the_model_file_ends_the_run_with_exit_3(tmp_path):
    # simulation: {ida: {max_steps: 60}}: the run stops when the 60 steps are used up,
    # long before t_end = 0.5, as a solver failure with the rows up to there.
    model, _ = pendulum_with_ida(tmp_path, "{rtol: 1.0e-8, atol: 1.0e-10, max_steps: 60}")
    p = run(["simulate", model, "--quiet"], tmp_path)
    assert p.returncode == 3, p.stderr
    err = p.stderr
    assert err.startswith("mbdae: error: the solver failed at t = "), err
    assert "IDA: the step budget of 60 steps is used up at t = " in err, err
    assert "the results up to there are in budget.h5" in err, err
    with h5py.File(tmp_path / "budget.h5", "r") as f:
        assert as_str(f.attrs["status"]) == "failed"
        assert "step budget of 60 steps" in as_str(f.attrs["failure_reason"])
        assert f.attrs["ida_max_steps"] == 60 and f.attrs["ida_min_step"] == 0
        assert f.attrs["steps_accepted"] == 60
        t_reached = float(f.attrs["t_reached"])
        assert 0 < t_reached < 0.5
        times = f["time"][()]
        assert len(times) >= 1 and times[0] == 0.0
        assert times[-1] <= t_reached < times[-1] + 0.01 + 1e-9
        assert f["q"].shape[0] == len(times)
    assert leftovers(tmp_path) == []
    # The same model with the default budget (and a smallest step IDA never reaches)
    # runs to its end.
    model, _ = pendulum_with_ida(tmp_path, "{rtol: 1.0e-8, atol: 1.0e-10, min_step: 1.0e-12}",
                                 "enough.yaml")
    p = run(["simulate", model, "--quiet"], tmp_path)
    assert p.returncode == 0, p.stderr
    with h5py.File(tmp_path / "enough.h5", "r") as f:
        assert as_str(f.attrs["status"]) == "done"
        assert f.attrs["ida_max_steps"] == 100000000 and f.attrs["ida_min_step"] == 1e-12
        assert f.attrs["steps_accepted"] > 60


@pytest.mark.parametrize("ida,message", [
    ("{max_steps: 0}", "simulation: ida max_steps must be a whole number >= 1, got 0"),
    ("{max_steps: 2.5}", "simulation: ida max_steps must be a whole number >= 1, got 2.5"),
    ("{max_steps: -3}", "simulation: ida max_steps must be a whole number >= 1, got -3"),
    ("{min_step: 0}", "simulation: ida min_step must be > 0, got 0"),
    ("{min_step: -1e-9}", "simulation: ida min_step must be > 0, got -1e-09"),
    ("{min_step: 1/0}", "simulation: 'ida min_step' evaluates to inf"),
    ("{max_step: 10}", "simulation: unknown key 'max_step'; did you mean 'max_steps'?"),
], ids=["max_steps-0", "max_steps-fraction", "max_steps-negative", "min_step-0",
        "min_step-negative", "min_step-inf", "misspelt"])
def test_bad_ida_step_settings_exit_2_with_file_and_line(tmp_path, ida, message):
    model, line = pendulum_with_ida(tmp_path, ida)
    p = run(["simulate", model, "--quiet"], tmp_path)
    assert p.returncode == 2, p.stderr
    assert p.stderr.startswith("mbdae: error: %s:%d:" % (model, line)), p.stderr
    assert message in p.stderr, p.stderr
    assert not list(tmp_path.glob("*.h5")) and leftovers(tmp_path) == []
    p = run(["check", model], tmp_path)
    assert p.returncode == 2 and message in p.stderr, p.stderr


def test_fourbar_through_its_singular_positions_runs_to_the_end(tmp_path):
    # IDA at rtol = atol = 1e-10 crept through the first singular position with steps of
    # 1e-20 s; since issue 11, part 1 it passes all of them (tests/app/test_singular_passage.py).
    model = copy_model("fourbar_singular.yaml", tmp_path)
    p = run(["simulate", model, "--quiet"], tmp_path)
    assert p.returncode == 0, p.stderr
    with h5py.File(tmp_path / "fourbar_singular.h5", "r") as f:
        assert as_str(f.attrs["status"]) == "done"
        assert float(f.attrs["t_reached"]) == pytest.approx(10.0, abs=1e-12)
    assert leftovers(tmp_path) == []


def test_model_is_never_the_results_file(tmp_path):
    model = copy_model("pendulum.yaml", tmp_path)
    original = (tmp_path / model).read_bytes()
    os.symlink(model, tmp_path / "link.yaml")
    os.link(tmp_path / model, tmp_path / "hard.yaml")
    (tmp_path / "sub").mkdir()
    for out in [model, "./" + model, "sub/../" + model, str(tmp_path / model), "link.yaml", "hard.yaml"]:
        p = run(["simulate", model, "-o", out, "--quiet"], tmp_path)
        assert p.returncode == 2, (out, p.stderr)
        assert "is the input file" in p.stderr, p.stderr
        assert (tmp_path / model).read_bytes() == original
    # The model through another name is refused as well.
    p = run(["simulate", "./" + model, "-o", "link.yaml", "--quiet"], tmp_path)
    assert p.returncode == 2, p.stderr
    p = run(["convert", model, "-o", "link.yaml"], tmp_path)
    assert p.returncode == 2 and "itself" in p.stderr, p.stderr
    assert (tmp_path / model).read_bytes() == original
    assert not list(tmp_path.glob("*.h5")) and leftovers(tmp_path) == []


def test_results_through_a_symbolic_link_are_written_where_it_points(tmp_path):
    model = copy_model("pendulum.yaml", tmp_path)
    (tmp_path / "data").mkdir()
    os.symlink("data/real.h5", tmp_path / "out.h5")
    p = run(["simulate", model, "-o", "out.h5", "--t-end", "0.1", "--quiet"], tmp_path)
    assert p.returncode == 0, p.stderr
    assert os.path.islink(tmp_path / "out.h5")
    with h5py.File(tmp_path / "data" / "real.h5", "r") as f:
        assert as_str(f.attrs["status"]) == "done"


@pytest.mark.parametrize("out,reason", [
    ("missing_dir/out.h5", "No such file or directory"),
    ("pendulum.yaml/out.h5", "Not a directory"),
    ("adir", "Is a directory"),
])
def test_unwritable_results_file_says_why(tmp_path, out, reason):
    model = copy_model("pendulum.yaml", tmp_path)
    (tmp_path / "adir").mkdir()
    p = run(["simulate", model, "-o", out, "--quiet"], tmp_path)
    assert p.returncode == 2, p.stderr
    assert p.stderr.strip() == "mbdae: error: cannot write the results file '%s': %s" % (out, reason)
    assert leftovers(tmp_path) == [] and not list(tmp_path.glob("*.h5"))


def test_a_refused_run_leaves_the_earlier_file(tmp_path):
    model = copy_model("pendulum.yaml", tmp_path)
    p = run(["simulate", model, "--t-end", "0.2", "--quiet"], tmp_path)
    assert p.returncode == 0, p.stderr
    before = (tmp_path / "pendulum.h5").read_bytes()
    p = run(["simulate", model, "--set", "nosuchparameter=1", "--quiet"], tmp_path)
    assert p.returncode == 2, p.stderr
    assert (tmp_path / "pendulum.h5").read_bytes() == before
    assert leftovers(tmp_path) == []


def start_long_run(tmp_path, model, out, integrator):
    """mbdae simulate of a run of 1e5 s (HHT: 1e8 steps), returns the process once the
    temporary results file exists (the run is then integrating or about to)."""
    proc = start_until_temporary([MBDAE, "simulate", model, "-o", out, "--integrator", integrator,
                                  "--t-end", "1e5", "--output-step", "0.01", "--quiet"],
                                 tmp_path, cwd=tmp_path)
    assert leftovers(tmp_path) == [out + ".%d.tmp" % proc.pid]
    return proc


@pytest.mark.parametrize("signum,integrator", [(signal.SIGTERM, "hht"), (signal.SIGINT, "hht"),
                                               (signal.SIGTERM, "ida")],
                         ids=["SIGTERM-hht", "SIGINT-hht", "SIGTERM-ida"])
def test_signal_stops_the_run_and_keeps_the_rows(tmp_path, signum, integrator):
    model = copy_model("pendulum.yaml", tmp_path)
    # An earlier results file of that name: whole and readable until the new run ends.
    p = run(["simulate", model, "-o", "run.h5", "--t-end", "0.2", "--quiet"], tmp_path)
    assert p.returncode == 0, p.stderr
    proc = start_long_run(tmp_path, model, "run.h5", integrator)
    with h5py.File(tmp_path / "run.h5", "r") as f:
        assert as_str(f.attrs["status"]) == "done" and f["time"][-1] == 0.2
    # Rows are being written to the temporary file: wait for a few (time.sleep only
    # paces the polling, the test does not depend on how long anything takes).
    time.sleep(0.5)
    proc.send_signal(signum)
    out, err = proc.communicate(timeout=120)
    assert proc.returncode == 128 + signum, (proc.returncode, err)
    name = "SIGTERM" if signum == signal.SIGTERM else "SIGINT"
    assert "mbdae: error: interrupted by %s at t = " % name in err, err
    assert "the results up to there are in run.h5" in err, err
    assert leftovers(tmp_path) == []
    with h5py.File(tmp_path / "run.h5", "r") as f:
        assert as_str(f.attrs["status"]) == "interrupted"
        t_reached = float(f.attrs["t_reached"])
        times = f["time"][()]
        assert f.attrs["t_end"] == 1e5
        assert len(times) >= 1 and times[0] == 0.0
        # The rows are the output times up to the last step taken.
        assert times[-1] <= t_reached < times[-1] + 0.01 + 1e-9
        assert t_reached < 1e5
        assert f["q"].shape[0] == len(times)
        assert "failure_reason" not in f.attrs
        assert as_str(f.attrs["integrator"]) == integrator
