"""The same robot in MuJoCo: an MJCF written from a :class:`StewartGeometry`, assembly, closure.

Model (names as in :func:`.sdf.write_sdf`): bodies ``base`` (fixed to the world),
``crank_i`` on hinge joints ``motor_i`` (axis u_i), ``rod_i`` on ball joints ``rod_ball_i`` at
the crank tips, ``platform`` on a free joint; six ``<equality><connect>`` pull site ``rod_top_i``
(rod top end) onto site ``platform_joint_i`` (platform joint p_i); six ``<motor>`` actuators
``motor_i`` (gear 1, torque in N m, no control range). Gravity is ``geometry.gravity`` along -z.
Every part of :func:`~.parts.robot_parts` is a geom named ``<link>/<part>`` in its body: the
collision ones in group 0 with contact on (MuJoCo skips parent-child pairs, as Drake skips jointed
bodies), the drawn-only ones in group 1 without.

Body frames, masses, COM offsets and rotational inertias are read from the Drake plant that
:func:`.plant.add_stewart_plant` builds from the same geometry at its home pose, so
both engines simulate one set of numbers (paper Table I, crank inertia corrected as in the SDF).
Joint coordinates match Drake's: ``motor_i`` reads the motor angle theta_i in rad (the hinge's
``ref`` is the home angle, so the model's configuration ``qpos0`` is the home pose, assembled),
and the rods' ball quaternions are the identity where Drake's ``BallRpyJoint`` reads rpy = 0.

The loops are closed by MuJoCo's soft constraints: the ``solref`` time constant, 1e-9 s, is
raised by MuJoCo to twice the time step (flag ``refsafe``), so the loops stiffen as the step
shrinks, as SAP's near-rigid constraints do; docs/accuracy.md measures the closure error this
leaves. ``mujoco`` (>= 4.0) is an optional dependency (``pip install "stewart-drake[mujoco]"``);
only :func:`load_model`, :func:`assemble` and the readers below import it; writing needs Drake.
"""

from __future__ import annotations

import numpy as np

from ..base.errors import InvalidConfigError
from ..robot.geometry import StewartGeometry
from ..robot.servo import ServoModel

#: Integrators accepted by :func:`write_mjcf` (MuJoCo names).
INTEGRATORS = ("implicitfast", "RK4", "implicit", "Euler")
#: RK4: at 1 ms a zero-torque fall from home keeps its energy to 2e-8 and its loops closed to
#: 2e-7 m for about three times the cost per step of implicitfast, which (first order, like SAP)
#: loses 1 % of the energy and opens the loops by 2e-5 m; docs/accuracy.md has the figures. Needs
#: MuJoCo >= 4.0, whose RK4 is fourth order for ball and free joints (3.2.7: loops open by 4e-5 m).
DEFAULT_INTEGRATOR = "RK4"
#: Default loop-closure constraint parameters (MuJoCo ``solref`` / ``solimp`` of the connects):
#: time constant 1e-9 s, which MuJoCo raises to twice the time step (flag ``refsafe``, on by
#: default), critical damping; impedance 0.9999 at any violation (the stiffest MuJoCo allows).
#: Chosen by the closure and hold-drift figures of docs/accuracy.md.
DEFAULT_SOLREF = (1e-9, 1.0)
DEFAULT_SOLIMP = (0.9999, 0.9999, 0.001, 0.5, 2.0)


def _num(v) -> str:
    """Numbers as MJCF text, exact to the last bit (repr of a double)."""
    return " ".join(repr(float(c)) for c in np.atleast_1d(v))


def _quat(R) -> np.ndarray:
    """(4,) quaternion [w, x, y, z] of a Drake RotationMatrix."""
    q = R.ToQuaternion()
    return np.array([q.w(), q.x(), q.y(), q.z()])


