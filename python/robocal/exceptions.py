"""robocal's exceptions.

Every error raised by robocal (including the compiled core) is a :class:`RobocalError`. Each
subclass also derives from the standard type a caller would naturally catch, so
``except ValueError`` keeps working for bad input and ``except numpy.linalg.LinAlgError`` for
singular problems.
"""

from __future__ import annotations

import numpy as np


class RobocalError(Exception):
    """Base class of all robocal errors."""


class ShapeError(RobocalError, ValueError):
    """An array has the wrong shape, length or joint count."""


class NonFiniteError(RobocalError, ValueError):
    """An input holds NaN or infinity."""


class InvalidParameterError(RobocalError, ValueError):
    """A parameter, option or name is outside its domain."""


class SingularError(RobocalError, np.linalg.LinAlgError):
    """A linear problem has no unique solution (degenerate data or geometry)."""


class NotPositiveDefiniteError(RobocalError, np.linalg.LinAlgError):
    """A matrix that must be positive definite is not."""


class DataError(RobocalError, ValueError):
    """A data file cannot be read as asked: the message names the file, row and column.

    Attributes ``path``, ``row`` (1-based line in the file, the header is row 1; a DataFrame's
    0-based position) and ``column``
    (a name) are set where known; ``message`` is the text without the location.
    """

    def __init__(self, message: str, path=None, row: int | None = None, column: str | None = None):
        where = ", ".join(p for p in (str(path) if path else "", f"row {row}" if row is not None else "", f"column {column!r}" if column else "") if p)
        super().__init__(f"{where}: {message}" if where else message)
        self.message, self.path, self.row, self.column = message, path, row, column


class OutputError(RobocalError, ValueError):
    """An output cannot be written where asked (it is an input, its folder is missing, the disk
    is full, ...): the message names the path."""


class NoConvergenceError(RobocalError, RuntimeError):
    """An iterative routine failed (results normally report non-convergence instead)."""


class MissingDependencyError(RobocalError, ImportError):
    """A feature needs an optional dependency that is not installed: the message says which
    and the ``pip install`` that brings it."""


__all__ = [
    "RobocalError",
    "ShapeError",
    "NonFiniteError",
    "InvalidParameterError",
    "SingularError",
    "NotPositiveDefiniteError",
    "NoConvergenceError",
    "DataError",
    "OutputError",
    "MissingDependencyError",
]
