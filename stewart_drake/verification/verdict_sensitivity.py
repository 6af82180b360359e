"""What a verification at a tolerance can see of the reference's motion: the smallest error of
the whole motion's scale, and the smallest tilt of the whole phantom, that would fail it
(:func:`sensitivity`); and whether it can tell the motion from none at all
(:func:`motion_unseen`: CANNOT JUDGE). Both from the reference over the window alone, never
from what was measured, so what is judged is not fitted to what judges it."""

from __future__ import annotations

import math

import numpy as np

from ..base.verdicts import axes_within
from ..organ_motion.fidelity import AXES, MOVING_P2P, format_angle, format_length

#: The largest turn of the measured axes from the base frame's that is named alone, rad: beyond
#: it a turn is named beside each axis's causes (a quarter turn is also an axis swapped or
#: reversed, which those name); and the largest tilt :func:`sensitivity` reports.
MAX_TURN_RAD = math.radians(60.0)

#: The least effect of a unit tilt on an axis that :func:`sensitivity` counts, (rad, m) per rad:
#: below it the axis does not see the tilt (round-off of a motion that does not move it).
MIN_TILT_EFFECT = (1e-9, 1e-6)

#: The base axes a tilt of the whole phantom is tried about, for :func:`sensitivity`.
_TILT_AXES = {"X": (1.0, 0.0, 0.0), "Y": (0.0, 1.0, 0.0), "Z": (0.0, 0.0, 1.0)}


def axis_tolerances(tolerance) -> np.ndarray:
    """(6,) the tolerance of each axis: the angle for the rotations, the length for the rest."""
    return np.array([tolerance[1]] * 3 + [tolerance[0]] * 3, dtype=float)


def axis_amount(k: int, v: float) -> str:
    """An axis's amount as text: a length for a translation, an angle for a rotation."""
    return format_length(abs(v)) if k >= 3 else format_angle(abs(v))


def sensitivity(t, x_d, measured, tolerance, removes_offsets: bool) -> dict:
    """What the check can see (module docstring), from the reference x_d (n, 6) over the window
    alone, on the ``measured`` (6,) bool axes at ``tolerance`` (m, rad).

    Returns:
        {"amplitude_fraction": the smallest error of the whole motion's scale (a fraction) that
        takes one measured axis's RMS error beyond its tolerance, "amplitude_axis": that axis
        (NaN, "" when the reference moves along no measured axis); "tilt_rad": the smallest
        turn of the whole phantom about an axis through the base frame's origin that does (NaN
        when none up to :data:`MAX_TURN_RAD` does),
        "tilt_about": that base axis, "tilt_axis": the measured axis that shows it}. A scale
        error e makes an axis's error e (r_k - its mean) (a scale about the motion's centre);
        a tilt a about u moves the platform by a u x p and turns it by a u, the offsets of
        ``removes_offsets`` frames taking the constant parts away.
    """
    tol = axis_tolerances(tolerance)
    seen = [int(k) for k in np.flatnonzero(measured)]
    out: dict = {"amplitude_fraction": math.nan, "amplitude_axis": ""}
    best = math.inf
    for k in seen:
        rms = float(np.std(x_d[:, k]))
        if rms > 0 and tol[k] / rms < best and np.ptp(x_d[:, k]) > MOVING_P2P[k]:
            best, out["amplitude_fraction"], out["amplitude_axis"] = (
                tol[k] / rms,
                tol[k] / rms,
                AXES[k],
            )
    tilt, about, shown = math.inf, "", ""
    p = x_d[:, 3:]
    for name, u in _TILT_AXES.items():
        moved = np.cross(np.asarray(u), p)  # (n, 3): a unit tilt's displacement
        for k in seen:
            if k >= 3:
                v = moved[:, k - 3]
                rms = float(np.std(v)) if removes_offsets else float(np.sqrt(np.mean(v * v)))
            else:
                rms = 0.0 if removes_offsets else abs(u[k])
            if rms > MIN_TILT_EFFECT[int(k >= 3)] and tol[k] / rms < tilt:
                tilt, about, shown = tol[k] / rms, name, AXES[k]
    out.update(
        {
            "tilt_rad": tilt if tilt <= MAX_TURN_RAD else math.nan,
            "tilt_about": about,
            "tilt_axis": shown,
        }
    )
    return out


def sensitivity_words(s: dict) -> str:
    """:func:`sensitivity` in words."""
    parts = []
    if math.isfinite(s["amplitude_fraction"]):
        parts.append(
            f"a scale of the whole motion off by {100 * s['amplitude_fraction']:.3g} % or more "
            f"(on {s['amplitude_axis']})"
        )
    if math.isfinite(s.get("tilt_rad", math.nan)):
        parts.append(
            f"a tilt of the whole phantom of {math.degrees(s['tilt_rad']):.3g} deg or more about "
            f"the base's {s['tilt_about']} (on {s['tilt_axis']})"
        )
    if not parts:
        return "this check sees no scale or tilt error: the reference moves along no axis measured"
    return "this check fails " + " and ".join(parts) + "; smaller ones pass"


def motion_unseen(x_d, measured, tolerance) -> str:
    """Why a check at ``tolerance`` (m, rad) cannot tell the reference's motion x_d (n, 6)
    over the window from none on the ``measured`` (6,) bool axes, or "" when it can (module
    docstring): the phantom at rest at the reference's mean pose errs by the reference's RMS
    about its mean on each axis, and would pass when every measured axis's is within the
    tolerance."""
    measured = np.asarray(measured, dtype=bool)
    tol = axis_tolerances(tolerance)
    rest = np.std(np.asarray(x_d, dtype=float), axis=0)
    seen = [int(k) for k in np.flatnonzero(measured)]
    if not seen or not axes_within(rest, tol, measured):  # at rest it would FAIL: seen
        return ""
    k = max(seen, key=lambda j: rest[j] / tol[j])
    return (
        "cannot judge: the phantom at rest would pass too (the reference moves "
        + ", ".join(f"{AXES[j]} {axis_amount(j, rest[j])}" for j in seen)
        + " RMS on the axes measured, each within the tolerance): judge at a tolerance below "
        f"{AXES[k]}'s {axis_amount(k, rest[k])}, or on a larger motion"
    )


__all__ = [
    "axis_tolerances",
    "axis_amount",
    "MAX_TURN_RAD",
    "MIN_TILT_EFFECT",
    "sensitivity",
    "sensitivity_words",
    "motion_unseen",
]
