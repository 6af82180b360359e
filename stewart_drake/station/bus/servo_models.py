"""The motion behind an emulated bus's servos (:mod:`.emulator`): a :class:`ServoBackend` the
emulator steps towards the wall clock; :class:`FirstOrderServos`, one rigid crank per servo,
``J dv/dt = K_t i - b v - c sign(v)`` with the current the servo can drive at that speed (12 V:
the stall current falling linearly to zero at the no-load speed), or a linear stage;
:class:`BenchServos`, servos as they are (:mod:`.servo_physics`) each on a pendulum, for
commissioning; and :class:`StackedServos`, several backends on one bus."""

from __future__ import annotations

import abc
import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ...base.errors import InvalidConfigError
from ...robot.motor_catalogue import catalogue_motor
from ..surrogate.linear_stage import LinearStage
from .servos import servo_spec


class ServoBackend(abc.ABC):
    """The motion behind a bus: ``n`` servos, state at their horns in the servos' own sense
    (positive = counts increasing)."""

    @abc.abstractmethod
    def advance(self, dt_s: float, current_A: np.ndarray) -> None:
        """Move the model ``dt_s`` seconds (>= 0) with currents ``current_A`` (n,), A (what
        the servos drive: zero for a servo whose torque is off)."""

    @abc.abstractmethod
    def positions_rad(self) -> np.ndarray:
        """(n,) horn angles, rad."""

    @abc.abstractmethod
    def velocities_rad_s(self) -> np.ndarray:
        """(n,) horn rates, rad/s."""

    def pwm_currents(self, duty) -> np.ndarray:
        """(n,) the currents a PWM ``duty`` (n,) in [-1, 1] drives through each servo's
        winding at its shaft's present rate, A (Position Control Mode: the firmware drives the
        PWM, the back-EMF and the winding make the current).

        Raises:
            InvalidConfigError: a backend with no winding to drive (the default).
        """
        raise InvalidConfigError(
            f"{type(self).__name__} has no PWM drive: its servos run Current Control Mode only"
        )


