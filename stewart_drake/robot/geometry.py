"""Geometry and inertial parameters of the rotary Stewart platform.

The default :class:`StewartGeometry` is exactly ``docs/reference_geometry.md``: the layout
the paper leaves open, with the paper's Table I masses and inertias. Frames: world = base frame B
(origin at the centre of the base plate's top face, z up); platform frame E (origin at the centre
of the circle of platform joints). Leg index i = 2k + (s+1)/2, k = 0, 1, 2, s = -1, +1.

Each leg may deviate from the drawing (the robot as built, or as a calibration found it): its
pivot and platform joint moved, its crank and rod lengths, its motor shaft tilted, its encoder's
zero (the optional per-leg fields, None for the drawing's value; docs/robot.md, "Per-leg
geometry"). Every consumer reads the per-leg arrays (:attr:`StewartGeometry.P_B`, ``p_E``,
``w_B``, ``u_B``, ``crank_lengths``, ``rod_lengths``, ``encoder_offsets``), which for the
symmetric robot hold the drawing's values exactly.

Its lengths hold at one temperature, ``lengths_at_c``; :meth:`StewartGeometry.at_temperature`
gives the robot at another, its rods and the rest of its kinematic loop scaled by their linear
expansion (docs/robot.md, "Temperature").
"""

from __future__ import annotations

import dataclasses
import functools
from dataclasses import dataclass, field

import numpy as np

from ..base.checks import as_array, as_number
from ..base.errors import InvalidGeometryError
from .kinematics import X_HOME, leg_reach_ratio
from .limits import LIMITS, limit_margins

#: Table I of the paper, principal moments about the COM in kg m^2, as printed.
TABLE_I_CRANK_INERTIA = (1e-6, 5.8e-5, 6e-5)

#: Largest |component| of a per-leg joint offset (``pivot_offsets_m``, ``platform_offsets_m``),
#: m: a build or calibration error, not a design change (move the anchors' radii or angles).
MAX_JOINT_OFFSET_M = 0.005
#: Largest |tilt| of a motor shaft about its crank direction (``shaft_tilts_rad``), rad.
MAX_SHAFT_TILT_RAD = 0.1
#: Largest |zero error| of an encoder (``encoder_offsets_rad``), rad: beyond it, zero the
#: encoder again.
MAX_ENCODER_OFFSET_RAD = 0.1
#: The per-leg fields of :class:`StewartGeometry`: name -> (shape, largest |value| or None
#: for a length, which must be > 0, what to do beyond that bound).
PER_LEG_FIELDS = {
    "pivot_offsets_m": ((6, 3), MAX_JOINT_OFFSET_M, "move the pivots by base_radius, pivot_z"),
    "platform_offsets_m": ((6, 3), MAX_JOINT_OFFSET_M, "move the joints by platform_radius"),
    "crank_lengths_m": ((6,), None, ""),
    "rod_lengths_m": ((6,), None, ""),
    "shaft_tilts_rad": ((6,), MAX_SHAFT_TILT_RAD, "a shaft tilted that far is another design"),
    "encoder_offsets_rad": ((6,), MAX_ENCODER_OFFSET_RAD, "zero the encoder again"),
}

#: The temperature a drawing's lengths hold at unless it says otherwise, degrees C: ISO 1's
#: reference temperature for geometrical product specifications.
REFERENCE_TEMPERATURE_C = 20.0
#: Linear expansion coefficient of aluminium alloys near room temperature, 1/K (6061: 23.6e-6,
#: 7075: 23.4e-6, 2024: 23.2e-6; the handbooks' round figure).
ALUMINIUM_EXPANSION_PER_K = 23e-6
#: The temperatures a robot's lengths may hold at, or a run may take, degrees C.
TEMPERATURE_RANGE_C = (-50.0, 150.0)
#: The linear expansion coefficients a part may have, 1/K: from carbon fibre along its fibres
#: (about -1e-6) past invar (1.2e-6) and the metals to filled plastics (PLA about 7e-5).
EXPANSION_RANGE_PER_K = (-2e-5, 2e-4)


