"""A robot's design: the few numbers a designer chooses, with their bounds, and the robot they make.

A :class:`Design` holds the layout of a 6-RSS rotary Stewart platform as a designer varies it
(link lengths, the two rings of anchors and their pair spacing, the cranks' direction, the home
height) and the motor, by name from :data:`~stewart_drake.robot.motor_catalogue.MOTOR_CATALOGUE`.
:meth:`Design.geometry` builds the :class:`~stewart_drake.robot.geometry.StewartGeometry` (from
which the SDF, the MJCF and the collision geometry are built) and :meth:`Design.servo` the
:class:`~stewart_drake.robot.servo.ServoModel`. :data:`DESIGN_BOUNDS` gives each variable's
bounds and unit; :func:`reference_design` is the reference robot (docs/reference_geometry.md)
exactly.

Pivot height and home height are one variable here: the toolkit's home pose is 0.30 m above the
base plate's top face (``kinematics.X_HOME``, which the references, the plant's initial state and
the controllers share), so the design's ``home_height`` is the home pose's height above the motor
shafts and the shafts sit at ``pivot_z = 0.30 - home_height`` in the base frame. Only this
difference enters the kinematics and the torques.

What the design does not vary is the reference robot's: the masses and inertias (Table I), the
joint limits, the parts' radii; the two plates follow the rings (the hub's radius 0.625 x the
pivot ring's, the platform plate 15 mm beyond its joint ring, as in the reference). Loaded with
``yaml_load_typed`` like a scenario (so this module must not use ``from __future__ import
annotations``).
"""

import dataclasses
from dataclasses import dataclass

import numpy as np

from ..base.errors import InvalidConfigError, InvalidGeometryError
from ..robot.geometry import StewartGeometry, _leg_angles, reference_geometry
from ..robot.kinematics import X_HOME
from ..robot.motor_catalogue import REFERENCE_MOTOR, CatalogueMotor, catalogue_motor
from ..robot.servo import ServoModel
from ..run.scenario import Robot, Scenario
from ..station.hardware import Motors

#: {variable: (lower, upper, unit, meaning)}: the bounds of :class:`Design`'s numbers.
DESIGN_BOUNDS: dict[str, tuple[float, float, str, str]] = {
    "crank_length": (0.03, 0.15, "m", "pivot to crank-tip joint, a"),
    "rod_length": (0.15, 0.50, "m", "joint centre to joint centre, s"),
    "base_radius": (0.10, 0.30, "m", "radius of the circle of crank pivots"),
    "base_pair_spacing_deg": (10.0, 60.0, "deg", "angle between the two pivots of a pair"),
    "platform_radius": (0.05, 0.20, "m", "radius of the circle of platform joints"),
    "platform_pair_spacing_deg": (10.0, 115.0, "deg", "angle between the two joints of a pair"),
    "crank_direction_deg": (
        45.0,
        135.0,
        "deg",
        "crank azimuth at theta = 0 from its pair's bisector (90: tangential)",
    ),
    "home_height": (0.20, 0.55, "m", "home pose's height above the motor shafts"),
}

#: The hub's radius over the pivot ring's, and the platform plate's overhang beyond its joint
#: ring, m: the reference robot's (0.125 / 0.20, 0.125 - 0.11).
HUB_RATIO, PLATFORM_PLATE_OVERHANG = 0.625, 0.015


