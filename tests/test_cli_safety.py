"""Issue 14: nothing lost, nothing leaked, no traceback.

Regression tests for every bad input the issue lists, then a Hypothesis fuzz of the command line
over every subcommand and option: never a traceback, never a hang, never an input changed.
"""

from __future__ import annotations

import errno
import hashlib
import json
import os
import signal
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, event, given, settings
from hypothesis import strategies as st

import robocal
from robocal.cli import COMMANDS, main
from robocal.exceptions import InvalidParameterError, OutputError, RobocalError
from robocal.data import write_canonical
from robocal.simulation import simulate, write_simulation

ROBOT = "abb-irb120"


def digest(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def snapshot(folder: Path) -> dict:
    return {p.name: digest(p) for p in sorted(folder.iterdir()) if p.is_file()}


@pytest.fixture(scope="module")
def inputs(tmp_path_factory):
    """A folder of inputs: data, a result, targets, a robot file, a diagnose report."""
    w = tmp_path_factory.mktemp("inputs")
    data, truth = simulate(ROBOT, "cable", samples=60, seed=3)
    write_simulation(data, truth, w / "d.csv", w / "truth.json")
    assert main(["calibrate", str(w / "d.csv"), "--robot", ROBOT, "--out", str(w / "result.json")]) == 0
    robot = robocal.robot(ROBOT)
    q = np.radians([[10, -20, 30, 40, 50, 60], [0, 0, 0, 0, 30, 0]])
    xyz = robot.predict("position", q)
    (w / "targets.csv").write_text("x,y,z\n" + "\n".join(",".join(f"{v:.6f}" for v in p) for p in xyz) + "\n")
    (w / "robot.json").write_text(
        json.dumps({"name": "two", "joints": [{"alpha": 0, "a": 300, "d": 0, "theta": 0}, {"alpha": 0, "a": 200, "d": 0, "theta": 0}]})
    )
    (w / "diag.json").write_text(json.dumps({"baseline": {"rmse_heldout": 0.1}, "effects": [], "model": {"causes": []}}))
    return w


def run(argv, capsys) -> tuple[int, str, str]:
    try:
        code = main([str(a) for a in argv])
    except SystemExit as exc:  # argparse: a usage line and exit status 2
        code = exc.code
    out, err = capsys.readouterr()
    return code, out, err


def refused(argv, capsys, *words) -> str:
    code, _, err = run(argv, capsys)
    assert code == 2, err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("robocal: error: "), err
    for w in words:
        assert w in lines[0], (w, lines[0])
    return lines[0]


# -- 1. an output that names an input ------------------------------------------------------------
@pytest.mark.parametrize(
    "argv",
    [
        ["calibrate", "{w}/d.csv", "--robot", ROBOT, "--out", "{w}/d.csv"],
        ["inspect", "{w}/d.csv", "--json", "{w}/d.csv"],
        ["compensate", "{w}/result.json", "{w}/targets.csv", "--out", "{w}/targets.csv"],
        ["compensate", "{w}/result.json", "{w}/targets.csv", "--out", "{w}/result.json"],
        ["export", "{w}/result.json", "--format", "dh", "--out", "{w}/result.json"],
        ["simulate", "--robot", "{w}/robot.json", "--samples", "20", "--out", "{w}/robot.json"],
        ["diagnose", "{w}/d.csv", "--robot", ROBOT, "--json", "{w}/d.csv"],
        ["calibrate", "{w}/d.csv", "--robot", ROBOT, "--out", "{w}/./sub/../d.csv"],
    ],
)
def test_an_output_that_is_an_input_is_refused_and_the_input_kept(inputs, capsys, argv):
    (inputs / "sub").mkdir(exist_ok=True)
    before = snapshot(inputs)
    refused([a.format(w=inputs) for a in argv], capsys, "is the input", "destroy")
    assert snapshot(inputs) == before


@pytest.mark.parametrize(
    "argv",
    [
        ["export", "{w}/result.json", "--format", "urdf", "--out", "{w}/d.csv"],
        ["compensate", "{w}/result.json", "{w}/targets.csv", "--out", "{w}/d.csv"],
        ["plan", "--from", "{w}/result.json", "--poses", "12", "--out", "{w}/d.csv"],
    ],
)
def test_an_output_that_is_a_results_training_data_is_refused(inputs, capsys, argv):
    """`export result.json --out data.csv` replaced the data the result was fitted on (and records by SHA-256)."""
    before = snapshot(inputs)
    refused([a.format(w=inputs) for a in argv], capsys, "training data of", "result.json", "destroy")
    assert snapshot(inputs) == before


def test_a_hard_link_to_an_input_is_the_input(inputs, tmp_path, capsys):
    link = tmp_path / "alias.csv"
    os.link(inputs / "d.csv", link)
    before = digest(inputs / "d.csv")
    refused(["calibrate", inputs / "d.csv", "--robot", ROBOT, "--out", link], capsys, "is the input")
    assert digest(inputs / "d.csv") == before


def test_simulate_refuses_one_file_for_both_outputs(tmp_path, capsys):
    refused(["simulate", "--samples", "20", "--out", tmp_path / "s.csv", "--truth", tmp_path / "s.csv"], capsys, "two outputs")
    assert not (tmp_path / "s.csv").exists()


# -- 2. unusable output paths ------------------------------------------------------------------
def test_simulate_with_a_bad_truth_path_writes_nothing(tmp_path, capsys):
    refused(["simulate", "--samples", "20", "--out", tmp_path / "s.csv", "--truth", tmp_path / "nodir" / "t.json"], capsys, "does not exist")
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize(
    "argv, words",
    [
        (["calibrate", "{w}/d.csv", "--robot", ROBOT, "--out", "{t}/nodir/r.json"], ["nodir", "does not exist"]),
        (["calibrate", "{w}/d.csv", "--robot", ROBOT, "--out", "{t}"], ["is a folder"]),
        (["export", "{w}/result.json", "--format", "urdf", "--out", "{t}/nodir/r.urdf"], ["does not exist"]),
        (["compensate", "{w}/result.json", "{w}/targets.csv", "--out", "{t}"], ["is a folder"]),
        (["report", "{w}/result.json", "--out", "{w}/d.csv"], ["exists and is not a folder"]),
        (["report", "{w}/result.json", "--out", "{w}"], ["not empty", "--force"]),
        (["report", "{w}/result.json", "--out", "{w}", "--force"], ["holds the input"]),
        (["compare", "{w}/d.csv", "--robot", ROBOT, "--out", "{w}"], ["not empty", "--force"]),
        (["diagnose", "{w}/d.csv", "--robot", ROBOT, "--out", "{w}"], ["not empty", "--force"]),
        (["demo", "--out", "{w}"], ["not empty", "--force"]),
        (["demo", "--out", "{w}/d.csv"], ["exists and is not a folder"]),
        (["inspect", "{t}/missing.csv"], ["missing.csv", "cannot read"]),
        (["export", "{t}/missing.json", "--format", "dh", "--out", "{t}/x.csv"], ["missing.json", "cannot read"]),
    ],
)
def test_unusable_output_paths_are_one_line_errors(inputs, tmp_path, capsys, argv, words):
    before = snapshot(inputs)
    refused([a.format(w=inputs, t=tmp_path) for a in argv], capsys, *words)
    assert snapshot(inputs) == before


def test_an_unwritable_folder_is_named(inputs, tmp_path, capsys):
    if os.geteuid() == 0:
        locked = Path("/proc")  # root may write anywhere on disk, but not into /proc
    else:
        locked = tmp_path / "locked"
        locked.mkdir()
        locked.chmod(0o500)
    line = refused(["calibrate", inputs / "d.csv", "--robot", ROBOT, "--out", locked / "r.json"], capsys, str(locked))
    assert "not writable" in line or "cannot write it" in line


def test_report_overwrites_an_existing_folder_only_with_force(inputs, tmp_path, capsys):
    out = tmp_path / "rep"
    assert run(["report", inputs / "result.json", "--out", out], capsys)[0] == 0
    first = digest(out / "index.html")
    refused(["report", inputs / "result.json", "--out", out], capsys, "--force")
    assert run(["report", inputs / "result.json", "--out", out, "--force"], capsys)[0] == 0
    assert digest(out / "index.html") == first
    assert not [p for p in out.iterdir() if p.name.startswith(".")]  # no temporary left behind


def test_a_failed_write_leaves_the_old_file_and_no_temporary(tmp_path, monkeypatch):
    from robocal import outputs

    target = tmp_path / "r.json"
    target.write_text("old")

    def full(*_):
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(outputs.os, "replace", full)
    with pytest.raises(OutputError, match=r"r.json: cannot write it \(No space left on device\)"):
        outputs.write_json(target, {"a": 1})
    assert target.read_text() == "old" and list(tmp_path.iterdir()) == [target]


def test_outputs_get_the_usual_file_mode(tmp_path):
    from robocal import outputs

    new = outputs.write_text(tmp_path / "new.txt", "x")
    mask = os.umask(0)
    os.umask(mask)
    assert new.stat().st_mode & 0o777 == 0o666 & ~mask  # not mkstemp's 0o600
    old = tmp_path / "old.txt"
    old.write_text("y")
    old.chmod(0o640)
    outputs.write_text(old, "z")
    assert old.stat().st_mode & 0o777 == 0o640 and old.read_text() == "z"


def test_os_errors_anywhere_are_exit_2_naming_the_path(inputs, tmp_path, capsys, monkeypatch):
    import robocal.cli.inspect as ins

    def broken(*_args, **_kw):
        raise PermissionError(errno.EACCES, "Permission denied", str(tmp_path / "x"))

    monkeypatch.setattr(ins, "inspect", broken)
    refused(["inspect", inputs / "d.csv"], capsys, str(tmp_path / "x"), "Permission denied")


def test_export_replaces_its_file_only_after_the_round_trip(inputs, tmp_path, capsys, monkeypatch):
    import robocal.export as ex

    out = tmp_path / "t.csv"
    out.write_text("previous good export")
    monkeypatch.setattr(ex, "POSITION_TOL", -1.0)  # every round trip fails
    code, stdout, _ = run(["export", inputs / "result.json", "--format", "dh", "--out", out], capsys)
    assert code == 1 and "not written" in stdout
    assert out.read_text() == "previous good export" and list(tmp_path.iterdir()) == [out]


# -- 3. report: no leak, everything escaped ------------------------------------------------------
def test_report_reads_only_the_file_whose_hash_the_result_records(inputs, tmp_path, capsys):
    secret = tmp_path / "secret.csv"
    secret.write_text("q1,q2,q3,q4,q5,q6,L\nTOP-SECRET-LINE,2,3,4,5,6,7\n")
    doc = json.loads((inputs / "result.json").read_text())
    doc["dataset"]["source"] = str(secret)
    doc["robot"] = "<script>alert(1)</script>"
    forged = tmp_path / "forged.json"
    forged.write_text(json.dumps(doc))
    assert run(["report", forged, "--out", tmp_path / "html"], capsys)[0] == 0
    page = (tmp_path / "html" / "index.html").read_text()
    assert "TOP-SECRET" not in page and "<script>" not in page and "&lt;script&gt;" in page
    assert "sha256 does not match" in page
    doc["dataset"]["sha256"] = digest(secret)  # the hash matches: read, but its content still not shown
    forged.write_text(json.dumps(doc))
    assert run(["report", forged, "--out", tmp_path / "html2"], capsys)[0] == 0
    assert "TOP-SECRET" not in (tmp_path / "html2" / "index.html").read_text()


def test_report_writes_terminal_controls_from_a_result_as_escapes(inputs, tmp_path, capsys):
    doc = json.loads((inputs / "result.json").read_text())
    doc["robot"] = "arm\x1b[2J\u202eX"  # erase the screen; show what follows reversed
    forged = tmp_path / "forged.json"
    forged.write_text(json.dumps(doc))
    assert run(["report", forged, "--out", tmp_path / "html"], capsys)[0] == 0
    page = (tmp_path / "html" / "index.html").read_text()
    assert "\x1b" not in page and "\u202e" not in page and r"arm\x1b[2J\u202eX" in page


def test_report_of_a_result_with_a_text_value_is_an_error(inputs, tmp_path, capsys):
    doc = json.loads((inputs / "result.json").read_text())
    doc["parameters"][0]["value"] = "250"
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps(doc))
    refused(["report", bad, "--out", tmp_path / "r"], capsys, "parameter 1, key 'value'", "valid number", "'250'")