def _inertial(body) -> str:
    """``<inertial>`` of a Drake RigidBody: mass, COM and full inertia about the COM, body frame."""
    M = body.default_spatial_inertia()
    p_BoBcm = M.get_com()
    I = M.Shift(p_BoBcm).CalcRotationalInertia().CopyToFullMatrix3()
    full = [I[0, 0], I[1, 1], I[2, 2], I[0, 1], I[0, 2], I[1, 2]]
    return (
        f'<inertial pos="{_num(p_BoBcm)}" mass="{_num(M.get_mass())}" fullinertia="{_num(full)}"/>'
    )


def _geom(part) -> str:
    """One MJCF ``<geom>`` of a :class:`~.parts.Part` (link frame = body frame); drawn-only parts
    in group 1 without contact."""
    from pydrake.math import RotationMatrix

    half = (
        [v / 2 for v in part.size]
        if part.shape == "box"
        else [part.size[0]]
        if part.shape == "sphere"
        else [part.size[0], part.size[1] / 2]
    )
    q = RotationMatrix(part.R_LG).ToQuaternion()
    rgba = " ".join(f"{c:g}" for c in part.colour)
    contact = (
        'contype="1" conaffinity="1" group="0"'
        if part.collides
        else 'contype="0" conaffinity="0" group="1"'
    )
    return (
        f'<geom name="{part.link}/{part.name}" type="{part.shape}" size="{_num(half)}" '
        f'pos="{_num(part.p_LG)}" quat="{_num([q.w(), q.x(), q.y(), q.z()])}" '
        f'rgba="{rgba}" {contact}/>'
    )


def _check_options(time_step: float, integrator: str, solref, solimp):
    if not (np.isfinite(time_step) and time_step > 0):
        raise InvalidConfigError(f"time_step must be a finite number of s > 0, got {time_step}")
    if integrator not in INTEGRATORS:
        raise InvalidConfigError(f"integrator {integrator!r} is not one of {INTEGRATORS}")
    solref, solimp = np.asarray(solref, dtype=float), np.asarray(solimp, dtype=float)
    if solref.shape != (2,) or not np.all(np.isfinite(solref)) or not np.all(solref > 0):
        raise InvalidConfigError(
            f"solref must be (time constant > 0 s, damping ratio > 0), got {solref.tolist()}"
        )
    if (
        solimp.shape != (5,)
        or not np.all(np.isfinite(solimp))
        or not (0 < solimp[0] < 1 and 0 < solimp[1] < 1)
    ):
        raise InvalidConfigError(
            f"solimp must be 5 numbers (d0, d_width in (0, 1), width, "
            f"midpoint, power), got {solimp.tolist()}"
        )
    return solref, solimp


