"""The nonlinear plant: SDF written from a geometry, a discrete SAP MultibodyPlant, assembly.

Model: base welded to the world; six cranks on actuated revolute joints ``motor_i`` (axis u_i);
six rods on ball joints ``rod_ball_i`` at the crank tips; a floating platform; six
``drake:ball_constraint`` elements closing the loops (rod top end = platform joint p_i).
Ball constraints are only enforced by a discrete plant using SAP, so :func:`add_stewart_plant`
always builds one (``time_step > 0``).

The SDF's zero configuration (all joint angles 0) is *not* assembled: the cranks are horizontal
there. :func:`add_stewart_plant` sets the default joint positions to the home pose, and
:func:`assemble` writes any reachable pose into a Context.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
from pydrake.math import RigidTransform, RollPitchYaw, RotationMatrix
from pydrake.multibody.parsing import Parser
from pydrake.multibody.plant import AddMultibodyPlant, MultibodyPlant, MultibodyPlantConfig
from pydrake.multibody.tree import PdControllerGains
from pydrake.systems.framework import Context, DiagramBuilder

from . import kinematics
from ..errors import InvalidConfigError
from .geometry import X_HOME, StewartGeometry
from .servo import ServoModel

MODEL_NAME = "rotary_stewart"
#: The committed SDF of the reference robot; a test checks it equals :func:`write_sdf` output.
REFERENCE_SDF = Path(__file__).resolve().parents[2] / "sdf" / "rotary_stewart.sdf"
_BASE_THICKNESS = 0.02
_PLATFORM_THICKNESS = 0.01


def _vec(v) -> str:
    return " ".join(f"{float(c):.12g}" for c in v)


def _pose(p, R: np.ndarray) -> str:
    rpy = RollPitchYaw(RotationMatrix(R)).vector()
    return _vec(np.concatenate([p, rpy]))


def _inertial(mass: float, moments, p_com) -> str:
    ixx, iyy, izz = moments
    return (f"      <inertial>\n        <pose>{_vec(p_com)} 0 0 0</pose>\n"
            f"        <mass>{mass:.12g}</mass>\n"
            f"        <inertia><ixx>{ixx:.12g}</ixx><iyy>{iyy:.12g}</iyy><izz>{izz:.12g}</izz>"
            f"<ixy>0</ixy><ixz>0</ixz><iyz>0</iyz></inertia>\n      </inertial>\n")


def _visual(name: str, pose: str, geometry: str, rgba: str) -> str:
    return (f"      <visual name=\"{name}\">\n        <pose>{pose}</pose>\n"
            f"        <geometry>{geometry}</geometry>\n"
            f"        <material><diffuse>{rgba}</diffuse></material>\n      </visual>\n")


def _axis_angle(u, angle: float) -> np.ndarray:
    """Rotation matrix (3, 3) of ``angle`` rad about the unit axis u (Rodrigues)."""
    u = np.asarray(u, dtype=float)
    K = np.array([[0, -u[2], u[1]], [u[2], 0, -u[0]], [-u[1], u[0], 0]])
    return np.eye(3) + np.sin(angle) * K + (1 - np.cos(angle)) * K @ K


def _min_rotation(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Smallest rotation taking unit vector a onto unit vector b, (3, 3)."""
    v = np.cross(a, b)
    c = float(np.dot(a, b))
    if c < -1 + 1e-12:
        raise InvalidConfigError("rod direction flipped by 180 degrees: the pose is not assemblable")
    K = np.array([[0, -v[2], v[1]], [v[2], 0, -v[0]], [-v[1], v[0], 0]])
    return np.eye(3) + K + K @ K / (1 + c)


def _rod_zero_rotations(geometry: StewartGeometry) -> list[np.ndarray]:
    """R_B_rod at the SDF zero configuration, chosen so the ball joints read rpy = 0 at home.

    At home the rod's z is along the rod and its x along the part of the rod end's bolt axis
    u_i normal to the rod. Drake's BallRpyJoint is singular where the rod points along +-x of
    this frame, 90 - 19.4 = 70.6 deg out of the crank's plane at the reference robot: outside
    the rod end's cone (crank_joint_cone_deg), so |pitch| <= 90 - (70.6 - 35) = 54.4 deg at
    every pose inside the limits (stewart_drake/model/ball_joints.py, docs/accuracy.md). The rod is
    axisymmetric, so this spin about its axis changes coordinates only, not the dynamics.
    """
    theta_home = kinematics.ik(geometry, X_HOME)
    q_B, _ = kinematics.platform_joints(geometry, X_HOME)
    tips = geometry.crank_tips(theta_home)
    rotations = []
    for i in range(6):
        u = geometry.u_B[i]
        z_rod = (q_B[i] - tips[i]) / geometry.rod_length
        x_rod = u - np.dot(u, z_rod) * z_rod                           # bolt axis, normal part
        x_rod /= np.linalg.norm(x_rod)
        R_home = np.column_stack([x_rod, np.cross(z_rod, x_rod), z_rod])
        rotations.append(_axis_angle(u, -theta_home[i]) @ R_home)
    return rotations


