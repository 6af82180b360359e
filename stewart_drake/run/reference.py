"""Reference and feed-forward torques, precomputed at the controller's sample instants.

The reference x_d(t) is known before the run, and so is the feed-forward torque that holds (or
drives) the platform along it. Evaluating both in Python at every 1 ms control step cost about a
third of the wall time of a run (IK, Jacobian and gravity gradient per step), so
:func:`add_reference_sources` evaluates them vectorized, and puts them in the Diagram as Drake
``TrajectorySource``s of zero-order holds, read in C++ with no Python call per step. The
feed-forward (IK, dynamics) is computed once for the whole run and kept as a numpy table (48 B a
step); the reference itself, cheap to evaluate, a stretch of :data:`FEED_ROWS` rows at a time.
A source holds only the stretch in force (:class:`StretchFeeder` swaps it every stretch): a
``BsplineTrajectory`` of order 1 keeps about 0.5 kB a step for the two, so a whole 25-minute
trace in one would hold 0.75 GB (a ``PiecewisePolynomial.ZeroOrderHold``, 3.3 kB a step).
The controller samples mid-interval (at k h + offset, 0 < offset < h), so each sample reads
exactly the value stored for step k, never its neighbour's, whatever the rounding of t.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from pydrake.math import BsplineBasis
from pydrake.systems.framework import LeafSystem, OutputPort, System
from pydrake.systems.primitives import TrajectorySource
from pydrake.trajectories import BsplineTrajectory

from ..base.errors import InvalidConfigError
from ..references.motion import Reference
from ..robot import kinematics
from ..robot.geometry import StewartGeometry
from ..robot.statics import feedforward_unchecked, holding_torques


@dataclass(frozen=True)
class StepTimes:
    """The times (k h + offset) + shift, k = 0..n - 1, s, made a stretch at a time: the numbers
    ``(np.arange(n) * h + offset) + shift`` holds, to the bit, without holding them (12 MB for
    a 25-minute run at 1 kHz). ``times[a:b]`` is rows a..b - 1 (a slice with unit step);
    ``size`` is n; :meth:`values` all of them.

    Attributes:
        size: n. period_s: h, s. offset_s: the offset, s. shift_s: added after, s.
    """

    size: int
    period_s: float
    offset_s: float = 0.0
    shift_s: float = 0.0
    ndim = 1

    def __getitem__(self, rows: slice) -> np.ndarray:
        a, b, _ = rows.indices(self.size)
        return (np.arange(a, b) * self.period_s + self.offset_s) + self.shift_s

    def values(self) -> np.ndarray:
        """(n,) all the times, s."""
        return self[:]


@dataclass
class ReferenceSources:
    """The two sources :func:`add_reference_sources` added, and the tables behind them.

    Attributes:
        x_d: a ``TrajectorySource``, output (18,) [pose, rate, acceleration] of the reference,
            its rows evaluated a stretch at a time (:data:`FEED_ROWS`).
        T_ff: a ``TrajectorySource``, output (6,) feed-forward motor torques, N m.
        feeder: the :class:`StretchFeeder` giving both their stretches.
        t_sample: (N,) controller sample instants, s.  t_eval: (N,) the times the reference was
        evaluated at (t_sample + lead). Both :class:`StepTimes` (made when read).
        T_ff_table: (N, 6).
    """

    x_d: TrajectorySource
    T_ff: TrajectorySource
    feeder: StretchFeeder
    t_sample: StepTimes
    t_eval: StepTimes
    T_ff_table: np.ndarray

    def release(self) -> None:
        """Drop the tables once the run is over and read (its feed-forward at the log times
        taken): a Drake Diagram holding Python systems outlives its last Python reference
        (pydrake's keep-alive links form a cycle the collector cannot see), so a long run's
        tables would stay until the process ends. The sources cannot output after this."""
        self.feeder.release()
        self.T_ff_table = np.zeros((0, 6))


#: Samples :func:`sample_reference` computes at once (5 s at 1 kHz): the inverse kinematics and
#: the feed-forward's intermediates take about 2.5 kB a sample; the tables kept, 0.2 kB.
SAMPLE_CHUNK = 5_000


def sample_reference(
    trajectory: Reference,
    geometry: StewartGeometry,
    duration_s: float,
    period_s: float,
    offset_s: float,
    lead_s: float,
    feedforward: str = "gravity",
    feedforward_lead_s: float = 0.0,
    keep_x_d: bool = True,
):
    """Reference and feed-forward at the sample instants t_k = k h + offset, k = 0..N.

    Args:
        feedforward_lead_s: the feed-forward is that of the reference this much later than
            x_d (s): with a computation delay the torque computed now acts one delay later, so
            it should hold (or drive) the platform where the reference will be then.
        keep_x_d: return the reference's table (False: None, for a caller that evaluates it
            a stretch at a time, :func:`reference_rows`, 0.14 kB a sample less).
    Returns:
        (t_sample (N,), t_eval (N,), x_d (N, 18) or None, T_ff (N, 6)) with t_eval = t_sample +
        lead_s, covering [0, duration_s] plus one period.
    Raises:
        InvalidConfigError: non-positive period or duration; UnreachablePoseError (naming the time
        and leg) if the reference leaves the workspace.
    """
    if not (np.isfinite(period_s) and period_s > 0 and np.isfinite(duration_s) and duration_s > 0):
        raise InvalidConfigError(f"period ({period_s}) and duration ({duration_s}) must be > 0 s")
    n = int(np.ceil(duration_s / period_s)) + 2
    t_sample = np.arange(n) * period_s + offset_s
    t_eval = t_sample + lead_s
    x_d, T_ff = (np.empty((n, 18)) if keep_x_d else None), np.empty((n, 6))
    for start in range(0, n, SAMPLE_CHUNK):  # the intermediates of a stretch at a time
        part = slice(start, start + SAMPLE_CHUNK)
        x, xd, xdd = trajectory.evaluate(t_eval[part])
        theta = kinematics.ik(geometry, x, t=t_eval[part])  # names the first unreachable time
        x_ff, xdd_ff, theta_ff = x, xdd, theta
        if feedforward_lead_s:
            t_ff = t_eval[part] + feedforward_lead_s
            x_ff, _, xdd_ff = trajectory.evaluate(t_ff)
            theta_ff = kinematics.ik(geometry, x_ff, t=t_ff)
        # The poses are checked by the inverse kinematics (ik): not again.
        T_ff[part] = feedforward_unchecked(geometry, x_ff, theta_ff, xdd_ff, feedforward)
        if x_d is not None:
            x_d[part] = np.concatenate([x, xd, xdd], axis=1)
    return t_sample, t_eval, x_d, T_ff


def reference_rows(trajectory: Reference, t_eval):
    """rows(a, b) -> (b - a, 18) [pose, rate, acceleration] of ``trajectory`` at t_eval[a:b]:
    the rows of :func:`sample_reference`'s table, made again when a stretch is fed (the
    reference's own ``evaluate``, row by row the same arithmetic)."""

    def rows(a: int, b: int) -> np.ndarray:
        return np.concatenate(trajectory.evaluate(t_eval[a:b]), axis=1)

    return rows


