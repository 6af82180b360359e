"""The clock and the frames that put a measured motion on its reference's
(``stewart-drake verify``): the reference's poses at any time (:func:`reference_poses`), the
frames fitted or given (:class:`FrameFit`: the tracker's frame in the base frame, the marker's
offset and axes on the platform), and the shift between the clocks.

The shift is found coarsely by cross-correlation over every shift allowed
(:func:`coarse_shift`: the measured positions against the reference's with the best rigid frame
at each shift, Kabsch on their cross-covariances, every shift at once by FFT), then finely by
least squares together with the frames, to a fraction of a sample (:data:`FIT_SAMPLES` samples
at most; the frames the data do not determine held by the prior :data:`FIT_PRIOR`).
:func:`~.verification.verify` runs these steps and judges the aligned motion.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np
from scipy.spatial.transform import Rotation

from ..references.motion import Reference
from ..robot.kinematics import rotation_rpy
from .measured_motion import MeasuredMotion

#: A rotation's weight against a translation in the fits, m per rad (a point 0.15 m from the
#: axis).
ROTATION_WEIGHT_M = 0.15
#: Weight of the prior that keeps a fitted frame where the data do not determine it: per sample,
#: m per rad for the rotations and dimensionless for the marker's offset (a bias of a few parts in
#: a million on what the motion determines).
FIT_PRIOR = (1e-5, 1e-3)

_W_ROT = np.array([ROTATION_WEIGHT_M] * 3)


# -- poses and frames ------------------------------------------------------------------------------


def _rotations(poses) -> Rotation:
    """The rotations R = Rz(psi) Ry(theta) Rx(phi) of poses (n, 6)."""
    return Rotation.from_euler("ZYX", np.asarray(poses)[:, 2::-1])


def _rpy(rotations: Rotation) -> np.ndarray:
    """(n, 3) roll, pitch, yaw of ``rotations`` (the inverse of :func:`_rotations`)."""
    return rotations.as_euler("ZYX")[:, ::-1]


def reference_poses(reference: Reference, t) -> np.ndarray:
    """(n, 6) the reference's poses at the times t (s), held at its first pose before t = 0
    and at its last after its ``end_time`` (a phantom at rest before and after its motion)."""
    end = getattr(reference, "end_time", None)
    held = np.clip(np.asarray(t, float), 0.0, math.inf if end is None else float(end))
    return np.asarray(reference.evaluate(held)[0], dtype=float)


@dataclass(frozen=True)
class FrameFit:
    """The frames that put the measured poses on the reference's.

    Attributes:
        how: "base" (the poses were the platform's in the base frame), "registration" (mapped by
            a registration file, ``note`` its words) or "fit" (a rigid transform fitted).
        R_BT, p_BT: (3, 3), (3,) m: the tracker's frame in the base frame (fitted; identity
            otherwise).
        R_ME, p_EM: (3, 3): the platform's frame in the marker's (6-DoF marker, fitted);
            (3,) m: the marker's origin on the platform, platform frame (fitted).
        free, fitted: of the ``fitted`` parameters of the frames, those the motion does not
            determine (a turn about the one line a motion runs along), held by the fit's prior
            (:data:`FIT_PRIOR`) where the coarse fit put them.
    """

    how: str
    R_BT: np.ndarray = field(default_factory=lambda: np.eye(3))
    p_BT: np.ndarray = field(default_factory=lambda: np.zeros(3))
    R_ME: np.ndarray = field(default_factory=lambda: np.eye(3))
    p_EM: np.ndarray = field(default_factory=lambda: np.zeros(3))
    free: int = 0
    fitted: int = 0
    note: str = ""

    def words(self) -> str:
        """What the frames did, in words."""
        if self.how == "base":
            return "none: the poses are the platform's in the base frame"
        if self.how == "registration":
            return f"from the registration file, nothing fitted: {self.note}"
        angle = math.degrees(Rotation.from_matrix(self.R_BT).magnitude())
        text = (
            f"fitted (a stated best fit): the tracker's frame at "
            f"{np.linalg.norm(self.p_BT) * 1e3:.4g} mm and {angle:.4g} deg from the base frame, "
            f"the marker {np.linalg.norm(self.p_EM) * 1e3:.3g} mm from the platform's origin"
        )
        if not np.allclose(self.R_ME, np.eye(3)):
            text += (
                f", its axes turned {math.degrees(Rotation.from_matrix(self.R_ME).magnitude()):.3g}"
                " deg from the platform's"
            )
        if self.free:
            text += (
                f"; {self.free} of its {self.fitted} parameters are not determined by this motion "
                "(a turn about the line it runs along, a part of the marker's offset that its "
                "turns do not show): they are held where the coarse fit put them, and no figure "
                "depends on them"
            )
        return (
            text + ". A best fit also removes any true constant error of the phantom (an offset "
            "or a tilt of its whole motion): give --registration REG.yaml to keep it"
        )

    def as_dict(self) -> dict:
        """The fit as JSON values: how, the transforms (rotation vectors, rad; positions, m)."""
        return {
            "how": self.how,
            "rotvec_BT_rad": Rotation.from_matrix(self.R_BT).as_rotvec().tolist(),
            "p_BT_m": np.asarray(self.p_BT).tolist(),
            "rotvec_ME_rad": Rotation.from_matrix(self.R_ME).as_rotvec().tolist(),
            "p_EM_m": np.asarray(self.p_EM).tolist(),
            "free": self.free,
            "fitted": self.fitted,
        }


def _in_base(fit: FrameFit, poses_TM: np.ndarray, reference_x: np.ndarray) -> np.ndarray:
    """(n, 6) the platform's poses in the base frame of the marker's poses_TM (n, 6) through the
    fitted frames: X_BE = X_BT X_TM X_ME; a marker without rotations (NaN) keeps NaN rotations
    and its offset p_EM is taken off along the reference's rotation (reference_x (n, 6))."""
    p_BE, R_BE = _platform(fit, poses_TM, _matrices(poses_TM), rotation_rpy(reference_x[:, :3]))
    out = np.full_like(poses_TM, np.nan)
    out[:, 3:] = p_BE
    if R_BE is not None:
        out[:, :3] = _rpy(Rotation.from_matrix(R_BE))
    return out


