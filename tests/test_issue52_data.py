"""Issue 52, data identity and reading (rows 1, 2, 3, 4, 9, 10, 18).

One regression test per row, and Hypothesis properties for the class of rows 3 and 4: the same
samples are recognised from their content, whatever their order or encoding.
"""

from __future__ import annotations

import json
import re

import pytest
import robocal
from robocal.cli import main
from robocal.data import load
from robocal.inspection import inspect
from robocal.report import report
from robocal.simulation import simulate, write_simulation
from robocal.verification import verify

#: The issue's robot: joint 2 prismatic (0..500 mm).
PRISMATIC_ROBOT = {
    "name": "prism6",
    "joints": [
        {"alpha": a, "a": length, "d": d, "theta": 0, **({"kind": "prismatic", "limits": [0, 500]} if j == 1 else {})}
        for j, (d, length, a) in enumerate(zip((400, 200, 0, 0, 300, 100), (0, 0, 300, 0, 0, 0), (0, -90, 0, 90, -90, 90)))
    ],
}


def run(argv, capsys) -> tuple[int, str, str]:
    """Exit code, stdout and stderr of a command line."""
    try:
        code = main([str(a) for a in argv])
    except SystemExit as exc:
        code = exc.code
    out = capsys.readouterr()
    return code, out.out, out.err


# -- row 1: prismatic joints are mm wherever a robot is known ----------------------------------------
@pytest.fixture(scope="module")
def prismatic(tmp_path_factory):
    """The issue's robot file, a position file of it and its calibration."""
    w = tmp_path_factory.mktemp("prismatic")
    (w / "pr.json").write_text(json.dumps(PRISMATIC_ROBOT))
    data, truth = simulate(str(w / "pr.json"), "position", samples=120, seed=1)
    write_simulation(data, truth, w / "pr.csv")
    assert main(["calibrate", str(w / "pr.csv"), "--robot", str(w / "pr.json"), "--out", str(w / "rpr.json"), "--quiet"]) == 0
    return w


def test_row1_verify_reads_a_prismatic_column_as_mm(prismatic):
    doc = json.loads((prismatic / "rpr.json").read_text())
    checked = verify(prismatic / "rpr.json", prismatic / "pr.csv")
    # Its own training file: the set-up re-fitted, the error is the calibration's (0.03 mm), not 0.3 mm
    assert checked["metrics"]["rmse"] < 1.5 * doc["metrics"]["train"]["rmse"]
    assert checked["metrics"]["rmse"] < 0.06


def test_row1_report_recomputes_a_prismatic_result_on_its_own_file(prismatic):
    page = report(prismatic / "rpr.json", prismatic / "rep").read_text()
    assert "they match the result file" in page and "edited or is corrupt" not in page


def test_row1_inspect_leaves_a_prismatic_column_out_of_the_angle_unit(prismatic):
    found = inspect(prismatic / "pr.csv", robot=str(prismatic / "pr.json"))
    largest = float(re.search(r"max \|q\| = ([0-9.]+) deg", found["angle_unit"]["message"]).group(1))
    assert found["angle_unit"]["plausible"] and largest <= 180.0  # the angles', not the mm column's (up to 500 "deg")
    assert load(prismatic / "pr.csv", robot=robocal.robot(str(prismatic / "pr.json"))).prismatic == (1,)  # a Robot says it too


def test_row1_out_of_limits_are_shown_in_the_joints_units(prismatic, tmp_path, capsys):
    lines = (prismatic / "pr.csv").read_text().splitlines()
    header = lines[0].split(",")
    cells = lines[1].split(",")
    cells[header.index("q2")] = "600"  # mm, beyond 0..500
    path = tmp_path / "far.csv"
    path.write_text("\n".join([lines[0], ",".join(cells), *lines[2:]]) + "\n")
    found = inspect(path, robot=str(prismatic / "pr.json"))
    assert [(e["row"], e["joint"], e["value"], e["limits"], e["unit"]) for e in found["out_of_limits"]] == [(2, 2, 600.0, [0.0, 500.0], "mm")]
    code, out, _ = run(["inspect", path, "--robot", prismatic / "pr.json"], capsys)
    assert code == 0 and "row 2, q2 = 600.000 mm (limits 0..500)" in out
