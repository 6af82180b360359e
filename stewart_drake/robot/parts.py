"""The robot's solid parts: what is drawn and what collides, sized as a buildable robot.

One table (:func:`robot_parts`) feeds the SDF's ``<visual>`` and ``<collision>`` elements
(:func:`~.sdf.write_sdf`) and, through the Drake plant, the MJCF's geoms (:mod:`~.mjcf`), so
what is seen, what Drake's ``SceneGraph`` measures and what MuJoCo collides are one set of
shapes. The kinematic layout is ``docs/reference_geometry.md``'s and is not changed here; the
parts around it are ours: the base's hub (``base_plate_radius``) and arms, the motor brackets
and housings, the cranks (capsules of radius :data:`CRANK_RADIUS`), the rods (``rod_radius``)
between their rod ends (spheres of ``rod_end_radius``), the platform's plate
(``platform_plate_radius``) and the tool. Their sizes, the reasons and the measured clearances:
docs/reference_geometry.md, "Parts and clearance".

Frames are the SDF's link frames: base = world (origin at the centre of the hub's top face);
crank_i at the pivot P_i, x along the crank, y = -u_i; rod_i at the crank tip, z along the rod;
platform = E.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .geometry import StewartGeometry
from .statics import p_ETool

#: Thickness of the base plate and of its arms, m (top face at z = 0).
BASE_THICKNESS = 0.02
#: Half-width of each base arm, m: it passes between the two cranks of a pair, whose hubs are
#: 2 x 0.0347 m apart at the reference robot (11 mm of clearance to a crank at its sweep).
ARM_HALF_WIDTH = 0.015
#: Crank arm: capsule radius, m, and the offset of its mid-plane from the joint plane, along the
#: motor's side of the shaft, m (the rod end's ball, rod_end_radius, sits in the joint plane).
CRANK_RADIUS = 0.004
CRANK_OFFSET = 0.011
#: Motor bracket: plate thickness, width and the offset of its inner face from the joint plane, m.
BRACKET_THICKNESS = 0.008
BRACKET_WIDTH = 0.06
BRACKET_OFFSET = 0.016
#: Motor + gearhead housing: radius and length, m (EC 45 flat 42.9 mm, GP 42 C 42 mm; 21 + 54 mm).
MOTOR_RADIUS = 0.0215
MOTOR_LENGTH = 0.075
#: Platform plate: thickness, m, and the gap between a rod end's ball and its underside, m.
PLATFORM_THICKNESS = 0.01
PLATFORM_GAP = 0.005
#: Tool: radius, m (it reaches the tool tip :data:`~.statics.p_ETool`).
TOOL_RADIUS = 0.006
#: Gap between a rod end's ball and the start of the rod's tube, m.
TUBE_GAP = 0.008

#: Colours (RGBA) of the part families.
COLOURS = {
    "base": (0.55, 0.55, 0.6, 1.0),
    "motor": (0.2, 0.2, 0.25, 1.0),
    "crank": (0.85, 0.45, 0.1, 1.0),
    "rod": (0.75, 0.75, 0.8, 1.0),
    "rod_end": (0.1, 0.3, 0.8, 1.0),
    "platform": (0.2, 0.6, 0.3, 1.0),
    "tool": (0.9, 0.1, 0.1, 1.0),
}


@dataclass(frozen=True)
class Part:
    """One solid shape attached to a link.

    Attributes:
        link: the SDF link ("base", "crank_i", "rod_i", "platform").
        name: the shape's name within the link (unique there), e.g. "tube", "motor_3".
        shape: "box" (size = 3 full lengths), "cylinder" (radius, length), "capsule" (radius,
            length of the cylindrical part), "sphere" (radius); m. Cylinder and capsule axes
            along the shape frame's z.
        size: the shape's dimensions, m.
        p_LG: (3,) origin of the shape frame G in the link frame L, m.
        R_LG: (3, 3) orientation of G in L.
        colour: RGBA. collides: registered as collision geometry (else drawn only).
    """

    link: str
    name: str
    shape: str
    size: tuple
    p_LG: np.ndarray
    R_LG: np.ndarray
    colour: tuple
    collides: bool = True

    @property
    def family(self) -> str:
        """The part's kind without its leg number, e.g. "rod tube", "base motor" (reports)."""
        link = self.link.rstrip("0123456789").rstrip("_")
        return f"{link} {self.name.rstrip('0123456789').rstrip('_')}"


