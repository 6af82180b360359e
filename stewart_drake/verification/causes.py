"""The causes of a measured motion's errors (``stewart-drake verify``'s FAIL, :func:`causes_of`),
found from the aligned motion over the window, per measured axis k with the reference's motion
r_k and the measured q_k, each less its mean:

- the phantom at rest: every measured axis along which the reference moves moved less than
  :data:`AT_REST_SHARE` of it (RMS);
- a sign: q_k runs against r_k (correlation below -:data:`FOLLOWS_CORRELATION`), or, reversed,
  matches the reference much better at another shift (:func:`reversed_match`);
- another motion, another period, or noise: q_k hardly follows r_k (correlation within
  +-:data:`FOLLOWS_CORRELATION`), its dominant period told apart from the reference's by more
  than :data:`PERIOD_SHARE` when it has one;
- a scale: q_k follows r_k with a gain g (least squares of q_k on r_k) whose error
  |g - 1| RMS(r_k) alone takes more than half the tolerance;
- another shape: the part of q_k that no scale of r_k explains, RMS(q_k) sqrt(1 - rho^2),
  exceeds the tolerance;
- an axis swapped or mislabelled: q_k moves more than the tolerance where the reference holds
  still, and says which of the reference's axes it follows;
- a constant offset (frames that remove none): the mean error of an axis over half the
  tolerance (the phantom set down off its place or tilted, or a registration out of date);
- the measured axes turned from the reference's (a tracker's frame turned), found by the least
  turn that matches them.

The verdict itself, and the causes it adds (the latency beyond its bound; the motion's shape
when none of these), are :mod:`~.measured_verdict`'s.
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..base.measures import rms_per_axis
from ..base.signals import PERIOD_POWER_SHARE, centred, dominant_period
from ..base.verdicts import axes_within
from ..organ_motion.fidelity import AXES, format_length
from .verdict_notes import (
    seconds,
)
from .verdict_sensitivity import (
    MAX_TURN_RAD,
    axis_amount,
    axis_tolerances,
)

#: A measured axis moved less than this share of the reference's motion (RMS) is at rest.

#: A measured axis moved less than this share of the reference's motion (RMS) is at rest.
AT_REST_SHARE = 0.1


#: A measured axis follows the reference's when their correlation exceeds this (runs against it
#: below its negative).
FOLLOWS_CORRELATION = 0.5


#: Two dominant periods differing by more than this share are told apart.
PERIOD_SHARE = 0.05


#: A measured axis whose sign reversed matches its reference this many times better (the least
#: mean squared distance at its best shift, :func:`reversed_match`) runs the wrong way.
REVERSED_RATIO = 0.25

#: The largest further shift searched with a turn of the measured axes, s (half a breath).
TURN_SEARCH_S = 2.5


def _signed(k: int, v: float) -> str:
    """An axis's signed amount as text (mm or deg)."""
    return f"{v * 1e3:+.3g} mm" if k >= 3 else f"{math.degrees(v):+.3g} deg"


def axis_figures(t, x, x_d, measured) -> dict:
    """{axis: figures} of each measured axis over the samples given (module docstring; keys as
    :class:`~.measured_verdict.Judgement`'s ``axes``): t (n,) s; x (n, 6) the aligned measured
    poses; x_d (n, 6) the reference's; measured (6,) bool."""
    out = {}
    for k in np.flatnonzero(measured):
        q, r = centred(x[:, k]), centred(x_d[:, k])
        var_q, var_r, cov = float(np.mean(q * q)), float(np.mean(r * r)), float(np.mean(q * r))
        both = var_q > 0 and var_r > 0
        period, share = dominant_period(t, x[:, k])
        ref_period, ref_share = dominant_period(t, x_d[:, k])
        out[AXES[k]] = {
            "rms": float(rms_per_axis(x[:, k] - x_d[:, k])),
            "motion_rms": math.sqrt(var_q),
            "reference_rms": math.sqrt(var_r),
            "gain": cov / var_r if var_r > 0 else math.nan,
            "correlation": cov / math.sqrt(var_q * var_r) if both else math.nan,
            "mean_error": float(np.mean(x[:, k] - x_d[:, k])),
            "period_s": period if share >= PERIOD_POWER_SHARE else math.nan,
            "reference_period_s": ref_period if ref_share >= PERIOD_POWER_SHARE else math.nan,
        }
    return out


