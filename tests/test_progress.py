"""Stage lines (robocal.progress): what a long command prints where no progress bar is drawn."""

from __future__ import annotations

import re

import pytest

from robocal import progress


@pytest.fixture
def stage_lines(monkeypatch):
    monkeypatch.setattr(progress, "STAGE_LINES", True)  # as the command line sets it for its run
    monkeypatch.setattr(progress, "QUIET", False)


def test_a_loop_and_a_stage_end_with_one_line_each(stage_lines, capsys):
    assert list(progress.progress([1, 2, 3], desc="work: round 1", unit="candidate")) == [1, 2, 3]
    with progress.stage("work: confirming round 1"):
        pass
    lines = capsys.readouterr().err.splitlines()
    assert len(lines) == 2
    assert re.fullmatch(r"robocal: work: round 1: 3 candidates in \d+\.\d s", lines[0])
    assert re.fullmatch(r"robocal: work: confirming round 1 in \d+\.\d s", lines[1])


def test_a_failed_stage_says_nothing_and_quiet_silences_all(stage_lines, capsys, monkeypatch):
    with pytest.raises(ValueError), progress.stage("work"):
        raise ValueError("the error line says it")
    monkeypatch.setattr(progress, "QUIET", True)
    list(progress.progress([1], desc="work"))
    with progress.stage("work"):
        pass
    assert capsys.readouterr().err == ""


def test_called_from_python_robocal_prints_no_stage_line(capsys):
    list(progress.progress([1], desc="work"))
    with progress.stage("work"):
        pass
    assert capsys.readouterr().err == ""
