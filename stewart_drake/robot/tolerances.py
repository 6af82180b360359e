"""Tolerances of the robot as built: per quantity a half-width and a distribution, the robot they
draw with a seed (a :class:`~.legs.LegParameters`, a geometry), and a scenario's
``robot_tolerances`` (:class:`RobotTolerances`).

A quantity's half-width h bounds its deviation from the drawing: "uniform" draws it uniformly in
[-h, h] (standard deviation h / sqrt(3)), "normal" from a normal law of standard deviation h / 3
(h is the process's 3-sigma band, as machining tolerances are read). Positions are drawn per
component (each of x, y, z within +-h). The defaults are a robot built to workshop tolerances
(docs/calibration.md, "Tolerances"): +-0.5 mm on every joint position (pivots and platform
joints), +-0.2 mm on the crank lengths, +-0.3 mm on the rod lengths, +-5 mrad on the encoder
zeros, and +-1 mrad of shaft tilt and of crank azimuth (a bracket machined to 0.1 mm over
100 mm).

They draw values of the per-leg model (:mod:`~.legs`) that the calibration identifies;
:meth:`Tolerances.as_built` gives the robot's geometry. A scenario names them in its
``robot_tolerances`` section (:class:`RobotTolerances`, the YAML form with its seed; this module
has no ``from __future__ import annotations``: Drake's YAML loader reads its field types).
"""

from dataclasses import dataclass, field, fields

import numpy as np

from ..base.checks import as_number, check_int
from ..base.errors import InvalidConfigError
from .geometry import PER_LEG_FIELDS, StewartGeometry
from .legs import PARAMETER_KINDS, LegParameters, parameter_kinds

#: The distributions a :class:`Tolerance` may name.
DISTRIBUTIONS = ("uniform", "normal")
#: Largest half-width of a tolerance, by unit: a robot drawn past it is not the drawing's robot
#: made with care (a joint 1 cm off, a crank turned 0.2 rad), and 1e308 overflowed the draw.
MAX_HALF_WIDTH = {"m": 0.01, "rad": 0.2}


@dataclass(frozen=True)
class Tolerance:
    """One quantity's tolerance.

    Attributes:
        half_width: h >= 0, in the quantity's unit (m or rad; the crank azimuth in rad).
        distribution: "uniform" on [-h, h], or "normal" with standard deviation h / 3.
    Raises:
        InvalidConfigError: a half-width negative, not finite or over the larger of
            :data:`MAX_HALF_WIDTH`, or another distribution.
    """

    half_width: float
    distribution: str = "uniform"

    def __post_init__(self):
        bound = max(MAX_HALF_WIDTH.values())
        object.__setattr__(
            self, "half_width", as_number("tolerance half_width", self.half_width, 0.0, bound)
        )
        if self.distribution not in DISTRIBUTIONS:
            raise InvalidConfigError(
                f"a tolerance's distribution is one of {', '.join(DISTRIBUTIONS)}, got "
                f"{self.distribution!r}"
            )

    @property
    def std(self) -> float:
        """Standard deviation of the drawn deviation, in the quantity's unit."""
        return self.half_width / (np.sqrt(3.0) if self.distribution == "uniform" else 3.0)

    def draw(self, rng: np.random.Generator, size) -> np.ndarray:
        """Deviations of shape ``size`` drawn from this tolerance."""
        if self.distribution == "uniform":
            return rng.uniform(-self.half_width, self.half_width, size)
        return rng.normal(0.0, self.half_width / 3.0, size)


#: The default half-widths, per field of :class:`Tolerances` (m or rad): a robot built to
#: workshop tolerances (module docstring). :class:`RobotTolerances` has the same defaults.
DEFAULT_HALF_WIDTHS = {
    "pivot_offsets_m": 0.5e-3,
    "platform_offsets_m": 0.5e-3,
    "crank_lengths_m": 0.2e-3,
    "rod_lengths_m": 0.3e-3,
    "shaft_tilts_rad": 1e-3,
    "crank_angles_deg": 1e-3,
    "encoder_offsets_rad": 5e-3,
}


