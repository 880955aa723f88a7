"""The :class:`Model` handle: one multibody model of the C API, with its solver state."""

import ctypes
import os

import numpy as np

from . import _lib
from . import gradient as _gradient
from ._lib import check, dptr, iptr
from .errors import ArgumentError, OrderError, SizeError

lib = _lib.lib

#: The vectors of :meth:`Model.vector`, by name (mbdae_vector), and their length.
VECTORS = {
    "mass_times_acc": (0, "nq"),      # M(q) a
    "constraint_forces": (1, "nq"),   # C_q^T lambda
    "quadratic_velocity": (2, "nq"),  # Q_v, the velocity-quadratic inertia terms
    "external_forces": (3, "nq"),     # gravity and force elements
    "sum_of_forces": (4, "nq"),       # Q = Q_v + external
    "constraints": (5, "nm"),         # C(q, t)
    "constraints_dt": (6, "nm"),      # dC/dt (partial)
    "constraints_qdot": (7, "nm"),    # d(C_q)/dt q'
    "constraints_dtt": (8, "nm"),     # d2C/dt2 (partial)
}

#: The matrices of :meth:`Model.matrix` and :meth:`Model.compose`, by name (mbdae_matrix).
MATRICES = {
    "mass": 0,             # M                      nq x nq
    "constraint_dq": 1,    # C_q                    nm x nq
    "mass_acc_dq": 2,      # d(M a)/dq at fixed a   nq x nq
    "force_dq": 3,         # dQ/dq                  nq x nq
    "force_dv": 4,         # dQ/dq'                 nq x nq
    "constraint_t_dq": 5,  # d(C_q^T lambda)/dq     nq x nq
    "newton_hht": 6,       # HHT Newton matrix      (nq + nm) square
    "newton_ida": 7,       # IDA Newton matrix      (2 nq + 2 nm) square
}

#: The keys of :attr:`Model.options`: the model file's ``simulation:`` block, then the
#: settings of :meth:`Model.gradient` (``gradient.*``; they do not restart the model).
OPTIONS = ("t_end", "output_step", "integrator", "hht.alpha", "hht.step", "hht.adaptive",
           "hht.tolerance", "hht.modified", "hht.form", "hht.dense_output", "hht.newton_tolerance",
           "hht.linear_solver", "hht.jacobian_cost", "hht.predictor", "hht.rotation_jacobian",
           "ida.rtol", "ida.atol",
           "ida.max_steps", "ida.min_step", "ida.dense_output", "ida.linear_solver", "erk.rtol", "erk.atol", "erk.max_steps",
           "erk.min_step", "erk.max_step", "output.bodies", "output.joints", "output.forces",
           "output.measures", "gradient.fd_step", "gradient.newton_factor",
           "gradient.trajectory_memory", "gradient.ida_checkpoint_steps")

_FORMATS = {"csc": _lib.CSC, "csr": _lib.CSR}
_DP = ctypes.POINTER(ctypes.c_double)


def _unknown(what, name, known, message=None):
    """ArgumentError for an unknown name: the C message (if any) and the names there are."""
    listed = ", ".join(known) if known else "none"
    if message:
        return ArgumentError("%s (there are: %s)" % (message, listed))
    return ArgumentError("mbdae: no %s called '%s' (there are: %s)" % (what, name, listed))


def _last_error():
    message = lib.mbdae_last_error()
    return message.decode("utf-8", "replace") if message else ""


def _as_vector(values, n, what):
    """`values` as a C-contiguous float64 1-D array of length n, else SizeError."""
    a = np.ascontiguousarray(values, dtype=np.float64)
    if a.ndim != 1:
        raise SizeError("%s must be a 1-D array of %d values, got shape %s" % (what, n, a.shape))
    if a.shape[0] != n:
        raise SizeError("%s has %d values; the model needs %d" % (what, a.shape[0], n))
    return a


class State:
    """A state of the model: time ``t`` and the arrays ``q``, ``v`` (= q'), ``a`` (= q'')
    of the coordinates and ``lambda_`` of the multipliers. Also readable as a mapping
    with the keys ``"t", "q", "v", "a", "lambda"``.
    """

    __slots__ = ("t", "q", "v", "a", "lambda_")
    _KEYS = ("t", "q", "v", "a", "lambda")

    def __init__(self, t, q, v, a=None, lambda_=None):
        self.t = t
        self.q = q
        self.v = v
        self.a = a
        self.lambda_ = lambda_

    def __getitem__(self, key):
        if key not in self._KEYS:
            raise KeyError(key)
        return getattr(self, "lambda_" if key == "lambda" else key)

    def keys(self):
        """The mapping keys: t, q, v, a, lambda."""
        return list(self._KEYS)

    def as_dict(self):
        """The state as a dict with the keys t, q, v, a, lambda."""
        return {k: self[k] for k in self._KEYS}

    def __repr__(self):
        return "State(t=%r, q=%r, v=%r, a=%r, lambda_=%r)" % (self.t, self.q, self.v, self.a,
                                                             self.lambda_)


