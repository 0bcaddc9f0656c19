"""Measured data in: the :class:`Dataset`, one reader per file format (:mod:`.formats`: the
canonical CSV, DataFrames, the public datasets) over one parsed table (:mod:`.table`), :func:`load`
which detects the format (:mod:`.loader`), and splits. The validation report of a file, which
fits the set-up, sits above the calibration: :mod:`robocal.inspection`."""

from .dataset import OBSERVATION_COLUMNS, Dataset
from .formats.cable import read_hsr, read_robotcali
from .formats.canonical import read_canonical, write_canonical
from .formats.frame import read_frame
from .formats.ipa import read_ipa
from .loader import FORMATS, detect_format, load
from .splits import chronological, configuration_groups, kfold, paper_split, random_split

__all__ = [
    "FORMATS",
    "OBSERVATION_COLUMNS",
    "Dataset",
    "chronological",
    "configuration_groups",
    "detect_format",
    "kfold",
    "load",
    "paper_split",
    "random_split",
    "read_canonical",
    "read_frame",
    "read_hsr",
    "read_ipa",
    "read_robotcali",
    "write_canonical",
]
