"""An internal target and its external surrogate measured on one clock, judged together
(``stewart-drake verify INTERNAL --surrogate EXTERNAL --measured INTERNAL_MEAS
--measured-surrogate EXTERNAL_MEAS``): each motion's fidelity, as ``verify`` gives it alone, and
their **relative latency**, as measured against as asked.

**The relative latency.** Motion management infers the target from the surrogate, so what counts
is whether the phantom keeps the two in the relation the pair was recorded with (the external
leading or lagging the internal by its own 0.4-1.8 s, IntERAct's traces), not each one's delay
from its command. Each measurement is put on its reference's clock by ``verify``'s own clock
search (:mod:`~stewart_drake.verification.alignment`: the shift d with the measured time + d the
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
:func:`~stewart_drake.verification.verify.verify`, as ``verify`` alone judges it (its
frames, its clock d_internal); then, on the internal's clock, the pair's relative latency by
the package's one definition (:func:`pair_relative_latency`, through
:func:`~stewart_drake.base.pair_figures.relative_latency`, the Diagram's pair report's and the
robot's session's): the internal's lag left along its reference's principal direction and the
surrogate's lag, each within :data:`~stewart_drake.base.pair_figures.LAG_SEARCH_S` (or within
:data:`RELATIVE_SEARCH_S`, or :data:`~stewart_drake.verification.measured_span.SEARCH_FACTOR`
times the bound if wider, at most 0.45 of a periodic surrogate's period so that a breath
earlier or later is never taken, when the surrogate's is at that edge), their difference
tau_rel. The surrogate's own fidelity is verify's on its own (its offset removed on the one
axis it moves, ``frame="axes"``).

**What is read** (:func:`~.pair_command.cmd_verify_pair`): two files of one camera or tracker on
its own clock, each read as ``verify`` reads a tracker's file; or the robot's encoder log for
both (:func:`~.pair_command.read_encoder_pair`: the platform by forward kinematics, the
surrogate's carriage ``s`` as its servo's encoder read it, both on the log's ``t_path``). The
surrogate's reference is its recorded trace, or a library motion's external signal made by a
correlation model as ``reproduce --surrogate model`` makes it
(:func:`~.external_reference.model_reference`).

**The verdict** (:func:`judge_relative`) PASSes when |tau_rel| is within
``max_relative_latency_s`` (:data:`MAX_RELATIVE_LATENCY_S`) and both motions follow their
references (else the latency means nothing); a FAIL names its cause (:mod:`.pair_causes`): a
motion at rest, reversed, of another period or not following its reference (another motion), the
two measurements swapped, the relative latency beyond its bound (and which one is late), or at
the edge of the search.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from functools import partial
from pathlib import Path
from typing import Any

import numpy as np

from ..base.errors import InvalidConfigError
from ..base.verdicts import verdict, within, worst
from .measured_verdict import (
    EDGE_S,
    seconds,
)
from .pair_causes import swapped_words, why_not_following

#: The largest |relative latency| that passes unless given, s. IntERAct's authors claim their two
#: platforms synchronised "within 0.1 s" (Kaczynska et al. 2026), and AAPM TG-142 (Klein et al.
#: 2009, Table V) asks a respiratory-gated beam's temporal accuracy of 100 ms: a surrogate 0.1 s
#: off its target moves the inferred target by 0.1 s times the breath's speed, 0.8 mm at the peak
#: of a 10 mm, 4 s breath.
MAX_RELATIVE_LATENCY_S = 0.1
#: Relative latencies up to this, s, are searched either way (or
#: :data:`~stewart_drake.verification.measured_span.SEARCH_FACTOR` times the bound, if wider): a
#: relative latency beyond the bound is found and fails rather than hidden at the edge; below half
#: a breath (about 4 s), so that a breath earlier or later is not matched.
RELATIVE_SEARCH_S = 1.5


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
            :class:`~stewart_drake.verification.verify.Verification`, as ``verify`` judges
            it alone (its figures, its verdict, its latency).
        relative_latency_s: tau_rel = d_surrogate - d_internal, s (module docstring).
        surrogate_shift_s: d_surrogate, the surrogate's shift found on the internal's clock, s
            (the measured time + it = the surrogate reference's time). internal_shift_s:
            d_internal, s: the internal's clock's shift less its lag left along its principal
            direction (:func:`pair_relative_latency`).
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

    @property
    def verdicts(self) -> tuple[str, str, str]:
        """The pair's three verdicts: the internal target's motion, the surrogate's (PASS, FAIL
        or CANNOT JUDGE each) and the relative latency's (PASS or FAIL). The command's exit
        status is the worst of them, as ``verify``'s of one motion: a motion that cannot be
        judged is not a pair that passed."""
        relative = verdict(self.judgement.passed)
        return self.internal.judgement.verdict, self.surrogate.judgement.verdict, relative

    @property
    def verdict(self) -> str:
        """The worst of :attr:`verdicts` (:func:`~stewart_drake.base.verdicts.worst`): FAIL,
        else CANNOT JUDGE, else PASS."""
        return worst(self.verdicts)

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
            "verdict": self.verdict,
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
    "measured time + d = the reference's; the internal's along its reference's principal "
    "direction); > 0: the internal target late against the surrogate; the clocks' offset cancels"
)


# -- the search ------------------------------------------------------------------------------------


def search_half_width(reference, max_relative_latency_s: float) -> float:
    """The relative latencies searched either way, s: :data:`RELATIVE_SEARCH_S`, or
    :data:`~stewart_drake.verification.measured_span.SEARCH_FACTOR` times the bound if wider; at
    most 0.45 of the surrogate reference's period when it repeats."""
    from .measured_span import SEARCH_FACTOR

    width = max(RELATIVE_SEARCH_S, SEARCH_FACTOR * max_relative_latency_s)
    period = getattr(reference, "repeat_period_s", None)
    return min(width, 0.45 * period) if period else width


