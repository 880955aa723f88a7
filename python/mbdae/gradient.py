"""Gradients of a model's objectives (:meth:`mbdae.Model.gradient`) and the objective
functions an optimiser calls (:meth:`mbdae.Model.objective_function`).

Both are layers on the C API's ``mbdae_gradient`` (api/mbdae.h): the adjoint, forward or
finite-difference gradient of the objectives of the model file (``objectives:``) with
respect to parameters ("k") and spline ordinates ("u1[3]", 0-based point index).
"""

import ctypes
import json
import re

import numpy as np

from . import _lib
from ._lib import check, dptr
from .errors import ArgumentError, SizeError

lib = _lib.lib

#: The methods of :meth:`mbdae.Model.gradient`.
METHODS = ("adjoint", "forward", "fd")

_ORDINATE = re.compile(r"^(.+)\[(\d+)\]$")


def _name_list(names, what):
    """None, a str (one name) or an iterable of str as a list of str (or None)."""
    if names is None:
        return None
    if isinstance(names, str):
        return [names]
    out = list(names)
    for n in out:
        if not isinstance(n, str):
            raise TypeError("%s are named by str, not %s" % (what, type(n).__name__))
    return out


class Gradient:
    """The values and gradients of objectives, as :meth:`mbdae.Model.gradient` returns
    them (a copy: later calls do not change it).

    Attributes:

    - ``objectives``: the objective names (rows of ``gradient``, in the model's order);
    - ``wrt``: what the gradient is taken with respect to (columns), "k" or "u1[3]";
    - ``values``: dict objective name -> G (the forward run's value);
    - ``gradient``: numpy array (objectives x wrt), ``gradient[i, k] = dG_i/dp_k``;
    - ``method`` ("adjoint", "forward", "fd"), ``integrator`` ("hht", "ida");
    - ``fd_steps``: dict wrt name -> the absolute central-difference step (fd; else None);
    - ``solver_cpu_time`` (the forward run), ``gradient_cpu_time`` (beyond it; fd: the
      perturbed runs), ``wall_time`` in seconds; ``forward_steps``, ``runs``,
      ``linear_solves`` (HHT: the sweep's solves of the Newton matrix; 0 otherwise).

    ``g["G"]`` is the dict wrt name -> dG/dp of objective G; :meth:`as_dict` gives
    ``{"G": {"value": ..., "gradient": {"k": ..., ...}}, ...}`` (the JSON of
    ``mbdae gradient --json``); ``str(g)`` the program's report.
    """

    def __init__(self, objectives, wrt, values, gradient, fd_steps, times, counters, report,
                 summary):
        self.objectives = list(objectives)
        self.wrt = list(wrt)
        self.values = dict(zip(self.objectives, (float(v) for v in values)))
        self.gradient = gradient
        self.fd_steps = None if fd_steps is None else dict(zip(self.wrt, map(float, fd_steps)))
        self.solver_cpu_time, self.gradient_cpu_time, self.wall_time = (float(t) for t in times)
        self.forward_steps = int(counters[0])
        self.runs = int(counters[1])
        # HHT's sweep: transposed (adjoint) or plain (forward) solves of the Newton matrix
        self.linear_solves = int(counters[2])
        self.method = summary.get("method")
        self.integrator = summary.get("integrator")
        self._report = report

    def __getitem__(self, objective):
        """dict wrt name -> dG/dp of `objective`."""
        try:
            i = self.objectives.index(objective)
        except ValueError:
            raise ArgumentError("mbdae: the gradient has no objective '%s' (it has: %s)"
                                % (objective, ", ".join(self.objectives)))
        return dict(zip(self.wrt, (float(x) for x in self.gradient[i])))

    def as_dict(self):
        """{objective: {"value": G, "gradient": {wrt name: dG/dp}}}."""
        return {o: {"value": self.values[o], "gradient": self[o]} for o in self.objectives}

    def value_array(self):
        """The values as a 1-D numpy array, in the order of ``objectives``."""
        return np.array([self.values[o] for o in self.objectives])

    def report(self):
        """The report ``mbdae gradient`` prints."""
        return self._report

    def __str__(self):
        return self._report

    def __repr__(self):
        return "<mbdae.Gradient %s (%s): %d objectives x %d wrt>" % (
            self.method, self.integrator, len(self.objectives), len(self.wrt))


def _report_text(handle, as_json):
    length = ctypes.c_size_t()
    check(lib.mbdae_gradient_report(handle, 1 if as_json else 0, None, 0, ctypes.byref(length)))
    buf = ctypes.create_string_buffer(length.value)
    check(lib.mbdae_gradient_report(handle, 1 if as_json else 0, buf, length.value, None))
    return buf.value.decode("utf-8", "replace")


