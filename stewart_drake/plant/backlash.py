"""The gearheads' play in the plant: each motor turns its crank through a backlash.

A servo with ``backlash_rad`` b > 0 (:class:`~stewart_drake.robot.servo.ServoModel`) changes each
leg of the SDF's tree from base --``motor_i``--> crank to base --``motor_i``--> ``rotor_i``
--``play_i``--> crank: the rotor is the gear train's output side as the motor drives it (a body
without mass: the motor's reflected inertia, its actuator and its friction stay on the revolute
joint ``motor_i``, :func:`~.plant.add_stewart_plant`), and the crank turns on it about the same
axis through ``play_i``, a revolute joint with position limits -b/2 and +b/2. Drake's SAP
enforces joint limits as unilateral constraints, implicitly, so inside the play nothing acts
between rotor and crank and at either end the gear carries whatever it must. The crank's angle
is the sum of the two joints' (``motor_i`` + ``play_i``): what the encoders on the output shaft
read (:func:`crank_state_selectors`). Modelling play as joint limits is Simscape Multibody's
way too ("Model Gear Backlash by Using Joint Limits").

Drake removes a joint only from a plant without constraints, so the SDF's six ball constraints
are removed first and added again as :func:`~.sdf.write_sdf` writes them (rod top
[0, 0, s_i] on the platform joint p_E_i). With b = 0 nothing here runs and the plant is
the SDF's, exactly.
"""

from __future__ import annotations

import numpy as np
from pydrake.geometry import CollisionFilterDeclaration, GeometrySet
from pydrake.multibody.tree import RevoluteJoint, SpatialInertia

from ..base.errors import InvalidConfigError
from ..robot.geometry import StewartGeometry


def add_gear_play(
    plant, scene_graph, model, geometry: StewartGeometry, backlash_rad: float
) -> None:
    """Put a rotor and a play of ``backlash_rad`` between each motor joint and its crank
    (before Finalize; module docstring).

    Args:
        plant: the MultibodyPlant with the robot's SDF parsed, not finalized.
        scene_graph: its SceneGraph (the base and the cranks, no longer neighbours in the tree,
            are kept from colliding, as Drake keeps neighbours).
        model: the robot's model instance.
        geometry: the robot (the ball constraints are added again from it).
        backlash_rad: b > 0, the total play at the output shaft, rad.
    Raises:
        InvalidConfigError: b not > 0; no reflected rotor inertia (``geometry.
            motor_reflected_inertia`` 0: a massless rotor inside a play has no dynamics); or
            constraints other than the SDF's six ball constraints.
    """
    if not backlash_rad > 0:
        raise InvalidConfigError(f"backlash_rad must be > 0 to add a play, got {backlash_rad}")
    if not geometry.motor_reflected_inertia > 0:
        raise InvalidConfigError(
            "gear play needs a rotor with inertia: the motors' reflected inertia is "
            f"{geometry.motor_reflected_inertia} kg m^2 (hardware.motors.rotor_inertia)"
        )
    rods = plant.HasBodyNamed("rod_0", model)
    constraints = plant.GetConstraintIds()
    if len(constraints) != (6 if rods else 0):
        raise InvalidConfigError(
            f"the plant has {len(constraints)} constraints; gear play expects the SDF's ball "
            f"constraints only ({6 if rods else 0})"
        )
    for constraint in constraints:
        plant.RemoveConstraint(constraint)
    half = 0.5 * float(backlash_rad)
    for i in range(6):
        joint = plant.GetJointByName(f"motor_{i}", model)
        F, M, axis = joint.frame_on_parent(), joint.frame_on_child(), joint.revolute_axis()
        damping = joint.default_damping()
        plant.RemoveJointActuator(plant.GetJointActuatorByName(f"motor_{i}", model))
        plant.RemoveJoint(joint)
        # Massless: the rotor's inertia is the actuator's reflected inertia on motor_i.
        rotor = plant.AddRigidBody(f"rotor_{i}", model, SpatialInertia.Zero())
        motor = plant.AddJoint(RevoluteJoint(f"motor_{i}", F, rotor.body_frame(), axis, damping))
        plant.AddJointActuator(f"motor_{i}", motor)
        plant.AddJoint(RevoluteJoint(f"play_{i}", rotor.body_frame(), M, axis, -half, half))
    if rods:
        platform = plant.GetBodyByName("platform", model)
        for i in range(6):
            rod = plant.GetBodyByName(f"rod_{i}", model)
            top = np.array([0.0, 0.0, float(geometry.rod_lengths[i])])  # each leg's rod
            plant.AddBallConstraint(rod, top, platform, np.asarray(geometry.p_E[i], dtype=float))
    base = GeometrySet(plant.GetBodyFrameIdOrThrow(plant.GetBodyByName("base", model).index()))
    cranks = GeometrySet(
        [
            plant.GetBodyFrameIdOrThrow(plant.GetBodyByName(f"crank_{i}", model).index())
            for i in range(6)
        ]
    )
    scene_graph.collision_filter_manager().Apply(
        CollisionFilterDeclaration().ExcludeBetween(base, cranks)
    )


