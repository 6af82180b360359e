"""A known motion for registering a tracker to the robot (:class:`RegistrationMotion`): measured
once, the tracker's frame and its marker's offset on the platform are fitted to it and kept,
and every later measured motion is judged in them (``stewart-drake calibrate --register``).

The way hexapod makers register an external tracker: a motion that moves along and turns about
every axis, so that no part of the frames is left undetermined. Ours: a cosine on each of the
six axes, each at its own period (translations 3, 4 and 5 s, rotations 6, 10 and 12 s: no two
alike, so that the fit tells every axis apart; together they repeat every 60 s), starting at
rest (each cosine at its trough with zero rate).
"""

import math
from dataclasses import dataclass

import numpy as np

from ...base.checks import as_number
from ...robot.geometry import X_HOME
from .core import LibraryMotion, check_centre

#: The periods of the cosines on [phi, theta, psi, X, Y, Z], s.
REGISTRATION_PERIODS_S = (6.0, 10.0, 12.0, 3.0, 4.0, 5.0)


@dataclass(frozen=True)
class RegistrationMotion(LibraryMotion):
    """A cosine on each of the six axes at the periods of :data:`REGISTRATION_PERIODS_S`:
    d_k(t) = -a_k / 2 cos(2 pi t / T_k) about ``centre`` (module docstring; ours, for
    registering a tracker, not an organ's motion).

    Attributes:
        amplitude_m: peak to peak of each translation, m; default 0.006 (within the reference
            robot's workspace about home with the rotations below).
        tilt_rad: peak to peak of each rotation, rad; default 2 deg (a marker 50 mm from the
            platform's axis moves 1.7 mm: its offset is well determined).
        centre: (6,) the pose the motion is centred on, rad and m; default home.
    """

    amplitude_m: float = 0.006
    tilt_rad: float = math.radians(2.0)
    centre: tuple = tuple(X_HOME)
    name: str = "registration"

    def __post_init__(self):
        _set = object.__setattr__
        _set(self, "amplitude_m", as_number(f"{self.name}: amplitude_m", self.amplitude_m, 0.0))
        _set(self, "tilt_rad", as_number(f"{self.name}: tilt_rad", self.tilt_rad, 0.0, math.pi / 4))
        _set(self, "centre", check_centre(self.name, self.centre))

    def displacement(self, t):
        """(n, 6) displacement, rate, acceleration from the centre at times t (n,)."""
        t = np.asarray(t, dtype=float)[:, None]
        w = 2 * math.pi / np.asarray(REGISTRATION_PERIODS_S)
        a = 0.5 * np.array([self.tilt_rad] * 3 + [self.amplitude_m] * 3)
        return -a * np.cos(w * t), a * w * np.sin(w * t), a * w * w * np.cos(w * t)

    @property
    def period_s(self) -> float:
        """The time after which every cosine has come round, s (60)."""
        return 60.0


__all__ = ["REGISTRATION_PERIODS_S", "RegistrationMotion"]
