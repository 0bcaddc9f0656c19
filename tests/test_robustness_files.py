"""Issue 28, files and their parsing (rows 1, 6, 11, 12, 17, 25-27, 29-31, 35).

One regression test per row, then a Hypothesis fuzz of corrupted result and robot files: each
corruption is either read as the same model or refused with a robocal error naming the file —
never a traceback, never a silently different model.
"""

from __future__ import annotations

import copy
import json
import math
from pathlib import Path

import numpy as np
import pytest
import robocal
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from robocal.cli import main
from robocal.compensation import read_targets
from robocal.data import load, write_canonical
from robocal.data.dataset import Dataset
from robocal.exceptions import DataError, InvalidParameterError, RobocalError
from robocal.report import report
from robocal.results import load_result
from robocal.robot_file import MAX_DEPTH, read_robot_file
from robocal.simulation import simulate, write_simulation

ROBOT = "ur10"


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    """A position data file of the UR10, its result and the UR10's robot file (degrees)."""
    w = tmp_path_factory.mktemp("files")
    data, truth = simulate(ROBOT, "position", samples=80, seed=2)
    write_simulation(data, truth, w / "pos.csv")
    assert main(["calibrate", str(w / "pos.csv"), "--robot", ROBOT, "--out", str(w / "res.json")]) == 0
    robocal.write_robot(robocal.robot(ROBOT), w / "ur10.json", degrees=True)
    return w


def run(argv, capsys) -> tuple[int, str]:
    """Exit code and stderr of a command line."""
    try:
        code = main([str(a) for a in argv])
    except SystemExit as exc:
        code = exc.code
    return code, capsys.readouterr().err


def edited(files: Path, name: str, change, source: str = "res.json") -> Path:
    """A copy of a JSON file of ``files`` with ``change(doc)`` applied."""
    doc = json.loads((files / source).read_text())
    change(doc)
    path = files / name
    path.write_text(json.dumps(doc))
    return path


# -- row 1: deep nesting -------------------------------------------------------------------------
@pytest.mark.parametrize("suffix", [".json", ".yaml"])
def test_row1_deeply_nested_documents_are_refused_naming_the_file(files, suffix, capsys):
    deep = files / f"deep{suffix}"
    deep.write_text("[" * 100_000 + "]" * 100_000)
    code, err = run(["simulate", "--robot", deep, "--measurement", "position", "--samples", 50, "--out", files / "s.csv"], capsys)
    assert code == 2 and f"{deep}: not a robot file" in err and "nested" in err and "Traceback" not in err
    if suffix == ".json":
        for argv in (
            ["export", deep, "--format", "dh", "--out", files / "x.csv"],
            ["report", files / "res.json", "--diagnosis", deep, "--out", files / "rep_deep"],
            ["calibrate", files / "pos.csv", "--robot", ROBOT, "--causes", deep],
        ):
            code, err = run(argv, capsys)
            assert code == 2 and f"{deep}: not a" in err and "nested" in err, err
    # nesting Python parses but no robocal document has: refused too, in the API
    moderate = files / f"moderate{suffix}"
    moderate.write_text(json.dumps({"schema": "robocal.result/1", "x": json.loads("[" * (MAX_DEPTH + 5) + "]" * (MAX_DEPTH + 5))}))
    with pytest.raises(InvalidParameterError, match=f"{moderate.name}.*nested more than {MAX_DEPTH}"):
        load_result(moderate)


# -- row 6: prismatic joints are mm in canonical files --------------------------------------------
@pytest.fixture(scope="module")
def prism(files) -> Path:
    """The UR10 with its third joint prismatic (0..500 mm), as a robot file."""
    return edited(files, "prism.json", lambda d: d["joints"][2].update(kind="prismatic", limits=[0, 500]), source="ur10.json")