def play_joint_indices(plant, model) -> tuple:
    """The ``JointIndex`` of the six ``play_i`` joints, leg order; () without gear play."""
    if not plant.HasJointNamed("play_0", model):
        return ()
    return tuple(plant.GetJointByName(f"play_{i}", model).index() for i in range(6))


def crank_coordinates(handles) -> tuple[list[tuple], list[tuple]]:
    """Where each crank's absolute angle is in the plant's q and v.

    Args:
        handles: the plant's :class:`~.plant.StewartPlantHandles`.
    Returns:
        (positions, velocities): 6 tuples each, leg order, of the indices whose sum is the
        crank's angle (rad) in q and its rate (rad/s) in v: the motor joint's, and with gear
        play the play joint's after it.
    """
    joints: list[tuple] = [(motor,) for motor in handles.motors]
    if handles.plays:
        joints = [(motor, play) for motor, play in zip(handles.motors, handles.plays)]
    positions = [tuple(j.position_start() for j in leg) for leg in joints]
    velocities = [tuple(j.velocity_start() for j in leg) for leg in joints]
    return positions, velocities


def crank_state_selectors(plant, handles) -> tuple:
    """(S_q, S_v), each (6, nq + nv): S_q @ state is the six cranks' absolute angles (rad),
    S_v @ state their rates (rad/s), from the plant's state vector [q, v]; ones and zeros, so
    that without gear play each row picks one entry, exactly."""
    nq = plant.num_positions()
    n = nq + plant.num_velocities()
    S_q, S_v = np.zeros((6, n)), np.zeros((6, n))
    positions, velocities = crank_coordinates(handles)
    for i in range(6):
        S_q[i, list(positions[i])] = 1.0
        S_v[i, [nq + k for k in velocities[i]]] = 1.0
    return S_q, S_v


def crank_angles(plant, context, handles) -> np.ndarray:
    """(6,) the cranks' absolute angles in ``context``, rad (the output shafts')."""
    q = plant.GetPositions(context)
    return np.array([sum(q[k] for k in leg) for leg in crank_coordinates(handles)[0]])


def crank_rates(plant, context, handles) -> np.ndarray:
    """(6,) the cranks' absolute rates in ``context``, rad/s."""
    v = plant.GetVelocities(context)
    return np.array([sum(v[k] for k in leg) for leg in crank_coordinates(handles)[1]])


def take_up_play(plant, context, handles, torques) -> None:
    """Rest each crank on the flank of its play that carries ``torques`` (6,) N m (the motors'
    holding torques): the crank keeps its angle, the play joint goes to -b/2 where the motor
    pushes the crank positive (the stop then pushes it so), +b/2 where negative, 0 for no
    torque, and the rotor to the crank's angle less the play. Nothing without gear play."""
    if not handles.plays:
        return
    cranks = crank_angles(plant, context, handles)
    for motor, play, crank, torque in zip(handles.motors, handles.plays, cranks, torques):
        offset = -float(np.sign(torque)) * play.position_upper_limits()[0]
        play.set_angle(context, offset)
        motor.set_angle(context, float(crank) - offset)