def _correlation(a, b) -> float:
    """The correlation of a (n,) and b (n,) (0 when either does not vary)."""
    a, b = centred(a), centred(b)
    den = math.sqrt(float(np.mean(a * a) * np.mean(b * b)))
    return float(np.mean(a * b)) / den if den > 0 else 0.0


def _least_turn(q, x_d, seen) -> tuple:
    """(the turn, the reference's centred positions r (n, 3), the RMS distance after it) of the
    centred measured positions q (n, 3) onto x_d's (n, 6) translations: Kabsch on the measured
    axes ``seen``."""
    from scipy.spatial.transform import Rotation

    r = np.zeros((len(q), 3))
    r[:, seen] = x_d[:, 3:][:, seen] - np.mean(x_d[:, 3:][:, seen], axis=0)
    # A motion along one line leaves a turn about it free: three unit pairs of a thousandth of
    # the motion's weight take the least turn among those that fit alike.
    eye = np.eye(3)
    weights = np.concatenate([np.ones(len(q)), np.full(3, 1e-3 * float(np.sum(r * r)))])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)
        turn, _ = Rotation.align_vectors(np.vstack([r, eye]), np.vstack([q, eye]), weights)
    after = float(np.sqrt(np.mean(np.sum((turn.apply(q) - r) ** 2, axis=1))))
    return turn, r, after


def _angle(fit) -> float:
    return float(fit[0].magnitude())


#: How near a quarter or a half turn (deg) a turn of the measured axes is one: its axes' own
#: words (swapped, reversed) say all of it, and the turn is not named again.
QUARTER_SLACK_DEG = 10.0


def _turned_axes(x, x_d, measured, tolerance, t=None, reference=None) -> tuple[str | None, float]:
    """(the cause, the turn, rad) when the measured translations (n, 6) are the reference's
    x_d (n, 6) turned (a tracker whose axes are not the base frame's, or a whole phantom set
    down tilted): the least turn between their motions (Kabsch on the centred positions of the
    two or three measured translations), at any angle over 1 deg, when the measured motion
    turned back either comes within a quarter of its distance from the reference's or within
    the ``tolerance`` (m, rad) on every measured translation; else (None, the turn). Beyond
    :data:`MAX_TURN_RAD` only the latter names it, and the words add that a quarter or half
    turn is also an axis swapped or reversed. With the times t (n,) on the reference's clock
    and the reference, the turn and a further shift (within half the reference's period, or
    :data:`TURN_SEARCH_S`) are found
    together (:func:`~.alignment.rigid_shift`: the best rotation at every shift): a
    turn that moves the motion off the axes it was asked along (a quarter turn) leaves the
    clock's own search with nothing to match; of the two fits (on the verdict's clock, and
    shifted), the least turn of those alike. Words only: the verdict is not changed."""
    seen = [k - 3 for k in (3, 4, 5) if measured[k]]
    if len(seen) < 2:
        return None, 0.0
    q = np.zeros((len(x), 3))
    q[:, seen] = x[:, 3:][:, seen] - np.mean(x[:, 3:][:, seen], axis=0)
    candidates = [x_d]  # the reference on the clock the verdict found
    if t is not None and reference is not None and len(t) > 10:
        from .alignment import reference_poses, rigid_shift

        period = getattr(reference, "repeat_period_s", None) or 2 * TURN_SEARCH_S
        half = min(0.5 * float(period), TURN_SEARCH_S)
        step = max(0.02, float(np.median(np.diff(t))))
        y = np.zeros((len(t), 3))
        y[:, seen] = x[:, 3:][:, seen]
        d, _ = rigid_shift(np.asarray(t, dtype=float), y, reference, (-half, half), step)
        candidates.append(reference_poses(reference, np.asarray(t, dtype=float) + d))
    fits = [_least_turn(q, candidate, seen) for candidate in candidates]
    # A motion in a plane fits a half turn about its normal half a period on as well as its own
    # turn: of the fits alike (within a tenth of the tolerance), the least turn.
    best = min(fit[2] for fit in fits)
    turn, r, after = min((f for f in fits if f[2] <= best + 0.1 * tolerance[0]), key=_angle)
    angle = float(turn.magnitude())
    back = turn.apply(q) - r
    before = float(np.sqrt(np.mean(np.sum((q - r) ** 2, axis=1))))
    within = axes_within(rms_per_axis(back[:, seen]), tolerance[0])
    large = angle > MAX_TURN_RAD
    # A large turn must explain the motion to the tolerance: it competes with an axis's own
    # causes (a reversed axis and a scaled one fit a half turn to a quarter of their distance).
    if not (math.radians(1.0) < angle and (within if large else after < 0.25 * before or within)):
        return None, angle
    return (
        f"the measured motion is turned {math.degrees(angle):.3g} deg from the reference's "
        f"(turned back, it comes within {format_length(after)} RMS of it, against "
        f"{format_length(before)}): the tracker's axes are not the base frame's"
        + (" (a quarter or half turn is also an axis swapped or reversed)" if large else "")
        + ", or the whole phantom is set down tilted; register the tracker (--registration "
        "REG.yaml, from fiducials or calibrate --register) to tell them apart",
        angle,
    )