class Row(State):
    """One stored output row: a :class:`State` plus ``measures`` (the measures' values,
    angles unwrapped as in the results file) and ``body_poses`` (bodies x 12: the
    centre-of-mass position, then the rotation matrix body -> world, row-major)."""

    __slots__ = ("measures", "body_poses")
    _KEYS = State._KEYS + ("measures", "body_poses")

    def __init__(self, t, q, v, a, lambda_, measures, body_poses):
        super().__init__(t, q, v, a, lambda_)
        self.measures = measures
        self.body_poses = body_poses

    def __repr__(self):
        return "Row(t=%r, q=%r, ...)" % (self.t, self.q)


class _Named:
    """Base of the name-keyed views (parameters, splines): the names of one kind, looked up
    by name or by zero-based index."""

    _kind = None
    _what = None

    def __init__(self, model):
        self._model = model

    def _index(self, key):
        m = self._model
        if isinstance(key, (int, np.integer)) and not isinstance(key, bool):
            n = m._count(self._kind)
            if not -n <= key < n:
                raise ArgumentError("mbdae: %s index %d out of range (the model has %d)"
                                    % (self._what, key, n))
            return int(key) % n
        if not isinstance(key, str):
            raise TypeError("a %s is named by a str or an int index, not %s"
                            % (self._what, type(key).__name__))
        index = ctypes.c_int()
        status = lib.mbdae_find(m._handle(), self._kind, key.encode(), ctypes.byref(index))
        if status == ArgumentError.status:
            message = _last_error()  # before other calls replace it
            raise _unknown(self._what, key, self.names(), message)
        check(status)
        return index.value

    def names(self):
        """The names, in the model's order."""
        return self._model._names(self._kind)

    def __iter__(self):
        return iter(self.names())

    def __len__(self):
        return self._model._count(self._kind)

    def __contains__(self, key):
        return key in self.names()

    def keys(self):
        """The names, in the model's order."""
        return self.names()

    def items(self):
        """(name, value) pairs."""
        return [(k, self[k]) for k in self.names()]

    def values(self):
        """The values, in the model's order."""
        return [self[k] for k in self.names()]

    def __repr__(self):
        return "{%s}" % ", ".join("%r: %r" % kv for kv in self.items())


class Parameters(_Named):
    """The model's parameters as a mapping name -> float (``m.parameters["k"] = 3.0``).

    Setting a value works as ``mbdae simulate --set NAME=VALUE``: everything that depends
    on the parameter is recomputed, and the next solve starts again from t = 0. A value
    that makes the model invalid raises :class:`mbdae.InputError` (the old value stays).
    """

    _kind = _lib.PARAMETERS
    _what = "parameter"

    def __getitem__(self, key):
        i = self._index(key)
        value = ctypes.c_double()
        check(lib.mbdae_get_parameter(self._model._handle(), i, ctypes.byref(value)))
        return value.value

    def __setitem__(self, key, value):
        i = self._index(key)
        check(lib.mbdae_set_parameter(self._model._handle(), i, float(value)))

    def update(self, values):
        """Sets several parameters from a mapping name -> value."""
        for k, v in dict(values).items():
            self[k] = v


class Splines(_Named):
    """The model's splines as a mapping name -> (x, y) numpy arrays.

    ``m.splines["drive"] = (x, y)`` replaces the points (x strictly increasing, at least 2
    points; the spline keeps its interpolation); the next solve starts again from t = 0.
    """

    _kind = _lib.SPLINES
    _what = "spline"

    def __getitem__(self, key):
        i = self._index(key)
        h = self._model._handle()
        n = ctypes.c_int()
        check(lib.mbdae_spline_size(h, i, ctypes.byref(n)))
        x = np.empty(n.value)
        y = np.empty(n.value)
        check(lib.mbdae_get_spline_points(h, i, dptr(x), dptr(y), n.value))
        return x, y

    def __setitem__(self, key, points):
        i = self._index(key)
        try:
            x, y = points
        except (TypeError, ValueError):
            raise SizeError("spline points are a pair (x, y) of 1-D arrays of the same length")
        x = np.ascontiguousarray(x, dtype=np.float64)
        y = np.ascontiguousarray(y, dtype=np.float64)
        if x.ndim != 1 or y.ndim != 1:
            raise SizeError("spline points: x and y must be 1-D arrays, got shapes %s and %s"
                            % (x.shape, y.shape))
        if x.shape != y.shape:
            raise SizeError("spline points: x has %d values and y has %d; they must match"
                            % (x.shape[0], y.shape[0]))
        check(lib.mbdae_set_spline_points(self._model._handle(), i, dptr(x), dptr(y),
                                          x.shape[0]))


