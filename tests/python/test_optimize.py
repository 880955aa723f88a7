"""Optimal control from Python: mbdae.optimize (the C API's mbdae_optimize) on the rotor
of tests/optimize/ (inertia J = 0.5 turned rest-to-rest by theta_f = 1 rad in T = 1 s by
a torque spline of 21 ordinates, minimum integral tau^2: the optimum is
12 J^2 theta_f^2 / T^3 = 3 with tau linear in t), the progress callback, the problem's
start: and parameters:, bad problem files; and the scipy route (Model.objective_function
with scipy.optimize.minimize) on the same rotor.
"""

import os
import shutil

import h5py
import numpy as np
import pytest
import scipy.optimize

import mbdae
from conftest import ROOT

HERE = os.path.join(ROOT, "tests", "optimize")
PROBLEM = os.path.join(HERE, "rotor_problem.yaml")
MODEL = os.path.join(HERE, "rotor.yaml")
J, THETA_F, T = 0.5, 1.0, 1.0
OPTIMUM = 12 * J ** 2 * THETA_F ** 2 / T ** 3
KNOTS = np.linspace(0, T, 21)


def linear_tau(j=J):
    """The continuous optimum tau(t) = 6 J theta_f / T^2 (1 - 2 t / T) at the knots."""
    return 6 * j * THETA_F / T ** 2 * (1 - 2 * KNOTS / T)


def problem_in(tmp_path, text):
    shutil.copy(MODEL, tmp_path / "rotor.yaml")
    path = tmp_path / "problem.yaml"
    path.write_text(text)
    return path


def test_rotor_optimum_and_one_progress_call_per_iteration(tmp_path):
    calls = []
    out = tmp_path / "rotor.h5"
    r = mbdae.optimize(PROBLEM, results=out, progress=lambda i, f, v: calls.append((i, f, v)))
    assert r.solved and r.status == "solved" and r.ipopt_status == "Solve_Succeeded"
    # measured 3.0000136 (4.5e-6 relative: HHT step 1e-3 and the trapezoidal quadrature)
    assert abs(r.objective - OPTIMUM) / OPTIMUM < 1e-4
    assert r.objective_name == "energy"
    assert r.constraint_violation < 1e-9
    assert r.constraints["final_angle"] == pytest.approx(THETA_F, abs=1e-9)
    assert abs(r.constraints["final_speed"]) < 1e-9
    assert list(r.variables) == ["tau[%d]" % i for i in range(21)]
    assert np.array_equal(r.x, list(r.variables.values()))
    assert np.max(np.abs(r.x - linear_tau())) < 1e-3  # measured 1.8e-4 (the CLI test's bound)
    # the callback: once per iteration, in order, the history's numbers
    assert 3 < r.iterations < 40
    assert r.history.shape == (r.iterations + 1, len(mbdae.HISTORY_COLUMNS))
    assert [c[0] for c in calls] == list(range(r.iterations + 1))
    assert np.array_equal([c[1] for c in calls], r.history[:, 1])
    assert np.array_equal([c[2] for c in calls], r.history[:, 2])
    assert r.history[0, 1] == 0 and r.history[0, 2] == pytest.approx(THETA_F, abs=1e-12)
    assert r.history[-1, 1] == pytest.approx(r.objective, rel=1e-9)
    # cost: about one run per iteration, plus the final run
    assert r.iterations <= r.gradient_evaluations <= 2 * r.iterations + 2
    assert r.runs == r.gradient_evaluations + 1 and r.failed_evaluations == 0
    assert 0 < r.gradient_cpu_time <= r.cpu_time and r.wall_time > 0
    text = str(r)
    assert text.startswith("status: solved") and "objective energy = 3.0000" in text
    assert r.as_dict()["objective"] == r.objective and r.results == str(out)
    with h5py.File(out, "r") as f:
        assert f.attrs["optimization_status"] == "solved"
        assert np.array_equal(f["optimization/variables"][:], r.x)


def test_progress_true_prints_a_line_per_iteration(capsys):
    r = mbdae.optimize(PROBLEM, progress=True)
    lines = [l for l in capsys.readouterr().out.splitlines() if l.split()[0].isdigit()]
    assert [int(l.split()[0]) for l in lines] == list(range(r.iterations + 1))
    assert float(lines[-1].split()[1]) == pytest.approx(r.history[-1, 1], rel=1e-12)


def test_progress_can_stop_and_its_exception_is_raised():
    r = mbdae.optimize(PROBLEM, progress=lambda i, f, v: i == 2)
    assert not r.solved and r.status == "failed" and r.ipopt_status == "User_Requested_Stop"
    assert r.history.shape[0] == 3

    def fail(i, f, v):
        if i == 1:
            raise ZeroDivisionError("from the callback")

    with pytest.raises(ZeroDivisionError, match="from the callback"):
        mbdae.optimize(PROBLEM, progress=fail)
    with pytest.raises(TypeError):
        mbdae.optimize(PROBLEM, progress=3)


