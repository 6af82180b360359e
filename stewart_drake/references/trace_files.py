"""Reading a recorded trace's text: its layout (separator, decimal mark, header or a phantom
format), its columns (names, units, the platform axis each goes to) and its samples, checked.

The file is text, one sample per line, its numbers separated by commas, semicolons, tabs or
spaces, with a decimal point or (with any separator but commas) a decimal comma. Its first line
names the columns and their units, or the ``columns`` given do (the same words, comma
separated), or it has none and is one of the phantom formats (:data:`TRACE_FORMATS`, by its
width when "auto"): the 7-column 6-D format :data:`PHANTOM_COLUMNS`, or a 2-column external
surrogate :data:`SURROGATE_COLUMNS` (its displacement on SI unless an axis map says otherwise);
or a Varian RPM export (``.vxp``, :mod:`~.vxp_files`: its header names its fields).
:func:`read_trace_table` splits the text into a header and rows; :func:`trace_samples` reads
the rows into a :class:`TraceTable` of times and numbers. What becomes of them (resampled,
low-passed, centred: a reference) is :func:`~.traces.load_trace`'s.
"""

import csv
import math
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..base.checks import MAX_POSITION_M
from ..base.errors import CorruptFileError, InvalidConfigError, MissingFileError
from ..base.trace_layouts import (
    HEADERLESS_FORMATS,
    PHANTOM_COLUMNS,
    SURROGATE_COLUMNS,
    headerless_format_of_width,
    trace_formats,
)
from ..base.units import UNITS
from ..robot.kinematics import AXIS_NAMES
from .organ.core import axis_index
from .vxp_files import VXP_AXIS, VXP_LAYOUT, VXP_OPENING, is_vxp, vxp_table

#: Largest trace file read, bytes (several hours at 100 Hz).
MAX_TRACE_BYTES = 256e6
#: Memory a trace takes per line while it is read, split, converted, smoothed and resampled,
#: bytes: 2.8 kB measured on a 4-column trace sampled at 25 Hz (70 times its 40-byte lines).
TRACE_BYTES_PER_LINE = 2.8e3
#: Time units of a trace's time column: factor to s (the one table's).
TIME_UNITS = UNITS["s"]
#: The layouts :func:`load_trace` reads as shipped (``format``): "auto" (a header line, else
#: the width decides: 7 columns are "phantom", 2 are "surrogate"), "csv" (a header line naming
#: each column and its unit), "phantom", "surrogate", "vxp" (a Varian RPM export: "auto" knows
#: it by its ``[Header]``); with any format added to the table,
#: :func:`stewart_drake.base.trace_layouts.trace_formats`.
TRACE_FORMATS = trace_formats()
#: Where a surrogate's displacement goes by default (``axis_map`` overrides it).
SURROGATE_AXIS = {"surrogate": "SI"}
#: The name that skips a column in ``columns`` (a tracker's frame counter): ``-,t [ms],X [mm]``.
SKIP_COLUMN = "-"
#: Largest median step between a trace's samples, s: slower than this a breath (about 4 s) is
#: not sampled, and the time column's unit is likely wrong (ms declared as s).
MAX_SAMPLE_STEP_S = 2.0


def _parse_header_cell(cell: str) -> tuple[str, str]:
    """(name, unit) of a header cell: ``SI [mm]``, ``SI (mm)``, ``SI_mm``, ``t``."""
    text = cell.strip()
    m = re.fullmatch(r"(.+?)\s*[\[(]\s*([^\])]*)\s*[\])]", text)
    if m:
        return m.group(1).strip(), m.group(2).strip()
    if "_" in text:
        name, unit = text.rsplit("_", 1)
        known = {u for table in (UNITS["m"], UNITS["rad"], TIME_UNITS) for u in table}
        if unit in known:
            return name, unit
    return text, ""


