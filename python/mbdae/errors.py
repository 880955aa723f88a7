"""The exceptions of :mod:`mbdae`: one class per status code of the C API.

Every exception is an :class:`Error` with the attributes ``status`` (the mbdae_status
value, 0 for errors found in Python before calling C) and ``message`` (the text; for an
error of the C library, ``mbdae_last_error()``). Each class also derives from the
built-in exception Python code would expect for that kind of mistake, so that e.g.
``except KeyError`` catches an unknown name and ``except OSError`` a file that cannot be
read.
"""


class Error(Exception):
    """Base of every mbdae error. ``status``: the C status code; ``message``: the text."""

    status = None

    def __init__(self, message, status=None):
        super().__init__(message)
        self.message = message
        if status is not None:
            self.status = status

    def __str__(self):
        return self.message


class InputError(Error, ValueError):
    """MBDAE_ERROR_INPUT: a model file or string with a mistake, or a bad option value."""

    status = 1


class ArgumentError(Error, KeyError):
    """MBDAE_ERROR_ARGUMENT: an index or name that does not exist (a KeyError too)."""

    status = 2


class SizeError(Error, ValueError):
    """MBDAE_ERROR_SIZE: an array whose length does not match the model."""

    status = 3


class OrderError(Error, RuntimeError):
    """MBDAE_ERROR_ORDER: a call that needs an earlier one (outputs before a solve, a
    closed model)."""

    status = 4


class SolverError(Error, RuntimeError):
    """MBDAE_ERROR_SOLVER: the assembly or the integrator failed (rows so far are kept)."""

    status = 5


class FileError(Error, OSError):
    """MBDAE_ERROR_IO: a file could not be read or written (an OSError too)."""

    status = 6

    def __str__(self):  # OSError's own __str__ would show the argument tuple
        return self.message


IOError_ = FileError  # the name used in the project's issue; same class


class InternalError(Error, RuntimeError):
    """MBDAE_ERROR_INTERNAL: a bug in the library; please report the message."""

    status = 7


_BY_STATUS = {c.status: c for c in (InputError, ArgumentError, SizeError, OrderError,
                                     SolverError, FileError, InternalError)}


def from_status(status, message):
    """The exception for C status `status` with `message`."""
    cls = _BY_STATUS.get(status)
    if cls is None:
        return Error("unknown status %d: %s" % (status, message), status)
    return cls(message)
