"""Optimal control and identification from Python (:func:`mbdae.optimize`): a problem file
solved as ``mbdae optimize`` solves it (single shooting with Ipopt, exact gradients,
docs/sensitivities.md), through the C API's ``mbdae_optimize`` (api/mbdae.h).

For an optimiser of your own, use :meth:`mbdae.Model.objective_function` instead (its
``fun`` and ``jac`` go to ``scipy.optimize.minimize``).
"""

import ctypes
import json
import os

import numpy as np

from . import _lib
from ._lib import check, dptr

lib = _lib.lib

#: The columns of :attr:`OptimizationResult.history` (MBDAE_OPTIMIZATION_HISTORY_COLUMNS).
HISTORY_COLUMNS = ("iteration", "objective", "constraint_violation", "dual_infeasibility",
                   "mu", "step", "line_search_trials", "gradient_evaluations")

# int (*)(int iteration, double objective, double constraint_violation, void* user_data)
_PROGRESS = ctypes.CFUNCTYPE(ctypes.c_int, ctypes.c_int, ctypes.c_double, ctypes.c_double,
                             ctypes.c_void_p)


def _declare():
    """The optimisation functions of api/mbdae.h (declared here, next to their use)."""
    vp = ctypes.c_void_p
    st = ctypes.c_int
    cp = ctypes.c_char_p
    signatures = {
        "mbdae_optimize": (st, [cp, cp, _PROGRESS, vp, ctypes.POINTER(vp)]),
        "mbdae_optimize_string": (st, [cp, cp, cp, _PROGRESS, vp, ctypes.POINTER(vp)]),
        "mbdae_optimization_free": (None, [vp]),
        "mbdae_optimization_report": (st, [vp, ctypes.c_int, ctypes.c_char_p, ctypes.c_size_t,
                                           ctypes.POINTER(ctypes.c_size_t)]),
        "mbdae_optimization_history": (st, [vp, _lib._c_double_p, ctypes.c_int,
                                            ctypes.POINTER(ctypes.c_int)]),
    }
    for name, (restype, argtypes) in signatures.items():
        try:
            f = getattr(lib, name)
        except AttributeError:
            raise ImportError("mbdae: %s has no %s (a library older than this package)"
                              % (_lib.path, name))
        f.restype = restype
        f.argtypes = argtypes


_declare()


class OptimizationResult:
    """How an optimisation ended, as :func:`mbdae.optimize` returns it.

    Attributes:

    - ``status``: "solved" or "failed"; ``solved``: bool (Ipopt ended with
      Solve_Succeeded or Solved_To_Acceptable_Level and the final run went through);
      ``ipopt_status``: Ipopt's return status, e.g. "Solve_Succeeded";
    - ``objective_name``, ``objective``: the minimised objective of the final run;
    - ``variables``: dict name -> value at the final point ("J", "tau[3]"); ``x``: the
      same as a numpy array in the problem's order;
    - ``constraints``: dict objective name -> value of the final run;
      ``constraint_violation``: the largest distance of a constraint to its bounds;
    - ``iterations``; ``history``: numpy array, one row per iteration (row 0: the
      starting point), columns :data:`HISTORY_COLUMNS`;
    - ``gradient_evaluations``, ``failed_evaluations``, ``hessian_evaluations`` (Hessians
      from differences of gradients, ``ipopt: {hessian_approximation: exact}``), ``runs``
      (whole simulations, the final run included); ``shooting_intervals``,
      ``shooting_defect`` (multiple shooting: the largest continuity defect); ``gradient_cpu_time``, ``cpu_time``, ``wall_time`` (seconds);
    - ``results``: the results file written (None without one); ``failure_reason``.

    ``str(result)`` is the report ``mbdae optimize`` prints; :meth:`as_dict` the object
    of ``mbdae optimize --json``.
    """

    def __init__(self, summary, report, history, results):
        self._summary = summary
        self._report = report
        self.status = summary["status"]
        self.solved = self.status == "solved"
        self.ipopt_status = summary["ipopt_status"]
        self.objective_name = summary["objective_name"]
        self.objective = _number(summary["objective"])
        self.variables = {k: _number(v) for k, v in summary["variables"].items()}
        self.x = np.array(list(self.variables.values()), dtype=np.float64)
        self.constraints = {k: _number(v) for k, v in summary["constraints"].items()}
        self.constraint_violation = _number(summary["constraint_violation"])
        self.iterations = int(summary["iterations"])
        self.history = history
        self.gradient_evaluations = int(summary["gradient_evaluations"])
        self.failed_evaluations = int(summary["failed_evaluations"])
        self.hessian_evaluations = int(summary.get("hessian_evaluations", 0))
        self.shooting_intervals = int(summary.get("shooting_intervals", 1))
        self.shooting_defect = _number(summary.get("shooting_defect", 0.0))
        self.runs = int(summary["runs"])
        self.gradient_cpu_time = _number(summary["gradient_cpu_time"])
        self.cpu_time = _number(summary["cpu_time"])
        self.wall_time = _number(summary["wall_time"])
        self.failure_reason = summary.get("failure_reason")
        self.results = results

    def as_dict(self):
        """The object ``mbdae optimize --json`` prints (a copy)."""
        return json.loads(json.dumps(self._summary))

    def report(self):
        """The report ``mbdae optimize`` prints."""
        return self._report

    def __str__(self):
        return self._report

    def __repr__(self):
        return "<mbdae.OptimizationResult %s (%s): %s = %.10g, %d iterations>" % (
            self.status, self.ipopt_status, self.objective_name, self.objective, self.iterations)