def _matrices(poses) -> np.ndarray | None:
    """(n, 3, 3) the rotation matrices of poses (n, 6), None when their rotations are NaN."""
    return rotation_rpy(poses[:, :3]) if np.all(np.isfinite(poses[:, :3])) else None


def _platform(fit: FrameFit, poses_TM, R_TM, R_ref) -> tuple:
    """(p_BE (n, 3), R_BE (n, 3, 3) or None) of the marker's poses_TM (n, 6) with their
    rotations R_TM (n, 3, 3) (None: not measured; the marker's offset then taken off along the
    reference's rotations R_ref (n, 3, 3))."""
    p_BM = poses_TM[:, 3:] @ fit.R_BT.T + fit.p_BT
    R_BE = None if R_TM is None else fit.R_BT @ R_TM @ fit.R_ME
    return p_BM - (R_ref if R_BE is None else R_BE) @ fit.p_EM, R_BE


def _rotation_error(R_ref, R) -> np.ndarray:
    """(n, 3) the rotation from R_ref (n, 3, 3) to R (n, 3, 3), in its own axes: the vector of
    the skew part of R_ref^T R (sin of the angle times the axis; the angle for small ones)."""
    E = np.swapaxes(R_ref, 1, 2) @ R
    return 0.5 * np.stack(
        [E[:, 2, 1] - E[:, 1, 2], E[:, 0, 2] - E[:, 2, 0], E[:, 1, 0] - E[:, 0, 1]], axis=1
    )


