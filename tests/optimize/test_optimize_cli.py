"""`mbdae optimize` (shared/spec/sensitivities.md, "Optimal control and identification"):
the known optimum of a rest-to-rest rotor turn, a parameter identified exactly, bad
problem files (exit 2 naming file and line, nothing written), non-convergence (exit 3,
the final point and the history still written).

Run by CTest (optimize.cli) with MBDAE_BIN and MBDAE_OPTIMIZE_DIR set.
"""
import json
import os
import shutil
import signal
import subprocess
import sys

import h5py
import numpy as np
import pytest

sys.path.insert(0, os.path.join(os.path.dirname(__file__), "..", "support"))
from running import signal_keeps_earlier_file, start_until_temporary, temporary_files  # noqa: E402

MBDAE = os.environ.get("MBDAE_BIN", "build/mbdae")
HERE = os.environ.get("MBDAE_OPTIMIZE_DIR", "tests/optimize")
J, THETA_F, T = 0.5, 1.0, 1.0  # rotor.yaml, rotor_problem.yaml
OPTIMUM = 12 * J**2 * THETA_F**2 / T**3


def optimize(problem, *args, expect=0):
    p = subprocess.run([MBDAE, "optimize", str(problem), *args], capture_output=True, text=True)
    assert p.returncode == expect, f"exit {p.returncode}\nstdout: {p.stdout}\nstderr: {p.stderr}"
    return p


def copy_problem(tmp_path, text=None):
    """rotor.yaml and a problem file (rotor_problem.yaml or `text`) in tmp_path."""
    shutil.copy(os.path.join(HERE, "rotor.yaml"), tmp_path / "rotor.yaml")
    problem = tmp_path / "problem.yaml"
    problem.write_text(text if text is not None else open(os.path.join(HERE, "rotor_problem.yaml")).read())
    return problem


@pytest.mark.parametrize("method", ["adjoint", "forward"])
def test_rotor_reaches_the_known_optimum(tmp_path, method):
    problem = copy_problem(tmp_path)
    if method != "adjoint":
        problem.write_text(problem.read_text() + f"method: {method}\n")
    out = tmp_path / "rotor.h5"
    p = optimize(problem, "--json", "-o", str(out))
    d = json.loads(p.stdout)
    assert d["status"] == "solved" and d["ipopt_status"] == "Solve_Succeeded"
    # minimum of integral tau^2 = 12 J^2 theta_f^2 / T^3 (measured: 4.5e-6 relative with
    # the HHT step 1e-3, the trapezoidal quadrature's and the scheme's O(h^2))
    assert abs(d["objective"] - OPTIMUM) / OPTIMUM < 1e-4
    assert d["constraint_violation"] < 1e-9
    assert d["constraints"]["final_angle"] == pytest.approx(THETA_F, abs=1e-9)
    assert abs(d["constraints"]["final_speed"]) < 1e-9
    # tau linear in t: 6 J theta_f / T^2 (1 - 2 t / T) at the 21 knots (measured max
    # deviation 1.8e-4, the discrete problem's)
    t = np.linspace(0, T, 21)
    tau = np.array([d["variables"][f"tau[{i}]"] for i in range(21)])
    assert np.max(np.abs(tau - 6 * J * THETA_F / T**2 * (1 - 2 * t / T))) < 1e-3
    # about one run and gradient per iteration (measured: 16 iterations, 17 evaluations)
    assert d["iterations"] < 40
    assert d["gradient_evaluations"] <= 2 * d["iterations"] + 2
    with h5py.File(out, "r") as f:
        assert f.attrs["status"] == "done" and f.attrs["optimization_status"] == "solved"
        g = f["optimization"]
        names = [n.decode() for n in g["variable_names"][:]]
        assert names == list(d["variables"])
        assert np.array_equal(g["variables"][:], tau)
        h = g["history"][:]
        cols = list(g["history"].attrs["columns"])
        assert cols[:3] == ["iteration", "objective", "constraint_violation"]
        assert h.shape == (d["iterations"] + 1, 5)
        assert np.array_equal(h[:, 0], np.arange(d["iterations"] + 1))
        assert h[0, 1] == 0 and h[0, 2] == pytest.approx(THETA_F)  # zero torque: not turned
        assert h[-1, 1] == pytest.approx(d["objective"], rel=1e-9)
        assert g.attrs["objective"] == d["objective"]
        # the final run's rows: the angle rises from 0 to theta_f
        assert f["time"].shape[0] == 101