def reversed_match(t, v, k: int, reference, span_s: float) -> tuple[float, float]:
    """(ratio, delta s): how much nearer the reference's axis k the measured axis v (n,) at the
    times t (n,) (the reference's clock) comes with its sign reversed than as it is, each at its
    best further shift within +-``span_s`` (each less its mean): the ratio of the two least mean
    squared distances, reversed over as is (below 1: reversed is nearer; 0: reversed, it matches
    exactly), and the shift at which
    reversed is nearest (:func:`~stewart_drake.base.lag.shift_scores` on that axis alone)."""
    from ..base.lag import shift_scores
    from .alignment import reference_poses

    y = np.zeros((len(t), 6))
    weights = np.zeros(6)
    weights[k] = 1.0
    step = max(0.02, float(np.median(np.diff(t))))

    def seen(times):
        return reference_poses(reference, times)

    best = []
    for sign in (1.0, -1.0):
        y[:, k] = sign * v
        d, score = shift_scores(t, y, weights, seen, (-span_s, span_s), step, True)
        # A mean square, though the FFT's rounding leaves an exact match a little below zero.
        best.append((max(float(np.min(score)), 0.0), float(d[int(np.argmin(score))])))
    (as_is, _), (flipped, delta) = best
    return (flipped / as_is if as_is > 0 else math.inf), delta


@dataclass(frozen=True)
class AxisCase:
    """What a criterion reads of one measured axis along which the reference moves.

    Attributes:
        t: (n,) s, the reference's clock. x: (n, 6) the aligned measured poses. k: the axis's
            index. fk: its :func:`axis_figures`. reference: the reference, or None (criteria
            that need it pass).
    """

    t: np.ndarray
    x: np.ndarray
    k: int
    fk: dict
    reference: Any


@dataclass(frozen=True)
class Criterion:
    """A criterion a measured axis along which the reference moves is judged by.

    Attributes:
        name: its name: the key under which each place that judges writes its words.
        compares: what it compares, in words. threshold: what fails, in words.
        fails: ``fails(case)`` (an :class:`AxisCase`): None when the axis meets it, else the
            figures its words take (a tuple, maybe empty).
    """

    name: str
    compares: str
    threshold: str
    fails: Callable[[AxisCase], tuple | None]

    def words(self, axis: str) -> str:
        """Its words where a place has none of its own: "<axis> fails <name> (<compares>:
        <threshold>)"."""
        return f"{axis} fails {self.name} ({self.compares}: {self.threshold})"


