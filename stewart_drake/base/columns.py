"""Columns of numbers: :func:`read_csv_columns` reads the columns of a CSV whose header names
each column with its unit, into SI arrays, row by row; :func:`interp_columns` resamples columns
at other times, :func:`uniform_columns` on a uniform grid."""

import csv
import math
import re
from pathlib import Path

import numpy as np

from .errors import CorruptFileError, InvalidConfigError, MissingFileError
from .fileio import check_parse_memory, decode_text, read_checked

#: A header cell: a column's name and its unit in brackets, ``X [mm]``.
HEADER_CELL = re.compile(r"\s*([^\[\]]+?)\s*\[\s*([^\[\]]*?)\s*\]\s*")


def header_cell(cell: str) -> tuple[str, str]:
    """(name, unit) of a header cell, ``X [mm]`` -> ("X", "mm"); a cell without brackets is
    its stripped name with the unit "" (for the caller to refuse or read past)."""
    m = HEADER_CELL.fullmatch(cell)
    return (m.group(1), m.group(2)) if m else (cell.strip(), "")


#: Memory the reading of such a CSV takes per line beyond its text, bytes: the SI values
#: of up to 15 columns and the line's number, 8 bytes each (the text costs one byte a byte).
CSV_BYTES_PER_LINE = 128.0


#: The most comment lines :func:`read_csv_columns` keeps for its caller (a file of a million
#: comments costs no more than its text).
MAX_KEPT_COMMENTS = 16


def _lines(text: str, comments: list | None = None):
    """(number from 1, line with its newline) of ``text``'s lines that are neither blank nor
    ``#`` comments, one at a time (the whole list of a long file's lines would cost ~60 bytes a
    line); lines end at ``\n``, ``\r\n`` or, in a file with no ``\n``, ``\r``. With
    ``comments``, the first :data:`MAX_KEPT_COMMENTS` comments' text (after the ``#``,
    stripped) is appended to it."""
    newline = "\n" if "\n" in text or "\r" not in text else "\r"
    start, number = 0, 0
    while start < len(text):
        end = text.find(newline, start)
        end = len(text) if end < 0 else end
        line = text[start:end]
        start, number = end + 1, number + 1
        if line.strip() and not line.lstrip().startswith("#"):
            yield number, line.rstrip("\r") + "\n"
        elif comments is not None and line.strip() and len(comments) < MAX_KEPT_COMMENTS:
            comments.append(line.strip()[1:].strip())


def read_csv_columns(
    path,
    what: str,
    max_bytes: float,
    remedy: str,
    columns_of,
    nan_ok=(),
    bad_cell: str = "",
    comments: list | None = None,
) -> tuple[dict, np.ndarray]:
    """The columns of a CSV whose first line names the columns with their units (``X [mm]``;
    ``#`` comments, blank lines), in SI units, read row by row into arrays allocated once from
    the file's line count, after its memory is estimated
    (:func:`~stewart_drake.base.fileio.check_parse_memory`): the peak is about 2.5 times the file.

    Args:
        path: the CSV.  what: its kind, for messages.  max_bytes: the largest such file.
        remedy: what a bad file is told to become.
        columns_of: header cells -> {name: (index, factor to SI)} of the columns to read
            (raising InvalidConfigError for a bad header).
        nan_ok: the columns where ``nan`` is a value.  bad_cell: appended to a bad cell's message.
        comments: a list the file's first :data:`MAX_KEPT_COMMENTS` comments are appended to
            (their text after the ``#``), or None.
    Returns:
        ({name: (N,) values}, (N,) the file's line of each row).
    Raises:
        MissingFileError: no such file.  CorruptFileError: not a regular file, too large, not
            UTF-8 or not CSV.  InvalidConfigError: too long for the memory, no header, a header
            ``columns_of`` refuses, a row of another width or a cell that is not a finite
            number (its line and column named).
    """
    path = Path(path)
    if not path.exists():
        raise MissingFileError(f"no {what} at {path}: check the path")
    raw = read_checked(path, what, max_bytes, remedy)
    rows_bound = check_parse_memory(path, what, raw, CSV_BYTES_PER_LINE, 1.0)
    text = decode_text(raw, path, what, remedy, "utf-8-sig")
    del raw
    numbered = _lines(text, comments)
    number = 0

    def cells_of():
        nonlocal number
        for k, line in numbered:
            number = k
            yield line

    reader = csv.reader(cells_of())
    try:
        header = next(reader, None)
        if header is None:
            raise InvalidConfigError(f"{path}: the {what} is empty; {remedy}")
        found = columns_of(header)
        width = len(header)
        out = {name: np.empty(rows_bound) for name in found}
        lines = np.empty(rows_bound, dtype=int)
        n = 0
        for row in reader:
            if len(row) != width:
                raise InvalidConfigError(
                    f"{path}, line {number}: {len(row)} cells where the header names {width}"
                )
            for name, (index, factor) in found.items():
                try:
                    v = float(row[index])
                except ValueError:
                    v = math.inf
                if not (math.isfinite(v) or (math.isnan(v) and name in nan_ok)):
                    raise InvalidConfigError(
                        f"{path}, line {number}, column {name}: {row[index].strip()[:40]!r} is "
                        f"not a finite number{bad_cell}"
                    )
                out[name][n] = v * factor
            lines[n] = number
            n += 1
    except csv.Error as err:
        raise CorruptFileError(path, what, f"not CSV ({err})", remedy) from None
    return {name: values[:n].copy() for name, values in out.items()}, lines[:n].copy()


