"""What a FAIL of an internal motion judged with its surrogate names (:mod:`.pair_judgement`):
a motion that does not follow its reference (at rest, reversed, of another period, another
motion) and two measurements swapped."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from ..organ_motion.fidelity import AXES, MOVING_P2P
from .causes import at_rest, axis_figures, moving_axis_cause
from .verdict_notes import seconds

#: Two measurements are swapped when each one's mean squared distance (each less its mean) to the
#: other's reference is under this share of its distance to its own: 4 times nearer the other's.
SWAPPED_RATIO = 0.25
#: One platform played the other's trace when its measurement's mean squared distance to the
#: other's reference is at most this share of its distance to its own (it comes 1.25 times nearer
#: the other's reference), while the other measurement is nearer its own. A right pair's
#: measurements come about 1.8 times nearer their own (shares 0.54 and 0.55 the other way on the
#: example pair; IntERAct's 21 right pairs 3.1 to 109 times nearer their own); one that played the
#: other's trace 1.86 times nearer the other's.
PLAYED_RATIO = 0.8
#: Shifts searched around the internal's for the swap's test, s either way.
SWAP_SEARCH_S = 5.0
#: Two matches whose scores differ by less than this share of the scores' range are a tie (a
#: reference that repeats, a period apart): the one nearer the pair's clock is taken.
TIE_SHARE = 0.05


def why_not_following(reference, t, x, x_d, measured) -> str | None:
    """None when the measured motion follows its reference (so that its clock means something),
    else why not, in words: at rest (every measured axis along which the reference moves moved
    less than :data:`~stewart_drake.verification.causes.AT_REST_SHARE` of it, RMS, as
    ``verify``'s verdict says it: against the reference's own motion, not the tolerance), then
    the first of the single motion's criteria an axis fails
    (:data:`~stewart_drake.verification.causes.CRITERIA`, through
    :func:`~stewart_drake.verification.causes.moving_axis_cause`, the one list of them): runs
    against its reference, reversed, another period, not following. A scale or a shape error
    does not stop the clock meaning something: the fidelity's verdict judges those.

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
    if all(at_rest(f[AXES[k]]) for k in axes):
        moved = ", ".join(
            f"{AXES[k]} {f[AXES[k]]['motion_rms'] * 1e3:.3g} mm RMS against its reference's "
            f"{f[AXES[k]]['reference_rms'] * 1e3:.3g} mm"
            if k >= 3
            else f"{AXES[k]} {math.degrees(f[AXES[k]]['motion_rms']):.3g} deg RMS"
            for k in axes
        )
        return f"did not move ({moved})"
    for k in axes:
        fk = f[AXES[k]]
        rho = fk["correlation"]
        criterion, figures = moving_axis_cause(t, x, k, fk, reference, skip=("at rest",))
        cause = None if criterion is None else criterion.name
        if cause == "runs against":
            return f"runs the wrong way on {AXES[k]} (correlation {rho:+.2f} with its reference)"
        if cause == "reversed":
            ratio = figures[0]
            better = f"{1 / ratio:.0f} times better" if ratio > 0 else "exactly"
            return (
                f"runs the wrong way on {AXES[k]} (reversed, it matches its reference {better}): "
                "a sign flipped or the axis reversed"
            )
        if cause == "another period":
            own, ref = fk["period_s"], fk["reference_period_s"]
            return (
                f"repeats every {own:.3g} s on {AXES[k]} where its reference does every {ref:.3g} s"
            )
        if cause == "not following":
            return (
                f"does not follow its reference on {AXES[k]} (correlation {rho:+.2f}): another "
                "motion, or noise"
            )
        if criterion is not None:  # a criterion without words of its own here
            return criterion.words(AXES[k])
    return None


# -- swapped files ---------------------------------------------------------------------------------


def _axis_moving_most(measured, reference, t_ref) -> int | None:
    """The measured axis (a column: a camera may see one) along which the reference moves most
    (by its RMS, a rotation weighted as verify's clock weighs it), or None; not the principal
    direction, which is a direction in space (:func:`~stewart_drake.base.signals.
    principal_direction`)."""
    from .alignment import axis_weights, reference_poses

    x_d = reference_poses(reference, t_ref)
    spread = np.std(x_d, axis=0) * axis_weights(measured)
    spread[np.ptp(x_d, axis=0) <= np.asarray(MOVING_P2P)] = 0.0
    return int(np.argmax(spread)) if np.any(spread > 0) else None


