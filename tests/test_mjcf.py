"""The same robot in MuJoCo: the MJCF loads, matches the Drake plant body for body, holds a pose
with the virtual-work torques and falls as the Drake plant does."""

import numpy as np
import pytest
from conftest import require_extra

# 4.0: RK4 became fourth order for ball and free joints; the bounds below are measured with it.
require_extra("mujoco")
import mujoco  # noqa: E402

from stewart_drake.analysis import accuracy
from stewart_drake.analysis.accuracy import X_TILTED, OpenLoopCase  # noqa: E402
from stewart_drake.base.errors import InvalidConfigError  # noqa: E402
from stewart_drake.cli.main import main  # noqa: E402
from stewart_drake.plant import mjcf  # noqa: E402
from stewart_drake.plant.closed_chain import assemble  # noqa: E402
from stewart_drake.plant.plant import make_plant
from stewart_drake.robot.geometry import X_HOME  # noqa: E402
from stewart_drake.run.plan import make_plan  # noqa: E402
from stewart_drake.run.scenario_io import load_scenario  # noqa: E402

BODIES = ["base"] + [f"{kind}_{i}" for i in range(6) for kind in ("crank", "rod")] + ["platform"]


@pytest.fixture(scope="module")
def model(geometry):
    return mjcf.load_model(geometry)


def test_model_has_the_robot_s_joints_loops_and_motors(model, geometry):
    assert (model.nq, model.nv, model.nu, model.neq) == (6 + 6 * 4 + 7, 6 + 6 * 3 + 6, 6, 6)
    assert all(model.joint(f"motor_{i}").type == mujoco.mjtJoint.mjJNT_HINGE for i in range(6))
    assert all(model.joint(f"rod_ball_{i}").type == mujoco.mjtJoint.mjJNT_BALL for i in range(6))
    assert model.joint("platform").type == mujoco.mjtJoint.mjJNT_FREE
    assert np.all(model.eq_type == mujoco.mjtEq.mjEQ_CONNECT)
    np.testing.assert_array_equal(model.actuator_gear[:, 0], 1.0)
    assert not model.actuator_ctrllimited.any()
    np.testing.assert_allclose(model.opt.gravity, [0, 0, -geometry.gravity])
    assert model.opt.integrator == mujoco.mjtIntegrator.mjINT_RK4


def test_bodies_frames_and_inertias_equal_the_drake_plant_s(model, geometry):
    """Same body frames, masses, COMs and inertias (world frame, at home) as the SDF's plant."""
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    plant, context, _, _, _ = make_plant(geometry)
    for name in BODIES:
        body, b = plant.GetBodyByName(name), model.body(name).id
        X_WB = plant.EvalBodyPoseInWorld(context, body)
        np.testing.assert_allclose(data.xpos[b], X_WB.translation(), atol=1e-12)
        np.testing.assert_allclose(data.xmat[b].reshape(3, 3), X_WB.rotation().matrix(), atol=1e-12)
        M_BBcm_W = body.CalcSpatialInertiaInBodyFrame(context).ReExpress(X_WB.rotation())
        p_com = M_BBcm_W.get_com()
        I_W = M_BBcm_W.Shift(p_com).CalcRotationalInertia().CopyToFullMatrix3()
        R_ip = data.ximat[b].reshape(3, 3)  # principal axes of the MuJoCo body
        assert model.body_mass[b] == pytest.approx(body.default_mass(), rel=1e-15)
        np.testing.assert_allclose(data.xipos[b], X_WB.translation() + p_com, atol=1e-12)
        np.testing.assert_allclose(R_ip @ np.diag(model.body_inertia[b]) @ R_ip.T, I_W, atol=1e-15)