def _trace_remedy(option: str = "--columns") -> str:
    """How to write a trace file: the remedy of the messages about one that cannot be read,
    naming the command's ``option`` that gives the columns (a reference's ``--columns`` also
    has ``--format``; a measured file's option has not)."""
    if option != "--columns":
        return (
            "write a first line naming each column and its unit, e.g. t [s],X [mm],Y [mm], or "
            f"give them with {option}"
        )
    return (
        "write a first line naming each column and its unit, e.g. t [s],SI [mm],AP [mm], or "
        "give them with --columns (a scenario's reference.columns), or --format phantom for "
        "the 7-column phantom format"
    )


def _number(cell: str) -> bool:
    """A cell that reads as a float (or is empty: a missing sample)."""
    try:
        float(cell) if cell.strip() else None
    except ValueError:
        return False
    return True


def _separator(lines: list) -> tuple[str | None, bool]:
    """(separator, decimal comma) of a trace's text from its first data lines: ";" or a tab
    (each with a decimal comma when the numbers have one), ",", or None (runs of spaces, with a
    decimal comma when the numbers have one)."""
    sample = [ln for ln in lines[1:21] if ln.strip()] or [ln for ln in lines if ln.strip()][:1]
    for sep in (";", "\t"):
        if sample and all(sep in ln for ln in sample):
            return sep, any("," in ln for ln in sample)
    if sample and all("," in ln for ln in sample):
        if all(all(_number(c) for c in ln.split(",")) for ln in sample):
            return ",", False
        spaced = [ln.replace(",", ".").split() for ln in sample]
        if all(len(cells) > 1 and all(_number(c) for c in cells) for cells in spaced):
            return None, True  # numbers with decimal commas separated by spaces
        return ",", False
    return None, False


#: A cell of a line whose cells are separated by spaces: a word or number, with the unit in
#: brackets that may follow it after spaces (``SI [mm]``, ``t (s)``).
_SPACED_CELL = re.compile(r"[^\s\[(]+(?:\s*[\[(][^\])]*[\])])?|[\[(][^\])]*[\])]")


def _split_lines(path: Path, text: str, option: str = "--columns") -> tuple[list, str]:
    """(rows of cell strings, one per non-blank line with its line number first; the layout
    in words) of a trace's text, whatever its separator and decimal mark."""
    lines = text.splitlines()
    sep, decimal_comma = _separator(lines)
    rows = []
    if sep in (",", ";"):
        reader = csv.reader(lines, delimiter=sep)
        try:
            for number, cells in enumerate(reader, start=1):
                if cells and any(c.strip() for c in cells):
                    rows.append([number] + cells)
        except csv.Error as err:
            raise CorruptFileError(
                path, "trace file", f"not delimited text ({err})", _trace_remedy(option)
            ) from None
    else:
        for number, line in enumerate(lines, start=1):
            # Without a separator a header's "t [s]  SI [mm]" keeps each unit with its name.
            cells = line.split(sep) if sep else _SPACED_CELL.findall(line)
            if any(c.strip() for c in cells):
                rows.append([number] + cells)
    if decimal_comma:
        rows = [[r[0]] + [str(c).replace(",", ".") for c in r[1:]] for r in rows]
    named = {",": "commas", ";": "semicolons", "\t": "tabs", None: "spaces"}[sep]
    return rows, f"separated by {named}" + (", decimal commas" if decimal_comma else "")


