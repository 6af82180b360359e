"""The figures of an internal-external pair, defined once: each signal's lag behind what it was
asked, their relative latency, and the pair's relationship (lead, hysteresis loop, correlation,
amplitude ratio, baseline drift). Below everything that measures a pair: the Diagram's pair
report (:mod:`stewart_drake.organ_motion.surrogate_pair`), the robot's session from its
encoders (:mod:`stewart_drake.live.session_surrogate`) and ``verify --surrogate`` from measured
files (:mod:`stewart_drake.verification.pair_judgement`) all take their relative latency from
:func:`relative_latency`.

Sign conventions (docs/surrogate.md, "Reading the relative latency"; the words for time offsets
as docs/index.md defines them):

- a **lag** d > 0: the measured signal comes d after the commanded one (measured(t) ~
  commanded(t - d)).
- the **relative latency** = d_internal - d_external: > 0, the internal target arrives late
  against the surrogate (the surrogate early), so the pair's reproduced lead of the external is
  the asked lead plus the relative latency. The sign is IntERAct's (``RMSEAlignMethod.m``:
  ``latency = shift6D - shift1D``) and ``verify --surrogate``'s
  (:mod:`stewart_drake.verification.pair_judgement`).
- a **lead** > 0: the external reaches each phase of the breath before the internal does
  (external(t) ~ k internal(t + lead)).
- the **hysteresis area** > 0: the loop in the (internal, external) plane runs clockwise, as it
  does when the external leads; per cycle, m^2 (a sine pair of amplitudes A_i, A_e and phase
  lead phi encloses pi A_i A_e sin phi).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .errors import InvalidConfigError
from .lag import inner_mask, signal_lag
from .signals import principal_direction

#: The lags a pair's relative latency searches either way, s (under half a breath, so that a
#: breath earlier or later is never matched): the Diagram's pair report's, the robot's session's
#: and ``verify --surrogate``'s (which widens it only for a lag found at its edge).
LAG_SEARCH_S = 0.5


def _uniform(t: np.ndarray) -> float:
    dt = np.diff(t)
    if t.ndim != 1 or len(t) < 8 or np.any(dt <= 0):
        raise InvalidConfigError("a pair's figures need at least 8 samples at increasing times")
    h = float(np.median(dt))
    if np.max(np.abs(dt - h)) > 1e-6 * max(h, 1e-9) + 1e-9:
        raise InvalidConfigError("a pair's figures need samples at a uniform step")
    return h


def _check_record(t: np.ndarray, max_s: float, uniform: bool = True) -> None:
    """Refuse samples not increasing (or, with ``uniform``, not at a uniform step), or fewer
    than 8 more than ``max_s`` from either end."""
    if uniform:
        _uniform(t)
    elif t.ndim != 1 or len(t) < 8 or np.any(np.diff(t) <= 0):
        raise InvalidConfigError("a pair's figures need at least 8 samples at increasing times")
    if np.count_nonzero(inner_mask(t, max_s)) < 8:
        raise InvalidConfigError(f"a lag of up to {max_s:g} s needs a longer record")


def lag_s(t, commanded, measured, max_s: float = LAG_SEARCH_S) -> float:
    """How late ``measured`` is behind ``commanded``, s: the shift d in [-max_s, max_s] that
    makes measured(t) - commanded(t - d) least in RMS once their mean difference (a constant
    offset) is removed; ``commanded`` joined by a cubic spline; the package's one lag search
    (:func:`~stewart_drake.base.lag.signal_lag`: every shift by FFT, then to a microsecond) over
    the samples more than ``max_s`` from either end; NaN for a command that does not move.

    Args:
        t: (n,) uniform s. commanded, measured: (n,) or (n, k) on ``t``.
    Raises:
        InvalidConfigError: too few samples, or not uniform.
    """
    t = np.asarray(t, float)
    _check_record(t, max_s)
    c = np.asarray(commanded, float).reshape(len(t), -1)
    m = np.asarray(measured, float).reshape(len(t), -1)
    return signal_lag(t, m, c, max_s, offsets=True, min_samples=8)[0]


def pair_lags(
    t,
    internal,
    internal_measured,
    external,
    external_measured,
    max_s: float,
    *,
    still_internal: float = 0.0,
    still_external: float = 0.0,
    min_samples: int = 8,
) -> tuple[np.ndarray | None, tuple[float, float], tuple[float, float]]:
    """Each motion's lag behind its command, the internal's along its principal direction: the
    one definition of what a relative latency subtracts (module docstring), the Diagram's pair
    report's and the robot's session's, both through :func:`relative_latency`.

    Each lag by the package's one lag search
    (:func:`~stewart_drake.base.lag.signal_lag`, a constant offset removed) within +-``max_s``
    over the samples more than ``max_s`` from either end; the internal's along the principal
    direction (:func:`~stewart_drake.base.signals.principal_direction`) of its command's
    translations.

    Args:
        t: (n,) s, increasing, the one clock of both.
        internal, internal_measured: (n, 6) poses or (n, 3) translations, m, as commanded
            and as reproduced; or (n,) a displacement already along one direction.
        external, external_measured: (n,) the surrogate as commanded and as reproduced, m.
        max_s: the largest lag searched, s.
        still_internal, still_external: a command that moves at most this peak to peak, m, has
            no lag (NaN).
        min_samples: the fewest samples compared.
    Returns:
        (u, (d_i, rms_i), (d_e, rms_e)): the (3,) direction the internal's lag is measured along
        (None for a displacement given along one; Z for fewer than 2 samples), each lag, s
        (> 0: late), and the RMS residual at it, m.
    Raises:
        InvalidConfigError: as :func:`~stewart_drake.base.lag.signal_lag`'s; a principal
            direction of non-finite samples.
    """
    c = np.asarray(internal, float)
    u = None
    if c.ndim == 2:
        u = principal_direction(c) if len(c) >= 2 else np.array([0.0, 0.0, 1.0])
        m = np.asarray(internal_measured, float)
        c = (c[:, 3:6] if c.shape[1] == 6 else c) @ u
        internal_measured = (m[:, 3:6] if m.shape[1] == 6 else m) @ u
    lags = [
        signal_lag(
            t, measured, commanded, max_s, offsets=True, still_below=still, min_samples=min_samples
        )
        for commanded, measured, still in (
            (c, internal_measured, still_internal),
            (external, external_measured, still_external),
        )
    ]
    return u, lags[0], lags[1]


@dataclass(frozen=True)
class PairLatency:
    """A pair's relative latency and the two lags it subtracts (module docstring).

    Attributes:
        relative_s: ``internal_lag_s - external_lag_s``, s (> 0: the internal target late);
            NaN when a command is still.
        internal_lag_s, external_lag_s: each motion's lag behind its command, s (> 0: late;
            NaN: a command that does not move).
        internal_rms_m, external_rms_m: the RMS residual at each lag (a constant offset
            removed), m.
        direction: the (3,) unit direction the internal's lag is measured along; None for a
            displacement given along one.
        samples: the samples compared, those more than the search's half-width from either end.
    """

    relative_s: float
    internal_lag_s: float
    external_lag_s: float
    internal_rms_m: float
    external_rms_m: float
    direction: tuple | None
    samples: int

    def as_dict(self) -> dict:
        """{"lag_internal_s", "lag_external_s", "relative_latency_s", "direction" (a list, or
        None)}: the Diagram's pair report's keys."""
        return {
            "lag_internal_s": self.internal_lag_s,
            "lag_external_s": self.external_lag_s,
            "relative_latency_s": self.relative_s,
            "direction": None if self.direction is None else list(self.direction),
        }


def relative_latency(
    t,
    internal,
    internal_measured,
    external,
    external_measured,
    max_s: float = LAG_SEARCH_S,
    *,
    still_internal: float = 0.0,
    still_external: float = 0.0,
    min_samples: int = 8,
) -> PairLatency:
    """The relative latency of a pair (module docstring): the internal target's lag less the
    surrogate's, each as :func:`pair_lags` measures it, each sample at its own time (a
    camera's uneven frames too). The one definition: the Diagram's pair report, the robot's
    session (from its encoders) and ``verify --surrogate`` (from measured files,
    :func:`~stewart_drake.verification.pair_judgement.pair_relative_latency`) all measure
    theirs here.

    Args:
        t: (n,) s, increasing, the one clock of both.
        internal, internal_measured, external, external_measured: as :func:`pair_lags`'s.
        max_s: the largest lag searched, s.
        still_internal, still_external, min_samples: as :func:`pair_lags`'s.
    Returns:
        :class:`PairLatency`.
    Raises:
        InvalidConfigError: fewer than 8 samples, not increasing, or fewer than 8 (and
            ``min_samples``) inside the search's margins; a principal direction of non-finite
            samples.
    """
    t = np.asarray(t, float)
    _check_record(t, max_s, uniform=False)
    u, (d_i, rms_i), (d_e, rms_e) = pair_lags(
        t,
        internal,
        internal_measured,
        external,
        external_measured,
        max_s,
        still_internal=still_internal,
        still_external=still_external,
        min_samples=min_samples,
    )
    return PairLatency(
        relative_s=d_i - d_e,
        internal_lag_s=d_i,
        external_lag_s=d_e,
        internal_rms_m=rms_i,
        external_rms_m=rms_e,
        direction=None if u is None else tuple(float(v) for v in u),
        samples=int(np.count_nonzero(inner_mask(t, max_s))),
    )


def lead_s(t, internal, external, max_s: float = 2.0) -> float:
    """The external's lead on the internal, s: the shift tau in [-max_s, max_s] at which the
    external(t), standardised, comes nearest the internal(t + tau), standardised (the one lag
    search, :func:`~stewart_drake.base.lag.best_shift`, a constant offset removed: for two
    standardised signals the mean squared distance is 2 (1 - Pearson's correlation), so the
    nearest shift is the most correlated; approximately here, the internal being standardised
    over the whole record and the external over the window), searched for the external and
    for its opposite (one search each: the nearest of each sign), the
    smaller in magnitude of the two taken (so that a pair whose axes point opposite ways, a
    tumour moving inferior as the chest rises, is not read half a breath off); over a window
    fixed for every tau (the record less max_s at each end; the internal linearly
    interpolated), on the samples' step, then to a microsecond.

    Args:
        t: (n,) uniform s. internal, external: (n,) m.
    Raises:
        InvalidConfigError: too few samples, not uniform, or a record shorter than 2 max_s.
    """
    from .lag import best_shift

    t = np.asarray(t, float)
    h = _uniform(t)
    i = np.asarray(internal, float)
    e = np.asarray(external, float)
    k = max(int(np.ceil(max_s / h)), 1)
    inner = (t >= t[0] + k * h) & (t <= t[-1] - k * h)
    if inner.sum() < 8:
        raise InvalidConfigError(f"a lead of up to {max_s:g} s needs a longer record")
    zi = (i - i.mean()) / (np.std(i) or 1.0)
    ze = e[inner] - e[inner].mean()
    ze /= np.std(ze) or 1.0

    def seen(times):
        return np.interp(times, t, zi)[:, None]

    leads = [
        best_shift(t[inner], sign * ze[:, None], np.ones(1), seen, (-k * h, k * h), h, True)
        for sign in (1.0, -1.0)
    ]
    return min(leads, key=abs)


def hysteresis_area(internal, external) -> float:
    """The area the pair's loop encloses per cycle, m^2, signed (module docstring): the
    shoelace sum over the whole cycles between the internal's first and last upward crossing
    of its mean, divided by their number; with one crossing or none, the whole record closed on
    itself as one cycle (a window of one whole cycle, as ``reproduce --cycles 1`` measures).

    Args:
        internal, external: (n,) m, sampled together.
    Raises:
        InvalidConfigError: the internal never crosses its mean (at rest).
    """
    i = np.asarray(internal, float) - np.mean(internal)
    e = np.asarray(external, float) - np.mean(external)
    up = np.flatnonzero((i[:-1] < 0) & (i[1:] >= 0))
    down = np.flatnonzero((i[:-1] >= 0) & (i[1:] < 0))
    if len(up) + len(down) == 0:
        raise InvalidConfigError("the hysteresis loop needs a motion that crosses its mean")
    a, b, cycles = (up[0], up[-1] + 1, len(up) - 1) if len(up) >= 2 else (0, len(i) - 1, 1)
    x, y = i[a : b + 1], e[a : b + 1]
    shoelace = 0.5 * float(np.sum(x[:-1] * y[1:] - x[1:] * y[:-1]) + x[-1] * y[0] - x[0] * y[-1])
    return -shoelace / cycles


def correlation(internal, external) -> float:
    """Pearson's correlation coefficient of the pair at no shift."""
    return float(np.corrcoef(np.asarray(internal, float), np.asarray(external, float))[0, 1])


def amplitude_ratio(internal, external) -> float:
    """The external's standard deviation over the internal's."""
    return float(np.std(external) / np.std(internal))


def baseline_drift(t, internal, external, lead: float = 0.0) -> float:
    """The external's drift against the internal, m/s: the coefficient of t in the least-squares
    fit external(t) = c + k internal(t + lead) + drift t.

    Args:
        t: (n,) s. internal, external: (n,) m. lead: the external's lead, s (:func:`lead_s`).
    """
    t = np.asarray(t, float)
    shifted = np.interp(t + lead, t, np.asarray(internal, float))
    keep = (t + lead >= t[0]) & (t + lead <= t[-1])
    A = np.column_stack([np.ones(keep.sum()), shifted[keep], t[keep] - t[keep].mean()])
    coef = np.linalg.lstsq(A, np.asarray(external, float)[keep], rcond=None)[0]
    return float(coef[2])


def pair_figures(t, internal, external, split_s: float | None = None, max_lead_s: float = 2.0):
    """Every relationship figure of a pair, as asked or as reproduced.

    Args:
        t: (n,) uniform s. internal, external: (n,) m (the internal along its main direction,
            :func:`~stewart_drake.base.signals.principal_displacement`).
        split_s: where the relationship changes, s: the lead and correlation are also given
            before and after it ("lead_before_s", "lead_after_s", ...), or None.
        max_lead_s: the largest lead searched, s (at most a quarter of the record's length).
    Returns:
        {"lead_s", "hysteresis_area_m2", "correlation", "amplitude_ratio",
        "drift_m_per_s"} (and the halves' with ``split_s``).
    """
    t = np.asarray(t, float)

    def longest(part: np.ndarray) -> float:  # a quarter of the record at most
        return min(max_lead_s, 0.25 * float(part[-1] - part[0]))

    lead = lead_s(t, internal, external, longest(t))
    out = {
        "lead_s": lead,
        "hysteresis_area_m2": hysteresis_area(internal, external),
        "correlation": correlation(internal, external),
        "amplitude_ratio": amplitude_ratio(internal, external),
        "drift_m_per_s": baseline_drift(t, internal, external, lead),
    }
    if split_s is not None:
        for name, part in (("before", t < split_s), ("after", t >= split_s)):
            tp = t[part]
            out[f"lead_{name}_s"] = lead_s(tp, internal[part], external[part], longest(tp))
            out[f"correlation_{name}"] = correlation(internal[part], external[part])
    return out
