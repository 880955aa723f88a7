"""mbdae.Model: loading, life, sizes and names, parameters, splines, options."""

import gc

import numpy as np
import pytest

import mbdae
from conftest import FREE_FALL, OSCILLATOR, PENDULUM


def test_package_metadata():
    assert mbdae.__version__ == "0.1.0"
    assert mbdae.api_version == 1
    assert mbdae.library_path.endswith("libmbdae.so")


def test_sizes_and_names_of_the_pendulum(pendulum):
    assert pendulum.nq == 7 and pendulum.num_coordinates == 7
    assert pendulum.coordinates == ["bob.x", "bob.y", "bob.z", "bob.e0", "bob.e1", "bob.e2",
                                    "bob.e3"]
    assert pendulum.bodies == ["bob"] and pendulum.num_bodies == 1
    assert pendulum.joints == ["pivot"] and pendulum.num_joints == 1
    assert pendulum.forces == [] and pendulum.num_forces == 0
    assert pendulum.measures == ["x", "y", "angle"] and pendulum.num_measures == 3
    assert list(pendulum.parameters) == ["L", "m"] and pendulum.num_parameters == 2
    assert list(pendulum.splines) == [] and pendulum.num_splines == 0
    # A revolute joint: 5 equations, plus the Euler-parameter normalisation.
    assert pendulum.nm == 6 and pendulum.num_multipliers == 6
    assert len(pendulum.multipliers) == 6
    assert "bob.euler_norm" in pendulum.multipliers
    assert all(n.startswith("pivot.") for n in pendulum.multipliers if n != "bob.euler_norm")
    assert pendulum.redundant == [] and pendulum.num_redundant == 0


def test_index_by_kind_and_name(oscillator):
    assert oscillator.index("bodies", "mass") == 0
    assert oscillator.index("forces", "excitation") == 2
    assert oscillator.index("measures", "v") == 1
    assert oscillator.index("coordinates", "mass.y") == 1
    assert oscillator.index("parameters", "k") == list(oscillator.parameters).index("k")
    with pytest.raises(mbdae.ArgumentError, match="nothere"):
        oscillator.index("bodies", "nothere")
    with pytest.raises(mbdae.ArgumentError, match="kinds are"):
        oscillator.index("wheels", "mass")


def test_from_string_and_context_manager():
    with mbdae.Model.from_string(FREE_FALL, "free_fall.yaml") as m:
        assert m.bodies == ["ball"]
        assert m.source == "free_fall.yaml"
        assert not m.closed
        assert "ball" in repr(m) or "free_fall" in repr(m)
    assert m.closed
    assert "closed" in repr(m)
    with pytest.raises(mbdae.OrderError, match="closed"):
        m.nq
    with pytest.raises(mbdae.OrderError):
        m.solve()
    m.close()  # a second close does nothing


def test_models_are_independent():
    a = mbdae.Model(OSCILLATOR)
    b = mbdae.Model(OSCILLATOR)
    a.parameters["m"] = 4.0
    assert a.parameters["m"] == 4.0 and b.parameters["m"] == 1.0
    a.close()
    assert b.nq == 7  # b still works after a is freed
    b.close()


def test_garbage_collected_model_is_freed():
    m = mbdae.Model(PENDULUM)
    del m
    gc.collect()  # __del__ frees the handle; nothing to observe but no crash


def test_parameters_get_set_and_dependants(oscillator):
    p = oscillator.parameters
    assert p["m"] == 1.0 and p["f0"] == 2.0
    assert p["k"] == pytest.approx((2 * np.pi * 2.0) ** 2, rel=1e-14)
    assert p[0] == p["m"] and p[-1] == p[len(p) - 1]
    assert dict(p.items())["zeta"] == 0.1
    assert "k" in p and "nothere" not in p
    p["f0"] = 3.0  # k and d depend on f0 and are recomputed
    assert p["k"] == pytest.approx((2 * np.pi * 3.0) ** 2, rel=1e-14)
    assert p["d"] == pytest.approx(2 * 0.1 * 2 * np.pi * 3.0, rel=1e-14)
    p.update({"m": 2.0, "zeta": 0.2})
    assert p["m"] == 2.0 and p["zeta"] == 0.2
    assert p["k"] == pytest.approx(2.0 * (2 * np.pi * 3.0) ** 2, rel=1e-14)


def test_parameter_changes_the_model(pendulum):
    pendulum.parameters["L"] = 2.0
    pendulum.assemble()
    assert pendulum.state.q[0] == pytest.approx(2.0, abs=1e-12)  # bob at [L, 0, 0]


