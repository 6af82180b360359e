"""A recorded trace read without what the recording added to the motion: its measurement noise
(:func:`smoothed_spline`, from the noise :func:`noise_estimate` finds in the samples) and the
seams of a looped recording (:func:`loop_seams`, :func:`blend_seams`).

Both are applied to the samples as read (:class:`~.trace_files.TraceTable`), before
:mod:`~.traces` makes the reference, and both are stated in the run's report with how far the
reference departs from the samples.
"""

import math
from dataclasses import dataclass

import numpy as np

from .smoothstep import smoothstep

#: Orders of the differences :func:`noise_estimate` reads.
NOISE_DIFFERENCE_ORDERS = range(2, 9)


def noise_estimate(yk: np.ndarray) -> float:
    """The standard deviation of the white measurement noise in evenly sampled ``yk``, m or rad.

    White noise of standard deviation s gives k-th differences of variance C(2k, k) s^2; the
    motion's own k-th differences shrink as (omega h)^k (a 10 mm breath at 0.25 Hz sampled at
    5 Hz: 0.1 mm at k = 4, 1e-3 mm at k = 8, against 0.84 and 11 mm from 0.1 mm of noise), so
    each order's estimate is the noise plus some motion, and the smallest over k = 2..8 is
    taken. Each is a robust scale (1.4826 x the median absolute deviation), so a step or a seam
    does not count as noise.
    """
    yk = np.asarray(yk, dtype=float)
    best = math.inf
    for k in NOISE_DIFFERENCE_ORDERS:
        dk = np.diff(yk, k)
        if dk.size < 4:
            break
        scale = 1.4826 * np.median(np.abs(dk - np.median(dk))) / math.sqrt(math.comb(2 * k, k))
        best = min(best, float(scale))
    return 0.0 if best == math.inf else best


#: Samples per piece of :func:`smoothed_spline` and the overlap of two pieces: FITPACK's cost
#: grows faster than the samples (6,500 at once: 3 s an axis; in pieces of 200: 0.15 s).
PIECE_SAMPLES, PIECE_OVERLAP = 200, 50


#: Points per sample interval at which a piece's curve is held within its samples' band.
BAND_POINTS = 8


def _within_band(fit, tk: np.ndarray, yk: np.ndarray) -> bool:
    """Whether ``fit`` stays, between and at the samples, within the samples' range widened by
    their own span either way (the bound a bridge across a gap keeps too)."""
    lo, hi, span = float(yk.min()), float(yk.max()), float(np.ptp(yk))
    grid = np.linspace(tk[0], tk[-1], BAND_POINTS * len(tk))
    values = fit(grid)
    return bool(
        np.all(np.isfinite(values))
        and values.min() >= lo - span - 1e-12
        and values.max() <= hi + span + 1e-12
    )


def _piece_fit(tk: np.ndarray, yk: np.ndarray, s: float):
    """One piece of :func:`smoothed_spline`: FITPACK's quintic at the discrepancy ``s``; where
    FITPACK fails (on a clean recording, s near 0, it may report "a theoretically impossible
    result" and return a curve 1e12 times the motion, for one piece of IntERAct-like 5 Hz
    samples after a gap), or its curve leaves the samples' band (:func:`_within_band`), the
    weight is doubled, up to four times; then a cubic spline through the samples, which
    keeps their noise but never leaves them far."""
    import warnings

    from scipy.interpolate import CubicSpline, UnivariateSpline

    for trial in range(5):
        with warnings.catch_warnings(record=True) as said:
            warnings.simplefilter("always")
            fit = UnivariateSpline(tk, yk, k=5, s=s * 2**trial)
        # FITPACK warns when the noise is ~0 and it runs out of knots (the departure says it);
        # "theoretically impossible" is its failure.
        failed = any("impossible" in str(w.message) for w in said)
        if not failed and _within_band(fit, tk, yk):
            return fit
        if s <= 0.0:
            break
    return CubicSpline(tk, yk)


