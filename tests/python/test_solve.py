"""mbdae.Model: assembling, solving, stepping, the state, stored outputs, results files."""

import numpy as np
import pytest

import mbdae


def step_response(p, force, t):
    """Closed-form response of the oscillator at rest to a constant force switched on at 0."""
    m, k, d = p["m"], p["k"], p["d"]
    wn = np.sqrt(k / m)
    zeta = d / (2 * np.sqrt(k * m))
    wd = wn * np.sqrt(1 - zeta ** 2)
    decay = np.exp(-zeta * wn * t)
    return force / k * (1 - decay * (np.cos(wd * t) + zeta / np.sqrt(1 - zeta ** 2) * np.sin(wd * t)))


def test_assemble_stores_the_initial_row(free_fall):
    assert len(free_fall.outputs) == 0
    free_fall.assemble()
    assert len(free_fall.outputs) == 1
    s = free_fall.state
    assert s.t == 0.0
    np.testing.assert_allclose(s.q, [0, 0, 10, 1, 0, 0, 0], atol=1e-14)
    np.testing.assert_allclose(s.v, [1, 0, 0, 0, 0, 0, 0], atol=1e-14)
    np.testing.assert_allclose(s.a[:3], [0, 0, -9.81], atol=1e-12)
    assert s["lambda"].shape == (free_fall.nm,) == (1,)  # the Euler-parameter normalisation


def test_free_fall_is_exact(free_fall):
    free_fall.solve()
    o = free_fall.outputs
    t = o.time
    np.testing.assert_allclose(t, np.arange(11) * 0.1, atol=1e-12)
    q = o.q
    assert q.shape == (11, 7)
    # HHT integrates a quadratic motion exactly (up to round-off).
    np.testing.assert_allclose(q[:, 0], t, atol=1e-10)
    np.testing.assert_allclose(q[:, 2], 10 - 0.5 * 9.81 * t ** 2, atol=1e-10)
    np.testing.assert_allclose(o.v[:, 2], -9.81 * t, atol=1e-10)
    np.testing.assert_allclose(o.a[:, 2], -9.81, atol=1e-9)
    np.testing.assert_allclose(o.measure("height"), q[:, 2], atol=1e-14)
    assert o.lambda_.shape == (11, 1)


def test_step_response_against_closed_form(oscillator):
    force = 3.0
    oscillator.splines["drive"] = ([0.0, 10.0], [force, force])  # a constant force
    oscillator.options["integrator"] = "ida"
    oscillator.options["ida.rtol"] = 1e-10
    oscillator.options["ida.atol"] = 1e-12
    oscillator.solve()
    t = oscillator.outputs.time
    x = oscillator.outputs.measure("x")
    exact = step_response(oscillator.parameters, force, t)
    assert len(t) == 1001
    static = force / oscillator.parameters["k"]
    assert np.max(np.abs(x - exact)) < 1e-6 * static
    assert x[-1] == pytest.approx(static, rel=1e-5)  # settled: exp(-zeta wn 10 s) = 3.5e-6


def test_hht_step_response(oscillator):
    force = 3.0
    oscillator.splines["drive"] = ([0.0, 10.0], [force, force])
    oscillator.solve()
    t = oscillator.outputs.time
    x = oscillator.outputs.q[:, 0]
    static = force / oscillator.parameters["k"]
    # second order: h = 1e-3 and (omega h)^2 = 1.6e-4
    assert np.max(np.abs(x - step_response(oscillator.parameters, force, t))) < 2e-3 * static


def test_parameter_change_restarts_from_zero(oscillator):
    oscillator.splines["drive"] = ([0.0, 10.0], [1.0, 1.0])
    oscillator.solve()
    x1 = oscillator.outputs.q[-1, 0]
    assert x1 == pytest.approx(1.0 / oscillator.parameters["k"], rel=1e-5)
    oscillator.parameters["f0"] = 4.0  # k four times larger
    oscillator.solve()
    assert len(oscillator.outputs) == 1001
    assert oscillator.outputs.q[-1, 0] == pytest.approx(x1 / 4, rel=1e-5)


