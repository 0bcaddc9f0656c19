"""The Rust core stays `cargo fmt --check` clean (rustfmt.toml) and clippy clean with `-D warnings`
(all targets, no default features: the pure core, no libpython). Clippy shares cargo's default
`target/` with the README's `cargo test --no-default-features`."""

from __future__ import annotations

import shutil
import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


def cargo(*args: str) -> subprocess.CompletedProcess:
    if shutil.which("cargo") is None:
        pytest.fail("cargo is missing: a Rust toolchain (with rustfmt and clippy) is required")
    return subprocess.run(["cargo", *args], check=False, cwd=ROOT, capture_output=True, text=True, timeout=1800)


def test_cargo_fmt_check():
    done = cargo("fmt", "--check", "--", "--color", "never")
    assert done.returncode == 0, f"cargo fmt --check (run `cargo fmt`):\n{done.stdout}\n{done.stderr}"


def test_cargo_clippy_deny_warnings():
    done = cargo("clippy", "--quiet", "--all-targets", "--no-default-features", "--", "-D", "warnings")
    assert done.returncode == 0, f"cargo clippy --all-targets --no-default-features -- -D warnings:\n{done.stdout}\n{done.stderr}"
