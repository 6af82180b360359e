"""The surrogate as a scenario's section (``surrogate``): its stage, and the external signal it
follows, recorded (a file read by the one checked reader, :func:`~.pairs.load_external`) or made
from the internal motion by a correlation model (:class:`~.correlation.CorrelationModel`)."""

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from scipy.interpolate import CubicSpline

from ...base.errors import InvalidConfigError, MissingFileError
from ...base.signals import principal_displacement
from ...base.trace_layouts import trace_formats
from .correlation import CorrelationModel
from .stage import SurrogateStage

#: The grid the external signal is made on, s.
SIGNAL_STEP_S = 1e-3


@dataclass
class ExternalSignal:
    """The surrogate's motion as asked, about the stroke's middle.

    Attributes:
        t: (n,) s, uniform from 0 (:data:`SIGNAL_STEP_S`). p: (n,) m. internal: (n,) the
            internal along its main direction on ``t``, m about its mean (None: not known).
        direction: (3,) the internal's main direction in the world (None: not known).
        source: what it was made from, in words.
    """

    t: np.ndarray
    p: np.ndarray
    internal: np.ndarray | None
    direction: np.ndarray | None
    source: str

    def __post_init__(self):
        self._spline = CubicSpline(self.t, self.p)

    def evaluate(self, t) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(p m, v m/s, a m/s^2) at times t (s), (n,) each; held at the ends."""
        t = np.clip(np.asarray(t, float), self.t[0], self.t[-1])
        return self._spline(t), self._spline(t, 1), self._spline(t, 2)


@dataclass
class SurrogateAxis:
    """The surrogate beside the platform, a scenario section (``surrogate:``).

    Attributes:
        stage: the :class:`~.stage.SurrogateStage`.
        trace: the external's recorded file (IntERAct's 2-column ``Resp/`` format, or a header
            naming its columns; docs/surrogate.md), or "" to make it from the internal motion by
            ``correlation``.
        format, columns: as the trace reader's (:func:`~stewart_drake.references.traces.
            load_trace`): to read one column of a file that holds both, name the others ``-``.
        correlation: the :class:`~.correlation.CorrelationModel` (without ``trace``).
        match_platform_lag: take the signal as late as the platform is measured to be on its
            own reference (:mod:`~.lag_matching`, as the robot's session does on the bus), so
            that the pair keeps its recorded timing whatever the platform's controller; False:
            the signal on the run's clock as is.
    """

    stage: SurrogateStage = field(default_factory=SurrogateStage)
    trace: str = ""
    format: str = "auto"
    columns: str = ""
    correlation: CorrelationModel = field(default_factory=CorrelationModel)
    match_platform_lag: bool = True

    def validate(self, control_period_s: float | None = None) -> "SurrogateAxis":
        """Check the section. Raises: InvalidConfigError (the field named), MissingFileError
        (no file at ``trace``)."""
        self.stage.validate(control_period_s)
        self.correlation.validate()
        if self.format not in trace_formats():
            raise InvalidConfigError(
                f"surrogate.format must be one of {', '.join(trace_formats())}, got {self.format!r}"
            )
        if self.trace and not Path(self.trace).is_file():
            raise MissingFileError(f"no file at {self.trace!r} (surrogate.trace): check the path")
        if not isinstance(self.match_platform_lag, bool):
            raise InvalidConfigError(
                "surrogate.match_platform_lag must be true or false, got "
                f"{self.match_platform_lag!r}"
            )
        return self

    def signal(self, reference, duration_s: float) -> ExternalSignal:
        """The external signal over [0, duration_s], centred on the middle of its range.

        Args:
            reference: the run's internal motion (``evaluate(t)`` -> pose, rate, acceleration).
            duration_s: s.
        Raises:
            InvalidConfigError, CorruptFileError, MissingFileError: the trace refused by the
                reader.
        """
        t = np.arange(0.0, duration_s + SIGNAL_STEP_S / 2, SIGNAL_STEP_S)
        s, u = principal_displacement(reference.evaluate(t)[0])
        if self.trace:
            from .pairs import load_external

            p = load_external(self.trace, self.format, self.columns, internal=reference)(t)
            source = f"recorded: {self.trace}"
        else:
            pad = self.correlation.max_lead_s() + SIGNAL_STEP_S
            t_ext = np.arange(-pad, duration_s + pad + SIGNAL_STEP_S / 2, SIGNAL_STEP_S)
            x = reference.evaluate(t_ext)[0][:, 3:6]
            s_ext = (x - x.mean(axis=0)) @ u
            p = self.correlation.external(t, lambda q: np.interp(q, t_ext, s_ext))
            source = "the internal through the correlation model"
        p = p - 0.5 * (p.max() + p.min())
        return ExternalSignal(t=t, p=p, internal=s, direction=u, source=source)

    def samples(self, signal: ExternalSignal, duration_s: float, period_s: float, offset_s):
        """(t, p, v, a) of ``signal`` at the controller's instants offset_s + k period_s in
        [0, duration_s], checked against the stage (:meth:`~.stage.SurrogateStage.
        check_signal`; raises InvalidConfigError)."""
        t = np.arange(offset_s, duration_s + period_s, period_s)
        p, v, a = signal.evaluate(t)
        self.stage.check_signal(t, p, v, a)
        return t, p, v, a