def _kabsch(H: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(R (..., 3, 3), score (...,)): the rotations maximising tr(R^T H) of cross-covariances H
    (..., 3, 3) (a sum of r y^T: R maps y onto r) and that maximum (Kabsch)."""
    U, S, Vt = np.linalg.svd(H)
    sign = np.sign(np.linalg.det(U @ Vt))
    sign = np.where(sign == 0, 1.0, sign)
    D = np.ones(S.shape)
    D[..., 2] = sign
    return (U * D[..., None, :]) @ Vt, np.sum(S * D, axis=-1)


def _registered(registration, measured: MeasuredMotion) -> FrameFit:
    """The frames of a registration (its ``X_TB``, ``X_PM``): identities for a 6-DoF marker,
    whose poses its ``base_poses`` converts; for a marker without rotations the tracker's frame
    in the base frame and the marker's offset on the platform (taken off along the reference's
    rotation)."""
    note = registration.words()
    if measured.rotations_measured:
        return FrameFit("registration", note=note)
    X_BT = registration.X_TB.inverse()
    return FrameFit(
        "registration",
        X_BT.rotation().matrix(),
        X_BT.translation(),
        p_EM=registration.X_PM.translation(),
        note=note,
    )


def _first_fit(reference: Reference, t_ref, y, R_BT) -> FrameFit:
    """The frames the fine fit starts from: the coarse rotation ``R_BT`` (3, 3), the
    translation that puts the measured positions' centroid on the reference's, for a 6-DoF
    marker its axes' mean turn from the platform's; the marker at the platform's origin."""
    x_d = reference_poses(reference, t_ref)
    p_BT = x_d[:, 3:].mean(axis=0) - y[:, 3:].mean(axis=0) @ R_BT.T
    R_ME = np.eye(3)
    if np.all(np.isfinite(y[:, :3])):
        R_ME = (Rotation.from_matrix(R_BT) * _rotations(y)).inv() * _rotations(x_d)
        R_ME = R_ME.mean().as_matrix()
    return FrameFit("fit", R_BT, p_BT, R_ME, np.zeros(3))


# -- the clock -------------------------------------------------------------------------------------


def coarse_shift(
    t, y, reference: Reference, shifts: tuple[float, float], step_s: float, fit_frame: bool
) -> tuple[float, np.ndarray]:
    """The shift d in [shifts] (measured time + d = the reference's time) at which the measured
    positions y best match the reference's, to ``step_s``: their mean squared distance, after
    the best rigid transform at each shift when ``fit_frame`` (Kabsch: the cross-covariances of
    every shift at once by FFT), else as they are; the reference held before its start and
    after its end (:func:`reference_poses`).

    Args:
        t: (n,) s, increasing. y: (n, 3) positions, m. shifts: (lo, hi) s. step_s: s.
    Returns:
        (d s, (3, 3) the rotation R_BT at d; the identity without ``fit_frame``).
    """
    from scipy.signal import correlate

    grid = t[0] + step_s * np.arange(int((t[-1] - t[0]) / step_s) + 1)
    ym = np.column_stack([np.interp(grid, t, y[:, c]) for c in range(3)])
    m = len(grid)
    k_shifts = int(np.floor((shifts[1] - shifts[0]) / step_s)) + 1
    r = reference_poses(reference, grid[0] + shifts[0] + step_s * np.arange(m + k_shifts - 1))
    r = r[:, 3:]
    ones = np.ones(m)
    S_r = np.column_stack([correlate(r[:, b], ones, "valid") for b in range(3)])  # (K, 3)
    S_rr = correlate(np.sum(r * r, axis=1), ones, "valid")
    C = np.empty((k_shifts, 3, 3))  # C[k, b, a] = sum_i r[i + k, b] y[i, a]
    for b in range(3):
        for a in range(3):
            C[:, b, a] = correlate(r[:, b], ym[:, a], "valid")
    if fit_frame:
        y0 = ym - ym.mean(axis=0)
        H = C - S_r[:, :, None] * ym.mean(axis=0)[None, None, :]
        R, score = _kabsch(H)
        ms = (np.sum(y0 * y0) + S_rr - np.sum(S_r * S_r, axis=1) / m - 2 * score) / m
    else:
        R = np.broadcast_to(np.eye(3), (k_shifts, 3, 3))
        ms = (np.sum(ym * ym) + S_rr - 2 * np.trace(C, axis1=1, axis2=2)) / m
    k = int(np.argmin(ms))
    return float(shifts[0] + k * step_s), np.array(R[k])


