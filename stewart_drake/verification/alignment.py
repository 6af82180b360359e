"""The clock and the frames that put a measured motion on its reference's
(``stewart-drake verify``), none of them fitted to the motion judged.

**The frames** (:class:`Frames`) say how the measured poses become the platform's in the base
frame B, and come from outside the motion judged:

- ``"encoders"``: the robot's encoder log, the platform's poses in B by forward kinematics;
- ``"registration"``: a tracker registered to the robot (a REG.yaml: fiducials, or the frames
  fitted once to a registration motion, :mod:`~.registration_motion`), its marker's poses mapped
  to the platform's in B; for a marker of positions only, its offset on the platform p_EM taken
  off along the reference's rotation;
- ``"base"``: the file gives the platform's poses in B already;
- ``"axes"``: each measured axis is the base frame's axis its column names, with a zero of its
  own: a constant offset per measured axis is removed (as phantom QA protocols do, IntERAct's
  analysis among them), never a rotation, a scale or a marker's lever arm, so that a motion
  of the wrong size, direction, sign or shape stays in the figures.

**The clock.** The shift d (measured time + d = the reference's time whose pose a sample shows)
minimises the weighted mean squared distance between the measured axes and the reference's
(:func:`~stewart_drake.base.lag.shift_scores`: translations in m, rotations weighted by
:data:`ROTATION_WEIGHT_M`; each axis less its mean difference where the frames remove offsets). It
is found coarsely over every shift allowed, every shift at once by FFT
(:func:`~stewart_drake.base.lag.coarse_shift`), then to a fraction of a sample by a bounded scalar
minimisation of the same score (:func:`~stewart_drake.base.lag.refine_shift`): the package's one
lag search, :mod:`stewart_drake.base.lag`. The distance is measured between what the tracker sees
and what the reference makes it see: with a registered marker of positions only, the reference's
marker point p + R p_EM, not the platform's origin (:func:`reference_seen`), so that a marker far
from the origin does not pull the clock.
**The span.** A sample is compared where its time on the reference's clock lies inside the
reference's span, from 0 to its end if it has one (:func:`in_span`; :func:`overlap` refuses
fewer than ten such samples): the clock search's refinement, ``verify``'s figures, a
registration motion's fit and ``verify --surrogate``'s pair all read it.
:func:`~.verification.verify` runs these steps and judges the aligned motion.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from scipy.spatial.transform import Rotation

from ..base.errors import InvalidConfigError
from ..base.lag import ROTATION_WEIGHT_M
from ..base.lag import rigid_shift as lag_rigid_shift
from ..organ_motion.fidelity import AXES, format_window
from ..references.motion import Reference
from ..robot.kinematics import rotation_rpy

#: The frames that a verification may take, and the words for each.
FRAME_KINDS = ("axes", "base", "registration", "encoders")


# -- poses and frames ------------------------------------------------------------------------------


def reference_poses(reference: Reference, t) -> np.ndarray:
    """(n, 6) the reference's poses at the times t (s), held at its first pose before t = 0
    and at its last after its ``end_time`` (a phantom at rest before and after its motion)."""
    end = getattr(reference, "end_time", None)
    held = np.clip(np.asarray(t, float), 0.0, math.inf if end is None else float(end))
    return np.asarray(reference.evaluate(held)[0], dtype=float)


@dataclass(frozen=True)
class Frames:
    """How the measured poses become the platform's in the base frame (module docstring).

    Attributes:
        how: one of :data:`FRAME_KINDS`.
        R_BT, p_BT: (3, 3), (3,) m: the tracker's frame in the base frame, for a registered
            marker of positions only (its positions are mapped so before the clock is sought);
            identity and zero otherwise.
        p_EM: (3,) m: that marker's origin on the platform, platform frame (zero otherwise).
        note: the registration's words, or with "axes" what the one measured axis is (the
            surrogate's carriage); "" otherwise.
    """

    how: str
    R_BT: np.ndarray = field(default_factory=lambda: np.eye(3))
    p_BT: np.ndarray = field(default_factory=lambda: np.zeros(3))
    p_EM: np.ndarray = field(default_factory=lambda: np.zeros(3))
    note: str = ""

    @property
    def removes_offsets(self) -> bool:
        """Whether a constant offset per measured axis is removed (the ``"axes"`` frames)."""
        return self.how == "axes"

    def words(self, offsets=None, measured=None) -> str:
        """What the frames did, in words: where they came from and, for ``"axes"``, the
        ``offsets`` (6,) removed from the ``measured`` (6,) bool axes."""
        if self.how == "encoders":
            return "none: the encoder log gives the platform's poses in the base frame"
        if self.how == "base":
            return "none: the file gives the platform's poses in the base frame; nothing removed"
        if self.how == "registration":
            return f"from the registration file, nothing fitted and no offset removed: {self.note}"
        removed = ""
        if offsets is not None and measured is not None:
            parts = [
                f"{AXES[k]} {offsets[k] * 1e3:+.4g} mm"
                if k >= 3
                else f"{AXES[k]} {math.degrees(offsets[k]):+.4g} deg"
                for k in range(6)
                if measured[k]
            ]
            removed = f" ({', '.join(parts)})"
        if self.note:  # a measurement of its own axis (the surrogate's carriage)
            return f"{self.note}, its constant offset removed{removed}, nothing else"
        return (
            "each measured axis taken as the base frame's axis its column names, its constant "
            f"offset removed{removed}, nothing else: a rotation of the tracker, a scale or a "
            "marker away from the platform's origin are not removed and show as errors; a "
            "constant offset of the whole phantom is not judged (give --registration REG.yaml "
            "to judge it)"
        )

    def as_dict(self) -> dict:
        """The frames as JSON values: how, the tracker's frame in B (a rotation vector, rad; a
        position, m), the marker's offset on the platform (m)."""
        return {
            "how": self.how,
            "rotvec_BT_rad": Rotation.from_matrix(self.R_BT).as_rotvec().tolist(),
            "p_BT_m": np.asarray(self.p_BT).tolist(),
            "p_EM_m": np.asarray(self.p_EM).tolist(),
            "removes_offsets": self.removes_offsets,
        }


