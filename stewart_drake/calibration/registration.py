"""The tracker's frames registered to the robot's: where the base frame B is in the tracker's frame
T, and where the tracker's marker M sits on the platform frame P (the frame E of the kinematics),
from fiducials the same tracker measured.

A tracker measures a marker (a 6-D target, or a few reflectors) in its own frame: X_TM. The
platform's pose in the base frame, which the kinematics and the calibration take, is then

    X_BP = X_TB^-1 X_TM X_PM^-1                                   (:meth:`Registration.base_poses`)

X_TB comes from fiducials on the base, each where the drawing puts it (p_BF, ``base_m``) and
where the tracker saw it (p_TF, ``tracker_m``); X_PM from fiducials on the platform seen once
together with the marker (``platform_points``: p_PF, p_TF, and the marker's pose X_TM then):
X_TP by the same fit, X_PM = X_TP^-1 X_TM. Each fit is the weighted rigid fit of
:func:`fit_frame` (scipy's ``Rotation.align_vectors``). Without ``platform_points`` the marker is
the platform frame (X_PM the identity, exactly).

**Uncertainty.** A small error of a frame is a 6-vector [rotation vector (rad), translation (m)],
expressed in the robot's frame it displaces: the true X_TB is X_TB Exp(e_B) (B moved by e_B,
in B), the true X_PM is Exp(e_M) X_PM (P moved by e_M, in P; to first order, X_MP's error
-e_M in P). ``cov_B`` and ``cov_M`` are their covariances: the fits' (the fiducials' noise
``point_sigma_m``, scaled up when the residuals say the fiducials are worse), and for X_PM the
noise of the marker's one measurement (``marker_in_tracker``'s ``rotation_sigma_rad`` and
``translation_sigma_m``). The same error of a frame is in every pose converted
(:meth:`Registration.pose_jacobians` maps it to a base-frame pose), so it is not a noise that
averages over poses: an identification carries it to its parameters' covariance whole.

The fiducials come from a REG.yaml, which :mod:`~.registration_file` reads (or frames fitted
once to a registration motion, which it reads and writes).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from pydrake.math import RigidTransform, RollPitchYaw, RotationMatrix
from scipy.spatial.transform import Rotation

from ..base.checks import as_array, as_poses
from ..base.errors import InvalidConfigError
from ..robot.kinematics import rotation_rpy

#: Fewest fiducials a frame's fit takes: three points not on one line fix a rigid motion.
MIN_POINTS = 3
#: A fiducial's measurement noise, one standard deviation per axis, m, unless REG.yaml says.
DEFAULT_POINT_SIGMA_M = 2e-6
#: A frame whose rotation the fiducials give to worse than this, one standard deviation, rad, is
#: not determined by them (points a few micrometres apart): refused.
MAX_ROTATION_SIGMA_RAD = 1e-2
#: The noise of ``marker_in_tracker``, (rad, m) per axis, unless REG.yaml says: one sample of
#: the tracker of docs/calibration.md's figures.
DEFAULT_MARKER_SIGMA = (20e-6, 5e-6)
#: Points whose spread off their best line is below this fraction of their spread along it lie
#: on one line for a fit: the rotation about that line is then barely known.
MIN_LINE_SPREAD = 0.01
#: Points that a mirrored frame (a reflection, det -1) fits with residuals under this share of
#: the best rigid motion's were measured in a left-handed frame (or with an axis reversed): the
#: fit is refused, since a rigid motion fitted to them would be wrong.
MIRROR_SHARE = 0.5
#: A fit whose RMS residual exceeds this, m, pairs the points wrongly (an order, a unit).
MAX_FIT_RMS_M = 5e-3


def _skew(v) -> np.ndarray:
    """(..., 3, 3) [v]x of v (..., 3)."""
    v = np.asarray(v, dtype=float)
    out = np.zeros(v.shape[:-1] + (3, 3))
    out[..., 0, 1], out[..., 0, 2] = -v[..., 2], v[..., 1]
    out[..., 1, 0], out[..., 1, 2] = v[..., 2], -v[..., 0]
    out[..., 2, 0], out[..., 2, 1] = -v[..., 1], v[..., 0]
    return out


def line_spread(points, weights=None) -> float:
    """The spread of points (n, 3) off their best line over their spread along it: the second
    singular value of the (weighted) centred cloud over the first (0 for points on one line or
    one point, about 1 for points spread in a plane or in space)."""
    p = np.asarray(points, dtype=float).reshape(-1, 3)
    w = np.ones(len(p)) if weights is None else np.asarray(weights, dtype=float)
    centred = (p - np.average(p, axis=0, weights=w)) * np.sqrt(w / w.sum())[:, None]
    s = np.linalg.svd(centred, compute_uv=False)
    return float(s[1] / s[0]) if len(s) > 1 and s[0] > 0 else 0.0


def fit_frame(points_a, points_b, weights=None) -> tuple[RigidTransform, np.ndarray, float]:
    """The rigid motion X_AB that best maps points known in B onto the same points measured in
    A, p_AQ ~ X_AB p_BQ, by weighted least squares (scipy's ``Rotation.align_vectors`` on the
    points about their weighted centroids).

    Args:
        points_a: (n, 3) the points measured in A, m (they carry the noise).
        points_b: (n, 3) the same points in B, m (exact: a drawing).
        weights: (n,) each point's inverse variance per axis, m^-2 (1 / sigma_i^2); None: equal
            weights, the variance estimated from the residuals.
    Returns:
        (X_AB, cov (6, 6), rms): ``cov`` the covariance of the small error e of X_AB, [rotation
        vector rad, translation m] expressed in B (true X_AB = X_AB Exp(e)), from the weights
        (or, without them, the residuals' variance over their 3n - 6 degrees of freedom); rms
        the residuals' RMS, sqrt(mean |p_AQ - X_AB p_BQ|^2), m.
    Raises:
        InvalidConfigError: not (n, 3) each, of different lengths, not finite, fewer than
            :data:`MIN_POINTS` points, weights not finite and > 0, points_b on one line
            (:func:`line_spread` below :data:`MIN_LINE_SPREAD`), or points that a mirrored
            frame fits far better (:data:`MIRROR_SHARE`: a left-handed tracker).
    Source: the weighted Kabsch fit; its covariance by linearizing each residual R^T e_i =
        e x p_BQ + v about the fit (the Gauss-Newton normal matrix).
    """
    a = as_array("points_a", points_a, last=3).reshape(-1, 3)
    b = as_array("points_b", points_b, last=3).reshape(-1, 3)
    if len(a) != len(b):
        raise InvalidConfigError(f"{len(a)} points measured but {len(b)} known: pair each one")
    if len(a) < MIN_POINTS:
        raise InvalidConfigError(
            f"{len(a)} points cannot fix a frame: at least {MIN_POINTS}, not on one line"
        )
    known = weights is not None
    w = np.ones(len(a)) if weights is None else as_array("weights", weights, shape=(len(a),))
    if not np.all(w > 0):
        raise InvalidConfigError("each point's weight must be > 0 (an inverse variance, m^-2)")
    spread = line_spread(b, w)
    if spread < MIN_LINE_SPREAD:
        raise InvalidConfigError(
            f"the {len(b)} points lie on one line (their spread off it is {spread:.2g} of their "
            f"spread along it, under {MIN_LINE_SPREAD:g}): the rotation about it is unknown; "
            f"use at least {MIN_POINTS} points spread over a plane"
        )
    ca, cb = np.average(a, axis=0, weights=w), np.average(b, axis=0, weights=w)
    rotation, _ = Rotation.align_vectors(a - ca, b - cb, weights=w)
    R = rotation.as_matrix()
    t = ca - R @ cb
    residual = a - (b @ R.T + t)
    rms = float(np.sqrt(np.mean(np.sum(residual**2, axis=1))))
    _check_handedness(a - ca, b - cb, w, rms)
    # Each residual, in B: R^T (a_i - R b_i - t) = e_rot x b_i + e_trans = [-[b_i]x, I] e.
    A = np.concatenate([-_skew(b), np.broadcast_to(np.eye(3), (len(b), 3, 3))], axis=2)
    information = np.einsum("n,nki,nkj->ij", w, A, A)
    cov = np.linalg.inv(information)
    if not known:
        cov *= float(np.sum(residual**2)) / max(3 * len(a) - 6, 1)
    return RigidTransform(RotationMatrix(R), t), 0.5 * (cov + cov.T), rms


def _check_handedness(a, b, w, rms: float) -> None:
    """Refuse centred points ``a`` (measured) and ``b`` (known) that a reflection fits far
    better than the best rotation did (``rms``, m): a tracker's left-handed frame, or one of
    its axes reversed, read as a right-handed one. Points on a plane fit a reflection and a
    rotation alike (the plane turned over), and pass: only points off one plane can tell.

    Raises:
        InvalidConfigError: the mirrored fit's RMS under :data:`MIRROR_SHARE` of ``rms``.
    """
    U, _, Vt = np.linalg.svd((b * w[:, None]).T @ a)
    M = (U @ Vt).T  # the best orthogonal map, a reflection when det < 0
    if np.linalg.det(M) > 0:
        return
    mirrored = float(np.sqrt(np.mean(np.sum((a - b @ M.T) ** 2, axis=1))))
    if mirrored < MIRROR_SHARE * rms:
        raise InvalidConfigError(
            f"the measured points fit a mirrored frame ({mirrored * 1e6:.3g} um RMS) far better "
            f"than any rigid motion ({rms * 1e6:.3g} um RMS): the tracker's frame is "
            "left-handed, or one of its axes reversed, as written; export it right-handed (or "
            "negate that axis) and register again"
        )


def rigid_fit_rows(points_b, weights=None) -> np.ndarray:
    """(6, 3n) L: the small rigid motion e [rotation vector rad, translation m] that
    :func:`fit_frame` fits to points displaced by d (n, 3) from ``points_b`` (n, 3), to first
    order e = L d.ravel() (about X_AB = I; each point weighted as in :func:`fit_frame`)."""
    b = np.asarray(points_b, dtype=float).reshape(-1, 3)
    w = np.ones(len(b)) if weights is None else np.asarray(weights, dtype=float)
    A = np.concatenate([-_skew(b), np.broadcast_to(np.eye(3), (len(b), 3, 3))], axis=2)
    information = np.einsum("n,nki,nkj->ij", w, A, A)
    rows = np.einsum("n,nki->ink", w, A).reshape(6, -1)
    return np.linalg.solve(information, rows)


def _pose_vector(X: RigidTransform) -> np.ndarray:
    """(6,) [phi, theta, psi, x, y, z] of X (roll-pitch-yaw as rotation_rpy)."""
    return np.concatenate([RollPitchYaw(X.rotation()).vector(), X.translation()])


def _transform(x) -> RigidTransform:
    """X of a pose vector (6,) [phi, theta, psi, x, y, z], rad and m."""
    x = np.asarray(x, dtype=float)
    return RigidTransform(RollPitchYaw(x[:3]), x[3:6])


@dataclass(frozen=True)
class Registration:
    """The tracker's frames in the robot's (module docstring).

    Attributes:
        X_TB: the base frame B in the tracker's frame T.
        X_PM: the marker M in the platform frame P (the identity when REG.yaml gives no
            ``platform_points``).
        cov_B: (6, 6) covariance of X_TB's small error e_B (true X_TB = X_TB Exp(e_B)),
            [rotation vector rad, translation m] in B.
        cov_M: (6, 6) covariance of X_PM's small error e_M (true X_PM = Exp(e_M) X_PM), same
            units, in P (zeros when X_PM is the identity by definition).
        rms_base_m, rms_platform_m: the fits' residuals, RMS, m (0 without platform points).
        base_points, platform_points: how many fiducials each fit used (0: none).
        source: for frames fitted to a registration motion, that fit in words ("" for
            fiducials).
    """

    X_TB: RigidTransform
    X_PM: RigidTransform
    cov_B: np.ndarray
    cov_M: np.ndarray
    rms_base_m: float
    rms_platform_m: float
    base_points: int = 0
    platform_points: int = 0
    source: str = ""

    def base_poses(self, poses_TM) -> np.ndarray:
        """The platform's poses in the base frame from the marker's in the tracker's frame:
        X_BP = X_TB^-1 X_TM X_PM^-1.

        Args:
            poses_TM: (N, 6) or (6,) the marker's poses in T, [phi, theta, psi, X, Y, Z], rad
                and m (R = Rz(psi) Ry(theta) Rx(phi), as
                :func:`~stewart_drake.robot.kinematics.rotation_rpy`).
        Returns:
            (N, 6) X_BP as pose vectors, same layout and units.
        Raises:
            InvalidConfigError: not (N, 6), not finite, a position beyond 1 km.
        """
        return _compose(self.X_TB.inverse(), poses_TM, self.X_PM.inverse())

    def tracker_poses(self, poses_BP) -> np.ndarray:
        """The inverse of :meth:`base_poses`: the marker's poses in T, X_TM = X_TB X_BP X_PM,
        from the platform's in B (N, 6) -> (N, 6), same layout and units."""
        return _compose(self.X_TB, poses_BP, self.X_PM)

    def pose_jacobians(self, poses_BP) -> np.ndarray:
        """(N, 6, 12) how the frames' errors [e_B, e_M] move the base-frame poses converted
        (N, 6): the true pose is the converted one displaced by J [e_B, e_M], the displacement
        [a small rotation of R_BP in B (rad), of p_BP in B (m)] (the identification's pose
        derivatives take it)."""
        x = as_poses("poses_BP", poses_BP).reshape(-1, 6)
        R, p = rotation_rpy(x[:, :3]), x[:, 3:]
        J = np.zeros((len(x), 6, 12))
        J[:, :3, :3] = -np.eye(3)  # X_BP = Exp(-e_B) X_BP: turned about B's origin
        J[:, 3:, :3] = _skew(p)
        J[:, 3:, 3:6] = -np.eye(3)
        J[:, :3, 6:9] = -R  # X_BP = X_BP Exp(-e_M): moved in P
        J[:, 3:, 9:] = -R
        return J

    def frames_covariance(self) -> np.ndarray:
        """(12, 12) the covariance of [e_B, e_M] (the two fits are independent)."""
        C = np.zeros((12, 12))
        C[:6, :6], C[6:, 6:] = self.cov_B, self.cov_M
        return C

    def pose_covariances(self, poses_BP, rotation_rad: float, translation_m: float):
        """(N, 6, 6) the covariance of each base-frame pose converted from a marker pose that
        the tracker measured with isotropic noise (``rotation_rad``, ``translation_m`` per
        axis, a small rotation in T and a shift): its rotation as measured, its position moved
        also by the rotation's error times the lever arm from the marker to P's origin."""
        x = as_poses("poses_BP", poses_BP).reshape(-1, 6)
        R_BP = rotation_rpy(x[:, :3])
        # The marker's rotation error turns P's origin about the marker: p_BP = p_BM + r with
        # r = R_BM p_MP = -R_BP p_PM, so dp_BP = n + delta x r.
        lever = -np.einsum("nij,j->ni", R_BP, self.X_PM.translation())
        J = np.zeros((len(x), 6, 6))
        J[:, :3, :3] = np.eye(3)
        J[:, 3:, :3] = -_skew(lever)
        J[:, 3:, 3:] = np.eye(3)
        sig = np.array([rotation_rad] * 3 + [translation_m] * 3) ** 2
        return np.einsum("nik,k,njk->nij", J, sig, J)

    def words(self) -> str:
        """The frames and their standard deviations as one line of text."""
        if self.source:
            return (
                f"X_TB {transform_words(self.X_TB, self.cov_B)}, X_PM "
                f"{transform_words(self.X_PM, self.cov_M)}, {self.source}"
            )
        marker = (
            f"X_PM {transform_words(self.X_PM, self.cov_M)} from {self.platform_points} "
            f"fiducials ({self.rms_platform_m * 1e6:.3g} um RMS)"
            if self.platform_points
            else "the marker is the platform frame (no platform_points)"
        )
        return (
            f"X_TB {transform_words(self.X_TB, self.cov_B)} from {self.base_points} fiducials "
            f"({self.rms_base_m * 1e6:.3g} um RMS); {marker}"
        )


@dataclass(frozen=True)
class RegisteredPoses:
    """Marker poses converted to the base frame, with what an identification needs of their
    errors (:func:`~.identify.identify`'s ``pose_covariances`` and ``frames``).

    Attributes:
        poses: (N, 6) the platform's poses in B, [rad, m].
        pose_covariances: (N, 6, 6) each one's noise (:meth:`Registration.pose_covariances`).
        frames: (J (N, 6, 12), C (12, 12)): the frames' error common to all of them
            (:meth:`Registration.pose_jacobians`, :meth:`Registration.frames_covariance`).
    """

    poses: np.ndarray
    pose_covariances: np.ndarray
    frames: tuple


def register_poses(
    registration: Registration, poses_TM, rotation_rad: float, translation_m: float
) -> RegisteredPoses:
    """:class:`RegisteredPoses` of the marker poses (N, 6) in T that a tracker measured with
    ``rotation_rad`` and ``translation_m`` of noise per axis.

    Raises:
        InvalidConfigError: poses not (N, 6), not finite, beyond 1 km.
    """
    x = registration.base_poses(poses_TM)
    return RegisteredPoses(
        x,
        registration.pose_covariances(x, rotation_rad, translation_m),
        (registration.pose_jacobians(x), registration.frames_covariance()),
    )


def transform_words(X: RigidTransform, cov: np.ndarray, exact: bool = False) -> str:
    """X and the standard deviation of its error as text, e.g. "rpy_rad [0, 0, 0.52], xyz_m
    [1, 0.2, 0] (+- 5.9 urad, 1.1 um per axis)"; ``exact``: every digit a float64 holds."""
    x = _pose_vector(X)

    def numbers(v):
        return ", ".join(repr(float(a)) if exact else f"{a:.6g}" for a in v)

    angle, shift = np.sqrt(np.trace(cov[:3, :3]) / 3), np.sqrt(np.trace(cov[3:, 3:]) / 3)
    return (
        f"rpy_rad [{numbers(x[:3])}], xyz_m [{numbers(x[3:])}] (+- {angle * 1e6:.3g} urad, "
        f"{shift * 1e6:.3g} um per axis)"
    )


def _compose(X_left: RigidTransform, poses, X_right: RigidTransform) -> np.ndarray:
    """(N, 6) the pose vectors of X_left X(x) X_right for each pose vector x of ``poses``."""
    x = as_poses("poses", poses).reshape(-1, 6)
    R = rotation_rpy(x[:, :3])
    Rl, pl = X_left.rotation().matrix(), X_left.translation()
    Rr, pr = X_right.rotation().matrix(), X_right.translation()
    R_out = Rl @ R @ Rr
    p_out = (np.einsum("nij,j->ni", R, pr) + x[:, 3:]) @ Rl.T + pl
    rpy = Rotation.from_matrix(R_out).as_euler("ZYX")[:, ::-1]
    return np.column_stack([rpy, p_out])


@dataclass(frozen=True)
class Fiducials:
    """What a REG.yaml holds (:mod:`~.registration_file`), as arrays in SI units.

    Attributes:
        base_B: (n, 3) the base's fiducials where the drawing puts them, in B, m.
        base_T: (n, 3) the same where the tracker saw them, in T, m.
        platform_P, platform_T: (m, 3) the platform's fiducials in P and in T, m, or None.
        marker_TM: (6,) the marker's pose in T when the platform's fiducials were measured,
            [phi, theta, psi, X, Y, Z] rad and m, or None (with ``platform_P``).
        point_sigma_m: a fiducial's measurement noise, one standard deviation per axis, m.
        marker_sigma: (rad, m) the noise of ``marker_TM``, per axis.
    """

    base_B: np.ndarray
    base_T: np.ndarray
    platform_P: np.ndarray | None = None
    platform_T: np.ndarray | None = None
    marker_TM: np.ndarray | None = None
    point_sigma_m: float = DEFAULT_POINT_SIGMA_M
    marker_sigma: tuple = DEFAULT_MARKER_SIGMA


def _marker_covariance(X_PM: RigidTransform, sigma) -> np.ndarray:
    """(6, 6) the covariance of X_PM's error e_M (in P) that the marker's measurement noise
    ``sigma`` (rad, m per axis: a small rotation u of R_TM in T and a shift m of p_TM) makes:
    X_PM = X_PT X_TM, so e_M = [u, m + p_PM x u] with u, m turned into P (isotropic noises
    stay isotropic when turned)."""
    J = np.eye(6)
    J[3:, :3] = _skew(X_PM.translation())
    sig = np.array([sigma[0]] * 3 + [sigma[1]] * 3) ** 2
    return J @ np.diag(sig) @ J.T


def _fit(points_T, points_R, sigma, what: str):
    """(X_TR, cov, rms) of a frame R from its fiducials, the covariance scaled by the residuals'
    reduced chi-square when they show more noise than ``sigma`` says.

    Raises:
        InvalidConfigError: as :func:`fit_frame`, residuals over :data:`MAX_FIT_RMS_M`, or a
            rotation known to worse than :data:`MAX_ROTATION_SIGMA_RAD` (points too close).
    """
    try:
        X, cov, rms = fit_frame(points_T, points_R, np.full(len(points_R), sigma**-2.0))
    except InvalidConfigError as err:
        raise InvalidConfigError(f"{what}: {err}") from None
    if rms > MAX_FIT_RMS_M:
        raise InvalidConfigError(
            f"{what}: the fiducials fit no rigid motion ({rms * 1e3:.3g} mm RMS off it, over "
            f"{MAX_FIT_RMS_M * 1e3:g} mm): check that each tracker_m is the same point as its "
            f"drawing's, in the same order, both in m"
        )
    chi2 = len(points_R) * rms**2 / (sigma**2 * max(3 * len(points_R) - 6, 1))
    cov = cov * max(1.0, chi2)
    turn = float(np.sqrt(np.max(np.linalg.eigvalsh(cov[:3, :3]))))
    if turn > MAX_ROTATION_SIGMA_RAD:
        extent = float(np.sqrt(np.mean(np.sum((points_R - points_R.mean(axis=0)) ** 2, axis=1))))
        raise InvalidConfigError(
            f"{what}: the fiducials are {extent * 1e3:.3g} mm RMS from their centre, too close to "
            f"fix a frame: its rotation is known to +- {turn * 1e3:.3g} mrad only (at most "
            f"{MAX_ROTATION_SIGMA_RAD * 1e3:g}); use fiducials spread over the body"
        )
    return X, cov, rms


def register(fiducials: Fiducials, where: str = "REG.yaml") -> Registration:
    """The :class:`Registration` that ``fiducials`` give (module docstring).

    Args:
        fiducials: :class:`Fiducials`.  where: how messages name their source (the file).
    Raises:
        InvalidConfigError: a fit refused (:func:`fit_frame`: fewer than 3 points, points on
            one line; the points fit no rigid motion), naming ``where`` and the section.
    """
    sigma = fiducials.point_sigma_m
    X_TB, cov_B, rms_B = _fit(fiducials.base_T, fiducials.base_B, sigma, f"{where}: base_points")
    if fiducials.platform_P is None:
        return Registration(
            X_TB, RigidTransform(), cov_B, np.zeros((6, 6)), rms_B, 0.0, len(fiducials.base_B), 0
        )
    X_TP, cov_P, rms_P = _fit(
        fiducials.platform_T, fiducials.platform_P, sigma, f"{where}: platform_points.points"
    )
    X_PM = X_TP.inverse() @ _transform(fiducials.marker_TM)
    cov_M = cov_P + _marker_covariance(X_PM, fiducials.marker_sigma)
    return Registration(
        X_TB, X_PM, cov_B, cov_M, rms_B, rms_P, len(fiducials.base_B), len(fiducials.platform_P)
    )
