"""The controller Diagram on the robot's servos: a session with its safety paths.

A scenario with a ``bus`` (the servos' port, ids and calibration) runs on the robot. The
session (:func:`run_on_robot`) is the only code that enables the servos' torque, and every way
out of it removes the torque:

1. the reference is checked whole before the port is opened (as a simulated run's is);
2. the servos are configured with the torque off and their settings read back
   (:meth:`~stewart_drake.station.bus.driver.DynamixelBus.configure`);
3. the pose is measured (encoders -> forward kinematics) and the run's reference gets a homing
   lead-in from that pose to the reference's start
   (:class:`~stewart_drake.references.homing.HomingReference`); that whole path, the measured
   pose first, passes every check of the admissible set
   (:func:`~stewart_drake.run.plan.check_reference`: reach, joint ranges, singularities,
   clearance, the motors' torque and speed) or nothing is powered;
4. only then the torque is enabled, and the Diagram runs at real time behind our watchdog
   (:class:`~.watchdog.LoopWatchdog`) and the servos' own bus watchdog;
5. the end, whatever ends it (the reference's end, Ctrl-C, SIGTERM, a bus error, a missed
   deadline, a guard trip, our watchdog), removes the torque, says in one line why it ended
   and whether every servo confirmed the torque off, and keeps the logs (the ``.npz`` of a
   simulated run; :func:`~stewart_drake.run.result.save_result`).

At the end of a run the torque is off: the platform comes down onto its stops. Home it low (the
scenario's reference ends where the platform may rest) or hold it (``hold_s``) and support it.

:func:`~.measure.measure_pose` is the dry run: it reads the bus with the torque off and returns
the pose and its verdict.
"""

from __future__ import annotations

import contextlib
import dataclasses
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from ..base.compiled import kernel_versions, versions_added
from ..base.errors import InvalidConfigError, StartPoseError, StewartError
from ..references.homing import HOME_S, HomingReference
from .measure import MeasuredPose, admissible_start, bus_config, pose_verdict
from .realtime import RealtimeLoop
from .session_signals import SessionSignals, signal_name
from .session_surrogate import check_surrogate_trace, command_surrogate, relative_latency_of_run
from .watchdog import LOOP_TIMEOUT_S, LoopWatchdog, check_loop_timeout, watchdog_monitor

if TYPE_CHECKING:
    from .session_surrogate import RelativeLatency


@dataclasses.dataclass
class RobotRun:
    """How a session on the robot ended.

    Attributes:
        reason: one line: why it ended.  ok: it ran to its end.
        torque_off_confirmed: every servo confirmed the torque off at the end.
        start: the :class:`MeasuredPose` it started from (None: ended before the measurement).
        logs: the ``.npz`` written (None: none, e.g. the run had not started).
        encoder_log: the encoders' readings with their times, written beside it
            (:func:`~stewart_drake.calibration.join.write_encoder_log`), or None.
        timing: the driver's timing summary (period, jitter, the loop's CPU time, round trips,
            measurement age, deadline misses and the late periods' causes:
            ``DynamixelDriver.timing_summary``); ``timing_lines`` as text, after what the loop
            was given (``realtime``).
        realtime: what the loop was given (:meth:`~.realtime.RealtimeLoop.granted`), or None
            when it asked for nothing.
        metrics: the run's metrics (:func:`~stewart_drake.run.metrics.compute_metrics`:
            tracking from the measured pose, torques), when its logs were read.
        exit_code: 0 at the end of the reference, 1 a refusal or failure, 128 + n a signal n.
        relative_latency: with a surrogate's trace, the
            :class:`~.session_surrogate.RelativeLatency` measured from the encoders
            (None: no surrogate, or no logs); its ``line()`` is the verdict.
        relative_latency_line: the verdict's line, or why it was not measured (None: no
            surrogate's trace).
        late_kernels: what numba compiled or loaded with the torque on (a warm-up that missed
            its argument types: :func:`~stewart_drake.base.compiled.versions_added`); empty.
    """

    reason: str
    ok: bool
    torque_off_confirmed: bool
    start: MeasuredPose | None = None
    logs: Path | None = None
    encoder_log: Path | None = None
    timing: dict | None = None
    timing_lines: list[str] = dataclasses.field(default_factory=list)
    realtime: str | None = None
    metrics: dict | None = None
    exit_code: int = 0
    relative_latency: RelativeLatency | None = None
    relative_latency_line: str | None = None
    late_kernels: list[str] = dataclasses.field(default_factory=list)


