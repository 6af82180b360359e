"""servo.py: the servo's output-shaft numbers from its motor data (module docstring), and what
the Drake plant makes of them: the reflected inertia read back from its joint actuators and its
mass matrix."""

import dataclasses

import numpy as np
import pytest
from pydrake.systems.framework import DiagramBuilder

from stewart_drake.base.errors import InvalidConfigError
from stewart_drake.plant.plant import add_stewart_plant
from stewart_drake.robot.geometry import StewartGeometry
from stewart_drake.robot.servo import ServoModel


def test_the_defaults_are_the_docstring_s_derived_numbers():
    s = ServoModel()
    assert s.peak_torque_Nm == pytest.approx(0.702, abs=5e-4)
    assert s.reflected_inertia == pytest.approx(2.50e-4, abs=5e-7)
    assert s.reflected_inertia == s.rotor_inertia * s.gear_ratio**2
    assert s.current_time_constant_s == pytest.approx(0.385e-3, abs=5e-7)
    assert s.coulomb_friction_Nm == pytest.approx(18.4e-3, abs=5e-5)
    assert s.viscous_damping == pytest.approx(1.21e-4, abs=5e-7)
    assert s.no_load_speed_rad_s == pytest.approx(152, abs=0.5)
    # half of the no-load friction is Coulomb, half viscous at the no-load speed (at the crank)
    assert s.viscous_damping * s.no_load_speed_rad_s == pytest.approx(s.coulomb_friction_Nm)


@pytest.mark.parametrize(
    "name, value, says",
    [
        ("gear_ratio", 0.0, r"servo.gear_ratio must be a finite number in \(0, inf\]"),
        ("rotor_inertia", -1e-6, r"servo.rotor_inertia must be a finite number in \[0, inf\]"),
        ("peak_torque_Nm", float("nan"), "servo.peak_torque_Nm"),
        ("friction_damping", "1e4", r"servo.friction_damping must be a number, got '1e4'"),
        ("name", 3, "servo.name must be a string"),
    ],
)
def test_a_bad_value_is_refused_naming_the_field(name, value, says):
    with pytest.raises(InvalidConfigError, match=says):
        ServoModel(**{name: value})


def _plant(servo, reflected):
    builder = DiagramBuilder()
    geometry = StewartGeometry(motor_reflected_inertia=reflected)
    plant, _, handles = add_stewart_plant(builder, geometry, servo=servo)
    return plant, handles


def test_the_plant_s_actuators_carry_rotor_inertia_times_gear_ratio_squared():
    """Read back from the Drake plant: on each motor joint, the last actuator (the one Drake
    uses) has the servo's gear ratio and a rotor inertia whose reflection is the servo's; the
    mass matrix grows by exactly that on the motor joints' diagonal and nowhere else."""
    servo = ServoModel(rotor_inertia=2e-5, gear_ratio=5.0)
    plant, handles = _plant(servo, servo.reflected_inertia)
    bare, _ = _plant(None, 0.0)
    for i, joint in enumerate(handles.motors):
        actuators = [
            plant.get_joint_actuator(k)
            for k in plant.GetJointActuatorIndices()
            if plant.get_joint_actuator(k).joint().index() == joint.index()
        ]
        assert [a.name() for a in actuators] == [f"motor_{i}", f"friction_{i}"]
        last = actuators[-1]
        assert last.default_gear_ratio() == 5.0
        assert last.default_rotor_inertia() * last.default_gear_ratio() ** 2 == pytest.approx(
            servo.rotor_inertia * servo.gear_ratio**2, rel=1e-15
        )
        assert last.default_reflected_inertia() == pytest.approx(5e-4, rel=1e-15)
    M = plant.CalcMassMatrix(plant.CreateDefaultContext())
    M_bare = bare.CalcMassMatrix(bare.CreateDefaultContext())
    extra = np.zeros_like(M)
    for joint in handles.motors:
        k = joint.velocity_start()
        extra[k, k] = servo.reflected_inertia
    np.testing.assert_allclose(M - M_bare, extra, atol=1e-15)


def test_a_servo_without_coulomb_friction_has_one_actuator_per_motor():
    servo = dataclasses.replace(ServoModel(), coulomb_friction_Nm=0.0)
    plant, handles = _plant(servo, servo.reflected_inertia)
    assert handles.n_actuators == 6 and handles.desired_state_port is None
    for joint in handles.motors:
        assert joint.default_damping() == servo.viscous_damping
    actuator = plant.GetJointActuatorByName("motor_0")
    assert actuator.default_reflected_inertia() == pytest.approx(servo.reflected_inertia)
