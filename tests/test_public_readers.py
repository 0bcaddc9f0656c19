"""Readers of the public datasets in their original formats: row counts, units, side columns,
format detection, and errors that name file, row and column."""

from __future__ import annotations

import shutil

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import robocal
from robocal.data import detect_format, load, read_canonical, read_hsr, read_ipa, read_robotcali
from robocal.exceptions import DataError, RobocalError

D1 = "hsr-robotcali"
D2 = "robotcali-abb-irb120"
D3 = "ipa-robot-accuracy-ur10"
SERIES = {
    "A": f"{D3}/Series_A/measurements_grid.csv",
    "B": f"{D3}/Series_B/measurements_joint_configurations.csv",
    "C": f"{D3}/Series_C/measurements_random_poses.csv",
}


# -- the real files ------------------------------------------------------------------------------
@pytest.mark.parametrize("name", ["HSR-RobotCali.xlsx", "hsr_jr680_cable.csv"])
def test_d1_rows_and_units(datasets, name):
    d = read_hsr(datasets / D1 / name)
    assert (len(d), d.robot, d.measurement, d.n_joints) == (2017, "hsr-jr680", "cable", 6)
    np.testing.assert_array_equal(d.rows, np.arange(2, 2019))
    np.testing.assert_allclose(np.degrees(d.q[0]), [7.959, -75.864, 215.116, -177.022, 37.363, 65.125])
    assert d.y[0, 0] == 351.0 and d.excluded == []


def test_d1_workbook_and_csv_agree(datasets):
    a, b = read_hsr(datasets / D1 / "HSR-RobotCali.xlsx"), read_hsr(datasets / D1 / "hsr_jr680_cable.csv")
    np.testing.assert_array_equal(a.q, b.q)
    np.testing.assert_array_equal(a.y, b.y)


@pytest.mark.parametrize("name, rows", [("RobotCali-new.xlsx", 1042), ("abb_irb120_cable.csv", 1042), ("RobotCali.xlsx", 120)])
def test_d2_rows_and_controller_xyz(datasets, name, rows):
    d = read_robotcali(datasets / D2 / name)
    assert (len(d), d.robot, d.measurement) == (rows, "abb-irb120", "cable")
    assert d.extra["controller_xyz"].shape == (rows, 3)
    # Units: the nominal flange position FK(q in rad) reproduces the controller's x, y, z (mm).
    fk = robocal.robot("abb-irb120").predict("position", d.q)
    error = np.linalg.norm(fk - d.extra["controller_xyz"], axis=1)
    assert np.mean(error < 1.0) > 0.99 and np.median(error) < 0.5


def test_d2_older_workbook_names_its_second_sheet(datasets):
    d = read_robotcali(datasets / D2 / "RobotCali.xlsx")
    assert any("sheet 'Sheet2' (10 rows" in n and "repeat rows 92-101" in n for n in d.notes)
    second = read_robotcali(datasets / D2 / "RobotCali.xlsx", sheet="Sheet2")
    assert len(second) == 10
    np.testing.assert_array_equal(second.y, d.y[90:100])
    with pytest.raises(DataError, match=r"no sheet 'Sheet9'; the workbook has \['Sheet1', 'Sheet2', 'Sheet3'\]"):
        read_robotcali(datasets / D2 / "RobotCali.xlsx", sheet="Sheet9")


def test_d2_subset_keeps_side_columns(datasets):
    d = read_robotcali(datasets / D2 / "RobotCali.xlsx")
    s = d.subset([3, 5])
    np.testing.assert_array_equal(s.extra["controller_xyz"], d.extra["controller_xyz"][[3, 5]])
    np.testing.assert_array_equal(s.rows, [5, 7])


@pytest.mark.parametrize("series, rows", [("A", 11911), ("B", 1495), ("C", 2773)])
def test_d3_rows(datasets, series, rows):
    # Series A has 11911 data rows: the "11910" quoted for it is `wc -l` minus the header, and the
    # file lacks a final newline.
    d = read_ipa(datasets / SERIES[series])
    assert (len(d), d.robot, d.measurement) == (rows, "ur10", "pose")
    assert d.rows[-1] == rows + 1


