"""The validation report finds what is planted in synthetic files and what is wrong in the real ones."""

from __future__ import annotations

import argparse
import json

import numpy as np
import pytest

import robocal
from robocal.cli import main
from robocal.data import Dataset, write_canonical
from robocal.cli.inspect import add_arguments, format_report, run
from robocal.inspection import inspect

ABB = robocal.robot("abb-irb120")


def cable_samples(m=150, seed=4, beyond_limit=None):
    """Noisy cable data of the ABB IRB 120 with a known set-up, joint values inside the limits
    except q1 = 170 deg at index ``beyond_limit``."""
    rng = np.random.default_rng(seed)
    lower, upper = np.array([j.limits for j in ABB.joints]).T
    q = rng.uniform(0.8 * lower, 0.8 * upper, (m, 6))
    if beyond_limit is not None:
        q[beyond_limit, 0] = np.radians(170.0)
    params = ABB.with_params(anchor_x=600.0, anchor_y=-300.0, anchor_z=-50.0, cable_offset=-20.0, tool_x=5.0, tool_y=-3.0, tool_z=40.0).params
    L = ABB.predict("cable", q, params)[:, 0] + rng.normal(0, 0.05, m)
    return Dataset(q=q, y=L, measurement="cable")


def planted_file(tmp_path):
    """A canonical cable file with a NaN (row 5), text (row 9), a duplicate of row 12 (row 13),
    q1 beyond its 165 deg limit (row 20) and a 40 mm cable error (row 30)."""
    d = cable_samples(beyond_limit=18)  # row 20
    d.q[11] = d.q[10]
    d.y[11] = d.y[10]  # rows 12 and 13 identical
    d.y[28, 0] += 40.0  # row 30
    path = write_canonical(d, tmp_path / "planted.csv")
    lines = path.read_text().splitlines()
    cells = lines[4].split(",")
    cells[2] = "nan"  # row 5, q3
    lines[4] = ",".join(cells)
    cells = lines[8].split(",")
    cells[6] = "12.5 mm"  # row 9, L
    lines[8] = ",".join(cells)
    path.write_text("\n".join(lines) + "\n")
    return path


def test_planted_problems_are_found_with_their_rows(tmp_path):
    report = inspect(planted_file(tmp_path), robot="abb-irb120")
    assert report["rows"] == 148
    assert [(e["row"], e["column"]) for e in report["bad_cells"]] == [(5, "q3"), (9, "L")]
    assert report["bad_cells"][1]["reason"] == "expected a number; got '12.5 mm'"
    assert report["duplicates"] == [[12, 13]]
    assert [(e["row"], e["joint"]) for e in report["out_of_limits"]] == [(20, 1)]
    assert report["out_of_limits"][0]["value"] == pytest.approx(170.0) and report["out_of_limits"][0]["unit"] == "deg"
    fit = report["fit"]
    assert [e["row"] for e in fit["outliers"]] == [30]
    assert fit["outliers"][0]["residual_mm"] == pytest.approx(40.0, abs=0.5)
    assert fit["scale"]["cable_mm"] == pytest.approx(0.05, rel=0.3)
    assert fit["fitted"]["anchor_x"] == pytest.approx(600.0, abs=1.0)
    assert report["angle_unit"]["plausible"] and report["cross_check"] is None
    assert report["problems"] == 2 + 1 + 1 + 1
    text = format_report(report)
    assert "row 9, column 'L': expected a number; got '12.5 mm'" in text and "row 30: residual" in text


def test_angle_unit_mistakes(tmp_path):
    d = cable_samples(m=40)
    rad_as_deg = inspect(write_canonical(d, tmp_path / "rad.csv", angle_unit="rad"), robot="abb-irb120", angle_unit="deg")
    assert not rad_as_deg["angle_unit"]["plausible"] and "look like radians" in rad_as_deg["angle_unit"]["message"]
    deg_as_rad = inspect(write_canonical(d, tmp_path / "deg.csv"), angle_unit="rad")
    assert not deg_as_rad["angle_unit"]["plausible"] and "look like degrees" in deg_as_rad["angle_unit"]["message"]
    assert deg_as_rad["fit"] is None  # no robot: no limits, no fit


def test_position_outlier_and_base_frame():
    ur10 = robocal.robot("ur10")
    rng = np.random.default_rng(1)
    q = rng.uniform(-2.5, 2.5, (200, 6))
    truth = ur10.with_params(base_x=2000.0, base_y=-1500.0, base_z=-800.0, base_rz=2.5, base_rx=0.1, tool_x=10.0, tool_y=-5.0, tool_z=90.0).params
    y = ur10.predict("position", q, truth) + rng.normal(0, 0.02, (200, 3))
    y[77] += [15.0, 0.0, -10.0]
    report = inspect(Dataset(q=q, y=y, measurement="position", robot="ur10"))
    fit = report["fit"]
    assert [e["row"] for e in fit["outliers"]] == [79]
    assert fit["fitted"]["base_rz"] == pytest.approx(2.5, abs=1e-3)
    assert fit["fitted"]["tool_z"] == pytest.approx(90.0, abs=0.1)


