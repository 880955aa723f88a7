"""Every mistake raises an mbdae.Error subclass with a message that says what is wrong."""

import numpy as np
import pytest

import mbdae
from conftest import FREE_FALL, OSCILLATOR


def test_exception_classes():
    for cls, status, builtin in [(mbdae.InputError, 1, ValueError),
                                 (mbdae.ArgumentError, 2, KeyError),
                                 (mbdae.SizeError, 3, ValueError),
                                 (mbdae.OrderError, 4, RuntimeError),
                                 (mbdae.SolverError, 5, RuntimeError),
                                 (mbdae.FileError, 6, OSError),
                                 (mbdae.InternalError, 7, RuntimeError)]:
        assert issubclass(cls, mbdae.Error) and issubclass(cls, builtin)
        assert cls.status == status
        e = cls("what went wrong")
        assert str(e) == "what went wrong" and e.message == "what went wrong"
    assert mbdae.IOError_ is mbdae.FileError


def test_missing_file(tmp_path):
    path = tmp_path / "nothere.yaml"
    with pytest.raises(mbdae.FileError) as info:
        mbdae.Model(path)
    assert "nothere.yaml" in str(info.value)
    assert info.value.status == 6


def test_bad_model_file(tmp_path):
    path = tmp_path / "bad.yaml"
    path.write_text("format: 1\nbodies:\n  - {name: a, mass: -1}\n")
    with pytest.raises(mbdae.InputError) as info:
        mbdae.Model(path)
    assert "bad.yaml" in str(info.value) and "mass" in str(info.value)


def test_bad_model_string():
    with pytest.raises(mbdae.InputError) as info:
        mbdae.Model.from_string("format: 1\nbodys: []\n", "typo.yaml")
    message = str(info.value)
    assert "bodys" in message and "typo.yaml" in message
    with pytest.raises(mbdae.InputError):
        mbdae.Model.from_string("format: [1\n")  # not YAML


def test_unknown_names(oscillator):
    with pytest.raises(mbdae.ArgumentError) as info:
        oscillator.parameters["stiffness"]
    assert "stiffness" in str(info.value) and "k" in str(info.value)
    with pytest.raises(KeyError):  # ArgumentError is a KeyError
        oscillator.parameters["stiffness"] = 1.0
    with pytest.raises(mbdae.ArgumentError, match="road"):
        oscillator.splines["road"]
    with pytest.raises(mbdae.ArgumentError, match="accel"):
        oscillator.measure_gradient("accel")
    with pytest.raises(mbdae.ArgumentError, match="out of range"):
        oscillator.parameters[17]
    with pytest.raises(TypeError):
        oscillator.parameters[1.5]
    with pytest.raises(mbdae.ArgumentError, match="kinetic_energy"):
        oscillator.vector("kinetic_energy")
    with pytest.raises(mbdae.ArgumentError, match="stiffness_matrix"):
        oscillator.matrix("stiffness_matrix")
    with pytest.raises(mbdae.ArgumentError, match="mass, "):  # lists the valid names
        oscillator.compose([("stiffness_matrix", 0, 0)], (7, 7))


def test_unknown_and_bad_options(oscillator):
    with pytest.raises(mbdae.Error) as info:
        oscillator.options["hht.gamma"] = 0.5
    assert "hht.gamma" in str(info.value)
    with pytest.raises(mbdae.Error, match="hht.gamma"):
        oscillator.options["hht.gamma"]
    with pytest.raises(mbdae.InputError, match="integrator"):
        oscillator.options["integrator"] = "euler"
    with pytest.raises(mbdae.InputError, match="alpha"):
        oscillator.options["hht.alpha"] = -0.5  # outside [-1/3, 0]
    with pytest.raises(TypeError):
        oscillator.options["t_end"] = [1, 2]
    assert oscillator.options["hht.alpha"] == -0.05  # unchanged


def test_wrong_array_sizes(oscillator):
    oscillator.assemble()
    s = oscillator.state
    with pytest.raises(mbdae.SizeError, match="q has 6 values; the model needs 7"):
        oscillator.set_state(0.0, s.q[:6], s.v)
    with pytest.raises(mbdae.SizeError, match="v has 8"):
        oscillator.set_state(0.0, s.q, np.zeros(8))
    with pytest.raises(mbdae.SizeError, match="lambda has 2 values; the model needs 6"):
        oscillator.set_state(0.0, s.q, s.v, s.a, np.zeros(2))
    with pytest.raises(mbdae.SizeError, match="1-D"):
        oscillator.set_state(0.0, s.q.reshape(7, 1), s.v)
    with pytest.raises(mbdae.SizeError, match="x has 3 values and y has 2"):
        oscillator.splines["drive"] = ([0, 1, 2], [0, 1])
    with pytest.raises(mbdae.SizeError, match="pair"):
        oscillator.splines["drive"] = np.zeros(5)
    with pytest.raises(mbdae.SizeError, match="shape"):
        oscillator.compose([("mass", 0, 0)], 7)
    np.testing.assert_array_equal(oscillator.state.q, s.q)  # nothing was changed


def test_bad_values_rejected_by_the_library(oscillator):
    with pytest.raises(mbdae.InputError) as info:
        oscillator.splines["drive"] = ([0, 2, 1], [0, 1, 2])  # x not increasing
    assert "drive" in str(info.value)
    np.testing.assert_array_equal(oscillator.splines["drive"][0], [0, 10])  # old points kept
    with pytest.raises(mbdae.Error) as info:
        oscillator.splines["drive"] = ([0], [1])  # one point
    assert info.value.status in (1, 3)
    with pytest.raises(mbdae.InputError, match="m"):
        oscillator.parameters["m"] = -1.0  # a negative mass
    assert oscillator.parameters["m"] == 1.0  # the old value stays


def test_missing_state_keys(free_fall):
    free_fall.assemble()
    with pytest.raises(mbdae.ArgumentError, match="needs 'v'"):
        free_fall.state = {"t": 0.0, "q": free_fall.state.q}
    with pytest.raises(mbdae.ArgumentError, match="velocity"):
        free_fall.state = {"t": 0.0, "q": free_fall.state.q, "v": free_fall.state.v,
                           "velocity": 1}


def test_output_rows_out_of_range(free_fall):
    with pytest.raises(mbdae.ArgumentError, match="0 rows"):
        free_fall.output(0)
    free_fall.solve()
    with pytest.raises(mbdae.ArgumentError, match="11 rows"):
        free_fall.output(11)


def test_solve_to_backwards(free_fall):
    free_fall.solve_to(0.5)
    with pytest.raises(mbdae.Error) as info:
        free_fall.solve_to(0.2)
    assert "0.2" in str(info.value) or "0.5" in str(info.value)


def test_write_results_to_a_missing_folder(tmp_path, free_fall):
    free_fall.solve()
    with pytest.raises(mbdae.FileError) as info:
        free_fall.write_results(tmp_path / "no" / "such" / "folder.h5")
    assert "folder.h5" in str(info.value)


def test_solver_failure():
    # A spring-damper whose markers coincide at t = 0: its length is zero.
    text = FREE_FALL.replace("simulation:", """forces:
  - {name: s, type: spring_damper, i: ball.cm, j: ground.O, stiffness: 1, free_length: 1}
simulation:""").replace("position: [0, 0, h]", "position: [0, 0, 0]")
    with mbdae.Model.from_string(text) as m:
        with pytest.raises(mbdae.Error) as info:
            m.solve()
        assert info.value.status in (1, 5)
        assert "length zero" in str(info.value)
