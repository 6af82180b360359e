"""References from samples of the pose: the C2 cubic spline through them
(:class:`CubicSplineTrajectory`, which recorded traces use too) and the reference CSV file of
``t, phi, theta, psi, X, Y, Z`` (:func:`load_csv_trajectory`, read through the checked path),
with :class:`CsvReference`, a scenario's choice of one.

Drake's YAML loader reads :class:`CsvReference`'s field types: this module must not use
``from __future__ import annotations``.
"""

import csv
import io
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..base.checks import as_poses
from ..base.errors import InvalidConfigError
from ..robot.geometry import StewartGeometry
from ..robot.kinematics import AXIS_NAMES
from .motion import Reference, ReferenceConfig


class CubicSplineTrajectory:
    """Samples of the pose joined by a cubic spline with continuous second derivatives (the
    not-a-knot spline, ``scipy.interpolate.CubicSpline``): pose, rate and acceleration, held at
    the end values' times outside the samples (the time is clamped, as Drake's
    ``PiecewisePolynomial`` does).

    It is the spline Drake's ``PiecewisePolynomial.CubicWithContinuousSecondDerivatives(t,
    samples, False)`` builds (the two agree to 1e-14), held as four coefficient arrays of shape
    (n - 1, 6): 0.2 kB per sample (its derivatives are made for the times asked, in
    :meth:`evaluate`) where Drake's polynomial objects take 4 kB and, for a million samples,
    35 s to build and differentiate.

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
        self._spline = CubicSpline(t, poses, axis=0, bc_type="not-a-knot")
        self.start_time, self.end_time = float(t[0]), float(t[-1])
        self.name = name

    def evaluate(self, t):
        """Pose, rate, acceleration at times t: three ``t.shape + (6,)`` arrays.

        The rate and acceleration are the spline's derivatives (``PPoly.derivative``) made for
        the intervals the times fall in only, not for the whole spline once: the same
        coefficients to the bit (each interval's are its own), without holding two more
        coefficient arrays (39 MB for a 25-minute trace)."""
        from scipy.interpolate import PPoly

        t = np.clip(np.asarray(t, dtype=float), self.start_time, self.end_time)
        spline = self._spline
        x = spline.x
        k = np.clip(np.searchsorted(x, t, side="right") - 1, 0, x.size - 2)
        a, b = (int(k.min()), int(k.max()) + 1) if k.size else (0, 1)
        piece = PPoly.construct_fast(spline.c[:, a:b], x[a : b + 1], spline.extrapolate, 0)
        return (spline(t), piece.derivative(1)(t), piece.derivative(2)(t))


CSV_COLUMNS = ("t",) + AXIS_NAMES
#: The same header with the columns' units written out (what ``stewart-drake calibrate --plan``
#: writes): the same file, the same units.
CSV_COLUMNS_WITH_UNITS = ("t [s]",) + tuple(
    f"{name} [{'rad' if k < 3 else 'm'}]" for k, name in enumerate(AXIS_NAMES)
)


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
    from ..base.fileio import check_parse_memory, read_checked

    if not path.exists():
        raise MissingFileError(f"no reference CSV at {path}: check the path")
    raw = read_checked(
        path,
        "reference CSV",
        MAX_CSV_BYTES,
        "write it with the header t,phi,theta,psi,X,Y,Z (s, rad, m)",
    )
    check_parse_memory(path, "reference CSV", raw, CSV_BYTES_PER_ROW)
    return raw


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
    """A reference from a CSV file: header ``t,phi,theta,psi,X,Y,Z`` (s, rad, m; or the same
    with the units written, :data:`CSV_COLUMNS_WITH_UNITS`), one row per
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
    if tuple(header) not in (CSV_COLUMNS, CSV_COLUMNS_WITH_UNITS):
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


__all__ = [
    "CubicSplineTrajectory",
    "CSV_COLUMNS",
    "CSV_COLUMNS_WITH_UNITS",
    "MAX_CSV_BYTES",
    "CSV_BYTES_PER_ROW",
    "CSV_MIN_DT_S",
    "CSV_MAX_T_S",
    "csv_rows",
    "csv_reference_bytes",
    "load_csv_trajectory",
    "CsvReference",
]