#: Most samples the fine fit uses (evenly picked): its 13 parameters need far fewer.
FIT_SAMPLES = 3000


def _fine_fit(
    t, y, measured: MeasuredMotion, reference: Reference, d0: float, fit: FrameFit, fitting: bool
) -> tuple[float, FrameFit]:
    """(d s, the frames) minimising the distance between the measured poses at t + d and the
    reference's (least squares, from the coarse shift d0 and frames ``fit``, on at most
    :data:`FIT_SAMPLES` samples): the shift alone, or with ``fitting`` the tracker's frame
    (turned about the measured positions' centroid, so that a tracker a metre away does not tie
    its rotation to its translation), the marker's offset and, for a 6-DoF marker, its axes."""
    from scipy.optimize import least_squares

    pick = slice(None, None, max(1, len(t) // FIT_SAMPLES))
    t, y = t[pick], y[pick]
    rot = measured.rotations_measured
    R_TM = _matrices(y) if rot else None
    n = len(t)
    prior_rot, prior_off = FIT_PRIOR[0] * math.sqrt(n), FIT_PRIOR[1] * math.sqrt(n)
    c_T = y[:, 3:].mean(axis=0)
    c_B0 = c_T @ fit.R_BT.T + fit.p_BT

    def unpack(p) -> FrameFit:
        if not fitting:
            return fit
        R_BT = Rotation.from_rotvec(p[1:4]).as_matrix() @ fit.R_BT
        R_ME = Rotation.from_rotvec(p[7:10]).as_matrix() @ fit.R_ME if rot else fit.R_ME
        p_BT = c_B0 + p[4:7] - R_BT @ c_T
        return FrameFit("fit", R_BT, p_BT, R_ME, p[-3:])

    def residuals(p) -> np.ndarray:
        x_d = reference_poses(reference, t + d0 + p[0])
        R_ref = rotation_rpy(x_d[:, :3])
        p_BE, R_BE = _platform(unpack(p), y, R_TM, R_ref)
        e = [(p_BE - x_d[:, 3:]).ravel()]
        if R_BE is not None:
            e.append((_rotation_error(R_ref, R_BE) * _W_ROT).ravel())
        if fitting:
            e += [prior_rot * p[1:4], prior_off * p[-3:]]
            if rot:
                e.append(prior_rot * p[7:10])
        return np.concatenate(e)

    p0 = np.zeros(1 + (0 if not fitting else (12 if rot else 9)))
    if fitting:
        p0[-3:] = fit.p_EM
    sol = least_squares(residuals, p0, method="trf", x_scale="jac")
    if not fitting:
        return d0 + float(sol.x[0]), fit
    # The translation has no prior (it is always determined): a weight of 1 m per m.
    weights = np.array([prior_rot] * 3 + [1.0] * 3 + [prior_rot] * (3 * rot) + [prior_off] * 3)
    out = replace(unpack(sol.x), free=_free(sol.jac, weights), fitted=len(p0) - 1)
    return d0 + float(sol.x[0]), out


def _free(jac: np.ndarray, weights: np.ndarray) -> int:
    """How many of the frames' parameters the data leave free: the directions of the Jacobian
    (m, 1 + k) whose columns 1.. are scaled by their prior's ``weights`` (k,) in which the
    residuals change by less than three times the prior's own change."""
    J = np.asarray(jac.todense() if hasattr(jac, "todense") else jac)[:, 1:] / weights
    s = np.linalg.svd(J, compute_uv=False)
    return int(np.count_nonzero(s < 3.0))


__all__ = [
    "ROTATION_WEIGHT_M",
    "FIT_PRIOR",
    "FIT_SAMPLES",
    "reference_poses",
    "FrameFit",
    "coarse_shift",
]