def write_sdf(geometry: StewartGeometry | None = None) -> str:
    """SDFormat 1.9 text of the robot, with Drake's ``drake:ball_constraint`` loop closures.

    Returns:
        The SDF as a string; links ``base``, ``crank_i``, ``rod_i``, ``platform``; joints
        ``motor_i`` (revolute, actuated) and ``rod_ball_i`` (ball); i = 0..5.
    Source: reference_geometry.md for the layout; paper Table I for masses and inertias (crank
    inertia corrected to the nearest physically valid tensor, docs/paper_notes.md).
    """
    g = geometry or StewartGeometry()
    a, s = g.crank_length, g.rod_length
    out = ['<?xml version="1.0"?>',
           "<!-- Generated by stewart_drake.plant.write_sdf(); do not edit by hand. -->",
           '<sdf version="1.9">', f'  <model name="{MODEL_NAME}">']
    out.append('    <link name="base">\n' + _inertial(g.base_mass, g.base_inertia,
                                                       [0, 0, -_BASE_THICKNESS / 2])
               + _visual("plate", f"0 0 {-_BASE_THICKNESS / 2} 0 0 0",
                         f"<cylinder><radius>{g.base_plate_radius:.12g}</radius>"
                         f"<length>{_BASE_THICKNESS}</length></cylinder>", "0.55 0.55 0.6 1")
               + "    </link>")
    out.append('    <joint name="weld_base" type="fixed"><parent>world</parent>'
               '<child>base</child></joint>')
    rod_R0 = _rod_zero_rotations(g)
    for i in range(6):
        d, u, P = g.d_B[i], g.u_B[i], g.P_B[i]
        R_crank = np.column_stack([d, -u, [0.0, 0.0, 1.0]])   # x along crank, y = shaft (-u)
        out.append(
            f'    <link name="crank_{i}">\n      <pose>{_pose(P, R_crank)}</pose>\n'
            + _inertial(g.crank_mass, g.crank_inertia, [a / 2, 0, 0])
            + _visual("arm", f"{a / 2:.12g} 0 0 0 1.5707963267949 0",
                      f"<cylinder><radius>0.008</radius><length>{a:.12g}</length></cylinder>",
                      "0.85 0.45 0.1 1")
            + _visual("motor", "0 0 0 1.5707963267949 0 0",
                      "<cylinder><radius>0.02</radius><length>0.03</length></cylinder>",
                      "0.2 0.2 0.25 1")
            + "    </link>")
        out.append(
            f'    <joint name="motor_{i}" type="revolute">\n      <parent>base</parent>'
            f"<child>crank_{i}</child>\n"
            f'      <axis><xyz expressed_in="__model__">{_vec(u)}</xyz></axis>\n    </joint>')
        out.append(
            f'    <link name="rod_{i}">\n      <pose>{_pose(P + a * d, rod_R0[i])}</pose>\n'
            + _inertial(g.rod_mass, g.rod_inertia, [0, 0, s / 2])
            + _visual("rod", f"0 0 {s / 2:.12g} 0 0 0",
                      f"<cylinder><radius>0.005</radius><length>{s:.12g}</length></cylinder>",
                      "0.75 0.75 0.8 1")
            + _visual("ball_bottom", "0 0 0 0 0 0", "<sphere><radius>0.011</radius></sphere>",
                      "0.1 0.3 0.8 1")
            + _visual("ball_top", f"0 0 {s:.12g} 0 0 0",
                      "<sphere><radius>0.011</radius></sphere>", "0.1 0.3 0.8 1")
            + "    </link>")
        out.append(f'    <joint name="rod_ball_{i}" type="ball"><parent>crank_{i}</parent>'
                   f"<child>rod_{i}</child></joint>")
    out.append(f'    <link name="platform">\n      <pose>{_vec(X_HOME[3:])} {_vec(X_HOME[:3])}</pose>\n'
               + _inertial(g.platform_mass, g.platform_inertia, [0, 0, 0])
               + _visual("disc", "0 0 0 0 0 0",
                         f"<cylinder><radius>{g.platform_radius + 0.01:.12g}</radius>"
                         f"<length>{_PLATFORM_THICKNESS}</length></cylinder>", "0.2 0.6 0.3 1")
               + _visual("tool", "0 0 0.04 0 0 0",
                         "<cylinder><radius>0.006</radius><length>0.08</length></cylinder>",
                         "0.9 0.1 0.1 1")
               + "    </link>")
    for i in range(6):
        out.append(
            "    <drake:ball_constraint>\n"
            f"      <drake:ball_constraint_body_A>rod_{i}</drake:ball_constraint_body_A>\n"
            "      <drake:ball_constraint_body_B>platform</drake:ball_constraint_body_B>\n"
            f"      <drake:ball_constraint_p_AP>0 0 {s:.12g}</drake:ball_constraint_p_AP>\n"
            f"      <drake:ball_constraint_p_BQ>{_vec(g.p_E[i])}</drake:ball_constraint_p_BQ>\n"
            "    </drake:ball_constraint>")
    out += ["  </model>", "</sdf>", ""]
    return "\n".join(out)


