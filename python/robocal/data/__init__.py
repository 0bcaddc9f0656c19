"""Measured data in: the :class:`Dataset`, the canonical CSV format, the readers of the public
datasets (:func:`load` detects the format) and splits. The validation report of a file, which
fits the set-up, sits above the calibration: :mod:`robocal.inspection`."""

from .canonical import read_canonical, write_canonical
from .dataset import OBSERVATION_COLUMNS, Dataset
from .frame import read_frame
from .public import FORMATS, detect_format, load, read_hsr, read_ipa, read_robotcali
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
