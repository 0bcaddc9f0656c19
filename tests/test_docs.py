"""The manual builds strictly: ``mkdocs build --strict`` (mkdocs.yml) fails on a broken link or anchor between pages, a
page outside the navigation, a cross-reference mkdocstrings cannot resolve, a docstring it cannot parse, and (the hook
tools/mkdocs_reference.py) a public name of ``robocal.__all__`` without a docstring. The command and schema reference
pages are generated from the code during the build, so a change to an option or a model shows up here."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest
import robocal
from robocal.cli import COMMANDS

ROOT = Path(__file__).resolve().parents[1]

pytest.importorskip("mkdocs", reason="the docs tools are not installed (the `test` and `docs` extras install them)")


def test_manual_builds_strictly(tmp_path):
    env = dict(os.environ, NO_MKDOCS_2_WARNING="1")
    done = subprocess.run(
        [sys.executable, "-m", "mkdocs", "build", "--strict", "--site-dir", str(tmp_path / "site")],
        check=False,
        cwd=ROOT,
        env=env,
        capture_output=True,
        text=True,
    )
    assert done.returncode == 0, done.stdout + done.stderr
    pages = {p.relative_to(tmp_path / "site").as_posix() for p in (tmp_path / "site").rglob("index.html")}
    # The generated reference pages exist and carry every command and every public name.
    assert {"reference/cli/index.html", "reference/api/index.html", "reference/schemas/index.html", "tutorial/index.html"} <= pages
    cli = (tmp_path / "site/reference/cli/index.html").read_text(encoding="utf-8")
    assert all(f'id="robocal-{name}"' in cli for name in COMMANDS)
    api = (tmp_path / "site/reference/api/index.html").read_text(encoding="utf-8")
    assert all(f"robocal.{name}" in api for name in robocal.__all__ if not name.startswith("__"))


def _hook():
    import importlib.util

    spec = importlib.util.spec_from_file_location("mkdocs_reference", ROOT / "tools" / "mkdocs_reference.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_command_reference_lists_every_option_of_every_command():
    from robocal.cli import build_parser

    page = _hook().cli_page()
    for name in COMMANDS:
        parser = build_parser(name).command_parser
        options = [s for a in parser._actions for s in a.option_strings if s not in ("-h", "--help")]
        assert options, name
        section = page.split(f"## robocal {name} ")[1].split("\n## ")[0]
        assert all(f"`{o}" in section or f", {o}" in section for o in options), (name, [o for o in options if o not in section])


def test_a_public_name_without_a_docstring_fails_the_build(monkeypatch):
    from mkdocs.exceptions import PluginError

    def undocumented():
        pass

    monkeypatch.setattr(robocal, "undocumented", undocumented, raising=False)
    monkeypatch.setattr(robocal, "__all__", [*robocal.__all__, "undocumented"])
    with pytest.raises(PluginError, match="undocumented"):
        _hook().check_docstrings()


def test_the_manual_carries_no_dated_development_log():
    # A manual states what is true now; history goes to CHANGELOG.md. A measurement's provenance is its command and
    # commit; the benchmark pages' dates come from their records at build time, not from docs/.
    import re

    dated = [
        f"{page.relative_to(ROOT)}:{n}: {line.strip()[:120]}"
        for page in sorted((ROOT / "docs").rglob("*.md"))
        for n, line in enumerate(page.read_text(encoding="utf-8").splitlines(), 1)
        if re.search(r"\b20\d\d-[01]\d-[0-3]\d\b", line)
    ]
    assert not dated, "dated passages in the manual (say what is true now; history goes to CHANGELOG.md):\n" + "\n".join(dated)