def run_on_robot(
    scenario,
    *,
    reference=None,
    home_s: float = HOME_S,
    hold_s: float = 0.0,
    loop_timeout_s: float = LOOP_TIMEOUT_S,
    out: str | Path = "results",
    stem: str = "robot",
    meshcat=None,
    progress: bool = False,
    say: Callable[[str], None] | None = None,
    before_torque: Callable | None = None,
    signals: SessionSignals | None = None,
    realtime: bool = False,
    surrogate=None,
) -> RobotRun:
    """Run the scenario's closed loop on the robot (the safety sequence of the module's
    docstring); never leaves the torque on.

    Args:
        scenario: a Scenario with a ``bus``.
        reference: overrides the scenario's reference (as ``make_stewart_diagram``'s).
        home_s: duration of the homing lead-in from the measured pose, s.
        hold_s: how long the reference's last pose is held after its end, s (then the torque
            goes off).
        loop_timeout_s: our watchdog's limit on a control period, s.
        out: folder of the logs (``<stem>.npz``; on a guard trip the guard's own file in its
            ``divergence_dir``).
        meshcat: optional Meshcat: the robot at its measured pose, live.
        progress: a progress bar.  say: where the one-line messages go (default stderr).
        before_torque: a test hook ``f(sd, simulator)`` called after every check, just before
            the torque is enabled.
        signals: the entered :class:`~.session_signals.SessionSignals` of a caller that says
            the end line itself (it holds signals through it, then calls ``settle``); None: the
            session's own, settled before it returns.
        realtime: run the loop as :class:`~.realtime.RealtimeLoop` asks (SCHED_FIFO, a core
            of its own, memory locked, the garbage collector between periods, shallow idle
            states); what the OS refuses is said in one line (``say``) and the run goes on.
        surrogate: the external surrogate's trace
            (:class:`~stewart_drake.station.surrogate.trace.SurrogateTrace`,
            :func:`~stewart_drake.station.surrogate.carriage.load_surrogate`), driven on the
            servo of ``bus.surrogate`` on the platform's clock
            (:class:`~stewart_drake.station.surrogate.carriage.SurrogateCommand`), its whole
            path checked against the stage's travel and speed before the torque goes on; the
            encoder log gains its columns and the run its relative latency. None: a surrogate's
            servo on the bus holds where it was read.
    Returns:
        :class:`RobotRun` (exit_code 0 only when the reference ran to its end and no signal
        came; a signal after the torque-off is named in ``reason`` and makes it 128 + n).
    Raises:
        InvalidConfigError: no bus, a bad scenario or argument; the reference refused by its
            checks (UnreachablePoseError, JointLimitError, SingularPoseError, InterferenceError,
            MotorLimitError) before anything is powered; StartPoseError: the measured pose.
        BusError, MissingServoError, ServoConfigMismatchError: the bus before the torque is on.
        (Once the torque is on nothing is raised: the end is reported in the RobotRun.)
    """
    from ..references.trajectories import as_trajectory
    from ..run.plan import run_reference

    say = say or (lambda line: print(line, file=sys.stderr, flush=True))
    scenario = scenario.validate()
    bus_config(scenario)
    check_loop_timeout(loop_timeout_s, scenario.control_period_s)
    if not 0 < home_s <= 60 or not 0 <= hold_s <= 3600:
        raise InvalidConfigError(
            f"home_s must be in (0, 60] s and hold_s in [0, 3600] s, got {home_s}, {hold_s}"
        )
    target = as_trajectory(reference) if reference is not None else run_reference(scenario)
    if surrogate is not None:
        check_surrogate_trace(scenario, surrogate)
    start = admissible_start(scenario)  # opens and closes the port; the torque stays off
    homed = HomingReference(target, start.x, home_s, t_end=scenario.duration_s)
    homed_run = dataclasses.replace(scenario, duration_s=homed.duration_s + hold_s)
    session = (homed_run, homed, start, loop_timeout_s, Path(out), stem, meshcat, progress, say)
    if signals is not None:
        return _run(*session, before_torque, signals, realtime, surrogate)
    with SessionSignals() as own:
        return own.settle(_run(*session, before_torque, own, realtime, surrogate))