def test_d2_cross_check_finds_the_corrupt_rows(datasets):
    report = inspect(datasets / "robotcali-abb-irb120" / "RobotCali-new.xlsx")
    check = report["cross_check"]
    assert check["rows_checked"] == 1042 and check["median_mm"] < 0.5
    assert [e["row"] for e in check["inconsistent"]] == [952, 859]
    assert check["inconsistent"][0]["difference_mm"][2] == pytest.approx(-99.15, abs=0.01)
    assert check["inconsistent"][1]["norm_mm"] == pytest.approx(1.15, abs=0.01)
    # the cable agrees with q at row 952: the controller's z is the corrupt value
    assert 952 not in [e["row"] for e in report["fit"]["outliers"]]


def test_cli_writes_json(datasets, tmp_path, capsys):
    parser = argparse.ArgumentParser()
    add_arguments(parser)
    out = tmp_path / "report.json"
    args = parser.parse_args([str(datasets / "robotcali-abb-irb120" / "RobotCali.xlsx"), "--json", str(out), "--strict"])
    assert run(args) == 0
    assert "120 cable samples (robotcali format), robot abb-irb120" in capsys.readouterr().out
    report = json.loads(out.read_text())
    assert report["rows"] == 120 and report["cross_check"]["inconsistent"] == []
    args = parser.parse_args([str(datasets / "robotcali-abb-irb120" / "RobotCali-new.xlsx"), "--strict"])
    assert run(args) == 1


def test_data_of_another_robot_are_a_problem(tmp_path, capsys):
    """Issue 52 #11: HSR cable data inspected as a UR10 passed --strict (inlier RMS 176 mm; 0.44 mm with the right robot)."""
    data, _ = robocal.simulate("hsr-jr680", "cable", samples=300, seed=1)
    path = write_canonical(data, tmp_path / "a.csv")
    right, wrong = inspect(str(path), robot="hsr-jr680"), inspect(str(path), robot="ur10")
    assert right["another_robot"] is None and right["problems"] == 0
    assert wrong["another_robot"].startswith("the data do not fit ur10: ") and "another robot than the one given" in wrong["another_robot"]
    assert wrong["problems"] == 1
    parser = argparse.ArgumentParser()
    add_arguments(parser)
    assert run(parser.parse_args([str(path), "--robot", "ur10", "--strict"])) == 1
    assert "another robot? the data do not fit ur10" in capsys.readouterr().out


def test_angle_unit_check_names_the_rows_and_the_columns_in_radians_in_a_degree_table():
    """A few rows, or one joint's column, read in radians among degrees are named (row numbers
    as in the file, header = 1; the column by its joint); the degree table itself passes."""
    from robocal.data.dataset import angle_unit_check

    degrees = np.random.default_rng(0).uniform(-170.0, 170.0, (40, 6))
    rows = degrees.copy()
    rows[5:8] = np.radians(rows[5:8])
    check = angle_unit_check(np.radians(rows), "deg")
    assert check["partial"] and check["message"].startswith("rows 7-9 (3 rows)")
    column = degrees.copy()
    column[:, 4] = np.radians(column[:, 4])
    check = angle_unit_check(np.radians(column), "deg")
    assert check["partial"] and check["message"].startswith("column(s) q5 stay within")
    assert angle_unit_check(np.radians(degrees), "deg")["plausible"]


def test_rows_within_2_pi_as_often_as_chance_gives_are_no_radians():
    """A one-joint arm of ±57°: one row in 9 is within ±6.3° by chance. Its own simulated data were
    refused as radians rows; a few rows in radians among six joints are still named."""
    from robocal.data.dataset import angle_unit_check

    rng = np.random.default_rng(1)
    one = rng.uniform(-57.0, 57.0, (200, 1))
    assert angle_unit_check(np.radians(one), "deg")["plausible"]
    six = rng.uniform(-170.0, 170.0, (200, 6))
    six[10:12] = np.radians(six[10:12])
    assert angle_unit_check(np.radians(six), "deg")["message"].startswith("rows 12-13 (2 rows)")


def test_a_bad_sigmas_is_named_once_in_the_command_line_s_words(tmp_path, capsys):
    path = write_canonical(robocal.simulate("hsr-jr680", "cable", samples=30, seed=1)[0], tmp_path / "a.csv")
    assert main(["inspect", str(path), "--robot", "hsr-jr680", "--sigmas", "0"]) == 2
    assert "robocal: error: `--sigmas`, the outlier threshold in robust standard deviations, must be finite and > 0; got 0" in capsys.readouterr().err
