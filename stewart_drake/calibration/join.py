"""The measurements joined from a session on the robot: the robot's encoder log, the tracker's
file and the planned path's windows, into the measurements file ``calibrate`` reads.

**Encoder log** (:func:`write_encoder_log`, written by ``stewart-drake robot`` beside its
``.npz`` as ``<stem>_encoders.csv``): one line per control period, ``time [s]`` (when the
servos were read, s since the Unix epoch on the robot computer's clock), ``t_run [s]`` (the
run's time, from the start of the homing lead-in), ``t_path [s]`` (the time on the reference's
own clock: a planned path's ``t [s]``; ``nan`` during the lead-in), ``q0 [rad]`` ..
``q5 [rad]`` (the encoders' raw readings, zero errors included); a run with a surrogate's servo
on the bus adds ``s [m]``, ``s_cmd [m]``, ``s_ref [m]`` and ``s_delay [s]`` (its carriage's
position read, commanded, its reference on the run's clock, and the delay the command was taken
with: lag matching, :mod:`~stewart_drake.station.surrogate.lag_matching`).

**Tracker file** (:func:`write_tracker_file`): one line per sample, ``time [s]`` on the same
clock as the encoder log's (a tracker's software on the robot computer, or a clock kept within
a few ms of it, e.g. by NTP; or on another clock, its offset given or estimated from the
motion both saw: :mod:`~.clock`), then the pose of the platform frame E in the base frame B,
``phi [rad]``, ``theta [rad]``, ``psi [rad]``, ``X [m]``, ``Y [m]``, ``Z [m]`` (other units of
:data:`~.files.ANGLE_UNITS`, :data:`~.files.LENGTH_UNITS` and ``ms`` for time are converted;
other columns are read past).

**The join** (:func:`join`): for each pose of the path's windows file (``<stem>_windows.csv``
of ``calibrate --plan``), the encoder log's lines whose ``t_path`` is in the pose's window give
the window on the shared clock (their first and last ``time``); the mean of those readings and
the mean of the tracker's poses in that interval (rotations averaged as rotations) are the
pose's measurement. Every file is read through :func:`~stewart_drake.base.fileio.read_checked`
and parsed as numbers only.
"""

from __future__ import annotations

import io
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from ..base.columns import header_cell, read_csv_columns
from ..base.errors import InvalidConfigError
from ..base.fileio import atomic_write
from ..base.units import ANGLE_UNITS, LENGTH_UNITS, UNITS
from .clock import ClockOffset, estimate_clock_offset, poses_at
from .files import POSE_COLUMNS, READING_COLUMNS

#: Largest file the join reads, bytes (a day of a 100 Hz log).
MAX_LOG_BYTES = 2e9
#: Units of a time column: factor to s (the one table's, a log's two).
TIME_UNITS = {unit: UNITS["s"][unit] for unit in ("s", "ms")}
#: The columns of each file, with their kind ("time", "angle", "length").
ENCODER_LOG_COLUMNS = {"time": "time", "t_run": "time", "t_path": "time"} | {
    n: "angle" for n in READING_COLUMNS
}
#: The encoder log's columns of a run with a surrogate on the bus: its carriage's position
#: read (``s``), commanded (``s_cmd``: its reference at the run's time less ``s_delay``) and
#: its reference on the run's clock (``s_ref``), and the lag matching's delay (``s_delay``).
SURROGATE_LOG_COLUMNS = {"s": "length", "s_cmd": "length", "s_ref": "length", "s_delay": "time"}
POSE_KINDS = {n: ("angle" if k < 3 else "length") for k, n in enumerate(POSE_COLUMNS)}
TRACKER_COLUMNS = {"time": "time"} | POSE_KINDS
WINDOW_COLUMNS = {"t_start": "time", "t_end": "time"} | POSE_KINDS
#: Fewest tracker samples a pose's window must hold.
MIN_TRACKER_SAMPLES = 3
#: How far a window's mean tracked pose may be from the planned pose (rad, m): beyond it, the
#: clocks or the tracker's frames are not the robot's.
MAX_POSE_GAP = (0.05, 0.01)
_UNITS = {"time": TIME_UNITS, "angle": ANGLE_UNITS, "length": LENGTH_UNITS}
_SI = {"time": "s", "angle": "rad", "length": "m"}


def _header_text(columns: dict) -> str:
    return ",".join(f"{n} [{_SI[kind]}]" for n, kind in columns.items())


