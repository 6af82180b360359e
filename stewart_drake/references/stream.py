"""A motion that arrives late, and the reference that follows it: each sample reaches the
controller a latency after it happened, and the follower commands where the motion is expected
to be by the time the robot gets there.

A :class:`Stream` is the samples of a motion (a recorded trace, a library motion, or a live
source) at their own rate, each known from its arrival, ``latency_s`` after it happened.
:func:`follow` turns it into a reference (:class:`FollowedStream`, a
:class:`~.motion.Reference`): at each arrival the predictor (:mod:`~.prediction`) gives the
positions 1..K samples ahead, which with the newest samples make a C2 curve of the time since
the newest sample, followed where the predictor's record chooses it, and the samples alone make
the curve followed without prediction (:class:`FollowedStream`). Nothing the reference does
at time t depends on a sample that arrives after t.
"""

import math
from dataclasses import dataclass

import numpy as np

from ..base.checks import check_memory
from ..base.errors import InvalidConfigError
from .prediction import OnlinePredictor, PredictorSettings, check_predictor

#: Past samples the follower's curves pass through before the newest.
PAST_NODES = 3
#: How long an axis takes to move between the held and the predicted curve, s.
SWITCH_S = 1.0
#: The blend from one arrival's curve to the next's, s (at most a sample step).
BLEND_S = 0.1
#: The held curve is read at most this many sample steps past its newest sample, then held: on
#: time, the next sample takes over one step and a blend after it; a stream that stalls (a live
#: source gone silent until its timeout) would otherwise ask for the cubic's extrapolation,
#: 22 mm after 0.5 s on breathing with 10 um of sample noise.
HELD_STEPS = 2.0
#: The rate a motion without samples of its own (a library motion) is streamed at, Hz: an
#: optical tracker's (25-30 Hz).
DEFAULT_STREAM_RATE_HZ = 25.0
#: The loop's lag behind its reference on ``reproduce``'s scenario, s: the fidelity report's
#: ``lag_all_s`` of ``reproduce breathing`` (0.048 ms: the inverse-dynamics feed-forward leaves
#: the loop almost no lag; docs/organ_motion.md, "Following a motion live").
LOOP_LAG_S = 5e-5


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
        step_s: the sample step, s, when ``t`` does not give it (a live stream's arrivals,
            spaced as they came: :class:`~.live_stream.LiveFollower`); None: ``t``'s.
    """

    t: np.ndarray
    poses: np.ndarray
    latency_s: float
    name: str = "stream"
    step_s: float | None = None

    @property
    def dt(self) -> float:
        """The sample step, s."""
        return float(self.step_s) if self.step_s is not None else float(self.t[1] - self.t[0])

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

    Two curves per arrival i, both C2 cubics (scipy's ``CubicSpline``, not-a-knot) of the time
    since the newest sample, tau:

    - the predicted curve, through the :data:`PAST_NODES` samples before the newest, the newest
      and the K predicted positions, read at tau = t + ``loop_lag_s`` - t_i;
    - the held curve, through those samples only, read one sample step and the latency behind
      (tau - latency - dt): without prediction the samples are joined smoothly, the newest
      reached one step after it arrived (a smooth curve cannot pass the newest sample before
      the next is known; holding it instead would ask the robot for a step at every sample),
      held :data:`HELD_STEPS` steps past the newest sample when the next does not come.

    Each is blended from arrival i - 1's to arrival i's over ``blend_s`` by the quintic
    smoothstep, and each axis weighs the two by u in [0, 1], which moves between them along the
    smoothstep over :data:`SWITCH_S` when the predictor's record switches that axis (and
    finishes a move before it starts another). The reference is C2 throughout.

    Attributes:
        name: "<motion> followed". stream: the stream. predictor: its name. settings: its
            :class:`~.prediction.PredictorSettings`. loop_lag_s, blend_s: as :func:`follow`.
        end_time: the stream's last sample's time, s (the true motion's length).
        tau: (n,) the predicted curve's nodes, s after the newest sample.
        nodes: (N, n, 6) each arrival's predicted curve through them, rad and m.
        using: (N, 6) bool, whether the predictor's record chose its positions on each axis.
        sigma: (N, K, 6) its uncertainty at each arrival: the RMS residual of what was used,
            per step ahead (NaN before any).
        clipped: predicted positions clipped to the motion's recent range (count,
            :class:`~.prediction.OnlinePredictor`).
        rejected: samples' axes taken as outliers, the prediction for them followed instead
            (count, :class:`~.prediction.OnlinePredictor`).
        fallbacks: the times the record dropped the prediction on an axis for no prediction
            (count, :class:`~.prediction.OnlinePredictor`).
        switches: (S, 3) the moves of u: (start time s, axis, direction +1 / -1).
    """

    def __init__(self, stream: Stream, predictor, settings, loop_lag_s, blend_s, nodes, using,
                 sigma, clipped):  # fmt: skip
        from scipy.interpolate import CubicSpline

        self.stream, self.predictor, self.settings = stream, predictor, settings
        self.loop_lag_s, self.blend_s = float(loop_lag_s), float(blend_s)
        self.name = f"{stream.name} followed"
        self.end_time = float(stream.t[-1])
        self.nodes, self.using, self.sigma, self.clipped = nodes, using, sigma, int(clipped)
        self.fallbacks = int(np.count_nonzero(using[:-1] & ~using[1:])) if len(using) else 0
        self.rejected = 0
        n, dt = nodes.shape[1], stream.dt
        self.tau = (np.arange(n) - PAST_NODES) * dt
        self._c = CubicSpline(self.tau, np.moveaxis(nodes, 1, 0), axis=0).c  # (4, n - 1, N, 6)
        held = self.tau[: PAST_NODES + 1]
        self._h = CubicSpline(held, np.moveaxis(nodes[:, : PAST_NODES + 1], 1, 0), axis=0).c
        self._delay = stream.latency_s + dt  # the held curve's lag behind the newest sample
        self.switches = _switches(stream.arrival, using, SWITCH_S)

    def _curve(self, c, tau, i, s, order: int) -> np.ndarray:
        """(M, 6) the ``order``-th derivative of the cubics ``c`` (4, n - 1, N, 6) on nodes
        ``tau`` of arrivals ``i`` (M,) at ``s`` (M,) s after their newest sample; the end
        pieces extend beyond the nodes."""
        j = np.clip(np.searchsorted(tau, s, side="right") - 1, 0, tau.size - 2)
        d = (np.clip(s, tau[0], None) - tau[j])[:, None]
        k = c[:, j, i]  # (4, M, 6)
        if order == 0:
            return ((k[0] * d + k[1]) * d + k[2]) * d + k[3]
        if order == 1:
            return (3 * k[0] * d + 2 * k[1]) * d + k[2]
        return 6 * k[0] * d + 2 * k[1]

    def curve(self, i, s, order: int = 0) -> np.ndarray:
        """(M, 6) the ``order``-th derivative of arrival ``i``'s predicted curve (i (M,) ints)
        at ``s`` (M,) s after its newest sample; held at its last node beyond it."""
        return self._curve(self._c, self.tau, i, np.minimum(s, self.tau[-1]), order)

    def _blended(self, c, tau, flat, i, shift: float) -> list:
        """[pose, rate, acceleration] (M, 6) of the curves ``c`` read ``shift`` s behind,
        blended from arrival i - 1's to arrival i's."""
        from .smoothstep import smoothstep

        s_ = self.stream
        prev = np.clip(i - 1, 0, None)
        ahead = flat + self.loop_lag_s - shift
        # Held beyond the predicted curve's last node, and the held curve beyond HELD_STEPS
        # sample steps past its newest sample (where a stream that stalls leaves it): no rate
        # beyond either, never the cubic's extrapolation.
        top = tau[-1] if c is self._c else HELD_STEPS * s_.dt
        new = [self._curve(c, tau, i, np.minimum(ahead - s_.t[i], top), k) for k in range(3)]
        old = [self._curve(c, tau, prev, np.minimum(ahead - s_.t[prev], top), k) for k in range(3)]
        for k in (1, 2):
            new[k][ahead - s_.t[i] > top] = 0.0
            old[k][ahead - s_.t[prev] > top] = 0.0
        blend = min(self.blend_s, s_.dt)
        w, dw, ddw = smoothstep((flat - s_.arrival[i]) / blend)
        w = np.where(i == 0, 1.0, w)[:, None]
        dw = np.where(i == 0, 0.0, dw / blend)[:, None]
        ddw = np.where(i == 0, 0.0, ddw / blend**2)[:, None]
        gap = [n - o for n, o in zip(new, old)]
        return [
            old[0] + w * gap[0],
            old[1] + w * gap[1] + dw * gap[0],
            old[2] + w * gap[2] + 2 * dw * gap[1] + ddw * gap[0],
        ]

    def weights(self, t) -> tuple:
        """(u, u', u'') (M, 6) each: the share of the predicted curve per axis at times ``t``
        (M,) s, and its derivatives."""
        from .smoothstep import smoothstep

        t = np.asarray(t, dtype=float)
        u, du, ddu = (np.zeros((t.size, 6)) for _ in range(3))
        for start, axis, direction in self.switches:
            S, dS, ddS = smoothstep((t - start) / SWITCH_S)
            a = int(axis)
            u[:, a] += direction * S
            du[:, a] += direction * dS / SWITCH_S
            ddu[:, a] += direction * ddS / SWITCH_S**2
        return u, du, ddu

    def evaluate(self, t):
        """Pose, rate and acceleration at times ``t`` (s, any shape): arrays of shape
        ``np.shape(t) + (6,)``, rad and m, per s, per s^2; the first sample, at rest, until
        the held curve leaves it."""
        t = np.asarray(t, dtype=float)
        shape, flat = t.shape, t.reshape(-1)
        s_ = self.stream
        i = np.searchsorted(s_.arrival, flat, side="right") - 1
        before = i < 0
        i = np.clip(i, 0, None)
        p = self._blended(self._c, self.tau, flat, i, 0.0)
        h = self._blended(self._h, self.tau[: PAST_NODES + 1], flat, i, self._delay)
        u, du, ddu = self.weights(flat)
        gap = [a - b for a, b in zip(p, h)]
        x = h[0] + u * gap[0]
        v = h[1] + u * gap[1] + du * gap[0]
        a = h[2] + u * gap[2] + 2 * du * gap[1] + ddu * gap[0]
        x[before], v[before], a[before] = s_.poses[0], 0.0, 0.0
        return tuple(q.reshape(shape + (6,)) for q in (x, v, a))

    def at_horizon(self, horizon_s: float, used: bool = False) -> np.ndarray:
        """(N, 6) what each arrival's predicted curve gives ``horizon_s`` after its newest
        sample: the predictor's own prediction at that horizon (rad and m); with ``used``, the
        newest sample itself on the axes where the record did not choose the prediction (what
        the predictor put forward at that arrival)."""
        i = np.arange(self.stream.t.size)
        predicted = self.curve(i, np.full(i.size, float(horizon_s)))
        return np.where(self.using, predicted, self.stream.poses) if used else predicted


