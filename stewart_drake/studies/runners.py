"""Runners: how a study's independent jobs are executed (in this process, or over processes).

A runner has ``n_workers`` and ``map(fn, jobs)`` yielding ``fn(job)`` for each job; jobs and
results are plain picklable values.
"""

from __future__ import annotations

import os


class SerialRunner:
    """Runs jobs one after the other in this process (``map`` like the builtin)."""

    n_workers = 1

    def map(self, fn, jobs):
        return map(fn, jobs)


class ProcessRunner:
    """Runs jobs over local processes; any object with the same ``map`` (a Ray or Dask
    executor's) can take its place, since jobs and results are plain picklable values."""

    def __init__(self, n_workers: int = 0):
        self.n_workers = n_workers or os.cpu_count() or 1

    def map(self, fn, jobs):
        from concurrent.futures import ProcessPoolExecutor

        with ProcessPoolExecutor(max_workers=self.n_workers) as pool:
            yield from pool.map(fn, jobs)


def runner_for_jobs(jobs: int):
    """The runner for a ``--jobs`` value: 1 runs here (:class:`SerialRunner`), 0 one process per
    core, N that many processes (:class:`ProcessRunner`)."""
    return SerialRunner() if jobs == 1 else ProcessRunner(jobs)