def read_table(path, what: str, columns: dict, remedy: str, nan_ok=(), comments=None) -> dict:
    """The columns ``columns`` ({name: kind}) of the CSV at ``path``, in SI units: {name: (N,)
    array, "lines": (N,) the file's line of each row}. The first line names every column with
    its unit in brackets; lines starting with ``#`` are comments (the first few appended to
    ``comments``, a list, when given); other columns are read past. Read row by row
    (:func:`~stewart_drake.base.columns.read_csv_columns`): a day-long encoder log fits in
    about 2.5 times its size.

    Raises:
        MissingFileError: no such file.  CorruptFileError: not a regular file, too large, not
            UTF-8 or not CSV.  InvalidConfigError: too long for the memory; a column missing,
            twice, without a unit or with a unit of another kind; a cell that is not a finite
            number (``nan`` allowed in the columns ``nan_ok``), its line and column named; no
            rows.
    """
    path = Path(path)

    def columns_of(cells: list) -> dict:
        found: dict = {}
        for index, cell in enumerate(cells):
            name, unit = header_cell(cell)
            if name not in columns:
                continue
            table = _UNITS[columns[name]]
            if name in found:
                raise InvalidConfigError(f"{path}: the column {name!r} appears twice in the header")
            if unit not in table:
                raise InvalidConfigError(
                    f"{path}: column {name!r} has the unit [{unit}]: write it in one of "
                    f"{', '.join(f'[{u}]' for u in table)}"
                )
            found[name] = (index, table[unit])
        missing = [n for n in columns if n not in found]
        if missing:
            raise InvalidConfigError(
                f"{path}: the header lacks the column{'s' if len(missing) > 1 else ''} "
                f"{', '.join(missing)}; {remedy}"
            )
        return found

    out, lines = read_csv_columns(
        path, what, MAX_LOG_BYTES, remedy, columns_of, nan_ok, comments=comments
    )
    if not len(lines):
        raise InvalidConfigError(f"{path}: the {what} has no rows; {remedy}")
    return {name: out[name] for name in columns} | {"lines": lines}


ENCODER_LOG_REMEDY = (
    "give the <stem>_encoders.csv that `stewart-drake robot` wrote beside its .npz "
    "(docs/calibration.md)"
)
TRACKER_REMEDY = (
    "write a first line naming every column with its unit, time [s],phi [rad],theta [rad],"
    "psi [rad],X [m],Y [m],Z [m], time on the robot computer's clock (docs/calibration.md)"
)
WINDOWS_REMEDY = "give the POSES.csv that `calibrate --plan` wrote, its _windows.csv beside it"
PATH_COLUMNS = {"t": "time"} | POSE_KINDS
PATH_REMEDY = "give the POSES.csv that `calibrate --plan` wrote"


#: What an encoder log without its surrogate's column is told.
CARRIAGE_REMEDY = (
    "give the <stem>_encoders.csv of a run with the surrogate's servo on the bus "
    "(`stewart-drake robot INTERNAL --surrogate EXTERNAL`), whose s [m] is the carriage read by "
    "its servo's encoder"
)


def read_encoder_log(path, carriage: bool = False) -> dict:
    """The encoder log at ``path`` (module docstring), read and checked whole by
    :func:`read_table`: {"t_path": (n,) s, NaN on the lead-in's lines; "q": (n, 6) the
    encoders' raw readings, rad; "time", "t_run": (n,) s; "lines": (n,) each row's line in the
    file, "bus": what its ``# bus:`` line says its bus was, or "" (:func:`encoder_log_bus`)},
    and with ``carriage`` "s": (n,) m, the surrogate's carriage as its servo's encoder
    read it (never ``s_cmd``, its command). Columns are taken by name; any others (``s_cmd``,
    a later column) are read past.

    Raises:
        MissingFileError, CorruptFileError, InvalidConfigError: as :func:`read_table`; with
            ``carriage``, a log without the ``s`` column (a run without the surrogate's servo),
            the column and the file named in one line.
    """
    columns = ENCODER_LOG_COLUMNS | ({"s": "length"} if carriage else {})
    remedy = CARRIAGE_REMEDY if carriage else ENCODER_LOG_REMEDY
    comments: list[str] = []
    log = read_table(path, "encoder log", columns, remedy, nan_ok=("t_path",), comments=comments)
    q = np.column_stack([log.pop(n) for n in READING_COLUMNS])
    _check_log_magnitudes(path, log, q)
    return log | {"q": q, "bus": encoder_log_bus(comments)}


