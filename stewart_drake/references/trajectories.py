"""Reference trajectories x_d(t) of the platform pose and their validation before a run.

A trajectory is any object with ``evaluate(t)`` mapping times t (s) to pose, rate and
acceleration, each ``t.shape + (6,)`` in [rad, rad, rad, m, m, m] (and /s, /s^2).
:func:`as_trajectory` accepts more and adapts it: an ``evaluate`` that takes one time only, a Drake
``Trajectory`` (e.g. a ``PiecewisePolynomial``), a CSV file of ``t, phi, theta, psi, X, Y, Z``
or a registered name. :func:`validate` checks one before a run;
:mod:`~stewart_drake.run.reference` puts one into a Diagram. What a reference is:
:class:`~.motion.Reference`.

A scenario chooses these references by :class:`NamedReference`, :class:`CsvReference`,
:class:`SineReference` and :class:`DataCollectionReference`, whose field types Drake's YAML
loader reads: this module must not use ``from __future__ import annotations``.
"""

import csv
import functools
import io
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np
from pydrake.trajectories import Trajectory

from ..base.checks import MAX_SEED, as_array, as_number, as_poses, check_int
from ..base.errors import InvalidConfigError
from ..robot import kinematics, limits
from ..robot.geometry import X_HOME, StewartGeometry
from ..robot.kinematics import AXIS_NAMES
from ..robot.trajectory_report import TrajectoryReport, merge_reports
from .motion import Reference, ReferenceConfig


def check_sine_bounds(trajectory) -> None:
    """Refuse a sine whose pose, rate or acceleration would overflow float64.

    Args:
        trajectory: a SineTrajectory (amplitude, frequency_hz, offset: 6 finite floats each).
    Raises:
        InvalidConfigError: |offset| + |A|, |A| 2 pi f or |A| (2 pi f)^2 not finite, naming the
            axis, so that ``evaluate`` is finite at every finite time.
    """
    A, f = np.abs(trajectory.amplitude), np.abs(trajectory.frequency_hz)
    with np.errstate(over="ignore", invalid="ignore"):
        w = 2 * np.pi * f
        peaks = np.stack([np.abs(trajectory.offset) + A, A * w, A * w * w])
    if not np.isfinite(peaks).all():
        axis = int(np.argwhere(~np.isfinite(peaks))[0][1])
        raise InvalidConfigError(
            f"{trajectory.name}: axis {axis} overflows float64 (amplitude "
            f"{A[axis]:.3g}, frequency {f[axis]:.3g} Hz); use SI units"
        )


def _check_offset(trajectory) -> None:
    """Set ``trajectory.offset`` to a tuple of 6 floats, or refuse it (NaN, inf, wrong size,
    a position beyond 1 km) naming the trajectory."""
    offset = as_poses(f"{trajectory.name}: offset", trajectory.offset)
    if offset.shape != (6,):
        raise InvalidConfigError(
            f"{trajectory.name}: offset must be one pose (6,) [phi, theta, "
            f"psi, X, Y, Z], got shape {offset.shape}"
        )
    object.__setattr__(trajectory, "offset", tuple(float(v) for v in offset))


@dataclass(frozen=True)
class SineTrajectory:
    """x_d(t) = offset + amplitude * sin(2 pi f t + phase), axis by axis.

    Attributes:
        amplitude: (6,) in rad and m.  frequency_hz: (6,) in Hz.  phase: (6,) in rad.
        offset: (6,) centre pose (default home).  name: label used in result files.
    """

    amplitude: tuple = (0.0,) * 6
    frequency_hz: tuple = (0.0,) * 6
    phase: tuple = (0.0,) * 6
    offset: tuple = tuple(X_HOME)
    name: str = "sine"

    def __post_init__(self):
        for attr in ("amplitude", "frequency_hz", "phase", "offset"):
            v = as_array(f"{self.name}: {attr}", getattr(self, attr), shape=(6,))
            object.__setattr__(self, attr, tuple(float(c) for c in v))
        check_sine_bounds(self)

    def evaluate(self, t):
        """Pose, rate, acceleration at times t: three (..., 6) arrays (t scalar gives (6,))."""
        t = np.asarray(t, dtype=float)[..., None]
        A, w = np.asarray(self.amplitude), 2 * np.pi * np.asarray(self.frequency_hz)
        arg = w * t + np.asarray(self.phase)
        s, c = np.sin(arg), np.cos(arg)
        return np.asarray(self.offset) + A * s, A * w * c, -A * w * w * s


def paper_manoeuvre() -> SineTrajectory:
    """Paper eqs. 37-38: phi = (pi/6) sin 2t rad, Z = 0.05 sin 2t + 0.30 m, others 0."""
    f = 2.0 / (2 * np.pi)
    return SineTrajectory(
        amplitude=(np.pi / 6, 0, 0, 0, 0, 0.05), frequency_hz=(f, 0, 0, 0, 0, f), name="paper"
    )


def hold_home() -> SineTrajectory:
    """Stay at the home pose."""
    return SineTrajectory(name="home")


#: Step sizes of :func:`step` by default: 20 mrad for angles, 5 mm for positions.
STEP_SIZE = (0.02, 0.02, 0.02, 0.005, 0.005, 0.005)


def _axis_index(axis) -> int:
    if isinstance(axis, str):
        if axis not in AXIS_NAMES:
            raise InvalidConfigError(f"unknown axis {axis!r}; choose one of {AXIS_NAMES}")
        return AXIS_NAMES.index(axis)
    if not (isinstance(axis, (int, np.integer)) and 0 <= axis < 6):
        raise InvalidConfigError(f"axis must be 0..5 or one of {AXIS_NAMES}, got {axis!r}")
    return int(axis)


