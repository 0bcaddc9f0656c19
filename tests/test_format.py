"""The code stays as ``ruff format`` (configured in pyproject.toml) writes it."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def test_python_sources_are_formatted():
    folders = [str(ROOT / f) for f in ("python", "tests", "benches", "examples")]
    done = subprocess.run([sys.executable, "-m", "ruff", "format", "--check", *folders], capture_output=True, text=True, cwd=ROOT)
    assert done.returncode == 0, f"run `ruff format python tests benches examples`:\n{done.stdout}{done.stderr}"
