"""Robust calibration: Huber and Cauchy losses with the outlying rows reported."""

from __future__ import annotations

import json

import numpy as np
import pytest

import robocal
from robocal.calibration import Problem
from robocal.calibration.lm import levenberg_marquardt
from robocal.exceptions import InvalidParameterError
from robocal.simulation import simulate


def clean_heldout_rmse(result, clean):
    """RMSE of a fit on the CLEAN versions of its held-out samples."""
    idx = np.searchsorted(clean.rows, result.held_out.rows)
    r = result.problem.with_data(clean.subset(idx)).data_residuals(result.x)
    return float(np.sqrt(np.mean(r * r)))


@pytest.mark.parametrize("measurement", ["cable", "position"])
@pytest.mark.parametrize("loss", ["huber", "cauchy"])
def test_two_percent_gross_outliers_land_within_ten_percent_of_the_clean_fit(measurement, loss):
    clean, _ = simulate("abb-irb120", measurement, samples=500, seed=5)
    dirty, truth = simulate("abb-irb120", measurement, samples=500, seed=5, outliers=0.02)
    reference = clean_heldout_rmse(robocal.calibrate(clean), clean)
    plain = clean_heldout_rmse(robocal.calibrate(dirty), clean)
    fit = robocal.calibrate(dirty, loss=loss)
    robust = clean_heldout_rmse(fit, clean)
    assert plain > 2 * reference  # the outliers do hurt a least-squares fit
    assert robust < 1.1 * reference
    hidden = {int(dirty.rows[i]) for e in truth["effects"] if e["kind"] == "outliers" for i in e["samples"]}
    in_training = hidden & {int(r) for r in fit.problem.data.rows}
    assert set(fit.robust["outlying_rows"]) == in_training
    doc = fit.to_dict()
    assert doc["robust"]["loss"] == loss and json.dumps(doc)


def test_clean_data_robust_equals_least_squares_closely():
    data, _ = simulate("hsr-jr680", "cable", samples=300, seed=2)
    plain, huber = robocal.calibrate(data), robocal.calibrate(data, loss="huber")
    assert huber.robust["outlying_rows"] == []
    assert abs(huber.metrics["test"]["rmse"] - plain.metrics["test"]["rmse"]) < 0.02 * plain.metrics["test"]["rmse"]


def test_bad_loss_arguments_are_named():
    data, _ = simulate("abb-irb120", "cable", samples=60, seed=1)
    problem = Problem.build(robocal.robot("abb-irb120"), data)
    with pytest.raises(InvalidParameterError, match="loss"):
        levenberg_marquardt(problem, loss="l1")
    with pytest.raises(InvalidParameterError, match="f_scale"):
        levenberg_marquardt(problem, loss="huber", f_scale=-1.0)


def test_cli_reports_outlying_rows(tmp_path, capsys):
    from robocal.cli import main
    from robocal.data import write_canonical

    data, _ = simulate("abb-irb120", "cable", samples=300, seed=5, outliers=0.02)
    csv = write_canonical(data, tmp_path / "d.csv")
    assert main(["calibrate", str(csv), "--robot", "abb-irb120", "--loss", "cauchy", "--out", str(tmp_path / "r.json")]) == 0
    assert "outlying rows" in capsys.readouterr().out
    assert json.loads((tmp_path / "r.json").read_text())["robust"]["loss"] == "cauchy"
