"""Parameter studies and Monte Carlo runs of one model on Dask (docs/sweeps.md).

:func:`sweep` runs a model once per point of a grid (the product of values) or of a
list of samples, each run a task on a Dask worker, and returns the requested outputs
as a pandas DataFrame, one row per run. :func:`main` is ``mbdae sweep STUDY.yaml``: the
study file (:func:`load_study`), the HDF5 results file (:func:`read_sweep`) written as
runs finish, resumption, a progress bar.

What a worker does (:func:`_run`): it loads the model once per (file, content, swept
names, options) and keeps it (a small cache per worker thread), then for each run sets
the swept parameters and spline ordinates, solves and/or computes the objectives and
their gradients, and returns plain numbers. A run that fails returns its message; it
never raises, so one bad run does not stop the study.
"""

import collections
import contextlib
import difflib
import hashlib
import itertools
import math
import os
import re
import signal
import sys
import threading
import time

import numpy as np

__all__ = ["sweep", "read_sweep", "load_study", "Study", "StudyError", "OUTPUT_KINDS",
           "main"]

#: The forms of an output request (``outputs=``), NAME optional where bracketed:
#: ``objectives`` (every objective), ``objective:G``, ``final[:NAME]``, ``min[:NAME]``,
#: ``max[:NAME]``, ``series[:NAME]`` (NAME a measure or a coordinate, or ``time`` for
#: series; without NAME every measure), ``gradient[:G]`` (dG/dp for each wrt; without
#: G every objective).
OUTPUT_KINDS = ("objectives", "objective", "final", "min", "max", "series", "gradient")

#: The states of a run in the results: not run yet, done, failed (with a message).
STATUSES = ("pending", "done", "failed")

#: A model text up to this size travels with each task, so that a worker without the
#: file (another machine) can load it; a bigger model is read from its path on the worker.
SHIP_MODEL_BYTES = 256 * 1024

#: The number of models a worker thread keeps loaded (least recently used dropped).
CACHE_SIZE = 4

_ORDINATE = re.compile(r"^(.+)\[(\d+)\]$")


class StudyError(ValueError):
    """A mistake in a study (the file's name, line and column in the message when it comes
    from a study file). ``mbdae sweep`` exits 2 with it."""


def _file_sha256(path):
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


# ---- the run, on a worker ------------------------------------------------------------------

class _Spec:
    """What every run of a study shares, sent with each task: the model (path, content
    hash and, if small, its text), the simulation options, the swept names, the output
    requests (expanded, as (kind, name) pairs), the gradient settings."""

    __slots__ = ("path", "sha256", "text", "options", "names", "outputs", "wrt", "method",
                 "objective_wrt")

    def __init__(self, path, sha256, text, options, names, outputs, wrt, method,
                 objective_wrt):
        self.path = path
        self.sha256 = sha256
        self.text = text
        self.options = tuple(options)
        self.names = tuple(names)
        self.outputs = tuple(outputs)
        self.wrt = None if wrt is None else tuple(wrt)
        self.method = method
        self.objective_wrt = objective_wrt

    def __getstate__(self):
        return {k: getattr(self, k) for k in self.__slots__}

    def __setstate__(self, state):
        for k, v in state.items():
            setattr(self, k, v)

    def cache_key(self):
        return (self.path, self.sha256, self.names, self.options)


_local = threading.local()
_stats_lock = threading.Lock()
_stats = {"loads": 0, "runs": 0}


def _worker_stats():
    """Models loaded and runs done by this process (the tests ask the workers)."""
    with _stats_lock:
        return dict(_stats)


def _load_model(spec):
    """The model of `spec`: from its file when the file there has the same content, else
    from the shipped text (relative references resolved against the file's folder)."""
    from .model import Model

    if os.path.isfile(spec.path) and _file_sha256(spec.path) == spec.sha256:
        model = Model(spec.path)
    elif spec.text is not None:
        model = Model.from_string(spec.text, spec.path)
    elif os.path.isfile(spec.path):
        raise RuntimeError("the model file %s on this worker differs from the one the study "
                           "was started with (sha256 %s)" % (spec.path, spec.sha256[:12]))
    else:
        raise RuntimeError("the model file %s is not on this worker (a model over %d bytes "
                           "is not shipped: put it at the same path on every worker)"
                           % (spec.path, SHIP_MODEL_BYTES))
    try:
        for key, value in spec.options:
            model.options[key] = value
    except Exception:
        model.close()
        raise
    with _stats_lock:
        _stats["loads"] += 1
    return model


def _cached_model(spec):
    cache = getattr(_local, "models", None)
    if cache is None:
        cache = _local.models = collections.OrderedDict()
    key = spec.cache_key()
    model = cache.get(key)
    if model is not None and not model.closed:
        cache.move_to_end(key)
        return model
    model = _load_model(spec)
    cache[key] = model
    while len(cache) > CACHE_SIZE:
        _, old = cache.popitem(last=False)
        old.close()
    return model


def _apply(model, names, values):
    """Sets the swept parameters and spline ordinates ("u[3]") to `values`."""
    params = set(model.parameters.names())
    ordinates = {}
    for name, value in zip(names, values):
        if name in params:
            model.parameters[name] = float(value)
            continue
        m = _ORDINATE.match(name)
        spline, point = m.group(1), int(m.group(2))
        if spline not in ordinates:
            x, y = model.splines[spline]
            ordinates[spline] = (x, y.copy())
        ordinates[spline][1][point] = float(value)
    for spline, points in ordinates.items():
        model.splines[spline] = points


def _history(model, name):
    """The stored history of a measure, a coordinate or the time."""
    if name == "time":
        return model.outputs.time
    if name in model.measures:
        return model.outputs.measure(name)
    return model.outputs.q[:, model.coordinates.index(name)]


def _run_batch(spec, values):
    """Runs one after another in one task: a list of :func:`_run` results."""
    return [_run(spec, v) for v in values]


