"""The station on the servo bus: the same ports as the simulated station, from the real servos.

:class:`HardwareStation` is what :func:`~stewart_drake.run.diagram.make_stewart_station`
builds for a scenario with ``bus``: a Diagram named "station" whose one system that touches the
robot is the :class:`DynamixelDriver` (a ``LeafSystem``: one sync read and one sync write of
the bus each control period, its timing measured). Every controller of the contract, the
tuners, the learners, the guard, the loggers and the LCM publishers connect to it exactly as to
:class:`~stewart_drake.station.station.StewartStation` (docs/station.md).

The driver updates at the plant's instants k h: it writes the torque the controllers computed
half a plant step after the previous update, then reads the servos and holds the reading for the
controllers' sample at k h + h_plant / 2, so a torque acts one control period after its
measurement, as the scenario says (``hardware.computation_delay_periods = 1``,
:meth:`~stewart_drake.station.bus.servos.DynamixelBusConfig.hardware`). It keeps its own
wall-clock schedule: an early period sleeps until due, a period more than one period late is a
deadline miss and the schedule moves on (:meth:`DynamixelDriver.timing_summary`). Misses are
said as a running summary (their count, the worst, their causes) when their count reaches a
power of two, so a machine too busy for the period shows a few lines, not one per miss. Why it
paces itself rather than Drake's ``Simulator``: docs/hardware_bus.md, "The station on the bus".
"""

from __future__ import annotations

import math
import sys
import time

import numpy as np
from pydrake.systems.framework import Diagram, DiagramBuilder, LeafSystem
from pydrake.systems.primitives import PassThrough
from tqdm import tqdm

from ...base.errors import DeadlineMissError, SimulationDivergedError
from ...control.estimator import PoseEstimator
from ...lcmtypes import lcmt_stewart_status
from ...plant.closed_chain import LoopClosure
from ...robot.forward_kinematics import fk
from ...robot.kinematics import X_HOME
from ...robot.single_pose import ik_single, jacobian_single
from ..station import PlatformPoseSensor, add_station_plant
from ..surrogate.bus_servo import SurrogateDrive
from .driver import DynamixelBus
from .measured_state import MeasuredPlantState, ShowMeasured, bus_kernels
from .position_mode import crank_inertia
from .servos import servo_spec
from .timing import CAUSES, LATE_FRACTION, LoopTiming

#: The driver's held measurement, in its discrete state: crank angles (6) rad, rates (6) rad/s,
#: torques the servos drive (6) N m, the platform pose (6) and rate (6) from them, then the loop's
#: numbers (deadline misses, achieved period us, measurement age us).
_Q, _V, _TAU, _X, _LOOP = slice(0, 6), slice(6, 12), slice(12, 18), slice(18, 30), slice(30, 33)
#: Numbers a period's reading keeps (:meth:`DynamixelDriver.readings`).
_ROW = 17


