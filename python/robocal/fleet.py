"""Calibrating a fleet: many datasets (robots) in one call, on all cores.

:func:`calibrate_many` runs :func:`robocal.calibrate` on each dataset in a pool of worker
processes — each worker's Rust core runs single-threaded (``RAYON_NUM_THREADS=1``) so that the
workers, not the threads inside one calibration, share the cores: many small calibrations
parallelise better across processes than inside each (the Python orchestration between Rust
calls holds the interpreter). Each result comes back as its result document
(:meth:`~robocal.calibration.CalibrationResult.to_dict`), or ``{"error": ...}`` naming the
dataset that failed; one failure does not stop the fleet.

For thousands of robots, the same function per dataset maps onto an existing distributed engine:
:func:`calibrate_one` is a plain picklable function of a path (or Dataset) and options returning
a JSON-able dict, e.g. with Dask ``client.map(calibrate_one, paths, robot=..., method=...)``
or Ray ``ray.remote(calibrate_one)``; ``benches/bench_fleet.py`` runs it on a local Dask cluster.
"""

from __future__ import annotations

import logging
import multiprocessing
import os
from concurrent.futures import ProcessPoolExecutor, ThreadPoolExecutor
from pathlib import Path
from typing import Iterable, Optional, Union

from .causes.extended import calibrate
from .data.dataset import Dataset
from .exceptions import InvalidParameterError, RobocalError

logger = logging.getLogger(__name__)


def calibrate_one(data: Union[str, Path, Dataset], **options) -> dict:
    """:func:`robocal.calibrate` of one dataset as its result document, or ``{"error", "data"}``
    if it fails with a robocal error (bad data, a problem that cannot be set up)."""
    where = str(data) if not isinstance(data, Dataset) else (data.source or repr(data))
    try:
        doc = calibrate(data, **options).to_dict()
    except RobocalError as exc:
        logger.info("calibrate_many: %s failed: %s", where, exc)
        return {"error": f"{type(exc).__name__}: {exc}", "data": where}
    logger.info("calibrate_many: %s calibrated", where)
    return doc


def _single_threaded_core() -> None:
    os.environ["RAYON_NUM_THREADS"] = "1"


def calibrate_many(datasets: Iterable[Union[str, Path, Dataset]], *, workers: Optional[int] = None, backend: str = "process", **options) -> list[dict]:
    """Calibrates every dataset; results in the order given.

    Parameters
    ----------
    datasets : iterable of paths or Datasets
    workers : int, optional
        Parallel workers (default: the number of CPUs).
    backend : {"process", "thread", "serial"}
        ``process``: a process pool, one single-threaded core per worker (the fastest for many
        calibrations); ``thread``: threads in this process (the Rust kernels release the
        interpreter, the orchestration does not); ``serial``: one after the other.
    **options
        Passed to :func:`robocal.calibrate` (``robot``, ``method``, ``test_fraction``, ...).
    """
    if isinstance(datasets, (str, bytes, Path, Dataset)) or not isinstance(datasets, Iterable):
        raise InvalidParameterError(f"`datasets` must be a list of paths or Datasets; got {type(datasets).__name__} {datasets!r:.80}")
    items = list(datasets)
    workers = (os.cpu_count() or 1) if workers is None else workers
    if isinstance(workers, bool) or not isinstance(workers, int) or workers < 1:
        raise InvalidParameterError(f"`workers` must be an integer >= 1; got {workers!r}")
    if backend == "serial" or len(items) <= 1:
        return [calibrate_one(d, **options) for d in items]
    if backend == "thread":
        with ThreadPoolExecutor(workers) as pool:
            return list(pool.map(lambda d: calibrate_one(d, **options), items))
    if backend == "process":
        # Spawned, not forked: a forked child inherits the parent's thread pool without its
        # threads, and the Rust core would wait on them for ever.
        spawn = multiprocessing.get_context("spawn")
        with ProcessPoolExecutor(workers, mp_context=spawn, initializer=_single_threaded_core) as pool:
            futures = [pool.submit(calibrate_one, d, **options) for d in items]
            return [f.result() for f in futures]
    raise InvalidParameterError(f"`backend` must be 'process', 'thread' or 'serial'; got {backend!r}")