def test_progress_lines_and_report(tmp_path):
    problem = copy_problem(tmp_path)
    p = optimize(problem, "-o", str(tmp_path / "r.h5"))
    lines = [l for l in p.stderr.splitlines() if l.startswith("mbdae:") and l.split()[1].isdigit()]
    assert len(lines) >= 5 and lines[0].split()[1] == "0"
    assert "status: solved" in p.stdout and "objective energy = 3.0000" in p.stdout
    q = optimize(problem, "--quiet", "-o", str(tmp_path / "q.h5"))
    assert q.stdout == "" and q.stderr == ""


def test_default_results_path_is_the_problem_with_h5(tmp_path):
    problem = copy_problem(tmp_path)
    problem.write_text(problem.read_text().replace("max_iter: 100", "max_iter: 3"))
    optimize(problem, "--quiet", expect=3)
    assert (tmp_path / "problem.h5").exists()


def test_parameter_identified_exactly(tmp_path):
    # constant torque 1 on the rotor: angle(1) = 1 / (2 J) (HHT exact for constant
    # acceleration); the J that puts it at 0.25 is 2, from a start at 0.5
    text = open(os.path.join(HERE, "rotor.yaml")).read()
    text = text.replace("y: [" + ", ".join(["0"] * 21) + "]", "y: [" + ", ".join(["1"] * 21) + "]")
    text = text.replace('  - {name: final_speed, terminal: "speed"}',
                        '  - {name: final_speed, terminal: "speed"}\n  - {name: miss, terminal: "(angle - 0.25)^2"}')
    (tmp_path / "rotor.yaml").write_text(text)
    for method in ("adjoint", "fd"):
        problem = tmp_path / f"id_{method}.yaml"
        problem.write_text("model: rotor.yaml\nvariables:\n  - {parameter: J, lower: 0.5, upper: 4}\n"
                           f"minimize: miss\nmethod: {method}\nipopt: {{tol: 1.0e-12}}\n")
        d = json.loads(optimize(problem, "--json", "--quiet", "-o", str(tmp_path / f"{method}.h5")).stdout)
        assert d["status"] == "solved"
        # measured: 5.5e-11 (adjoint), 1.4e-10 (fd)
        assert d["variables"]["J"] == pytest.approx(2.0, abs=1e-8)


GOOD = open(os.path.join(HERE, "rotor_problem.yaml")).read()


@pytest.mark.parametrize("change,line,needle", [
    (("{spline: tau,", "{spline: nope,"), 6, "unknown spline 'nope'"),
    (("{spline: tau, lower: -40, upper: 40}", "{parameter: Jx, lower: 0, upper: 1}"), 6, "unknown parameter 'Jx'"),
    (("minimize: energy", "minimize: power"), 7, "unknown objective 'power'"),
    (("{objective: final_speed,", "{objective: final_sped,"), 10, "unknown objective 'final_sped'"),
    (("lower: -40, upper: 40", "lower: 40, upper: -40"), 6, "greater than upper bound"),
    (("model: rotor.yaml", "model: missing.yaml"), 4, "missing.yaml' does not exist"),
    (("minimize: energy", "minimise: energy"), 7, "unknown key 'minimise'"),
    (("max_iter: 100", "max_iters: 100"), 11, "unknown Ipopt option 'max_iters'"),
    (("max_iter: 100", "max_iter: many"), 11, "takes an integer"),
    (("ipopt:", "simulation: {integrator: ida, ida: {max_steps: 0}}\nipopt:"), 11, "ida max_steps must be a whole number"),
    (("ipopt:", "simulation: {integrator: ida, ida: {min_step: -1}}\nipopt:"), 11, "ida min_step must be a positive number"),
    (("ipopt:", "simulation: {hht: {start: smooth}}\nipopt:"), 11, "hht start must be consistent or perturbed"),
    (("ipopt:", "simulation: {output_accelerations: exact}\nipopt:"), 11, "output_accelerations must be solved or integrator"),
])
def test_bad_problem_exits_2_naming_file_and_line(tmp_path, change, line, needle):
    assert change[0] in GOOD
    problem = copy_problem(tmp_path, GOOD.replace(*change))
    out = tmp_path / "bad.h5"
    p = optimize(problem, "--json", "-o", str(out), expect=2)
    assert f"{problem}:{line}:" in p.stderr and needle in p.stderr, p.stderr
    assert p.stdout == "" and not out.exists() and not (tmp_path / "problem.h5").exists()