def test_d3_conversions(datasets):
    d = read_ipa(datasets / SERIES["A"])
    # first row: joints in rad as in the file; position in mm; temperature; goal in mm / rad
    np.testing.assert_allclose(d.q[0], [-1.5708, -1.5708, 0.0, -1.5708, 0.0, 0.0])
    np.testing.assert_allclose(d.y[0, :3], [2361.9831, -1368.5474, 119.39713])
    assert d.temp[0] == pytest.approx(23.68)
    np.testing.assert_allclose(d.extra["goal_pose"][0], [365.141, -0.212669, 1427.3, 1.57002, 1.57007, 1.57073])
    # quaternions: unit, w >= 0, and back to the file's intrinsic XYZ Euler angles
    from scipy.spatial.transform import Rotation

    quat = d.y[:, 3:]
    np.testing.assert_allclose(np.linalg.norm(quat, axis=1), 1.0, atol=1e-12)
    assert np.all(quat[:, 0] >= 0)
    back = Rotation.from_quat(quat[:5, [1, 2, 3, 0]]).as_euler("XYZ", degrees=True)
    np.testing.assert_allclose(back[0], [-90.409151, -59.885105, -90.887438], atol=1e-9)
    # position-only reading
    p = read_ipa(datasets / SERIES["A"], measurement="position")
    np.testing.assert_array_equal(p.y, d.y[:, :3])


def test_d3_clock_and_degraded_timestamps(datasets):
    a = read_ipa(datasets / SERIES["A"])
    assert a.t[0] == 0.0 and a.t.min() == 0.0 and a.t.max() == pytest.approx(362933.0)
    assert any("the clock goes backwards at 9 rows (1361, 11904" in n for n in a.notes)
    for series in "BC":
        d = read_ipa(datasets / SERIES[series])
        assert d.t is None
        assert any("lossy scientific notation (e.g. '2,02011E+13'" in n and "not usable as a clock" in n for n in d.notes)
        assert d.extra["measurement_std"].shape == (len(d), 6)


@pytest.mark.parametrize(
    "path, fmt",
    [
        (f"{D1}/HSR-RobotCali.xlsx", "hsr"),
        (f"{D1}/hsr_jr680_cable.csv", "canonical"),
        (f"{D2}/RobotCali-new.xlsx", "robotcali"),
        (f"{D2}/RobotCali.xlsx", "robotcali"),
        (f"{D2}/abb_irb120_cable.csv", "robotcali"),
        (SERIES["A"], "ipa"),
        (SERIES["B"], "ipa"),
        (SERIES["C"], "ipa"),
    ],
)
def test_format_detection_by_content(datasets, tmp_path, path, fmt):
    # renamed to a neutral name: the content decides, not the file name
    copy = tmp_path / "data.bin"
    shutil.copyfile(datasets / path, copy)
    assert detect_format(copy) == fmt
    assert len(load(copy)) > 0


@pytest.mark.parametrize(
    "path, reader",
    [
        (f"{D1}/HSR-RobotCali.xlsx", read_hsr),
        (f"{D1}/hsr_jr680_cable.csv", read_canonical),
        (f"{D2}/abb_irb120_cable.csv", read_robotcali),
        (SERIES["B"], read_ipa),
    ],
)
def test_load_reads_the_file_once(datasets, monkeypatch, path, reader):
    # What recognising the format read (a workbook's sheet, a text) serves its reader: the file's bytes are read once.
    import robocal.data.table as table

    reads, read_regular = [], table.read_regular
    monkeypatch.setattr(table, "read_regular", lambda *args, **kw: reads.append(args[0]) or read_regular(*args, **kw))
    d = load(datasets / path)
    assert len(reads) == 1
    alone = reader(datasets / path)
    assert len(reads) == 2
    for name in ("q", "y", "rows"):
        np.testing.assert_array_equal(getattr(d, name), getattr(alone, name))


def test_load_with_robot_and_overrides(datasets):
    d = load(datasets / D1 / "hsr_jr680_cable.csv", robot="hsr-jr680")
    assert (d.robot, len(d)) == ("hsr-jr680", 2017)
    assert load(datasets / D1 / "hsr_jr680_cable.csv", format="hsr").robot == "hsr-jr680"
    assert load(datasets / SERIES["B"], measurement="position").y.shape == (1495, 3)
    with pytest.raises(DataError, match=r"this is robotcali data of the abb-irb120; got robot='ur10'"):
        load(datasets / D2 / "RobotCali.xlsx", robot="ur10")
    with pytest.raises(DataError, match=r"ipa files give joint angles in rad; got angle_unit='deg'"):
        load(datasets / SERIES["B"], angle_unit="deg")
    with pytest.raises(DataError, match=r"hsr files hold cable measurements; got measurement='pose'"):
        load(datasets / D1 / "HSR-RobotCali.xlsx", measurement="pose")


