"""The robot's Drake plant behind the bus emulator, in a process of its own.

In one process with the control loop, the emulator's plant (:class:`~.plant_backend.
StationServos`) and the Diagram share Python's GIL: a step of the Drake plant holds it, and on
a loaded machine the plant slips behind the wall clock in chunks of up to the emulator's
``max_step_s`` (one current held over 20 ms, a state 20 ms stale), which no controller tuned
for a period of a few ms survives. A servo computes on its own chip; here the emulator does in
its own process (``multiprocessing``, spawned), and records the platform's *true* pose at
every step of its plant, for a run's tracking beside the pose the driver measures.

On a real robot only the encoders' pose exists (and a tracker's, ``verify``). On the emulator
the plant behind the bus is known at every one of its steps (:meth:`EmulatorProcess.truth`), so
a rehearsal can say how far the robot's own figures are from the motion it really made:
:func:`truth_and_reading` pairs them on the run's clock, :func:`truth_lines` says them.

    with EmulatorProcess(x0=x_d0) as emu:       # emu.port: the pty to open the bus on
        ...                                      # run the loop
    t, x = emu.truth()                           # perf_counter times (s), poses (n, 12)

``time.perf_counter`` is the system's monotonic clock on Linux, the same in both processes.
"""

from __future__ import annotations

import gc
import multiprocessing
import time
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..base.errors import BusError
from ..base.measures import peak_per_axis, rms_per_axis
from ..robot.kinematics import AXIS_NAMES, X_HOME
from ..station.bus.emulator_config import EMULATED_BUS
from ..station.bus.servos import DEFAULT_MODEL


@dataclass(frozen=True)
class _ChildArgs:
    """What the child's emulator is made of (:class:`EmulatorProcess`'s arguments, the scenario
    as YAML): pickled to the spawned process."""

    ids: list
    model: str
    x0: np.ndarray
    scenario_yaml: str
    tick_s: float
    max_step_s: float
    zero_counts: list | None
    realtime: bool
    surrogate: Any = None
    servos: Any = None
    baud_rate: int = 1_000_000
    period_s: float | None = None


def _serve(conn, made: _ChildArgs) -> None:  # pragma: no cover
    """The child: a :class:`~.emulator.BusEmulator` on a plant that records its pose; sends
    ("port", the port), serves until told to stop, then sends the record. If it cannot start it
    sends ("error", one line) instead of a traceback on the terminal.

    It ignores the terminal's signals (SIGINT, SIGTERM, SIGHUP, SIGQUIT): an operator's Ctrl-C (or a
    signal to the job's process group) is for the robot's session, which then turns the torque off
    through this emulator and must find it still answering, as servos keep answering a stopped
    program. It ends when the parent says stop or its end of the pipe closes (the parent gone)."""
    import signal
    import sys

    from ..execution.runners import TERMINAL_SIGNALS

    # The bus thread sleeps out each packet's time on the wire while the model thread steps the
    # plant: Python's default 5 ms between the threads' turns at the GIL would delay each reply
    # by up to that, several times a packet; servos answer on their own chips.
    sys.setswitchinterval(2e-4)
    for name in TERMINAL_SIGNALS:  # the session's (SessionSignals)
        if hasattr(signal, name):
            signal.signal(getattr(signal, name), signal.SIG_IGN)
    try:
        emu = _start(made)
        # What start-up made (Drake, the plant, the modules) is never scanned again: a full
        # collection over it paused the servos' answers by 35 to 45 ms every few minutes.
        gc.collect()
        gc.freeze()
        _start_threads(emu, made.realtime)
    except Exception as err:  # noqa: BLE001 - reported to the parent in one line
        conn.send(("error", f"{type(err).__name__}: {err}".splitlines()[0]))
        return
    try:
        conn.send(("port", emu.port))
        try:
            conn.recv()  # stop
        except EOFError:  # the parent is gone: nobody to answer
            return
        record = emu.with_backend(lambda b: getattr(b, "parts", [b])[0].record.rows())
        conn.send((record, emu.slipped_s))
    finally:
        emu.close()