def _run(spec, values):
    """One run: returns {"outputs": {column: value}, "status", "message", "wall_time",
    "worker"}. Never raises for a failure of the run itself."""
    from .errors import InputError

    start = time.perf_counter()
    outputs = {}
    status, message = "done", ""
    try:
        model = _cached_model(spec)
        _apply(model, spec.names, values)
        if any(kind in ("final", "min", "max", "series") for kind, _ in spec.outputs):
            model.assemble()  # from t = 0 even when nothing changed since the last run
            model.solve()
            for kind, name in spec.outputs:
                if kind in ("final", "min", "max", "series"):
                    h = _history(model, name)
                    if kind == "series":
                        outputs["series:" + name] = np.array(h, dtype=np.float64)
                    elif kind == "final":
                        outputs["final:" + name] = float(h[-1])
                    elif kind == "min":
                        outputs["min:" + name] = float(np.min(h))
                    else:
                        outputs["max:" + name] = float(np.max(h))
        objectives = [n for k, n in spec.outputs if k == "objective"]
        gradients = [n for k, n in spec.outputs if k == "gradient"]
        if gradients:
            wanted = sorted(set(objectives) | set(gradients))
            g = model.gradient(objectives=wanted, wrt=list(spec.wrt), method=spec.method)
            for name in objectives:
                outputs["objective:" + name] = g.values[name]
            for name in gradients:
                row = g[name]
                for w in spec.wrt:
                    outputs["gradient:%s:%s" % (name, w)] = row[w]
        elif objectives:
            # Values only: the cheapest exact gradient there is (forward, one column).
            try:
                g = model.gradient(objectives=objectives, wrt=[spec.objective_wrt],
                                   method="forward")
            except InputError:  # no exact derivative for that name: differences then
                g = model.gradient(objectives=objectives, wrt=[spec.objective_wrt],
                                   method="fd")
            for name in objectives:
                outputs["objective:" + name] = g.values[name]
    except Exception as e:  # a failed run is a result, not an error of the study
        from .errors import Error

        status = "failed"
        message = str(e) if isinstance(e, Error) else "%s: %s" % (type(e).__name__, e)
        outputs = {}
    with _stats_lock:
        _stats["runs"] += 1
    return {"outputs": outputs, "status": status, "message": message,
            "wall_time": time.perf_counter() - start,
            "worker": "%s:%d" % (os.uname().nodename, os.getpid())}


# ---- the plan: runs, columns, checks against the model --------------------------------------

def _as_value(name, value, where=""):
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise StudyError("%sparameter '%s': %r is not a number" % (where, name, value))
    return v


def _samples_from(parameters):
    """(names, values as an (n_runs, n_names) array) from a grid dict, a list of dicts or a
    pandas DataFrame."""
    try:
        import pandas as pd
    except ImportError:  # pragma: no cover - pandas is a dependency of sweep
        pd = None
    if pd is not None and isinstance(parameters, pd.DataFrame):
        names = [str(c) for c in parameters.columns]
        values = parameters.to_numpy(dtype=np.float64)
        return names, values.reshape(len(parameters), len(names))
    if isinstance(parameters, dict):
        names = [str(k) for k in parameters]
        axes = []
        for k in parameters:
            v = parameters[k]
            if isinstance(v, (str, bytes)):
                raise StudyError("parameter '%s': %r is not a number or a list of numbers"
                                 % (k, v))
            if np.ndim(v) == 0:
                axes.append([_as_value(k, v)])
            else:
                axis = [_as_value(k, x) for x in np.asarray(v).ravel()]
                if not axis:
                    raise StudyError("parameter '%s': no values" % k)
                axes.append(axis)
        values = np.array(list(itertools.product(*axes)), dtype=np.float64)
        return names, values.reshape(-1, len(names))
    rows = list(parameters)
    if not rows:
        raise StudyError("parameters: no samples")
    names = None
    values = []
    for i, row in enumerate(rows):
        if not isinstance(row, dict):
            raise StudyError("sample %d: a sample is a dict name -> value, not %s"
                             % (i, type(row).__name__))
        if names is None:
            names = [str(k) for k in row]
        elif set(row) != set(names):
            raise StudyError("sample %d sets %s; sample 0 sets %s (every sample sets the same "
                             "names)" % (i, ", ".join(sorted(row)) or "nothing",
                                         ", ".join(sorted(names)) or "nothing"))
        values.append([_as_value(k, row[k], "sample %d: " % i) for k in names])
    return names, np.array(values, dtype=np.float64).reshape(len(rows), len(names))


def _expand_outputs(model, requests, names, wrt):
    """The output requests as (kind, name) pairs in column order, checked against the
    model; `requests` holds strings. Raises StudyError naming a bad request, with
    `where(i)` as its prefix when given as (request, where) pairs."""
    measures = model.measures
    coordinates = model.coordinates
    objectives = model.objectives
    out = []
    for request in requests:
        where = ""
        if isinstance(request, tuple):
            request, where = request
        if not isinstance(request, str):
            raise StudyError("%soutputs: %r is not a text such as 'objectives' or 'final:x'"
                             % (where, request))
        kind, _, name = request.partition(":")
        kind, name = kind.strip(), name.strip()
        if kind not in OUTPUT_KINDS:
            close = difflib.get_close_matches(kind, OUTPUT_KINDS, 1)
            raise StudyError("%soutputs: unknown output '%s'%s (there are: objectives, "
                             "objective:NAME, final[:NAME], min[:NAME], max[:NAME], "
                             "series[:NAME], gradient[:NAME])"
                             % (where, request,
                                "; did you mean '%s'?" % close[0] if close else ""))
        if kind == "objectives":
            if name:
                raise StudyError("%soutputs: 'objectives' takes no name (objective:%s is one "
                                 "objective)" % (where, name))
            if not objectives:
                raise StudyError("%soutputs: 'objectives': the model has no objectives"
                                 % where)
            out += [("objective", o) for o in objectives]
        elif kind in ("objective", "gradient"):
            if not name:
                if kind == "objective":
                    raise StudyError("%soutputs: 'objective' needs a name: objective:NAME "
                                     "(the model's: %s)" % (where, ", ".join(objectives)
                                                           or "none"))
                if not objectives:
                    raise StudyError("%soutputs: 'gradient': the model has no objectives"
                                     % where)
                out += [("gradient", o) for o in objectives]
            elif name not in objectives:
                raise StudyError("%soutputs: '%s': the model has no objective '%s' (it has: %s)"
                                 % (where, request, name, ", ".join(objectives) or "none"))
            else:
                out.append((kind, name))
        else:
            if not name:
                out += [(kind, m) for m in measures]
                continue
            known = measures + coordinates + (["time"] if kind == "series" else [])
            if name not in known:
                close = difflib.get_close_matches(name, known, 1)
                raise StudyError("%soutputs: '%s': no measure or coordinate '%s'%s (measures: "
                                 "%s)" % (where, request, name,
                                          "; did you mean '%s'?" % close[0] if close else "",
                                          ", ".join(measures) or "none"))
            out.append((kind, name))
    # A gradient comes with the objective's value: its column goes first.
    with_values = []
    for kind, name in out:
        if kind == "gradient" and ("objective", name) not in out:
            with_values.append(("objective", name))
        with_values.append((kind, name))
    seen = set()
    unique = []
    for pair in with_values:
        if pair not in seen:
            seen.add(pair)
            unique.append(pair)
    return unique


