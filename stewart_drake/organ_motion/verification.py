"""A motion measured on a real phantom judged against the reference it was asked to follow
(``stewart-drake verify``): the same figures as a reproduction's (:func:`~.fidelity.fidelity`,
the report of :mod:`~.fidelity_report`) from a tracker's export or the robot's encoder log.

What is measured (:class:`~.measured_motion.MeasuredMotion`) is a tracker's file read by the
readers of recorded traces (:func:`~.measured_motion.read_measured`: a header naming columns and
units, semicolons or commas, decimal commas, ms, a frame column skipped with ``-``), the poses of
its marker M in the tracker's frame T on the tracker's clock, or the robot's encoder log turned
into platform poses by forward kinematics (:func:`~.measured_motion.encoder_motion`), on the
reference's own clock. :func:`verify` then, with the clock and the frames of :mod:`~.alignment`,

1. **aligns the clocks**: the shift d (measured time + d = the reference's time whose pose it
   shows) is found coarsely by cross-correlation over every shift allowed, the measured positions
   against the reference's with the best rigid frame at each shift (the sum of the singular
   values of their cross-covariance, all shifts at once by FFT), then finely with the frames
   (step 2) by least squares, to a fraction of a sample;
2. **puts the frames together**: the poses are already the platform's in the base frame (the
   encoder log; ``frame="base"``; or mapped by a registration, ``base_poses``), or a rigid
   transform of the tracker's frame and the marker's offset on the platform are fitted
   (``frame="fit"``): the fit also removes any true constant error of the phantom (an offset or a
   tilt of its whole motion), and the report says so with what it removed;
3. **separates the latency from the clock offset**: only their difference is in the data
   (d = clock offset - latency). With the clocks' relation known (``clock_offset_s``: measured
   time + offset = the reference's time; the encoder log's ``t_path`` is the reference's clock
   itself) the latency is the offset less the shift; without it the whole shift is reported as
   the latency, ``clock_offset_s`` 0, and the report says that the two were not separated;
4. **measures** the aligned motion over the reference's whole cycles inside the recording
   (after the motion's first cycle when the recording holds its start: the start-up, reported
   apart) with :func:`~.fidelity.fidelity`: RMS, peak, gamma, harmonics, the error per cycle.
   The figures are those of the motion with its latency removed; the latency is given on its own.

A marker that gives positions only (a reflector, a 3-DoF target) is measured in translation; the
rotation figures are then NaN and named as not measured.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import ClassVar

import numpy as np

from ..base.errors import InvalidConfigError
from ..references.motion import Reference
from .alignment import (
    FrameFit,
    _fine_fit,
    _first_fit,
    _in_base,
    _registered,
    coarse_shift,
    reference_poses,
)
from .fidelity import AXES, fidelity, startup_figures, time_lag
from .measured_motion import MeasuredMotion

#: Largest latency searched when the clocks' relation is known, s (at most 0.45 of a periodic
#: reference's period, so that a cycle earlier or later is never taken).
MAX_LATENCY_S = 0.5
#: Longest stretch of a reference without cycles the shift is searched over when the clocks'
#: relation is not known, s (an hour: the longest run reproduce makes).
MAX_SEARCH_S = 3600.0
#: Shortest measured motion without cycles that is judged, s (a breath).
MIN_SPAN_S = 4.0
#: Step of the coarse clock search, s (finer when the measured samples are).
COARSE_STEP_S = 0.02
#: Jitter of a file's time steps beyond which its samples are resampled to an even grid (as a
#: share of the median step).
MAX_JITTER = 0.01


# -- the verification ------------------------------------------------------------------------------


@dataclass(frozen=True)
class MeasuredRun:
    """The aligned motion, as a run's log: t (n,) the reference's times, s; x (n, 6) the
    measured platform poses in the base frame (NaN on the axes not measured); x_d (n, 6) the
    reference's."""

    t: np.ndarray
    x: np.ndarray
    x_d: np.ndarray