def _tol(name: str):
    return field(default_factory=lambda: Tolerance(DEFAULT_HALF_WIDTHS[name]))


@dataclass(frozen=True)
class Tolerances:
    """The tolerance of each per-leg quantity of :class:`~.legs.LegParameters`; field names
    are its fields' (module docstring for the defaults).

    Attributes:
        pivot_offsets_m, platform_offsets_m: each component of each joint's position, m.
        crank_lengths_m, rod_lengths_m: m.  shaft_tilts_rad: rad.
        crank_angles_deg: the crank azimuth's deviation, in rad (the field's name kept).
        encoder_offsets_rad: rad.
    """

    pivot_offsets_m: Tolerance = _tol("pivot_offsets_m")
    platform_offsets_m: Tolerance = _tol("platform_offsets_m")
    crank_lengths_m: Tolerance = _tol("crank_lengths_m")
    rod_lengths_m: Tolerance = _tol("rod_lengths_m")
    shaft_tilts_rad: Tolerance = _tol("shaft_tilts_rad")
    crank_angles_deg: Tolerance = _tol("crank_angles_deg")
    encoder_offsets_rad: Tolerance = _tol("encoder_offsets_rad")

    def scaled(self, factor: float) -> "Tolerances":
        """Every half-width times ``factor`` (>= 0), distributions kept."""
        factor = as_number("tolerance factor", factor, 0.0)
        return Tolerances(
            **{
                f.name: Tolerance(
                    getattr(self, f.name).half_width * factor, getattr(self, f.name).distribution
                )
                for f in fields(self)
            }
        )

    def half_widths(self) -> np.ndarray:
        """(66,) the half-width of each entry of the deviation vector (:mod:`~.legs`)."""
        return np.array([getattr(self, kind).half_width for kind in parameter_kinds()])

    def stds(self) -> np.ndarray:
        """(66,) the standard deviation of each entry of the deviation vector."""
        return np.array([getattr(self, kind).std for kind in parameter_kinds()])

    def deviations(self, seed: int) -> np.ndarray:
        """(66,) a deviation vector (:mod:`~.legs`'s order and units) drawn with ``seed``
        (0 .. 2^32 - 1); the same seed draws the same vector.

        Raises:
            InvalidConfigError: a seed out of range.
        """
        rng = np.random.default_rng(check_int("seed", seed, 0, 2**32 - 1))
        parts = [getattr(self, kind).draw(rng, 6 * width) for kind, width, _ in PARAMETER_KINDS]
        return np.concatenate(parts)

    def draw(self, geometry: StewartGeometry, seed: int) -> LegParameters:
        """A robot as built: ``geometry``'s legs with deviations drawn with ``seed``.

        Args:
            geometry: the nominal robot.  seed: 0 .. 2^32 - 1.
        Returns:
            :class:`~.legs.LegParameters`; the same seed draws the same robot.
        Raises:
            InvalidConfigError: a seed out of range. InvalidGeometryError: a drawn rod not
                longer than its crank (half-widths of the order of the lengths).
        """
        return LegParameters.nominal(geometry).shifted(self.deviations(seed))

    def as_built(self, geometry: StewartGeometry, seed: int) -> StewartGeometry:
        """The geometry of a robot as built: ``geometry`` with deviations drawn with ``seed``
        added to its per-leg values (its per-leg fields, or the drawing's where null). For a
        symmetric ``geometry``, ``draw(geometry, seed).geometry(geometry)`` to the bit.

        Raises:
            InvalidConfigError: a seed out of range. InvalidGeometryError: a drawn robot the
                geometry refuses (a deviation beyond its bounds, legs that cannot close).
        """
        symmetric = geometry.replace(**{name: None for name in PER_LEG_FIELDS})
        legs = LegParameters.of(geometry).shifted(self.deviations(seed))
        return legs.geometry(symmetric)