#: The fewest samples inside the reference's span that are compared alone (:func:`span_mask`).
MIN_INSIDE = 10


def span_mask(reference, t_ref) -> np.ndarray:
    """(n,) bool: which of the times ``t_ref`` (s, on the reference's clock) fall inside the
    reference's span, [0, its ``end_time``] (no end: from 0 on;
    :func:`~stewart_drake.verification.alignment.in_span`, as ``verify`` reads it); all of
    them when fewer than :data:`MIN_INSIDE` do (a measurement mostly outside is compared whole
    rather than on a handful of samples)."""
    from .alignment import in_span

    t_ref = np.asarray(t_ref, dtype=float)
    use = in_span(reference, t_ref)
    return use if np.count_nonzero(use) >= MIN_INSIDE else np.ones(len(t_ref), dtype=bool)


def pair_relative_latency(internal, surrogate_reference, surrogate_measured, half_width_s: float):
    """The pair's relative latency on the internal's clock, by the package's one definition
    (:func:`~stewart_drake.base.pair_figures.relative_latency`, the Diagram's pair report's and
    the robot's session's).

    The internal: its measured poses wherever ``verify`` compared them (its start-up too), on
    its reference's clock and in its frames, against its reference, along the principal
    direction of the reference's measured translations (of its rotations, if it measured no
    translation). The surrogate: its measured axes, linearly interpolated to the same times on
    the one measured clock, against its reference. Each lag within
    +-:data:`~stewart_drake.base.pair_figures.LAG_SEARCH_S` (the pair's usual search), or within
    +-``half_width_s`` when the surrogate's lag is found within
    :data:`~.measured_verdict.EDGE_S` of that edge; a constant offset removed; over the samples
    more than the search's half-width from either end. The internal's lag is what its 6-D clock
    search left along that direction (microseconds on a pure lag).

    Args:
        internal: the internal motion's
            :class:`~stewart_drake.verification.verify.Verification`.
        surrogate_reference: its reference. surrogate_measured: its
            :class:`~stewart_drake.verification.measured_motion.MeasuredMotion`, on the
            internal measurement's clock.
        half_width_s: the lags searched either way, s.
    Returns:
        :class:`~stewart_drake.base.pair_figures.PairLatency`, its lags on the internal's
        clock (the measured time + the internal's shift).
    Raises:
        InvalidConfigError: fewer than 8 samples where both measurements and both references
            overlap, more than ``half_width_s`` from the window's ends.
    """
    from ..base.columns import interp_columns
    from ..base.pair_figures import LAG_SEARCH_S, relative_latency
    from .alignment import in_span, reference_poses

    t, x, x_d = internal.result.t, internal.result.x, internal.result.x_d
    d_i = internal.shift_s
    s_t = np.asarray(surrogate_measured.t, dtype=float)
    seen = np.asarray(internal.measured.measured, dtype=bool)
    keep = in_span(surrogate_reference, t) & (t - d_i >= s_t[0]) & (t - d_i <= s_t[-1])
    keep &= np.all(np.isfinite(x[:, seen]), axis=1)
    t, x, x_d = t[keep], np.where(np.isfinite(x[keep]), x[keep], x_d[keep]), x_d[keep]
    block = slice(3, 6) if seen[3:6].any() else slice(0, 3)
    mask = seen[block].astype(float)  # the axes not measured take no part
    axes = np.flatnonzero(np.asarray(surrogate_measured.measured, dtype=bool))
    s_y = np.asarray(surrogate_measured.poses, dtype=float)[:, axes]
    pair = partial(
        relative_latency,
        t,
        x_d[:, block] * mask,
        x[:, block] * mask,
        reference_poses(surrogate_reference, t)[:, axes],
        interp_columns(t - d_i, s_t, s_y),
    )
    narrow = min(LAG_SEARCH_S, half_width_s)
    found = pair(narrow)
    if narrow < half_width_s and not abs(found.external_lag_s) < narrow - EDGE_S:
        found = pair(half_width_s)  # at the edge of the pair's usual search: look wider
    return found


