"""Per-leg geometry (robot/geometry.py, docs/robot.md "Per-leg geometry"): a robot whose legs
each deviate from the drawing, through the kinematics, the compiled kernels, the Drake plant,
its SDF, the MuJoCo twin, the encoders and the scenario file; and the symmetric robot, given
its drawn values leg by leg, computing exactly what the drawing does."""

import dataclasses

import numpy as np
import pytest
from conftest import (
    assert_plant_has_the_legs_of,
    drawn_robot,
    needs_extra,
    random_reachable_poses,
)
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder

from stewart_drake.base.errors import InvalidGeometryError
from stewart_drake.plant.closed_chain import (
    LoopClosure,
    assemble,
    loop_closure_errors,
)
from stewart_drake.plant.plant import make_plant, platform_pose
from stewart_drake.plant.sdf import write_sdf
from stewart_drake.robot import kinematics, single_pose, statics
from stewart_drake.robot.forward_kinematics import fk
from stewart_drake.robot.geometry import PER_LEG_FIELDS, X_HOME, StewartGeometry
from stewart_drake.robot.limits import _joint_axes, limit_margins
from stewart_drake.robot.path_checks import compiled_kinematics

NOMINAL = StewartGeometry()


def drawn_values() -> StewartGeometry:
    """The symmetric robot with every per-leg field given, equal to the drawing."""
    return NOMINAL.replace(
        pivot_offsets_m=np.zeros((6, 3)),
        platform_offsets_m=np.zeros((6, 3)),
        crank_lengths_m=[NOMINAL.crank_length] * 6,
        rod_lengths_m=[NOMINAL.rod_length] * 6,
        shaft_tilts_rad=[0.0] * 6,
        encoder_offsets_rad=[0.0] * 6,
    )


ROBOT = drawn_robot()


@pytest.fixture(scope="module")
def poses():
    return random_reachable_poses(ROBOT, 30, seed=3, margin=0.9)


# -- the model ------------------------------------------------------------------------------------


def test_the_fields_are_stored_as_tuples_and_the_arrays_follow_the_documented_signs():
    g = ROBOT
    assert isinstance(g.pivot_offsets_m, tuple) and isinstance(g.pivot_offsets_m[0], tuple)
    np.testing.assert_array_equal(g.P_B, NOMINAL.P_B + np.array(g.pivot_offsets_m))
    np.testing.assert_array_equal(g.p_E, NOMINAL.p_E + np.array(g.platform_offsets_m))
    np.testing.assert_array_equal(g.crank_lengths, g.crank_lengths_m)
    t = np.array(g.shaft_tilts_rad)[:, None]
    z = np.array([0.0, 0.0, 1.0])
    np.testing.assert_allclose(g.u_B, np.cos(t) * NOMINAL.u_B - np.sin(t) * z, atol=1e-15)
    np.testing.assert_allclose(g.w_B, np.cos(t) * z + np.sin(t) * NOMINAL.u_B, atol=1e-15)
    np.testing.assert_allclose(g.u_B, np.cross(g.d_B, g.w_B), atol=0)
    tips = g.crank_tips(np.full(6, np.pi / 2))  # a quarter turn puts the tip along w_i
    np.testing.assert_allclose(tips, g.P_B + g.crank_lengths[:, None] * g.w_B, atol=1e-15)
    assert not g.symmetric and NOMINAL.symmetric


def test_ik_then_fk_round_trips_and_every_rod_has_its_own_length(poses):
    theta = kinematics.ik(ROBOT, poses)
    # The drawn robot's angles differ by what the deviations are worth: the test can see them.
    assert np.abs(theta - kinematics.ik(NOMINAL, poses)).max() > 1e-3
    ell = kinematics.platform_joints(ROBOT, poses)[0] - ROBOT.crank_tips(theta)
    np.testing.assert_allclose(
        np.linalg.norm(ell, axis=-1),
        np.broadcast_to(ROBOT.rod_lengths, theta.shape),
        rtol=0,
        atol=1e-14,
    )
    x, status = fk(ROBOT, theta)
    assert status.converged
    np.testing.assert_allclose(x, poses, rtol=0, atol=1e-12)


