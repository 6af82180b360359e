"""A motion followed live: samples received one at a time as they arrive, from any source (an
LCM channel, :mod:`stewart_drake.live.follow`), and followed by the same predictor and the same
curves as a recorded stream (:func:`~.stream.follow`).

:class:`LiveFollower` takes each sample with its sequence number and the time it was taken on
the source's clock (``utime``, microseconds), stamped with when it arrived on the follower's
clock, and refuses what a stream cannot be (:class:`~stewart_drake.base.errors.LiveSourceError`):
a sample that is not six finite numbers, out of order or repeated, spaced otherwise than the
stream's rate, or after more than :data:`MAX_GAP_S` of missing samples. A few missing samples
are filled in on the straight line between the two that arrived (both are known when the second
arrives: nothing later is used). Its reference at a time (:meth:`LiveFollower.evaluate`) is
what :class:`~.stream.FollowedStream` gives there from the two newest arrivals: each sample is
assumed ``latency_s`` old when it arrives, so the clocks of the source and of the follower never
need to agree. Fed a recorded stream's samples at their arrival times, it gives the offline
follower's reference (``tests/test_live_follow.py``).
"""

from __future__ import annotations

import math

import numpy as np

from ..base.errors import InvalidConfigError, LiveSourceError
from .prediction import DEFAULT_PREDICTOR, OnlinePredictor, PredictorSettings, check_predictor
from .stream import (
    BLEND_S,
    LOOP_LAG_S,
    PAST_NODES,
    SWITCH_S,
    FollowedStream,
    Stream,
    check_latency,
    follower_steps,
)

#: The longest run of missing samples filled in, s; a longer gap ends the stream.
MAX_GAP_S = 0.5
#: How far the spacing of two samples' ``utime`` may be from the stream's rate (times the
#: samples between them), as a share of it.
SPACING_TOLERANCE = 0.5
#: The start of a move of u that completed long ago (:meth:`LiveFollower.switches`), s.
_LONG_AGO = -1e9


def _seconds(duration_s: float) -> str:
    """A duration for a message: in ms below 1 s, else in s (4 significant digits)."""
    if abs(duration_s) < 1.0:
        return f"{duration_s * 1e3:.4g} ms"
    return f"{duration_s:.4g} s"


