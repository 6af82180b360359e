"""A scenario's ``robot_tolerances``: the robot as built drawn from the tolerances of its parts
with a seed (robot/tolerances.py, docs/scenarios.md "The robot as built, drawn"). The plant Drake
builds is the drawn robot, read back from the plant; the controller keeps ``robot``."""

import dataclasses

import numpy as np
import pytest
from conftest import assert_plant_has_the_legs_of
from pydrake.common.yaml import yaml_load_typed

from stewart_drake.base.errors import CorruptFileError, InvalidConfigError, InvalidGeometryError
from stewart_drake.plant.closed_chain import LoopClosure, loop_closure_errors
from stewart_drake.robot.geometry import StewartGeometry
from stewart_drake.robot.kinematics import X_HOME, ik
from stewart_drake.robot.legs import LegParameters
from stewart_drake.robot.tolerances import RobotTolerances, Tolerance, Tolerances, ToleranceSpec
from stewart_drake.run.diagram import held_station
from stewart_drake.run.plan import make_plan
from stewart_drake.run.scenario import Robot, Scenario, _scenario_from_yaml, dump_scenario
from stewart_drake.run.scenario_io import load_scenario

NOMINAL = load_scenario("paper_hardware").robot.build()


def _plan(*overrides):
    return make_plan(load_scenario("paper_hardware", overrides), with_reference=False)


def _legs_of(g: StewartGeometry) -> dict:
    """The leg values every part of the package computes from."""
    return {
        "P_B": g.P_B,
        "p_E": g.p_E,
        "crank_lengths": g.crank_lengths,
        "rod_lengths": g.rod_lengths,
        "u_B": g.u_B,
        "w_B": g.w_B,
        "d_B": g.d_B,
        "encoder_offsets": g.encoder_offsets,
    }


def test_the_plan_simulates_the_robot_the_tolerances_draw_and_the_controller_keeps_robot():
    plan = _plan("robot_tolerances={seed: 3}")
    drawn = Tolerances().draw(NOMINAL, 3).geometry(NOMINAL)
    assert plan.plant_geometry == drawn.replace(
        motor_reflected_inertia=plan.servo.reflected_inertia
    )
    assert plan.geometry == NOMINAL.replace(motor_reflected_inertia=plan.servo.reflected_inertia)
    # The same as giving the drawn robot as robot_as_built.
    scenario = load_scenario("paper_hardware")
    scenario.robot_as_built = Robot.from_value(drawn)
    assert make_plan(scenario, with_reference=False).plant_geometry == plan.plant_geometry


def test_the_plant_drake_builds_has_the_drawn_legs():
    """Read back from the station's plant: the pivots, the motor axes, the crank lengths and
    the encoders' zeros are the drawn robot's; its ball constraints hold the drawn robot's
    platform joints and rod lengths (the loops, measured with the drawn points, stay closed
    while the plant moves; measured with the nominal robot's they are open by a millimetre)."""
    plan = _plan("robot_tolerances={seed: 3}")
    drawn = Tolerances().as_built(NOMINAL, 3)
    station, simulator, context = held_station(plan, X_HOME)
    plant, handles = station.plant, station.handles
    pc = plant.GetMyContextFromRoot(simulator.get_context())
    assert_plant_has_the_legs_of(plant, pc, handles, drawn)
    assert np.abs(drawn.P_B - NOMINAL.P_B).max() > 1e-4
    assert np.abs(drawn.u_B - NOMINAL.u_B).max() > 1e-4
    theta = np.array([j.get_angle(pc) for j in handles.motors])
    np.testing.assert_allclose(theta, ik(drawn, X_HOME), rtol=0, atol=1e-9)
    reading = station.GetOutputPort("motor_angle").Eval(context)
    quantum = plan.scenario.hardware.encoders.quantum_rad
    np.testing.assert_allclose(reading, theta + drawn.encoder_offsets, rtol=0, atol=quantum)
    assert np.abs(drawn.encoder_offsets).max() > 10 * quantum
    assert loop_closure_errors(plant, pc, handles).max() < 1e-9
    simulator.AdvanceTo(0.1)
    q = plant.GetPositions(pc)
    assert LoopClosure(handles)(q).max() < 1e-6
    assert LoopClosure(dataclasses.replace(handles, geometry=NOMINAL))(q).max() > 1e-4


def test_the_same_seed_draws_the_same_robot_and_another_seed_another():
    a, b = _plan("robot_tolerances={seed: 3}"), _plan("robot_tolerances={seed: 3}")
    c = _plan("robot_tolerances={seed: 4}")
    assert a.plant_geometry == b.plant_geometry
    assert np.abs(a.plant_geometry.P_B - c.plant_geometry.P_B).max() > 1e-5
    assert np.abs(a.plant_geometry.encoder_offsets - c.plant_geometry.encoder_offsets).max() > 1e-4


def test_zero_half_widths_draw_the_nominal_robot_to_the_bit():
    zero = "{half_width: 0}"
    kinds = [f.name for f in RobotTolerances.__dataclass_fields__.values() if f.name != "seed"]
    plan = _plan("robot_tolerances={seed: 11, " + ", ".join(f"{k}: {zero}" for k in kinds) + "}")
    drawn, nominal = _legs_of(plan.plant_geometry), _legs_of(plan.geometry)
    for name in drawn:
        assert np.array_equal(drawn[name], nominal[name]), name