@dataclass
class FirstOrderServos(ServoBackend):
    """``n`` independent horns: ``J dv/dt = K_t i - b v - c sign(v)``, the current bounded by
    what 12 V drives at speed v: ``|i| <= i_stall (1 - |v| / w_0)`` in the sense of motion.

    Attributes:
        inertia: J, kg m^2 at the horn (the rotor's reflected inertia plus a crank's).
        torque_constant: K_t, N m/A at the horn.  viscous: b, N m s/rad.  coulomb: c, N m.
        stall_current_A: i_stall; inf: no voltage limit.  no_load_speed: w_0, rad/s.
        q0: (n,) initial horn angles, rad.  substep_s: the integrator's largest step, s.
    """

    inertia: float
    torque_constant: float
    viscous: float = 0.0
    coulomb: float = 0.0
    stall_current_A: float = math.inf
    no_load_speed: float = math.inf
    q0: np.ndarray = field(default_factory=lambda: np.zeros(1))
    substep_s: float = 1e-3

    def __post_init__(self):
        if not (self.inertia > 0 and self.torque_constant > 0):
            raise InvalidConfigError("inertia and torque_constant must be > 0")
        self._q = np.array(self.q0, dtype=float)
        self._v = np.zeros_like(self._q)

    @classmethod
    def from_catalogue(cls, name: str, q0, load_inertia: float = 0.0, **overrides):
        """The catalogue motor ``name``'s reflected rotor inertia (plus ``load_inertia``,
        kg m^2), friction and no-load speed, and the bus's K_t and stall current."""
        servo = catalogue_motor(name).servo
        spec = servo_spec(name, torque_control=False)
        kw: dict[str, Any] = dict(
            inertia=servo.rotor_inertia * servo.gear_ratio**2 + load_inertia,
            torque_constant=spec.torque_constant_Nm_per_A,
            viscous=servo.viscous_damping,
            coulomb=servo.coulomb_friction_Nm,
            stall_current_A=spec.stall_current_A,
            no_load_speed=servo.no_load_speed_rad_s,
            q0=np.asarray(q0, dtype=float),
        )
        kw.update(overrides)
        return cls(**kw)

    @classmethod
    def linear_stage(cls, stage: LinearStage, s0_m=0.0):
        """A surrogate's stage: its catalogue servo turning its transmission
        (:class:`~stewart_drake.station.surrogate.linear_stage.LinearStage`), with the stage's
        inertia at the horn (the rotor's and the carriage's; the belt's or screw's own inertia and
        friction are not modelled), the carriage at ``s0_m`` (m from the horn's angle 0)."""
        return cls.from_catalogue(
            stage.motor, [s0_m / stage.metres_per_rad], inertia=stage.inertia_at_horn_kg_m2()
        )

    def advance(self, dt_s, current_A):
        # Plain floats: numpy's per-call overhead on 6 numbers (np.clip alone ~40 us) would
        # make the model slower than real time on a loaded machine.
        n = max(1, math.ceil(dt_s / self.substep_s))
        h = dt_s / n
        K, J, b, c = self.torque_constant, self.inertia, self.viscous, self.coulomb
        i_stall, w0 = self.stall_current_A, self.no_load_speed
        q, v = self._q.tolist(), self._v.tolist()
        for k, i in enumerate(np.asarray(current_A, dtype=float).tolist()):
            qk, vk = q[k], v[k]
            for _ in range(n):
                # The drive's voltage limit: no current beyond i_stall (1 - |v|/w_0) pushing on.
                if i * vk > 0:
                    headroom = i_stall * min(max(1 - abs(vk) / w0, 0.0), 1.0)
                    i_eff = max(-headroom, min(headroom, i))
                else:
                    i_eff = i
                tau = K * i_eff - b * vk
                if vk != 0.0:
                    tau -= math.copysign(c, vk)
                else:  # dry friction holds a horn at rest unless the drive exceeds it
                    tau = math.copysign(max(abs(tau) - c, 0.0), tau)
                v_new = vk + h * tau / J
                # A horn that crosses zero speed within a step stops there; from rest, the
                # dry friction's rule above decides whether it starts again.
                if vk * v_new < 0:
                    v_new = 0.0
                qk += h * 0.5 * (vk + v_new)
                vk = v_new
            q[k], v[k] = qk, vk
        self._q, self._v = np.array(q), np.array(v)

    def positions_rad(self):
        return self._q.copy()

    def velocities_rad_s(self):
        return self._v.copy()

    def pwm_currents(self, duty):
        """The current a duty drives: 12 V over the winding (``12 / i_stall`` ohm) against the
        back-EMF (12 V at the no-load speed): ``i_stall (d - v / w_0)``, A."""
        if not math.isfinite(self.stall_current_A):
            return super().pwm_currents(duty)
        v = self._v / self.no_load_speed if math.isfinite(self.no_load_speed) else 0.0
        return self.stall_current_A * (np.asarray(duty, dtype=float) - v)