def _check_names(model, names, what="parameters"):
    """Every swept name is a parameter or a spline ordinate "SPLINE[i]" in range."""
    params = model.parameters.names()
    splines = model.splines.names()
    for name in names:
        if name in params:
            continue
        m = _ORDINATE.match(name)
        if m and m.group(1) in splines:
            n = len(model.splines[m.group(1)][0])
            if int(m.group(2)) < n:
                continue
            raise StudyError("%s: '%s': spline '%s' has %d points (0 .. %d)"
                             % (what, name, m.group(1), n, n - 1))
        close = difflib.get_close_matches(name, params, 1)
        raise StudyError("%s: '%s' is neither a parameter%s nor a spline ordinate SPLINE[i] "
                         "(parameters: %s; splines: %s)"
                         % (what, name, " (did you mean '%s'?)" % close[0] if close else "",
                            ", ".join(params) or "none", ", ".join(splines) or "none"))


class _Plan:
    """A study made concrete: the model's spec, the swept names and the values of every
    run, the output columns."""

    def __init__(self, model_path, names, values, outputs, options=None, wrt=None,
                 method="adjoint", output_where=None):
        from .model import Model
        from .gradient import METHODS

        self.model_path = os.path.abspath(os.fspath(model_path))
        if not os.path.isfile(self.model_path):
            raise StudyError("%s: cannot open the model file" % model_path)
        with open(self.model_path, "rb") as f:
            data = f.read()
        sha = hashlib.sha256(data).hexdigest()
        text = None
        if len(data) <= SHIP_MODEL_BYTES:
            try:
                text = data.decode("utf-8")
            except UnicodeDecodeError:
                text = None
        self.names = list(names)
        if len(set(self.names)) != len(self.names):
            dup = [n for n in self.names if self.names.count(n) > 1][0]
            raise StudyError("parameters: '%s' is given twice" % dup)
        self.values = np.asarray(values, dtype=np.float64).reshape(-1, len(self.names))
        if len(self.values) == 0:
            raise StudyError("the study has no runs")
        if not isinstance(method, str) or method not in METHODS:
            raise StudyError("method: '%s' is not one of %s" % (method, ", ".join(METHODS)))
        options = dict(options or {})
        with Model(self.model_path) as m:
            for key, value in options.items():
                try:
                    m.options[key] = value
                except Exception as e:
                    raise StudyError("options: %s: %s" % (key, e))
            _check_names(m, self.names)
            if isinstance(outputs, str):
                outputs = [outputs]
            requests = list(outputs)
            if output_where:
                requests = list(zip(requests, output_where))
            self.outputs = _expand_outputs(m, requests, self.names, wrt)
            if wrt is None:
                wrt = list(self.names) if self.names else m.parameters.names()
            else:
                wrt = [wrt] if isinstance(wrt, str) else list(wrt)
                _check_names(m, wrt, "wrt")
            if any(k == "gradient" for k, _ in self.outputs) and not wrt:
                raise StudyError("gradient outputs need wrt names (the model has no "
                                 "parameters)")
            # Objective values alone come from a forward gradient with one column.
            objective_wrt = (self.names[0] if self.names else
                             (m.parameters.names() or [None])[0])
            if objective_wrt is None and m.splines.names():
                objective_wrt = m.splines.names()[0] + "[0]"
        self.wrt = list(wrt)
        self.method = method
        self.options = options
        self.spec = _Spec(self.model_path, sha, text, sorted(options.items()), self.names,
                          self.outputs, self.wrt, method, objective_wrt)
        self.columns = []
        for kind, name in self.outputs:
            if kind == "gradient":
                self.columns += ["gradient:%s:%s" % (name, w) for w in self.wrt]
            else:
                self.columns.append("%s:%s" % (kind, name))

    @property
    def runs(self):
        return len(self.values)


# ---- running the tasks ----------------------------------------------------------------------

def _cpu_count():
    try:
        return len(os.sched_getaffinity(0))
    except (AttributeError, OSError):
        return os.cpu_count() or 1


def _import_distributed():
    try:
        import distributed  # noqa: F401
    except ImportError as e:
        raise ImportError("mbdae sweep needs dask and distributed (Debian: apt-get install "
                          "python3-dask python3-distributed): %s" % e)
    return distributed


@contextlib.contextmanager
def _connect(client, workers=None):
    """A dask.distributed Client: the one given, one connected to an address, or one of
    a LocalCluster started here (and closed at the end)."""
    distributed = _import_distributed()
    if client is None:
        # Spawned worker processes import mbdae: make sure they find this package.
        here = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
        path = os.environ.get("PYTHONPATH", "")
        if here not in path.split(os.pathsep):
            os.environ["PYTHONPATH"] = here + (os.pathsep + path if path else "")
        n = workers or _cpu_count()
        cluster = distributed.LocalCluster(n_workers=n, threads_per_worker=1, processes=True,
                                           dashboard_address=None)
        try:
            with distributed.Client(cluster) as c:
                yield c
        finally:
            cluster.close()
    elif isinstance(client, str):
        with distributed.Client(client) as c:
            yield c
    else:
        yield client


def _execute(plan, indices, client, retries=1, workers=None, batch=1):
    """Runs `indices` of `plan` and yields (index, result) as runs finish. client:
    None (a LocalCluster of `workers` processes, default one per core), "serial" (here,
    one after another), an address or a dask.distributed.Client. batch: runs per task."""
    indices = list(indices)
    if client == "serial":
        for i in indices:
            yield i, _run(plan.spec, plan.values[i])
        return
    with _connect(client, workers) as c:
        from distributed import as_completed

        token = hashlib.sha256(("%s %f %d" % (plan.spec.sha256, time.time(), os.getpid()))
                               .encode()).hexdigest()[:10]
        batch = max(1, int(batch))
        chunks = [indices[k:k + batch] for k in range(0, len(indices), batch)]
        keys = ["mbdae-runs-%s-%d" % (token, chunk[0]) for chunk in chunks]
        futures = c.map(_run_batch, [plan.spec] * len(chunks),
                        [plan.values[chunk] for chunk in chunks], key=keys, retries=retries,
                        pure=False)
        index = {f.key: chunk for f, chunk in zip(futures, chunks)}
        finished = as_completed(futures)
        del futures  # as_completed holds them until they are handed out
        for future in finished:
            chunk = index.pop(future.key)
            try:
                results = future.result()
            except Exception as e:  # the task itself failed: its workers died too often
                results = [{"outputs": {}, "status": "failed",
                            "message": "%s: %s" % (type(e).__name__, e),
                            "wall_time": math.nan, "worker": ""}] * len(chunk)
            future.release()  # nothing to recompute if its worker dies later
            del future
            for i, result in zip(chunk, results):
                yield i, result


def _new_table(plan):
    """The result columns of a study, all runs pending."""
    n = plan.runs
    table = {"outputs": {}, "status": np.array(["pending"] * n, dtype=object),
             "message": np.array([""] * n, dtype=object),
             "wall_time": np.full(n, math.nan), "worker": np.array([""] * n, dtype=object)}
    for c in plan.columns:
        table["outputs"][c] = (np.empty(n, dtype=object) if c.startswith("series:")
                               else np.full(n, math.nan))
    return table


