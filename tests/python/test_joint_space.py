"""Joint space of the UR20 arm imported from URDF (examples/urdf_arm/ur20.urdf) against an
independent recursive Newton-Euler implementation written here in numpy from the arm's
DH table (not from the URDF): the joint-space mass matrix, bias and gravity vectors and
inverse dynamics at random states; the Jacobian of the absolute coordinates against
central differences; refusals of models that are not trees.

Run by CTest (tests/python/CMakeLists.txt via tests/urdf/CMakeLists.txt); by hand:
    PYTHONPATH=build/python /usr/bin/python3 -m pytest tests/python/test_joint_space.py
"""

import math
import os

import numpy as np
import pytest

import mbdae

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
UR20 = os.path.join(ROOT, "examples", "urdf_arm", "ur20.urdf")

# The UR20's published table (Universal Robots, "DH Parameters for calculations of
# kinematics and dynamics"): standard DH; centre of mass and inertia (about the centre of
# mass) of link k in DH frame k.
A = [0, -0.8620, -0.7287, 0, 0, 0]
D = [0.2363, 0, 0, 0.2010, 0.1593, 0.1543]
ALPHA = [math.pi / 2, 0, 0, math.pi / 2, -math.pi / 2, 0]
MASS = [16.343, 29.632, 7.879, 3.054, 3.126, 0.846]
COM = [[0, -0.0610, 0.0062], [0.5226, 0, 0.2098], [0.3234, 0, 0.0604],
       [0, -0.0026, 0.0393], [0, 0.0024, 0.0379], [0, -0.0003, -0.0318]]
INERTIA = [[0.0887, -0.0001, -0.0001, 0.0763, 0.0072, 0.0842],
           [0.1467, 0.0002, -0.0516, 4.6659, 0.0, 4.6348],
           [0.0261, -0.0001, -0.0290, 0.7576, 0.0, 0.7533],
           [0.0056, 0.0, 0.0, 0.0054, 0.0004, 0.0040],
           [0.0059, 0.0, 0.0, 0.0058, -0.0004, 0.0043],
           [0.0009, 0.0, 0.0, 0.0009, 0.0, 0.0012]]  # xx xy xz yy yz zz
GRAVITY = np.array([0, 0, -9.81])


def dh(theta, d, a, alpha):
    ct, st, ca, sa = math.cos(theta), math.sin(theta), math.cos(alpha), math.sin(alpha)
    R = np.array([[ct, -st * ca, st * sa], [st, ct * ca, -ct * sa], [0, sa, ca]])
    return R, np.array([a * ct, a * st, d])


def rnea(q, qd, qdd, gravity=GRAVITY):
    """Recursive Newton-Euler in world axes (Luh, Walker, Paul 1980): joint k turns about
    z_{k-1} through o_{k-1}; gravity enters as the base's acceleration -g."""
    n = 6
    R, o = np.eye(3), np.zeros(3)
    w, dw, ao = np.zeros(3), np.zeros(3), -gravity
    frames, forces, moments, comps = [], [], [], []
    for k in range(n):
        z, o_prev = R[:, 2].copy(), o.copy()
        Rk, pk = dh(q[k], D[k], A[k], ALPHA[k])
        R, o = R @ Rk, o + R @ pk
        dw = dw + z * qdd[k] + np.cross(w, z * qd[k])
        w = w + z * qd[k]
        c = o + R @ np.array(COM[k])
        r_c, r_o = c - o_prev, o - o_prev
        ac = ao + np.cross(dw, r_c) + np.cross(w, np.cross(w, r_c))
        ao = ao + np.cross(dw, r_o) + np.cross(w, np.cross(w, r_o))
        xx, xy, xz, yy, yz, zz = INERTIA[k]
        Iw = R @ np.array([[xx, xy, xz], [xy, yy, yz], [xz, yz, zz]]) @ R.T
        forces.append(MASS[k] * ac)
        moments.append(Iw @ dw + np.cross(w, Iw @ w))
        frames.append((z, o_prev, o))
        comps.append(c)
    tau = np.zeros(n)
    F, N = np.zeros(3), np.zeros(3)  # from link k+1 on link k, N about o_k
    for k in reversed(range(n)):
        z, o_prev, o = frames[k]
        N = moments[k] + np.cross(comps[k] - o_prev, forces[k]) + N + np.cross(o - o_prev, F)
        F = forces[k] + F
        tau[k] = z @ N
    return tau


def crba_mass_matrix(q):
    """Composite rigid bodies (Walker and Orin 1982): column j is the force of the
    composite of links j..6 accelerated by a unit rate of joint j, about each joint."""
    n = 6
    R, o = np.eye(3), np.zeros(3)
    z_axes, origins, coms, inertias = [], [], [], []
    for k in range(n):
        z_axes.append(R[:, 2].copy())
        origins.append(o.copy())
        Rk, pk = dh(q[k], D[k], A[k], ALPHA[k])
        R, o = R @ Rk, o + R @ pk
        coms.append(o + R @ np.array(COM[k]))
        xx, xy, xz, yy, yz, zz = INERTIA[k]
        inertias.append(R @ np.array([[xx, xy, xz], [xy, yy, yz], [xz, yz, zz]]) @ R.T)
    M = np.zeros((n, n))
    for j in range(n):
        # The composite body of links j..n-1: mass, centre of mass, inertia about it.
        m = sum(MASS[j:])
        c = sum(MASS[k] * coms[k] for k in range(j, n)) / m
        I = np.zeros((3, 3))
        for k in range(j, n):
            r = coms[k] - c
            I += inertias[k] + MASS[k] * (r @ r * np.eye(3) - np.outer(r, r))
        zj, oj = z_axes[j], origins[j]
        f = m * np.cross(zj, c - oj)  # force of the composite for a unit rate
        nm = I @ zj                   # moment about its centre of mass
        for i in range(j + 1):
            n_i = nm + np.cross(c - origins[i], f)
            M[i, j] = M[j, i] = z_axes[i] @ n_i
    return M