def test_home_is_assembled_and_assemble_closes_any_reachable_pose(model, geometry, random_poses):
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    assert mjcf.loop_closure_errors(model, data).max() < 1e-9
    np.testing.assert_allclose(mjcf.platform_pose(model, data), X_HOME, atol=1e-12)
    plant, context, handles, _, _ = make_plant(geometry)
    for x in [X_TILTED, *random_poses[:10]]:
        theta = mjcf.assemble(model, data, geometry, x)
        assert mjcf.loop_closure_errors(model, data).max() < 1e-9
        np.testing.assert_allclose(mjcf.platform_pose(model, data), x, atol=1e-12)
        np.testing.assert_allclose(mjcf.motor_angles(model, data), theta, atol=0)
        assemble(plant, context, handles, x)  # the ball quaternions are Drake's rpy
        for i, joint in enumerate(handles.rod_balls):
            adr = model.joint(f"rod_ball_{i}").qposadr[0]
            R = np.empty(9)
            mujoco.mju_quat2Mat(R, data.qpos[adr : adr + 4])
            R_FM = joint.frame_on_child().CalcPose(context, joint.frame_on_parent()).rotation()
            np.testing.assert_allclose(R.reshape(3, 3), R_FM.matrix(), atol=1e-12)


@pytest.mark.parametrize(
    "x0, position_bound, rotation_bound",
    [
        # Measured over 1 s at 1 ms (RK4): home 1.2e-8 m, 8.0e-10 rad; tilted 9.2e-8 m, 7.8e-5 rad.
        # The held pose is an unstable equilibrium (constant torques; fastest mode e^(9.9 t), from
        # kinematics), so the tilted drift is its first 1e-9 of numerical error grown 2e4 times.
        (X_HOME, 5e-8, 5e-9),
        (X_TILTED, 5e-7, 5e-4),
    ],
)
def test_virtual_work_torques_hold_a_pose_for_a_second(
    geometry, x0, position_bound, rotation_bound
):
    run = accuracy.simulate(
        "mujoco_rk4",
        OpenLoopCase("hold", tuple(x0), 1.0),
        1e-3,
        geometry,
        sample_times=(0.25, 0.5, 0.75, 1.0),
    )
    drift = run.x - x0
    assert np.abs(drift[:, 3:]).max() < position_bound
    assert np.abs(drift[:, :3]).max() < rotation_bound
    assert run.max_closure_m < 5e-8  # 1.3e-8 m measured


def test_too_little_torque_does_not_hold(geometry):
    """The hold is physics, not a frozen model: 10 % less torque sags by millimetres."""
    run = accuracy.simulate(
        "mujoco_rk4", OpenLoopCase("sag", tuple(X_HOME), 0.9), 1e-3, geometry, sample_times=(0.1,)
    )
    assert run.x[0, 5] < X_HOME[5] - 2e-3


def test_zero_torque_fall_matches_drake_at_equal_step(geometry):
    """Platform position after 0.05 and 0.1 s of a fall from home, both engines at 0.1 ms.

    Measured: 2.5e-5 and 4.8e-5 m apart (the platform falls 49 mm), all of it the Drake plant's
    first-order error: extrapolated to step 0 from 0.1 and 0.05 ms it agrees with MuJoCo to
    3.7e-10 and 7.5e-9 m.
    """
    fall = accuracy.SCENARIOS[0]
    drake = accuracy.simulate("drake_sap", fall, 1e-4, geometry)
    mj = accuracy.simulate("mujoco_rk4", fall, 1e-4, geometry)
    assert X_HOME[5] - mj.x[1, 5] > 0.045  # a real fall
    position, rotation = accuracy.pose_errors(mj.x, drake.x)
    assert np.all(position < [5e-5, 1e-4])
    assert rotation.max() < 1e-9  # symmetric fall: both stay level
    drake_fine = accuracy.simulate("drake_sap", fall, 5e-5, geometry)
    position, _ = accuracy.pose_errors(mj.x, 2 * drake_fine.x - drake.x)
    assert position.max() < 1e-7