def test_the_compiled_and_single_pose_forms_give_the_numpy_numbers(poses):
    from stewart_drake.control.lqi.gain import body_constants, input_matrix
    from stewart_drake.control.lqi.reschedule import input_matrix as compiled_input_matrix

    theta, ratio = kinematics.ik_unchecked(ROBOT, poses)
    legs = single_pose.leg_constants(ROBOT)
    for x, th in zip(poses[:10], theta):
        np.testing.assert_allclose(single_pose.ik_scalar(legs, x.tolist()), th, atol=1e-13)
        th_single, cache = single_pose.ik_single(ROBOT, x)
        np.testing.assert_allclose(th_single, th, atol=1e-13)
        J = kinematics.jacobian(ROBOT, x)
        np.testing.assert_allclose(single_pose.jacobian_single(ROBOT, cache), J, atol=1e-12)
        M = statics.task_inertia(ROBOT, x)
        np.testing.assert_allclose(statics.task_inertia_single(ROBOT, cache, J), M, atol=1e-14)
        B = input_matrix(ROBOT, x)
        B_c, _, ok = compiled_input_matrix(
            statics.kernel_constants(ROBOT)[0], body_constants(ROBOT), x
        )
        assert ok
        np.testing.assert_allclose(B_c, B, rtol=0, atol=1e-10 * np.abs(B).max())
    # The validator's kernels: numpy's numbers to the last bit, the torques to 1e-9 of peak.
    sample = compiled_kinematics(ROBOT, poses, _joint_axes(ROBOT))
    np.testing.assert_array_equal(sample.ratio, ratio)
    np.testing.assert_array_equal(sample.theta, theta)
    np.testing.assert_array_equal(sample.J, kinematics.jacobian(ROBOT, poses, theta))
    rng = np.random.default_rng(1)
    x_dot, x_ddot = rng.normal(0, 0.2, poses.shape), rng.normal(0, 2.0, poses.shape)
    T, _ = statics.motor_effort(ROBOT, poses, x_dot, x_ddot)
    T_c, _ = statics.motor_effort_compiled(ROBOT, poses, x_dot, x_ddot, None, theta, sample.J)
    np.testing.assert_allclose(T_c, T, rtol=0, atol=1e-9 * np.abs(T).max())


def test_the_limits_read_each_tilted_shaft():
    """The crank joint's bolt is parallel to u_i: its margin moves with the tilt."""
    tilted = NOMINAL.replace(shaft_tilts_rad=[0.05, 0, 0, 0, 0, 0])
    m0 = limit_margins(NOMINAL, X_HOME)["crank_joint"]
    m1 = limit_margins(tilted, X_HOME)["crank_joint"]
    assert abs(m1[0] - m0[0]) > 0.01 and np.allclose(m1[1:], m0[1:], atol=1e-3)


# -- the Drake plant, its SDF and the MuJoCo twin -------------------------------------------------


def test_the_plant_closes_each_leg_where_the_kinematics_put_it(poses):
    plant, context, handles, diagram, root = make_plant(ROBOT)
    assert_plant_has_the_legs_of(plant, context, handles, ROBOT)
    for x in poses[:5]:
        assemble(plant, context, handles, x)
        assert loop_closure_errors(plant, context, handles).max() < 1e-12
        theta = np.array([joint.get_angle(context) for joint in handles.motors])
        x_drake, _ = platform_pose(plant, context, handles)
        np.testing.assert_allclose(fk(ROBOT, theta, x0=x)[0], x_drake, rtol=0, atol=1e-9)


def test_drakes_ball_constraints_hold_the_geometrys_points():
    """Drake's constraints act on the points the SDF gives it: the loops, measured with the
    robot's own points, stay closed while the plant moves (a tenth of a second of free fall at
    the holding torques); measured with the drawn robot's points they are 0.1 mm open."""
    plant, context, handles, diagram, root = make_plant(ROBOT)
    assemble(plant, context, handles, X_HOME)
    handles.actuation_port.FixValue(context, statics.holding_torques(ROBOT, X_HOME) + 0.05)
    simulator = Simulator(diagram, root)
    simulator.AdvanceTo(0.1)
    q = plant.GetPositions(context)
    x, _ = platform_pose(plant, context, handles)
    assert np.abs(x - X_HOME).max() > 1e-4  # it moved
    assert LoopClosure(handles)(q).max() < 1e-6  # SAP's near-rigid constraints give way 4e-7 m
    nominal_handles = dataclasses.replace(handles, geometry=NOMINAL)
    assert LoopClosure(nominal_handles)(q).max() > 1e-4
    theta = np.array([joint.get_angle(context) for joint in handles.motors])
    np.testing.assert_allclose(fk(ROBOT, theta, x0=x)[0], x, rtol=0, atol=1e-7)


