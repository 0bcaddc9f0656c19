"""Measured data in: the :class:`Dataset`, the canonical CSV format and (later) the readers of
the public datasets, validation and splits."""

from .canonical import read_canonical, write_canonical
from .dataset import OBSERVATION_COLUMNS, Dataset

__all__ = ["OBSERVATION_COLUMNS", "Dataset", "read_canonical", "write_canonical"]