@dataclass
class Design:
    """The variables of a design; bounds and units in :data:`DESIGN_BOUNDS`; defaults the
    reference robot.

    Attributes:
        crank_length: a, m. rod_length: s, m.
        base_radius: radius of the crank pivots' circle, m.
        base_pair_spacing_deg: angle between the two pivots of a pair, deg (the geometry's
            ``pivot_angles_deg`` are 120 k -+ half of it).
        platform_radius: radius of the platform joints' circle, m.
        platform_pair_spacing_deg: angle between the two joints of a pair, deg.
        crank_direction_deg: azimuth of each crank at theta = 0 from its pair's bisector, deg
            (``crank_angles_deg`` = 120 k -+ it; 90: tangential, the reference).
        home_height: the home pose's height above the motor shafts, m (module docstring).
        motor: the catalogue's name of the motor at every crank.
    """

    crank_length: float = 0.11
    rod_length: float = 0.404
    base_radius: float = 0.20
    base_pair_spacing_deg: float = 20.0
    platform_radius: float = 0.11
    platform_pair_spacing_deg: float = 110.0
    crank_direction_deg: float = 90.0
    home_height: float = 0.37
    motor: str = REFERENCE_MOTOR

    def validate(self) -> "Design":
        """Check each variable against its bounds and the motor's name; returns self.

        Raises:
            InvalidConfigError: names the variable, its bounds and unit.
        """
        for name, (lo, hi, unit, _) in DESIGN_BOUNDS.items():
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, (int, float)):
                raise InvalidConfigError(f"design.{name} must be a number in {unit}, got {value!r}")
            if not (np.isfinite(value) and lo <= value <= hi):
                raise InvalidConfigError(
                    f"design.{name} = {value!r} {unit} is outside its bounds "
                    f"[{lo:g}, {hi:g}] {unit}"
                )
        try:
            catalogue_motor(self.motor)
        except InvalidConfigError as err:
            raise InvalidConfigError(f"design.{err}") from None
        return self

    def _geometry_fields(self) -> dict:
        """The :class:`StewartGeometry` fields this design sets."""
        return dict(
            base_radius=self.base_radius,
            pivot_z=float(X_HOME[5]) - self.home_height,
            pivot_angles_deg=_leg_angles(self.base_pair_spacing_deg / 2),
            platform_radius=self.platform_radius,
            platform_angles_deg=_leg_angles(self.platform_pair_spacing_deg / 2),
            crank_angles_deg=_leg_angles(self.crank_direction_deg),
            crank_length=self.crank_length,
            rod_length=self.rod_length,
            base_plate_radius=HUB_RATIO * self.base_radius,
            platform_plate_radius=self.platform_radius + PLATFORM_PLATE_OVERHANG,
        )

    def rod_length_range(self) -> tuple[float, float]:
        """[lo, hi], m: the rod lengths with which every leg closes at the home pose, the other
        variables as they are (lo > hi: none). An optimizer may draw ``rod_length`` in it."""
        self.validate()
        return _closing_rod_lengths(self._geometry_fields())

    def geometry(self) -> StewartGeometry:
        """The robot of this design (masses, inertias and limits the reference's; motors'
        reflected inertia 0, as a scenario's ``robot``: its ``hardware.motors`` sets it).

        Raises:
            InvalidConfigError: a variable outside its bounds (named).
            InvalidGeometryError: a robot that cannot be built, named by the variable to
                change: ``rod_length`` when a leg cannot close at home (with the lengths that
                would), else the geometry's own reason.
        """
        self.validate()
        changes = self._geometry_fields()
        if self.rod_length <= self.crank_length:
            raise InvalidGeometryError(
                f"design.rod_length ({self.rod_length} m) must exceed design.crank_length "
                f"({self.crank_length} m)"
            )
        lo, hi = _closing_rod_lengths(changes)
        if not lo <= self.rod_length <= hi:
            fix = (
                f"rod lengths in [{lo:.4g}, {hi:.4g}] m close every leg"
                if lo <= hi
                else "no rod length closes every leg: change crank_length, the radii, the pair "
                "spacings or home_height"
            )
            raise InvalidGeometryError(
                f"design.rod_length = {self.rod_length} m cannot close every leg at the home "
                f"pose; with the other variables as they are, {fix}"
            )
        try:
            return dataclasses.replace(reference_geometry(), **changes)
        except InvalidGeometryError as err:
            raise InvalidGeometryError(
                f"design {self.summary()}: {err} (or change crank_direction_deg, the radii or "
                f"home_height)"
            ) from None

    def servo(self) -> ServoModel:
        """The motor's :class:`~stewart_drake.robot.servo.ServoModel`."""
        return self.catalogue_entry().servo

    def catalogue_entry(self) -> CatalogueMotor:
        """The motor's catalogue entry (price, mass, continuous torque, encoder).

        Raises:
            InvalidConfigError: a name not in the catalogue.
        """
        try:
            return catalogue_motor(self.motor)
        except InvalidConfigError as err:
            raise InvalidConfigError(f"design.{err}") from None

    def apply_to(self, scenario: Scenario) -> Scenario:
        """``scenario`` with this design's robot and, when it has hardware, its motors and their
        encoder resolution; changed in place, validated and returned (a scenario file of the
        design is then ``dump_scenario`` of it, which every command takes).

        Raises:
            InvalidConfigError, InvalidGeometryError: as :meth:`geometry`, or the scenario's own
                validation.
        """
        scenario.robot = Robot.from_value(self.geometry())
        if scenario.hardware is not None:
            entry = self.catalogue_entry()
            scenario.hardware.motors = Motors.from_value(entry.servo)
            scenario.hardware.encoders.counts_per_rev = entry.encoder_counts_per_rev
        return scenario.validate()

    def summary(self) -> str:
        """The variables on one line, with units."""
        numbers = ", ".join(
            f"{name} = {getattr(self, name):.4g} {unit}"
            for name, (_, _, unit, _) in DESIGN_BOUNDS.items()
        )
        return f"({numbers}, motor = {self.motor})"


def reference_design() -> Design:
    """The reference robot as a design: its geometry equals ``reference_geometry()``."""
    return Design()


def random_design(rng: np.random.Generator, motor: str = REFERENCE_MOTOR) -> Design:
    """A design drawn uniformly within :data:`DESIGN_BOUNDS` (it may not close at home)."""
    values = {name: float(rng.uniform(lo, hi)) for name, (lo, hi, _, _) in DESIGN_BOUNDS.items()}
    return Design(**values, motor=motor)


def _closing_rod_lengths(fields: dict) -> tuple[float, float]:
    """[lo, hi] of the rod lengths with which every leg closes at the home pose, m (lo > hi:
    none).

    Each crank tip moves on a circle (centre P_i, radius a, in the plane of d_i and z); a rod of
    length s closes leg i iff s lies between the least and the greatest distance from the
    platform joint p_i at home to that circle: with q = p_i - P_i split into q_u along the shaft
    u_i and q_in in the crank's plane, sqrt(q_u^2 + (|q_in| -+ a)^2).
    """

    def ring(radius, angles_deg, z=0.0):
        a = np.deg2rad(np.asarray(angles_deg))
        return np.stack([radius * np.cos(a), radius * np.sin(a), np.full_like(a, z)], axis=1)

    P = ring(fields["base_radius"], fields["pivot_angles_deg"], fields["pivot_z"])
    p = ring(fields["platform_radius"], fields["platform_angles_deg"], float(X_HOME[5]))
    d = ring(1.0, fields["crank_angles_deg"])
    u = np.cross(d, [0.0, 0.0, 1.0])
    q = p - P
    q_u = np.einsum("ij,ij->i", q, u)
    q_in = np.linalg.norm(q - q_u[:, None] * u, axis=1)
    a = fields["crank_length"]
    near = np.sqrt(q_u**2 + (q_in - a) ** 2)
    far = np.sqrt(q_u**2 + (q_in + a) ** 2)
    return float(near.max()), float(far.min())
