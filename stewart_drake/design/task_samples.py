"""A design task sampled once, for every candidate a search judges.

:func:`task_samples` samples the requirements (:class:`~stewart_drake.design.requirements.
DesignRequirements`) once: the motions' poses, rates and accelerations at
:data:`MOTION_RATE_HZ`, the required box at :data:`BOX_POINTS` points per side each tilted by the
cone's angle about :data:`TILT_DIRECTIONS` horizontal axes (:func:`tilted_box_poses`). Every
candidate is then one vectorized pass over those poses (:func:`~.margins.evaluate`); a search
stores the samples (:meth:`TaskSamples.save`) for its workers and keys its results by their
digest.
"""

from __future__ import annotations

import hashlib
import json
from dataclasses import dataclass

import numpy as np

from .requirements import ACCURACY_FLOOR_SHARE, DesignRequirements
from .variables import reference_design

#: Sample rate of the motions, Hz: 100 samples a second resolve the torque peaks of the library's
#: motions (heartbeat harmonics to 6 Hz) to within 1 %.
MOTION_RATE_HZ = 100.0
#: Longest stretch of a motion sampled, s (a periodic motion: one period, at most this).
MAX_MOTION_S = 60.0
#: Points per side of the required box (3: corners, edge midpoints, faces and centre).
BOX_POINTS = 3
#: Horizontal axes the platform is tilted about at each point of the box (evenly spread).
TILT_DIRECTIONS = 8
#: Clearance is measured at every this-many-th motion sample (0.2 s at 100 Hz) and at every
#: workspace pose; parts move < 3 mm in 0.2 s along the library's motions.
CLEARANCE_STRIDE = 20


@dataclass(frozen=True)
class TaskSamples:
    """What a task asks of any design, sampled once (:func:`task_samples`).

    Attributes:
        labels: each motion's name.
        x, x_dot, x_ddot: (n, 6) the motions' poses [rad, m], rates and accelerations, one after
            the other.
        motion: (n,) int, the motion each sample belongs to (an index of ``labels``).
        workspace_x: (m, 6) the required workspace's poses, held (m = 0: none).
        payload_kg: mass at the platform frame's origin, kg.
        torque_share, speed_share: what the motions may use of the motor's peak torque and
            no-load speed (1 - the requirements' margins).
        resolution: (2,) the largest pose error the encoders may leave, [m, rad]
            (:class:`~stewart_drake.design.requirements.Resolution`); inf: not judged.
        floor: (2,) the largest the encoders' floor may be, RMS per axis [m, rad]: the
            required accuracy times its share
            (:class:`~stewart_drake.design.requirements.Accuracy`); inf: not judged.
    """

    labels: tuple
    x: np.ndarray
    x_dot: np.ndarray
    x_ddot: np.ndarray
    motion: np.ndarray
    workspace_x: np.ndarray
    payload_kg: float
    torque_share: float
    speed_share: float
    resolution: tuple = (float("inf"), float("inf"))
    floor: tuple = (float("inf"), float("inf"))

    @property
    def clearance_x(self) -> np.ndarray:
        """(k, 6) the poses at which clearance is measured (:data:`CLEARANCE_STRIDE`)."""
        return np.concatenate([self.x[::CLEARANCE_STRIDE], self.workspace_x])

    def digest(self) -> str:
        """16 hex digits identifying the samples (a search's settings)."""
        h = hashlib.sha256()
        for a in (self.x, self.x_dot, self.x_ddot, self.motion, self.workspace_x):
            h.update(np.ascontiguousarray(a, dtype=float).tobytes())
        h.update(
            json.dumps(
                [self.labels, self.payload_kg, self.torque_share, self.speed_share]
                + [str(v) for v in self.resolution]
                + [str(v) for v in self.floor]
            ).encode()
        )
        return h.hexdigest()[:16]

    def save(self, path) -> None:
        """Write the samples to ``path`` (.npz, arrays only, atomically: a search killed while
        it writes leaves no half file for the next one to resume from; read back with
        :meth:`load`)."""
        from ..base.fileio import save_npz

        save_npz(
            path,
            {
                "labels": np.array(self.labels, dtype=str),
                "x": self.x,
                "x_dot": self.x_dot,
                "x_ddot": self.x_ddot,
                "motion": self.motion,
                "workspace_x": self.workspace_x,
                "scalars": np.array([self.payload_kg, self.torque_share, self.speed_share]),
                "resolution": np.array(self.resolution, dtype=float),
                "floor": np.array(self.floor, dtype=float),
            },
        )

    @classmethod
    def load(cls, path) -> TaskSamples:
        """Read what :meth:`save` wrote, through :class:`~stewart_drake.base.npz.CheckedNpz`
        (numbers and text only, each entry's header checked before it is loaded).

        Raises:
            CorruptFileError: not such a file (names it and the entry at fault).
            OSError: the file cannot be read.
        """
        from ..base.npz import CheckedNpz

        f = CheckedNpz(path, "design task samples (.npz)", "run the design search again")
        scalars, resolution, floor = f.array("scalars"), f.array("resolution"), f.array("floor")
        if scalars.shape != (3,):
            raise f.corrupt(f"the entry 'scalars' must hold 3 numbers, has {scalars.shape}")
        payload, torque_share, speed_share = (float(v) for v in scalars)
        return cls(
            f.texts("labels"),
            f.array("x"),
            f.array("x_dot"),
            f.array("x_ddot"),
            f.integers("motion"),
            f.array("workspace_x"),
            payload,
            torque_share,
            speed_share,
            tuple(float(v) for v in resolution.ravel()),
            tuple(float(v) for v in floor.ravel()),
        )


