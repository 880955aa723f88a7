"""Measures, vectors and sparse matrices at the current state, checked against finite
differences of the library's own values at perturbed states (set through the state
setter) and against the equations of motion M a + C_q^T lambda = Q at solved states."""

import numpy as np
import pytest
import scipy.sparse as sp

import mbdae

# A tumbling body on a spherical joint at an offset marker, pulled by a spring-damper
# from another marker, under gravity: every vector and matrix is non-trivial.
TOP = """
format: 1
name: spring top
gravity: [0, 0, -9.81]
ground:
  markers:
    anchor: {position: [0.3, 0.2, 0.5]}
bodies:
  - name: top
    mass: 2.0
    inertia: [0.02, 0.03, 0.045, 0.001, -0.002, 0.003]
    position: [0, 0, 0.2]
    orientation: {axis: [1, 1, 0], angle: 0.3}
    angular_velocity: [1, -2, 5]
    markers:
      tip: {position: [0, 0, -0.2]}
      hook: {position: [0.1, 0, 0.1]}
measures:
  - {name: height, type: translational, i: top.hook, component: z, frame: world}
  - {name: tilt, type: rotational, i: top.cm, j: ground.O, axis: x}
  - {name: stretch, type: translational, i: top.hook, j: ground.anchor, component: distance}
joints:
  - {name: pivot, type: spherical, i: top.tip, j: ground.O}
forces:
  - {name: spring, type: spring_damper, i: top.hook, j: ground.anchor, stiffness: 40, damping: 0.7, free_length: 0.1}
simulation: {t_end: 0.2, output_step: 0.01, integrator: ida, ida: {rtol: 1.0e-10, atol: 1.0e-12}}
"""

EPS = 1e-6


@pytest.fixture
def top():
    with mbdae.Model.from_string(TOP, "top.yaml") as m:
        m.solve_to(0.1)  # a state in motion, away from the initial values
        yield m


def perturbed(m, base, fn, dq=None, dv=None):
    """Central difference of fn() along (dq, dv) from state base (a, lambda kept fixed)."""
    out = []
    for sign in (1, -1):
        q = base.q + (sign * EPS * dq if dq is not None else 0)
        v = base.v + (sign * EPS * dv if dv is not None else 0)
        m.set_state(base.t, q, v, base.a, base.lambda_)
        out.append(np.array(fn(), copy=True))
    m.set_state(base.t, base.q, base.v, base.a, base.lambda_)
    return (out[0] - out[1]) / (2 * EPS)


def fd_matrix(m, base, fn, wrt="q"):
    n = m.nq
    cols = []
    for j in range(n):
        e = np.zeros(n)
        e[j] = 1.0
        cols.append(perturbed(m, base, fn, dq=e) if wrt == "q" else
                    perturbed(m, base, fn, dv=e))
    return np.column_stack(cols)


def assert_close(actual, expected, rel=1e-6):
    scale = max(1.0, np.max(np.abs(expected)))
    assert np.max(np.abs(actual - expected)) <= rel * scale, \
        "max difference %g (scale %g)" % (np.max(np.abs(actual - expected)), scale)


def test_measure_values_and_gradients(top):
    base = top.state
    values = top.measure_values()
    assert values.shape == (3,)
    assert values[0] == pytest.approx(top.output(-1).measures[0], abs=1e-14)
    for k, name in enumerate(top.measures):
        g = top.measure_gradient(name)
        np.testing.assert_array_equal(g, top.measure_gradient(k))
        fd = np.array([perturbed(top, base, lambda: top.measure_values()[k], dq=e)
                       for e in np.eye(top.nq)])
        assert_close(g, fd, 1e-7)


def test_residual_identity_at_a_solved_state(top):
    s = top.state
    Ma = top.vector("mass_times_acc")
    Ct_lambda = top.vector("constraint_forces")
    Q = top.vector("sum_of_forces")
    assert np.max(np.abs(Ma + Ct_lambda - Q)) <= 1e-6 * np.max(np.abs(Q))
    assert_close(Q, top.vector("quadratic_velocity") + top.vector("external_forces"), 1e-13)
    # the vectors against the matrices
    M = top.matrix("mass")
    Cq = top.matrix("constraint_dq")
    assert_close(Ma, M @ s.a, 1e-12)
    assert_close(Ct_lambda, Cq.T @ s.lambda_, 1e-12)
    # gravity and the spring act on the body; the spin gives rotational quadratic terms
    # (none on the centre-of-mass coordinates)
    assert top.vector("external_forces")[2] < -0.5 * 2.0 * 9.81
    qv = top.vector("quadratic_velocity")
    np.testing.assert_array_equal(qv[:3], 0.0)
    assert np.max(np.abs(qv[3:])) > 1.0
    # a solved state satisfies the constraints at position and velocity level
    assert np.max(np.abs(top.vector("constraints"))) < 1e-8
    assert np.max(np.abs(Cq @ s.v + top.vector("constraints_dt"))) < 1e-8
    np.testing.assert_array_equal(top.vector("constraints_dt"), 0.0)  # scleronomic
    np.testing.assert_array_equal(top.vector("constraints_dtt"), 0.0)


