"""An external surrogate's recorded trace: the one reader of its file, for the Diagram's stage
(``reproduce --surrogate``) and the robot's (``robot --surrogate``) alike.

:func:`load_surrogate_trace` reads the file through the one checked reader of traces
(:func:`~stewart_drake.references.traces.load_trace`: its checks, smoothing and resampling;
IntERAct's ``Resp/`` 2-column files are its "surrogate" format, time s and displacement mm on SI),
centred on its mean, and keeps its one displaced line: a :class:`SurrogateTrace`, the carriage's
position ``s`` (m) as the file's own displacement (the axis map's sign undone) about its mean.
"""

import numpy as np

from ...base.errors import InvalidConfigError
from ...references.traces import load_trace
from ...robot.kinematics import AXIS_NAMES


class SurrogateTrace:
    """One displaced axis of a loaded trace as the carriage's position.

    Attributes:
        trace: the loaded reference (``evaluate(t)`` -> 6-D poses, rates, accelerations).
        axis: the index (0..5) of its displaced platform axis; sign: +1 or -1, the map's sign
            undone (``s`` is the file's own displacement).
        centre: the trace's value of that axis at zero displacement.
        path: the file's path.  duration_s: its length, s.
    """

    def __init__(self, trace, axis: int, sign: float, centre: float, path: str):
        self.trace, self.axis, self.sign, self.centre = trace, int(axis), float(sign), centre
        self.path = path
        self.duration_s = float(getattr(trace, "end_time", np.inf))

    def on_clock_of(self, internal) -> "SurrogateTrace":
        """This trace on the clock of ``internal``, the motion it was recorded with
        (:func:`~stewart_drake.references.clock.on_clock_of`: a file that starts later is played
        later by as much)."""
        from ...references.clock import on_clock_of

        shifted = on_clock_of(self.trace, internal)
        if shifted is self.trace:
            return self
        return SurrogateTrace(shifted, self.axis, self.sign, self.centre, self.path)

    def evaluate(self, t):
        """(s, v, a) at trace times t (s), m, m/s, m/s^2, arrays of t's shape; held at the
        recording's ends."""
        x, v, a = self.trace.evaluate(np.asarray(t, dtype=float))
        k, sign = self.axis, self.sign
        return (
            sign * (np.asarray(x)[..., k] - self.centre),
            sign * np.asarray(v)[..., k],
            sign * np.asarray(a)[..., k],
        )


def load_surrogate_trace(
    path,
    format: str = "auto",
    columns: str = "",
    *,
    option: str = "--surrogate",
    columns_option: str | None = None,
) -> SurrogateTrace:
    """The external surrogate's trace at ``path``, centred on its mean.

    Args:
        path: a 2-column file (time, displacement in mm: the "surrogate" format), or a headed
            file of one translation (or one whose other columns ``columns`` names ``-``).
        format, columns: as :func:`~stewart_drake.references.traces.load_trace`'s.
        option: how a refusal names where the path came from (the command's option).
        columns_option: the command's option that names the columns, offered in a refusal
            (None: the command has none).
    Returns:
        :class:`SurrogateTrace`.
    Raises:
        MissingFileError, CorruptFileError, InvalidConfigError: as ``load_trace``'s; a trace of
            more than one axis or of none (the surrogate moves along one line), or of a
            rotation, named with ``option`` and the path.
    """
    trace = load_trace(path, format=format, columns=columns, centre_on="mean")
    info = getattr(trace, "info", None)
    axes = tuple(getattr(info, "axes", ()))
    if len(axes) != 1 or axes[0][1:] not in AXIS_NAMES[3:]:
        fix = "give a 2-column file (time, displacement in mm)"
        if columns_option:
            fix += f", or name the other columns '-' ({columns_option})"
        raise InvalidConfigError(
            f"{option} {path}: the surrogate moves along one line; this file gives "
            f"{', '.join(axes) or 'no axis'}: {fix}"
        )
    axis = AXIS_NAMES.index(axes[0][1:])
    sign = -1.0 if axes[0][0] == "-" else 1.0
    return SurrogateTrace(trace, axis, sign, float(trace.centre[axis]), str(path))