def _run(
    scenario,
    homed,
    start,
    loop_timeout_s,
    out,
    stem,
    meshcat,
    progress,
    say,
    before_torque,
    signals,
    realtime,
    surrogate=None,
) -> RobotRun:
    """Build, check, power and run (see :func:`run_on_robot`)."""
    from ..run.simulate import advance
    from ..station.guard import advance as guarded

    sd, simulator, context, station = _build(scenario, homed, meshcat, progress)
    bus = station.bus
    bus.open()
    ended = RobotRun("", False, True, start=start)
    powered, wall = False, 0.0
    try:
        bus.configure()
        station.assemble(context, start.x)  # the driver holds its first reading
        _check_still(sd, bus, start)
        if surrogate is not None:
            command_surrogate(station.driver, surrogate, homed, scenario)
        if before_torque is not None:
            before_torque(sd, simulator)
        powered = True

        def body():
            simulator.Initialize()  # paces real time from here
            guarded(
                sd,
                simulator,
                lambda: advance(simulator, sd.plan.duration_s, progress, "on the robot"),
            )

        announce = (
            f"torque on: homing for {homed.home_s:g} s from the measured pose, then "
            f"{getattr(homed.reference, 'name', 'the reference')}"
        )
        talk = (loop_timeout_s, say, announce)
        wall = _drive(bus, simulator, *talk, body, ended, signals, realtime, station.driver)
    finally:
        signals.hold()
        _stop(bus, station.driver, ended)
    if not powered:
        return ended
    _keep_logs(ended, sd, simulator, wall, out / f"{stem}.npz", homed, surrogate is not None)
    return ended


def _stop(bus, driver, ended: RobotRun) -> None:
    """Every session's end, whatever ended it: the torque removed (``ended`` says whether every
    servo confirmed it), the loop's timing read from ``driver`` with what the loop was given
    (None: no timing to read), and the port closed, whatever the first two do."""
    try:
        ended.torque_off_confirmed = bus.torque_off()
        if driver is not None:
            ended.timing = driver.timing_summary()
            given = [] if ended.realtime is None else [f"realtime: {ended.realtime}"]
            ended.timing_lines = given + driver.timing_lines()
        if ended.late_kernels:
            late = ", ".join(ended.late_kernels)
            ended.timing_lines.append(f"compiled or loaded with the torque on (a stall): {late}")
    finally:
        bus.close()


def _build(scenario, homed, meshcat, progress):
    """The checked closed loop of ``scenario`` on the servo bus, its reference ``homed``:
    (StewartDiagram, Simulator, its Context, the HardwareStation), initialized; the bus not
    opened yet.

    Raises:
        InvalidConfigError: the station is not on the servo bus; as the reference's checks.
    """
    from pydrake.systems.analysis import ApplySimulatorConfig, Simulator

    from ..run.diagram import build_diagram
    from ..run.plan import checked_plan
    from ..station.bus.station import HardwareStation

    # As a simulated run's (run.simulate.build_simulator), but the station is assembled
    # from the servos' reading, once the bus is open. The whole path, from the measured pose,
    # is checked here, before the port is opened again.
    plan = checked_plan(scenario, reference=homed, progress=progress)
    sd = build_diagram(plan, meshcat)
    simulator = Simulator(sd.diagram)
    ApplySimulatorConfig(plan.scenario.simulator, simulator)
    context = simulator.get_mutable_context()
    sd.initialize(context)
    station = sd.station
    if not isinstance(station, HardwareStation):  # a scenario with a bus builds one
        raise InvalidConfigError("the run's station is not on the servo bus")
    return sd, simulator, context, station


def _check_still(sd, bus, start: MeasuredPose) -> None:
    """Refuse to start when the platform moved since ``start`` was measured (by more than
    0.01 rad or 2 mm in any coordinate).

    Raises:
        StartPoseError: it moved (by how much).
    """
    again = pose_verdict(sd.plan, bus.read_state().q)
    moved = np.abs(again.x - start.x)
    if np.max(moved[:3]) > 0.01 or np.max(moved[3:]) > 0.002:
        raise StartPoseError(
            "the platform moved between the measurement and the start (by "
            f"{np.degrees(moved[:3]).max():.2f} deg, {moved[3:].max() * 1e3:.2f} mm): "
            "hold it still and run again"
        )


