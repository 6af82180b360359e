"""An emulated tracker and the robot's encoders: what a calibration's measurements are made of.

A tracker (a laser tracker with a 6-D probe, an optical tracker with marker frames on the base
and the platform) measures the pose of the platform frame E in the base frame B with noise: the
position off by a Gaussian vector of ``translation_m`` per axis, the orientation turned by a
small rotation exp([delta]x) (delta Gaussian, ``rotation_rad`` per axis, base frame). Set up
as a real one stands (:class:`TrackerSetup`), it measures its marker M in its own frame T
instead (X_TM = X_TB X_BE X_EM, the noise in T), and the fiducials that register T and M to the
robot (:meth:`TrackerSetup.fiducials`, :mod:`~.registration`). At each
pose the six encoders read each crank's angle plus its zero offset, quantized to the encoder's
counts (:class:`~stewart_drake.station.hardware.Encoders`: 2^17 per revolution, a quantum of
47.9 urad, an RMS error of 13.8 urad).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from pydrake.common.eigen_geometry import AngleAxis
from pydrake.math import RigidTransform, RollPitchYaw, RotationMatrix
from scipy.spatial.transform import Rotation

from ..base.checks import as_number, as_poses, check_int
from ..base.errors import InvalidConfigError
from ..robot.geometry import StewartGeometry
from ..robot.kinematics import rotation_rpy
from ..robot.legs import LegParameters, readings
from ..station.hardware import Encoders
from .registration import DEFAULT_POINT_SIGMA_M, Fiducials, Registration

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


#: The platform's home pose, where :meth:`TrackerSetup.fiducials` measures the platform's.
HOME_POSE = (0.0, 0.0, 0.0, 0.0, 0.0, 0.30)


#: Samples of the marker's pose averaged when the platform's fiducials are measured (2 s of a
#: 50 Hz tracker, the platform at rest).
MARKER_SAMPLES = 100
#: The noise a REG.yaml states for fiducials emulated without any (it must be > 0), m.
_LEAST_SIGMA_M = 1e-9


@dataclass(frozen=True)
class TrackerSetup:
    """Where an emulated tracker stands and what it sees besides the platform.

    Attributes:
        X_TB: the base frame B in the tracker's frame T.
        X_PM: the tracker's marker M in the platform frame P (E).
        base_B: (n, 3) the base's fiducials in B, m (where the drawing puts them).
        platform_P: (m, 3) the platform's fiducials in P, m, or None (the marker is then
            registered as P itself: X_PM should be the identity).
    """

    X_TB: RigidTransform
    X_PM: RigidTransform
    base_B: np.ndarray
    platform_P: np.ndarray | None = None

    def registration(self) -> Registration:
        """The setup's exact frames, as a :class:`~.registration.Registration` without error."""
        zero = np.zeros((6, 6))
        return Registration(self.X_TB, self.X_PM, zero, zero, 0.0, 0.0)

    def tracker_poses(self, x) -> np.ndarray:
        """(N, 6) the marker's poses in T, exactly, at the platform's poses x (N, 6) in B."""
        return self.registration().tracker_poses(x)

    def fiducials(
        self,
        noise: MeasurementNoise,
        seed: int,
        point_sigma_m: float = DEFAULT_POINT_SIGMA_M,
        pose=HOME_POSE,
        marker_samples: int = MARKER_SAMPLES,
    ) -> Fiducials:
        """The fiducials as the tracker measures them (what REG.yaml holds): each with a
        Gaussian error of ``point_sigma_m`` per axis; the platform's with the platform at
        ``pose`` (6,) in B, the marker's pose then the mean of ``marker_samples`` samples with
        the tracker's ``noise`` (its noise divided by sqrt(marker_samples), as REG.yaml says).

        Raises:
            InvalidConfigError: a seed out of 0 .. 2^32 - 1, a sigma not finite and >= 0,
                fewer than 1 sample.
        """
        rng = np.random.default_rng(check_int("seed", seed, 0, 2**32 - 1))
        sigma = as_number("point_sigma_m", point_sigma_m, 0.0)
        root = np.sqrt(check_int("marker_samples", marker_samples, 1, 10**9))
        mean_noise = MeasurementNoise(
            noise.translation_m / root, noise.rotation_rad / root, noise.counts_per_rev
        )

        def seen(X_TR, points):
            p = np.asarray(points, dtype=float).reshape(-1, 3)
            return X_TR.multiply(p.T).T + rng.normal(0.0, sigma, p.shape)

        base_T = seen(self.X_TB, self.base_B)
        if self.platform_P is None:
            return Fiducials(self.base_B.copy(), base_T, point_sigma_m=max(sigma, _LEAST_SIGMA_M))
        x = as_poses("pose", pose).reshape(6)
        X_TP = self.X_TB @ RigidTransform(RollPitchYaw(x[:3]), x[3:])
        marker = noisy_poses(self.tracker_poses(x), mean_noise, rng)[0]
        return Fiducials(
            self.base_B.copy(),
            base_T,
            self.platform_P.copy(),
            seen(X_TP, self.platform_P),
            marker,
            max(sigma, _LEAST_SIGMA_M),
            (mean_noise.rotation_rad, mean_noise.translation_m),
        )