def compute(model, objectives=None, wrt=None, method="adjoint", wrt_splines=False,
            results=None):
    """See :meth:`mbdae.Model.gradient`."""
    import os

    objectives = _name_list(objectives, "objectives")
    wrt = _name_list(wrt, "wrt entries")
    if not isinstance(method, str):
        raise TypeError("method is a str (%s), not %s" % (", ".join(METHODS),
                                                         type(method).__name__))
    h = model._handle()
    obj_array, n_obj = _lib.names_array(objectives)
    wrt_array, n_wrt = _lib.names_array(wrt)
    path = None if results is None else os.fsencode(results)
    check(lib.mbdae_gradient(h, method.encode(), obj_array, n_obj, wrt_array, n_wrt,
                             1 if wrt_splines else 0, path))
    names = model._names(_lib.GRADIENT_OBJECTIVES)
    wrt_names = model._names(_lib.GRADIENT_WRT)
    no, nw = len(names), len(wrt_names)

    def get(what, n):
        out = np.empty(n)
        check(lib.mbdae_get_gradient(h, what, dptr(out), n))
        return out

    values = get(_lib.GRAD_VALUES, no)
    grad = get(_lib.GRAD_GRADIENT, no * nw).reshape(no, nw)
    summary = json.loads(_report_text(h, True))
    fd_steps = get(_lib.GRAD_FD_STEPS, nw) if summary.get("method") == "fd" else None
    return Gradient(names, wrt_names, values, grad, fd_steps, get(_lib.GRAD_TIMES, 3),
                    get(_lib.GRAD_COUNTERS, 4), _report_text(h, False), summary)


class _Evaluations:
    """What the objective functions of one optimisation share: the model, the variables,
    the method, the objectives asked for, and the last point with its gradient."""

    def __init__(self, model, wrt, method, wrt_splines_names):
        self.model = model
        self.wrt = wrt
        self.method = method
        self.objectives = []
        self.last_x = None
        self.last = None
        self.runs = 0
        # Each variable: ("parameter", name) or ("ordinate", spline, point).
        self.targets = []
        splines = wrt_splines_names
        params = model.parameters.names()
        for name in wrt:
            m = _ORDINATE.match(name)
            if name in params:
                self.targets.append(("parameter", name, None))
            elif m and m.group(1) in splines:
                spline, point = m.group(1), int(m.group(2))
                n = len(model.splines[spline][0])
                if point >= n:
                    raise ArgumentError("mbdae: wrt '%s': spline '%s' has %d points (0 .. %d)"
                                        % (name, spline, n, n - 1))
                self.targets.append(("ordinate", spline, point))
            else:
                raise ArgumentError("mbdae: wrt '%s' is neither a parameter (%s) nor a spline "
                                    "ordinate SPLINE[i] (splines: %s)"
                                    % (name, ", ".join(params) or "none",
                                       ", ".join(splines) or "none"))

    def current(self):
        """The model's current values of the variables."""
        x = np.empty(len(self.wrt))
        points = {}
        for k, (kind, name, point) in enumerate(self.targets):
            if kind == "parameter":
                x[k] = self.model.parameters[name]
            else:
                if name not in points:
                    points[name] = self.model.splines[name]
                x[k] = points[name][1][point]
        return x

    def apply(self, x):
        """Sets the model's parameters and spline ordinates to x."""
        ordinates = {}
        for (kind, name, point), value in zip(self.targets, x):
            if kind == "parameter":
                self.model.parameters[name] = float(value)
            else:
                if name not in ordinates:
                    xs, ys = self.model.splines[name]
                    ordinates[name] = (xs, ys.copy())
                ordinates[name][1][point] = float(value)
        for name, points in ordinates.items():
            self.model.splines[name] = points

    def add(self, objective):
        if objective not in self.objectives:
            known = self.model.objectives
            if objective not in known:
                raise ArgumentError("mbdae: there is no objective called '%s' (the model's "
                                    "objectives: %s)" % (objective, ", ".join(known) or "none"))
            self.objectives.append(objective)
            self.last_x = None  # the cached run lacks it

    def at(self, x):
        """The Gradient at x (one run per new x: fun and jac at the same x share it)."""
        x = np.array(x, dtype=np.float64, copy=True).reshape(-1)
        if x.shape[0] != len(self.wrt):
            raise SizeError("mbdae: x has %d values; the variables are %d (%s)"
                            % (x.shape[0], len(self.wrt), ", ".join(self.wrt)))
        if not np.all(np.isfinite(x)):
            raise ArgumentError("mbdae: x must be finite, got %r" % (x,))
        if self.last_x is None or not np.array_equal(x, self.last_x):
            self.last_x = None
            self.apply(x)
            self.last = compute(self.model, self.objectives, self.wrt, self.method)
            self.last_x = x
            self.runs += 1
        return self.last


