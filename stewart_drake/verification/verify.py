"""A motion measured on a real phantom judged against the reference it was asked to follow
(``stewart-drake verify``): the same figures as a reproduction's (:func:`~.fidelity.fidelity`,
the report of :mod:`~.fidelity_report`) from a tracker's export, a single-axis sensor's file or
the robot's encoder log, and a verdict that names what it compares and why it fails
(:mod:`~.measured_verdict`).

What is measured (:class:`~.measured_motion.MeasuredMotion`) is a file read by the readers of
recorded traces (:func:`~.measured_motion.read_measured`: a header naming columns and units,
semicolons or commas, decimal commas, ms, a frame column skipped with ``-``): a marker's poses in
a tracker's frame T on the tracker's clock, any of its axes (a laser displacement sensor or a
depth camera gives one); or the robot's encoder log turned into platform poses by forward
kinematics (:func:`~.measured_motion.encoder_motion`), or the surrogate's carriage in that log
(:func:`~.measured_motion.carriage_motion`: its offset removed, as ``"axes"`` removes one), on
the reference's own clock. :func:`verify` then, with the clock and the frames of :mod:`~.alignment`,

1. **takes the frames from outside the motion judged**: the encoder log's base frame, a
   registration (``registration``: fiducials, or a registration motion measured once,
   :mod:`~.registration_motion`), the base frame as the file says (``frame="base"``), or each
   measured axis as the base frame's axis its column names with a constant offset of its own
   (``frame="axes"``, the default: what phantom QA protocols remove). Nothing is fitted to the
   motion judged but the clock and, with ``"axes"``, one constant per measured axis: no
   rotation, scale or marker lever arm, which would absorb the very errors to be found;
2. **aligns the clocks**: the shift d (measured time + d = the reference's time whose pose it
   shows) that brings the measured axes nearest the reference's, each less its mean difference
   whatever the frames (a constant offset is judged on its own, and would pull the clock
   towards where the reference's mean over the window comes nearest it), coarsely over every
   shift allowed by FFT, then to a fraction of a sample, on the file's times less its first
   (a clock counting from 1970 keeps its digits);
3. **separates the latency from the clock offset**: only their difference is in the data
   (d = clock offset - latency). With the clocks' relation known (``clock_offset_s``: measured
   time + offset = the reference's time; the encoder log's ``t_path`` is the reference's clock
   itself) the latency is the offset less the shift, and it is judged against
   ``max_latency_s``; without it the whole shift is reported as the latency, ``clock_offset_s``
   0, not judged, and the report says that the two were not separated;
4. **measures** the aligned motion over the reference's whole cycles inside the recording
   (after the motion's first cycle when the recording holds its start: the start-up, reported
   apart) with :func:`~.fidelity.fidelity`: RMS, peak, gamma, harmonics, the error per cycle, on
   the axes measured (the others NaN and named as not measured);
5. **judges** (:func:`~.measured_verdict.judge`): every measured axis's RMS error within the
   tolerance and, with the clocks known, the latency within its bound; a failure names its
   causes (the phantom at rest, a wrong amplitude, sign, axis or period, another motion, a
   constant offset, the latency), and the report gives the smallest amplitude and tilt error
   the check can see (:func:`~.verdict_sensitivity.sensitivity`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, ClassVar

import numpy as np

from ..base.errors import InvalidConfigError
from ..base.lag import coarse_shift, refine_shift
from ..organ_motion.fidelity import AXES, fidelity, startup_figures, time_lag
from ..references.motion import Reference
from .alignment import (
    Frames,
    axis_weights,
    overlap,
    platform_poses,
    reference_poses,
    reference_seen,
    registered_frames,
)
from .measured_motion import MeasuredMotion
from .measured_span import (
    CYCLE_SLACK,
    MAX_REFERENCE_TIME_S,
    MAX_SEARCH_S,
    MIN_SPAN_S,
    SEARCH_FACTOR,
    check_length,
    check_reference_time,
    cycle_window,
    outside_words,
    search_range,
    uncompared,
)
from .measured_verdict import judge, seconds
from .verdict_notes import outliers, uncompared_words

#: The largest latency that passes when the clocks' relation is known, s, unless given.
MAX_LATENCY_S = 0.5
#: The largest clock offset taken, s (about 317 years: a clock counting from 1970 fits, with
#: float64's steps there under a microsecond).
MAX_CLOCK_OFFSET_S = 1e10
#: Step of the coarse clock search, s (finer when the measured samples are).
COARSE_STEP_S = 0.02
#: Jitter of a file's time steps beyond which the report says how uneven they are (as a share
#: of the median step); they are judged at their own times either way.
MAX_JITTER = 0.01
#: The longest step between two measured samples judged across unless given, s.
MAX_GAP_S = 0.5
#: The RMS error per axis that passes unless given, (m, rad): verify's ``--tolerance`` default.
DEFAULT_TOLERANCE = (1e-4, math.radians(0.1))
#: The frames' words for the surrogate's carriage in the encoder log (a measurement of kind
#: "carriage": :func:`~.measured_motion.carriage_motion`).
CARRIAGE = "the surrogate's carriage s of the encoder log, put on its reference's one axis"


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
        frame: the frames (:class:`~.alignment.Frames`).
        offsets: (6,) the constant offset removed from each measured axis (the ``"axes"``
            frames; zeros otherwise), rad and m: measured less reference, over the window.
        removed: what was removed before the figures, in words (the clock, the frames, any
            resampling, what the recording holds outside the reference).
        searched_s: (lo, hi) the shifts searched, s. max_latency_s: the latency's bound, s.
        uncompared: {"samples": the recording's, "before", "after": those the clock puts
            before the reference's start and after its end, "before_s", "after_s": their
            spans, s, "whole": whether the clock was known or searched among the shifts that
            compare the whole recording}: what the verdict leaves out (its line says so).
        pauses: ((t of the file before the pause, s; its length, s), ...): the planned pauses
            the segments were judged across (``verify``'s ``pauses``), () without.
        outliers: the frames compared that lie far off the rest
            (:func:`~.verdict_notes.outliers`).
        excluded: how many frames ``exclude_outliers`` left out (0: none).
            ``outliers["indices"]``: theirs among the measured file's samples.
        judgement: the verdict (:class:`~.measured_verdict.Judgement`), set by :func:`verify`.
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
    frame: Frames
    offsets: np.ndarray
    removed: list
    searched_s: tuple = (0.0, 0.0)
    max_latency_s: float = MAX_LATENCY_S
    uncompared: dict = field(default_factory=dict)
    pauses: tuple = ()
    outliers: dict = field(default_factory=dict)
    excluded: int = 0
    judgement: Any = None
    learn_cycles: int = 0
    scale: float = 1.0
    learned_from: str = ""
    wall_s: float = 0.0
    #: The figure's name of the curve beside the reference's.
    curve_label: ClassVar[str] = "measured"

    @property
    def learning(self) -> str:
        """The report title's words on the run: what measured it."""
        by = {"encoders": "the encoders", "carriage": "the surrogate servo's encoder"}
        name = Path(self.measured.path).name
        return f"measured by {by.get(self.measured.kind, 'the tracker')}, {name}"

    def resolution(self) -> tuple[float, float]:
        """(0, 0): the measured pose's resolution is the instrument's, not known here."""
        return (0.0, 0.0)

    @property
    def tolerance(self) -> tuple[float, float]:
        """(m, rad) the tolerance its verdict was judged at (:attr:`judgement`'s)."""
        return self.judgement.tolerance


