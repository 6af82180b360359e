"""The robot following a motion live: poses received over LCM as they happen (a tracker's marker
mapped to the platform, a surrogate signal, a tumour position from imaging), each arriving late,
followed with the latency predicted away (``stewart-drake robot --follow-lcm CHANNEL --latency
S``; docs/organ_motion.md, "Following a motion live", and docs/lcm.md).

- :class:`LcmPoseSource` subscribes to a channel of
  :class:`~stewart_drake.lcmtypes.lcmt_stewart_pose_sample` on a ``DrakeLcm`` and hands each
  sample, in the order received, to a :class:`~stewart_drake.references.live_stream.
  LiveFollower` (the predictor and the curves of ``reproduce --stream``, fed causally).
- :class:`FollowReference` is the closed loop's live reference (as teleop's
  :class:`~stewart_drake.run.reference.TeleopReference`): every control period it reads what
  has arrived, takes the follower's pose, rate and acceleration, and shapes them into a
  reference the robot can follow with the :class:`~stewart_drake.run.shaping.Shaper` that
  ``reproduce --stream`` shapes with (the same reference for the same arrivals): the followed
  reference itself while every motor's torque and crank speed are within the share of the
  motors' a reference may use (the validator's numbers) and, every ``limits.target_period_s``,
  its pose admissible (reach, joint ranges, singularities, clearance, holding torques:
  :func:`~stewart_drake.run.reference.guarded_admissible`); else a critically damped filter
  towards it, fed forward with its rate and acceleration, within all of them, stopped at the
  farthest admissible pose towards a pose that is not. It starts where the robot rests and
  joins the followed reference through teleop's filter (``limits.bandwidth_hz``, and box).
  What was shaped, and by how much, is said at the end.
- :func:`follow_on_robot` is the session: the measured start pose (admissible, or nothing is
  powered), the servos configured, a first sample awaited with the torque off, then the run
  behind the session's safety paths (:mod:`~.session`). A source that fails (no sample within
  its timeout, a sample out of order, repeated, not six finite numbers, or spaced otherwise
  than its rate: :class:`~stewart_drake.base.errors.LiveSourceError`) ends the run within a
  chunk (:data:`CHUNK_S`) with the torque off and one line.
"""

from __future__ import annotations

import collections
import functools
import math
import struct
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
from pydrake.systems.framework import LeafSystem

from ..base.errors import InvalidConfigError, LiveSourceError
from ..references.live_stream import LiveFollower
from ..references.prediction import DEFAULT_PREDICTOR
from ..references.stream import DEFAULT_STREAM_RATE_HZ
from ..robot.statics import holding_torques
from ..run.shaping import Shaper, ShapingLimits, shaping_limits
from .watchdog import LOOP_TIMEOUT_S

#: How long a session waits for the first sample, the torque off, s.
FIRST_SAMPLE_S = 5.0
#: The shortest time without a sample that ends a run, s (at least 5 sample steps).
SAMPLE_TIMEOUT_S = 0.5
#: How much simulated time the session advances between its looks at the source, s.
CHUNK_S = 0.05
#: Samples received and not yet read that end a run (the loop cannot keep up with the source).
MAX_QUEUED = 10_000


def sample_timeout(rate_hz: float, timeout_s: float | None = None) -> float:
    """The time without a sample that ends a run: ``timeout_s``, else the larger of
    :data:`SAMPLE_TIMEOUT_S` and 5 sample steps, s."""
    return float(timeout_s) if timeout_s is not None else max(SAMPLE_TIMEOUT_S, 5.0 / rate_hz)