def test_simulation_overrides_reach_the_final_run(tmp_path):
    # the problem's simulation: block takes the model's keys: IDA's step budget (too
    # small: the run fails, exit 3, as the model file's max_steps would), HHT's start and
    # the output rows' accelerations (written as the final run's attributes)
    problem = copy_problem(tmp_path, GOOD.replace(
        "ipopt:", "simulation: {hht: {start: perturbed}, output_accelerations: integrator}\nipopt:"))
    out = tmp_path / "o.h5"
    d = json.loads(optimize(problem, "--json", "-o", str(out)).stdout)
    assert d["status"] == "solved" and abs(d["objective"] - OPTIMUM) / OPTIMUM < 1e-4
    with h5py.File(out, "r") as f:
        assert f.attrs["output_accelerations"] == "integrator"
    problem = copy_problem(tmp_path, GOOD.replace(
        "ipopt:", "simulation: {integrator: ida, ida: {max_steps: 5}}\nipopt:"))
    p = optimize(problem, "--json", "-o", str(tmp_path / "ida.h5"), expect=3)
    assert "max_steps" in p.stderr or "step budget" in p.stderr, p.stderr


def test_missing_problem_file_exits_2(tmp_path):
    p = optimize(tmp_path / "none.yaml", expect=2)
    assert "none.yaml" in p.stderr


def test_no_convergence_exits_3_with_history_and_point(tmp_path):
    problem = copy_problem(tmp_path, GOOD.replace("max_iter: 100", "max_iter: 2"))
    out = tmp_path / "nc.h5"
    p = optimize(problem, "--json", "-o", str(out), expect=3)
    d = json.loads(p.stdout)
    assert d["status"] == "failed" and d["ipopt_status"] == "Maximum_Iterations_Exceeded"
    assert d["iterations"] == 2
    assert "not solved" in p.stderr and str(out) in p.stderr
    with h5py.File(out, "r") as f:
        assert f.attrs["optimization_status"] == "failed"
        g = f["optimization"]
        assert g["history"].shape == (3, 5)
        assert np.array_equal(g["variables"][:], [d["variables"][f"tau[{i}]"] for i in range(21)])
        assert g.attrs["objective"] == pytest.approx(d["objective"], rel=1e-15)
    assert tmp_files(tmp_path) == []


# ---- multiple shooting (`shooting:`) ---------------------------------------------------

def shooting_problem(tmp_path, theta_f=1.0, intervals=4, change=None):
    """rotor_shooting.yaml and rotor_shooting_problem.yaml (final angle theta_f) in tmp_path."""
    shutil.copy(os.path.join(HERE, "rotor_shooting.yaml"), tmp_path / "rotor_shooting.yaml")
    text = open(os.path.join(HERE, "rotor_shooting_problem.yaml")).read()
    text = text.replace("equals: 1.0}", "equals: %r}" % theta_f).replace("intervals: 4", "intervals: %d" % intervals)
    if change:
        assert change[0] in text
        text = text.replace(*change)
    problem = tmp_path / "shooting.yaml"
    problem.write_text(text)
    return problem


@pytest.mark.parametrize("theta_f", [1.0, 7.0])
def test_multiple_shooting_reaches_the_known_optimum(tmp_path, theta_f):
    # 7 rad: the nodes at t = 0.5 and 0.75 s lie beyond pi (3.5 and 5.906 rad): the
    # intervals' angles must continue the node's turn, not restart at the principal value
    out = tmp_path / "shoot.h5"
    d = json.loads(optimize(shooting_problem(tmp_path, theta_f), "--json", "-o", str(out)).stdout)
    optimum = 12 * J**2 * theta_f**2 / T**3
    assert d["status"] == "solved" and d["shooting_intervals"] == 4
    # measured: 4.5e-6 relative, as single shooting (the same HHT steps)
    assert abs(d["objective"] - optimum) / optimum < 1e-4
    # the continuity constraints are met to Ipopt's tolerance (measured 5e-14 at 1 rad)
    assert d["shooting_defect"] < 1e-8 * max(1.0, theta_f)
    # the node variables are the optimal motion at t = 0.25, 0.5, 0.75 s:
    # angle theta_f (3 s^2 - 2 s^3), speed 6 theta_f / T s (1 - s), s = t / T
    for k in (1, 2, 3):
        s = k / 4
        assert d["variables"][f"a0@{k}"] == pytest.approx(theta_f * (3 * s**2 - 2 * s**3), abs=2e-4 * theta_f)
        assert d["variables"][f"w0@{k}"] == pytest.approx(6 * theta_f / T * s * (1 - s), abs=2e-4 * theta_f)
    # the final run is one run over [0, T]: HHT restarted at the nodes differs from it by
    # the scheme's error only (measured 1.2e-6 rad at 1 rad)
    assert d["constraints"]["final_angle"] == pytest.approx(theta_f, abs=1e-5 * theta_f)
    assert abs(d["constraints"]["final_speed"]) < 1e-5 * theta_f
    # one run and gradient per interval and evaluation, after the 3 runs of the forward
    # sweep that starts the node variables (measured: 17 iterations, 99 at 1 rad)
    assert (d["gradient_evaluations"] - 3) % 4 == 0 and d["iterations"] < 40
    with h5py.File(out, "r") as f:
        assert f["optimization"].attrs["shooting_intervals"] == 4


