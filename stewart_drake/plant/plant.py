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

import math
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

import numpy as np
from pydrake.geometry import CollisionFilterDeclaration, GeometrySet
from pydrake.math import RigidTransform, RollPitchYaw, RotationMatrix
from pydrake.multibody.parsing import Parser
from pydrake.multibody.plant import AddMultibodyPlant, MultibodyPlant, MultibodyPlantConfig
from pydrake.multibody.tree import BodyIndex, ModelInstanceIndex, PdControllerGains, RigidBody
from pydrake.systems.framework import Context, DiagramBuilder, InputPort

from ..base.errors import InvalidConfigError
from ..robot import kinematics
from ..robot.geometry import X_HOME, StewartGeometry
from ..robot.servo import ServoModel

MODEL_NAME = "rotary_stewart"
#: The committed SDF of the reference robot; a test checks it equals :func:`write_sdf` output.
REFERENCE_SDF = Path(__file__).resolve().parents[2] / "sdf" / "rotary_stewart.sdf"
_BASE_THICKNESS = 0.02

#: How the six rods are modelled (docs/plant_speed.md measures both).
#: "bodies": each rod a rigid body on a ball joint at its crank tip, its top closed on the
#: platform by a ball constraint (30 velocities, 18 constraint equations): exact rigid-body
#: dynamics of the rods, spin about their axes included.
#: "distance": each rod a Drake distance constraint (a rigid massless link) between crank tip and
#: platform joint (12 velocities, 6 equations), the rod's mass m lumped m/2 at each end, added to
#: the crank's and the platform's inertia. Exact for the rods' weight (the potential energy of a
#: rod is m g times its centre's height, the mean of its ends') and for the translation of its
#: centre; but two end masses carry m s^2/4 about the rod's centre, normal to it, where the rod
#: has I_c (paper Table I: 0.0016 kg m^2, against m s^2/4 = 0.0033 kg m^2): an excess inertia
#: of m s^2/4 - I_c on the rod's rotation, and the rod's spin inertia is dropped. A rod's
#: kinetic energy is exactly (m/8)|v_A + v_B|^2 + (I_c / 2 s^2)|v_A - v_B|^2 in its end
#: velocities; its cross term v_A . v_B couples crank and platform and cannot be carried by
#: either body, so no split of the mass at the ends is exact; the measured effect on torques
#: and tracking is in docs/plant_speed.md.
ROD_MODELS = ("bodies", "distance")
#: Positions and velocities of the plant with rods as distance constraints: 6 cranks and the
#: platform's quaternion and position (a test reads them back from Drake).
DISTANCE_NQ, DISTANCE_NV = 13, 12


def check_rod_model(rod_model) -> str:
    """``rod_model`` if it is one of :data:`ROD_MODELS`.

    Raises:
        InvalidConfigError: any other value.
    """
    if rod_model not in ROD_MODELS:
        raise InvalidConfigError(f"rod_model must be one of {ROD_MODELS}, got {rod_model!r}")
    return rod_model


def _vec(v) -> str:
    return " ".join(f"{float(c) + 0.0:.12g}" for c in v)  # + 0.0: no "-0" in the text


def _pose(p, R: np.ndarray) -> str:
    rpy = RollPitchYaw(RotationMatrix(R)).vector()
    return _vec(np.concatenate([p, rpy]))


def _inertial(mass: float, moments, p_com) -> str:
    """An SDF ``<inertial>``: ``moments`` (3,) principal moments or a (3, 3) tensor about the
    centre of mass p_com (link frame), kg m^2."""
    I = np.asarray(moments, dtype=float)
    I = np.diag(I) if I.ndim == 1 else I
    return (
        f"      <inertial>\n        <pose>{_vec(p_com)} 0 0 0</pose>\n"
        f"        <mass>{mass:.12g}</mass>\n"
        f"        <inertia><ixx>{I[0, 0]:.12g}</ixx><iyy>{I[1, 1]:.12g}</iyy>"
        f"<izz>{I[2, 2]:.12g}</izz><ixy>{I[0, 1] + 0.0:.12g}</ixy><ixz>{I[0, 2] + 0.0:.12g}</ixz>"
        f"<iyz>{I[1, 2] + 0.0:.12g}</iyz></inertia>\n      </inertial>\n"
    )