@dataclass(frozen=True)
class StepTrajectory:
    """A step of ``size`` on one axis at ``t_step``: x_d = offset + size e_axis H(t - t_step).

    Rate and acceleration are zero (the step is a reference, not a motion plan: its response
    gives the settling time). Attributes: axis 0..5, size in rad or m, t_step in s, offset (6,).
    """

    axis: int = 5
    size: float = 0.005
    t_step: float = 0.5
    offset: tuple = tuple(X_HOME)
    name: str = "step"

    def __post_init__(self):
        object.__setattr__(self, "axis", _axis_index(self.axis))
        object.__setattr__(self, "size", as_number(f"{self.name}: size", self.size))
        object.__setattr__(self, "t_step", as_number(f"{self.name}: t_step", self.t_step, 0.0))
        _check_offset(self)

    def evaluate(self, t):
        """Pose, rate, acceleration at times t: three (..., 6) arrays (t scalar gives (6,))."""
        t = np.asarray(t, dtype=float)[..., None]
        e = np.zeros(6)
        e[self.axis] = self.size
        x = np.asarray(self.offset) + e * (t >= self.t_step)
        return x, np.zeros_like(x), np.zeros_like(x)


@dataclass(frozen=True)
class ChirpTrajectory:
    """Exponential sine sweep on one axis, for the closed loop's frequency response.

    x_d = offset + A(t) sin(phase(t)) e_axis, instantaneous frequency
    f(t) = f0 (f1/f0)^(t/duration_s) Hz, phase(t) = 2 pi f0 T (k^(t/T) - 1) / ln k, k = f1/f0;
    after ``duration_s`` the sweep holds f1. The envelope A(t) = min(amplitude,
    max_acceleration / (2 pi f(t))^2) is the shaker test's constant-displacement,
    constant-acceleration profile: the full amplitude where the motors can give it, an amplitude
    falling as 1/f^2 above the corner where its acceleration would exceed what they give.

    Attributes: axis, amplitude (rad or m), f0_hz, f1_hz (> f0_hz), duration_s, offset (6,),
    max_acceleration (rad/s^2 or m/s^2; None: the amplitude at every frequency).
    """

    axis: int = 5
    amplitude: float = 2e-4
    f0_hz: float = 1.0
    f1_hz: float = 50.0
    duration_s: float = 8.0
    offset: tuple = tuple(X_HOME)
    name: str = "sweep"
    max_acceleration: float | None = None

    def __post_init__(self):
        object.__setattr__(self, "axis", _axis_index(self.axis))
        for name, lo in (("amplitude", None), ("f0_hz", 0.0), ("f1_hz", 0.0), ("duration_s", 0.0)):
            object.__setattr__(
                self,
                name,
                as_number(f"{self.name}: {name}", getattr(self, name), lo, lo_open=lo is not None),
            )
        if self.max_acceleration is not None:
            object.__setattr__(
                self,
                "max_acceleration",
                as_number(
                    f"{self.name}: max_acceleration", self.max_acceleration, 0.0, lo_open=True
                ),
            )
        if not self.f0_hz < self.f1_hz:
            raise InvalidConfigError(
                f"{self.name}: need f0_hz < f1_hz, got {self.f0_hz}, {self.f1_hz}"
            )
        _check_offset(self)

    def frequency(self, t) -> np.ndarray:
        """Instantaneous frequency f(t) in Hz."""
        t = np.minimum(np.asarray(t, dtype=float), self.duration_s)
        return self.f0_hz * (self.f1_hz / self.f0_hz) ** (t / self.duration_s)

    def phase(self, t) -> np.ndarray:
        """phase(t) in rad (continuous; linear in t after duration_s)."""
        t = np.asarray(t, dtype=float)
        T, k = self.duration_s, self.f1_hz / self.f0_hz
        tc = np.minimum(t, T)
        ph = 2 * np.pi * self.f0_hz * T * (k ** (tc / T) - 1) / np.log(k)
        return ph + 2 * np.pi * self.f1_hz * np.maximum(t - T, 0.0)

    def envelope(self, t) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The envelope A(t) and its first two time derivatives (rad or m, per s, per s^2)."""
        t = np.asarray(t, dtype=float)
        A = np.full(t.shape, float(abs(self.amplitude)))
        A_dot, A_ddot = np.zeros(t.shape), np.zeros(t.shape)
        if self.max_acceleration is not None:
            w = 2 * np.pi * self.frequency(t)
            limited = self.max_acceleration / (w * w)
            over = limited < A
            # A = a_max / w^2 with w = w0 k^(t/T): A' = -2 A ln k / T, A'' = (2 ln k / T)^2 A
            # while the sweep runs, constant once it holds f1.
            rate = np.where(
                t < self.duration_s, -2 * np.log(self.f1_hz / self.f0_hz) / self.duration_s, 0.0
            )
            A = np.where(over, limited, A)
            A_dot = np.where(over, rate * limited, 0.0)
            A_ddot = np.where(over, rate * rate * limited, 0.0)
        sign = 1.0 if self.amplitude >= 0 else -1.0
        return sign * A, sign * A_dot, sign * A_ddot

    def evaluate(self, t):
        """Pose, rate, acceleration at times t: three (..., 6) arrays (t scalar gives (6,))."""
        t = np.asarray(t, dtype=float)
        ph = self.phase(t)[..., None]
        w = 2 * np.pi * self.frequency(t)[..., None]
        T, k = self.duration_s, self.f1_hz / self.f0_hz
        w_dot = np.where(t[..., None] < T, w * np.log(k) / T, 0.0)
        A, A_dot, A_ddot = (v[..., None] for v in self.envelope(t))
        e = np.zeros(6)
        e[self.axis] = 1.0
        s, c = np.sin(ph), np.cos(ph)
        x = np.asarray(self.offset) + e * A * s
        x_dot = e * (A_dot * s + A * w * c)
        x_ddot = e * (A_ddot * s + 2 * A_dot * w * c + A * (w_dot * c - w * w * s))
        return x, x_dot, x_ddot


def step(axis) -> StepTrajectory:
    """A step of :data:`STEP_SIZE` on ``axis`` (name or index) at t = 0.5 s from home."""
    k = _axis_index(axis)
    return StepTrajectory(axis=k, size=STEP_SIZE[k], name=f"step_{AXIS_NAMES[k]}")


#: Amplitudes of :func:`sweep`: (rad on an angle, m on a position), where the motors follow it.
SWEEP_AMPLITUDE = (2e-3, 2e-4)
#: Accelerations that cap the sweep's amplitude at high frequency (rad/s^2, m/s^2): the largest
#: the motors follow at 50 Hz within the pre-run check's margin (90 % of the peak torque) with a
#: 20 % payload (0.8 mrad and 0.08 mm at 50 Hz); the corner, where the cap takes over, is 31.6 Hz.
SWEEP_MAX_ACCELERATION = (8e-4 * (2 * np.pi * 50.0) ** 2, 8e-5 * (2 * np.pi * 50.0) ** 2)


def sweep(axis="Z") -> ChirpTrajectory:
    """A 1 -> 50 Hz sweep over 8 s on ``axis``, then held at 50 Hz: :data:`SWEEP_AMPLITUDE`
    (0.2 mm on a position, 2 mrad on an angle) up to the corner where its acceleration reaches
    :data:`SWEEP_MAX_ACCELERATION`, then falling as 1/f^2 (0.08 mm, 0.8 mrad at 50 Hz)."""
    k = _axis_index(axis)
    i = 1 if k >= 3 else 0
    return ChirpTrajectory(
        axis=k,
        amplitude=SWEEP_AMPLITUDE[i],
        max_acceleration=SWEEP_MAX_ACCELERATION[i],
        name=f"sweep_{AXIS_NAMES[k]}",
    )


def helix() -> SineTrajectory:
    """Surgical-style path: a 5 mm circle in X-Y at 2 Hz while Z rises and falls 3 mm at
    0.25 Hz, with a 20 mrad wobble of the tool axis (theta) at 1 Hz; well inside the workspace."""
    return SineTrajectory(
        amplitude=(0, 0.02, 0, 0.005, 0.005, 0.003),
        frequency_hz=(0, 1.0, 0, 2.0, 2.0, 0.25),
        phase=(0, 0, 0, np.pi / 2, 0, 0),
        name="helix",
    )


TRAJECTORIES: dict[str, Callable[[], Any]] = {
    "paper": paper_manoeuvre,
    "home": hold_home,
    "helix": helix,
    **{f"step_{a}": functools.partial(step, a) for a in AXIS_NAMES},
    **{f"sweep_{a}": functools.partial(sweep, a) for a in AXIS_NAMES},
}


def make_trajectory(name: str):
    """A trajectory by name: "paper", "home", "helix", "step_<axis>", "sweep_<axis>" with axis
    one of phi, theta, psi, X, Y, Z.

    Raises:
        InvalidConfigError: unknown name (the message lists the known ones).
    """
    try:
        return TRAJECTORIES[name]()
    except KeyError:
        raise InvalidConfigError(
            f"unknown trajectory {name!r}; choose one of {sorted(TRAJECTORIES)}"
        ) from None


class ScalarEvaluate:
    """Adapter for an ``evaluate(t)`` that takes one time at a time: evaluates it per sample.

    Args:
        source: object whose ``evaluate(t: float)`` returns (pose, rate, acceleration), each (6,).
        name: label used in result files (default ``source.name`` or "custom").
    """

    def __init__(self, source, name: str | None = None):
        self.source = source
        self.name: str = name or str(getattr(source, "name", "custom"))

    def evaluate(self, t):
        """Pose, rate, acceleration at times t: three ``t.shape + (6,)`` arrays."""
        t = np.asarray(t, dtype=float)
        rows = [self.source.evaluate(float(tk)) for tk in t.reshape(-1)]
        return tuple(
            np.array([np.reshape(r[k], 6) for r in rows], dtype=float).reshape(t.shape + (6,))
            for k in range(3)
        )


class DrakeTrajectory:
    """A Drake ``Trajectory`` of the pose (6 rows, 1 column) as a reference: pose from
    ``value``, rate and acceleration from ``MakeDerivative(1)`` and ``MakeDerivative(2)``.

    Args:
        trajectory: a ``pydrake.trajectories.Trajectory`` with rows() == 6, cols() == 1, twice
            differentiable (e.g. ``PiecewisePolynomial.CubicWithContinuousSecondDerivatives``).
        name: label used in result files.
    Attributes:
        end_time: the trajectory's last time, s; a run may not last longer.
    Raises:
        InvalidConfigError: not a 6 x 1 trajectory.
    """

    def __init__(self, trajectory, name: str = "drake_trajectory"):
        if not isinstance(trajectory, Trajectory) or (trajectory.rows(), trajectory.cols()) != (
            6,
            1,
        ):
            shape = (
                (trajectory.rows(), trajectory.cols())
                if isinstance(trajectory, Trajectory)
                else type(trajectory).__name__
            )
            raise InvalidConfigError(
                f"a Drake reference must be a Trajectory of 6 rows and 1 "
                f"column ([phi, theta, psi, X, Y, Z]), got {shape}"
            )
        self.trajectory = trajectory
        self._derivatives = (trajectory, trajectory.MakeDerivative(1), trajectory.MakeDerivative(2))
        self.start_time, self.end_time = trajectory.start_time(), trajectory.end_time()
        self.name = name

    def evaluate(self, t):
        """Pose, rate, acceleration at times t: three ``t.shape + (6,)`` arrays."""
        t = np.asarray(t, dtype=float)
        flat = t.reshape(-1).tolist()
        return tuple(
            np.asarray(d.vector_values(flat)).T.reshape(t.shape + (6,)) for d in self._derivatives
        )


class CubicSplineTrajectory:
    """Samples of the pose joined by a cubic spline with continuous second derivatives (the
    not-a-knot spline, ``scipy.interpolate.CubicSpline``): pose, rate and acceleration, held at
    the end values' times outside the samples (the time is clamped, as Drake's
    ``PiecewisePolynomial`` does).

    It is the spline Drake's ``PiecewisePolynomial.CubicWithContinuousSecondDerivatives(t,
    samples, False)`` builds (the two agree to 1e-14), held as four coefficient arrays of shape
    (n - 1, 6): about 0.6 kB per sample with its derivatives where Drake's polynomial objects
    take 4 kB and, for a million samples, 35 s to build and differentiate.

    Args:
        t: (n,) sample times, s, strictly increasing; n >= 3.
        poses: (n, 6) the pose at each time [rad, rad, rad, m, m, m].
        name: label used in result files.
    Attributes:
        start_time, end_time: the first and last sample times, s; a run may not last longer.
    """

    def __init__(self, t, poses, name: str = "spline"):
        from scipy.interpolate import CubicSpline

        t, poses = np.asarray(t, dtype=float), np.asarray(poses, dtype=float)
        spline = CubicSpline(t, poses, axis=0, bc_type="not-a-knot")
        self._derivatives = (spline, spline.derivative(1), spline.derivative(2))
        self.start_time, self.end_time = float(t[0]), float(t[-1])
        self.name = name

    def evaluate(self, t):
        """Pose, rate, acceleration at times t: three ``t.shape + (6,)`` arrays."""
        t = np.clip(np.asarray(t, dtype=float), self.start_time, self.end_time)
        return tuple(d(t) for d in self._derivatives)


CSV_COLUMNS = ("t",) + AXIS_NAMES


#: Largest reference CSV read, bytes (about six million rows of seven numbers).
MAX_CSV_BYTES = 1e9
#: Memory a run holds per row of a reference CSV, bytes: measured 0.44 kB at the peak of
#: `stewart-drake run` (a 2e5-row file against a 1e3-row one over the same 10 s: the spline's
#: coefficients and its derivatives'), and 0.93 kB per 7-column row while the text is parsed,
#: with slack.
CSV_BYTES_PER_ROW = 1.5e3
#: Closest sample times of a reference CSV, s (Drake's spline refuses 2.2e-16 and its
#: accelerations reach 1e18 at 1e-9 s), and the latest time, s (cubic terms of 1e300 s segments
#: overflow inside Drake, which aborts the process).
CSV_MIN_DT_S = 1e-6
CSV_MAX_T_S = 1e7


def _read_csv_bytes(path: Path) -> bytes:
    from ..base.errors import MissingFileError
    from ..base.fileio import read_checked

    if not path.exists():
        raise MissingFileError(f"no reference CSV at {path}: check the path")
    return read_checked(
        path,
        "reference CSV",
        MAX_CSV_BYTES,
        "write it with the header t,phi,theta,psi,X,Y,Z (s, rad, m)",
    )


def csv_rows(raw: bytes, path, kind: str, remedy: str) -> list[list[str]]:
    """The rows of CSV bytes (UTF-8, with or without a byte-order mark).

    Raises:
        CorruptFileError: not UTF-8 text, or not CSV (a NUL byte, a field beyond the csv
            module's limit); names ``path`` as a ``kind`` and says ``remedy``.
    """
    from ..base.errors import CorruptFileError
    from ..base.fileio import decode_text

    text = decode_text(raw, path, kind, remedy, encoding="utf-8-sig")
    try:
        return list(csv.reader(io.StringIO(text, newline="")))
    except csv.Error as err:
        raise CorruptFileError(path, kind, f"not CSV ({err})", remedy) from None


def csv_reference_bytes(path) -> float:
    """Memory a run holds for the reference CSV ``path``, bytes (its lines times
    :data:`CSV_BYTES_PER_ROW`), counted before anything is parsed.

    Raises:
        MissingFileError: no such file. CorruptFileError: not a regular file, or larger than
            :data:`MAX_CSV_BYTES`.
    """
    return (_read_csv_bytes(Path(path)).count(b"\n") + 1) * CSV_BYTES_PER_ROW


def load_csv_trajectory(path) -> "CubicSplineTrajectory":
    """A reference from a CSV file: header ``t,phi,theta,psi,X,Y,Z`` (s, rad, m), one row per
    sample, times strictly increasing from 0; at least 3 rows. The samples are joined by a cubic
    spline with continuous second derivatives (:class:`CubicSplineTrajectory`), which gives the
    rate and the acceleration the controller and the feed-forward need. The file is read through
    the checked path (a regular file of at most :data:`MAX_CSV_BYTES`), its memory
    (:func:`csv_reference_bytes`) checked against the machine's before it is parsed; UTF-8, with
    or without a byte-order mark.

    Returns:
        :class:`CubicSplineTrajectory` named after the file's stem; its ``end_time`` bounds the
        run.
    Raises:
        MissingFileError: no such file. CorruptFileError: not a regular file, too large, not
            UTF-8 text, or not CSV (a NUL byte, a field beyond the csv module's limit).
        InvalidConfigError: another header, a row that is not 7 numbers (its line named), a
            non-finite value, times not increasing from 0 by at least :data:`CSV_MIN_DT_S` or
            beyond :data:`CSV_MAX_T_S`, fewer than 3 rows, or more rows than the memory holds.
    """
    path = Path(path)
    data = _csv_samples(path)
    _check_csv_times(path, data[:, 0])
    as_poses(f"{path}: the poses", data[:, 1:])
    return CubicSplineTrajectory(data[:, 0], data[:, 1:], name=path.stem)


def _csv_samples(path: Path) -> np.ndarray:
    """(n, 7) the rows [t, pose] of a reference CSV, read through the checked path, its memory
    checked before it is parsed (see :func:`load_csv_trajectory`).

    Raises:
        MissingFileError, CorruptFileError, InvalidConfigError: as load_csv_trajectory.
    """
    from ..base.checks import check_memory

    raw = _read_csv_bytes(path)
    remedy = "write it as UTF-8 text with the header t,phi,theta,psi,X,Y,Z (s, rad, m)"
    rows_in_file = raw.count(b"\n") + 1
    check_memory(
        f"a reference of {rows_in_file} rows ({path})",
        rows_in_file * CSV_BYTES_PER_ROW,
        "sample the reference more coarsely (one row per control period is plenty)",
    )
    rows = csv_rows(raw, path, "reference CSV", remedy)
    del raw
    header = [h.strip() for h in rows[0]] if rows else []
    if tuple(header) != CSV_COLUMNS:
        # What the line holds is not quoted: a file named by mistake may be a private one.
        got = f"it has {len(header)} column{'s' if len(header) != 1 else ''} of other names"
        raise InvalidConfigError(
            f"{path}: the first line must be the header {','.join(CSV_COLUMNS)}; "
            + (got if header else "it is empty")
        )
    values = []
    for line, row in enumerate(rows[1:], start=2):
        if not row or all(not c.strip() for c in row):
            continue
        try:
            numbers = [float(c) for c in row]
        except ValueError:
            numbers = []
        if len(numbers) != 7 or not np.all(np.isfinite(numbers)):
            raise InvalidConfigError(
                f"{path}, line {line}: expected 7 finite numbers "
                f"(t [s], phi, theta, psi [rad], X, Y, Z [m]), got "
                f"{','.join(row)[:200]!r}"
            )
        values.append(numbers)
    del rows
    return np.array(values).reshape(-1, 7)


def _check_csv_times(path: Path, t: np.ndarray) -> None:
    """At least 3 samples, from 0 s, strictly increasing by at least :data:`CSV_MIN_DT_S`, up
    to :data:`CSV_MAX_T_S`.

    Raises:
        InvalidConfigError: names the file and what to change.
    """
    if len(t) < 3:
        raise InvalidConfigError(f"{path}: a reference needs at least 3 samples, got {len(t)}")
    if t[0] != 0.0 or np.any(np.diff(t) <= 0):
        raise InvalidConfigError(f"{path}: times must start at 0 s and strictly increase")
    if t[-1] > CSV_MAX_T_S:
        raise InvalidConfigError(
            f"{path}: the last time is {t[-1]:.6g} s; a reference ends by "
            f"{CSV_MAX_T_S:g} s (times are in s)"
        )
    k = int(np.argmin(np.diff(t)))
    if t[k + 1] - t[k] < CSV_MIN_DT_S:
        raise InvalidConfigError(
            f"{path}: samples must be at least {CSV_MIN_DT_S:g} s apart; "
            f"those at t = {t[k]:.6g} s and {t[k + 1]:.6g} s are "
            f"{t[k + 1] - t[k]:.3g} s apart (times are in s)"
        )


def as_trajectory(source) -> Reference:
    """A reference object with a vectorized ``evaluate`` from whatever the user gives.

    Args:
        source: a registered name (:data:`TRAJECTORIES`), a path to a ``.csv`` file
            (:func:`load_csv_trajectory`), a Drake ``Trajectory`` (:class:`DrakeTrajectory`),
            or an object with ``evaluate(t)``: used as is when it accepts an array of times and
            returns three ``(n, 6)`` arrays, else wrapped in :class:`ScalarEvaluate`.
    Returns:
        an object with ``evaluate(t)`` -> (pose, rate, acceleration), each ``t.shape + (6,)``,
        and a ``name``.
    Raises:
        InvalidConfigError: none of the above, or an ``evaluate`` whose output does not have
            three (6,) parts; MissingFileError: a CSV path that does not exist.
    """
    if isinstance(source, (str, Path)):
        if str(source).lower().endswith(".csv"):
            return load_csv_trajectory(source)
        return make_trajectory(str(source))
    if isinstance(source, Trajectory):
        return DrakeTrajectory(source)
    if not callable(getattr(source, "evaluate", None)):
        raise InvalidConfigError(
            f"a reference must be a name, a .csv path, a Drake Trajectory or "
            f"an object with evaluate(t); got {type(source).__name__}"
        )
    probe = np.array([0.0, 1e-3])
    try:
        out = source.evaluate(probe)
        if len(out) == 3 and all(np.shape(part) == (2, 6) for part in out):
            return source
    except Exception:  # noqa: BLE001 - an evaluate that takes one time only fails here
        pass
    wrapped = ScalarEvaluate(source)
    try:
        wrapped.evaluate(probe)
    except Exception as err:  # noqa: BLE001 - say what is wrong with the user's object
        raise InvalidConfigError(
            f"{type(source).__name__}.evaluate(t) must return (pose, rate, acceleration), each 6 "
            f"numbers [rad, m, /s, /s^2] for one t (or (n, 6) for n times): {err}"
        ) from None
    return wrapped


#: Samples :func:`validate` checks at once (5 s at 1 kHz; about 9 kB each while checked).
VALIDATE_CHUNK_SAMPLES = 5_000


def validate(
    trajectory: Reference,
    geometry: StewartGeometry,
    duration_s: float,
    dt: float = 1e-3,
    cond_threshold: float = limits.DEFAULT_COND_THRESHOLD,
    min_sigma_min_inv: float = limits.DEFAULT_MIN_SIGMA_MIN_INV,
    raise_refused: bool = True,
    progress=None,
    keep_series: bool = True,
    **checks,
) -> TrajectoryReport:
    """Sample a trajectory on [0, duration_s] every ``dt`` and validate it, in stretches of
    :data:`VALIDATE_CHUNK_SAMPLES` samples, so that the memory the check takes beyond its
    ``series`` does not grow with the duration.

    The samples go to :func:`~stewart_drake.robot.limits.validate_trajectory`, the one validator
    of a reference: finite pose, rate and acceleration; loop closure, motor travel, ball-joint
    cones; cond(J) and 1/sigma_max(J); with ``checks``, the clearance between parts and the
    motors' torque and speed; each failure naming its first time and leg, parts, motor or measure.

    Args:
        trajectory: an object with ``evaluate(t)`` -> (pose, rate, acceleration), each (n, 6).
        geometry: the robot. duration_s: s, > 0. dt: sampling period, s (the control period).
        cond_threshold, min_sigma_min_inv: singularity thresholds (see the validator).
        raise_refused: raise on the first refused sample (else only report it).
        progress: None, or an object with ``update(n)`` (a tqdm bar) told of each stretch's
            samples as it is checked.
        keep_series: keep the report's sample-by-sample ``series`` (for plots; about 0.3 kB a
            sample); False drops each stretch's.
        checks: keyword arguments of the validator (``clearance``, ``min_clearance_m``,
            ``motor_limits``, ``allow_infeasible``).
    Returns:
        :class:`~stewart_drake.robot.trajectory_report.TrajectoryReport`.
    Raises:
        InvalidConfigError, UnreachablePoseError, JointLimitError, SingularPoseError,
            InterferenceError, MotorLimitError: see
            :func:`~stewart_drake.robot.limits.validate_trajectory`; InvalidConfigError also for
            a duration beyond a reference's ``end_time`` (a CSV or Drake trajectory).
    """
    if not (np.isfinite(duration_s) and duration_s > 0):
        raise InvalidConfigError(f"duration must be > 0 s, got {duration_s}")
    end = getattr(trajectory, "end_time", None)
    if end is not None and duration_s > end + 1e-9:
        raise InvalidConfigError(
            f"the reference {getattr(trajectory, 'name', '')} ends at "
            f"t = {end:g} s: run at most that long (duration_s) or extend it"
        )
    t_all = np.arange(0.0, duration_s + 0.5 * dt, dt)
    reports = []
    for start in range(0, t_all.size, VALIDATE_CHUNK_SAMPLES):
        t = t_all[start : start + VALIDATE_CHUNK_SAMPLES]
        x, x_dot, x_ddot = trajectory.evaluate(t)
        report = limits.validate_trajectory(
            geometry,
            t,
            x,
            cond_threshold=cond_threshold,
            min_sigma_min_inv=min_sigma_min_inv,
            raise_refused=raise_refused,
            x_dot=x_dot,
            x_ddot=x_ddot,
            **checks,
        )
        reports.append(report if keep_series else replace(report, series={}))
        if progress is not None:
            progress.update(t.size)
    return merge_reports(reports)


#: Acceleration caps of the data-collection trajectories: rad/s^2 for angles, m/s^2 for positions.
DATA_ACCEL_CAP = (30.0, 30.0, 30.0, 3.0, 3.0, 3.0)
#: Fraction of the motors' limit the collection path's inverse-dynamics torques may use.
DATA_TORQUE_MARGIN = 0.7
#: Amplitudes the paper names for its data (angles +-pi/6 rad, translations 0.3 m).
PAPER_DATA_AMPLITUDE = (np.pi / 6, np.pi / 6, np.pi / 6, 0.3, 0.3, 0.3)


def _max_single_axis_amplitude(geometry: StewartGeometry, axis: int, ratio_max: float) -> float:
    """Largest a with home +- a e_axis reachable at ratio <= ratio_max (bisection)."""
    lo, hi = 0.0, PAPER_DATA_AMPLITUDE[axis]
    for _ in range(40):
        mid = 0.5 * (lo + hi)
        x = np.tile(X_HOME, (2, 1))
        x[0, axis] += mid
        x[1, axis] -= mid
        if np.all(np.abs(kinematics.leg_reach_ratio(geometry, x)) <= ratio_max):
            lo = mid
        else:
            hi = mid
    return lo


def _slack(
    geometry: StewartGeometry, x, ratio_max: float, cond_threshold: float, min_sigma_min_inv: float
) -> np.ndarray:
    """(n,) smallest margin of poses x (n, 6) over the checks of :func:`validate`, each
    normalized by its bound; < 0 where refused. Checks: closure at ``ratio_max``, motor travel,
    both ball-joint cones, then (only when every pose passes those: the SVD is the dear part)
    cond(J) and 1/sigma_max(J)."""
    theta, ratio = kinematics.ik_unchecked(geometry, x)
    margins = limits.limit_margins_unchecked(geometry, x, theta, ratio)
    travel = np.deg2rad(geometry.motor_angle_max_deg - geometry.motor_angle_min_deg) / 2
    slack = np.min(
        np.concatenate(
            [
                (ratio_max - np.abs(ratio)) / ratio_max,
                margins["motor_angle"] / travel,
                margins["crank_joint"] / np.deg2rad(geometry.crank_joint_cone_deg),
                margins["platform_joint"] / np.deg2rad(geometry.platform_joint_cone_deg),
            ],
            axis=-1,
        ),
        axis=-1,
    )
    slack = np.nan_to_num(slack, nan=-np.inf)
    if np.all(slack >= 0):
        cond, inv = kinematics.singularity_measures_unchecked(geometry, x, theta)
        singular = np.minimum(
            (cond_threshold - cond) / cond_threshold,
            (inv - min_sigma_min_inv) / max(min_sigma_min_inv, 1e-12),
        )
        slack = np.minimum(slack, np.nan_to_num(singular, nan=-np.inf))
    return slack


def data_collection_trajectory(
    seed: int = 0,
    geometry: StewartGeometry | None = None,
    duration_s: float = 10.0,
    ratio_max: float = 0.9,
    dt: float = 1e-3,
    cond_threshold: float = limits.DEFAULT_COND_THRESHOLD,
    min_sigma_min_inv: float = limits.DEFAULT_MIN_SIGMA_MIN_INV,
    torque_limit_Nm: float | None = None,
) -> SineTrajectory:
    """Excitation for the tuner's training data (paper section III.D), deterministic in ``seed``.

    Every axis moves at once, one sine each, with a frequency drawn in [1, 5] Hz and a random
    phase. The paper's amplitudes (+-pi/6 rad, 0.3 m) are far outside this robot's workspace, so
    each axis's amplitude is (a) capped by what that axis alone admits at |L|/sqrt(M^2+N^2) <=
    ``ratio_max``, (b) capped by DATA_ACCEL_CAP / (2 pi f)^2 so the torques stay physical, then
    (c) all amplitudes are scaled by the largest factor (bisection) with which the path passes
    every check of the pre-run validation (:func:`validate` sampled every ``dt`` over
    ``duration_s``: loop closure at ``ratio_max``, motor travel, both ball-joint cones, cond(J)
    and 1/sigma_max(J) with the given thresholds, GuardConfig's by default). The bisection runs
    on the critical samples only and is confirmed on all of them (docs/paper_notes.md).

    Args:
        seed: random seed of frequencies and phases. geometry: the robot (default reference).
        duration_s: s the path must pass over. ratio_max: closure bound, < 1. dt: sampling, s
            (the control period the pre-run check uses).
        cond_threshold, min_sigma_min_inv: singularity thresholds (GuardConfig's defaults).
        torque_limit_Nm: the motors' limit, N m, or None. With one, (d) the amplitudes shrink
            further until the inverse-dynamics torques of the path (gravity, inertia and
            velocity products, rotors included) stay within :data:`DATA_TORQUE_MARGIN` of it
            (the pre-run check then adds the friction against its own margin): the motors keep
            headroom for feedback (ours: the paper's robot has no limit; on the robot as built,
            without this every run of the collection loses the platform in 0.2 s).
    Returns:
        SineTrajectory named ``data_seed<seed>`` that ``validate(..., dt=dt)`` accepts.
    """
    geometry = geometry or StewartGeometry()
    rng = np.random.default_rng(seed)
    f = rng.uniform(1.0, 5.0, 6)
    phase = rng.uniform(0, 2 * np.pi, 6)
    single = np.array([_max_single_axis_amplitude(geometry, k, ratio_max) for k in range(6)])
    amp = np.minimum(single, np.asarray(DATA_ACCEL_CAP) / (2 * np.pi * f) ** 2)
    t = np.arange(0.0, duration_s + 0.5 * dt, dt)  # the samples of validate()

    def path(scale, times=t):
        return SineTrajectory(
            amplitude=tuple(scale * amp), frequency_hz=tuple(f), phase=tuple(phase)
        ).evaluate(times)

    scale = _scale_within_checks(
        geometry,
        lambda sc, k=slice(None): path(sc, t[k])[0],
        (ratio_max, cond_threshold, min_sigma_min_inv),
    )
    if torque_limit_Nm is not None:
        scale = _scale_within_torque(
            geometry, lambda sc: path(sc, t[::5]), scale, DATA_TORQUE_MARGIN * torque_limit_Nm
        )
    return SineTrajectory(
        amplitude=tuple(scale * amp),
        frequency_hz=tuple(f),
        phase=tuple(phase),
        name=f"data_seed{seed}",
    )


def _scale_within_checks(geometry: StewartGeometry, poses, checks: tuple) -> float:
    """The largest factor s <= 1 (bisection, a hair inside) with which ``poses(s, k)`` (the
    path's poses at the samples k, all by default) passes the checks of :func:`_slack`. The
    bisection runs on the samples that refused a scale so far, and each round is confirmed on
    all of them."""
    scale, critical = 1.0, np.zeros(0, dtype=int)
    for _ in range(20):  # each round adds the samples that refused the scale
        slack = _slack(geometry, poses(scale), *checks)
        if np.all(slack >= 0):
            break
        critical = np.union1d(
            critical, np.union1d(np.flatnonzero(slack < 0), np.argsort(slack)[:64])
        )
        lo, hi = 0.0, scale
        for _ in range(40):
            mid = 0.5 * (lo + hi)
            fits = np.all(_slack(geometry, poses(mid, critical), *checks) >= 0)
            lo, hi = (mid, hi) if fits else (lo, mid)
        scale = lo * (1 - 1e-3)  # a hair inside: no pass or fail by round-off
    return scale


def _scale_within_torque(geometry: StewartGeometry, motion, scale: float, bound: float) -> float:
    """``scale``, or the largest factor below it (bisection) with which the inverse-dynamics
    torques of ``motion(s)`` (pose, rate, acceleration) stay within ``bound``, N m."""
    from ..robot.statics import inverse_dynamics_torques

    def peak(sc):
        return np.abs(inverse_dynamics_torques(geometry, *motion(sc))).max()

    if peak(scale) > bound:
        lo, hi = 0.0, scale
        for _ in range(30):
            mid = 0.5 * (lo + hi)
            lo, hi = (mid, hi) if peak(mid) <= bound else (lo, mid)
        scale = lo
    return scale


# -- a scenario's choices of these references ------------------------------------------------------


@dataclass
class NamedReference(ReferenceConfig):
    """A reference of :data:`TRAJECTORIES`: "paper" (eqs. 37-38), "home", "helix",
    "step_<axis>", "sweep_<axis>"."""

    name: str = "paper"

    def validate(self) -> None:
        make_trajectory(self.name)  # unknown name: lists the known ones

    def make(
        self, geometry: StewartGeometry, duration_s: float, torque_limit_Nm: float | None
    ) -> Reference:
        return make_trajectory(self.name)


@dataclass
class CsvReference(ReferenceConfig):
    """A reference from a CSV file ``t,phi,theta,psi,X,Y,Z`` (s, rad, m), joined by a C2 cubic
    spline (:func:`load_csv_trajectory`). A relative path is relative to the working folder."""

    path: str = ""

    def validate(self) -> None:
        from ..base.errors import MissingFileError

        if not self.path or not Path(self.path).exists():
            raise MissingFileError(
                f"no reference CSV at {self.path!r} (reference.path): check the path"
            )

    def make(
        self, geometry: StewartGeometry, duration_s: float, torque_limit_Nm: float | None
    ) -> Reference:
        return load_csv_trajectory(self.path)

    @property
    def label(self) -> str:
        return Path(self.path).stem

    def memory_bytes(self) -> float:
        """The spline of the file's samples (:func:`csv_reference_bytes`)."""
        return csv_reference_bytes(self.path)

    def memory_note(self) -> tuple:
        return (f" on the reference {self.path}", ", and sample the reference CSV more coarsely")


@dataclass
class SineReference(ReferenceConfig):
    """x_d(t) = offset + amplitude sin(2 pi f t + phase), axis by axis (6 values each: rad, m,
    Hz, rad); see :class:`SineTrajectory`."""

    amplitude: list[float] = field(default_factory=lambda: [0.0] * 6)
    frequency_hz: list[float] = field(default_factory=lambda: [0.0] * 6)
    phase: list[float] = field(default_factory=lambda: [0.0] * 6)
    offset: list[float] = field(default_factory=lambda: [0.0, 0.0, 0.0, 0.0, 0.0, 0.30])
    name: str = "sine"

    def validate(self) -> None:
        self._sine()  # checks shapes and overflow

    def make(
        self, geometry: StewartGeometry, duration_s: float, torque_limit_Nm: float | None
    ) -> Reference:
        return self._sine()

    def _sine(self) -> SineTrajectory:
        return SineTrajectory(
            amplitude=tuple(self.amplitude),
            frequency_hz=tuple(self.frequency_hz),
            phase=tuple(self.phase),
            offset=tuple(self.offset),
            name=self.name,
        )


@dataclass
class DataCollectionReference(ReferenceConfig):
    """The seeded excitation of the tuner's data collection (every axis at 1-5 Hz inside the
    workspace; :func:`data_collection_trajectory`), as long as the run, within the robot's
    workspace and its motors' torque limit."""

    seed: int = 0

    def validate(self) -> None:
        check_int("reference.seed", self.seed, 0, MAX_SEED)

    def make(
        self, geometry: StewartGeometry, duration_s: float, torque_limit_Nm: float | None
    ) -> Reference:
        return data_collection_trajectory(
            self.seed, geometry, duration_s=duration_s, torque_limit_Nm=torque_limit_Nm
        )

    @property
    def label(self) -> str:
        return f"data_seed{self.seed}"
