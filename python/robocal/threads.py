"""Independent pieces of work spread over the machine's cores by threads.

The work robocal spreads — a cross-validation's fold fits — spends its time in the Rust core and
in NumPy/SciPy, which release the GIL, so threads run it in parallel without copying the data
to other processes. A piece that spreads work again (a session's diagnosis, whose folds are
spread) runs its own pieces one after the other: the cores are busy already.

``ROBOCAL_THREADS=N`` caps the threads (1: everything in the calling thread), for a controller
PC that must keep cores for other work.
"""

from __future__ import annotations

import os
import threading
from concurrent.futures import ThreadPoolExecutor
from typing import Optional

from .exceptions import InvalidParameterError

_inside = threading.local()


def cores() -> int:
    """The threads to spread work over: ``ROBOCAL_THREADS`` if set, else the cores this process
    may run on."""
    setting = os.environ.get("ROBOCAL_THREADS", "").strip()
    if setting:
        if not setting.isdigit() or int(setting) < 1:
            raise InvalidParameterError(f"ROBOCAL_THREADS must be a whole number of threads, at least 1; got {setting!r}")
        return int(setting)
    return len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count() or 1


#: A screening (a small linear solve per fold) on fewer residual rows than this runs in the
#: calling thread: its NumPy calls are short, and the threads' contention for the interpreter
#: cost more than a second core gave (the simulated cable case of benches/bench_diagnose.py:
#: docs/benchmarks.md).
MIN_ROWS = 10_000


def thread_map(work, items, rows: Optional[int] = None) -> list:
    """``[work(item) for item in items]``, the items spread over :func:`cores` threads; results
    in the items' order, the first exception raised as it would be in the loop. ``rows``: the
    residual rows of the problem when each item is small work (a linear solve), which is spread
    only from :data:`MIN_ROWS` rows; None when each item is large (a nonlinear fit)."""
    items = list(items)
    n = min(cores(), len(items))
    if n <= 1 or (rows is not None and rows < MIN_ROWS) or getattr(_inside, "busy", False):
        return [work(item) for item in items]

    def run(item):
        _inside.busy = True
        try:
            return work(item)
        finally:
            _inside.busy = False

    with ThreadPoolExecutor(n) as pool:
        return list(pool.map(run, items))