class LiveFollower:
    """The reference that follows a stream whose samples arrive one at a time (module
    docstring).

    Args:
        latency_s: how old a sample is when it arrives, s (plus the loop's lag when known).
        rate_hz: the samples' rate, Hz (their ``utime`` spacing is checked against it).
        predictor: one of :data:`~.prediction.PREDICTORS`. settings: its settings.
        loop_lag_s, blend_s: as :func:`~.stream.follow`. name: the source's name (messages).
    Attributes:
        dt: the sample step, s. steps: K, the samples ahead predicted.
        received: samples taken (filled-in ones not counted). filled: samples filled in.
        used_samples: samples after which the predictor's positions were chosen on some axis.
        last_arrival: when the newest sample arrived, s on the follower's clock (None before).
        using: (6,) bool, whether the predictor's positions are chosen on each axis now.
        sigma: (K, 6) their uncertainty (:class:`~.prediction.OnlinePredictor`).
    Raises:
        InvalidConfigError: a bad latency, rate or predictor.
    """

    def __init__(
        self,
        latency_s: float,
        rate_hz: float,
        predictor: str = DEFAULT_PREDICTOR,
        settings: PredictorSettings | None = None,
        loop_lag_s: float = LOOP_LAG_S,
        blend_s: float = BLEND_S,
        name: str = "live stream",
    ):
        self.latency_s = check_latency(latency_s)
        self.predictor = check_predictor(predictor)
        if not (isinstance(rate_hz, (int, float)) and math.isfinite(rate_hz)):
            raise InvalidConfigError(f"the stream's rate must be a number of Hz, got {rate_hz!r}")
        if not 0 < rate_hz <= 1000:
            raise InvalidConfigError(f"the stream's rate must be in (0, 1000] Hz, got {rate_hz!r}")
        if not (math.isfinite(loop_lag_s) and 0 <= loop_lag_s < 1 and blend_s > 0):
            raise InvalidConfigError(
                f"loop_lag_s must be in [0, 1) s and blend_s > 0 s, got {loop_lag_s}, {blend_s}"
            )
        self.settings = settings or PredictorSettings()
        self.name, self.dt = str(name), 1.0 / float(rate_hz)
        self.loop_lag_s, self.blend_s = float(loop_lag_s), float(blend_s)
        self.steps = follower_steps(self.latency_s, self.dt, self.loop_lag_s, min(blend_s, self.dt))
        self._model = OnlinePredictor(predictor, self.dt, self.steps, 6, self.settings)
        self._past: np.ndarray | None = None  # the PAST_NODES samples before the newest
        self._newest: tuple | None = None  # (arrival, pose, nodes, using, sigma)
        self._before: tuple | None = None  # the arrival followed before the newest's instant
        self._window: FollowedStream | None = None
        self._moves: list = []  # moves of u not yet complete: (start, axis, direction)
        self._base = np.zeros(6)  # u of the completed moves
        self._heading = np.zeros(6, dtype=bool)  # where u is going, per axis
        self._free_at = np.full(6, -np.inf)
        self.received = self.filled = self.used_samples = 0
        self.last_arrival: float | None = None
        self._last: tuple | None = None  # (seq, utime, pose) of the newest sample taken
        self.using = np.zeros(6, dtype=bool)
        self.sigma = np.full((self.steps, 6), np.nan)

    @property
    def clipped(self) -> int:
        """Predicted positions clipped to the motion's recent range (count)."""
        return self._model.clipped

    @property
    def rejected(self) -> int:
        """Samples' axes taken as outliers (count, :class:`~.prediction.OnlinePredictor`)."""
        return self._model.rejected

    @property
    def fallbacks(self) -> int:
        """The times an axis went back to no prediction, its record no longer better (count,
        :class:`~.prediction.OnlinePredictor`)."""
        return self._model.fallbacks

    def receive(self, now: float, seq: int, utime_us: int, pose) -> None:
        """Take sample ``seq`` (taken at ``utime_us`` on the source's clock, us), which arrived
        at ``now`` (s on the follower's clock, never earlier than the previous arrival).

        Raises:
            LiveSourceError: a pose that is not 6 finite numbers; ``seq`` or ``utime_us`` not
                after the previous sample's; a spacing more than :data:`SPACING_TOLERANCE` off
                the rate; more than :data:`MAX_GAP_S` of samples missing before it. Each names
                the source and the sample.
        """
        where = f"{self.name}: sample {seq}"
        try:
            y = np.asarray(pose, dtype=float).reshape(-1)
        except (TypeError, ValueError):
            y = np.zeros(0)
        if y.shape != (6,) or not np.all(np.isfinite(y)):
            shown = ", ".join(f"{v:g}" for v in y[:8]) if y.size else repr(pose)[:80]
            raise LiveSourceError(f"{where} is not 6 finite numbers: [{shown}]")
        if self.last_arrival is not None and now < self.last_arrival:
            raise LiveSourceError(f"{where} arrived at {now} s, before the previous one")
        if self._last is not None:
            seq0, utime0, y0 = self._last
            if seq <= seq0 or utime_us <= utime0:
                raise LiveSourceError(
                    f"{where} (utime {utime_us}) after sample {seq0} (utime {utime0}): out of "
                    "order or repeated"
                )
            gap = seq - seq0
            elapsed = (utime_us - utime0) * 1e-6
            if abs(elapsed / gap / self.dt - 1.0) > SPACING_TOLERANCE:
                rate = f"the stream's rate ({1 / self.dt:.4g} Hz)"
                if gap == 1:
                    raise LiveSourceError(
                        f"{where}: the samples are {_seconds(elapsed)} apart, not the "
                        f"{_seconds(self.dt)} of {rate}"
                    )
                raise LiveSourceError(
                    f"{where} (utime {utime_us}) is {_seconds(elapsed)} after sample {seq0} "
                    f"(utime {utime0}) on the source's clock, but {gap} samples after it: "
                    f"{_seconds(gap * self.dt)} at {rate}; the source's numbering or its clock "
                    "jumped"
                )
            if (gap - 1) * self.dt > MAX_GAP_S:
                raise LiveSourceError(
                    f"{where}: samples {seq0 + 1}..{seq - 1} are missing "
                    f"({(gap - 1) * self.dt:.3g} s, more than {MAX_GAP_S:g} s)"
                )
            for j in range(1, gap):  # the missing ones, on the line between the two known
                self._take(now, y0 + (y - y0) * (j / gap))
                self.filled += 1
        self._take(now, y)
        self._last = (int(seq), int(utime_us), y)
        self.received += 1
        self.used_samples += int(self.using.any())

    def _take(self, now: float, y: np.ndarray) -> None:
        """Sample ``y`` into the predictor and the curves, arrived at ``now``."""
        if self._past is None:
            self._past = np.repeat(y[None, :], PAST_NODES, axis=0)
        ahead = self._model.raw_update(y)
        y = self._model.sample  # the outliers' axes replaced
        nodes = np.concatenate([self._past, y[None, :], ahead])
        self.using, self.sigma = self._model.using.copy(), self._model.sigma.copy()
        self._past = np.concatenate([self._past[1:], y[None, :]])
        if self.last_arrival is None or now > self.last_arrival:
            self._before = self._newest  # what was followed until now
        self._newest = (float(now), y, nodes, self.using, self.sigma)
        self.last_arrival = float(now)
        self._window = None
        for axis in range(6):  # the moves of u, as FollowedStream's (stream._switches)
            if self.using[axis] != self._heading[axis] and now >= self._free_at[axis]:
                self._heading[axis] = self.using[axis]
                self._moves.append((float(now), axis, 1.0 if self.using[axis] else -1.0))
                self._free_at[axis] = now + SWITCH_S

    def switches(self, now: float) -> np.ndarray:
        """(S, 3) the moves of u in force at ``now``: those that completed folded into one
        per axis started long ago, then those under way (as :class:`~.stream.FollowedStream`'s
        ``switches``)."""
        under_way = []
        for start, axis, direction in self._moves:
            if start + SWITCH_S <= now:
                self._base[axis] += direction
            else:
                under_way.append((start, axis, direction))
        self._moves = under_way
        done = [(_LONG_AGO, a, self._base[a]) for a in range(6) if self._base[a] != 0]
        return np.array(done + under_way, dtype=float).reshape(-1, 3)

    def evaluate(self, now: float):
        """(pose, rate, acceleration) (6,) each of the followed reference at ``now`` (s, at
        or after the newest arrival: its curve blended from the one followed before), rad and
        m, per s, per s^2; None before the first sample."""
        if self._newest is None:
            return None
        if self._window is None:
            arrivals = [a for a in (self._before, self._newest) if a is not None]
            t = np.array([a[0] for a in arrivals]) - self.latency_s
            stream = Stream(t, np.array([a[1] for a in arrivals]), self.latency_s, self.name,
                            step_s=self.dt)  # fmt: skip
            self._window = FollowedStream(
                stream,
                self.predictor,
                self.settings,
                self.loop_lag_s,
                self.blend_s,
                np.array([a[2] for a in arrivals]),
                np.array([a[3] for a in arrivals]),
                np.array([a[4] for a in arrivals]),
                self.clipped,
            )
        self._window.switches = self.switches(now)
        x, v, a = self._window.evaluate(np.array([float(now)]))
        return x[0], v[0], a[0]


__all__ = ["LiveFollower", "MAX_GAP_S", "SPACING_TOLERANCE"]