#: The largest encoder reading an encoder log may hold, rad (a multi-turn count of 2^31 on a
#: 4096-count encoder is 3.3e6 rad): beyond it the value is a broken file, not a crank.
MAX_READING_RAD = 1e7
#: The largest time an encoder log may hold, s (a run's clock, or seconds since 1970).
MAX_LOG_TIME_S = 1e10


def _check_log_magnitudes(path, log: dict, q: np.ndarray) -> None:
    """Refuse, before any arithmetic on them, readings, times or a carriage's ``s`` beyond any a
    run makes (a 1e308 overflows every sum), naming the line, the column and the value.

    Raises:
        InvalidConfigError: one line.
    """
    from ..base.checks import MAX_POSITION_M

    checks = [(name, q[:, j], MAX_READING_RAD, "rad") for j, name in enumerate(READING_COLUMNS)]
    checks += [
        (name, log[name], MAX_LOG_TIME_S, "s")
        for name in ("time", "t_run", "t_path")
        if name in log
    ]
    if "s" in log:
        checks.append(("s", log["s"], MAX_POSITION_M, "m"))
    for name, values, bound, unit in checks:
        size = np.abs(np.nan_to_num(np.asarray(values, dtype=float), nan=0.0))
        if size.size and size.max() > bound:
            r = int(np.argmax(size))
            raise InvalidConfigError(
                f"{path}, line {int(log['lines'][r])}: {name} = {float(values[r]):.4g} {unit}, "
                f"beyond the {bound:g} {unit} any run's log holds: the file is damaged or not "
                "an encoder log"
            )


def encoder_log_path(npz) -> Path:
    """The encoder log beside a robot run's ``.npz``: ``<stem>_encoders.csv``."""
    npz = Path(npz)
    return npz.with_name(f"{npz.stem}_encoders.csv")


#: The encoder log's comment line that says what its bus was (:func:`write_encoder_log`).
BUS_COMMENT = "# bus: "


def write_encoder_log(path, time_s, t_run, t_path, q, surrogate=None, bus: str = "") -> Path:
    """Write the encoder log (module docstring) at ``path`` atomically: ``time_s``, ``t_run``,
    ``t_path`` (n,) s, ``q`` (n, 6) rad; with ``surrogate`` = (s, s_cmd, s_ref, s_delay),
    (n,) each, m, m, m and s, four more columns (:data:`SURROGATE_LOG_COLUMNS`: the
    surrogate's carriage read by its servo's encoder, commanded in that period, its reference
    on the run's clock, the delay its command was taken with), or (s, s_cmd) alone, two (a
    carriage commanded along its reference itself, without lag matching); with ``bus``, a
    comment line under the header, ``# bus: <bus>`` (:data:`BUS_COMMENT`: whether the servos
    were emulated, in words; one line), which :func:`read_encoder_log` reads back; returns the
    path."""
    columns = [time_s, t_run, t_path, np.asarray(q).reshape(-1, 6)]
    header = ENCODER_LOG_COLUMNS
    if surrogate is not None:
        if len(surrogate) not in (2, len(SURROGATE_LOG_COLUMNS)):
            raise ValueError(
                f"surrogate: (s, s_cmd, s_ref, s_delay) or (s, s_cmd), got {len(surrogate)}"
            )
        columns += [np.asarray(c, dtype=float) for c in surrogate]
        header = header | dict(list(SURROGATE_LOG_COLUMNS.items())[: len(surrogate)])
    text = _header_text(header)
    if bus:
        text += "\n" + BUS_COMMENT + " ".join(str(bus).split())
    _write_csv(path, text, np.column_stack(columns))
    return Path(path)


def encoder_log_bus(comments) -> str:
    """What an encoder log says its bus was, from its comments' text (the ``# bus:`` line
    :func:`write_encoder_log` writes under the header), or "" for a log that says nothing of it
    (one written before the line existed, or by hand)."""
    tag = BUS_COMMENT[1:].strip()  # "bus:", the comment's text after its "#"
    for text in comments:
        if text.startswith(tag):
            return text[len(tag) :].strip()
    return ""


def write_tracker_file(path, time_s, poses) -> Path:
    """Write a tracker file (module docstring) at ``path`` atomically: ``time_s`` (n,) s,
    ``poses`` (n, 6) rad and m; returns the path."""
    values = np.column_stack([time_s, np.asarray(poses).reshape(-1, 6)])
    _write_csv(path, _header_text(TRACKER_COLUMNS), values)
    return Path(path)


