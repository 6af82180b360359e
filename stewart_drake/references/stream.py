"""A motion that arrives late, and the reference that follows it: each sample reaches the
controller a latency after it happened, and the follower commands where the motion is expected
to be by the time the robot gets there.

A :class:`Stream` is the samples of a motion (a recorded trace, a library motion, or a live
source) at their own rate, each known from its arrival, ``latency_s`` after it happened.
:func:`follow` turns it into a reference (:class:`FollowedStream`, a
:class:`~.motion.Reference`): at each arrival the predictor (:mod:`~.prediction`) gives the
positions 1..K samples ahead, which with the newest samples make a C2 cubic (scipy's
``CubicSpline``, not-a-knot) of the time since the newest sample; the reference at time t is
that curve at t + ``loop_lag_s`` minus the newest sample's time, blended from the previous
arrival's curve over ``blend_s`` by the quintic smoothstep (so the reference stays C2 for the
feed-forward). Nothing the reference does at time t depends on a sample that arrives after t.
"""

import math
from dataclasses import dataclass

import numpy as np

from ..base.errors import InvalidConfigError
from .prediction import OnlinePredictor, PredictorSettings, check_predictor

#: Past samples the follower's curve passes through before the newest.
PAST_NODES = 2
#: The blend from one arrival's curve to the next's, s (at most a sample step).
BLEND_S = 0.1
#: The rate a motion without samples of its own (a library motion) is streamed at, Hz: an
#: optical tracker's (25-30 Hz).
DEFAULT_STREAM_RATE_HZ = 25.0
#: The loop's lag behind its reference on ``reproduce``'s scenario, s: the fidelity report's
#: ``lag_all_s`` of ``reproduce breathing`` (measured by tools/stream_prediction_table.py).
LOOP_LAG_S = 0.001


def check_latency(latency_s) -> float:
    """``latency_s`` as a float when it is finite and > 0 (at most 10 s).

    Raises:
        InvalidConfigError: a latency <= 0, NaN, infinite or above 10 s.
    """
    try:
        value = float(latency_s)
    except (TypeError, ValueError):
        raise InvalidConfigError(f"the latency must be a number of s, got {latency_s!r}") from None
    if not (math.isfinite(value) and 0 < value <= 10.0):
        raise InvalidConfigError(f"the latency must be in (0, 10] s, got {latency_s!r}")
    return value


@dataclass(frozen=True)
class Stream:
    """The samples of a motion as they arrive.

    Attributes:
        t: (N,) the times the samples were taken, s, evenly spaced (step ``dt``).
        poses: (N, 6) the samples [phi, theta, psi, X, Y, Z], rad and m.
        latency_s: how long after it was taken a sample arrives, s.
        name: the motion's name.
    """

    t: np.ndarray
    poses: np.ndarray
    latency_s: float
    name: str = "stream"

    @property
    def dt(self) -> float:
        """The sample step, s."""
        return float(self.t[1] - self.t[0])

    @property
    def arrival(self) -> np.ndarray:
        """(N,) when each sample arrives, s."""
        return self.t + self.latency_s


def stream_of(reference, latency_s: float, rate_hz: float, duration_s: float) -> Stream:
    """The samples of ``reference`` (any :class:`~.motion.Reference`: the true motion) every
    1 / ``rate_hz`` s from 0 to ``duration_s``, arriving ``latency_s`` late.

    Raises:
        InvalidConfigError: a bad latency (:func:`check_latency`), a rate not in (0, 1000] Hz,
            fewer than 3 samples.
    """
    latency_s = check_latency(latency_s)
    if not (np.isfinite(rate_hz) and 0 < rate_hz <= 1000):
        raise InvalidConfigError(f"the stream's rate must be in (0, 1000] Hz, got {rate_hz!r}")
    t = np.arange(0.0, duration_s + 1e-9, 1.0 / rate_hz)
    if t.size < 3:
        raise InvalidConfigError(
            f"a stream of {duration_s:g} s at {rate_hz:g} Hz has {t.size} samples: at least 3"
        )
    poses = np.asarray(reference.evaluate(t)[0], dtype=float).reshape(-1, 6)
    return Stream(t, poses, latency_s, getattr(reference, "name", "stream"))