# -- bad input ----------------------------------------------------------------------------------
def write(tmp_path, text, name="f.csv"):
    path = tmp_path / name
    path.write_text(text)
    return path


IPA_HEADER = (
    "Timestamp;shoulder_pan_joint;shoulder_lift_joint;elbow_joint;wrist_1_joint;wrist_2_joint;wrist_3_joint;measurement_temperature;"
    "measurement_x;measurement_y;measurement_z;measurement_rx;measurement_ry;measurement_rz"
)
IPA_ROW = "20200714163904;0,1;0,2;0,3;0,4;0,5;0,6;23,5;1000,5;-20,25;300;-90;-59,5;-90,25"


def test_ipa_minimal_file(tmp_path):
    d = read_ipa(write(tmp_path, f"{IPA_HEADER}\n{IPA_ROW}\n"))
    np.testing.assert_allclose(d.q[0], [0.1, 0.2, 0.3, 0.4, 0.5, 0.6])
    np.testing.assert_allclose(d.y[0, :3], [1000.5, -20.25, 300])
    assert d.t.tolist() == [0.0] and d.temp.tolist() == [23.5]


@pytest.mark.parametrize(
    "reader, text, message, row, column",
    [
        (read_hsr, "", "empty", 1, None),
        (read_hsr, "q1,q2,q3,q4,q5,q6,L\n", "header but no data rows", 2, None),
        (read_hsr, "q1;q2;q3;q4;q5;q6;L\n1;2;3;4;5;6;7\n", "single column containing ';'", 1, None),
        (read_hsr, "q1,q2,q3,q4,q5,q6,L\n1,2,3,4,five,6,7\n", "expected a number; got 'five'", 2, "q5"),
        (read_hsr, "q1,q2,q3,q4,q5,q6,L\n1,2,3,4,5,6,7\n1,2,3,4,5,6,nan\n", "expected a finite number", 3, "L"),
        (read_hsr, "q1,q2,q3,q4,q5,q6,L\n1,2,3,4,5,6,7\n1,2,3,4,5,6\n", "expected 7 cells like the header; got 6", 3, None),
        (read_hsr, "q1,q2,q3,q4,q5,q6,Length\n1,2,3,4,5,6,7\n", r"missing \['L'\]", 1, None),
        (read_hsr, "q1,q2,q3,q4,q5,q6,q7,L\n1,2,3,4,5,6,7,8\n", r"hsr-jr680 has 6 joints .*\['q1', .*'q7'\]", 1, None),
        (read_robotcali, "x,y,zz,q1,q2,q3,q4,q5,q6,L\n1,2,3,4,5,6,7,8,9,10\n", r"missing \['z'\] \(misspelt\? found 'zz' for 'z'\)", 1, None),
        (read_ipa, IPA_HEADER.replace("elbow_joint", "elbow_jiont") + "\n" + IPA_ROW + "\n", "found 'elbow_jiont' for 'elbow_joint'", 1, None),
        (read_ipa, IPA_HEADER.replace(";", ",") + "\n", "single column containing ','", 1, None),
        (read_ipa, IPA_HEADER + "\n" + IPA_ROW.replace("1000,5", "1000,5x") + "\n", "expected a number; got '1000,5x'", 2, "measurement_x"),
        (read_ipa, IPA_HEADER + "\n" + IPA_ROW.replace("20200714163904", "20201314163904") + "\n", "expected a time yyyymmddHHMMSS", 2, "Timestamp"),
    ],
)
def test_bad_files_name_file_row_and_column(tmp_path, reader, text, message, row, column):
    path = write(tmp_path, text)
    with pytest.raises(DataError, match=message) as err:
        reader(path)
    assert (err.value.row, err.value.column) == (row, column)
    assert str(path) in str(err.value)


SEPARATOR_NAMES = {",": "','", ";": "';'", "\t": "tab"}


@settings(suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow])
@given(
    st.sampled_from([(read_hsr, ",", "q1,q2,q3,q4,q5,q6,L"), (read_canonical, ",", "q1,q2,q3,q4,q5,q6,L"), (read_ipa, ";", IPA_HEADER)]),
    st.sampled_from([",", ";", "\t"]),
)
def test_a_file_of_another_separator_is_named_by_its_own(tmp_path, reader_case, used):
    """Issue 52 #20: ``--format ipa`` on a comma file said "this file is ';'-separated". Every
    delimited reader names the separator the file holds as the file's, and its own as expected."""
    reader, expected, header = reader_case
    if used == expected:
        return
    path = write(tmp_path, header.replace(expected, used) + "\n")
    with pytest.raises(DataError) as err:
        reader(path)
    message = str(err.value)
    assert f"this file looks {SEPARATOR_NAMES[used]}-separated" in message
    assert f"the format it is read as is {SEPARATOR_NAMES[expected]}-separated" in message
    assert (err.value.row, str(path) in message) == (1, True)