def _samples(
    t: np.ndarray, max_gap_s: float, pauses: bool = False, pausable: bool = True
) -> tuple[str, tuple]:
    """(the words on the samples' steps, "" when even to :data:`MAX_JITTER`; the pauses, ((t
    of the file before it, s; its length, s), ...)): the samples are judged at their own times,
    never resampled (an interpolation between two noisy samples halves their noise and
    flatters the figures). With ``pauses`` a step longer than ``max_gap_s`` is a planned pause
    (between imaging arcs): the stretches either side are segments of one run, each judged at
    its own samples' times, nothing bridged; the steps' words are then of the steps within the
    segments. ``pausable``: whether the command takes ``--measured-pauses`` (its refusal
    names it).

    Raises:
        InvalidConfigError: without ``pauses``, a step longer than ``max_gap_s`` (the tracker
            lost the marker, or a planned pause), where it is named.
    """
    steps = np.diff(t)
    k = int(np.argmax(steps))
    if steps[k] > max_gap_s and not pauses:
        raise InvalidConfigError(
            f"the measured samples stop for {seconds(float(steps[k]))} after t = "
            f"{t[k]:.6g} s of the file, longer than --measured-max-gap {seconds(max_gap_s)}: "
            "verify compares measured samples only. "
            + (
                "A planned pause (between imaging arcs)? give --measured-pauses to judge the "
                "stretches either side as segments of one run, nothing bridged. "
                if pausable
                else ""
            )
            + "The tracker lost the marker? cut the file to a stretch without it"
        )
    long = np.flatnonzero(steps > max_gap_s)
    found = tuple((float(t[j]), float(steps[j])) for j in long)
    steps = np.delete(steps, long)
    if steps.size == 0:
        return "", found
    dt = float(np.median(steps))
    if np.max(np.abs(steps - dt)) <= MAX_JITTER * dt:
        return "", found
    return (
        f"the samples' steps range {steps.min() * 1e3:.4g}-{steps.max() * 1e3:.4g} ms "
        f"(median {dt * 1e3:.4g} ms): each is judged at its own time, nothing resampled"
    ), found


