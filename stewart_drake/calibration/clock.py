"""The tracker's clock against the robot computer's: the offset found from the motion both saw.

A tracker on its own computer stamps its samples on its own clock; the join
(:mod:`~stewart_drake.calibration.join`) needs them on the robot computer's, the encoder log's
``time``. Both saw the same motion: the robot drove the planned path, whose pose at each line of
the encoder log is known from the line's ``t_path``, and the tracker followed the platform.
:func:`estimate_clock_offset` finds the offset d (tracker time + d = robot time) in two steps:

1. **coarse**: the d of least RMS distance between the two speed profiles, each sampled every
   :data:`COARSE_DT_S` over its own clock's span (the path's speed 0 off its span), over every
   offset at which the two spans meet: d to a sample, whatever its size (a tracker that stamps
   the time since its own start is millions of seconds off);
2. **fine**: the d within two coarse samples of it that minimises the RMS distance between the
   tracked poses on the path and the planned ones at t + d, to a microsecond.

Both are the package's one lag search (:mod:`stewart_drake.base.lag`: every shift at once by FFT
in :func:`~stewart_drake.base.lag.coarse_shift`, then scipy's bounded scalar minimisation in
:func:`~stewart_drake.base.lag.refine_shift`).

The planned pose stands for the robot's: the robot follows the path within its calibration
errors (millimetres, a constant the fit does not trade against time) and its controller's lag
(under a millisecond at the path's speeds). Poses are compared in one length, rotations weighted
by :data:`ROTATION_WEIGHT_M` (a point that far from the axis). Refused, with what to do instead:
a span longer than :data:`MAX_SPAN_S` (the allocation is bounded), a record that never moves
(:data:`MIN_PEAK_SPEED`),
fewer than :data:`MIN_OVERLAP` tracked samples on the path once aligned, a residual above
:data:`MAX_RESIDUAL_M` (the tracker did not see this path, or its frames are not B and E).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..base.columns import interp_columns
from ..base.errors import InvalidConfigError
from ..base.lag import ROTATION_WEIGHT_M, coarse_shift, refine_shift

#: The coarse step's sampling period, s: the path's moves last a second or more.
COARSE_DT_S = 0.1
#: Longest span of either clock the estimate samples, s (a day: 864,000 coarse samples).
MAX_SPAN_S = 86400.0
#: Below this peak speed a record does not move, m/s (rotations weighted): a tracker's noise at
#: rest is a few hundredths of it, the path's moves up to 30 times it.
MIN_PEAK_SPEED = 1e-3
#: Fewest tracked samples that must fall on the path once aligned.
MIN_OVERLAP = 100
#: Largest RMS distance between the aligned tracked poses and the planned ones, m: the join's
#: own bound on a window's pose (:data:`~.join.MAX_POSE_GAP`). A robot drawn from the default
#: tolerances is 2.3 mm RMS off its path; a tracker that saw another path tens of millimetres.
MAX_RESIDUAL_M = 0.01
_WEIGHT = np.array([ROTATION_WEIGHT_M] * 3 + [1.0] * 3)
_REMEDY = (
    "give the offset with --tracker-clock-offset SECONDS (the tracker's time + SECONDS = the "
    "robot computer's), or record the tracker on the robot computer's clock"
)


@dataclass(frozen=True)
class ClockOffset:
    """The estimated offset of a tracker's clock.

    Attributes:
        offset_s: d, s: the tracker's time + d is the robot computer's.
        residual_m: RMS distance between the aligned tracked poses and the planned ones, m
            (rotations weighted by :data:`ROTATION_WEIGHT_M`).
        samples: tracked samples compared.
    """

    offset_s: float
    residual_m: float
    samples: int


def _checked_span(what: str, t: np.ndarray) -> float:
    span = float(t[-1] - t[0])
    if not 0 < span <= MAX_SPAN_S:
        raise InvalidConfigError(
            f"the {what} spans {span:.6g} s: the clock offset is estimated over spans of at most "
            f"{MAX_SPAN_S:g} s with increasing times; {_REMEDY}"
        )
    return span


def poses_at(t, t_known, x_known) -> np.ndarray:
    """(len(t), 6) the poses x_known (n, 6), known at the increasing times t_known (n,),
    interpolated linearly at the times t (held at the ends), each coordinate alone."""
    return interp_columns(t, t_known, x_known)


def _speeds(t: np.ndarray, x: np.ndarray, span: float) -> tuple[np.ndarray, np.ndarray]:
    """(times (k,) s, speeds (k,) m/s): the weighted speed of poses x (n, 6) at times t over
    each COARSE_DT_S from t[0], at the start of each."""
    grid = t[0] + COARSE_DT_S * np.arange(int(span / COARSE_DT_S) + 1)
    sampled = poses_at(grid, t, x)
    return grid[:-1], np.linalg.norm(np.diff(sampled, axis=0) * _WEIGHT, axis=1) / COARSE_DT_S


def estimate_clock_offset(robot_t, planned, tracker_t, tracked) -> ClockOffset:
    """Estimate the offset of a tracker's clock (module docstring).

    Args:
        robot_t: (n,) s, the robot computer's clock at the encoder log's lines on the path.
        planned: (n, 6) the path's poses at those lines, rad and m.
        tracker_t: (m,) s, the tracker's clock, increasing.
        tracked: (m, 6) the tracked poses, rad and m.
    Returns:
        :class:`ClockOffset`.
    Raises:
        InvalidConfigError: as the module docstring lists, each with what to do instead.
    """
    robot_t, tracker_t = np.asarray(robot_t, float), np.asarray(tracker_t, float)
    planned = np.asarray(planned, float).reshape(len(robot_t), 6)
    tracked = np.asarray(tracked, float).reshape(len(tracker_t), 6)
    if np.any(np.diff(robot_t) <= 0) or np.any(np.diff(tracker_t) <= 0):
        raise InvalidConfigError(f"the clocks' times must increase line by line; {_REMEDY}")
    g_robot, v_robot = _speeds(robot_t, planned, _checked_span("path in the encoder log", robot_t))
    g_tracker, v_tracker = _speeds(tracker_t, tracked, _checked_span("tracker file", tracker_t))
    for what, v in (("path", v_robot), ("tracker", v_tracker)):
        if not np.max(v) >= MIN_PEAK_SPEED:
            raise InvalidConfigError(
                f"the {what} never moves (its speed stays under {MIN_PEAK_SPEED * 1e3:g} mm/s): "
                f"the clock offset is found from the motion both saw; {_REMEDY}"
            )

    def path_speed(times):  # the path's speed at robot times, 0 off its span (at rest)
        return np.interp(times, g_robot, v_robot, left=0.0, right=0.0)[:, None]

    # Every offset at which the two spans meet.
    span = (g_robot[0] - g_tracker[-1], g_robot[-1] - g_tracker[0])
    coarse = coarse_shift(
        g_tracker, v_tracker[:, None], np.ones(1), path_speed, span, COARSE_DT_S, False
    )

    def planned_at(times):
        return poses_at(times, robot_t, planned)

    def on_path(d: float) -> np.ndarray:  # the tracked samples on the path at offset d
        return (tracker_t + d >= robot_t[0]) & (tracker_t + d <= robot_t[-1])

    def mean_square(d: float) -> tuple[float, int]:
        on = on_path(d)
        gap = tracked[on] - planned_at(tracker_t[on] + d)
        count = int(on.sum())
        return (float(np.mean(np.sum((gap * _WEIGHT) ** 2, axis=1))) if count else np.inf), count

    # The fine step compares the tracked samples on the path at the coarse offset.
    on = on_path(coarse)
    d = coarse
    if np.count_nonzero(on) >= 2:
        d = refine_shift(tracker_t[on], tracked[on], _WEIGHT, planned_at, d, 2 * COARSE_DT_S, False)
    ms, count = mean_square(d)
    if count < MIN_OVERLAP:
        raise InvalidConfigError(
            f"only {count} tracked samples fall on the path at the best offset ({d:+.4f} s), "
            f"fewer than {MIN_OVERLAP}: the tracker must record the whole path; {_REMEDY}"
        )
    residual = float(np.sqrt(ms))
    if not residual <= MAX_RESIDUAL_M:
        raise InvalidConfigError(
            f"at the best offset ({d:+.4f} s) the tracked poses are {residual * 1e3:.3g} mm RMS "
            f"from the planned path (at most {MAX_RESIDUAL_M * 1e3:g} mm): the tracker did not "
            f"see this path, or its frames are not B and E (give them: --registration REG.yaml, "
            f"docs/calibration.md); {_REMEDY}"
        )
    return ClockOffset(d, residual, count)
