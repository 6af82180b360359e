"""A reference made of a few sines per axis, whose every figure has a closed form: the unit tests
of ``stewart-drake verify``'s modules (tests/test_alignment.py, test_measured_verdict.py,
test_verification.py, test_registration_motion.py) hold their numbers to it instead of to the
library's motions."""

import math
from dataclasses import dataclass

import numpy as np

from stewart_drake.base.errors import InvalidConfigError


@dataclass(frozen=True)
class Harmonics:
    """x(t) = centre + sum_j amplitude[j] sin(2 pi (j + 1) t / period_s + phase[j]), rad and m.

    Attributes:
        amplitude: (J, 6) the amplitude of harmonic j + 1 on each axis, rad and m.
        period_s: the fundamental's period, s.
        phase: (J,) rad, one per harmonic (None: zeros).
        centre: (6,) the pose it moves about.
        periodic: whether it says so (``repeat_period_s``, ``cycles``, ``frequencies_hz``), as a
            library motion does; without, it is a motion without cycles (a trace's).
        end_time: its last time, s, or None.
    """

    amplitude: tuple
    period_s: float = 4.0
    phase: tuple | None = None
    centre: tuple = (0.0,) * 6
    periodic: bool = True
    end_time: float | None = None
    name: str = "harmonics"

    @property
    def repeat_period_s(self) -> float | None:
        return self.period_s if self.periodic else None

    def cycles(self, t_end: float):
        if not self.periodic:
            raise InvalidConfigError(f"{self.name} does not repeat: it has no cycles")
        k = max(1, math.ceil(t_end / self.period_s - 1e-9))
        return np.arange(k + 1) * self.period_s, np.ones(k)

    def frequencies_hz(self) -> dict:
        return {"breathing": 1.0 / self.period_s}

    def evaluate(self, t):
        """(x, rate, acceleration), each (..., 6), at the times t (any shape), s."""
        t = np.asarray(t, dtype=float)[..., None]
        x = np.broadcast_to(np.asarray(self.centre, float), t.shape[:-1] + (6,)).copy()
        v, a = np.zeros_like(x), np.zeros_like(x)
        amplitude = np.atleast_2d(np.asarray(self.amplitude, dtype=float))
        phases = np.zeros(len(amplitude)) if self.phase is None else self.phase
        for j, (amp, phase) in enumerate(zip(amplitude, phases, strict=True)):
            w = 2 * np.pi * (j + 1) / self.period_s
            s, c = np.sin(w * t + phase), np.cos(w * t + phase)
            x += amp * s
            v += amp * w * c
            a -= amp * w * w * s
        return x, v, a


def along(axis: str, amplitude: float, *harmonics: float) -> tuple:
    """(J, 6) amplitudes on one axis ("phi" .. "Z"): the fundamental's, then the others'."""
    k = ("phi", "theta", "psi", "X", "Y", "Z").index(axis)
    rows = np.zeros((1 + len(harmonics), 6))
    rows[:, k] = (amplitude, *harmonics)
    return tuple(map(tuple, rows))


def rpy_matrix(rpy) -> np.ndarray:
    """(..., 3, 3) R = Rz(psi) Ry(theta) Rx(phi) of roll, pitch, yaw (..., 3), rad, written out
    here (not the package's) so that the tests' frames do not lean on the code they check."""
    rpy = np.asarray(rpy, dtype=float)
    cr, sr = np.cos(rpy[..., 0]), np.sin(rpy[..., 0])
    cp, sp = np.cos(rpy[..., 1]), np.sin(rpy[..., 1])
    cy, sy = np.cos(rpy[..., 2]), np.sin(rpy[..., 2])
    return np.stack(
        [
            np.stack([cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr], axis=-1),
            np.stack([sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr], axis=-1),
            np.stack([-sp, cp * sr, cp * cr], axis=-1),
        ],
        axis=-2,
    )
