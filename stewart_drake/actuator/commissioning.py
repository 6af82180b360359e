"""Commissioning a servo on its bench over the robot's bus: the servo in Current Control Mode,
a pendulum on its horn, driven by a bounded excitation of its Goal Current and logged as a bench
log (:mod:`.bench_log`, ``mode: current``) that ``servo identify`` fits: the servo's motor
constant, rotor and friction as it is, before it goes into the robot. The current loop's lag
is among the figures fitted, but a 10 ms period holds each current for ten of its time constants:
below about 3 ms the logs cannot tell it (docs/servo_bench.md).

The excitation (:func:`excitation_current`): a chirp of the current from 0.2 to 2 Hz whose
amplitude ramps in over a second, over a slower sine, so that the log holds reversals at rest
(the friction's static part), sliding at several rates (its Stribeck and viscous parts), loads
that rise and fall (its load-dependent part) and accelerations (the rotor). Its amplitude is
bounded by the pendulum: the motor's torque at most 0.8 of the arm's largest gravity torque
(:func:`safe_amplitude_A`), so the arm never goes over the top; a guard removes the torque if the
arm passes ``guard_rad`` anyway. Every end (the excitation's, the guard's, an error, Ctrl-C)
removes the torque (the driver's own torque off), and what was logged is kept.

Each period the bus is read, then the new Goal Current written (one period apart: the control
loop's own rhythm); the log gives each Goal Current at the time it was written and the angle
read interpolated to it, so that a replay holds each current from when the servo had it.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np

from ..base.checks import as_number
from ..base.errors import InvalidConfigError
from .bench_log import BenchLog


@dataclass(frozen=True)
class Pendulum:
    """The bench: a point mass ``mass_kg`` at ``length_m`` on the horn (the arm's own mass
    ``arm_mass_kg``, uniform), the servo's supply ``supply_V``."""

    mass_kg: float
    length_m: float
    arm_mass_kg: float = 0.0
    supply_V: float = 12.0

    def __post_init__(self):
        as_number("--mass", self.mass_kg, 0.0, 100.0, lo_open=True)
        as_number("--length", self.length_m, 0.0, 2.0, lo_open=True)
        as_number("arm_mass_kg", self.arm_mass_kg, 0.0, 100.0)
        as_number("supply_V", self.supply_V, 0.0, 60.0, lo_open=True)

    @property
    def gravity_Nm(self) -> float:
        """The arm's largest gravity torque, horizontal, N m."""
        return (self.mass_kg + self.arm_mass_kg / 2.0) * 9.80665 * self.length_m


def safe_amplitude_A(pendulum: Pendulum, torque_constant_Nm_per_A: float) -> float:
    """The excitation's largest current, A: the motor's torque (at the bus's stall ratio, and a
    third more for a motor stronger than it) at most 0.8 of the arm's largest gravity torque:
    the arm held below about 53 deg at rest, enough to slide the gears' friction."""
    return 0.8 * pendulum.gravity_Nm / (torque_constant_Nm_per_A * 4.0 / 3.0)


def excitation_current(t, amplitude_A: float, seconds: float) -> np.ndarray:
    """(n,) the Goal Current at times ``t`` (s, from 0), A (module docstring): within
    ``amplitude_A`` of zero, ramped in over the first second and out over the last."""
    t = np.asarray(t, dtype=float)
    ramp = np.clip(np.minimum(t, seconds - t), 0.0, 1.0)
    f0, f1 = 0.2, 2.0
    phase = 2 * math.pi * (f0 * t + 0.5 * (f1 - f0) / seconds * t * t)
    return amplitude_A * ramp * (0.6 * np.sin(phase) + 0.4 * np.sin(2 * math.pi * 0.13 * t))


def excite(
    bus,
    pendulum: Pendulum,
    currents_A: np.ndarray,
    period_s: float,
    guard_rad: float = 1.5,
    commanded: bool = False,
    name: str = "excitation",
) -> BenchLog:
    """Drive the bus's one servo (opened, configured and enabled here; the torque removed at
    every end) with ``currents_A`` (n,), one a period, and log it (module docstring).

    Args:
        bus: a :class:`~stewart_drake.station.bus.driver.DynamixelBus` of one id (not opened).
        pendulum: the bench.  currents_A: the Goal Current each period, A.
        period_s: the period, s.  guard_rad: the angle past which the torque is removed.
        commanded: the bus advances its model one period a write (an emulator's commanded
            clock): no waiting, and the times are the periods'.
    Returns:
        the log, up to where it ended.
    Raises:
        InvalidConfigError: a bus of more than one servo.
        BusError: as the driver's (the torque removed first).
    """
    if len(bus.ids) != 1:
        raise InvalidConfigError(f"the bench holds one servo, the bus names {len(bus.ids)}")
    k_t = bus.spec.torque_constant_Nm_per_A
    reads, writes, q, sent, on = [], [], [], [], []
    with bus:
        bus.configure()
        bus.enable_torque()
        start = time.perf_counter()
        try:
            for k, i in enumerate(np.asarray(currents_A, dtype=float)):
                if not commanded:
                    _sleep_until(start + k * period_s)
                state = bus.read_state()
                reads.append(k * period_s if commanded else state.t - start)
                q.append(float(state.q[0]))
                if abs(q[-1]) > guard_rad:
                    break
                applied = bus.write_torques(np.array([k_t * i]))
                writes.append(k * period_s if commanded else time.perf_counter() - start)
                sent.append(float(applied[0]) / k_t)
                on.append(True)
        finally:
            bus.torque_off()
    n = len(writes)
    t_w, t_r = np.array(writes), np.array(reads[: n + 1] if n else [])
    if n < 2:
        raise InvalidConfigError("the excitation ended before two periods were logged")
    angle = np.interp(t_w, t_r, np.array(q[: len(t_r)]))
    return BenchLog(
        "",
        pendulum.mass_kg,
        pendulum.length_m,
        pendulum.arm_mass_kg,
        0.0,
        pendulum.supply_V,
        bus.spec.name,
        name,
        t_w - t_w[0],
        np.array(sent),
        angle,
        np.array(on),
        "current",
    )


def _sleep_until(t: float) -> None:
    wait = t - time.perf_counter()
    if wait > 0:
        time.sleep(wait)
