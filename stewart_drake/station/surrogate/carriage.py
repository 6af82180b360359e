"""The external surrogate's command on the robot: its recorded trace, read and checked, on the
run's clock beside the platform's reference (``stewart-drake robot INTERNAL --surrogate
EXTERNAL``).

:func:`load_surrogate` reads the external file through the one reader of it, the Diagram's too
(:func:`~stewart_drake.station.surrogate.trace.load_surrogate_trace`, on the checked reader of
traces; IntERAct's ``Resp/`` 2-column files are its "surrogate" format, the displacement in mm on
SI) and keeps its one displaced axis
(:class:`~stewart_drake.station.surrogate.trace.SurrogateTrace`): the carriage's position ``s`` (m)
is that displacement, centred on its mean (the stage's mid-travel). :class:`SurrogateCommand` puts
it on the run's clock exactly as :class:`~stewart_drake.references.homing.HomingReference` puts the
platform's: the same lead-in (a quintic from where the carriage was read to the trace's start, in
the same ``home_s``), then the trace on the same warped clock tau(t), ended at rest at the same
time; so the two references are one clock's, and whatever differs between the two motions measured
is the two loops' (their relative latency:
:func:`stewart_drake.base.pair_figures.relative_latency`).
"""

from __future__ import annotations

import numpy as np

from ...references.homing import HomingReference
from .trace import SurrogateTrace, load_surrogate_trace


def load_surrogate(path) -> SurrogateTrace:
    """The external surrogate's trace at ``path`` for ``robot --surrogate`` (a 2-column file:
    time, displacement in mm; or a headed file with one axis), read by the one reader of the
    external's file (:func:`~stewart_drake.station.surrogate.trace.load_surrogate_trace`),
    centred on its mean.

    Raises:
        MissingFileError, CorruptFileError, InvalidConfigError: as ``load_trace``'s; a trace of
            more than one axis (the surrogate moves along one), or a rotation (named
            ``--surrogate PATH``).
    """
    return load_surrogate_trace(path, option="--surrogate")


class SurrogateCommand:
    """The carriage's command on the run's clock (module docstring): from ``s_start`` (m, where
    it was read) to the trace's start in ``homed.home_s``, then the trace on ``homed``'s warped
    clock.

    Args:
        surrogate: the :class:`SurrogateTrace`. homed: the platform's
            :class:`~stewart_drake.references.homing.HomingReference` (its lead-in, end and
            ramps are taken).
        s_start: the carriage's position read before the torque goes on, m.
    """

    def __init__(self, surrogate: SurrogateTrace, homed: HomingReference, s_start: float):
        # On the platform's motion's clock: the two files' times as written relate them.
        surrogate = surrogate.on_clock_of(homed.reference)
        self.surrogate = surrogate
        self.homed = HomingReference(
            _Line(surrogate), _line_pose(s_start), homed.home_s, homed.t_end, homed.ramp_s
        )

    def evaluate(self, t):
        """(s, v, a) commanded at run times t (s, any shape): m, m/s, m/s^2."""
        x, v, a = self.homed.evaluate(np.asarray(t, dtype=float))
        return x[..., 3], v[..., 3], a[..., 3]

    def __call__(self, t: float) -> tuple[float, float, float]:
        """(s, v, a) at one run time ``t``."""
        s, v, a = self.evaluate(np.array([t]))
        return float(s[0]), float(v[0]), float(a[0])

    def sampled(self, period_s: float, t_end: float) -> SampledCommand:
        """This command sampled every ``period_s`` from 0 to ``t_end`` (s), for the driver's
        per-period call: an evaluation of the spline and the warp costs some 0.3 ms, a
        lookup a microsecond."""
        return SampledCommand(self, period_s, t_end)


class SampledCommand:
    """A :class:`SurrogateCommand` sampled on the control period's grid, evaluated by linear
    interpolation between its samples (exact at the grid's instants, where the driver asks);
    before 0 and after ``t_end`` its first and last samples.

    Args:
        command: the command.  period_s: the grid's step, s.  t_end: its last time, s.
    """

    def __init__(self, command: SurrogateCommand, period_s: float, t_end: float):
        self.period_s = float(period_s)
        n = int(np.ceil(t_end / self.period_s)) + 1
        self._table = np.column_stack(command.evaluate(np.arange(n) * self.period_s))
        self._last = n - 1

    def __call__(self, t: float) -> tuple[float, float, float]:
        """(s, v, a) at run time ``t``, m, m/s, m/s^2."""
        x = t / self.period_s
        k = min(max(int(x), 0), self._last)
        w = min(max(x - k, 0.0), 1.0) if k < self._last else 0.0
        row, nxt = self._table[k], self._table[min(k + 1, self._last)]
        return (
            float(row[0] + w * (nxt[0] - row[0])),
            float(row[1] + w * (nxt[1] - row[1])),
            float(row[2] + w * (nxt[2] - row[2])),
        )


def _line_pose(s: float) -> np.ndarray:
    """A 6-vector holding ``s`` in its X slot: the carriage as a pose for HomingReference."""
    x = np.zeros(6)
    x[3] = s
    return x


class _Line:
    """A :class:`SurrogateTrace` as a 6-D reference (``s`` in the X slot) for
    :class:`~stewart_drake.references.homing.HomingReference`, which warps and leads in every
    coordinate alike."""

    def __init__(self, surrogate: SurrogateTrace):
        self.surrogate = surrogate
        self.name = "surrogate"

    def evaluate(self, t):
        t = np.asarray(t, dtype=float)
        out = []
        for part in self.surrogate.evaluate(t):
            full = np.zeros(t.shape + (6,))
            full[..., 3] = part
            out.append(full)
        return tuple(out)
