"""Our watchdog on the robot: the torque removed when the control loop stops completing periods.

:class:`LoopWatchdog` runs a thread that removes the servos' torque when no period completed for
its timeout; :func:`watchdog_monitor` is the Simulator's monitor that kicks it after every step
and ends the run at the step after a trip. A session (:mod:`~.session`) runs its loop behind
both.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable

from ..base.errors import InvalidConfigError, LoopStalledError

#: Default time our watchdog lets pass without a completed control period, s.
LOOP_TIMEOUT_S = 0.1


#: Longest loop timeout, s (the bus rehearsal's, on a loaded machine, is 5 s).
MAX_LOOP_TIMEOUT_S = 10.0


def check_loop_timeout(timeout_s: float, control_period_s: float) -> float:
    """Refuse, before anything is powered, a loop timeout our watchdog could not keep: shorter
    than two control periods (the first period a little late would remove the torque; 1e-9 s
    removed it at once) or longer than :data:`MAX_LOOP_TIMEOUT_S`.

    Returns:
        ``timeout_s``.
    Raises:
        InvalidConfigError: names ``--loop-timeout``, the period and the range that fits.
    """
    low = 2.0 * control_period_s
    if not low <= timeout_s <= MAX_LOOP_TIMEOUT_S:
        raise InvalidConfigError(
            f"--loop-timeout {timeout_s:g} s: our watchdog needs at least two control periods "
            f"(2 x {control_period_s:g} s) and at most {MAX_LOOP_TIMEOUT_S:g} s; give a value in "
            f"[{low:g}, {MAX_LOOP_TIMEOUT_S:g}] s"
        )
    return timeout_s


class LoopWatchdog:
    """Our watchdog: removes the servos' torque when the control loop stops completing periods.

    :meth:`kick` marks a completed period (the session kicks from the Simulator's monitor,
    after every step); a thread checks every ``timeout_s / 4`` and, if no kick came for
    ``timeout_s``, calls ``torque_off()`` itself (under the bus's lock, waiting for a transfer in
    progress at most 1 s) and records why in ``tripped``; the monitor then raises
    :class:`~stewart_drake.base.errors.LoopStalledError` at the loop's next step, which ends the run
    (a flag, not a signal to the main thread: a process started in the background of a script
    ignores SIGINT, and would run on). The
    servos' own bus watchdog (``bus.watchdog_s``) is the backstop when this process dies; some
    firmware does not stop on it (docs/hardware_bus.md), so this one does not rely on it.

    Args:
        torque_off: callable removing the torque (returns whether confirmed).
        timeout_s: the longest time without a completed period, s.
    """

    def __init__(self, torque_off: Callable[[], bool], timeout_s: float = LOOP_TIMEOUT_S):
        if not 0 < timeout_s <= 10:
            raise InvalidConfigError(f"the loop timeout must be in (0, 10] s, got {timeout_s}")
        self.torque_off, self.timeout_s = torque_off, float(timeout_s)
        self.tripped: str | None = None
        self._last = time.perf_counter()
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="robot-watchdog", daemon=True)

    def kick(self) -> None:
        self._last = time.perf_counter()

    @property
    def native_id(self) -> int | None:
        """The OS's id of the watchdog's thread (None before it starts)."""
        return self._thread.native_id

    def __enter__(self):
        self.kick()
        self._thread.start()
        return self

    def __exit__(self, *exc):
        self._stop.set()
        self._thread.join(2.0)

    def _run(self) -> None:
        while not self._stop.wait(self.timeout_s / 4):
            late = time.perf_counter() - self._last
            if late > self.timeout_s:
                confirmed = self.torque_off()
                self.tripped = (
                    f"the control loop stopped: no period completed for {late * 1e3:.0f} ms "
                    f"(limit {self.timeout_s * 1e3:.0f} ms); our watchdog removed the torque "
                    + ("(confirmed)" if confirmed else "(NOT confirmed: cut the servos' power)")
                )
                return


def watchdog_monitor(watchdog: LoopWatchdog):
    """The Simulator's monitor: each step completed kicks ``watchdog``; returns Drake's
    "continue" status."""
    from pydrake.systems.framework import EventStatus

    succeeded = EventStatus.Succeeded()

    def monitor(context):
        if watchdog.tripped is not None:
            raise LoopStalledError(watchdog.tripped)
        watchdog.kick()
        return succeeded

    return monitor
