"""What a run's Diagram logs (:func:`add_run_logs`): arrays sized for the run, one time base per
logger, a chosen precision per signal.

Drake's ``VectorLogSink`` keeps doubles and doubles its capacity when full, so a log can hold
twice (and while it grows, three times) what it logged; a 25-minute run at 1 kHz logging the
plant's 86-entry state took gigabytes. :class:`SignalLog` logs several vector inputs at one
period into arrays allocated once for the run's length (grown only if the run outlasts it), each
in its own dtype: the run's full-rate signals in float32 (7 significant digits: 30 nm at the
platform's 0.3 m height, a thousandth of the smallest error a report resolves), the plant state a
replay needs in float64 at its own, slower period. :mod:`.result` reads them back.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from pydrake.systems.framework import LeafSystem
from pydrake.systems.primitives import Multiplexer, VectorLogSink

#: How often a :class:`SignalLog` moves what Drake's C++ sink logged into its arrays, s: a
#: sink keeps float64 rows in memory that doubles when full, so it holds at most this much run.
DRAIN_PERIOD_S = 1.0


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
    ``FindLog(root_context)`` moves what the sink still holds in that Context into the arrays
    and gives the signal's :class:`LogView` (the arrays live in the system: one run per
    Diagram, as every builder here makes)."""

    def __init__(self, log: SignalLog, name: str):
        self.log, self.name = log, name

    def FindLog(self, context=None) -> LogView:  # noqa: N802 - Drake's name
        if context is not None:
            self.log.drain(context)
        return LogView(self.log, self.name)

    def set_name(self, name: str) -> None:  # noqa: ARG002 - the system carries its own name
        """Kept for the loggers' common interface: the signals share their system's name."""