def smoothed_spline(tk: np.ndarray, yk: np.ndarray):
    """(curve, departure): the samples ``yk`` at ``tk`` joined without their measurement
    noise, as a callable of time, and the RMS by which the curve departs from them.

    A quintic smoothing spline by the discrepancy principle: FITPACK's
    (``scipy.interpolate.UnivariateSpline``, k = 5) fewest knots whose least-squares spline
    departs from the n samples by the noise they hold (sum of squared departures n s^2, s from
    :func:`noise_estimate`), so a clean recording is followed to within its rounding and a noisy
    one loses its noise and keeps its motion. Quintic, so that the jerk the feed-forward reads
    is smooth too: on IntERAct's lung 1 with 0.1 mm of white noise added the reference's RMS
    acceleration and jerk are within 5 % of the clean trace's (a cubic: jerk 2.3x on one axis).
    The fit is a projection, not a penalty: it does not shrink the breath's harmonics as a
    penalised (Reinsch) spline does: at the weight where it departs by the noise, that one is
    6 % low on a 4 s breath's second harmonic sampled at 5 Hz. Its weight chosen by generalized
    cross-validation instead was not reliable on a clean 10 Hz export.

    A long trace is fitted in pieces of :data:`PIECE_SAMPLES` that overlap by
    :data:`PIECE_OVERLAP`, cross-faded over each overlap by the quintic smoothstep (a partition
    of unity, so the curve stays C2 and within the noise of both pieces).
    """
    tk, yk = np.asarray(tk, dtype=float), np.asarray(yk, dtype=float)
    n, s2 = len(yk), noise_estimate(yk) ** 2
    step = PIECE_SAMPLES - PIECE_OVERLAP
    starts = list(range(0, max(n - PIECE_OVERLAP, 1), step))
    pieces = [(a, n if a == starts[-1] else a + PIECE_SAMPLES) for a in starts]
    fits = [_piece_fit(tk[a:b], yk[a:b], (b - a) * s2) for a, b in pieces]
    # Piece i rises over (t at its start, t at the end of piece i - 1).
    rise = [(tk[a], tk[pieces[i][1] - 1]) for i, (a, _) in enumerate(pieces[1:])]
    support = [
        (-math.inf if i == 0 else tk[a], math.inf if i + 1 == len(pieces) else tk[b - 1])
        for i, (a, b) in enumerate(pieces)
    ]

    def curve(t):
        t = np.atleast_1d(np.asarray(t, dtype=float))
        out = np.zeros_like(t)
        for i, fit in enumerate(fits):
            live = (t >= support[i][0]) & (t <= support[i][1])
            tl = t[live]
            w = np.ones_like(tl)  # piece i's share: the shares add up to one
            if i > 0:
                lo, hi = rise[i - 1]
                w *= smoothstep((tl - lo) / (hi - lo))[0]
            if i + 1 < len(fits):
                lo, hi = rise[i]
                w *= 1.0 - smoothstep((tl - lo) / (hi - lo))[0]
            out[live] += w * fit(tl)
        return out

    return curve, float(np.sqrt(np.mean((curve(tk) - yk) ** 2)))


#: Fewest samples a loop repeats (shorter repeats are a still patient, not a loop).
MIN_LOOP_SAMPLES = 10
#: Shortest loop, s: a recording repeated to make a trace holds several breaths (IntERAct's:
#: 60 s to 10 min); a shorter exact repeat is a synthetic periodic motion, not a loop.
MIN_LOOP_S = 10.0
#: Share of the samples after the first loop that must repeat it exactly.
MIN_LOOP_SHARE = 0.9
#: A join of a loop is a seam when its step beyond the motion's own (:func:`_seam_steps`) is this
#: many robust standard deviations of that quantity over the whole recording, on some axis (a
#: recording that repeats without a step, as a synthetic periodic motion does, has none).
SEAM_JUMP = 10.0
#: Default time over which a seam is blended, s: the quintic blend's peak acceleration is
#: 5.8 x jump / time^2, 14 mm/s^2 for IntERAct liver 1's 9.5 mm seams (a 12 mm breath of 4 s
#: peaks at 15 mm/s^2).
SEAM_BLEND_S = 2.0


@dataclass(frozen=True)
class LoopSeams:
    """The seams of a looped recording (:func:`loop_seams`).

    Attributes:
        period: the loop's length, samples (the median between seams).
        seams: indices s of the samples after which the recording starts again with a step
            (the seam lies between samples s and s + 1); empty when it joins without one.
    """

    period: int
    seams: tuple