def _start_threads(emu, realtime: bool) -> None:  # pragma: no cover
    """Start the emulator's threads; with ``realtime``, on SCHED_FIFO one priority below the
    loop's (:data:`~.realtime.PRIORITY`; the plant's thread one below the bus's) and on every
    core but the loop's
    (:func:`~.realtime.loop_core`), where the OS allows: the threads inherit the policy and
    the cores of the thread that starts them, which then goes back to the normal policy."""
    import os

    from .realtime import PRIORITY, loop_core

    if not realtime:
        emu.start()
        return
    old = None
    try:
        cores = os.sched_getaffinity(0)
        others = cores - {loop_core()}
        old = (os.sched_getscheduler(0), os.sched_getparam(0), cores)
        if others:
            os.sched_setaffinity(0, others)
        os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(PRIORITY - 1))
    except (AttributeError, OSError):  # refused: the loop's own line says so
        pass
    try:
        emu.start()
        model = getattr(emu._model_thread, "native_id", None)
        if old is not None and model is not None:
            # The plant one priority below the bus: a servo answers on its own chip, so a reply
            # whose time is up runs before the next step of the plant (on one core, threads of
            # one FIFO priority take turns only when one blocks).
            try:
                os.sched_setscheduler(model, os.SCHED_FIFO, os.sched_param(PRIORITY - 2))
            except OSError:
                pass
    finally:
        if old is not None:
            try:
                os.sched_setscheduler(0, old[0], old[1])
                os.sched_setaffinity(0, old[2])
            except OSError:
                pass


class RecordRows:
    """Rows of ``width`` floats [time, values...] kept in numpy blocks of :data:`BLOCK_ROWS`
    allocated as they fill: a plant step's record costs no Python object, so the emulator's
    process never pauses for a garbage collection over hundreds of thousands of them (as a list
    of tuples did: 40 to 50 ms at about 90 s of a run, a late reply on the bus)."""

    BLOCK_ROWS = 16_384

    def __init__(self, width: int):
        self._blocks: list[np.ndarray] = []
        self.width, self._n = int(width), 0

    def add(self, t: float, values) -> None:
        k = self._n % self.BLOCK_ROWS
        if k == 0:
            self._blocks.append(np.empty((self.BLOCK_ROWS, self.width)))
        row = self._blocks[-1][k]
        row[0] = t
        row[1:] = values
        self._n += 1

    def rows(self) -> np.ndarray:
        """(n, width) every row added, oldest first."""
        if not self._blocks:
            return np.zeros((0, self.width))
        return np.concatenate(self._blocks)[: self._n]


def _start(made: _ChildArgs):  # pragma: no cover
    """The child's :class:`~.emulator.BusEmulator` (not started) on the recording plant (with
    ``servos``, an :class:`~stewart_drake.station.bus.emulator_config.EmulatedServos` that
    departs from the controller's model, :class:`~.plant_backend.RealisticServos` and the bus's
    timing), and with ``surrogate`` (a :class:`~stewart_drake.station.bus.servos.
    SurrogateServoConfig`) its stage as the last servo, the carriage at mid-travel."""
    from ..run.scenario import _scenario_from_yaml
    from ..station.bus.bus_timing import BusTiming
    from ..station.bus.emulator import BusEmulator
    from ..station.bus.servo_models import FirstOrderServos, ServoBackend, StackedServos
    from .plant_backend import RealisticServos, StationServos, dynamixel_scenario

    ids, model, x0, servos = list(made.ids), made.model, made.x0, made.servos
    zero_counts, surrogate = made.zero_counts, made.surrogate
    scenario = dynamixel_scenario(model, _scenario_from_yaml(made.scenario_yaml))
    departs = servos is not None and servos.departs()
    base = RealisticServos if departs else StationServos

    class Recorded(base):  # type: ignore[valid-type, misc]
        def __init__(self):
            if departs:
                super().__init__(scenario, model, x0, servos)
            else:
                super().__init__(scenario, model, x0)
            station = self.station
            self._port = station.GetOutputPort("platform_state")
            self._context = station.GetMyContextFromRoot(self.simulator.get_context())
            self.record = RecordRows(13)
            self.t_model = 0.0  # the loop's clock: the time the model was carried

        def advance(self, dt_s, current_A):
            super().advance(dt_s, current_A)
            self.t_model += dt_s
            t = time.perf_counter() if made.period_s is None else self.t_model
            self.record.add(t, self._port.Eval(self._context))

    backend: ServoBackend = Recorded()
    models = None
    if surrogate is not None:
        stage = FirstOrderServos.linear_stage(surrogate.stage)
        backend = StackedServos(backend, stage)
        ids = [*ids, surrogate.id]
        from ..station.bus.servos import servo_spec

        cranks = zero_counts or [servo_spec(model, torque_control=False).zero_count] * (
            len(ids) - 1
        )
        zero_counts = [*cranks, surrogate.zero_counts]
        models = {surrogate.id: surrogate.model}
    timing = None
    if servos is not None and (
        servos.latency_timer_ms or servos.reply_jitter_us or servos.return_delay_us
        or servos.crc_error_rate or servos.timeout_rate
    ):  # fmt: skip
        timing = BusTiming(
            made.baud_rate,
            servos.latency_timer_ms,
            servos.reply_jitter_us,
            servos.crc_error_rate,
            servos.timeout_rate,
            servos.seed,
        )
    return BusEmulator(
        ids,
        model,
        backend=backend,
        zero_counts=zero_counts,
        tick_s=made.tick_s,
        max_step_s=made.max_step_s,
        models=models,
        timing=timing,
        return_delay_us=0.0 if servos is None else servos.return_delay_us,
        command_step_s=made.period_s,
        catch_up=made.period_s is not None,
    )