class BenchServos(ServoBackend):
    """Servos each on a pendulum of its own, as a bench holds them for commissioning
    (:mod:`stewart_drake.actuator.commissioning`), their drive and friction ``servos``'s
    (:class:`~.emulator_config.EmulatedServos`: what a real one hides) run by
    :mod:`.servo_physics`: each servo's current follows its Goal Current through its current
    loop, within what its supply drives against the back-EMF; ``J q'' = k i - G sin(q + q_offset)
    + friction``, J the pendulum's ``m l^2`` and the rotor's reflected inertia (the catalogue's
    times ``servos.rotor_inertia_scale``), the friction the budget (the load the pendulum's
    gravity) as a stopping torque, semi-implicit Euler at :data:`STEP_S`.

    Args:
        servos: the drawn servos (n of them).  mass_kg, length_m: each pendulum's point mass
            and arm.  q0: (n,) the shafts' angles at rest, rad.  q_offset_rad: (n,) the
            bench's zero errors (the arm hangs down at -q_offset).
    """

    STEP_S = 5e-4

    def __init__(self, servos, mass_kg: float, length_m: float, q0=None, q_offset_rad=None):
        from .servo_physics import warm_up

        warm_up()
        n = len(servos.k_Nm_per_A)
        self.servos = servos
        #: The rotor's inertia at the shaft, kg m^2 (what a bench identifies as its armature).
        self.armature = catalogue_motor(servos.model).servo.reflected_inertia
        self.armature *= servos.rotor_inertia_scale
        self.inertia = mass_kg * length_m**2 + self.armature
        self.gravity_Nm = mass_kg * 9.80665 * length_m
        self.q_offset = np.zeros(n) if q_offset_rad is None else np.asarray(q_offset_rad, float)
        self._q = np.zeros(n) if q0 is None else np.array(q0, dtype=float)
        self._v = np.zeros(n)
        self._i = np.zeros(n)

    def advance(self, dt_s, current_A):
        from .servo_physics import current_step, friction_budget, stopping_friction

        s = self.servos
        n_steps = max(1, math.ceil(dt_s / self.STEP_S))
        h = dt_s / n_steps
        target = np.asarray(current_A, dtype=float).tolist()
        q, v, i = self._q.tolist(), self._v.tolist(), self._i.tolist()
        for k, goal in enumerate(target):
            for _ in range(n_steps):
                i[k] = current_step(
                    i[k], goal, h, s.current_time_constant_s, v[k], s.supply_V,
                    s.k_Nm_per_A[k], s.resistance_ohm[k], s.current_limit_A,
                )  # fmt: skip
                tau_m = s.k_Nm_per_A[k] * i[k]
                tau_e = -self.gravity_Nm * math.sin(q[k] + self.q_offset[k])
                net = tau_m + tau_e
                budget = friction_budget(s.friction[k], v[k], tau_m, tau_e)
                net += stopping_friction(self.inertia, h, v[k], net, budget)
                v[k] += h * net / self.inertia
                q[k] += h * v[k]
        self._q, self._v, self._i = np.array(q), np.array(v), np.array(i)

    def currents_A(self) -> np.ndarray:
        """(n,) the currents the servos drive now, A (Present Current)."""
        return self._i.copy()

    def positions_rad(self):
        return self._q.copy()

    def velocities_rad_s(self):
        return self._v.copy()


class StackedServos(ServoBackend):
    """Several backends behind one bus, their servos in order: the robot's six cranks, then a
    surrogate's stage (:meth:`FirstOrderServos.linear_stage`), say. Each part is advanced with
    its own servos' currents, the same ``dt_s``: one clock for all."""

    def __init__(self, *parts: ServoBackend):
        self.parts = parts
        self._sizes = [len(part.positions_rad()) for part in parts]

    def advance(self, dt_s, current_A):
        current_A = np.asarray(current_A, dtype=float)
        start = 0
        for part, n in zip(self.parts, self._sizes):
            part.advance(dt_s, current_A[start : start + n])
            start += n

    def positions_rad(self):
        return np.concatenate([part.positions_rad() for part in self.parts])

    def velocities_rad_s(self):
        return np.concatenate([part.velocities_rad_s() for part in self.parts])

    def pwm_currents(self, duty):
        """Each part's servos at their duty; a part with no winding to drive (a stage in Current
        Control Mode beside cranks in Position Control Mode, none of its duties set) zeros.

        Raises:
            InvalidConfigError: a duty set on a part with no PWM drive.
        """
        duty = np.asarray(duty, dtype=float)
        out, start = [], 0
        for part, n in zip(self.parts, self._sizes):
            share = duty[start : start + n]
            try:
                out.append(np.asarray(part.pwm_currents(share), dtype=float))
            except InvalidConfigError:
                if np.any(share):
                    raise
                out.append(np.zeros(n))
            start += n
        return np.concatenate(out)


__all__ = [
    "ServoBackend",
    "FirstOrderServos",
    "BenchServos",
    "StackedServos",
]