def judged_window(ver) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(t, x, x_d) of a :class:`Verification` over the window it judged: the reference's times
    (n,) s, the measured poses (n, 6) (the axes not measured the reference's) and the
    reference's (n, 6)."""
    t, x, x_d = ver.result.t, ver.result.x, ver.result.x_d
    w0, w1 = ver.fidelity["window_s"]
    m = (t >= w0 - 1e-9) & (t <= w1 + 1e-9)
    return t[m], np.where(np.isfinite(x[m]), x[m], x_d[m]), x_d[m]


def _not_measured(fid: dict, measured: np.ndarray, t, x, x_d) -> dict:
    """``fid`` with the figures of the axes not measured NaN (their harmonics and lags left out;
    the lag of the whole motion from the measured axes; the 3-D figures of rotation or
    translation NaN when none of its axes is measured, else over the axes measured), and
    ``measured`` naming the others."""
    off = [k for k in range(6) if not measured[k]]
    if not off:
        return {**fid, "measured": list(AXES)}
    fid = dict(fid)
    for key in ("rms", "peak", "rms_fraction", "peak_fraction"):
        fid[key] = [math.nan if k in off else v for k, v in enumerate(fid[key])]
    cycles = dict(fid["cycles"])
    per_axis = cycles.get("rms", [])  # each cycle's per-axis RMS
    cycles["rms"] = [[math.nan if k in off else v for k, v in enumerate(c)] for c in per_axis]
    if not np.any(measured[:3]):
        fid["rms_rotation_rad"] = fid["peak_rotation_rad"] = math.nan
        cycles["rms_rotation_rad"] = [math.nan] * len(cycles["rms_rotation_rad"])
    if not np.any(measured[3:]):
        fid["rms_translation_m"] = fid["peak_translation_m"] = math.nan
        for key in ("rms_translation_m", "peak_translation_m"):
            cycles[key] = [math.nan] * len(cycles[key])
    fid["cycles"] = cycles
    fid["lag_s"] = {a: v for a, v in fid["lag_s"].items() if measured[AXES.index(a)]}
    fid["harmonics"] = [h for h in fid["harmonics"] if measured[AXES.index(h["axis"])]]
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
    frame: str = "axes",
    registration=None,
    max_latency_s: float = MAX_LATENCY_S,
    tolerance: tuple[float, float] = DEFAULT_TOLERANCE,
    max_gap_s: float = MAX_GAP_S,
    pauses: bool = False,
    exclude_outliers: bool = False,
    action_level: tuple[float, float] | None = None,
    _whole: bool = True,
    _excluded: int = 0,
) -> Verification:
    """Judge a measured motion against the reference it was asked to follow (module docstring).

    Args:
        reference: the motion asked for (:class:`~stewart_drake.references.motion.Reference`).
        measured: the motion measured (:func:`~.measured_motion.read_measured`,
            :func:`~.measured_motion.encoder_motion`).
        clock_offset_s: s, the measured time + this is the reference's (None: not known; the
            encoder log is on the reference's clock, 0).
        frame: "axes" (each measured axis is the base frame's axis its column names, with its
            constant offset removed) or "base" (the poses are the platform's in the base frame
            already; nothing removed); ignored for the encoder log.
        registration: the tracker's frames registered to the robot
            (:class:`~stewart_drake.calibration.registration.Registration`: ``X_TB``,
            ``X_PM``, ``base_poses``, ``words``), or None; replaces ``frame``. It needs the
            marker's X, Y and Z, and its three rotations or none.
        max_latency_s: the largest latency that passes when the clocks' relation is known, s;
            latencies up to :data:`SEARCH_FACTOR` times it (at most 0.45 of a periodic
            reference's period) are searched, so that one beyond it is found and fails.
        tolerance: (m, rad) the RMS error per axis that passes (the judgement's).
        max_gap_s: the longest step between two measured samples judged across, s: the
            samples are judged at their own times, nothing interpolated between them.
        pauses: a longer step is a planned pause: the stretches either side are judged as
            segments of one run (each sample at its own time, nothing bridged), and the
            verdict line names the pauses; without, such a step is refused.
        exclude_outliers: judge without the frames far off the rest
            (:func:`~.verdict_notes.outliers`, found on the clock of the whole recording):
            they are left out of the file and it is judged again, its line saying how many;
            without, the line names them and the verdict of the rest.
        action_level: (m, rad) the RMS error per axis beyond which a PASS is ACTION
            (:func:`~.verdict_levels.axis_levels`), or None.
    Returns:
        :class:`Verification`, its ``judgement`` the verdict with its causes.
    Raises:
        InvalidConfigError: a frame that is neither "axes" nor "base"; a registration for a
            file without the marker's X, Y and Z; a file none of whose axes the reference moves
            along; a step between samples longer than ``max_gap_s`` (without ``pauses``); a
            recording not one whole
            cycle of the reference long (or a breath, without cycles), before or after the
            alignment; no overlap with the reference once aligned; a clock offset not within
            +-:data:`MAX_CLOCK_OFFSET_S`; the measured motion beyond
            :data:`MAX_REFERENCE_TIME_S` on the reference's clock.
    """
    if frame not in ("axes", "base"):
        raise InvalidConfigError(f"frame must be 'axes' or 'base', got {frame!r}")
    if clock_offset_s is not None and not abs(clock_offset_s) <= MAX_CLOCK_OFFSET_S:
        raise InvalidConfigError(
            f"the clock offset must be a number within +-{MAX_CLOCK_OFFSET_S:g} s (a tracker "
            f"counting seconds since 1970 is 1.7e9 s off), got {clock_offset_s}"
        )
    t, y = measured.t, np.array(measured.poses, dtype=float)
    options = dict(frame=frame, registration=registration, max_latency_s=max_latency_s)
    options.update(tolerance=tolerance, max_gap_s=max_gap_s, pauses=pauses)
    options.update(action_level=action_level)
    if clock_offset_s is not None:
        check_reference_time(float(t[0] + clock_offset_s), float(t[-1] + clock_offset_s))
    seen = measured.measured.copy()
    clock_offset_s, clock, frames, y = _clock_and_frames(
        measured, y, frame, registration, clock_offset_s
    )
    resampled, paused = _samples(t, max_gap_s, pauses)
    check_length(reference, t)
    # The search runs on the file's times less its first, so that a clock counting from 1970
    # (1.7e9 s) keeps its digits: D, the reference's time at the file's first sample, is the
    # shift d plus that first time.
    t_first = float(t[0])
    t_rel = t - t_first
    (lo, hi), whole = search_range(reference, t, clock_offset_s, max_latency_s, _whole)
    step = max(COARSE_STEP_S, float(np.median(np.diff(t))))
    D = _searched_shift(reference, t_rel, y, seen, frames, (lo + t_first, hi + t_first), step)
    offsets = frames.removes_offsets
    d = D - t_first
    keep = overlap(reference, t_rel + D, 0.0)
    t_ref = t_rel[keep] + D
    check_reference_time(float(t_ref[0]), float(t_ref[-1]))
    x_d = reference_poses(reference, t_ref)
    x = platform_poses(frames, y[keep], x_d)
    (w0, w1), starts, holds_start = cycle_window(reference, float(t_ref[0]), float(t_ref[-1]))
    removed = np.zeros(6)
    if offsets:
        inside = (t_ref >= w0 - 1e-9) & (t_ref <= w1 + 1e-9)
        removed[seen] = np.mean(x[inside][:, seen] - x_d[inside][:, seen], axis=0)
        x = x - removed
    x_fid = np.where(np.isfinite(x), x, x_d)  # the axes not measured compare to themselves
    fid = fidelity(t_ref, x_fid, x_d, (w0, w1), _frequencies(reference), starts)
    _check_judgeable(reference, fid, seen, measured)
    x_start = np.where(np.isfinite(x), x, x_d)
    if not measured.rotations_measured:
        x_start[:, :3] = np.nan
    offset = 0.0 if clock_offset_s is None else float(clock_offset_s)
    latency = (offset + t_first) - D  # offset - d, without d's large digits
    # Over every frame compared, the start-up's too: an outlier there moves the clock as much.
    far = outliers(x_fid, x_d, seen, tolerance, frames.removes_offsets)
    far["indices"] = np.flatnonzero(keep)[far.pop("mask")]
    ver = Verification(
        name=getattr(reference, "name", "reference"),
        reference=reference,
        measured=measured,
        result=MeasuredRun(t_ref, x, x_d),
        cycle_starts=starts,
        fidelity=_not_measured(fid, seen, t_ref, x_fid, x_d),
        startup=startup_figures(t_ref, x_start, x_d, w0 if holds_start else float(t_ref[0])),
        shift_s=d,
        clock_offset_s=offset,
        clock=clock,
        latency_s=latency,
        frame=frames,
        offsets=removed,
        removed=_removed_words(d, offset, latency, clock, frames, removed, seen, resampled)
        + outside_words(t_rel + D, t_ref, (w0, w1), holds_start),
        searched_s=(lo, hi),
        max_latency_s=max_latency_s,
        uncompared=uncompared(t_rel + D, t_ref, whole, reference),
        pauses=paused,
        outliers=far,
        excluded=_excluded,
    )
    if exclude_outliers and ver.outliers["frames"]:
        return _without_outliers(ver, reference, measured, clock_offset_s, options, _whole)
    ver.judgement = judge(ver, tolerance, action_level)
    if _whole and clock == "not known" and ver.judgement.verdict == "FAIL":
        return _best_part(ver, reference, measured, options)
    return ver


