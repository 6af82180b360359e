"""What of a measured recording :func:`~.verification.verify` compares: the shifts its clock
search may take (:func:`search_range`: those that compare the whole recording when the clocks are
not known), the whole cycles of the reference inside it (:func:`cycle_window`), and what is left
out (:func:`uncompared`, :func:`outside_words`); with the refusals of a recording too short or
too far from the reference's clock to judge."""

from __future__ import annotations

import numpy as np

from ..base.errors import InvalidConfigError
from ..organ_motion.fidelity import format_window
from ..references.motion import Reference, reference_cycles
from .verdict_notes import MAX_UNCOMPARED_SHARE

#: With the clocks' relation known, latencies up to this many times the largest that passes
#: are searched (at most 0.45 of a periodic reference's period, so that a cycle earlier or
#: later is never taken): a latency beyond the bound is found, and fails, rather than hidden at
#: the edge of the search.
SEARCH_FACTOR = 3.0
#: Longest stretch of a reference without cycles the shift is searched over when the clocks'
#: relation is not known, s (an hour: the longest run reproduce makes).
MAX_SEARCH_S = 3600.0
#: The share of a cycle a recording may miss at either end of the window and the cycle still
#: count as whole (cut to the recording).
CYCLE_SLACK = 0.02
#: The latest time of the reference's clock a measured motion may lie at, s (11.6 days: a
#: tracker's clock since it booted): a motion's cycles up to there are held in memory.
MAX_REFERENCE_TIME_S = 1e6
#: Shortest measured motion without cycles that is judged, s (a breath).
MIN_SPAN_S = 4.0


def search_range(
    reference: Reference, t: np.ndarray, clock_offset_s, max_latency_s: float, whole: bool = True
):
    """((lo, hi) s: the shifts searched, whether they compare the whole recording). Known
    clocks: the offset less the latencies up to :data:`SEARCH_FACTOR` times ``max_latency_s``
    either way (at most 0.45 of a periodic reference's period). Unknown: the shifts that compare
    the whole recording, either end allowed :data:`~.verdict_notes.MAX_UNCOMPARED_SHARE` of
    its length outside the reference (a tracker started a little before the motion), up to the
    reference's end (one period of a periodic one, :data:`MAX_SEARCH_S` of one without an end);
    a recording longer than the reference allows no such shift, and then its start may lie from
    half its length before the motion's start (the verdict, which then leaves more than that
    share uncompared, cannot judge). Not ``whole``: that wider range whatever the recording's
    length (the best match of a part, for :func:`~.verification.verify`; the registration's
    fit)."""
    period = getattr(reference, "repeat_period_s", None)
    if clock_offset_s is not None:
        lat = SEARCH_FACTOR * max_latency_s
        lat = lat if not period else min(lat, 0.45 * period)
        return (clock_offset_s - lat, clock_offset_s + lat), True
    span = float(t[-1] - t[0])
    end = getattr(reference, "end_time", None)
    slack = MAX_UNCOMPARED_SHARE * span
    if end is None:
        lo = -t[0] - (slack if whole else 0.5 * span)
        return (lo, -t[0] + float(period or MAX_SEARCH_S)), whole
    if whole and float(end) - span + slack >= -slack:  # the recording fits in the reference
        return (-t[0] - slack, -t[0] + float(end) - span + slack), True
    return (-t[0] - 0.5 * span, -t[0] + max(float(end) - 0.5 * span, 0.0)), False


def cycle_window(reference: Reference, a: float, b: float) -> tuple[tuple, np.ndarray, bool]:
    """((w0, w1) the window measured, (K + 1,) the cycle starts in [a, b], whether the recording
    [a, b] (reference time, s) holds the motion's first cycle): the whole cycles after the first
    one of the motion (a cycle that the recording misses by at most :data:`CYCLE_SLACK` of a
    cycle at either end counts, cut to the recording: a run logged until its end stops a
    period or two short of it); all of [a, b] for a reference without cycles.

    Raises:
        InvalidConfigError: not one whole cycle (or :data:`MIN_SPAN_S` without cycles).
    """
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
    slack = CYCLE_SLACK * float(np.median(np.diff(starts)))
    inside = starts[(starts >= max(a, starts[1]) - slack) & (starts <= b + slack)]
    inside = np.clip(inside, max(a, starts[1]), b)  # a recording a few samples short of a cycle
    if inside.size < 2:
        cycle = float(np.median(np.diff(starts)))
        raise InvalidConfigError(
            f"the measured motion covers t = {format_window(a, b)} s of {name} once aligned: "
            f"not one whole cycle ({cycle:.3g} s) after the motion's first; record at least two "
            "cycles"
        )
    return (float(inside[0]), float(inside[-1])), inside, holds_start


def check_reference_time(a: float, b: float) -> None:
    """Refuse a measured motion that, on the reference's clock, lies in [a, b] s beyond
    :data:`MAX_REFERENCE_TIME_S` either way: no run of a phantom is that long, and the cycles
    of a motion up to there would take memory in proportion (a clock offset of 1e10 s, or one
    of the wrong sign or unit).

    Raises:
        InvalidConfigError: naming the times and what to check.
    """
    if max(abs(a), abs(b)) > MAX_REFERENCE_TIME_S:
        raise InvalidConfigError(
            f"the measured motion lies at t = {a:.6g} to {b:.6g} s of the reference's clock, "
            f"beyond the {MAX_REFERENCE_TIME_S:g} s a phantom's run can last: measured time + "
            "--clock-offset = the reference's time; check the offset's sign and unit"
        )


def check_length(reference: Reference, t: np.ndarray) -> None:
    """Refuse a recording shorter than one cycle of the reference (or a breath, without)."""
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


def uncompared(t_all, t_ref, whole: bool, reference: Reference | None = None) -> dict:
    """:attr:`~.verify.Verification.uncompared` of the recording's times ``t_all`` on the
    reference's clock, of which ``t_ref`` are compared; ``whole``: the clock known or searched
    among the shifts that compare the whole recording (:func:`search_range`); ``reference``: the
    motion, whose length (from its start to its ``end_time``; none for one that repeats or has
    no end) gives ``longer_s``, by how much the recording outlasts it: that much no clock can
    compare."""
    before, after = t_all < t_ref[0], t_all > t_ref[-1]
    span = float(t_all[-1] - t_all[0])
    end = getattr(reference, "end_time", None)
    repeats = getattr(reference, "repeat_period_s", None) is not None
    length = (
        None
        if end is None or repeats
        else float(end) - float(getattr(reference, "start_time", 0.0))
    )
    return {
        "whole": bool(whole),
        "samples": int(t_all.size),
        "before": int(before.sum()),
        "after": int(after.sum()),
        "before_s": float(t_ref[0] - t_all[0]),
        "after_s": float(t_all[-1] - t_ref[-1]),
        "span_s": span,
        "longer_s": 0.0 if length is None else max(0.0, span - length),
    }


def outside_words(t_all, t_ref, window, holds_start: bool) -> list:
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
            f"the figures are over whole cycles, t = {format_window(*window)} s: "
            f"{head:.3g} s before ({what}) and {tail:.3g} s after are outside them"
        )
    return ["what the figures leave out: " + "; ".join(parts)] if parts else []


__all__ = [
    "SEARCH_FACTOR",
    "MAX_SEARCH_S",
    "CYCLE_SLACK",
    "MAX_REFERENCE_TIME_S",
    "MIN_SPAN_S",
    "search_range",
    "cycle_window",
    "check_reference_time",
    "check_length",
    "uncompared",
    "outside_words",
]
