"""The robot's Drake plant behind the bus emulator: six servos that move the platform.

:class:`StationServos` is a :class:`~stewart_drake.station.bus.servo_models.ServoBackend` that
steps the station of a scenario (:func:`~stewart_drake.run.diagram.held_station`: the closed-chain
MultibodyPlant with the motors' reflected inertia and friction) with the servos' torques ``K_t i``
on ``motor_torque``, and reports the crank joints' angles and rates read from the plant (not through
the station's encoders: the emulator quantizes to the servo's 4096 counts),
each angle plus its encoder's zero error: with the scenario's ``robot_as_built``, the plant is
that robot and the servos read its ``encoder_offsets_rad`` (the plan's ``plant_geometry``), as a
servo mounted a little off its zero does; the controller, on the bus, believes ``robot``.
Servo ``k`` of the bus is crank ``k`` (reference_geometry.md leg order), mounted in the crank's
sense (direction +1).

Use :func:`dynamixel_scenario` for the robot built with a catalogue Dynamixel: its servo in the
plant, and neither computation delay nor current-loop lag in the station (the real loop now has
its own delay, and the servo its own current loop) nor encoder noise.

While no servo drives any current (torque off everywhere, or every watchdog tripped), the plant
is not stepped and its velocities are zeroed: the platform rests where it is. The real robot
would sag onto its hard stops, which the plant does not model (its cranks would turn past them
and the closed chain leave its workspace). Once a servo drives current, the plant moves from
that rest. The plant steps at the scenario's ``plant_time_step_s``; it must run faster than
real time (about 3x on the development machine, holding) or the emulator's answers fall behind.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from ..plant.backlash import crank_angles, crank_rates
from ..robot.kinematics import X_HOME
from ..robot.motor_catalogue import catalogue_motor
from ..station.bus.servo_models import ServoBackend
from ..station.bus.servos import servo_spec


def dynamixel_scenario(model: str = "XM430-W350-T", scenario=None):
    """``scenario`` (default the paper's, :class:`~..scenario.Scenario`) built with six
    catalogue Dynamixels ``model`` and no computation delay, current-loop lag or encoder noise
    in the station (the bus and the servos bring their own); the gears' play is
    ``scenario``'s (``hardware.motors.backlash_rad``, 0 by default), and so is the servo itself
    when the scenario's ``hardware.motors`` is that model (its friction, say: a robot whose
    servos differ from the catalogue's estimates)."""
    from ..run.scenario import Scenario
    from ..station.hardware import Hardware, Motors

    base = scenario if scenario is not None else Scenario()
    hardware = base.hardware if base.hardware is not None else Hardware()
    servo = catalogue_motor(model).servo
    if base.hardware is not None and base.hardware.motors.name == servo.name:
        servo = base.hardware.motors.build()
    servo = dataclasses.replace(
        servo, current_time_constant_s=0.0, backlash_rad=hardware.motors.backlash_rad
    )
    hardware = dataclasses.replace(
        hardware,
        motors=Motors.from_value(servo),
        computation_delay_periods=0,
        encoders=dataclasses.replace(hardware.encoders, noise_counts=0.0),
    )
    return dataclasses.replace(base, hardware=hardware)


def behind_the_bus(scenario, servos=None, **changes):
    """The scenario the bus emulator simulates behind a robot's ``scenario``: no bus, the plant
    at a 2 ms step (half the CPU of 1 ms), the station's control and logs at the same period,
    and ``changes`` (fields of the scenario, e.g. ``robot_as_built``).

    With ``servos`` (:class:`~stewart_drake.station.bus.emulator_config.EmulatedServos`), the
    robot departs from the one the controller believes as they say: its servos' rotors and
    viscous friction scaled, their gear play, the platform's mass, and its temperature (its
    lengths at ``lengths_at_c`` + the rise, the controller not told); the servos' drive and
    friction budget are :class:`RealisticServos`'."""
    import copy

    plant = copy.copy(scenario.plant)
    plant.time_step = 0.002
    if servos is not None and servos.departs():
        changes = _departed(scenario, servos) | changes
    if getattr(scenario.controller, "streams_goals", False):  # the servos' loop, not the host's
        from ..control.servo.driver import CrankServoDriver

        changes = {"controller": CrankServoDriver()} | changes
    return dataclasses.replace(
        scenario, bus=None, plant=plant, control_period_s=0.002, log_period_s=0.002, **changes
    )


def _departed(scenario, servos) -> dict:
    """The scenario fields of the robot ``servos`` describe (:func:`behind_the_bus`)."""
    from ..station.bus.servo_physics import FRICTION
    from ..station.hardware import Hardware, Motors

    hardware = scenario.hardware
    if hardware is None:
        bus = scenario.bus
        hardware = bus.hardware(scenario.control_period_s) if bus is not None else Hardware()
    base = hardware.motors.build()
    rest = servos.friction[:, FRICTION["coulomb_Nm"]] + servos.friction[:, FRICTION["stribeck_Nm"]]
    loaded = servos.friction[:, [FRICTION["load_motor"], FRICTION["load_motor_stribeck"]]]
    # Each step sets each servo's own budget on its friction actuator; a set whose friction acts
    # only under load (friction_scale 0 leaves the gears' efficiency) still needs the actuators.
    budget = float(np.max(rest)) if np.max(rest) > 0 or not np.any(loaded) else 1e-12
    servo = dataclasses.replace(
        base,
        rotor_inertia=base.rotor_inertia * servos.rotor_inertia_scale,
        viscous_damping=base.viscous_damping * servos.viscous_scale,
        coulomb_friction_Nm=budget,
        backlash_rad=servos.backlash_rad,
    )
    out = {
        "hardware": dataclasses.replace(hardware, motors=Motors.from_value(servo)),
        "payload_scale": scenario.payload_scale * servos.mass_scale,
    }
    if servos.temperature_rise_K:
        out["temperature_c"] = scenario.robot.build().lengths_at_c + servos.temperature_rise_K
        out["compensate_temperature"] = False
    return out


class StationServos(ServoBackend):
    """Six servos at the cranks of the station of ``scenario``, assembled at pose ``x0``.

    Args:
        scenario: a Scenario or plan (default :func:`dynamixel_scenario` of ``model``).
        model: the bus's servo model (its torque constant turns current into torque).
        x0: (6,) starting pose [rad, m] (default home).
    Raises:
        UnreachablePoseError: ``x0`` cannot be assembled; InvalidConfigError: a bad scenario.
    """

    def __init__(self, scenario=None, model: str = "XM430-W350-T", x0=X_HOME):
        from ..run.diagram import held_station

        self.spec = servo_spec(model)
        scenario = dynamixel_scenario(model) if scenario is None else scenario
        self.station, self.simulator, _ = held_station(scenario, x0, T=np.zeros(6))
        self._root = self.simulator.get_mutable_context()
        self._plant_context = self.station.plant.GetMyMutableContextFromRoot(self._root)
        self._torque_port = self.simulator.get_system().get_input_port(0)
        self._motors = list(self.station.handles.motors)

    def advance(self, dt_s, current_A):
        tau = self.spec.torque_constant_Nm_per_A * np.asarray(current_A, dtype=float)
        if not np.any(tau):  # at rest (the plant's clock stops with it: only steps count)
            plant = self.station.plant
            plant.SetVelocities(self._plant_context, np.zeros(plant.num_velocities()))
            return
        self._torque_port.FixValue(self._root, tau)
        self.simulator.AdvanceTo(self._root.get_time() + dt_s)

    def positions_rad(self):
        # The servo's encoder is on its output shaft: the crank's angle, after any gear play,
        # plus its zero error (the robot as built's encoder offsets).
        station = self.station
        theta = crank_angles(station.plant, self._plant_context, station.handles)
        return theta + station.plan.plant_geometry.encoder_offsets

    def velocities_rad_s(self):
        station = self.station
        return crank_rates(station.plant, self._plant_context, station.handles)

    def _motor_rates(self) -> np.ndarray:
        """(6,) the motors' rates at the horn, rad/s (inside any gear play)."""
        return np.array([m.get_angular_rate(self._plant_context) for m in self._motors])

    def pwm_currents(self, duty):
        """The catalogue's servo driven at ``duty`` of its family's supply: ``(d V - k_e v) /
        R``, ``R`` the supply over the stall current, ``k_e`` the supply over the no-load speed
        (the catalogue's figures, as the controller believes them), A."""
        from ..station.bus.protocol import SUPPLY_V

        supply = SUPPLY_V[self.spec.table.family]
        servo = catalogue_motor(self.spec.name).servo
        k_e = supply / servo.no_load_speed_rad_s
        r = supply / self.spec.stall_current_A
        return (np.asarray(duty, dtype=float) * supply - k_e * self._motor_rates()) / r


class RealisticServos(StationServos):
    """:class:`StationServos` whose servos are ``servos``
    (:class:`~stewart_drake.station.bus.emulator_config.EmulatedServos`): each servo's current
    follows its Goal Current through the current loop's lag, within what its supply drives
    against the back-EMF (:func:`~stewart_drake.station.bus.servo_physics.current_step`); its
    torque is ``k i`` with its own motor constant; its gear train's friction budget
    (:func:`~stewart_drake.station.bus.servo_physics.friction_budget`, the load taken as the
    motor's torque, which the closed chain carries) is set each step as the effort limit of its
    crank's friction actuator, which SAP applies implicitly as the torque that stops the joint,
    clipped to it; its encoder reads with its transition noise and non-linearity (the X series'
    on the output shaft, the DYNAMIXEL-P's on the motor's, inside the gears' play), in counts,
    the non-linearity's error at angle 0 taken into the zero count as a calibration there does.

    Args:
        scenario: the robot behind the bus (:func:`behind_the_bus` with ``servos``).
        model: the bus's servo model.  x0: (6,) the pose it starts at.  servos: the set.
    """

    def __init__(self, scenario, model: str, x0, servos):
        super().__init__(scenario, model, x0)
        from ..station.bus.servo_physics import warm_up

        warm_up()
        self.servos = servos
        plant = self.station.plant
        # crank k's friction actuator is "friction_k" (plant.add_stewart_plant); a set drawn
        # without friction (friction_scale 0) has a plant without them, and nothing to set.
        names = [f"friction_{k}" for k in range(6)]
        self._friction = (
            [plant.GetJointActuatorByName(name) for name in names]
            if plant.HasJointActuatorNamed(names[0])
            else []
        )
        self._i = np.zeros(6)
        self._rng = np.random.default_rng([servos.seed, 1])
        self._count = self.spec.rad_per_count
        self._budget = np.zeros(6)
        self._plant_step_s = float(plant.time_step())
        self._held_s = 0.0  # advanced since the simulator's last step, s

    def advance(self, dt_s, current_A):
        from ..station.bus.servo_physics import current_step, friction_budget

        target = np.asarray(current_A, dtype=float)
        s = self.servos
        if not np.any(target) and not np.any(self._i):  # at rest, unpowered
            super().advance(dt_s, target)
            return
        v = self._motor_rates()
        for k in range(6):
            self._i[k] = current_step(
                self._i[k], target[k], dt_s, s.current_time_constant_s, v[k], s.supply_V,
                s.k_Nm_per_A[k], s.resistance_ohm[k], s.current_limit_A,
            )  # fmt: skip
        # The discrete plant moves only at its steps, each under the torque and friction set
        # by the advance that starts there: an advance within a step (a servo's 1 ms firmware
        # on a 2 ms plant) only moves the currents and the clock (the same motion, less CPU).
        start = self._root.get_time() + self._held_s
        self._held_s += dt_s
        h_p = self._plant_step_s
        if math.ceil(start / h_p - 1e-6) * h_p >= start + dt_s - 1e-9:
            return
        tau = s.k_Nm_per_A * self._i
        for k, actuator in enumerate(self._friction):
            self._budget[k] = friction_budget(s.friction[k], v[k], tau[k], -tau[k])
            # Drake takes only a positive limit: 1e-12 N m is none (a servo without dry friction
            # and without load)
            actuator.set_effort_limit(max(float(self._budget[k]), 1e-12))
        self._torque_port.FixValue(self._root, tau)
        self.simulator.AdvanceTo(start + dt_s)
        self._held_s = 0.0

    def currents_A(self) -> np.ndarray:
        """(6,) the currents the servos drive now, A (Present Current)."""
        return self._i.copy()

    def pwm_currents(self, duty):
        """Each servo as it is driven at ``duty`` of its supply (the family's where the set
        has no voltage limit): ``(d V - k v) / R`` with its own motor constant and winding, A."""
        from ..station.bus.protocol import SUPPLY_V

        s = self.servos
        supply = s.supply_V if np.isfinite(s.supply_V) else SUPPLY_V[self.spec.table.family]
        drive = np.asarray(duty, dtype=float) * supply - s.k_Nm_per_A * self._motor_rates()
        return drive / s.resistance_ohm

    def positions_rad(self):
        s = self.servos
        offsets = self.station.plan.plant_geometry.encoder_offsets
        if s.family == "P":  # the encoder on the motor's shaft: inside the play
            theta = np.array([m.get_angle(self._plant_context) for m in self._motors])
        else:
            theta = super().positions_rad() - offsets
        # the non-linearity as the zero calibration leaves it (``robot --calibrate 0`` reads the
        # counts at angle 0, its error there with them)
        error = s.inl_counts * (np.sin(theta + s.inl_phase) - np.sin(s.inl_phase))
        if s.encoder_noise_counts > 0:
            error = error + self._rng.normal(0.0, s.encoder_noise_counts, 6)
        return theta + offsets + error * self._count