def test_distance_constraints_read_back_each_legs_points_and_length():
    plant, context, handles, _, _ = make_plant(ROBOT, rod_model="distance")
    params = [
        plant.GetDistanceConstraintParams(context, i)
        for i in sorted(plant.GetConstraintIds(), key=lambda c: c.get_value())
    ]
    assert len(params) == 6
    for i, p in enumerate(params):
        np.testing.assert_array_equal(p.p_AP(), [ROBOT.crank_lengths[i], 0.0, 0.0])
        np.testing.assert_array_equal(p.p_BQ(), ROBOT.p_E[i])
        assert p.distance() == ROBOT.rod_lengths[i]


def test_the_sdf_writes_each_legs_lengths():
    from xml.etree import ElementTree

    # The drake: tags as plain names (the SDF declares no namespace for them).
    root = ElementTree.fromstring(write_sdf(ROBOT).replace("drake:", "drake_"))
    p_AP = [
        [float(v) for v in c.find("drake_ball_constraint_p_AP").text.split()]
        for c in root.iter("drake_ball_constraint")
    ]
    np.testing.assert_allclose(np.array(p_AP)[:, 2], ROBOT.rod_lengths, rtol=0, atol=1e-12)
    coms = {
        link.get("name"): [float(v) for v in link.find("inertial/pose").text.split()[:3]]
        for link in root.iter("link")
    }
    a = [2 * coms[f"crank_{i}"][0] for i in range(6)]
    np.testing.assert_allclose(a, ROBOT.crank_lengths, rtol=0, atol=1e-12)
    assert write_sdf(ROBOT) != write_sdf(NOMINAL)


@needs_extra("mujoco")
def test_the_mujoco_twin_has_each_legs_sites_and_closes_its_loops(poses):
    from xml.etree import ElementTree

    from stewart_drake.plant import mjcf

    text = mjcf.write_mjcf(ROBOT)
    sites = {
        s.get("name"): np.array(s.get("pos").split(), float)
        for s in ElementTree.fromstring(text).iter("site")
    }
    for i in range(6):
        np.testing.assert_array_equal(sites[f"platform_joint_{i}"], ROBOT.p_E[i])
        np.testing.assert_array_equal(sites[f"rod_top_{i}"], [0.0, 0.0, ROBOT.rod_lengths[i]])
    mujoco = mjcf.import_mujoco()
    model = mujoco.MjModel.from_xml_string(text)
    data = mujoco.MjData(model)
    for x in poses[:3]:
        mjcf.assemble(model, data, ROBOT, x)
        assert mjcf.loop_closure_errors(model, data).max() < 1e-9
        np.testing.assert_allclose(mjcf.platform_pose(model, data), x, atol=1e-12)


# -- the symmetric robot, leg by leg --------------------------------------------------------------


def test_the_drawn_values_leg_by_leg_compute_the_drawing_to_the_bit(poses):
    g0, g1 = NOMINAL, drawn_values()
    assert g0 != g1 and g1.symmetric is False
    for name in ("P_B", "p_E", "d_B", "w_B", "u_B", "crank_lengths", "rod_lengths"):
        assert np.array_equal(getattr(g0, name), getattr(g1, name)), name
    x = poses
    theta = kinematics.ik(g0, x)
    assert np.array_equal(theta, kinematics.ik(g1, x))
    assert np.array_equal(fk(g0, theta)[0], fk(g1, theta)[0])
    assert np.array_equal(kinematics.jacobian(g0, x), kinematics.jacobian(g1, x))
    assert np.array_equal(kinematics.wrench_map(g0, x), kinematics.wrench_map(g1, x))
    assert np.array_equal(statics.holding_torques(g0, x), statics.holding_torques(g1, x))
    assert np.array_equal(statics.task_inertia(g0, x), statics.task_inertia(g1, x))
    m0, m1 = limit_margins(g0, x), limit_margins(g1, x)
    assert all(np.array_equal(m0[k], m1[k]) for k in m0)
    k0, k1 = (compiled_kinematics(g, x, _joint_axes(g)) for g in (g0, g1))
    assert all(np.array_equal(a, b) for a, b in zip(k0[:5], k1[:5]))
    assert statics.kernel_constants(g0)[0].tobytes() == statics.kernel_constants(g1)[0].tobytes()
    assert single_pose.leg_constants(g0) == single_pose.leg_constants(g1)
    assert write_sdf(g0) == write_sdf(g1)