def test_solve_to_is_bitwise_one_solve(oscillator):
    t = np.linspace(0, 10, 41)
    oscillator.splines["drive"] = (t, np.sin(2 * t))
    oscillator.options["t_end"] = 2.0
    oscillator.solve()
    whole = oscillator.outputs.q.copy(), oscillator.outputs.lambda_.copy()
    with mbdae.Model(oscillator.source) as m:
        m.splines["drive"] = (t, np.sin(2 * t))
        m.options["t_end"] = 2.0
        m.assemble()
        for k in range(1, 201):
            m.solve_to(k * 0.01)
            assert m.time == pytest.approx(k * 0.01, abs=1e-12)
        assert len(m.outputs) == 201
        np.testing.assert_array_equal(m.outputs.q, whole[0])
        np.testing.assert_array_equal(m.outputs.lambda_, whole[1])


def test_state_get_and_set(free_fall):
    free_fall.solve_to(0.5)
    s = free_fall.state
    assert isinstance(s, mbdae.State)
    assert s.t == pytest.approx(0.5, abs=1e-12)
    assert s.q[2] == pytest.approx(10 - 0.5 * 9.81 * 0.25, abs=1e-10)
    assert s.as_dict()["lambda"] is s.lambda_
    assert set(s.keys()) == {"t", "q", "v", "a", "lambda"}
    # Set the state back by t = 0.3 s of free fall: from there the motion is exact again.
    q = s.q.copy()
    v = s.v.copy()
    q[2] = 10 - 0.5 * 9.81 * 0.3 ** 2
    v[2] = -9.81 * 0.3
    free_fall.state = {"t": 0.3, "q": q, "v": v}  # a and lambda computed
    s2 = free_fall.state
    assert s2.t == 0.3
    np.testing.assert_array_equal(s2.q, q)
    assert s2.a[2] == pytest.approx(-9.81, abs=1e-10)
    free_fall.solve_to(0.8)
    assert free_fall.state.q[2] == pytest.approx(10 - 0.5 * 9.81 * 0.8 ** 2, abs=1e-9)
    # A State object, all fields given.
    free_fall.state = s
    assert free_fall.state.t == s.t
    np.testing.assert_array_equal(free_fall.state.v, s.v)
    np.testing.assert_array_equal(free_fall.state.a, s.a)


def test_outputs_arrays_agree_with_rows(pendulum):
    pendulum.options["t_end"] = 0.5
    pendulum.options["output_step"] = 0.05
    pendulum.solve()
    o = pendulum.outputs
    assert len(o) == 11
    r = pendulum.output(4)
    assert isinstance(r, mbdae.Row)
    assert r.t == o.time[4]
    np.testing.assert_array_equal(r.q, o.q[4])
    np.testing.assert_array_equal(r.v, o.v[4])
    np.testing.assert_array_equal(r.a, o.a[4])
    np.testing.assert_array_equal(r["lambda"], o.lambda_[4])
    np.testing.assert_array_equal(r.measures, o.measures[4])
    np.testing.assert_array_equal(r.body_poses, o.body_poses[4])
    np.testing.assert_array_equal(o[-1].q, o.q[-1])
    # measures x, y are the body's position; the body poses hold it and the rotation
    np.testing.assert_allclose(o.measures[:, 0], o.q[:, 0], atol=1e-14)
    np.testing.assert_allclose(o.measures[:, 1], o.q[:, 1], atol=1e-14)
    np.testing.assert_allclose(o.body_positions[:, 0, :], o.q[:, :3], atol=1e-14)
    R = o.body_rotations[:, 0]
    np.testing.assert_allclose(R @ R.transpose(0, 2, 1), np.broadcast_to(np.eye(3), R.shape),
                               atol=1e-12)
    # the link angle is atan2(y, x) of the bob, and the rotation is about z by that angle
    angle = o.measure("angle")
    np.testing.assert_allclose(angle, np.arctan2(o.q[:, 1], o.q[:, 0]), atol=1e-8)
    np.testing.assert_allclose(R[:, 0, 0], np.cos(angle), atol=1e-8)
    # the link length stays 1
    np.testing.assert_allclose(np.hypot(o.q[:, 0], o.q[:, 1]), 1.0, atol=1e-8)


def test_write_results(tmp_path, free_fall):
    h5py = pytest.importorskip("h5py")
    free_fall.solve()
    path = tmp_path / "free_fall.h5"
    free_fall.write_results(path)
    with h5py.File(path, "r") as f:
        np.testing.assert_array_equal(f["/time"][:], free_fall.outputs.time)
        np.testing.assert_array_equal(f["/q"][:], free_fall.outputs.q)
        np.testing.assert_array_equal(f["/measures/height"][:], free_fall.outputs.q[:, 2])
        assert list(f["/q_names"].asstr()[:]) == free_fall.coordinates
