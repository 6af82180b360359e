"""Recorded internal-external pairs: the external's file read by the one reader of it, the
robot's too (:func:`~stewart_drake.station.surrogate.trace.load_surrogate_trace`, on the
checked reader of traces; IntERAct's ``Resp/`` files are its "surrogate" format, 2 columns, time
s and displacement mm), as a signal in m on the run's clock.

A pair is two files (IntERAct's ``Internal/NAME.txt`` and ``Resp/NAME_resp.txt``), or one file
with a header naming both: the internal read with the external's column named ``-`` (skipped),
the external with the internal's columns named ``-`` (``--surrogate-columns``).
"""

from __future__ import annotations

from collections.abc import Callable

from .trace import load_surrogate_trace


def load_external(path, format: str = "auto", columns: str = "", internal=None) -> Callable:
    """The external signal of a recorded file, m about its mean, as a function of t (s) on the
    clock of ``internal`` (the motion it was recorded with: their files' times as written
    relate them, :meth:`~stewart_drake.station.surrogate.trace.SurrogateTrace.on_clock_of`;
    None: the file's own, from its first time).

    The file is read whole by
    :func:`~stewart_drake.station.surrogate.trace.load_surrogate_trace` (the checks,
    smoothing and resampling of :func:`~stewart_drake.references.traces.load_trace`) with a
    one-axis trace expected: the displacement is the file's own, about its mean.

    Args:
        path: the file. format, columns: as ``load_trace``'s. internal: the internal motion
            (a reference), or None.
    Returns:
        f(t (n,) s) -> (n,) m, held at the recording's ends.
    Raises:
        MissingFileError, CorruptFileError, InvalidConfigError: as ``load_trace``; a file of
            more than one axis or none, or of a rotation (named ``--surrogate PATH``, offering
            ``--surrogate-columns``).
    """
    trace = load_surrogate_trace(
        path, format, columns, option="--surrogate", columns_option="--surrogate-columns"
    )
    if internal is not None:
        trace = trace.on_clock_of(internal)

    def external(q):
        return trace.evaluate(q)[0]

    return external
