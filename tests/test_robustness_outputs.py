"""Issue 28, outputs and crashes: nothing replaced but regular files, no race, no traceback.

One test per row (2 Ctrl-C, 3 NUL in an API path, 4 a device or FIFO as data or document, 5 special files as
outputs, 10 two runs into one folder, 19 terminal escapes from a robot file, 21 demo's partial
output), then a Hypothesis fuzz of the class: whatever kind of node an output path names, a
command either refuses it (exit 2, one line naming it, the node untouched) or writes a regular
file. Devices are made with ``mknod`` inside ``tmp_path`` only (as root), never taken from /dev.
"""

from __future__ import annotations

import json
import os
import signal
import stat
import subprocess
import sys
import time
from pathlib import Path

import pytest
import robocal
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from robocal import files, outputs
from robocal.cli import main
from robocal.data import table
from robocal.exceptions import DataError, InvalidParameterError, OutputError
from test_cli_safety import ROBOT, digest, inputs, refused, run  # noqa: F401 (inputs: a fixture)

ROOT = os.geteuid() == 0


def node(path: Path) -> tuple:
    """What a path is, to compare before and after: its kind, its link target and its inode."""
    if not os.path.lexists(path):
        return ("missing",)
    info = os.lstat(path)
    return stat.S_IFMT(info.st_mode), info.st_ino, os.readlink(path) if stat.S_ISLNK(info.st_mode) else None


def no_temporaries(folder: Path) -> bool:
    return not [p for p in folder.iterdir() if p.name.startswith(".")]


# -- row 2: Ctrl-C --------------------------------------------------------------------------------
def test_ctrl_c_is_one_line_exit_130_and_keeps_the_old_file(tmp_path, capsys, monkeypatch):
    from robocal import simulation

    out = tmp_path / "s.csv"
    out.write_text("previous output")

    def interrupted(dataset, path):
        Path(path).write_text("half a fi")  # the temporary holds a partial write when Ctrl-C comes
        raise KeyboardInterrupt

    monkeypatch.setattr(simulation, "write_canonical", interrupted)
    code, _, err = run(["simulate", "--samples", "20", "--out", out], capsys)
    assert code == 130 and err == "robocal: interrupted\n"
    assert out.read_text() == "previous output" and no_temporaries(tmp_path)


def test_ctrl_c_in_a_report_releases_the_folder(inputs, tmp_path, capsys, monkeypatch):  # noqa: F811
    import robocal.cli.report as report_cli

    def interrupted(*_args, **_kw):
        raise KeyboardInterrupt

    monkeypatch.setattr(report_cli, "report", interrupted)
    code, _, err = run(["report", inputs / "result.json", "--out", tmp_path / "rep"], capsys)
    assert code == 130 and err == "robocal: interrupted\n"
    assert not (tmp_path / "rep").exists()  # created by the run, left empty: removed with its lock


#: The command line with its CSV writer held mid-write: it writes the staged file, says so by
#: creating the file argv[1], and waits for a signal. The SIGINT then always arrives while the
#: output is being written, whatever the machine's speed (a timed loop lost the race under load:
#: the child finished first).
_HELD_WRITER = """
import signal, sys
from pathlib import Path
from robocal import simulation
from robocal.cli import main

# Ctrl-C as a terminal delivers it, however the suite was started: a shell's background job
# (``pytest &``, ``nohup``) starts with SIGINT ignored, which the child would inherit and hang in
# pause() until the test's bound.
signal.signal(signal.SIGINT, signal.default_int_handler)

real = simulation.write_canonical

def held(dataset, path):
    real(dataset, path)
    Path(sys.argv[1]).touch()
    signal.pause()

simulation.write_canonical = held
sys.exit(main(sys.argv[2:]))
"""


