"""Recorded internal-external pairs: the external's file read by the one checked reader
(:func:`~stewart_drake.references.traces.load_trace`; IntERAct's ``Resp/`` files are its
"surrogate" format, 2 columns, time s and displacement mm), as a signal in m on the run's clock.

A pair is two files (IntERAct's ``Internal/NAME.txt`` and ``Resp/NAME_resp.txt``), or one file
with a header naming both: the internal read with the external's column named ``-`` (skipped),
the external with the internal's columns named ``-`` (``--surrogate-columns``).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from ...references.traces import load_trace


def load_external(path, format: str = "auto", columns: str = "") -> Callable:
    """The external signal of a recorded file, m about its mean, as a function of t (s).

    The file is read whole by :func:`~stewart_drake.references.traces.load_trace` (its checks,
    smoothing and resampling) with a one-axis trace expected: the displacement is the
    platform's translation it maps to (a surrogate's: SI), taken with its sign.

    Args:
        path: the file. format, columns: as ``load_trace``'s.
    Returns:
        f(t (n,) s) -> (n,) m, held at the recording's ends.
    Raises:
        MissingFileError, CorruptFileError, InvalidConfigError: as ``load_trace``; a file that
            moves more than one axis or none.
    """
    from ...base.errors import InvalidConfigError

    trace = load_trace(path, format=format, columns=columns, centre_on="mean")
    t = np.arange(trace.start_time, trace.end_time, 1e-2)
    x = trace.evaluate(t)[0]
    moving = np.flatnonzero(np.ptp(x, axis=0) > 0)
    if len(moving) != 1 or moving[0] < 3:
        raise InvalidConfigError(
            f"{path}: an external surrogate moves one translation, this file moves "
            f"{len(moving)} axes: name the other columns '-' (--surrogate-columns)"
        )
    k = int(moving[0])
    centre = float(x[:, k].mean())

    def external(q):
        return trace.evaluate(np.asarray(q, float))[0][:, k] - centre

    return external
