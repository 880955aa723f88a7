"""Objectives and gradients from Python (Model.objectives, Model.gradient,
Model.objective_function) on the oscillator of tests/api/models/gradient_oscillator.yaml:
m x'' + c x' + k x = u(t), objectives G = int 0.5 x^2 + v(T), E = int c v^2,
fit = int (x - ref(t))^2.

References through the package itself: objective values from the rows of m.solve()
(output at every HHT step: the trapezoidal rule over the rows is the run's quadrature),
gradients by central differences of such solves; and identifications with
scipy.optimize.minimize whose answers are known.
"""

import os

import numpy as np
import pytest
import scipy.interpolate
import scipy.optimize

import mbdae
from conftest import PENDULUM, ROOT

MODEL = os.path.join(ROOT, "tests", "api", "models", "gradient_oscillator.yaml")


@pytest.fixture
def osc():
    with mbdae.Model(MODEL) as m:
        yield m


def trapz(y, t):
    return float(np.sum(0.5 * (y[1:] + y[:-1]) * np.diff(t)))


def solved_objectives(m):
    """G, E, fit from the stored rows of a solve (ref: natural cubic, as the model's)."""
    m.solve()
    t = m.outputs.time
    x, v = m.outputs.measure("x"), m.outputs.measure("v")
    rx, ry = m.splines["ref"]
    ref = scipy.interpolate.CubicSpline(rx, ry, bc_type="natural")(t)
    return {"G": trapz(0.5 * x ** 2, t) + v[-1], "E": trapz(m.parameters["c"] * v ** 2, t),
            "fit": trapz((x - ref) ** 2, t)}


def set_variable(m, name, value):
    if "[" in name:
        spline, i = name[:-1].split("[")
        x, y = m.splines[spline]
        y[int(i)] = value
        m.splines[spline] = (x, y)
    else:
        m.parameters[name] = value


def get_variable(m, name):
    if "[" in name:
        spline, i = name[:-1].split("[")
        return m.splines[spline][1][int(i)]
    return m.parameters[name]


def central_differences(m, wrt, rel_step=1e-4):
    """{objective: array over wrt} of (G(p + h) - G(p - h)) / 2h from solves."""
    out = {o: np.empty(len(wrt)) for o in ("G", "E", "fit")}
    for k, name in enumerate(wrt):
        p = get_variable(m, name)
        h = rel_step * max(abs(p), 1.0)
        set_variable(m, name, p + h)
        plus = solved_objectives(m)
        set_variable(m, name, p - h)
        minus = solved_objectives(m)
        set_variable(m, name, p)
        for o in out:
            out[o][k] = (plus[o] - minus[o]) / (2 * h)
    return out


def set_reference(m, k=6.0, c=0.3, every=10):
    """ref := the motion x(t) of the model with stiffness k and damping c (sampled every
    `every` rows), then k and c set back to what they were."""
    k0, c0 = m.parameters["k"], m.parameters["c"]
    m.parameters["k"], m.parameters["c"] = k, c
    m.solve()
    t, x = m.outputs.time[::every], m.outputs.measure("x")[::every]
    m.parameters["k"], m.parameters["c"] = k0, c0
    m.splines["ref"] = (t, x)


# ---- values, gradients and their forms -------------------------------------------------

def test_objective_names(osc):
    assert osc.objectives == ["G", "E", "fit"]
    assert osc.index("objectives", "fit") == 2
    with mbdae.Model(PENDULUM) as p:
        assert p.objectives == []
        with pytest.raises(mbdae.InputError, match="no objectives"):
            p.gradient()


def test_gradient_against_central_differences_of_solves(osc):
    set_reference(osc)
    wrt = ["mass", "k", "c", "x0", "v0", "u[2]", "ref[50]"]
    g = osc.gradient(wrt=wrt)
    assert g.objectives == ["G", "E", "fit"] and g.wrt == wrt
    assert g.method == "adjoint" and g.integrator == "hht"
    assert g.gradient.shape == (3, len(wrt)) and g.gradient.dtype == np.float64
    solved = solved_objectives(osc)
    for o in g.objectives:
        assert g.values[o] == pytest.approx(solved[o], rel=1e-11, abs=1e-14)
    fd = central_differences(osc, wrt)
    worst = 0.0
    for i, o in enumerate(g.objectives):
        scale = np.maximum(1.0, np.abs(fd[o]))
        err = np.abs(g.gradient[i] - fd[o]) / scale
        worst = max(worst, err.max())
        assert err.max() < 1e-7, (o, g.gradient[i], fd[o])
    print("adjoint vs central differences of solves: worst %.2e" % worst)
    # the fit objective depends on ref[50] and not on ...; G does not use ref at all
    assert g["G"]["ref[50]"] == 0.0
    assert abs(g["fit"]["ref[50]"]) > 1e-6


