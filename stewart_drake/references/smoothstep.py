"""The quintic smoothstep, the one blend every reference uses where a motion must start, stop or
turn without a step in its acceleration.

S(x) = 10 x^3 - 15 x^4 + 6 x^5 rises from 0 at x = 0 to 1 at x = 1 with S' and S'' zero at
both ends (the minimum-jerk polynomial of a rest-to-rest move): a step, a fade or a blend made
of it is C2. :func:`smoothstep` gives S, S' and S''; :func:`smooth_ramp` its integral, a ramp
whose slope rises smoothly from 0 to 1. Users: the organ-motion library's rounded corners,
drifts, excursions and breath-hold (:mod:`~.organ`), the tuner study's min-jerk segments and
tremor fades (:mod:`~stewart_drake.tuner.tasks`) and the robot session's homing ramp
(:class:`~stewart_drake.references.homing.HomingReference`).
"""

import numpy as np


def smoothstep(x):
    """(S, S', S'') of the quintic smoothstep S(x) = 10 x^3 - 15 x^4 + 6 x^5 on [0, 1] (0 below,
    1 above): S' and S'' vanish at both ends, so a step or a blend made of it is C2.

    Args:
        x: array-like of any shape, dimensionless (a time over the blend's length).
    Returns:
        three float arrays of x's shape: S, dS/dx, d2S/dx2 (x clipped to [0, 1] first, so the
            derivatives are 0 outside it).
    """
    x = np.clip(np.asarray(x, dtype=float), 0.0, 1.0)
    return (
        x**3 * (10.0 - 15.0 * x + 6.0 * x * x),
        30.0 * x * x * (1.0 - x) ** 2,
        60.0 * x * (1.0 - x) * (1.0 - 2.0 * x),
    )


def smooth_ramp(x, scale: float = 1.0):
    """(scale J, J', J'') of J(x), the integral of :func:`smoothstep` from -inf to x: 0 below 0,
    x - 1/2 above 1, a ramp whose slope rises smoothly from 0 to 1 over [0, 1] (C3).

    Args:
        x: array-like of any shape, dimensionless.
        scale: factor of J, multiplied into x^4 before the polynomial (a ramp of length R over
            a time s: R J(s / R) with x = s / R, scale = R).
    Returns:
        three float arrays of x's shape: scale J(x), J'(x) = S(x), J''(x) = S'(x).
    """
    x = np.asarray(x, dtype=float)
    c = np.clip(x, 0.0, 1.0)
    S, dS, _ = smoothstep(x)
    return np.where(x > 1.0, scale * (x - 0.5), scale * c**4 * (2.5 - 3.0 * c + c * c)), S, dS


__all__ = ["smoothstep", "smooth_ramp"]