def _best_match(
    t, v, reference, j: int, shifts: tuple, step: float, around_s: float
) -> tuple[float, float]:
    """(the least mean squared distance, each less its mean, between v (n,) at the times t (n,)
    and the reference's axis j over the ``shifts`` (lo, hi) s, in v's units squared; the shift
    where it is, s). Of the coarse scores' local minima within :data:`TIE_SHARE` of the least
    (a reference that repeats matches a period away about as well), the one nearest
    ``around_s`` is taken, then refined to a microsecond
    (:func:`~stewart_drake.base.lag.shift_scores`, :func:`~stewart_drake.base.lag.refine_shift`)
    and scored there (:func:`~stewart_drake.base.lag.shift_score`)."""
    from ..base.lag import refine_shift, shift_score, shift_scores
    from .alignment import reference_poses

    y = np.asarray(v, dtype=float)[:, None]
    weights = np.ones(1)

    def seen(times):
        return reference_poses(reference, times)[:, j : j + 1]

    d_grid, score = shift_scores(t, y, weights, seen, shifts, step, True)
    least = float(np.min(score))
    inner = np.r_[True, score[1:] <= score[:-1]] & np.r_[score[:-1] <= score[1:], True]
    ties = np.flatnonzero(inner & (score <= least + TIE_SHARE * (float(np.max(score)) - least)))
    d0 = float(d_grid[ties[np.argmin(np.abs(d_grid[ties] - around_s))]])
    d = min(max(refine_shift(t, y, weights, seen, d0, step, True), shifts[0]), shifts[1])
    return max(shift_score(t, y, weights, seen, d, True), 0.0), d


def swapped_words(
    pair_refs, pair_measured, around_s: float, relative_latency_s: float
) -> str | None:
    """The cause when the two measurements are swapped, or one platform played the other's
    trace, else None. Each measurement is matched (its axis along which its reference moves
    most, at its best shift within :data:`SWAP_SEARCH_S` of ``around_s``, each less its mean) to
    its own reference and to the other's; swapped when each one's distance to the other's
    reference is under :data:`SWAPPED_RATIO` of its distance to its own, or when each matches the
    other's at least as well and, exchanged, the pair's relative latency is smaller than as
    given; one played the other's trace when it alone comes nearer the other's reference, its
    distance to it at most :data:`PLAYED_RATIO` of its distance to its own (the other nearer its
    own). Looked for on every pair, a PASS included: a bound on the relative latency wide enough
    to hold such a pair's would pass it otherwise (a surrogate platform given the internal trace
    measures 450 ms late on the example pair, within a 0.6 s bound).

    Args:
        pair_refs: (internal reference, surrogate reference). pair_measured: (internal
            measured, surrogate measured) (:class:`~stewart_drake.verification.measured_motion.
            MeasuredMotion`). around_s: the internal's shift, s. relative_latency_s: as given,
            s.
    """
    from .verify import COARSE_STEP_S

    axes = []
    for ref, m in zip(pair_refs, pair_measured):
        k = _axis_moving_most(m.measured, ref, m.t + around_s)
        if k is None:
            return None
        axes.append(k)
    ratios, crossed = [], []
    for own in (0, 1):
        m = pair_measured[own]
        step = max(COARSE_STEP_S, float(np.median(np.diff(m.t))))
        shifts = (around_s - SWAP_SEARCH_S, around_s + SWAP_SEARCH_S)
        v = np.asarray(m.poses[:, axes[own]], dtype=float)
        mine, _ = _best_match(m.t, v, pair_refs[own], axes[own], shifts, step, around_s)
        theirs, d = _best_match(m.t, v, pair_refs[1 - own], axes[1 - own], shifts, step, around_s)
        ratios.append(math.inf if theirs <= 0 else mine / theirs)
        crossed.append(d)
    exchanged = crossed[0] - crossed[1]  # the surrogate's reference's shift less the internal's
    strong = all(r > 1.0 / SWAPPED_RATIO for r in ratios)
    in_sync = all(r >= 1.0 for r in ratios) and abs(exchanged) < abs(relative_latency_s)
    a, b = (Path(m.path).name for m in pair_measured)
    if not (strong or in_sync):
        return _played_words(ratios, (a, b))
    return (
        f"the two measurements swapped: {a} comes {ratios[0]:.3g} times nearer the surrogate's "
        f"reference than the internal's, and {b} {ratios[1]:.3g} times nearer the internal's "
        f"than the surrogate's (mean squared distances); exchanged, their relative latency is "
        f"{seconds(exchanged)}: give each file to its option"
    )


def _played_words(ratios: list, names: tuple) -> str | None:
    """The cause when one measurement alone comes nearer the other's reference, its distance to
    it at most :data:`PLAYED_RATIO` of its distance to its own (``ratios``: each one's mean
    squared distance to its own reference over the other's), the other nearer its own; else
    None."""
    played = [r >= 1.0 / PLAYED_RATIO for r in ratios]
    if played[0] == played[1]:
        return None
    k = 0 if played[0] else 1
    if not ratios[1 - k] < 1.0:
        return None
    platform, other = ("internal", "surrogate") if k == 0 else ("surrogate", "internal")
    return (
        f"the {platform} platform played the {other}'s trace: {names[k]} comes "
        f"{ratios[k]:.3g} times nearer the {other}'s reference than the {platform}'s, where "
        f"{names[1 - k]} comes {1.0 / ratios[1 - k]:.3g} times nearer its own (mean squared "
        f"distances, each less its mean): give the {platform} platform its own trace"
    )


__all__ = [
    "SWAPPED_RATIO",
    "PLAYED_RATIO",
    "SWAP_SEARCH_S",
    "TIE_SHARE",
    "why_not_following",
    "swapped_words",
]