def _clock_and_frames(measured, y, frame: str, registration, clock_offset_s):
    """(the clock offset, s or None, the clock's words, the :class:`~.alignment.Frames`, the
    measured poses (n, 6) in them) of a measured motion: the encoder log's own clock and
    frames, else the clock given or not known and the frames asked for (a registration's
    mapping the tracker's poses into the base frame)."""
    if measured.from_the_robot:
        clock_offset_s, clock = 0.0, "the encoder log's t_path is the reference's own clock"
        # The carriage's s is about the stage's mid-travel: its offset removed, as a camera's.
        encoders = measured.kind == "encoders"
        frames = Frames("encoders") if encoders else Frames("axes", note=CARRIAGE)
    else:
        clock = "given (--clock-offset)" if clock_offset_s is not None else "not known"
        frames = Frames(frame) if registration is None else _registered(registration, measured)
    if frames.how == "registration":
        if measured.rotations_measured:
            y = np.asarray(registration.base_poses(y), dtype=float)
        else:
            y[:, 3:] = y[:, 3:] @ frames.R_BT.T + frames.p_BT
    return clock_offset_s, clock, frames, y


def _searched_shift(reference, t_rel, y, seen, frames, bounds, step: float) -> float:
    """D, s: the reference's time at the measured file's first sample, searched within
    ``bounds`` (s) on the file's times less its first (``t_rel``): coarse at ``step`` (s, the
    file's own sample period or :data:`COARSE_STEP_S`), then refined where
    the shifted file overlaps the reference. The clock is searched with each axis's constant
    offset removed, whatever the frames: an offset (a phantom set down off its place) would
    otherwise pull the shift towards where the reference's mean over the window comes nearest
    it. The offset is judged on its own."""
    weights = axis_weights(seen)

    def shown(times):
        return reference_seen(frames, reference, times)

    D0 = coarse_shift(t_rel, y, weights, shown, bounds, step, True)
    use = overlap(reference, t_rel + D0, step)
    return refine_shift(t_rel[use], y[use], weights, shown, D0, step, True)