# -- 4. robot files ------------------------------------------------------------------------------
@pytest.mark.parametrize(
    "change, words",
    [
        ({"hayatti": True}, ["joint 2, key 'hayatti'", "unknown key"]),
        ({"limit": [-10, 10]}, ["joint 2, key 'limit'", "unknown key"]),
        ({"hayati": "no"}, ["joint 2, key 'hayati'", "valid boolean", "'no'"]),
        ({"a": True}, ["joint 2, key 'a'", "valid number"]),
        ({"kind": "spherical"}, ["joint 2, key 'kind'", "'revolute' or 'prismatic'"]),
        ({"limits": [1, 2, 3]}, ["joint 2, key 'limits'", "at most 2"]),
    ],
)
def test_robot_files_are_read_strictly(tmp_path, change, words):
    spec = {"name": "two", "joints": [{"alpha": 0, "a": 300, "d": 0, "theta": 0}, {"alpha": 0, "a": 200, "d": 0, "theta": 0, **change}]}
    path = tmp_path / "r.json"
    path.write_text(json.dumps(spec))
    with pytest.raises(InvalidParameterError) as info:
        robocal.robot(str(path))
    assert str(path) in str(info.value)
    for w in words:
        assert w in str(info.value)


def test_a_prismatic_joint_is_prismatic(tmp_path):
    path = tmp_path / "r.yaml"
    path.write_text("joints:\n  - {alpha: 0, a: 300, d: 0, theta: 0}\n  - {alpha: 0, a: 0, d: 100, theta: 0, kind: prismatic, limits: [0, 500]}\n")
    r = robocal.robot(str(path))
    assert [j.kind for j in r.joints] == ["revolute", "prismatic"] and r.joints[1].limits == (0.0, 500.0)
    np.testing.assert_allclose(r.fkine([0.0, 50.0])[0, 2, 3], 150.0)  # d + q along z