def emulated_setup(
    geometry: StewartGeometry,
    distance_m: float = 1.0,
    angle_deg: float = 30.0,
    marker_offset_m: float = 0.05,
    marker_angle_deg: float = 10.0,
) -> TrackerSetup:
    """A tracker ``distance_m`` from the base's origin, its frame turned ``angle_deg`` about an
    oblique axis; a marker ``marker_offset_m`` from the platform frame's origin, turned
    ``marker_angle_deg``; four fiducials on the base (outside the pivots, 10 mm below them)
    and four on the platform plate (at 0.9 of its radius, 10 mm above P).
    """
    axis = np.array([1.0, -2.0, 3.0]) / np.sqrt(14.0)
    direction = np.array([2.0, 1.0, 0.5]) / np.sqrt(5.25)
    X_TB = RigidTransform(
        RotationMatrix(AngleAxis(np.radians(angle_deg), axis)), distance_m * direction
    )
    offset = np.array([1.0, 1.0, 0.5]) / 1.5
    X_PM = RigidTransform(
        RotationMatrix(AngleAxis(np.radians(marker_angle_deg), np.array([0.0, 0.6, 0.8]))),
        marker_offset_m * offset,
    )
    a = np.radians([20.0, 100.0, 200.0, 290.0])
    r_b = 1.1 * geometry.base_radius
    base = np.column_stack([r_b * np.cos(a), r_b * np.sin(a), np.full(4, geometry.pivot_z - 0.01)])
    r_p = 0.9 * geometry.platform_plate_radius
    b = np.radians([45.0, 135.0, 225.0, 315.0])
    platform = np.column_stack([r_p * np.cos(b), r_p * np.sin(b), np.full(4, 0.01)])
    return TrackerSetup(X_TB, X_PM, base, platform)


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
    setup: TrackerSetup | None = None,
) -> Measurements:
    """Emulate measuring the robot ``legs`` at poses x (N, 6): the tracker's noisy poses and
    the quantized readings (offsets included) at the true ones. With a ``setup``, the poses
    measured are the marker's in the tracker's frame (:meth:`TrackerSetup.tracker_poses`),
    the noise in that frame; ``true_poses`` stay the platform's in B.

    Raises:
        UnreachablePoseError: the robot as built cannot close a leg at a pose.
        InvalidConfigError: x not (N, 6) or not finite, a seed out of 0 .. 2^32 - 1.
    """
    rng = np.random.default_rng(check_int("seed", seed, 0, 2**32 - 1))
    x = as_poses("pose x", x).reshape(-1, 6)
    q = quantize(readings(geometry, legs, x), noise.counts_per_rev)
    seen = x if setup is None else setup.tracker_poses(x)
    return Measurements(poses=noisy_poses(seen, noise, rng), readings=q, true_poses=x.copy())


#: The emulated tracker's sampling rate, Hz.
TRACKER_RATE_HZ = 50.0


def track(
    t,
    x,
    noise: MeasurementNoise,
    seed: int,
    rate_hz: float = TRACKER_RATE_HZ,
    setup: TrackerSetup | None = None,
):
    """Emulate a tracker following the platform: the poses x (n, >= 6) at times t (n,) s
    (increasing: a plant's record of its true pose), sampled every 1 / ``rate_hz`` s from t[0]
    (each sample the last pose recorded at or before its time), each with the tracker's noise
    (:func:`noisy_poses`); with a ``setup``, the marker's poses in the tracker's frame.

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
    seen = x[index] if setup is None else setup.tracker_poses(x[index])
    return times, noisy_poses(seen, noise, rng)