class DynamixelDriver(LeafSystem):
    """The servos of a :class:`~.driver.DynamixelBus` as a Drake system, one period at a time.

    Every ``period_s`` (offset 0, the plant's instants) it waits for the period's wall-clock
    time, writes ``motor_torque`` (one GroupSyncWrite), reads the servos (one GroupSyncRead) and
    holds what it read and the pose from it; :meth:`seed` holds a first reading. The caller
    opens, configures and enables the bus. On a deadline miss past ``max_deadline_misses``, or
    any error in a period, the torque is removed before the error propagates
    (docs/hardware_bus.md, "The station on the bus").

    Input port: ``motor_torque`` (6,): crank torques to apply, N m (clipped by the bus to the
        servos' Current Limit); on a bus in Position Control Mode (its ``position_gains_raw``)
        ``crank_goal`` (12,) instead: the cranks' goal angles rad (the robot's; the encoders'
        zero errors added) and Profile Velocities rad/s, one sync write a period.
    Output ports (the held measurement): ``motor_angle`` (6,) rad; ``motor_rate`` (6,) rad/s
        (the servos' Present Velocity, 0.024 rad/s a unit); ``motor_torque_applied`` (6,) N m
        (Present Current x K_t); ``platform_state`` (12,) [pose rad, m; rates rad/s, m/s] from
        the angles and rates; ``loop`` (4,) for the LCM status
        (:data:`~stewart_drake.station.lcm_publish.LoopStatus`: mode, deadline misses,
        achieved period us, measurement age us).

    Args:
        bus: the :class:`~.driver.DynamixelBus` (six servos, the cranks' order).
        geometry: the robot (:class:`~stewart_drake.robot.geometry.StewartGeometry`), for the
            forward kinematics.
        period_s: the control period, s. max_deadline_misses: misses allowed.
        x_initial: (6,) where forward kinematics starts before the first reading.
        stream: where the misses' summary lines go (:meth:`miss_line`, one when their count
            reaches a power of two; default stderr). timing_window: periods kept for
            :meth:`timing_summary` (its records are allocated once, 9 numbers a period).
        surrogate: None, or the :class:`~..surrogate.bus_servo.SurrogateDrive` of a bus with a
            surrogate's servo: each period its torque goes in the same sync write as the
            cranks', from the reading of the same sync read.
        quantum_rad: one count of the servos' encoders, rad (default the X series' 4096 a
            turn; the station gives its model's), where the forward kinematics stops.
    Attributes:
        timing: the :class:`~.timing.LoopTiming` records of the run.
        between_periods: None, or a callable the loop calls when it has time left before a
            period is due, before it sleeps (a session collects Python's garbage there, so that
            no collection falls inside a period).
    Raises:
        DeadlineMissError: (during simulation) past ``max_deadline_misses``.
    """

    def __init__(
        self,
        bus,
        geometry,
        period_s: float,
        max_deadline_misses: int = 10,
        x_initial=X_HOME,
        stream=None,
        timing_window: int = 360_000,
        surrogate: SurrogateDrive | None = None,
        quantum_rad: float = 2 * np.pi / 4096,
    ):
        super().__init__()
        self.bus, self.geometry = bus, geometry
        self.surrogate = surrogate
        self.period_s, self.max_deadline_misses = float(period_s), int(max_deadline_misses)
        #: One count of the servos' encoders, rad.
        self.quantum_rad = float(quantum_rad)
        self.stream = stream
        self._x_initial = np.asarray(x_initial, dtype=float)
        self._fk = PoseEstimator(
            geometry, period_s, quantum_rad, self._x_initial, max_iterations=20
        )
        self._tau = self.DeclareVectorInputPort("motor_torque", 6)
        #: In Position Control Mode (the bus's ``position_gains_raw``): the goals' port, the
        #: cranks' angles (6) rad and Profile Velocities (6) rad/s; ``motor_torque`` unread.
        self._goal = (
            self.DeclareVectorInputPort("crank_goal", 12)
            if getattr(bus, "position_gains_raw", None) is not None
            else None
        )
        self._kernels = bus_kernels()
        #: The period's measurement, assembled here before it is copied into the state.
        self._held, self._x_start = np.zeros(_LOOP.start), np.zeros(6)
        initial = np.zeros(_LOOP.stop)
        initial[_X][:6] = self._x_initial
        self._state = self.DeclareDiscreteState(initial)
        for name, part in (
            ("motor_angle", _Q),
            ("motor_rate", _V),
            ("motor_torque_applied", _TAU),
            ("platform_state", _X),
        ):
            self.DeclareVectorOutputPort(
                name,
                part.stop - part.start,
                self._output(part),
                prerequisites_of_calc={self.discrete_state_ticket(self._state)},
            )
        self.DeclareVectorOutputPort(
            "loop",
            4,
            self._CalcLoop,
            prerequisites_of_calc={self.discrete_state_ticket(self._state)},
        )
        self.DeclarePeriodicDiscreteUpdateEvent(self.period_s, 0.0, self._Update)
        self.between_periods = None
        self.timing = LoopTiming(self.period_s, timing_window)
        self.reset_timing()

    # --- outputs -----------------------------------------------------------------------------

    def _output(self, part: slice):
        def calc(context, output):
            output.SetFromVector(context.get_discrete_state(self._state).value()[part])

        return calc

    def _CalcLoop(self, context, output):
        misses, period_us, age_us = context.get_discrete_state(self._state).value()[_LOOP]
        output.SetFromVector([lcmt_stewart_status.MODE_RUNNING, misses, period_us, age_us])

    # --- the measurement ---------------------------------------------------------------------

    def _measure(self, x_prev) -> np.ndarray:
        """One read of the bus and the pose from it: the state vector (without the loop).
        The pose: Newton on the IK from the previous pose (compiled, :func:`.kernels.measure_pose`:
        within a hundredth of a count), or if that fails the full
        :func:`~.forward_kinematics.fk`, which raises when the angles are no pose of the robot;
        the rate x_dot = J^-1 theta_dot."""
        state = self.bus.read_state()
        self._last_read_t, self._read_s = state.t, state.round_trip_s
        if self.surrogate is not None:
            self.surrogate.reading(state.s, state.s_dot)
        held, start = self._held, self._x_start
        held[_Q], held[_V], held[_TAU] = state.q, state.v, state.tau
        start[:] = x_prev
        fk_ = self._fk
        pose = held[_X]
        if not self._kernels.measure_pose(
            fk_.legs, fk_.mode, fk_.tol, fk_.max_iterations, start, held[_Q], held[_V], pose
        ):
            theta = state.q - self.geometry.encoder_offsets  # the encoders' zero errors
            x, _ = fk(self.geometry, theta, x0=x_prev, tol=fk_.tol)
            _, cache = ik_single(self.geometry, x)
            pose[:6] = x
            pose[6:] = np.linalg.solve(jacobian_single(self.geometry, cache), state.v)
        return held

    def seed(self, context) -> np.ndarray:
        """Read the bus once and hold the reading in ``context`` (this system's): what the
        controllers see before the first period. Moves nothing. Returns the (6,) crank angles.

        Raises:
            BusError: the bus is not open or does not answer (torque off first);
            ForwardKinematicsError: the angles are no pose of the robot.
        """
        held = context.get_mutable_discrete_state(self._state).get_mutable_value()
        held[: _LOOP.start] = self._measure(self._x_initial)
        return held[_Q].copy()

    # --- the period --------------------------------------------------------------------------

    def reset_timing(self, timing_window: int | None = None) -> None:
        """Forget the timing records and the schedule (the next period starts a new one);
        ``timing_window``: keep that many periods from now on."""
        if timing_window is not None:
            self.timing = LoopTiming(self.period_s, timing_window)
        self.timing.reset()
        #: Deadline misses, and bursts of consecutive ones, so far.
        self.misses, self.bursts, self._in_burst = 0, 0, False
        #: The latest start of a missed period, s late, and its Diagram time; misses by cause.
        self.worst_miss_s, self.worst_miss_t = 0.0, math.nan
        self.miss_causes = [0] * len(CAUSES)
        self._wall0: float | None = None
        #: Wall-clock time the schedule was moved on by after misses, s: the Diagram's clock
        #: (and the reference) is that much behind the wall clock.
        self.skipped_s = 0.0
        self._last_start = self._last_read_t = float("nan")
        #: Every period's reading: (Diagram time, read time (perf_counter), q0..q5, the pose
        #: x (6) from them, the surrogate's position read and commanded, m, and the lag
        #: matching's delay of its command after this period, s) rows, the first
        #: ``_n_readings`` of them; grown by half when a run outlasts them.
        self._readings = np.empty((1024, _ROW))
        self._n_readings = 0

    def _Update(self, context, discrete_state):
        try:
            self._period(context, discrete_state)
        except BaseException:
            self.bus.torque_off()  # never raises; the error says what happened
            raise

    def _wait_until(self, due: float) -> tuple[float, float]:
        """Sleep until ``due`` (perf_counter s), after :attr:`between_periods` when there is
        time; (now, the sleep asked for, s)."""
        now = time.perf_counter()
        if now < due and self.between_periods is not None:
            self.between_periods()
            now = time.perf_counter()
        if now >= due:
            return now, 0.0
        time.sleep(due - now)
        return time.perf_counter(), due - now

    def _period(self, context, discrete_state):
        t = context.get_time()
        if self._wall0 is None:
            self._wall0 = time.perf_counter() - t
        due = self._wall0 + t
        now, slept = self._wait_until(due)
        late = now - due
        cause = self.timing.begin(now, late, slept)
        tau = (self._tau if self._goal is None else self._goal).Eval(context)
        if not math.isfinite(tau.sum()):
            raise SimulationDivergedError(
                f"the controller commanded non-finite torques or goals {tau}; torque off", t
            )
        w0 = time.perf_counter()
        if self._goal is not None:  # the robot's angles plus the encoders' zero errors
            s_commanded = math.nan
            if self.surrogate is not None:  # its torque first: the goals are the period's
                tau_s, s_commanded = self.surrogate.torque(t)
                self.bus.write_surrogate_torque(tau_s)
            self.bus.write_goals(tau[:6] + self.geometry.encoder_offsets, tau[6:])
        elif self.surrogate is None:
            self.bus.write_torques(tau)
            s_commanded = math.nan
        else:  # the seventh row of the same sync write, from the same (last) reading
            tau_s, s_commanded = self.surrogate.torque(t)
            self.bus.write_torques(tau, tau_s)
        w1 = time.perf_counter()
        age = 0.5 * (w0 + w1) - self._last_read_t
        held = context.get_discrete_state(self._state).value()
        measured = self._measure(held[_X][:6])
        if self.surrogate is not None:  # lag matching learns the platform's lag from its pose
            self.surrogate.platform_reading(t, measured[_X][:6])
        self._keep_reading(t, measured, s_commanded)
        period = now - self._last_start
        self._last_start = now
        self.timing.end(self._read_s, w1 - w0, age)
        if late > self.period_s:
            self._wall0 += late  # skip: the next period is due one period from now
            self.skipped_s += late
            self._missed(t, late, cause)
        else:
            self._in_burst = False
        out = discrete_state.get_mutable_vector(self._state).get_mutable_value()
        out[: _LOOP.start] = measured
        # 0 for what was not measured (the first period has no previous one; a run that did not
        # seed has no previous reading): the LCM status's convention.
        loop = out[_LOOP]
        loop[0] = self.misses
        loop[1] = 1e6 * period if period == period else 0.0
        loop[2] = 1e6 * age if age == age else 0.0

    def _keep_reading(self, t: float, measured, s_commanded: float) -> None:
        """This period's reading (``measured``: the held state vector) and the surrogate's
        position commanded (NaN: none) into the preallocated rows (grown by half when full)."""
        k = self._n_readings
        if k == len(self._readings):
            grown = np.empty((len(self._readings) * 3 // 2, _ROW))
            grown[:k] = self._readings
            self._readings = grown
        row = self._readings[k]
        row[0], row[1], row[2:8], row[8:14] = t, self._last_read_t, measured[_Q], measured[_X][:6]
        row[14] = self.surrogate.held[0] if self.surrogate is not None else math.nan
        row[15] = s_commanded
        row[16] = self.surrogate.delay_s if self.surrogate is not None else math.nan
        self._n_readings = k + 1

    def _missed(self, t: float, late: float, cause: int) -> None:
        self.misses += 1
        if self.misses > self.max_deadline_misses:
            raise DeadlineMissError(self.misses, self.max_deadline_misses, self.period_s, late, t)
        if not self._in_burst:
            self.bursts += 1
        self._in_burst = True
        if late > self.worst_miss_s:
            self.worst_miss_s, self.worst_miss_t = late, t
        self.miss_causes[cause] += 1
        if self.misses & (self.misses - 1) == 0:  # 1, 2, 4, 8, ...: a line each
            # Above a progress bar on the same stream, which tqdm then draws again below it.
            stream = self.stream or sys.stderr
            tqdm.write(self.miss_line(), file=stream)
            stream.flush()

    def miss_line(self) -> str:
        """The deadline misses so far in one line: their count (in how many bursts), the worst
        (how late it started, when) and their causes (:data:`~.timing.CAUSES`, most first)."""
        by_cause = sorted(
            ((n, CAUSES[c] or "cause unknown") for c, n in enumerate(self.miss_causes) if n),
            key=lambda pair: -pair[0],
        )
        causes = ", ".join(f"{what} {n}" for n, what in by_cause)
        return (
            f"deadline misses: {self.misses} so far in {self.bursts} bursts, of "
            f"{self.max_deadline_misses} allowed (periods of {1e3 * self.period_s:g} ms started "
            f"over a period late); the worst {1e3 * self.worst_miss_s:.1f} ms late at t = "
            f"{self.worst_miss_t:.3f} s; by cause: {causes}; next line at "
            f"{2 * self.misses} misses"
        )

    def readings(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Every period's reading since the run started (:meth:`reset_timing`): (t (n,) the
        Diagram's time, s; t_read (n,) when the servos were read, ``time.perf_counter`` s, the
        midpoint of the sync read; q (n, 6) the crank angles read, rad: each encoder's raw
        angle, its zero error included)."""
        r = self._readings[: self._n_readings]
        return r[:, 0].copy(), r[:, 1].copy(), r[:, 2:8].copy()

    def pose_readings(self) -> np.ndarray:
        """(n, 6) the platform's pose measured each period of :meth:`readings` (the forward
        kinematics of its crank angles), rad and m."""
        return self._readings[: self._n_readings, 8:14].copy()

    def surrogate_readings(self) -> tuple[np.ndarray, np.ndarray]:
        """The surrogate's carriage each period of :meth:`readings`: (s (n,) read, m; s_c (n,)
        commanded for that period, m); NaN without a surrogate (and s_c NaN in the first
        period's row when it was read before the loop started)."""
        r = self._readings[: self._n_readings]
        return r[:, 14].copy(), r[:, 15].copy()

    def surrogate_delays(self) -> np.ndarray:
        """(n,) the delay the surrogate's command was taken with after each period of
        :meth:`readings` (lag matching; 0 without it, NaN without a surrogate), s."""
        return self._readings[: self._n_readings, 16].copy()

    def timing_summary(self) -> dict:
        """The loop's timing over the periods kept (:meth:`.timing.LoopTiming.summary`: the
        achieved period, its jitter, the bus's round trips, the measurement's age, how late each
        period started, the loop thread's CPU time and run-queue wait a period, the late
        periods' causes), s; and "misses", "bursts", "skipped" (s the schedule moved on by)."""
        out = self.timing.summary()
        out.update(misses=self.misses, bursts=self.bursts, skipped=self.skipped_s)
        return out

    def timing_lines(self) -> list[str]:
        """:meth:`timing_summary` as lines of text, ms; the last says whether the period
        held (no deadline miss)."""
        s = self.timing_summary()
        lines = [
            f"{s['periods']} periods of {1e3 * s['nominal']:g} ms, {s['misses']} deadline misses "
            f"in {s['bursts']} bursts, {1e3 * s['skipped']:.1f} ms skipped"
        ]
        for name in ("period", "jitter", "cpu", "wait", "read", "write", "age", "late"):
            v = s[name]
            if v["n"]:
                lines.append(
                    f"{name:>7}: median {1e3 * v['median']:7.3f}  p99 {1e3 * v['p99']:7.3f}  "
                    f"worst {1e3 * v['worst']:7.3f} ms"
                )
        if s["first_age"] > self.period_s:
            lines.append(
                f"the first period's measurement was {1e3 * s['first_age']:.0f} ms old: read "
                "before the loop started (the session's wait for a first sample, its checks), "
                "not a late period; the ages above are the later periods'"
            )
        retried = getattr(self.bus, "reads_retried", {})
        if retried:
            lines.append(
                f"reads sent again: {sum(retried.values())} ("
                + ", ".join(
                    f"{n} {cause} repl{'y' if n == 1 else 'ies'}" for cause, n in retried.items()
                )
                + "), each period's reading the retry's"
            )
        causes = ", ".join(f"{what} {n}" for what, n in s["late_causes"].items())
        late = sum(s["late_causes"].values())
        if late:
            lines.append(
                f"late periods (over {1e3 * LATE_FRACTION * s['nominal']:g} ms): {late}, by cause: "
                f"{causes}"
            )
        if s["misses"]:
            lines.append(
                f"the period did not hold: {s['misses']} periods started over a period late"
            )
        elif s["periods"]:
            lines.append("the period held: no period started a period late")
        return lines


class HardwareStation(Diagram):
    """The robot on its servo bus, with the ports of
    :class:`~stewart_drake.station.station.StewartStation`; a Diagram named "station".

    Input ports:
        ``motor_torque`` (6,): crank torques, N m, written to the servos each period.
        ``crank_goal`` (12,): with the scenario's ``bus.position_loop`` only, in place of the
            torques: the cranks' goal angles rad and Profile Velocities rad/s written each
            period (the servos in Position Control Mode with the loop's gains).
        ``tool_wrench`` (6,): accepted and ignored (a wrench on the real robot is applied by
            the world, not by the Diagram; the scenario refuses a ``disturbance`` with a bus).
    Output ports:
        ``motor_angle`` (6,) rad, ``motor_rate`` (6,) rad/s: what the servos read.
        ``motor_torque_applied`` (6,) N m: the torques the servos report driving
            (Present Current x K_t), not the command.
        ``platform_state`` (12,): *no ground truth on a robot*: the forward kinematics of the
            measured crank angles, and rates x_dot = J^-1 theta_dot from the measured crank
            rates; what the "x" log and the guard's tracking check then read.
        ``plant_state`` (nq + nv,): the MultibodyPlant assembled at that pose and rate
            (:class:`~.measured_state.MeasuredPlantState`), for the loggers, replays and the guard.
        ``loop`` (4,): the driver's loop status for the LCM status (mode, deadline misses,
            period us, measurement age us).
    Attributes:
        bus: the :class:`~.driver.DynamixelBus` (the caller opens, configures, enables torque
            and closes it). driver: the :class:`DynamixelDriver`. plan: the run's plan.
        plant, scene_graph, handles, sensor: the robot's MultibodyPlant and its SceneGraph in
            a Diagram of their own (``model``), never simulated: kinematics, visualization and
            the guard's geometry; ``sensor`` the pose from a plant state. loop_closure: the
            :class:`~stewart_drake.plant.closed_chain.LoopClosure` the guard and the run's
            result read, as the simulated station's.
        logged_pose_lag_s: how long before its log time a logged ``platform_state`` was read,
            s: one control period (Drake publishes a log at t before the driver's update at t,
            so the log at t holds the reading of t - h); the run's result compares it with the
            reference at the time it was read (:func:`~stewart_drake.run.result.finish_result`).
    Args:
        plan: the :class:`~stewart_drake.run.plan.RunPlan` of a scenario with ``bus``; a
            ``bus.surrogate`` gives the driver its :class:`~..surrogate.bus_servo.SurrogateDrive`
            (the surrogate's stage driven in the same packets, its command the session's).
        meshcat: optional pydrake Meshcat: the robot drawn at its measured pose every
            ``scenario.visualization.publish_period``.
    Raises:
        MissingExtraError: dynamixel-sdk is not installed.
    """

    def __init__(self, plan, meshcat=None):
        super().__init__()
        scenario = plan.scenario
        model_builder = DiagramBuilder()
        plant, scene_graph, handles = add_station_plant(model_builder, plan)
        if meshcat is not None:
            from pydrake.visualization import ApplyVisualizationConfig

            ApplyVisualizationConfig(scenario.visualization, model_builder, meshcat=meshcat)
        self.model = model_builder.Build()
        self.plant, self.scene_graph, self.handles, self.plan = plant, scene_graph, handles, plan
        self.loop_closure = LoopClosure(handles)
        #: The plant state is assembled at the measured pose
        #: (:class:`~.measured_state.MeasuredPlantState`): its loops close by construction, and
        #: the guard does not measure them each period.
        self.loops_closed_by_construction = True
        self.logged_pose_lag_s = plan.control_period_s
        self.sensor = PlatformPoseSensor(plant, handles)
        loop, raw = scenario.bus.position_loop, None
        if loop is not None:
            spec = servo_spec(scenario.bus.model, torque_control=False)
            raw = loop.raw_gains(spec, crank_inertia(plan.geometry, spec.name))
        self.bus = DynamixelBus.from_config(scenario.bus, position_gains_raw=raw)
        builder = DiagramBuilder()
        surrogate = scenario.bus.surrogate
        self.driver = builder.AddNamedSystem(
            "driver",
            DynamixelDriver(
                self.bus,
                plan.geometry,
                plan.control_period_s,
                scenario.bus.max_deadline_misses,
                surrogate=(
                    None if surrogate is None else SurrogateDrive(surrogate, plan.control_period_s)
                ),
                quantum_rad=self.bus.spec.rad_per_count,
            ),
        )
        command = builder.AddNamedSystem("motor_torque", PassThrough(6))
        builder.ExportInput(command.get_input_port(), "motor_torque")
        builder.Connect(command.get_output_port(), self.driver.GetInputPort("motor_torque"))
        if raw is not None:
            builder.ExportInput(self.driver.GetInputPort("crank_goal"), "crank_goal")
        ignored = builder.AddNamedSystem("tool_wrench", PassThrough(6))
        builder.ExportInput(ignored.get_input_port(), "tool_wrench")
        for name in ("motor_angle", "motor_rate", "motor_torque_applied", "platform_state", "loop"):
            builder.ExportOutput(self.driver.GetOutputPort(name), name)
        state = builder.AddNamedSystem("measured_plant_state", MeasuredPlantState(plant, handles))
        builder.Connect(self.driver.GetOutputPort("platform_state"), state.get_input_port())
        builder.ExportOutput(state.get_output_port(), "plant_state")
        self.show = None
        if meshcat is not None:
            self.show = builder.AddNamedSystem(
                "show_measured",
                ShowMeasured(self.model, plant, scenario.visualization.publish_period),
            )
            builder.Connect(state.get_output_port(), self.show.get_input_port())
        builder.BuildInto(self)
        self.set_name("station")

    def use_bus(self, bus) -> None:
        """Drive ``bus`` instead of the scenario's: anything with the
        :class:`~.driver.DynamixelBus` methods the driver calls (``read_state``,
        ``write_torques``, ``torque_off``), e.g. a rehearsal's or a test's."""
        self.bus = self.driver.bus = bus

    def logged_pose(self):
        """What a run logs as the platform's pose and rate: (``platform_state`` port, None),
        the measured pose itself (its ``plant_state`` is assembled from it)."""
        return self.GetOutputPort("platform_state"), None

    def initialize(self, root_context, T0=None, seed: int = 0) -> None:
        """Forget the driver's timing records (the next period starts its schedule). The
        servos hold no pipe to fill: ``T0`` and ``seed`` are the simulated station's and are
        not used."""
        self.driver.reset_timing()

    def assemble(self, root_context, x=X_HOME, x_dot=None) -> np.ndarray:
        """Read the servos once (the bus must be open) and hold the reading as the
        measurement the controllers start from; returns the (6,) measured crank angles. The
        robot is where it is: ``x`` and ``x_dot`` (the simulated station's arguments) are not
        imposed, ``x`` only starts the forward kinematics; the caller checks that the measured
        pose is where the run starts.

        Raises:
            BusError: the bus is not open or does not answer.
            ForwardKinematicsError: the angles are no pose of the robot.
        """
        driver = self.driver
        driver._x_initial = np.asarray(x, dtype=float)
        return driver.seed(driver.GetMyMutableContextFromRoot(root_context))
