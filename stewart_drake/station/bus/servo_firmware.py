"""The servo's own position loop, as a DYNAMIXEL's firmware runs it in Position Control Mode:
the goal turned into a desired trajectory by the profile, then a PID on the position error with
a velocity feed-forward, whose output is the motor's PWM (the e-Manual's position controller,
the same structure in the X series and the DYNAMIXEL-P: Position P, I, D Gains, Feedforward 1st
Gain, Profile Velocity, Goal PWM; the velocity PI gains belong to Velocity Control Mode). It
runs each period of the firmware's own loop on its own encoder, with no bus between the
measurement and the motor.

Per servo, each firmware period ``h``, on the encoder's whole counts::

    p_d  moves towards the goal at the profile velocity v_p (reaching it, stops): v_d its rate
    v_hat += (1 - exp(-h / T_v)) ((read - read_prev) / h - v_hat)
    u    = K_P e + I + K_D (v_d - v_hat) + K_FF v_d,    e = p_d - read,    I += K_I e h

``u`` is a voltage (the duty ``u / V`` within ``[-1, 1]``: the PWM Limit); the integral stops
growing in the sense that saturates (the e-Manual's anti-windup, whose gain it does not give).
A host streams each goal with the profile velocity that reaches it in one control period
(Profile Velocity and Goal Position are contiguous in both tables, one sync write): the
trajectory then interpolates the goals linearly, a period behind them, and the feed-forward acts
on their slope. The motor's current is what the duty drives against the back-EMF
(:func:`~.servo_physics.pwm_current`, within the current limit where the supply allows:
:func:`~.servo_physics.limited_duty`).

What is ours, not ROBOTIS's: the gains are given in SI (V per rad, V per rad s, V s per rad),
not in the control table's raw units, whose scaling the e-Manual gives for the X series only
(``K_PP = P / 128`` and so on, in PWM units) and the bench identifies (docs/servo_bench.md); the
loop's period and the velocity estimate's filter are not published (:func:`position_gains`'
defaults are assumptions, said where they are used).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from ...base.checks import as_number
from ...base.compiled import njit_cached


@dataclass(frozen=True)
class PositionGains:
    """The position controller's gains and the firmware's figures, SI.

    Attributes:
        p_V_per_rad: ``K_P``.  i_V_per_rad_s: ``K_I``.  d_V_s_per_rad: ``K_D``.
        ff_V_s_per_rad: ``K_FF``, on the desired velocity (the back-EMF constant cancels it).
        supply_V: the supply the duty is a share of.  velocity_filter_s: ``T_v``, s.
        period_s: the firmware loop's period ``h``, s.
    Raises:
        InvalidConfigError: a gain negative or not finite, a period or supply not positive.
    """

    p_V_per_rad: float
    i_V_per_rad_s: float
    d_V_s_per_rad: float
    ff_V_s_per_rad: float
    supply_V: float
    velocity_filter_s: float = 2e-3
    period_s: float = 1e-3

    def __post_init__(self):
        for name in ("p_V_per_rad", "i_V_per_rad_s", "d_V_s_per_rad", "ff_V_s_per_rad"):
            as_number(name, getattr(self, name), 0.0, math.inf)
        as_number("supply_V", self.supply_V, 0.0, 1e3, lo_open=True)
        as_number("velocity_filter_s", self.velocity_filter_s, 0.0, 1.0)
        as_number("period_s", self.period_s, 0.0, 0.1, lo_open=True)


def position_gains(
    inertia_kg_m2: float,
    k_Nm_per_A: float,
    resistance_ohm: float,
    supply_V: float,
    position_hz: float,
    damping: float = 1.0,
    integral_ratio: float = 4.0,
    period_s: float = 1e-3,
    velocity_filter_s: float = 2e-3,
) -> PositionGains:
    """Gains that make the loop on a shaft of ``inertia_kg_m2`` (the rotor reflected through the
    gears and the crank's share of the platform), driven by a motor of ``k_Nm_per_A`` and
    ``resistance_ohm``, a second-order system of ``position_hz`` and ``damping``: a voltage
    ``u`` gives the torque ``k (u - k v) / R``, so the stiffness ``J w^2`` needs ``K_P = J w^2 R
    / k``, and the damping ``2 zeta w J`` what the back-EMF's ``k^2 / R`` leaves, ``K_D = (2 zeta
    w J - k^2 / R) R / k`` (none if the back-EMF is enough); the integral's corner ``w /
    integral_ratio``: ``K_I = K_P w / integral_ratio``; ``K_FF = k``, the back-EMF of the
    desired velocity.

    The loop's period (1 ms) and the velocity filter (2 ms) are ours: ROBOTIS does not publish
    them (measured on the realistic emulator's robot in ``benchmarks/servo_position_loop.py``).

    Raises:
        InvalidConfigError: a figure not positive, or a loop within 4 periods of the firmware's.
    """
    as_number("inertia_kg_m2", inertia_kg_m2, 0.0, math.inf, lo_open=True)
    as_number("k_Nm_per_A", k_Nm_per_A, 0.0, math.inf, lo_open=True)
    as_number("resistance_ohm", resistance_ohm, 0.0, math.inf, lo_open=True)
    as_number("position_hz", position_hz, 0.0, 0.25 / period_s / (2 * math.pi), lo_open=True)
    as_number("damping", damping, 0.0, 10.0, lo_open=True)
    as_number("integral_ratio", integral_ratio, 1.0, math.inf)
    w = 2 * math.pi * position_hz
    j, k, r = inertia_kg_m2, k_Nm_per_A, resistance_ohm
    k_p = j * w * w * r / k
    return PositionGains(
        p_V_per_rad=k_p,
        i_V_per_rad_s=k_p * w / integral_ratio,
        d_V_s_per_rad=max(0.0, 2 * damping * w * j - k * k / r) * r / k,
        ff_V_s_per_rad=k,
        supply_V=supply_V,
        velocity_filter_s=velocity_filter_s,
        period_s=period_s,
    )


class PositionFirmware:
    """``n`` servos' position controllers (module docstring): :meth:`set_goal` as a write of
    Profile Velocity and Goal Position, :meth:`duty` once a firmware period.

    Args:
        gains: the gains (one set for all).  rad_per_count: the encoder's count, rad.
        read_rad: (n,) the encoders' readings when the torque goes on, rad: the trajectory and
            the goal start there, at rest.
    """

    def __init__(self, gains: PositionGains, rad_per_count: float, read_rad):
        self.gains = gains
        self.count = float(rad_per_count)
        start = self._counts(read_rad)
        self._prev = start.copy()
        #: (n,) the desired trajectory, counts (Position Trajectory), and its goal.
        self.trajectory = start.copy()
        self.goal = start.copy()
        self._profile = np.zeros_like(start)  # counts a period
        self.v_hat = np.zeros_like(start)
        #: (n,) the position loop's integral, V.
        self.integral = np.zeros_like(start)

    def _counts(self, rad) -> np.ndarray:
        return np.rint(np.asarray(rad, dtype=float) / self.count)

    def set_goal(self, goal_rad, profile_velocity_rad_s=None) -> None:
        """A new Goal Position (rad, (n,), held in whole counts) and Profile Velocity (rad/s,
        (n,); None: none, the trajectory jumps to the goal, with no velocity to feed forward)."""
        self.goal = np.ascontiguousarray(self._counts(goal_rad))
        if profile_velocity_rad_s is None:
            self._profile = np.full_like(self.goal, np.inf)
        else:
            v = np.abs(np.asarray(profile_velocity_rad_s, dtype=float))
            self._profile = np.ascontiguousarray(v * self.gains.period_s / self.count)

    def duty(self, read_rad) -> np.ndarray:
        """(n,) the PWM duty this period, in [-1, 1], from the encoder's reading (rad, rounded
        to whole counts). Compiled (:func:`firmware_step`): the bus emulator runs it for each
        servo each millisecond of its model."""
        out = np.empty(self.goal.size)
        firmware_step(
            self.goal, self._profile, self.trajectory, self._prev, self.v_hat, self.integral,
            np.asarray(read_rad, dtype=float), self.count, self._gains, out,
        )  # fmt: skip
        return out

    @property
    def gains(self) -> PositionGains:
        """The gains the loop runs (settable: a new table's take effect at the next period)."""
        return self._gains_si

    @gains.setter
    def gains(self, g: PositionGains) -> None:
        h = g.period_s
        a = 1.0 - math.exp(-h / g.velocity_filter_s) if g.velocity_filter_s > 0 else 1.0
        self._gains_si = g
        self._gains = np.array(
            [g.p_V_per_rad, g.i_V_per_rad_s, g.d_V_s_per_rad, g.ff_V_s_per_rad, g.supply_V, h, a]
        )


@njit_cached
def firmware_step(goal, profile, trajectory, prev, v_hat, integral, read_rad, count, gains, out):
    """One firmware period of each servo (module docstring), its state updated in place:
    ``trajectory``, ``prev`` (the last reading, counts), ``v_hat`` rad/s and ``integral`` V
    (n,); ``goal`` counts and ``profile`` counts a period (inf: no profile) (n,); ``gains`` [K_P,
    K_I, K_D, K_FF, supply V, period s, the velocity filter's share a period]; the duty into
    ``out`` (n,)."""
    k_p, k_i, k_d, k_ff, supply, h, a = (
        gains[0], gains[1], gains[2], gains[3], gains[4], gains[5], gains[6],
    )  # fmt: skip
    for j in range(goal.size):
        step = min(max(goal[j] - trajectory[j], -profile[j]), profile[j])
        trajectory[j] += step
        v_d = 0.0 if math.isinf(profile[j]) else step * count / h  # a jump: none
        read = np.rint(read_rad[j] / count)
        rate = (read - prev[j]) * count / h
        prev[j] = read
        v_hat[j] += a * (rate - v_hat[j])
        e = (trajectory[j] - read) * count
        u = k_p * e + integral[j] + k_d * (v_d - v_hat[j]) + k_ff * v_d
        grow = k_i * e * h
        if not ((u >= supply and grow > 0) or (u <= -supply and grow < 0)):
            integral[j] += grow
        out[j] = min(max(u / supply, -1.0), 1.0)


def warm_up() -> None:
    """Compile (or load from the cache) :func:`firmware_step` with the types its callers pass."""
    one = np.zeros(1)
    firmware_step(
        one, np.ones(1), np.zeros(1), np.zeros(1), np.zeros(1), np.zeros(1), np.zeros(1),
        1e-3, np.ones(7), np.zeros(1),
    )  # fmt: skip


#: The raw gains' divisors (X series e-Manual, "Position PID Gain": K_PD = D / 16, K_PI = I /
#: 65536, K_PP = P / 128, K_FF1st = FF / 4), in the order of
#: :attr:`~.protocol.ControlTable.position_gains`; the DYNAMIXEL-P's e-Manual gives none, and
#: these are taken for it too until its bench says otherwise (docs/servo_bench.md).
GAIN_DIVISORS = (16.0, 65536.0, 128.0, 4.0)
#: The raw gains' largest value, by family (e-Manual, "Control Table").
GAIN_MAX = {"X": 16383, "P": 32767}


def _unit_scales(spec, supply_V: float, period_s: float) -> np.ndarray:
    """SI per raw unit of (K_D, K_I, K_P, K_FF): the firmware's output in PWM units over
    ``spec.table.pwm_full`` of ``supply_V``, its error in counts, its integral summed and its
    rates differenced each ``period_s``."""
    volts_per_count = supply_V / spec.table.pwm_full / spec.rad_per_count
    h = period_s
    return volts_per_count * np.array([h, 1.0 / h, 1.0, h]) / np.array(GAIN_DIVISORS)


def raw_position_gains(gains: PositionGains, spec) -> tuple[int, int, int, int]:
    """The control table's (Position D, I, P, Feedforward 1st) Gains of ``gains`` on the
    servo ``spec`` (a :class:`~.servos.ServoSpec`), rounded.

    Raises:
        InvalidConfigError: a gain past the table's largest value (named, with its SI figure).
    """
    from ...base.errors import InvalidConfigError

    scales = _unit_scales(spec, gains.supply_V, gains.period_s)
    si = (gains.d_V_s_per_rad, gains.i_V_per_rad_s, gains.p_V_per_rad, gains.ff_V_s_per_rad)
    raw = tuple(int(round(v / k)) for v, k in zip(si, scales, strict=True))
    top = GAIN_MAX[spec.table.family]
    for name, value, figure in zip(("D", "I", "P", "Feedforward 1st"), raw, si, strict=True):
        if value > top:
            raise InvalidConfigError(
                f"{spec.name}'s Position {name} Gain would be {value} ({figure:.4g} SI), past "
                f"its table's {top}: a slower loop, or a servo of finer counts"
            )
    return raw  # type: ignore[return-value]


def table_position_gains(raw, spec, supply_V: float, period_s: float = 1e-3) -> PositionGains:
    """The :class:`PositionGains` the firmware of ``spec`` runs for the control table's
    (Position D, I, P, Feedforward 1st) Gains ``raw`` at ``supply_V``."""
    d, i, p, ff = (
        float(v) * k for v, k in zip(raw, _unit_scales(spec, supply_V, period_s), strict=True)
    )
    return PositionGains(p, i, d, ff, supply_V, period_s=period_s)


class FirmwareLoops:
    """The emulated servos' firmware (:class:`~.emulator.BusEmulator`'s part): each servo in
    Position Control Mode runs a :class:`PositionFirmware` from its own control table every
    :attr:`FIRMWARE_PERIOD_S` of the model, its PWM driving the backend's winding."""

    #: The period of an emulated servo's own position loop, s (not published: ours).
    FIRMWARE_PERIOD_S = 1e-3
    # The emulator's own (BusEmulator.__init__ sets them): what this part reads.
    ids: list
    servos: dict
    backend: Any
    zero_counts: np.ndarray
    _firmware: dict
    _pwm_currents: dict

    def _commands(self) -> tuple[np.ndarray, dict]:
        """(the Goal Currents each servo drives (n,), A; {index: its timed command} of the
        servos in Position Control Mode: (command, the goal and profile before its last write,
        that write's time), :meth:`~.servo_table.ServoTable.timed_command`), read from the
        tables (the caller holds their lock)."""
        currents = np.array([self.servos[i].current_A() for i in self.ids])
        commands = {
            k: self.servos[i].timed_command()
            for k, i in enumerate(self.ids)
            if self.servos[i].in_position_mode()
        }
        return currents, commands

    def _advance(
        self, dt_s: float, currents: np.ndarray, commands: dict, start_t: float | None = None
    ) -> None:
        """Step the backend ``dt_s`` from the instant ``start_t`` (perf_counter s; None: the
        commanded clock, every command acts from the start): the servos in Current Control Mode
        at their Goal Current, those in Position Control Mode (``commands``) by their own loop
        each firmware period, each on the goal it held at that period's start (a goal written
        during the step acts from the period it arrived in, not from the step's start)."""
        for k in list(self._firmware):
            if k not in commands:  # its torque went off, or its mode changed: the loop restarts
                del self._firmware[k]
                self._pwm_currents.pop(k, None)
        if dt_s <= 0.0:
            return
        if not commands:
            self.backend.advance(dt_s, currents)
            return
        steps = max(1, round(dt_s / self.FIRMWARE_PERIOD_S))
        h = dt_s / steps
        for j in range(steps):
            read = self.backend.positions_rad()
            duty = np.zeros(len(self.ids))
            now = math.inf if start_t is None else start_t + j * h
            for k, (command, before, written_t) in commands.items():
                if now < written_t:  # not yet arrived: the goal before it
                    command = (*before, command[2])
                duty[k] = self._firmware_of(k, command, read[k]).duty(read[k : k + 1])[0]
            drive = self.backend.pwm_currents(duty)
            for k in commands:
                currents[k] = self._pwm_currents[k] = float(drive[k])
            self.backend.advance(h, currents)

    def _firmware_of(self, k: int, command: tuple, read_rad: float):
        """Servo ``k``'s position loop, made when its torque went on (from where it is) and
        told of every new command."""
        from .protocol import SUPPLY_V

        spec = self.servos[self.ids[k]].spec
        held = self._firmware.get(k)
        if held is not None and held[1] == command:
            return held[0]
        goal_counts, profile_units, raw = command
        gains = table_position_gains(raw, spec, SUPPLY_V[spec.table.family], self.FIRMWARE_PERIOD_S)
        if held is None:
            firmware = PositionFirmware(gains, spec.rad_per_count, [read_rad])
        else:
            firmware = held[0]
            firmware.gains = gains
        goal = (goal_counts - float(self.zero_counts[k])) * spec.rad_per_count
        profile = None if profile_units == 0 else [profile_units * spec.velocity_unit_rad_s]
        if held is None or held[1][:2] != command[:2]:
            firmware.set_goal([goal], profile)
        self._firmware[k] = (firmware, command)
        return firmware


__all__ = [
    "PositionGains",
    "position_gains",
    "PositionFirmware",
    "GAIN_DIVISORS",
    "GAIN_MAX",
    "raw_position_gains",
    "table_position_gains",
    "FirmwareLoops",
    "firmware_step",
    "warm_up",
]
