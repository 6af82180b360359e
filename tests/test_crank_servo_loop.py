"""The crank servo closing the loop on the simulated robot of the servo bus (``paper_bus``: its
4096-count encoders, one period of delay, the XM430's friction and current loop, 10 ms): the
library's breathing within the bounds the encoders allow, far inside what the paper's LQI does
on the same robot; the friction believed found when the plant's is half or 1.5 times the
catalogue's; a payload the controller does not know held by its integral action."""

import dataclasses

import numpy as np
import pytest

from stewart_drake.control.lqi.driver import LqiDriver
from stewart_drake.organ_motion.reproduction import reproduce
from stewart_drake.references.organ.breathing import Breathing
from stewart_drake.robot import kinematics
from stewart_drake.robot.geometry import X_HOME
from stewart_drake.run.plan import make_plan
from stewart_drake.run.scenario_io import load_scenario
from stewart_drake.run.simulate import run_experiment

#: The encoders' floor at home (one count of 4096 uniform on each crank through J^-1, RMS):
#: X, Y, Z m and roll, pitch, yaw rad (docs/robot.md, "The error budget").
FLOOR = {"X": 134e-6, "Y": 134e-6, "Z": 19.7e-6, "phi": 465e-6, "theta": 465e-6, "psi": 859e-6}
AXES = ("phi", "theta", "psi", "X", "Y", "Z")


def _floor_from_the_jacobian(geometry) -> np.ndarray:
    """The floor computed here: each crank uniform within half a count, independent."""
    q = 2 * np.pi / 4096
    J_inv = np.linalg.inv(kinematics.jacobian(geometry, X_HOME))
    return np.sqrt(np.sum(J_inv**2, axis=1) * q**2 / 12)


def test_the_floors_figures_are_the_jacobians(geometry):
    floor = _floor_from_the_jacobian(geometry)
    for k, axis in enumerate(AXES):
        assert floor[k] == pytest.approx(FLOOR[axis], rel=0.01)


def _bus(**changes):
    scenario = load_scenario("paper_bus", [])
    return dataclasses.replace(scenario, **changes)


def _hardware(scenario, friction_scale=1.0):
    """The bus scenario as a simulation without the bus, its hardware written out, the plant's
    Coulomb friction scaled."""
    hw = scenario.bus.hardware(scenario.control_period_s)
    motors = dataclasses.replace(
        hw.motors, coulomb_friction_Nm=hw.motors.coulomb_friction_Nm * friction_scale
    )
    return dataclasses.replace(scenario, bus=None, hardware=dataclasses.replace(hw, motors=motors))


@pytest.fixture(scope="module")
def breathing_runs():
    """(servo, LQI) reproductions of the library's breathing on paper_bus, 3 cycles measured."""
    servo = reproduce(_bus(), Breathing(), eval_cycles=3)
    lqi = reproduce(
        _bus(controller=LqiDriver(omega_Q=0.01, schedule_period_s=0.02), feedforward="gravity"),
        Breathing(),
        eval_cycles=3,
    )
    return servo, lqi


def test_breathing_on_the_bus_robot_is_within_the_encoders_bounds(breathing_runs):
    """The true pose's RMS error per axis within 1.35 times the encoders' floor, and at least a
    fifth of it: a controller that reads one count in 4096 cannot hold the cranks much closer
    than that, and a figure far below it would be measuring something else.

    Why 1.35: the loop is quantised to counts, so a rounding difference (another CPU's BLAS,
    another numpy) moves which count a crank reads at a reversal, and the figure with it. Eight
    runs of this breathing with its amplitude moved by 0 to 1e-9 of itself gave, as a multiple of
    the floor, phi 0.61-0.74, theta 0.90-1.02, psi 0.58-0.67, X 0.78-0.90, Y 0.51-0.67, Z
    1.05-1.17 (max / min of an axis up to 1.31); another machine's theta 1.06. The bound holds the
    largest of them with that spread's margin again; the wrong loops this test is for (friction
    not fed forward, no integral action) miss the floor by 3 to 50 times (docs/robot.md)."""
    servo, _ = breathing_runs
    rms = dict(zip(AXES, servo.fidelity["rms"]))
    for axis in AXES:
        assert 0.2 * FLOOR[axis] < rms[axis] < 1.35 * FLOOR[axis], (axis, rms[axis], FLOOR[axis])