def registered_frames(registration) -> Frames:
    """The :class:`Frames` of a registration (its ``X_TB``, ``X_PM``, ``words()``) for a
    marker of positions only: the tracker's frame in B and the marker's offset on the
    platform. (A 6-DoF marker's poses are mapped whole by ``registration.base_poses``; its
    frames are then the identity.)"""
    X_BT = registration.X_TB.inverse()
    return Frames(
        "registration",
        X_BT.rotation().matrix(),
        X_BT.translation(),
        registration.X_PM.translation(),
        note=registration.words(),
    )


def reference_seen(frames: Frames, reference: Reference, t) -> np.ndarray:
    """(n, 6) what the measured file shows of the reference at the times t: its poses, with
    the positions of a registered marker of positions only (p + R p_EM) in place of the
    platform's origin."""
    x = reference_poses(reference, t)
    if np.any(frames.p_EM):
        x[:, 3:] += rotation_rpy(x[:, :3]) @ frames.p_EM
    return x


def platform_poses(frames: Frames, y: np.ndarray, x_d: np.ndarray) -> np.ndarray:
    """(n, 6) the platform's poses in B from the measured y (n, 6) as compared (a registered
    marker's positions already in B): the marker's offset p_EM taken off along the reference's
    rotation x_d (n, 6) where it has one; NaN on the axes not measured."""
    x = np.array(y, dtype=float)
    if np.any(frames.p_EM):
        x[:, 3:] -= rotation_rpy(x_d[:, :3]) @ frames.p_EM
    return x


def axis_weights(measured) -> np.ndarray:
    """(6,) each axis's weight in the clock's score: 1 for a measured translation (m),
    :data:`ROTATION_WEIGHT_M` for a measured rotation (m per rad), 0 for an axis not measured."""
    w = np.array([ROTATION_WEIGHT_M] * 3 + [1.0] * 3)
    return np.where(np.asarray(measured, dtype=bool), w, 0.0)


def rigid_shift(
    t, y, reference: Reference, shifts: tuple[float, float], step_s: float
) -> tuple[float, np.ndarray]:
    """(d s, R_BT (3, 3)): the shift in [shifts] (to ``step_s``) at which the measured
    positions y (n, 3), turned by the best rotation at each shift and put on the reference's
    centroid, come nearest the reference's positions, and the rotation at that shift: the
    package's one rotation-aware shift search (:func:`~stewart_drake.base.lag.rigid_shift`) on
    the reference's translations."""
    return lag_rigid_shift(
        t, y, lambda times: reference_poses(reference, times)[:, 3:], shifts, step_s
    )


def in_span(reference: Reference, t_ref: np.ndarray, margin: float = 0.0) -> np.ndarray:
    """(n,) bool: the times ``t_ref`` (s, the reference's clock) inside its span, ``margin`` s
    in: [margin, ``end_time`` - margin] (no ``end_time``: from ``margin`` on)."""
    end = getattr(reference, "end_time", None)
    top = math.inf if end is None else float(end) - margin
    return (t_ref >= margin) & (t_ref <= top)


def overlap(reference: Reference, t_ref: np.ndarray, margin: float) -> np.ndarray:
    """(n,) bool: the times t_ref (s, the reference's) inside its span, ``margin`` s in
    (:func:`in_span`), where a measured motion is compared with it.

    Raises:
        InvalidConfigError: fewer than 10 such times (no overlap).
    """
    on = in_span(reference, t_ref, margin)
    if np.count_nonzero(on) < 10:
        end = getattr(reference, "end_time", None)
        runs = "from 0 s on" if end is None else f"over 0-{end:.4g} s"
        raise InvalidConfigError(
            f"once aligned, the measured motion spans t = {format_window(t_ref[0], t_ref[-1])} "
            f"s of the reference's clock, which runs {runs}: no overlap; check --clock-offset "
            "and that the file recorded this motion"
        )
    return on


__all__ = [
    "in_span",
    "overlap",
    "ROTATION_WEIGHT_M",
    "FRAME_KINDS",
    "reference_poses",
    "rigid_shift",
    "Frames",
    "registered_frames",
    "reference_seen",
    "platform_poses",
    "axis_weights",
]
