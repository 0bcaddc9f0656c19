"""The scripts in examples/ run as a user would run them (small data; the public-dataset one
reads ../shared/datasets)."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"
SIMULATED = ["calibrate_simulated.py", "diagnose_and_compensate.py", "export_urdf.py"]


def run(script: str, *args) -> str:
    done = subprocess.run([sys.executable, str(EXAMPLES / script), *map(str, args)], capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr[-2000:]
    return done.stdout


@pytest.mark.parametrize("script", SIMULATED)
def test_example_runs(script, tmp_path):
    out = run(script, tmp_path)
    assert out.strip()


def test_examples_are_all_tested():
    assert sorted(p.name for p in EXAMPLES.glob("*.py")) == sorted(SIMULATED + ["public_dataset.py"])


def test_public_dataset_example(datasets):
    out = run("public_dataset.py", datasets)
    assert "geometric calibration: held-out RMSE" in out and "diagnosis:" in out
