"""What the benchmark scripts report about the machine they ran on, and the code they ran."""

from __future__ import annotations

import os
import platform
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def cpu_model() -> str:
    try:
        with open("/proc/cpuinfo") as f:
            for line in f:
                if line.startswith("model name"):
                    return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or "unknown CPU"


def load_averages() -> list[float] | None:
    """The 1-, 5- and 15-minute load averages, rounded to 0.01 (None where the system keeps none):
    what every bench reports beside its timings."""
    try:
        return [round(x, 2) for x in os.getloadavg()]
    except (OSError, AttributeError):
        return None


def load_text(all_three: bool = False) -> str:
    """:func:`load_averages` as the benches print it: the 1-minute figure, or all three
    (``all_three``), two decimals each; "n/a" where there are none."""
    loads = load_averages()
    if loads is None:
        return "n/a"
    return " ".join(f"{x:.2f}" for x in (loads if all_three else loads[:1]))


def ram_gib() -> float | None:
    try:
        return round(os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES") / 2**30, 1)
    except (ValueError, OSError, AttributeError):
        return None


def _version(module: str) -> str | None:
    try:
        return __import__(module).__version__
    except ImportError:
        return None


def describe() -> dict:
    """The machine and the software a figure was measured with (the versions of what the bench imported)."""
    robocal = sys.modules.get("robocal") or __import__("robocal")
    return {
        "cpu": cpu_model(),
        "cores": os.cpu_count(),
        "ram_gib": ram_gib(),
        "os": f"{platform.system()} {platform.release()}",
        "python": platform.python_version(),
        "numpy": _version("numpy"),
        "scipy": _version("scipy"),
        "robocal": robocal.__version__,
        # A stale robocal in site-packages would time other code than the commit's.
        "robocal_path": str(Path(robocal.__file__).parent),
    }


# What decides the figures; edits elsewhere (the manual, the tests) leave a record clean.
CODE = ("python", "rust", "benches", "Cargo.toml", "Cargo.lock", "pyproject.toml")


def git_state() -> dict:
    """The commit of the tree the bench ran from and whether its code (:data:`CODE`) differed from it."""

    def git(*args: str) -> str:
        return subprocess.run(["git", "-C", str(ROOT), *args], capture_output=True, text=True, check=True).stdout.strip()

    try:
        return {"commit": git("rev-parse", "HEAD"), "dirty": bool(git("status", "--porcelain", "--untracked-files=no", "--", *CODE))}
    except (OSError, subprocess.CalledProcessError):
        return {"commit": "unknown", "dirty": None}