class LcmPoseSource:
    """The samples of ``channel`` on ``lcm`` (a ``DrakeLcm``), queued as LCM delivers them.

    Args:
        lcm: the ``DrakeLcm`` (``memq://`` in one process, ``udpm://`` between processes).
        channel: the channel (at most 63 printable characters).
    Attributes:
        log: [(arrival s, seq, utime us), ...] of every sample handed to the follower (a live
            session's record, 3 numbers a sample).
    Raises:
        InvalidConfigError: an empty or too long channel.
    """

    def __init__(self, lcm, channel: str):
        from ..station.lcm_publish import LCM_MAX_CHANNEL_CHARS

        if not (isinstance(channel, str) and channel and channel.isprintable()):
            raise InvalidConfigError(f"the channel must be printable text, got {channel!r}")
        if len(channel) > LCM_MAX_CHANNEL_CHARS:
            raise InvalidConfigError(
                f"the channel {channel!r} is longer than LCM's {LCM_MAX_CHANNEL_CHARS} characters"
            )
        self.lcm, self.channel = lcm, channel
        self._queue: collections.deque = collections.deque()
        self.log: list[tuple[float, int, int]] = []
        self._subscription = lcm.Subscribe(channel, self._queue.append)

    def wait(self, timeout_s: float) -> bool:
        """Handle LCM until a sample is queued or ``timeout_s`` passed; whether one is."""
        deadline = time.monotonic() + timeout_s
        while not self._queue:
            left = deadline - time.monotonic()
            if left <= 0:
                return False
            self.lcm.HandleSubscriptions(int(min(left, 0.1) * 1000) + 1)
        return True

    def drain(self, now: float, follower: LiveFollower) -> int:
        """Hand every sample queued to ``follower``, arrived at ``now`` (s); their count.

        Raises:
            LiveSourceError: more than :data:`MAX_QUEUED` waiting; a message that is not a
                pose sample; a sample the follower refuses.
        """
        from ..lcmtypes import lcmt_stewart_pose_sample

        self.lcm.HandleSubscriptions(0)
        if len(self._queue) > MAX_QUEUED:
            raise LiveSourceError(
                f"{self.channel}: {len(self._queue)} samples waiting: the loop cannot keep up"
            )
        n = 0
        while self._queue:
            data = self._queue.popleft()
            try:
                sample = lcmt_stewart_pose_sample.decode(data)
            except (ValueError, struct.error):  # a wrong fingerprint; a message cut short
                raise LiveSourceError(
                    f"{self.channel}: a message that is not an lcmt_stewart_pose_sample "
                    f"({len(data)} bytes)"
                ) from None
            follower.receive(now, sample.seq, sample.utime, sample.pose)
            self.log.append((float(now), int(sample.seq), int(sample.utime)))
            n += 1
        return n