def _write_csv(path, header: str, values: np.ndarray) -> None:
    buffer = io.StringIO()
    buffer.write(header + "\n")
    np.savetxt(buffer, values, delimiter=",", fmt="%.17g")
    text = buffer.getvalue()
    atomic_write(Path(path), lambda f: f.write(text.encode()))


@dataclass(frozen=True)
class Joined:
    """The measurements of a session, one row per pose of the path's windows.

    Attributes:
        poses: (N, 6) the tracker's mean pose in each window, rad and m.
        readings: (N, 6) the encoders' mean readings there, rad.
        planned: (N, 6) the poses planned.
        windows: (N, 2) each window on the shared clock, s.
        readings_used, tracker_used: (N,) the encoder log's lines and the tracker's samples
            averaged.
        reading_spread: (N,) the largest standard deviation of a reading within its window,
            rad (0 for a platform at rest: quantized readings do not move).
        clock_offset_s: s added to the tracker's times (0: it stamped on the robot's clock).
        clock: the estimate of that offset (:class:`~.clock.ClockOffset`), or None when given.
    """

    poses: np.ndarray
    readings: np.ndarray
    planned: np.ndarray
    windows: np.ndarray
    readings_used: np.ndarray
    tracker_used: np.ndarray
    reading_spread: np.ndarray
    clock_offset_s: float = 0.0
    clock: ClockOffset | None = None


def mean_pose(poses) -> np.ndarray:
    """(6,) the mean of poses (N, 6): the rotations' mean as a rotation (roll-pitch-yaw of
    R_BE = Rz(psi) Ry(theta) Rx(phi)), the positions' mean."""
    poses = np.asarray(poses, dtype=float).reshape(-1, 6)
    rpy = Rotation.from_euler("ZYX", poses[:, 2::-1]).mean().as_euler("ZYX")[::-1]
    return np.concatenate([rpy, poses[:, 3:].mean(axis=0)])


def _is_estimate(clock_offset, path_file) -> bool:
    """Whether the tracker's clock offset is to be estimated (``"estimate"``), else a number.

    Raises:
        InvalidConfigError: neither a finite number nor ``"estimate"``; ``"estimate"`` without
            the path file.
    """
    estimate = isinstance(clock_offset, str) and clock_offset == "estimate"
    if not estimate and not (
        isinstance(clock_offset, (int, float)) and math.isfinite(clock_offset)
    ):
        raise InvalidConfigError(
            f"the tracker's clock offset must be a number of seconds or 'estimate', got "
            f"{clock_offset!r}"
        )
    if estimate and path_file is None:
        raise InvalidConfigError("estimating the tracker's clock offset needs the path file")
    return estimate


def _check_gap(tracker_file, k: int, gap) -> None:
    """Refuse pose ``k``'s mean tracked pose ``gap`` (6,) (rad, m) from the planned one beyond
    :data:`MAX_POSE_GAP`: the tracker's frames are not B and E, or its clock is another.

    Raises:
        InvalidConfigError: naming the pose, the gap and what to give.
    """
    if np.max(gap[:3]) > MAX_POSE_GAP[0] or np.max(gap[3:]) > MAX_POSE_GAP[1]:
        raise InvalidConfigError(
            f"{tracker_file}: the mean tracked pose of pose {k} is {np.max(gap[:3]):.3g} rad "
            f"and {np.max(gap[3:]) * 1e3:.3g} mm from the planned one: the tracker must "
            f"measure the platform frame E in the base frame B, or its frames be given "
            f"(--registration REG.yaml, docs/calibration.md), on the robot's clock"
        )