def zero_order_hold(breaks, table) -> BsplineTrajectory:
    """A zero-order hold of ``table``'s rows: row k on [breaks[k], breaks[k + 1]), the time
    clamped to [breaks[0], breaks[-1]] (the last row only closes the last interval), as
    ``PiecewisePolynomial.ZeroOrderHold(breaks, table.T)`` gives to the bit, in a fifteenth of
    its memory: a ``BsplineTrajectory`` of order 1 (its knots the breaks, its control points
    the rows).

    Args:
        breaks: (N,) strictly increasing times, s; N >= 2. table: (N, n) the values.
    Returns:
        a ``BsplineTrajectory`` of n rows and 1 column.
    """
    breaks, table = np.asarray(breaks, dtype=float), np.asarray(table, dtype=float)
    points = [row.reshape(-1, 1) for row in table[:-1]]
    return BsplineTrajectory(BsplineBasis(1, breaks), points)


#: Rows a stretch of the run's reference holds (:func:`add_reference_sources`): 5 s at a bus's
#: 10 ms. A stretch is made inside one period of the loop, where its cost adds to the period's
#: (5,000 rows of an IntERAct trace took 13 to 19 ms, a 10 ms period missed every 50 s);
#: 500 take about a tenth.
FEED_ROWS = 500
#: Rows each stretch of :class:`StretchFeeder` holds beyond its own on either side, so that a
#: read just before or after the stretch changes (the event's time rounded) finds its row.
STRETCH_PAD = 8