def write_mjcf(
    geometry: StewartGeometry | None = None,
    time_step: float = 1e-3,
    integrator: str = DEFAULT_INTEGRATOR,
    solref=DEFAULT_SOLREF,
    solimp=DEFAULT_SOLIMP,
    servo: ServoModel | None = None,
    torque_limit_Nm: float | None = None,
) -> str:
    """MJCF text of the robot, assembled at the home pose, loops closed by ``connect``.

    The robot as built: ``geometry.motor_reflected_inertia`` is each motor hinge's ``armature``;
    a ``servo`` adds its viscous friction as the hinge's ``damping`` and its Coulomb friction as
    ``frictionloss``, and a ``jointpos`` sensor ``encoder_i`` per motor (quantize its reading
    with :func:`encoder_angles`); ``torque_limit_Nm`` bounds each actuator's force
    (``forcerange``). Without them (the ideal robot) the text is the same as before them.

    Args:
        geometry: the robot; default reference_geometry.md.
        time_step: MuJoCo's ``option/timestep`` in s (> 0); 1e-3 like the Drake plant.
        integrator: one of :data:`INTEGRATORS`.
        solref, solimp: the six connect constraints' MuJoCo parameters, (2,) and (5,).
        servo: the motors' friction (:class:`~.servo.ServoModel`), or None (frictionless).
        torque_limit_Nm: the actuators' saturation in N m (> 0), or None (unlimited).
    Returns:
        The MJCF as a string (bodies, joints, sites and actuators named as in the module
        docstring; leg i = 0..5 in reference_geometry.md order).
    Raises:
        InvalidConfigError: a time step, integrator, solver parameter or torque limit out of
            range.
    Source: body frames and inertias of the Drake plant at home (same SDF, Table I).
    """
    from ..robot.parts import robot_parts
    from .plant import make_plant
    from .sdf import MODEL_NAME

    solref, solimp = _check_options(time_step, integrator, solref, solimp)
    force = _force_attributes(torque_limit_Nm)
    g = geometry or StewartGeometry()
    motor_extra = _motor_attributes(g, servo)
    plant, context, handles, _, _ = make_plant(g)
    shapes: dict[str, list[str]] = {}
    for part in robot_parts(g):
        shapes.setdefault(part.link, []).append(_geom(part))
    out = [
        '<?xml version="1.0"?>',
        "<!-- Generated by stewart_drake.plant.mjcf.write_mjcf(); do not edit by hand. -->",
        f'<mujoco model="{MODEL_NAME}">',
        '  <compiler angle="radian" autolimits="true"/>',
        f'  <option timestep="{_num(time_step)}" integrator="{integrator}" '
        f'gravity="0 0 {_num(-g.gravity)}"/>',
        "  <worldbody>",
        '    <body name="base">',
        f"      {_inertial(plant.GetBodyByName('base', handles.model_instance))}",
        *(f"      {geom}" for geom in shapes["base"]),
        "    </body>",
    ]
    theta_home = [joint.get_angle(context) for joint in handles.motors]
    for i in range(6):
        out += _leg_xml(plant, context, handles, i, theta_home[i], motor_extra, shapes)
    X_WE = plant.EvalBodyPoseInWorld(context, handles.platform)
    out += [
        f'    <body name="platform" {_frame(X_WE)}>',
        '      <freejoint name="platform"/>',
        f"      {_inertial(handles.platform)}",
        *(f"      {geom}" for geom in shapes["platform"]),
    ]
    out += [
        f'      <site name="platform_joint_{i}" pos="{_num(g.p_E[i])}" size="0.011"/>'
        for i in range(6)
    ]
    out += ["    </body>", "  </worldbody>"]
    out += _loops_and_actuators_xml(solref, solimp, force, servo is not None)
    out += ["</mujoco>", ""]
    return "\n".join(out)


def _force_attributes(torque_limit_Nm: float | None) -> str:
    """The actuators' ``forcerange`` attributes of a torque limit in N m (none for None).

    Raises:
        InvalidConfigError: a limit that is not a finite number > 0.
    """
    if torque_limit_Nm is not None and not (np.isfinite(torque_limit_Nm) and torque_limit_Nm > 0):
        raise InvalidConfigError(
            f"torque_limit_Nm must be a finite number of N m > 0, got {torque_limit_Nm}"
        )
    return (
        ""
        if torque_limit_Nm is None
        else f' forcelimited="true" forcerange="{_num([-torque_limit_Nm, torque_limit_Nm])}"'
    )


def _motor_attributes(g: StewartGeometry, servo: ServoModel | None) -> str:
    """The motor hinges' extra attributes: ``armature`` (the reflected rotor inertia) and, with
    a servo, ``damping`` and ``frictionloss``; each only where it is > 0."""
    motor_extra = ""
    if g.motor_reflected_inertia > 0:
        motor_extra += f' armature="{_num(g.motor_reflected_inertia)}"'
    if servo is not None:
        if servo.viscous_damping > 0:
            motor_extra += f' damping="{_num(servo.viscous_damping)}"'
        if servo.coulomb_friction_Nm > 0:
            motor_extra += f' frictionloss="{_num(servo.coulomb_friction_Nm)}"'
    return motor_extra