# -- whether a motion follows its reference --------------------------------------------------------


def _at_shift(reference, measured, d: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(t, x, x_d) of ``measured`` put on ``reference``'s clock by the shift d (s), over the
    samples inside the reference's span (:func:`span_mask`), each measured axis less its mean
    difference."""
    from .alignment import reference_poses

    t_ref = measured.t + d
    keep = span_mask(reference, t_ref)
    t_ref = t_ref[keep]
    x_d = reference_poses(reference, t_ref)
    x = np.array(measured.poses[keep], dtype=float)
    seen = np.asarray(measured.measured, dtype=bool)
    x[:, seen] -= np.mean(x[:, seen] - x_d[:, seen], axis=0)
    return t_ref, np.where(np.isfinite(x), x, x_d), x_d


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
    inside = within(relative_latency_s, max_relative_latency_s) and not at_edge
    value = f"{'at least ' if at_edge else ''}{seconds(relative_latency_s)}"
    if at_edge:  # past half a breath, a breath earlier or later may match better than the true
        late = "which one is late is not known beyond the relative latencies searched"
    elif relative_latency_s > 0:
        late = "the internal target late against the surrogate"
    elif relative_latency_s < 0:
        late = "the surrogate late against the internal target"
    else:
        late = "neither late"
    if meaningful and not inside:
        causes.append(
            f"relative latency {value} beyond --max-relative-latency "
            f"{seconds(max_relative_latency_s)}: {late}"
            + (" (at the edge of the relative latencies searched)" if at_edge else "")
        )
    passed = meaningful and inside
    if meaningful:
        figure = (
            f"relative latency {value} ({late}) "
            f"{'within' if inside else 'beyond'} +-{seconds(max_relative_latency_s)}"
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
            (:func:`~stewart_drake.verification.measured_motion.read_measured`).
        clock_offset_s, frame, registration, max_latency_s, tolerance, max_gap_s: as
            :func:`~stewart_drake.verification.verify.verify` takes them (the surrogate is
            judged with the frames "axes": its offset removed on its axis); None: verify's
            defaults.
        max_relative_latency_s: the largest |relative latency| that passes, s (> 0).
    Returns:
        :class:`PairVerification`.
    Raises:
        InvalidConfigError: what :func:`~stewart_drake.verification.verify.verify` refuses
            of either; a bound not a positive number; two measurements whose times do not
            overlap (not on one clock).
    """
    from . import verify as verification

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
    pair = pair_relative_latency(internal, surrogate_reference, surrogate_measured, half)
    # On the internal's clock a lag is minus a shift; an internal whose reference does not
    # move along the direction has no lag of its own there: its clock's shift stands.
    d_int = d_i - (pair.internal_lag_s if math.isfinite(pair.internal_lag_s) else 0.0)
    d_s = d_i - pair.external_lag_s
    tau = d_s - d_int
    why = _not_following(internal, surrogate, d_s)
    names = (Path(internal_measured.path).name, Path(surrogate_measured.path).name)
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
    notes = _own_match_notes(surrogate.shift_s - d_s, names[1], half)
    return PairVerification(
        internal, surrogate, float(tau), float(d_s), float(d_int), (-half, half), notes, judgement
    )


def _not_following(internal, surrogate, d_s: float) -> tuple:
    """(why the internal does not follow its reference, why the surrogate does not), each
    None when it does (:func:`~.pair_causes.why_not_following`): the internal over the window
    ``verify`` judged; the surrogate on the internal's clock at its shift ``d_s`` (s), unless
    the internal's shift means nothing: then over its own judged window."""
    from .verify import judged_window

    why_internal = why_not_following(
        internal.reference, *judged_window(internal), internal.measured.measured
    )
    if why_internal:
        seen = judged_window(surrogate)
    else:
        seen = _at_shift(surrogate.reference, surrogate.measured, d_s)
    return why_internal, why_not_following(surrogate.reference, *seen, surrogate.measured.measured)


def _own_match_notes(apart: float, name: str, half: float) -> list[str]:
    """The note when the surrogate alone matches its reference best ``apart`` s from where
    it stands on the internal's clock (more than two of verify's coarse steps): its fidelity
    and the pair's relative latency are then measured at two shifts."""
    from .verify import COARSE_STEP_S

    if abs(apart) <= 2 * COARSE_STEP_S:
        return []
    return [
        f"on its own, {name} matches its reference best {seconds(abs(apart))} "
        f"{'later' if apart > 0 else 'earlier'} than on the internal's clock: its fidelity is "
        "that of its own best match, the relative latency that of the pair's (searched "
        f"within +-{seconds(half)} of the internal's)"
    ]


__all__ = [
    "MAX_RELATIVE_LATENCY_S",
    "RELATIVE_SEARCH_S",
    "DEFINITION",
    "RelativeJudgement",
    "PairVerification",
    "search_half_width",
    "span_mask",
    "pair_relative_latency",
    "judge_relative",
    "check_one_clock",
    "verify_pair",
]