def follower_steps(latency_s: float, dt: float, loop_lag_s: float, blend_s: float) -> int:
    """K, the samples ahead a follower predicts: past the newest sample's age at the next
    arrival, the blend and the loop's lag."""
    return int(math.ceil((latency_s + loop_lag_s + dt + blend_s) / dt - 1e-9)) + 1


class FollowedStream:
    """The reference that follows a :class:`Stream` (:func:`follow`): ``evaluate(t)`` -> pose,
    rate, acceleration (a :class:`~.motion.Reference`), with the follower's record.

    Attributes:
        name: "<motion> followed". stream: the stream. predictor: its name. settings: its
            :class:`~.prediction.PredictorSettings`. loop_lag_s, blend_s: as :func:`follow`.
        end_time: the stream's last sample's time, s (the true motion's length).
        tau: (n,) the curve's nodes, s after the newest sample (from -PAST_NODES dt to K dt).
        nodes: (N, n, 6) each arrival's curve through them, rad and m.
        using: (N, 6) bool, whether the predictor's positions were used on each axis.
        sigma: (N, K, 6) its uncertainty at each arrival: the RMS residual of what was used,
            per step ahead (NaN before any).
        clipped: predicted positions clipped to the motion's range so far (count,
            :class:`~.prediction.OnlinePredictor`).
    """

    def __init__(self, stream: Stream, predictor, settings, loop_lag_s, blend_s, nodes, using,
                 sigma, clipped):  # fmt: skip
        from scipy.interpolate import CubicSpline

        self.stream, self.predictor, self.settings = stream, predictor, settings
        self.loop_lag_s, self.blend_s = float(loop_lag_s), float(blend_s)
        self.name = f"{stream.name} followed"
        self.end_time = float(stream.t[-1])
        self.nodes, self.using, self.sigma, self.clipped = nodes, using, sigma, int(clipped)
        n = nodes.shape[1]
        self.tau = (np.arange(n) - PAST_NODES) * stream.dt
        self._c = CubicSpline(self.tau, np.moveaxis(nodes, 1, 0), axis=0).c  # (4, n - 1, N, 6)

    def curve(self, i, s, order: int = 0) -> np.ndarray:
        """(M, 6) the ``order``-th derivative of arrival ``i``'s curve (i (M,) ints) at ``s``
        (M,) s after its newest sample; held at its ends beyond its nodes."""
        s = np.clip(s, self.tau[0], self.tau[-1])
        j = np.clip(np.searchsorted(self.tau, s, side="right") - 1, 0, self.tau.size - 2)
        d = (s - self.tau[j])[:, None]
        c = self._c[:, j, i]  # (4, M, 6)
        if order == 0:
            return ((c[0] * d + c[1]) * d + c[2]) * d + c[3]
        if order == 1:
            return (3 * c[0] * d + 2 * c[1]) * d + c[2]
        return 6 * c[0] * d + 2 * c[1]

    def evaluate(self, t):
        """Pose, rate and acceleration at times ``t`` (s, any shape): arrays of shape
        ``np.shape(t) + (6,)``, rad and m, per s, per s^2; the first sample, at rest, before
        it arrives."""
        from .smoothstep import smoothstep

        t = np.asarray(t, dtype=float)
        shape, flat = t.shape, t.reshape(-1)
        s_ = self.stream
        i = np.searchsorted(s_.arrival, flat, side="right") - 1
        before = i < 0
        i = np.clip(i, 0, None)
        prev = np.clip(i - 1, 0, None)
        ahead = flat + self.loop_lag_s
        new = [self.curve(i, ahead - s_.t[i], k) for k in range(3)]
        old = [self.curve(prev, ahead - s_.t[prev], k) for k in range(3)]
        blend = min(self.blend_s, s_.dt)
        w, dw, ddw = smoothstep((flat - s_.arrival[i]) / blend)
        w = np.where(i == 0, 1.0, w)[:, None]
        dw = np.where(i == 0, 0.0, dw / blend)[:, None]
        ddw = np.where(i == 0, 0.0, ddw / blend**2)[:, None]
        gap = [n - o for n, o in zip(new, old)]
        x = old[0] + w * gap[0]
        v = old[1] + w * gap[1] + dw * gap[0]
        a = old[2] + w * gap[2] + 2 * dw * gap[1] + ddw * gap[0]
        x[before], v[before], a[before] = s_.poses[0], 0.0, 0.0
        return tuple(q.reshape(shape + (6,)) for q in (x, v, a))

    def at_horizon(self, horizon_s: float) -> np.ndarray:
        """(N, 6) what each arrival's curve gives ``horizon_s`` after its newest sample: the
        predictor's own prediction at that horizon (rad and m)."""
        i = np.arange(self.stream.t.size)
        return self.curve(i, np.full(i.size, float(horizon_s)))