@dataclass
class ToleranceSpec:
    """The YAML form of one :class:`Tolerance` (a scenario's ``robot_tolerances``).

    Attributes:
        half_width: h >= 0, in the quantity's unit (m or rad).
        distribution: "uniform" on [-h, h], or "normal" with standard deviation h / 3.
    """

    half_width: float = 0.0
    distribution: str = "uniform"


def _spec(name: str):
    """The default of :class:`RobotTolerances`' field ``name``: :data:`DEFAULT_HALF_WIDTHS`'."""
    return field(
        default_factory=lambda: ToleranceSpec(
            DEFAULT_HALF_WIDTHS[_TOLERANCES_FIELD.get(name, name)]
        )
    )


#: Field of :class:`RobotTolerances` -> field of :class:`Tolerances` where they differ: the
#: crank azimuth's tolerance is in rad, whatever the per-leg field's name says.
_TOLERANCES_FIELD = {"crank_azimuths_rad": "crank_angles_deg"}


@dataclass
class RobotTolerances:
    """A scenario's ``robot_tolerances``: the robot as built drawn from the tolerances of its
    parts, with a seed; the plant follows the drawn robot, the controller ``robot``.

    Attributes:
        seed: 0 .. 2^32 - 1; the same seed draws the same robot.
        pivot_offsets_m, platform_offsets_m: each component of each joint's position, m
            (default +-0.5 mm).
        crank_lengths_m: m (+-0.2 mm).  rod_lengths_m: m (+-0.3 mm).
        shaft_tilts_rad: rad (+-1 mrad).  crank_azimuths_rad: rad (+-1 mrad).
        encoder_offsets_rad: rad (+-5 mrad).
    Each a :class:`ToleranceSpec`; the defaults are :class:`Tolerances`'.
    """

    seed: int = 0
    pivot_offsets_m: ToleranceSpec = _spec("pivot_offsets_m")
    platform_offsets_m: ToleranceSpec = _spec("platform_offsets_m")
    crank_lengths_m: ToleranceSpec = _spec("crank_lengths_m")
    rod_lengths_m: ToleranceSpec = _spec("rod_lengths_m")
    shaft_tilts_rad: ToleranceSpec = _spec("shaft_tilts_rad")
    crank_azimuths_rad: ToleranceSpec = _spec("crank_azimuths_rad")
    encoder_offsets_rad: ToleranceSpec = _spec("encoder_offsets_rad")

    def tolerances(self) -> Tolerances:
        """The :class:`Tolerances` these fields give.

        Raises:
            InvalidConfigError: a half-width negative, not a number or over
                :data:`MAX_HALF_WIDTH` (10 mm, 0.2 rad), or another distribution; names the
                field (``robot_tolerances.rod_lengths_m.half_width``).
        """
        given = {}
        for f in fields(self):
            if f.name == "seed":
                continue
            spec, where = getattr(self, f.name), f"robot_tolerances.{f.name}"
            if not isinstance(spec, ToleranceSpec):
                raise InvalidConfigError(
                    f"{where} must be a ToleranceSpec (half_width, distribution), got "
                    f"{type(spec).__name__}"
                )
            unit = "m" if f.name.endswith("_m") else "rad"
            half_width = as_number(
                f"{where}.half_width", spec.half_width, 0.0, MAX_HALF_WIDTH[unit]
            )
            if spec.distribution not in DISTRIBUTIONS:
                raise InvalidConfigError(
                    f"{where}.distribution must be one of {', '.join(DISTRIBUTIONS)}, got "
                    f"{spec.distribution!r}"
                )
            given[_TOLERANCES_FIELD.get(f.name, f.name)] = Tolerance(half_width, spec.distribution)
        return Tolerances(**given)

    def as_built(self, geometry: StewartGeometry) -> StewartGeometry:
        """The robot as built about ``geometry`` (:meth:`Tolerances.as_built` with ``seed``).

        Raises:
            InvalidConfigError: a field out of range (named). InvalidGeometryError: a drawn
                robot the geometry refuses (half-widths too large for it).
        """
        tolerances = self.tolerances()
        seed = check_int("robot_tolerances.seed", self.seed, 0, 2**32 - 1)
        return tolerances.as_built(geometry, seed)
