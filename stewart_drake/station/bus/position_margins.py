"""What the servos' own position loop survives: a crank whose inertia, or a motor whose torque per
volt, departs from what its gains were placed on, and a delay inside the servo (its winding, its
PWM) beyond the firmware's period, each exactly sampled.

The loop of :class:`~.servo_firmware.PositionFirmware` about a goal at rest, on one crank: the
shaft ``J q'' = (k / R) (u - k q')``, driven each firmware period ``h`` by the voltage ``u``
computed from that period's reading, with the plant's acceleration ``g`` times the design's (``g``
= the true torque per volt over the believed times the believed inertia over the true: the
catalogue's rotor is uncertain by a factor of 2, a servo's constant by its gears' losses)::

    v_hat+ = v_hat + a ((q - q_prev) / h - v_hat)        a = 1 - exp(-h / T_v)
    u      = -K_P q + I - K_D v_hat+                     I+ = I - K_I q h

The voltage acting ``extra_delay_s`` later than computed switches within each period, as the
crank servo's (:mod:`stewart_drake.control.servo.margins`), from the command before to this one
at ``tau``: the zero-order hold's exact discretisation over the two parts. The loop is stable when
every eigenvalue of one period lies inside the unit circle. The bus's delay is outside this loop
(the host streams goals: a late goal is a lag of the motion, which the goals' lead carries, not a
loop's delay), so what matters here is the gain; :func:`position_margin_lines` says both.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.linalg import expm

from ...base.checks import as_number
from ...control.robustness import GAIN_RANGE, RobustRange, stable_gain_range
from .servo_firmware import PositionGains

#: The gains a shipped position loop must survive (the crank servo's: docs/robot.md).


def _hold(A: np.ndarray, B: np.ndarray, t: float) -> tuple[np.ndarray, np.ndarray]:
    """(exp(A t), int_0^t exp(A s) ds B) by one matrix exponential."""
    n = A.shape[0]
    M = np.zeros((n + 1, n + 1))
    M[:n, :n], M[:n, n] = A * t, B * t
    E = expm(M)
    return E[:n, :n], E[:n, n]


def position_closed_loop(
    gains: PositionGains,
    inertia_kg_m2: float,
    k_Nm_per_A: float,
    resistance_ohm: float,
    gain: float = 1.0,
    extra_delay_s: float = 0.0,
) -> np.ndarray:
    """One firmware period of the loop (module docstring) as a matrix on the state [q, q', q_prev,
    v_hat, I, u_1 .. u_(m + 1)], u_j the voltages computed j periods ago still to act.

    Raises:
        InvalidConfigError: a gain not > 0, a negative delay, an inertia, constant or winding
            not > 0.
    """
    g = as_number("gain", gain, 0.0, lo_open=True)
    extra = as_number("extra_delay_s", extra_delay_s, 0.0, 1.0)
    J = as_number("inertia_kg_m2", inertia_kg_m2, 0.0, math.inf, lo_open=True)
    k = as_number("k_Nm_per_A", k_Nm_per_A, 0.0, math.inf, lo_open=True)
    R = as_number("resistance_ohm", resistance_ohm, 0.0, math.inf, lo_open=True)
    h = gains.period_s
    a = 1.0 - math.exp(-h / gains.velocity_filter_s) if gains.velocity_filter_s > 0 else 1.0
    A = np.array([[0.0, 1.0], [0.0, -g * k * k / (R * J)]])
    B = np.array([0.0, g * k / (R * J)])
    m = int(math.floor(extra / h + 1e-12))
    tau = extra - m * h
    # over one period: the older voltage for tau, then the newer for h - tau
    Phi_new, Gam_new = _hold(A, B, h - tau)
    Phi_old, Gam_old = _hold(A, B, tau)
    Gam_old = Phi_new @ Gam_old
    Phi = Phi_new @ Phi_old
    n = 5 + m + 1
    M = np.zeros((n, n))
    # this period's voltage u = row ``u`` of the state now
    u = np.zeros(n)
    rate = np.zeros(n)
    rate[0], rate[2] = 1.0 / h, -1.0 / h
    v_hat_next = np.zeros(n)
    v_hat_next[3] = 1.0 - a
    v_hat_next += a * rate
    u[0], u[4] = -gains.p_V_per_rad, 1.0
    u -= gains.d_V_s_per_rad * v_hat_next
    # the voltages acting this period: the one computed m periods ago from tau, m + 1 before it
    new = u if m == 0 else _unit(n, 5 + m - 1)
    old = _unit(n, 5 + m)
    M[0:2, 0:2] = Phi
    M[0:2, :] += np.outer(Gam_new, new) + np.outer(Gam_old, old)
    M[2, 0] = 1.0  # q_prev+ = q
    M[3, :] = v_hat_next
    M[4, 4], M[4, 0] = 1.0, -gains.i_V_per_rad_s * h
    M[5, :] = u  # u_1+ = this period's
    for j in range(6, n):
        M[j, j - 1] = 1.0
    return M


def _unit(n: int, i: int) -> np.ndarray:
    e = np.zeros(n)
    e[i] = 1.0
    return e


def spectral_radius(*args, **kw) -> float:
    """The largest |eigenvalue| of :func:`position_closed_loop`'s matrix (same arguments)."""
    return float(np.max(np.abs(np.linalg.eigvals(position_closed_loop(*args, **kw)))))


