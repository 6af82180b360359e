"""The verdict line's notes on what a verdict on a measured motion did not judge
(:func:`~.measured_verdict.judge` appends them): the measured samples outside the reference
(:func:`uncompared_words`, and when a clock that leaves too many out cannot judge), the planned
pauses judged across (:func:`pause_words`), the constants the frames removed
(:func:`removed_offset_words`), the frames far off the rest (:func:`outliers`,
:func:`outlier_words`). A verdict names what it leaves out on its own line, never only in
its report."""

from __future__ import annotations

import numpy as np

from ..base.measures import rms_per_axis
from ..base.verdicts import axes_within
from ..organ_motion.fidelity import AXES
from .verdict_sensitivity import axis_amount, axis_tolerances

#: The largest share of the measured samples a clock found (the clocks' relation not known) may
#: leave uncompared, outside the reference, and the verdict still judge (CANNOT JUDGE beyond).
MAX_UNCOMPARED_SHARE = 0.1
#: A frame is an outlier when its error on some measured axis lies this many robust standard
#: deviations (1.4826 x the median absolute deviation) from the median error...
OUTLIER_SIGMAS = 6.0
#: ... and this many times the axis's tolerance: a frame within a few tolerances is the motion's
#: own error, never an outlier, however quiet the rest.
OUTLIER_TOLERANCES = 5.0
#: Pauses named one by one on a verdict line; more are counted.
NAMED_PAUSES = 3


def seconds(value: float) -> str:
    """A time in s as text: ``60.1 ms`` below a second, else ``1232 s`` (4 digits)."""
    return f"{value * 1e3:.4g} ms" if abs(value) < 1.0 else f"{value:.4g} s"


def uncompared_words(uncompared: dict) -> tuple[str, str]:
    """(the words on the measured samples outside the reference, "" if none; why the verdict
    cannot judge, "" unless a clock found among shifts that need not compare the whole recording
    left more than :data:`MAX_UNCOMPARED_SHARE` of them beyond what the recording outlasts the
    reference by). ``uncompared``: {"samples", "before", "after", "before_s", "after_s",
    "whole", "span_s", "longer_s"}, the recording's samples, those before the reference's start
    and after its end, their spans, s, whether the clock was known or searched among the shifts
    that compare the whole recording, the recording's span and by how much it outlasts the
    reference, s (:attr:`~.verify.Verification.uncompared`)."""
    n = int(uncompared.get("samples", 0))
    before, after = int(uncompared.get("before", 0)), int(uncompared.get("after", 0))
    if not n or not before + after:
        return "", ""
    where = [
        f"{which} {seconds(float(uncompared[f'{side}_s']))}, {what}"
        for side, count, which, what in (
            ("before", before, "its first", "before the reference's start"),
            ("after", after, "its last", "after the reference's end"),
        )
        if count
    ]
    share = (before + after) / n
    longer, span = float(uncompared.get("longer_s", 0.0)), float(uncompared.get("span_s", 0.0))
    if longer > 0.0:
        where.append(f"the recording {seconds(longer)} longer than the reference")
    words = (
        f"{before + after} of {n} measured samples not compared ({share:.0%}: {'; '.join(where)})"
    )
    # What no clock could compare (a recording longer than its reference) is not the clock's
    # choice: the share judged is of the rest.
    chosen = share - (longer / span if span > 0.0 else 0.0)
    if uncompared.get("whole", True) or chosen <= MAX_UNCOMPARED_SHARE:
        return words, ""
    return words, (
        f"the clock found leaves {words[0].lower() + words[1:]}, over "
        f"{MAX_UNCOMPARED_SHARE:.0%} of the recording: the search may have cut the recording where "
        "it departs; give --clock-offset (the measured time + it = the reference's) to judge "
        "it on a known clock, or cut the file to the reference's span"
    )


def pause_words(pauses) -> str:
    """The verdict line's words on the planned pauses the segments were judged across ("" for
    none): ``pauses`` ((t of the file before the pause, s; its length, s), ...)."""
    if not pauses:
        return ""
    named = [f"{seconds(length)} after t = {t:.6g} s" for t, length in pauses[:NAMED_PAUSES]]
    more = len(pauses) - NAMED_PAUSES
    listed = ", ".join(named) + (f" and {more} more" if more > 0 else "")
    which = "a pause" if len(pauses) == 1 else f"{len(pauses)} pauses"
    return (
        f"; judged in {len(pauses) + 1} segments across {which} ({listed} of the file): "
        "each sample at its own time, nothing bridged"
    )