class Options:
    """The simulation settings as a mapping key -> value, with the keys and values of the
    model file's ``simulation:`` block (:data:`OPTIONS`): ``m.options["hht.alpha"] = -0.3``,
    ``m.options["integrator"] = "ida"`` (``"hht"``, ``"ida"`` or ``"kinematic"``: the
    kinematic analysis of a model without degrees of freedom),
    ``m.options["hht.adaptive"] = True``.

    Values are given as numbers, booleans or text and read back as float, bool or str.
    They take effect at the next assembly (set them before solving). ``output.bodies``,
    ``output.joints``, ``output.forces`` and ``output.measures`` (the elements given
    datasets in the results file, docs/results-file.md "Chosen elements") take ``"all"``
    or a list of names (``[]``: none) and read back as ``"all"`` or a list.
    """

    def __init__(self, model):
        self._model = model

    @staticmethod
    def _text(value):
        if isinstance(value, (bool, np.bool_)):
            return "true" if value else "false"
        if isinstance(value, (int, np.integer)):
            return str(int(value))
        if isinstance(value, (float, np.floating)):
            return repr(float(value))
        if isinstance(value, str):
            return value
        if isinstance(value, (list, tuple)) and all(isinstance(v, str) for v in value):
            return ",".join(value) if value else "none"
        raise TypeError("an option value is a number, a bool, a str or a list of str, not %s"
                        % type(value).__name__)

    def __setitem__(self, key, value):
        check(lib.mbdae_set_option(self._model._handle(), str(key).encode(),
                                   self._text(value).encode()))

    def text(self, key):
        """The value of option `key` as the library writes it."""
        size = 256
        while True:
            buf = ctypes.create_string_buffer(size)
            status = lib.mbdae_get_option(self._model._handle(), str(key).encode(), buf, size)
            if status == SizeError.status and size < 1 << 16:
                size *= 16
                continue
            check(status)
            return buf.value.decode()

    def __getitem__(self, key):
        text = self.text(key)
        if str(key).startswith("output."):
            return text if text == "all" else [] if text == "none" else text.split(",")
        if text in ("true", "false"):
            return text == "true"
        try:
            return float(text)
        except ValueError:
            return text

    def __iter__(self):
        return iter(OPTIONS)

    def __len__(self):
        return len(OPTIONS)

    def keys(self):
        """The option keys (:data:`OPTIONS`)."""
        return list(OPTIONS)

    def items(self):
        """(key, value) pairs of every option."""
        return [(k, self[k]) for k in OPTIONS]

    def __repr__(self):
        return "{%s}" % ", ".join("%r: %r" % kv for kv in self.items())