class FollowReference(LeafSystem):
    """The live reference that follows a source (module docstring), for the closed loop in
    place of the precomputed sources (``make_stewart_diagram``'s ``reference_system``).

    Output ports (state, held between updates): ``x_d`` (18,) [pose, rate, acceleration]
    (rad, m, /s, /s^2), ``T_ff`` (6,) the holding torques of the pose, N m, ``limited`` (1,)
    1 while the pose is stopped short of the followed one. Discrete state: ``x_d``, ``T_ff``
    and the :class:`~stewart_drake.run.shaping.Shaper`'s state. The source and the follower
    are Python objects outside the Context (a live source is not replayed).

    Every control period it reads what has arrived and gives the follower's pose, rate and
    acceleration shaped by the :class:`~stewart_drake.run.shaping.Shaper` of ``shaping``
    (the one ``reproduce --stream`` shapes with): the followed reference itself while it is
    within the robot's limits, else a critically damped filter towards it within them; from
    where the robot rests until it first joins the followed reference.

    Args:
        geometry: the robot the controller believes in (the holding torques fed forward).
        x_initial: (6,) where it rests. source: :class:`LcmPoseSource`. follower: its
            :class:`~stewart_drake.references.live_stream.LiveFollower`.
        shaping: :class:`~stewart_drake.run.shaping.ShapingLimits` (its ``period_s`` is the
            control period).
        sample_timeout_s: the time without a sample that ends the run, s.
    Attributes:
        failure: why the source failed (one line), or None; from then on the reference comes
            to rest where it is.
        shaper: the :class:`~stewart_drake.run.shaping.Shaper` (:meth:`record` says what it
            shaped, from the Context).
    """

    X_D, T_FF = slice(0, 18), slice(18, 24)
    SHAPER = slice(24, 24 + Shaper.SIZE)
    LIMITED = slice(24 + Shaper.LIMITED.start, 24 + Shaper.LIMITED.stop)

    def __init__(
        self,
        geometry,
        x_initial,
        source: LcmPoseSource,
        follower: LiveFollower,
        shaping: ShapingLimits,
        sample_timeout_s: float = SAMPLE_TIMEOUT_S,
    ):
        super().__init__()
        self.geometry, self.h = geometry, float(shaping.period_s)
        self.source, self.follower = source, follower
        self.shaper = Shaper(shaping)
        self.sample_timeout_s = float(sample_timeout_s)
        self.x_initial = np.asarray(x_initial, dtype=float).reshape(6).copy()
        self.T_ff_initial = holding_torques(geometry, self.x_initial)
        self.failure: str | None = None
        self._t = np.zeros(0)  # the record: times, s, and [x_d (18), T_ff (6)] (float32)
        self._values = np.zeros((0, 24), dtype=np.float32)
        self._n = 0
        # Any: Drake 1.51's stubs type a state as ndarray[float64, ...], which no array matches.
        state: Any = np.zeros(self.SHAPER.stop)
        state[self.X_D][:6] = self.x_initial
        state[self.T_FF] = self.T_ff_initial
        state[self.SHAPER] = self.shaper.initial_state(self.x_initial)
        self._state = self.DeclareDiscreteState(state)
        ticket = {self.xd_ticket()}
        for name, part in (("x_d", self.X_D), ("T_ff", self.T_FF), ("limited", self.LIMITED)):
            size = part.stop - part.start
            self.DeclareVectorOutputPort(
                name, size, self._output(part), prerequisites_of_calc=ticket
            )
        self.DeclarePeriodicDiscreteUpdateEvent(self.h, 0.0, self._Update)

    def _output(self, part: slice):
        def calc(context, output):
            value = context.get_discrete_state(self._state).get_value()
            output.SetFromVector(value[part])

        return calc

    def _listen(self, now: float) -> None:
        """Read what has arrived; record the source's failure."""
        if self.failure is not None:
            return
        try:
            self.source.drain(now, self.follower)
        except LiveSourceError as err:
            self.failure = str(err)
            return
        last = self.follower.last_arrival
        if last is not None and now - last > self.sample_timeout_s:
            seq = self.source.log[-1][1] if self.source.log else None
            self.failure = (
                f"{self.source.channel}: no sample for {now - last:.3g} s after sample {seq} "
                f"(the timeout is {self.sample_timeout_s:g} s)"
            )

    def _Update(self, context, discrete_state):
        state = discrete_state.get_mutable_value(self._state)
        now = context.get_time()
        self._listen(now)
        followed = self.follower.evaluate(now) if self.failure is None else None
        shaper_state = state[self.SHAPER]  # a view: the shaper moves it to the next period's
        checks = int(shaper_state[Shaper.COUNTER][0]) % self.shaper.steps_per_check == 0
        x_d, _ = self.shaper.step(shaper_state, now, followed)
        state[self.X_D] = x_d
        if checks:
            state[self.T_FF] = holding_torques(self.geometry, x_d[:6])
        self._keep(now, np.concatenate([state[self.X_D], state[self.T_FF]]))

    def _keep(self, now: float, values: np.ndarray) -> None:
        """Add what the outputs hold from ``now`` on to the record (grown by doubling)."""
        if self._n == self._t.size:
            size = max(1024, 2 * self._n)
            self._t = np.resize(self._t, size)
            self._values = np.resize(self._values, (size, 24))
        self._t[self._n], self._values[self._n] = now, values
        self._n += 1

    def _held(self, t, part: slice) -> np.ndarray:
        """The recorded outputs ``part`` at times ``t`` (s, any shape): each held from its
        update to the next; the start's before the first."""
        t = np.asarray(t, dtype=float)
        if self._n == 0:
            first = np.concatenate([self.x_initial, np.zeros(12), self.T_ff_initial])
            return np.broadcast_to(first[part], t.shape + (part.stop - part.start,)).copy()
        i = np.clip(np.searchsorted(self._t[: self._n], t, side="right") - 1, 0, None)
        return self._values[i, part].astype(float)

    def evaluate(self, t):
        """Pose, rate and acceleration the reference gave at times ``t`` (s, any shape; its
        record, 24 float32 numbers a control period): the run's reference, as a precomputed
        one's ``evaluate`` (arrays of shape ``t.shape + (6,)``)."""
        x_d = self._held(t, slice(0, 18))
        return x_d[..., 0:6], x_d[..., 6:12], x_d[..., 12:18]

    def feedforward_at(self, t) -> np.ndarray:
        """The holding torques the reference gave at times ``t`` (s), N m (its record)."""
        return self._held(t, slice(18, 24))

    def record(self, context):
        """The :class:`~stewart_drake.run.shaping_record.ShapingRecord` of the periods shaped so
        far, from this system's state in ``context``: the root Context (the Diagram's when this
        system is in one, else its own; a subcontext of a Diagram's is refused by Drake)."""
        mine = self.GetMyContextFromRoot(context)
        return self.shaper.record_of(mine.get_discrete_state(self._state).get_value()[self.SHAPER])

    def summary(self, context) -> str:
        """One line: what was received, predicted and shaped (the shaping from ``context``, the
        root Context as :meth:`record`)."""
        f = self.follower
        used = f.used_samples / f.received * 100 if f.received else 0.0
        return (
            f"followed {self.source.channel}: {f.received} samples ({f.filled} missing ones "
            f"filled in), {f.latency_s:g} s late at {1 / f.dt:.4g} Hz, predictor "
            f"{f.predictor} used on {used:.0f} % of them, {f.fallbacks} fallback"
            f"{'' if f.fallbacks == 1 else 's'} to no prediction where it stopped paying "
            f"({f.rejected} sample axes taken as outliers, {f.clipped} predicted positions "
            "clipped to the motion's recent range); the "
            f"reference {self.record(context).words()}"
        )


