"""Task families for the tuner study: references that need adaptation, with seeds.

A fixed weight ratio omega_Q / omega_R is a compromise between moving fast (a stiff loop tracks
the motion) and holding still (a soft loop amplifies less encoder quantization and spends less
feedback torque). These families alternate the two, each deterministic in its seed:

* ``dash_hold``: fast min-jerk dashes (0.3-0.5 s) between random poses, alternating with holds;
* ``disturbed_hold``: slow moves between holds while a tool wrench acts (a push, a twist or a
  contact force, sized to stay within the motors' reach);
* ``surgical``: a slow precise approach, work with tremor-scale motion (8-12 Hz, tens of um and
  tenths of mrad), fast repositioning, repeated;
* ``multisine``: three random sines per axis (0.2-2.5 Hz) inside the workspace;
* ``paper``: the paper manoeuvre (eqs. 37-38; no seed).

:func:`make_task` returns a :class:`Task` (the reference, the disturbance or None, a name). Poses
stay within a box around home (``POSE_BOX``); every reference is checked by the same validator as
any run (workspace, joint cones, singularity, clearance between the parts), and a seed whose draw
is refused is redrawn deterministically. Every task is also within the motors' reach: the
reference's own inverse-dynamics torque (gravity, inertia and velocity products, rotors included:
:func:`~.statics.inverse_dynamics_torques`) stays within ``LOAD_MARGIN`` of the peak torque, the
rest being left to friction and the feedback. A multi-sine is scaled down until it fits; a draw
of the other families that does not fit is redrawn. A reference the motors cannot follow
measures their saturation, not the weights. Ours: the paper trains and tests on one sine family
only.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..base.checks import check_int
from ..base.errors import InvalidConfigError, StewartError
from ..plant.clearance import clearance_model
from ..references.motion import Reference
from ..references.organ.combinators import MotionSum
from ..references.smoothstep import smoothstep
from ..references.trajectories import SineTrajectory, paper_manoeuvre
from ..robot import limits, statics
from ..robot.geometry import StewartGeometry
from ..robot.kinematics import X_HOME
from ..station.station import ToolDisturbance

FAMILIES = ("dash_hold", "disturbed_hold", "surgical", "multisine", "paper")
#: Half-widths of the box around home the tasks' poses stay in: rad (roll, pitch, yaw), m (X, Y, Z).
POSE_BOX = np.array([0.15, 0.15, 0.2, 0.015, 0.015, 0.015])
#: Fraction of the motors' peak torque a task's load may take: the static load (gravity + tool
#: wrench) of ``disturbed_hold``, the reference's inverse-dynamics torque of every family.
LOAD_MARGIN = 0.8
#: Factor a multi-sine's amplitudes shrink by, per try, until the task fits the motors.
SHRINK = 0.85


#: Fade-in and fade-out time of the tremor-scale motions, s.
RAMP_S = 0.05


@dataclass(frozen=True)
class WaypointTrajectory:
    """Min-jerk (quintic) segments through waypoints, plus optional tremor-scale sines.

    Between waypoint k and k + 1 the pose follows x_k + (x_{k+1} - x_k) s(tau), s = 10 tau^3 -
    15 tau^4 + 6 tau^5, tau = (t - t_k) / (t_{k+1} - t_k): rest to rest, continuous acceleration.
    Two equal waypoints are a hold. Before the first and after the last waypoint the pose holds.

    Attributes:
        times: (K,) increasing, s. poses: (K, 6) [rad, m].
        tremor: (M, 6 + 6 + 2) rows [amplitude (6), frequency Hz (6), t_on, t_off]: a sine
            amplitude sin(2 pi f (t - t_on)) added on [t_on, t_off), faded in and out over
            :data:`RAMP_S` by the min-jerk polynomial (continuous acceleration).
        name: label used in result files.
    """

    times: tuple
    poses: tuple
    tremor: tuple = ()
    name: str = "waypoints"

    def evaluate(self, t):
        """Pose, rate, acceleration at times t: three (..., 6) arrays (t scalar gives (6,))."""
        t = np.asarray(t, dtype=float)
        T, X = np.asarray(self.times), np.asarray(self.poses)
        tt = t[..., None]
        k = np.clip(np.searchsorted(T, t, side="right") - 1, 0, len(T) - 2)
        t0, t1 = T[k][..., None], T[k + 1][..., None]
        d = t1 - t0
        s, ds, dds = smoothstep((tt - t0) / d)
        ds, dds = ds / d, dds / d**2
        delta = X[k + 1] - X[k]
        x, v, a = X[k] + delta * s, delta * ds, delta * dds
        for row in self.tremor:
            A, f, on, off = np.asarray(row[:6]), np.asarray(row[6:12]), row[12], row[13]
            w = 2 * np.pi * f
            # Faded in and out over RAMP_S by the min-jerk polynomial: the pose, rate and
            # acceleration stay continuous (a linear fade would put steps in the acceleration).
            q_on, d_on, dd_on = smoothstep((tt - on) / RAMP_S)
            q_off, d_off, dd_off = smoothstep((off - tt) / RAMP_S)
            d_on, d_off = d_on / RAMP_S, -d_off / RAMP_S
            dd_on, dd_off = dd_on / RAMP_S**2, dd_off / RAMP_S**2
            g = q_on * q_off
            dg = d_on * q_off + q_on * d_off
            ddg = dd_on * q_off + 2 * d_on * d_off + q_on * dd_off
            sn, cs = np.sin(w * (tt - on)), np.cos(w * (tt - on))
            x = x + g * A * sn
            v = v + g * A * w * cs + dg * A * sn
            a = a - g * A * w * w * sn + 2 * dg * A * w * cs + ddg * A * sn
        return x, v, a


@dataclass(frozen=True)
class Task:
    """One task: ``reference`` (:class:`~.motion.Reference`), ``disturbance`` (a ToolDisturbance or
    None), ``family`` and ``seed``; ``name`` = "<family>_s<seed>"."""

    family: str
    seed: int
    reference: Reference
    disturbance: ToolDisturbance | None = None

    @property
    def name(self) -> str:
        return self.family if self.family == "paper" else f"{self.family}_s{self.seed}"


def _pose(rng, scale=1.0) -> np.ndarray:
    return X_HOME + scale * rng.uniform(-1, 1, 6) * POSE_BOX


def _holds_and_moves(rng, duration_s, hold_s, move_s, pose_scale=1.0) -> WaypointTrajectory:
    """From home: a hold (duration drawn in ``hold_s``), a move to a random pose (duration drawn
    in ``move_s``, pose box scaled by ``pose_scale``), repeated until ``duration_s``."""
    times, poses, t, x = [0.0], [X_HOME.copy()], 0.0, X_HOME.copy()
    while t < duration_s:
        hold = rng.uniform(*hold_s)
        times.append(t + hold)
        poses.append(x)
        move = rng.uniform(*move_s)
        x = _pose(rng, pose_scale)
        times.append(t + hold + move)
        poses.append(x)
        t += hold + move
    return WaypointTrajectory(tuple(times), tuple(map(tuple, poses)))


def _dash_hold(rng, duration_s):
    return _holds_and_moves(rng, duration_s, (0.5, 1.0), (0.3, 0.5)), None


def _surgical(rng, duration_s):
    times, poses, tremor, t, x = [0.0], [X_HOME.copy()], [], 0.0, X_HOME.copy()
    while t < duration_s:
        approach = rng.uniform(1.5, 2.5)  # slow, precise
        x = x + rng.uniform(-1, 1, 6) * POSE_BOX * 0.3
        x = np.clip(x, X_HOME - POSE_BOX, X_HOME + POSE_BOX)
        times.append(t + approach)
        poses.append(x)
        t += approach
        work = rng.uniform(1.0, 2.0)  # tremor-scale motion while working
        amp = np.zeros(6)
        axes = rng.choice(6, size=2, replace=False)
        amp[axes] = np.where(axes < 3, rng.uniform(2e-4, 8e-4, 2), rng.uniform(5e-5, 1.5e-4, 2))
        tremor.append(tuple(amp) + tuple(rng.uniform(8.0, 12.0, 6)) + (t, t + work))
        times.append(t + work)
        poses.append(x)
        t += work
        reposition = rng.uniform(0.3, 0.4)  # fast
        x = _pose(rng)
        times.append(t + reposition)
        poses.append(x)
        t += reposition
    return WaypointTrajectory(tuple(times), tuple(map(tuple, poses)), tuple(tremor)), None


def _multisine(rng, duration_s, geometry, peak_torque):
    f = rng.uniform(0.2, 2.5, (3, 6))
    phase = rng.uniform(0, 2 * np.pi, (3, 6))
    weights = rng.uniform(0.2, 1.0, (3, 6))
    cap = np.array([30.0, 30.0, 30.0, 3.0, 3.0, 3.0])  # the data collection's acceleration caps
    amp = weights / weights.sum(axis=0) * POSE_BOX
    amp = np.minimum(amp, cap / 3 / (2 * np.pi * f) ** 2)
    for _ in range(20):  # shrink until the motors can follow
        parts = [
            SineTrajectory(
                amplitude=tuple(amp[i]),
                frequency_hz=tuple(f[i]),
                phase=tuple(phase[i]),
                offset=tuple(X_HOME if i == 0 else np.zeros(6)),
            )
            for i in range(3)
        ]
        reference = MotionSum(parts=tuple(parts), centre=None, name="multisine")
        if _within_reach(reference, duration_s, geometry, peak_torque):
            break
        amp = SHRINK * amp
    return reference, None


def _within_reach(reference, duration_s, geometry, peak_torque) -> bool:
    """Whether the reference's inverse-dynamics torque stays within LOAD_MARGIN of the peak."""
    try:
        T = statics.inverse_dynamics_torques(
            geometry, *reference.evaluate(np.arange(0.0, duration_s + 1e-9, 0.005))
        )
    except StewartError:
        return False
    return bool(np.abs(T).max() <= LOAD_MARGIN * peak_torque)


