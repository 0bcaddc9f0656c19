"""Fleet calibration: many datasets in one call, the same results on every backend, failures
reported per dataset."""

from __future__ import annotations

import pytest

import robocal
from robocal.data import write_canonical
from robocal.exceptions import InvalidParameterError


@pytest.fixture(scope="module")
def fleet(tmp_path_factory):
    folder = tmp_path_factory.mktemp("fleet")
    paths = []
    for i in range(3):
        data, _ = robocal.simulate("abb-irb120", "cable", samples=150, seed=i)
        paths.append(str(write_canonical(data, folder / f"robot{i}.csv")))
    broken = folder / "broken.csv"
    broken.write_text("q1,q2,q3,q4,q5,q6,L\n1,2,3,4,5,6,not-a-number\n")
    return paths, str(broken)


def parameters(doc: dict) -> list[float]:
    return [p["value"] for p in doc["parameters"]]


@pytest.mark.parametrize("backend", ["thread", "process"])
def test_every_backend_gives_the_serial_results_in_order(fleet, backend):
    paths, _ = fleet
    options = {"robot": "abb-irb120", "method": "lm", "seed": 3}
    serial = robocal.calibrate_many(paths, backend="serial", **options)
    parallel = robocal.calibrate_many(paths, workers=2, backend=backend, **options)
    assert [parameters(d) for d in parallel] == [parameters(d) for d in serial]
    assert [d["metrics"] for d in parallel] == [d["metrics"] for d in serial]
    # Each robot has its own geometry: the fleet did not return one result three times.
    assert len({tuple(parameters(d)) for d in serial}) == 3


def test_a_robot_object_goes_to_the_worker_processes(fleet):
    """A Robot, not only a name, reaches spawned workers (issue 52 #14: its chain could not be pickled)."""
    paths, _ = fleet
    by_name = robocal.calibrate_many(paths[:2], backend="serial", robot="abb-irb120", method="lm", seed=3)
    by_object = robocal.calibrate_many(paths[:2], workers=2, robot=robocal.robot("abb-irb120"), method="lm", seed=3)
    assert [parameters(d) for d in by_object] == [parameters(d) for d in by_name]


def test_a_bad_dataset_is_reported_and_the_rest_still_calibrate(fleet):
    paths, broken = fleet
    results = robocal.calibrate_many([paths[0], broken, paths[1]], workers=2, robot="abb-irb120")
    assert "error" not in results[0] and "error" not in results[2]
    assert results[1]["data"] == broken
    assert "DataError" in results[1]["error"] and "row" in results[1]["error"]


def test_bad_options_are_named(fleet):
    paths, _ = fleet
    with pytest.raises(InvalidParameterError, match="workers"):
        robocal.calibrate_many(paths, workers=0)
    with pytest.raises(InvalidParameterError, match="backend"):
        robocal.calibrate_many(paths, backend="gpu")
