"""A motion's external signal made by a correlation model, as the surrogate's reference that
``verify INTERNAL --surrogate model --surrogate-param KEY=VALUE ...`` judges a measured surrogate
against: the same signal ``reproduce INTERNAL --surrogate model`` moves the surrogate's stage by
(:meth:`~stewart_drake.station.surrogate.axis.SurrogateAxis.signal` of the model
:func:`~stewart_drake.execution.trace_options.correlation_model` reads from the same words),
on SI (the platform's X), as a 2-column recorded file is read.

When the internal motion repeats (a library motion) and the model neither drifts nor changes,
the external repeats with it: it is made over two of the internal's periods and evaluated
modulo one, so that a measurement of any length is judged. Otherwise it is made over the
internal's own span (a trace's ``end_time``) or ``duration_s``, and a measurement is judged
where it overlaps it.
"""

from __future__ import annotations

import numpy as np

from ..base.errors import InvalidConfigError

#: The platform's axis a model's external signal is put on, with its sign: SI, X (as a 2-column
#: recorded file is read; the carriage's ``s`` is the signal itself).
MODEL_AXIS = (3, 1.0)


class ExternalReference:
    """The external signal (:class:`~stewart_drake.station.surrogate.axis.ExternalSignal`) as a
    reference of the platform's pose: the signal p (m) on X, the other axes 0.

    Attributes:
        name: "model". signal: the ExternalSignal. carriage_axis: :data:`MODEL_AXIS`.
        repeat_period_s: the internal's period when the external repeats with it, else None.
        end_time: the signal's last time, s, when it does not repeat (else None).
    """

    def __init__(self, signal, repeat_period_s: float | None, internal, name: str = "model"):
        self.signal = signal
        self.name = name
        self.carriage_axis = MODEL_AXIS
        self.repeat_period_s = repeat_period_s
        self.end_time = None if repeat_period_s else float(signal.t[-1])
        self._internal = internal

    def evaluate(self, t) -> tuple:
        """(pose, rate, acceleration) at times t (s, any shape), each ``np.shape(t) + (6,)``:
        the signal's p, v, a on X."""
        t = np.asarray(t, dtype=float)
        u = np.mod(t, self.repeat_period_s) if self.repeat_period_s else t
        out = []
        for part in self.signal.evaluate(u.ravel()):
            full = np.zeros(u.shape + (6,))
            full[..., MODEL_AXIS[0]] = MODEL_AXIS[1] * part.reshape(u.shape)
            out.append(full)
        return tuple(out)

    def frequencies_hz(self) -> dict:
        """The internal's fundamentals when the external repeats with it, else {}."""
        own = getattr(self._internal, "frequencies_hz", None)
        return own() if self.repeat_period_s and callable(own) else {}


def model_reference(internal, params, duration_s: float) -> ExternalReference:
    """The external signal of ``internal`` through the correlation model of ``params``
    (``KEY=VALUE`` words, as ``reproduce --surrogate-param`` takes them), as a reference (module
    docstring).

    Args:
        internal: the internal motion (``evaluate(t)``; a library motion's ``repeat_period_s``,
            a trace's ``end_time``). params: the words, or None for the motion itself.
        duration_s: s, the span made when the internal neither repeats nor ends.
    Raises:
        InvalidConfigError: what :func:`~stewart_drake.execution.trace_options.
            correlation_model` refuses (an unknown key, a value without its unit).
    """
    from ..execution.trace_options import correlation_model
    from ..station.surrogate.axis import SurrogateAxis

    model = correlation_model(params)
    period = getattr(internal, "repeat_period_s", None)
    steady = model.drift_m_per_s == 0.0 and model.change_at_s is None
    repeats = period if period and steady else None
    end = getattr(internal, "end_time", None)
    span = 2.0 * repeats if repeats else float(end if end is not None else duration_s)
    if not span > 0:
        raise InvalidConfigError(f"the external signal needs a span, got {span} s")
    signal = SurrogateAxis(correlation=model).signal(internal, span)
    return ExternalReference(signal, repeats, internal)


__all__ = ["MODEL_AXIS", "ExternalReference", "model_reference"]