def _store(plan, table, i, result):
    table["status"][i] = result["status"]
    table["message"][i] = result["message"]
    table["wall_time"][i] = result["wall_time"]
    table["worker"][i] = result["worker"]
    for c in plan.columns:
        v = result["outputs"].get(c)
        if c.startswith("series:"):
            table["outputs"][c][i] = v
        else:
            table["outputs"][c][i] = math.nan if v is None else v


def _frame(plan, table):
    import pandas as pd

    data = collections.OrderedDict()
    for k, name in enumerate(plan.names):
        data[name] = plan.values[:, k]
    for c in plan.columns:
        data[c] = table["outputs"][c]
    data["status"] = table["status"]
    data["message"] = table["message"]
    data["wall_time"] = table["wall_time"]
    data["worker"] = table["worker"]
    frame = pd.DataFrame(data)
    frame.index.name = "run"
    return frame


class _Progress:
    """A bar on a terminal, a line per tenth of the runs otherwise, or nothing."""

    def __init__(self, total, stream=None, mode="auto"):
        self.stream = stream or sys.stderr
        if mode == "auto":
            mode = "bar" if self.stream.isatty() else "lines"
        self.mode = mode
        self.total = total
        self.start = time.monotonic()
        self.last = 0.0
        self.next_tenth = 1
        self.drawn = False

    def update(self, done, failed):
        if not self.mode or self.total <= 0:
            return
        fraction = min(1.0, done / self.total)
        elapsed = time.monotonic() - self.start
        if self.mode == "lines":
            if fraction + 1e-12 >= self.next_tenth / 10:
                while self.next_tenth <= 10 and fraction + 1e-12 >= self.next_tenth / 10:
                    self.next_tenth += 1
                self.stream.write("mbdae: sweep: %d of %d runs (%3.0f %%), %d failed, %.1f s\n"
                                  % (done, self.total, 100 * fraction, failed, elapsed))
                self.stream.flush()
            return
        now = time.monotonic()
        if self.drawn and fraction < 1 and now - self.last < 0.1:
            return
        self.last, self.drawn = now, True
        width = 30
        filled = int(fraction * width)
        bar = "=" * filled + (">" if filled < width else "") + " " * (width - filled - 1)
        self.stream.write("\r[%s] %3.0f %%  %d of %d runs, %d failed, %.1f s "
                          % (bar[:width], 100 * fraction, done, self.total, failed, elapsed))
        self.stream.flush()

    def finish(self):
        if self.mode == "bar" and self.drawn:
            self.stream.write("\n")
            self.stream.flush()
        self.drawn = False


def sweep(model, parameters=None, outputs=("objectives",), client=None, *, options=None,
          wrt=None, method="adjoint", retries=1, workers=None, batch=1, progress=False,
          on_result=None):
    """Runs `model` once per point of `parameters` on Dask and returns a pandas DataFrame,
    one row per run (index ``run``).

    model: the model file's path. parameters: a dict name -> values (a grid: every
    combination, the last name varying fastest; a single number is the same in every run),
    a list of dicts name -> value (samples, each setting the same names) or a DataFrame
    (one sample per row). Names are parameters ("k") or spline ordinates ("u[3]").
    None: a single run with the model as it is.

    outputs: a list of requests, each a column (or several) of the result:
    ``"objectives"`` (every objective, columns ``objective:G``), ``"objective:G"``,
    ``"final:NAME"``, ``"min:NAME"``, ``"max:NAME"`` (a measure or a coordinate:
    ``final:xs``), ``"series:NAME"`` (its whole history as a numpy array; ``series:time``
    the output times), ``final``/``min``/``max``/``series`` alone for every measure,
    ``"gradient:G"`` (dG/dp for each wrt: columns ``gradient:G:k``; ``"gradient"`` for
    every objective). wrt: what gradients are taken with respect to (default: the swept
    names); method: "adjoint", "forward" or "fd".

    client: None starts a LocalCluster of `workers` processes (default one per core, one
    thread each) and closes it at the end; an address ("tcp://host:8786") or a
    ``dask.distributed.Client`` uses that cluster; "serial" runs here, one after another.
    options: simulation settings for every run (the keys of :data:`mbdae.OPTIONS`).
    retries: re-submissions of a task that raised outside the run (a run's own failure is a
    result, not retried). batch: runs per task (one after another on the worker; more
    than 1 spreads Dask's cost per task over several short runs, results then come back
    a batch at a time). progress: True for a bar (a terminal) or lines on stderr.
    on_result: called as ``on_result(run, row)`` in this process as each run finishes
    (row: dict with the outputs, status, message, wall_time, worker).

    Columns: the swept names, the output columns, ``status`` ("done" or "failed"),
    ``message`` (why a run failed), ``wall_time`` (seconds on the worker), ``worker``.
    """
    if parameters is None:
        names, values = [], np.zeros((1, 0))
    else:
        names, values = _samples_from(parameters)
    plan = _Plan(model, names, values, outputs, options, wrt, method)
    table = _new_table(plan)
    bar = _Progress(plan.runs, mode="auto" if progress else None)
    done = failed = 0
    try:
        for i, result in _execute(plan, range(plan.runs), client, retries, workers, batch):
            _store(plan, table, i, result)
            done += 1
            failed += result["status"] != "done"
            bar.update(done, failed)
            if on_result is not None:
                row = dict(result["outputs"])
                row.update({k: result[k] for k in ("status", "message", "wall_time",
                                                   "worker")})
                on_result(i, row)
    finally:
        bar.finish()
    return _frame(plan, table)


# ---- the study file -------------------------------------------------------------------------

STUDY_KEYS = ("format", "model", "options", "parameters", "samples", "seed", "outputs", "wrt",
              "method", "retries")
DISTRIBUTIONS = {"normal": ("mean", "std"), "uniform": ("low", "high"),
                 "lognormal": ("mu", "sigma")}


class Study:
    """A study file made concrete: the model path, the swept names and the values of every
    run, the output requests, options, wrt, method, retries, and the file's text."""

    def __init__(self, path, text, model, names, values, outputs, output_where, options, wrt,
                 method, retries):
        self.path = path
        self.text = text
        self.model = model
        self.names = names
        self.values = values
        self.outputs = outputs
        self.output_where = output_where
        self.options = options
        self.wrt = wrt
        self.method = method
        self.retries = retries

    def plan(self):
        return _Plan(self.model, self.names, self.values, self.outputs, self.options,
                     self.wrt, self.method, self.output_where)