def _frame_with_z(axis) -> np.ndarray:
    """A rotation (3, 3) whose z column is the unit vector ``axis``."""
    z = np.asarray(axis, dtype=float) / np.linalg.norm(axis)
    helper = np.array([1.0, 0.0, 0.0]) if abs(z[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    x = np.cross(helper, z)
    x /= np.linalg.norm(x)
    return np.column_stack([x, np.cross(z, x), z])


def motor_outward(geometry: StewartGeometry) -> np.ndarray:
    """(6, 3) unit shaft directions o_i = +-u_i pointing from the joint plane to the motor: the
    one with a positive radial component (the rods run inward, so the motor sits outboard)."""
    u = geometry.u_B
    radial = np.sum(u * geometry.P_B, axis=1)
    return u * np.where(radial >= 0, 1.0, -1.0)[:, None]


def robot_parts(geometry: StewartGeometry | None = None) -> list[Part]:
    """Every solid part of the robot, in link frames (module docstring).

    Returns:
        list of :class:`Part`, links in SDF order (base, then crank_i and rod_i per leg, then
        the platform).
    """
    g = geometry or StewartGeometry()
    outward = motor_outward(g)
    parts = _base_parts(g, outward)
    for i in range(6):
        parts += _leg_parts(g, outward, i)
    return parts + _platform_parts(g)


def _base_parts(g: StewartGeometry, outward: np.ndarray) -> list[Part]:
    """The base's parts: hub, one arm per leg pair, a bracket and a motor per leg (``outward``:
    :func:`motor_outward`)."""
    parts = [
        Part(
            "base",
            "plate",
            "cylinder",
            (g.base_plate_radius, BASE_THICKNESS),
            np.array([0.0, 0.0, -BASE_THICKNESS / 2]),
            np.eye(3),
            COLOURS["base"],
        )
    ]
    bracket_reach = BRACKET_OFFSET + BRACKET_THICKNESS
    for k in range(3):
        pair = slice(2 * k, 2 * k + 2)
        direction = np.sum(g.P_B[pair, :2], axis=0)
        direction /= np.linalg.norm(direction)
        # The arm reaches the brackets' outer faces (measured along the arm's direction).
        reach = float(
            np.max(
                g.P_B[pair, :2] @ direction + bracket_reach * np.abs(outward[pair, :2] @ direction)
            )
        )
        R = np.column_stack(
            [[direction[0], direction[1], 0.0], [-direction[1], direction[0], 0.0], [0.0, 0.0, 1.0]]
        )
        parts.append(
            Part(
                "base",
                f"arm_{k}",
                "box",
                (reach, 2 * ARM_HALF_WIDTH, BASE_THICKNESS),
                np.array([reach / 2 * direction[0], reach / 2 * direction[1], -BASE_THICKNESS / 2]),
                R,
                COLOURS["base"],
            )
        )
    for i in range(6):
        parts += _motor_parts(g, outward[i], i)
    return parts


def _motor_parts(g: StewartGeometry, o: np.ndarray, i: int) -> list[Part]:
    """Leg i's motor bracket and motor housing on the base, the motor along ``o`` (its shaft
    direction from the joint plane, :func:`motor_outward`)."""
    P = g.P_B[i]
    t = np.cross([0.0, 0.0, 1.0], o)
    t = t / np.linalg.norm(t)
    # A tilted shaft (o_z != 0) turns the bracket with it, about t: its frame stays orthonormal.
    R = np.column_stack([o, t, [0.0, 0.0, 1.0] if o[2] == 0.0 else np.cross(o, t)])
    # The bracket hangs from the arm's underside to 5 mm below the motor or, for a motor
    # whose housing reaches above that underside (a design with the shafts high), stands
    # on the arm's top face up to 5 mm above it.
    bottom = P[2] - MOTOR_RADIUS - 0.005
    if bottom < -BASE_THICKNESS:
        z_lo, z_hi = bottom, -BASE_THICKNESS
    else:
        z_lo, z_hi = 0.0, max(P[2] + MOTOR_RADIUS + 0.005, 0.005)
    centre = P + o * (BRACKET_OFFSET + BRACKET_THICKNESS / 2)
    bracket_reach = BRACKET_OFFSET + BRACKET_THICKNESS
    return [
        Part(
            "base",
            f"bracket_{i}",
            "box",
            (BRACKET_THICKNESS, BRACKET_WIDTH, z_hi - z_lo),
            np.array([centre[0], centre[1], 0.5 * (z_lo + z_hi)]),
            R,
            COLOURS["base"],
        ),
        Part(
            "base",
            f"motor_{i}",
            "cylinder",
            (MOTOR_RADIUS, MOTOR_LENGTH),
            P + o * (bracket_reach + MOTOR_LENGTH / 2),
            _frame_with_z(o),
            COLOURS["motor"],
        ),
    ]


def _leg_parts(g: StewartGeometry, outward: np.ndarray, i: int) -> list[Part]:
    """Leg i's crank arm and its rod: tube and the two rod ends."""
    a, s = float(g.crank_lengths[i]), float(g.rod_lengths[i])
    eye = np.eye(3)
    # Crank frame: y = -u_i; the motor side o_i = +-u_i is -+y.
    side = -1.0 if np.dot(outward[i], g.u_B[i]) > 0 else 1.0
    r_end, r_rod = g.rod_end_radius, g.rod_radius
    start = r_end + TUBE_GAP
    return [
        Part(
            f"crank_{i}",
            "arm",
            "capsule",
            (CRANK_RADIUS, a),
            np.array([a / 2, side * CRANK_OFFSET, 0.0]),
            _frame_with_z([1, 0, 0]),
            COLOURS["crank"],
        ),
        Part(
            f"rod_{i}",
            "tube",
            "capsule",
            (r_rod, s - 2 * start - 2 * r_rod),
            np.array([0.0, 0.0, s / 2]),
            eye,
            COLOURS["rod"],
        ),
        Part(f"rod_{i}", "end_bottom", "sphere", (r_end,), np.zeros(3), eye, COLOURS["rod_end"]),
        Part(
            f"rod_{i}",
            "end_top",
            "sphere",
            (r_end,),
            np.array([0.0, 0.0, s]),
            eye,
            COLOURS["rod_end"],
        ),
    ]


def _platform_parts(g: StewartGeometry) -> list[Part]:
    """The platform's plate, the sockets' studs (drawn only) and the tool."""
    eye = np.eye(3)
    plate_bottom = g.rod_end_radius + PLATFORM_GAP
    parts = [
        Part(
            "platform",
            "plate",
            "cylinder",
            (g.platform_plate_radius, PLATFORM_THICKNESS),
            np.array([0.0, 0.0, plate_bottom + PLATFORM_THICKNESS / 2]),
            eye,
            COLOURS["platform"],
        )
    ]
    for i in range(6):
        parts.append(
            Part(
                "platform",
                f"stud_{i}",
                "cylinder",
                (0.004, plate_bottom),
                g.p_E[i] + [0.0, 0.0, plate_bottom / 2],
                eye,
                COLOURS["platform"],
                collides=False,
            )
        )
    tool_start = plate_bottom + PLATFORM_THICKNESS
    parts.append(
        Part(
            "platform",
            "tool",
            "cylinder",
            (TOOL_RADIUS, p_ETool[2] - tool_start),
            np.array([0.0, 0.0, 0.5 * (p_ETool[2] + tool_start)]),
            eye,
            COLOURS["tool"],
        )
    )
    return parts