def nearest_valid_principal_moments(moments, margin: float = 1e-9) -> tuple[float, float, float]:
    """Nearest principal moments (Euclidean norm) that satisfy the triangle inequality.

    Args:
        moments: (3,) principal moments of inertia about the COM, kg m^2.
        margin: slack in kg m^2 kept above equality so that rounding cannot fail Drake's check.
    Returns:
        (3,) moments, unchanged if already valid. For Table I's crank (1e-6, 5.8e-5, 6e-5), whose
        Ixx + Iyy < Izz, the deficit is spread equally: (1.334e-6, 5.8334e-5, 5.9666e-5).
    Source: paper Table I fails ``RotationalInertia.CouldBePhysicallyValid``; docs/paper_notes.md.
    """
    m = as_array("principal moments", moments, shape=(3,), error=InvalidGeometryError).copy()
    if np.any(m < 0):
        raise InvalidGeometryError(f"principal moments must be 3 finite values >= 0, got {moments}")
    for _ in range(3):  # each projection fixes the largest violation; at most three are needed
        deficits = np.array([m[1] + m[2] - m[0], m[0] + m[2] - m[1], m[0] + m[1] - m[2]])
        j = int(np.argmin(deficits))
        if deficits[j] >= margin:
            break
        # Project onto the half-space sum_k sign_k m_k >= margin, normal n with n[j] = -1.
        n = np.ones(3)
        n[j] = -1.0
        m += n * (margin - deficits[j]) / 3.0
    return float(m[0]), float(m[1]), float(m[2])


def _ring(radius: float, angles_deg, z: float = 0.0) -> np.ndarray:
    a = np.deg2rad(np.asarray(angles_deg, dtype=float))
    return np.stack([radius * np.cos(a), radius * np.sin(a), np.full_like(a, z)], axis=1)


def _frozen(a: np.ndarray) -> np.ndarray:
    """Read-only array: the geometry caches its anchors, so callers must not mutate them."""
    a.setflags(write=False)
    return a


def _leg_angles(spread_deg: float) -> tuple[float, ...]:
    """Angles 120 k + spread * s in leg order i = 2k + (s+1)/2, degrees."""
    return tuple(120.0 * k + spread_deg * s for k in range(3) for s in (-1, 1))


#: The largest length (m) and mass (kg) a robot's field may take.
MAX_LENGTH_M = 100.0
MAX_MASS_KG = 1e5


