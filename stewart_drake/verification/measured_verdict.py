"""The verdict on a measured motion (``stewart-drake verify``): what it compares, whether it
passes, and, when it fails, why (:func:`judge`); and what the check can see at all
(:func:`~.verdict_sensitivity.sensitivity`).

A verdict compares the motion measured on the axes it measures, put on the reference's clock and
in the frames of :mod:`~.alignment` (nothing fitted to it but the clock and, with the ``"axes"``
frames, one constant per axis), against the reference: PASS when every measured axis's RMS error
over the window is within the tolerance and, with the clocks' relation known, the latency
within its bound. With an action level (``--action-level``, TG-142's; pylinac's
``action_tolerance``), a PASS with an axis's RMS error beyond it is ACTION instead: within the
tolerance, to be looked at before it fails (:func:`~.verdict_levels.axis_levels`). A FAIL names
its causes: those of the aligned motion over the window (:func:`~.causes.causes_of`: at rest, a
sign, another period or motion, a scale, another shape, an axis swapped, a constant offset, the
frames turned), then the latency beyond its bound, and, when none of these, the motion's shape.

A verdict names the measured samples it leaves uncompared, those the clock puts before the
reference's start or after its end, on its line. With the clocks' relation not known, the clock
is searched among the shifts that compare the whole recording, either end allowed
:data:`~.verdict_notes.MAX_UNCOMPARED_SHARE` of it outside the reference (a tracker started a
little early): a search free to leave more out trades the recording's hard part for a better
score (a robot that stopped, a platform that ran reversed for its first half) or cuts a right
recording at a wrong repeat of its trace. A recording that no such shift fits (longer than its
reference) is searched more widely, and a clock that then leaves more than that share out beyond
what the recording outlasts the reference by makes the verdict CANNOT JUDGE, whether the rest
would pass or fail (:mod:`~.verdict_notes`). The clock given (``--clock-offset``) judges what
the user said, and the verdict then says what it left out.

A verdict that would PASS is CANNOT JUDGE instead when the phantom at rest would pass too: when
on every measured axis the reference's own motion over the window (its RMS about its mean, the
error of a platform resting at the reference's mean pose) is within the tolerance. Such a check
cannot tell the motion from none, and says how small a tolerance, or how large a motion, it
needs. A FAIL stays a FAIL: an error beyond the tolerance is seen whatever the motion.

:func:`~.verdict_sensitivity.sensitivity` computes, from the reference alone, the smallest
error of the whole motion's amplitude and the smallest tilt of the whole phantom (about an
axis through the base frame's origin) that fail at the tolerance on the axes measured: a check
that cannot see a 3 % scale error says so before anyone relies on it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..base.verdicts import axes_within, verdict, within
from ..organ_motion.fidelity import AXES, format_angle, format_length, format_window
from .causes import axis_figures, causes_of
from .verdict_levels import action_words, axis_levels
from .verdict_notes import (
    outlier_words,
    pause_words,
    removed_offset_words,
    seconds,
    uncompared_words,
)
from .verdict_sensitivity import (
    axis_amount,
    axis_tolerances,
    motion_unseen,
    sensitivity,
)

#: A latency found within this many seconds of the edge of the shifts searched is "at least".
EDGE_S = 0.05


@dataclass
class Judgement:
    """A measured motion's verdict (module docstring).

    Attributes:
        passed: whether every measured axis is within the tolerance and the rest holds (the
            verdict PASS or ACTION). line: it in one line: the verdict's word
            (:attr:`verdict`), what was compared, the tolerance, the window, the largest
            errors, the latency, and the causes of a FAIL (or why it cannot judge).
        compared: what was compared, in words (the file, its axes, the frames, the reference).
        causes: why it fails, one phrase each (empty when it passes).
        axes: {axis: {"rms", "motion_rms", "reference_rms", "gain", "correlation",
            "mean_error", "period_s", "reference_period_s"}} per measured axis over the window
            (m or rad; NaN where undefined).
        latency_judged: whether the latency was judged (the clocks' relation known).
        sensitivity: :func:`sensitivity`.
        cannot_judge: why the check cannot tell the motion from none at the tolerance (module
            docstring), or "" when it can.
        action_level: (m, rad) the action level judged against, or None.
        action: {axis: RMS error, m or rad} of the measured axes within the tolerance but
            beyond the action level (empty without one).
        tolerance: (m, rad) the tolerance judged against: what the report, the figure and
            the record state beside the verdict, read from here.
    """

    passed: bool
    line: str
    compared: str
    causes: list = field(default_factory=list)
    axes: dict = field(default_factory=dict)
    latency_judged: bool = False
    sensitivity: dict = field(default_factory=dict)
    cannot_judge: str = ""
    action_level: tuple | None = None
    action: dict = field(default_factory=dict)
    tolerance: tuple = (math.nan, math.nan)

    @property
    def verdict(self) -> str:
        """``"PASS"``, ``"ACTION"`` (passed, an axis beyond the action level), ``"FAIL"`` or
        ``"CANNOT JUDGE"``."""
        return verdict(self.passed, bool(self.cannot_judge), bool(self.action))

    def as_dict(self) -> dict:
        """The judgement as JSON values."""
        return {
            "verdict": self.verdict,
            "passed": self.passed,
            "cannot_judge": self.cannot_judge,
            "line": self.line,
            "compared": self.compared,
            "causes": list(self.causes),
            "axes": self.axes,
            "latency_judged": self.latency_judged,
            "sensitivity": self.sensitivity,
            "action_level": None if self.action_level is None else list(self.action_level),
            "action": self.action,
        }


def compared_words(ver) -> str:
    """What a verification compares, in words: the file, its axes, the frames, the reference."""
    m = ver.measured
    axes = ", ".join(a for a, s in zip(AXES, m.measured) if s)
    how = {
        "axes": "each axis's offset removed",
        "base": "in the base frame as given",
        "registration": "registered to the base frame",
        "encoders": "the encoders' pose",
    }[ver.frame.how]
    return f"{Path(m.path).name} ({axes}; {how}) against {ver.name}"


def judge(ver, tolerance: tuple[float, float], action_level=None) -> Judgement:
    """The verdict on a :class:`~.verify.Verification` at ``tolerance`` (m, rad):
    PASS when every measured axis's RMS error over the window is within it and, with the clocks'
    relation known, |latency| within ``ver.max_latency_s``; ACTION instead when an axis is
    beyond ``action_level`` (m, rad; None: none); a FAIL's causes (module docstring)."""
    fid = ver.fidelity
    measured = np.asarray(ver.measured.measured, dtype=bool)
    tol = axis_tolerances(tolerance)
    rms = np.asarray(fid["rms"], dtype=float)
    w0, w1 = fid["window_s"]
    t, x, x_d = ver.result.t, ver.result.x, ver.result.x_d
    m = (t >= w0 - 1e-9) & (t <= w1 + 1e-9)
    x_w = np.where(np.isfinite(x[m]), x[m], x_d[m])
    ok = axes_within(rms, tol, measured)
    latency_judged = ver.clock != "not known"
    latency_ok = not latency_judged or within(ver.latency_s, ver.max_latency_s)
    unseen = "" if not (ok and latency_ok) else motion_unseen(x_d[m], measured, tolerance)
    left_out, too_much = uncompared_words(getattr(ver, "uncompared", {}))
    unseen = "; ".join(w for w in (too_much, unseen) if w)
    passed = ok and latency_ok and not unseen
    moving = np.array([a in fid["moving"] for a in AXES])
    causes: list[str] = []
    follows = True
    if not ok:
        causes, follows = causes_of(
            t[m],
            x_w,
            x_d[m],
            measured,
            moving,
            tolerance,
            ver.frame.removes_offsets,
            ver.reference,
            ver.latency_s,
            float(np.linalg.norm(ver.frame.p_EM)),
        )
    if not latency_ok:
        lo, hi = ver.searched_s
        edge = min(abs(ver.shift_s - lo), abs(ver.shift_s - hi)) < EDGE_S
        text = (
            f"latency {'at least ' if edge else ''}{seconds(ver.latency_s)} beyond "
            f"--max-latency {seconds(ver.max_latency_s)}"
            + (" (at the edge of the shifts searched)" if edge else "")
        )
        causes.append(text if follows else f"{text}, of no meaning while the above holds")
    if not ok and len(causes) == (0 if latency_ok else 1):
        causes.insert(
            0,
            "no offset, scale, sign, axis, period or latency explains it: the motion departs "
            "from the reference in its shape",
        )
    largest = []
    for kind, axes in (("translation", range(3, 6)), ("rotation", range(3))):
        ks = [k for k in axes if measured[k]]
        if ks:
            k = max(ks, key=lambda j: rms[j])
            largest.append(f"{AXES[k]} {axis_amount(k, rms[k])}")
        else:
            largest.append(f"{kind} not measured")
    if not follows:
        lat = f"latency {seconds(ver.latency_s)} of no meaning (the motion does not follow)"
    elif latency_judged:
        lat = (
            f"latency {seconds(ver.latency_s)} {'within' if latency_ok else 'beyond'} "
            f"{seconds(ver.max_latency_s)}"
        )
    else:
        lat = "latency not judged (the clocks' relation not given)"
    compared = compared_words(ver)
    levels = axis_levels(rms, measured, tolerance, action_level)
    action = {a: float(rms[AXES.index(a)]) for a, v in levels.items() if v == "ACTION"}
    action = action if passed else {}
    word = verdict(passed, bool(unseen), bool(action))
    line = (
        f"{word}: {compared}: RMS error per axis "
        f"{'within' if ok else 'beyond'} {format_length(tolerance[0])} | "
        f"{format_angle(tolerance[1])} over t = {format_window(w0, w1)} s (largest: "
        f"{', '.join(largest)}); {lat}"
        + action_words(action, action_level)
        + (f"; cause: {'; '.join(causes)}" if causes else "")
        + (f"; {left_out}" if left_out and not too_much else "")
        + (f"; {unseen}" if unseen else "")
        + outlier_words(
            getattr(ver, "outliers", {}), measured, tolerance, getattr(ver, "excluded", 0)
        )
        + pause_words(getattr(ver, "pauses", ()))
        + removed_offset_words(ver, tolerance)
    )
    return Judgement(
        passed,
        line,
        compared,
        causes,
        axis_figures(t[m], x_w, x_d[m], measured),
        latency_judged,
        sensitivity(t[m], x_d[m], measured, tolerance, ver.frame.removes_offsets),
        unseen,
        action_level,
        action,
        (float(tolerance[0]), float(tolerance[1])),
    )


__all__ = [
    "EDGE_S",
    "Judgement",
    "compared_words",
    "judge",
    "seconds",
]
