"""Recorded traces of organ motion as references of the platform pose.

:func:`load_trace` reads a CSV of 1 to 6 axes whose header names each column and its unit
(``t [s], SI [mm], AP [mm], pitch [deg]``), at any sample rate and with gaps, maps the trace's
axes onto the platform's (platform or patient axis names, :data:`~.core.PATIENT_AXES`,
or a map of the trace's own names), resamples it to a C2 spline
(:class:`~.samples.CubicSplineTrajectory`), optionally low-passes it without
phase lag (``scipy.signal.filtfilt``) and centres it at a chosen pose (:data:`CENTRE_MODES`).
The result is a :class:`TraceTrajectory` that says what was read and done (:class:`TraceInfo`).
The project's own CSV (``t,phi,theta,psi,X,Y,Z`` in s, rad, m, its units written or not) is
read as it always was (:func:`~.samples.load_csv_trajectory`). :class:`TraceReference` is a
scenario's choice of a trace.

Drake's YAML loader reads :class:`TraceReference`'s field types: this module must not use
``from __future__ import annotations``.
"""

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..base.checks import as_array, as_number, as_poses
from ..base.errors import InvalidConfigError, MissingFileError
from ..base.trace_layouts import trace_formats
from ..robot.geometry import X_HOME, StewartGeometry
from ..robot.kinematics import AXIS_NAMES
from .motion import Reference, ReferenceConfig
from .organ.combinators import layered, scaled
from .organ.core import check_centre
from .organ.library import make_layers
from .samples import (
    CSV_BYTES_PER_ROW,
    CSV_COLUMNS,
    CSV_COLUMNS_WITH_UNITS,
    CubicSplineTrajectory,
    load_csv_trajectory,
)
from .trace_cleaning import MIN_LOOP_S, SEAM_BLEND_S, blend_seams, loop_seams, smoothed_spline
from .trace_files import (
    TraceTable,
    read_trace_table,
    repaired_words,
    trace_samples,
)

#: How a trace's samples are joined (``smoothing`` of :func:`load_trace`): a smoothing spline
#: that drops their measurement noise, or a cubic spline through every sample.
SMOOTHING_MODES = ("auto", "none")
#: Which pose of a trace goes to its centre (``centre_on`` of :func:`load_trace`): its mean, its
#: first sample, or none (the trace's values are displacements from the centre).
CENTRE_MODES = ("mean", "first", "none")


