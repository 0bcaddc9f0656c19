"""No test depends on the machine's speed: the suite runs on busy machines (issue 52: green ten times
in a row beside two CPU-heavy jobs). Hypothesis has two timers — a deadline per example and the
health check on slow data generation — and a test that names its own settings replaces the shared
profile's (tests/conftest.py) for what it names."""

from __future__ import annotations

import ast
from pathlib import Path

TESTS = Path(__file__).resolve().parent


def _settings_calls():
    """``(file, line, call)`` of every ``settings(...)`` / ``register_profile(...)`` call in the tests."""
    for path in sorted(TESTS.glob("*.py")):
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.Call) and getattr(node.func, "id", getattr(node.func, "attr", None)) in ("settings", "register_profile"):
                yield path.name, node.lineno, node


def test_no_hypothesis_timer_can_fail_a_test_on_a_busy_machine():
    timed = []
    for name, line, call in _settings_calls():
        keywords = {k.arg: k.value for k in call.keywords}
        deadline = keywords.get("deadline")
        if deadline is not None and not (isinstance(deadline, ast.Constant) and deadline.value is None):
            timed.append(f"{name}:{line}: a deadline")
        checks = keywords.get("suppress_health_check")
        if checks is not None and "too_slow" not in ast.unparse(checks) and "list(HealthCheck)" not in ast.unparse(checks):
            timed.append(f"{name}:{line}: suppress_health_check without HealthCheck.too_slow (it replaces the profile's)")
    assert not timed, timed
    assert any(name == "conftest.py" for name, _, _ in _settings_calls())  # the scan reads the profile too