class StretchFeeder(LeafSystem):
    """Drake ``TrajectorySource``s of tables' zero-order holds, fed a stretch at a time.

    Each table is the zero-order hold of its rows on ``breaks`` (:func:`zero_order_hold`: row
    k on [breaks[k], breaks[k + 1]), read, not interpolated), output by a C++
    ``TrajectorySource`` (no Python call when it is read). A source holds only the stretch of
    ``stretch`` rows in force, plus :data:`STRETCH_PAD` rows either side: this system (no
    ports) gives each source the next stretch by ``UpdateTrajectory`` at the time it begins
    (a periodic event every ``stretch`` rows; the first at initialization), so a long run
    holds no row per step. The sources'
    values depend on the run's time only: one run per Diagram, as every builder here makes.

    Args:
        breaks: the N times k h (+ offset), s (:class:`StepTimes`); N >= 2, h > 0.
        tables: {name: rows} with ``rows(a, b)`` -> (b - a, n) rows a..b - 1 of the table (a
            pure function, e.g. a numpy table's slice).
        stretch: rows a source holds (plus the pads).
    Attributes:
        sources: {name: ``TrajectorySource``} to add to the Diagram (output (n,)).
    Raises:
        InvalidConfigError: fewer than 2 breaks, or a step h <= 0.
    """

    def __init__(self, breaks: StepTimes, tables: dict, stretch: int = 5_000):
        super().__init__()
        self.breaks = breaks
        if breaks.size < 2 or not breaks.period_s > 0:
            raise InvalidConfigError(
                f"a StretchFeeder needs N >= 2 breaks a step h > 0 apart, got {breaks}"
            )
        h = float(breaks.period_s)
        self._h, self._stretch, self._tables = h, int(stretch), dict(tables)
        self._k = 0
        self.sources = {name: TrajectorySource(self._hold(name, 0)) for name in self._tables}
        self.DeclareInitializationPublishEvent(self._Feed)
        self.DeclarePeriodicPublishEvent(self._stretch * h, self._stretch * h, self._Feed)

    def _hold(self, name: str, k: int):
        """The zero-order hold of stretch k of table ``name``, with its pads."""
        a = max(k * self._stretch - STRETCH_PAD, 0)
        b = min((k + 1) * self._stretch + STRETCH_PAD, self.breaks.size)
        return zero_order_hold(self.breaks[a:b], self._tables[name](a, b))

    def _Feed(self, context) -> None:
        k = int(round(context.get_time() / (self._stretch * self._h)))
        if k == self._k and context.get_time() > 0.0:
            return
        if not self._tables:
            raise RuntimeError("this StretchFeeder was released: its run is over")
        if k * self._stretch >= self.breaks.size - 1:  # past the table: the last stretch holds
            return
        self._k = k
        for name, source in self.sources.items():
            source.UpdateTrajectory(self._hold(name, k))

    def release(self) -> None:
        """Drop the tables and the stretches held (:meth:`ReferenceSources.release`): each
        source then holds zeros over the first two breaks."""
        for source in self.sources.values():
            n = source.get_output_port().size()
            source.UpdateTrajectory(zero_order_hold(self.breaks[:2], np.zeros((2, n))))
        self._tables = {}
        self.breaks = StepTimes(0, self.breaks.period_s)