@dataclass(frozen=True)
class TraceInfo:
    """What :func:`load_trace` read and did.

    Attributes:
        path: the file.  columns: the trace's column names (time first).  units: their units.
        axes: the platform axis each column went to, with its sign ("+X", "-theta").
        samples: rows read.  sample_rate_hz: median rate of the file.
        gaps: ((start s, length s), ...) intervals longer than 2.5 samples without data on
            some axis, bridged by the spline.
        lowpass_hz: the zero-phase low-pass applied, or None.
        duration_s: length of the reference, s.  centred_on: "mean", "first" or "none".
        layout: how the file was read (its format, separator and decimal mark).
        removed: (6,) the pose taken off the trace to centre it (its mean or first sample on
            the trace's axes, rad and m; zeros for "none").
        dropped: what was left out as an export's artefact (a last line of zeros), or "".
        smoothing: "auto" (a smoothing spline per axis,
            :func:`~.trace_cleaning.smoothed_spline`) or "none".
        departures: ((axis, RMS departure of the reference from its samples, rad or m), ...).
        loop_period_s: the loop of a looped recording, s (0: not a loop;
            :func:`~.trace_cleaning.loop_seams`).  seams: its seams blended.
        seam_blend_s: the time each was blended over, s (0: left as recorded).
        seam_jumps: ((axis, largest jump taken out, rad or m), ...).
        start_s: the file's first time as written, s: the reference plays from its first
            sample at t = 0, and t + start_s is the file's own clock (two files recorded on one
            clock keep their relation through it: :func:`~.clock.on_clock_of`).
        repaired: a line per time repaired from the file's frame counter
            (:func:`~.trace_files.repaired_times`), or ().
    """

    path: str
    columns: tuple
    units: tuple
    axes: tuple
    samples: int
    sample_rate_hz: float
    gaps: tuple
    lowpass_hz: float | None
    duration_s: float
    centred_on: str
    layout: str = "csv"
    removed: tuple = (0.0,) * 6
    dropped: str = ""
    smoothing: str = "none"
    departures: tuple = ()
    loop_period_s: float = 0.0
    seams: int = 0
    seam_blend_s: float = 0.0
    seam_jumps: tuple = ()
    start_s: float = 0.0
    repaired: tuple = ()

    def centring(self) -> str:
        """What centring took off the trace, in words: ``its mean removed (Z -490.1 mm)``."""
        if self.centred_on == "none":
            return "not centred (its values are displacements from the centre)"
        what = "its mean" if self.centred_on == "mean" else "its first sample"
        values = [(axis[1:], self.removed[AXIS_NAMES.index(axis[1:])]) for axis in self.axes]
        return f"{what} removed ({_in_words(values, '.4g')})"

    def summary(self) -> str:
        gaps = ", ".join(f"{g[1]:.3g} s at t = {g[0]:.4g} s" for g in self.gaps) or "none"
        mapping = ", ".join(
            f"{c} [{u}] -> {a}" for c, u, a in zip(self.columns[1:], self.units[1:], self.axes)
        )
        return (
            f"{Path(self.path).name} ({self.layout}): {self.samples} samples at "
            f"{self.sample_rate_hz:.4g} Hz "
            f"over {self.duration_s:.4g} s; {mapping}; gaps bridged: {gaps}; "
            f"low-pass: {'none' if self.lowpass_hz is None else f'{self.lowpass_hz:g} Hz'}; "
            f"{self.smoothing_words()}; {self.seam_words()}; "
            f"centred: {self.centring()}"
            + (f"; left out: {self.dropped}" if self.dropped else "")
            + repaired_words(self.repaired)
        )

    def smoothing_words(self) -> str:
        """How the samples were joined, in words: ``joined without their noise (quintic
        smoothing spline, discrepancy principle): the reference departs from the samples by X
        0.012 mm, theta 0.004 deg RMS`` or ``joined through every sample (no smoothing)``."""
        if self.smoothing != "auto" or not self.departures:
            return "joined through every sample (no smoothing)"
        return (
            "joined without their noise (quintic smoothing spline, discrepancy principle): the "
            f"reference departs from the samples by {_in_words(self.departures, '.2g')} RMS"
        )

    def seam_words(self) -> str:
        """A looped recording's seams, in words: ``a loop of 62 s: 20 seams blended over 2 s
        (largest jump X 9.5 mm)``, ``not a loop``, or ``a loop of 62 s: its 20 seams left as
        recorded``."""
        if self.loop_period_s <= 0.0:
            return "not a loop"
        loop = f"a loop of {self.loop_period_s:.4g} s"
        if self.seams == 0:
            return f"{loop} without a seam"
        if self.seam_blend_s <= 0.0:
            return f"{loop}: its {self.seams} seams left as recorded"
        jumps = _in_words(self.seam_jumps, ".2g")
        return (
            f"{loop}: {self.seams} seam{'s' if self.seams > 1 else ''} blended over "
            f"{self.seam_blend_s:g} s "
            f"(largest jump {jumps})"
        )


def _in_words(values, fmt: str) -> str:
    """``X 9.5 mm, theta 0.2 deg`` of ((axis name, value in m or rad), ...)."""
    parts = []
    for axis, value in values:
        k = AXIS_NAMES.index(axis)
        scale, unit = (1e3, "mm") if k >= 3 else (180 / math.pi, "deg")
        parts.append(f"{axis} {value * scale:{fmt}} {unit}")
    return ", ".join(parts)


class TraceTrajectory(CubicSplineTrajectory):
    """A recorded trace as a reference: a :class:`~.samples.CubicSplineTrajectory` (C2 cubic
    spline through the resampled poses) with the trace's import record (``info``,
    :class:`TraceInfo`) and its ``centre`` pose, the fixed point of
    :class:`~.combinators.ScaledReference`."""

    def __init__(self, t, poses, info: TraceInfo, centre, name: str):
        super().__init__(t, poses, name=name)
        self.info = info
        self.centre = tuple(float(v) for v in centre)

    def frequencies_hz(self) -> dict:
        return {}