# -- 5. units ------------------------------------------------------------------------------------
def _write_rad(inputs, path):
    lines = (inputs / "d.csv").read_text().splitlines()
    header = lines[0].split(",")
    rows = [[repr(float(np.radians(float(v)))) if h.startswith("q") else v for h, v in zip(header, line.split(","))] for line in lines[1:]]
    path.write_text("\n".join([lines[0]] + [",".join(r) for r in rows]) + "\n")


def test_radians_in_a_degree_file_are_refused_unless_said(inputs, tmp_path, capsys):
    rad = tmp_path / "rad.csv"
    _write_rad(inputs, rad)
    refused(["calibrate", rad, "--robot", ROBOT], capsys, "q1..q6", "look like radians", "--angle-unit rad")
    refused(["compare", rad, "--robot", ROBOT, "--out", tmp_path / "c"], capsys, "look like radians")
    code, out, _ = run(["calibrate", rad, "--robot", ROBOT, "--angle-unit", "rad"], capsys)
    assert code == 0 and "RMSE 0.0" in out


def test_degrees_read_as_radians_are_noted(inputs, capsys):
    code, out, _ = run(["calibrate", inputs / "d.csv", "--robot", ROBOT, "--angle-unit", "rad"], capsys)
    assert code == 0 and "look like degrees" in out and "kept in rad as asked" in out


