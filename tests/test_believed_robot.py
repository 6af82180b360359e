"""The controller believes one robot, the plant is another: ``robot`` is what the controller,
its estimator and the feed-forward use, ``robot_as_built`` what is simulated
(docs/calibration.md)."""

import dataclasses

import numpy as np
import pytest

from stewart_drake.base.errors import InvalidConfigError, InvalidGeometryError
from stewart_drake.plant.closed_chain import loop_closure_errors
from stewart_drake.robot.forward_kinematics import fk
from stewart_drake.robot.geometry import StewartGeometry
from stewart_drake.robot.kinematics import X_HOME, ik
from stewart_drake.run.diagram import controller_context, held_station
from stewart_drake.run.plan import make_plan
from stewart_drake.run.scenario import Robot, Scenario, _scenario_from_yaml, dump_scenario
from stewart_drake.run.scenario_io import load_scenario

#: A robot as built: every kind of per-leg deviation, of the order of the default tolerances
#: (docs/calibration.md).
_OFFSETS = (0.004, -0.003, 0.002, -0.001, 0.003, -0.004)


def _as_built() -> StewartGeometry:
    rng = np.random.default_rng(7)
    return StewartGeometry().replace(
        pivot_offsets_m=tuple(map(tuple, rng.uniform(-5e-4, 5e-4, (6, 3)).tolist())),
        platform_offsets_m=tuple(map(tuple, rng.uniform(-5e-4, 5e-4, (6, 3)).tolist())),
        crank_lengths_m=tuple((0.11 + rng.uniform(-2e-4, 2e-4, 6)).tolist()),
        rod_lengths_m=tuple((0.404 + rng.uniform(-3e-4, 3e-4, 6)).tolist()),
        encoder_offsets_rad=_OFFSETS,
    )


def _scenario(**changes) -> Scenario:
    scenario = load_scenario("paper_hardware")
    scenario.robot_as_built = Robot.from_value(_as_built())
    return dataclasses.replace(scenario, **changes)


def test_without_a_robot_as_built_the_plant_is_the_robot():
    plan = make_plan(load_scenario("paper_hardware"), with_reference=False)
    assert plan.scenario.robot_as_built is None
    assert plan.plant_geometry is plan.geometry
    heavy = make_plan(load_scenario("paper_hardware", ["payload_scale=1.2"]), with_reference=False)
    assert heavy.plant_geometry == heavy.geometry.replace(
        platform_mass=1.2 * heavy.geometry.platform_mass,
        platform_inertia=tuple(1.2 * v for v in heavy.geometry.platform_inertia),
    )


def test_the_plant_is_the_robot_as_built_with_the_motors_and_payload_of_the_plan():
    plan = make_plan(_scenario(payload_scale=1.2), with_reference=False)
    assert plan.geometry == load_scenario("paper_hardware").robot.build().replace(
        motor_reflected_inertia=plan.servo.reflected_inertia
    )
    assert plan.plant_geometry == _as_built().replace(
        motor_reflected_inertia=plan.servo.reflected_inertia,
        platform_mass=1.2 * plan.geometry.platform_mass,
        platform_inertia=tuple(1.2 * v for v in plan.geometry.platform_inertia),
    )


def test_the_plant_closes_the_as_built_loops_and_the_estimator_believes_the_robot():
    plan = make_plan(_scenario(), with_reference=False)
    station, simulator, context = held_station(plan, X_HOME)
    assert station.handles.geometry == plan.plant_geometry
    # The plant is assembled with the as-built legs: its cranks at the as-built IK, loops closed.
    crank = station.GetOutputPort("motor_angle").Eval(context)
    theta = ik(plan.plant_geometry, X_HOME)
    quantum = plan.scenario.hardware.encoders.quantum_rad
    # The encoders add the as-built zero errors (then round to their count).
    np.testing.assert_allclose(crank, theta + np.array(_OFFSETS), atol=quantum)
    assert np.max(np.abs(crank - ik(plan.geometry, X_HOME) - _OFFSETS)) > 100 * quantum
    plant_context = station.plant.GetMyContextFromRoot(simulator.get_context())
    assert np.max(loop_closure_errors(station.plant, plant_context, station.handles)) < 1e-9
    pose = station.GetOutputPort("platform_state").Eval(context)[:6]
    np.testing.assert_allclose(pose, X_HOME, atol=1e-9)
    # The controller's estimator is the believed robot's: no zero errors, nominal legs; the pose
    # it estimates from these readings is off by what the believed robot's FK predicts.
    estimator = controller_context(plan, X_HOME, np.zeros(6)).pose_estimator
    assert estimator.geometry is plan.geometry
    x_hat, _, converged = estimator.estimate(crank, X_HOME)
    assert converged
    np.testing.assert_allclose(x_hat, fk(plan.geometry, crank, x0=X_HOME)[0], atol=1e-6)
    # ... which, but for the encoders' rounding (half a count: 24 urad), the IK predicts.
    expected, _ = fk(plan.geometry, theta + np.array(_OFFSETS), x0=X_HOME)
    np.testing.assert_allclose(x_hat, expected, atol=1e-4)
    assert np.linalg.norm(x_hat[3:] - X_HOME[3:]) > 1e-4  # millimetres off, not noise


def test_a_robot_as_built_goes_through_yaml():
    scenario = _scenario()
    loaded = _scenario_from_yaml(dump_scenario(scenario))
    assert loaded.robot_as_built == scenario.robot_as_built
    assert make_plan(loaded, with_reference=False).plant_geometry == (
        make_plan(scenario, with_reference=False).plant_geometry
    )
    assert (
        _scenario_from_yaml(dump_scenario(load_scenario("paper_hardware"))).robot_as_built is None
    )


def test_a_bad_robot_as_built_is_named():
    scenario = _scenario()
    scenario.robot_as_built.encoder_offsets_rad = [0.5] * 6
    with pytest.raises(InvalidGeometryError, match="robot_as_built: .*encoder_offsets_rad"):
        scenario.validate()
    scenario.robot_as_built = {"rod_length": 0.4}
    with pytest.raises(InvalidConfigError, match="robot_as_built must be None or a Robot"):
        scenario.validate()
    scenario.robot_as_built = Robot(rod_lengths_m=[0.4] * 5)
    with pytest.raises(InvalidGeometryError, match="robot_as_built: .*rod_lengths_m"):
        scenario.validate()
