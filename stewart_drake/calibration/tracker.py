"""An emulated tracker and the robot's encoders: what a calibration's measurements are made of.

A tracker (a laser tracker with a 6-D probe, an optical tracker with marker frames on the base
and the platform) measures the pose of the platform frame E in the base frame B with noise: the
position off by a Gaussian vector of ``translation_m`` per axis, the orientation turned by a
small rotation exp([delta]x) (delta Gaussian, ``rotation_rad`` per axis, base frame). At each
pose the six encoders read each crank's angle plus its zero offset, quantized to the encoder's
counts (:class:`~stewart_drake.station.hardware.Encoders`: 2^17 per revolution, a quantum of
47.9 urad, an RMS error of 13.8 urad).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from ..base.checks import as_number, as_poses, check_int
from ..base.errors import InvalidConfigError
from ..robot.geometry import StewartGeometry
from ..robot.kinematics import rotation_rpy
from ..robot.legs import LegParameters, readings
from ..station.hardware import Encoders

#: Counts per revolution of the robot's encoders (the ``hardware.encoders`` default).
COUNTS_PER_REV = Encoders().counts_per_rev


@dataclass(frozen=True)
class MeasurementNoise:
    """The noise a calibration's measurements carry.

    Attributes:
        translation_m: standard deviation of the tracker's position per axis, m.
        rotation_rad: standard deviation of the tracker's small rotation per axis, rad.
        counts_per_rev: the encoders' counts per revolution; their quantum 2 pi / counts
            leaves an error uniform over one count (RMS quantum / sqrt(12)).
    Raises:
        InvalidConfigError: a negative or non-finite deviation, or fewer than 2 counts.
    """

    translation_m: float = 5e-6
    rotation_rad: float = 20e-6
    counts_per_rev: int = COUNTS_PER_REV

    def __post_init__(self):
        for name in ("translation_m", "rotation_rad"):
            object.__setattr__(self, name, as_number(f"noise {name}", getattr(self, name), 0.0))
        object.__setattr__(
            self, "counts_per_rev", check_int("counts_per_rev", self.counts_per_rev, 2, 2**40)
        )

    @property
    def quantum_rad(self) -> float:
        """One count, rad."""
        return 2.0 * np.pi / self.counts_per_rev

    @property
    def quantization_rms_rad(self) -> float:
        """RMS error of a quantized reading, quantum / sqrt(12), rad."""
        return self.quantum_rad / np.sqrt(12.0)

    def words(self) -> str:
        """e.g. "5 um / 20 urad, 17-bit encoders"."""
        bits = np.log2(self.counts_per_rev)
        enc = f"{bits:.0f}-bit" if bits == round(bits) else f"{self.counts_per_rev}-count"
        return (
            f"{self.translation_m * 1e6:.3g} um / {self.rotation_rad * 1e6:.3g} urad, "
            f"{enc} encoders"
        )


def noisy_poses(x, noise: MeasurementNoise, rng: np.random.Generator) -> np.ndarray:
    """The tracker's measurement of poses x (N, 6): each turned by exp([delta]x) and shifted
    (module docstring); (N, 6) [rad, m], roll-pitch-yaw as
    :func:`~stewart_drake.robot.kinematics.rotation_rpy`."""
    x = as_poses("pose x", x).reshape(-1, 6)
    delta = rng.normal(0.0, noise.rotation_rad, (len(x), 3))
    R = Rotation.from_rotvec(delta).as_matrix() @ rotation_rpy(x[:, :3])
    rpy = Rotation.from_matrix(R).as_euler("ZYX")[:, ::-1]
    return np.column_stack([rpy, x[:, 3:] + rng.normal(0.0, noise.translation_m, (len(x), 3))])


def quantize(angles, counts_per_rev: int) -> np.ndarray:
    """Angles (rad) as an absolute encoder of ``counts_per_rev`` reads them: the nearest count,
    rad."""
    quantum = 2.0 * np.pi / counts_per_rev
    return np.round(np.asarray(angles, dtype=float) / quantum) * quantum


@dataclass(frozen=True)
class Measurements:
    """Poses measured by a tracker with the encoder readings there.

    Attributes:
        poses: (N, 6) the platform's pose [phi, theta, psi, X, Y, Z] as measured, rad and m.
        readings: (N, 6) the encoders' readings q0..q5, rad.
        true_poses: (N, 6) the poses as they were (an emulation knows them), or None.
    """

    poses: np.ndarray
    readings: np.ndarray
    true_poses: np.ndarray | None = None


def measure(
    geometry: StewartGeometry,
    legs: LegParameters,
    x,
    noise: MeasurementNoise,
    seed: int,
) -> Measurements:
    """Emulate measuring the robot ``legs`` at poses x (N, 6): the tracker's noisy poses and
    the quantized readings (offsets included) at the true ones.

    Raises:
        UnreachablePoseError: the robot as built cannot close a leg at a pose.
        InvalidConfigError: x not (N, 6) or not finite, a seed out of 0 .. 2^32 - 1.
    """
    rng = np.random.default_rng(check_int("seed", seed, 0, 2**32 - 1))
    x = as_poses("pose x", x).reshape(-1, 6)
    q = quantize(readings(geometry, legs, x), noise.counts_per_rev)
    return Measurements(poses=noisy_poses(x, noise, rng), readings=q, true_poses=x.copy())


#: The emulated tracker's sampling rate, Hz.
TRACKER_RATE_HZ = 50.0


def track(t, x, noise: MeasurementNoise, seed: int, rate_hz: float = TRACKER_RATE_HZ):
    """Emulate a tracker following the platform: the poses x (n, >= 6) at times t (n,) s
    (increasing: a plant's record of its true pose), sampled every 1 / ``rate_hz`` s from t[0]
    (each sample the last pose recorded at or before its time), each with the tracker's noise
    (:func:`noisy_poses`).

    Returns:
        (times (m,) s, poses (m, 6) rad and m).
    Raises:
        InvalidConfigError: a seed out of range, a rate not > 0, fewer than 2 records.
    """
    rng = np.random.default_rng(check_int("seed", seed, 0, 2**32 - 1))
    rate_hz = as_number("rate_hz", rate_hz, 0.0, lo_open=True)
    t = np.asarray(t, dtype=float).reshape(-1)
    x = np.asarray(x, dtype=float).reshape(len(t), -1)[:, :6]
    if len(t) < 2:
        raise InvalidConfigError(f"a tracker needs at least 2 records of the pose, got {len(t)}")
    times = np.arange(t[0], t[-1], 1.0 / rate_hz)
    index = np.searchsorted(t, times, side="right") - 1
    return times, noisy_poses(x[index], noise, rng)