@dataclass(frozen=True)
class StewartPlantHandles:
    """What a caller needs to address the robot inside a plant (indices are Drake's)."""

    geometry: StewartGeometry
    model_instance: object
    platform: object            # RigidBody
    cranks: tuple               # 6 RigidBody
    rods: tuple                 # 6 RigidBody
    motors: tuple               # 6 RevoluteJoint
    rod_balls: tuple            # 6 BallRpyJoint
    rod_top_in_rod: np.ndarray  # (3,) p_AP of every ball constraint, rod frame
    actuation_port: object      # plant input port of the model's actuators (see n_actuators)
    n_actuators: int = 6        # 6 motors, + 6 dry-friction actuators when the servo has friction
    desired_state_port: object = None   # the friction actuators' desired state (zeros), or None


def add_stewart_plant(builder: DiagramBuilder, geometry: StewartGeometry | None = None,
                      time_step: float = 1e-3, sdf_file: str | Path | None = None,
                      discrete_contact_approximation: str = "sap",
                      plant_config: MultibodyPlantConfig | None = None,
                      servo: ServoModel | None = None):
    """Add the robot as a discrete SAP MultibodyPlant (+ SceneGraph) to ``builder``.

    Args:
        builder: the DiagramBuilder to add to.
        geometry: the robot; default reference_geometry.md. Its ``gravity`` (m/s^2, along -z)
            is the plant's gravity field.
        time_step: plant period in s; must be > 0 (ball constraints need a discrete plant).
        sdf_file: load this SDF instead of the text :func:`write_sdf` makes of ``geometry``
            (its names must follow write_sdf's).
        discrete_contact_approximation: a SAP-family approximation: "sap", "lagged", "similar".
        plant_config: Drake's ``MultibodyPlantConfig`` (a scenario's ``plant``); when given, its
            ``time_step`` and ``discrete_contact_approximation`` replace the two arguments above.
        servo: the motors' gearing and friction (:class:`~.servo.ServoModel`), or None for ideal
            torque sources. The motors' reflected inertia is ``geometry.motor_reflected_inertia``
            (the JointActuators' rotor inertia x gear ratio^2, which Drake adds to the mass
            matrix); the servo's viscous friction is Drake joint damping (implicit in SAP); its
            Coulomb friction is a second actuator on each motor joint, PD-controlled by SAP with
            no stiffness, damping ``servo.friction_damping`` towards zero velocity and an effort
            limit of ``servo.coulomb_friction_Nm``: a dry friction SAP solves implicitly (drake
            1.51 has no joint dry friction: it loads an SDF joint's ``<dynamics><friction>``
            without a word, even with strict parsing, and ignores it; a test holds this).
    Returns:
        (plant, scene_graph, handles): plant is finalized; its default positions are the home
        pose, assembled. With friction, ``handles.actuation_port`` takes 12 values (the six
        motor torques, then six zeros) and ``handles.desired_state_port`` must be fixed to zeros.
    Raises:
        InvalidConfigError: time_step <= 0 or a non-SAP approximation (constraints ignored).
    """
    if plant_config is not None:
        time_step = plant_config.time_step
        discrete_contact_approximation = plant_config.discrete_contact_approximation
    if not (np.isfinite(time_step) and time_step > 0):
        raise InvalidConfigError(
            f"time_step must be > 0 s (got {time_step}): Drake enforces ball constraints only in "
            f"a discrete plant")
    if discrete_contact_approximation not in ("sap", "lagged", "similar"):
        raise InvalidConfigError(
            f"discrete_contact_approximation {discrete_contact_approximation!r} does not enforce "
            f"ball constraints; use 'sap', 'lagged' or 'similar'")
    geometry = geometry or StewartGeometry()
    if plant_config is None:
        plant_config = MultibodyPlantConfig(
            time_step=time_step, discrete_contact_approximation=discrete_contact_approximation)
    plant, scene_graph = AddMultibodyPlant(plant_config, builder)
    # Drake's default is 9.81 m/s^2 whatever the geometry says; holding torques and feed-forward
    # use geometry.gravity, so the plant must too.
    plant.mutable_gravity_field().set_gravity_vector([0.0, 0.0, -geometry.gravity])
    parser = Parser(plant)
    if sdf_file is None:
        (model,) = parser.AddModelsFromString(write_sdf(geometry), "sdf")
    else:
        (model,) = parser.AddModels(str(sdf_file))
    motors = [plant.GetJointByName(f"motor_{i}", model) for i in range(6)]
    gear = servo.gear_ratio if servo is not None else 1.0
    if geometry.motor_reflected_inertia > 0:
        for index in plant.GetJointActuatorIndices(model):
            actuator = plant.get_joint_actuator(index)
            actuator.set_default_gear_ratio(gear)
            actuator.set_default_rotor_inertia(geometry.motor_reflected_inertia / gear ** 2)
    if servo is not None:
        for i, joint in enumerate(motors):
            joint.set_default_damping(servo.viscous_damping)
            if servo.coulomb_friction_Nm > 0:
                friction = plant.AddJointActuator(f"friction_{i}", joint,
                                                  effort_limit=servo.coulomb_friction_Nm)
                friction.set_controller_gains(PdControllerGains(p=0.0, d=servo.friction_damping))
    plant.Finalize()
    n_actuators = plant.num_actuators()
    handles = StewartPlantHandles(
        geometry=geometry, model_instance=model,
        platform=plant.GetBodyByName("platform", model),
        cranks=tuple(plant.GetBodyByName(f"crank_{i}", model) for i in range(6)),
        rods=tuple(plant.GetBodyByName(f"rod_{i}", model) for i in range(6)),
        motors=tuple(plant.GetJointByName(f"motor_{i}", model) for i in range(6)),
        rod_balls=tuple(plant.GetJointByName(f"rod_ball_{i}", model) for i in range(6)),
        rod_top_in_rod=np.array([0.0, 0.0, geometry.rod_length]),
        actuation_port=plant.get_actuation_input_port(model), n_actuators=n_actuators,
        desired_state_port=(plant.get_desired_state_input_port(model) if n_actuators > 6
                            else None))
    if n_actuators not in (6, 12):
        raise InvalidConfigError(f"expected 6 motor actuators, the SDF gives {n_actuators}")
    theta_home = kinematics.ik(geometry, X_HOME)
    for joint, angle in zip(handles.motors, theta_home):
        joint.set_default_angle(float(angle))
    plant.SetDefaultFloatingBaseBodyPose(handles.platform, pose_to_transform(X_HOME))
    return plant, scene_graph, handles