def with_point_masses(mass: float, moments, p_com, m_point: float, points) -> tuple:
    """A body's inertia with point masses ``m_point`` (kg) added at ``points`` (n, 3), link
    frame (parallel-axis theorem).

    Returns:
        (mass kg, (3, 3) inertia about the new centre of mass kg m^2, (3,) new centre of mass m).
    """
    points = np.atleast_2d(np.asarray(points, dtype=float))
    p_com = np.asarray(p_com, dtype=float)
    total = mass + m_point * len(points)
    c = (mass * p_com + m_point * points.sum(axis=0)) / total

    def shifted(m, r):  # inertia of a point mass m at offset r
        return m * (np.dot(r, r) * np.eye(3) - np.outer(r, r))

    I = np.diag(np.asarray(moments, dtype=float)) + shifted(mass, p_com - c)
    for p in points:
        I = I + shifted(m_point, p - c)
    return total, I, c


def _geometry_xml(part) -> str:
    size = " ".join(f"{v:.12g}" for v in part.size)
    if part.shape == "box":
        return f"<box><size>{size}</size></box>"
    if part.shape == "sphere":
        return f"<sphere><radius>{part.size[0]:.12g}</radius></sphere>"
    radius, length = part.size
    return (
        f"<{part.shape}><radius>{radius:.12g}</radius><length>{length:.12g}</length></{part.shape}>"
    )


#: Contact parameters of every collision shape (SAP point contact): Coulomb friction of steel and
#: aluminium parts, dry, and a stiffness under which a 20 N push sinks 0.02 mm.
CONTACT_FRICTION = 0.3
CONTACT_STIFFNESS_N_PER_M = 1e6


def _part_xml(part, collision: bool) -> str:
    pose = _pose(part.p_LG, part.R_LG)
    rgba = " ".join(f"{c:.12g}" for c in part.colour)
    out = (
        f'      <visual name="{part.name}">\n        <pose>{pose}</pose>\n'
        f"        <geometry>{_geometry_xml(part)}</geometry>\n"
        f"        <material><diffuse>{rgba}</diffuse></material>\n      </visual>\n"
    )
    if collision and part.collides:
        out += (
            f'      <collision name="{part.name}">\n        <pose>{pose}</pose>\n'
            f"        <geometry>{_geometry_xml(part)}</geometry>\n"
            "        <drake:proximity_properties>"
            f"<drake:mu_dynamic>{CONTACT_FRICTION}</drake:mu_dynamic>"
            f"<drake:mu_static>{CONTACT_FRICTION}</drake:mu_static>"
            f"<drake:point_contact_stiffness>{CONTACT_STIFFNESS_N_PER_M:g}"
            "</drake:point_contact_stiffness></drake:proximity_properties>\n"
            "      </collision>\n"
        )
    return out


def _end_mass_inertial(mass: float, moments, p_com, m_end: float, points) -> str:
    """:func:`_inertial` of a body carrying the rods' lumped end masses (none when m_end = 0,
    the text then unchanged)."""
    if m_end == 0:
        return _inertial(mass, moments, p_com)
    return _inertial(*with_point_masses(mass, moments, p_com, m_end, points))


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
        raise InvalidConfigError(
            "rod direction flipped by 180 degrees: the pose is not assemblable"
        )
    K = np.array([[0, -v[2], v[1]], [v[2], 0, -v[0]], [-v[1], v[0], 0]])
    return np.eye(3) + K + K @ K / (1 + c)


def _rod_zero_rotations(geometry: StewartGeometry) -> list[np.ndarray]:
    """R_B_rod at the SDF zero configuration, chosen so the ball joints read rpy = 0 at home.

    At home the rod's z is along the rod and its x along the part of the rod end's bolt axis
    u_i normal to the rod. Drake's BallRpyJoint is singular where the rod points along +-x of
    this frame, 90 - 19.4 = 70.6 deg out of the crank's plane at the reference robot: outside
    the rod end's cone (crank_joint_cone_deg), so |pitch| <= 90 - (70.6 - 35) = 54.4 deg at
    every pose inside the limits (stewart_drake/plant/ball_joints.py, docs/accuracy.md). The rod is
    axisymmetric, so this spin about its axis changes coordinates only, not the dynamics.
    """
    theta_home = kinematics.ik(geometry, X_HOME)
    q_B, _ = kinematics.platform_joints(geometry, X_HOME)
    tips = geometry.crank_tips(theta_home)
    rotations = []
    for i in range(6):
        u = geometry.u_B[i]
        z_rod = (q_B[i] - tips[i]) / geometry.rod_length
        x_rod = u - np.dot(u, z_rod) * z_rod  # bolt axis, normal part
        x_rod /= np.linalg.norm(x_rod)
        R_home = np.column_stack([x_rod, np.cross(z_rod, x_rod), z_rod])
        rotations.append(_axis_angle(u, -theta_home[i]) @ R_home)
    return rotations


