"""The reference that follows a late motion, shaped into one the robot can follow: period by
period, causally, within the limits the one reference validator judges; ``reproduce --stream``
and ``robot --follow-lcm`` shape alike.

The followed reference (:mod:`~stewart_drake.references.stream`) asks for more than the motion
itself: each arrival revises the prediction, and the blend from one arrival's curve to the
next's asks for accelerations the motion never has (IntERAct's first liver trace at 5 Hz, 0.2 s
late: 0.62 m/s^2 and 4.1 rad/s^2 where the motion needs 0.03 m/s^2 and 0.21 rad/s^2), which
the motors' torque must give. :class:`Shaper` takes the followed reference's pose, rate and
acceleration at each control period, knowing nothing later, and gives the reference the robot
is given:

- the followed reference itself while it is within the robot's limits: each motor's torque and
  crank speed within the share a reference may use
  (:func:`~stewart_drake.robot.limits.sample_effort`, the validator's own numbers, against
  :class:`~stewart_drake.robot.limits.MotorLimits`) at every period, and its pose admissible
  (:func:`~.reference.guarded_admissible`: reach, joint ranges, singularities, clearance,
  holding torques) at every ``target_period_s``;
- else a critically damped second-order filter towards it at :data:`FOLLOW_BANDWIDTH_HZ`, fed
  forward with its rate and acceleration (teleop's form, :class:`~.reference.TeleopReference`,
  faster than teleop's 2 Hz: the sooner it is back on the followed reference, the less it lags
  it), integrated at
  constant acceleration over the period, its acceleration scaled towards zero until every
  motor's torque and next crank speed are within: at a given pose and rate the torque is affine
  in the acceleration (tau = M(q) q'' + h(q, q')), the property on which the dynamic scaling of
  trajectories rests (Hollerbach, ASME J. Dyn. Syst. Meas. Control 106, 102, 1984; Bobrow,
  Dubowsky and Gibson, Int. J. Robot. Res. 4(3), 3, 1985), so the largest scale is found in
  closed form from the effort at zero acceleration and at the wanted one. A pose that is not
  admissible is not followed: the filter goes to the farthest admissible pose towards it and
  stops there (``limited``). Where the reference does not go towards the followed one (its
  approach from where it started, live from where the robot rests; coming to rest when nothing
  is followed; stopping short), the filter is teleop's own (``bandwidth_hz``, 2 Hz) and the
  acceleration and the next rate are also clipped to the box of
  :class:`~.reference.ReferenceFilterLimits`, as teleop's reference is;
- back on the followed reference once within :data:`REJOIN_POSE` and :data:`REJOIN_RATE` of
  it, where it is within the limits again (the reference steps by at most those).

The choices are ours: the filter is the live path's (teleop's); while it follows, the limits
are the validator's alone, not teleop's box (the library's breathing sampled at 5 Hz with 0.1
mm of noise, 0.2 s late: the box moved the reference up to 2.4 mm from the followed one, the
motors' torque alone 0.12 mm), and its bandwidth is 10 Hz, not 2 (the library's sharkfin 0.2 s
late, the first 60 s: translation RMS against the true motion 2.16 mm at 2 Hz, 1.70 at 5, 1.60
at 10, 1.70 at 20, where the followed reference is at 1.46 and none at 2.52);
the rejoining tolerances are ours; and the torque is bounded :data:`EFFORT_SAFETY` inside the
validator's limit, for the rounding between the affine step and the validator's own
evaluation. Only what
the follower adds is shaped: a motion that itself needs more than the robot gives is refused (or
scaled) before it is followed (:func:`~stewart_drake.organ_motion.streaming.reproduce_stream`).
:class:`ShapingRecord` counts what was shaped and by how much; :func:`shape_followed` shapes a
whole followed reference offline (:class:`ShapedReference`), stepping the same :class:`Shaper`
as the live reference (:class:`~stewart_drake.live.follow.FollowReference`) steps, so both give
the same reference for the same arrivals.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from ..base.errors import InvalidConfigError, StewartError
from ..robot.geometry import StewartGeometry
from ..robot.limits import MotorLimits, sample_effort
from .reference import ReferenceFilterLimits
from .shaping_record import (
    CLIPPED_FLAG,
    LIMITED_FLAG,
    OVER_FLAG,
    SCALED_FLAG,
    SHAPED_FLAG,
    ShapingRecord,
    count_joined,
    count_shaped,
)

#: The natural frequency of the filter that brings the shaped reference back onto the followed
#: one once it has joined it, Hz (module docstring) ...
FOLLOW_BANDWIDTH_HZ = 10.0
#: ... at most this over the control period (omega h; the filter integrated at constant
#: acceleration over a period is stable below 1).
FOLLOW_OMEGA_H = 0.5
#: The shaped reference rejoins the followed one when every axis's pose is within this of it
#: (m or rad) ...
REJOIN_POSE = 1e-6
#: ... and every axis's rate within this (m/s or rad/s).
REJOIN_RATE = 1e-5
#: The share of the validator's torque and speed limits below which the shaping keeps each
#: motor: the validator evaluates the torque of the shaped acceleration directly, the shaping
#: from the affine form (they differ by rounding, 1e-16 of the torque), and where the compiled
#: form cannot finish a pose the validator's numpy form differs by up to 5e-10 of it.
EFFORT_SAFETY = 1e-6
#: Control periods the offline shaping evaluates at once (the followed reference, its effort and
#: its admissibility: about 0.5 kB a period).
SHAPE_CHUNK = 50_000


@dataclass(frozen=True)
class ShapingLimits:
    """What a followed reference is shaped within (module docstring): the robot's, as the
    validator judges them, and the control period at which they are kept.

    Attributes:
        geometry: the robot whose motors' torques are computed: a run's ``plant_geometry``,
            the robot the validator checks.
        motors: its :class:`~stewart_drake.robot.limits.MotorLimits` (peak torque, no-load
            speed, the share a reference may use, the servo's friction).
        admissible: ``admissible(x (N, 6)) -> (N,) bool``, the poses a reference may take.
        filter: :class:`~.reference.ReferenceFilterLimits`: the filter's bandwidth (Hz), how
            often the pose is checked (s), and the rate and acceleration box [rad/s, m/s;
            rad/s^2, m/s^2] of the approach, of coming to rest and of stopping short.
        period_s: the control period, s.
        follow_bandwidth_hz: the natural frequency of the filter back onto the followed
            reference once joined, Hz (at most :data:`FOLLOW_OMEGA_H` / (2 pi ``period_s``)
            is used).
    Raises:
        InvalidConfigError: a period or a bandwidth not finite and > 0.
    """

    geometry: StewartGeometry
    motors: MotorLimits
    admissible: Callable
    filter: ReferenceFilterLimits = field(default_factory=ReferenceFilterLimits)
    period_s: float = 1e-3
    follow_bandwidth_hz: float = FOLLOW_BANDWIDTH_HZ

    def __post_init__(self):
        for what, value in (
            ("the control period", self.period_s),
            ("the following bandwidth", self.follow_bandwidth_hz),
        ):
            if not (isinstance(value, (int, float)) and math.isfinite(value)):
                raise InvalidConfigError(f"{what} must be a number, got {value!r}")
            if not value > 0:
                raise InvalidConfigError(f"{what} must be > 0, got {value!r}")

    def follow_omega(self) -> float:
        """The natural frequency of the filter back onto the followed reference, rad/s:
        ``follow_bandwidth_hz``, at most :data:`FOLLOW_OMEGA_H` / ``period_s``."""
        return min(2 * math.pi * self.follow_bandwidth_hz, FOLLOW_OMEGA_H / self.period_s)

    def effort_limits(self) -> tuple[float, float]:
        """(torque N m, crank speed rad/s) each motor is kept within: the validator's limits
        (the share ``margin`` of the peak and of the no-load speed) less
        :data:`EFFORT_SAFETY`; inf where a limit is not known."""
        m, keep = self.motors, 1.0 - EFFORT_SAFETY
        torque = math.inf if m.peak_torque_Nm is None else m.margin * m.peak_torque_Nm * keep
        speed = math.inf if m.max_speed_rad_s is None else m.margin * m.max_speed_rad_s * keep
        return torque, speed


def shaping_limits(plan, limits: ReferenceFilterLimits | None = None) -> ShapingLimits:
    """The :class:`ShapingLimits` of the run of ``plan`` (a :class:`~.plan.RunPlan`): the robot
    its validator checks (``plant_geometry``), the plan's ``motor_limits``, the admissible
    poses of that robot with the scenario's guard (:func:`~.reference.guarded_admissible` with
    its clearance model), ``limits`` (default teleop's) and the scenario's control period."""
    from ..plant.clearance import clearance_model
    from .reference import guarded_admissible

    geometry = plan.plant_geometry
    admissible = guarded_admissible(plan, clearance_model(geometry), geometry)
    return ShapingLimits(
        geometry,
        plan.motor_limits,
        admissible,
        limits or ReferenceFilterLimits(),
        float(plan.control_period_s),
    )


class Shaper:
    """The shaping of a followed reference, one control period at a time (module docstring).

    Its state is a (:data:`SIZE`,) array the caller keeps (a Drake system in its discrete
    state): by the slices below, the pose and rate the shaped reference has at the next period
    when it is not on the followed one (rad, m; /s), the goal (the last admissible followed
    pose, or the farthest admissible towards it), and 1.0/0.0 flags: on the followed reference,
    stopped short, joined it once; the periods so far; and the counts of what was shaped
    (:meth:`record_of` reads them: all that changes is in the state, none in the shaper).
    :meth:`step` reads the followed reference at the period and writes what the robot is given
    then.

    Args:
        limits: :class:`ShapingLimits`.
    Attributes:
        steps_per_check: the periods between two checks of the pose.
    """

    X, V, GOAL = slice(0, 6), slice(6, 12), slice(12, 18)
    ON_PATH, LIMITED, JOINED, COUNTER = slice(18, 19), slice(19, 20), slice(20, 21), slice(21, 22)
    RECORD = slice(22, 22 + len(ShapingRecord.FIELDS))
    SIZE = RECORD.stop
    #: The flags of a shaped period (:meth:`step`'s second value; 0: the followed reference).
    SHAPED_FLAG, LIMITED_FLAG, CLIPPED_FLAG = SHAPED_FLAG, LIMITED_FLAG, CLIPPED_FLAG
    SCALED_FLAG, OVER_FLAG = SCALED_FLAG, OVER_FLAG

    def __init__(self, limits: ShapingLimits):
        self.limits = limits
        self.h = float(limits.period_s)
        self.steps_per_check = max(1, int(round(limits.filter.target_period_s / self.h)))
        self._rate = np.asarray(limits.filter.rate, dtype=float)
        self._acc = np.asarray(limits.filter.acceleration, dtype=float)
        self._omega = 2 * np.pi * limits.filter.bandwidth_hz  # the approach's, teleop's
        self._omega_follow = limits.follow_omega()
        self._torque, self._speed = limits.effort_limits()

    def initial_state(self, x_initial) -> np.ndarray:
        """(:data:`SIZE`,) the state of a reference at rest at ``x_initial`` (6,) [rad, m],
        its goal, not on a followed reference (it joins one within the rejoining tolerances)."""
        state = np.zeros(self.SIZE)
        state[self.X] = state[self.GOAL] = np.asarray(x_initial, dtype=float).reshape(6)
        state[self.RECORD] = ShapingRecord.initial_values()
        return state

    def record_of(self, state) -> ShapingRecord:
        """The :class:`ShapingRecord` of the periods stepped from ``state`` (:data:`SIZE`,)."""
        return ShapingRecord.from_values(self.h, np.asarray(state)[self.RECORD])

    def within(self, x, v, a) -> np.ndarray:
        """(n,) bool: the followed reference's samples (n, 6) each (pose, rate, acceleration)
        that may be given as they are: every motor's torque and crank speed within
        :meth:`ShapingLimits.effort_limits`."""
        x, v, a = (np.asarray(q, dtype=float).reshape(-1, 6) for q in (x, v, a))
        T, speed = self._effort(x, v, a)
        return np.all(np.abs(T) <= self._torque, axis=1) & np.all(
            np.abs(speed) <= self._speed, axis=1
        )

    def _effort(self, x, v, a) -> tuple:
        """(T, crank speed) (n, 6) of the samples; inf where the pose cannot be computed."""
        try:
            return sample_effort(self.limits.geometry, x, v, a, self.limits.motors.servo)
        except StewartError:  # a pose whose effort the validator also refuses
            inf = np.full(np.shape(x), np.inf)
            return inf, inf

    def goal_toward(self, goal, target, points: int = 17) -> np.ndarray:
        """The farthest admissible pose on the segment from the (admissible) ``goal`` to
        ``target``, to 1/(``points`` - 1) of it: (6,)."""
        s = np.linspace(0.0, 1.0, points)[1:, None]
        ok = np.asarray(self.limits.admissible(goal + s * (target - goal)), dtype=bool)
        good = int(np.argmin(ok)) if not ok.all() else ok.size
        return goal + (s[good - 1, 0] if good > 0 else 0.0) * (target - goal)

    def step(self, state, t: float, followed=None, within=None, admissible=None) -> tuple:
        """One control period at ``t`` (s): the reference the robot is given, and why.

        Args:
            state: (:data:`SIZE`,) the shaper's state, changed in place to the next period's.
            followed: (pose, rate, acceleration) (6,) each of the followed reference at ``t``,
                or None (nothing has arrived, or the source failed: the reference comes to
                rest where it is).
            within: :meth:`within` of ``followed`` when already computed (None: computed here,
                when needed). admissible: whether its pose is admissible, when already computed
                (read at the periods that check it).
        Returns:
            ((18,) [pose, rate, acceleration] given at ``t``, flags: 0 when it is the followed
            reference, else :data:`SHAPED_FLAG` with :data:`LIMITED_FLAG`,
            :data:`CLIPPED_FLAG`, :data:`SCALED_FLAG`, :data:`OVER_FLAG` for what bound it).
        """
        k = int(state[self.COUNTER][0])
        state[self.COUNTER] = k + 1
        x, v = state[self.X].copy(), state[self.V].copy()
        zero = np.zeros(6)
        if followed is None:  # from where it is (on the followed reference: where it went)
            state[self.LIMITED] = 0.0
            target = (x, zero, zero)
        else:
            x_f, v_f, a_f = (np.asarray(q, dtype=float).reshape(6) for q in followed)
            if k % self.steps_per_check == 0:
                if admissible is None:
                    admissible = bool(np.asarray(self.limits.admissible(x_f[None, :]))[0])
                state[self.GOAL] = x_f if admissible else self.goal_toward(state[self.GOAL], x_f)
                state[self.LIMITED] = 0.0 if admissible else 1.0
            on_path = state[self.ON_PATH][0] > 0
            if on_path:  # it was on the followed reference: it is where that is now
                x, v = x_f.copy(), v_f.copy()
            limited = state[self.LIMITED][0] > 0
            target = (state[self.GOAL].copy(), zero, zero) if limited else (x_f, v_f, a_f)
            near = on_path or (
                np.max(np.abs(x - x_f)) <= REJOIN_POSE and np.max(np.abs(v - v_f)) <= REJOIN_RATE
            )
            if not limited and near:
                if within is None:
                    within = bool(self.within(x_f, v_f, a_f)[0])
                if within:
                    self._pass(state, x_f, v_f, a_f)
                    count_joined(state[self.RECORD], t)
                    return np.concatenate([x_f, v_f, a_f]), 0
        state[self.ON_PATH] = 0.0
        # Towards the followed reference, once joined, only the robot's limits bound it; the
        # box of the limits bounds the approach, coming to rest and stopping short (teleop's).
        boxed = followed is None or state[self.JOINED][0] == 0 or state[self.LIMITED][0] > 0
        a, what = self._acceleration(x, v, target, boxed)
        what |= self.SHAPED_FLAG | (self.LIMITED_FLAG if state[self.LIMITED][0] > 0 else 0)
        state[self.X] = x + self.h * v + 0.5 * self.h**2 * a
        state[self.V] = v + self.h * a
        count_shaped(
            state[self.RECORD], t, what, None if followed is None else x - target_pose(followed)
        )
        return np.concatenate([x, v, a]), what

    def _pass(self, state, x_f, v_f, a_f) -> None:
        """The state after a period given the followed reference: on it, and where it goes
        at constant acceleration (the start of a shaped period when it next fails)."""
        state[self.ON_PATH] = state[self.JOINED] = 1.0
        state[self.X] = x_f + self.h * v_f + 0.5 * self.h**2 * a_f
        state[self.V] = v_f + self.h * a_f

    def passed(self, state, t: float, count: int, last, goal=None) -> None:
        """``count`` periods from ``t`` (s) given the followed reference as they are (each as
        :meth:`step` would have: on the followed reference, within every limit, its pose
        admissible at each check), ``last`` ((6,) x3) the last of them, ``goal`` the pose of
        the last check among them (None: none)."""
        state[self.COUNTER] += count
        if goal is not None:
            state[self.GOAL] = goal
            state[self.LIMITED] = 0.0
        self._pass(state, *last)
        count_joined(state[self.RECORD], t, count)

    def _acceleration(self, x, v, target, boxed: bool) -> tuple:
        """(a (6,), flags): the filter's acceleration towards ``target`` from pose ``x`` and
        rate ``v``, within every motor's torque and next crank speed and, when ``boxed``, the
        limits' box and the next rate's (at teleop's bandwidth; else at the following one)."""
        x_t, v_t, a_t = target
        w, h = (self._omega if boxed else self._omega_follow), self.h
        wanted = a_t + w * w * (x_t - x) + 2 * w * (v_t - v)
        a = wanted
        if boxed:
            a = np.clip(wanted, -self._acc, self._acc)
            a = np.clip(a, (-self._rate - v) / h, (self._rate - v) / h)
        what = self.CLIPPED_FLAG if np.any(a != wanted) else 0
        zero = np.zeros(6)
        T, speed = self._effort(np.stack([x, x, x]), np.stack([v, v, v + h * a]),
                                np.stack([zero, a, zero]))  # fmt: skip
        s_torque = _largest_scale(T[0], T[1] - T[0], self._torque)
        s_speed = _largest_scale(speed[0], speed[2] - speed[0], self._speed)
        if s_torque is None or s_speed is None or not np.all(np.abs(speed[0]) <= self._speed):
            return zero, what | self.OVER_FLAG
        s = min(s_torque, s_speed)
        if s < 1.0:
            what |= self.SCALED_FLAG
            a = s * a
        return a, what


def target_pose(followed) -> np.ndarray:
    """(6,) the pose of a followed (pose, rate, acceleration)."""
    return np.asarray(followed[0], dtype=float).reshape(6)


def _largest_scale(base, change, limit: float) -> float | None:
    """The largest s in [0, 1] with |base + s change| <= limit on every motor ((6,) each);
    None when even s = 0 is over (or a value is not finite)."""
    if not np.max(np.abs(base)) <= limit:  # also NaN
        return None
    if not math.isfinite(limit) or np.max(np.abs(base + change)) <= limit:
        return 1.0  # within at s = 1, hence at every s between (|.| is convex)
    if not np.all(np.isfinite(change)):
        return None
    bound = np.where(change > 0, limit, -limit)
    moving = change != 0
    return max(0.0, min(1.0, float(np.min((bound[moving] - base[moving]) / change[moving]))))


class ShapedReference:
    """A followed reference shaped for the robot (:func:`shape_followed`): the followed one in
    the periods given as they were, else the shaped pose, rate and acceleration of each period,
    at constant acceleration over it. A :class:`~stewart_drake.references.motion.Reference`.

    Attributes:
        name: the followed reference's, "and shaped". followed: the followed reference.
        end_time: its ``end_time`` (s). period_s: the control period, s.
        record: the :class:`ShapingRecord`. shaped_periods: (m,) the indices k of the shaped
            periods (each [k h, (k + 1) h)). values: (m, 18) their [pose, rate, acceleration]
            at k h.
    """

    def __init__(self, followed, period_s: float, shaped_periods, values, record):
        self.followed, self.period_s = followed, float(period_s)
        self.name = f"{followed.name} and shaped"
        self.end_time = getattr(followed, "end_time", None)
        self.shaped_periods = np.asarray(shaped_periods, dtype=np.int64).reshape(-1)
        self.values = np.asarray(values, dtype=float).reshape(-1, 18)
        self.record = record
        self.stream = getattr(followed, "stream", None)

    def evaluate(self, t):
        """Pose, rate and acceleration at times ``t`` (s, any shape): arrays of shape
        ``np.shape(t) + (6,)``, rad and m, per s, per s^2."""
        t = np.asarray(t, dtype=float)
        shape, flat = t.shape, t.reshape(-1)
        x, v, a = (np.array(q, dtype=float).reshape(-1, 6) for q in self.followed.evaluate(flat))
        if self.shaped_periods.size:
            k = np.floor(flat / self.period_s + 1e-9).astype(np.int64)
            j = np.clip(np.searchsorted(self.shaped_periods, k), 0, self.shaped_periods.size - 1)
            mine = (self.shaped_periods[j] == k) & (flat >= 0)
            if np.any(mine):
                row = self.values[j[mine]]
                tau = (flat[mine] - k[mine] * self.period_s)[:, None]
                a[mine] = row[:, 12:]
                v[mine] = row[:, 6:12] + tau * row[:, 12:]
                x[mine] = row[:, :6] + tau * row[:, 6:12] + 0.5 * tau**2 * row[:, 12:]
        return tuple(q.reshape(shape + (6,)) for q in (x, v, a))


def shape_followed(followed, limits: ShapingLimits, duration_s: float) -> ShapedReference:
    """``followed`` (any Reference, a :class:`~stewart_drake.references.stream.FollowedStream`)
    shaped period by period over [0, ``duration_s``] and a few periods beyond, from its pose at
    rest at t = 0, as :class:`Shaper` shapes it live: the periods where it is on the followed
    reference and within every limit pass in stretches (:meth:`Shaper.passed`), the others are
    stepped one at a time (:meth:`Shaper.step`), with the followed reference's checks computed
    for :data:`SHAPE_CHUNK` periods at once.

    Returns:
        :class:`ShapedReference`.
    Raises:
        InvalidConfigError: a duration not finite and > 0.
    """
    if not (math.isfinite(duration_s) and duration_s > 0):
        raise InvalidConfigError(f"the duration must be > 0 s, got {duration_s!r}")
    shaper = Shaper(limits)
    h, every = shaper.h, shaper.steps_per_check
    n = int(math.ceil(duration_s / h)) + 3
    x0 = np.asarray(followed.evaluate(np.zeros(1))[0], dtype=float).reshape(6)
    state = shaper.initial_state(x0)
    periods, values = [], []
    for start in range(0, n, SHAPE_CHUNK):
        k = np.arange(start, min(start + SHAPE_CHUNK, n))
        t = k * h
        x, v, a = (np.asarray(q, dtype=float).reshape(-1, 6) for q in followed.evaluate(t))
        within = shaper.within(x, v, a)
        check = k % every == 0
        admissible = np.ones(k.size, dtype=bool)
        if np.any(check):
            admissible[check] = np.asarray(limits.admissible(x[check]), dtype=bool)
        passes = within & admissible  # may pass, when on the followed reference
        fails = np.flatnonzero(~passes)
        j = 0
        while j < k.size:
            if state[Shaper.ON_PATH][0] > 0 and state[Shaper.LIMITED][0] == 0 and passes[j]:
                j = _pass_stretch(shaper, state, j, t, (x, v, a), fails, check)
                continue
            out, what = shaper.step(
                state, float(t[j]), (x[j], v[j], a[j]), bool(within[j]),
                bool(admissible[j]) if check[j] else None,
            )  # fmt: skip
            if what:
                periods.append(int(k[j]))
                values.append(out)
            j += 1
    record = shaper.record_of(state)
    return ShapedReference(followed, h, periods, np.array(values).reshape(-1, 18), record)


def _pass_stretch(shaper: Shaper, state, j: int, t, followed, fails, check) -> int:
    """Give the followed reference as it is from period ``j`` of a chunk (times ``t``, the
    followed (pose, rate, acceleration) (n, 6) each) up to the first period after it that may
    not pass (``fails``: their indices, sorted; ``check``: (n,) the periods that check the
    pose); that period's index (n: none in the chunk)."""
    x, v, a = followed
    after = np.searchsorted(fails, j)
    stop = int(fails[after]) if after < fails.size else t.size
    checked = np.flatnonzero(check[j:stop])
    goal = x[j + checked[-1]] if checked.size else None
    shaper.passed(state, float(t[j]), stop - j, (x[stop - 1], v[stop - 1], a[stop - 1]), goal)
    return stop


__all__ = [
    "ShapingLimits",
    "shaping_limits",
    "Shaper",
    "ShapedReference",
    "shape_followed",
    "target_pose",
    "REJOIN_POSE",
    "REJOIN_RATE",
    "EFFORT_SAFETY",
    "FOLLOW_BANDWIDTH_HZ",
    "FOLLOW_OMEGA_H",
    "SHAPE_CHUNK",
]
