"""What the crank servo's loop survives: a plant whose gain departs from the design's (the
motor's torque per ampere, the rotors' inertia the catalogue does not know) and a delay beyond
the design's ``delay_periods`` (a slow bus, a late write), each exactly sampled.

:func:`robust_closed_loop` is one period of the loop with the estimator in it, as
:meth:`~.design.CrankLoop.closed_loop`, but with the true crank's acceleration ``g`` times the
command and the command acting ``extra_delay_s`` later than the design assumes. Writing the
extra delay as ``m`` whole periods and ``tau`` in [0, h), the command that acts switches within
each period at ``tau`` from ``a[k - d - m - 1]`` to ``a[k - d - m]`` (the modified z-transform
of the double integrator, exact for a held command):

    omega+ = omega + g (u_a tau + u_b (h - tau))
    theta+ = theta + h omega + g (u_a (tau h - tau^2 / 2) + u_b (h - tau)^2 / 2)

The loop is stable when every eigenvalue lies inside the unit circle (:func:`is_stable`);
:func:`gain_range` scans the gains about 1 that keep it so, :func:`delay_margin_s` the largest
extra delay. The shipped bus scenarios' servos hold the required
range (:mod:`stewart_drake.control.robustness`: gain 0.5 to 2 with 6 ms more delay;
tests/test_servo_margins.py); :func:`robust_range` is what a loop survives, and ``stewart-drake
analyze`` states each scenario's (:func:`margin_lines`).
"""

from __future__ import annotations

import math

import numpy as np

from ...base.checks import as_number
from ..robustness import EXTRA_DELAY_S, GAIN_RANGE, RobustRange, stable_gain_range
from .design import CrankLoop


def robust_closed_loop(loop: CrankLoop, gain: float = 1.0, extra_delay_s: float = 0.0):
    """The loop's state matrix over one period (module docstring): state [theta, omega, z, p_1
    .. p_d, theta_bar, omega_bar, delta_bar, e_1 .. e_(m + 1)], e_j = a[k - d - j] the commands
    already out of the controller's pending list, about a reference at rest.

    Raises:
        InvalidConfigError: a gain not > 0 or a negative extra delay.
    """
    g = as_number("gain", gain, 0.0, lo_open=True)
    extra = as_number("extra_delay_s", extra_delay_s, 0.0)
    d, h = loop.delay_periods, loop.h
    m = int(math.floor(extra / h + 1e-12))
    tau = extra - m * h
    i_p, i_bar = 3, 3 + d
    i_e = i_bar + 3
    n = i_e + m + 1
    unit = np.eye(n)
    L = loop.L
    xhat = np.zeros((3, n))
    xhat[:, i_bar : i_bar + 3] = np.eye(3) - np.outer(L, [1.0, 0.0, 0.0])
    xhat[:, 0] += L
    a = -loop.K[0] * unit[2] - loop.K[1] * xhat[0] - loop.K[2] * xhat[1]
    for j in range(d):
        a = a - loop.K[3 + j] * unit[i_p + j]
    believed = a if d == 0 else unit[i_p]  # what the estimator thinks acts: p_1
    newest = unit[i_p] if d > 0 else a  # a[k - d]
    u_b = newest if m == 0 else unit[i_e + m - 1]
    u_a = unit[i_e + m]
    T = np.zeros((n, n))
    T[1] = unit[1] + g * (u_a * tau + u_b * (h - tau))
    T[0] = (
        unit[0] + h * unit[1] + g * (u_a * (tau * h - 0.5 * tau * tau) + u_b * 0.5 * (h - tau) ** 2)
    )
    T[2] = unit[2] + h * xhat[0]
    for j in range(d):
        T[i_p + j] = unit[i_p + j + 1] if j < d - 1 else a
    T[i_bar : i_bar + 3] = loop.Phi @ xhat + np.outer(loop.Gamma, believed)
    T[i_e] = newest
    for j in range(1, m + 1):
        T[i_e + j] = unit[i_e + j - 1]
    return T


