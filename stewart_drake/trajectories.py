"""Reference trajectories x_d(t) of the platform pose and their validation before a run.

A trajectory maps times t (N,) in s to pose, rate and acceleration, each (N, 6) in
[rad, rad, rad, m, m, m] (and /s, /s^2). :class:`ReferenceSource` puts one into a Diagram.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from pydrake.systems.framework import BasicVector, LeafSystem

from . import kinematics
from .errors import InvalidConfigError
from .geometry import X_HOME, StewartGeometry
from .validation import as_array, check_sine_bounds


@dataclass(frozen=True)
class SineTrajectory:
    """x_d(t) = offset + amplitude * sin(2 pi f t + phase), axis by axis.

    Attributes:
        amplitude: (6,) in rad and m.  frequency_hz: (6,) in Hz.  phase: (6,) in rad.
        offset: (6,) centre pose (default home).  name: label used in result files.
    """

    amplitude: tuple = (0.0,) * 6
    frequency_hz: tuple = (0.0,) * 6
    phase: tuple = (0.0,) * 6
    offset: tuple = tuple(X_HOME)
    name: str = "sine"

    def __post_init__(self):
        for attr in ("amplitude", "frequency_hz", "phase", "offset"):
            v = as_array(f"{self.name}: {attr}", getattr(self, attr), shape=(6,))
            object.__setattr__(self, attr, tuple(float(c) for c in v))
        check_sine_bounds(self)

    def evaluate(self, t):
        """Pose, rate, acceleration at times t: three (..., 6) arrays (t scalar gives (6,))."""
        t = np.asarray(t, dtype=float)[..., None]
        A, w = np.asarray(self.amplitude), 2 * np.pi * np.asarray(self.frequency_hz)
        arg = w * t + np.asarray(self.phase)
        s, c = np.sin(arg), np.cos(arg)
        return np.asarray(self.offset) + A * s, A * w * c, -A * w * w * s


def paper_manoeuvre() -> SineTrajectory:
    """Paper eqs. 37-38: phi = (pi/6) sin 2t rad, Z = 0.05 sin 2t + 0.30 m, others 0."""
    f = 2.0 / (2 * np.pi)
    return SineTrajectory(amplitude=(np.pi / 6, 0, 0, 0, 0, 0.05), frequency_hz=(f, 0, 0, 0, 0, f),
                          name="paper")


def hold_home() -> SineTrajectory:
    """Stay at the home pose."""
    return SineTrajectory(name="home")


TRAJECTORIES = {"paper": paper_manoeuvre, "home": hold_home}


def make_trajectory(name: str):
    """A trajectory by name ("paper", "home").

    Raises:
        InvalidConfigError: unknown name (the message lists the known ones).
    """
    try:
        return TRAJECTORIES[name]()
    except KeyError:
        raise InvalidConfigError(
            f"unknown trajectory {name!r}; choose one of {sorted(TRAJECTORIES)}") from None


def validate_trajectory(geometry: StewartGeometry, trajectory, duration_s: float,
                        dt: float = 1e-3) -> dict:
    """Check that every sample of the trajectory on [0, duration_s] is reachable.

    Returns:
        dict with ``max_ratio`` (largest |L|/sqrt(M^2+N^2) over legs and time), ``t_max_ratio``
        and ``leg_max_ratio``.
    Raises:
        UnreachablePoseError: naming the first time and leg that cannot close.
        InvalidConfigError: non-positive duration or a non-finite sample.
    """
    if not (np.isfinite(duration_s) and duration_s > 0):
        raise InvalidConfigError(f"duration must be > 0 s, got {duration_s}")
    t = np.arange(0.0, duration_s + 0.5 * dt, dt)
    x, x_dot, x_ddot = trajectory.evaluate(t)
    for name, arr in (("pose", x), ("rate", x_dot), ("acceleration", x_ddot)):
        if not np.all(np.isfinite(arr)):
            k = int(np.argmax(~np.all(np.isfinite(arr), axis=1)))
            raise InvalidConfigError(f"trajectory {name} is not finite at t = {t[k]:.4g} s")
    kinematics.ik(geometry, x, t=t)              # raises at the first unreachable sample
    ratio = np.abs(kinematics.leg_reach_ratio(geometry, x))
    k, leg = np.unravel_index(int(np.argmax(ratio)), ratio.shape)
    return {"max_ratio": float(ratio[k, leg]), "t_max_ratio": float(t[k]), "leg_max_ratio": int(leg)}


class ReferenceSource(LeafSystem):
    """A trajectory as a Drake source.

    Output port: ``x_d`` (18,) = [pose (6,), rate (6,), acceleration (6,)] at context time
    t + ``lead_s``.

    Args:
        trajectory: any object with ``evaluate(t)`` (see module docstring).
        lead_s: evaluate ahead of the context time, s. A discrete MultibodyPlant stores, from
            its update at t_n on, the configuration of physical time t_n + h; a controller
            sampling at t_n + h/2 must compare it with x_d(t_n + h), i.e. lead by h/2.
    """

    def __init__(self, trajectory, lead_s: float = 0.0):
        super().__init__()
        self.trajectory = trajectory
        self.lead_s = float(lead_s)
        self.DeclareVectorOutputPort("x_d", 18, self._Calc,
                                     prerequisites_of_calc={self.time_ticket()})

    def _Calc(self, context, output: BasicVector):
        x, x_dot, x_ddot = self.trajectory.evaluate(context.get_time() + self.lead_s)
        output.SetFromVector(np.concatenate([x, x_dot, x_ddot]))


#: Acceleration caps of the data-collection trajectories: rad/s^2 for angles, m/s^2 for positions.
DATA_ACCEL_CAP = (30.0, 30.0, 30.0, 3.0, 3.0, 3.0)
#: Amplitudes the paper names for its data (angles +-pi/6 rad, translations 0.3 m).
PAPER_DATA_AMPLITUDE = (np.pi / 6, np.pi / 6, np.pi / 6, 0.3, 0.3, 0.3)


def _max_single_axis_amplitude(geometry: StewartGeometry, axis: int, ratio_max: float) -> float:
    """Largest a with home +- a e_axis reachable at ratio <= ratio_max (bisection)."""
    lo, hi = 0.0, PAPER_DATA_AMPLITUDE[axis]
    for _ in range(40):
        mid = 0.5 * (lo + hi)
        x = np.tile(X_HOME, (2, 1))
        x[0, axis] += mid
        x[1, axis] -= mid
        if np.all(np.abs(kinematics.leg_reach_ratio(geometry, x)) <= ratio_max):
            lo = mid
        else:
            hi = mid
    return lo


def data_collection_trajectory(seed: int = 0, geometry: StewartGeometry | None = None,
                               duration_s: float = 10.0, ratio_max: float = 0.9) -> SineTrajectory:
    """Excitation for the tuner's training data (paper section III.D), deterministic in ``seed``.

    Every axis moves at once, one sine each, with a frequency drawn in [1, 5] Hz and a random
    phase. The paper's amplitudes (+-pi/6 rad, 0.3 m) are far outside this robot's workspace, so
    each axis's amplitude is (a) capped by what that axis alone admits at |L|/sqrt(M^2+N^2) <=
    ``ratio_max``, (b) capped by DATA_ACCEL_CAP / (2 pi f)^2 so the torques stay physical, then
    (c) all amplitudes are scaled by one factor until the whole trajectory stays below
    ``ratio_max`` over ``duration_s`` (docs/paper_notes.md).

    Returns:
        SineTrajectory named ``data_seed<seed>``.
    """
    geometry = geometry or StewartGeometry()
    rng = np.random.default_rng(seed)
    f = rng.uniform(1.0, 5.0, 6)
    phase = rng.uniform(0, 2 * np.pi, 6)
    single = np.array([_max_single_axis_amplitude(geometry, k, ratio_max) for k in range(6)])
    amp = np.minimum(single, np.asarray(DATA_ACCEL_CAP) / (2 * np.pi * f) ** 2)
    t = np.arange(0.0, duration_s, 1e-3)

    def fits(scale):
        traj = SineTrajectory(amplitude=tuple(scale * amp), frequency_hz=tuple(f),
                              phase=tuple(phase))
        ratio = np.abs(kinematics.leg_reach_ratio(geometry, traj.evaluate(t)[0]))
        return np.all(ratio <= ratio_max)

    lo, hi = 0.0, 1.0
    if fits(1.0):
        lo = 1.0
    else:
        for _ in range(30):
            mid = 0.5 * (lo + hi)
            lo, hi = (mid, hi) if fits(mid) else (lo, mid)
    return SineTrajectory(amplitude=tuple(lo * amp), frequency_hz=tuple(f), phase=tuple(phase),
                          name=f"data_seed{seed}")