def _frame(X) -> str:
    """The ``pos`` and ``quat`` attributes of a pose (a Drake ``RigidTransform``)."""
    return f'pos="{_num(X.translation())}" quat="{_num(_quat(X.rotation()))}"'


def _leg_xml(plant, context, handles, i: int, theta_home: float, motor_extra: str, shapes):
    """Leg i's bodies: ``crank_i`` (at its pose in the Drake plant at home, on the hinge
    ``motor_i`` whose ``ref`` is the home angle ``theta_home``, rad) and inside it ``rod_i`` on
    its ball joint, with the site ``rod_top_i``. ``shapes``: {link: its geoms}."""
    crank, rod = handles.cranks[i], handles.rods[i]
    X_WC = plant.EvalBodyPoseInWorld(context, crank)
    X_CR = X_WC.InvertAndCompose(plant.EvalBodyPoseInWorld(context, rod))
    return [
        f'    <body name="crank_{i}" {_frame(X_WC)}>',
        f"      {_inertial(crank)}",
        f'      <joint name="motor_{i}" type="hinge" '
        f'axis="{_num(handles.motors[i].revolute_axis())}" ref="{_num(theta_home)}"'
        f"{motor_extra}/>",
        *(f"      {geom}" for geom in shapes[f"crank_{i}"]),
        f'      <body name="rod_{i}" {_frame(X_CR)}>',
        f"        {_inertial(rod)}",
        f'        <joint name="rod_ball_{i}" type="ball"/>',
        *(f"        {geom}" for geom in shapes[f"rod_{i}"]),
        f'        <site name="rod_top_{i}" pos="{_num(handles.rod_top_in_rod[i])}" size="0.011"/>',
        "      </body>",
        "    </body>",
    ]


def _loops_and_actuators_xml(solref, solimp, force: str, encoders: bool) -> list[str]:
    """The ``<equality>`` of the six loop connects, the ``<actuator>`` of the six motors (with
    the ``force`` range attributes) and, with ``encoders``, the ``<sensor>`` of their angles."""
    out = ["  <equality>"]
    out += [
        f'    <connect name="loop_{i}" site1="rod_top_{i}" site2="platform_joint_{i}" '
        f'solref="{_num(solref)}" solimp="{_num(solimp)}"/>'
        for i in range(6)
    ]
    out += ["  </equality>", "  <actuator>"]
    out += [f'    <motor name="motor_{i}" joint="motor_{i}" gear="1"{force}/>' for i in range(6)]
    out += ["  </actuator>"]
    if encoders:
        out += ["  <sensor>"]
        out += [f'    <jointpos name="encoder_{i}" joint="motor_{i}"/>' for i in range(6)]
        out += ["  </sensor>"]
    return out


def import_mujoco():
    """The ``mujoco`` module. Raises InvalidConfigError (with the install line) if missing."""
    try:
        import mujoco
    except ImportError:
        raise InvalidConfigError(
            'MuJoCo is not installed: pip install "stewart-drake[mujoco]" (or pip install mujoco)'
        ) from None
    return mujoco


def load_model(geometry: StewartGeometry | None = None, **options):
    """``mujoco.MjModel`` of :func:`write_mjcf` (same keyword options).

    Raises:
        InvalidConfigError: MuJoCo not installed, or an option out of range.
    """
    return import_mujoco().MjModel.from_xml_string(write_mjcf(geometry, **options))


def _qpos_addresses(model, prefix: str) -> list:
    """qpos addresses of the joints ``<prefix>0`` .. ``<prefix>5``."""
    return [int(model.joint(f"{prefix}{i}").qposadr[0]) for i in range(6)]