class _Reader:
    """The study file's YAML nodes with their positions for messages."""

    def __init__(self, path, text):
        import yaml

        self.path = path
        self.yaml = yaml
        self.constructor = yaml.SafeLoader("")

    def where(self, node):
        m = node.start_mark
        return "%s:%d:%d: " % (self.path, m.line + 1, m.column + 1)

    def fail(self, node, message):
        raise StudyError(self.where(node) + message)

    def value(self, node):
        return self.constructor.construct_object(node, deep=True)

    def mapping(self, node, what):
        if not isinstance(node, self.yaml.MappingNode):
            self.fail(node, "%s: expected a mapping (key: value lines)" % what)
        out = collections.OrderedDict()
        for k, v in node.value:
            key = self.value(k)
            if not isinstance(key, str):
                key = str(key)
            if key in out:
                self.fail(k, "%s: '%s' is given twice" % (what, key))
            out[key] = (k, v)
        return out

    def number(self, node, what, integer=False, positive=False):
        if not isinstance(node, self.yaml.ScalarNode):
            self.fail(node, "%s: expected a number" % what)
        v = self.value(node)
        if isinstance(v, bool) or not isinstance(v, (int, float)):
            self.fail(node, "%s: expected a number, got '%s'" % (what, node.value))
        if integer and (not float(v).is_integer()):
            self.fail(node, "%s: expected a whole number, got %s" % (what, node.value))
        if positive and not v > 0:
            self.fail(node, "%s: must be > 0, got %s" % (what, node.value))
        return int(v) if integer else float(v)

    def text(self, node, what):
        if not isinstance(node, self.yaml.ScalarNode) or not isinstance(self.value(node), str):
            self.fail(node, "%s: expected a text" % what)
        return self.value(node)

    def sequence(self, node, what):
        if not isinstance(node, self.yaml.SequenceNode):
            self.fail(node, "%s: expected a list" % what)
        return node.value

    def unknown(self, key_node, key, known, what):
        close = difflib.get_close_matches(key, known, 1)
        self.fail(key_node, "%s: unknown key '%s'%s (the keys are: %s)"
                  % (what, key, "; did you mean '%s'?" % close[0] if close else "",
                     ", ".join(known)))