def test_fixed_parameter_and_start_from_a_string():
    # J = 1 fixed by `parameters:`: optimum 12 J^2 = 12; every ordinate starting at 1
    # (constant torque): objective 1, angle(1) = 1 / (2 J) = 0.5, speed(1) = 1 / J = 1,
    # so the start's violation is 1
    text = open(PROBLEM).read()
    text = text.replace("model: rotor.yaml", "model: rotor.yaml\nparameters: {J: 1.0}")
    text = text.replace("upper: 40}", "upper: 40, start: 1}")
    r = mbdae.optimize_string(text, os.path.join(HERE, "inline.yaml"))
    assert r.solved
    assert abs(r.objective - 12.0) / 12.0 < 1e-4
    assert np.max(np.abs(r.x - linear_tau(1.0))) < 4e-3
    assert r.history[0, 1] == pytest.approx(1.0, abs=1e-12)
    assert r.history[0, 2] == pytest.approx(1.0, abs=1e-8)  # measured 3.5e-10 off (Newton)


def test_exact_hessian_and_shooting_counts_reach_python():
    # ipopt: {hessian_approximation: exact} (the Lagrangian's Hessian from differences of
    # the adjoint gradients): the same optimum; the counts reach OptimizationResult
    text = open(PROBLEM).read().replace("ipopt: {", "ipopt: {hessian_approximation: exact, ")
    r = mbdae.optimize_string(text, os.path.join(HERE, "inline.yaml"))
    assert r.solved
    assert abs(r.objective - OPTIMUM) / OPTIMUM < 1e-4
    assert 1 <= r.hessian_evaluations <= r.iterations + 1
    # a Hessian: one evaluation per ordinate (21) besides the point's own
    assert r.gradient_evaluations >= 21 * r.hessian_evaluations
    assert r.shooting_intervals == 1 and r.shooting_defect == 0


@pytest.mark.parametrize("change,line,needle", [
    (("upper: 40}", "upper: 40, start: -41}"), 6, "start -41 is outside the bounds [-40, 40]"),
    (("upper: 40}", "upper: 40, start: [0, 1]}"), 6, "start has 2 values, the variable 21 ordinates"),
    (("model: rotor.yaml", "model: rotor.yaml\nparameters: {g: 2.0}"), 5, "unknown parameter 'g'"),
    (("minimize: energy", "minimize: power"), 7, "unknown objective 'power'"),
])
def test_bad_problem_file_raises_input_error_naming_file_and_line(tmp_path, change, line, needle):
    text = open(PROBLEM).read()
    assert change[0] in text
    path = problem_in(tmp_path, text.replace(*change))
    out = tmp_path / "bad.h5"
    with pytest.raises(mbdae.InputError) as e:
        mbdae.optimize(path, results=out)
    assert str(e.value).startswith("%s:%d:" % (path, line)) and needle in str(e.value), str(e.value)
    assert e.value.status == 1 and not out.exists()


def test_missing_files_raise_file_error(tmp_path):
    with pytest.raises(mbdae.FileError, match="none.yaml"):
        mbdae.optimize(tmp_path / "none.yaml")
    with pytest.raises(mbdae.FileError, match="No such file or directory"):
        mbdae.optimize(PROBLEM, results=tmp_path / "no" / "r.h5")


def test_scipy_route_reaches_the_same_optimum():
    # The same problem with scipy's SLSQP: Model.objective_function over the 21 ordinates,
    # the constraints as functions sharing its runs, exact adjoint gradients as jac.
    with mbdae.Model(MODEL) as m:
        wrt = ["tau[%d]" % i for i in range(21)]
        energy = m.objective_function("energy", wrt)
        angle = energy.for_objective("final_angle")
        speed = energy.for_objective("final_speed")
        r = scipy.optimize.minimize(
            energy, energy.x0, jac=energy.jac, method="SLSQP", bounds=[(-40, 40)] * 21,
            constraints=[{"type": "eq", "fun": lambda x: angle(x) - THETA_F, "jac": angle.jac},
                         {"type": "eq", "fun": speed, "jac": speed.jac}],
            options={"ftol": 1e-12, "maxiter": 100})
        assert r.success, r.message
        assert abs(r.fun - OPTIMUM) / OPTIMUM < 1e-4
        assert abs(angle(r.x) - THETA_F) < 1e-8 and abs(speed(r.x)) < 1e-8
        assert np.max(np.abs(r.x - linear_tau())) < 1e-3
        # about one run per SLSQP iteration (fun and jac at one x share it)
        assert energy.runs <= r.nfev + r.njev + 1