class EmulatorProcess:
    """A :class:`~.emulator.BusEmulator` with the robot's Drake plant
    (:class:`~.plant_backend.StationServos` of ``dynamixel_scenario(model, scenario)``) in a
    spawned process.

    Args:
        x0: (6,) the pose the robot starts at [rad, m].
        ids, model: the bus's servos. scenario: the robot (default the paper's), as a
            Scenario: its robot and plant settings are used.
        tick_s, max_step_s: the emulator's (:class:`~.emulator.BusEmulator`).
        start_timeout_s: how long to wait for the child's port.
        zero_counts: (n,) the counts each servo reports at its crank's zero angle (default
            2048, the bus's default).
        realtime: the emulator's threads on SCHED_FIFO one priority below the control loop's,
            off its core (where the OS allows): the servos it stands in for compute on chips of
            their own, not on the loop's computer.
        surrogate: None, or the bus's surrogate servo
            (:class:`~stewart_drake.station.bus.servos.SurrogateServoConfig`): its stage
            (:meth:`~stewart_drake.station.bus.servo_models.FirstOrderServos.linear_stage`) answers
            as one more servo, its carriage at mid-travel, on the plant's clock.
        servos: None (the controller's own model), or the servos as built
            (:class:`~stewart_drake.station.bus.emulator_config.EmulatedServos`, drawn by a
            scenario's ``emulator``): their drive, friction and encoders, and the bus's timing.
        baud_rate: the bus's, bps (the wire's time of each packet).
        period_s: None (default): the plant on the wall clock. The control period, s: on the
            loop's clock, the plant carried one period at each command up to its instant
            (:class:`~stewart_drake.station.bus.emulator.BusEmulator`'s ``catch_up``), its
            :meth:`truth` on the loop's time.
    Attributes:
        port: the pty's path (after :meth:`start`). slipped_s: the plant's slip, s (after
            :meth:`close`).
    Raises:
        BusError: the child did not start in time.
    """

    def __init__(
        self,
        x0=X_HOME,
        ids=(1, 2, 3, 4, 5, 6),
        model: str = DEFAULT_MODEL,
        scenario=None,
        tick_s: float = 0.001,
        max_step_s: float = 0.02,
        start_timeout_s: float = 120.0,
        zero_counts=None,
        realtime: bool = False,
        surrogate=None,
        servos=None,
        baud_rate: int = 1_000_000,
        period_s: float | None = None,
    ):
        from ..run.scenario import Scenario, dump_scenario

        self._args = _ChildArgs(
            list(ids),
            model,
            np.asarray(x0, dtype=float),
            dump_scenario(scenario if scenario is not None else Scenario()),
            tick_s,
            max_step_s,
            None if zero_counts is None else [int(c) for c in zero_counts],
            bool(realtime),
            surrogate,
            servos,
            int(baud_rate),
            None if period_s is None else float(period_s),
        )
        #: The control period of the loop's clock, or None: the wall clock.
        self.period_s = self._args.period_s
        self.start_timeout_s = start_timeout_s
        #: The servos behind the bus (None: the controller's own model).
        self.servos = servos
        self.port: str | None = None
        self.slipped_s = float("nan")
        self._record = np.zeros((0, 13))
        self._process: Any = None

    def start(self) -> EmulatorProcess:
        context = multiprocessing.get_context("spawn")
        self._conn, child = context.Pipe()
        self._process = context.Process(target=_serve, args=(child, self._args), daemon=True)
        self._process.start()
        try:
            deadline = time.monotonic() + self.start_timeout_s
            while not self._conn.poll(0.2):
                if not self._process.is_alive() or time.monotonic() > deadline:
                    code = self._process.exitcode
                    raise BusError(
                        "the bus emulator's process "
                        + (f"exited ({code})" if code is not None else "did not start in time")
                        + " (a script that starts it needs `if __name__ == '__main__':`)"
                    )
            kind, value = self._conn.recv()
            if kind == "error":  # the child's own one line: no traceback, no hint
                raise BusError(f"the bus emulator did not start: {value}")
        except BaseException:  # a refusal, or Ctrl-C while it starts: no orphan
            self.close(timeout_s=1.0)
            raise
        self.port = value
        return self

    def close(self, timeout_s: float = 30.0) -> None:
        """Stop the child and collect its record. Idempotent."""
        if self._process is None:
            return
        if self.port is not None:
            _EMULATED_PORTS.pop(self.port, None)
        try:
            if self._process.is_alive():
                self._conn.send("stop")
                if self._conn.poll(timeout_s):
                    self._record, self.slipped_s = self._conn.recv()
        except (BrokenPipeError, EOFError, OSError):
            pass
        self._process.join(timeout_s)
        if self._process.is_alive():  # SIGKILL: the child ignores SIGTERM (:func:`_serve`)
            self._process.kill()
            self._process.join(timeout_s)
        self._process = None

    def __enter__(self):
        return self.start()

    def __exit__(self, *exc):
        self.close()

    def truth(self) -> tuple[np.ndarray, np.ndarray]:
        """(t (n,) s, x (n, 12) the platform's true pose and rate) at every step of the plant
        while a servo drove it (after :meth:`close`): t the wall clock's (perf_counter), or on
        the loop's clock (``period_s``) the loop's time since its first command."""
        return self._record[:, 0], self._record[:, 1:]