def follow_on_robot(
    scenario,
    lcm,
    channel: str,
    latency_s: float,
    *,
    rate_hz: float = DEFAULT_STREAM_RATE_HZ,
    predictor: str = DEFAULT_PREDICTOR,
    settings=None,
    duration_s: float | None = None,
    first_sample_s: float = FIRST_SAMPLE_S,
    sample_timeout_s: float | None = None,
    loop_timeout_s: float = LOOP_TIMEOUT_S,
    limits=None,
    out: str | Path = "results",
    stem: str = "robot_follow",
    say: Callable[[str], None] | None = None,
    signals=None,
    before_torque: Callable | None = None,
    realtime: bool = False,
):
    """Follow the poses published on ``channel`` with the robot of ``scenario.bus`` (module
    docstring); never leaves the torque on.

    Args:
        scenario: a Scenario with a ``bus``. lcm: the ``DrakeLcm`` to listen on.
        channel: the channel of ``lcmt_stewart_pose_sample``. latency_s: how old a sample is
            when it arrives, s (plus the loop's lag when known). rate_hz: the samples' rate.
        predictor: one of :data:`~stewart_drake.references.prediction.PREDICTORS`; settings:
            its :class:`~stewart_drake.references.prediction.PredictorSettings` (the shipped).
        duration_s: how long to follow once the torque is on, s (None: until the source stops
            or a signal).
        first_sample_s: how long to wait for the first sample with the torque off, s.
        sample_timeout_s: the time without a sample that ends the run (:func:`sample_timeout`).
        loop_timeout_s: our watchdog's limit on a control period, s. limits: the reference's
            :class:`~stewart_drake.run.reference.ReferenceFilterLimits`.
        out, stem: the logs, ``<out>/<stem>.npz``. say: where lines go (default stderr).
        signals: as :func:`~.session.run_on_robot`'s. before_torque: a test hook
            ``f(sd, simulator, reference)`` called once a first sample is in, just before the
            torque is enabled (``reference``: the :class:`FollowReference`).
        realtime: run the loop as :class:`~.realtime.RealtimeLoop` asks, as
            :func:`~.session.run_on_robot` does (a refusal said in one line; the run goes on).
    Returns:
        :class:`~.session.RobotRun`: ok and exit code 0 when ``duration_s`` was followed to its
        end; a source that failed (or never sent) ends it with ``LiveSourceError: ...``, 1.
    Raises:
        InvalidConfigError: a bad argument (named), before the bus is opened; and as
            :func:`~.session.run_on_robot` before the torque is on.
    """
    from .measure import admissible_start, bus_config
    from .session_signals import SessionSignals
    from .watchdog import check_loop_timeout

    say = say or (lambda line: print(line, file=sys.stderr, flush=True))
    scenario = scenario.validate()
    bus_config(scenario)
    check_loop_timeout(loop_timeout_s, scenario.control_period_s)
    follower = LiveFollower(latency_s, rate_hz, predictor, settings, name=channel)
    timeout = sample_timeout(rate_hz, sample_timeout_s)
    for name, value, high in (
        ("duration_s", duration_s, 86_400.0),
        ("first_sample_s", first_sample_s, 3600.0),
        ("sample_timeout_s", timeout, 60.0),
    ):
        if value is not None and not (math.isfinite(value) and 0 < value <= high):
            raise InvalidConfigError(f"{name} must be in (0, {high:g}] s, got {value!r}")
    source = LcmPoseSource(lcm, channel)
    start = admissible_start(scenario)  # opens and closes the port; the torque stays off
    session = (scenario, start, source, follower, duration_s, first_sample_s, timeout)
    rest = (loop_timeout_s, limits, Path(out), stem, say, before_torque, realtime)
    if signals is not None:
        return _follow(*session, *rest, signals)
    with SessionSignals() as own:
        return own.settle(_follow(*session, *rest, own))