def join(
    encoder_log, tracker_file, windows_file, clock_offset=0.0, path_file=None, registration=None
) -> Joined:
    """Join a session's files (module docstring): each a path, read and checked whole before
    anything is joined.

    Args:
        encoder_log, tracker_file, windows_file: the session's files.
        clock_offset: s added to the tracker's times to put them on the robot computer's clock
            (0: the tracker stamps on it), or ``"estimate"``: found from the motion both saw
            (:func:`~.clock.estimate_clock_offset`), which needs ``path_file``.
        path_file: the path ``calibrate --plan`` wrote (POSES.csv), read with ``"estimate"``.
        registration: the tracker's frames (:class:`~.registration.Registration`), when its
            poses are its marker's in its own frame: they are compared with the path (the
            clock's estimate, the gap to each planned pose) once converted to the base frame,
            and the poses joined stay the marker's in the tracker's frame (a measurements file
            that ``calibrate --registration`` reads).
    Returns:
        :class:`Joined`, its ``clock`` the offset applied.
    Raises:
        MissingFileError, CorruptFileError, InvalidConfigError: as :func:`read_table`; a window
            the encoder log does not reach (the run ended early, or drove another path); a
            window with fewer than :data:`MIN_TRACKER_SAMPLES` tracker samples (the clocks
            differ, or the tracker lost the target); a mean tracked pose beyond
            :data:`MAX_POSE_GAP` of the planned pose (the tracker's frames are not B and E);
            an offset that is neither a finite number nor ``"estimate"``, ``"estimate"``
            without ``path_file`` or refused by :func:`~.clock.estimate_clock_offset`.
    """
    estimate = _is_estimate(clock_offset, path_file)
    log = read_encoder_log(encoder_log)
    tracker = read_table(tracker_file, "tracker file", TRACKER_COLUMNS, TRACKER_REMEDY)
    plan = read_table(windows_file, "windows file", WINDOW_COLUMNS, WINDOWS_REMEDY)
    q_log = log["q"]
    x_tracker = np.column_stack([tracker[n] for n in POSE_COLUMNS])
    x_base = x_tracker if registration is None else registration.base_poses(x_tracker)
    planned = np.column_stack([plan[n] for n in POSE_COLUMNS])
    clock = None
    if estimate:
        clock = _estimated_offset(log, tracker["time"], x_base, path_file)
        clock_offset = clock.offset_s
    tracker["time"] = tracker["time"] + float(clock_offset)
    n = len(planned)
    poses, readings = np.empty((n, 6)), np.empty((n, 6))
    windows, spread = np.empty((n, 2)), np.empty(n)
    n_log, n_tracker = np.empty(n, dtype=int), np.empty(n, dtype=int)
    for k in range(n):
        a, b = plan["t_start"][k], plan["t_end"][k]
        rows = (log["t_path"] >= a) & (log["t_path"] <= b)
        if not np.any(rows):
            raise InvalidConfigError(
                f"{encoder_log}: no reading in the window of pose {k} ([{a:g}, {b:g}] s of the "
                f"path, line {plan['lines'][k]} of {windows_file}): the run ended before it or "
                f"drove another path; drive the whole path (stewart-drake robot POSES.csv)"
            )
        w0, w1 = float(log["time"][rows].min()), float(log["time"][rows].max())
        samples = (tracker["time"] >= w0) & (tracker["time"] <= w1)
        if samples.sum() < MIN_TRACKER_SAMPLES:
            span = f"{tracker['time'].min():.3f} .. {tracker['time'].max():.3f}"
            raise InvalidConfigError(
                f"{tracker_file}: {int(samples.sum())} samples in the window of pose {k} "
                f"({w0:.3f} .. {w1:.3f} s on the robot's clock; the file spans {span} s): its "
                f"time [s] must be on the robot computer's clock (s since the epoch) or its "
                f"offset given (calibrate --join ... --tracker-clock-offset SECONDS, or "
                f"estimate to find it from the motion), at least {MIN_TRACKER_SAMPLES} "
                f"samples a window"
            )
        poses[k] = mean_pose(x_tracker[samples])
        readings[k] = q_log[rows].mean(axis=0)
        spread[k] = float(np.max(q_log[rows].std(axis=0)))
        windows[k], n_log[k], n_tracker[k] = (w0, w1), rows.sum(), samples.sum()
        _check_gap(tracker_file, k, np.abs(mean_pose(x_base[samples]) - planned[k]))
    return Joined(
        poses, readings, planned, windows, n_log, n_tracker, spread, float(clock_offset), clock
    )


def _estimated_offset(log: dict, tracker_t, x_tracker, path_file) -> ClockOffset:
    """The tracker's clock offset from the encoder log's lines on the path (their ``t_path``
    put on the path file's poses) and the tracked poses."""
    path = read_table(path_file, "path file", PATH_COLUMNS, PATH_REMEDY)
    on = np.isfinite(log["t_path"])
    if not np.any(on):
        raise InvalidConfigError(
            "the encoder log has no line on the path (t_path is nan throughout): drive the "
            "path (stewart-drake robot POSES.csv)"
        )
    x_path = np.column_stack([path[n] for n in POSE_COLUMNS])
    t_path = log["t_path"][on]
    planned = poses_at(t_path, path["t"], x_path)
    return estimate_clock_offset(log["time"][on], planned, tracker_t, x_tracker)
