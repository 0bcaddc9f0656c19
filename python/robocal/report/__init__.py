"""The calibration report (``robocal report``): :func:`report` writes one self-contained HTML
page with its figures from a result file.

Three concerns, one module each: :mod:`.page` (the page, the inputs it reads and their
evaluation), :mod:`.figures` (the PNG figures, also drawn by ``robocal diagnose``) and
:mod:`.text` (the words and tables shared with the command line).
"""

from .page import report

__all__ = ["report"]