def removed_offset_words(ver, tolerance: tuple[float, float]) -> str:
    """The verdict line's words on the constants the frames removed ("" when none is larger
    than its axis's tolerance): with ``--frame axes`` each measured axis's mean error is removed
    and not judged, as phantom QA protocols do (a tracker's origin is anywhere); one larger than
    the tolerance may be that origin, or a phantom set down off its place, or a localisation
    error, and a verdict that passes it says so. ``ver.offsets`` (6,) m and rad."""
    if not ver.frame.removes_offsets:
        return ""
    offsets = np.asarray(getattr(ver, "offsets", np.zeros(6)), dtype=float)
    measured = np.asarray(ver.measured.measured, dtype=bool)
    beyond = measured & (np.abs(offsets) > axis_tolerances(tolerance))
    if not np.any(beyond):
        return ""
    amounts = ", ".join(
        f"{AXES[k]} {offsets[k] * 1e3:+.4g} mm"
        if k >= 3
        else f"{AXES[k]} {'+' if offsets[k] > 0 else '-'}{axis_amount(int(k), offsets[k])}"
        for k in np.flatnonzero(beyond)
    )
    return (
        f"; a constant removed and not judged, larger than the tolerance: {amounts} (each "
        "measured axis's mean error, with --frame axes: a tracker's origin, a phantom set down "
        "off its place, or a localisation error; --frame base or --registration judges it)"
    )


def outliers(x: np.ndarray, x_d: np.ndarray, measured, tolerance, removes_offsets=False) -> dict:
    """The frames far off the rest (a marker mis-detected, a reflection taken for it): those
    whose error x - x_d on some measured axis lies beyond :data:`OUTLIER_SIGMAS` robust standard
    deviations of that axis's error from its median and beyond :data:`OUTLIER_TOLERANCES` times
    its tolerance.

    Args:
        x, x_d: (n, 6) the frames measured and the reference's, rad and m (NaN where not
            measured). measured: (6,) bool. tolerance: (m, rad). removes_offsets:
            the frames remove each axis's mean error (``--frame axes``): the other frames'
            RMS is then about their own mean, as a verdict without the outliers takes it.
    Returns:
        {"frames": how many, "samples": n, "largest": (6,) the largest |error - median| beyond
        its axis's bound (0 on an axis where no frame is: an outlier on Y is no reason to name
        its X), "rest_rms": (6,) the RMS error of the other frames (NaN not measured), "mask":
        (n,) which frames}.
    """
    measured = np.asarray(measured, dtype=bool)
    e = np.where(measured, np.asarray(x, dtype=float) - np.asarray(x_d, dtype=float), 0.0)
    centred = np.abs(e - np.median(e, axis=0))
    sigma = 1.4826 * np.median(centred, axis=0)
    bound = np.maximum(OUTLIER_SIGMAS * sigma, OUTLIER_TOLERANCES * axis_tolerances(tolerance))
    beyond = (centred > bound) & measured
    flagged = np.any(beyond, axis=1)
    rest = e[~flagged] if np.any(~flagged) else e
    if removes_offsets:
        rest = rest - rest.mean(axis=0)
    return {
        "frames": int(flagged.sum()),
        "samples": int(len(e)),
        "largest": np.where(beyond, centred, 0.0).max(axis=0, initial=0.0),
        "rest_rms": np.where(measured, rms_per_axis(rest), np.nan),
        "mask": flagged,
    }


def outlier_words(found: dict, measured, tolerance, excluded: int = 0) -> str:
    """The verdict line's words on :func:`outliers` ("" when there are none and none were
    excluded): how many, how far, the other frames' RMS (on the clock the outliers helped find:
    a glitch moves the clock, so the figure is a guide, not the verdict of the rest), and the
    option that judges without them on their own clock; or, ``excluded`` > 0, how many were left
    out."""
    if excluded:
        return (
            f"; {excluded} frames excluded as outliers (--exclude-outliers: beyond "
            f"{OUTLIER_SIGMAS:g} robust SD and {OUTLIER_TOLERANCES:g}x the tolerance from the "
            "median error on some axis); the rest judged"
        )
    if not found or not found.get("frames"):
        return ""
    measured = np.asarray(measured, dtype=bool)
    tol = axis_tolerances(tolerance)
    largest = np.asarray(found["largest"], dtype=float)
    far = ", ".join(
        f"{AXES[k]} {axis_amount(int(k), largest[k])}"
        for k in np.flatnonzero(measured & (largest > 0))
    )
    rest = np.asarray(found["rest_rms"], dtype=float)
    rest_ok = axes_within(rest, tol, measured)
    rms = ", ".join(  # below a nanometre or nanoradian: 0, not float noise
        f"{AXES[k]} {axis_amount(int(k), rest[k] if rest[k] >= 1e-9 else 0.0)}"
        for k in np.flatnonzero(measured)
    )
    return (
        f"; {found['frames']} of {found['samples']} frames compared are outliers (beyond "
        f"{OUTLIER_SIGMAS:g} robust SD and {OUTLIER_TOLERANCES:g}x the tolerance from the "
        f"median error on some axis; up to {far} off it: a marker mis-detected?); the other "
        f"{found['samples'] - found['frames']} frames, on the clock found with the outliers: "
        f"RMS {rms}, {'within' if rest_ok else 'beyond'} the tolerance; --exclude-outliers "
        "judges without them, on a clock found without them"
    )


__all__ = [
    "MAX_UNCOMPARED_SHARE",
    "NAMED_PAUSES",
    "seconds",
    "uncompared_words",
    "pause_words",
    "removed_offset_words",
    "OUTLIER_SIGMAS",
    "OUTLIER_TOLERANCES",
    "outliers",
    "outlier_words",
]
