"""Joint space of a tree of revolute, prismatic and fixed joints (a URDF import, a serial
arm): the joint-space mass matrix, bias and gravity vectors and inverse dynamics, exact
from the redundant-coordinate equations (C API ``mbdae_joint_*``, docs/urdf.md)::

    with mbdae.Model("examples/urdf_arm/ur20.urdf") as m:
        js = m.joint_space
        M = js.mass_matrix(q)
        tau = js.inverse_dynamics(q, qd, qdd)
"""

import ctypes

import numpy as np

from . import _lib
from ._lib import check

lib = _lib.lib

_vp, _st, _i, _d = ctypes.c_void_p, ctypes.c_int, ctypes.c_int, ctypes.c_double
_dp = ctypes.POINTER(ctypes.c_double)
for _name, _args in {
        "mbdae_joint_count": [_vp, ctypes.POINTER(ctypes.c_int)],
        "mbdae_joint_name": [_vp, _i, ctypes.c_char_p, ctypes.c_size_t, ctypes.POINTER(ctypes.c_int)],
        "mbdae_joint_mass_matrix": [_vp, _dp, _i, _dp],
        "mbdae_inverse_dynamics": [_vp, _d, _dp, _dp, _dp, _i, _dp],
        "mbdae_joint_bias": [_vp, _d, _dp, _dp, _i, _dp],
        "mbdae_joint_gravity": [_vp, _d, _dp, _i, _dp],
        "mbdae_joint_to_absolute": [_vp, _dp, _dp, _i, _dp, _dp, _i],
        "mbdae_joint_from_absolute": [_vp, _dp, _dp, _dp, _i, _dp, _dp, _dp, _i]}.items():
    _f = getattr(lib, _name)
    _f.restype = _st
    _f.argtypes = _args


def _ptr(a):
    return None if a is None else a.ctypes.data_as(_dp)


class JointSpace:
    """The joint coordinates of a model (``Model.joint_space``): ``names``, ``is_angle``
    and the dynamics at a joint state. Vectors are numpy arrays of length ``n``; ``t`` is
    the time of force values over t (0 by default)."""

    def __init__(self, model):
        self._model = model
        n = ctypes.c_int()
        check(lib.mbdae_joint_count(model._handle(), ctypes.byref(n)))
        self.n = n.value
        self.names, self.is_angle = [], []
        buf = ctypes.create_string_buffer(1024)
        angle = ctypes.c_int()
        for k in range(self.n):
            check(lib.mbdae_joint_name(model._handle(), k, buf, len(buf), ctypes.byref(angle)))
            self.names.append(buf.value.decode())
            self.is_angle.append(bool(angle.value))

    def _vec(self, x, what):
        if x is None:
            return None
        a = np.ascontiguousarray(x, dtype=float)
        if a.shape != (self.n,):
            from .errors import SizeError
            raise SizeError("mbdae: %s must have %d entries (the joint coordinates), got shape %s"
                            % (what, self.n, a.shape))
        return a

    def mass_matrix(self, q):
        """M_q(q) = J^T M J, n x n (symmetric)."""
        q = self._vec(q, "q")
        M = np.empty((self.n, self.n), order="F")
        check(lib.mbdae_joint_mass_matrix(self._model._handle(), _ptr(q), self.n, _ptr(M)))
        return np.ascontiguousarray(M)

    def inverse_dynamics(self, q, qd=None, qdd=None, t=0.0):
        """tau = J^T (M x'' - Q): the generalized joint forces for the accelerations qdd."""
        q, qd, qdd = self._vec(q, "q"), self._vec(qd, "qd"), self._vec(qdd, "qdd")
        tau = np.empty(self.n)
        check(lib.mbdae_inverse_dynamics(self._model._handle(), float(t), _ptr(q), _ptr(qd), _ptr(qdd),
                                         self.n, _ptr(tau)))
        return tau

    def bias(self, q, qd, t=0.0):
        """b(q, qd) = C(q, qd) qd + g(q) = tau(q, qd, 0)."""
        return self.inverse_dynamics(q, qd, None, t)

    def gravity(self, q, t=0.0):
        """g(q) = tau(q, 0, 0): gravity and the model's other forces at rest."""
        return self.inverse_dynamics(q, None, None, t)

    def absolute(self, q, qd=None):
        """The absolute coordinates and velocities (x, xd) of a joint state, e.g. for
        ``Model.set_state``."""
        q, qd = self._vec(q, "q"), self._vec(qd, "qd")
        nq = self._model.nq
        x, xd = np.empty(nq), np.empty(nq)
        check(lib.mbdae_joint_to_absolute(self._model._handle(), _ptr(q), _ptr(qd), self.n, _ptr(x), _ptr(xd),
                                          nq))
        return x, xd

    def from_absolute(self, x, xd=None, xdd=None):
        """The joint state (q, qd, qdd) of absolute coordinates, velocities and
        accelerations that satisfy the joints (e.g. ``Model.state``'s q, v, a); angles in
        (-pi, pi]."""
        nq = self._model.nq

        def arr(a):
            return None if a is None else np.ascontiguousarray(a, dtype=float)
        x, xd, xdd = arr(x), arr(xd), arr(xdd)
        q, qd, qdd = np.empty(self.n), np.empty(self.n), np.empty(self.n)
        check(lib.mbdae_joint_from_absolute(self._model._handle(), _ptr(x), _ptr(xd), _ptr(xdd), nq, _ptr(q),
                                            _ptr(qd), _ptr(qdd), self.n))
        return q, qd, qdd
