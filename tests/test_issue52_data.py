"""Issue 52, data identity and reading (rows 1, 2, 3, 4, 9, 10, 18).

One regression test per row, and Hypothesis properties for the class of rows 3 and 4: the same
samples are recognised from their content, whatever their order or encoding.
"""

from __future__ import annotations

import dataclasses
import json
import re
from pathlib import Path

import numpy as np
import pytest
import robocal
from hypothesis import given, settings
from hypothesis import strategies as st
from robocal.cli import main
from robocal.data import load
from robocal.data.identity import require_distinct_sessions
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


# -- rows 3 and 4: the same samples are recognised from their content -----------------------------
@pytest.fixture(scope="module")
def cable(tmp_path_factory):
    """A cable file of the HSR (the issue's a.csv, smaller), its calibration and a second session."""
    w = tmp_path_factory.mktemp("cable")
    data, truth = simulate("hsr-jr680", "cable", samples=100, seed=1)
    write_simulation(data, truth, w / "a.csv")
    write_simulation(simulate("hsr-jr680", "cable", samples=100, seed=1, session=1)[0], truth, w / "b.csv")
    assert main(["calibrate", str(w / "a.csv"), "--robot", "hsr-jr680", "--out", str(w / "ra.json"), "--quiet"]) == 0
    return w


def reencoded(source: Path, target: Path, *, order=None, columns=None, crlf=False, bom=False, drop_t=False, digits=None, nudge=0.0) -> Path:
    """``source``'s samples written otherwise: rows in ``order``, columns in ``columns`` order, CRLF
    line ends, a BOM, without ``t``, cells with ``digits`` significant digits, readings moved by ``nudge`` mm."""
    lines = source.read_text().splitlines()
    header, rows = lines[0].split(","), [line.split(",") for line in lines[1:]]
    rows = [rows[i] for i in (range(len(rows)) if order is None else order)]
    names = [h for h in (columns or header) if not (drop_t and h == "t")]

    def cell(name, text):
        value = float(text) + (nudge if name == "L" else 0.0)
        return repr(value) if digits is None else f"{value:.{digits}g}"

    out = [",".join(names)] + [",".join(cell(n, r[header.index(n)]) for n in names) for r in rows]
    end = "\r\n" if crlf else "\n"
    target.write_bytes((("\ufeff" if bom else "") + end.join(out) + end).encode("utf-8"))
    return target


def test_row3_a_shuffled_or_nudged_copy_is_not_a_second_session(cable, tmp_path, capsys):
    shuffled = reencoded(cable / "a.csv", tmp_path / "s.csv", order=np.random.default_rng(0).permutation(100))
    nudged = reencoded(cable / "a.csv", tmp_path / "n.csv", nudge=1e-9)
    for copy in (shuffled, nudged):
        code, _, err = run(["calibrate", cable / "a.csv", copy, "--robot", "hsr-jr680", "--quiet"], capsys)
        assert code == 2 and "are the same samples (100 of the 100 samples of session 2 are samples of session 1" in err
    code, _, err = run(["diagnose", cable / "a.csv", shuffled, "--robot", "hsr-jr680", "--quiet", "--json", tmp_path / "d.json"], capsys)
    assert code == 2 and "the same samples" in err
    assert main(["calibrate", str(cable / "a.csv"), str(cable / "b.csv"), "--robot", "hsr-jr680", "--quiet"]) == 0  # a second measurement is a session


def test_row3_a_partial_copy_is_said(cable, caplog):
    a, b = load(cable / "a.csv"), load(cable / "b.csv")
    mixed = dataclasses.replace(b, q=np.vstack([b.q[:80], a.q[:20]]), y=np.vstack([b.y[:80], a.y[:20]]), t=None, rows=np.arange(2, 102), source="mixed")
    with caplog.at_level("WARNING", logger="robocal"):
        require_distinct_sessions([a, mixed])
    assert "session 2 (mixed) shares 20 of its 100 samples with session 1 (rows 82-101)" in caplog.text
    with pytest.raises(robocal.exceptions.InvalidParameterError, match="60 of the 100 samples of session 2"):
        require_distinct_sessions([a, dataclasses.replace(mixed, q=np.vstack([b.q[:40], a.q[:60]]), y=np.vstack([b.y[:40], a.y[:60]]))])


