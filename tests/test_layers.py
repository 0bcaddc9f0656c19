"""The package's layers hold: each imports only from the layers below it, the NumPy oracle only
from tests and benchmarks (the import-linter contracts of ``pyproject.toml``; README,
"Architecture"). A failure prints the offending import chain."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path


def test_import_contracts_hold():
    # In a process of its own: import-linter configures logging with every existing logger
    # disabled, which would silence robocal's loggers for the tests that run after this one.
    pyproject = Path(__file__).resolve().parents[1] / "pyproject.toml"
    run = "from importlinter.cli import lint_imports; import sys; sys.exit(lint_imports(config_filename=sys.argv[1], no_cache=True, no_logo=True))"
    done = subprocess.run([sys.executable, "-c", run, str(pyproject)], capture_output=True, text=True)
    assert done.returncode == 0, done.stdout + done.stderr
