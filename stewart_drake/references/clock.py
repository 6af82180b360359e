"""A recorded trace on another file's clock: two files recorded together (a motion and its
surrogate, a motion and the robot's log) are related by the times each file wrote, never both
re-zeroed onto 0 (a file that starts later is played later by as much)."""

import numpy as np


def clock_start_s(reference) -> float | None:
    """The first time as written of the trace a reference plays (``info.start_s``, through the
    wrappers that keep the reference they wrap as ``reference``: a scale, layers, the homing),
    s; None for a reference of no file (a motion of the library has no recorded clock)."""
    for _ in range(16):  # wrappers do not nest deeper
        info = getattr(reference, "info", None)
        if info is not None and hasattr(info, "start_s"):
            return float(info.start_s)
        reference = getattr(reference, "reference", None)
        if reference is None:
            break
    return None


class OnClockOf:
    """A reference on another's clock: ``reference`` recorded on one clock with ``internal``,
    its file starting ``lag_s`` = its first time less the internal's later, is evaluated at the
    internal's times less ``lag_s`` (held before its start and after its end, as a trace is).
    What the reference says of itself (name, centre, info, cycles found where it peaks) stays;
    its start and end move by the lag.

    Args:
        reference: a :class:`~.motion.Reference` (a trace). lag_s: s.
    """

    def __init__(self, reference, lag_s: float):
        self.reference, self.lag_s = reference, float(lag_s)
        self.name = getattr(reference, "name", "reference")
        self.info = getattr(reference, "info", None)
        self.centre = getattr(reference, "centre", None)
        end = getattr(reference, "end_time", None)
        self.end_time = None if end is None else float(end) + self.lag_s
        self.start_time = float(getattr(reference, "start_time", 0.0) or 0.0) + self.lag_s

    def evaluate(self, t):
        """Pose, rate, acceleration at the internal's times t (s), as ``reference`` gives them
        at t - lag_s."""
        return self.reference.evaluate(np.asarray(t, dtype=float) - self.lag_s)

    def frequencies_hz(self) -> dict:
        f = getattr(self.reference, "frequencies_hz", None)
        return f() if callable(f) else {}


def on_clock_of(reference, internal):
    """``reference`` (a surrogate's trace) on the clock of ``internal`` (the motion it was
    recorded with): the two files' times as written relate them (:func:`clock_start_s`); a file
    that starts later than the other is played later by as much, never re-zeroed onto it.
    Returns ``reference`` itself when both start together, or when either has no file's clock
    (a motion of the library: each then starts at 0).

    Raises:
        InvalidConfigError: two files whose times as written do not overlap (not recorded
            together: the one would play the other's first or last pose throughout).
    """
    mine, theirs = clock_start_s(reference), clock_start_s(internal)
    if mine is None or theirs is None or mine == theirs:
        return reference
    lag = mine - theirs
    spans = [getattr(r, "end_time", None) for r in (reference, internal)]
    if None not in spans and (lag >= spans[1] or lag + spans[0] <= 0.0):
        from ..base.errors import InvalidConfigError

        def written(start, span):
            return f"t = {start:.6g}-{start + span:.6g} s as written"

        raise InvalidConfigError(
            f"{getattr(reference, 'name', 'the surrogate')} ({written(mine, spans[0])}) and "
            f"{getattr(internal, 'name', 'the motion')} ({written(theirs, spans[1])}) do not "
            "overlap: they were not recorded together; give the two files of one session"
        )
    return OnClockOf(reference, lag)


__all__ = ["clock_start_s", "OnClockOf", "on_clock_of"]