def test_spline_points_round_trip(oscillator):
    x, y = oscillator.splines["drive"]
    np.testing.assert_array_equal(x, [0.0, 10.0])
    np.testing.assert_array_equal(y, [0.0, 0.0])
    t = np.linspace(0, 10, 11)
    oscillator.splines["drive"] = (t, np.sin(t))
    x, y = oscillator.splines[0]
    assert isinstance(x, np.ndarray) and x.dtype == np.float64
    np.testing.assert_array_equal(x, t)
    np.testing.assert_array_equal(y, np.sin(t))
    oscillator.splines["drive"] = ([0, 5, 10], [1, 2, 3])  # lists are accepted
    np.testing.assert_array_equal(oscillator.splines["drive"][1], [1.0, 2.0, 3.0])
    assert list(oscillator.splines) == ["drive"]


def test_options_set_and_get(oscillator):
    o = oscillator.options
    assert o["integrator"] == "hht"
    assert o["hht.alpha"] == -0.05
    assert o["t_end"] == 10.0
    o["hht.alpha"] = -0.3
    assert o["hht.alpha"] == -0.3
    o["hht.step"] = 2.5e-4
    assert o["hht.step"] == 2.5e-4
    o["hht.adaptive"] = True
    assert o["hht.adaptive"] is True
    o["hht.adaptive"] = False
    assert o["hht.adaptive"] is False
    o["integrator"] = "ida"
    assert o["integrator"] == "ida"
    o["t_end"] = 2  # an int
    assert o["t_end"] == 2.0
    assert set(o.keys()) == set(mbdae.OPTIONS)
    assert len(dict(o.items())) == len(mbdae.OPTIONS)


def test_option_values_take_effect(free_fall):
    free_fall.options["t_end"] = 0.5
    free_fall.options["output_step"] = 0.05
    free_fall.solve()
    assert len(free_fall.outputs) == 11
    assert free_fall.outputs.time[-1] == pytest.approx(0.5, abs=1e-12)


# The slider-crank of docs/model-format.md: a planar loop of spatial joints, where three
# equations of the prismatic joint are redundant (guide.x, guide.ry, guide.rz).
SLIDER_CRANK = """
format: 1
name: slider crank
gravity: [0, -9.81, 0]
parameters: {r: 0.1, l: 3 * r, xb: sqrt(l^2 - r^2), phi: -asin(r / l)}
ground:
  markers:
    rail: {orientation: {axis: [0, 1, 0], angle: pi/2}}
bodies:
  - name: crank
    geometry: {shape: box, size: [r, 0.02, 0.01], density: 7800}
    position: [0, r/2, 0]
    orientation: {axis: [0, 0, 1], angle: pi/2}
    markers:
      O: {position: [-r/2, 0, 0]}
      A: {position: [r/2, 0, 0]}
  - name: rod
    mass: 0.5
    inertia: [1.0e-5, 0.5*l^2/12, 0.5*l^2/12]
    position: [xb/2, r/2, 0]
    orientation: {axis: [0, 0, 1], angle: phi}
    markers:
      A: {position: [-l/2, 0, 0]}
      B: {position: [l/2, 0, 0]}
  - name: slider
    geometry: {shape: box, size: [0.04, 0.02, 0.02], density: 7800}
    position: [xb, 0, 0]
    markers:
      rail: {orientation: {axis: [0, 1, 0], angle: pi/2}}
joints:
  - {name: bearing, type: revolute, i: crank.O, j: ground.O}
  - {name: crank_pin, type: revolute, i: rod.A, j: crank.A}
  - {name: wrist_pin, type: revolute, i: rod.B, j: slider.cm}
  - {name: guide, type: prismatic, i: slider.rail, j: ground.rail}
simulation: {t_end: 0.1, output_step: 0.01}
"""


def test_redundant_equations_are_named():
    with mbdae.Model.from_string(SLIDER_CRANK, "slider_crank.yaml") as m:
        assert m.nq == 21 and m.num_bodies == 3 and m.num_joints == 4
        assert sorted(m.redundant) == ["guide.ry", "guide.rz", "guide.x"]
        assert m.num_redundant == 3
        # 3 x 5 (revolute) + 5 (prismatic) + 3 normalisations, minus the redundant ones
        assert m.nm == 15 + 5 + 3 - 3 == len(m.multipliers)
        assert not set(m.redundant) & set(m.multipliers)
        m.solve()
        assert m.num_outputs == 11 == len(m.outputs)
        assert m.outputs.lambda_.shape == (11, m.nm)
        assert np.max(np.abs(m.vector("constraints"))) < 1e-8