def test_forms_of_the_result(osc):
    g = osc.gradient(objectives="E", wrt=["c", "k"], method="forward")
    assert g.objectives == ["E"] and g.wrt == ["c", "k"]
    assert list(g.values) == ["E"]
    d = g.as_dict()
    assert set(d) == {"E"} and set(d["E"]) == {"value", "gradient"}
    assert d["E"]["gradient"] == g["E"] == {"c": g.gradient[0, 0], "k": g.gradient[0, 1]}
    assert d["E"]["value"] == g.values["E"] == g.value_array()[0]
    assert g.fd_steps is None
    assert g.forward_steps == 2000 and g.runs >= 1
    assert g.solver_cpu_time > 0 and g.gradient_cpu_time >= 0 and g.wall_time > 0
    assert "objective E" in str(g) and "dE/dp" in g.report()
    with pytest.raises(mbdae.ArgumentError, match="no objective 'G'"):
        g["G"]
    # A Gradient is a copy: a later call does not change it.
    before = g.gradient.copy()
    osc.gradient(wrt=["mass"])
    np.testing.assert_array_equal(g.gradient, before)
    assert g.wrt == ["c", "k"]


def test_methods_agree_and_fd_steps(osc):
    wrt = ["k", "c", "u[1]"]
    adjoint = osc.gradient(wrt=wrt, method="adjoint")
    forward = osc.gradient(wrt=wrt, method="forward")
    osc.options["gradient.fd_step"] = 1e-4
    assert osc.options["gradient.fd_step"] == 1e-4
    fd = osc.gradient(wrt=wrt, method="fd")
    assert fd.method == "fd" and fd.runs == 1 + 2 * len(wrt)
    assert fd.fd_steps == pytest.approx({"k": 4e-4, "c": 1e-4, "u[1]": 1e-4}, rel=1e-15)
    scale = np.maximum(1.0, np.abs(adjoint.gradient))
    assert np.max(np.abs(forward.gradient - adjoint.gradient) / scale) < 1e-10
    assert np.max(np.abs(fd.gradient - adjoint.gradient) / scale) < 1e-7


def test_wrt_splines_and_spline_ordinates(osc):
    assert osc.spline_ordinates("u") == ["u[0]", "u[1]", "u[2]", "u[3]", "u[4]"]
    g = osc.gradient(objectives=["G"], wrt=["k"], wrt_splines=True)
    assert g.wrt == ["k"] + osc.spline_ordinates("u") + osc.spline_ordinates("ref")
    # u[0] (the force at t = 0) moves the block; ref does not enter G
    assert abs(g["G"]["u[0]"]) > 1e-4
    assert g["G"]["ref[0]"] == 0.0 and g["G"]["ref[1]"] == 0.0


def test_gradient_leaves_outputs_alone_and_writes_results(osc, tmp_path):
    import h5py

    osc.solve_to(0.25)
    q = osc.outputs.q
    path = tmp_path / "gradient.h5"
    g = osc.gradient(wrt=["k", "c"], results=path)
    np.testing.assert_array_equal(osc.outputs.q, q)
    assert osc.time == pytest.approx(0.25, abs=1e-12)
    with h5py.File(path, "r") as f:
        group = f["objectives/G"]
        assert group.attrs["value"] == pytest.approx(g.values["G"], rel=1e-14)
        names = [n.decode() if isinstance(n, bytes) else str(n)
                 for n in np.atleast_1d(group.attrs["gradient_names"])]
        assert names == ["k", "c"]
        np.testing.assert_allclose(np.asarray(group["gradient"]), g.gradient[0], rtol=1e-14)


# ---- mistakes -----------------------------------------------------------------------

def test_bad_names_and_methods(osc):
    with pytest.raises(mbdae.ArgumentError, match="no objective called 'energy'") as e:
        osc.gradient(objectives=["G", "energy"])
    assert "G, E, fit" in str(e.value)
    with pytest.raises(KeyError):
        osc.gradient(wrt=["stiffness"])
    with pytest.raises(mbdae.ArgumentError, match=r"u\[7\]"):
        osc.gradient(wrt=["u[7]"])
    with pytest.raises(mbdae.ArgumentError, match="unknown gradient method 'newton'"):
        osc.gradient(method="newton")
    with pytest.raises(mbdae.ArgumentError, match="'k' twice"):
        osc.gradient(wrt=["k", "k"])
    with pytest.raises(TypeError):
        osc.gradient(wrt=[1, 2])
    with pytest.raises(mbdae.InputError, match="gradient.fd_step"):
        osc.options["gradient.fd_step"] = -1
    with pytest.raises(mbdae.ArgumentError, match="energy"):
        osc.objective_function("energy", ["k"])
    with pytest.raises(mbdae.ArgumentError, match="stiffness"):
        osc.objective_function("G", ["stiffness"])
    with pytest.raises(mbdae.ArgumentError, match="newton"):
        osc.objective_function("G", ["k"], method="newton")
    f = osc.objective_function("G", ["k", "c"])
    with pytest.raises(mbdae.SizeError, match="x has 3 values"):
        f([1.0, 2.0, 3.0])


