"""The control loop's clock on the servo bus: what each period cost and why a late one was late.

:class:`LoopTiming` keeps one row a period in an array allocated once (a ring of ``capacity``
rows): when the period started on the wall clock (``time.perf_counter``), the achieved period,
the bus's read and write round trips, the age of the measurement the torque came from, how
late the period started, the loop thread's CPU time until the next period
(``time.thread_time``, CLOCK_THREAD_CPUTIME_ID), the time the thread spent runnable but not
running in that interval (Linux's ``/proc/thread-self/schedstat``: being preempted, or waiting
for a core after a sleep) and, for a late period, its cause.

A period is *late* when it starts more than :data:`LATE_FRACTION` of a period after it is due.
The interval since the previous period started is the sleep the loop asked for, plus its work:
the loop's CPU time (``"loop CPU"``), the time it waited for a core (``"preempted"``; without
schedstat, taken as zero), and the rest, off the CPU: waiting for the bus's reply, up to the
bus's round trips (``"bus reply"``), and beyond them ``"blocked"`` (Python's GIL held by
another thread, a lock, a page read from disk). A late period's cause is the largest of the
four. docs/hardware_bus.md, "Timing".
"""

from __future__ import annotations

import math
import os
import time

import numpy as np

#: A period that starts more than this fraction of a period after it is due is late (its cause
#: is recorded).
LATE_FRACTION = 0.2

#: The causes of a late period, by code (0: on time).
CAUSES = ("", "bus reply", "loop CPU", "preempted", "blocked")
BUS, CPU, PREEMPTED, BLOCKED = 1, 2, 3, 4

#: The record's columns, in order.
COLUMNS = ("start", "period", "read", "write", "age", "late", "cpu", "wait", "cause")
_START, _PERIOD, _READ, _WRITE, _AGE, _LATE, _CPU, _WAIT, _CAUSE = range(len(COLUMNS))


def _or_zero(value) -> float:
    """``value``, 0.0 for NaN (what was not measured)."""
    value = float(value)
    return value if value == value else 0.0


def stats(values) -> dict:
    """{"n", "median", "p99", "worst"} of ``values`` (s, NaN left out); {"n": 0} when none.
    "worst" is the largest magnitude, with its sign."""
    v = np.asarray(values, dtype=float)
    v = v[np.isfinite(v)]
    if not v.size:
        return {"n": 0}
    return {
        "n": int(v.size),
        "median": float(np.median(v)),
        "p99": float(np.percentile(v, 99)),
        "worst": float(v[np.argmax(np.abs(v))]),
    }


class _RunQueueClock:
    """The calling thread's time spent runnable but not running, s, from Linux's
    ``/proc/thread-self/schedstat`` (its second field, ns), opened in the thread it measures;
    ``read()`` is NaN where the file is missing (another OS, a kernel without schedstats)."""

    def __init__(self):
        try:
            self._fd: int | None = os.open("/proc/thread-self/schedstat", os.O_RDONLY)
        except OSError:
            self._fd = None

    def read(self) -> float:
        if self._fd is None:
            return math.nan
        try:
            return 1e-9 * int(os.pread(self._fd, 64, 0).split()[1])
        except (OSError, IndexError, ValueError):
            return math.nan

    def close(self) -> None:
        if self._fd is not None:
            os.close(self._fd)
            self._fd = None