def _short_run(robot: StewartGeometry, duration_s: float):
    from stewart_drake.run.scenario import Robot
    from stewart_drake.run.scenario_io import load_scenario
    from stewart_drake.run.simulate import run_experiment

    scenario = load_scenario("paper_hardware", [f"duration_s={duration_s}"])
    scenario.robot = Robot.from_value(robot)
    return run_experiment(scenario)


def test_a_closed_loop_on_the_drawn_values_is_the_drawings_to_the_bit():
    a, b = _short_run(NOMINAL, 0.3), _short_run(drawn_values(), 0.3)
    for name in ("t", "x", "x_d", "T", "closure", "status", "integral", "T_ff", "state"):
        assert np.array_equal(getattr(a, name), getattr(b, name)), name


def _tolerance_run(overrides, as_built=None):
    from stewart_drake.run.scenario import Robot
    from stewart_drake.run.scenario_io import load_scenario
    from stewart_drake.run.simulate import run_experiment

    scenario = load_scenario("paper_hardware", ["duration_s=0.3", *overrides])
    scenario.robot_as_built = None if as_built is None else Robot.from_value(as_built)
    return run_experiment(scenario)


_RUN_FIELDS = ("t", "x", "x_d", "T", "closure", "status", "integral", "T_ff", "state")


def test_a_closed_loop_on_a_robot_drawn_with_zero_tolerances_is_the_drawings_to_the_bit():
    kinds = ("pivot_offsets_m", "platform_offsets_m", "crank_lengths_m", "rod_lengths_m")
    kinds += ("shaft_tilts_rad", "crank_azimuths_rad", "encoder_offsets_rad")
    zero = ", ".join(f"{k}: {{half_width: 0}}" for k in kinds)
    a, b = _tolerance_run(()), _tolerance_run((f"robot_tolerances={{seed: 5, {zero}}}",))
    for name in _RUN_FIELDS:
        assert np.array_equal(getattr(a, name), getattr(b, name)), name


def test_a_closed_loop_on_drawn_tolerances_is_that_robot_as_built_to_the_bit():
    """``robot_tolerances`` is the drawn robot given as ``robot_as_built``: the same run."""
    from stewart_drake.robot.tolerances import Tolerances

    drawn = Tolerances().draw(NOMINAL, 5).geometry(NOMINAL)
    a = _tolerance_run(("robot_tolerances={seed: 5}",))
    b = _tolerance_run((), as_built=drawn)
    for name in _RUN_FIELDS:
        assert np.array_equal(getattr(a, name), getattr(b, name)), name
    # ... and not the nominal robot's: the encoders' zeros alone move the pose by millimetres.
    assert np.abs(a.x[-1, 3:6] - _tolerance_run(()).x[-1, 3:6]).max() > 1e-4


def test_the_drawn_robot_tracks_as_well_when_the_controller_knows_it():
    """The plant and the controller share the drawn robot, encoder zeros included: the zeros
    the encoders add, the estimator takes back, and the run tracks as the symmetric one."""
    nominal, drawn = _short_run(NOMINAL, 0.3), _short_run(ROBOT, 0.3)

    def error(run):
        keep = run.t > 0.1
        return np.abs(run.x[keep, :6] - run.x_d[keep, :6]).max(axis=0)

    e0, e1 = error(nominal), error(drawn)
    assert np.all(e1 < 2 * e0 + np.array([2e-5] * 3 + [2e-6] * 3)), (e0, e1)


# -- the encoders ---------------------------------------------------------------------------------