# -- 6. data -------------------------------------------------------------------------------------
def _canonical(tmp_path, header, rows, name="x.csv") -> Path:
    path = tmp_path / name
    path.write_text(header + "\n" + "\n".join(rows) + "\n")
    return path


@pytest.mark.parametrize(
    "header, row, words",
    [
        ("q1,q2,q3,q4,q5,q6,L,L", "10,20,30,40,50,60,900,901", ["row 1, column 'L'", "more than once"]),
        ("q1,q2,q3,q4,q5,q6,L", "10,20,30,40,50,60,1_0", ["row 2, column 'L'", "expected a number; got '1_0'"]),
        ("q1,q2,q3,q4,q5,q6,L", "10,20,30,40,50,60,1e300", ["row 2, column 'L'", "beyond"]),
        ("q1,q2,q3,q4,q5,q6,L", "10,20,30,40,50,60,０", ["row 2, column 'L'", "expected a number"]),
    ],
)
def test_bad_cells_name_file_row_and_column(tmp_path, capsys, header, row, words):
    path = _canonical(tmp_path, header, [row] * 30)
    refused(["calibrate", path, "--robot", ROBOT], capsys, str(path), *words)


def test_a_huge_cell_is_not_echoed(tmp_path, capsys):
    path = _canonical(tmp_path, "q1,q2,q3,q4,q5,q6,L", ["10,20,30,40,50,60," + "9" * 100000 + "x"])
    line = refused(["calibrate", path, "--robot", ROBOT], capsys, "row 2, column 'L'", "100001 characters")
    assert len(line) < 400


