"""A scenario that drives the servo bus, given to a simulation (``stewart-drake run --scenario
paper_bus``): the robot the bus drives is simulated with the bus's servos and encoders, the bus
left closed (it used to fail with "the bus on /dev/ttyUSB0 is not open: call open() first")."""

import numpy as np
import pytest

from stewart_drake.robot.motor_catalogue import catalogue_motor
from stewart_drake.run.plan import make_plan
from stewart_drake.run.scenario_io import ROBOT_SCENARIO, load_scenario
from stewart_drake.run.simulate import run_experiment, simulated_robot
from stewart_drake.station.station import StewartStation


def test_the_bus_scenario_is_simulated_with_its_servos_and_its_bus_closed():
    on_bus = load_scenario(ROBOT_SCENARIO)
    assert on_bus.bus is not None and on_bus.hardware is None
    simulated = simulated_robot(on_bus)
    assert simulated.bus is None and on_bus.bus is not None  # the user's scenario untouched
    servo = catalogue_motor(on_bus.bus.model).servo
    motor = simulated.hardware.motors
    # The bus's servo as the catalogue has it, and one period of delay as the driver makes.
    assert motor.coulomb_friction_Nm == pytest.approx(servo.coulomb_friction_Nm, rel=1e-12)
    assert simulated.hardware.computation_delay_periods == 1
    assert simulated.control_period_s == on_bus.control_period_s == pytest.approx(0.005)
    assert make_plan(simulated).station_factory is StewartStation


def test_a_plan_built_for_the_bus_is_simulated_on_the_simulated_station():
    on_bus = make_plan(load_scenario(ROBOT_SCENARIO))
    assert on_bus.station_factory is not StewartStation
    plan = simulated_robot(on_bus)
    assert plan.station_factory is StewartStation and plan.scenario.bus is None
    # The robot's values were the bus's servos' already: the same plan otherwise.
    assert plan.scenario.hardware == on_bus.scenario.hardware is not None
    assert plan.torque_limit_Nm == on_bus.torque_limit_Nm
    assert plan.delay_periods == on_bus.delay_periods == 1
    assert plan.reference is on_bus.reference


def test_a_bus_scenario_runs_as_a_simulation():
    scenario = load_scenario(ROBOT_SCENARIO)
    scenario.duration_s = 0.3
    result = run_experiment(scenario)
    assert result.t[-1] == pytest.approx(0.3, abs=0.011)
    assert np.all(np.isfinite(result.x))