def add_reference_sources(
    builder,
    trajectory: Reference,
    geometry: StewartGeometry,
    duration_s: float,
    period_s: float,
    offset_s: float = 0.0,
    lead_s: float = 0.0,
    feedforward: str = "gravity",
    feedforward_lead_s: float = 0.0,
) -> ReferenceSources:
    """Add the reference x_d and the feed-forward T_ff as zero-order holds: Drake
    ``TrajectorySource``s fed a stretch at a time (:class:`StretchFeeder`).

    A consumer that samples at t_k = k h + offset_s reads x_d(t_k + lead_s) and the feed-forward
    at that reference. Each value is stored on [k h, (k + 1) h), so ``offset_s`` must lie strictly
    inside (0, h) for the sample to be unambiguous; offset 0 is allowed for consumers that sample
    exactly at k h (the value then also holds on the whole interval).

    Args:
        builder: the DiagramBuilder. trajectory: object with ``evaluate(t)``.
        geometry: the robot the controller believes in. duration_s: run length, s.
        period_s: controller period h, s. offset_s: sample offset in [0, h), s.
        lead_s: evaluate the reference this far ahead of the sample, s (see diagram.py).
        feedforward: see :func:`~stewart_drake.robot.statics.feedforward_torques`.
    Returns:
        :class:`ReferenceSources` (systems named "reference" and "feedforward").
    """
    if not 0.0 <= offset_s < period_s:
        raise InvalidConfigError(f"offset_s must be in [0, period_s), got {offset_s}")
    t_sample, t_eval, x_d, T_ff = sample_reference(
        trajectory,
        geometry,
        duration_s,
        period_s,
        offset_s,
        lead_s,
        feedforward,
        feedforward_lead_s,
        keep_x_d=False,
    )
    # The times as the sampling made them (bit for bit), made again when read, not held.
    n = t_sample.size
    del t_sample, t_eval
    t_sample = StepTimes(n, period_s, offset_s)
    t_eval = StepTimes(n, period_s, offset_s, lead_s)
    breaks = StepTimes(n, period_s, offset_s, -offset_s)  # k h: the sample inside its interval
    feeder = StretchFeeder(
        breaks,
        {"x_d": reference_rows(trajectory, t_eval), "T_ff": lambda a, b: T_ff[a:b]},
        stretch=FEED_ROWS,
    )
    builder.AddNamedSystem("reference_feeder", feeder)
    ref = builder.AddNamedSystem("reference", feeder.sources["x_d"])
    ff = builder.AddNamedSystem("feedforward", feeder.sources["T_ff"])
    return ReferenceSources(
        x_d=ref, T_ff=ff, feeder=feeder, t_sample=t_sample, t_eval=t_eval, T_ff_table=T_ff
    )


@dataclass(frozen=True)
class RunReference:
    """A run's reference in its Diagram (:func:`add_run_reference`): its system (the
    :class:`ReferenceSources`, or a live reference system), its ``x_d`` (18) and ``T_ff`` (6)
    output ports, and where the run starts: x0, x_dot0 (6,) [rad, m; rad/s, m/s] and the
    feed-forward T_ff_initial (6,) N m."""

    system: ReferenceSources | System
    x_d: OutputPort
    T_ff: OutputPort
    x0: np.ndarray
    x_dot0: np.ndarray
    T_ff_initial: np.ndarray


