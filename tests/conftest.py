"""Shared test settings: a deterministic hypothesis profile and the public datasets."""

from __future__ import annotations

import os
from pathlib import Path

import pytest
from hypothesis import HealthCheck, settings

# No test may depend on the machine's speed (the suite runs on busy machines): no deadline, and the health
# check on slow data generation suppressed here and wherever a test names the checks it suppresses.
settings.register_profile("ci", derandomize=True, deadline=None, max_examples=50, suppress_health_check=[HealthCheck.too_slow])
settings.register_profile("thorough", deadline=None, max_examples=500)
settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "ci"))

DATASETS = Path(os.environ.get("ROBOCAL_DATASETS", Path(__file__).resolve().parents[1] / ".." / "shared" / "datasets")).resolve()


@pytest.fixture(scope="session")
def datasets() -> Path:
    """The public datasets (never copied into the repo). CI sets ROBOCAL_REQUIRE_DATASETS=1 so
    that their absence fails instead of skipping."""
    if not DATASETS.is_dir():
        if os.environ.get("ROBOCAL_REQUIRE_DATASETS"):
            pytest.fail(f"public datasets not found at {DATASETS} (set ROBOCAL_DATASETS)")
        pytest.skip(f"public datasets not found at {DATASETS} (set ROBOCAL_DATASETS)")
    return DATASETS
