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
            v = np.asarray(getattr(self, attr), dtype=float)
            if v.shape != (6,) or not np.all(np.isfinite(v)):
                raise InvalidConfigError(f"{self.name}: {attr} needs 6 finite values, got {v}")
            object.__setattr__(self, attr, tuple(float(c) for c in v))

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

    Output port: ``x_d`` (18,) = [pose (6,), rate (6,), acceleration (6,)] at the context time.
    """

    def __init__(self, trajectory):
        super().__init__()
        self.trajectory = trajectory
        self.DeclareVectorOutputPort("x_d", 18, self._Calc,
                                     prerequisites_of_calc={self.time_ticket()})

    def _Calc(self, context, output: BasicVector):
        x, x_dot, x_ddot = self.trajectory.evaluate(context.get_time())
        output.SetFromVector(np.concatenate([x, x_dot, x_ddot]))