def test_a_normal_tolerance_draws_its_block_of_the_deviation_vector():
    spec = RobotTolerances(seed=5, rod_lengths_m=ToleranceSpec(1e-3, "normal"))
    deviations = spec.tolerances().deviations(5)
    assert spec.tolerances().rod_lengths_m == Tolerance(1e-3, "normal")
    rods = spec.as_built(NOMINAL).rod_lengths - NOMINAL.rod_length
    np.testing.assert_allclose(rods, deviations[42:48], rtol=0, atol=1e-15)  # the rods' block


def test_the_yaml_form_has_the_tolerances_defaults_and_its_own_field_names():
    assert RobotTolerances().tolerances() == Tolerances()
    spec = RobotTolerances(crank_azimuths_rad=ToleranceSpec(2e-3))
    assert spec.tolerances().crank_angles_deg.half_width == 2e-3


def test_as_built_adds_to_a_per_leg_robot_and_is_draw_on_the_symmetric_one():
    tolerances = Tolerances()
    assert tolerances.as_built(NOMINAL, 8) == tolerances.draw(NOMINAL, 8).geometry(NOMINAL)
    of, nominal = LegParameters.of(NOMINAL), LegParameters.nominal(NOMINAL)
    for name in LegParameters.__dataclass_fields__:
        assert np.array_equal(getattr(of, name), getattr(nominal, name)), name
    first = tolerances.as_built(NOMINAL, 8)
    twice = tolerances.as_built(first, 9)
    step = tolerances.deviations(9)
    np.testing.assert_allclose(twice.P_B - first.P_B, step[:18].reshape(6, 3), atol=1e-15)
    np.testing.assert_allclose(
        twice.encoder_offsets - first.encoder_offsets, step[60:], rtol=0, atol=1e-15
    )


def test_robot_tolerances_go_through_yaml_and_a_scenario_without_them_writes_none():
    scenario = load_scenario("paper_hardware", ["robot_tolerances={seed: 12}"])
    scenario.robot_tolerances.shaft_tilts_rad = ToleranceSpec(2e-3, "normal")
    loaded = _scenario_from_yaml(dump_scenario(scenario))
    assert loaded.robot_tolerances == scenario.robot_tolerances
    assert "robot_tolerances" not in dump_scenario(load_scenario("paper_hardware"))
    text = "robot_tolerances:\n  seed: 2\n  crank_lengths_m: {half_width: 0.0001}\n"
    spec = yaml_load_typed(schema=Scenario, data=text, allow_schema_with_no_yaml=True)
    assert spec.robot_tolerances.crank_lengths_m == ToleranceSpec(1e-4, "uniform")
    assert spec.robot_tolerances.rod_lengths_m == ToleranceSpec(3e-4, "uniform")
    text = "robot_tolerances:\n  crank_lengths_m: {distribution: normal}\n"
    spec = yaml_load_typed(schema=Scenario, data=text, allow_schema_with_no_yaml=True)
    assert spec.robot_tolerances.crank_lengths_m == ToleranceSpec(2e-4, "normal")  # its default h


@pytest.mark.parametrize(
    "override, message",
    [
        (
            "robot_tolerances.rod_lengths_m.half_width=-1e-4",
            r"robot_tolerances\.rod_lengths_m\.half_width must be .* got -0\.0001",
        ),
        (
            "robot_tolerances.shaft_tilts_rad.distribution=cauchy",
            r"robot_tolerances\.shaft_tilts_rad\.distribution must be one of uniform, normal",
        ),
        ("robot_tolerances.seed=-1", r"robot_tolerances\.seed must be an integer in"),
        ("robot_tolerances.seed=4294967296", r"robot_tolerances\.seed must be an integer in"),
        ("robot_tolerances.seed=1.5", r"--set robot_tolerances\.seed=1\.5"),
        (
            "robot_as_built={}",
            "robot_as_built and robot_tolerances both give the robot as built: set one",
        ),
    ],
)
def test_a_bad_tolerance_is_refused_naming_its_field(override, message):
    with pytest.raises(InvalidConfigError, match=message):
        load_scenario("paper_hardware", ["robot_tolerances={seed: 1}", override])


def test_tolerances_the_robot_cannot_take_are_refused_naming_the_section():
    with pytest.raises(InvalidGeometryError, match=r"robot_tolerances: .*pivot_offsets_m"):
        load_scenario("paper_hardware", ["robot_tolerances={pivot_offsets_m: {half_width: 0.01}}"])
    scenario = Scenario()
    scenario.robot_tolerances = {"seed": 1}
    with pytest.raises(InvalidConfigError, match="robot_tolerances must be None or a Robot"):
        scenario.validate()


def test_a_file_with_an_unknown_tolerance_field_is_refused(tmp_path):
    path = tmp_path / "s.yaml"
    path.write_text("robot_tolerances:\n  seed: 1\n  crank_length_m: {half_width: 0.001}\n")
    with pytest.raises(CorruptFileError, match="crank_length_m"):
        load_scenario(str(path))


def test_not_on_the_servo_bus():
    with pytest.raises(InvalidConfigError, match="robot_tolerances is simulated"):
        load_scenario("paper_bus", ["robot_tolerances={seed: 1}"])