def loop_seams(data: np.ndarray) -> LoopSeams | None:
    """The seams of ``data`` if it is a loop, else None.

    A looped recording (a short recording repeated to make a long trace, as IntERAct's liver 1:
    62 s, 21 times) starts again from its first row, exactly, on every axis at once, which no
    patient does; where it starts again the motion jumps (9.5 mm in 0.2 s on liver 1). A
    restart is a row from which :data:`MIN_LOOP_SAMPLES` rows of the file's start come again,
    equal on every column, from one of its first :data:`MIN_LOOP_SAMPLES` rows (IntERAct's
    copies start again from its row 0 or 1), at least :data:`MIN_LOOP_SAMPLES` after the last
    restart: the loop is found at the file's own seam, where the recording's end meets its
    start, never inside it (a recording of one axis, rounded, holds many rows equal to an
    earlier one by chance: those are no seams). Each copy, from a restart to the next (or the
    file's end), must repeat the recording row for row over at least :data:`MIN_LOOP_SHARE` of
    its rows (the copies need not be of one length: liver 1's are 310 and 311 samples). A seam
    is a restart where the motion steps (:data:`SEAM_JUMP`).

    Args:
        data: (n, m) the axis columns as read (NaN: a missing cell).
    Returns:
        :class:`LoopSeams`, or None (not a loop).
    """
    data = np.ascontiguousarray(np.asarray(data, dtype=float))
    n, k = len(data), MIN_LOOP_SAMPLES
    if n < 2 * k:
        return None
    head: dict = {}
    for j in range(k):
        head.setdefault(data[j].tobytes(), j)
    restarts: list = []  # (row, the recording's row it starts again from)
    for i in range(k, n - k + 1):
        source = head.get(data[i].tobytes())
        if source is None or (restarts and i - restarts[-1][0] < k):
            continue
        if np.array_equal(data[i : i + k], data[source : source + k], equal_nan=True):
            restarts.append((i, source))
    if not restarts:
        return None
    length = restarts[0][0]  # the recording: the rows before it first starts again
    for (a, j), b in zip(restarts, [r for r, _ in restarts[1:]] + [n]):
        m = min(b - a, length - j)
        equal = np.all((data[a : a + m] == data[j : j + m]) | np.isnan(data[j : j + m]), axis=1)
        if np.count_nonzero(equal) < MIN_LOOP_SHARE * m:
            return None
    rows = [r for r, _ in restarts]
    steps = np.diff(data, axis=0)
    jumps = steps[1:-1] - 0.5 * (steps[:-2] + steps[2:])  # row s - 1: _seam_steps' jump at s
    scale = 1.4826 * np.nanmedian(np.abs(jumps - np.nanmedian(jumps, axis=0)), axis=0)
    seams = tuple(
        s
        for s in (r - 1 for r in rows)
        if 1 <= s <= len(jumps) and np.any(np.abs(np.nan_to_num(jumps[s - 1])) > SEAM_JUMP * scale)
    )
    return LoopSeams(int(np.median(np.diff([0, *rows]))), seams)


def _seam_steps(data: np.ndarray, s: int) -> tuple[np.ndarray, np.ndarray]:
    """((m,) the jump in position at the middle of samples s and s + 1, each side extrapolated
    by its own step; (m,) the jump in the step, per sample): zeros where a neighbour is missing
    or off the ends."""
    if s < 1 or s + 2 >= len(data):
        return np.zeros(data.shape[1]), np.zeros(data.shape[1])
    y = data[s - 1 : s + 3]
    before, after = y[1] - y[0], y[3] - y[2]
    return np.nan_to_num((y[2] - y[1]) - 0.5 * (before + after)), np.nan_to_num(after - before)


def blend_seams(t: np.ndarray, data: np.ndarray, seams: LoopSeams, blend_s: float):
    """(data with its seams blended, the largest jump taken out per column): at each seam the
    jump in position and in rate beyond the motion's own is spread over ``blend_s`` by the
    quintic smoothstep w, half before the seam and half after, so the trace is unchanged
    outside the blends and has no step in position or rate.

    With the jumps dy and dv (position and rate, each side extrapolated to the seam's time
    t_s by its own rate), the correction is (dy + dv (t - t_s)) (w(t) - H(t - t_s)) (H: the
    unit step): zero outside the blend, and its step and its rate's step at t_s cancel the
    seam's.

    Args:
        t: (n,) the sample times, s. data: (n, m) the axis columns (NaN: missing).
        seams: from :func:`loop_seams`. blend_s: the blend's length, s (> 0).
    Returns:
        ((n, m) float array, (m,) the largest |jump| removed per column, in the columns' units).
    """
    out = np.array(data, dtype=float)
    largest = np.zeros(out.shape[1])
    for s in seams.seams:
        jump, step_jump = _seam_steps(data, s)
        h = t[s + 1] - t[s]
        t_seam = 0.5 * (t[s] + t[s + 1])
        w = smoothstep((t - t_seam) / blend_s + 0.5)[0] - (t > t_seam)
        out += np.outer(w, jump) + np.outer(w * (t - t_seam), step_jump / h)
        largest = np.maximum(largest, np.abs(jump))
    return out, largest