@settings(max_examples=25)
@given(order=st.permutations(range(100)), nudge=st.floats(-1e-9, 1e-9), keep=st.integers(50, 100))
def test_row3_property_any_row_permutation_of_a_session_is_the_same_session(cable, order, nudge, keep):
    a = load(cable / "a.csv")
    copy = a.subset(np.asarray(order[:keep]))  # rows shuffled, up to half of them left out
    copy = dataclasses.replace(copy, y=copy.y + nudge, source=None)
    with pytest.raises(robocal.exceptions.InvalidParameterError, match="the same samples"):
        require_distinct_sessions([a, copy])
    with pytest.raises(robocal.exceptions.InvalidParameterError, match="the same samples"):
        require_distinct_sessions([copy, a])


def test_row4_verify_recognises_its_training_samples_in_any_encoding(cable, tmp_path):
    crlf = reencoded(cable / "a.csv", tmp_path / "c.csv", crlf=True)
    checked = verify(cable / "ra.json", crlf)
    assert checked["held_out"] is False and "80 of the 100 samples are training samples" in checked["notes"][0]
    assert verify(cable / "ra.json", cable / "b.csv")["held_out"] is True
    doc = json.loads((cable / "ra.json").read_text())
    held = load(cable / "a.csv")
    held = held.subset(np.isin(held.rows, doc["dataset"]["rows_held_out"]))
    assert verify(cable / "ra.json", held)["held_out"] is True and not verify(cable / "ra.json", held)["notes"]  # the calibration's own held-out rows are new


def test_row4_a_result_without_a_fingerprint_falls_back_to_the_file_hash(cable, tmp_path):
    doc = json.loads((cable / "ra.json").read_text())
    del doc["dataset"]["fingerprint"]  # a result written before robocal recorded one
    (tmp_path / "old.json").write_text(json.dumps(doc))
    checked = verify(tmp_path / "old.json", cable / "a.csv")
    assert checked["held_out"] is False and "same SHA-256" in checked["notes"][0]


@settings(max_examples=20)
@given(
    seed=st.integers(0, 2**32 - 1),
    shuffle=st.booleans(),
    reorder=st.booleans(),
    crlf=st.booleans(),
    bom=st.booleans(),
    drop_t=st.booleans(),
    digits=st.sampled_from([None, 15, 12]),
)
def test_row4_property_any_reencoding_of_a_training_file_is_not_held_out(cable, tmp_path_factory, seed, shuffle, reorder, crlf, bom, drop_t, digits):
    rng = np.random.default_rng(seed)
    header = (cable / "a.csv").read_text().splitlines()[0].split(",")
    path = reencoded(
        cable / "a.csv",
        tmp_path_factory.mktemp("enc") / "x.csv",
        order=rng.permutation(100) if shuffle else None,
        columns=list(rng.permutation(header)) if reorder else None,
        crlf=crlf,
        bom=bom,
        drop_t=drop_t,
        digits=digits,
    )
    assert verify(cable / "ra.json", path)["held_out"] is False


# -- row 9: a row of only empty cells is left out with a note ------------------------------------
@pytest.mark.parametrize("columnar", [True, False])
def test_row9_a_row_of_only_empty_cells_is_said(cable, tmp_path, monkeypatch, capsys, columnar):
    import pyarrow  # noqa: F401  (loaded: the columnar reader takes any size)
    from robocal.data import table

    monkeypatch.setattr(table, "COLUMNAR", columnar)
    lines = (cable / "a.csv").read_text().splitlines()
    path = tmp_path / "e.csv"
    path.write_text("\n".join(lines[:51] + [",,,,,,,", ""] + lines[51:]) + "\n")  # row 52; a blank line (row 53) holds no cells
    data = load(path)
    assert len(data) == 100 and data.excluded == [{"row": 52, "column": None, "reason": "every cell of the row is empty"}]
    assert "left out 1 row(s) of only empty cells (rows 52; see `excluded`)" in data.notes
    found = inspect(path)
    assert [(e["row"], e["column"]) for e in found["bad_cells"]] == [(52, None)] and found["problems"] >= 1
    code, out, _ = run(["inspect", path], capsys)
    assert "row 52: every cell of the row is empty" in out
    (tmp_path / "one.csv").write_text("\n".join(lines[:51] + [",,,,,,1,"] + lines[51:]) + "\n")
    with pytest.raises(robocal.exceptions.DataError, match="row 52, column 'q1'.*empty"):  # a cell given: the row is data, its empty cells are errors
        load(tmp_path / "one.csv")


# -- row 18: an over-long cell is named by row and column --------------------------------------------
@pytest.mark.parametrize("position", [2, 7])
def test_row18_a_cell_beyond_the_csv_limit_is_named(cable, tmp_path, capsys, position):
    lines = (cable / "a.csv").read_text().splitlines()
    cells = lines[10].split(",")
    cells[position] += "1" * 200_000
    lines[10] = ",".join(cells)
    path = tmp_path / "long.csv"
    path.write_text("\n".join(lines) + "\n")
    name = lines[0].split(",")[position]
    with pytest.raises(robocal.exceptions.DataError) as info:
        load(path)
    assert (info.value.row, info.value.column) == (11, name) and "characters, beyond the 131072" in info.value.message
    code, _, err = run(["inspect", path], capsys)
    assert code == 2 and f"long.csv, row 11, column '{name}': a cell of " in err and "Traceback" not in err