def at_rest(fk: dict) -> bool:
    """Whether a measured axis along which the reference moves is at rest: its RMS motion
    below :data:`AT_REST_SHARE` of the reference's (``fk``: its :func:`axis_figures`)."""
    return fk["motion_rms"] < AT_REST_SHARE * fk["reference_rms"]


def _at_rest(case: AxisCase) -> tuple | None:
    return () if at_rest(case.fk) else None


def _runs_against(case: AxisCase) -> tuple | None:
    return () if case.fk["correlation"] < -FOLLOWS_CORRELATION else None


def _reversed(case: AxisCase) -> tuple | None:
    if case.reference is None:
        return None
    period = getattr(case.reference, "repeat_period_s", None) or 4.0
    ratio, delta = reversed_match(
        case.t, case.x[:, case.k], case.k, case.reference, min(0.5 * period, 2.0)
    )
    return (ratio, delta) if ratio < REVERSED_RATIO else None


def _another_period(case: AxisCase) -> tuple | None:
    own, ref_period = case.fk["period_s"], case.fk["reference_period_s"]
    apart = (
        math.isfinite(own)
        and math.isfinite(ref_period)
        and abs(own / ref_period - 1.0) > PERIOD_SHARE
    )
    return () if apart else None


def _not_following(case: AxisCase) -> tuple | None:
    return () if not case.fk["correlation"] > FOLLOWS_CORRELATION else None


#: The criteria a measured axis along which the reference moves is judged by, in the order
#: :func:`moving_axis_cause` tries them: the one list for a motion judged alone
#: (:func:`causes_of`) and with its surrogate
#: (:func:`~stewart_drake.verification.pair_causes.why_not_following`), and the one place a
#: criterion is added (docs/development.md, "Where a maintainer adds a thing"). Each place writes
#: its own words for the criteria it knows, and :meth:`Criterion.words` for one it does not.
CRITERIA: list[Criterion] = [
    Criterion(
        "at rest", "its RMS motion against the reference's", "below AT_REST_SHARE of it", _at_rest
    ),
    Criterion(
        "runs against",
        "its correlation with the reference",
        "below -FOLLOWS_CORRELATION",
        _runs_against,
    ),
    Criterion(
        "reversed",
        "it reversed against as it is, each at its best shift (reversed_match)",
        "nearer by more than 1 / REVERSED_RATIO",
        _reversed,
    ),
    Criterion(
        "another period",
        "its dominant period against the reference's",
        "apart by more than PERIOD_SHARE",
        _another_period,
    ),
    Criterion(
        "not following",
        "its correlation with the reference",
        "not above FOLLOWS_CORRELATION",
        _not_following,
    ),
]


def moving_axis_cause(
    t, x, k: int, fk: dict, reference, skip: tuple = ()
) -> tuple[Criterion | None, tuple]:
    """The first of :data:`CRITERIA` (its names in ``skip`` left out) that the measured axis
    ``k`` fails, in their order, or None when it follows its reference.

    Args:
        t: (n,) s, the reference's clock. x: (n, 6) the aligned measured poses. k: the axis.
        fk: the axis's :func:`axis_figures`. reference: the reference (None: the reversed
            criterion is not tried). skip: criteria not tried (the pair judges "at rest" over
            every axis at once).
    Returns:
        (the :class:`Criterion` failed, or None; the figures its words take: (ratio, delta s)
        of :func:`reversed_match` for "reversed", () for the others).
    """
    case = AxisCase(t, x, k, fk, reference)
    for criterion in CRITERIA:
        if criterion.name in skip:
            continue
        figures = criterion.fails(case)
        if figures is not None:
            return criterion, figures
    return None, ()