def test_duplicate_target_columns_are_refused(inputs, tmp_path, capsys):
    path = _canonical(tmp_path, "x,y,z,x", ["1,2,3,4"], "t.csv")
    refused(["compensate", inputs / "result.json", path, "--out", tmp_path / "j.csv"], capsys, "column 'x'", "more than once")


def test_forty_thousand_columns_are_refused(tmp_path, capsys):
    header = ",".join([f"q{i}" for i in range(1, 40001)] + ["L"])
    path = _canonical(tmp_path, header, [",".join(["1"] * 40001)])
    refused(["calibrate", path, "--robot", ROBOT], capsys, "6 joints", "40000 joint columns")


@pytest.mark.parametrize(
    "argv",
    [
        ["export", "{w}/result.json", "--format", "dh", "--out", "{t}/x.csv", "--samples", "100000000"],
        ["simulate", "--samples", "100000000", "--out", "{t}/s.csv"],
    ],
)
def test_sample_counts_are_bounded(inputs, tmp_path, capsys, argv):
    refused([a.format(w=inputs, t=tmp_path) for a in argv], capsys, "at most 1,000,000")
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize(
    "argv,words",
    [
        (["plan", "--robot", ROBOT, "--measurement", "cable", "--poses", "1000000"], "`--poses` must be at most 500"),
        (["plan", "--robot", ROBOT, "--measurement", "cable", "--poses", "300", "--candidates", "100"], "`--candidates` must be an integer >= 300"),
        (["plan", "--measurement", "cable", "--poses", "10"], "pass `--robot`"),
        (["plan", "--robot", ROBOT, "--measurement", "cable", "--poses", "10", "--joint-range", "9=1,2"], "`--joint-range`: joint 9 is not a joint"),
        (["simulate", "--samples", "0"], "`--samples` must be an integer >= 1"),
    ],
)
def test_errors_name_the_option_not_the_librarys_argument(tmp_path, capsys, argv, words):
    """Issue 52 #15: the library's argument names (`candidates`, `robot`, `joint_ranges`) are the options the user typed."""
    refused([*argv, "--out", tmp_path / "p.csv"], capsys, words)


def test_a_joint_range_is_refused_in_the_degrees_it_was_given(tmp_path, capsys):
    """Issue 52 #15: `2=10,10` was echoed in radians as `joint_ranges[2]`."""
    code, _, err = run(["plan", "--robot", ROBOT, "--measurement", "cable", "--poses", "10", "--joint-range", "2=10,10", "--out", tmp_path / "p.csv"], capsys)
    assert code == 2 and err.strip().splitlines()[-1].endswith("argument --joint-range: expected J=LO,HI with LO < HI; got '2=10,10'")


def test_too_few_samples_say_what_needs_how_many(inputs, tmp_path, capsys):
    lines = (inputs / "d.csv").read_text().splitlines()
    one = _canonical(tmp_path, lines[0], lines[1:2], "one.csv")
    refused(["calibrate", one, "--robot", ROBOT], capsys, "needs at least 2 samples; the data have 1")
    refused(["compare", one, "--robot", ROBOT, "--out", tmp_path / "c"], capsys, "needs at least 120 samples; the data have 1")
    sixteen = _canonical(tmp_path, lines[0], lines[1:17], "sixteen.csv")
    refused(["calibrate", sixteen, "--robot", ROBOT, "--test-fraction", "0"], capsys, "16 residuals for 16 identifiable parameters", "0 degrees of freedom")