def _follow(
    scenario, start, source, follower, duration_s, first_sample_s, timeout, loop_timeout_s,
    limits, out, stem, say, before_torque, realtime, signals,
):  # fmt: skip
    """The powered part of :func:`follow_on_robot`."""
    from ..station.bus.driver import DynamixelBus
    from ..station.guard import advance as guarded
    from .measure import bus_config
    from .session import RobotRun, _drive, _keep_logs, _stop

    bus = DynamixelBus.from_config(bus_config(scenario)).open()
    ended = RobotRun("", False, True, start=start)
    powered, wall, sd, simulator, reference = False, 0.0, None, None, None
    try:
        bus.configure()
        sd, simulator, reference = _build(scenario, start.x, source, follower, limits, timeout)
        sd.station.use_bus(bus)
        sd.station.assemble(simulator.get_mutable_context(), start.x)
        if not source.wait(first_sample_s):
            ended.reason = (
                f"LiveSourceError: {source.channel}: no sample within {first_sample_s:g} s; "
                "nothing was powered"
            )
            ended.exit_code = 1
            return ended
        if before_torque is not None:
            before_torque(sd, simulator, reference)
        powered = True
        end = math.inf if duration_s is None else float(duration_s)

        def body():
            simulator.Initialize()  # paces real time from here
            while simulator.get_context().get_time() < end:
                t_next = min(simulator.get_context().get_time() + CHUNK_S, end)
                guarded(sd, simulator, functools.partial(simulator.AdvanceTo, t_next))
                if reference.failure is not None:
                    raise LiveSourceError(reference.failure)

        announce = (
            f"torque on: following {source.channel} ({follower.latency_s:g} s late, predictor "
            f"{follower.predictor}) from the measured pose"
        )
        driver = sd.station.driver
        talk = (loop_timeout_s, say, announce, body, ended, signals, realtime, driver)
        wall = _drive(bus, simulator, *talk)
        if ended.ok and duration_s is not None:
            ended.reason = f"followed {source.channel} for {duration_s:g} s"
    finally:
        signals.hold()
        _stop(bus, None if sd is None else sd.station.driver, ended)
    if powered:
        say(reference.summary(simulator.get_context()))
        _keep_logs(ended, sd, simulator, wall, out / f"{stem}.npz", _NoReferenceClock())
    return ended


class _NoReferenceClock:
    """A live run's reference has no clock of its own: the encoder log's ``t_path`` is NaN
    (:func:`~.session._keep_logs` writes the log and the encoders' readings beside it)."""

    @staticmethod
    def reference_time(t) -> np.ndarray:
        return np.full(np.shape(t), np.nan)


def _build(scenario, x0, source, follower, limits, timeout):
    """(StewartDiagram, Simulator, FollowReference): the closed loop of ``scenario`` with the
    live reference, initialized, its station not yet assembled."""
    from pydrake.systems.analysis import ApplySimulatorConfig, Simulator

    from ..run.diagram import make_stewart_diagram
    from ..run.plan import make_plan

    plan = make_plan(scenario, with_reference=False)
    reference = FollowReference(
        plan.geometry, x0, source, follower, shaping_limits(plan, limits), sample_timeout_s=timeout
    )
    sd = make_stewart_diagram(plan, None, reference_system=reference)
    simulator = Simulator(sd.diagram)
    ApplySimulatorConfig(plan.scenario.simulator, simulator)
    sd.initialize(simulator.get_mutable_context())
    return sd, simulator, reference


__all__ = [
    "LcmPoseSource",
    "FollowReference",
    "follow_on_robot",
    "sample_timeout",
    "FIRST_SAMPLE_S",
    "SAMPLE_TIMEOUT_S",
    "CHUNK_S",
    "MAX_QUEUED",
]