#: The reply timeout of the emulated bus when the scenario leaves the SDK's, s. The SDK's (about
#: 34 ms) is a USB adapter's latency timer; the emulator's pseudo-terminal passes each packet
#: through the kernel's tty workers, which a loaded machine delays by up to a second each way
#: whatever the emulator does (docs/hardware_bus.md, "What is emulated"): with 34 ms a busy
#: machine's delay reads as a servo that does not answer.
EMULATED_REPLY_TIMEOUT_S = 2.0
#: Our watchdog's least limit for a session on the emulator on the loop's clock, s: its plant's
#: step holds the read after each command, and a loaded machine stalls it for a second or so.
EMULATED_LOOP_TIMEOUT_S = 2.0


def start_emulator(scenario, x0, realtime: bool = False) -> EmulatorProcess:
    """Start the bus emulator with the scenario's robot (its Drake plant at a 2 ms step, half
    the CPU of 1 ms; on ``emulator.clock: loop`` the deadline misses counted and not fatal, the
    emulator's own step holding the loop's reads; its servos and bus as the scenario's
    ``emulator`` draws them, ``servos`` on the process returned) behind it in a process of its
    own, resting at pose ``x0``, and point ``scenario.bus`` at its pseudo-terminal, with a reply
    timeout of :data:`EMULATED_REPLY_TIMEOUT_S` unless the scenario sets one; returns the
    :class:`~stewart_drake.live.emulator_process.EmulatorProcess` (close it). With ``realtime``
    the emulator's threads run on SCHED_FIFO one priority below the loop, off the loop's core:
    they stand in for servos, which compute on chips of their own."""
    from ..station.bus.servos import servo_spec
    from .plant_backend import behind_the_bus

    bus = scenario.bus
    if bus.reply_timeout_s is None:
        bus.reply_timeout_s = EMULATED_REPLY_TIMEOUT_S
    if scenario.emulator.clock == "loop":  # a late period is the emulator's step, not a robot's
        bus.max_deadline_misses = max(bus.max_deadline_misses, 10**9)
    servos = scenario.emulator.draw(servo_spec(bus.model, torque_control=False), len(bus.ids))
    robot = behind_the_bus(scenario, servos)
    emulator = EmulatorProcess(
        x0=x0,
        ids=bus.ids,
        model=bus.model,
        scenario=robot,
        zero_counts=bus.zero_counts,
        start_timeout_s=300.0,
        realtime=realtime,
        surrogate=bus.surrogate,
        servos=servos,
        baud_rate=bus.baud_rate,
        period_s=scenario.control_period_s if scenario.emulator.clock == "loop" else None,
    ).start()
    bus.port = port = str(emulator.port)
    _EMULATED_PORTS[port] = EMULATED_BUS + servos.summary()
    return emulator


