"""The terminal's signals (SIGINT, SIGTERM, SIGHUP, SIGQUIT) around a session on the robot
(:mod:`.session`): the first ends the run; once the torque is going off a signal is recorded, not
raised, so nothing cuts short the torque-off's confirmation, the logs or the end line
(:class:`SessionSignals`)."""

from __future__ import annotations

import signal
import threading

from ..execution.runners import TERMINAL_SIGNALS


def signal_name(err: BaseException) -> tuple[str, int]:
    """(the name of the signal an interrupt ``err`` names, SIGINT by default; the exit status
    128 + its number)."""
    signum = getattr(err, "signum", signal.SIGINT)
    return signal.Signals(signum).name, 128 + int(signum)


class SessionSignals:
    """The terminal's signals around a session on the robot (main thread only; a signal
    the process was started ignoring stays ignored).

    Until :meth:`hold` (the torque-off) the first of them raises
    :class:`~stewart_drake.execution.runners.Interrupted` (a KeyboardInterrupt naming it, as
    the CLI's handlers do): it ends the run. From then on, and after that first one, a signal is
    recorded in ``received`` instead of raised, so that nothing cuts short the torque-off's
    confirmation, closing the bus, the logs or the end line (an operator's Ctrl-C as the
    platform settles would otherwise lose all of them); :meth:`settle` then names it in the
    session's reason and exit status.

        with SessionSignals() as signals:
            run = run_on_robot(scenario, signals=signals)
            signals.settle(run)
            print(end_line(run))
        sys.exit(run.exit_code)

    Attributes:
        received: the first signal number recorded while held, or None.
        raised: the signal raised (the first), or None.
    """

    NAMES = TERMINAL_SIGNALS

    def __init__(self):
        self.received: int | None = None
        self.raised: int | None = None
        self.holding = False
        self._settled = False
        self._old: dict = {}

    def __enter__(self) -> SessionSignals:
        if threading.current_thread() is threading.main_thread():
            for name in self.NAMES:
                signum = getattr(signal, name, None)
                if signum is not None and signal.getsignal(signum) is not signal.SIG_IGN:
                    self._old[signum] = signal.signal(signum, self._handle)
        return self

    def __exit__(self, *exc) -> None:
        for signum, handler in self._old.items():
            signal.signal(signum, handler)
        self._old.clear()

    def arm(self) -> None:
        """Just before the torque goes on: raise a signal received so far that did not stop
        the session (one raised where code swallowed it, "Exception ignored" in a callback of
        numba's compiler; one recorded after that; one the command's own handlers raised
        before the session began, :func:`~stewart_drake.execution.runners.interrupt_raised`),
        and raise the next again: while the torque is on a signal is never held.

        Raises:
            Interrupted: the first such signal.
        """
        from ..execution.runners import Interrupted, interrupt_raised

        for seen in (self.raised, self.received, interrupt_raised()):
            if seen is not None:
                raise Interrupted(seen)
        self.holding = False

    def hold(self) -> None:
        """From now on, record signals instead of raising them."""
        self.holding = True

    def _handle(self, signum, frame) -> None:
        from ..execution.runners import Interrupted

        if self.holding:
            if self.received is None:
                self.received = int(signum)
            return
        self.holding = True  # the one raised ends the run; the next must not cut its end
        self.raised = int(signum)  # known to arm() even if the raise is swallowed
        raise Interrupted(signum)

    def settle(self, run):
        """Name a recorded signal in ``run.reason`` (once) and make the exit status 128 + its
        number where the session had otherwise succeeded; returns ``run`` (a
        :class:`~.session.RobotRun`)."""
        if self.received is None or self._settled:
            return run
        self._settled = True
        name = signal.Signals(self.received).name
        kept = "held until the logs were saved" if run.logs is not None else "held to the end"
        run.reason += f"; {name} received after the torque went off: {kept}"
        if run.exit_code == 0:
            run.exit_code = 128 + self.received
        return run


__all__ = [
    "SessionSignals",
    "signal_name",
]