def add_run_reference(
    builder, plan, trajectory: Reference | None, station, reference_system=None
) -> RunReference:
    """The reference of the run of ``plan`` (a :class:`~.plan.RunPlan`): the precomputed
    reference and feed-forward of ``trajectory`` (:func:`add_reference_sources` at the plan's
    control period and sample offset, led by half a plant step, with the scenario's
    feed-forward led by the computation delay), or the live ``reference_system`` with its
    inputs exported, and for a display its ``x_d``, its ``limited`` port if it has one and the
    ``station``'s ``platform_state``."""
    h_plant, h = plan.plant_time_step_s, plan.control_period_s
    if reference_system is None:
        assert trajectory is not None, "a run without a live reference needs its trajectory"
        ref = add_reference_sources(
            builder,
            trajectory,
            plan.geometry,
            plan.duration_s,
            period_s=h,
            offset_s=plan.sample_offset_s,
            lead_s=0.5 * h_plant,
            feedforward=plan.scenario.feedforward,
            feedforward_lead_s=plan.delay_periods * h,
        )
        x0, x_dot0, _ = (np.asarray(v, dtype=float) for v in trajectory.evaluate(0.0))
        return RunReference(
            ref,
            ref.x_d.get_output_port(),
            ref.T_ff.get_output_port(),
            x0,
            x_dot0,
            ref.T_ff_table[0].copy(),  # a view would keep the whole table after its release
        )
    ref = builder.AddNamedSystem("reference", reference_system)
    for i in range(ref.num_input_ports()):
        builder.ExportInput(ref.get_input_port(i), ref.get_input_port(i).get_name())
    builder.ExportOutput(station.GetOutputPort("platform_state"), "platform_state")
    builder.ExportOutput(ref.GetOutputPort("x_d"), "x_d")
    if ref.HasOutputPort("limited"):
        builder.ExportOutput(ref.GetOutputPort("limited"), "limited")
    return RunReference(
        ref,
        ref.GetOutputPort("x_d"),
        ref.GetOutputPort("T_ff"),
        np.asarray(ref.x_initial, dtype=float),
        np.zeros(6),
        np.asarray(ref.T_ff_initial, dtype=float),
    )


@dataclass(frozen=True)
class ReferenceFilterLimits:
    """How fast a live reference may move (:class:`TeleopReference`); SI units.

    Attributes:
        rate: (6,) largest |rate| [rad/s x3, m/s x3].
        acceleration: (6,) largest |acceleration| [rad/s^2 x3, m/s^2 x3].
        bandwidth_hz: natural frequency of the critically damped approach to the target, Hz.
        target_period_s: how often the target is read (and the feed-forward re-computed), s.
    """

    rate: tuple = (0.5, 0.5, 0.5, 0.05, 0.05, 0.05)
    acceleration: tuple = (5.0, 5.0, 5.0, 0.5, 0.5, 0.5)
    bandwidth_hz: float = 2.0
    target_period_s: float = 0.02

    def __post_init__(self):
        for name in ("rate", "acceleration"):
            v = np.asarray(getattr(self, name), dtype=float)
            if v.shape != (6,) or not np.all(np.isfinite(v)) or np.any(v <= 0):
                raise InvalidConfigError(
                    f"ReferenceFilterLimits.{name} needs 6 finite values "
                    f"> 0, got {getattr(self, name)!r}"
                )
        for name in ("bandwidth_hz", "target_period_s"):
            v = getattr(self, name)
            if not (np.isfinite(v) and v > 0):
                raise InvalidConfigError(f"ReferenceFilterLimits.{name} must be > 0, got {v!r}")