def test_the_encoders_read_each_zero_error_and_the_estimator_takes_it_back():
    from stewart_drake.control.estimator import PoseEstimator
    from stewart_drake.run.diagram import make_stewart_station
    from stewart_drake.run.scenario import Robot
    from stewart_drake.run.scenario_io import load_scenario

    scenario = load_scenario("paper_hardware")
    scenario.robot = Robot.from_value(ROBOT)
    builder = DiagramBuilder()
    station = builder.AddSystem(make_stewart_station(scenario))
    context = builder.Build().CreateDefaultContext()
    x = X_HOME + np.array([0.02, -0.01, 0.03, 0.004, 0.0, 0.01])
    theta = station.assemble(context, x)
    measured = station.GetOutputPort("motor_angle").Eval(station.GetMyContextFromRoot(context))
    quantum = scenario.hardware.encoders.quantum_rad
    assert np.abs(measured - (theta + ROBOT.encoder_offsets)).max() <= quantum / 2 + 1e-12
    # The estimator takes the zeros back: the pose of the counts, within what a count is worth
    # (J^-1 times half a count: 3e-5 rad here); the zeros left in would be worth millimetres.
    estimator = PoseEstimator(ROBOT, 1e-3, quantum, max_iterations=50)
    x_hat = estimator.estimate(measured, X_HOME)[0]
    np.testing.assert_allclose(x_hat, fk(ROBOT, measured - ROBOT.encoder_offsets)[0], atol=1e-6)
    assert np.abs(x_hat - x).max() < 1e-4
    unaware = ROBOT.replace(encoder_offsets_rad=None)
    x_unaware = PoseEstimator(unaware, 1e-3, quantum, max_iterations=50).estimate(measured, X_HOME)
    assert np.abs(x_unaware[0] - x).max() > 1e-3


# -- the scenario file and the checks -------------------------------------------------------------


def test_every_per_leg_field_round_trips_through_the_scenario_yaml():
    from pydrake.common.yaml import yaml_load_typed

    from stewart_drake.run.scenario import Robot, Scenario, dump_scenario

    scenario = Scenario()
    scenario.robot = Robot.from_value(ROBOT)
    text = dump_scenario(scenario)
    for name in PER_LEG_FIELDS:
        assert f"\n  {name}:" in text, name
    loaded = yaml_load_typed(schema=Scenario, data=text)
    assert loaded.robot.build() == ROBOT
    assert not any(name in dump_scenario(Scenario()) for name in PER_LEG_FIELDS)


@pytest.mark.parametrize(
    "name, value, message",
    [
        ("pivot_offsets_m", np.zeros((6, 2)), r"pivot_offsets_m must have shape \(6, 3\)"),
        (
            "platform_offsets_m",
            np.full((6, 3), 0.01),
            r"platform_offsets_m\[0, 0\] = 0.01 .* beyond",
        ),
        ("crank_lengths_m", [0.11] * 5 + [float("nan")], "crank_lengths_m has a non-finite"),
        ("rod_lengths_m", [0.404] * 5 + [-0.4], r"rod_lengths_m\[5\] = -0.4 m"),
        ("crank_lengths_m", [0.11] * 5 + [0.5], "change rod_lengths_m or crank_lengths_m"),
        ("shaft_tilts_rad", [0.2] + [0.0] * 5, r"shaft_tilts_rad\[0\] = 0.2 is beyond"),
        ("encoder_offsets_rad", [0.0] * 7, r"encoder_offsets_rad must have shape \(6,\)"),
        ("rod_lengths_m", [0.404] * 5 + [0.2], "leg 5 cannot close at the home pose"),
    ],
)
def test_a_bad_per_leg_value_names_its_field(name, value, message):
    with pytest.raises(InvalidGeometryError, match=message):
        NOMINAL.replace(**{name: value})


def test_a_bad_per_leg_value_in_a_scenario_names_its_field():
    from stewart_drake.run.scenario import Scenario

    scenario = Scenario()
    scenario.robot.shaft_tilts_rad = [0.0, 0.0, 0.3, 0.0, 0.0, 0.0]
    with pytest.raises(InvalidGeometryError, match=r"robot: shaft_tilts_rad\[2\]"):
        scenario.validate()
