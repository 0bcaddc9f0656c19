"""One reader per measurement file format, each building a :class:`~robocal.data.Dataset` from a
:class:`~robocal.data.table.Table` (the layer below, which knows no format):

- :mod:`~robocal.data.formats.canonical`: robocal's own CSV (docs/data-format.md), and its writer;
- :mod:`~robocal.data.formats.frame`: a pandas DataFrame with the canonical columns;
- :mod:`~robocal.data.formats.cable`: D1 and D2, the drawstring datasets (``hsr``, ``robotcali``);
- :mod:`~robocal.data.formats.ipa`: D3, the UR10 laser-tracker series (``ipa``).

:mod:`robocal.data.loader` recognises a file's format and calls its reader. A new format is one
module here, its name in ``loader.FORMATS`` and its recognition in ``loader.detect_format``.
"""