class TeleopReference(LeafSystem):
    """A live reference: a target pose (Meshcat sliders) filtered into a pose the robot can
    follow, with its rate, acceleration and feed-forward, for the closed loop in place of the
    precomputed sources of :func:`add_reference_sources`.

    Input port:  ``target`` (abstract ``RigidTransform``): the pose wanted, X_WE as Drake's
        ``MeshcatPoseSliders`` give it (roll-pitch-yaw and position).
    Output ports (state, held between updates): ``x_d`` (18,) [pose, rate, acceleration]
        (rad, m, /s, /s^2), ``T_ff`` (6,) the holding torques of the pose, N m.
    Discrete state, by the index slices below: x (6), v (6), a (6), goal (6), T_ff (6), and the
    control periods so far (1).

    Every control period the pose approaches the goal as a critically damped second-order
    system at ``limits.bandwidth_hz``, its acceleration and rate clipped to ``limits``
    (rate-limited). Every ``limits.target_period_s`` the target is read and becomes the goal
    when ``admissible`` accepts it; otherwise the goal is the farthest admissible pose on the
    segment from the last goal to the target (workspace-limited: the robot stops at the
    boundary rather than the reference leaving it), and the feed-forward is re-computed at the
    current pose.

    Args:
        geometry: the robot the controller believes in. x_initial: (6,) start pose [rad, m].
        period_s: control period, s. limits: :class:`ReferenceFilterLimits`.
        admissible: ``admissible(x (N, 6)) -> (N,) bool``, the poses the reference may take
            (:func:`admissible_poses` with the scenario's thresholds, by default).
    Raises:
        InvalidConfigError: a bad period or limits; UnreachablePoseError: x_initial.
    """

    #: Index slices of the parts of the state.
    X, V, A, GOAL, T_FF, COUNTER, LIMITED = (
        slice(0, 6),
        slice(6, 12),
        slice(12, 18),
        slice(18, 24),
        slice(24, 30),
        slice(30, 31),
        slice(31, 32),
    )

    def __init__(
        self,
        geometry: StewartGeometry,
        x_initial,
        period_s: float,
        limits: ReferenceFilterLimits | None = None,
        admissible=None,
    ):
        super().__init__()
        from pydrake.common.value import AbstractValue
        from pydrake.math import RigidTransform

        if not (np.isfinite(period_s) and period_s > 0):
            raise InvalidConfigError(f"period_s must be > 0 s, got {period_s}")
        self.geometry, self.h = geometry, float(period_s)
        self.limits = limits or ReferenceFilterLimits()
        self.admissible = admissible or (lambda x: admissible_poses(geometry, x))
        self.steps_per_target = max(1, int(round(self.limits.target_period_s / self.h)))
        self._rate = np.asarray(self.limits.rate, dtype=float)
        self._acc = np.asarray(self.limits.acceleration, dtype=float)
        self._omega = 2 * np.pi * self.limits.bandwidth_hz
        x0 = np.asarray(x_initial, dtype=float)
        #: (6,) the start pose and its holding torques, N m.
        self.x_initial = x0.copy()
        self.T_ff_initial = holding_torques(geometry, x0)
        state = np.zeros(32)
        state[self.X], state[self.GOAL], state[self.T_FF] = x0, x0, self.T_ff_initial
        self._target = self.DeclareAbstractInputPort("target", AbstractValue.Make(RigidTransform()))
        self._state = self.DeclareDiscreteState(state)
        self._x_d = self.DeclareVectorOutputPort(
            "x_d", 18, self._CalcXd, prerequisites_of_calc={self.xd_ticket()}
        )
        self.DeclareVectorOutputPort(
            "T_ff", 6, self._CalcTff, prerequisites_of_calc={self.xd_ticket()}
        )
        self.DeclareVectorOutputPort(
            "limited",
            1,
            lambda context, output: output.SetFromVector(
                # The stubs take an int; Drake takes the DiscreteStateIndex it returned.
                context.get_discrete_state(self._state).get_value()[self.LIMITED]  # type: ignore[call-overload]
            ),
            prerequisites_of_calc={self.xd_ticket()},
        )
        self.DeclarePeriodicDiscreteUpdateEvent(
            period_sec=self.h, offset_sec=0.0, update=self._Update
        )

    def _CalcXd(self, context, output):
        output.SetFromVector(context.get_discrete_state(self._state).get_value()[:18])

    def _CalcTff(self, context, output):
        output.SetFromVector(context.get_discrete_state(self._state).get_value()[self.T_FF])

    def goal_toward(self, goal, target) -> np.ndarray:
        """The target if admissible, else the farthest admissible pose on the segment from the
        (admissible) goal to it, to 1/64 of the segment: (6,)."""
        s = np.linspace(0.0, 1.0, 65)[:, None]
        path = goal + s * (target - goal)
        ok = np.asarray(self.admissible(path), dtype=bool)
        last = int(np.argmin(ok)) - 1 if not ok.all() else 64
        return path[max(last, 0)]

    def _Update(self, context, discrete_state):
        state = discrete_state.get_mutable_value(self._state)
        steps = state[self.COUNTER]
        if steps[0] % self.steps_per_target == 0:  # read the target, re-plan
            from pydrake.math import RollPitchYaw

            X_WE = self._target.Eval(context)
            target = np.concatenate([RollPitchYaw(X_WE.rotation()).vector(), X_WE.translation()])
            if np.all(np.isfinite(target)) and np.any(target != state[self.GOAL]):
                state[self.GOAL] = self.goal_toward(state[self.GOAL], target)
                state[self.LIMITED] = float(np.any(state[self.GOAL] != target))
            state[self.T_FF] = holding_torques(self.geometry, state[self.X])
        steps += 1.0
        h, w = self.h, self._omega
        x, v = state[self.X], state[self.V]
        a = np.clip(w * w * (state[self.GOAL] - x) - 2 * w * v, -self._acc, self._acc)
        v_next = np.clip(v + h * a, -self._rate, self._rate)
        state[self.A] = (v_next - v) / h
        state[self.V] = v_next
        state[self.X] = x + h * v_next