@dataclass(frozen=True)
class StewartGeometry:
    """Layout, link lengths and inertias of a 6-RSS rotary Stewart platform; SI units, angles
    of the layout in degrees. Defaults: ``reference_geometry.md`` (limits: "Joint limits").

    Attributes:
        base_radius: radius of the circle of crank pivots P_i, m.
        pivot_z: height of the motor shafts in the base frame, m (negative: under the plate).
        pivot_angles_deg: (6,) b_i, azimuth of P_i.
        platform_radius: radius of the circle of platform joints p_i, m.
        platform_angles_deg: (6,) c_i, azimuth of p_i in E.
        crank_angles_deg: (6,) beta_i, azimuth of the crank direction d_i at theta_i = 0.
        crank_length: a, pivot to crank-tip joint, m. rod_length: s, joint centre to joint
            centre, m.
        *_mass: kg. *_inertia: principal moments about the COM, kg m^2, body axes of
            reference_geometry.md (rod: z along the rod; crank: x along the crank).
        gravity: magnitude of g, m/s^2, acting along -z.
        motor_angle_min_deg, motor_angle_max_deg: motor travel, deg, theta_i in [-180, 180).
        crank_joint_cone_deg: largest tilt asin |e_rod . u_i| of the rod out of its crank's
            plane, deg.
        platform_joint_cone_deg: cone half-angle of the ball sockets about the rods at home, deg.
        base_plate_radius: radius of the base's hub, m (:mod:`~.parts`; not kinematic).
        rod_radius: radius of the rods' tubes, m. rod_end_radius: radius of the spheres that
            stand for the rod ends at the joint centres, m.
        platform_plate_radius: radius of the platform's plate, m (above the joint centres).
        motor_reflected_inertia: rotor inertia x gear ratio^2 of each motor at its crank shaft,
            kg m^2; 0 for ideal torque sources.
    Temperature (docs/robot.md, "Temperature"; :meth:`at_temperature`):
        lengths_at_c: the temperature every length of the kinematic loop holds at, degrees C
            (default :data:`REFERENCE_TEMPERATURE_C`; a calibration writes the temperature of
            its measurements), in :data:`TEMPERATURE_RANGE_C`.
        rod_expansion_per_k: linear expansion coefficient of the rods, joint centre to joint
            centre, 1/K (default :data:`ALUMINIUM_EXPANSION_PER_K`).
        frame_expansion_per_k: that of the rest of the loop, 1/K: the cranks, the pivots'
            ring and height (the base and the motors' brackets) and the platform joints' ring
            (default aluminium too). Both in :data:`EXPANSION_RANGE_PER_K`.
    Per leg (None: every leg as drawn; docs/robot.md, "Per-leg geometry"):
        pivot_offsets_m: (6, 3) added to the pivots P_i, frame B, m (<= :data:`MAX_JOINT_OFFSET_M`).
        platform_offsets_m: (6, 3) added to the platform joints p_i, frame E, m (same bound).
        crank_lengths_m: (6,) each leg's crank length a_i, m (centre of mass at a_i / 2).
        rod_lengths_m: (6,) each leg's rod length s_i, m (mass and inertia as drawn).
        shaft_tilts_rad: (6,) rotation t_i of leg i's crank plane about d_i, rad, |t_i| <=
            :data:`MAX_SHAFT_TILT_RAD`: w_i = cos t z + sin t (d_i x z), shaft u_i = d_i x w_i.
        encoder_offsets_rad: (6,) encoder i reads theta_i + offset_i, rad, |offset_i| <=
            :data:`MAX_ENCODER_OFFSET_RAD`.
    Raises:
        InvalidGeometryError: naming the field to change: a non-positive or non-finite length
            or mass, a wrong count, an inertia failing the triangle inequality (use
            :func:`nearest_valid_principal_moments`), a per-leg value of the wrong shape or past
            its bound, legs that cannot close at home, or home outside a joint limit.
    """

    base_radius: float = 0.20
    pivot_z: float = -0.07
    pivot_angles_deg: tuple[float, ...] = field(default_factory=lambda: _leg_angles(10.0))
    platform_radius: float = 0.11
    platform_angles_deg: tuple[float, ...] = field(default_factory=lambda: _leg_angles(55.0))
    crank_angles_deg: tuple[float, ...] = field(default_factory=lambda: _leg_angles(90.0))
    crank_length: float = 0.11
    rod_length: float = 0.404
    rod_mass: float = 0.08
    rod_inertia: tuple[float, float, float] = (0.0016, 0.0016, 0.000001)
    crank_mass: float = 0.04
    crank_inertia: tuple[float, float, float] = field(
        default_factory=lambda: nearest_valid_principal_moments(TABLE_I_CRANK_INERTIA)
    )
    platform_mass: float = 1.0
    platform_inertia: tuple[float, float, float] = (0.003, 0.003, 0.006)
    base_mass: float = 7.0
    base_inertia: tuple[float, float, float] = (0.027, 0.027, 0.054)
    base_plate_radius: float = 0.125
    rod_radius: float = 0.005
    rod_end_radius: float = 0.007
    platform_plate_radius: float = 0.125
    gravity: float = 9.81
    motor_angle_min_deg: float = -90.0
    motor_angle_max_deg: float = 90.0
    crank_joint_cone_deg: float = 35.0
    platform_joint_cone_deg: float = 40.0
    motor_reflected_inertia: float = 0.0
    lengths_at_c: float = REFERENCE_TEMPERATURE_C
    rod_expansion_per_k: float = ALUMINIUM_EXPANSION_PER_K
    frame_expansion_per_k: float = ALUMINIUM_EXPANSION_PER_K
    pivot_offsets_m: tuple[tuple[float, float, float], ...] | None = None
    platform_offsets_m: tuple[tuple[float, float, float], ...] | None = None
    crank_lengths_m: tuple[float, ...] | None = None
    rod_lengths_m: tuple[float, ...] | None = None
    shaft_tilts_rad: tuple[float, ...] | None = None
    encoder_offsets_rad: tuple[float, ...] | None = None

    def __post_init__(self):
        self._check_numbers()
        self._check_tuples()
        self._check_per_leg()
        self._check_ranges()
        self._check_home()

    def _check_numbers(self) -> None:
        """Each scalar field a finite number (lengths and masses > 0, gravity >= 0), stored as
        a float."""
        object.__setattr__(
            self,
            "motor_reflected_inertia",
            as_number(
                "motor_reflected_inertia",
                self.motor_reflected_inertia,
                0.0,
                error=InvalidGeometryError,
            ),
        )
        # Beyond any Stewart platform built (a motion simulator's is some 10 m and 10 t), and
        # far inside what Drake's dynamics can hold without overflow (a mass of 1e308 kg
        # crashed it).
        largest = {"m": MAX_LENGTH_M, "kg": MAX_MASS_KG}
        for name, unit in (
            ("base_radius", "m"),
            ("platform_radius", "m"),
            ("crank_length", "m"),
            ("rod_length", "m"),
            ("rod_mass", "kg"),
            ("crank_mass", "kg"),
            ("platform_mass", "kg"),
            ("base_mass", "kg"),
            ("base_plate_radius", "m"),
            ("rod_radius", "m"),
            ("rod_end_radius", "m"),
            ("platform_plate_radius", "m"),
        ):
            object.__setattr__(
                self,
                name,
                as_number(
                    name,
                    getattr(self, name),
                    0.0,
                    largest[unit],
                    lo_open=True,
                    error=InvalidGeometryError,
                ),
            )
        for name, lo in (("gravity", 0.0), ("pivot_z", None)):
            object.__setattr__(
                self, name, as_number(name, getattr(self, name), lo, error=InvalidGeometryError)
            )
        for name in (
            "motor_angle_min_deg",
            "motor_angle_max_deg",
            "crank_joint_cone_deg",
            "platform_joint_cone_deg",
        ):
            object.__setattr__(
                self, name, as_number(name, getattr(self, name), error=InvalidGeometryError)
            )
        for name, (lo, hi) in (
            ("lengths_at_c", TEMPERATURE_RANGE_C),
            ("rod_expansion_per_k", EXPANSION_RANGE_PER_K),
            ("frame_expansion_per_k", EXPANSION_RANGE_PER_K),
        ):
            object.__setattr__(
                self, name, as_number(name, getattr(self, name), lo, hi, error=InvalidGeometryError)
            )
        if self.rod_length <= self.crank_length:
            raise InvalidGeometryError(
                f"rod_length ({self.rod_length} m) must exceed crank_length ({self.crank_length} m)"
            )

    def _check_tuples(self) -> None:
        """The layout's six angles and each body's three principal moments (positive, a rigid
        body's), stored as tuples of floats."""
        for name in ("pivot_angles_deg", "platform_angles_deg", "crank_angles_deg"):
            angles = as_array(name, getattr(self, name), shape=(6,), error=InvalidGeometryError)
            object.__setattr__(self, name, tuple(float(v) for v in angles))
        for name in ("rod_inertia", "crank_inertia", "platform_inertia", "base_inertia"):
            moments = as_array(name, getattr(self, name), shape=(3,), error=InvalidGeometryError)
            if np.any(moments <= 0):
                raise InvalidGeometryError(
                    f"{name} needs 3 positive moments, got {moments.tolist()}"
                )
            a, b, c = moments
            if a + b < c * (1 - 1e-12) or a + c < b * (1 - 1e-12) or b + c < a * (1 - 1e-12):
                fix = nearest_valid_principal_moments(moments)
                raise InvalidGeometryError(
                    f"{name} = {moments.tolist()} kg m^2 fails the triangle inequality "
                    f"(no rigid body has it); the nearest valid one is {list(fix)}"
                )
            object.__setattr__(self, name, tuple(float(v) for v in moments))

    def _check_per_leg(self) -> None:
        """Each per-leg field None or its shape of finite numbers within its bound (lengths
        > 0, each rod longer than its crank), stored as (nested) tuples of floats."""
        for name, (shape, bound, remedy) in PER_LEG_FIELDS.items():
            value = getattr(self, name)
            if value is None:
                continue
            a = as_array(name, value, shape=shape, error=InvalidGeometryError)
            if bound is None and np.any(a <= 0):
                leg = int(np.argmin(a))
                raise InvalidGeometryError(f"{name}[{leg}] = {a[leg]} m: every length must be > 0")
            if bound is not None and np.any(np.abs(a) > bound):
                index = tuple(int(k) for k in np.argwhere(np.abs(a) > bound)[0])
                raise InvalidGeometryError(
                    f"{name}{list(index)} = {a[index]:.6g} is beyond +-{bound:g}, the bound of "
                    f"one leg's deviation from the drawing: {remedy}"
                )
            rows = a.tolist()  # Python floats
            object.__setattr__(self, name, tuple(map(tuple, rows)) if a.ndim == 2 else tuple(rows))
        short = self.rod_lengths <= self.crank_lengths
        if np.any(short):
            leg = int(np.argmax(short))
            raise InvalidGeometryError(
                f"leg {leg}'s rod ({self.rod_lengths[leg]} m) must exceed its crank "
                f"({self.crank_lengths[leg]} m): change rod_lengths_m or crank_lengths_m"
            )

    def _check_ranges(self) -> None:
        """The motor travel and the ball joints' cones."""
        lo, hi = self.motor_angle_min_deg, self.motor_angle_max_deg
        if not (np.isfinite(lo) and np.isfinite(hi) and -180.0 <= lo < hi <= 180.0):
            raise InvalidGeometryError(
                f"motor angle range [{lo}, {hi}] deg must satisfy -180 <= min < max <= 180"
            )
        for name in ("crank_joint_cone_deg", "platform_joint_cone_deg"):
            value = getattr(self, name)
            if not (np.isfinite(value) and 0.0 < value <= 90.0):
                raise InvalidGeometryError(f"{name} must be in (0, 90] degrees, got {value}")

    def _check_home(self) -> None:
        """Every leg closes at the home pose, inside every joint limit."""
        # Assembly at home must be possible, or nothing downstream can work.
        ratio = leg_reach_ratio(self, X_HOME)
        if np.any(~np.isfinite(ratio)) or np.any(np.abs(ratio) > 1):
            leg = int(np.argmax(np.where(np.isfinite(ratio), np.abs(ratio), np.inf)))
            raise InvalidGeometryError(
                f"leg {leg} cannot close at the home pose {X_HOME.tolist()}: "
                f"|L|/sqrt(M^2+N^2) = {abs(ratio[leg]):.4g} > 1; change the rod or crank length "
                f"(rod_lengths_m, crank_lengths_m for one leg) or the anchor radii"
            )
        margins = limit_margins(self, X_HOME)
        for name in LIMITS[1:]:
            if np.any(margins[name] < 0):
                leg = int(np.argmin(margins[name]))
                raise InvalidGeometryError(
                    f"the home pose violates the {name} limit of leg {leg} by "
                    f"{np.rad2deg(-margins[name][leg]):.3g} deg; widen that limit"
                )

    def replace(self, **changes) -> StewartGeometry:
        """A copy with some fields changed (validated again)."""
        return dataclasses.replace(self, **changes)

    def at_temperature(self, temperature_c: float) -> StewartGeometry:
        """This robot at ``temperature_c``: each rod's length times 1 + ``rod_expansion_per_k``
        (T - ``lengths_at_c``), and every other length of the loop (the cranks, the pivots'
        ring, height and offsets, the platform joints' ring and offsets) times 1 +
        ``frame_expansion_per_k`` (T - ``lengths_at_c``); angles, masses, inertias and the
        parts' sizes unchanged (an inertia changes by 2 alpha dT, 5e-4 at 10 K on aluminium).
        Its ``lengths_at_c`` becomes ``temperature_c``.

        With both coefficients equal the robot is scaled about the base frame's origin: the
        motor angles of a pose are those of the robot at ``lengths_at_c`` with the pose's
        position scaled alike, and the orientation unchanged. Going from T0 to T1, then to T2,
        differs from going to T2 at once by alpha^2 (T1 - T0)(T2 - T1), a few 1e-8 of each length.

        Args:
            temperature_c: degrees C, in :data:`TEMPERATURE_RANGE_C`.
        Returns:
            the geometry, validated; this very geometry when ``temperature_c`` is its
            ``lengths_at_c`` (nothing is recomputed, to the bit).
        Raises:
            InvalidGeometryError: a temperature out of range or not a number, or a robot that
                scaled no longer closes at home (names the field).
        """
        t = as_number(
            "temperature_c", temperature_c, *TEMPERATURE_RANGE_C, error=InvalidGeometryError
        )
        if t == self.lengths_at_c:
            return self
        rod = 1.0 + self.rod_expansion_per_k * (t - self.lengths_at_c)
        frame = 1.0 + self.frame_expansion_per_k * (t - self.lengths_at_c)

        def scaled(value, k):
            if value is None:
                return None
            a = np.asarray(value, dtype=float) * k
            return tuple(map(tuple, a.tolist())) if a.ndim == 2 else tuple(a.tolist())

        return self.replace(
            lengths_at_c=t,
            rod_length=self.rod_length * rod,
            rod_lengths_m=scaled(self.rod_lengths_m, rod),
            crank_length=self.crank_length * frame,
            crank_lengths_m=scaled(self.crank_lengths_m, frame),
            base_radius=self.base_radius * frame,
            pivot_z=self.pivot_z * frame,
            pivot_offsets_m=scaled(self.pivot_offsets_m, frame),
            platform_radius=self.platform_radius * frame,
            platform_offsets_m=scaled(self.platform_offsets_m, frame),
        )

    @property
    def symmetric(self) -> bool:
        """Whether every per-leg field is None: the robot as drawn."""
        return all(getattr(self, name) is None for name in PER_LEG_FIELDS)

    @functools.cached_property
    def P_B(self) -> np.ndarray:
        """(6, 3) crank pivots (motor shaft points) P_i in the base frame, m: the drawn ring
        plus ``pivot_offsets_m``."""
        P = _ring(self.base_radius, self.pivot_angles_deg, self.pivot_z)
        if self.pivot_offsets_m is not None:
            P = P + np.asarray(self.pivot_offsets_m)
        return _frozen(P)

    @functools.cached_property
    def p_E(self) -> np.ndarray:
        """(6, 3) platform joint centres p_i in the platform frame E, m: the drawn ring plus
        ``platform_offsets_m``."""
        p = _ring(self.platform_radius, self.platform_angles_deg)
        if self.platform_offsets_m is not None:
            p = p + np.asarray(self.platform_offsets_m)
        return _frozen(p)

    @functools.cached_property
    def crank_lengths(self) -> np.ndarray:
        """(6,) crank lengths a_i, m (``crank_lengths_m``, else ``crank_length`` for every
        leg)."""
        lengths = self.crank_lengths_m
        return _frozen(np.full(6, self.crank_length) if lengths is None else np.array(lengths))

    @functools.cached_property
    def rod_lengths(self) -> np.ndarray:
        """(6,) rod lengths s_i, m (``rod_lengths_m``, else ``rod_length`` for every leg)."""
        lengths = self.rod_lengths_m
        return _frozen(np.full(6, self.rod_length) if lengths is None else np.array(lengths))

    @functools.cached_property
    def shaft_inertias(self) -> np.ndarray:
        """(6,) each crank's inertia about its shaft with its motor's, kg m^2:
        ``crank_inertia[1]`` + ``crank_mass`` (a_i / 2)^2 + ``motor_reflected_inertia``."""
        return _frozen(
            np.array(
                [
                    self.crank_inertia[1]
                    + self.crank_mass * (0.5 * float(a)) ** 2
                    + self.motor_reflected_inertia
                    for a in self.crank_lengths
                ]
            )
        )

    @functools.cached_property
    def encoder_offsets(self) -> np.ndarray:
        """(6,) encoder zero errors, rad (``encoder_offsets_rad``, else zeros): encoder i reads
        theta_i + offset_i."""
        offsets = self.encoder_offsets_rad
        return _frozen(np.zeros(6) if offsets is None else np.array(offsets))

    @functools.cached_property
    def d_B(self) -> np.ndarray:
        """(6, 3) unit crank directions d_i at theta_i = 0, base frame."""
        return _frozen(_ring(1.0, self.crank_angles_deg))

    @functools.cached_property
    def w_B(self) -> np.ndarray:
        """(6, 3) unit second axes w_i of the crank planes, base frame: z_hat, turned by
        ``shaft_tilts_rad`` about d_i, w_i = cos t_i z_hat + sin t_i (d_i x z_hat); the crank
        tip is P_i + a_i (cos theta_i d_i + sin theta_i w_i)."""
        z = np.zeros((6, 3))
        z[:, 2] = 1.0
        if self.shaft_tilts_rad is None:
            return _frozen(z)
        t = np.asarray(self.shaft_tilts_rad)[:, None]
        return _frozen(np.cos(t) * z + np.sin(t) * np.cross(self.d_B, z))

    @functools.cached_property
    def u_B(self) -> np.ndarray:
        """(6, 3) unit motor shaft axes u_i = d_i x w_i (d_i x z_hat untilted); positive
        theta_i turns the crank from d_i towards w_i (raises the crank tip)."""
        return _frozen(np.cross(self.d_B, self.w_B))

    def crank_tips(self, theta) -> np.ndarray:
        """(..., 6, 3) crank-tip joint centres P_i + a_i (cos theta_i d_i + sin theta_i w_i)
        for motor angles theta (..., 6) in rad, base frame."""
        theta = np.asarray(theta, dtype=float)[..., None]
        return self.P_B + self.crank_lengths[:, None] * (
            np.cos(theta) * self.d_B + np.sin(theta) * self.w_B
        )


#: The reference robot of reference_geometry.md.
def reference_geometry() -> StewartGeometry:
    """The default robot, exactly ``docs/reference_geometry.md``."""
    return StewartGeometry()
