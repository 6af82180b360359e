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


def behind_the_bus(scenario, **changes):
    """The scenario the bus emulator simulates behind a robot's ``scenario``: no bus, the plant
    at a 2 ms step (half the CPU of 1 ms), the station's control and logs at the same period,
    and ``changes`` (fields of the scenario, e.g. ``robot_as_built``)."""
    import copy

    plant = copy.copy(scenario.plant)
    plant.time_step = 0.002
    return dataclasses.replace(
        scenario, bus=None, plant=plant, control_period_s=0.002, log_period_s=0.002, **changes
    )


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