def test_the_lqi_on_the_same_robot_is_several_times_further(breathing_runs):
    servo, lqi = breathing_runs
    s, q = servo.fidelity["rms"], lqi.fidelity["rms"]
    assert q[3] > 3 * s[3]  # X, the motion's axis
    assert q[1] > 2 * s[1]  # theta


@pytest.mark.parametrize("plant_friction", [0.5, 1.5])
def test_the_friction_believed_converges_on_the_plants(plant_friction):
    """The plant's dry friction half or 1.5 times the catalogue's the controller starts from:
    after 6 breaths the cranks that the breathing turns believe the plant's within 20 %."""
    scenario = _hardware(_bus(duration_s=24.0), plant_friction)
    result = run_experiment(scenario, reference=Breathing())
    friction = result.metrics["status"]["friction_mean_Nm"]
    true = 0.205 * plant_friction
    # the mean over six cranks; two of them barely turn under an X breath (their estimate
    # moves less), so the mean is held to 25 %
    assert friction == pytest.approx(true, rel=0.25)
    assert abs(friction - true) < abs(0.205 - true)  # it moved towards the plant's


def test_a_payload_the_controller_does_not_know_is_held_by_the_integral():
    """Half again the platform's mass (payload_scale 1.5) holding home: the gravity
    feed-forward is short by a third of the platform's weight, which sags the platform by
    about 3 counts' worth of Z at first; the integral (its corner at 2.5 / 4 Hz) builds with
    that error and pushes the cranks through their dry friction after about 5 s, and from
    6.5 s on it is within two counts of home (measured at the 5 ms period: 2.9 counts until
    5 s, within one from 6 s on; at 10 ms the sag is 4.3 counts and the integral, fed a
    larger error, breaks through at 3.5 s)."""
    from stewart_drake.references.trajectories import NamedReference

    scenario = _bus(duration_s=8.0, payload_scale=1.5, reference=NamedReference(name="home"))
    result = run_experiment(scenario)
    count = _floor_from_the_jacobian(make_plan(_bus(), with_reference=False).geometry) * np.sqrt(
        12
    )  # one count, per axis
    early = result.x[result.t < 0.5, 5] - result.x_d[result.t < 0.5, 5]
    assert np.abs(early).max() > 2 * count[5]  # the payload did sag it
    e = result.x[result.t >= 6.5, :6] - result.x_d[result.t >= 6.5, :6]
    assert np.all(np.abs(e).max(axis=0) < 2 * count), np.abs(e).max(axis=0) / count


def test_a_calibrated_robots_encoder_zeros_are_taken_off_its_readings():
    """A robot whose encoders read +-5 mrad off each crank's zero, known to the controller (a
    calibrated robot: its ``encoder_offsets_rad``) and built so in the plant, holding home: from
    2 s on within two counts of home on every axis. Added instead of removed, the offsets would
    turn the platform by tens of mrad (yaw -47.5 mrad at rest, as measured once such a bug)."""
    from stewart_drake.references.trajectories import NamedReference

    offsets = [5e-3, -5e-3, 5e-3, -5e-3, 5e-3, -5e-3]
    scenario = _bus(duration_s=3.0, reference=NamedReference(name="home"))
    scenario.robot.encoder_offsets_rad = offsets
    scenario = _hardware(scenario)
    result = run_experiment(scenario)
    geometry = make_plan(scenario, with_reference=False).geometry
    np.testing.assert_allclose(geometry.encoder_offsets, offsets)  # the robot the loop believes
    count = _floor_from_the_jacobian(geometry) * np.sqrt(12)
    e = result.x[result.t >= 2.0, :6] - result.x_d[result.t >= 2.0, :6]
    assert np.all(np.abs(e).max(axis=0) < 2 * count), np.abs(e).max(axis=0) / count