class SignalLog(LeafSystem):
    """Signals logged every ``period_s`` (first at t = 0, as ``LogVectorOutput``) by Drake's C++
    ``VectorLogSink`` (no Python call per sample), and moved every
    ``drain_period_s`` into arrays allocated once for the run, each in its own dtype, after an
    optional conversion (e.g. plant states to platform poses, vectorized).

    :meth:`add` adds it with its sink. The sink's log lives in the run's Context: :meth:`bind`
    (:meth:`~.diagram.StewartDiagram.initialize` does it) tells the periodic drain where it
    is, and a handle's ``FindLog(root_context)`` drains what is left. A run never bound still
    logs every sample, its sink holding them until it is read.

    Args:
        signals: {name: (port, dtype)} or {name: (port, dtype, size, convert)}: the
            ``OutputPort`` logged and the array's dtype; ``convert(rows)`` maps the sink's
            float64 rows (n, port size) to the signal's (n, size).
        period_s: the logging period, s (> 0).
        duration_s: the run's length, s: the arrays hold floor(duration_s / period_s) + 2
            samples (a longer run grows them by half).
        drain_period_s: how often the sink is drained, s.
    Attributes:
        t: (capacity,) float64 sample times, s. values: {name: (capacity, size)} arrays.
        num_samples: samples moved so far (the first ``num_samples`` rows are the log).
        sink: the ``VectorLogSink`` (:meth:`add` adds and connects it).
    """

    def __init__(
        self,
        signals: dict,
        period_s: float,
        duration_s: float,
        drain_period_s: float = DRAIN_PERIOD_S,
    ):
        super().__init__()
        self.period_s = float(period_s)
        capacity = int(np.floor(duration_s / period_s + 1e-6)) + 2
        self.t = np.empty(capacity)
        specs = {name: (*spec, spec[0].size(), None)[:4] for name, spec in signals.items()}
        self.values = {
            name: np.empty((capacity, size), dtype=dtype)
            for name, (_, dtype, size, _) in specs.items()
        }
        self._convert = {name: spec[3] for name, spec in specs.items()}
        self._ports = {name: spec[0] for name, spec in specs.items()}
        self.sink: Any = None  # a VectorLogSink, added by add()
        self._columns: dict = {}
        self._context: Any = None
        self.num_samples = 0
        self.DeclareInitializationPublishEvent(self._Reset)
        self.DeclarePeriodicPublishEvent(drain_period_s, drain_period_s, self._Drain)

    @classmethod
    def add(cls, builder, name: str, signals: dict, period_s: float, duration_s: float):
        """Add a :class:`SignalLog` named ``name`` of ``signals`` (as the constructor takes
        them) to ``builder``, with its ``VectorLogSink`` (``<name>_sink``) and, for more than
        one signal, the ``Multiplexer`` that gathers them (``<name>_mux``): one sink's event
        a sample, not one per signal."""
        log = builder.AddNamedSystem(name, cls(signals, period_s, duration_s))
        ports = list(log._ports.values())
        sizes = [port.size() for port in ports]
        log.sink = builder.AddNamedSystem(
            f"{name}_sink", VectorLogSink(sum(sizes), publish_period=period_s)
        )
        if len(ports) == 1:
            builder.Connect(ports[0], log.sink.get_input_port())
        else:
            mux = builder.AddNamedSystem(f"{name}_mux", Multiplexer(sizes))
            for i, port in enumerate(ports):
                builder.Connect(port, mux.get_input_port(i))
            builder.Connect(mux.get_output_port(), log.sink.get_input_port())
        ends = np.cumsum([0, *sizes])
        log._columns = {
            signal: slice(a, b) for signal, a, b in zip(log._ports, ends[:-1], ends[1:])
        }
        log._ports = {}  # the ports' systems are the Diagram's: not held here
        return log

    def logger(self, name: str) -> SignalLogger:
        """The handle of signal ``name`` (its ``FindLog``)."""
        return SignalLogger(self, name)

    def nbytes(self) -> int:
        """Bytes the arrays hold (allocated, not only logged)."""
        return self.t.nbytes + sum(v.nbytes for v in self.values.values())

    def bind(self, root_context) -> None:
        """Drain the sink's log in ``root_context`` (the run's) from now on."""
        self._context = self.sink.GetMyMutableContextFromRoot(root_context)

    def unbind(self) -> None:
        """Forget the run's Context (a read run's: its Context can then be freed)."""
        self._context = None

    def drain(self, root_context=None) -> None:
        """Move what the sink holds (in ``root_context``, binding it; else in the bound
        Context) into the arrays, converted, and clear the sink."""
        if root_context is not None:
            self.bind(root_context)
        if self._context is None:
            return
        log = self.sink.GetMutableLog(self._context)
        n = log.num_samples()
        if n == 0:
            return
        k = self.num_samples
        self._reserve(k + n)
        self.t[k : k + n] = log.sample_times()
        rows = log.data().T
        for name, columns in self._columns.items():
            convert = self._convert[name]
            values = rows[:, columns]
            self.values[name][k : k + n] = values if convert is None else convert(values)
        log.Clear()
        self.num_samples = k + n

    def _reserve(self, n: int) -> None:
        """Grow the arrays by half (at least to n rows) when the run outlasts them."""
        if n <= self.t.size:
            return
        grow = max(n - self.t.size, self.t.size // 2, 2)
        self.t = np.concatenate([self.t, np.empty(grow)])
        for name, v in self.values.items():
            self.values[name] = np.concatenate([v, np.empty((grow, v.shape[1]), v.dtype)])

    def _Reset(self, context) -> None:
        # A run initialized again starts its log again: what the sink holds goes too (this
        # event runs before the sink's first sample: the log is added to the Diagram first).
        self.num_samples = 0
        if self._context is not None:
            self.sink.GetMutableLog(self._context).Clear()

    def _Drain(self, context) -> None:
        self.drain()


def add_run_logs(builder, station, controller, outputs: set, plan, learner=None) -> dict:
    """The run's logs (:class:`SignalLog`): every ``log_period_s`` in float32 the true platform
    pose and rate "x", the applied torques "T" and the controller's "status", "integral", "e_bar"
    when it has them (named in ``outputs``); every ``state_log_period_s`` the plant's "state" in
    float64 (a replay's frames, the loop-closure error, a divergence record) and a learner's
    status under its ``status_port`` name (it changes once a cycle or stretch: logging it every
    millisecond cost 0.26 kB a sample; the correction itself is not logged, nothing reads it).

    Args:
        builder: the DiagramBuilder. station: the station (its ports). controller: the
            controller system. outputs: the controller's output ports to log. plan: the run's
            :class:`~.plan.RunPlan` (its scenario's periods and duration). learner: the
            learner system, or None.
    Returns:
        {name: logger}, each with Drake's ``FindLog(context)``.
    """
    scenario = plan.scenario
    pose_port, to_pose = station.logged_pose()
    signals = {
        "x": (pose_port, np.float32) if to_pose is None else (pose_port, np.float32, 12, to_pose),
        "T": (station.GetOutputPort("motor_torque_applied"), np.float32),
    }
    for name in ("status", "integral", "e_bar"):
        if name in outputs:
            signals[name] = (controller.GetOutputPort(name), np.float32)
    slow = {"state": (station.GetOutputPort("plant_state"), np.float64)}
    if learner is not None:
        slow[learner.status_port] = (learner.GetOutputPort(learner.status_port), np.float64)
    loggers = {}
    for log_name, period, group in (
        ("log_signals", scenario.log_period_s, signals),
        ("log_state", scenario.state_log_period_s, slow),
    ):
        log = SignalLog.add(builder, log_name, group, period, scenario.duration_s)
        loggers.update({name: log.logger(name) for name in group})
    return loggers


__all__ = [
    "DRAIN_PERIOD_S",
    "LogView",
    "SignalLogger",
    "SignalLog",
    "add_run_logs",
]