def read_trace_table(
    path: Path, format: str, columns: str, columns_option: str = "--columns"
) -> tuple[list, list, str]:
    """(header cells, data rows (each its line number then its cells), layout in words) of a
    trace file in any of :data:`TRACE_FORMATS`, or given its columns (by the command's
    ``columns_option``, which the refusals name).

    Raises:
        MissingFileError, CorruptFileError: no such file, too large, not UTF-8 text.
        InvalidConfigError: an unknown format, a file without a header whose width says no
            format, a header where the format has none, an empty file.
    """
    from ..base.fileio import check_parse_memory, decode_text, read_checked

    remedy = _trace_remedy(columns_option)

    if format not in trace_formats():
        raise InvalidConfigError(
            f"trace format {format!r}: use one of {', '.join(trace_formats())}"
        )
    if not path.exists():
        raise MissingFileError(f"no trace at {path}: check the path")
    raw = read_checked(path, "trace file", MAX_TRACE_BYTES, remedy)
    check_parse_memory(path, "trace file", raw, TRACE_BYTES_PER_LINE)
    text = decode_text(raw, path, "trace file", remedy, encoding="utf-8-sig")
    del raw
    if "\0" in text:
        raise CorruptFileError(path, "trace file", "not text (a NUL byte)", remedy)
    if format == "vxp" or (format == "auto" and is_vxp(text)):
        if not is_vxp(text):
            raise InvalidConfigError(
                f"{path}: not a Varian RPM export (its first line is not {VXP_OPENING}); leave "
                "--format vxp out to read it by its header"
            )
        if columns:
            raise InvalidConfigError(
                f"{path}: a Varian RPM export names its fields in its header (Data_layout): "
                f"leave {columns_option} out"
            )
        return vxp_table(path, text)
    rows, layout = _split_lines(path, text, columns_option)
    del text
    if not rows:
        raise InvalidConfigError(f"{path}: empty; {remedy}")
    headed = not all(_number(c) for c in rows[0][1:])
    if format in HEADERLESS_FORMATS and headed:
        raise InvalidConfigError(
            f"{path}: the {format} format has no header line, but line {rows[0][0]} is not "
            f"all numbers; leave --format out to read the header"
        )
    if format == "csv" and not headed and not columns:
        raise InvalidConfigError(f"{path}: no header line naming the columns; {remedy}")
    data = rows[1:] if headed else rows
    if columns:
        header, how = [c.strip() for c in str(columns).split(",")], "columns given"
    elif headed:
        header, how = rows[0][1:], "header"
    else:
        width = len(rows[0]) - 1
        kind = format if format != "auto" else headerless_format_of_width(width)
        if kind is None:
            known = "; ".join(
                f"{name}: {len(cols.split(','))} columns, {cols}"
                for name, cols in HEADERLESS_FORMATS.items()
            )
            raise InvalidConfigError(
                f"{path}: no header line and {width} columns, which no format without a header "
                f"has ({known}); {remedy}"
            )
        header = [c.strip() for c in HEADERLESS_FORMATS[kind].split(",")]
        how = f"{kind} format, no header"
    return header, data, f"{how}, {layout}"


def _column_axis(path: Path, name: str, unit: str, axis_map: dict) -> tuple[int, float]:
    """(platform axis 0..5, factor to rad or m with the axis's sign) of one axis column."""
    k, sign = axis_index(axis_map.get(name, name))
    kind = "m" if k >= 3 else "rad"
    table = {u.lower(): f for u, f in UNITS[kind].items()}
    if unit.lower() not in table:
        other = "rad" if kind == "m" else "m"
        hint = (
            f"a {'length' if other == 'm' else 'angle'} on a "
            f"{'rotation' if kind == 'rad' else 'translation'} axis"
            if unit.lower() in {u.lower() for u in UNITS[other]}
            else f"units: {', '.join(UNITS[kind])}"
        )
        raise InvalidConfigError(
            f"{path}: column {name!r} goes to the platform's "
            f"{AXIS_NAMES[k]} and needs a unit of "
            f"{'length' if kind == 'm' else 'angle'}, got "
            f"{unit or 'none'!r} ({hint}); e.g. '{name} [mm]'"
        )
    return k, sign * table[unit.lower()]