def test_tilted_fall_agrees_with_drake_extrapolated(geometry):
    """The tilted fall rotates: Drake (0.1, 0.05 ms, extrapolated to step 0) vs MuJoCo (0.1 ms).

    Measured at 0.1 s: 1.1e-8 m and 4.4e-8 rad; 4.6e-5 m and 3.0e-5 rad without extrapolation.
    """
    fall = accuracy.SCENARIOS[1]
    mj = accuracy.simulate("mujoco_rk4", fall, 1e-4, geometry)
    x_drake = (
        2 * accuracy.simulate("drake_sap", fall, 5e-5, geometry).x
        - accuracy.simulate("drake_sap", fall, 1e-4, geometry).x
    )
    position, rotation = accuracy.pose_errors(mj.x, x_drake)
    assert position.max() < 1e-7 and rotation.max() < 5e-7
    assert accuracy.pose_errors(mj.x[1], fall.x0)[1] > 0.01  # it does rotate (0.02 rad)


def test_loops_stay_closed_and_energy_kept_in_a_fall_at_1_ms(geometry):
    run = accuracy.simulate("mujoco_rk4", accuracy.SCENARIOS[0], 1e-3, geometry)
    assert run.max_closure_m < 1e-6  # 2.3e-7 m measured
    assert abs(run.energy_change) < 1e-6  # 2.0e-8 measured


def test_bad_options_are_refused():
    with pytest.raises(InvalidConfigError, match="integrator"):
        mjcf.write_mjcf(integrator="Verlet")
    with pytest.raises(InvalidConfigError, match="time_step"):
        mjcf.write_mjcf(time_step=0.0)
    with pytest.raises(InvalidConfigError, match="solref"):
        mjcf.write_mjcf(solref=(0.0, 1.0))