def load_study(path):
    """Reads and checks a study file (docs/sweeps.md); raises StudyError with
    file:line:column for any mistake (the model's names checked too)."""
    import yaml

    try:
        with open(path, encoding="utf-8") as f:
            text = f.read()
    except OSError as e:
        raise StudyError("%s: cannot open the study file: %s" % (path, e.strerror or e))
    except UnicodeDecodeError as e:
        raise StudyError("%s: not a UTF-8 text file: %s" % (path, e))
    r = _Reader(path, text)
    try:
        root = yaml.compose(text, Loader=yaml.SafeLoader)
    except yaml.YAMLError as e:
        mark = getattr(e, "problem_mark", None) or getattr(e, "context_mark", None)
        problem = getattr(e, "problem", None) or str(e)
        if mark is not None:
            raise StudyError("%s:%d:%d: YAML: %s" % (path, mark.line + 1, mark.column + 1,
                                                      problem))
        raise StudyError("%s: YAML: %s" % (path, problem))
    if root is None:
        raise StudyError("%s:1:1: study: the file is empty (it needs model:, parameters: and "
                         "outputs:)" % path)
    top = r.mapping(root, "study")
    for key, (k, _) in top.items():
        if key not in STUDY_KEYS:
            r.unknown(k, key, STUDY_KEYS, "study")
    for key in ("model", "parameters", "outputs"):
        if key not in top:
            raise StudyError("%s:%d:1: study: '%s:' is missing (a study needs model:, "
                             "parameters: and outputs:)" % (path, root.start_mark.line + 1,
                                                            key))
    if "format" in top:
        k, v = top["format"]
        if r.number(v, "format", integer=True) != 1:
            r.fail(v, "format: this program reads study files of format 1, not %s" % v.value)
    # model, relative to the study file
    k, v = top["model"]
    model = r.text(v, "model")
    model_path = model if os.path.isabs(model) else os.path.join(
        os.path.dirname(os.path.abspath(path)), model)
    if not os.path.isfile(model_path):
        r.fail(v, "model: cannot open '%s' (looked for %s)" % (model, model_path))
    model_where = r.where(v)
    # options
    options = collections.OrderedDict()
    if "options" in top:
        from .model import OPTIONS

        for key, (kn, vn) in r.mapping(top["options"][1], "options").items():
            if key not in OPTIONS:
                r.unknown(kn, key, OPTIONS, "options")
            value = r.value(vn)
            if not isinstance(value, (int, float, str, bool)):
                r.fail(vn, "options: %s: expected a number, true/false or a text" % key)
            options[key] = value
    # samples and seed
    samples = seed = None
    if "samples" in top:
        samples_node = top["samples"][1]
        samples = r.number(samples_node, "samples", integer=True, positive=True)
    if "seed" in top:
        seed_node = top["seed"][1]
        seed = r.number(seed_node, "seed", integer=True)
        if seed < 0:
            r.fail(seed_node, "seed: must be >= 0, got %d" % seed)
    # parameters: grid axes, constants, distributions
    params = r.mapping(top["parameters"][1], "parameters")
    names, axes, draws = [], [], []
    for name, (kn, vn) in params.items():
        what = "parameters: %s" % name
        names.append(name)
        if isinstance(vn, yaml.SequenceNode):
            items = r.sequence(vn, what)
            if not items:
                r.fail(vn, "%s: the list of values is empty" % what)
            axes.append((len(names) - 1, [r.number(x, what) for x in items]))
        elif isinstance(vn, yaml.ScalarNode):
            axes.append((len(names) - 1, [r.number(vn, what)]))
        else:
            spec = r.mapping(vn, what)
            if "values" in spec:
                for key, (kk, _) in spec.items():
                    if key != "values":
                        r.fail(kk, "%s: 'values' goes alone (not with '%s')" % (what, key))
                items = r.sequence(spec["values"][1], what + ": values")
                if not items:
                    r.fail(spec["values"][1], "%s: values: the list is empty" % what)
                axes.append((len(names) - 1, [r.number(x, what + ": values") for x in items]))
            elif "linspace" in spec:
                for key, (kk, _) in spec.items():
                    if key != "linspace":
                        r.fail(kk, "%s: 'linspace' goes alone (not with '%s')" % (what, key))
                ln = spec["linspace"][1]
                items = r.sequence(ln, what + ": linspace")
                if len(items) != 3:
                    r.fail(ln, "%s: linspace: expected [start, stop, count]" % what)
                a = r.number(items[0], what + ": linspace start")
                b = r.number(items[1], what + ": linspace stop")
                n = r.number(items[2], what + ": linspace count", integer=True, positive=True)
                axes.append((len(names) - 1, list(np.linspace(a, b, n))))
            elif "distribution" in spec:
                dn = spec["distribution"][1]
                kind = r.text(dn, what + ": distribution")
                if kind not in DISTRIBUTIONS:
                    close = difflib.get_close_matches(kind, DISTRIBUTIONS, 1)
                    r.fail(dn, "%s: distribution: unknown '%s'%s (there are: %s)"
                           % (what, kind, "; did you mean '%s'?" % close[0] if close else "",
                              ", ".join(DISTRIBUTIONS)))
                keys = DISTRIBUTIONS[kind]
                args = {}
                for key, (kk, vv) in spec.items():
                    if key == "distribution":
                        continue
                    if key not in keys:
                        r.unknown(kk, key, ("distribution",) + keys, what + " (%s)" % kind)
                    args[key] = r.number(vv, "%s: %s" % (what, key))
                for key in keys:
                    if key not in args:
                        r.fail(vn, "%s: a %s distribution needs '%s' (%s)"
                               % (what, kind, key, ", ".join(keys)))
                if kind == "normal" and args["std"] < 0:
                    r.fail(spec["std"][1], "%s: std must be >= 0" % what)
                if kind == "lognormal" and args["sigma"] < 0:
                    r.fail(spec["sigma"][1], "%s: sigma must be >= 0" % what)
                if kind == "uniform" and not args["low"] < args["high"]:
                    r.fail(spec["high"][1], "%s: high must be > low" % what)
                draws.append((len(names) - 1, kind, args, kn))
            else:
                close = [k for k in spec]
                r.fail(vn, "%s: expected a number, a list of values, {values: [...]}, "
                       "{linspace: [start, stop, count]} or {distribution: ...} (got the keys "
                       "%s)" % (what, ", ".join(close)))
    if draws and samples is None:
        r.fail(draws[0][3], "parameters: %s has a distribution: the study needs 'samples:' "
               "(the number of draws)" % names[draws[0][0]])
    if draws and seed is None:
        r.fail(draws[0][3], "parameters: %s has a distribution: the study needs 'seed:' (the "
               "random generator's seed, so that a rerun draws the same values)"
               % names[draws[0][0]])
    if samples is not None and not draws:
        r.fail(samples_node, "samples: no parameter has a distribution (samples: is the number "
               "of draws of a Monte Carlo study)")
    # the runs: every grid point (last name fastest), then each sample (fastest)
    grid = list(itertools.product(*[axis for _, axis in axes]))
    n_samples = samples or 1
    values = np.empty((len(grid) * n_samples, len(names)))
    for g, point in enumerate(grid):
        for (k, _), x in zip(axes, point):
            values[g * n_samples:(g + 1) * n_samples, k] = x
    if draws:
        rng = np.random.default_rng(seed)
        for k, kind, args, _ in draws:
            if kind == "normal":
                x = rng.normal(args["mean"], args["std"], samples)
            elif kind == "uniform":
                x = rng.uniform(args["low"], args["high"], samples)
            else:
                x = rng.lognormal(args["mu"], args["sigma"], samples)
            values[:, k] = np.tile(x, len(grid))
    # outputs
    ok, on = top["outputs"]
    if isinstance(on, yaml.ScalarNode):
        items = [on]
    else:
        items = r.sequence(on, "outputs")
    if not items:
        r.fail(on, "outputs: the list is empty")
    outputs = [r.text(x, "outputs") for x in items]
    output_where = [r.where(x) for x in items]
    wrt = None
    if "wrt" in top:
        wn = top["wrt"][1]
        wrt = [r.text(x, "wrt") for x in ([wn] if isinstance(wn, yaml.ScalarNode)
                                           else r.sequence(wn, "wrt"))]
    method = "adjoint"
    if "method" in top:
        mn = top["method"][1]
        method = r.text(mn, "method")
        from .gradient import METHODS

        if method not in METHODS:
            r.fail(mn, "method: '%s' is not one of %s" % (method, ", ".join(METHODS)))
    retries = 1
    if "retries" in top:
        retries = r.number(top["retries"][1], "retries", integer=True)
        if retries < 0:
            r.fail(top["retries"][1], "retries: must be >= 0")
    study = Study(path, text, model_path, names, values, outputs, output_where, options, wrt,
                  method, retries)
    # The model's names: parameters, outputs, wrt, options (each with its line).
    try:
        study.plan_checked = study.plan()
    except StudyError as e:
        message = str(e)
        if not re.match(r"^.+:\d+:\d+: ", message):
            node = None
            if message.startswith("parameters: '"):
                bad = message.split("'")[1]
                node = params.get(bad, (None,))[0]
            elif message.startswith("wrt"):
                node = top["wrt"][1]
            elif message.startswith("options: "):
                bad = message[len("options: "):].split(":")[0]
                node = r.mapping(top["options"][1], "options").get(bad, (None, None))[1]
            if node is not None:
                message = r.where(node) + message
            else:
                message = model_where + "model: " + message
        raise StudyError(message)
    except Exception as e:  # the model itself does not load
        raise StudyError("%smodel: %s" % (model_where, e))
    return study


# ---- the results file -------------------------------------------------------------------

RESULTS_KIND = "mbdae sweep"


def _write_results(path, study, plan, table, final=False):
    """The whole results file, written as PATH.PID.tmp beside it and renamed over PATH:
    a reader (or a kill at any moment) sees the previous file or this one, never half."""
    import h5py
    from . import __version__

    tmp = "%s.%d.tmp" % (path, os.getpid())
    n = plan.runs
    status = table["status"]
    try:
        with h5py.File(tmp, "w") as f:
            f.attrs["format"] = 1
            f.attrs["kind"] = RESULTS_KIND
            f.attrs["mbdae_version"] = __version__
            f.attrs["study"] = study.path
            f.attrs["study_text"] = study.text
            f.attrs["model"] = plan.model_path
            f.attrs["model_sha256"] = plan.spec.sha256
            s = h5py.string_dtype()
            f.attrs.create("parameters", data=list(plan.names), shape=(len(plan.names),),
                           dtype=s)
            f.attrs.create("columns", data=list(plan.columns), shape=(len(plan.columns),),
                           dtype=s)
            f.attrs["runs"] = n
            f.attrs["done"] = int(np.sum(status == "done"))
            f.attrs["failed"] = int(np.sum(status == "failed"))
            f.attrs["pending"] = int(np.sum(status == "pending"))
            f.attrs["complete"] = bool(final and f.attrs["pending"] == 0)
            f.create_dataset("run", data=np.arange(n, dtype=np.int64))
            g = f.create_group("parameters")
            for k, name in enumerate(plan.names):
                g.create_dataset(name, data=plan.values[:, k])
            g = f.create_group("outputs")
            for c in plan.columns:
                col = table["outputs"][c]
                if c.startswith("series:"):
                    width = max([len(x) for x in col if x is not None] or [0])
                    data = np.full((n, width), math.nan)
                    for i, x in enumerate(col):
                        if x is not None:
                            data[i, :len(x)] = x
                    d = g.create_dataset(c, data=data)
                    d.attrs["padding"] = "NaN after a run's last row; all NaN if not done"
                else:
                    g.create_dataset(c, data=col.astype(np.float64))
            f.create_dataset("status", data=np.array(list(status), dtype=object), dtype=s)
            f.create_dataset("message", data=np.array(list(table["message"]), dtype=object),
                             dtype=s)
            f.create_dataset("wall_time", data=table["wall_time"])
            f.create_dataset("worker", data=np.array(list(table["worker"]), dtype=object),
                             dtype=s)
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        raise