def interp_columns(t_new, t, Y, period: float | None = None, out=None) -> np.ndarray:
    """Each column of Y, known at the times t, linearly interpolated at t_new: numpy's
    ``np.interp`` column by column, so held at the ends (or wrapped, with ``period``).

    Args:
        t_new: (m,) where the values are wanted.  t: (n,) increasing, where Y is known (any
            order with ``period``).  Y: (n, k) the values, a column per signal.
        period: the period of t (e.g. 1.0 for a phase in [0, 1)); None: not periodic.
        out: (m, k) filled column by column and returned (cast to its dtype; one (m,) float64
            column at a time in memory); None: a new float64 array.
    Returns:
        (m, k) the values at t_new.
    Raises:
        ValueError: Y not 2-D with a row per time, or ``out`` not (m, k) (np.interp's own
            refusals otherwise).
    """
    Y = np.asarray(Y)
    if Y.ndim != 2 or Y.shape[0] != len(t):
        raise ValueError(f"Y of shape {Y.shape}: expected ({len(t)}, k), a row per time")
    shape = (len(t_new), Y.shape[1])
    if out is None:
        out = np.empty(shape)
    elif out.shape != shape:
        raise ValueError(f"out of shape {out.shape}: expected {shape}")
    for c in range(Y.shape[1]):
        out[:, c] = np.interp(t_new, t, Y[:, c], period=period)
    return out


def uniform_columns(t, Y, step_s: float) -> tuple[np.ndarray, np.ndarray]:
    """Columns known at the times ``t`` resampled on a uniform grid: ``t[0]``, ``t[0]`` +
    ``step_s``, ... up to ``t[-1]`` (the last step whole; :func:`interp_columns`, linear).

    Args:
        t: (n,) increasing, s. Y: (n, k) a column per signal. step_s: the grid's step, s.
    Returns:
        (grid (m,), Y on it (m, k)).
    Raises:
        InvalidConfigError: ``step_s`` not a finite number > 0, or ``t`` empty.
        ValueError: as :func:`interp_columns`.
    """
    t = np.asarray(t, dtype=float)
    if not (np.isfinite(step_s) and step_s > 0) or t.size == 0:
        raise InvalidConfigError(
            f"a uniform grid needs times and a step > 0 s, got {t.size} times, step {step_s}"
        )
    grid = t[0] + step_s * np.arange(int((t[-1] - t[0]) / step_s) + 1)
    return grid, interp_columns(grid, t, Y)