def test_constraints_qdot_is_the_derivative_of_cq_along_v(top):
    s = top.state
    fd = perturbed(top, s, lambda: top.matrix("constraint_dq") @ s.v, dq=s.v)
    assert_close(top.vector("constraints_qdot"), fd, 1e-7)


def test_constraint_jacobian_by_differences(top):
    s = top.state
    assert_close(top.matrix("constraint_dq").toarray(),
                 fd_matrix(top, s, lambda: top.vector("constraints")), 1e-7)


@pytest.mark.parametrize("name,vector,wrt", [
    ("force_dq", "sum_of_forces", "q"),
    ("force_dv", "sum_of_forces", "v"),
    ("mass_acc_dq", "mass_times_acc", "q"),
    ("constraint_t_dq", "constraint_forces", "q"),
])
def test_matrix_by_differences(top, name, vector, wrt):
    s = top.state
    J = top.matrix(name)
    assert J.shape == (top.nq, top.nq)
    assert_close(J.toarray(), fd_matrix(top, s, lambda: top.vector(vector), wrt), 1e-6)


def test_formats_shapes_and_structural_pattern(top):
    nq, nm = top.nq, top.nm
    for name in mbdae.MATRICES:
        csc = top.matrix(name)
        csr = top.matrix(name, format="csr")
        assert isinstance(csc, sp.csc_matrix) and isinstance(csr, sp.csr_matrix)
        assert csc.shape == csr.shape == top.matrix_shape(name)
        np.testing.assert_array_equal(csc.toarray(), csr.toarray())
        assert csc.nnz == csr.nnz
    assert top.matrix_shape("newton_hht") == (nq + nm, nq + nm)
    assert top.matrix_shape("newton_ida") == (2 * (nq + nm), 2 * (nq + nm))
    M = top.matrix("mass").toarray()
    np.testing.assert_allclose(M[:3, :3], 2.0 * np.eye(3), atol=1e-14)
    np.testing.assert_allclose(M, M.T, atol=1e-14)


def test_compose_blocks(top):
    nq, nm = top.nq, top.nm
    M = top.matrix("mass")
    Cq = top.matrix("constraint_dq")
    kkt = top.compose([("mass", 0, 0), ("constraint_dq", 0, nq, 1.0, True),
                       {"matrix": "constraint_dq", "row": nq, "col": 0}], (nq + nm, nq + nm))
    expected = sp.bmat([[M, Cq.T], [Cq, None]]).toarray()
    np.testing.assert_array_equal(kkt.toarray(), expected)
    # scaled and overlapping blocks add up; a larger shape pads with zeros
    sum3 = top.compose([("mass", 1, 2), ("mass", 1, 2, 2.0)], (nq + 3, nq + 4), "csr")
    assert sum3.shape == (nq + 3, nq + 4)
    np.testing.assert_allclose(sum3.toarray()[1:nq + 1, 2:nq + 2], 3 * M.toarray(), rtol=1e-15)
    assert sum3.toarray()[0].max() == 0 and sum3.toarray()[:, :2].max() == 0
    with pytest.raises(mbdae.ArgumentError):
        top.compose([("mass", 1, 0)], (nq, nq))  # outside the matrix
    assert top.compose([], (3, 4)).nnz == 0


def test_newton_matrix_of_hht(top):
    nq, nm = top.nq, top.nm
    h = 2e-3
    top.set_newton_step(h)
    alpha = top.options["hht.alpha"]
    beta = (1 - alpha) ** 2 / 4
    gamma = 0.5 - alpha
    K = (top.matrix("mass_acc_dq") + top.matrix("constraint_t_dq") - top.matrix("force_dq"))
    top_left = top.matrix("mass") / (1 + alpha) + beta * h ** 2 * K - gamma * h * top.matrix("force_dv")
    Cq = top.matrix("constraint_dq")
    expected = sp.bmat([[top_left, Cq.T / (1 + alpha)], [Cq, None]]).toarray()
    assert_close(top.matrix("newton_hht").toarray(), expected, 1e-12)
