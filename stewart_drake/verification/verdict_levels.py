"""The levels of a measured motion's verdict per axis (``stewart-drake verify``): PASS within the
tolerance, FAIL beyond it, and ACTION within it but beyond an action level (TG-142's action
level, pylinac's ``action_tolerance``: to be looked at before it fails); the action level's
check against the tolerance and the verdict line's words on the axes beyond it. The verdict
itself is :func:`~.measured_verdict.judge`'s.
"""

from __future__ import annotations

import numpy as np

from ..base.verdicts import axis_level
from ..organ_motion.fidelity import AXES, format_angle, format_length
from .verdict_sensitivity import axis_amount, axis_tolerances


def axis_levels(rms, measured, tolerance, action_level=None) -> dict:
    """{axis: "PASS", "ACTION" or "FAIL"} per measured axis: FAIL when its RMS error is beyond
    the tolerance, ACTION when within it but beyond the action level (when given), else PASS.

    Args:
        rms: (6,) RMS error per axis, rad and m. measured: (6,) bool. tolerance, action_level:
            (m, rad); action_level may be None.
    """
    tol = axis_tolerances(tolerance)
    act = None if action_level is None else axis_tolerances(action_level)
    return {
        AXES[k]: axis_level(rms[k], tol[k], None if act is None else act[k])
        for k in np.flatnonzero(measured)
    }


def check_action_level(action_level, tolerance) -> None:
    """Refuse an action level not within (0, tolerance] on both kinds of axis.

    Raises:
        InvalidConfigError: naming ``--action-level`` and the bound.
    """
    from ..base.errors import InvalidConfigError

    for value, limit, what, shown in zip(
        action_level, tolerance, ("length", "angle"), (format_length, format_angle)
    ):
        if not 0.0 < value <= limit:
            raise InvalidConfigError(
                f"--action-level: its {what} must be above 0 and at most the --tolerance's "
                f"{shown(limit)}, got {shown(value)}"
            )


def action_words(action: dict, action_level) -> str:
    """The verdict line's note on the axes beyond the action level, or "" without any."""
    if not action:
        return ""
    axes = ", ".join(f"{a} {axis_amount(AXES.index(a), v)}" for a, v in action.items())
    return (
        f"; beyond the action level {format_length(action_level[0])} | "
        f"{format_angle(action_level[1])}: {axes} (within the tolerance: to be looked at "
        "before it fails)"
    )


__all__ = ["axis_levels", "check_action_level", "action_words"]