def _trace_grid(path: Path, t: np.ndarray, resample_hz: float) -> np.ndarray:
    """(m,) the times the trace is resampled at, s: every 1 / resample_hz from 0, and the
    trace's own end (its memory checked first).

    Raises:
        InvalidConfigError: a trace shorter than two resampling steps (the spline needs three
            samples), or one that needs more memory than the machine has.
    """
    from ..base.checks import check_memory

    if t[-1] < 2.0 / resample_hz:
        raise InvalidConfigError(
            f"{path}: the trace lasts {t[-1]:.4g} s, shorter than two resampling steps "
            f"({2.0 / resample_hz:g} s at {resample_hz:g} Hz): record a longer trace"
        )

    check_memory(
        f"a trace of {t[-1]:.4g} s resampled at {resample_hz:g} Hz ({path})",
        (t[-1] * resample_hz + 1) * CSV_BYTES_PER_ROW,
        "cut the trace into shorter files, or lower the resampling rate",
    )
    grid = np.arange(0.0, t[-1] - 0.5 / resample_hz, 1.0 / resample_hz)
    return np.append(grid, t[-1])  # the trace's own end


def _gaps(
    path: Path, name: str, tk: np.ndarray, t_end: float, rate: float, max_gap_s: float
) -> list:
    """[(start s, length s), ...] the intervals longer than 2.5 samples (at ``rate``, Hz)
    without data in one column sampled at tk (s) of a trace from 0 to t_end (s); refused
    beyond max_gap_s."""
    gaps = []
    spans = np.diff(np.concatenate([[0.0], tk, [t_end]]))
    starts = np.concatenate([[0.0], tk])
    for start, span in zip(starts, spans):
        if span > 2.5 / rate:
            if span > max_gap_s:
                raise InvalidConfigError(
                    f"{path}: column {name!r} has no data for {span:.3g} s from t = "
                    f"{start:.4g} s, more than max_gap_s = {max_gap_s:g} s (a spline would "
                    f"invent that motion); fill the gap or raise max_gap_s (--max-gap)"
                )
            gaps.append((float(start), float(span)))
    return gaps


#: Fewest samples an axis needs to be smoothed (fewer: joined through its samples).
MIN_SMOOTHED_SAMPLES = 10


def _resampled(
    path: Path,
    t,
    data,
    names,
    targets,
    factors,
    grid,
    rate: float,
    max_gap_s: float,
    smoothing: str = "auto",
) -> tuple[np.ndarray, list, dict]:
    """(displacement (m, 6) on the grid in rad and m, gaps bridged [(start s, length s)],
    {axis name: departure from its samples (rad or m)}): each axis column joined by a smoothing
    spline (:func:`~.trace_cleaning.smoothed_spline`; ``smoothing`` "none": a cubic spline
    through its samples); axes without a column zero."""
    from scipy.interpolate import CubicSpline

    displacement = np.zeros((grid.size, 6))
    gaps = []
    departures = {}
    for j, (k, factor) in enumerate(zip(targets, factors), start=1):
        ok = np.isfinite(data[:, j])
        if np.count_nonzero(ok) < 4:
            raise InvalidConfigError(f"{path}: column {names[j]!r} has fewer than 4 samples")
        tk = t[ok]
        gaps += _gaps(path, names[j], tk, t[-1], rate, max_gap_s)
        yk = data[ok, j] * factor
        if smoothing == "auto" and len(tk) >= MIN_SMOOTHED_SAMPLES:
            spline, departures[AXIS_NAMES[k]] = smoothed_spline(tk, yk)
        else:
            spline = CubicSpline(tk, yk)
        displacement[:, k] = spline(np.clip(grid, tk[0], tk[-1]))
    return displacement, gaps, departures


#: Lowest corner of a trace's low-pass, Hz: a breath is 0.1-0.5 Hz, so a lower corner removes the
#: motion itself.
MIN_LOWPASS_HZ = 0.01


def _lowpassed(
    displacement: np.ndarray, lowpass_hz: float | None, resample_hz: float
) -> np.ndarray:
    """(m, 6) the displacement low-passed without phase lag (a 2nd-order Butterworth filter run
    forwards and backwards), or as it is without ``lowpass_hz`` or with 15 samples or fewer."""
    from scipy.signal import butter, filtfilt

    if lowpass_hz is not None and len(displacement) > 15:
        b, a = butter(2, lowpass_hz / (0.5 * resample_hz))
        displacement = filtfilt(
            b,
            a,
            displacement,
            axis=0,
            padtype="odd",
            padlen=min(len(displacement) - 1, 3 * int(resample_hz / lowpass_hz)),
        )
    return displacement


