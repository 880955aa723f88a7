"""Loading libmbdae.so and declaring the C functions of api/mbdae.h for ctypes.

The library is looked for, in this order:

1. the file named by the environment variable ``MBDAE_LIBRARY``;
2. ``libmbdae.so`` next to this package (the build copies it there:
   ``<build>/python/mbdae/libmbdae.so``);
3. the build tree of a source checkout: ``<source>/build/api/libmbdae.so`` when the
   package is imported from ``<source>/python/mbdae``.

Nothing here is public: use :mod:`mbdae`.
"""

import ctypes
import os

from . import errors

API_VERSION = 1  # MBDAE_API_VERSION of the header this package was written against

# mbdae_kind
COORDINATES, MULTIPLIERS, REDUNDANT, BODIES, JOINTS, FORCES, MEASURES, PARAMETERS, \
    SPLINES, OUTPUTS, OBJECTIVES, GRADIENT_OBJECTIVES, GRADIENT_WRT = range(13)

# mbdae_output
OUT_TIME, OUT_Q, OUT_V, OUT_A, OUT_LAMBDA, OUT_MEASURES, OUT_BODY_POSES = range(7)

# mbdae_gradient_output
GRAD_VALUES, GRAD_GRADIENT, GRAD_FD_STEPS, GRAD_TIMES, GRAD_COUNTERS = range(5)

# mbdae_sparse_format
CSC, CSR = 0, 1

_c_double_p = ctypes.POINTER(ctypes.c_double)
_c_int_p = ctypes.POINTER(ctypes.c_int)


class Block(ctypes.Structure):
    """mbdae_block: scale times matrix `which` (transposed if `transpose`) at (row, col)."""

    _fields_ = [("which", ctypes.c_int), ("scale", ctypes.c_double), ("row", ctypes.c_int),
                ("col", ctypes.c_int), ("transpose", ctypes.c_int)]


def _candidates():
    """The places to look for the library, in order, as (description, path)."""
    out = []
    env = os.environ.get("MBDAE_LIBRARY")
    if env:
        out.append(("MBDAE_LIBRARY", env))
    here = os.path.dirname(os.path.abspath(__file__))
    out.append(("next to the package", os.path.join(here, "libmbdae.so")))
    source = os.path.dirname(os.path.dirname(here))
    out.append(("the build tree", os.path.join(source, "build", "api", "libmbdae.so")))
    return out


def _declare(lib):
    """Declares argument and result types of every function of api/mbdae.h."""
    vp = ctypes.c_void_p
    st = ctypes.c_int  # mbdae_status
    cp = ctypes.c_char_p
    i = ctypes.c_int
    d = ctypes.c_double
    dp = _c_double_p
    ip = _c_int_p
    signatures = {
        "mbdae_last_error": (cp, []),
        "mbdae_version": (cp, []),
        "mbdae_api_version": (i, []),
        "mbdae_model_from_file": (st, [cp, ctypes.POINTER(vp)]),
        "mbdae_model_from_string": (st, [cp, cp, ctypes.POINTER(vp)]),
        "mbdae_model_free": (None, [vp]),
        "mbdae_count": (st, [vp, i, ip]),
        "mbdae_name": (st, [vp, i, i, ctypes.POINTER(cp)]),
        "mbdae_find": (st, [vp, i, cp, ip]),
        "mbdae_get_parameter": (st, [vp, i, dp]),
        "mbdae_set_parameter": (st, [vp, i, d]),
        "mbdae_spline_size": (st, [vp, i, ip]),
        "mbdae_get_spline_points": (st, [vp, i, dp, dp, i]),
        "mbdae_set_spline_points": (st, [vp, i, dp, dp, i]),
        "mbdae_set_option": (st, [vp, cp, cp]),
        "mbdae_get_option": (st, [vp, cp, ctypes.c_char_p, ctypes.c_size_t]),
        "mbdae_assemble": (st, [vp]),
        "mbdae_solve": (st, [vp]),
        "mbdae_solve_to": (st, [vp, d]),
        "mbdae_get_state": (st, [vp, dp, dp, dp, dp, dp, i, i]),
        "mbdae_set_state": (st, [vp, d, dp, dp, dp, dp, i, i]),
        "mbdae_get_output": (st, [vp, i, i, dp, i]),
        "mbdae_write_results": (st, [vp, cp]),
        "mbdae_measure_values": (st, [vp, dp, i]),
        "mbdae_measure_gradient": (st, [vp, i, dp, i]),
        "mbdae_get_vector": (st, [vp, i, dp, i]),
        "mbdae_set_newton_step": (st, [vp, d]),
        "mbdae_get_matrix": (st, [vp, ctypes.POINTER(Block), i, i, i, i, ip, ip, ip, dp]),
        "mbdae_gradient": (st, [vp, cp, ctypes.POINTER(cp), i, ctypes.POINTER(cp), i, i, cp]),
        "mbdae_get_gradient": (st, [vp, i, dp, i]),
        "mbdae_gradient_report": (st, [vp, i, ctypes.c_char_p, ctypes.c_size_t,
                                       ctypes.POINTER(ctypes.c_size_t)]),
    }
    for name, (restype, argtypes) in signatures.items():
        f = getattr(lib, name)
        f.restype = restype
        f.argtypes = argtypes


def _load():
    tried = []
    env = os.environ.get("MBDAE_LIBRARY")
    if env and not os.path.isfile(env):  # an explicit choice that fails is not skipped
        raise ImportError("mbdae: MBDAE_LIBRARY is %s, which is not a file" % env)
    for where, path in _candidates():
        if not os.path.isfile(path):
            tried.append("%s: %s (no such file)" % (where, path))
            continue
        try:
            lib = ctypes.CDLL(path)
        except OSError as e:
            if where == "MBDAE_LIBRARY":
                raise ImportError("mbdae: MBDAE_LIBRARY: cannot load %s: %s" % (path, e))
            tried.append("%s: %s (%s)" % (where, path, e))
            continue
        try:
            _declare(lib)
        except AttributeError as e:
            raise ImportError("mbdae: %s is not the mbdae C API library (%s)" % (path, e))
        if lib.mbdae_api_version() != API_VERSION:
            raise ImportError("mbdae: %s implements C API version %d, this package needs %d"
                              % (path, lib.mbdae_api_version(), API_VERSION))
        return lib, path
    raise ImportError("mbdae: libmbdae.so not found; build it (bash scripts/build.sh) or set "
                      "MBDAE_LIBRARY to its path. Tried:\n  " + "\n  ".join(tried))


lib, path = _load()


def check(status):
    """Raises the exception of a non-zero mbdae_status with the C message."""
    if status != 0:
        message = lib.mbdae_last_error()
        raise errors.from_status(status, message.decode("utf-8", "replace") if message else "")


def dptr(array):
    """A double* to the data of a float64 C-contiguous numpy array (None for None)."""
    if array is None:
        return None
    return array.ctypes.data_as(_c_double_p)


def names_array(names):
    """A (char** array, count) pair for a list of str, or (None, 0) for None."""
    if names is None:
        return None, 0
    encoded = [n.encode() for n in names]
    array = (ctypes.c_char_p * max(1, len(encoded)))(*encoded)
    return array, len(encoded)


def iptr(array):
    """An int* to the data of an int32 C-contiguous numpy array."""
    return array.ctypes.data_as(_c_int_p)
