"""The nonlinear plant: a discrete SAP MultibodyPlant of the robot, with its constraints.

The robot is parsed from :func:`~.sdf.write_sdf` (base welded to the world, six actuated cranks
``motor_i``, six rods on ball joints, a floating platform, the loops closed by ball constraints;
or, with rods as distance constraints, :data:`~.sdf.ROD_MODELS`, the cranks and platform with
one distance constraint per leg added here). Ball constraints are only enforced by a discrete
plant using SAP, so :func:`add_stewart_plant` always builds one (``time_step > 0``).

The SDF's zero configuration (all joint angles 0) is *not* assembled: the cranks are horizontal
there. :func:`add_stewart_plant` sets the default joint positions to the home pose, and
:func:`~.closed_chain.assemble` writes any reachable pose into a Context.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
from pydrake.geometry import CollisionFilterDeclaration, GeometrySet
from pydrake.math import RigidTransform, RollPitchYaw
from pydrake.multibody.parsing import Parser
from pydrake.multibody.plant import AddMultibodyPlant, MultibodyPlant, MultibodyPlantConfig
from pydrake.multibody.tree import BodyIndex, ModelInstanceIndex, PdControllerGains, RigidBody
from pydrake.systems.framework import Context, DiagramBuilder, InputPort

from ..base.errors import InvalidConfigError
from ..robot import kinematics
from ..robot.geometry import X_HOME, StewartGeometry
from ..robot.servo import ServoModel
from .backlash import add_gear_play, play_joint_indices
from .sdf import check_rod_model, write_sdf

#: Positions and velocities of the plant with rods as distance constraints: 6 cranks and the
#: platform's quaternion and position (a test reads them back from Drake).
DISTANCE_NQ, DISTANCE_NV = 13, 12


@dataclass(frozen=True)
class StewartPlantHandles:
    """What a caller needs to address the robot inside a plant: the plant and Drake's indices.

    The bodies, joints and ports are looked up in the plant each time they are asked for
    (``platform``, ``cranks``, ``rods``, ``motors``, ``rod_balls``, ``actuation_port``,
    ``desired_state_port``: fresh pydrake handles, a few microseconds each), never stored: a
    pydrake ``RigidBody``, ``Joint`` or port of the plant kept in a Python object holds the plant
    through pybind's keep-alive, which Python's garbage collector cannot see through, so the
    Diagram around it could never be freed (drake 1.58 frees a Diagram with Python systems
    otherwise; docs/performance.md). Keep the indices, or ask again, rather than the handles.

    Attributes:
        geometry: the robot.  plant: the finalized MultibodyPlant.  model_instance: the robot's.
        platform_index, crank_indices (6), rod_indices (6; empty with distance-constraint
        rods): ``BodyIndex``.  motor_indices (6), rod_ball_indices (6 or empty): ``JointIndex``
        (revolute motors, ball rod tops).  rod_top_in_rod: (6, 3) p_AP of each leg's ball
        constraint, its rod's frame, m ([0, 0, s_i]).  n_actuators: 6 motors, + 6 dry-friction
        actuators when the servo has friction.  rod_model: one of ``ROD_MODELS``.  play_indices
        (6 or empty): ``JointIndex`` of the gear-play joints (crank on rotor; :mod:`~.backlash`),
        empty without backlash; with them a crank's angle is its motor joint's plus its play's.
    """

    geometry: StewartGeometry
    plant: MultibodyPlant
    model_instance: ModelInstanceIndex
    platform_index: BodyIndex
    crank_indices: tuple
    rod_indices: tuple
    motor_indices: tuple
    rod_ball_indices: tuple
    rod_top_in_rod: np.ndarray
    n_actuators: int = 6
    rod_model: str = "bodies"
    play_indices: tuple = ()

    @property
    def platform(self) -> RigidBody:
        """The platform body (its frame is E at the tool's centre)."""
        return self.plant.get_body(self.platform_index)

    @property
    def cranks(self) -> tuple:
        """The 6 crank bodies, leg order."""
        return tuple(map(self.plant.get_body, self.crank_indices))

    @property
    def rods(self) -> tuple:
        """The 6 rod bodies, leg order (empty with rods as distance constraints)."""
        return tuple(map(self.plant.get_body, self.rod_indices))

    @property
    def motors(self) -> tuple:
        """The 6 motor ``RevoluteJoint``, leg order."""
        return tuple(map(self.plant.get_joint, self.motor_indices))

    @property
    def plays(self) -> tuple:
        """The 6 gear-play ``RevoluteJoint`` (crank on its rotor), leg order; empty without."""
        return tuple(map(self.plant.get_joint, self.play_indices))

    @property
    def rod_balls(self) -> tuple:
        """The 6 crank-to-rod ``BallRpyJoint``, leg order (empty with distance rods)."""
        return tuple(map(self.plant.get_joint, self.rod_ball_indices))

    @property
    def actuation_port(self) -> InputPort:
        """The plant's input port of the robot's actuators (``n_actuators`` values)."""
        return self.plant.get_actuation_input_port(self.model_instance)

    @property
    def desired_state_port(self) -> InputPort | None:
        """The friction actuators' desired state (fix it to zeros), or None without them."""
        if self.n_actuators == 6:
            return None
        return self.plant.get_desired_state_input_port(self.model_instance)


def add_stewart_plant(
    builder: DiagramBuilder,
    geometry: StewartGeometry | None = None,
    time_step: float = 1e-3,
    sdf_file: str | Path | None = None,
    discrete_contact_approximation: str = "sap",
    plant_config: MultibodyPlantConfig | None = None,
    servo: ServoModel | None = None,
    contact: bool = False,
    rod_model: str = "bodies",
):
    """Add the robot as a discrete SAP MultibodyPlant (+ SceneGraph) to ``builder``.

    Args:
        builder: the DiagramBuilder to add to.
        geometry: the robot; default reference_geometry.md. Its ``gravity`` (m/s^2, along -z)
            is the plant's gravity field.
        time_step: plant period in s; must be > 0 (ball constraints need a discrete plant).
        sdf_file: load this SDF instead of the text :func:`~.sdf.write_sdf` makes of ``geometry``
            (its names must follow write_sdf's).
        discrete_contact_approximation: a SAP-family approximation: "sap", "lagged", "similar".
        plant_config: Drake's ``MultibodyPlantConfig`` (a scenario's ``plant``); when given, its
            ``time_step`` and ``discrete_contact_approximation`` replace the two arguments above.
        servo: the motors' gearing and friction (:class:`~.servo.ServoModel`), or None for ideal
            torque sources. The reflected inertia ``geometry.motor_reflected_inertia`` (kg m^2)
            is set on the last actuator of each motor joint (the one Drake reads); the viscous
            friction is joint damping; the Coulomb friction ``servo.coulomb_friction_Nm`` a
            second actuator, PD-controlled by SAP towards zero velocity (damping
            ``servo.friction_damping``; why: docs/hardware.md, "Friction"); ``backlash_rad`` > 0
            adds a rotor and a play per motor (:func:`~.backlash.add_gear_play`).
        contact: register the parts' collision geometry (:mod:`~.parts`) for SAP point contact
            (:data:`~.sdf.CONTACT_STIFFNESS_N_PER_M`); False filters it out (parts pass through).
        rod_model: "bodies" or "distance" (:data:`~.sdf.ROD_MODELS`); "distance" is one rigid
            ``AddDistanceConstraint`` of ``geometry.rod_lengths[i]`` per leg, crank tip to
            platform joint, with no ``sdf_file`` and no rod collision geometry.
    Returns:
        (plant, scene_graph, handles): plant is finalized; its default positions are the home
        pose, assembled. With friction, ``handles.actuation_port`` takes 12 values (the six
        motor torques, then six zeros) and ``handles.desired_state_port`` must be fixed to zeros.
    Raises:
        InvalidConfigError: time_step <= 0, a non-SAP approximation (constraints ignored), an
            unknown ``rod_model`` or an ``sdf_file`` with rod_model "distance".
    """
    plant_config = _plant_config(
        time_step, discrete_contact_approximation, plant_config, rod_model, sdf_file
    )
    geometry = geometry or StewartGeometry()
    plant, scene_graph = AddMultibodyPlant(plant_config, builder)
    # Drake's default is 9.81 m/s^2 whatever the geometry says; holding torques and feed-forward
    # use geometry.gravity, so the plant must too.
    plant.mutable_gravity_field().set_gravity_vector([0.0, 0.0, -geometry.gravity])
    model = _add_robot_model(plant, scene_graph, geometry, sdf_file, contact, rod_model)
    if servo is not None and servo.backlash_rad > 0:
        add_gear_play(plant, scene_graph, model, geometry, servo.backlash_rad)
    _add_motors(plant, model, geometry, servo)
    if rod_model == "distance":
        _add_rod_constraints(plant, model, geometry)
    plant.Finalize()
    handles = _handles(plant, model, geometry, rod_model)
    _set_home_defaults(plant, handles)
    return plant, scene_graph, handles


def _plant_config(
    time_step: float,
    discrete_contact_approximation: str,
    plant_config: MultibodyPlantConfig | None,
    rod_model: str,
    sdf_file,
) -> MultibodyPlantConfig:
    """The checked ``MultibodyPlantConfig`` of :func:`add_stewart_plant`'s arguments.

    Raises:
        InvalidConfigError: as :func:`add_stewart_plant`.
    """
    if plant_config is not None:
        time_step = plant_config.time_step
        discrete_contact_approximation = plant_config.discrete_contact_approximation
    if not (np.isfinite(time_step) and time_step > 0):
        raise InvalidConfigError(
            f"time_step must be > 0 s (got {time_step}): Drake enforces ball constraints only in "
            f"a discrete plant"
        )
    if discrete_contact_approximation not in ("sap", "lagged", "similar"):
        raise InvalidConfigError(
            f"discrete_contact_approximation {discrete_contact_approximation!r} does not enforce "
            f"ball constraints; use 'sap', 'lagged' or 'similar'"
        )
    check_rod_model(rod_model)
    if rod_model != "bodies" and sdf_file is not None:
        raise InvalidConfigError(
            f"an sdf_file models the rods as bodies; rod_model {rod_model!r} takes none"
        )
    if plant_config is None:
        plant_config = MultibodyPlantConfig(
            time_step=time_step, discrete_contact_approximation=discrete_contact_approximation
        )
    return plant_config


def _set_home_defaults(plant, handles: StewartPlantHandles) -> None:
    """The finalized plant's default positions: the motor angles and platform pose of home."""
    theta_home = kinematics.ik(handles.geometry, X_HOME)
    for joint, angle in zip(handles.motors, theta_home):
        joint.set_default_angle(float(angle))
    plant.SetDefaultFloatingBaseBodyPose(handles.platform, pose_to_transform(X_HOME))


def _add_robot_model(
    plant, scene_graph, geometry: StewartGeometry, sdf_file, contact: bool, rod_model: str
):
    """The robot's model instance, from :func:`~.sdf.write_sdf` of ``geometry`` or from ``sdf_file``
    (its collision geometry filtered out without ``contact``)."""
    parser = Parser(plant)
    if sdf_file is None:
        text = write_sdf(geometry, collision=contact, rod_model=rod_model)
        (model,) = parser.AddModelsFromString(text, "sdf")
        return model
    (model,) = parser.AddModels(str(sdf_file))
    if not contact:
        frames = [plant.GetBodyFrameIdOrThrow(index) for index in plant.GetBodyIndices(model)]
        scene_graph.collision_filter_manager().Apply(
            CollisionFilterDeclaration().ExcludeWithin(GeometrySet(frames))
        )
    return model


def _add_motors(plant, model, geometry: StewartGeometry, servo: ServoModel | None) -> None:
    """The servo on each motor joint (before Finalize): viscous friction as joint damping,
    Coulomb friction as a second, PD-controlled actuator, and the reflected rotor inertia on
    the joint's last actuator."""
    gear = servo.gear_ratio if servo is not None else 1.0
    for i in range(6):
        joint = plant.GetJointByName(f"motor_{i}", model)
        # Looked up by name: before Finalize() drake's GetJointActuatorIndices(model) is empty.
        last = plant.GetJointActuatorByName(f"motor_{i}", model)
        if servo is not None:
            joint.set_default_damping(servo.viscous_damping)
            if servo.coulomb_friction_Nm > 0:
                last = plant.AddJointActuator(
                    f"friction_{i}", joint, effort_limit=servo.coulomb_friction_Nm
                )
                last.set_controller_gains(PdControllerGains(p=0.0, d=servo.friction_damping))
        # Drake keeps one reflected inertia per joint, from the joint's last actuator (on 1.51 a
        # later actuator's value replaces an earlier one's, zero included), so the rotor goes on
        # the last actuator of each motor joint; a test reads the mass matrix back.
        last.set_default_gear_ratio(gear)
        last.set_default_rotor_inertia(geometry.motor_reflected_inertia / gear**2)


def _add_rod_constraints(plant, model, geometry: StewartGeometry) -> None:
    """One rigid distance constraint per leg, crank tip (crank frame [a_i, 0, 0]) to platform
    joint (platform frame p_E_i), of length s_i."""
    platform = plant.GetBodyByName("platform", model)
    for i in range(6):
        crank = plant.GetBodyByName(f"crank_{i}", model)
        tip = np.array([float(geometry.crank_lengths[i]), 0.0, 0.0])
        plant.AddDistanceConstraint(
            crank,
            tip,
            platform,
            np.asarray(geometry.p_E[i], dtype=float),
            float(geometry.rod_lengths[i]),
        )


def _handles(plant, model, geometry: StewartGeometry, rod_model: str) -> StewartPlantHandles:
    """The handles of the finalized plant's robot.

    Raises:
        InvalidConfigError: the model has other than 6 motor actuators (12 with friction).
    """
    n_actuators = plant.num_actuators()
    if n_actuators not in (6, 12):
        raise InvalidConfigError(f"expected 6 motor actuators, the SDF gives {n_actuators}")
    bodies = rod_model == "bodies"
    return StewartPlantHandles(
        geometry=geometry,
        plant=plant,
        model_instance=model,
        platform_index=plant.GetBodyByName("platform", model).index(),
        crank_indices=tuple(plant.GetBodyByName(f"crank_{i}", model).index() for i in range(6)),
        rod_indices=tuple(
            plant.GetBodyByName(f"rod_{i}", model).index() for i in range(6) if bodies
        ),
        motor_indices=tuple(plant.GetJointByName(f"motor_{i}", model).index() for i in range(6)),
        rod_ball_indices=tuple(
            plant.GetJointByName(f"rod_ball_{i}", model).index() for i in range(6) if bodies
        ),
        rod_top_in_rod=np.column_stack([np.zeros((6, 2)), geometry.rod_lengths]),
        n_actuators=n_actuators,
        rod_model=rod_model,
        play_indices=play_joint_indices(plant, model),
    )


def make_plant(
    geometry: StewartGeometry | None = None,
    time_step: float = 1e-3,
    contact: bool = False,
    rod_model: str = "bodies",
):
    """A standalone finalized plant assembled at home (``contact``: with collision geometry;
    ``rod_model``: :data:`~.sdf.ROD_MODELS`; see :func:`add_stewart_plant`).

    Returns:
        (plant, plant_context, handles, diagram, root_context): the plant's Context lives inside
        the Diagram's (the plant is registered with a SceneGraph), so both are returned.
    """
    builder = DiagramBuilder()
    plant, _, handles = add_stewart_plant(
        builder, geometry, time_step, contact=contact, rod_model=rod_model
    )
    diagram = builder.Build()
    context = diagram.CreateDefaultContext()
    return plant, plant.GetMyMutableContextFromRoot(context), handles, diagram, context


def pose_to_transform(x) -> RigidTransform:
    """X_BE of pose x = [phi, theta, psi, X, Y, Z] (rad, m)."""
    x = np.asarray(x, dtype=float)
    return RigidTransform(RollPitchYaw(x[:3]), x[3:6])


def platform_pose(plant: MultibodyPlant, context: Context, handles: StewartPlantHandles):
    """Measured pose x (6,) and rate x_dot (6,) of the platform [rad, m; rad/s, m/s]."""
    X_WE = plant.EvalBodyPoseInWorld(context, handles.platform)
    V_WE = plant.EvalBodySpatialVelocityInWorld(context, handles.platform)
    rpy = RollPitchYaw(X_WE.rotation())
    x = np.concatenate([rpy.vector(), X_WE.translation()])
    rpy_dot = np.linalg.solve(kinematics.angular_velocity_map(x[:3]), V_WE.rotational())
    return x, np.concatenate([rpy_dot, V_WE.translational()])