def _centred(displacement: np.ndarray, centre_on: str, targets) -> tuple:
    """((m, 6) the displacement with its mean over the trace's axes (``"mean"``) or its first
    sample (``"first"``) removed, in place, or as it is (``"none"``); (6,) what was removed,
    rad and m)."""
    if centre_on == "mean":
        removed = displacement.mean(axis=0) * np.isin(np.arange(6), targets)
    elif centre_on == "first":
        removed = displacement[0].copy()
    elif centre_on == "none":
        removed = np.zeros(6)
    else:
        raise InvalidConfigError(f"centre_on must be 'mean', 'first' or 'none', got {centre_on!r}")
    displacement -= removed
    return displacement, removed


def load_trace(
    path,
    axis_map: dict | None = None,
    centre=None,
    centre_on: str = "mean",
    lowpass_hz: float | None = None,
    max_gap_s: float = 1.0,
    resample_hz: float = 100.0,
    format: str = "auto",
    columns: str = "",
    smoothing: str = "auto",
    seam_blend_s: float = SEAM_BLEND_S,
):
    """A reference from a recorded trace of 1 to 6 axes.

    Text, one sample per line, a header of columns with units (or ``columns``, or a phantom
    format: :data:`~.trace_files.PHANTOM_COLUMNS`, :data:`~.trace_files.SURROGATE_COLUMNS`): time
    and 1 to 6 axes (:data:`~.core.PATIENT_AXES`), samples at most
    :data:`~.trace_files.MAX_SAMPLE_STEP_S` apart; each axis smoothed
    (:func:`~.trace_cleaning.smoothed_spline`), seams blended (:func:`~.trace_cleaning.loop_seams`)
    and joined by a C2 spline. A project CSV goes to :func:`~.samples.load_csv_trajectory`. The
    formats, units and steps: docs/organ_motion.md, "Recorded traces".

    Args:
        path: the text file (UTF-8, at most :data:`~.trace_files.MAX_TRACE_BYTES`).
        axis_map: {column name: platform axis with an optional sign}, e.g. ``{"SI": "-Z"}``;
            it takes precedence over the names' own meaning.
        centre: (6,) the pose the trace is centred on, rad and m; default home.
        centre_on: the trace's pose that goes to ``centre``: "mean", "first", or "none" (the
            values are displacements from ``centre``).
        lowpass_hz: corner of the zero-phase low-pass, Hz, below half ``resample_hz``, or None.
        max_gap_s: longest interval an axis may go without data, s (longer: refused).
        resample_hz: rate of the samples joined by the C2 spline, Hz.
        format: one of :func:`~stewart_drake.base.trace_layouts.trace_formats` ("auto": by
            the file's width).
        columns: the columns' names and units when the file has no header (or to replace
            it), e.g. ``"t [s], SI [mm]"``; a column named ``-``
            (:data:`~.trace_files.SKIP_COLUMN`) is not read.
        smoothing: "auto" or "none" (:data:`SMOOTHING_MODES`; "none": a cubic spline through
            every sample); ``info.departures`` gives how far the reference departs from them.
        seam_blend_s: time over which each seam of a looped recording is blended, s (0: none;
            at most half the loop); ``info.seam_words()`` says what was done.
    Returns:
        :class:`TraceTrajectory` (its ``info`` says what was read, dropped and done), or the
        :class:`~.samples.CubicSplineTrajectory` of a project CSV.
    Raises:
        MissingFileError, CorruptFileError: no such file, not a regular file, too large, not
            UTF-8 or not CSV.
        InvalidConfigError: no time column, a missing or unknown unit, an unknown axis, two
            columns on one axis, a length on an angle or the reverse, a row that is not numbers
            (its line named), times not increasing (the line named) or too far apart for their
            unit (the likely unit named), a gap longer than ``max_gap_s`` (its time named),
            fewer than 4 samples on an axis.
    """
    path = Path(path)
    header, rows, layout = read_trace_table(path, format, columns)
    if tuple(h.strip() for h in header) in (CSV_COLUMNS, CSV_COLUMNS_WITH_UNITS) and not columns:
        return load_csv_trajectory(path)
    table = trace_samples(path, header, rows, layout, axis_map)
    del rows
    return _trace_trajectory(
        path,
        table,
        centre,
        centre_on,
        lowpass_hz,
        max_gap_s,
        resample_hz,
        smoothing,
        seam_blend_s,
    )