def make_plant(geometry: StewartGeometry | None = None, time_step: float = 1e-3):
    """A standalone finalized plant assembled at home.

    Returns:
        (plant, plant_context, handles, diagram, root_context): the plant's Context lives inside
        the Diagram's (the plant is registered with a SceneGraph), so both are returned.
    """
    builder = DiagramBuilder()
    plant, _, handles = add_stewart_plant(builder, geometry, time_step)
    diagram = builder.Build()
    context = diagram.CreateDefaultContext()
    return plant, plant.GetMyMutableContextFromRoot(context), handles, diagram, context


def pose_to_transform(x) -> RigidTransform:
    """X_BE of pose x = [phi, theta, psi, X, Y, Z] (rad, m)."""
    x = np.asarray(x, dtype=float)
    return RigidTransform(RollPitchYaw(x[:3]), x[3:6])


def assemble(plant: MultibodyPlant, context: Context, handles: StewartPlantHandles, x,
             x_dot=None) -> np.ndarray:
    """Write a consistent configuration of every joint for platform pose x into ``context``.

    Cranks from the closed-form IK, rods pointing from crank tip to platform joint (no spin),
    platform at x. With ``x_dot`` (6,) [rad/s, m/s], velocities are set consistently too
    (theta_dot = J x_dot); otherwise all velocities are zero.
    Returns:
        (6,) motor angles in rad.
    Raises:
        UnreachablePoseError: x cannot be reached (names the leg).
    """
    g = handles.geometry
    x = np.asarray(x, dtype=float)
    theta = kinematics.ik(g, x)
    for joint, angle in zip(handles.motors, theta):
        joint.set_angle(context, float(angle))
    plant.SetFloatingBaseBodyPoseInWorldFrame(context, handles.platform, pose_to_transform(x))
    q_B, _ = kinematics.platform_joints(g, x)
    tips = g.crank_tips(theta)
    for i, joint in enumerate(handles.rod_balls):
        joint.set_angles(context, np.zeros(3))
        X_WF = plant.EvalBodyPoseInWorld(context, handles.rods[i])   # rod frame at rpy = 0
        z_F = X_WF.rotation().inverse().multiply((q_B[i] - tips[i]) / g.rod_length)
        R_FM = _min_rotation(np.array([0.0, 0.0, 1.0]), np.asarray(z_F))
        joint.set_angles(context, RollPitchYaw(RotationMatrix(R_FM)).vector())
    plant.SetVelocities(context, handles.model_instance,
                        np.zeros(plant.num_velocities(handles.model_instance)))
    if x_dot is not None:
        _set_velocities(plant, context, handles, x, np.asarray(x_dot, dtype=float), theta)
    return theta