# -- row 10: a `t` out of row order is said, with what robocal does ------------------------------
def test_row10_a_time_column_out_of_row_order_is_said(cable, tmp_path, caplog, capsys):
    assert not any("clock goes backwards" in n for n in load(cable / "a.csv").notes)  # in order: nothing to say
    lines = (cable / "a.csv").read_text().splitlines()
    header, rows = lines[0].split(","), [line.split(",") for line in lines[1:]]
    k = header.index("t")
    times = [r[k] for r in rows]
    for r, t in zip(rows, np.random.default_rng(4).permutation(times)):
        r[k] = t
    path = tmp_path / "shuffled_t.csv"
    path.write_text("\n".join([lines[0]] + [",".join(r) for r in rows]) + "\n")
    with caplog.at_level("WARNING", logger="robocal"):
        data = load(path)
    note = next(n for n in data.notes if "clock goes backwards" in n)
    assert "robocal orders the samples by `t`" in note and "correct `t` or drop the column" in note
    assert "shuffled_t.csv: the clock goes backwards" in caplog.text  # logged by the reader: every command (diagnose too) shows it
    code, _, err = run(["inspect", path], capsys)
    assert code == 0 and "robocal: WARNING:" in err and "the clock goes backwards" in err


# -- row 2: the report of a multi-session result checks and shows every session ----------------------
@pytest.fixture(scope="module")
def two_sessions(cable):
    """A fit of the cable fixture's two sessions."""
    path = cable / "rab.json"
    assert main(["calibrate", str(cable / "a.csv"), str(cable / "b.csv"), "--robot", "hsr-jr680", "--out", str(path), "--quiet"]) == 0
    return path


def test_row2_report_of_sessions_checks_each_against_its_own_metrics(two_sessions, tmp_path):
    page = report(two_sessions, tmp_path / "rep").read_text()
    assert "edited or is corrupt" not in page
    assert "recomputed from the parameter values on the data of every session, each at its own set-up: they match the result file" in page
    assert "session 2, held out" in page and "1: " in page and "a.csv; 2: " in page  # both sessions listed and measured
    assert "Per-sample error on all 200 samples of 2 sessions" in page
    assert "session 1&#x27;s samples only" in page  # ISO 9283 distances never compare two set-ups


def test_row2_report_data_of_a_later_session_is_shown_at_its_own_set_up(two_sessions, cable, tmp_path):
    """--data of session 2's file was "not verified to be the file calibrated on" and its figures
    taken at session 1's set-up: 0.55 mm calibrated where the fit left 0.03 mm."""
    page = report(two_sessions, tmp_path / "rep", data=str(cable / "b.csv")).read_text()
    second = json.loads(two_sessions.read_text())["sessions"][1]["metrics"]["test"]
    assert "the file of session 2 (sha256 matches)" in page and "session 2&#x27;s samples only" in page
    assert f"the {second['n']} held-out samples" in page and f"RMS {second['rmse']:.4f}" in page


def test_row2_an_edited_session_or_pooled_metric_is_still_found(two_sessions, tmp_path):
    doc = json.loads(two_sessions.read_text())
    doc["sessions"][1]["metrics"]["test"]["rmse"] *= 2
    (tmp_path / "s.json").write_text(json.dumps(doc))
    page = report(tmp_path / "s.json", tmp_path / "rep_s").read_text()
    assert "edited or is corrupt" in page and "session 2 test RMSE" in page
    doc = json.loads(two_sessions.read_text())
    doc["metrics"]["train"]["rmse"] *= 2
    (tmp_path / "p.json").write_text(json.dumps(doc))
    page = report(tmp_path / "p.json", tmp_path / "rep_p").read_text()
    assert "edited or is corrupt" in page and "all sessions train RMSE" in page


def test_row2_a_session_whose_file_is_missing_is_said(two_sessions, tmp_path):
    doc = json.loads(two_sessions.read_text())
    doc["sessions"][1]["source"] = str(tmp_path / "gone.csv")
    (tmp_path / "m.json").write_text(json.dumps(doc))
    page = report(tmp_path / "m.json", tmp_path / "rep_m").read_text()
    assert "gone.csv is not on this machine" in page and "the files of sessions 2 are not at hand" in page and "edited" not in page