def write_sdf(
    geometry: StewartGeometry | None = None, collision: bool = True, rod_model: str = "bodies"
) -> str:
    """SDFormat 1.9 text of the robot, with Drake's ``drake:ball_constraint`` loop closures.

    Args:
        geometry: the robot; default reference_geometry.md.
        collision: also write every part's ``<collision>`` (:func:`~.parts.robot_parts`, with
            SAP point-contact properties); False draws the parts only (a plant without contact).
        rod_model: "bodies" (each rod a link on a ball joint, closed by a ball constraint) or
            "distance": no rod links, joints or constraints (Drake 1.51's parser has no
            distance constraint; :func:`add_stewart_plant` adds them), each rod's mass lumped
            half at its crank tip and half at its platform joint (:data:`ROD_MODELS`); the
            rods' shapes are then not written (their clearance is checked kinematically,
            :mod:`~.clearance`).
    Returns:
        The SDF as a string; links ``base``, ``crank_i``, ``rod_i``, ``platform``; joints
        ``motor_i`` (revolute, actuated) and ``rod_ball_i`` (ball); i = 0..5.
    Raises:
        InvalidConfigError: ``rod_model`` not one of :data:`ROD_MODELS`.
    Source: reference_geometry.md for the layout; paper Table I for masses and inertias (crank
    inertia corrected to the nearest physically valid tensor, docs/paper_notes.md); the parts'
    shapes are ours (:mod:`~.parts`).
    """
    # Long: one document written element after element, in the order the file reads.
    from ..robot.parts import robot_parts

    check_rod_model(rod_model)
    g = geometry or StewartGeometry()
    a, s = g.crank_length, g.rod_length
    bodies = rod_model == "bodies"
    m_end = 0.0 if bodies else g.rod_mass / 2  # each rod end's lumped mass, kg
    shapes: dict[str, list] = {}
    for part in robot_parts(g):
        shapes.setdefault(part.link, []).append(_part_xml(part, collision))
    out = [
        '<?xml version="1.0"?>',
        "<!-- Generated by stewart_drake.plant.plant.write_sdf(); do not edit by hand. -->",
        '<sdf version="1.9">',
        f'  <model name="{MODEL_NAME}">',
    ]
    out.append(
        '    <link name="base">\n'
        + _inertial(g.base_mass, g.base_inertia, [0, 0, -_BASE_THICKNESS / 2])
        + "".join(shapes["base"])
        + "    </link>"
    )
    out.append(
        '    <joint name="weld_base" type="fixed"><parent>world</parent><child>base</child></joint>'
    )
    rod_R0 = _rod_zero_rotations(g)
    for i in range(6):
        d, u, P = g.d_B[i], g.u_B[i], g.P_B[i]
        R_crank = np.column_stack([d, -u, [0.0, 0.0, 1.0]])  # x along crank, y = shaft (-u)
        out.append(
            f'    <link name="crank_{i}">\n      <pose>{_pose(P, R_crank)}</pose>\n'
            + _end_mass_inertial(g.crank_mass, g.crank_inertia, [a / 2, 0, 0], m_end, [[a, 0, 0]])
            + "".join(shapes[f"crank_{i}"])
            + "    </link>"
        )
        out.append(
            f'    <joint name="motor_{i}" type="revolute">\n      <parent>base</parent>'
            f"<child>crank_{i}</child>\n"
            f'      <axis><xyz expressed_in="__model__">{_vec(u)}</xyz></axis>\n    </joint>'
        )
        if not bodies:
            continue
        out.append(
            f'    <link name="rod_{i}">\n      <pose>{_pose(P + a * d, rod_R0[i])}</pose>\n'
            + _inertial(g.rod_mass, g.rod_inertia, [0, 0, s / 2])
            + "".join(shapes[f"rod_{i}"])
            + "    </link>"
        )
        out.append(
            f'    <joint name="rod_ball_{i}" type="ball"><parent>crank_{i}</parent>'
            f"<child>rod_{i}</child></joint>"
        )
    out.append(
        f'    <link name="platform">\n      <pose>{_vec(X_HOME[3:])} '
        f"{_vec(X_HOME[:3])}</pose>\n"
        + _end_mass_inertial(g.platform_mass, g.platform_inertia, [0, 0, 0], m_end, g.p_E)
        + "".join(shapes["platform"])
        + "    </link>"
    )
    for i in range(6 if bodies else 0):
        out.append(
            "    <drake:ball_constraint>\n"
            f"      <drake:ball_constraint_body_A>rod_{i}</drake:ball_constraint_body_A>\n"
            "      <drake:ball_constraint_body_B>platform</drake:ball_constraint_body_B>\n"
            f"      <drake:ball_constraint_p_AP>0 0 {s:.12g}</drake:ball_constraint_p_AP>\n"
            f"      <drake:ball_constraint_p_BQ>{_vec(g.p_E[i])}</drake:ball_constraint_p_BQ>\n"
            "    </drake:ball_constraint>"
        )
    out += ["  </model>", "</sdf>", ""]
    return "\n".join(out)


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
        (revolute motors, ball rod tops).  rod_top_in_rod: (3,) p_AP of every ball
        constraint, rod frame, m.  n_actuators: 6 motors, + 6 dry-friction actuators when the
        servo has friction.  rod_model: one of ``ROD_MODELS``.
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
        sdf_file: load this SDF instead of the text :func:`write_sdf` makes of ``geometry``
            (its names must follow write_sdf's).
        discrete_contact_approximation: a SAP-family approximation: "sap", "lagged", "similar".
        plant_config: Drake's ``MultibodyPlantConfig`` (a scenario's ``plant``); when given, its
            ``time_step`` and ``discrete_contact_approximation`` replace the two arguments above.
        servo: the motors' gearing and friction (:class:`~.servo.ServoModel`), or None for ideal
            torque sources. The motors' reflected inertia is ``geometry.motor_reflected_inertia``
            (a JointActuator's rotor inertia x gear ratio^2, which Drake adds to the mass
            matrix: set on the last actuator of each motor joint, the one Drake reads); the
            servo's viscous friction is Drake joint damping (implicit in SAP); its
            Coulomb friction is a second actuator on each motor joint, PD-controlled by SAP with
            no stiffness, damping ``servo.friction_damping`` towards zero velocity and an effort
            limit of ``servo.coulomb_friction_Nm``: a dry friction SAP solves implicitly (drake
            1.51 has no joint dry friction: it loads an SDF joint's ``<dynamics><friction>``
            without a word, even with strict parsing, and ignores it; a test holds this).
        contact: register the parts' collision geometry (:mod:`~.parts`), so that SAP turns a
            collision into contact forces (point contact, :data:`CONTACT_STIFFNESS_N_PER_M`);
            False leaves it out (an SDF file's collision geometry is then filtered): parts pass
            through each other unseen, at no cost per step.
        rod_model: "bodies" or "distance" (:data:`ROD_MODELS`); "distance" adds one
            ``AddDistanceConstraint`` (rigid, length ``geometry.rod_length``) per leg between
            the crank tip and the platform joint, and then takes no ``sdf_file``. Its rods have
            no collision geometry: contact between a rod and another part is not simulated.
    Returns:
        (plant, scene_graph, handles): plant is finalized; its default positions are the home
        pose, assembled. With friction, ``handles.actuation_port`` takes 12 values (the six
        motor torques, then six zeros) and ``handles.desired_state_port`` must be fixed to zeros.
    Raises:
        InvalidConfigError: time_step <= 0, a non-SAP approximation (constraints ignored), an
            unknown ``rod_model`` or an ``sdf_file`` with rod_model "distance".
    """
    # Long for its docstring (every argument and Drake's behaviour it relies on); the steps are
    # functions below.
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
    geometry = geometry or StewartGeometry()
    if plant_config is None:
        plant_config = MultibodyPlantConfig(
            time_step=time_step, discrete_contact_approximation=discrete_contact_approximation
        )
    plant, scene_graph = AddMultibodyPlant(plant_config, builder)
    # Drake's default is 9.81 m/s^2 whatever the geometry says; holding torques and feed-forward
    # use geometry.gravity, so the plant must too.
    plant.mutable_gravity_field().set_gravity_vector([0.0, 0.0, -geometry.gravity])
    model = _add_robot_model(plant, scene_graph, geometry, sdf_file, contact, rod_model)
    _add_motors(plant, model, geometry, servo)
    if rod_model == "distance":
        _add_rod_constraints(plant, model, geometry)
    plant.Finalize()
    handles = _handles(plant, model, geometry, rod_model)
    theta_home = kinematics.ik(geometry, X_HOME)
    for joint, angle in zip(handles.motors, theta_home):
        joint.set_default_angle(float(angle))
    plant.SetDefaultFloatingBaseBodyPose(handles.platform, pose_to_transform(X_HOME))
    return plant, scene_graph, handles


def _add_robot_model(
    plant, scene_graph, geometry: StewartGeometry, sdf_file, contact: bool, rod_model: str
):
    """The robot's model instance, from :func:`write_sdf` of ``geometry`` or from ``sdf_file``
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
    """One rigid distance constraint per leg, crank tip (crank frame [a, 0, 0]) to platform
    joint (platform frame p_E_i), of length s."""
    platform = plant.GetBodyByName("platform", model)
    tip = np.array([geometry.crank_length, 0.0, 0.0])
    for i in range(6):
        crank = plant.GetBodyByName(f"crank_{i}", model)
        plant.AddDistanceConstraint(
            crank, tip, platform, np.asarray(geometry.p_E[i], dtype=float), geometry.rod_length
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
        rod_top_in_rod=np.array([0.0, 0.0, geometry.rod_length]),
        n_actuators=n_actuators,
        rod_model=rod_model,
    )


def make_plant(
    geometry: StewartGeometry | None = None,
    time_step: float = 1e-3,
    contact: bool = False,
    rod_model: str = "bodies",
):
    """A standalone finalized plant assembled at home (``contact``: with collision geometry;
    ``rod_model``: :data:`ROD_MODELS`; see :func:`add_stewart_plant`).

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


def assemble(
    plant: MultibodyPlant, context: Context, handles: StewartPlantHandles, x, x_dot=None
) -> np.ndarray:
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
        X_WF = plant.EvalBodyPoseInWorld(context, handles.rods[i])  # rod frame at rpy = 0
        z_F = X_WF.rotation().inverse().multiply((q_B[i] - tips[i]) / g.rod_length)
        R_FM = _min_rotation(np.array([0.0, 0.0, 1.0]), np.asarray(z_F))
        joint.set_angles(context, RollPitchYaw(RotationMatrix(R_FM)).vector())
    plant.SetVelocities(
        context, handles.model_instance, np.zeros(plant.num_velocities(handles.model_instance))
    )
    if x_dot is not None:
        _set_velocities(plant, context, handles, x, np.asarray(x_dot, dtype=float), theta)
    return theta


def assembled_positions(plant: MultibodyPlant, handles: StewartPlantHandles, x) -> np.ndarray:
    """The plant's positions q of the robot assembled at poses x, vectorized: (..., nq).

    The same configuration :func:`assemble` writes (a test holds them to 1e-12), computed in
    numpy for a batch: crank angles from the IK; each rod's ball-joint rpy from its direction,
    the joint frame F being the rod's SDF frame turned with its crank, R_WF = Rot(u_i, theta_i)
    R0_i; the platform's quaternion [w, x, y, z] and position. For sweeps that only pose the
    robot (clearance), where :func:`assemble` would cost a Drake call per joint.

    Args:
        x: (..., 6) poses [rad, m]; unreachable ones give NaN rows.
    """
    g = handles.geometry
    x = np.asarray(x, dtype=float)
    theta, _ = kinematics.ik_unchecked(g, x)
    q_B, _ = kinematics.platform_joints(g, x)
    ell = (q_B - g.crank_tips(theta)) / g.rod_length  # (..., 6, 3) unit
    q = np.zeros(x.shape[:-1] + (plant.num_positions(),))
    R0 = _rod_zero_rotations_cached(g)
    motors, rod_balls = handles.motors, handles.rod_balls
    for i in range(6):
        q[..., motors[i].position_start()] = theta[..., i]
        if not rod_balls:
            continue
        u = g.u_B[i]
        c, s_ = np.cos(theta[..., i])[..., None], np.sin(theta[..., i])[..., None]
        # Rot(u, -theta) ell (Rodrigues), then into the zero-configuration rod frame.
        v = ell[..., i, :]
        v = v * c - np.cross(u, v) * s_ + u * (v @ u)[..., None] * (1 - c)
        z_F = v @ R0[i]
        rpy = _rpy_of_min_rotation_from_z(z_F)
        start = rod_balls[i].position_start()
        q[..., start : start + 3] = rpy
    start = handles.platform.floating_positions_start()
    q[..., start : start + 4] = _quaternion_rpy(x[..., :3])
    q[..., start + 4 : start + 7] = x[..., 3:]
    return q


def rod_bodies_positions(geometry: StewartGeometry, states) -> np.ndarray:
    """Positions (N, nq) of the plant with rods as bodies, from the states (N, >= 13) of a plant
    whose rods are distance constraints (its positions first): the same motor angles and
    platform pose, each rod from crank tip to platform joint without spin. How a run of the
    "distance" model is drawn and checked with the rods' shapes.
    """
    plant, context, handles, _, _ = make_plant(geometry, rod_model="distance")
    bodies, _, body_handles, _, _ = make_plant(geometry)
    states = np.atleast_2d(np.asarray(states, dtype=float))
    poses = []
    for row in states[:, : plant.num_positions()]:
        plant.SetPositions(context, row)
        poses.append(platform_pose(plant, context, handles)[0])
    q = assembled_positions(bodies, body_handles, np.array(poses))
    for joint, body_joint in zip(handles.motors, body_handles.motors):
        q[:, body_joint.position_start()] = states[:, joint.position_start()]
    return q


@lru_cache(maxsize=32)
def _rod_zero_rotations_cached(geometry: StewartGeometry) -> tuple:
    return tuple(_rod_zero_rotations(geometry))


def _rpy_of_min_rotation_from_z(z: np.ndarray) -> np.ndarray:
    """(..., 3) roll-pitch-yaw of the smallest rotation taking e_z onto the unit vectors z."""
    v = np.stack([-z[..., 1], z[..., 0], np.zeros(z.shape[:-1])], axis=-1)  # e_z x z
    c = z[..., 2]
    K = np.zeros(z.shape[:-1] + (3, 3))
    K[..., 0, 2], K[..., 1, 2] = v[..., 1], -v[..., 0]
    K[..., 2, 0], K[..., 2, 1] = -v[..., 1], v[..., 0]
    K[..., 0, 1], K[..., 1, 0] = -v[..., 2], v[..., 2]
    R = np.eye(3) + K + (K @ K) / (1 + c)[..., None, None]
    roll = np.arctan2(R[..., 2, 1], R[..., 2, 2])
    pitch = np.arctan2(-R[..., 2, 0], np.hypot(R[..., 0, 0], R[..., 1, 0]))
    yaw = np.arctan2(R[..., 1, 0], R[..., 0, 0])
    return np.stack([roll, pitch, yaw], axis=-1)


def _quaternion_rpy(rpy: np.ndarray) -> np.ndarray:
    """(..., 4) unit quaternion [w, x, y, z] of R = Rz(yaw) Ry(pitch) Rx(roll)."""
    h = 0.5 * np.asarray(rpy, dtype=float)
    cr, sr = np.cos(h[..., 0]), np.sin(h[..., 0])
    cp, sp = np.cos(h[..., 1]), np.sin(h[..., 1])
    cy, sy = np.cos(h[..., 2]), np.sin(h[..., 2])
    return np.stack(
        [
            cr * cp * cy + sr * sp * sy,
            sr * cp * cy - cr * sp * sy,
            cr * sp * cy + sr * cp * sy,
            cr * cp * sy - sr * sp * cy,
        ],
        axis=-1,
    )


def _set_velocities(plant, context, handles, x, x_dot, theta):
    """Velocities consistent with x_dot: motors, platform, rods (normal rotation, no spin)."""
    g = handles.geometry
    J = kinematics.jacobian(g, x, theta)
    theta_dot = J @ x_dot
    for joint, rate in zip(handles.motors, theta_dot):
        joint.set_angular_rate(context, float(rate))
    E = kinematics.angular_velocity_map(x[:3])
    from pydrake.multibody.math import SpatialVelocity

    plant.SetFreeBodySpatialVelocity(
        context, handles.platform, SpatialVelocity(E @ x_dot[:3], x_dot[3:])
    )
    # Rod angular velocity w = ell x (v_q - v_tip) / s^2, as an rpy rate of the ball joint.
    q_B, r_B = kinematics.platform_joints(g, x)
    tips = g.crank_tips(theta)
    c, s_ = np.cos(theta), np.sin(theta)
    for i, joint in enumerate(handles.rod_balls):
        ell = q_B[i] - tips[i]
        v_q = x_dot[3:] + np.cross(E @ x_dot[:3], r_B[i])
        v_tip = g.crank_length * theta_dot[i] * (-s_[i] * g.d_B[i] + c[i] * np.array([0, 0, 1.0]))
        w_rod_W = np.cross(ell, v_q - v_tip) / g.rod_length**2
        w_crank_W = theta_dot[i] * g.u_B[i]
        X_WC = plant.EvalBodyPoseInWorld(context, handles.cranks[i])
        X_CF = joint.frame_on_parent().GetFixedPoseInBodyFrame()
        R_WF = X_WC.rotation().multiply(X_CF.rotation())
        # BallRpyJoint's generalized velocity is w_FM expressed in F (not rpy rates).
        joint.set_angular_velocity(
            context, np.asarray(R_WF.inverse().multiply(w_rod_W - w_crank_W))
        )


def closed_chain_inverse_dynamics(
    plant: MultibodyPlant,
    context: Context,
    handles: StewartPlantHandles,
    x,
    x_dot,
    x_ddot,
    step: float = 1e-6,
) -> np.ndarray:
    """Motor torques that move the plant's closed chain along (x, x_dot, x_ddot), (6,) in N m.

    Drake's inverse dynamics of the tree, tau = M v_dot + C v - tau_g (``CalcInverseDynamics``
    and ``CalcGravityGeneralizedForces``, with the actuators' reflected inertia), projected on
    the motions the loops allow: with v = N x_dot the tree velocities of a platform rate (as
    :func:`assemble` sets them, rods without spin), the ball constraints' forces do no work
    along N, so N^T tau = N^T B T = J^T T (the motors' rows of N are J). v_dot = N x_ddot +
    (dN/dt) x_dot, the second term by a central difference along x_dot. Joint damping and
    friction are not included. Overwrites the positions and velocities in ``context``.

    Args:
        x, x_dot, x_ddot: (6,) pose, rate and acceleration of the platform (SI).
        step: finite-difference step on the pose, rad or m.
    Returns:
        (6,) torques, N m: the independent check of
        :func:`~.statics.inverse_dynamics_torques` (a test holds them together).
    Raises:
        UnreachablePoseError: x (or a pose ``step`` away along x_dot) cannot be assembled.
    """
    from pydrake.multibody.tree import MultibodyForces

    x, x_dot, x_ddot = (np.asarray(v, dtype=float) for v in (x, x_dot, x_ddot))

    def velocities(pose, rate):
        assemble(plant, context, handles, pose, rate)
        return plant.GetVelocities(context).copy()

    N = np.column_stack([velocities(x, e) for e in np.eye(6)])
    speed = float(np.linalg.norm(x_dot))
    dN_x_dot = np.zeros(N.shape[0])
    if speed > 0:
        d = step * x_dot / speed
        dN_x_dot = (velocities(x + d, x_dot) - velocities(x - d, x_dot)) * (speed / (2 * step))
    assemble(plant, context, handles, x, x_dot)
    tau = plant.CalcInverseDynamics(
        context, N @ x_ddot + dN_x_dot, MultibodyForces(plant)
    ) - plant.CalcGravityGeneralizedForces(context)
    J = kinematics.jacobian(handles.geometry, x)
    return np.linalg.solve(J.T, N.T @ tau)


def loop_closure_errors(
    plant: MultibodyPlant, context: Context, handles: StewartPlantHandles
) -> np.ndarray:
    """(6,) distance in m between each rod's top end and its platform joint (0 when closed);
    with rods as distance constraints, |crank tip to platform joint - rod length|."""
    # The ignores: pydrake's stubs type multiply's (3, n) array argument as a RigidTransform.
    X_WE = plant.EvalBodyPoseInWorld(context, handles.platform)
    p_W_joint = X_WE.multiply(handles.geometry.p_E.T)  # type: ignore[arg-type]  # (3, 6) joints
    rods = handles.rods
    if not rods:
        tip = np.array([handles.geometry.crank_length, 0.0, 0.0])
        p_W_tip = np.column_stack(
            [
                plant.EvalBodyPoseInWorld(context, crank).multiply(tip)  # type: ignore[arg-type]
                for crank in handles.cranks
            ]
        )
        length = np.sqrt(((p_W_joint - p_W_tip) ** 2).sum(axis=0))
        return np.abs(length - handles.geometry.rod_length)
    p_W_top = np.column_stack(
        [
            plant.EvalBodyPoseInWorld(context, rod).multiply(handles.rod_top_in_rod)  # type: ignore[arg-type]
            for rod in rods
        ]
    )
    return np.sqrt(((p_W_top - p_W_joint) ** 2).sum(axis=0))


class LoopClosure:
    """:func:`loop_closure_errors` of the plant's positions q, from q alone (no Context, no
    forward kinematics of the tree), in plain Python floats: for a check at every step of a run,
    where a Context's kinematics or numpy's per-call overhead on (6, 3) arrays costs several
    times more (docs/plant_speed.md).

    Crank tips from the motor angles (as :meth:`~.geometry.StewartGeometry.crank_tips`); with
    rods as bodies, each rod's top at s R_WF R_FM(rpy) e_z from its tip, where R_WF =
    Rot(u_i, theta_i) R0_i is the ball joint's frame (as :func:`assembled_positions` poses it)
    and R_FM = Rz(yaw) Ry(pitch) Rx(roll) Drake's BallRpyJoint; the platform joints from its
    (normalized) quaternion and position. A test holds it to :func:`loop_closure_errors` at
    1e-12 m.

    Args:
        handles: the plant's :class:`StewartPlantHandles`.
    """

    def __init__(self, handles: StewartPlantHandles):
        g = handles.geometry
        self._motors = [joint.position_start() for joint in handles.motors]
        self._balls = [joint.position_start() for joint in handles.rod_balls]
        self._platform = handles.platform.floating_positions_start()
        R0 = _rod_zero_rotations_cached(g)
        self._legs = [
            tuple(float(v) for v in (*g.P_B[i], *g.d_B[i], *g.u_B[i], *g.p_E[i], *np.ravel(R0[i])))
            for i in range(6)
        ]
        self._a, self._s = float(g.crank_length), float(g.rod_length)

    def __call__(self, q) -> np.ndarray:
        """(6,) distance in m between each rod's top end and its platform joint, from q (nq,)."""
        q = np.asarray(q, dtype=float).tolist()
        i = self._platform
        w, x, y, z = q[i : i + 4]
        n = 1.0 / math.sqrt(w * w + x * x + y * y + z * z)
        w, x, y, z = w * n, x * n, y * n, z * n
        r00, r01, r02 = 1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)
        r10, r11, r12 = 2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)
        r20, r21, r22 = 2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)
        X, Y, Z = q[i + 4 : i + 7]
        a, s = self._a, self._s
        out = []
        for k, (px, py, pz, dx, dy, dz, ux, uy, uz, ex, ey, ez, *R0) in enumerate(self._legs):
            th = q[self._motors[k]]
            c, sn = math.cos(th), math.sin(th)
            tx, ty, tz = px + a * c * dx, py + a * c * dy, pz + a * (c * dz + sn)  # crank tip
            jx = r00 * ex + r01 * ey + r02 * ez + X - tx  # tip to platform joint
            jy = r10 * ex + r11 * ey + r12 * ez + Y - ty
            jz = r20 * ex + r21 * ey + r22 * ez + Z - tz
            if not self._balls:
                out.append(abs(math.sqrt(jx * jx + jy * jy + jz * jz) - s))
                continue
            j = self._balls[k]
            cr, sr = math.cos(q[j]), math.sin(q[j])
            cp, sp = math.cos(q[j + 1]), math.sin(q[j + 1])
            cy, sy = math.cos(q[j + 2]), math.sin(q[j + 2])
            fx, fy, fz = cy * sp * cr + sy * sr, sy * sp * cr - cy * sr, cp * cr  # R_FM e_z
            vx = R0[0] * fx + R0[1] * fy + R0[2] * fz  # R0 R_FM e_z, then Rot(u, theta)
            vy = R0[3] * fx + R0[4] * fy + R0[5] * fz
            vz = R0[6] * fx + R0[7] * fy + R0[8] * fz
            uv = (ux * vx + uy * vy + uz * vz) * (1 - c)
            lx = vx * c + (uy * vz - uz * vy) * sn + ux * uv
            ly = vy * c + (uz * vx - ux * vz) * sn + uy * uv
            lz = vz * c + (ux * vy - uy * vx) * sn + uz * uv
            gx, gy, gz = s * lx - jx, s * ly - jy, s * lz - jz
            out.append(math.sqrt(gx * gx + gy * gy + gz * gz))
        return np.array(out)


def platform_pose(plant: MultibodyPlant, context: Context, handles: StewartPlantHandles):
    """Measured pose x (6,) and rate x_dot (6,) of the platform [rad, m; rad/s, m/s]."""
    X_WE = plant.EvalBodyPoseInWorld(context, handles.platform)
    V_WE = plant.EvalBodySpatialVelocityInWorld(context, handles.platform)
    rpy = RollPitchYaw(X_WE.rotation())
    x = np.concatenate([rpy.vector(), X_WE.translation()])
    rpy_dot = np.linalg.solve(kinematics.angular_velocity_map(x[:3]), V_WE.rotational())
    return x, np.concatenate([rpy_dot, V_WE.translational()])