def _number(x):
    return float("nan") if x is None else float(x)


def _report_text(handle, as_json):
    length = ctypes.c_size_t()
    flag = 1 if as_json else 0
    check(lib.mbdae_optimization_report(handle, flag, None, 0, ctypes.byref(length)))
    buf = ctypes.create_string_buffer(length.value)
    check(lib.mbdae_optimization_report(handle, flag, buf, length.value, None))
    return buf.value.decode("utf-8", "replace")


def _history(handle):
    rows = ctypes.c_int()
    check(lib.mbdae_optimization_history(handle, None, 0, ctypes.byref(rows)))
    out = np.empty((rows.value, len(HISTORY_COLUMNS)))
    check(lib.mbdae_optimization_history(handle, dptr(out), out.size, None))
    return out


def _print_progress(iteration, objective, violation):
    if iteration % 20 == 0:
        print("%4s  %-22s  %s" % ("iter", "objective", "violation"), flush=False)
    print("%4d  %22.14e  %10.3e" % (iteration, objective, violation), flush=True)


def _run(call, results, progress):
    """Runs `call(results_bytes, callback, handle_ref)` with the progress adapter; the
    result object, or the exception of the callback (re-raised after the C call)."""
    if progress is True:
        progress = _print_progress
    elif progress is not None and progress is not False and not callable(progress):
        raise TypeError("progress is None, True or a callable (iteration, objective, "
                        "constraint_violation), not %s" % type(progress).__name__)
    raised = []

    def adapter(iteration, objective, violation, _user_data):
        try:
            return 1 if progress(iteration, objective, violation) is True else 0
        except BaseException as e:  # stop Ipopt, abandon the results file, re-raise below
            raised.append(e)
            return -1

    callback = _PROGRESS(adapter) if progress else _PROGRESS()
    path = None if results is None else os.fsencode(results)
    handle = ctypes.c_void_p()
    status = call(path, callback, ctypes.byref(handle))
    try:
        if raised:
            raise raised[0]
        check(status)
        summary = json.loads(_report_text(handle, True))
        return OptimizationResult(summary, _report_text(handle, False), _history(handle),
                                  None if results is None else os.fspath(results))
    finally:
        if handle:
            lib.mbdae_optimization_free(handle)


def optimize(problem, results=None, progress=None):
    """Solves the problem file `problem` (a path) as ``mbdae optimize`` does.

    The problem file (docs/sensitivities.md) names the model (relative to the problem
    file), the variables (parameters and spline ordinates, with bounds and optional
    ``start:``), fixed ``parameters:``, the objective to minimise and the constraints
    (objectives of the model with bounds), simulation overrides, Ipopt options and the
    gradient method.

    ``results``: None (no file) or the path of the results file (the run at the final
    point plus ``/optimization``), written as ``mbdae optimize -o`` writes it: into
    ``RESULTS.PID.tmp`` beside it and renamed over it at the end, so that an earlier file
    stays whole until then and after a call that fails; the problem file and its model
    file are refused (:class:`mbdae.FileError`). ``progress``: None; True (a line per
    iteration on stdout); or a callable ``progress(iteration, objective,
    constraint_violation)`` called after every Ipopt iteration (iteration 0: the
    starting point) -- returning True stops the optimisation (the result is then
    "failed" with ipopt_status "User_Requested_Stop", its final run written as usual),
    and an exception it raises (also KeyboardInterrupt) stops it, abandons the results
    file (an earlier file stays) and is raised again here.

    Returns an :class:`OptimizationResult`, also when Ipopt did not converge (check
    ``result.solved``). Raises :class:`mbdae.InputError` for a mistake in the problem
    file (the message names the file, line and column) or its model,
    :class:`mbdae.FileError` for a problem file that cannot be read or a results path that
    cannot be written (the system's reason) or is an input file.
    """
    if not isinstance(problem, (str, bytes, os.PathLike)):
        raise TypeError("problem is the path of a problem file, not %s" % type(problem).__name__)
    path = os.fsencode(problem)
    return _run(lambda res, cb, h: lib.mbdae_optimize(path, res, cb, None, h), results, progress)


def optimize_string(text, name="", results=None, progress=None):
    """:func:`optimize` with the problem as YAML text: `name` is used in messages and the
    problem's ``model:`` is resolved against its folder ("" = the working folder)."""
    if not isinstance(text, str):
        raise TypeError("text is the problem as a str, not %s" % type(text).__name__)
    encoded = text.encode()
    name = os.fsencode(name) if name else b""
    return _run(lambda res, cb, h: lib.mbdae_optimize_string(encoded, name, res, cb, None, h),
                results, progress)