def _set_velocities(plant, context, handles, x, x_dot, theta):
    """Velocities consistent with x_dot: motors, platform, rods (normal rotation, no spin)."""
    g = handles.geometry
    J = kinematics.jacobian(g, x, theta)
    theta_dot = J @ x_dot
    for joint, rate in zip(handles.motors, theta_dot):
        joint.set_angular_rate(context, float(rate))
    E = kinematics.angular_velocity_map(x[:3])
    from pydrake.multibody.math import SpatialVelocity

    plant.SetFreeBodySpatialVelocity(context, handles.platform,
                                     SpatialVelocity(E @ x_dot[:3], x_dot[3:]))
    # Rod angular velocity w = ell x (v_q - v_tip) / s^2, as an rpy rate of the ball joint.
    q_B, r_B = kinematics.platform_joints(g, x)
    tips = g.crank_tips(theta)
    c, s_ = np.cos(theta), np.sin(theta)
    for i, joint in enumerate(handles.rod_balls):
        ell = q_B[i] - tips[i]
        v_q = x_dot[3:] + np.cross(E @ x_dot[:3], r_B[i])
        v_tip = g.crank_length * theta_dot[i] * (-s_[i] * g.d_B[i] + c[i] * np.array([0, 0, 1.0]))
        w_rod_W = np.cross(ell, v_q - v_tip) / g.rod_length ** 2
        w_crank_W = theta_dot[i] * g.u_B[i]
        X_WC = plant.EvalBodyPoseInWorld(context, handles.cranks[i])
        X_CF = joint.frame_on_parent().GetFixedPoseInBodyFrame()
        R_WF = X_WC.rotation().multiply(X_CF.rotation())
        # BallRpyJoint's generalized velocity is w_FM expressed in F (not rpy rates).
        joint.set_angular_velocity(context, np.asarray(R_WF.inverse().multiply(w_rod_W - w_crank_W)))


def loop_closure_errors(plant: MultibodyPlant, context: Context,
                        handles: StewartPlantHandles) -> np.ndarray:
    """(6,) distance in m between each rod's top end and its platform joint (0 when closed)."""
    p_W_joint = plant.EvalBodyPoseInWorld(context, handles.platform).multiply(
        handles.geometry.p_E.T)                                   # (3, 6) platform joints
    p_W_top = np.column_stack([plant.EvalBodyPoseInWorld(context, rod).multiply(
        handles.rod_top_in_rod) for rod in handles.rods])         # (3, 6) rod top ends
    return np.sqrt(((p_W_top - p_W_joint) ** 2).sum(axis=0))


def platform_pose(plant: MultibodyPlant, context: Context, handles: StewartPlantHandles):
    """Measured pose x (6,) and rate x_dot (6,) of the platform [rad, m; rad/s, m/s]."""
    X_WE = plant.EvalBodyPoseInWorld(context, handles.platform)
    V_WE = plant.EvalBodySpatialVelocityInWorld(context, handles.platform)
    rpy = RollPitchYaw(X_WE.rotation())
    x = np.concatenate([rpy.vector(), X_WE.translation()])
    rpy_dot = np.linalg.solve(kinematics.angular_velocity_map(x[:3]), V_WE.rotational())
    return x, np.concatenate([rpy_dot, V_WE.translational()])