class Outputs:
    """The stored output rows of the last run, as 2-D numpy arrays (one row per output
    time): ``time`` (1-D), ``q``, ``v``, ``a`` (rows x nq), ``lambda_`` (rows x nm),
    ``measures`` (rows x number of measures, angles unwrapped), ``body_poses``
    (rows x bodies x 12), ``body_positions`` (rows x bodies x 3), ``body_rotations``
    (rows x bodies x 3 x 3). ``len(m.outputs)`` is the number of rows; ``m.outputs[i]``
    is row i as a :class:`Row`. Each attribute reads the rows when it is accessed.
    """

    def __init__(self, model):
        self._model = model

    def __len__(self):
        return self._model._count(_lib.OUTPUTS)

    def __getitem__(self, row):
        return self._model.output(row)

    def _table(self, what, width):
        m = self._model
        h = m._handle()
        rows = len(self)
        out = np.empty((rows, width))
        if rows and width:
            base = out.ctypes.data
            stride = out.strides[0]
            get = lib.mbdae_get_output
            cast = ctypes.cast
            for r in range(rows):
                check(get(h, r, what, cast(base + r * stride, _DP), width))
        return out

    @property
    def time(self):
        """The output times (rows)."""
        return self._table(_lib.OUT_TIME, 1)[:, 0]

    @property
    def q(self):
        """Coordinates (rows x nq)."""
        return self._table(_lib.OUT_Q, self._model.nq)

    @property
    def v(self):
        """Velocities q' (rows x nq)."""
        return self._table(_lib.OUT_V, self._model.nq)

    @property
    def a(self):
        """Accelerations q'' (rows x nq)."""
        return self._table(_lib.OUT_A, self._model.nq)

    @property
    def lambda_(self):
        """Multipliers (rows x nm)."""
        return self._table(_lib.OUT_LAMBDA, self._model.nm)

    @property
    def measures(self):
        """Measures (rows x number of measures), angles unwrapped as in the results file."""
        return self._table(_lib.OUT_MEASURES, self._model.num_measures)

    @property
    def body_poses(self):
        """Body poses (rows x bodies x 12): position (3), rotation body -> world row-major (9)."""
        nb = self._model.num_bodies
        return self._table(_lib.OUT_BODY_POSES, 12 * nb).reshape(-1, nb, 12)

    @property
    def body_positions(self):
        """Centre-of-mass positions (rows x bodies x 3)."""
        return self.body_poses[:, :, :3]

    @property
    def body_rotations(self):
        """Rotation matrices body -> world (rows x bodies x 3 x 3)."""
        p = self.body_poses
        return p[:, :, 3:].reshape(p.shape[0], p.shape[1], 3, 3)

    def measure(self, name):
        """The stored history of one measure (by name or index), 1-D."""
        return self.measures[:, self._model._measure_index(name)]


