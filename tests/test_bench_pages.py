"""The benchmark pages' figures come from the benches' records (benches/records/*.json, written by ``--record``) and
are rendered by the mkdocs hook tools/bench_pages.py: every record renders, every record is quoted by a page and every
page's marker has its record, and a record that does not say its command, commit or machine is refused."""

from __future__ import annotations

import copy
import importlib.util
import json
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
RECORDS = sorted((ROOT / "benches" / "records").glob("*.json"))


def _module(path: Path, name: str):
    spec = importlib.util.spec_from_file_location(name, path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


pages = _module(ROOT / "tools" / "bench_pages.py", "bench_pages")


def _markers() -> dict[str, list[str]]:
    found: dict[str, list[str]] = {}
    for page in (ROOT / "docs").rglob("*.md"):
        for m in pages.MARKER.finditer(page.read_text(encoding="utf-8")):
            found.setdefault(m["name"], []).append(page.relative_to(ROOT).as_posix())
    return found


def test_there_are_records_and_pages_that_quote_them():
    assert RECORDS
    assert _markers()


@pytest.mark.parametrize("path", RECORDS, ids=lambda p: p.stem)
def test_every_record_renders_with_its_provenance_and_tables(path):
    record = json.loads(path.read_text(encoding="utf-8"))
    text = pages.render(record, path.stem)
    assert f"`{record['command']}`" in text or record["command"] in text
    assert record["commit"][:10] in text and record["machine"]["cpu"] in text
    # The figures: every table row the bench printed is on the page.
    for table in record["tables"]:
        assert table["rows"], table["columns"]
    for line in record["output"].splitlines():
        if line.startswith("|"):
            assert line in text
    # Headings sit under the page's "##" section.
    assert not any(line.startswith(("# ", "## ")) for line in text.splitlines())


def test_every_record_is_quoted_and_every_marker_has_its_record():
    markers = _markers()
    assert sorted(markers) == sorted(p.stem for p in RECORDS), "records no page quotes, or markers without a record"


@pytest.mark.parametrize("field", ["command", "commit", "machine", "date", "load", "output", "machine.cpu", "machine.robocal"])
def test_a_record_without_its_provenance_is_refused(field):
    record = json.loads(RECORDS[0].read_text(encoding="utf-8"))
    broken = copy.deepcopy(record)
    if "." in field:
        outer, inner = field.split(".")
        del broken[outer][inner]
    else:
        del broken[field]
    with pytest.raises(ValueError, match=field):
        pages.render(broken, "broken")
    pages.render(record, "whole")  # the same record whole renders


def test_an_unknown_commit_is_refused():
    record = json.loads(RECORDS[0].read_text(encoding="utf-8"))
    with pytest.raises(ValueError, match="commit"):
        pages.render({**record, "commit": "unknown"}, "unknown")


def test_a_marker_without_its_record_fails(tmp_path):
    with pytest.raises(ValueError, match="no benchmark record"):
        pages.expand("text\n<!-- record: nothing-here -->\nmore\n", tmp_path)


def test_a_busy_machine_is_said_and_a_dirty_tree_too():
    record = json.loads(RECORDS[0].read_text(encoding="utf-8"))
    cores = record["machine"]["cores"]
    busy = pages.provenance({**record, "load": {"start": [float(cores), 0, 0], "end": [0.1, 0, 0]}, "dirty": True})
    idle = pages.provenance({**record, "load": {"start": [0.0, 0, 0], "end": [0.1, 0, 0]}, "dirty": False})
    assert "not idle timings" in busy and "not idle timings" not in idle
    assert "uncommitted changes" in busy and "uncommitted changes" not in idle


def test_recording_writes_a_record_the_pages_accept(tmp_path, monkeypatch, capsys):
    monkeypatch.syspath_prepend(str(ROOT / "benches"))
    record_module = _module(ROOT / "benches" / "record.py", "bench_record")
    argv = [str(ROOT / "benches" / "bench_x.py"), "--size", "3", "--record", str(tmp_path)]
    with record_module.recording(str(tmp_path), argv):
        print("## Part 1\n\n| kernel | time |\n|---|---:|\n| fk | 1.0 ms |\n| jacobian \\| cable | 2.0 ms |")
    assert "| fk | 1.0 ms |" in capsys.readouterr().out  # still printed
    written = json.loads((tmp_path / "bench_x.json").read_text(encoding="utf-8"))
    assert written["command"] == "python benches/bench_x.py --size 3"  # --record changes nothing measured
    assert written["tables"] == [{"heading": "Part 1", "columns": ["kernel", "time"], "rows": [["fk", "1.0 ms"], ["jacobian \\| cable", "2.0 ms"]]}]
    assert len(written["load"]["start"]) == 3 and written["machine"]["cores"]
    assert "### Part 1" in pages.render(written, "bench_x")


def test_plain_text_output_is_kept_as_printed():
    record = json.loads(RECORDS[0].read_text(encoding="utf-8"))
    text = pages.render({**record, "output": "solver   reached\nrobocal  200/200\n", "tables": []}, "plain")
    assert "```text\nsolver   reached\nrobocal  200/200\n```" in text
