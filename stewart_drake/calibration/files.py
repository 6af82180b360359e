"""The calibration's files: the measurements CSV it reads, the robot section and the poses it
writes.

**Measurements** (:func:`read_measurements`): UTF-8 text, comma separated, a first line that
names every column with its unit in brackets, one measured pose per line; lines that start
with ``#`` are comments. Required columns: the six encoder readings ``q0 [rad]`` ..
``q5 [rad]`` and the pose of the platform frame in the base frame ``phi [rad]``, ``theta
[rad]``, ``psi [rad]`` (roll, pitch, yaw of R_BE = Rz(psi) Ry(theta) Rx(phi)), ``X [m]``,
``Y [m]``, ``Z [m]``, in any order. Units converted: angles in rad, mrad, urad or deg, lengths
in m, cm, mm or um, readings also in ``counts`` (of the encoders' counts per revolution). Other
columns (a time, a pose number) are read past and named. The file is read through
:func:`~stewart_drake.base.fileio.read_checked` (a regular file of at most
:data:`MAX_MEASUREMENTS_BYTES`) and parsed as numbers only.

**Robot** (:func:`robot_yaml`): a scenario's ``robot:`` section, every field of
:class:`~stewart_drake.run.scenario.Robot` with the identified crank azimuths in
``crank_angles_deg``, and the per-leg fields of :class:`~stewart_drake.robot.legs.LegParameters`;
its lengths hold at the temperature of the measurements (``lengths_at_c``,
:func:`nominal_at_temperature`, :func:`robot_section`).

**Registration** (:func:`registration_yaml`): the REG.yaml of fiducials
(:mod:`~.registration`), as an emulated tracker measured them.

**Poses** (:func:`write_path`): the path through the chosen poses as a reference CSV the robot
command drives (``t [s],phi [rad],...,Z [m]``), and beside it ``<stem>_windows.csv``, each
pose with the window of time to measure it in.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields
from pathlib import Path

import numpy as np

from ..base.columns import header_cell, read_csv_columns
from ..base.errors import InvalidConfigError
from ..base.fileio import atomic_write
from ..base.units import ANGLE_UNITS, LENGTH_UNITS  # a column's (readings take "counts" too)
from ..robot.geometry import StewartGeometry
from ..robot.legs import PARAMETER_KINDS, LegParameters
from .identify import MIN_POSES
from .poses import PosePath
from .registration import Fiducials

#: Largest measurements file read, bytes (a million poses).
MAX_MEASUREMENTS_BYTES = 200e6
#: The columns a measurements file must have, with their SI units.
READING_COLUMNS = tuple(f"q{i}" for i in range(6))
POSE_COLUMNS = ("phi", "theta", "psi", "X", "Y", "Z")
#: What a bad measurements file is told to become.
MEASUREMENTS_REMEDY = (
    "write a first line naming every column with its unit, q0 [rad],...,q5 [rad],phi [rad],"
    "theta [rad],psi [rad],X [m],Y [m],Z [m] (docs/calibration.md)"
)


@dataclass(frozen=True)
class MeasurementsFile:
    """A measurements file as read.

    Attributes:
        poses: (N, 6) the tracker's poses, rad and m.  readings: (N, 6) the encoders', rad.
        lines: (N,) the line of the file each row came from.
        ignored: the header cells of the columns not read.
        converted: ((column, unit), ...) the columns converted from another unit.
    """

    poses: np.ndarray
    readings: np.ndarray
    lines: tuple
    ignored: tuple
    converted: tuple


def _column_factor(path, name: str, unit: str, counts_per_rev: int) -> float:
    """The factor to SI of column ``name`` in ``unit``.

    Raises:
        InvalidConfigError: a unit that is not this column's kind.
    """
    angle = name in READING_COLUMNS or name in POSE_COLUMNS[:3]
    table = dict(ANGLE_UNITS) if angle else dict(LENGTH_UNITS)
    if name in READING_COLUMNS:
        table["counts"] = 2.0 * math.pi / counts_per_rev
    if unit not in table:
        raise InvalidConfigError(
            f"{path}: column {name!r} has the unit [{unit}], which is not "
            f"{'an angle' if angle else 'a length'}: write it in one of "
            f"{', '.join(f'[{u}]' for u in table)}"
        )
    return table[unit]


def _header(path, cells: list, counts_per_rev: int) -> tuple[dict, list, list]:
    """({name: (index, factor)} of the required columns, the other cells, the converted
    (name, unit)).

    Raises:
        InvalidConfigError: a required column missing, twice, or without a unit or a known one.
    """
    found, ignored, converted = {}, [], []
    required = READING_COLUMNS + POSE_COLUMNS
    for index, cell in enumerate(cells):
        name, unit = header_cell(cell)
        if name not in required:
            ignored.append(cell.strip())
            continue
        if not unit:
            raise InvalidConfigError(
                f"{path}: column {name!r} has no unit: write it as '{name} [rad]' or "
                f"'{name} [{'m' if name in POSE_COLUMNS[3:] else 'deg'}]' (units in brackets)"
            )
        if name in found:
            raise InvalidConfigError(f"{path}: the column {name!r} appears twice in the header")
        factor = _column_factor(path, name, unit, counts_per_rev)
        if factor != 1.0:
            converted.append((name, unit))
        found[name] = (index, factor)
    missing = [n for n in required if n not in found]
    if missing:
        raise InvalidConfigError(
            f"{path}: the header lacks the column{'s' if len(missing) > 1 else ''} "
            f"{', '.join(missing)}; {MEASUREMENTS_REMEDY}"
        )
    return found, ignored, converted


#: Poses closer than this, per coordinate (rad, m), are one pose measured again.
DISTINCT_POSE = np.array([1e-3, 1e-3, 1e-3, 1e-4, 1e-4, 1e-4])


def read_measurements(path, counts_per_rev: int = 2**17) -> MeasurementsFile:
    """The measured poses and readings of a measurements file (module docstring), read by
    :func:`~stewart_drake.base.columns.read_csv_columns`.

    Args:
        path: the CSV.  counts_per_rev: the encoders' counts per revolution (for readings in
            ``counts``).
    Returns:
        :class:`MeasurementsFile`, in SI units.
    Raises:
        MissingFileError: no such file.  CorruptFileError: not a regular file, too large, not
            UTF-8 or not CSV.  InvalidConfigError: too long for the memory, a header without a
            required column, a unit unknown or of the wrong kind, a cell that is not a finite
            number (its line and column named), fewer than :data:`~.identify.MIN_POSES` poses
            or distinct poses (:data:`DISTINCT_POSE`).
    """
    header: dict = {}

    def columns_of(cells):
        header["found"], header["ignored"], header["converted"] = _header(
            path, cells, counts_per_rev
        )
        return header["found"]

    columns, lines = read_csv_columns(
        path,
        "measurements file",
        MAX_MEASUREMENTS_BYTES,
        MEASUREMENTS_REMEDY,
        columns_of,
        bad_cell="; remove the line or measure that pose again",
    )
    values = np.column_stack([columns[name] for name in READING_COLUMNS + POSE_COLUMNS])
    if len(values) < MIN_POSES:
        raise InvalidConfigError(
            f"{path}: {len(values)} measured poses are too few: each leg's 11 parameters need "
            f"at least {MIN_POSES} (60 or more for a useful accuracy, docs/calibration.md)"
        )
    distinct = len(np.unique(np.round(values[:, 6:] / DISTINCT_POSE), axis=0))
    if distinct < MIN_POSES:
        raise InvalidConfigError(
            f"{path}: {len(values)} measured poses, but only {distinct} distinct (poses within "
            f"0.1 mm and 1 mrad of each other are one): a pose measured again tells nothing of the "
            f"geometry, and each leg's 11 parameters need at least {MIN_POSES} distinct poses "
            f"(60 or more, spread over the workspace: calibrate --plan N chooses them)"
        )
    return MeasurementsFile(
        poses=values[:, 6:],
        readings=values[:, :6],
        lines=tuple(lines.tolist()),
        ignored=tuple(header["ignored"]),
        converted=tuple(header["converted"]),
    )


def measurements_csv(poses, q) -> str:
    """The text of a measurements file of poses (N, 6) and readings (N, 6), SI units, every
    digit a float64 holds."""
    header = [f"{n} [rad]" for n in READING_COLUMNS] + [
        f"{n} [{'rad' if k < 3 else 'm'}]" for k, n in enumerate(POSE_COLUMNS)
    ]
    lines = [",".join(header)]
    for qk, xk in zip(np.asarray(q), np.asarray(poses)):
        lines.append(",".join(repr(float(v)) for v in (*qk, *xk)))
    return "\n".join(lines) + "\n"


def write_measurements(path, poses, q) -> Path:
    """Write :func:`measurements_csv` to ``path`` atomically (a regular file only)."""
    text = measurements_csv(poses, q)
    atomic_write(Path(path), lambda f: f.write(text.encode()))
    return Path(path)


def _yaml_value(value) -> str:
    """A number or a list of numbers as YAML flow text (floats as repr: exact; an exponent's
    mantissa with its point)."""
    if isinstance(value, (list, tuple, np.ndarray)):
        return "[" + ", ".join(_yaml_value(v) for v in value) + "]"
    text = repr(float(value))
    mantissa, e, exponent = text.partition("e")
    # YAML 1.1 readers (PyYAML) take 1e-06 for a string: a float's mantissa needs its point.
    return f"{mantissa}.0e{exponent}" if e and "." not in mantissa else text


def nominal_at_temperature(scenario) -> StewartGeometry:
    """The nominal robot a calibration identifies about: the robot ``scenario`` (a
    :class:`~stewart_drake.run.scenario.Scenario`) believes
    (:func:`~stewart_drake.run.plan.robot_geometry`), at its ``temperature_c`` when one is
    given (the temperature during the measurements, ``calibrate --temperature``), whether or
    not the controller is told it: the identified lengths then hold at that temperature.

    Returns:
        :class:`~stewart_drake.robot.geometry.StewartGeometry` (the believed robot itself
        without a temperature, or when it is at that temperature already).
    Raises:
        as :func:`~stewart_drake.run.plan.make_plan` (the scenario is validated here).
    """
    from ..run.plan import robot_geometry

    geometry = robot_geometry(scenario)
    t = scenario.temperature_c
    return geometry if t is None else geometry.at_temperature(t)


def robot_section(robot, nominal: StewartGeometry):
    """The :class:`~stewart_drake.run.scenario.Robot` a calibration about ``nominal`` writes
    (:func:`robot_yaml`): the scenario's ``robot`` itself when ``nominal`` holds its lengths at
    the same temperature, else ``nominal``'s fields (its lengths and ``lengths_at_c`` at the
    temperature of the measurements)."""
    from ..run.scenario import Robot

    if nominal.lengths_at_c == robot.lengths_at_c:
        return robot
    return Robot.from_value(nominal)


def robot_yaml(robot, legs: LegParameters, comments: tuple = ()) -> str:
    """A scenario's ``robot:`` section: the fields of ``robot`` (a
    :class:`~stewart_drake.run.scenario.Robot`, the nominal robot) with ``crank_angles_deg``
    from ``legs``, then the per-leg fields of ``legs``; ``comments`` go first, as ``#`` lines.
    """
    lines = [f"# {c}" for c in comments] + ["robot:"]
    per_leg = {name for name, _, _ in PARAMETER_KINDS}
    for f in fields(robot):
        if f.name in per_leg:
            continue
        lines.append(f"  {f.name}: {_yaml_value(getattr(robot, f.name))}")
    for name, width, _ in PARAMETER_KINDS:
        value = np.asarray(getattr(legs, name))
        if width == 3:
            lines.append(f"  {name}:")
            lines += [f"    - {_yaml_value(row)}" for row in value]
        else:
            lines.append(f"  {name}: {_yaml_value(value)}")
    return "\n".join(lines) + "\n"


def write_robot(path, robot, legs: LegParameters, comments: tuple = ()) -> Path:
    """Write :func:`robot_yaml` to ``path`` atomically (a regular file only)."""
    text = robot_yaml(robot, legs, comments)
    atomic_write(Path(path), lambda f: f.write(text.encode()))
    return Path(path)


def registration_yaml(fiducials: Fiducials) -> str:
    """The REG.yaml text of ``fiducials`` (every digit a float64 holds)."""

    def point(robot_key, p_R, p_T):
        return f"  - {{{robot_key}: {_yaml_value(p_R)}, tracker_m: {_yaml_value(p_T)}}}"

    lines = [f"point_sigma_m: {_yaml_value(fiducials.point_sigma_m)}", "base_points:"]
    lines += [point("base_m", a, b) for a, b in zip(fiducials.base_B, fiducials.base_T)]
    if fiducials.platform_P is not None and fiducials.platform_T is not None:
        x = np.asarray(fiducials.marker_TM, dtype=float)
        lines += [
            "platform_points:",
            "  marker_in_tracker:",
            f"    rpy_rad: {_yaml_value(x[:3])}",
            f"    xyz_m: {_yaml_value(x[3:])}",
            f"    rotation_sigma_rad: {_yaml_value(fiducials.marker_sigma[0])}",
            f"    translation_sigma_m: {_yaml_value(fiducials.marker_sigma[1])}",
            "  points:",
        ]
        lines += [
            "  " + point("platform_m", a, b)
            for a, b in zip(fiducials.platform_P, fiducials.platform_T)
        ]
    return "\n".join(lines) + "\n"


def registration_path(path) -> Path:
    """The REG.yaml beside an emulated measurements file: ``<stem>_registration.yaml``."""
    path = Path(path)
    return path.with_name(f"{path.stem}_registration.yaml")


def write_registration(path, fiducials: Fiducials) -> Path:
    """Write :func:`registration_yaml` to ``path`` atomically (a regular file only)."""
    text = registration_yaml(fiducials)
    atomic_write(Path(path), lambda f: f.write(text.encode()))
    return Path(path)


#: The header of a path's CSV: the reference CSV's columns with their SI units.
PATH_HEADER = "t [s],phi [rad],theta [rad],psi [rad],X [m],Y [m],Z [m]"


def windows_path(path) -> Path:
    """The file beside a path's CSV that lists its poses and their windows."""
    path = Path(path)
    return path.with_name(f"{path.stem}_windows{path.suffix or '.csv'}")


def write_path(path, plan: PosePath) -> tuple[Path, Path]:
    """Write the path ``plan`` as a reference CSV at ``path`` (:data:`PATH_HEADER`) and its
    poses with their windows at :func:`windows_path`; returns both paths."""
    rows = [PATH_HEADER] + [
        ",".join(repr(float(v)) for v in (t, *x)) for t, x in zip(plan.t, plan.x)
    ]
    text = "\n".join(rows) + "\n"
    header = "pose,t_start [s],t_end [s]," + PATH_HEADER.split(",", 1)[1]
    win = [header] + [
        ",".join([str(k)] + [repr(float(v)) for v in (*w, *x)])
        for k, (w, x) in enumerate(zip(plan.windows, plan.poses))
    ]
    other = windows_path(path)
    atomic_write(Path(path), lambda f: f.write(text.encode()))
    atomic_write(other, lambda f: f.write(("\n".join(win) + "\n").encode()))
    return Path(path), other