class Model:
    """One multibody model of the C API with its solver state.

    ``Model(path)`` loads a model file (the project's ``.yaml`` format or a FreeDyn
    ``.fds`` file); :meth:`from_string` loads model text. Use it as a context manager
    (``with mbdae.Model("m.yaml") as m: ...``) or call :meth:`close`; models are
    independent of each other.

    Typical use::

        with mbdae.Model("examples/pendulum.yaml") as m:
            m.parameters["L"] = 2.0
            m.options["integrator"] = "hht"
            m.solve()
            t, q = m.outputs.time, m.outputs.q

    Every failing call raises an :class:`mbdae.Error` subclass with the library's message.
    """

    def __init__(self, path):
        """Loads the model file `path` (.yaml or .fds)."""
        self._h = None
        handle = ctypes.c_void_p()
        check(lib.mbdae_model_from_file(os.fsencode(path), ctypes.byref(handle)))
        self._h = handle
        self.source = os.fspath(path)
        self._init_views()

    @classmethod
    def from_string(cls, text, name=""):
        """A model from its text in the project's format. `name` is used in messages, and
        relative paths in the model (spline data files, meshes) are resolved against its
        folder ("": the working folder)."""
        self = cls.__new__(cls)
        self._h = None
        handle = ctypes.c_void_p()
        check(lib.mbdae_model_from_string(text.encode(), os.fsencode(name),
                                          ctypes.byref(handle)))
        self._h = handle
        self.source = name
        self._init_views()
        return self

    def _init_views(self):
        self._names_cache = {}
        self.parameters = Parameters(self)
        self.splines = Splines(self)
        self.options = Options(self)
        self.outputs = Outputs(self)

    # ---- life ------------------------------------------------------------------------

    def close(self):
        """Frees the model; calling it again does nothing. Every later call raises
        :class:`mbdae.OrderError`."""
        if self._h is not None:
            lib.mbdae_model_free(self._h)
            self._h = None

    @property
    def closed(self):
        """True after :meth:`close`."""
        return self._h is None

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()
        return False

    def __del__(self):
        if getattr(self, "_h", None) is not None and lib is not None:
            lib.mbdae_model_free(self._h)
            self._h = None

    def __repr__(self):
        if self._h is None:
            return "<mbdae.Model %r (closed)>" % self.source
        return "<mbdae.Model %r: %d bodies, %d coordinates>" % (self.source, self.num_bodies,
                                                               self.nq)

    def _handle(self):
        if self._h is None:
            raise OrderError("mbdae: the model %r is closed" % self.source)
        return self._h

    # ---- sizes and names ---------------------------------------------------------------

    def _count(self, kind):
        n = ctypes.c_int()
        check(lib.mbdae_count(self._handle(), kind, ctypes.byref(n)))
        return n.value

    def _names(self, kind):
        # The structure (bodies, coordinates, ...) never changes; multipliers and redundant
        # equations may change at a re-assembly, and the names of the stored gradient at
        # each gradient, so they are read each time.
        cached = kind not in (_lib.MULTIPLIERS, _lib.REDUNDANT, _lib.GRADIENT_OBJECTIVES,
                              _lib.GRADIENT_WRT)
        if cached and kind in self._names_cache:
            return list(self._names_cache[kind])
        h = self._handle()
        p = ctypes.c_char_p()
        names = []
        for i in range(self._count(kind)):
            check(lib.mbdae_name(h, kind, i, ctypes.byref(p)))
            names.append(p.value.decode())
        if cached:
            self._names_cache[kind] = tuple(names)
        return names

    @property
    def nq(self):
        """Number of coordinates q (7 per body)."""
        return self._count(_lib.COORDINATES)

    @property
    def nm(self):
        """Number of multipliers (independent constraint equations; assembles if needed)."""
        return self._count(_lib.MULTIPLIERS)

    num_coordinates = nq
    num_multipliers = nm

    @property
    def joint_space(self):
        """The joint coordinates of a tree of revolute, prismatic and fixed joints, with the
        joint-space mass matrix, bias, gravity and inverse dynamics
        (:class:`mbdae.joint_space.JointSpace`; a model that is not such a tree raises
        InputError)."""
        from .joint_space import JointSpace
        return JointSpace(self)

    @property
    def num_redundant(self):
        """Number of constraint equations set aside as redundant (assembles if needed)."""
        return self._count(_lib.REDUNDANT)

    @property
    def num_bodies(self):
        """Number of bodies."""
        return self._count(_lib.BODIES)

    @property
    def num_joints(self):
        """Number of joints."""
        return self._count(_lib.JOINTS)

    @property
    def num_forces(self):
        """Number of force elements."""
        return self._count(_lib.FORCES)

    @property
    def num_measures(self):
        """Number of measures."""
        return self._count(_lib.MEASURES)

    @property
    def num_parameters(self):
        """Number of parameters."""
        return self._count(_lib.PARAMETERS)

    @property
    def num_splines(self):
        """Number of splines."""
        return self._count(_lib.SPLINES)

    @property
    def num_outputs(self):
        """Number of stored output rows."""
        return self._count(_lib.OUTPUTS)

    @property
    def coordinates(self):
        """Names of the coordinates: "body.x", "body.y", "body.z", "body.e0" ... "body.e3"."""
        return self._names(_lib.COORDINATES)

    @property
    def multipliers(self):
        """Names of the multipliers, the independent constraint equations (assembles if
        needed)."""
        return self._names(_lib.MULTIPLIERS)

    @property
    def redundant(self):
        """Names of the constraint equations set aside as redundant (assembles if needed)."""
        return self._names(_lib.REDUNDANT)

    @property
    def bodies(self):
        """Names of the bodies."""
        return self._names(_lib.BODIES)

    @property
    def joints(self):
        """Names of the joints."""
        return self._names(_lib.JOINTS)

    @property
    def forces(self):
        """Names of the force elements."""
        return self._names(_lib.FORCES)

    @property
    def measures(self):
        """Names of the measures."""
        return self._names(_lib.MEASURES)

    @property
    def objectives(self):
        """Names of the objectives (``objectives:`` of the model file)."""
        return self._names(_lib.OBJECTIVES)

    def _find(self, kind, what, name):
        index = ctypes.c_int()
        status = lib.mbdae_find(self._handle(), kind, name.encode(), ctypes.byref(index))
        if status == ArgumentError.status:
            message = _last_error()  # before other calls replace it
            raise _unknown(what, name, self._names(kind), message)
        check(status)
        return index.value

    def _measure_index(self, key):
        if isinstance(key, str):
            return self._find(_lib.MEASURES, "measure", key)
        n = self.num_measures
        if not isinstance(key, (int, np.integer)) or not -n <= key < n:
            raise ArgumentError("mbdae: measure index %r out of range (the model has %d)"
                                % (key, n))
        return int(key) % n

    def index(self, kind, name):
        """The zero-based index of item `name` of `kind` ("coordinates", "multipliers",
        "redundant", "bodies", "joints", "forces", "measures", "parameters", "splines",
        "objectives")."""
        kinds = {"coordinates": (_lib.COORDINATES, "coordinate"),
                 "multipliers": (_lib.MULTIPLIERS, "multiplier"),
                 "redundant": (_lib.REDUNDANT, "redundant equation"),
                 "bodies": (_lib.BODIES, "body"), "joints": (_lib.JOINTS, "joint"),
                 "forces": (_lib.FORCES, "force"), "measures": (_lib.MEASURES, "measure"),
                 "parameters": (_lib.PARAMETERS, "parameter"),
                 "splines": (_lib.SPLINES, "spline"),
                 "objectives": (_lib.OBJECTIVES, "objective")}
        if kind not in kinds:
            raise ArgumentError("mbdae: no kind '%s'; the kinds are: %s"
                                % (kind, ", ".join(kinds)))
        return self._find(kinds[kind][0], kinds[kind][1], name)

    # ---- solving -----------------------------------------------------------------------

    def assemble(self):
        """Consistent initial conditions at t = 0 (positions, velocities, accelerations,
        multipliers; redundant equations set aside). Clears the stored outputs, stores the
        row at t = 0 and makes that the current state."""
        check(lib.mbdae_assemble(self._handle()))

    def solve(self):
        """Integrates from the current state to t_end (assembling first if needed),
        storing a row at every output time. Raises :class:`mbdae.SolverError` if the
        integrator fails (the rows so far are kept)."""
        check(lib.mbdae_solve(self._handle()))

    def solve_to(self, t):
        """Integrates from the current state to time `t`, storing a row at every output
        time passed on the way. Calling it at every output time gives bitwise the rows of
        one :meth:`solve`."""
        check(lib.mbdae_solve_to(self._handle(), float(t)))

    @property
    def time(self):
        """The time of the current state."""
        t = ctypes.c_double()
        check(lib.mbdae_get_state(self._handle(), ctypes.byref(t), None, None, None, None,
                                  0, 0))
        return t.value

    @property
    def state(self):
        """The current state as a :class:`State` (t, q, v, a, lambda_). Assigning a
        :class:`State` or a mapping with keys t, q, v and optionally a, lambda sets the
        current state and restarts the integrator from it (a and lambda, if missing, are
        computed from the equations of motion)."""
        nq, nm = self.nq, self.nm
        t = ctypes.c_double()
        q, v, a, lam = np.empty(nq), np.empty(nq), np.empty(nq), np.empty(nm)
        check(lib.mbdae_get_state(self._handle(), ctypes.byref(t), dptr(q), dptr(v), dptr(a),
                                  dptr(lam), nq, nm))
        return State(t.value, q, v, a, lam)

    @state.setter
    def state(self, s):
        if isinstance(s, State):
            self.set_state(s.t, s.q, s.v, s.a, s.lambda_)
        else:
            s = dict(s)
            unknown = set(s) - {"t", "q", "v", "a", "lambda", "lambda_"}
            if unknown:
                raise ArgumentError("mbdae: a state has the keys t, q, v, a, lambda; not %s"
                                    % ", ".join(sorted(map(str, unknown))))
            for k in ("t", "q", "v"):
                if k not in s:
                    raise ArgumentError("mbdae: a state needs '%s'" % k)
            self.set_state(s["t"], s["q"], s["v"], s.get("a"), s.get("lambda", s.get("lambda_")))

    def set_state(self, t, q, v, a=None, lambda_=None):
        """Sets the current state (time t, coordinates q, velocities v; accelerations a and
        multipliers lambda_ optional: computed from the equations of motion when None)
        and restarts the integrator from it. q and v are used as given (not projected)."""
        nq = self.nq
        q = _as_vector(q, nq, "q")
        v = _as_vector(v, nq, "v")
        a = None if a is None else _as_vector(a, nq, "a")
        nm = self.nm
        lam = None if lambda_ is None else _as_vector(lambda_, nm, "lambda")
        check(lib.mbdae_set_state(self._handle(), float(t), dptr(q), dptr(v), dptr(a),
                                  dptr(lam), nq, nm))

    # ---- stored outputs ----------------------------------------------------------------

    def output(self, row):
        """Stored output row `row` (negative counts from the end) as a :class:`Row`."""
        n = self.num_outputs
        if not isinstance(row, (int, np.integer)) or not -n <= row < n:
            raise ArgumentError("mbdae: output row %r out of range (%d rows stored)" % (row, n))
        row = int(row) % n
        h = self._handle()
        nq, nm, nme, nb = self.nq, self.nm, self.num_measures, self.num_bodies

        def get(what, width):
            out = np.empty(width)
            check(lib.mbdae_get_output(h, row, what, dptr(out), width))
            return out

        return Row(get(_lib.OUT_TIME, 1)[0], get(_lib.OUT_Q, nq), get(_lib.OUT_V, nq),
                   get(_lib.OUT_A, nq), get(_lib.OUT_LAMBDA, nm), get(_lib.OUT_MEASURES, nme),
                   get(_lib.OUT_BODY_POSES, 12 * nb).reshape(nb, 12))

    def write_results(self, path):
        """Writes the stored rows as a results file (HDF5, docs/results-file.md).

        As ``mbdae simulate`` writes it: into ``PATH.PID.tmp`` beside `path`, renamed over
        it when complete (an earlier file stays whole if writing fails). Raises
        :class:`mbdae.FileError` for the model file itself (by any spelling or link) or a
        path the system refuses (its reason), :class:`mbdae.OrderError` without rows."""
        check(lib.mbdae_write_results(self._handle(), os.fsencode(path)))

    # ---- measures, vectors and matrices at the current state ---------------------------

    def measure_values(self):
        """The values of all measures at the current state (1-D, in the order of
        :attr:`measures`; angles not unwrapped)."""
        n = self.num_measures
        out = np.empty(n)
        check(lib.mbdae_measure_values(self._handle(), dptr(out), n))
        return out

    def measure_gradient(self, measure):
        """d(measure)/dq at the current state (1-D, nq); `measure` is a name or an index."""
        i = self._measure_index(measure)
        nq = self.nq
        out = np.empty(nq)
        check(lib.mbdae_measure_gradient(self._handle(), i, dptr(out), nq))
        return out

    def vector(self, name):
        """A vector at the current state, by name: "mass_times_acc" (M a),
        "constraint_forces" (C_q^T lambda), "quadratic_velocity", "external_forces",
        "sum_of_forces" (all nq), "constraints" (C), "constraints_dt" (dC/dt),
        "constraints_qdot" (d(C_q)/dt q'), "constraints_dtt" (d2C/dt2) (all nm)."""
        if name not in VECTORS:
            raise _unknown("vector", name, list(VECTORS))
        which, size = VECTORS[name]
        n = self.nq if size == "nq" else self.nm
        out = np.empty(n)
        check(lib.mbdae_get_vector(self._handle(), which, dptr(out), n))
        return out

    def matrix_shape(self, name):
        """The shape of matrix `name` (see :meth:`matrix`)."""
        if name not in MATRICES:
            raise _unknown("matrix", name, list(MATRICES))
        nq = self.nq
        if name == "constraint_dq":
            return (self.nm, nq)
        if name == "newton_hht":
            n = nq + self.nm
            return (n, n)
        if name == "newton_ida":
            n = 2 * (nq + self.nm)
            return (n, n)
        return (nq, nq)

    def matrix(self, name, format="csc"):
        """A sparse matrix at the current state as a scipy.sparse matrix ("csc" or "csr"):
        "mass" (M), "constraint_dq" (C_q), "mass_acc_dq" (d(M a)/dq), "force_dq"
        (dQ/dq), "force_dv" (dQ/dq'), "constraint_t_dq" (d(C_q^T lambda)/dq),
        "newton_hht" and "newton_ida" (the integrators' Newton matrices at the step of
        :meth:`set_newton_step`). The pattern is the structural one (explicit zeros kept).
        """
        return self.compose([(name, 0, 0)], self.matrix_shape(name), format)

    def compose(self, blocks, shape, format="csc"):
        """The sum of scaled, placed matrices as one sparse matrix of `shape` (rows, cols).

        Each block is a tuple ``(name, row, col[, scale[, transpose]])`` or a dict with
        the keys ``matrix``, ``row``, ``col`` and optionally ``scale`` (default 1) and
        ``transpose`` (default False): `scale` times matrix `name` (see :meth:`matrix`),
        its top-left corner at (row, col). Overlapping entries are added. Example, the
        matrix [[M, C_q^T], [C_q, 0]]::

            nq, nm = m.nq, m.nm
            K = m.compose([("mass", 0, 0), ("constraint_dq", 0, nq, 1.0, True),
                           ("constraint_dq", nq, 0)], (nq + nm, nq + nm))
        """
        import scipy.sparse as sp

        if format not in _FORMATS:
            raise ArgumentError("mbdae: format '%s' is not one of csc, csr" % format)
        try:
            rows, cols = (int(s) for s in shape)
        except (TypeError, ValueError):
            raise SizeError("mbdae: shape must be a pair (rows, cols), got %r" % (shape,))
        blocks = list(blocks)
        array = (_lib.Block * max(1, len(blocks)))()
        for k, b in enumerate(blocks):
            if isinstance(b, dict):
                extra = set(b) - {"matrix", "row", "col", "scale", "transpose"}
                if extra or not {"matrix", "row", "col"} <= set(b):
                    raise ArgumentError("mbdae: block %d: a dict block has the keys matrix, "
                                        "row, col and optionally scale, transpose" % k)
                name, row, col = b["matrix"], b["row"], b["col"]
                scale, transpose = b.get("scale", 1.0), b.get("transpose", False)
            else:
                b = tuple(b)
                if not 3 <= len(b) <= 5:
                    raise ArgumentError("mbdae: block %d: (name, row, col[, scale[, "
                                        "transpose]]), got %r" % (k, b))
                name, row, col = b[:3]
                scale = b[3] if len(b) > 3 else 1.0
                transpose = b[4] if len(b) > 4 else False
            if name not in MATRICES:
                raise _unknown("matrix", name, list(MATRICES))
            array[k] = _lib.Block(MATRICES[name], float(scale), int(row), int(col),
                                  1 if transpose else 0)
        fmt = _FORMATS[format]
        h = self._handle()
        nnz = ctypes.c_int()
        check(lib.mbdae_get_matrix(h, array, len(blocks), rows, cols, fmt, ctypes.byref(nnz),
                                   None, None, None))
        nptr = (cols if fmt == _lib.CSC else rows) + 1
        ptr = np.zeros(nptr, dtype=np.int32)
        idx = np.zeros(nnz.value, dtype=np.int32)
        val = np.zeros(nnz.value)
        check(lib.mbdae_get_matrix(h, array, len(blocks), rows, cols, fmt, ctypes.byref(nnz),
                                   iptr(ptr), iptr(idx), dptr(val)))
        cls = sp.csc_matrix if fmt == _lib.CSC else sp.csr_matrix
        return cls((val, idx, ptr), shape=(rows, cols))

    def set_newton_step(self, h):
        """The step h of the Newton matrices "newton_hht" and "newton_ida" (default: the
        option hht.step)."""
        check(lib.mbdae_set_newton_step(self._handle(), float(h)))

    # ---- objectives and gradients (gradient.py) -----------------------------------------

    def gradient(self, objectives=None, wrt=None, method="adjoint", wrt_splines=False,
                 results=None):
        """Values and gradients of the model's objectives with the current parameters,
        spline points and options, as a :class:`mbdae.Gradient` (``.values`` dict,
        ``.gradient`` numpy array objectives x wrt, ``.wrt``, ``.as_dict()``, times).

        objectives: a name or a list of names (None: every objective); rows come in the
        model's order. wrt: parameter names and spline ordinates "SPLINE[i]" (None: every
        parameter); wrt_splines adds every spline ordinate. method: "adjoint" (HHT: the
        discrete adjoint of the run; IDA: IDAS adjoint), "forward" (direct
        differentiation; IDAS forward) or "fd" (central differences of whole runs, step
        ``options["gradient.fd_step"]`` times max(|p|, 1)). results: a path for the
        results file of the forward run with /objectives/NAME (None: no file), written as
        ``mbdae gradient -o`` writes it: into ``PATH.PID.tmp`` beside it and renamed over
        it at the end (an earlier file stays whole until then, and after an error other
        than a failed run, whose file is written with status "failed").

        Runs its own simulations: the stored outputs and the current state are left as
        they were. Raises ArgumentError for an unknown objective, wrt name or method,
        InputError for what the method cannot differentiate (the message names it),
        SolverError when a run fails, FileError for a results path that is the model file
        or that the system refuses (its reason).
        """
        return _gradient.compute(self, objectives, wrt, method, wrt_splines, results)

    def objective_function(self, objective, wrt=None, method="adjoint", scale=1.0):
        """Objective `objective` as a function f(x) of the variables `wrt` (parameter
        names and spline ordinates "SPLINE[i]"; None: every parameter) for an optimiser,
        with f.jac(x) its gradient, f.x0 the current values (a :class:`mbdae.
        ObjectiveFunction`)::

            f = m.objective_function("misfit", ["k", "c"])
            r = scipy.optimize.minimize(f, f.x0, jac=f.jac, method="BFGS")

        f(x) sets the model's parameters and spline ordinates to x and computes value and
        gradient in one run (cached: f(x), f.jac(x) at the same x cost one run). scale
        multiplies value and gradient (-1: maximise).
        """
        return _gradient.objective_function(self, objective, wrt, method, scale)

    def spline_ordinates(self, spline):
        """The wrt names of every ordinate of spline `spline`: ["u1[0]", "u1[1]", ...]."""
        return _gradient.spline_ordinates(self, spline)