def _trace_trajectory(
    path: Path,
    table: TraceTable,
    centre,
    centre_on,
    lowpass_hz,
    max_gap_s,
    resample_hz,
    smoothing: str = "auto",
    seam_blend_s: float = SEAM_BLEND_S,
) -> "TraceTrajectory":
    """The :class:`TraceTrajectory` of a trace's samples (see :func:`load_trace`): resampled at
    ``resample_hz``, low-passed, centred, with its :class:`TraceInfo`."""
    t, targets = table.t, table.targets
    rate = 1.0 / float(np.median(np.diff(t)))
    max_gap_s = as_number("max_gap_s", max_gap_s, 0.0, lo_open=True)
    resample_hz = as_number("resample_hz", resample_hz, 1.0, 1e4)
    if lowpass_hz is not None:
        # Below MIN_LOWPASS_HZ the filter removes every breath (and its design is singular).
        lowpass_hz = as_number("lowpass_hz", lowpass_hz, MIN_LOWPASS_HZ, 0.5 * resample_hz)
    grid = _trace_grid(path, t, resample_hz)
    if smoothing not in SMOOTHING_MODES:
        raise InvalidConfigError(f"smoothing must be 'auto' or 'none', got {smoothing!r}")
    data, loop_s, seams, jumps, seam_blend_s = _without_seams(table, rate, seam_blend_s)
    displacement, gaps, departures = _resampled(
        path, t, data, table.names, targets, table.factors, grid, rate, max_gap_s, smoothing
    )
    displacement, removed = _centred(
        _lowpassed(displacement, lowpass_hz, resample_hz), centre_on, targets
    )
    centre = X_HOME if centre is None else np.asarray(check_centre("trace", centre))
    poses = as_poses(f"{path}: the trace's poses", centre + displacement)
    info = TraceInfo(
        path=str(path),
        columns=tuple(table.names),
        units=tuple(table.units),
        axes=tuple(
            f"{'+' if f > 0 else '-'}{AXIS_NAMES[k]}" for k, f in zip(targets, table.factors)
        ),
        samples=len(t),
        sample_rate_hz=rate,
        gaps=tuple(sorted(set(gaps))),
        lowpass_hz=lowpass_hz,
        duration_s=float(grid[-1]),
        centred_on=centre_on,
        layout=table.layout,
        removed=tuple(float(v) for v in removed),
        dropped=table.dropped,
        smoothing=smoothing,
        departures=tuple((axis, float(v)) for axis, v in departures.items()),
        loop_period_s=loop_s,
        seams=seams,
        seam_blend_s=seam_blend_s if seams else 0.0,
        seam_jumps=jumps,
        start_s=float(table.start_s),
        repaired=tuple(table.repaired),
    )
    return TraceTrajectory(grid, poses, info, centre, name=path.stem)


def _without_seams(table: TraceTable, rate: float, blend_s: float):
    """(the table's data with a loop's seams blended, the loop in s (0: not a loop or shorter
    than :data:`~.trace_cleaning.MIN_LOOP_S`), its seams, ((axis, largest jump taken out, rad
    or m), ...), the blend's length in s: ``blend_s``, at most half the loop)."""
    blend_s = as_number("seam_blend_s", blend_s, 0.0)
    loop = loop_seams(table.data[:, 1:])
    if loop is None or loop.period / rate < MIN_LOOP_S:
        return table.data, 0.0, 0, (), 0.0
    loop_s = loop.period / rate
    if blend_s == 0.0 or not loop.seams:
        return table.data, loop_s, len(loop.seams), (), 0.0
    blend_s = min(blend_s, 0.5 * loop_s)  # blends that do not meet
    blended, largest = blend_seams(table.t, table.data[:, 1:], loop, blend_s)
    jumps = tuple(
        (AXIS_NAMES[k], abs(float(j * f)))
        for k, f, j in zip(table.targets, table.factors, largest)
        if j > 0.0
    )
    return np.column_stack([table.data[:, 0], blended]), loop_s, len(loop.seams), jumps, blend_s


# -- a scenario's choice of a trace ----------------------------------------------------------------