def test_cli_writes_an_mjcf_that_loads(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    assert main(["mjcf"]) == 0
    assert "rotary_stewart.xml" in capsys.readouterr().out
    model = mujoco.MjModel.from_xml_path(str(tmp_path / "rotary_stewart.xml"))
    assert model.neq == 6
    out = tmp_path / "sub" / "robot.xml"
    assert main(["mjcf", "--scenario", "paper_ideal", "--out", str(out)]) == 0
    assert out.read_text() == mjcf.write_mjcf()  # the ideal robot: as before
    # By default the robot as built, from the same scenario as every other command: the
    # plan's armature, friction, torque limit and encoders, read back from what MuJoCo built.
    plan = make_plan(load_scenario("paper_hardware"), with_reference=False)
    built = mujoco.MjModel.from_xml_path(str(tmp_path / "rotary_stewart.xml"))
    motors = [built.joint(f"motor_{i}") for i in range(6)]
    assert [float(j.armature[0]) for j in motors] == pytest.approx(
        [plan.geometry.motor_reflected_inertia] * 6
    )
    assert [float(built.dof_frictionloss[j.dofadr[0]]) for j in motors] == pytest.approx(
        [plan.servo.coulomb_friction_Nm] * 6
    )
    assert built.actuator_forcerange[:, 1] == pytest.approx([plan.torque_limit_Nm] * 6)
    assert built.nsensor == 6


def test_every_part_collides_in_mujoco_where_it_does_in_drake(model, geometry, random_poses):
    """The MJCF carries the SDF's collision geometry: at random poses and at one where the hub
    plate and a rod overlap, MuJoCo's own distance of every pair Drake's SceneGraph measures
    agrees (both use GJK for some shape pairs: within 0.5 mm, most to 1e-6 m), and MuJoCo
    reports contacts exactly where Drake finds overlaps."""
    import mujoco

    from stewart_drake.plant.clearance import ClearanceModel
    from stewart_drake.robot.parts import robot_parts

    colliding = [p for p in robot_parts(geometry) if p.collides]
    assert all(model.geom(f"{p.link}/{p.name}").contype[0] == 1 for p in colliding)
    data = mujoco.MjData(model)
    drake = ClearanceModel(geometry)
    overlap = np.array([0.2102, 0.2411, -0.2047, -0.0222, 0.0979, 0.2157])
    differences, fromto = [], np.zeros(6)
    for x in [*random_poses[:8], overlap]:
        mjcf.assemble(model, data, geometry, x)
        pairs = drake.contacts(x, 0.03)
        for c in pairs:
            theirs = mujoco.mj_geomDistance(
                model, data, model.geom(c.part_a).id, model.geom(c.part_b).id, 0.1, fromto
            )
            differences.append(abs(theirs - c.distance))
        assert data.ncon == sum(c.distance < 0 for c in pairs)
    assert max(differences) < 5e-4 and np.median(differences) < 1e-6
    assert data.ncon == 2  # the overlapping pose: two rods


def _as_built():
    from stewart_drake.run.plan import make_plan
    from stewart_drake.run.scenario_io import load_scenario

    plan = make_plan(load_scenario("paper_hardware"))
    hw = plan.scenario.hardware
    return plan, hw


def test_the_twin_as_built_carries_the_plan_s_servo_and_limits():
    """Armature, damping, friction loss and force range read back from the compiled model."""
    plan, hw = _as_built()
    servo = plan.servo
    model = mjcf.load_model(plan.geometry, servo=servo, torque_limit_Nm=plan.torque_limit_Nm)
    dofs = [int(model.joint(f"motor_{i}").dofadr[0]) for i in range(6)]
    np.testing.assert_array_equal(model.dof_armature[dofs], servo.reflected_inertia)
    np.testing.assert_array_equal(model.dof_damping[dofs], servo.viscous_damping)
    np.testing.assert_array_equal(model.dof_frictionloss[dofs], servo.coulomb_friction_Nm)
    np.testing.assert_array_equal(
        model.actuator_forcerange, [[-plan.torque_limit_Nm, plan.torque_limit_Nm]] * 6
    )
    assert model.nsensor == 6
    data = mujoco.MjData(model)
    theta = mjcf.assemble(model, data, plan.geometry, X_TILTED)
    q = hw.encoders.quantum_rad
    read = mjcf.encoder_angles(model, data, q)
    assert np.abs(read - theta).max() <= q / 2 + 1e-15
    np.testing.assert_array_equal(np.round(read / q), np.round(read / q).round())
    # Without a servo the text is the ideal robot's, byte for byte.
    assert mjcf.write_mjcf(mjcf_geometry := plan.geometry.replace(motor_reflected_inertia=0.0)) == (
        mjcf.write_mjcf(mjcf_geometry, servo=None, torque_limit_Nm=None)
    )
    with pytest.raises(InvalidConfigError, match="no encoders"):
        mjcf.encoder_angles(mjcf.load_model(), mujoco.MjData(mjcf.load_model()), q)
    with pytest.raises(InvalidConfigError, match="torque_limit_Nm"):
        mjcf.write_mjcf(torque_limit_Nm=-1.0)


@pytest.mark.parametrize("built", [False, True])
def test_holding_torques_hold_in_both_twins(built):
    """Gravity torques hold the tilted pose for 0.5 s, ideal or as built (friction only helps)."""
    from stewart_drake.robot.statics import holding_torques

    plan, _ = _as_built()
    g = plan.geometry if built else plan.geometry.replace(motor_reflected_inertia=0.0)
    extra = dict(servo=plan.servo, torque_limit_Nm=plan.torque_limit_Nm) if built else {}
    model = mjcf.load_model(g, **extra)
    data = mujoco.MjData(model)
    mjcf.assemble(model, data, g, X_TILTED)
    data.ctrl[:] = holding_torques(g, X_TILTED)
    for _ in range(500):
        mujoco.mj_step(model, data)
    drift = mjcf.platform_pose(model, data) - X_TILTED
    assert np.abs(drift[3:]).max() < 1e-4
    assert np.abs(drift[:3]).max() < 1e-3