@dataclass
class Verification:
    """A measured motion judged against its reference (:func:`verify`); what
    :mod:`~.fidelity_report` writes up, as it does a :class:`~.reproduction.Reproduction`.

    Attributes:
        name: the reference's name. reference: the reference. measured: the
            :class:`~.measured_motion.MeasuredMotion` as read.
        result: the aligned motion (:class:`MeasuredRun`), over the recording's overlap with
            the reference.
        cycle_starts: (K + 1,) the reference's cycles in the overlap, s (empty without).
        fidelity: :func:`~.fidelity.fidelity` over the measured window, the axes not measured
            NaN and ``measured`` naming those that are.
        startup: the recording before the window when it holds the motion's start: {"window_s",
            "rms_translation_m", "rms_rotation_rad", "peak_translation_m",
            "peak_rotation_rad"}; an empty window otherwise.
        shift_s: d, the measured time + d is the reference's time its pose shows, s.
        clock_offset_s: the measured clock's offset (measured time + offset = the reference's
            time), s: given, the encoder log's (0), or 0 when not known.
        clock: how the offset was known, in words. latency_s: the phantom's lag behind the
            reference, s (> 0: late): offset - shift.
        frame: the frames (:class:`~.alignment.FrameFit`).
        removed: what was removed before the figures, in words (the clock, the frames, any
            resampling, what the recording holds outside the reference).
    """

    name: str
    reference: Reference
    measured: MeasuredMotion
    result: MeasuredRun
    cycle_starts: np.ndarray
    fidelity: dict
    startup: dict
    shift_s: float
    clock_offset_s: float
    clock: str
    latency_s: float
    frame: FrameFit
    removed: list
    learn_cycles: int = 0
    scale: float = 1.0
    learned_from: str = ""
    wall_s: float = 0.0
    #: The figure's name of the curve beside the reference's.
    curve_label: ClassVar[str] = "measured"

    @property
    def learning(self) -> str:
        """The report title's words on the run: what measured it."""
        return (
            f"measured by the encoders, {Path(self.measured.path).name}"
            if self.measured.kind == "encoders"
            else f"measured by the tracker, {Path(self.measured.path).name}"
        )

    def resolution(self) -> tuple[float, float]:
        """(0, 0): the measured pose's resolution is the instrument's, not known here."""
        return (0.0, 0.0)


def _even(t: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray, str]:
    """(t, y, what was done in words or ""): the samples as they are when their steps are even
    to :data:`MAX_JITTER`, else resampled linearly to an even grid at their median step."""
    steps = np.diff(t)
    dt = float(np.median(steps))
    if np.max(np.abs(steps - dt)) <= MAX_JITTER * dt:
        return t, y, ""
    grid = t[0] + dt * np.arange(int(np.floor((t[-1] - t[0]) / dt + 1e-9)) + 1)
    out = np.column_stack([np.interp(grid, t, y[:, c]) for c in range(y.shape[1])])
    words = (
        f"resampling: {len(t)} samples whose steps range {steps.min() * 1e3:.4g}-"
        f"{steps.max() * 1e3:.4g} ms resampled linearly to {len(grid)} at {dt * 1e3:.4g} ms"
    )
    return grid, out, words


def _search(reference: Reference, t: np.ndarray, clock_offset_s, max_latency_s: float):
    """(lo, hi) s: the shifts searched. Known clocks: the offset less the latencies up to
    ``max_latency_s`` (at most 0.45 of a periodic reference's period); unknown: every shift that
    puts the recording's start from half its length before the motion's start to the end of the
    reference (one period of a periodic one, :data:`MAX_SEARCH_S` of one without an end)."""
    period = getattr(reference, "repeat_period_s", None)
    if clock_offset_s is not None:
        lat = max_latency_s if not period else min(max_latency_s, 0.45 * period)
        return clock_offset_s - lat, clock_offset_s + lat
    span = float(t[-1] - t[0])
    end = getattr(reference, "end_time", None)
    top = float(end) - 0.5 * span if end is not None else float(period or MAX_SEARCH_S)
    return -t[0] - 0.5 * span, -t[0] + max(top, 0.0)