def _switches(arrival: np.ndarray, using: np.ndarray, switch_s: float) -> np.ndarray:
    """(S, 3) the moves of each axis's weight u between the held and the predicted curve:
    (start s, axis, +1 towards the predicted, -1 back), started at the arrival where the
    record's choice differs from where u is going, once the move before has finished."""
    moves = []
    for axis in range(using.shape[1]):
        state, free_at = False, -np.inf
        for a, use in zip(arrival, using[:, axis]):
            if bool(use) != state and a >= free_at:
                state = bool(use)
                moves.append((a, axis, 1.0 if state else -1.0))
                free_at = a + switch_s
    return np.array(moves, dtype=float).reshape(-1, 3)


def follow(
    stream: Stream,
    predictor: str = "linear",
    settings: PredictorSettings | None = None,
    loop_lag_s: float = LOOP_LAG_S,
    blend_s: float = BLEND_S,
    progress=None,
) -> FollowedStream:
    """The reference that follows ``stream`` with ``predictor`` (module docstring).

    Args:
        stream: the samples and their latency. predictor: one of
            :data:`~.prediction.PREDICTORS`. settings: its settings (default the shipped).
        loop_lag_s: how far the robot lags its reference, s (added to the horizon).
        blend_s: the blend between arrivals' curves, s (at most the sample step is used).
        progress: called with (arrivals followed, arrivals) at most every
            :data:`PROGRESS_S` of wall-clock time, or None.
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
    check_memory(
        f"following {stream.name}'s {stream.t.size} samples at {1 / dt:.4g} Hz, {steps} steps "
        "ahead",
        follow_memory_bytes(stream.t.size, steps),
        "lower the stream's rate (--stream-rate) or shorten the run (--duration)",
    )
    nodes, using, sigma, clipped, rejected = _arrivals(stream, predictor, settings, steps, progress)
    followed = FollowedStream(
        stream, predictor, settings, loop_lag_s, blend_s, nodes, using, sigma, clipped
    )
    followed.rejected = rejected
    return followed


def follow_memory_bytes(samples: int, steps: int) -> float:
    """Estimated peak memory of :func:`follow` on ``samples`` arrivals predicting ``steps``
    ahead, bytes: each arrival's nodes, uncertainty and choice (float64, 6 axes), and the two
    cubic splines' coefficients (4 per piece) with the solver's temporaries (taken as twice
    the coefficients: an upper bound with slack)."""
    n = PAST_NODES + 1 + steps
    per_arrival = 6 * 8 * (n + steps + 1 + 3 * 4 * (n - 1 + PAST_NODES))
    return float(samples) * per_arrival


def _arrivals(stream: Stream, predictor: str, settings, steps: int, progress=None):
    """The follower's record of every arrival, in order: (nodes (N, n, 6), using (N, 6),
    sigma (N, K, 6), clipped count, rejected count); ``progress(i, N)`` every
    :data:`PROGRESS_S` at most."""
    import time

    N = stream.t.size
    said = time.monotonic()
    model = OnlinePredictor(predictor, stream.dt, steps, 6, settings)
    n = PAST_NODES + 1 + steps
    nodes, using = np.empty((N, n, 6)), np.zeros((N, 6), dtype=bool)
    sigma = np.empty((N, steps, 6))
    past = np.repeat(stream.poses[:1], PAST_NODES, axis=0)
    for i, raw in enumerate(stream.poses):
        ahead = model.raw_update(raw)
        y = model.sample  # the outliers' axes replaced
        nodes[i] = np.concatenate([past, y[None, :], ahead])
        using[i], sigma[i] = model.using, model.sigma
        past = np.concatenate([past[1:], y[None, :]])
        if progress is not None and i % 256 == 0 and time.monotonic() - said >= PROGRESS_S:
            said = time.monotonic()
            progress(i, N)
    return nodes, using, sigma, model.clipped, model.rejected


#: The longest the follower runs without telling its ``progress``, s of wall-clock time.
PROGRESS_S = 2.0


__all__ = [
    "Stream",
    "stream_of",
    "check_latency",
    "follow",
    "follower_steps",
    "follow_memory_bytes",
    "FollowedStream",
    "PAST_NODES",
    "SWITCH_S",
    "DEFAULT_STREAM_RATE_HZ",
    "LOOP_LAG_S",
    "BLEND_S",
    "HELD_STEPS",
    "PROGRESS_S",
]
