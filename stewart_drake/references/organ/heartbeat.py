"""Cardiac motion: a fundamental at the heart rate and its harmonics (:class:`Heartbeat`)."""

from dataclasses import dataclass

import numpy as np

from ...base.checks import as_array, as_number
from ...base.errors import InvalidConfigError
from ...robot.geometry import X_HOME
from .core import LibraryMotion, along, check_centre, unit_direction

#: Bound on the size of a heartbeat's largest relative harmonic amplitude, and its inverse
#: (their ratios are what matter).
MAX_RELATIVE_HARMONIC = 1e6
#: Relative amplitudes of the heartbeat's harmonics by default (ours; see :class:`Heartbeat`).
HEARTBEAT_HARMONICS = (1.0, 0.5, 0.25)


@dataclass(frozen=True)
class Heartbeat(LibraryMotion):
    """Cardiac motion: a fundamental at the heart rate and its harmonics.

    d(t) = amplitude_m / p2p * sum_k a_k sin(2 pi k f t + phi_k) along ``direction``, with
    f = rate_bpm / 60 and p2p the peak to peak of the sum (so ``amplitude_m`` is the peak to
    peak of the motion).

    Attributes:
        amplitude_m: peak to peak, m; default 0.002 (Seppenwoolde et al., IJROBP 53, 822, 2002:
            a cardiac component of 1-4 mm in lung tumours near the heart).
        rate_bpm: beats per minute; default 72 (a resting adult).
        harmonics: relative amplitudes a_1, a_2, ... of the fundamental and its harmonics;
            default (1, 0.5, 0.25): ours, a beat sharper than a sine (Seppenwoolde et al. give
            the amplitude, not the shape).
        harmonic_phases_rad: phi_k, rad (as many as harmonics; default zeros).
        direction: unit vector or axis name; default "LR" (the platform's Y; Seppenwoolde et
            al. found the cardiac component mostly left-right).
        centre: (6,) pose, rad and m; default home.
    """

    amplitude_m: float = 0.002
    rate_bpm: float = 72.0
    harmonics: tuple = HEARTBEAT_HARMONICS
    harmonic_phases_rad: tuple = ()
    direction: tuple | str = "LR"
    centre: tuple = tuple(X_HOME)
    name: str = "heartbeat"

    def __post_init__(self):
        _set = object.__setattr__
        _set(self, "amplitude_m", as_number(f"{self.name}: amplitude_m", self.amplitude_m, 0.0))
        _set(self, "rate_bpm", as_number(f"{self.name}: rate_bpm", self.rate_bpm, 1.0, 600.0))
        a = as_array(f"{self.name}: harmonics", self.harmonics).reshape(-1)
        if a.size < 1 or a.size > 20 or not np.any(a != 0):
            raise InvalidConfigError(
                f"{self.name}: harmonics needs 1 to 20 relative "
                f"amplitudes, not all zero, got {self.harmonics!r}"
            )
        if not 1.0 / MAX_RELATIVE_HARMONIC <= np.max(np.abs(a)) <= MAX_RELATIVE_HARMONIC:
            # Only their ratios matter (the sum is scaled to amplitude_m); beyond these the
            # acceleration's sums overflow float64, or the scale dividing by their peak to peak.
            raise InvalidConfigError(
                f"{self.name}: harmonics are relative amplitudes, the largest between "
                f"{1.0 / MAX_RELATIVE_HARMONIC:g} and {MAX_RELATIVE_HARMONIC:g} in size, got "
                f"{self.harmonics!r}: divide them by the largest"
            )
        phases = (
            np.zeros(a.size)
            if len(self.harmonic_phases_rad) == 0
            else as_array(
                f"{self.name}: harmonic_phases_rad", self.harmonic_phases_rad, shape=(a.size,)
            )
        )
        _set(self, "harmonics", tuple(float(v) for v in a))
        _set(self, "harmonic_phases_rad", tuple(float(v) for v in phases))
        _set(self, "direction", unit_direction(f"{self.name}: direction", self.direction))
        _set(self, "centre", check_centre(self.name, self.centre))
        _set(self, "_p2p", self._peak_to_peak())

    @property
    def frequency_hz(self) -> float:
        return self.rate_bpm / 60.0

    @property
    def period_s(self) -> float:
        return 60.0 / self.rate_bpm

    def _unit(self, t):
        f, k = self.frequency_hz, np.arange(1, len(self.harmonics) + 1)
        arg = 2 * np.pi * f * np.asarray(t, dtype=float)[:, None] * k + np.asarray(
            self.harmonic_phases_rad
        )
        w = 2 * np.pi * f * k
        a = np.asarray(self.harmonics)
        return (np.sin(arg) @ a, np.cos(arg) @ (a * w), -np.sin(arg) @ (a * w * w))

    def _peak_to_peak(self) -> float:
        s = self._unit(np.linspace(0.0, self.period_s, 4001))[0]
        return float(s.max() - s.min())

    def displacement(self, t):
        """(n, 6) displacement, rate, acceleration from the centre at times t (n,)."""
        scale = self.amplitude_m / self._p2p
        s, ds, dds = self._unit(t)
        return along(np.asarray(self.direction) * scale, s, ds, dds)

    def frequencies_hz(self) -> dict:
        return {"cardiac": self.frequency_hz}


__all__ = ["Heartbeat", "HEARTBEAT_HARMONICS", "MAX_RELATIVE_HARMONIC"]
