"""The package's layers hold: each imports only from the layers below it, the NumPy oracle only
from tests and benchmarks (the import-linter contracts of ``pyproject.toml``; README,
"Architecture"). A failure prints the offending import chain."""

from __future__ import annotations

from pathlib import Path

from importlinter.cli import lint_imports


def test_import_contracts_hold():
    pyproject = Path(__file__).resolve().parents[1] / "pyproject.toml"
    assert lint_imports(config_filename=str(pyproject), no_cache=True, no_logo=True) == 0