def _without_outliers(ver, reference, measured, clock_offset_s, options, whole):
    """``ver`` judged again without its outliers: those measured frames left out of the file,
    on the same options, the count said on its line."""
    from dataclasses import replace

    drop = np.zeros(len(measured.t), dtype=bool)
    drop[ver.outliers["indices"]] = True
    kept = replace(measured, t=measured.t[~drop], poses=np.asarray(measured.poses)[~drop])
    return verify(
        reference, kept, clock_offset_s, _whole=whole, _excluded=int(drop.sum()), **options
    )


def _best_part(ver: Verification, reference: Reference, measured, options: dict):
    """A FAIL of the whole recording, the clocks not known, against the best match that may
    leave part of it out (:func:`search_range` not ``whole``): a recording whose tracker started
    well before the motion (a lead-in at rest) matches one cycle off when compared whole. That
    match is the verdict when it leaves at most
    :data:`~.verdict_notes.MAX_UNCOMPARED_SHARE` out (its line says what); else the FAIL
    stands, and when the part would pass what it compares, it says so: a robot that stopped and
    a recording that runs on past the motion's end look alike without the clock."""
    try:
        part = verify(reference, measured, _whole=False, **options)
    except InvalidConfigError:
        return ver
    left, too_much = uncompared_words(part.uncompared)
    if not too_much:
        return part
    if part.judgement.causes:
        return ver
    note = (
        f"a part of it matches, leaving {left.replace(' not compared', '')} out: a robot that "
        "stopped, or a recording that runs on past the motion? give --clock-offset (the "
        "measured time + it = the reference's) to judge it on a known clock, or cut the file "
        "to the motion's span"
    )
    ver.judgement.causes.append(note)
    ver.judgement.line += f"; {note}"
    return ver