#: The ports of the bus emulators :func:`start_emulator` started in this process and that are not
#: closed, each with its servos in words: what a run on that port writes of its bus.
_EMULATED_PORTS: dict[str, str] = {}


def bus_words(port: str) -> str:
    """What this process knows of the bus on ``port``, in the words a run's encoder log keeps
    (:func:`~stewart_drake.calibration.join.write_encoder_log`'s ``bus``): ``emulated: `` and
    the emulator's servos when :func:`start_emulator` serves it, else the servos on ``port``,
    not emulated by this run (a bus emulator this process did not start cannot be told from
    servos, so that is all it says)."""
    return _EMULATED_PORTS.get(port, f"the servos on {port}, not emulated by this run")


def truth_and_reading(sd, truth, window, loop_clock: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """(true errors (n, 6), encoder errors (m, 6)) over the run's ``window`` (start, end) s,
    rad and m: the emulator's plant at each of its steps against the reference at the Diagram
    time of its wall-clock time, and the pose the driver measured each period against the
    reference at that period.

    Args:
        sd: the run's :class:`~stewart_drake.run.diagram.StewartDiagram` (its station's driver
            kept every period's reading and wall-clock start).
        truth: (t (k,) perf_counter s, x (k, 12)) of the emulator
            (:meth:`EmulatorProcess.truth`).
        window: (start, end) Diagram time, s.
        loop_clock: the emulator on the loop's clock: ``truth``'s times are the loop's since
            its first command, the Diagram's.
    """
    driver = sd.station.driver
    t_periods = driver.readings()[0]
    t_true, x_true = truth
    if loop_clock:
        inside = np.ones(len(t_true), dtype=bool)
        t_run = t_true + t_periods[0]
    else:
        walls = driver.timing.rows()[:, 0]
        n = min(len(walls), len(t_periods))
        inside = (t_true >= walls[0]) & (t_true <= walls[n - 1])
        t_run = np.interp(t_true[inside], walls[:n], t_periods[:n])
    keep = (t_run >= window[0]) & (t_run <= window[1])
    e_true = x_true[inside][keep, :6] - sd.trajectory.evaluate(t_run[keep])[0]
    read = (t_periods >= window[0]) & (t_periods <= window[1])
    e_read = driver.pose_readings()[read] - sd.trajectory.evaluate(t_periods[read])[0]
    return e_true, e_read


def truth_lines(sd, truth, window, floor, emulator=None) -> list[str]:
    """The true and the encoders' RMS (peak) error per axis over ``window``, beside the
    encoders' floor (6,) [rad, m] (:func:`~stewart_drake.analysis.error_budget.
    quantization_floor`), and what the encoders cannot see; mrad and mm. With the
    ``emulator`` (:class:`EmulatorProcess`, closed): its clock, and on the
    wall clock how far its plant fell behind (its figures then the emulator's, not a robot's)."""
    loop_clock = emulator is not None and emulator.period_s is not None
    e_true, e_read = truth_and_reading(sd, truth, window, loop_clock)
    if len(e_true) == 0 or len(e_read) == 0:
        return ["the emulator's true pose: no step of its plant inside the measured window"]

    def cells(e):
        return [f"{1e3 * r:.3g} ({1e3 * p:.3g})" for r, p in zip(rms_per_axis(e), peak_per_axis(e))]

    true, read = cells(e_true), cells(e_read)
    lines = [
        f"on the emulator, t in [{window[0]:g}, {window[1]:g}] s, RMS (peak), mrad | mm:",
        f"  {'':>6}  {'true pose':>18}  {'encoders read':>18}  {'floor':>7}",
    ]
    for k, axis in enumerate(AXIS_NAMES):
        lines.append(f"  {axis:>6}  {true[k]:>18}  {read[k]:>18}  {1e3 * floor[k]:7.3g}")
    lines.append(
        "  the true pose is the emulator's plant; the encoders cannot see a crank within its "
        "count (the floor: half a count, uniform, through J^-1) nor what bends between the "
        "cranks and the platform (the emulated robot is rigid)"
    )
    if loop_clock:
        lines.append(
            "  the emulator's plant on the loop's clock: carried one control period at each "
            "command (emulator.clock: loop), immune to this machine's speed"
        )
    elif emulator is not None and emulator.slipped_s > 0:
        lines.append(
            f"  the emulator's plant fell {emulator.slipped_s:.3f} s behind the wall clock "
            "(this machine could not run it in real time): its figures are the emulator's, not "
            "a robot's; emulator.clock: loop carries it on the loop's clock instead"
        )
    return lines