def assemble(model, data, geometry: StewartGeometry | None, x) -> np.ndarray:
    """Write the assembled configuration of platform pose x into ``data`` (at rest, ctrl 0).

    As :func:`.closed_chain.assemble`: cranks from the closed-form IK, each rod along
    crank tip -> platform joint by the smallest rotation from its home direction (no spin, so
    the ball quaternion equals Drake's rpy), platform at x. Ends with ``mj_forward``.
    Args:
        model, data: of :func:`load_model` (``mujoco.MjModel``, ``mujoco.MjData``).
        geometry: the robot the model was written from (None: the reference robot).
        x: (6,) pose [phi, theta, psi, X, Y, Z] in rad and m.
    Returns:
        (6,) motor angles in rad.
    Raises:
        UnreachablePoseError: x cannot be reached (names the leg).
    """
    from pydrake.math import RollPitchYaw

    from ..robot import kinematics

    mujoco = import_mujoco()
    g = geometry or StewartGeometry()
    x = np.asarray(x, dtype=float)
    theta = kinematics.ik(g, x)
    mujoco.mj_resetData(model, data)  # qpos0: home; velocities 0
    data.qpos[_qpos_addresses(model, "motor_")] = theta
    free = int(model.joint("platform").qposadr[0])
    q = RollPitchYaw(x[:3]).ToQuaternion()
    data.qpos[free : free + 7] = [*x[3:], q.w(), q.x(), q.y(), q.z()]
    balls = _qpos_addresses(model, "rod_ball_")
    for adr in balls:
        data.qpos[adr : adr + 4] = [1.0, 0.0, 0.0, 0.0]
    mujoco.mj_kinematics(model, data)  # rod frames F at ball = identity
    q_B, _ = kinematics.platform_joints(g, x)
    ell = q_B - g.crank_tips(theta)
    for i, adr in enumerate(balls):
        R_WF = data.xmat[model.body(f"rod_{i}").id].reshape(3, 3)
        quat = np.empty(4)
        mujoco.mju_quatZ2Vec(quat, R_WF.T @ ell[i])  # smallest rotation z -> rod in F
        data.qpos[adr : adr + 4] = quat
    mujoco.mj_forward(model, data)
    return theta


def loop_closure_errors(model, data) -> np.ndarray:
    """(6,) distance in m between each rod's top end and its platform joint (0 when closed)."""
    top = [model.site(f"rod_top_{i}").id for i in range(6)]
    joint = [model.site(f"platform_joint_{i}").id for i in range(6)]
    return np.linalg.norm(data.site_xpos[top] - data.site_xpos[joint], axis=1)


def platform_pose(model, data) -> np.ndarray:
    """(6,) platform pose [phi, theta, psi, X, Y, Z] (rad, m), Drake's roll-pitch-yaw."""
    from pydrake.math import RollPitchYaw, RotationMatrix

    body = model.body("platform").id
    R = RotationMatrix(data.xmat[body].reshape(3, 3).copy())
    return np.concatenate([RollPitchYaw(R).vector(), data.xpos[body]])


def motor_angles(model, data) -> np.ndarray:
    """(6,) motor angles theta_i in rad (hinge ``motor_i`` positions)."""
    return data.qpos[_qpos_addresses(model, "motor_")].copy()


def encoder_angles(model, data, quantum_rad: float) -> np.ndarray:
    """(6,) motor angles in rad as the encoders read them: sensors ``encoder_i`` of a model
    written with a servo, rounded to whole counts of ``quantum_rad`` (rad per count, > 0).

    Raises:
        InvalidConfigError: no encoder sensors (the ideal robot), or a quantum out of range.
    """
    if not (np.isfinite(quantum_rad) and quantum_rad > 0):
        raise InvalidConfigError(
            f"quantum_rad must be a finite number of rad > 0, got {quantum_rad}"
        )
    try:
        adr = [int(model.sensor(f"encoder_{i}").adr[0]) for i in range(6)]
    except KeyError:
        raise InvalidConfigError(
            "the model has no encoders: write it with a servo (write_mjcf(servo=...))"
        ) from None
    return np.round(data.sensordata[adr] / quantum_rad) * quantum_rad
