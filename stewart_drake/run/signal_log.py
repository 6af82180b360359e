"""A run's logs, in arrays sized for the run: one time base per logger, a chosen precision per
signal.

Drake's ``VectorLogSink`` keeps doubles and doubles its capacity when full, so a log can hold
twice (and while it grows, three times) what it logged; a 25-minute run at 1 kHz logging the
plant's 86-entry state took gigabytes. :class:`SignalLog` logs several vector inputs at one
period into arrays allocated once for the run's length (grown only if the run outlasts it), each
in its own dtype: the run's full-rate signals in float32 (7 significant digits: 30 nm at the
platform's 0.3 m height, a thousandth of the smallest error a report resolves), the plant state
a replay needs in float64 at its own, slower period.
"""

from __future__ import annotations

import numpy as np
from pydrake.systems.framework import LeafSystem


class LogView:
    """One signal of a :class:`SignalLog` as Drake's ``VectorLog`` shows it:
    ``sample_times()`` (n,) s and ``data()`` (size, n), views of the logged arrays (no copy)."""

    def __init__(self, log: SignalLog, name: str):
        self._log, self._name = log, name

    def sample_times(self) -> np.ndarray:
        return self._log.t[: self._log.num_samples]

    def data(self) -> np.ndarray:
        return self._log.values[self._name][: self._log.num_samples].T

    def num_samples(self) -> int:
        return self._log.num_samples


class SignalLogger:
    """The handle of one signal of a :class:`SignalLog`, as ``LogVectorOutput`` returns one:
    ``FindLog(context)`` gives its :class:`LogView` (the log lives in the system: one run per
    Diagram, as every builder here makes)."""

    def __init__(self, log: SignalLog, name: str):
        self.log, self.name = log, name

    def FindLog(self, context=None) -> LogView:  # noqa: N802 - Drake's name
        return LogView(self.log, self.name)

    def set_name(self, name: str) -> None:  # noqa: ARG002 - the system carries its own name
        """Kept for the loggers' common interface: the signals share their system's name."""


class SignalLog(LeafSystem):
    """Log vector inputs every ``period_s`` (first at t = 0, as ``LogVectorOutput``) into
    preallocated arrays.

    Input ports: one per signal, named as given, of its size.

    Args:
        signals: {name: (size, dtype)} e.g. {"x": (12, np.float32)}.
        period_s: the logging period, s (> 0).
        duration_s: the run's length, s: the arrays hold floor(duration_s / period_s) + 2
            samples (a longer run grows them by half).
    Attributes:
        t: (capacity,) float64 sample times, s. values: {name: (capacity, size)} arrays.
        num_samples: samples logged (the first ``num_samples`` rows are the log).
    """

    def __init__(self, signals: dict, period_s: float, duration_s: float):
        super().__init__()
        self.period_s = float(period_s)
        capacity = int(np.floor(duration_s / period_s + 1e-6)) + 2
        self.t = np.empty(capacity)
        self.values = {
            name: np.empty((capacity, size), dtype=dtype) for name, (size, dtype) in signals.items()
        }
        self._ports = [
            (name, self.DeclareVectorInputPort(name, size)) for name, (size, _) in signals.items()
        ]
        self.num_samples = 0
        self.DeclareInitializationPublishEvent(self._Reset)
        self.DeclarePeriodicPublishEvent(period_s, 0.0, self._Log)

    def logger(self, name: str) -> SignalLogger:
        """The handle of signal ``name`` (its ``FindLog``)."""
        return SignalLogger(self, name)

    def nbytes(self) -> int:
        """Bytes the arrays hold (allocated, not only logged)."""
        return self.t.nbytes + sum(v.nbytes for v in self.values.values())

    def _Reset(self, context) -> None:
        self.num_samples = 0

    def _Log(self, context) -> None:
        k = self.num_samples
        if k == self.t.size:  # the run outlasts the arrays: grow by half
            grow = max(2, self.t.size // 2)
            self.t = np.concatenate([self.t, np.empty(grow)])
            for name, v in self.values.items():
                self.values[name] = np.concatenate([v, np.empty((grow, v.shape[1]), v.dtype)])
        self.t[k] = context.get_time()
        for name, port in self._ports:
            self.values[name][k] = port.Eval(context)
        self.num_samples = k + 1