def _keep_logs(
    ended: RobotRun,
    sd,
    simulator,
    wall: float,
    path: Path,
    homed,
    judge: bool = False,
) -> None:
    """The run's metrics and its logs saved at ``path`` into ``ended``, and the encoders'
    readings beside it (their times on the computer's clock, s since the epoch, and on the
    reference's clock of ``homed``; with a surrogate on the bus, its carriage's position read
    and commanded); with ``judge`` the relative latency of the platform and the surrogate
    (:func:`~.session_surrogate.judged_relative_latency`). A failure to write them is told in
    ``ended.reason``, never raised."""
    from ..calibration.join import encoder_log_path, write_encoder_log
    from ..run.result import finish_result, read_run, save_result
    from .emulator_process import bus_words

    try:
        logs = read_run(sd, simulator.get_context())
        if len(logs.result.t) < 2:  # one sample has no metrics: nothing ran to keep
            ended.reason += "; it ended within its first logged period: there are no logs to write"
            ended.exit_code = ended.exit_code or 1
            return
        result = finish_result(logs, wall)
        ended.metrics = result.metrics
        ended.logs = save_result(result, path)
        driver = sd.station.driver
        t, t_read, q = driver.readings()
        epoch = time.time() - time.perf_counter()  # perf_counter is the monotonic clock
        tau = homed.reference_time(t)
        carriage = None
        if driver.surrogate is not None:
            s, s_cmd = driver.surrogate_readings()
            reference = driver.surrogate.reference
            s_ref = reference.evaluate(t)[0] if reference is not None else s_cmd
            carriage = (s, s_cmd, s_ref, driver.surrogate_delays())
        bus = bus_words(sd.station.bus.port_name)  # emulated or not, as far as the run knows
        ended.encoder_log = write_encoder_log(
            encoder_log_path(path), t_read + epoch, t, tau, q, surrogate=carriage, bus=bus
        )
        if judge and carriage is not None:
            try:
                ended.relative_latency = relative_latency_of_run(driver, homed, t, carriage)
                ended.relative_latency_line = ended.relative_latency.line()
            except InvalidConfigError as err:  # too short a run to measure it
                ended.relative_latency_line = f"relative latency not measured: {err}"
    except Exception as err:  # noqa: BLE001 - the end must be reported whatever the logs do
        ended.reason += f"; the logs could not be written: {err}"
        ended.exit_code = ended.exit_code or 1  # a run without its record is not a success


def _drive(
    bus,
    simulator,
    loop_timeout_s,
    say,
    announce,
    body,
    ended: RobotRun,
    signals: SessionSignals,
    realtime: bool = False,
    driver=None,
) -> float:
    """Enable the torque, say ``announce``, run ``body()`` (which advances ``simulator``)
    behind our watchdog, and record in ``ended`` how it ended; returns the wall time, s. From
    the end of ``body()`` on, ``signals`` are held. The caller removes the torque (in a
    ``finally``). With ``realtime`` the loop runs as :class:`~.realtime.RealtimeLoop` asks
    (a refusal said in one line first), our watchdog's thread one priority above it, and
    ``driver`` (the :class:`~stewart_drake.station.bus.station.DynamixelDriver`) collects the
    garbage between periods."""
    with contextlib.ExitStack() as held:
        if realtime:
            loop = held.enter_context(RealtimeLoop())
            ended.realtime = loop.granted()
            refused = loop.line()
            if refused is not None:
                say(refused)
            if driver is not None:
                driver.between_periods = loop.collect
                held.callback(setattr, driver, "between_periods", None)
        else:
            loop = None
        return _drive_held(
            bus, simulator, loop_timeout_s, say, announce, body, ended, signals, loop
        )


def _drive_held(bus, simulator, loop_timeout_s, say, announce, body, ended, signals, loop) -> float:
    """:func:`_drive` once the loop has what it asked for (``loop``: the entered
    :class:`~.realtime.RealtimeLoop`, or None)."""
    from ..execution.runners import interrupt_in

    watchdog = LoopWatchdog(bus.torque_off, loop_timeout_s)
    simulator.set_monitor(watchdog_monitor(watchdog))
    simulator.set_target_realtime_rate(1.0)
    signals.arm()
    wall0 = time.perf_counter()
    kernels = kernel_versions()
    try:
        try:
            # In the try: a signal the moment the torque is on ends the run as any other.
            bus.enable_torque()
            say(announce)
            with watchdog:
                if loop is not None:
                    loop.lift(watchdog.native_id)
                body()
        finally:
            signals.hold()
            ended.late_kernels = versions_added(kernels)
        ended.reason, ended.ok = "the reference ran to its end", True
    except KeyboardInterrupt as err:
        name, ended.exit_code = signal_name(err)
        ended.reason = f"interrupted by {name}"
        if watchdog.tripped:  # it came while the loop was stalled
            ended.reason += f" after {watchdog.tripped}"
    except StewartError as err:  # a bus error, a missed deadline, a guard trip
        # Without the driver's verdict on the torque-off it attempted when the bus failed: the
        # end line gives the verdict of the last torque-off, the one that counts.
        what = getattr(err, "failure", None) or str(err)
        ended.reason, ended.exit_code = f"{type(err).__name__}: {what}", 1
    except (RuntimeError, SystemError) as err:  # inside Drake (the guard saved the logs)
        interrupt = interrupt_in(err)  # a signal inside compiled code comes back wrapped
        if interrupt is not None:
            name, ended.exit_code = signal_name(interrupt)
            ended.reason = f"interrupted by {name}"
        else:
            ended.reason, ended.exit_code = f"{type(err).__name__}: {err}", 1
    if watchdog.tripped is not None and not ended.reason.startswith("LoopStalledError"):
        # The stall came first: what ended the run after it (the guard, seeing the platform
        # that drifted under the last torques, at the loop's first check) is its consequence.
        ended.reason = f"LoopStalledError: {watchdog.tripped}; then {ended.reason}"
        ended.ok, ended.exit_code = False, ended.exit_code or 1
    return time.perf_counter() - wall0