def _window(reference: Reference, a: float, b: float) -> tuple[tuple, np.ndarray, bool]:
    """((w0, w1) the window measured, (K + 1,) the cycle starts in [a, b], whether the recording
    [a, b] (reference time, s) holds the motion's first cycle): the whole cycles after the first
    one of the motion; all of [a, b] for a reference without cycles.

    Raises:
        InvalidConfigError: not one whole cycle (or :data:`MIN_SPAN_S` without cycles).
    """
    from ..references.motion import reference_cycles

    name = getattr(reference, "name", "the reference")
    try:
        starts, _ = reference_cycles(reference, b)
    except InvalidConfigError:
        starts = np.zeros(0)
    if starts.size < 2:
        if b - a < MIN_SPAN_S:
            raise InvalidConfigError(
                f"the measured motion covers {b - a:.3g} s of {name} once aligned, shorter than "
                f"a breath ({MIN_SPAN_S:g} s): record a longer stretch"
            )
        return (a, b), np.zeros(0), False
    holds_start = a < starts[1]
    inside = starts[(starts >= max(a, starts[1]) - 1e-9) & (starts <= b + 1e-9)]
    if inside.size < 2:
        cycle = float(np.median(np.diff(starts)))
        raise InvalidConfigError(
            f"the measured motion covers t = {a:.4g}-{b:.4g} s of {name} once aligned: not one "
            f"whole cycle ({cycle:.3g} s) after the motion's first; record at least two cycles"
        )
    return (float(inside[0]), float(inside[-1])), inside, holds_start


def _not_measured(fid: dict, measured: np.ndarray, t, x, x_d) -> dict:
    """``fid`` with the figures of the axes not measured NaN (their harmonics and lags left out;
    the lag of the whole motion from the measured axes), and ``measured`` naming the others."""
    off = [k for k in range(6) if not measured[k]]
    if not off:
        return {**fid, "measured": list(AXES)}
    fid = dict(fid)
    for key in ("rms", "peak", "rms_fraction", "peak_fraction"):
        fid[key] = [math.nan if k in off else v for k, v in enumerate(fid[key])]
    fid["rms_rotation_rad"] = fid["peak_rotation_rad"] = math.nan
    fid["lag_s"] = {a: v for a, v in fid["lag_s"].items() if measured[AXES.index(a)]}
    fid["harmonics"] = [h for h in fid["harmonics"] if measured[AXES.index(h["axis"])]]
    fid["cycles"] = {
        **fid["cycles"],
        "rms_rotation_rad": [math.nan] * len(fid["cycles"]["rms_rotation_rad"]),
    }
    moving = [AXES.index(a) for a in fid["moving"] if measured[AXES.index(a)]]
    if moving:
        w0, w1 = fid["window_s"]
        m = (t >= w0 - 1e-9) & (t <= w1 + 1e-9)
        p2p = np.asarray(fid["p2p"])[moving]
        fid["lag_all_s"] = time_lag(t[m], x[m][:, moving], x_d[m][:, moving], weights=1 / p2p)
    fid["measured"] = [a for a, m in zip(AXES, measured) if m]
    return fid