def test_node_variables_start_where_given(tmp_path):
    # `start:` of the node variables (the closed-form motion at t = 0.25, 0.5, 0.75 s):
    # no forward sweep, and the same optimum
    nodes_a = [3 * s**2 - 2 * s**3 for s in (0.25, 0.5, 0.75)]
    nodes_w = [6 * s * (1 - s) for s in (0.25, 0.5, 0.75)]
    change = ("    - {parameter: a0, measure: angle}\n    - {parameter: w0, measure: speed}",
              "    - {parameter: a0, measure: angle, start: %r}\n    - {parameter: w0, measure: speed, start: %r}"
              % (nodes_a, nodes_w))
    d = json.loads(optimize(shooting_problem(tmp_path, change=change), "--json", "-o", str(tmp_path / "s.h5")).stdout)
    assert d["status"] == "solved"
    assert abs(d["objective"] - OPTIMUM) / OPTIMUM < 1e-4
    assert d["gradient_evaluations"] % 4 == 0  # whole evaluations only: no sweep runs


@pytest.mark.parametrize("shooting", [False, True])
def test_exact_hessian_by_differences_of_gradients(tmp_path, shooting):
    # ipopt: {hessian_approximation: exact}: the Lagrangian's Hessian from forward
    # differences of the adjoint gradients; the same optimum in fewer iterations
    # (measured: 7 against 17 with the limited-memory Hessian, shooting)
    change = ("ipopt: {", "ipopt: {hessian_approximation: exact, ")
    if shooting:
        problem = shooting_problem(tmp_path, change=change)
    else:
        problem = copy_problem(tmp_path)
        problem.write_text(problem.read_text().replace(*change))
    p = optimize(problem, "--json", "-o", str(tmp_path / "h.h5"))
    d = json.loads(p.stdout)
    assert d["status"] == "solved"
    assert abs(d["objective"] - OPTIMUM) / OPTIMUM < 1e-4
    # shooting: the final run over [0, T] differs from the restarted intervals (1.4e-6)
    assert d["constraint_violation"] < (1e-5 if shooting else 1e-9)
    assert 1 <= d["hessian_evaluations"] <= d["iterations"] + 1
    assert d["iterations"] <= 12
    if shooting:
        assert d["shooting_defect"] < 1e-8
        # per Hessian: the 21 ordinates rerun all 4 intervals, the 6 node variables one each,
        # plus the 4 unperturbed intervals
        per_hessian = 21 * 4 + 6 + 4
        assert d["gradient_evaluations"] >= per_hessian * d["hessian_evaluations"]


@pytest.mark.parametrize("change, line, needle", [
    (("    - {parameter: a0, measure: angle}", "    - {parameter: a0, measure: angle, start: [0.1, 0.5]}"), 16,
     "expected 'start': a list of 3 values"),
    (("    - {parameter: a0, measure: angle}", "    - {parameter: a0, measure: angle, upper: 1, start: [0.1, 0.5, 2]}"), 16,
     "start 2 is outside the bounds"),
    (("    - {parameter: a0, measure: angle}", "    - {parameter: a0, measure: angel}"), 16, "unknown measure 'angel'"),
    (("time: t0", "time: tt"), 14, "unknown parameter 'tt'"),
    (("    - {parameter: w0, measure: speed}", "    - {parameter: a0, measure: speed}"), 17, "used twice"),
    (("intervals: 4", "intervals: 0"), 13, "intervals must be an integer from 1 to 1000"),
    (("variables:\n", "variables:\n  - {parameter: t0}\n"), 15, "is a variable"),
])
def test_bad_shooting_exits_2_naming_file_and_line(tmp_path, change, line, needle):
    problem = shooting_problem(tmp_path, change=change)
    out = tmp_path / "bad.h5"
    p = optimize(problem, "--json", "-o", str(out), expect=2)
    assert f"{problem}:{line}:" in p.stderr and needle in p.stderr, p.stderr
    assert p.stdout == "" and not out.exists()