@dataclass
class TraceReference(ReferenceConfig):
    """A recorded trace of 1 to 6 axes: a CSV whose header names each column and its unit
    (:func:`load_trace`); the project's own ``t,phi,theta,psi,X,Y,Z`` CSV too.

    Attributes:
        path: the file (relative to the working folder).
        axis_map: trace column -> platform axis with an optional sign ({SI: -Z}).
        centre: (6,) the pose the trace is centred on, rad and m.
        centre_on: "mean", "first" or "none" (which pose of the trace goes to ``centre``).
        lowpass_hz: corner of the zero-phase low-pass, Hz (0: none).
        max_gap_s: longest interval without data an axis may have, s.
        scale: the trace shrunk about its centre, in (0, 1].
        format: the file's layout, one of
            :func:`~stewart_drake.base.trace_layouts.trace_formats` ("auto": its header, else
            its width). columns: its columns' names and units when it has no header line.
        add: motions of the library laid on the trace, name -> parameters
            (``{baseline_drift: {drift: 3mm}}``: a drift on a recording,
            :func:`~.combinators.layered`); the scale shrinks the sum.
        smoothing: "auto" (each axis joined by a smoothing spline that drops the recording's
            measurement noise, :func:`~.trace_cleaning.smoothed_spline`) or "none" (through
            every sample).
        seam_blend_s: a looped recording's seams blended over this time, s (0: left).
    """

    path: str = ""
    axis_map: dict[str, str] = field(default_factory=dict)
    centre: list[float] = field(default_factory=lambda: [0.0, 0.0, 0.0, 0.0, 0.0, 0.30])
    centre_on: str = "mean"
    lowpass_hz: float = 0.0
    max_gap_s: float = 1.0
    scale: float = 1.0
    format: str = "auto"
    columns: str = ""
    add: dict[str, dict[str, str]] = field(default_factory=dict)
    smoothing: str = "auto"
    seam_blend_s: float = SEAM_BLEND_S

    def validate(self) -> None:
        as_number("reference.scale", self.scale, 0.0, 1.0, lo_open=True)
        if self.smoothing not in SMOOTHING_MODES:
            raise InvalidConfigError(
                f"reference.smoothing must be one of {', '.join(SMOOTHING_MODES)}, got "
                f"{self.smoothing!r}"
            )
        if self.format not in trace_formats():
            raise InvalidConfigError(
                f"reference.format must be one of {', '.join(trace_formats())}, got {self.format!r}"
            )
        if not self.path or not Path(self.path).exists():
            raise MissingFileError(f"no trace at {self.path!r} (reference.path): check the path")
        if self.centre_on not in CENTRE_MODES:
            raise InvalidConfigError(
                f"reference.centre_on must be one of {CENTRE_MODES}, got {self.centre_on!r}"
            )
        if as_number("reference.lowpass_hz", self.lowpass_hz, 0.0) != 0.0:
            as_number("reference.lowpass_hz", self.lowpass_hz, MIN_LOWPASS_HZ)
        as_number("reference.max_gap_s", self.max_gap_s, 0.0, lo_open=True)
        as_number("reference.seam_blend_s", self.seam_blend_s, 0.0)
        as_array("reference.centre", self.centre, shape=(6,))
        make_layers(self.add)  # names an unknown motion or parameter

    def load(self) -> "TraceTrajectory | CubicSplineTrajectory":
        """The trace as read (:func:`load_trace` with these settings), before ``add`` and
        ``scale``."""
        return load_trace(
            self.path,
            self.axis_map,
            self.centre,
            self.centre_on,
            self.lowpass_hz or None,
            self.max_gap_s,
            format=self.format,
            columns=self.columns,
            smoothing=self.smoothing,
            seam_blend_s=self.seam_blend_s,
        )

    def make(
        self, geometry: StewartGeometry, duration_s: float, torque_limit_Nm: float | None
    ) -> Reference:
        return scaled(layered(self.load(), make_layers(self.add)), self.scale)

    @property
    def label(self) -> str:
        return "+".join([Path(self.path).stem, *self.add])

    def memory_note(self) -> tuple:
        return (f" of the trace {self.path}", " (reproduce --duration replays its start)")


__all__ = [
    "load_trace",
    "TraceTrajectory",
    "TraceInfo",
    "CENTRE_MODES",
    "MIN_LOWPASS_HZ",
    "TraceReference",
]
