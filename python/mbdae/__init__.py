"""mbdae: drive multibody models from Python, step by step, with every internal vector and
matrix.

A thin layer on the C API (api/mbdae.h) through ctypes: numpy arrays in and out, scipy
sparse matrices for the matrices, exceptions with the library's message. Example::

    import mbdae

    with mbdae.Model("examples/pendulum.yaml") as m:
        m.options["integrator"] = "hht"
        m.options["hht.step"] = 1e-3
        m.solve()
        print(m.outputs.time[-1], m.outputs.q[-1])

Gradients of the model's objectives (``objectives:`` of the model file) with respect to
parameters and spline ordinates: ``m.gradient(wrt=["k"], method="adjoint")``; as a
function for ``scipy.optimize.minimize``: ``f = m.objective_function("G", ["k"])``,
``minimize(f, f.x0, jac=f.jac)``. A problem file solved with Ipopt as ``mbdae optimize``
does: ``r = mbdae.optimize("problem.yaml")``, ``r.objective``, ``r.variables``. Many runs
on Dask (a parameter grid or Monte Carlo samples, one row per run in a pandas DataFrame):
``mbdae.sweep("model.yaml", {"k": [1, 2], "c": [0.1, 0.2]}, ["objectives", "final:x"])``.

The library libmbdae.so is found through the environment variable MBDAE_LIBRARY, next to
this package, or in the build tree of a source checkout (see :data:`library_path`).
"""

from . import _lib
from .errors import (ArgumentError, Error, FileError, InputError, InternalError, IOError_,
                     OrderError, SizeError, SolverError)
from .gradient import METHODS, Gradient, ObjectiveFunction
from .model import MATRICES, OPTIONS, VECTORS, Model, Row, State
from .optimize import HISTORY_COLUMNS, OptimizationResult, optimize, optimize_string
from .sweep import StudyError, read_sweep, sweep

__version__ = _lib.lib.mbdae_version().decode()
#: The path of the loaded libmbdae.so.
library_path = _lib.path
#: The C API version (MBDAE_API_VERSION) of the loaded library.
api_version = _lib.lib.mbdae_api_version()

__all__ = ["Model", "State", "Row", "Error", "InputError", "ArgumentError", "SizeError",
           "OrderError", "SolverError", "FileError", "IOError_", "InternalError", "VECTORS",
           "MATRICES", "OPTIONS", "METHODS", "Gradient", "ObjectiveFunction", "optimize",
           "optimize_string", "OptimizationResult", "HISTORY_COLUMNS", "sweep", "read_sweep",
           "StudyError", "library_path",
           "api_version", "__version__"]
