"""Every subcommand end to end through the installed entry point (``python -m robocal``), as a
user runs it: simulate → inspect → calibrate → diagnose → compensate → export → report →
compare, and the bad-use cases (one line on stderr, exit 2, no traceback)."""

from __future__ import annotations

import json
import subprocess
import sys

import pytest


def robocal(*args, cwd=None):
    return subprocess.run([sys.executable, "-m", "robocal", "--quiet", *map(str, args)], capture_output=True, text=True, cwd=cwd, timeout=600)


@pytest.fixture(scope="module")
def workdir(tmp_path_factory):
    return tmp_path_factory.mktemp("cli")


def ok(done):
    assert done.returncode == 0, done.stderr[-2000:]
    return done.stdout


def test_every_subcommand_end_to_end(workdir):
    w = workdir
    ok(
        robocal(
            "simulate",
            "--robot",
            "abb-irb120",
            "--measurement",
            "position",
            "--samples",
            "300",
            "--seed",
            "2",
            "--effect",
            "backlash:joint=2,width=0.03",
            "--out",
            w / "d.csv",
            "--truth",
            w / "truth.json",
        )
    )
    assert "300" in ok(robocal("inspect", w / "d.csv", "--robot", "abb-irb120"))  # the row count is reported
    out = ok(robocal("calibrate", w / "d.csv", "--robot", "abb-irb120", "--out", w / "result.json"))
    assert "test:  RMSE" in out and json.loads((w / "result.json").read_text())["schema"] == "robocal.result/1"
    out = ok(robocal("diagnose", w / "d.csv", "--robot", "abb-irb120", "--json", w / "diag.json", "--out", w / "diag"))
    assert "backlash joint 2" in out
    ok(robocal("calibrate", w / "d.csv", "--robot", "abb-irb120", "--causes", w / "diag.json", "--out", w / "extended.json"))
    assert json.loads((w / "extended.json").read_text())["causes"][0]["kind"] == "backlash"
    (w / "targets.csv").write_text("x,y,z\n300,100,400\n250,-100,450\n")
    ok(robocal("compensate", w / "result.json", w / "targets.csv", "--out", w / "joints.csv"))
    assert len((w / "joints.csv").read_text().splitlines()) == 3
    ok(robocal("export", w / "result.json", "--format", "urdf", "--out", w / "robot.urdf"))
    assert (w / "robot.urdf").read_text().count("<joint ") >= 6
    ok(robocal("report", w / "result.json", "--diagnosis", w / "diag.json", "--out", w / "report"))
    assert (w / "report" / "index.html").stat().st_size > 1000
    ok(robocal("compare", w / "d.csv", "--robot", "abb-irb120", "--protocol", "80-20", "--repeats", "1", "--methods", "lm", "vslm", "--out", w / "cmp"))
    assert (w / "cmp" / "table_VIII.md").exists()


def test_debug_shows_the_diagnostic_log_and_quiet_nothing(workdir):
    """``--debug`` adds the package's log (``logging``, one line per message, the module named)
    on stderr and leaves the results on stdout as they were; ``--quiet`` leaves stderr empty."""
    w = workdir
    ok(robocal("simulate", "--robot", "abb-irb120", "--measurement", "position", "--samples", "60", "--seed", "3", "--out", w / "log.csv"))
    run = [sys.executable, "-m", "robocal", "inspect", str(w / "log.csv"), "--robot", "abb-irb120"]
    quiet = subprocess.run(run + ["--quiet"], capture_output=True, text=True, timeout=600)
    debug = subprocess.run(run + ["--debug"], capture_output=True, text=True, timeout=600)
    assert quiet.returncode == debug.returncode == 0 and quiet.stderr == ""
    assert debug.stdout == quiet.stdout
    assert "robocal: INFO: robocal.data.loader: load: " in debug.stderr and "60 position samples" in debug.stderr


@pytest.mark.parametrize(
    "args, fragment",
    [
        (["calibrate", "no-such-file.csv", "--robot", "ur10"], "no-such-file.csv"),
        (["calibrate", "{d}", "--robot", "kuka-kr16"], "kuka-kr16"),
        (["calibrate", "{d}", "--robot", "abb-irb120", "--measurement", "cable"], "cable"),
        (["compensate", "{bad}", "{d}", "--out", "{w}/j.csv"], "not a robocal result file"),
        (["report", "{bad}", "--out", "{w}/r"], "not a robocal result file"),
        (["export", "{bad}", "--format", "dh", "--out", "{w}/t.csv"], "not a robocal result file"),
        (["simulate", "--effect", "wobble", "--out", "{w}/s.csv"], "wobble"),
    ],
)
def test_bad_use_is_one_line_and_exit_2(workdir, args, fragment):
    w = workdir
    if not (w / "d.csv").exists():
        ok(robocal("simulate", "--robot", "abb-irb120", "--measurement", "position", "--samples", "100", "--out", w / "d.csv"))
    (w / "bad.json").write_text('{"schema": "robocal.result/1", "robot_model": 3')
    done = robocal(*[a.format(d=w / "d.csv", bad=w / "bad.json", w=w) for a in args])
    assert done.returncode == 2, (done.returncode, done.stdout, done.stderr)
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("robocal: error:") and fragment in lines[0], done.stderr


def test_what_follows_the_sensor_is_said_on_the_command_line_and_in_the_report(workdir):
    """A tracker's own error of no candidate's shape (0.1 mm, each axis periodic in another)
    reaches the user as a finding on the command line and in the HTML report: what is left
    follows the sensor's reading. A drawstring's periodic error is named as the sensor's own."""
    from helpers import with_sensor_error
    from robocal.simulation import simulate, write_simulation

    w = workdir
    data, truth = simulate("hsr-jr680", "cable", samples=1000, seed=5)
    write_simulation(with_sensor_error(data, 0.1, 100.0), truth, w / "drum.csv", w / "drum_truth.json")
    out = ok(robocal("diagnose", w / "drum.csv", "--robot", "hsr-jr680"))
    assert "+ sensor_periodic: amplitude" in out
    data, truth = simulate("ur10", "position", samples=1000, seed=5)
    write_simulation(with_sensor_error(data, 0.1, 300.0), truth, w / "sensor.csv", w / "sensor_truth.json")
    out = ok(robocal("diagnose", w / "sensor.csv", "--robot", "ur10", "--json", w / "sensor_diag.json"))
    assert "follows the sensor's reading" in out
    ok(robocal("calibrate", w / "sensor.csv", "--robot", "ur10", "--out", w / "sensor_result.json"))
    ok(robocal("report", w / "sensor_result.json", "--diagnosis", w / "sensor_diag.json", "--out", w / "sensor_report"))
    assert "What is left: not noise:" in (page := (w / "sensor_report" / "index.html").read_text())
    assert "follows the sensor&#x27;s reading" in page  # HTML-escaped