def test_diagnose_refuses_before_any_work(inputs, tmp_path, capsys, monkeypatch):
    """Issue 52 #17 and #19: one path for --json and --out, and a session too small for the folds,
    are refused before the first diagnosis, naming the path (they came after seconds of work)."""
    import robocal.diagnosis as diagnosis
    from robocal.diagnosis import sessions

    def work(*_args, **_kw):
        raise AssertionError("the diagnosis of a session started")

    monkeypatch.setattr(diagnosis, "diagnose_session", work)  # one session
    monkeypatch.setattr(sessions, "diagnose", work)  # each session of several
    same = tmp_path / "X"
    refused(
        ["diagnose", inputs / "d.csv", "--robot", ROBOT, "--json", same, "--out", same], capsys, f"{same}: the same path", "output file and as an output folder"
    )
    assert not same.exists()
    paths = []
    for session, rows in ((1, 60), (2, 3)):
        data, _ = simulate(ROBOT, "cable", samples=rows, seed=3, session=session)
        paths.append(write_canonical(data, tmp_path / f"s{session}.csv"))
    refused(["diagnose", inputs / "d.csv", *paths, "--robot", ROBOT], capsys, f"{paths[1]}: diagnose needs at least 20 samples for 5 folds; got 3")


def test_documented_optional_columns_are_accepted(inputs, tmp_path, capsys):
    lines = (inputs / "d.csv").read_text().splitlines()
    path = _canonical(tmp_path, lines[0] + ",temp,sample", [f"{line},,S{i}" for i, line in enumerate(lines[1:])])
    code, out, err = run(["--quiet", "calibrate", path, "--robot", ROBOT, "--quiet"], capsys)
    assert code == 0, err
    d = robocal.load(path)
    assert np.isnan(d.temp).all() and not any("sample" in n for n in d.notes)


def test_public_functions_take_what_users_pass(inputs):
    result = robocal.calibrate(str(inputs / "d.csv"), robot=ROBOT, test_fraction="0.2")  # a number given as text
    assert result.metrics["test"]["n"] == 12
    rows = robocal.compensate(str(inputs / "result.json"), np.array([[400.0, 300.0, 500.0]]))
    assert len(rows) == 1 and rows[0]["row"] == 2
    for bad in (np.zeros(3), "not-a-number", None):
        with pytest.raises(RobocalError):
            robocal.compensate(str(inputs / "result.json"), bad if bad is not None else np.zeros((2, 4)))
    with pytest.raises(InvalidParameterError, match="test_fraction"):
        robocal.calibrate(str(inputs / "d.csv"), robot=ROBOT, test_fraction="a fifth")


@settings(max_examples=40, deadline=None, derandomize=True, suppress_health_check=list(HealthCheck))
@given(
    fraction=st.one_of(st.floats(allow_nan=True), st.text(max_size=6), st.none(), st.booleans(), st.lists(st.floats(), max_size=2)),
    targets=st.one_of(st.lists(st.lists(st.floats(-2000, 2000), min_size=0, max_size=8), max_size=3), st.text(max_size=6), st.integers(), st.none()),
)
def test_fuzz_the_public_functions_users_call_first(inputs, fraction, targets):
    """``calibrate(test_fraction=...)`` and ``compensate(result, targets)``: a result or a
    robocal error, never a TypeError from inside."""
    for call in (
        lambda: robocal.calibrate(str(inputs / "d.csv"), robot=ROBOT, test_fraction=fraction, max_nfev=5),
        lambda: robocal.compensate(str(inputs / "result.json"), targets),
    ):
        try:
            call()
        except RobocalError:
            pass


# -- 7. the fuzz -----------------------------------------------------------------------------------
def _pools(w: Path, t: Path) -> dict:
    """Per kind of argument, values that should work and values that should not (wrong, hostile,
    an input named as an output); each is drawn half of the time."""
    anything = [w / "d.csv", w / "result.json", w / "targets.csv", w / "robot.json", w / "diag.json", t / "missing.csv", w, "/dev/null", "", "\x00x"]
    return {
        "data": ([w / "d.csv"], anything),
        "result": ([w / "result.json"], anything),
        "targets": ([w / "targets.csv"], anything),
        "diagnosis": ([w / "diag.json"], anything),
        "out": ([t / "new.csv", t / "new.json", "-"], anything + [t / "nodir" / "x.csv", t, "/proc/nope/x"]),
        "folder": ([t / "fresh"], [w, w / "d.csv", t / "nodir" / "deep", "/proc/nope", "\x00"]),
        "robot": ([ROBOT], ["ur10", "nope", w / "robot.json", w / "d.csv", ""]),
        "int": (["1", "2", "3"], ["0", "-3", "x", "1e3", "100000000", "99999999999999999999"]),
        "float": (["0.2", "0.05"], ["0", "-1", "nan", "inf", "1e400", "abc", "0.99"]),
        "text": ([], []),
    }