def test_row6_prismatic_columns_are_written_and_read_in_mm(files, prism):
    robot = robocal.robot(str(prism))
    assert robot.prismatic == (2,)
    rng = np.random.default_rng(0)
    q = np.radians(rng.uniform(-90, 90, (30, 6)))
    q[:, 2] = rng.uniform(0, 500, 30)  # mm
    data = Dataset(q=q, y=robot.predict("position", q), measurement="position", prismatic=robot.prismatic)
    write_canonical(data, files / "prism.csv")
    written = np.loadtxt(files / "prism.csv", delimiter=",", skiprows=1)
    np.testing.assert_allclose(written[:, 2], q[:, 2], rtol=1e-15)  # not mm x 180/pi
    back = load(files / "prism.csv", robot=str(prism))
    assert back.prismatic == (2,)
    np.testing.assert_allclose(back.q, q, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(robot.residuals("position", back.q, back.y), 0.0, atol=1e-6)


def test_row6_a_prismatic_column_of_small_mm_is_not_taken_for_radians(files, prism):
    robot = robocal.robot(str(prism))
    rng = np.random.default_rng(1)
    q = np.radians(rng.uniform(-90, 90, (30, 6)))
    q[:, 2] = rng.uniform(0, 3, 30)  # mm, within 2 pi
    write_canonical(Dataset(q=q, y=robot.predict("position", q), measurement="position", prismatic=(2,)), files / "small.csv")
    back = load(files / "small.csv", robot=str(prism))
    np.testing.assert_allclose(back.q[:, 2], q[:, 2], rtol=1e-12)


# -- row 11: a hand-edited result's report -------------------------------------------------------
def test_row11_report_recomputes_plausibility_and_metrics_from_the_values(files):
    path = edited(files, "r_a2.json", lambda d: [p.update(value=p["value"] + 5000) for p in d["parameters"] if p["name"] == "a2"])
    page = report(path, files / "rep_a2").read_text()
    assert "No kinematic parameter moved" not in page
    (a2,) = [p for p in json.loads(path.read_text())["parameters"] if p["name"] == "a2"]
    assert "1 kinematic parameter moved beyond 10 mm" in page and f"<code>a2</code>: {a2['value'] - a2['nominal']:+.0f} mm" in page
    assert "the file was edited or is corrupt" in page
    assert "metrics do not match its values" in page
    clean = report(files / "res.json", files / "rep_clean").read_text()
    assert "the file was edited" not in clean and "they match the result file" in clean


# -- row 12 and 35: corrupt results and robot files ---------------------------------------------
def test_row12_a_result_whose_robot_model_has_fewer_joints_than_its_parameters_is_refused(files, capsys):
    path = edited(files, "r_5j.json", lambda d: d["robot_model"].update(joints=d["robot_model"]["joints"][:5]))
    with pytest.raises(InvalidParameterError, match=r"r_5j.json: robot_model has 5 joints \(42 parameters\).*47 values"):
        load_result(path)
    without_nominal = edited(files, "r_5jb.json", lambda d: (d["robot_model"].update(joints=d["robot_model"]["joints"][:5]), d["robot_model"].pop("nominal")))
    with pytest.raises(InvalidParameterError, match=r"r_5jb.json.*\['alpha6'.*robot_model \(5 joints\); the parameters hold 6 joints"):
        load_result(without_nominal)
    code, err = run(["export", path, "--format", "dh", "--out", files / "r5j.csv"], capsys)
    assert code == 2 and "r_5j.json" in err and not (files / "r5j.csv").exists()


def test_row35_compensate_with_a_five_joint_result_names_the_file_and_the_mismatch(files, capsys):
    path = edited(files, "r_5j35.json", lambda d: d["robot_model"].update(joints=d["robot_model"]["joints"][:5]))
    (files / "t1.csv").write_text("x,y,z\n500,200,300\n")
    code, err = run(["compensate", path, files / "t1.csv", "--out", files / "j.csv"], capsys)
    assert code == 2 and "r_5j35.json: robot_model has 5 joints" in err and "`params`" not in err


def test_row12_unknown_or_repeated_parameters_are_refused(files):
    extra = edited(files, "r_zzz.json", lambda d: d["parameters"].append(dict(d["parameters"][0], name="zzz")))
    with pytest.raises(InvalidParameterError, match=r"r_zzz.json.*\['zzz'\] are not parameters"):
        load_result(extra)
    twice = edited(files, "r_twice.json", lambda d: d["parameters"].append(dict(d["parameters"][6], value=0.0)))
    with pytest.raises(InvalidParameterError, match=r"r_twice.json.*\['a2'\] appear more than once"):
        load_result(twice)


@pytest.mark.parametrize("suffix", [".json", ".yaml"])
def test_row12_duplicate_keys_are_refused_naming_file_and_key(files, suffix, capsys):
    robot = files / f"dk{suffix}"
    if suffix == ".json":
        robot.write_text((files / "ur10.json").read_text().replace('"name": "ur10",', '"name": "ur10", "name": "other",', 1))
    else:
        robot.write_text("name: ur10\nname: other\njoints:\n  - {alpha: 0, a: 100, d: 0, theta: 0}\n")
    code, err = run(["simulate", "--robot", robot, "--measurement", "position", "--samples", 50, "--out", files / "s.csv"], capsys)
    assert code == 2 and f"{robot}: key 'name' appears twice" in err
    result = files / "dm.json"
    result.write_text((files / "res.json").read_text().replace('"method": "lm",', '"method": "lm", "method": "x",', 1))
    assert result.read_text().count('"method"') == 2
    with pytest.raises(InvalidParameterError, match="dm.json: key 'method' appears twice"):
        load_result(result)


# -- row 17: targets columns ---------------------------------------------------------------------
@pytest.mark.parametrize(
    "header, message",
    [("x,y,z,qw,qx", r"only \['qw', 'qx'\] of the quaternion columns"), ("x,y,z,foo", r"unknown columns \['foo'\]"), ("x,y,z,q7", r"unknown columns \['q7'\]")],
)
def test_row17_targets_with_partial_quaternions_or_unknown_columns_are_refused(tmp_path, header, message):
    path = tmp_path / "t.csv"
    path.write_text(header + "\n" + ",".join(["1"] * len(header.split(","))) + "\n")
    with pytest.raises(DataError, match=message + ".*x,y,z, optionally qw,qx,qy,qz") as info:
        read_targets(path, 6)
    assert info.value.path == path and info.value.row == 1


# -- rows 25, 26: delimiters, comments, quotes ---------------------------------------------------
def test_row25_tabs_and_comment_lines_are_named(files, tmp_path):
    text = (files / "pos.csv").read_text()
    (tmp_path / "tab.csv").write_text(text.replace(",", "\t"))
    with pytest.raises(DataError, match="tab-separated.*canonical files are comma-separated"):
        load(tmp_path / "tab.csv")
    (tmp_path / "comment.csv").write_text("# exported by a controller\n" + text)
    with pytest.raises(DataError, match="the first line is a comment.*the header must be the first line") as info:
        load(tmp_path / "comment.csv")
    assert info.value.row == 1


def test_row26_a_quoted_header_is_read_as_the_csv_it_is(files, tmp_path):
    lines = (files / "pos.csv").read_text().splitlines()
    lines[0] = ",".join(f'"{h}"' for h in lines[0].split(","))
    (tmp_path / "quoted.csv").write_text("\n".join(lines) + "\n")
    quoted, plain = load(tmp_path / "quoted.csv", robot=ROBOT), load(files / "pos.csv", robot=ROBOT)
    np.testing.assert_array_equal(quoted.q, plain.q)
    np.testing.assert_array_equal(quoted.y, plain.y)


# -- row 27: quaternion rows ---------------------------------------------------------------------
def test_row27_a_bad_quaternion_names_the_file_and_its_row(tmp_path):
    data, truth = simulate(ROBOT, "pose", samples=20, seed=5)
    write_simulation(data, truth, tmp_path / "pose.csv")
    lines = (tmp_path / "pose.csv").read_text().splitlines()
    cells = lines[3].split(",")
    cells[9] = "5"  # qw of file row 4
    lines[3] = ",".join(cells)
    (tmp_path / "pb.csv").write_text("\n".join(lines) + "\n")
    with pytest.raises(DataError, match="pb.csv, row 4: the quaternion.*unit norm") as info:
        load(tmp_path / "pb.csv")
    assert info.value.row == 4
    (tmp_path / "t.csv").write_text("x,y,z,qw,qx,qy,qz\n500,200,300,1,0,0,0\n500,200,300,2,0,0,0\n")
    with pytest.raises(DataError, match=r"t.csv, row 3: the quaternion.*got norm 2"):
        read_targets(tmp_path / "t.csv", 6)


# -- row 29: xlsx formulas -------------------------------------------------------------------------
def test_row29_a_formula_without_cached_value_is_named_as_such(tmp_path):
    openpyxl = pytest.importorskip("openpyxl")
    book = openpyxl.Workbook()
    sheet = book.active
    sheet.append(["q1", "q2", "q3", "q4", "q5", "q6", "L"])
    for k in range(12):
        sheet.append([10.0 * k, 5.0, -3.0, 20.0, 30.0, 40.0, 1000.0 + k])
    sheet["G5"] = "=G4+1"  # openpyxl writes no cached value
    book.save(tmp_path / "f.xlsx")
    with pytest.raises(DataError, match=r"the cell holds the formula '=G4\+1' without a cached value: open and save") as info:
        load(tmp_path / "f.xlsx")
    assert (info.value.row, info.value.column) == (5, "L") and "empty" not in str(info.value)


# -- rows 30, 31: robot-file limits and huge parameters -----------------------------------------
def test_row30_bad_limits_name_the_file_and_joint_in_degrees(files, capsys):
    for limits in ([10, -10], [5, 5]):
        path = edited(files, "lim.json", lambda d, limits=limits: d["joints"][0].update(limits=limits), source="ur10.json")
        with pytest.raises(InvalidParameterError, match=rf"lim.json: joint 1, key 'limits'.*got \[{limits[0]}.0, {limits[1]}.0\] \(deg\)"):
            read_robot_file(path)
    code, err = run(["simulate", "--robot", path, "--measurement", "position", "--samples", 50, "--out", files / "s.csv"], capsys)
    assert code == 2 and "lim.json: joint 1" in err and "0.1745" not in err


def test_row30_missing_limits_in_a_radian_document_are_180_degrees(tmp_path):
    doc = {"units": {"angle": "rad"}, "joints": [{"alpha": 0, "a": 100, "d": 0, "theta": 0}]}
    (tmp_path / "r.json").write_text(json.dumps(doc))
    assert read_robot_file(tmp_path / "r.json").joints[0].limits == (-math.pi, math.pi)


def test_row31_a_huge_parameter_is_named_with_its_file(files, capsys):
    path = edited(files, "r_1e300.json", lambda d: [p.update(value=1e300) for p in d["parameters"] if p["name"] == "a2"])
    code, err = run(["export", path, "--format", "dh", "--out", files / "e.csv"], capsys)
    assert code == 2 and "r_1e300.json: a2 must lie within" in err and "index 6" in err and not (files / "e.csv").exists()
    robot = edited(files, "a300.json", lambda d: d["joints"][1].update(a=1e300), source="ur10.json")
    with pytest.raises(InvalidParameterError, match="a300.json: a2 must lie within"):
        read_robot_file(robot)


# -- the class: corrupted documents ------------------------------------------------------------
def _corrupt(doc: dict, kind: str, k: int):
    """``doc`` (a result document) with one corruption; returns (text, expect_same_model)."""
    doc = copy.deepcopy(doc)
    model = doc["robot_model"]
    if kind == "nest":
        doc["parameters"][k % len(doc["parameters"])]["value"] = json.loads("[" * (MAX_DEPTH + 1 + k) + "1" + "]" * (MAX_DEPTH + 1 + k))
    elif kind == "drop_required":
        where, key = [
            (doc, "parameters"),
            (doc, "robot_model"),
            (doc, "measurement"),
            (model, "joints"),
            (model["joints"][k % 6], "alpha"),
            (model["joints"][k % 6], "a"),
            (doc["parameters"][k % 40], "value"),
            (doc["parameters"][k % 40], "name"),
        ][k % 8]
        del where[key]
    elif kind == "extra_strict":
        target = [model, model["joints"][k % 6], model["base"], model["sensor"]][k % 4]
        target["hayatti"] = True
    elif kind == "extra_open":  # top-level keys beyond the schema are kept, not read
        doc["note"] = "hand-written"
        return json.dumps(doc), True
    elif kind == "cut_joints":
        model["joints"] = model["joints"][: 1 + k % 5]
    elif kind == "add_joint":
        model["joints"].append(dict(model["joints"][0]))
    elif kind == "drop_parameter":
        del doc["parameters"][k % len(doc["parameters"])]
    elif kind == "rename_parameter":
        doc["parameters"][k % len(doc["parameters"])]["name"] += "x"
    elif kind == "wrong_type":
        doc["parameters"][k % len(doc["parameters"])]["value"] = str(doc["parameters"][k % len(doc["parameters"])]["value"])
    elif kind == "nominal_length":
        model["nominal"] = model["nominal"][: -1 - k % 5]
    text = json.dumps(doc)
    if kind == "duplicate_key":
        text = text.replace('"measurement": ', '"measurement": "pose", "measurement": ', 1)
    return text, False


KINDS = [
    "nest",
    "drop_required",
    "extra_strict",
    "extra_open",
    "cut_joints",
    "add_joint",
    "drop_parameter",
    "rename_parameter",
    "wrong_type",
    "nominal_length",
    "duplicate_key",
]


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow])
@given(kind=st.sampled_from(KINDS), k=st.integers(0, 200), seed=st.integers(0, 2**16))
def test_corrupted_result_files_are_read_alike_or_refused_naming_the_file(files, kind, k, seed):
    original, doc = load_result(files / "res.json")
    text, same = _corrupt(doc, kind, k)
    path = files / f"fuzz_{seed}.json"
    path.write_text(text)
    try:
        robot, _ = load_result(path)
    except RobocalError as exc:
        assert not same, f"{kind}: refused a file that holds the same model: {exc}"
        assert str(path) in str(exc), f"{kind}: the error does not name the file: {exc}"
        return
    finally:
        path.unlink()
    assert same, f"{kind} was accepted"
    assert robot.joints == original.joints
    np.testing.assert_array_equal(robot.params, original.params)


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow])
@given(k=st.integers(0, 10_000), cut=st.integers(1, 40), suffix=st.sampled_from([".json", ".yaml"]))
def test_truncated_or_nested_robot_files_never_give_a_traceback(files, k, cut, suffix):
    """A robot file cut short, wrapped in brackets, or with one character doubled: read as a
    robot or refused naming the file."""
    text = (files / "ur10.json").read_text()
    variants = [text[: len(text) - cut], "[" * k + text + "]" * k, text[: k % len(text)] + text[k % len(text)] + text[k % len(text) :]]
    for n, variant in enumerate(variants):
        path = files / f"fuzz_robot_{n}{suffix}"
        path.write_text(variant)
        try:
            robot = read_robot_file(path)
        except RobocalError as exc:
            assert str(path) in str(exc)
        else:
            assert robot.n_joints >= 1 and np.all(np.isfinite(robot.params))
        finally:
            path.unlink()