def test_a_failed_run_raises_solver_error():
    text = open(MODEL).read()
    text = text.replace('"spline(u, t)"', '"spline(u, t) + 0.01*log(tf - t)"')
    text = text.replace("  mass: 1.5", "  tf: 5\n  mass: 1.5")
    with mbdae.Model.from_string(text, "failing.yaml") as m:
        good = m.gradient(wrt=["k"])
        m.parameters["tf"] = 1.0
        with pytest.raises(mbdae.SolverError, match="forward run failed at t = "):
            m.gradient(wrt=["k"])
        f = m.objective_function("G", ["k"])
        with pytest.raises(mbdae.SolverError):
            f(f.x0)


# ---- the optimisation driver -------------------------------------------------------

def test_objective_function_shares_one_run_per_point(osc):
    f = osc.objective_function("G", ["k", "u[2]"])
    np.testing.assert_array_equal(f.x0, [4.0, 0.5])
    x = np.array([5.0, 0.25])
    value = f(x)
    grad = f.jac(x)
    assert f.runs == 1
    assert osc.parameters["k"] == 5.0 and osc.splines["u"][1][2] == 0.25
    g = osc.gradient(wrt=["k", "u[2]"])
    assert value == g.values["G"]
    np.testing.assert_array_equal(grad, g.gradient[0])
    e = f.for_objective("E", scale=-2.0)
    assert e(x) == pytest.approx(-2.0 * g.values["E"], rel=1e-14)
    assert f.runs == 2  # E was not in the cached run
    f(x), e.jac(x), f.jac(x)
    assert f.runs == 2 and e.runs == 2
    v, j = f.value_and_jac([4.0, 0.5])
    assert f.runs == 3 and j.shape == (2,)
    f.set([4.5, 0.5])
    assert osc.parameters["k"] == 4.5


def test_minimize_identifies_stiffness_and_damping(osc):
    # The target motion is the model's own with k = 6, c = 0.3 (sampled every 0.01 s,
    # interpolated by a natural cubic spline); BFGS with the adjoint gradient from
    # k = 4, c = 0.4 finds them back.
    set_reference(osc, k=6.0, c=0.3)
    f = osc.objective_function("fit", ["k", "c"])
    x0 = f.x0
    np.testing.assert_array_equal(x0, [4.0, 0.4])
    r = scipy.optimize.minimize(f, x0, jac=f.jac, method="BFGS", options={"gtol": 1e-10})
    print("BFGS: %s, x = %r, fit = %.3e, %d runs" % (r.message, r.x, r.fun, f.runs))
    assert r.success
    assert r.x[0] == pytest.approx(6.0, abs=1e-5)  # found to 1e-8 (the reference is a
    assert r.x[1] == pytest.approx(0.3, abs=1e-6)  # cubic interpolant of sampled rows)
    assert r.fun < 1e-10
    assert f.runs < 60


def test_minimize_identifies_force_ordinates(osc):
    # The target motion is that of the model with the force ordinates u[1..3] = (1, 0.5,
    # -0.5) (the file's); starting from zero force, L-BFGS-B over the three ordinates with
    # jac= finds them back.
    set_reference(osc)  # k = 6, c = 0.3
    osc.parameters["k"], osc.parameters["c"] = 6.0, 0.3
    wrt = ["u[1]", "u[2]", "u[3]"]
    f = osc.objective_function("fit", wrt, scale=1e4)
    f.set([0.0, 0.0, 0.0])
    r = scipy.optimize.minimize(f, f.x0, jac=f.jac, method="L-BFGS-B",
                                bounds=[(-5, 5)] * 3, options={"ftol": 1e-15, "gtol": 1e-12})
    print("L-BFGS-B: %s, x = %r, fit = %.3e, %d runs" % (r.message, r.x, r.fun, f.runs))
    assert r.success
    np.testing.assert_allclose(r.x, [1.0, 0.5, -0.5], atol=1e-5)  # found to 2e-8