#: Per subcommand: the kinds of its positional arguments, and its options with the kind each
#: takes (None: a flag). Heavy runs are pinned small (compare: one lm split; diagnose: 2 folds;
#: demo: its output folder is drawn from refused ones) so that the fuzz stays well under a minute.
SPECS = {
    "demo": ([], {"--out": "folder", "--samples": "int", "--seed": "int"}),
    "inspect": (
        ["data"],
        {"--robot": "robot", "--format": "text", "--angle-unit": "text", "--measurement": "text", "--sigmas": "float", "--json": "out", "--strict": None},
    ),
    "calibrate": (
        ["data"],
        {
            "--robot": "robot",
            "--measurement": "text",
            "--method": "text",
            "--test-fraction": "float",
            "--seed": "int",
            "--kinematic-prior": "text",
            "--loss": "text",
            "--causes": "diagnosis",
            "--prior": "result",
            "--out": "out",
            "--json": None,
            "--angle-unit": "text",
        },
    ),
    "simulate": (
        [],
        {
            "--robot": "robot",
            "--measurement": "text",
            "--samples": "int",
            "--seed": "int",
            "--session": "int",
            "--effect": "text",
            "--noise": "float",
            "--outliers": "float",
            "--no-geometric-error": None,
            "--out": "out",
            "--truth": "out",
        },
    ),
    "compare": (
        ["data"],
        {
            "--robot": "robot",
            "--measurement": "text",
            "--subset": "int",
            "--seed": "int",
            "--kinematic-prior": "text",
            "--out": "folder",
            "--force": None,
            "--angle-unit": "text",
        },
    ),
    "diagnose": (
        ["data"],
        {
            "--robot": "robot",
            "--measurement": "text",
            "--alpha": "float",
            "--plain-dh": None,
            "--seed": "int",
            "--json": "out",
            "--out": "folder",
            "--force": None,
        },
    ),
    "compensate": (["result", "targets"], {"--out": "out", "--angle-unit": "text", "--frame": "text", "--user-frame": "text"}),
    "verify": (["result", "data"], {"--measurement": "text", "--angle-unit": "text", "--json": "out"}),
    "monitor": (
        ["result", "data"],
        {"--json-lines": "out", "--out": "out", "--new-session": None, "--mean-run-length": "float", "--opening": "int", "--angle-unit": "text"},
    ),
    "report": (["result"], {"--out": "folder", "--data": "data", "--diagnosis": "diagnosis", "--force": None, "--angle-unit": "text"}),
    "export": (
        ["result"],
        {"--format": "text", "--table-format": "text", "--out": "out", "--name": "text", "--samples": "int", "--seed": "int", "--angles": "text"},
    ),
    "plan": (
        [],
        {
            "--robot": "robot",
            "--measurement": "text",
            "--poses": "int",
            "--from": "result",
            "--data": "data",
            "--out": "out",
            "--json": "out",
            "--seed": "int",
            "--noise": "float",
            "--passes": "int",
            "--criterion": "text",
            "--angle-unit": "text",
        },
    ),
}
#: Values of the options that take a word: the valid ones and some that are not.
CHOICES = {
    "--format": ["dh", "mdh", "urdf", "ur-yaml", "canonical", "sdf"],
    "--angle-unit": ["deg", "rad", "grad"],
    "--measurement": ["cable", "position", "pose"],
    "--method": ["lm", "vslm", "nope"],
    "--loss": ["huber", "linear", "l1"],
    "--table-format": ["csv", "json", "xlsx"],
    "--kinematic-prior": ["10,1", "1", "a,b", "-1,0"],
    "--effect": ["backlash:joint=2", "wobble", "joint_periodic:joint=9"],
    "--name": ["r", "<b>&"],
    "--frame": ["base", "session", "session:1", "session:2", "user", "tool", "session:0"],
    "--angles": ["readings", "model", "raw"],
    "--criterion": ["I", "D", "Ds", "ds"],
    "--user-frame": ["0,0,0,0,0,0", "100,0,500,0,0,90", "1,2,3", "a,b,c,d,e,f", "nan,0,0,0,0,0"],
}
#: Options always drawn (required, or without which the canonical file cannot be calibrated).
REQUIRED = {
    "export": ["--format", "--out"],
    "compensate": ["--out"],
    "report": ["--out"],
    "simulate": ["--out"],
    "compare": ["--out", "--robot"],
    "calibrate": ["--robot"],
    "diagnose": ["--robot"],
    "plan": ["--out", "--poses"],
}
PINNED = {
    "compare": ["--methods", "lm", "--repeats", "1", "--protocol", "80-20"],
    "diagnose": ["--folds", "2"],
    "demo": ["--samples", "60"],
    "plan": ["--candidates", "500"],
}
READS = ("data", "result", "targets", "diagnosis", "robot")