@pytest.fixture(scope="module")
def arm():
    with mbdae.Model(UR20) as m:
        yield m


def test_names(arm):
    js = arm.joint_space
    assert js.n == 6 and js.names == ["joint_%d" % k for k in range(1, 7)] and all(js.is_angle)


def test_crba_and_rnea_agree():
    # The two references agree with each other (M columns from Newton-Euler without gravity).
    rng = np.random.default_rng(3)
    q = rng.uniform(-math.pi, math.pi, 6)
    Mr = np.column_stack([rnea(q, np.zeros(6), e, np.zeros(3)) for e in np.eye(6)])
    assert np.abs(Mr - crba_mass_matrix(q)).max() < 1e-13


def test_dynamics_against_newton_euler(arm):
    js = arm.joint_space
    rng = np.random.default_rng(14)
    worst = {}
    for _ in range(20):
        q = rng.uniform(-2 * math.pi, 2 * math.pi, 6)
        qd = rng.uniform(-3, 3, 6)
        qdd = rng.uniform(-10, 10, 6)
        zero = np.zeros(6)
        checks = {
            "mass_matrix": (js.mass_matrix(q), crba_mass_matrix(q)),
            "gravity": (js.gravity(q), rnea(q, zero, zero)),
            "bias": (js.bias(q, qd), rnea(q, qd, zero)),
            "inverse_dynamics": (js.inverse_dynamics(q, qd, qdd), rnea(q, qd, qdd)),
        }
        for name, (got, ref) in checks.items():
            err = np.abs(got - ref).max() / max(1.0, np.abs(ref).max())
            worst[name] = max(worst.get(name, 0.0), err)
    print("largest relative differences:", worst)
    for name, err in worst.items():
        assert err < 1e-10, (name, err)


def test_mass_matrix_symmetric_positive_and_called_twice(arm):
    js = arm.joint_space
    q = np.array([0.3, -1.1, 0.7, 2.0, -0.4, 1.3])
    M1, M2 = js.mass_matrix(q), js.mass_matrix(q)
    assert np.array_equal(M1, M2)  # nothing left over from the first call
    assert np.abs(M1 - M1.T).max() == 0
    assert np.linalg.eigvalsh(M1).min() > 0


def test_jacobian_against_central_differences(arm):
    # x' = J q' of joint_to_absolute against central differences of the positions.
    js = arm.joint_space
    rng = np.random.default_rng(5)
    q = rng.uniform(-math.pi, math.pi, 6)
    qd = rng.uniform(-1, 1, 6)
    _, xd = js.absolute(q, qd)
    h = 1e-6
    xp, _ = js.absolute(q + h * qd)
    xm, _ = js.absolute(q - h * qd)
    fd = (xp - xm) / (2 * h)
    assert np.abs(fd - xd).max() < 1e-8


def test_free_fall_rows_satisfy_the_joint_space_equations(arm, tmp_path):
    # Along an integrated fall (IDA, tight tolerances), M(q) qdd + b(q, qd) = 0 at the rows,
    # with q, qd, qdd from the measures of the joint angles.
    js = arm.joint_space
    x0, xd0 = js.absolute(np.array([0.2, -0.8, 0.9, -0.3, 0.5, 0.1]), np.array([0.5, 0, -0.3, 0, 0.2, 0]))
    arm.options["integrator"] = "ida"
    arm.options["ida.rtol"] = 1e-10
    arm.options["ida.atol"] = 1e-12
    arm.options["t_end"] = 0.3
    arm.options["output_step"] = 0.1
    arm.state = {"t": 0.0, "q": x0, "v": xd0}
    q0, qd0, _ = js.from_absolute(x0, xd0)
    assert np.abs(q0 - [0.2, -0.8, 0.9, -0.3, 0.5, 0.1]).max() < 1e-14
    assert np.abs(qd0 - [0.5, 0, -0.3, 0, 0.2, 0]).max() < 1e-14
    arm.solve()
    s = arm.state
    assert s.t == pytest.approx(0.3)
    q, qd, qdd = js.from_absolute(s.q, s.v, s.a)
    assert np.abs(q - q0).max() > 0.05  # it fell
    residual = js.mass_matrix(q) @ qdd + js.bias(q, qd)
    print("free fall: max |M qdd + b| =", np.abs(residual).max(), "N m; max |b| =", np.abs(js.bias(q, qd)).max())
    assert np.abs(residual).max() < 1e-8 * np.abs(js.bias(q, qd)).max()


def test_not_a_tree_is_an_input_error():
    text = """
format: 1
gravity: [0, 0, -9.81]
bodies:
  - {name: a, mass: 1, inertia: [1, 1, 1]}
joints:
  - {name: s, type: spherical, i: a.cm, j: ground.O}
"""
    with mbdae.Model.from_string(text) as m:
        with pytest.raises(mbdae.InputError, match="joint 's': joint space needs a tree"):
            m.joint_space