def test_a_real_sigint_while_writing(tmp_path):
    """The reproducer: a real SIGINT while the staged file is written; no traceback, the old file kept."""
    out, writing = tmp_path / "big.csv", tmp_path / "writing"
    out.write_text("old")
    argv = [sys.executable, "-c", _HELD_WRITER, writing, "simulate", "--robot", "ur10", "--measurement", "position", "--samples", "3000", "--out", out]
    proc = subprocess.Popen(argv, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    try:
        hang = time.monotonic() + 600  # a bound against a hang only: the child cannot finish before it signals
        while not writing.exists():
            assert proc.poll() is None and time.monotonic() < hang, proc.communicate()[1] if proc.poll() is not None else "no write started"
            time.sleep(0.01)
        proc.send_signal(signal.SIGINT)
        _, err = proc.communicate(timeout=600)  # a bound against a hang only
    finally:
        proc.kill()
    assert proc.returncode == 130 and err == "robocal: interrupted\n", err
    assert out.read_text() == "old" and no_temporaries(tmp_path)


# -- issue 52 #16: each output's write error names that output -----------------------------------
def test_a_file_size_limit_names_the_csv_not_the_truth(tmp_path):
    """The reproducer (``ulimit -f 50``): the CSV is too large, the truth is not; the error named the truth."""
    import resource

    out, truth = tmp_path / "big.csv", tmp_path / "t.json"
    out.write_text("old")
    argv = [sys.executable, "-m", "robocal", "simulate", "--robot", "ur10", "--measurement", "pose", "--samples", "3000", "--out", out, "--truth", truth]
    done = subprocess.run(argv, capture_output=True, text=True, preexec_fn=lambda: resource.setrlimit(resource.RLIMIT_FSIZE, (50 * 1024, 50 * 1024)))
    assert done.returncode == 2 and done.stderr == f"robocal: error: {out}: cannot write it (File too large)\n", done.stderr
    assert out.read_text() == "old" and not truth.exists() and no_temporaries(tmp_path)


def test_a_failing_truth_write_names_the_truth(tmp_path, capsys, monkeypatch):
    out, truth = tmp_path / "s.csv", tmp_path / "t.json"
    real_write_text = Path.write_text

    def full_disk(path, text, *args, **kw):
        if path.name.startswith(".t.json"):
            raise OSError(28, "No space left on device")
        return real_write_text(path, text, *args, **kw)

    monkeypatch.setattr(Path, "write_text", full_disk)
    code, _, err = run(["simulate", "--samples", "20", "--out", out, "--truth", truth], capsys)
    assert code == 2 and err == f"robocal: error: {truth}: cannot write it (No space left on device)\n"
    assert not out.exists() and not truth.exists() and no_temporaries(tmp_path)


# -- row 3: NUL in an API path --------------------------------------------------------------------
@pytest.mark.parametrize("call", [lambda: robocal.load("a\x00b.csv"), lambda: robocal.load(Path("a\x00b.csv"), format="canonical")])
def test_a_nul_in_a_data_path_is_a_robocal_error(call):
    with pytest.raises(DataError, match="NUL character"):
        call()


# -- row 4: a device or a FIFO as the data file ----------------------------------------------------
def _alarm(*_):
    raise TimeoutError("the reader blocked")


@pytest.fixture
def no_hang():
    old = signal.signal(signal.SIGALRM, _alarm)
    signal.alarm(20)
    yield
    signal.alarm(0)
    signal.signal(signal.SIGALRM, old)


def _special_inputs(tmp_path) -> list[tuple[Path, str]]:
    fifo = tmp_path / "fifo.csv"
    os.mkfifo(fifo)
    made = [(fifo, "is a FIFO")]
    if ROOT:
        zero = tmp_path / "zero.csv"
        os.mknod(zero, 0o444 | stat.S_IFCHR, os.makedev(1, 5))  # /dev/zero's numbers, in tmp_path
        made.append((zero, "is a character device"))
    return made


def test_a_fifo_or_a_device_as_data_is_refused_at_once(inputs, tmp_path, capsys, no_hang):  # noqa: F811
    for path, words in _special_inputs(tmp_path):
        refused(["calibrate", path, "--robot", "ur10"], capsys, str(path), words, "not a regular file")
        refused(["report", inputs / "result.json", "--data", path, "--out", tmp_path / "rep"], capsys, str(path), words)
        with pytest.raises(DataError, match="not a regular file"):
            robocal.load(path)
    assert not (tmp_path / "rep").exists()


def test_a_data_file_beyond_the_size_limit_is_refused_unread(inputs, monkeypatch, capsys):  # noqa: F811
    monkeypatch.setattr(table, "MAX_FILE_BYTES", 1000)
    refused(["calibrate", inputs / "d.csv", "--robot", ROBOT], capsys, str(inputs / "d.csv"), "bytes; robocal reads files up to 1,000 bytes")


def _special_documents(tmp_path, name: str) -> list[tuple[Path, str]]:
    """A FIFO (and, as root, a character device with /dev/zero's numbers) named ``name``, in tmp_path."""
    fifo = tmp_path / name
    os.mkfifo(fifo)
    made = [(fifo, "is a FIFO")]
    if ROOT:
        zero = tmp_path / f"zero-{name}"
        os.mknod(zero, 0o444 | stat.S_IFCHR, os.makedev(1, 5))
        made.append((zero, "is a character device"))
    return made


@pytest.mark.parametrize("name", ["r.json", "r.yaml", "r.csv", "r.urdf"])
def test_a_fifo_or_a_device_as_robot_result_or_diagnosis_is_refused_at_once(inputs, tmp_path, capsys, no_hang, name):  # noqa: F811
    """Row 4 for documents (robot, result, parameter table, URDF, diagnose report): read through
    the same regular-file check as data files (robocal.files), never opened to block."""
    for path, words in _special_documents(tmp_path, name):
        refused(
            ["simulate", "--robot", path, "--measurement", "position", "--samples", "10", "--out", tmp_path / "s.csv"],
            capsys,
            str(path),
            words,
            "not a regular file",
        )
        if name.endswith(".json"):
            refused(["export", path, "--format", "dh", "--out", tmp_path / "x.csv"], capsys, str(path), words)
            refused(["report", path, "--out", tmp_path / "rep"], capsys, str(path), words)
            refused(["report", inputs / "result.json", "--diagnosis", path, "--out", tmp_path / "rep"], capsys, str(path), words)
            refused(["calibrate", inputs / "d.csv", "--robot", ROBOT, "--causes", path], capsys, str(path), words)
            with pytest.raises(InvalidParameterError, match="not a regular file"):
                robocal.load_result(path)
        with pytest.raises(InvalidParameterError, match="not a regular file"):
            robocal.robot(str(path))
    assert not (tmp_path / "s.csv").exists() and not (tmp_path / "x.csv").exists() and not (tmp_path / "rep").exists()


def test_a_robot_file_beyond_the_size_limit_is_refused_unread(inputs, monkeypatch, capsys):  # noqa: F811
    monkeypatch.setattr(files, "MAX_FILE_BYTES", 100)
    refused(
        ["export", inputs / "result.json", "--format", "dh", "--out", inputs / "x.csv"],
        capsys,
        str(inputs / "result.json"),
        "robocal reads files up to 100 bytes",
    )
    assert not (inputs / "x.csv").exists()


def test_data_and_documents_share_one_reader():
    """One regular-file reader (robocal.files) for data (DataError) and documents (InvalidParameterError)."""
    from robocal import robot_file

    assert table.open_regular is files.open_regular and robot_file.read_regular is files.read_regular and table.read_regular is files.read_regular


# -- row 5: an output that is not a regular file -------------------------------------------------------
def _make(kind: str, path: Path, tmp_path: Path) -> None:
    """``path`` made as a node of ``kind`` (all inside tmp_path)."""
    if kind == "file":
        path.write_text("previous")
    elif kind == "folder":
        path.mkdir()
    elif kind == "fifo":
        os.mkfifo(path)
    elif kind == "chardev":
        os.mknod(path, 0o666 | stat.S_IFCHR, os.makedev(1, 3))  # /dev/null's numbers, in tmp_path
    elif kind.startswith("link to "):
        target = tmp_path / f"target-{path.name}"
        if kind != "link to nothing":
            _make(kind[len("link to ") :], target, tmp_path)
        path.symlink_to(target)


SPECIAL = ["fifo", "link to file", "link to fifo", "link to nothing", "link to folder"] + (["chardev"] if ROOT else [])


@pytest.mark.parametrize("kind", SPECIAL)
@pytest.mark.parametrize(
    "argv",
    [
        ["export", "{w}/result.json", "--format", "dh", "--out", "{p}"],
        ["inspect", "{w}/d.csv", "--json", "{p}"],
        ["simulate", "--samples", "20", "--out", "{p}"],
    ],
)
def test_a_special_output_is_refused_and_kept(inputs, tmp_path, capsys, kind, argv):  # noqa: F811
    path = tmp_path / "out"
    _make(kind, path, tmp_path)
    before = node(path)
    target = tmp_path / "target-out"
    target_before = digest(target) if target.is_file() else node(target)
    line = refused([a.format(w=inputs, p=path) for a in argv], capsys, str(path))
    assert "not a regular file" in line or "is a folder" in line  # a link to a folder is a folder
    assert node(path) == before and (digest(target) if target.is_file() else node(target)) == target_before
    assert no_temporaries(tmp_path)


def test_staged_checks_again_right_before_the_rename(tmp_path):
    """The path became a FIFO while the output was being written: refused, FIFO kept."""
    path = tmp_path / "r.json"
    with pytest.raises(OutputError, match="r.json: is a FIFO"), outputs.Staged(path) as stage:
        stage.tmp.write_text("{}")
        os.mkfifo(path)
    assert stat.S_ISFIFO(os.lstat(path).st_mode) and no_temporaries(tmp_path)


# -- row 10: two runs into one folder ---------------------------------------------------------------
def test_a_claimed_folder_refuses_a_second_run(inputs, tmp_path, capsys):  # noqa: F811
    same = tmp_path / "same"
    (claim,) = outputs.check_outputs(folders=[same])  # the first run, still writing
    (same / "index.html").write_text("first")
    refused(["report", inputs / "result.json", "--out", same], capsys, str(same), "another robocal run")
    refused(["report", inputs / "result.json", "--out", same, "--force"], capsys, "another robocal run")
    claim.release()
    assert (same / "index.html").read_text() == "first" and no_temporaries(same)
    refused(["report", inputs / "result.json", "--out", same], capsys, "not empty", "--force")  # the check runs under the lock


def test_two_reports_started_together_one_refused(inputs, tmp_path):  # noqa: F811
    """The reproducer: of two concurrent runs into one new folder, exactly one writes it."""
    same = tmp_path / "same"
    cal = tmp_path / "other.json"
    doc = json.loads((inputs / "result.json").read_text())
    doc["robot"] = "second-robot"
    cal.write_text(json.dumps(doc))
    procs = [
        subprocess.Popen([sys.executable, "-m", "robocal", "report", str(r), "--out", str(same)], stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
        for r in (inputs / "result.json", cal)
    ]
    results = [(p.wait(timeout=120), p.stderr.read()) for p in procs]
    codes = sorted(code for code, _ in results)
    assert codes == [0, 2], results
    winner = next(i for i, (code, _) in enumerate(results) if code == 0)
    assert ("second-robot" in (same / "index.html").read_text()) == (winner == 1)
    assert no_temporaries(same)


def test_a_refused_run_into_a_new_folder_leaves_no_folder(tmp_path, capsys):
    bad = tmp_path / "bad.csv"
    bad.write_text("q1,q2\n1,2\n")
    refused(["compare", bad, "--robot", ROBOT, "--out", tmp_path / "new" / "cmp"], capsys)
    assert list(tmp_path.iterdir()) == [bad]


@pytest.mark.parametrize("command", ["diagnose", "report", "compare"])
def test_a_file_name_given_for_an_output_folder_is_refused_before_any_work(inputs, tmp_path, capsys, command):  # noqa: F811
    """``diagnose --out report.json`` made a folder called report.json: a new folder named like a
    file is a file name in the wrong place. An existing folder of that name is the user's choice."""
    data, result = inputs / "d.csv", inputs / "result.json"
    argv = {"diagnose": ["diagnose", data, "--robot", ROBOT], "report": ["report", result], "compare": ["compare", data, "--robot", ROBOT]}[command]
    err = refused([*argv, "--out", tmp_path / "out.json"], capsys)
    assert "an output folder is expected" in err and "(.json)" in err
    assert not (tmp_path / "out.json").exists()


# -- row 19: what goes to the terminal ---------------------------------------------------------------
HOSTILE = "ur10\x1b[2K\r  train: RMSE 0.0001 (faked)\n  fake \u202eline"


def test_a_robot_name_cannot_drive_the_terminal(tmp_path, capsys):
    robocal.write_robot(robocal.robot("ur10"), tmp_path / "ur10.json", degrees=True)
    spec = json.loads((tmp_path / "ur10.json").read_text())
    spec["name"] = HOSTILE
    (tmp_path / "ansi.json").write_text(json.dumps(spec))
    code, out, err = run(["simulate", "--robot", tmp_path / "ansi.json", "--measurement", "position", "--samples", "20", "--out", tmp_path / "s.csv"], capsys)
    assert code == 0, err
    assert not any(c in out for c in "\x1b\r\u202e")
    wrote = [line for line in out.splitlines() if line.startswith("wrote ")]
    assert len(wrote) == 1 and "ur10\\x1b[2K\\r  train: RMSE 0.0001 (faked)\\n  fake \\u202eline to " in wrote[0]


def test_an_error_line_cannot_drive_the_terminal(tmp_path, capsys):
    missing = tmp_path / "x\x1b[2K\u202e.csv"
    line = refused(["calibrate", missing, "--robot", ROBOT], capsys, "cannot read")
    assert "\x1b" not in line and "\u202e" not in line and "\\x1b[2K\\u202e.csv" in line


def test_printable_keeps_lines_unless_one_line():
    assert outputs.printable("a\x1bb\r\u2066c\nd\te") == "a\\x1bb\\r\\u2066c\nd\te"
    assert outputs.printable("a\nb\tc", one_line=True) == "a\\nb\\tc"
    assert outputs.printable("µm ±0.1 °, Zürich") == "µm ±0.1 °, Zürich"  # ordinary text is left alone


# -- row 21: demo checks it can finish before it writes ------------------------------------------------
@pytest.mark.parametrize("samples", ["10", "30"])
def test_demo_with_too_few_samples_writes_nothing(tmp_path, capsys, samples):
    refused(["demo", "--samples", samples, "--out", tmp_path / "d"], capsys, f"--samples {samples} is too few for the demo", "degrees of freedom")
    assert not (tmp_path / "d").exists()
    (tmp_path / "empty").mkdir()
    refused(["demo", "--samples", samples, "--out", tmp_path / "empty"], capsys, "too few")
    assert list((tmp_path / "empty").iterdir()) == []  # an existing empty folder stays empty: no --force needed next time


# -- the class: any kind of node as an output ------------------------------------------------------------
KINDS = ["missing", "file", "folder", *SPECIAL]
COMMANDS = {
    "export": ["export", "{w}/result.json", "--format", "dh", "--out", "{p}"],
    "inspect": ["inspect", "{w}/d.csv", "--json", "{p}"],
    "simulate": ["simulate", "--samples", "20", "--out", "{p}"],
    "calibrate": ["calibrate", "{w}/d.csv", "--robot", ROBOT, "--out", "{p}"],
}


@settings(max_examples=30, deadline=None, derandomize=True, suppress_health_check=list(HealthCheck))
@given(kind=st.sampled_from(KINDS), command=st.sampled_from(sorted(COMMANDS)), name=st.sampled_from(["o.csv", "o.json", "o"]))
def test_fuzz_outputs_are_regular_files_or_refused(inputs, tmp_path_factory, kind, command, name):  # noqa: F811
    import contextlib
    import io

    t = tmp_path_factory.mktemp("kind")
    path = t / name
    _make(kind, path, t)
    before, target = node(path), t / f"target-{name}"
    target_before = node(target)
    err = io.StringIO()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
        code = main([a.format(w=inputs, p=path) for a in COMMANDS[command]])
    if kind in ("missing", "file"):
        assert code == 0, err.getvalue()
        assert stat.S_ISREG(os.lstat(path).st_mode) and path.read_text() != "previous"
    else:
        lines = err.getvalue().strip().splitlines()
        assert code == 2 and len(lines) == 1 and lines[0].startswith("robocal: error: ") and str(path) in lines[0], err.getvalue()
        assert node(path) == before and node(target) == target_before
    assert no_temporaries(t)
