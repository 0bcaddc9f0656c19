"""Independent pieces of work spread over the machine's cores by threads.

The work robocal spreads — a cross-validation's fold fits — spends its time in the Rust core and
in NumPy/SciPy, which release the GIL, so threads run it in parallel without copying the data
to other processes. A piece that spreads work again (a session's diagnosis, whose folds are
spread) runs its own pieces one after the other: the cores are busy already.
"""

from __future__ import annotations

import os
import threading
from concurrent.futures import ThreadPoolExecutor

_inside = threading.local()


def cores() -> int:
    """The cores this process may run on."""
    return len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count() or 1


def thread_map(work, items) -> list:
    """``[work(item) for item in items]``, the items spread over :func:`cores` threads; results
    in the items' order, the first exception raised as it would be in the loop."""
    items = list(items)
    n = min(cores(), len(items))
    if n <= 1 or getattr(_inside, "busy", False):
        return [work(item) for item in items]

    def run(item):
        _inside.busy = True
        try:
            return work(item)
        finally:
            _inside.busy = False

    with ThreadPoolExecutor(n) as pool:
        return list(pool.map(run, items))
