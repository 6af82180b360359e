"""An internal target and its external surrogate measured on one clock, judged together
(``stewart-drake verify INTERNAL --surrogate EXTERNAL --measured INTERNAL_MEAS
--measured-surrogate EXTERNAL_MEAS``): each motion's fidelity, as ``verify`` gives it alone, and
their **relative latency**, as measured against as asked.

**The relative latency.** Motion management infers the target from the surrogate, so what counts
is whether the phantom keeps the two in the relation the pair was recorded with (the external
leading or lagging the internal by its own 0.4-1.8 s, IntERAct's traces), not each one's delay
from its command. Each measurement is put on its reference's clock by ``verify``'s own clock
search (:mod:`~stewart_drake.organ_motion.alignment`: the shift d with the measured time + d the
reference's time whose pose a sample shows, nothing fitted but the clock and a constant per
measured axis). With the two measurements on one clock (one camera seeing both platforms, or two
instruments sharing a clock) and the two references on one clock (the recorded pair, both from
t = 0), the relative latency is

    tau_rel = latency_internal - latency_surrogate = d_surrogate - d_internal   (s)

in which the clocks' offset cancels: it is judged whether or not ``--clock-offset`` is given.
tau_rel > 0: the internal target late against the surrogate (the surrogate early); tau_rel < 0:
the surrogate late. Its asked value is 0: the pair's own lead is in the two references, and
tau_rel is how far the measured pair departs from it. The convention is IntERAct's (Kaczynska et
al. 2026, ``RMSEAlignMethod.m``: ``latency = shift6D - shift1D``, each shift the delay of a
measured motion behind its command).

**How it is found** (:func:`verify_pair`): the internal motion by
:func:`~stewart_drake.organ_motion.verification.verify`, as ``verify`` alone judges it (its
frames, its clock); the surrogate's shift then searched on the internal's clock, within
:data:`RELATIVE_SEARCH_S` (or :data:`~stewart_drake.organ_motion.verification.SEARCH_FACTOR`
times the bound, if wider; at most 0.45 of a periodic surrogate's period, so a breath earlier or
later is never taken) of d_internal, by the same search (FFT over every shift on a grid, then to a
fraction of a sample: :func:`relative_shift`). The surrogate's own fidelity is verify's on its
own (its offset removed on the one axis it moves, ``frame="axes"``).

**What is read** (:func:`cmd_verify_pair`): two files of one camera or tracker on its own clock,
each read as ``verify`` reads a tracker's file; or the robot's encoder log for both
(:func:`read_encoder_pair`: the platform by forward kinematics, the surrogate's carriage ``s``
as its servo's encoder read it, both on the log's ``t_path``). The surrogate's reference is its
recorded trace, or a library motion's external signal made by a correlation model as
``reproduce --surrogate model`` makes it (:func:`~.external_reference.model_reference`).

**The verdict** (:func:`judge_relative`) PASSes when |tau_rel| is within
``max_relative_latency_s`` (:data:`MAX_RELATIVE_LATENCY_S`) and both motions follow their
references (else the latency means nothing); a FAIL names its cause: a motion at rest, reversed,
of another period or not following its reference (another motion), the two measurements swapped,
the relative latency beyond its bound (and which one is late), or at the edge of the search.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from functools import partial
from pathlib import Path
from typing import Any

import numpy as np

from ..base.errors import InvalidConfigError
from ..base.tables import markdown_lines
from ..organ_motion.fidelity import AXES, MOVING_P2P
from ..organ_motion.measured_verdict import (
    AT_REST_SHARE,
    EDGE_S,
    FOLLOWS_CORRELATION,
    PERIOD_SHARE,
    axis_figures,
    reversed_match,
    seconds,
)

#: The largest |relative latency| that passes unless given, s. IntERAct's authors claim their two
#: platforms synchronised "within 0.1 s" (Kaczynska et al. 2026), and AAPM TG-142 (Klein et al.
#: 2009, Table V) asks a respiratory-gated beam's temporal accuracy of 100 ms: a surrogate 0.1 s
#: off its target moves the inferred target by 0.1 s times the breath's speed, 0.8 mm at the peak
#: of a 10 mm, 4 s breath.
MAX_RELATIVE_LATENCY_S = 0.1
#: Relative latencies up to this, s, are searched either way (or
#: :data:`~stewart_drake.organ_motion.verification.SEARCH_FACTOR` times the bound, if wider): a
#: relative latency beyond the bound is found and fails rather than hidden at the edge; below half
#: a breath (about 4 s), so that a breath earlier or later is not matched.
RELATIVE_SEARCH_S = 1.5
#: A measured axis whose sign reversed matches its reference this many times better (least mean
#: squared distance, at its best shift) runs the wrong way (as
#: :func:`~stewart_drake.organ_motion.measured_verdict.causes_of` says it).
REVERSED_RATIO = 0.25
#: Two measurements are swapped when each matches the other's reference this many times better
#: (least mean squared distance, each less its mean) than its own.
SWAPPED_RATIO = 0.25
#: Shifts searched around the internal's for the swap's test, s either way.
SWAP_SEARCH_S = 5.0


@dataclass
class RelativeJudgement:
    """The verdict on the relative latency (module docstring).

    Attributes:
        passed: the verdict. line: it in one line: PASS or FAIL, what was compared, the relative
            latency and its bound, and the causes of a FAIL.
        relative_latency_s: tau_rel, s (> 0: the internal target late against the surrogate).
        max_relative_latency_s: the bound, s. meaningful: whether both motions follow their
            references (else tau_rel means nothing). at_edge: tau_rel found at the edge of the
            shifts searched (it is at least that).
        causes: why it fails, one phrase each (empty when it passes).
    """

    passed: bool
    line: str
    relative_latency_s: float
    max_relative_latency_s: float
    meaningful: bool
    at_edge: bool
    causes: list = field(default_factory=list)

    def as_dict(self) -> dict:
        """The judgement as JSON values."""
        return {
            "passed": self.passed,
            "line": self.line,
            "relative_latency_s": self.relative_latency_s,
            "max_relative_latency_s": self.max_relative_latency_s,
            "meaningful": self.meaningful,
            "at_edge": self.at_edge,
            "causes": list(self.causes),
        }


@dataclass
class PairVerification:
    """An internal motion and its surrogate measured on one clock, judged (:func:`verify_pair`).

    Attributes:
        internal, surrogate: each motion's
            :class:`~stewart_drake.organ_motion.verification.Verification`, as ``verify`` judges
            it alone (its figures, its verdict, its latency).
        relative_latency_s: tau_rel = d_surrogate - d_internal, s (module docstring).
        surrogate_shift_s: d_surrogate, the surrogate's shift found on the internal's clock, s
            (the measured time + it = the surrogate reference's time). internal_shift_s:
            d_internal, s.
        searched_s: (lo, hi) the relative latencies searched, s.
        notes: what the report adds in words (the surrogate's own shift when it departs from
            the pair's).
        judgement: the relative latency's verdict (:class:`RelativeJudgement`).
    """

    internal: Any
    surrogate: Any
    relative_latency_s: float
    surrogate_shift_s: float
    internal_shift_s: float
    searched_s: tuple
    notes: list
    judgement: RelativeJudgement

    @property
    def passed(self) -> bool:
        """The relative latency within its bound and neither fidelity FAILing: a fidelity that
        cannot be judged at the tolerance (a motion that moves less than it, CANNOT JUDGE) is
        said beside, and does not stop the pair's timing from being judged."""
        fidelities = all(ver.judgement.verdict != "FAIL" for ver in (self.internal, self.surrogate))
        return bool(fidelities and self.judgement.passed)

    def as_dict(self) -> dict:
        """The pair's figures as JSON values: the verdicts, the relative latency with its
        definition, each motion's file, shift, latency, RMS error and verdict line."""

        def one(ver) -> dict:
            return {
                "reference": ver.name,
                "measured": ver.measured.path,
                "axes": ver.fidelity["measured"],
                "shift_s": ver.shift_s,
                "latency_s": ver.latency_s,
                "clock": ver.clock,
                "rms": [None if math.isnan(v) else v for v in ver.fidelity["rms"]],
                "window_s": list(ver.fidelity["window_s"]),
                "verdict": ver.judgement.verdict,
                "passed": ver.judgement.passed,
                "line": ver.judgement.line,
            }

        return {
            "passed": self.passed,
            "relative_latency_s": self.relative_latency_s,
            "definition": DEFINITION,
            "internal_shift_s": self.internal_shift_s,
            "surrogate_shift_s": self.surrogate_shift_s,
            "searched_s": list(self.searched_s),
            "relative": self.judgement.as_dict(),
            "internal": one(self.internal),
            "surrogate": one(self.surrogate),
            "notes": list(self.notes),
        }


#: The relative latency's definition and sign, in the report's words.
DEFINITION = (
    "relative latency = the internal target's latency - the surrogate's = d_surrogate - "
    "d_internal, each d the shift that puts its measured motion on its reference's clock (the "
    "measured time + d = the reference's); > 0: the internal target late against the surrogate; "
    "the clocks' offset cancels"
)


# -- the search ------------------------------------------------------------------------------------


def search_half_width(reference, max_relative_latency_s: float) -> float:
    """The relative latencies searched either way, s: :data:`RELATIVE_SEARCH_S`, or
    :data:`~stewart_drake.organ_motion.verification.SEARCH_FACTOR` times the bound if wider; at
    most 0.45 of the surrogate reference's period when it repeats."""
    from ..organ_motion.verification import SEARCH_FACTOR

    width = max(RELATIVE_SEARCH_S, SEARCH_FACTOR * max_relative_latency_s)
    period = getattr(reference, "repeat_period_s", None)
    return min(width, 0.45 * period) if period else width


def relative_shift(reference, measured, around_s: float, half_width_s: float) -> float:
    """The shift d (s; the measured time + d = the reference's time) of least distance between
    the measured axes and the reference's, each less its mean difference (``verify``'s frames
    "axes"), within ``around_s`` +- ``half_width_s``: the package's one lag search
    (:func:`~stewart_drake.base.lag.best_shift`, as ``verify``'s clock): coarsely over every
    shift by FFT, then to a fraction of a sample on the samples inside the reference's span.

    Args:
        reference: the surrogate's reference. measured: its
            :class:`~stewart_drake.organ_motion.measured_motion.MeasuredMotion`.
        around_s, half_width_s: s.
    """
    from ..base.lag import best_shift
    from ..organ_motion.alignment import Frames, axis_weights, reference_seen
    from ..organ_motion.verification import COARSE_STEP_S

    t, y = measured.t, np.asarray(measured.poses, dtype=float)
    frames = Frames("axes")
    weights = axis_weights(measured.measured)
    step = max(COARSE_STEP_S, float(np.median(np.diff(t))))
    end = getattr(reference, "end_time", None)

    def seen(times):
        return reference_seen(frames, reference, times)

    def inside(d0: float) -> np.ndarray:
        t_ref = t + d0
        use = (t_ref >= 0.0) & (t_ref <= (math.inf if end is None else float(end)))
        return use if np.count_nonzero(use) >= 10 else np.ones(len(t), dtype=bool)

    bounds = (around_s - half_width_s, around_s + half_width_s)
    return best_shift(t, y, weights, seen, bounds, step, True, inside)


# -- whether a motion follows its reference --------------------------------------------------------


def _window(ver) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(t, x, x_d) of a verification over its window: the reference's times (n,) s, the
    measured poses (n, 6) (the axes not measured the reference's) and the reference's (n, 6)."""
    t, x, x_d = ver.result.t, ver.result.x, ver.result.x_d
    w0, w1 = ver.fidelity["window_s"]
    m = (t >= w0 - 1e-9) & (t <= w1 + 1e-9)
    return t[m], np.where(np.isfinite(x[m]), x[m], x_d[m]), x_d[m]


def _at_shift(reference, measured, d: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(t, x, x_d) of ``measured`` put on ``reference``'s clock by the shift d (s), over the
    samples inside the reference's span, each measured axis less its mean difference."""
    from ..organ_motion.alignment import reference_poses

    t_ref = measured.t + d
    end = getattr(reference, "end_time", None)
    keep = (t_ref >= 0.0) & (t_ref <= (math.inf if end is None else float(end)))
    if np.count_nonzero(keep) < 10:
        keep = np.ones(len(t_ref), dtype=bool)
    t_ref = t_ref[keep]
    x_d = reference_poses(reference, t_ref)
    x = np.array(measured.poses[keep], dtype=float)
    seen = np.asarray(measured.measured, dtype=bool)
    x[:, seen] -= np.mean(x[:, seen] - x_d[:, seen], axis=0)
    return t_ref, np.where(np.isfinite(x), x, x_d), x_d


def why_not_following(reference, t, x, x_d, measured) -> str | None:
    """None when the measured motion follows its reference (so that its clock means something),
    else why not, in words: at rest (every measured axis along which the reference moves moved
    less than :data:`~stewart_drake.organ_motion.measured_verdict.AT_REST_SHARE` of it, RMS, as
    ``verify``'s verdict says it: against the reference's own motion, not the tolerance),
    reversed
    (an axis's correlation below -:data:`~stewart_drake.organ_motion.measured_verdict.
    FOLLOWS_CORRELATION`, or its sign reversed matching :data:`REVERSED_RATIO` times better at
    another shift), another period, or not following (correlation within
    +-:data:`~stewart_drake.organ_motion.measured_verdict.FOLLOWS_CORRELATION`). A scale or a
    shape error does not stop the clock meaning something: the fidelity's verdict judges those.

    Args:
        reference: the reference. t: (n,) s, the reference's clock. x, x_d: (n, 6) the aligned
            measured poses and the reference's. measured: (6,) bool.
    """
    measured = np.asarray(measured, dtype=bool)
    moving = np.ptp(x_d, axis=0) > np.asarray(MOVING_P2P)
    axes = [int(k) for k in np.flatnonzero(measured & moving)]
    if not axes:
        return "moves along no axis measured"
    f = axis_figures(t, x, x_d, measured)
    if all(f[AXES[k]]["motion_rms"] < AT_REST_SHARE * f[AXES[k]]["reference_rms"] for k in axes):
        moved = ", ".join(
            f"{AXES[k]} {f[AXES[k]]['motion_rms'] * 1e3:.3g} mm RMS against its reference's "
            f"{f[AXES[k]]['reference_rms'] * 1e3:.3g} mm"
            if k >= 3
            else f"{AXES[k]} {math.degrees(f[AXES[k]]['motion_rms']):.3g} deg RMS"
            for k in axes
        )
        return f"did not move ({moved})"
    period = getattr(reference, "repeat_period_s", None) or 4.0
    for k in axes:
        fk = f[AXES[k]]
        rho = fk["correlation"]
        if rho < -FOLLOWS_CORRELATION:
            return f"runs the wrong way on {AXES[k]} (correlation {rho:+.2f} with its reference)"
        ratio, _ = reversed_match(t, x[:, k], k, reference, min(0.5 * period, 2.0))
        if ratio < REVERSED_RATIO:
            better = f"{1 / ratio:.0f} times better" if ratio > 0 else "exactly"
            return (
                f"runs the wrong way on {AXES[k]} (reversed, it matches its reference {better}): "
                "a sign flipped or the axis reversed"
            )
        own, ref = fk["period_s"], fk["reference_period_s"]
        if math.isfinite(own) and math.isfinite(ref) and abs(own / ref - 1.0) > PERIOD_SHARE:
            return (
                f"repeats every {own:.3g} s on {AXES[k]} where its reference does every {ref:.3g} s"
            )
        if not rho > FOLLOWS_CORRELATION:
            return (
                f"does not follow its reference on {AXES[k]} (correlation {rho:+.2f}): another "
                "motion, or noise"
            )
    return None


# -- swapped files ---------------------------------------------------------------------------------


def _principal_axis(measured, reference, t_ref) -> int | None:
    """The measured axis along which the reference moves most (by its RMS, a rotation
    weighted as verify's clock weighs it), or None."""
    from ..organ_motion.alignment import axis_weights, reference_poses

    x_d = reference_poses(reference, t_ref)
    spread = np.std(x_d, axis=0) * axis_weights(measured)
    spread[np.ptp(x_d, axis=0) <= np.asarray(MOVING_P2P)] = 0.0
    return int(np.argmax(spread)) if np.any(spread > 0) else None


def _best_match(t, v, reference, j: int, shifts: tuple, step: float) -> tuple[float, float]:
    """(the least mean squared distance, each less its mean, between v (n,) at the times t (n,)
    and the reference's axis j over the ``shifts`` (lo, hi) s, in v's units squared; the shift
    where it is, s) (:func:`~stewart_drake.organ_motion.alignment.shift_scores`)."""
    from ..organ_motion.alignment import reference_poses, shift_scores

    y = np.zeros((len(t), 6))
    y[:, 0] = v
    weights = np.zeros(6)
    weights[0] = 1.0

    def seen(times):
        r = np.zeros((len(times), 6))
        r[:, 0] = reference_poses(reference, times)[:, j]
        return r

    d, score = shift_scores(t, y, weights, seen, shifts, step, True)
    k = int(np.argmin(score))
    return max(float(score[k]), 0.0), float(d[k])


def swapped_words(
    pair_refs, pair_measured, around_s: float, relative_latency_s: float
) -> str | None:
    """The cause when the two measurements are swapped, else None. Each measurement is matched
    (its axis along which its reference moves most, at its best shift within
    :data:`SWAP_SEARCH_S` of ``around_s``, each less its mean) to its own reference and to the
    other's; swapped when each matches the other's reference :data:`SWAPPED_RATIO` times better,
    or when each matches the other's at least as well and, exchanged, the pair's relative
    latency is smaller than as given. Looked for on every pair, a PASS included: a bound on the
    relative latency wide enough to hold a swapped pair's would pass it otherwise.

    Args:
        pair_refs: (internal reference, surrogate reference). pair_measured: (internal
            measured, surrogate measured) (:class:`~stewart_drake.organ_motion.measured_motion.
            MeasuredMotion`). around_s: the internal's shift, s. relative_latency_s: as given,
            s.
    """
    from ..organ_motion.verification import COARSE_STEP_S

    axes = []
    for ref, m in zip(pair_refs, pair_measured):
        k = _principal_axis(m.measured, ref, m.t + around_s)
        if k is None:
            return None
        axes.append(k)
    ratios, crossed = [], []
    for own in (0, 1):
        m = pair_measured[own]
        step = max(COARSE_STEP_S, float(np.median(np.diff(m.t))))
        shifts = (around_s - SWAP_SEARCH_S, around_s + SWAP_SEARCH_S)
        v = np.asarray(m.poses[:, axes[own]], dtype=float)
        mine, _ = _best_match(m.t, v, pair_refs[own], axes[own], shifts, step)
        theirs, d = _best_match(m.t, v, pair_refs[1 - own], axes[1 - own], shifts, step)
        ratios.append(math.inf if theirs <= 0 else mine / theirs)
        crossed.append(d)
    exchanged = crossed[0] - crossed[1]  # the surrogate's reference's shift less the internal's
    strong = all(r > 1.0 / SWAPPED_RATIO for r in ratios)
    in_sync = all(r >= 1.0 for r in ratios) and abs(exchanged) < abs(relative_latency_s)
    if not (strong or in_sync):
        return None
    a, b = (Path(m.path).name for m in pair_measured)
    return (
        f"the two measurements swapped: {a} comes {ratios[0]:.3g} times nearer the surrogate's "
        f"reference than the internal's, and {b} {ratios[1]:.3g} times nearer the internal's "
        f"than the surrogate's (mean squared distances); exchanged, their relative latency is "
        f"{seconds(exchanged)}: give each file to its option"
    )


# -- the verdict -----------------------------------------------------------------------------------


def judge_relative(
    relative_latency_s: float,
    max_relative_latency_s: float,
    half_width_s: float,
    names: tuple[str, str],
    not_following: tuple,
    swapped: str | None,
) -> RelativeJudgement:
    """The relative latency's verdict (module docstring).

    Args:
        relative_latency_s: tau_rel, s. max_relative_latency_s: its bound, s. half_width_s: the
            relative latencies searched either way, s. names: (the internal's measured file, the
            surrogate's), for the line. not_following: (why the internal does not follow its
            reference, why the surrogate does not), each None when it does. swapped: the words
            of :func:`swapped_words`, or None.
    """
    causes = []
    if swapped:
        causes.append(swapped)
    for who, why in zip(("the internal target", "the surrogate"), not_following):
        if why:
            causes.append(f"{who} {why}")
    meaningful = not causes
    at_edge = abs(abs(relative_latency_s) - half_width_s) < EDGE_S
    within = abs(relative_latency_s) <= max_relative_latency_s and not at_edge
    value = f"{'at least ' if at_edge else ''}{seconds(relative_latency_s)}"
    if at_edge:  # past half a breath, a breath earlier or later may match better than the true
        late = "which one is late is not known beyond the relative latencies searched"
    elif relative_latency_s > 0:
        late = "the internal target late against the surrogate"
    else:
        late = "the surrogate late against the internal target"
    if meaningful and not within:
        causes.append(
            f"relative latency {value} beyond --max-relative-latency "
            f"{seconds(max_relative_latency_s)}: {late}"
            + (" (at the edge of the relative latencies searched)" if at_edge else "")
        )
    passed = meaningful and within
    if meaningful:
        figure = (
            f"relative latency {value} ({late}) "
            f"{'within' if within else 'beyond'} +-{seconds(max_relative_latency_s)}"
        )
    else:
        figure = f"relative latency {value} of no meaning while the cause holds"
    line = (
        f"{'PASS' if passed else 'FAIL'}: {names[0]} (internal) against {names[1]} (surrogate) on "
        f"one clock: {figure}" + (f"; cause: {'; '.join(causes)}" if causes else "")
    )
    return RelativeJudgement(
        passed,
        line,
        float(relative_latency_s),
        float(max_relative_latency_s),
        meaningful,
        bool(at_edge),
        causes,
    )


def check_one_clock(internal_measured, surrogate_measured) -> None:
    """Refuse two measurements whose times do not overlap: they cannot be on one clock.

    Raises:
        InvalidConfigError: no overlap, both spans named.
    """
    a0, a1 = float(internal_measured.t[0]), float(internal_measured.t[-1])
    b0, b1 = float(surrogate_measured.t[0]), float(surrogate_measured.t[-1])
    if min(a1, b1) <= max(a0, b0):
        raise InvalidConfigError(
            f"{internal_measured.path} spans t = {a0:.6g}-{a1:.6g} s and "
            f"{surrogate_measured.path} t = {b0:.6g}-{b1:.6g} s: they do not overlap, so they are "
            "not on one clock; give two measurements made together on one clock (one camera "
            "seeing both platforms, or instruments sharing a clock)"
        )


def verify_pair(
    internal_reference,
    surrogate_reference,
    internal_measured,
    surrogate_measured,
    clock_offset_s: float | None = None,
    frame: str = "axes",
    registration=None,
    max_latency_s: float | None = None,
    max_relative_latency_s: float = MAX_RELATIVE_LATENCY_S,
    tolerance: tuple[float, float] | None = None,
    max_gap_s: float | None = None,
) -> PairVerification:
    """Judge an internal motion and its surrogate measured on one clock (module docstring).

    Args:
        internal_reference, surrogate_reference: the two motions asked for, on one clock
            (:class:`~stewart_drake.references.motion.Reference`; the surrogate's from
            :func:`~stewart_drake.references.traces.load_trace`, a 2-column file on SI).
        internal_measured, surrogate_measured: the two measurements, on one clock
            (:func:`~stewart_drake.organ_motion.measured_motion.read_measured`).
        clock_offset_s, frame, registration, max_latency_s, tolerance, max_gap_s: as
            :func:`~stewart_drake.organ_motion.verification.verify` takes them (the surrogate is
            judged with the frames "axes": its offset removed on its axis); None: verify's
            defaults.
        max_relative_latency_s: the largest |relative latency| that passes, s (> 0).
    Returns:
        :class:`PairVerification`.
    Raises:
        InvalidConfigError: what :func:`~stewart_drake.organ_motion.verification.verify` refuses
            of either; a bound not a positive number; two measurements whose times do not
            overlap (not on one clock).
    """
    from ..organ_motion import verification

    if not max_relative_latency_s > 0 or not math.isfinite(max_relative_latency_s):
        raise InvalidConfigError(
            f"the relative latency's bound must be a positive number of s, got "
            f"{max_relative_latency_s}"
        )
    check_one_clock(internal_measured, surrogate_measured)
    tol = verification.DEFAULT_TOLERANCE if tolerance is None else tolerance
    alone = partial(
        verification.verify,
        clock_offset_s=clock_offset_s,
        max_latency_s=verification.MAX_LATENCY_S if max_latency_s is None else max_latency_s,
        tolerance=tol,
        max_gap_s=verification.MAX_GAP_S if max_gap_s is None else max_gap_s,
    )
    internal = alone(internal_reference, internal_measured, frame=frame, registration=registration)
    surrogate = alone(surrogate_reference, surrogate_measured)
    d_i = internal.shift_s
    half = search_half_width(surrogate_reference, max_relative_latency_s)
    d_s = relative_shift(surrogate_reference, surrogate_measured, d_i, half)
    tau = d_s - d_i
    t, x, x_d = _window(internal)
    why_internal = why_not_following(internal_reference, t, x, x_d, internal_measured.measured)
    # On the internal's clock, unless the internal's shift means nothing: then on its own.
    if why_internal:
        t, x, x_d = _window(surrogate)
    else:
        t, x, x_d = _at_shift(surrogate_reference, surrogate_measured, d_s)
    why_surrogate = why_not_following(surrogate_reference, t, x, x_d, surrogate_measured.measured)
    names = (Path(internal_measured.path).name, Path(surrogate_measured.path).name)
    why = (why_internal, why_surrogate)
    judgement = judge_relative(tau, max_relative_latency_s, half, names, why, None)
    if internal.frame.how != "registration":  # a registered tracker's axes are not B's
        swapped = swapped_words(
            (internal_reference, surrogate_reference),
            (internal_measured, surrogate_measured),
            d_i,
            tau,
        )
        if swapped:
            judgement = judge_relative(tau, max_relative_latency_s, half, names, why, swapped)
    notes = []
    apart = surrogate.shift_s - d_s
    if abs(apart) > 2 * verification.COARSE_STEP_S:
        notes.append(
            f"on its own, {names[1]} matches its reference best {seconds(abs(apart))} "
            f"{'later' if apart > 0 else 'earlier'} than on the internal's clock: its fidelity is "
            "that of its own best match, the relative latency that of the pair's (searched "
            f"within +-{seconds(half)} of the internal's)"
        )
    return PairVerification(
        internal, surrogate, float(tau), float(d_s), float(d_i), (-half, half), notes, judgement
    )


# -- the command -----------------------------------------------------------------------------------

#: The end of an encoder log's name (``<stem>_encoders.csv``, as ``robot`` writes it): given to
#: ``--measured`` it is read as ``verify`` alone reads it (the platform by forward kinematics),
#: given to ``--measured-surrogate`` for its surrogate's carriage ``s``; both on ``t_path``.
ENCODER_LOG_SUFFIX = "_encoders.csv"
#: ``--surrogate``'s word for the motion's external signal made by a correlation model
#: (:func:`~.external_reference.model_reference`) instead of a recorded file.
MODEL = "model"


def add_pair_arguments(vp) -> None:
    """Add to ``verify``'s parser ``vp`` the options of an internal motion judged with its
    surrogate (``--surrogate``, ``--measured-surrogate``, their columns and maps,
    ``--max-relative-latency``); ``verify`` runs :func:`cmd_verify_pair` when they are given, and
    as before otherwise."""
    from ..execution.options import positive_float

    vp.add_argument(
        "--surrogate",
        default=None,
        metavar="EXTERNAL",
        help="judge the motion with its external surrogate on one clock: the surrogate's "
        "recorded trace (a 2-column file, time and displacement, on SI; or a header naming its "
        "column and unit), on the motion's clock, or 'model' for the motion through a "
        "correlation model (--surrogate-param), as reproduce --surrogate model makes it, on SI; "
        "with --measured-surrogate; reports both fidelities and their relative latency "
        "(default: none, the motion alone)",
    )
    vp.add_argument(
        "--surrogate-param",
        nargs="*",
        default=None,
        metavar="KEY=VALUE",
        help="with --surrogate model: ratio=0.8 lead=0.3s drift=2mm/min change_at=20s "
        "lead_after=-0.2s ratio_after=1.2 blend=1s, as reproduce takes them (default: none, "
        "the motion itself: ratio 1, no lead, no drift, no change)",
    )
    vp.add_argument(
        "--surrogate-map",
        action="append",
        metavar="COLUMN=AXIS",
        help="put the surrogate trace's column on an axis, with a sign (repeatable) (default: a "
        "2-column file's displacement on SI)",
    )
    vp.add_argument(
        "--measured-surrogate",
        default=None,
        metavar="FILE",
        help="the surrogate's motion measured on the same clock as --measured (one camera seeing "
        "both platforms): a file read as --measured is, e.g. t [s],depth [mm]; or the robot "
        f"run's encoder log (a name ending in {ENCODER_LOG_SUFFIX}, the one given to --measured): "
        "its carriage's s [m] as the surrogate servo's encoder read it (default: none)",
    )
    vp.add_argument(
        "--measured-surrogate-columns",
        default=None,
        metavar="'t [s],X [mm]'",
        help="the measured surrogate file's columns and units when it has no header line (or to "
        "replace it) (default: its header)",
    )
    vp.add_argument(
        "--measured-surrogate-map",
        action="append",
        metavar="COLUMN=AXIS",
        help="put a measured surrogate column on an axis, with a sign (repeatable): the "
        "surrogate trace's axis, SI by default (default: by name)",
    )
    vp.add_argument(
        "--max-relative-latency",
        type=positive_float,
        default=MAX_RELATIVE_LATENCY_S,
        metavar="S",
        help="the largest |relative latency| of the motion against its surrogate that passes, "
        "s (> 0: the internal target late): IntERAct's claimed sync and AAPM TG-142's gating "
        "accuracy",
    )
    vp.set_defaults(func=partial(_verify_or_pair, vp.get_default("func")))


def is_encoder_log(path) -> bool:
    """Whether ``path`` names a robot run's encoder log (:data:`ENCODER_LOG_SUFFIX`)."""
    return str(path).endswith(ENCODER_LOG_SUFFIX)


def carriage_axis(reference) -> tuple[int, float]:
    """(axis 3..5, sign +-1) along which the surrogate's ``reference`` moves: the one
    translation of a trace (its import record's ``info.axes``, e.g. "+X", "-Z"; the carriage's
    ``s`` is the trace's own displacement, the map's sign undone, as the robot drives it), or
    a reference's own ``carriage_axis``.

    Raises:
        InvalidConfigError: a reference of more than one axis, or of a rotation.
    """
    own = getattr(reference, "carriage_axis", None)
    if own is not None:
        return own
    axes = tuple(getattr(getattr(reference, "info", None), "axes", ()))
    if len(axes) != 1 or axes[0][1:] not in AXES[3:]:
        raise InvalidConfigError(
            f"the surrogate's carriage moves along one line, its reference along "
            f"{', '.join(axes) or 'no axis named'}: give --surrogate one displacement (a "
            "2-column file, or one column mapped with --surrogate-map)"
        )
    return AXES.index(axes[0][1:]), (-1.0 if axes[0][0] == "-" else 1.0)


def read_encoder_pair(path, surrogate_path, geometry, surrogate_reference) -> tuple:
    """(the platform's, the carriage's) :class:`~stewart_drake.organ_motion.measured_motion.
    MeasuredMotion` from robot runs' encoder logs (one log may be given for both): the platform
    by forward kinematics of ``geometry``, the carriage's ``s`` (as its servo's encoder read
    it, never its command ``s_cmd``) on the axis of ``surrogate_reference``
    (:func:`carriage_axis`), each on its log's ``t_path``, the lead-in left out. Each log is
    read by the one checked reader of encoder logs
    (:func:`~stewart_drake.calibration.join.read_encoder_log`), its columns by name.

    Raises:
        MissingFileError, CorruptFileError, InvalidConfigError: as that reader's (a log without
            the ``s`` column named with its file); as :func:`carriage_axis`.
        ForwardKinematicsError: a reading forward kinematics cannot solve.
    """
    from ..calibration.join import read_encoder_log
    from ..organ_motion.measured_motion import carriage_motion, encoder_motion

    axis, sign = carriage_axis(surrogate_reference)
    same = Path(path).resolve() == Path(surrogate_path).resolve()
    log = read_encoder_log(surrogate_path, carriage=True)
    carriage = carriage_motion(surrogate_path, log["t_path"], log["s"], axis, sign)
    if not same:
        log = read_encoder_log(path)
    return encoder_motion(path, log["t_path"], log["q"], geometry), carriage


def _verify_or_pair(alone, args) -> int:
    """``verify``: the pair (:func:`cmd_verify_pair`) when a surrogate or its measurement is
    given, else ``alone``, verify's own command."""
    if args.surrogate is None and args.measured_surrogate is None and not args.surrogate_param:
        return alone(args)
    return cmd_verify_pair(args)


def _check_pair_options(args) -> None:
    """Refuse, before any work, what the pair does not take (one line each).

    Raises:
        InvalidConfigError: --surrogate-param without ``--surrogate model``, or a model refused
            (:func:`~stewart_drake.station.surrogate.report.correlation_model`); --surrogate-map
            with a model; a surrogate without its measurement or the reverse, several
            --measured, --save-registration, an encoder log beside a tracker's file (not one
            clock) or with --measured-surrogate-columns or -map (its columns are its own),
            --frame other than axes or base.
    """
    if args.surrogate == MODEL:
        from ..station.surrogate.report import correlation_model

        correlation_model(args.surrogate_param)  # refused before any work
        if args.surrogate_map:
            raise InvalidConfigError(
                "--surrogate model is put on SI: leave --surrogate-map out (map the measured "
                "surrogate's column with --measured-surrogate-map instead)"
            )
    elif args.surrogate_param:
        raise InvalidConfigError(
            "--surrogate-param sets a correlation model: give --surrogate model"
        )
    if args.surrogate is None or args.measured_surrogate is None:
        given, missing = (
            ("--surrogate", "--measured-surrogate")
            if args.measured_surrogate is None
            else ("--measured-surrogate", "--surrogate")
        )
        raise InvalidConfigError(
            f"{given} judges the motion with its surrogate: give {missing} too (the surrogate's "
            "trace and its measurement on the clock of --measured)"
        )
    if len(args.measured) != 1:
        raise InvalidConfigError(
            "with --surrogate, give one --measured (the internal motion's measurement)"
        )
    if args.save_registration:
        raise InvalidConfigError("--save-registration registers a tracker: leave --surrogate out")
    logs = [is_encoder_log(p) for p in (args.measured[0], args.measured_surrogate)]
    if logs[0] != logs[1]:
        log, other = (
            (args.measured[0], args.measured_surrogate)
            if logs[0]
            else (args.measured_surrogate, args.measured[0])
        )
        raise InvalidConfigError(
            f"{log} is an encoder log, on the reference's clock (t_path), and {other} a "
            "tracker's or a camera's file, on its own: they are not on one clock; give the "
            "encoder log to both --measured and --measured-surrogate, or two files of one camera"
        )
    if logs[1] and (args.measured_surrogate_columns or args.measured_surrogate_map):
        raise InvalidConfigError(
            f"{args.measured_surrogate}: an encoder log's columns are its own (the carriage's "
            "s [m]): leave --measured-surrogate-columns and --measured-surrogate-map out"
        )
    if args.frame not in ("axes", "base"):
        raise InvalidConfigError(f"--frame is axes or base, got {args.frame!r}")
    if args.registration and args.frame != "axes":
        raise InvalidConfigError("--registration gives the frames: leave --frame out")


def cmd_verify_pair(args) -> int:
    """``stewart-drake verify INTERNAL --surrogate EXTERNAL --measured INTERNAL_MEAS
    --measured-surrogate EXTERNAL_MEAS``: read the two references and the two measurements,
    judge them (:func:`verify_pair`), write each motion's report as ``verify`` does and the
    pair's (``verify_<motion>_pair.md|.json``), print the three verdicts; 0 when all three pass,
    2 otherwise.

    Raises:
        InvalidConfigError, MissingFileError, CorruptFileError: a bad option or file (one line),
            before any report.
    """
    import sys

    from ..base.fileio import check_replaceable
    from ..calibration.registration_file import read_registration
    from ..execution.options import key_values
    from ..organ_motion.command import motion_scenario
    from ..organ_motion.fidelity import parse_tolerance
    from ..organ_motion.measured_motion import read_measured
    from ..references.traces import load_trace
    from ..run.plan import robot_geometry
    from .external_reference import model_reference

    _check_pair_options(args)
    tolerance = parse_tolerance(args.tolerance)
    scenario, name = motion_scenario(args)
    registration = read_registration(args.registration) if args.registration else None
    out = Path(args.out)
    paths = (args.measured[0], args.measured_surrogate)
    stems = [
        f"verify_{name}_{Path(paths[0]).stem}",
        f"verify_{Path(args.surrogate).stem}_{Path(paths[1]).stem}",
        f"verify_{name}_pair",
    ]
    if len(set(stems)) != 3:
        raise InvalidConfigError(
            "the motion's and the surrogate's reports would have one name: give files of "
            "different names"
        )
    for stem in stems:
        for suffix in (".md", ".png", ".json") if stem != stems[2] else (".md", ".json"):
            check_replaceable(out / f"{stem}{suffix}")
    reference = scenario.reference.make(robot_geometry(scenario), scenario.duration_s, None)
    if args.surrogate == MODEL:
        surrogate = model_reference(reference, args.surrogate_param, scenario.duration_s)
    else:
        print(f"verify: reading {args.surrogate}", file=sys.stderr, flush=True)
        surrogate = load_trace(args.surrogate, key_values(args.surrogate_map, "--surrogate-map"))
        surrogate = _on_the_motions_clock(surrogate, reference, args.surrogate)
    print(f"verify: reading {paths[0]}", file=sys.stderr, flush=True)
    if is_encoder_log(paths[0]):
        internal_measured, surrogate_measured = read_encoder_pair(
            paths[0], paths[1], robot_geometry(scenario), surrogate
        )
    else:
        internal_measured = read_measured(
            paths[0], args.measured_columns or "", key_values(args.measured_map, "--measured-map")
        )
        print(f"verify: reading {paths[1]}", file=sys.stderr, flush=True)
        surrogate_measured = read_measured(
            paths[1],
            args.measured_surrogate_columns or "",
            key_values(args.measured_surrogate_map, "--measured-surrogate-map"),
            "--measured-surrogate-columns",
        )
    print("verify: aligning and judging the motion and its surrogate", file=sys.stderr, flush=True)
    pair = verify_pair(
        reference,
        surrogate,
        internal_measured,
        surrogate_measured,
        clock_offset_s=args.clock_offset,
        frame=args.frame,
        registration=registration,
        max_latency_s=args.max_latency,
        max_relative_latency_s=args.max_relative_latency,
        tolerance=tolerance,
        max_gap_s=args.measured_max_gap,
    )
    written = write_pair(pair, out, tolerance, stems)
    print(pair.internal.judgement.line)
    print(pair.surrogate.judgement.line)
    print(pair.judgement.line)
    for note in pair.notes:
        print(note)
    print(f"wrote {', '.join(str(p) for p in written)}")
    return 0 if pair.passed else 2


def _on_the_motions_clock(surrogate, reference, path):
    """The surrogate's trace on the motion's clock, their files' times taken as written
    (:func:`~stewart_drake.references.clock.on_clock_of`), said on stderr when they do not
    start together."""
    import sys

    from ..references.clock import OnClockOf, on_clock_of

    shifted = on_clock_of(surrogate, reference)
    if isinstance(shifted, OnClockOf):
        lag = shifted.lag_s
        print(
            f"verify: {path} starts {seconds(abs(lag))} {'after' if lag > 0 else 'before'} the "
            "motion's file on their clock: its times taken as written, not re-zeroed",
            file=sys.stderr,
            flush=True,
        )
    return shifted


def pair_markdown(pair: PairVerification) -> str:
    """The pair's page: the three verdicts, the relative latency with its definition, each
    motion's shift and latency, and where each motion's own report is."""
    rows = []
    for what, ver in (("internal", pair.internal), ("surrogate", pair.surrogate)):
        rms = [v for v in ver.fidelity["rms"] if not math.isnan(v)]
        rows.append(
            [
                what,
                ver.name,
                Path(ver.measured.path).name,
                ", ".join(ver.fidelity["measured"]),
                f"{-ver.shift_s:+.4f}",
                f"{max(rms) * 1e3:.3g}",
                ver.judgement.verdict,
            ]
        )
    lines = [
        f"# {pair.internal.name} with its surrogate {pair.surrogate.name}, measured on one clock",
        "",
        f"**{'PASS' if pair.passed else 'FAIL'}**: the relative latency, and neither fidelity "
        "failing (one that cannot be judged at the tolerance is said so below).",
        "",
        f"- {pair.internal.judgement.line}",
        f"- {pair.surrogate.judgement.line}",
        f"- **{pair.judgement.line}**",
        "",
        f"Relative latency: {seconds(pair.relative_latency_s)} ({DEFINITION}). Searched "
        f"within {seconds(pair.searched_s[0])} to {seconds(pair.searched_s[1])}; the bound "
        f"+-{seconds(pair.judgement.max_relative_latency_s)}.",
        "",
        *markdown_lines(
            [
                "motion",
                "reference",
                "measured",
                "axes",
                "delay behind its reference [s]",
                "largest RMS error [mm or rad x 1e3]",
                "verdict",
            ],
            rows,
            [None, None, None, None, "right", "right", None],
        ),
        "",
        "Each delay is -d, on the measured clock: it holds the clocks' offset unless "
        "--clock-offset was given; their difference, the relative latency, does not.",
    ]
    lines += [""] + [f"- {n}" for n in pair.notes] if pair.notes else []
    return "\n".join(lines) + "\n"


def write_pair(pair: PairVerification, out, tolerance, stems) -> list:
    """Write each motion's report (as ``verify`` does: ``<stem>.md|.png|.json``) and the
    pair's ``<stem>.md`` (:func:`pair_markdown`) and ``<stem>.json``
    (:meth:`PairVerification.as_dict`) into ``out``, the stems (internal, surrogate, pair).

    Returns:
        the paths written.
    """
    import json

    from ..base.fileio import atomic_write
    from ..organ_motion.verification_report import write_verification

    out = Path(out)
    written = [*write_verification(pair.internal, out, tolerance, stems[0])]
    written += write_verification(pair.surrogate, out, tolerance, stems[1])
    md, js = out / f"{stems[2]}.md", out / f"{stems[2]}.json"
    text = pair_markdown(pair)
    atomic_write(md, lambda f: f.write(text.encode()))
    data = json.dumps(pair.as_dict(), indent=1)
    atomic_write(js, lambda f: f.write(data.encode()))
    return written + [md, js]


__all__ = [
    "MAX_RELATIVE_LATENCY_S",
    "RELATIVE_SEARCH_S",
    "REVERSED_RATIO",
    "SWAPPED_RATIO",
    "SWAP_SEARCH_S",
    "DEFINITION",
    "RelativeJudgement",
    "PairVerification",
    "search_half_width",
    "relative_shift",
    "why_not_following",
    "swapped_words",
    "judge_relative",
    "check_one_clock",
    "verify_pair",
    "ENCODER_LOG_SUFFIX",
    "MODEL",
    "is_encoder_log",
    "carriage_axis",
    "read_encoder_pair",
    "add_pair_arguments",
    "cmd_verify_pair",
    "pair_markdown",
    "write_pair",
]