def _trace_header(path: Path, cells: list, axis_map: dict | None, option: str = "--columns"):
    """(names, units, targets, factors) of a trace's header row: the column names and units
    (time first), and for each axis column its platform axis 0..5 and its factor to rad or m
    (signed)."""
    header = [_parse_header_cell(c) for c in cells]
    names = [h[0] for h in header]
    if names[0].lower() not in ("t", "time"):  # unquoted: a file named by mistake may be private
        raise InvalidConfigError(
            f"{path}: the first column must be the time (t [s]), and the first line does not "
            f"name one; {_trace_remedy(option)} (a column before the time is skipped by naming "
            f"it {SKIP_COLUMN}: {option} '{SKIP_COLUMN},t [ms],X [mm],...')"
        )
    if not 2 <= len(header) <= 7:
        raise InvalidConfigError(
            f"{path}: a trace has a time column and 1 to 6 axes, got {len(header) - 1} axes"
        )
    units = [h[1] for h in header]
    if units[0].lower() not in TIME_UNITS:
        raise InvalidConfigError(
            f"{path}: the time column needs its unit ({', '.join(TIME_UNITS)}"
            f"), e.g. 't [s]', got {cells[0]!r}"
        )
    axis_map = dict(axis_map or {})
    unknown = set(axis_map) - set(names[1:])
    if unknown:
        raise InvalidConfigError(
            f"{path}: axis_map names {', '.join(sorted(unknown))}, which "
            f"the trace has not (its columns: {', '.join(names[1:])})"
        )
    targets, factors = [], []
    for name, unit in header[1:]:
        k, factor = _column_axis(path, name, unit, axis_map)
        if k in targets:
            raise InvalidConfigError(
                f"{path}: two columns go to the platform's {AXIS_NAMES[k]}; "
                f"map one elsewhere with axis_map (--map NAME=AXIS)"
            )
        targets.append(k)
        factors.append(factor)
    return names, units, targets, factors


def _trace_values(path: Path, rows: list, width: int, keep: list) -> tuple:
    """((n, len(keep)) the numbers of the data rows' columns ``keep`` in the file's units, NaN
    where a cell is empty; (n,) the rows' line numbers) of the data rows (each its line number,
    then its ``width`` cells; the cells of the other columns are not read)."""
    values, lines = [], []
    for line, *row in rows:
        if len(row) != width:
            raise InvalidConfigError(
                f"{path}, line {line}: {len(row)} fields, the columns are {width}"
            )
        cells = [row[j] for j in keep]
        try:
            numbers = [float(c) if c.strip() else math.nan for c in cells]
        except ValueError:
            raise InvalidConfigError(
                f"{path}, line {line}: not numbers: {','.join(cells)[:200]!r}"
                + ("" if len(keep) == width else f" (read columns {[j + 1 for j in keep]})")
            ) from None
        if not math.isfinite(numbers[0]):
            raise InvalidConfigError(f"{path}, line {line}: the time is missing")
        if any(math.isinf(v) for v in numbers):
            raise InvalidConfigError(f"{path}, line {line}: an infinite value")
        values.append(numbers)
        lines.append(line)
    return np.array(values, dtype=float).reshape(-1, len(keep)), np.array(lines, dtype=int)


def _without_end_marker(path: Path, data: np.ndarray, lines: np.ndarray) -> tuple:
    """(data, lines, what was left out in words or "") of a trace's rows: a last row of zeros (a
    tracker's export ends so) is not a sample, and is left out, when it comes after a later time
    or, on a clock that runs below zero, at a step other than the file's (more than half the
    median step off it): time 0 then is no sample's."""
    if len(data) > 3 and not np.any(data[-1]):
        last = float(data[-2, 0])
        step = float(np.median(np.diff(data[:-1, 0])))
        if last > 0 or (step > 0 and abs(-last - step) > 0.5 * step):
            return data[:-1], lines[:-1], f"line {lines[-1]} (all zeros after the last sample)"
    return data, lines, ""