def teleop_on_robot(
    scenario,
    meshcat,
    *,
    duration_s: float | None = None,
    loop_timeout_s: float = LOOP_TIMEOUT_S,
    say: Callable[[str], None] | None = None,
    signals: SessionSignals | None = None,
    realtime: bool = False,
) -> RobotRun:
    """``teleop`` on the robot: the live Meshcat (sliders, gauges, the reference's ghost, the
    robot drawn at its measured pose) driving the servos of ``scenario.bus``.

    The sliders start at the measured pose (it must be in the admissible set: nothing is
    powered otherwise) and the reference follows them only through admissible poses at
    bounded rate (:class:`~stewart_drake.run.reference.TeleopReference`), so no homing
    is needed. The pause button is off: on the robot time does not stop (a paused loop would
    trip the watchdogs and drop the platform). Ends after ``duration_s`` (None: at Ctrl-C or
    SIGTERM) with the torque off and one line, as :func:`run_on_robot`; a live session keeps
    no logs (as ``teleop`` in simulation).

    ``signals``, ``realtime``: as :func:`run_on_robot`'s.

    Raises:
        as :func:`run_on_robot` before the torque is on.
    """
    say = say or (lambda line: print(line, file=sys.stderr, flush=True))
    bus_config(scenario)
    check_loop_timeout(loop_timeout_s, getattr(scenario, "scenario", scenario).control_period_s)
    start = admissible_start(scenario)
    session = (scenario, meshcat, duration_s, loop_timeout_s, say, start)
    if signals is not None:
        return _teleop(*session, signals, realtime)
    with SessionSignals() as own:
        return own.settle(_teleop(*session, own, realtime))


def _teleop(
    scenario, meshcat, duration_s, loop_timeout_s, say, start, signals, realtime
) -> RobotRun:
    """The powered part of :func:`teleop_on_robot`."""
    from ..execution.runners import Interrupted
    from ..station.bus.driver import DynamixelBus
    from .teleop import build_teleop, run_teleop

    bus = DynamixelBus.from_config(bus_config(scenario)).open()
    ended = RobotRun("", False, True, start=start)
    try:
        bus.configure()
        run = build_teleop(scenario, meshcat, x_initial=start.x, bus=bus)
        run.paused = lambda: False  # type: ignore[method-assign]

        def body():
            stats = run_teleop(run, duration_s, report=None)
            if "interrupted_by" in stats:
                raise Interrupted(stats["interrupted_by"])

        announce = f"torque on: open {meshcat.web_url()} ; the sliders move the robot"
        driver = getattr(run.loop.station, "driver", None)
        talk = (loop_timeout_s, say, announce)
        _drive(bus, run.simulator, *talk, body, ended, signals, realtime, driver)
        if ended.ok:
            ended.reason = "the session ran its duration"
    finally:
        signals.hold()
        _stop(bus, None, ended)
    return ended


def end_line(run: RobotRun) -> str:
    """The one line a session ends with: why, the torque off, where the logs are."""
    torque = (
        "torque off (confirmed by every servo)"
        if run.torque_off_confirmed
        else "torque off NOT confirmed: cut the servos' power"
    )
    logs = f"; logs in {run.logs}" if run.logs is not None else ""
    if run.encoder_log is not None:
        logs += f" and {run.encoder_log}"
    return f"{run.reason}; {torque}{logs}"