def tilted_box_poses(box_m, tilt_deg: float, centre_m, points: int = BOX_POINTS) -> np.ndarray:
    """Poses of a required workspace: a grid of the box, each untilted and tilted by
    ``tilt_deg`` about :data:`TILT_DIRECTIONS` horizontal axes, (points^3 (1 + directions), 6).

    The platform's normal then sweeps the cone's rim; yaw stays 0 (the task's cone is about
    tilt). Poses are [roll, pitch, yaw, X, Y, Z] as everywhere (R = Rz Ry Rx).
    """
    from scipy.spatial.transform import Rotation

    axes = [np.linspace(-s / 2, s / 2, points) if s > 0 else np.zeros(1) for s in box_m]
    p = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3) + np.asarray(centre_m)
    a = 2 * np.pi * np.arange(TILT_DIRECTIONS) / TILT_DIRECTIONS
    rotvec = np.deg2rad(tilt_deg) * np.stack([np.cos(a), np.sin(a), np.zeros_like(a)], axis=1)
    rpy = np.concatenate([np.zeros((1, 3)), Rotation.from_rotvec(rotvec).as_euler("xyz")])
    if tilt_deg == 0:
        rpy = rpy[:1]
    rpy_all = np.repeat(rpy[None], len(p), axis=0).reshape(-1, 3)
    p_all = np.repeat(p, len(rpy), axis=0)
    return np.concatenate([rpy_all, p_all], axis=1)


def task_samples(requirements: DesignRequirements) -> TaskSamples:
    """Sample a task once for every candidate (module docstring).

    Each motion is built for the reference robot (only the data-collection excitation uses the
    robot, and a task names its motions) and sampled over its length: the paper manoeuvre and
    the sine references over their period (at most :data:`MAX_MOTION_S`), a periodic library
    motion over one repeat period, a trace over its recording.

    Raises:
        InvalidConfigError, MissingFileError, CorruptFileError: a motion that cannot be built.
    """
    requirements.validate()
    geometry = reference_design().geometry()
    labels, xs, xds, xdds, which = [], [], [], [], []
    for i, choice in enumerate(requirements.motions):
        reference = choice.make(geometry, MAX_MOTION_S, None)
        start, duration = _motion_span(reference)
        t = start + np.arange(0.0, duration + 0.5 / MOTION_RATE_HZ, 1.0 / MOTION_RATE_HZ)
        x, xd, xdd = reference.evaluate(t)
        labels.append(choice.label)
        xs.append(x)
        xds.append(xd)
        xdds.append(xdd)
        which.append(np.full(len(t), i))
    workspace = requirements.workspace
    ws_x = (
        np.zeros((0, 6))
        if workspace is None
        else tilted_box_poses(workspace.box_m, workspace.tilt_deg, workspace.centre_m)
    )
    empty = np.zeros((0, 6))
    return TaskSamples(
        tuple(labels),
        np.concatenate(xs) if xs else empty,
        np.concatenate(xds) if xs else empty,
        np.concatenate(xdds) if xs else empty,
        np.concatenate(which) if xs else np.zeros(0, dtype=int),
        ws_x,
        float(requirements.payload_kg),
        1.0 - requirements.margins.torque,
        1.0 - requirements.margins.speed,
        (float("inf"), float("inf"))
        if requirements.resolution is None
        else (requirements.resolution.translation_m, requirements.resolution.rotation_rad),
        (float("inf"), float("inf"))
        if requirements.accuracy is None
        else (
            ACCURACY_FLOOR_SHARE * requirements.accuracy.translation_m,
            ACCURACY_FLOOR_SHARE * requirements.accuracy.rotation_rad,
        ),
    )


def _motion_span(reference) -> tuple[float, float]:
    """(start, length) of a motion to sample, s: a recording from its first sample over its
    length, a periodic motion over one repeat period (at least 10 s), else 10 s (the paper
    manoeuvre's run); at most :data:`MAX_MOTION_S`."""
    end = getattr(reference, "end_time", None)
    if end is not None:
        start = float(getattr(reference, "start_time", 0.0))
        return start, min(float(end) - start, MAX_MOTION_S)
    period = getattr(reference, "repeat_period_s", None)
    if isinstance(period, (int, float)) and period > 0:
        return 0.0, float(min(max(period, 10.0), MAX_MOTION_S))
    return 0.0, 10.0
