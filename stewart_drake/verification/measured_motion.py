"""A motion measured on a real phantom, as read (``stewart-drake verify``'s input): a tracker's
export or the robot's encoder log turned into poses with their clock (:class:`MeasuredMotion`).

A tracker's file is read by the readers of recorded traces (:func:`read_measured`: a header
naming columns and units, semicolons or commas, decimal commas, ms, a frame column skipped with
``-``; the marker's orientation as roll, pitch and yaw or as a unit quaternion ``qw qx qy qz``,
as most trackers export it): the poses of its marker M in the tracker's frame T on the
tracker's clock. The robot's
encoder log is turned into platform poses in the base frame by forward kinematics
(:func:`encoder_motion`), and its surrogate's carriage into a motion of one axis
(:func:`carriage_motion`), both on the reference's own clock. :mod:`~.alignment` puts either on the
reference's clock and frame, and :mod:`~.verification` judges it.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from ..base.errors import InvalidConfigError
from ..organ_motion.fidelity import AXES
from ..station.bus.emulator_config import EMULATED_BUS

#: The kinds of a :class:`MeasuredMotion` read from the robot's own encoder log.
ROBOT_KINDS = ("encoders", "carriage")


@dataclass(frozen=True)
class MeasuredMotion:
    """A motion measured on a phantom, as read.

    Attributes:
        path: the file. kind: "tracker" (a tracker's file), "encoders" (the robot's encoder
            log, by forward kinematics) or "carriage" (the surrogate's carriage in that log).
        t: (n,) s, increasing: the file's own clock ("tracker"), or the reference's clock
            ("encoders", "carriage": the log's ``t_path``).
        poses: (n, 6) [phi, theta, psi, X, Y, Z] rad and m: the marker M in the tracker's frame
            T ("tracker"), the platform E in the base frame B ("encoders"), the carriage's
            position on its reference's axis ("carriage"); NaN on the axes not measured.
        measured: (6,) bool, the axes the file measures: any of them (a single-axis sensor
            measures one).
        layout: how the file was read, in words. dropped: what was left out as an export's
            artefact, or "". repaired: a line per time repaired from the file's frame counter
            (:func:`~stewart_drake.references.trace_files.repaired_times`), or ().
        bus: an encoder log's bus as its run wrote it (emulated or not, in words), or "" where
            the file does not say (a tracker's file; a log written without it).
    """

    path: str
    kind: str
    t: np.ndarray
    poses: np.ndarray
    measured: np.ndarray
    layout: str = ""
    dropped: str = ""
    repaired: tuple = ()
    bus: str = ""

    @property
    def from_the_robot(self) -> bool:
        """Whether the motion is the robot's own encoder log ("encoders", "carriage"): on the
        reference's own clock, and not independent of the robot it judges."""
        return self.kind in ROBOT_KINDS

    @property
    def rotations_measured(self) -> bool:
        """Whether the file measures the rotations (a 6-DoF marker, the encoder log)."""
        return bool(np.all(self.measured[:3]))

    def words(self) -> str:
        """What was read, in words: the file, its samples, rate and span, its axes."""
        from ..references.trace_files import repaired_words

        dt = float(np.median(np.diff(self.t)))
        axes = ", ".join(a for a, m in zip(AXES, self.measured) if m)
        what = {
            "encoders": "the robot's encoder log, by forward kinematics",
            "carriage": "the robot's encoder log, the surrogate's carriage s",
        }.get(self.kind, "")
        return (
            f"{Path(self.path).name} ({what or self.layout}): {len(self.t)} samples at "
            f"{1 / dt:.4g} Hz over {self.t[-1] - self.t[0]:.4g} s; measured {axes}"
            + ("" if self.rotations_measured else " (rotation not measured)")
            + (f"; left out: {self.dropped}" if self.dropped else "")
            + repaired_words(self.repaired)
        )


MEASURED_REMEDY = (
    "give a file whose first line names the time and the axes measured with their units: the "
    "marker's X, Y, Z (and phi, theta, psi, or a quaternion qw, qx, qy, qz, or none), e.g. t "
    "[ms];X [mm];Y [mm];Z [mm], or one or two axes of a single-axis sensor, e.g. t [s],Z [mm]; "
    "or name its columns with --measured-columns ('-,t [ms],X [mm],Y [mm],Z [mm]' skips a frame "
    "counter)"
)

#: The names of a quaternion's columns (any case, a unit in brackets ignored): its scalar part
#: ``qw`` (``q0``, as NDI's trackers write it) and its vector part ``qx qy qz``.
QUATERNION_COLUMNS = {"qw": 0, "q0": 0, "qx": 1, "qy": 2, "qz": 3}
#: How far a quaternion's norm may be from 1 before its columns are taken for something else.
QUATERNION_NORM_TOLERANCE = 0.05


def _quaternion_columns(path, header: list) -> list | None:
    """[j_w, j_x, j_y, j_z] the header's columns of a quaternion, or None without one.

    Raises:
        InvalidConfigError: some of the four but not all, or one twice.
    """
    found: dict[int, list] = {}
    for j, cell in enumerate(header):
        name = cell.strip().strip('"').split("[")[0].split("(")[0].strip().lower()
        if name in QUATERNION_COLUMNS:
            found.setdefault(QUATERNION_COLUMNS[name], []).append(j)
    if not found:
        return None
    if sorted(found) != [0, 1, 2, 3] or any(len(v) > 1 for v in found.values()):
        named = ", ".join(header[j].strip() for v in found.values() for j in v)
        raise InvalidConfigError(
            f"{path}: a quaternion needs one column each of qw (or q0), qx, qy and qz, got "
            f"{named}; {MEASURED_REMEDY}"
        )
    return [found[k][0] for k in range(4)]


def _quaternion_rpy(path, rows: list, columns: list, n: int) -> np.ndarray:
    """(n, 3) roll, pitch, yaw (rad, unwrapped in time) of the quaternions in ``columns`` of the
    first ``n`` data rows (each its line number, then its cells).

    Raises:
        InvalidConfigError: a cell missing or not a number, a norm off 1 by more than
            :data:`QUATERNION_NORM_TOLERANCE` (its line named).
    """
    q = np.empty((n, 4))
    for i, (line, *cells) in enumerate(rows[:n]):
        try:
            q[i] = [float(cells[j]) for j in columns]
        except ValueError:
            q[i] = np.nan
        norm = float(np.linalg.norm(q[i]))
        if not abs(norm - 1.0) <= QUATERNION_NORM_TOLERANCE:
            what = "is missing or not a number" if not np.isfinite(norm) else f"has norm {norm:.4g}"
            raise InvalidConfigError(
                f"{path}, line {line}: the quaternion (qw, qx, qy, qz) {what}, not 1: check the "
                f"columns' names and order (the tracker lost the marker?)"
            )
    rpy = Rotation.from_quat(q[:, [1, 2, 3, 0]]).as_euler("ZYX")[:, ::-1]
    return np.unwrap(rpy, axis=0)


def read_measured(
    path,
    columns: str = "",
    axis_map: dict | None = None,
    columns_option: str = "--measured-columns",
) -> MeasuredMotion:
    """A tracker's file as a :class:`MeasuredMotion`: read by the readers of recorded traces
    (:func:`~stewart_drake.references.trace_files.read_trace_table`, any separator and decimal
    mark, a header or ``columns``, a column named ``-`` skipped, a closing line of zeros left
    out), on the file's own clock (its times as written, in s).

    Args:
        path: the file. columns: its columns' names and units when it has no header (or to
            replace it). axis_map: {column: axis with an optional sign}. columns_option: the
            command's option that gives ``columns``, which the refusals name.
    Returns:
        :class:`MeasuredMotion` of kind "tracker".
    Raises:
        MissingFileError, CorruptFileError: no such file, not a regular file, too large, not
            UTF-8 text.
        InvalidConfigError: what the trace readers refuse (no time column, a unit missing or of
            the wrong kind, times not increasing, a row that is not numbers: the line named);
            no axis, or some rotations but not three; a missing or NaN
            value (its line and column named); a quaternion's columns not all four, beside
            roll, pitch or yaw, or one of norm off 1 (its line named).
    """
    from ..references.trace_files import SKIP_COLUMN, TIME_UNITS, read_trace_table, trace_samples

    path = Path(path)
    header, rows, layout = read_trace_table(path, "auto", columns, columns_option)
    quaternion = _quaternion_columns(path, header)
    if quaternion is not None:  # read apart: four columns, three axes
        header = [SKIP_COLUMN if j in quaternion else h for j, h in enumerate(header)]
    table = trace_samples(path, header, rows, layout, axis_map, columns_option)
    if quaternion is not None and any(k < 3 for k in table.targets):
        raise InvalidConfigError(
            f"{path}: both a quaternion and roll, pitch or yaw columns: give one of them"
        )
    if not table.targets and quaternion is None:
        raise InvalidConfigError(
            f"{path}: a measured motion needs at least one axis besides the time; {MEASURED_REMEDY}"
        )
    n = len(table.t)
    values = table.data[:, 1:]
    bad = np.argwhere(~np.isfinite(values))
    if bad.size:
        i, j = (int(v) for v in bad[0])
        raise InvalidConfigError(
            f"{path}, line {rows[i][0]}: {table.names[j + 1]} is missing or NaN (the tracker "
            f"lost the marker?); verify compares measured samples only: cut the file to a stretch "
            f"without gaps"
        )
    poses = np.full((n, 6), np.nan)
    for j, (k, factor) in enumerate(zip(table.targets, table.factors)):
        poses[:, k] = values[:, j] * factor
    start = float(table.data[0, 0]) * TIME_UNITS[table.units[0].lower()]
    measured = np.zeros(6, dtype=bool)
    measured[table.targets] = True
    if quaternion is not None:
        poses[:, :3] = _quaternion_rpy(path, rows, quaternion, n)
        measured[:3] = True
    return MeasuredMotion(
        str(path),
        "tracker",
        table.t + start,
        poses,
        measured,
        table.layout,
        table.dropped,
        tuple(table.repaired),
    )


def _on_reference_clock(path, t_path: np.ndarray) -> np.ndarray:
    """(n,) bool: the encoder log's lines on the reference's clock (``t_path`` not NaN).

    Raises:
        InvalidConfigError: fewer than 4 such lines, or their times not increasing.
    """
    on = np.isfinite(t_path)
    if np.count_nonzero(on) < 4 or np.any(np.diff(t_path[on]) <= 0):
        raise InvalidConfigError(
            f"{path}: the encoder log needs at least 4 lines on the reference's clock (t_path), "
            f"increasing; give the <stem>_encoders.csv a robot run wrote"
        )
    return on


def encoder_motion(path, t_path, readings, geometry, bus: str = "") -> MeasuredMotion:
    """The robot's encoder log as a :class:`MeasuredMotion`: the platform's poses in the base
    frame by forward kinematics of ``geometry`` (the encoders' zero errors taken off first), on
    the reference's clock (the log's ``t_path``; its lines without one, the lead-in, left out).

    Args:
        path: the log, for messages. t_path: (n,) s, NaN on the lead-in's lines.
        readings: (n, 6) the encoders' raw readings, rad. geometry: the robot.
        bus: what the log says its bus was (:attr:`MeasuredMotion.bus`).
    Raises:
        InvalidConfigError: no line on the reference's clock, its times not increasing.
        ForwardKinematicsError: a reading forward kinematics cannot solve (named).
    """
    from ..robot.forward_kinematics import fk

    t_path, readings = np.asarray(t_path, float), np.asarray(readings, float).reshape(-1, 6)
    on = _on_reference_clock(path, t_path)
    theta = readings[on] - np.asarray(geometry.encoder_offsets)
    x = np.empty((len(theta), 6))
    x0 = None
    for a in range(0, len(theta), 2000):  # each block from the last pose of the one before
        x[a : a + 2000], _ = fk(geometry, theta[a : a + 2000], x0=x0)
        x0 = x[min(a + 1999, len(theta) - 1)]
    return MeasuredMotion(
        str(path), "encoders", t_path[on], x, np.ones(6, dtype=bool), "encoder log", bus=bus
    )


def carriage_motion(path, t_path, s, axis: int, sign: float = 1.0) -> MeasuredMotion:
    """The surrogate's carriage in the robot's encoder log as a :class:`MeasuredMotion` of one
    axis: its position ``s`` as its servo's encoder read it, on the reference's clock (the log's
    ``t_path``, as the platform's from the same log: :func:`encoder_motion`; the lead-in's
    lines left out), on the surrogate reference's ``axis`` with its ``sign`` (``s`` is the
    trace's own displacement, the axis map's sign undone), about the stage's mid-travel.

    Args:
        path: the log, for messages. t_path: (n,) s, NaN on the lead-in's lines. s: (n,) m.
        axis: 3, 4 or 5 (X, Y or Z). sign: +1 or -1.
    Returns:
        :class:`MeasuredMotion` of kind "carriage", NaN on the other five axes.
    Raises:
        InvalidConfigError: no line on the reference's clock, its times not increasing.
    """
    t_path, s = np.asarray(t_path, float), np.asarray(s, float)
    on = _on_reference_clock(path, t_path)
    poses = np.full((int(np.count_nonzero(on)), 6), np.nan)
    poses[:, axis] = sign * s[on]
    measured = np.zeros(6, dtype=bool)
    measured[axis] = True
    return MeasuredMotion(
        str(path), "carriage", t_path[on], poses, measured, "encoder log, the surrogate's s"
    )


__all__ = [
    "ROBOT_KINDS",
    "EMULATED_BUS",
    "MeasuredMotion",
    "MEASURED_REMEDY",
    "QUATERNION_COLUMNS",
    "QUATERNION_NORM_TOLERANCE",
    "read_measured",
    "encoder_motion",
    "carriage_motion",
]