class LoopTiming:
    """Per-period timing records of a control loop, in an array allocated once.

    Call :meth:`begin` in the loop's thread when a period starts (after any sleep to its due
    time), then :meth:`end` when its bus work is done; :meth:`summary` reports.

    Args:
        period_s: the nominal period, s.
        capacity: rows kept (the last ``capacity`` periods).
    """

    def __init__(self, period_s: float, capacity: int = 360_000):
        self.period_s = float(period_s)
        self._rows = np.full((max(int(capacity), 2), len(COLUMNS)), math.nan)
        self.reset()

    def reset(self) -> None:
        """Forget every record."""
        self._rows[:] = math.nan
        self.count = 0  # periods recorded so far (the ring holds the last len(_rows))
        self._cpu0 = self._wait0 = self._start0 = math.nan
        self._slept = 0.0
        self._clock: _RunQueueClock | None = None

    def begin(self, now: float, late: float, slept: float) -> int:
        """Period ``count`` started at ``now`` (perf_counter s), ``late`` s after it was due,
        having asked to sleep ``slept`` s before it. Closes the previous period's row (its CPU
        and run-queue wait until now) and returns this period's cause code (0: on time)."""
        cpu, wait = time.thread_time(), math.nan
        if self._clock is None:
            self._clock = _RunQueueClock()
        wait = self._clock.read()
        rows, k = self._rows, self.count
        cause = 0
        if k:
            prev = rows[(k - 1) % len(rows)]
            prev[_CPU] = cpu - self._cpu0
            prev[_WAIT] = wait - self._wait0
            if late > LATE_FRACTION * self.period_s:
                cause = self._cause(prev, now - self._start0, slept)
        row = rows[k % len(rows)]
        row[_START], row[_LATE], row[_CAUSE] = now, late, cause
        row[_PERIOD] = now - self._start0
        row[_CPU] = row[_WAIT] = row[_READ] = row[_WRITE] = row[_AGE] = math.nan
        self._cpu0, self._wait0, self._start0 = cpu, wait, now
        return cause

    def end(self, read_s: float, write_s: float, age_s: float) -> None:
        """The bus's round trips and the measurement's age of the period begun last, s."""
        row = self._rows[(self.count) % len(self._rows)]
        row[_READ], row[_WRITE], row[_AGE] = read_s, write_s, age_s
        self.count += 1

    @staticmethod
    def _cause(prev, interval: float, slept: float) -> int:
        """The largest share of the work in ``interval`` (s since the previous period started,
        ``slept`` of it asked for): the loop's CPU, its wait for a core, its wait off the CPU
        for the bus's reply (up to the round trips), or blocked otherwise."""
        cpu, wait = float(prev[_CPU]), _or_zero(prev[_WAIT])
        off = max(0.0, interval - slept - cpu - wait)
        bus = min(off, _or_zero(prev[_READ]) + _or_zero(prev[_WRITE]))
        shares = (bus, cpu, wait, off - bus)
        return (BUS, CPU, PREEMPTED, BLOCKED)[shares.index(max(shares))]

    def rows(self) -> np.ndarray:
        """(n, len(COLUMNS)) the records kept, oldest first (a copy); columns :data:`COLUMNS`,
        s (cause: a code of :data:`CAUSES`). The last row's cpu and wait are NaN (its period
        had not ended)."""
        n, size = self.count, len(self._rows)
        if n <= size:
            return self._rows[:n].copy()
        k = n % size
        return np.concatenate([self._rows[k:], self._rows[:k]])

    def summary(self) -> dict:
        """{"period", "jitter" (|period - nominal|: a period short or long alike), "read", "write"
        (the bus's round trips), "age" (of the measurement when its torque was written, from the
        second period on), "late" (start - due), "cpu" (the loop thread's CPU time a period), "wait"
        (its time runnable but not running a period): each :func:`stats`, s; "first_age": the first
        period's measurement's age, s (NaN when not kept): a reading taken before the loop started
        (a session's seed, then its checks, a wait for a first sample), not a late period's;
        "late_causes" {cause: periods} of the late periods (:data:`LATE_FRACTION`); "periods",
        "nominal"}."""
        r = self.rows()
        period = r[1:, _PERIOD]
        causes = r[:, _CAUSE][np.isfinite(r[:, _CAUSE])].astype(int)
        first = self.count <= len(self._rows)  # the ring still holds the first period
        return {
            "period": stats(period),
            "jitter": stats(np.abs(period - self.period_s)),
            "read": stats(r[:, _READ]),
            "write": stats(r[:, _WRITE]),
            "age": stats(r[1:, _AGE] if first else r[:, _AGE]),
            "first_age": float(r[0, _AGE]) if first and len(r) else math.nan,
            "late": stats(r[:, _LATE]),
            "cpu": stats(r[:, _CPU]),
            "wait": stats(r[:, _WAIT]),
            "late_causes": {
                CAUSES[c]: int(np.sum(causes == c))
                for c in (BUS, CPU, PREEMPTED, BLOCKED)
                if c in causes
            },
            "periods": self.count,
            "nominal": self.period_s,
        }