def _text(x):
    return x.decode("utf-8", "replace") if isinstance(x, bytes) else str(x)


def read_sweep(path):
    """The results file of ``mbdae sweep`` as a pandas DataFrame laid out as
    :func:`sweep` returns it (series columns hold numpy arrays without the NaN padding;
    None for runs not done). The file's attributes are in ``frame.attrs``."""
    import h5py
    import pandas as pd

    with h5py.File(path, "r") as f:
        if _text(f.attrs.get("kind", "")) != RESULTS_KIND:
            raise StudyError("%s is not a results file of mbdae sweep (no attribute kind = "
                             "'%s')" % (path, RESULTS_KIND))
        names = [_text(x) for x in f.attrs["parameters"]]
        columns = [_text(x) for x in f.attrs["columns"]]
        data = collections.OrderedDict()
        for name in names:
            data[name] = f["parameters"][name][()]
        status = np.array([_text(x) for x in f["status"][()]], dtype=object)
        for c in columns:
            d = f["outputs"][c][()]
            if c.startswith("series:"):
                col = np.empty(len(d), dtype=object)
                for i, row in enumerate(d):
                    if status[i] == "done":
                        keep = np.nonzero(~np.isnan(row))[0]
                        col[i] = row[:keep[-1] + 1] if len(keep) else row[:0]
                data[c] = col
            else:
                data[c] = d
        data["status"] = status
        data["message"] = np.array([_text(x) for x in f["message"][()]], dtype=object)
        data["wall_time"] = f["wall_time"][()]
        data["worker"] = np.array([_text(x) for x in f["worker"][()]], dtype=object)
        attrs = {k: (_text(v) if isinstance(v, (bytes, str)) else v)
                 for k, v in f.attrs.items()}
    frame = pd.DataFrame(data)
    frame.index.name = "run"
    frame.attrs.update(attrs)
    return frame


def _resume(path, study, plan, table):
    """Takes over the runs of an earlier results file of the same study; StudyError when
    the file holds another study."""
    try:
        old = read_sweep(path)
    except StudyError:
        raise StudyError("%s exists and is not a results file of mbdae sweep: remove it or "
                         "give another name with -o" % path)
    except Exception as e:
        raise StudyError("%s exists and cannot be read (%s): remove it or give another name "
                         "with -o" % (path, e))
    a = old.attrs
    why = None
    old_names = [_text(n) for n in a.get("parameters", [])]
    if a.get("model_sha256") != plan.spec.sha256:
        why = "the model file has changed since (sha256 %s, now %s)" % (
            str(a.get("model_sha256"))[:12], plan.spec.sha256[:12])
    elif int(a.get("runs", -1)) != plan.runs:
        why = "it has %s runs, the study %d" % (a.get("runs"), plan.runs)
    elif old_names != plan.names:
        why = "its parameters are %s, the study's %s" % (", ".join(old_names) or "none",
                                                        ", ".join(plan.names) or "none")
    elif [_text(c) for c in a.get("columns", [])] != plan.columns:
        why = "its outputs are %s, the study's %s" % (
            ", ".join(_text(c) for c in a.get("columns", [])), ", ".join(plan.columns))
    else:
        old_values = old[plan.names].to_numpy(dtype=np.float64).reshape(plan.runs, -1)
        differ = np.nonzero(~((old_values == plan.values) |
                              (np.isnan(old_values) & np.isnan(plan.values))).all(axis=1))[0]
        if len(differ):
            why = "the parameter values of run %d differ" % differ[0]
    if why:
        raise StudyError("%s holds the results of another study (%s): remove it or give "
                         "another name with -o" % (path, why))
    for i in range(plan.runs):
        st = old["status"].iat[i]
        if st == "pending":
            continue
        table["status"][i] = st
        table["message"][i] = old["message"].iat[i]
        table["wall_time"][i] = old["wall_time"].iat[i]
        table["worker"][i] = old["worker"].iat[i]
        for c in plan.columns:
            table["outputs"][c][i] = old[c].iat[i]


# ---- mbdae sweep ----------------------------------------------------------------------------

USAGE = ("usage: mbdae sweep STUDY.yaml [-o STUDY.h5] [--scheduler ADDRESS] [--workers N]\n"
         "                   [--retry-failed] [--flush-interval S] [--quiet]\n")

HELP = """
Runs the study (docs/sweeps.md): the model once per grid point or sample, each run a
task on a Dask cluster, the results in one HDF5 file (one row per run: parameter
values, outputs, status, message).
  -o, --output FILE     results file (default: the study's path with .h5)
  --scheduler ADDRESS   a running Dask scheduler (tcp://host:8786); default: a local
                        cluster of one worker process per core
  --workers N           the local cluster's worker processes
  --retry-failed        run the runs that failed in an earlier file again
  --flush-interval S    write the results file at most every S seconds (default 1;
                        always at the end)
  --quiet               no progress, no summary
A rerun with the same results file skips the runs it holds (done or failed). The file
is written as FILE.PID.tmp beside it and renamed, so it is always whole. Progress on
stderr (a bar on a terminal, a line every 10 % otherwise), the summary on stdout.
exit codes: 0 every run done; 2 bad input (nothing run); 3 some run failed (all runs
recorded); 130 / 143 stopped by SIGINT / SIGTERM (the finished runs written); 1 other.
"""


class _Stop(BaseException):
    # Not an Exception: a signal raised while a result is being taken (future.result(),
    # a run in this process) must end the study, not be recorded as that run's failure.
    def __init__(self, signal_number):
        super().__init__(signal_number)
        self.signal_number = signal_number