# ---- the results file: written beside it, renamed at the end (docs/cli.md) -------------

tmp_files = temporary_files


def test_an_earlier_results_file_is_replaced_at_the_end(tmp_path):
    problem = copy_problem(tmp_path)
    out = tmp_path / "out.h5"
    out.write_bytes(b"earlier results")
    optimize(problem, "--quiet", "-o", str(out))
    with h5py.File(out, "r") as f:
        assert f.attrs["optimization_status"] == "solved" and "optimization/history" in f
    assert tmp_files(tmp_path) == []


def test_results_file_is_never_the_problem_or_its_model(tmp_path):
    copy_problem(tmp_path)
    os.symlink("problem.yaml", tmp_path / "plink.yaml")
    os.symlink("rotor.yaml", tmp_path / "mlink.yaml")
    originals = {n: (tmp_path / n).read_bytes() for n in ["problem.yaml", "rotor.yaml"]}
    for out, needle in [("problem.yaml", "is the input file"), ("./problem.yaml", "is the input file"),
                        ("plink.yaml", "is the input file"), ("rotor.yaml", "is the model file"),
                        ("./rotor.yaml", "is the model file"), ("mlink.yaml", "is the model file"),
                        (str(tmp_path / "rotor.yaml"), "is the model file")]:
        p = subprocess.run([MBDAE, "optimize", "problem.yaml", "-o", out, "--quiet"], cwd=tmp_path,
                           capture_output=True, text=True, timeout=120)
        assert p.returncode == 2, (out, p.stderr)
        assert needle in p.stderr, p.stderr
        for n, text in originals.items():
            assert (tmp_path / n).read_bytes() == text
    assert not list(tmp_path.glob("*.h5")) and tmp_files(tmp_path) == []


def test_unwritable_results_file_says_why(tmp_path):
    copy_problem(tmp_path)
    p = subprocess.run([MBDAE, "optimize", "problem.yaml", "-o", "missing_dir/out.h5", "--quiet"], cwd=tmp_path,
                       capture_output=True, text=True, timeout=120)
    assert p.returncode == 2, p.stderr
    assert p.stderr.strip() == ("mbdae: error: cannot write the results file 'missing_dir/out.h5': "
                                "No such file or directory")
    assert tmp_files(tmp_path) == [] and not list(tmp_path.glob("*.h5"))


@pytest.mark.parametrize("signum", [signal.SIGTERM, signal.SIGINT], ids=["SIGTERM", "SIGINT"])
def test_signal_removes_the_temporary_file_and_keeps_the_earlier_one(tmp_path, signum):
    problem = copy_problem(tmp_path)
    # HHT step 1e-5 (1e5 steps a run) and no iteration limit: still going when the signal comes.
    rotor = tmp_path / "rotor.yaml"
    rotor.write_text(rotor.read_text().replace("hht: {step: 1.0e-3}", "hht: {step: 1.0e-5}"))
    problem.write_text(problem.read_text().replace("max_iter: 100", "max_iter: 100000"))
    out = tmp_path / "out.h5"
    out.write_bytes(b"earlier results")
    proc = start_until_temporary([MBDAE, "optimize", str(problem), "--quiet", "-o", str(out)],
                                 tmp_path)
    signal_keeps_earlier_file(proc, out, tmp_path, signum, b"earlier results")


def test_a_looser_newton_threshold_of_the_model_is_not_taken(tmp_path):
    """hht: {newton_tolerance: 1e-4} in the model: the gradient runs and the final run keep
    1e-12 (docs/hht.md, "Newton threshold"), so the optimisation and its file are the
    default's."""
    problem = copy_problem(tmp_path)
    p = optimize(problem, "--json", "-o", str(tmp_path / "d.h5"))
    default = json.loads(p.stdout)
    text = (tmp_path / "rotor.yaml").read_text()
    assert "hht: {step: 1.0e-3}" in text
    (tmp_path / "rotor.yaml").write_text(text.replace("hht: {step: 1.0e-3}",
                                                      "hht: {step: 1.0e-3, newton_tolerance: 1.0e-4}"))
    p = optimize(problem, "--json", "-o", str(tmp_path / "l.h5"))
    loose = json.loads(p.stdout)
    assert loose["objective"] == default["objective"]
    assert loose["variables"] == default["variables"]
    with h5py.File(tmp_path / "l.h5", "r") as f, h5py.File(tmp_path / "d.h5", "r") as g:
        assert f.attrs["hht_newton_tolerance"] == 1e-12
        assert np.array_equal(f["/q"][:], g["/q"][:])