def verify(
    reference: Reference,
    measured: MeasuredMotion,
    clock_offset_s: float | None = None,
    frame: str = "fit",
    registration=None,
    max_latency_s: float = MAX_LATENCY_S,
) -> Verification:
    """Judge a measured motion against the reference it was asked to follow (module docstring).

    Args:
        reference: the motion asked for (:class:`~stewart_drake.references.motion.Reference`).
        measured: the motion measured (:func:`~.measured_motion.read_measured`,
            :func:`~.measured_motion.encoder_motion`).
        clock_offset_s: s, the measured time + this is the reference's (None: not known; the
            encoder log is on the reference's clock, 0).
        frame: "fit" (fit the tracker's frame and the marker's offset) or "base" (the poses are
            the platform's in the base frame already); ignored for the encoder log.
        registration: the tracker's frames registered from fiducials
            (:class:`~stewart_drake.calibration.registration.Registration`: ``X_TB``,
            ``X_PM``, ``base_poses``, ``words``), or None; replaces ``frame``.
        max_latency_s: the largest latency searched when the clocks' relation is known, s.
    Returns:
        :class:`Verification`.
    Raises:
        InvalidConfigError: a frame that is neither "fit" nor "base"; a recording not one whole
            cycle of the reference long (or a breath, without cycles), before or after the
            alignment; no overlap with the reference once aligned; a non-finite offset.
    """
    if frame not in ("fit", "base"):
        raise InvalidConfigError(f"frame must be 'fit' or 'base', got {frame!r}")
    if clock_offset_s is not None and not math.isfinite(clock_offset_s):
        raise InvalidConfigError(f"the clock offset must be a finite number, got {clock_offset_s}")
    t, y = measured.t, measured.poses
    if measured.kind == "encoders":
        clock_offset_s, clock = 0.0, "the encoder log's t_path is the reference's own clock"
        fit = FrameFit("base")
    else:
        clock = "given (--clock-offset)" if clock_offset_s is not None else "not known"
        fit = FrameFit(frame) if registration is None else _registered(registration, measured)
    if fit.how == "registration" and measured.rotations_measured:
        y = np.asarray(registration.base_poses(y), dtype=float)
    t, y, resampled = _even(t, y)
    _check_length(reference, t)
    fitting = fit.how == "fit"
    step = max(COARSE_STEP_S, float(np.median(np.diff(t))))
    lo, hi = _search(reference, t, clock_offset_s, max_latency_s)
    y_coarse = y[:, 3:] @ fit.R_BT.T + fit.p_BT
    d0, R0 = coarse_shift(t, y_coarse, reference, (lo, hi), step, fitting)
    if fitting:
        fit = _first_fit(reference, t + d0, y, R0)
    use = _overlap(reference, t + d0, step)
    d, fit = _fine_fit(t[use], y[use], measured, reference, d0, fit, fitting)
    keep = _overlap(reference, t + d, 0.0)
    t_ref = t[keep] + d
    x_d = reference_poses(reference, t_ref)
    x = _in_base(fit, y[keep], x_d)
    (w0, w1), starts, holds_start = _window(reference, float(t_ref[0]), float(t_ref[-1]))
    x_fid = np.where(np.isfinite(x), x, x_d)  # the axes not measured compare to themselves
    fid = fidelity(t_ref, x_fid, x_d, (w0, w1), _frequencies(reference), starts)
    offset = 0.0 if clock_offset_s is None else float(clock_offset_s)
    return Verification(
        name=getattr(reference, "name", "reference"),
        reference=reference,
        measured=measured,
        result=MeasuredRun(t_ref, x, x_d),
        cycle_starts=starts,
        fidelity=_not_measured(fid, measured.measured, t_ref, x_fid, x_d),
        startup=startup_figures(t_ref, x, x_d, w0 if holds_start else float(t_ref[0])),
        shift_s=d,
        clock_offset_s=offset,
        clock=clock,
        latency_s=offset - d,
        frame=fit,
        removed=_removed_words(d, offset, offset - d, clock, fit, resampled)
        + _outside_words(t + d, t_ref, (w0, w1), holds_start),
    )


def _check_length(reference: Reference, t: np.ndarray) -> None:
    """Refuse a recording shorter than one cycle of the reference (or a breath, without)."""
    from ..references.motion import reference_cycles

    span = float(t[-1] - t[0])
    period = getattr(reference, "repeat_period_s", None)
    end = getattr(reference, "end_time", None)
    if period is None:
        try:
            starts, _ = reference_cycles(
                reference, max(4 * span, 60.0) if end is None else float(end)
            )
            period = float(np.median(np.diff(starts)))
        except InvalidConfigError:
            period = MIN_SPAN_S
    if span < period:
        raise InvalidConfigError(
            f"the measured motion lasts {span:.3g} s, shorter than one cycle of "
            f"{getattr(reference, 'name', 'the reference')} ({period:.3g} s): record at least "
            f"two cycles"
        )