def follow(
    stream: Stream,
    predictor: str = "linear",
    settings: PredictorSettings | None = None,
    loop_lag_s: float = LOOP_LAG_S,
    blend_s: float = BLEND_S,
) -> FollowedStream:
    """The reference that follows ``stream`` with ``predictor`` (module docstring).

    Args:
        stream: the samples and their latency. predictor: one of
            :data:`~.prediction.PREDICTORS`. settings: its settings (default the shipped).
        loop_lag_s: how far the robot lags its reference, s (added to the horizon).
        blend_s: the blend between arrivals' curves, s (at most the sample step is used).
    Returns:
        :class:`FollowedStream`.
    Raises:
        InvalidConfigError: an unknown predictor; a bad latency; a stream shorter than the
            predictor needs (its history, the steps it predicts and the record that decides
            whether its predictions are used), naming both lengths.
    """
    check_predictor(predictor)
    check_latency(stream.latency_s)
    settings = settings or PredictorSettings()
    if not (np.isfinite(loop_lag_s) and 0 <= loop_lag_s < 1 and np.isfinite(blend_s)):
        raise InvalidConfigError(f"loop_lag_s must be in [0, 1) s, got {loop_lag_s!r}")
    if not blend_s > 0:
        raise InvalidConfigError(f"blend_s must be > 0 s, got {blend_s!r}")
    dt = stream.dt
    steps = follower_steps(stream.latency_s, dt, loop_lag_s, min(blend_s, dt))
    needed = settings.samples_needed(dt, steps) if predictor != "none" else 3
    if stream.t.size < needed:
        raise InvalidConfigError(
            f"the stream of {stream.name} has {stream.t.size} samples "
            f"({stream.t[-1]:.3g} s): the {predictor} predictor needs {needed} "
            f"({(needed - 1) * dt:.3g} s at {1 / dt:.3g} Hz) before it can predict"
        )
    nodes, using, sigma, clipped = _arrivals(stream, predictor, settings, steps)
    return FollowedStream(
        stream, predictor, settings, loop_lag_s, blend_s, nodes, using, sigma, clipped
    )


def _arrivals(stream: Stream, predictor: str, settings, steps: int):
    """The follower's record of every arrival, in order: (nodes (N, n, 6), using (N, 6),
    sigma (N, K, 6), clipped count)."""
    N = stream.t.size
    model = OnlinePredictor(predictor, stream.dt, steps, 6, settings)
    n = PAST_NODES + 1 + steps
    nodes, using = np.empty((N, n, 6)), np.zeros((N, 6), dtype=bool)
    sigma = np.empty((N, steps, 6))
    past = np.repeat(stream.poses[:1], PAST_NODES, axis=0)
    for i, y in enumerate(stream.poses):
        ahead = model.update(y)
        # An axis not predicted holds the newest sample exactly, its past too (no overshoot).
        held = np.where(model.using[None, :], past, y[None, :])
        nodes[i] = np.concatenate([held, y[None, :], ahead])
        using[i], sigma[i] = model.using, model.sigma
        past = np.concatenate([past[1:], y[None, :]])
    return nodes, using, sigma, model.clipped


__all__ = [
    "Stream",
    "stream_of",
    "check_latency",
    "follow",
    "follower_steps",
    "FollowedStream",
    "DEFAULT_STREAM_RATE_HZ",
    "LOOP_LAG_S",
    "BLEND_S",
]