def _times(
    path: Path, data: np.ndarray, lines: np.ndarray, unit: str, option: str = "--columns"
) -> np.ndarray:
    """(n,) a trace's times from 0, s, checked: increasing, over at least 4 rows, at a step a
    breath can be sampled at.

    Raises:
        InvalidConfigError: a time not after the one before (its line named), fewer than 4
            rows, a median step over :data:`MAX_SAMPLE_STEP_S` (the likely unit named).
    """
    raw = data[:, 0]
    if len(raw) < 4:
        raise InvalidConfigError(f"{path}: times must strictly increase, over at least 4 rows")
    bad = np.flatnonzero(np.diff(raw) <= 0)
    if bad.size:
        i = int(bad[0]) + 1
        raise InvalidConfigError(
            f"{path}, line {lines[i]}: the time {raw[i]:.10g} is not after the line before's "
            f"({raw[i - 1]:.10g}, line {lines[i - 1]}); times must strictly increase: remove "
            f"or correct that line"
        )
    factor = TIME_UNITS[unit.lower()]
    step_raw, span_raw = float(np.median(np.diff(raw))), float(raw[-1] - raw[0])
    if step_raw * factor > MAX_SAMPLE_STEP_S:
        likely = [u for u, f in TIME_UNITS.items() if 1e-4 <= step_raw * f <= MAX_SAMPLE_STEP_S]
        guess = (
            f"likely in {likely[0]}: as 't [{likely[0]}]' they are "
            f"{1 / (step_raw * TIME_UNITS[likely[0]]):.4g} Hz over "
            f"{span_raw * TIME_UNITS[likely[0]]:.4g} s"
            if likely
            else "check the time column's unit"
        )
        raise InvalidConfigError(
            f"{path}: the times are {guess}; declared in {unit} they would be "
            f"{step_raw * factor:.4g} s apart ({1 / (step_raw * factor):.3g} Hz) over "
            f"{span_raw * factor:.4g} s, too slow to sample a breath (write the time's unit in "
            f"the header or {option})"
        )
    return (raw - raw[0]) * factor


@dataclass(frozen=True)
class TraceTable:
    """A trace file's samples as read (:func:`trace_samples`), before anything is resampled.

    Attributes:
        names: the column names read, time first (skipped columns left out).
        units: their units as written ("s", "mm", "deg").
        targets: for each axis column, the platform axis 0..5 it goes to.
        factors: for each axis column, its factor to rad or m, with the axis's sign.
        t: (n,) the times from 0, s, strictly increasing.
        data: (n, len(names)) the numbers in the file's units, NaN where a cell was empty.
        layout: how the file was read, in words (its format, separator and decimal mark).
        dropped: what was left out as an export's artefact (a last line of zeros), or "".
        start_s: the first time as written, s: ``t`` + start_s is the file's own clock, on
            which two files recorded together (a motion and its surrogate) are related.
        repaired: a line per time repaired from the frame counter (:func:`repaired_times`),
            in words, or ().
    """

    names: list
    units: list
    targets: list
    factors: list
    t: np.ndarray
    data: np.ndarray
    layout: str
    dropped: str
    start_s: float = 0.0
    repaired: tuple = ()