def causes_of(
    t,
    x,
    x_d,
    measured,
    moving,
    tolerance,
    removes_offsets: bool,
    reference=None,
    latency_s=0.0,
    lever_m=0.0,
) -> tuple[list, bool]:
    """(causes, follows): the causes of the errors over the samples given (module docstring),
    one phrase each, and whether the measured motion follows the reference at all (no axis at
    rest, reversed, of another period or not following: else its latency means nothing).

    Args:
        t: (n,) s. x, x_d: (n, 6) the aligned measured poses and the reference's. measured,
            moving: (6,) bool, the axes measured and those along which the reference moves.
        tolerance: (m, rad). removes_offsets: the frames removed each axis's offset.
        reference: when given, a sign is found even where the clock's shift hid it (the axis
            reversed matches the reference much better at another shift).
        latency_s: the latency found, s, for the words of a reversed axis.
        lever_m: the distance of a registered marker of positions only from the platform's
            origin, m (0 otherwise): taken off along the reference's rotation, it shows as
            motion where the platform does not turn as asked, which the words say.
    """
    tol = axis_tolerances(tolerance)
    figures = axis_figures(t, x, x_d, measured)
    seen = [int(k) for k in np.flatnonzero(measured)]
    moving_seen = [k for k in seen if moving[k]]
    f = {k: figures[AXES[k]] for k in seen}
    # At rest: along the reference's motion, less than a share of it (never the tolerance: a
    # motion smaller than the tolerance moved all the same); where it holds still, within the
    # tolerance.
    still = all(at_rest(f[k]) if moving[k] else f[k]["motion_rms"] <= tol[k] for k in seen)
    if moving_seen and still:
        moved = ", ".join(
            f"{AXES[k]} {axis_amount(k, f[k]['motion_rms'])} RMS against the reference's "
            f"{axis_amount(k, f[k]['reference_rms'])}"
            for k in moving_seen
        )
        return [f"the phantom did not move ({moved})"], False
    turned, angle = (
        _turned_axes(x, x_d, measured, tolerance, t, reference) if removes_offsets else (None, 0.0)
    )
    if turned is not None and angle <= MAX_TURN_RAD:
        return [turned], True
    causes, follows = _moving_axes_causes(t, x, f, moving_seen, tol, reference, latency_s)
    causes += _still_axes_causes(x, x_d, f, seen, moving, tol, removes_offsets, lever_m)
    if not removes_offsets:
        causes += _offset_causes(f, seen, tol)
    if turned is not None and not _turn_said(angle, causes, moving_seen):
        causes.append(turned)
    return causes, follows


def _moving_axes_causes(t, x, f, moving_seen, tol, reference, latency_s) -> tuple[list, bool]:
    """(causes, follows) of the measured axes along which the reference moves (``f``: each
    axis's :func:`axis_figures`; ``tol``: each axis's tolerance): at rest, reversed, another
    period, not following, another amplitude or shape."""
    causes: list[str] = []
    follows = True
    for k in moving_seen:
        a, fk = AXES[k], f[k]
        rho, gain = fk["correlation"], fk["gain"]
        criterion, figures = moving_axis_cause(t, x, k, fk, reference)
        cause = None if criterion is None else criterion.name
        if cause == "at rest":
            causes.append(
                f"{a} did not move ({axis_amount(k, fk['motion_rms'])} RMS where the reference "
                f"moves {axis_amount(k, fk['reference_rms'])})"
            )
            follows = False
            continue
        if cause == "reversed":
            ratio, delta = figures
            better = f"{1 / ratio:.0f} times better" if ratio > 0 else "exactly"
            causes.append(
                f"{a} runs the wrong way (reversed, it matches the reference {better}, at a "
                f"latency of {seconds(latency_s - delta)}): a sign flipped or the axis reversed"
            )
            follows = False
            continue
        follows = follows and cause is None
        if cause == "runs against":
            causes.append(
                f"{a} runs the wrong way (correlation {rho:+.2f} with the reference, gain "
                f"{gain:+.2f}): a sign flipped or the axis reversed"
            )
        elif cause == "another period":
            causes.append(
                f"{a} repeats every {fk['period_s']:.3g} s where the reference does every "
                f"{fk['reference_period_s']:.3g} s: another period"
            )
        elif cause == "not following":
            causes.append(
                f"{a} does not follow the reference (correlation {rho:+.2f}): another motion, "
                "or noise"
            )
        elif criterion is not None:  # a criterion without words of its own here
            causes.append(criterion.words(a))
        else:
            if abs(gain - 1.0) * fk["reference_rms"] > 0.5 * tol[k]:
                causes.append(f"{a} moves {gain:.3g}x the reference's amplitude")
            shape = fk["motion_rms"] * math.sqrt(max(1.0 - rho * rho, 0.0))
            if shape > tol[k]:
                causes.append(
                    f"{a} departs from the reference's shape ({axis_amount(k, shape)} RMS of it "
                    f"that no scale of the reference explains; correlation {rho:.3f}): another "
                    "motion, or the motion distorted"
                )
                follows = False
    return causes, follows


