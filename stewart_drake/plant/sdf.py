"""The robot's SDF: written from a geometry, with Drake's ball constraints closing the loops.

Model: base welded to the world; six cranks on actuated revolute joints ``motor_i`` (axis u_i);
six rods on ball joints ``rod_ball_i`` at the crank tips; a floating platform; six
``drake:ball_constraint`` elements closing the loops (rod top end = platform joint p_i). Each
leg is written with its own pivot, shaft axis, crank and rod length and platform joint (the
geometry's per-leg arrays; docs/robot.md, "Per-leg geometry"). With
rods as distance constraints (:data:`ROD_MODELS`) the rods' links, joints and constraints are
left out and :func:`~.plant.add_stewart_plant` adds the constraints.

The SDF's zero configuration (all joint angles 0) is *not* assembled: the cranks are horizontal
there; :func:`~.plant.add_stewart_plant` sets the default joint positions to the home pose.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from pydrake.math import RollPitchYaw, RotationMatrix

from ..base.errors import InvalidConfigError
from ..robot import kinematics
from ..robot.geometry import X_HOME, StewartGeometry

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


def rod_zero_rotations(geometry: StewartGeometry) -> list[np.ndarray]:
    """R_B_rod at the SDF zero configuration, chosen so the ball joints read rpy = 0 at home.

    At home the rod's z is along the rod and its x along the part of the rod end's bolt axis
    u_i normal to the rod. Drake's BallRpyJoint is singular where the rod points along +-x of
    this frame, 90 - 19.4 = 70.6 deg out of the crank's plane at the reference robot: outside
    the rod end's cone (crank_joint_cone_deg), so |pitch| <= 90 - (70.6 - 35) = 54.4 deg at
    every pose inside the limits (stewart_drake/plant/ball_joints.py, docs/accuracy.md). The rod is
    axisymmetric, so this spin about its axis changes coordinates only, not the dynamics.

    Returns:
        6 rotation matrices (3, 3), leg order: R_B_rod_i at the zero configuration.
    """
    theta_home = kinematics.ik(geometry, X_HOME)
    q_B, _ = kinematics.platform_joints(geometry, X_HOME)
    tips = geometry.crank_tips(theta_home)
    rotations = []
    for i in range(6):
        u = geometry.u_B[i]
        z_rod = (q_B[i] - tips[i]) / geometry.rod_lengths[i]
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
            distance constraint; :func:`~.plant.add_stewart_plant` adds them), each rod's mass
            lumped half at its crank tip and half at its platform joint (:data:`ROD_MODELS`);
            the rods' shapes are then not written (their clearance is checked kinematically,
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
    from ..robot.parts import robot_parts

    check_rod_model(rod_model)
    g = geometry or StewartGeometry()
    bodies = rod_model == "bodies"
    m_end = 0.0 if bodies else g.rod_mass / 2  # each rod end's lumped mass, kg
    shapes: dict[str, list] = {}
    for part in robot_parts(g):
        shapes.setdefault(part.link, []).append(_part_xml(part, collision))
    out = [
        '<?xml version="1.0"?>',
        "<!-- Generated by stewart_drake.plant.sdf.write_sdf(); do not edit by hand. -->",
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
    rod_R0 = rod_zero_rotations(g)
    for i in range(6):
        out += _leg_xml(g, i, shapes, m_end, rod_R0[i] if bodies else None)
    out.append(
        f'    <link name="platform">\n      <pose>{_vec(X_HOME[3:])} '
        f"{_vec(X_HOME[:3])}</pose>\n"
        + _end_mass_inertial(g.platform_mass, g.platform_inertia, [0, 0, 0], m_end, g.p_E)
        + "".join(shapes["platform"])
        + "    </link>"
    )
    out += [_ball_constraint_xml(g, i) for i in range(6 if bodies else 0)]
    out += ["  </model>", "</sdf>", ""]
    return "\n".join(out)


def _leg_xml(g: StewartGeometry, i: int, shapes: dict, m_end: float, R0_rod) -> list[str]:
    """Leg i's SDF elements: crank link, motor joint and, with ``R0_rod`` (the rod's frame at
    the zero configuration, :func:`rod_zero_rotations`; None with rods as distance
    constraints), rod link and ball joint. ``shapes``: {link: its parts' XML}; ``m_end``: each
    rod end's lumped mass, kg. The crank's frame: at the pivot P_i, x along the crank d_i, y
    the shaft -u_i, z the crank plane's second axis w_i (z untilted)."""
    a, s = float(g.crank_lengths[i]), float(g.rod_lengths[i])
    d, u, w, P = g.d_B[i], g.u_B[i], g.w_B[i], g.P_B[i]
    R_crank = np.column_stack([d, -u, w])  # x along crank, y = shaft (-u)
    out = [
        f'    <link name="crank_{i}">\n      <pose>{_pose(P, R_crank)}</pose>\n'
        + _end_mass_inertial(g.crank_mass, g.crank_inertia, [a / 2, 0, 0], m_end, [[a, 0, 0]])
        + "".join(shapes[f"crank_{i}"])
        + "    </link>",
        f'    <joint name="motor_{i}" type="revolute">\n      <parent>base</parent>'
        f"<child>crank_{i}</child>\n"
        f'      <axis><xyz expressed_in="__model__">{_vec(u)}</xyz></axis>\n    </joint>',
    ]
    if R0_rod is None:
        return out
    return out + [
        f'    <link name="rod_{i}">\n      <pose>{_pose(P + a * d, R0_rod)}</pose>\n'
        + _inertial(g.rod_mass, g.rod_inertia, [0, 0, s / 2])
        + "".join(shapes[f"rod_{i}"])
        + "    </link>",
        f'    <joint name="rod_ball_{i}" type="ball"><parent>crank_{i}</parent>'
        f"<child>rod_{i}</child></joint>",
    ]


def _ball_constraint_xml(g: StewartGeometry, i: int) -> str:
    """The ``drake:ball_constraint`` closing leg i: rod i's top end on platform joint p_i."""
    return (
        "    <drake:ball_constraint>\n"
        f"      <drake:ball_constraint_body_A>rod_{i}</drake:ball_constraint_body_A>\n"
        "      <drake:ball_constraint_body_B>platform</drake:ball_constraint_body_B>\n"
        f"      <drake:ball_constraint_p_AP>0 0 {float(g.rod_lengths[i]):.12g}"
        "</drake:ball_constraint_p_AP>\n"
        f"      <drake:ball_constraint_p_BQ>{_vec(g.p_E[i])}</drake:ball_constraint_p_BQ>\n"
        "    </drake:ball_constraint>"
    )