def test_bad_rows_are_excluded_only_on_request(tmp_path):
    path = write(tmp_path, "q1,q2,q3,q4,q5,q6,L\n1,2,3,4,5,6,7\n1,2,3,4,?,6,7\n\n1,2,3,4,5,6,8\n1,2,3\n")
    with pytest.raises(DataError, match="row 3, column 'q5'"):
        read_hsr(path)
    d = read_hsr(path, exclude_bad_rows=True)
    assert d.rows.tolist() == [2, 5]
    assert d.excluded == [
        {"row": 3, "column": "q5", "reason": "expected a number; got '?'"},
        {"row": 6, "column": None, "reason": "expected 7 cells like the header; got 3"},
    ]
    assert "excluded 2 rows with bad cells (see `excluded`)" in d.notes
    assert load(path, exclude_bad_rows=True, angle_unit="deg").rows.tolist() == [2, 5]  # canonical: the same policy


def test_truncated_and_corrupt_workbooks(datasets, tmp_path):
    data = (datasets / D2 / "RobotCali.xlsx").read_bytes()
    path = tmp_path / "cut.xlsx"
    path.write_bytes(data[: len(data) // 2])
    with pytest.raises(DataError, match="not a readable .xlsx workbook"):
        read_robotcali(path)
    with pytest.raises(DataError, match="not a readable .xlsx workbook"):
        load(path)


def test_workbook_with_text_and_empty_cells(tmp_path):
    openpyxl = pytest.importorskip("openpyxl")
    book = openpyxl.Workbook()
    sheet = book.active
    sheet.append(["q1", "q2", "q3", "q4", "q5", "q6", "L"])
    sheet.append([1, 2, 3, 4, 5, 6, 7])
    sheet.append([1, 2, "n/a", 4, 5, 6, 7])
    sheet.append([1, 2, 3, 4, 5, None, 7])
    path = tmp_path / "d1.xlsx"
    book.save(path)
    with pytest.raises(DataError, match=r"row 3, column 'q3': expected a number; got 'n/a'"):
        load(path)
    d = load(path, exclude_bad_rows=True)
    assert [e["row"] for e in d.excluded] == [3, 4] and d.excluded[1]["reason"] == "expected a number; the cell is empty"


def test_unknown_format_says_what_was_found(tmp_path):
    with pytest.raises(DataError, match=r"unknown format: the first line has 3 ','-separated field\(s\) \['a', 'b', 'c'\]"):
        load(write(tmp_path, "a,b,c\n1,2,3\n"))
    with pytest.raises(DataError, match="`format` must be one of"):
        load(write(tmp_path, "q1,L\n1,2\n"), format="excel")
    with pytest.raises(DataError, match="not a UTF-8 text file"):
        (tmp_path / "b.csv").write_bytes(b"\xff\xfe\x00q1")
        load(tmp_path / "b.csv")
    with pytest.raises(DataError, match="cannot read the file"):
        load(tmp_path / "missing.csv")
    (tmp_path / "u.csv").write_text("q1,q2,q3,q4,q5,q6,L\n1,2,3,4,5,6,7\n", encoding="utf-16")
    with pytest.raises(DataError, match="UTF-16 byte-order mark; save it as UTF-8"):
        load(tmp_path / "u.csv")


def test_a_file_of_only_bad_rows_names_the_first(tmp_path):
    with pytest.raises(DataError, match=r"no valid data rows \(2 rows with bad cells excluded; the first, row 2, column 'q3': expected a number; got 'x'\)"):
        load(write(tmp_path, "q1,q2,q3,q4,q5,q6,L\n1,2,x,4,5,6,7\n1,2,y,4,5,6,7\n"), exclude_bad_rows=True)


def test_robot_joint_count_must_match(tmp_path):
    path = write(tmp_path, "q1,q2,L\n1,2,3\n")
    with pytest.raises(DataError, match=r"robot 'ur10' has 6 joints; the file has 2 joint columns"):
        load(path, robot="ur10")
    assert read_canonical(path).n_joints == 2


def test_errors_are_robocal_errors_and_value_errors(tmp_path):
    with pytest.raises(RobocalError):
        load(write(tmp_path, "nothing"))
    with pytest.raises(ValueError):
        load(write(tmp_path, "nothing"))