def trace_samples(
    path: Path,
    header: list,
    rows: list,
    layout: str,
    axis_map: dict | None,
    columns_option: str = "--columns",
):
    """The :class:`TraceTable` of a trace's header cells and data rows (as
    :func:`read_trace_table` gives them): the columns named ``-`` (:data:`SKIP_COLUMN`) left
    out, each axis column mapped to the platform (``axis_map`` first; a surrogate's column to
    SI by default, :data:`SURROGATE_AXIS`), the numbers read, a last line of zeros left out,
    the times checked and made s from 0; the refusals name ``columns_option``, the command's
    option that gives the columns.

    Raises:
        InvalidConfigError: every column skipped, no time column, a column without a unit or of
            an unknown one, an axis the platform does not have, two columns on one axis, a
            length on an angle or the reverse, a row that is not numbers (its line named),
            times not increasing (the line named) or too far apart for their unit.
    """
    if "surrogate" in layout:
        axis_map = {**SURROGATE_AXIS, **(axis_map or {})}
    elif layout.startswith(VXP_LAYOUT):
        axis_map = {**VXP_AXIS, **(axis_map or {})}
    frame = _frame_column(path, header)
    keep = [j for j, h in enumerate(header) if h.strip() != SKIP_COLUMN and j != frame[0]]
    if not keep:
        raise InvalidConfigError(f"{path}: every column is skipped ({SKIP_COLUMN!r})")
    cells = [header[j] for j in keep]
    names, units, targets, factors = _trace_header(path, cells, axis_map, columns_option)
    data, lines = _trace_values(path, rows, len(header), keep)
    counter = None if frame[0] is None else _trace_values(path, rows, len(header), [frame[0]])[0]
    data, lines, dropped = _without_end_marker(path, data, lines)
    repaired: tuple = ()
    if counter is not None:
        factor = TIME_UNITS[units[0].lower()]
        data[:, 0], repaired = repaired_times(
            path, data[:, 0], counter[: len(data), 0], lines, factor, units[0], frame[1]
        )
    t = _times(path, data, lines, units[0], columns_option)
    _check_magnitudes(path, data, lines, names, units, targets, factors)
    start = float(data[0, 0]) * TIME_UNITS[units[0].lower()]
    return TraceTable(names, units, targets, factors, t, data, layout, dropped, start, repaired)


#: The name of a frame counter's column (any case): read beside the time, never an axis; a
#: time column that jumps back or changes unit while it climbs is repaired from it. Its unit,
#: when given, is its rate (``frame [30 Hz]``); without one the rate comes from the good lines.
FRAME_COLUMN = "frame"
#: A time further than this share of a frame's step from the counter's line is repaired.
FRAME_SLACK = 0.5
#: At most this share of the lines may be repaired: beyond it the counter, not the time, is
#: in doubt.
MAX_REPAIRED_SHARE = 0.5


def _frame_column(path: Path, header: list) -> tuple:
    """(the index of the frame counter's column or None, its rate in Hz or None)."""
    found = [j for j, h in enumerate(header) if _parse_header_cell(h)[0].lower() == FRAME_COLUMN]
    if not found:
        return None, None
    if len(found) > 1:
        raise InvalidConfigError(f"{path}: {len(found)} frame counters: name one 'frame'")
    unit = _parse_header_cell(header[found[0]])[1].replace(" ", "").lower()
    if not unit:
        return found[0], None
    if not unit.endswith("hz"):
        raise InvalidConfigError(
            f"{path}: the frame counter's unit is its rate ('frame [30 Hz]'), got {unit!r}"
        )
    try:
        rate = float(unit[:-2])
    except ValueError:
        rate = math.nan
    if not (math.isfinite(rate) and 0 < rate <= 1e5):
        raise InvalidConfigError(f"{path}: the frame counter's rate must be in (0, 1e5] Hz")
    return found[0], rate


def repaired_words(repaired) -> str:
    """The import record's words for the times repaired from the frame counter
    (:func:`repaired_times`' lines): "; N times repaired from the frame counter: ...", or ""."""
    if not repaired:
        return ""
    return f"; {len(repaired)} times repaired from the frame counter: " + "; ".join(repaired)