def test_every_subcommand_is_covered():
    assert set(SPECS) == set(COMMANDS)


@st.composite
def command_lines(draw, w: Path, t: Path):
    """``(argv, files it reads)``: a subcommand with its positional arguments, its required
    options and up to four others."""
    pools = _pools(w, t)

    def value(kind, option=None):
        if option in CHOICES:
            return draw(st.sampled_from(CHOICES[option]) | st.sampled_from(CHOICES[option]) | st.text(max_size=8))
        good, bad = pools[kind]
        # two draws in three from the good values: bad ones alone would stop most commands at
        # their first argument and leave the work behind it unexercised
        return str(draw(st.sampled_from(good) | st.sampled_from(good) | st.sampled_from(bad)) if good else draw(st.text(max_size=8)))

    command = draw(st.sampled_from(sorted(SPECS)))
    positional, options = SPECS[command]
    argv = [command]
    read = []
    for kind in positional:
        argv.append(value(kind))
        read.append(argv[-1])
    chosen = list(dict.fromkeys(REQUIRED.get(command, []) + draw(st.lists(st.sampled_from(sorted(options)), max_size=4, unique=True))))
    for option in chosen:
        kind = options[option]
        argv += [option] if kind is None else [option, value(kind, option)]
        if kind in READS:
            read.append(argv[-1])
    if command == "demo" and "--out" not in argv:
        argv += ["--out", str(w)]  # refused: the demo itself takes seconds
    return argv + PINNED.get(command, []) + (["--quiet"] if draw(st.booleans()) else []), read


@pytest.fixture(scope="module")
def fuzz_dirs(tmp_path_factory, inputs):
    """A copy of the inputs (a command may legitimately overwrite a file named only as its
    output) and a folder for outputs."""
    import shutil

    w = tmp_path_factory.mktemp("fuzz_in")
    for f in inputs.iterdir():
        if f.is_file():
            shutil.copy(f, w / f.name)
    return w, tmp_path_factory.mktemp("fuzz_out")


def _alarm(*_):
    raise TimeoutError("a command ran for more than 60 s")


@settings(max_examples=200, deadline=None, derandomize=True, suppress_health_check=list(HealthCheck))
@given(data=st.data())
def test_fuzz_the_command_line(fuzz_dirs, data):
    """Any command line: exit 0, 1 or 2; on 2 one line ``robocal: error: ...`` or argparse's
    usage; never a traceback, never a hang, never a file it reads changed."""
    import contextlib
    import io

    w, t = fuzz_dirs
    argv, read = data.draw(command_lines(w, t))
    read = [Path(p) for p in read if p and "\x00" not in p and Path(p).is_file() and Path(p).parent == w]
    before = {p: digest(p) for p in read}
    err = io.StringIO()
    old = signal.signal(signal.SIGALRM, _alarm)
    signal.alarm(60)
    cwd = os.getcwd()
    os.chdir(t)  # an output named "-" or relative lands among the outputs, not in the checkout
    try:
        with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
            try:
                code = main(argv)
            except SystemExit as exc:
                code = exc.code
    finally:
        os.chdir(cwd)
        signal.alarm(0)
        signal.signal(signal.SIGALRM, old)
    event(f"{argv[0]} exit {code}")  # shown by --hypothesis-show-statistics: what the fuzz reached
    assert code in (0, 1, 2), (argv, code)
    assert "Traceback" not in err.getvalue(), (argv, err.getvalue())
    if code == 2 and "usage:" not in err.getvalue():
        lines = err.getvalue().strip().splitlines()
        assert len(lines) == 1 and lines[0].startswith("robocal: error: "), (argv, err.getvalue())
    assert {p: digest(p) for p in read} == before, argv