def _disturbed_hold(rng, duration_s, geometry, peak_torque):
    reference = _holds_and_moves(rng, duration_s, (1.0, 2.0), (0.8, 1.2), pose_scale=0.5)
    kind = ("push", "twist", "contact")[rng.integers(3)]
    direction = rng.normal(size=3)
    direction /= np.linalg.norm(direction)
    start = rng.uniform(0.3, 1.0)
    frequency = float(rng.uniform(1.0, 4.0))
    # The largest magnitude whose static load stays within LOAD_MARGIN of the peak torque at
    # every pose of the task: the load is T_g + m T_unit, linear in the magnitude m >= 0.
    unit = np.zeros(6)
    unit[: 3 if kind == "twist" else 6][-3:] = direction
    allowed = np.inf
    for xk in reference.evaluate(np.arange(0.0, duration_s, 0.05))[0]:
        T_g = statics.holding_torques(geometry, xk)
        T_unit = statics.tool_load_torques(geometry, xk, unit) - T_g
        limit = LOAD_MARGIN * peak_torque
        room = np.where(T_unit > 0, limit - T_g, limit + T_g) / np.maximum(np.abs(T_unit), 1e-12)
        allowed = min(allowed, float(room.min()))
    magnitude = float(rng.uniform(0.4, 0.9) * allowed)
    return reference, ToolDisturbance(
        kind=kind,
        magnitude=magnitude,
        direction=list(direction),
        start_s=start,
        frequency_hz=frequency,
    )


