"""A tracker registered by a known motion (``stewart-drake calibrate --register``,
:mod:`~.registration_command`): the
tracker's frame T in the base frame B and its marker M on the platform P fitted, once, to a
motion the phantom was asked to make and the tracker measured (:func:`fit_registration`), then
kept as a REG.yaml that every later verification takes (``--registration``) and none fits
again.

This is the one place where frames are fitted to a motion, and that motion is not judged: a fit
absorbs any error the phantom made during it (an offset, a tilt, a wrong scale of its whole
motion shows as a frame), which is why the registration motion is a short, known one (the
library's ``registration``: every axis moves and turns at its own period, so that the motion
determines every parameter of the frames) and why the fit refuses to write a frame the motion
leaves undetermined or that the measurement does not follow, and a file that a mirrored
frame or rotations turning the other way explain better than it does as written (a proper
rotation fits a mirrored motion only so well, and a marker's lever arm absorbs reversed
rotations: neither leaves a residual large enough to be refused by it alone).

The fit: the clock shift d coarsely by cross-correlation with the best rotation at each shift
(Kabsch on the cross-covariances of every shift at once, by FFT), then the shift, the
tracker's frame (turned about the measured positions' centroid, so that a tracker a metre away
does not tie its rotation to its translation), the marker's offset on the platform and, for a
6-DoF marker, its axes, together by least squares (scipy); a direction of them the data do not
determine is refused (:func:`fit_registration`).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, NamedTuple

import numpy as np
from scipy.spatial.transform import Rotation

from ..base.errors import InvalidConfigError
from ..references.motion import Reference
from ..robot.kinematics import rotation_rpy
from .alignment import ROTATION_WEIGHT_M, reference_poses, rigid_shift
from .measured_motion import MeasuredMotion

#: Most samples the fit uses (evenly picked): its 13 parameters need far fewer.
FIT_SAMPLES = 3000
#: The largest RMS distance between the measured marker and the reference's once fitted, m: more
#: is not this motion, a marker that slipped, or a tracker that lost it.
MAX_REGISTRATION_RMS_M = 1e-3
#: The largest RMS angle between a 6-DoF marker's rotation and the reference's once fitted,
#: rad: more is a marker whose rotations are not this motion's (turning the other way, another
#: convention of angles).
MAX_REGISTRATION_RMS_RAD = math.radians(0.5)
#: Another reading of the file (a mirrored frame, reversed rotations) whose residual is under
#: this share of the file's as written explains the motion better: the file is refused.
BETTER_SHARE = 0.5
#: A direction of the frames' parameters known worse than this, one standard deviation (rotations
#: counted as the displacement of a point :data:`~.alignment.ROTATION_WEIGHT_M` from the axis),
#: is not determined by the motion, m.
MAX_FRAME_SIGMA_M = 1e-3
#: The least noise the determination assumes, m (a fit to noise-free samples has none).
MIN_NOISE_M = 10e-6
#: Shortest registration motion fitted, s.
MIN_REGISTRATION_S = 10.0

_W_ROT = np.array([ROTATION_WEIGHT_M] * 3)


@dataclass(frozen=True)
class MotionRegistration:
    """The tracker's frames fitted to a registration motion (module docstring).

    Attributes:
        R_BT, p_BT: (3, 3), (3,) m: the tracker's frame T in the base frame B.
        R_PM, p_PM: (3, 3), (3,) m: the marker's frame M in the platform frame P (R_PM the
            identity for a marker of positions only, whose axes are not measured).
        sigma_B, sigma_M: (rad, m): one standard deviation per axis of each frame's rotation
            and translation, from the fit's covariance (the residuals' variance times the
            inverse of the normal matrix), the larger of the three axes.
        rms_m: the RMS distance between the measured marker and the reference's once fitted, m;
            rms_rad: the same of a 6-DoF marker's rotation (NaN without), rad.
        shift_s: d, measured time + d = the reference's, s. samples: the samples fitted.
        motion: the reference's name. measured: the measured file's name.
    """

    R_BT: np.ndarray
    p_BT: np.ndarray
    R_PM: np.ndarray
    p_PM: np.ndarray
    sigma_B: tuple
    sigma_M: tuple
    rms_m: float
    rms_rad: float
    shift_s: float
    samples: int
    motion: str
    measured: str

    def words(self) -> str:
        """The fit in one line: its source and its residual."""
        rot = "" if math.isnan(self.rms_rad) else f", {self.rms_rad * 1e6:.3g} urad"
        return (
            f"fitted to {self.motion} measured in {self.measured} ({self.samples} samples, "
            f"{self.rms_m * 1e6:.3g} um RMS{rot} off the motion once fitted)"
        )


def _rotations(poses) -> Rotation:
    """The rotations R = Rz(psi) Ry(theta) Rx(phi) of poses (n, 6)."""
    return Rotation.from_euler("ZYX", np.asarray(poses)[:, 2::-1])


def _rotation_error(R_ref, R) -> np.ndarray:
    """(n, 3) the rotation from R_ref (n, 3, 3) to R (n, 3, 3), in its own axes: the vector of
    the skew part of R_ref^T R (sin of the angle times the axis; the angle for small ones)."""
    E = np.swapaxes(R_ref, 1, 2) @ R
    return 0.5 * np.stack(
        [E[:, 2, 1] - E[:, 1, 2], E[:, 0, 2] - E[:, 2, 0], E[:, 1, 0] - E[:, 0, 1]], axis=1
    )


def _check_registration_input(measured: MeasuredMotion, name: str, max_gap_s: float) -> None:
    """The refusals of :func:`fit_registration` made before any fit: not a tracker's X, Y and
    Z, some rotations but not three, a step between samples longer than ``max_gap_s``, or
    shorter than :data:`MIN_REGISTRATION_S` (``name``: the reference's, for the message)."""
    from .verify import _samples, seconds

    if measured.kind != "tracker" or not np.all(measured.measured[3:]):
        raise InvalidConfigError(
            f"{measured.path}: a registration needs a tracker's X, Y and Z of the marker (a "
            "3-D tracker's export), not an encoder log or a single-axis sensor"
        )
    if np.any(measured.measured[:3]) and not measured.rotations_measured:
        raise InvalidConfigError(
            f"{measured.path}: a registration takes the marker's three rotations or none"
        )
    t = measured.t
    _samples(t, max_gap_s, pausable=False)  # a registration takes no pause
    if t[-1] - t[0] < MIN_REGISTRATION_S:
        raise InvalidConfigError(
            f"{measured.path}: the registration motion lasts {seconds(t[-1] - t[0])}, shorter "
            f"than {MIN_REGISTRATION_S:g} s: record at least 30 s of {name}"
        )


def fit_registration(
    reference: Reference,
    measured: MeasuredMotion,
    clock_offset_s: float | None = None,
    max_latency_s: float = 0.5,
    max_gap_s: float = 0.5,
) -> MotionRegistration:
    """The tracker's frames fitted to a registration motion (module docstring).

    Args:
        reference: the motion asked for (the library's ``registration``, or any motion that
            determines the frames). measured: the tracker's view of it: the marker's X, Y, Z
            (and its three rotations, or none), on the tracker's clock, in its frame.
        clock_offset_s: measured time + this = the reference's, s (None: searched).
        max_latency_s: with ``clock_offset_s``, the largest latency searched, s.
        max_gap_s: the longest step between two samples fitted across, s.
    Returns:
        :class:`MotionRegistration`.
    Raises:
        InvalidConfigError: not a tracker's X, Y and Z (an encoder log; a single-axis sensor;
            some rotations but not three); shorter than :data:`MIN_REGISTRATION_S`; a motion
            that leaves a parameter of the frames undetermined (a turn about the one line it
            runs along); the measured marker farther than :data:`MAX_REGISTRATION_RMS_M` (or
            a 6-DoF marker turned more than :data:`MAX_REGISTRATION_RMS_RAD`) RMS from the
            reference once fitted; the file read as a mirrored frame, or with its rotations
            reversed, fitting clearly better (:data:`BETTER_SHARE`): a frame fitted to it as
            written would be wrong; a step between samples longer than ``max_gap_s``.
    """
    from .measured_span import search_range

    name = getattr(reference, "name", "the reference")
    _check_registration_input(measured, name, max_gap_s)
    t, y = measured.t, measured.poses
    rot = measured.rotations_measured
    search, _ = search_range(reference, t, clock_offset_s, max_latency_s, whole=False)
    fit = _fit(reference, t, y, rot, search)
    sol, J, e, unpack, rms_m, rms_rad = fit.sol, fit.J, fit.e, fit.unpack, fit.rms_m, fit.rms_rad
    _check_fit(fit, measured, name, rot)
    _check_as_written(fit, reference, measured, search)
    R_BT, p_BT, R_ME, p_EM = unpack(sol.x)
    sigma_B, sigma_M = _frame_sigmas(J, e, sol.x, unpack, rot)
    return MotionRegistration(
        R_BT,
        p_BT,
        R_ME.T,
        p_EM,
        sigma_B,
        sigma_M,
        rms_m,
        rms_rad,
        fit.shift_s,
        fit.samples,
        name,
        str(measured.path),
    )


def _check_fit(fit, measured: MeasuredMotion, name: str, rot: bool) -> None:
    """Refuse a fit whose residual is too large, then one that leaves a parameter of the
    frames undetermined (:func:`fit_registration`'s Raises)."""
    sol, J, e, rms_m, rms_rad = fit.sol, fit.J, fit.e, fit.rms_m, fit.rms_rad
    # The residual first: a marker that did not follow the motion leaves residuals so large
    # that every direction of the frames looks undetermined too, and that refusal would send
    # the user to the registration motion they have just measured.
    if rms_m > MAX_REGISTRATION_RMS_M or (rot and rms_rad > MAX_REGISTRATION_RMS_RAD):
        raise InvalidConfigError(
            f"{measured.path}: the marker stays {rms_m * 1e3:.3g} mm"
            + (f", {math.degrees(rms_rad):.3g} deg" if rot else "")
            + f" RMS from {name} once the frames are fitted (at most "
            f"{MAX_REGISTRATION_RMS_M * 1e3:g} mm"
            + (f", {math.degrees(MAX_REGISTRATION_RMS_RAD):g} deg" if rot else "")
            + "): not this motion, a marker that slipped, or a tracker that lost it; measure "
            "the registration again"
        )
    free = _undetermined(J[:, 1:], e, rot)
    if free:
        raise InvalidConfigError(
            f"{name} leaves {free} of the frames' {len(sol.x) - 1} parameters undetermined "
            "(a turn about a line the motion runs along, or a marker offset its turns do not "
            "show): register with the library's motion registration, which moves along and "
            "turns about every axis"
        )


def _check_as_written(fit, reference, measured: MeasuredMotion, search) -> None:
    """Refuse a file that, read as a mirrored frame or with its rotations reversed, the
    registration motion explains clearly better (:func:`fit_registration`'s Raises)."""
    t, y, rot = measured.t, measured.poses, measured.rotations_measured
    rms_m, rms_rad = fit.rms_m, fit.rms_rad
    for what, y_other in _other_frames(y, rot):
        other = _fit(reference, t, y_other, rot, search)
        if _explains_better(other, fit, rot):
            raise InvalidConfigError(
                f"{measured.path}: {what} explains the registration motion better than the "
                f"file as written ({other.rms_m * 1e6:.3g} um RMS against {rms_m * 1e6:.3g} um"
                + (
                    f"; {other.rms_rad * 1e6:.3g} urad against {rms_rad * 1e6:.3g} urad"
                    if rot
                    else ""
                )
                + "): a frame fitted to it would be wrong; correct the export (its axes' "
                "signs, its rotations' sense) and measure again"
            )


class _Fit(NamedTuple):
    """A least-squares fit of the frames (:func:`_fit`): scipy's solution, its Jacobian and
    residuals, the parameters' unpacking into (R_BT, p_BT, R_ME, p_EM), the residuals' RMS (m,
    and rad of a 6-DoF marker, else NaN), the shift d (s) and the samples fitted."""

    sol: Any
    J: np.ndarray
    e: np.ndarray
    unpack: Callable
    rms_m: float
    rms_rad: float
    shift_s: float
    samples: int


def _fit(reference: Reference, t, y, rot: bool, search: tuple) -> _Fit:
    """The frames fitted to the measured marker y (n, 6) at the times t (module docstring):
    the shift coarsely with the best rotation at each (:func:`rigid_shift`, within
    ``search``), then every parameter by least squares."""
    from .alignment import overlap

    step = max(0.02, float(np.median(np.diff(t))))
    d0, R0 = rigid_shift(t, y[:, 3:], reference, search, step)
    use = overlap(reference, t + d0, step)
    t, y = t[use], y[use]
    # As many as allowed, spread evenly from the first sample to the last.
    pick = np.round(np.linspace(0, len(t) - 1, min(len(t), FIT_SAMPLES))).astype(int)
    t, y = t[pick], y[pick]
    x_d0 = reference_poses(reference, t + d0)
    p0_BT = x_d0[:, 3:].mean(axis=0) - y[:, 3:].mean(axis=0) @ R0.T
    R0_ME = np.eye(3)
    if rot:
        R0_ME = ((Rotation.from_matrix(R0) * _rotations(y)).inv() * _rotations(x_d0)).mean()
        R0_ME = R0_ME.as_matrix()
    R_TM = rotation_rpy(y[:, :3]) if rot else None
    n = len(t)
    c_T = y[:, 3:].mean(axis=0)
    c_B0 = c_T @ R0.T + p0_BT

    def unpack(p):
        R_BT = Rotation.from_rotvec(p[1:4]).as_matrix() @ R0
        R_ME = Rotation.from_rotvec(p[7:10]).as_matrix() @ R0_ME if rot else R0_ME
        return R_BT, c_B0 + p[4:7] - R_BT @ c_T, R_ME, p[-3:]

    def residuals(p) -> np.ndarray:
        R_BT, p_BT, R_ME, p_EM = unpack(p)
        x_d = reference_poses(reference, t + d0 + p[0])
        R_ref = rotation_rpy(x_d[:, :3])
        p_BM = y[:, 3:] @ R_BT.T + p_BT
        R_BE = None if R_TM is None else R_BT @ R_TM @ R_ME
        e = [(p_BM - (R_ref if R_BE is None else R_BE) @ p_EM - x_d[:, 3:]).ravel()]
        if R_BE is not None:
            e.append((_rotation_error(R_ref, R_BE) * _W_ROT).ravel())
        return np.concatenate(e)

    from scipy.optimize import least_squares

    p_start = np.zeros(13 if rot else 10)
    sol = least_squares(residuals, p_start, method="trf", x_scale="jac")
    J = np.asarray(sol.jac)
    e = residuals(sol.x)
    pos = e[: 3 * n].reshape(n, 3)
    rms_m = float(np.sqrt(np.mean(np.sum(pos**2, axis=1))))
    rms_rad = (
        float(np.sqrt(np.mean(np.sum((e[3 * n :].reshape(n, 3) / _W_ROT) ** 2, axis=1))))
        if rot
        else math.nan
    )
    return _Fit(sol, J, e, unpack, rms_m, rms_rad, d0 + float(sol.x[0]), n)


def _other_frames(y, rot: bool) -> list:
    """[(what, y')]: the measured marker y (n, 6) as a mirrored frame or reversed rotations
    would have it written: X's sign flipped (a left-handed export; the rotations about Y and Z
    reflected with it), and with a 6-DoF marker the three rotations negated (turning the other
    way)."""
    mirrored = np.array(y, dtype=float)
    mirrored[:, 3] = -mirrored[:, 3]
    if rot:
        mirrored[:, 1:3] = -mirrored[:, 1:3]
    out = [("a mirrored tracker's frame (one axis's sign flipped)", mirrored)]
    if rot:
        reversed_ = np.array(y, dtype=float)
        reversed_[:, :3] = -reversed_[:, :3]
        out.append(("the marker's rotations run the other way", reversed_))
    return out


def _explains_better(other: _Fit, fit: _Fit, rot: bool) -> bool:
    """Whether the fit ``other`` (:func:`_fit`) explains the motion clearly better than ``fit``:
    its positions' residual under :data:`BETTER_SHARE` of the other's, or, with rotations, its
    rotations' residual so, the positions' no worse."""
    if other.rms_m < BETTER_SHARE * fit.rms_m:
        return True
    return bool(rot and other.rms_rad < BETTER_SHARE * fit.rms_rad and other.rms_m <= fit.rms_m)


def _undetermined(J, e, rot: bool) -> int:
    """How many directions of the frames' parameters the data leave undetermined: those of
    the residuals' Jacobian J (m, k) (the frames' k parameters, without the shift; rotations
    scaled to m at :data:`~.alignment.ROTATION_WEIGHT_M`) known to worse than
    :data:`MAX_FRAME_SIGMA_M`, with the residuals' e (m,) noise (at least :data:`MIN_NOISE_M`
    per coordinate)."""
    scale = np.array(
        [ROTATION_WEIGHT_M] * 3 + [1.0] * 3 + [ROTATION_WEIGHT_M] * (3 * rot) + [1.0] * 3
    )
    Js = J / scale
    noise = max(float(np.sqrt(np.mean(e**2))), MIN_NOISE_M)
    lam = np.linalg.eigvalsh(Js.T @ Js)
    return int(np.count_nonzero(noise**2 > MAX_FRAME_SIGMA_M**2 * np.clip(lam, 0.0, None)))


def _frame_sigmas(J, e, p, unpack, rot: bool) -> tuple[tuple, tuple]:
    """((rad, m) of X_TB, (rad, m) of X_PM): the largest standard deviation per axis of each
    frame's rotation and translation, from the fit's covariance s^2 (J^T J)^-1 (J (m, k) the
    residuals' Jacobian, e (m,) the residuals) carried to the frames by finite
    differences of ``unpack``."""
    dof = max(len(e) - J.shape[1], 1)
    cov = float(np.sum(e**2)) / dof * np.linalg.pinv(J.T @ J)

    def frames(q) -> np.ndarray:
        R_BT, p_BT, R_ME, p_EM = unpack(q)
        R_TB = R_BT.T
        return np.concatenate(
            [
                Rotation.from_matrix(R_TB).as_rotvec(),
                -R_TB @ p_BT,
                Rotation.from_matrix(R_ME.T).as_rotvec(),
                p_EM,
            ]
        )

    base = frames(p)
    D = np.empty((12, len(p)))
    for j in range(len(p)):
        h = 1e-7 * max(1.0, abs(p[j]))
        q = p.copy()
        q[j] += h
        D[:, j] = (frames(q) - base) / h
    C = D @ cov @ D.T
    sd = np.sqrt(np.clip(np.diag(C), 0.0, None))
    marker_rot = float(sd[6:9].max()) if rot else 0.0
    return (float(sd[:3].max()), float(sd[3:6].max())), (marker_rot, float(sd[9:].max()))


__all__ = [
    "FIT_SAMPLES",
    "MAX_REGISTRATION_RMS_M",
    "MAX_FRAME_SIGMA_M",
    "MIN_NOISE_M",
    "MIN_REGISTRATION_S",
    "MotionRegistration",
    "rigid_shift",
    "fit_registration",
]