def _parse(argv):
    args = {"study": None, "output": None, "scheduler": None, "workers": None,
            "retry_failed": False, "quiet": False, "flush_interval": 1.0}
    i = 0

    def value(flag):
        nonlocal i
        if i + 1 >= len(argv):
            raise StudyError("%s needs a value" % flag)
        i += 1
        return argv[i]

    while i < len(argv):
        a = argv[i]
        if a in ("-h", "--help"):
            args["help"] = True
        elif a in ("-o", "--output"):
            args["output"] = value(a)
        elif a == "--scheduler":
            args["scheduler"] = value(a)
        elif a == "--workers":
            v = value(a)
            if not v.isdigit() or int(v) < 1:
                raise StudyError("--workers: expected a whole number >= 1, got '%s'" % v)
            args["workers"] = int(v)
        elif a == "--flush-interval":
            v = value(a)
            try:
                args["flush_interval"] = float(v)
            except ValueError:
                raise StudyError("--flush-interval: expected seconds, got '%s'" % v)
            if not args["flush_interval"] >= 0:
                raise StudyError("--flush-interval: expected seconds >= 0, got '%s'" % v)
        elif a == "--retry-failed":
            args["retry_failed"] = True
        elif a == "--quiet":
            args["quiet"] = True
        elif a.startswith("-") and a != "-":
            raise StudyError("unknown option '%s'" % a)
        elif args["study"] is None:
            args["study"] = a
        else:
            raise StudyError("one study file only ('%s' and '%s')" % (args["study"], a))
        i += 1
    if not args.get("help") and args["study"] is None:
        raise StudyError("no study file")
    return args


def _same_file(a, b):
    try:
        return os.path.samefile(a, b)
    except OSError:
        return os.path.abspath(a) == os.path.abspath(b)


def main(argv=None):
    """``mbdae sweep STUDY.yaml [-o STUDY.h5] [--scheduler ADDRESS] ...``; the exit code."""
    argv = sys.argv[1:] if argv is None else list(argv)
    err = sys.stderr
    try:
        args = _parse(argv)
    except StudyError as e:
        err.write("mbdae: error: sweep: %s\n%s" % (e, USAGE))
        return 2
    if args.get("help"):
        sys.stdout.write(USAGE + HELP)
        return 0
    try:
        import pandas  # noqa: F401
    except ImportError as e:
        err.write("mbdae: error: mbdae sweep needs pandas (Debian: apt-get install "
                  "python3-pandas): %s\n" % e)
        return 1
    try:
        study = load_study(args["study"])
        plan = study.plan_checked
        output = args["output"]
        if output is None:
            output = re.sub(r"\.(ya?ml|json)$", "", args["study"], flags=re.I) + ".h5"
        if _same_file(output, args["study"]) or _same_file(output, plan.model_path):
            raise StudyError("the results file '%s' is the %s file: give another name with -o"
                             % (output, "study" if _same_file(output, args["study"])
                                else "model"))
        folder = os.path.dirname(os.path.abspath(output))
        if not os.path.isdir(folder) or not os.access(folder, os.W_OK):
            raise StudyError("%s: cannot write the results file there (%s)"
                             % (output, "no such folder" if not os.path.isdir(folder)
                                else "permission denied"))
        table = _new_table(plan)
        skipped = 0
        if os.path.exists(output):
            _resume(output, study, plan, table)
            keep = ("done",) if args["retry_failed"] else ("done", "failed")
            for i in range(plan.runs):
                if table["status"][i] in keep:
                    skipped += 1
                else:
                    table["status"][i] = "pending"
                    table["message"][i] = ""
    except StudyError as e:
        err.write("mbdae: error: %s\n" % e)
        return 2
    todo = [i for i in range(plan.runs) if table["status"][i] == "pending"]
    if todo:
        try:
            _import_distributed()
        except ImportError as e:
            err.write("mbdae: error: %s\n" % e)
            return 1
    # The cluster's own log lines below warnings only (a stale worker folder purged, ...).
    import logging

    for name in ("distributed", "distributed.diskutils"):
        logging.getLogger(name).setLevel(logging.WARNING)
    quiet = args["quiet"]
    bar = _Progress(plan.runs, mode=None if quiet else "auto")
    done = skipped
    failed = int(np.sum(table["status"] == "failed"))
    start = time.monotonic()

    def on_signal(signal_number, frame):
        raise _Stop(signal_number)

    old_handlers = {s: signal.signal(s, on_signal) for s in (signal.SIGINT, signal.SIGTERM)}
    stopped = None
    try:
        if not quiet and skipped:
            err.write("mbdae: sweep: %d of %d runs are in %s already; %d to run\n"
                      % (skipped, plan.runs, output, len(todo)))
        _write_results(output, study, plan, table)
        last_write = time.monotonic()
        bar.update(done, failed)
        if todo:
            client = args["scheduler"]
            for i, result in _execute(plan, todo, client, study.retries, args["workers"]):
                _store(plan, table, i, result)
                done += 1
                failed += result["status"] != "done"
                bar.update(done, failed)
                if time.monotonic() - last_write >= args["flush_interval"]:
                    _write_results(output, study, plan, table)
                    last_write = time.monotonic()
    except _Stop as s:
        stopped = s.signal_number
    except OSError as e:
        bar.finish()
        err.write("mbdae: error: %s\n" % e)
        return 1
    finally:
        for s, h in old_handlers.items():
            signal.signal(s, h)
    bar.finish()
    # Ignore further signals while the final file is written (it is renamed whole anyway).
    with _signals_held():
        _write_results(output, study, plan, table, final=stopped is None)
    elapsed = time.monotonic() - start
    n_done = int(np.sum(table["status"] == "done"))
    n_failed = int(np.sum(table["status"] == "failed"))
    if stopped is not None:
        err.write("mbdae: error: interrupted by %s: %d of %d runs done, %d failed; they are in "
                  "%s (a rerun goes on from there)\n"
                  % ("SIGINT" if stopped == signal.SIGINT else "SIGTERM", n_done, plan.runs,
                     n_failed, output))
        return 128 + stopped
    if not quiet:
        sys.stdout.write("mbdae: sweep: %d runs: %d done, %d failed; %d run now in %.1f s, %d "
                         "taken from the earlier file; results in %s\n"
                         % (plan.runs, n_done, n_failed, len(todo), elapsed, skipped, output))
    if n_failed:
        failed_runs = [i for i in range(plan.runs) if table["status"][i] == "failed"]
        for i in failed_runs[:5]:
            err.write("mbdae: run %d (%s) failed: %s\n"
                      % (i, ", ".join("%s = %.10g" % (n, plan.values[i, k])
                                      for k, n in enumerate(plan.names)),
                         table["message"][i]))
        if len(failed_runs) > 5:
            err.write("mbdae: ... and %d more failed runs (status and message in %s)\n"
                      % (len(failed_runs) - 5, output))
        return 3
    return 0


@contextlib.contextmanager
def _signals_held():
    old = {s: signal.signal(s, signal.SIG_IGN) for s in (signal.SIGINT, signal.SIGTERM)}
    try:
        yield
    finally:
        for s, h in old.items():
            signal.signal(s, h)


if __name__ == "__main__":
    sys.exit(main())