def _overlap(reference: Reference, t_ref: np.ndarray, margin: float) -> np.ndarray:
    """(n,) bool: the times t_ref (s, the reference's) inside its span, ``margin`` s in.

    Raises:
        InvalidConfigError: fewer than 10 such times (no overlap).
    """
    end = getattr(reference, "end_time", None)
    top = math.inf if end is None else float(end) - margin
    on = (t_ref >= margin) & (t_ref <= top)
    if np.count_nonzero(on) < 10:
        raise InvalidConfigError(
            f"once aligned, the measured motion spans t = {t_ref[0]:.4g}-{t_ref[-1]:.4g} s of "
            f"the reference's clock, which runs over 0-{'' if end is None else f'{end:.4g}'} s: "
            f"no overlap; check --clock-offset and that the file recorded this motion"
        )
    return on


def _frequencies(reference: Reference) -> dict:
    """The fundamentals of a reference that repeats ({} for one that does not)."""
    repeats = getattr(reference, "repeat_period_s", None) is not None
    frequencies = getattr(reference, "frequencies_hz", None)
    return frequencies() if repeats and callable(frequencies) else {}


def seconds(value: float) -> str:
    """A time in s as text: ``60.1 ms`` below a second, else ``1232 s`` (4 digits)."""
    return f"{value * 1e3:.4g} ms" if abs(value) < 1.0 else f"{value:.4g} s"


def _removed_words(d, offset, latency, clock, fit: FrameFit, resampled) -> list:
    """The report's lines on what the alignment removed: the clock, the frames, any
    resampling."""
    if clock == "not known":
        clock_line = (
            f"the clock: the measured motion shifted by {d:+.6g} s onto the reference's clock "
            f"(cross-correlation, then least squares). The clocks' relation was not given, so the "
            f"whole shift is reported as the latency ({seconds(latency)}) with clock offset "
            f"0: it holds any offset of the tracker's clock; give --clock-offset S (the measured "
            f"time + S = the reference's) to separate the phantom's own lag"
        )
    else:
        clock_line = (
            f"the clock: the measured motion shifted by {d:+.6g} s onto the reference's clock "
            f"(cross-correlation, then least squares): the clock offset {offset:+.6g} s ({clock}) "
            f"less the latency, {seconds(latency)} (> 0: the phantom late)"
        )
    lines = [clock_line, f"the frames: {fit.words()}"]
    if resampled:
        lines.append(resampled)
    return lines


def _outside_words(t_all, t_ref, window, holds_start: bool) -> list:
    """The report's line on the parts of the recording outside the figures (none if none)."""
    before = float(t_ref[0] - t_all[0])
    after = float(t_all[-1] - t_ref[-1])
    parts = []
    if before > 0 or after > 0:
        parts.append(
            f"{before:.3g} s of the recording before the reference's start and {after:.3g} s "
            f"after its end are not compared"
        )
    head = window[0] - t_ref[0]
    tail = t_ref[-1] - window[1]
    if head > 0 or tail > 0:
        what = "the motion's first cycle, the start-up" if holds_start else "part of a cycle"
        parts.append(
            f"the figures are over whole cycles, t = {window[0]:.4g}-{window[1]:.4g} s: "
            f"{head:.3g} s before ({what}) and {tail:.3g} s after are outside them"
        )
    return ["what the figures leave out: " + "; ".join(parts)] if parts else []


__all__ = [
    "MAX_LATENCY_S",
    "MAX_SEARCH_S",
    "MIN_SPAN_S",
    "COARSE_STEP_S",
    "MAX_JITTER",
    "MeasuredRun",
    "Verification",
    "seconds",
    "verify",
]
