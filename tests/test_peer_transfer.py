"""benches/peer_transfer.py compares robocal with pybotics, which robocal does not depend on: where pybotics is not
installed, the bench says how to install it and stops, without a traceback."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import robocal

ROOT = Path(__file__).resolve().parents[1]

# The bench run as if pybotics were not installed, whether or not it is here.
WITHOUT_PYBOTICS = """
import importlib.metadata as metadata, runpy, sys
real = metadata.version
def version(name):
    if name == "pybotics":
        raise metadata.PackageNotFoundError(name)
    return real(name)
metadata.version = version
sys.argv = ["peer_transfer.py"]
runpy.run_path("benches/peer_transfer.py", run_name="__main__")
"""


def test_the_bench_without_pybotics_says_how_to_install_it():
    # The robocal this test runs with (an installed one has its compiled core; the source tree's may not).
    path = os.pathsep.join([str(ROOT / "benches"), str(Path(robocal.__file__).parents[1]), os.environ.get("PYTHONPATH", "")])
    run = subprocess.run(
        [sys.executable, "-c", WITHOUT_PYBOTICS], check=False, cwd=ROOT, env={**os.environ, "PYTHONPATH": path}, capture_output=True, text=True
    )
    assert run.returncode == 1
    assert "pip install pybotics==3.1.2" in run.stderr
    assert "Traceback" not in run.stderr
