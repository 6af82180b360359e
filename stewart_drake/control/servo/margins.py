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
extra delay. The shipped bus scenarios' servos hold :data:`GAIN_RANGE` with
:data:`EXTRA_DELAY_S` (tests/test_servo_margins.py); ``stewart-drake analyze`` states each
scenario's (:func:`margin_lines`).
"""

from __future__ import annotations

import math

import numpy as np

from ...base.checks import as_number
from .design import CrankLoop

#: The plant gains a shipped crank servo must survive: the catalogue's rotor inertia is uncertain
#: by a factor of 2 (docs/motor_catalogue.md) and a servo's torque per ampere departs from its
#: stall ratio by as much (the gears' losses, unit to unit).
GAIN_RANGE = (0.5, 2.0)
#: The delay beyond the design's a shipped crank servo must survive, s: the bus's own (a sync
#: read and its adapter, about 2 ms) and 4 ms more.
EXTRA_DELAY_S = 6e-3


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
    stable, scanned log-uniformly from 1/100 to 100 (``steps`` gains) and refined by bisection
    to 0.1 %; (nan, nan) when it is unstable at gain 1."""
    if not is_stable(loop, 1.0, extra_delay_s):
        return (math.nan, math.nan)
    grid = np.exp(np.linspace(math.log(0.01), math.log(100.0), steps))
    stable = np.array([is_stable(loop, g, extra_delay_s) for g in grid])
    one = int(np.searchsorted(grid, 1.0))
    lo_k, hi_k = one, one - 1
    while lo_k > 0 and stable[lo_k - 1]:
        lo_k -= 1
    while hi_k < steps - 1 and stable[hi_k + 1]:
        hi_k += 1

    def edge(inside: float, outside: float) -> float:
        for _ in range(40):
            mid = math.sqrt(inside * outside)
            if is_stable(loop, mid, extra_delay_s):
                inside = mid
            else:
                outside = mid
            if abs(math.log(outside / inside)) < 1e-3:
                break
        return inside

    lo = grid[0] if lo_k == 0 else edge(grid[lo_k], grid[lo_k - 1])
    hi = grid[-1] if hi_k == steps - 1 else edge(grid[hi_k], grid[hi_k + 1])
    return (float(lo), float(hi))


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


def margin_lines(loop: CrankLoop) -> list[str]:
    """What ``analyze`` says of a crank servo's loop: its stable range of plant gain with no
    extra delay and with :data:`EXTRA_DELAY_S`, its delay margin at gain 1 and at the range's
    ends, and whether it holds what the shipped scenarios must (:data:`GAIN_RANGE` with
    :data:`EXTRA_DELAY_S`)."""
    lo0, hi0 = gain_range(loop, 0.0)
    lo, hi = gain_range(loop, EXTRA_DELAY_S)
    need_lo, need_hi = GAIN_RANGE
    holds = lo <= need_lo and hi >= need_hi
    extra_ms = 1e3 * EXTRA_DELAY_S
    delays = ", ".join(
        f"{1e3 * delay_margin_s(loop, g):.1f} ms at gain {g:g}" for g in (need_lo, 1.0, need_hi)
    )
    return [
        f"the crank servo's loop (f_c {loop.bandwidth_hz:g} Hz, estimator "
        f"{loop.observer_bandwidth_hz:g} Hz, {1e3 * loop.h:g} ms, {loop.delay_periods} period(s) "
        f"of delay designed for):",
        f"  stable for a plant gain (true / believed torque per command) of {lo0:.2f} to "
        f"{hi0:.2f}; with {extra_ms:g} ms more delay, {lo:.2f} to {hi:.2f}",
        f"  delay it takes beyond the design's: {delays}",
        f"  {'holds' if holds else 'does NOT hold'} what a shipped servo must: gain "
        f"{need_lo:g} to {need_hi:g} with {extra_ms:g} ms more delay (the catalogue's rotor "
        "within a factor of 2, the bus's own delay and 4 ms)",
    ]