def spectral_radius(loop: CrankLoop, gain: float = 1.0, extra_delay_s: float = 0.0) -> float:
    """The largest eigenvalue's modulus of :func:`robust_closed_loop`."""
    return float(np.max(np.abs(np.linalg.eigvals(robust_closed_loop(loop, gain, extra_delay_s)))))


def is_stable(loop: CrankLoop, gain: float = 1.0, extra_delay_s: float = 0.0) -> bool:
    """Whether the loop with this plant gain and extra delay converges (spectral radius < 1)."""
    return spectral_radius(loop, gain, extra_delay_s) < 1.0


def gain_range(loop: CrankLoop, extra_delay_s: float = 0.0, steps: int = 400) -> tuple:
    """(lowest, highest) plant gain, about 1, for which the loop with ``extra_delay_s`` is
    stable (:func:`~stewart_drake.control.robustness.stable_gain_range`: a log grid from 1/100 to
    100 of ``steps`` gains, each edge bisected to 0.1 %); (nan, nan) when it is unstable at
    gain 1."""
    return stable_gain_range(lambda g: is_stable(loop, g, extra_delay_s), steps)


def delay_margin_s(loop: CrankLoop, gain: float = 1.0, longest_s: float = 0.1) -> float:
    """The largest extra delay, s (to 10 us), up to ``longest_s``, for which the loop with plant
    ``gain`` is stable: its first loss of stability, scanned at a tenth of a period then
    bisected; 0 when it is unstable without one."""
    if not is_stable(loop, gain, 0.0):
        return 0.0
    step = loop.h / 10
    inside = 0.0
    while inside + step <= longest_s:
        if not is_stable(loop, gain, inside + step):
            outside = inside + step
            while outside - inside > 1e-5:
                mid = 0.5 * (inside + outside)
                if is_stable(loop, gain, mid):
                    inside = mid
                else:
                    outside = mid
            return inside
        inside += step
    return longest_s


def robust_range(loop: CrankLoop) -> RobustRange:
    """What the crank servo's loop survives: its stable plant gains with no extra delay and
    with :data:`~stewart_drake.control.robustness.EXTRA_DELAY_S`, its delay margin at gain 1
    and at the required range's ends (in ``notes``), against
    :data:`~stewart_drake.control.robustness.GAIN_RANGE`."""
    delays = ", ".join(
        f"{1e3 * delay_margin_s(loop, g):.1f} ms at gain {g:g}"
        for g in (GAIN_RANGE[0], 1.0, GAIN_RANGE[1])
    )
    return RobustRange(
        loop=(
            f"the crank servo's loop (f_c {loop.bandwidth_hz:g} Hz, estimator "
            f"{loop.observer_bandwidth_hz:g} Hz, {1e3 * loop.h:g} ms, {loop.delay_periods} "
            "period(s) of delay designed for)"
        ),
        gains=gain_range(loop, 0.0),
        delayed_gains=gain_range(loop, EXTRA_DELAY_S),
        extra_delay_s=EXTRA_DELAY_S,
        notes=(f"delay it takes beyond the design's: {delays}",),
    )


def margin_lines(loop: CrankLoop) -> list[str]:
    """What ``analyze`` says of a crank servo's loop (:func:`robust_range`): its stable range of
    plant gain with no extra delay and with the extra delay, its delay margin at gain 1 and at
    the range's ends, and whether it holds what the shipped scenarios must."""
    r = robust_range(loop)
    (lo0, hi0), (lo, hi) = r.gains, r.delayed_gains
    extra_ms = 1e3 * r.extra_delay_s
    return [
        f"{r.loop}:",
        f"  stable for a plant gain (true / believed torque per command) of {lo0:.2f} to "
        f"{hi0:.2f}; with {extra_ms:g} ms more delay, {lo:.2f} to {hi:.2f}",
        *(f"  {note}" for note in r.notes),
        f"  {'holds' if r.holds else 'does NOT hold'} what a shipped servo must: gain "
        f"{r.required[0]:g} to {r.required[1]:g} with {extra_ms:g} ms more delay (the "
        "catalogue's rotor within a factor of 2, the bus's own delay and 4 ms)",
    ]