def make_task(
    family: str,
    seed: int = 0,
    duration_s: float = 5.0,
    geometry: StewartGeometry | None = None,
    peak_torque_Nm: float = 0.702,
) -> Task:
    """The task of ``family`` drawn from ``seed`` (see the module docstring).

    Args:
        family: one of :data:`FAMILIES`. seed: >= 0. duration_s: s (the reference covers it).
        geometry: the robot (default the reference geometry). peak_torque_Nm: the motors' peak
            torque, N m (sizes the tool wrench of ``disturbed_hold``, bounds every reference's
            inverse-dynamics torque: module docstring).
    Returns:
        :class:`Task` whose reference passes the run's validator over ``duration_s``.
    Raises:
        InvalidConfigError: an unknown family, a negative seed or a non-positive duration.
    """
    if family not in FAMILIES:
        raise InvalidConfigError(f"unknown task family {family!r}; choose one of {FAMILIES}")
    check_int("task seed", seed, 0)
    if not (np.isfinite(duration_s) and duration_s > 0):
        raise InvalidConfigError(f"duration_s must be > 0 s, got {duration_s}")
    geometry = geometry or StewartGeometry()
    if family == "paper":
        return Task(family, 0, paper_manoeuvre())
    t = np.arange(0.0, duration_s + 5e-4, 1e-3)
    for attempt in range(100):  # deterministic redraws of a refused draw
        rng = np.random.default_rng([int(seed), attempt, FAMILIES.index(family)])
        if family == "disturbed_hold":
            reference, disturbance = _disturbed_hold(rng, duration_s, geometry, peak_torque_Nm)
        elif family == "multisine":
            reference, disturbance = _multisine(rng, duration_s, geometry, peak_torque_Nm)
        else:
            reference, disturbance = {"dash_hold": _dash_hold, "surgical": _surgical}[family](
                rng, duration_s
            )
        x, xd, xdd = reference.evaluate(t)
        try:
            report = limits.validate_trajectory(
                geometry,
                t,
                x,
                x_dot=xd,
                x_ddot=xdd,
                raise_refused=False,
                clearance=clearance_model(geometry),
            )
        except StewartError:
            continue
        if report.ok and _within_reach(reference, duration_s, geometry, peak_torque_Nm):
            return Task(family, int(seed), _named(reference, family, seed), disturbance)
    raise InvalidConfigError(f"no valid {family} task in 100 draws from seed {seed}")


def _named(reference, family, seed):
    return reference.__class__(**{**reference.__dict__, "name": f"{family}_s{seed}"})