def repaired_times(path, raw, frames, lines, factor: float, unit: str, rate_hz=None) -> tuple:
    """(times (n,) in the file's unit, the repairs in words) of a time column beside a frame
    counter: the counter must climb; the times then lie on a line of it, t = a + b (frame),
    b a frame's step (1 / ``rate_hz``, or the median step of consecutive lines) and a their
    median offset from it; a time further than :data:`FRAME_SLACK` of a step from that line
    (a glitch of the export: another unit for a run of lines, a jump back) is replaced by the
    line's, and said, line by line. Nothing is repaired when every time is on the line.

    Raises:
        InvalidConfigError: a counter that does not climb (its line named), or more than
            :data:`MAX_REPAIRED_SHARE` of the times off the line (the counter is in doubt).
    """
    raw = np.asarray(raw, dtype=float)
    frames = np.asarray(frames, dtype=float)
    if not np.all(np.isfinite(frames)):
        i = int(np.flatnonzero(~np.isfinite(frames))[0])
        raise InvalidConfigError(f"{path}, line {lines[i]}: the frame counter is missing")
    steps = np.diff(frames)
    if np.any(steps <= 0):
        i = int(np.flatnonzero(steps <= 0)[0]) + 1
        raise InvalidConfigError(
            f"{path}, line {lines[i]}: the frame counter {frames[i]:.10g} is not after the line "
            f"before's ({frames[i - 1]:.10g}): a counter climbs; remove or correct that line"
        )
    if rate_hz is not None:
        b = 1.0 / (rate_hz * factor)
    else:  # the median slope over pairs half the file apart: the rounding of each time is lost
        half = len(raw) // 2
        later, earlier = slice(half, None), slice(0, len(raw) - half)
        b = float(np.median((raw[later] - raw[earlier]) / (frames[later] - frames[earlier])))
    if not (np.isfinite(b) and b > 0):
        raise InvalidConfigError(f"{path}: the times do not climb with the frame counter")
    a = float(np.median(raw - b * frames))
    line = a + b * frames
    bad = np.abs(raw - line) > FRAME_SLACK * b
    if not bad.any():
        return raw, ()
    if bad.mean() > MAX_REPAIRED_SHARE:
        raise InvalidConfigError(
            f"{path}: {int(bad.sum())} of {len(raw)} times lie off the frame counter's line "
            f"({1 / (b * factor):.4g} Hz): the counter, not the times, is in doubt; correct the "
            "file"
        )
    out = np.where(bad, line, raw)
    said = tuple(
        f"line {lines[i]}: the time {raw[i]:.10g} {unit} repaired to {out[i]:.10g} {unit} from "
        f"frame {frames[i]:.10g} ({1 / (b * factor):.4g} frames a second)"
        for i in np.flatnonzero(bad)
    )
    return out, said


#: Largest angle a trace's rotation may reach, rad (a motion turns a platform by a fraction of
#: a turn; a value past this is a wrong unit or a broken export).
MAX_TRACE_ANGLE_RAD = 100.0


def _check_magnitudes(path, data, lines, names, units, targets, factors) -> None:
    """Refuse, before any arithmetic on them (a spline of 1e300 mm overflows), an axis value
    beyond :data:`~stewart_drake.base.checks.MAX_POSITION_M` or :data:`MAX_TRACE_ANGLE_RAD`,
    naming its line, column, value and unit."""
    for j, (k, factor) in enumerate(zip(targets, factors), start=1):
        column = np.abs(np.nan_to_num(data[:, j]))
        bound = MAX_POSITION_M if k >= 3 else MAX_TRACE_ANGLE_RAD
        if column.size and column.max() * abs(factor) > bound:
            r = int(np.argmax(column))
            raise InvalidConfigError(
                f"{path}, line {lines[r]}: {names[j]} = {data[r, j]:.4g} {units[j]}, beyond the "
                f"{bound:g} {'m' if k >= 3 else 'rad'} any motion of a platform reaches; check "
                f"the value and the column's unit"
            )


__all__ = [
    "MAX_TRACE_BYTES",
    "TIME_UNITS",
    "TRACE_FORMATS",
    "PHANTOM_COLUMNS",
    "SURROGATE_COLUMNS",
    "SURROGATE_AXIS",
    "SKIP_COLUMN",
    "MAX_SAMPLE_STEP_S",
    "read_trace_table",
    "repaired_times",
    "repaired_words",
    "FRAME_COLUMN",
    "TraceTable",
    "trace_samples",
]