class ObjectiveFunction:
    """An objective of the model as a function of chosen parameters and spline ordinates,
    for optimisers such as ``scipy.optimize.minimize``::

        f = m.objective_function("misfit", ["k", "c"])
        r = scipy.optimize.minimize(f, f.x0, jac=f.jac, method="BFGS")

    ``f(x)`` is ``scale * G`` at the variables x (in the order of ``f.wrt``), ``f.jac(x)``
    its gradient (numpy, one entry per variable), ``f.value_and_jac(x)`` both (for
    ``jac=True``). Evaluating at x sets the model's parameters and spline ordinates to x
    (they stay there: after an optimisation the model holds the last point evaluated; use
    :meth:`set` to choose) and computes the value and the gradient in one
    ``Model.gradient`` call; the last x is cached, so ``f(x)`` then ``f.jac(x)`` cost one
    run. :meth:`for_objective` gives the function of another objective sharing the same
    runs (constraints: ``{"type": "eq", "fun": c, "jac": c.jac}``).
    """

    def __init__(self, evaluations, objective, scale=1.0):
        self._e = evaluations
        self.objective = objective
        self.scale = float(scale)
        evaluations.add(objective)

    @property
    def wrt(self):
        """The variables' names, in the order of x."""
        return list(self._e.wrt)

    @property
    def method(self):
        """The gradient method ("adjoint", "forward", "fd")."""
        return self._e.method

    @property
    def x0(self):
        """The model's current values of the variables (a starting point)."""
        return self._e.current()

    @property
    def runs(self):
        """Gradient runs so far (shared with the functions of :meth:`for_objective`)."""
        return self._e.runs

    @property
    def last(self):
        """The :class:`Gradient` of the last point evaluated (None before the first)."""
        return self._e.last

    def __call__(self, x):
        g = self._e.at(x)
        return self.scale * g.values[self.objective]

    def jac(self, x):
        """The gradient at x: d(scale * G)/dx (1-D numpy array, one entry per variable)."""
        g = self._e.at(x)
        return self.scale * g.gradient[g.objectives.index(self.objective)].copy()

    def value_and_jac(self, x):
        """(f(x), f.jac(x)) from one run (for ``minimize(f.value_and_jac, x0, jac=True)``)."""
        return self(x), self.jac(x)

    def set(self, x):
        """Sets the model's parameters and spline ordinates to x (no run)."""
        x = np.asarray(x, dtype=np.float64).reshape(-1)
        if x.shape[0] != len(self._e.wrt):
            raise SizeError("mbdae: x has %d values; the variables are %d"
                            % (x.shape[0], len(self._e.wrt)))
        self._e.apply(x)
        self._e.last_x = None

    def for_objective(self, objective, scale=1.0):
        """The function of another objective of the model over the same variables, sharing
        this one's runs (each run then computes both)."""
        return ObjectiveFunction(self._e, objective, scale)

    def __repr__(self):
        return "<mbdae.ObjectiveFunction %s%s of (%s), %s>" % (
            "" if self.scale == 1.0 else "%g * " % self.scale, self.objective,
            ", ".join(self._e.wrt), self._e.method)


def objective_function(model, objective, wrt=None, method="adjoint", scale=1.0):
    """See :meth:`mbdae.Model.objective_function`."""
    if not isinstance(objective, str):
        raise TypeError("objective is a name (str), not %s" % type(objective).__name__)
    if method not in METHODS:
        raise ArgumentError("mbdae: unknown gradient method '%s'; the methods are %s"
                            % (method, ", ".join(METHODS)))
    wrt = _name_list(wrt, "wrt entries")
    if wrt is None:
        wrt = model.parameters.names()
    if len(set(wrt)) != len(wrt):
        raise ArgumentError("mbdae: wrt lists a name twice: %s" % ", ".join(wrt))
    if not wrt:
        raise ArgumentError("mbdae: no variables: wrt is empty and the model has no parameters")
    e = _Evaluations(model, wrt, method, model.splines.names())
    return ObjectiveFunction(e, objective, scale)


def spline_ordinates(model, spline):
    """The names "SPLINE[0]", "SPLINE[1]", ... of every ordinate of a spline."""
    n = len(model.splines[spline][0])
    return ["%s[%d]" % (spline, i) for i in range(n)]