def gain_range(
    gains, inertia_kg_m2, k_Nm_per_A, resistance_ohm, extra_delay_s=0.0, steps: int = 400
) -> tuple[float, float]:
    """(lowest, highest) plant gain about 1 that keeps the loop stable
    (:func:`~stewart_drake.control.robustness.stable_gain_range`: a log grid from 0.01 to 100 of
    ``steps`` points, each edge bisected); (nan, nan) when the design itself is not."""

    def stable(g):
        return (
            spectral_radius(gains, inertia_kg_m2, k_Nm_per_A, resistance_ohm, g, extra_delay_s)
            < 1.0
        )

    return stable_gain_range(stable, steps)


def delay_margin_s(gains, inertia_kg_m2, k_Nm_per_A, resistance_ohm, gain=1.0, longest_s=0.02):
    """The longest delay inside the servo (0.01 ms resolution) the loop survives at ``gain``, s
    (``longest_s`` if it survives that)."""
    step = 1e-5
    for n in range(int(round(longest_s / step)) + 1):
        if spectral_radius(gains, inertia_kg_m2, k_Nm_per_A, resistance_ohm, gain, n * step) >= 1:
            return max(0.0, (n - 1) * step)
    return longest_s


def position_robust_range(gains, inertia_kg_m2, k_Nm_per_A, resistance_ohm) -> RobustRange:
    """What a position loop survives: its stable plant gains (the bus's delay is outside this
    loop, so none is asked beyond the firmware's own), and in ``notes`` those with 1 ms more
    delay inside the servo and the delay it survives at the design's gain."""
    both = gain_range(gains, inertia_kg_m2, k_Nm_per_A, resistance_ohm)
    lo1, hi1 = gain_range(gains, inertia_kg_m2, k_Nm_per_A, resistance_ohm, 1e-3)
    margin = delay_margin_s(gains, inertia_kg_m2, k_Nm_per_A, resistance_ohm)
    return RobustRange(
        loop=f"the servos' position loop ({1e3 * gains.period_s:g} ms on each servo's encoder)",
        gains=both,
        delayed_gains=both,
        extra_delay_s=0.0,
        notes=(
            f"{lo1:.2f} to {hi1:.2f} with 1 ms more delay inside the servo; survives "
            f"{1e3 * margin:.2f} ms of such delay at the design's gain",
            "the bus's delay is outside this loop (a late goal lags the motion, which the "
            "goals' lead carries)",
        ),
    )


def position_margin_lines(gains, inertia_kg_m2, k_Nm_per_A, resistance_ohm) -> list[str]:
    """What ``analyze`` says of a position loop (:func:`position_robust_range`): its stable
    plant gains, those with 1 ms more delay inside the servo, the delay it survives, against
    :data:`~stewart_drake.control.robustness.GAIN_RANGE`."""
    r = position_robust_range(gains, inertia_kg_m2, k_Nm_per_A, resistance_ohm)
    (lo, hi), (within, outside) = r.gains, r.notes
    return [
        f"{r.loop}: stable for a plant gain (true / believed torque per volt over inertia) of "
        f"{lo:.2f} to {hi:.2f}, {within}",
        f"  {'holds' if r.holds else 'does NOT hold'} the shipped range {r.required[0]:g} to "
        f"{r.required[1]:g}; {outside}",
    ]


__all__ = [
    "GAIN_RANGE",
    "position_closed_loop",
    "spectral_radius",
    "gain_range",
    "delay_margin_s",
    "position_margin_lines",
    "position_robust_range",
]
