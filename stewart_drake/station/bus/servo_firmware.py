"""The servo's own position loop, as a DYNAMIXEL-P's firmware runs it in Position Control Mode:
a cascade of a position P term, a velocity PI loop and the current loop (the e-Manual's control
block diagram of the PH42/PM42 series: Position P Gain, Velocity P and I Gains), each period of
the firmware's own loop, on its own encoder, with no bus between the measurement and the current.

Per servo, each firmware period ``h``, on the encoder's whole counts (the goal rounded as the
control table holds it)::

    v_cmd = K_pp (goal - read) + v_ff
    v_hat += (1 - exp(-h / T_v)) ((read - read_prev) / h - v_hat)
    i     = K_vp (v_cmd - v_hat) + I + i_ff,     I += K_vi (v_cmd - v_hat) h

``i`` within the current limit; the integral ``I`` stops growing in the sense that saturates
(conditional integration: the anti-windup). ``v_ff`` and ``i_ff`` are the velocity and current
feed-forward a host streams with the goal (the P series' Goal Velocity and Goal Current as
feed-forward: what a controller streaming goal positions sends). The integral holds what the
model does not: the gears' load-dependent friction (a band of positions where a P loop sticks),
a motor constant off the catalogue's, a payload. The current that results is what the servo's
current loop follows (:func:`~.servo_physics.current_step`).

What is ours, not ROBOTIS's: the gains are given in SI (A per rad/s, 1/s), not in the control
table's raw units, whose scaling the e-Manual does not give (the bench identifies them:
docs/servo_bench.md); the loop's period and the velocity filter are not published either
(:class:`CascadeGains`' defaults are assumptions, said where they are used). The X series' own
position loop is another (a PID whose output is the PWM, or the current in Current-based
Position Control Mode) and is not this module's.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ...base.checks import as_number


@dataclass(frozen=True)
class CascadeGains:
    """The cascade's gains, SI.

    Attributes:
        position_per_s: ``K_pp``, the velocity commanded per radian of position error, 1/s.
        velocity_A_s_per_rad: ``K_vp``, A per rad/s of velocity error.
        velocity_integral_A_per_rad: ``K_vi``, A per rad/s of velocity error per second.
        velocity_filter_s: ``T_v``, the velocity estimate's first-order filter, s.
        period_s: the firmware loop's period ``h``, s.
        current_limit_A: the current's bound, A.
    Raises:
        InvalidConfigError: a gain negative or not finite, a period or limit not positive.
    """

    position_per_s: float
    velocity_A_s_per_rad: float
    velocity_integral_A_per_rad: float
    velocity_filter_s: float
    period_s: float
    current_limit_A: float

    def __post_init__(self):
        for name in ("position_per_s", "velocity_A_s_per_rad", "velocity_integral_A_per_rad"):
            as_number(name, getattr(self, name), 0.0, math.inf)
        as_number("velocity_filter_s", self.velocity_filter_s, 0.0, 1.0)
        as_number("period_s", self.period_s, 0.0, 0.1, lo_open=True)
        as_number("current_limit_A", self.current_limit_A, 0.0, 1e3, lo_open=True)


def cascade_gains(
    inertia_kg_m2: float,
    k_Nm_per_A: float,
    current_limit_A: float,
    velocity_hz: float = 60.0,
    position_hz: float = 8.0,
    period_s: float = 1e-3,
    velocity_filter_s: float = 2e-3,
) -> CascadeGains:
    """Gains that put the velocity loop's crossover at ``velocity_hz`` on a shaft of
    ``inertia_kg_m2`` (the rotor reflected through the gears and the crank's share of the
    platform) driven at ``k_Nm_per_A``, its integral's corner a quarter of it, and the position
    loop's at ``position_hz`` (well inside: a cascade's outer loop is slower than its inner):
    ``K_vp = 2 pi f_v J / k``, ``K_vi = K_vp 2 pi f_v / 4``, ``K_pp = 2 pi f_p``.

    The defaults, 60 Hz and 8 Hz at 1 kHz with a 2 ms velocity filter, are ours (a DYNAMIXEL-P's
    loop period is not published): measured on the realistic emulator's robot in
    ``benchmarks/servo_position_loop.py``.

    Raises:
        InvalidConfigError: a figure not positive, or a velocity loop not above the position's.
    """
    as_number("inertia_kg_m2", inertia_kg_m2, 0.0, math.inf, lo_open=True)
    as_number("k_Nm_per_A", k_Nm_per_A, 0.0, math.inf, lo_open=True)
    as_number("position_hz", position_hz, 0.0, math.inf, lo_open=True)
    as_number("velocity_hz", velocity_hz, position_hz, 0.25 / period_s, lo_open=True)
    w_v = 2 * math.pi * velocity_hz
    k_vp = w_v * inertia_kg_m2 / k_Nm_per_A
    return CascadeGains(
        position_per_s=2 * math.pi * position_hz,
        velocity_A_s_per_rad=k_vp,
        velocity_integral_A_per_rad=k_vp * w_v / 4.0,
        velocity_filter_s=velocity_filter_s,
        period_s=period_s,
        current_limit_A=current_limit_A,
    )


class CascadeFirmware:
    """``n`` servos' cascades (module docstring), one :meth:`current` a firmware period.

    Args:
        gains: the cascade's gains (one set for all).  rad_per_count: the encoder's count, rad.
        read_rad: (n,) the encoders' readings when the torque goes on, rad (the velocity
            estimate starts from them at rest).
    """

    def __init__(self, gains: CascadeGains, rad_per_count: float, read_rad):
        self.gains = gains
        self.count = float(rad_per_count)
        self._prev = self._counts(read_rad)
        self.v_hat = np.zeros_like(self._prev)
        #: (n,) the velocity loop's integral, A.
        self.integral = np.zeros_like(self._prev)

    def _counts(self, rad) -> np.ndarray:
        return np.rint(np.asarray(rad, dtype=float) / self.count)

    def current(self, goal_rad, read_rad, velocity_ff=0.0, current_ff=0.0) -> np.ndarray:
        """(n,) the current the cascade commands this period, A, from the goal and the
        encoder's reading (rad, each rounded to whole counts) and the feed-forward (rad/s, A)."""
        g = self.gains
        h = g.period_s
        read = self._counts(read_rad)
        rate = (read - self._prev) * self.count / h
        self._prev = read
        a = 1.0 - math.exp(-h / g.velocity_filter_s) if g.velocity_filter_s > 0 else 1.0
        self.v_hat = self.v_hat + a * (rate - self.v_hat)
        error = (self._counts(goal_rad) - read) * self.count
        v_error = g.position_per_s * error + velocity_ff - self.v_hat
        i = g.velocity_A_s_per_rad * v_error + self.integral + current_ff
        limit = g.current_limit_A
        # conditional integration: the integral does not grow in the sense that saturates
        grow = g.velocity_integral_A_per_rad * v_error * h
        held = ((i >= limit) & (grow > 0)) | ((i <= -limit) & (grow < 0))
        self.integral = self.integral + np.where(held, 0.0, grow)
        return np.clip(i, -limit, limit)


__all__ = ["CascadeGains", "cascade_gains", "CascadeFirmware"]