def _check_judgeable(reference: Reference, fid: dict, seen, measured: MeasuredMotion) -> None:
    """Refuse a file none of whose axes the reference moves along: at rest or moving, the
    phantom would pass alike.

    Raises:
        InvalidConfigError: no measured axis among those the reference moves along.
    """
    if not any(seen[AXES.index(a)] for a in fid["moving"]):
        axes = ", ".join(a for a, m in zip(AXES, seen) if m)
        raise InvalidConfigError(
            f"{measured.path} measures {axes}, along which "
            f"{getattr(reference, 'name', 'the reference')} does not move (it moves "
            f"{', '.join(fid['moving']) or 'along no axis'}): nothing of the motion can be "
            "judged; measure along an axis it moves"
        )


def _registered(registration, measured: MeasuredMotion) -> Frames:
    """The :class:`~.alignment.Frames` of a registration for ``measured``: its marker's X, Y
    and Z needed (and its three rotations or none); a 6-DoF marker's poses are mapped whole
    (the frames' own fields stay the identity).

    Raises:
        InvalidConfigError: a file without the marker's X, Y and Z, or with some rotations but
            not three.
    """
    if not np.all(measured.measured[3:]) or (
        np.any(measured.measured[:3]) and not measured.rotations_measured
    ):
        axes = ", ".join(a for a, m in zip(AXES, measured.measured) if m)
        raise InvalidConfigError(
            f"{measured.path}: a registration maps a tracker's marker (its X, Y and Z, and its "
            f"three rotations or none) to the platform; this file measures {axes}: judge it "
            "without --registration, each axis as the base frame's (--frame axes)"
        )
    if measured.rotations_measured:
        return Frames("registration", note=registration.words())
    return registered_frames(registration)


def _frequencies(reference: Reference) -> dict:
    """The fundamentals of a reference that repeats ({} for one that does not)."""
    repeats = getattr(reference, "repeat_period_s", None) is not None
    frequencies = getattr(reference, "frequencies_hz", None)
    return frequencies() if repeats and callable(frequencies) else {}


def _removed_words(d, offset, latency, clock, frames: Frames, removed, seen, resampled) -> list:
    """The report's lines on what the alignment removed: the clock, the frames (and the
    offsets ``removed`` (6,) of the ``seen`` (6,) axes), any resampling."""
    clock_line = (
        f"the clock: the measured motion shifted by {d:+.6g} s onto the reference's clock (the "
        f"shift of least distance, by FFT, then to a fraction of a sample)"
    )
    if clock == "not known":
        clock_line += (
            f". The clocks' relation was not given, so the whole shift is reported as the "
            f"latency ({seconds(latency)}) with clock offset 0 and is not judged: it holds any "
            f"offset of the tracker's clock; give --clock-offset S (the measured time + S = the "
            f"reference's) to separate the phantom's own lag and judge it"
        )
    else:
        clock_line += (
            f": the clock offset {offset:+.6g} s ({clock}) less the latency, {seconds(latency)} "
            f"(> 0: the phantom late)"
        )
    lines = [clock_line, f"the frames: {frames.words(removed, seen)}"]
    if resampled:
        lines.append(resampled)
    return lines


__all__ = [
    "MAX_LATENCY_S",
    "SEARCH_FACTOR",
    "DEFAULT_TOLERANCE",
    "MAX_SEARCH_S",
    "MIN_SPAN_S",
    "CYCLE_SLACK",
    "COARSE_STEP_S",
    "MAX_JITTER",
    "MAX_GAP_S",
    "MAX_CLOCK_OFFSET_S",
    "MAX_REFERENCE_TIME_S",
    "MeasuredRun",
    "Verification",
    "judged_window",
    "seconds",
    "verify",
]