def guarded_admissible(plan, clearance, geometry: StewartGeometry | None = None):
    """``admissible(x (N, 6)) -> (N,) bool``, :func:`admissible_poses` as the run of ``plan``
    (a :class:`~.plan.RunPlan`) judges a live reference's poses: its scenario's guard thresholds,
    its motors' peak torque, and ``clearance`` (a
    :class:`~stewart_drake.plant.clearance.ClearanceModel`) with the guard's least clearance;
    of ``geometry`` (default the robot the controller believes in, ``plan.geometry``)."""
    peak, guard = plan.torque_limit_Nm, plan.scenario.guard
    geometry = plan.geometry if geometry is None else geometry

    def admissible(x) -> np.ndarray:
        return admissible_poses(
            geometry,
            x,
            guard.cond_threshold,
            guard.min_sigma_min_inv,
            peak,
            clearance=clearance,
            min_clearance_m=guard.min_clearance_m,
        )

    return admissible


def admissible_poses(
    geometry: StewartGeometry,
    x,
    cond_threshold: float = 200.0,
    min_sigma_min_inv: float = 0.01,
    peak_torque_Nm: float | None = None,
    torque_fraction: float = 0.9,
    clearance=None,
    min_clearance_m: float = 0.003,
) -> np.ndarray:
    """(N,) bool: poses x (N, 6) in the admissible set (:func:`~.admissible.classify`, the rule
    ``workspace`` maps and ``check`` applies): inside every joint limit, away from
    singularities (cond(J) at most ``cond_threshold``, 1/sigma_max(J) at least
    ``min_sigma_min_inv``, the guard's thresholds), given the motors' peak torque held by at
    most ``torque_fraction`` of it (:func:`~.statics.holding_torques`), and given a
    :class:`~stewart_drake.plant.clearance.ClearanceModel` no two parts closer than
    ``min_clearance_m`` (m; without one the clearance is not judged)."""
    from ..plant.admissible import classify
    from ..robot.limits import MotorLimits

    x = np.atleast_2d(np.asarray(x, dtype=float))
    motors = None
    if peak_torque_Nm is not None:
        motors = MotorLimits(peak_torque_Nm=peak_torque_Nm, margin=torque_fraction)
    flags = classify(
        geometry,
        x,
        cond_threshold,
        min_clearance_m if clearance is not None else None,
        motors,
        min_sigma_min_inv,
        clearance,
    )
    return np.asarray(flags["admissible"], dtype=bool).reshape(-1)