def _still_axes_causes(x, x_d, f, seen, moving, tol, removes_offsets, lever_m) -> list[str]:
    """The causes of the measured axes that move where the reference holds still: following
    another of its axes (swapped or mislabelled, a frame turned), or a marker's lever arm."""
    causes = []
    for k in seen:
        if moving[k] or f[k]["motion_rms"] <= tol[k]:
            continue
        likeness = [  # the reference's axes of the same kind (a translation's translations)
            (abs(_correlation(x[:, k], x_d[:, j])), j)
            for j in np.flatnonzero(moving)
            if j != k and (j >= 3) == (k >= 3)
        ]
        best = max(likeness, default=(0.0, -1))
        moves = axis_amount(k, f[k]["motion_rms"])
        text = f"{AXES[k]} moves {moves} RMS where the reference holds still"
        swapped = best[0] > 0.8 and f[k]["motion_rms"] > 0.5 * float(np.std(x_d[:, best[1]]))
        if swapped:
            text += (
                f" (it follows the reference's {AXES[best[1]]}: axes swapped or mislabelled"
                + (", or the tracker's frame turned from the base's" if removes_offsets else "")
                + "?)"
            )
        elif lever_m > 0 and bool(np.any(moving[:3])):
            text += (
                f" (the marker, {lever_m * 1e3:.3g} mm from the platform's origin, is taken off "
                "along the reference's rotation: a platform that does not turn as asked shows "
                "that lever arm as motion)"
            )
        causes.append(text)
    return causes


def _offset_causes(f, seen, tol) -> list[str]:
    """A constant offset over half an axis's tolerance, named (where the frames kept it)."""
    off = [k for k in seen if abs(f[k]["mean_error"]) > 0.5 * tol[k]]
    if not off:
        return []
    return [
        "a constant offset of "
        + ", ".join(f"{AXES[k]} {_signed(k, f[k]['mean_error'])}" for k in off)
        + " (the phantom set down off its place or tilted, or a registration out of "
        "date)"
    ]


def _turn_said(angle: float, causes: list, moving_seen: list) -> bool:
    """Whether the axes' own words already say a turn of ``angle`` (rad).

    A turn beyond MAX_TURN_RAD, named after each axis's words unless they say it already: a
    quarter or half turn (within QUARTER_SLACK_DEG) whose words are an axis swapped, or every
    moving axis reversed with nothing moving where the reference holds still. A turn between
    (135 deg) reverses one axis and moves another: only the turn names the whole.
    """
    degrees = math.degrees(angle)
    square = min(abs(degrees - 90.0), abs(degrees - 180.0)) <= QUARTER_SLACK_DEG
    reversed_all = all(
        any(c.startswith(f"{AXES[k]} runs the wrong way") for c in causes) for k in moving_seen
    )
    stray = any("where the reference holds still" in c for c in causes)
    swapped = any("axes swapped" in c for c in causes)
    return square and (swapped or (reversed_all and not stray))


__all__ = [
    "AT_REST_SHARE",
    "AxisCase",
    "CRITERIA",
    "Criterion",
    "FOLLOWS_CORRELATION",
    "PERIOD_SHARE",
    "REVERSED_RATIO",
    "moving_axis_cause",
    "at_rest",
    "axis_figures",
    "causes_of",
    "reversed_match",
]
