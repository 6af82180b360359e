"""Identification of the per-leg parameters from poses measured by a tracker and the encoders'
readings there, with its identifiability analysis, uncertainties and outliers.

The residual of reading j at pose k is the model's prediction minus the reading, r = theta(x_k; p) +
o - q (:func:`~stewart_drake.robot.legs.readings`, wrapped to [-pi, pi)), whitened by the noise it
carries: the tracker's noise mapped through the derivative of the readings with respect to the pose,
and the encoders' quantization, Sigma_k = G_k diag(sigma_rot^2 I, sigma_pos^2 I) G_k^T + (quantum^2
/ 12) I (6 x 6 per pose: one pose error moves all six readings), r_w = L_k^-1 r with Sigma_k = L_k
L_k^T, evaluated once at the nominal robot. ``scipy.optimize.least_squares`` minimizes sum |r_w|^2
(or a robust loss of it) over the deviation vector of :mod:`~stewart_drake.robot.legs`.

Identifiability. The deviations are scaled by their tolerances' standard deviations (each unit is
one standard deviation of the robot as drawn, :class:`~stewart_drake.robot.tolerances.Tolerances`),
and the whitened Jacobian J_s = L^-1 J diag(std) is decomposed, J_s = U S V^T. A combination v_i
(a column of V) is determined by the data to 1 / S_i (in the prior's standard deviations); the
rule: **a combination whose singular value is below ``min_singular`` (default 1: the data tell
less about it than the tolerance already does) is not identified and stays nominal** (the
least-squares solution of minimum norm in the scaled deviations: the step is confined to the
other combinations). A parameter of zero tolerance is not identified at all. Each identified
parameter's covariance is s^2 diag(std) V_k S_k^-2 V_k^T diag(std) with s^2 the residuals'
reduced chi-square. Outliers: a reading whose studentized residual r / (s sqrt(Sigma_jj - h_jj))
(h_jj the variance the fit's parameters explain, J C J^T) exceeds ``outlier_threshold`` is
flagged; ``drop_outliers`` identifies again without the poses that hold one, ``robust`` uses the
soft-L1 loss instead of the square.

Registered poses. Poses converted from a tracker's frame (:mod:`~.registration`) carry two more
errors. Their own noise, turned by the marker's lever arm, is each pose's: ``pose_covariances``
replaces the isotropic diag(sigma_rot^2 I, sigma_pos^2 I) in Sigma_k. The frames' error is the
same in every pose, so it does not average out over them and would be wrong as a noise per pose:
it moves every reading at once (r_k changes by G_k J_k e for a frames' error e of covariance C,
``frames = (J, C)``), and the per-leg parameters absorb such a rigid motion of the base or of the
platform whole. It is carried to the parameters instead: their covariance gains K C K^T, K the
least-squares solution's derivative with respect to e (:attr:`Identification.frames_covariance`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import least_squares
from scipy.spatial.transform import Rotation

from ..base.checks import as_array, as_number, as_poses
from ..base.errors import InvalidConfigError, UnreachablePoseError
from ..robot.geometry import StewartGeometry
from ..robot.kinematics import wrap_angle
from ..robot.legs import (
    N_PARAMETERS,
    LegParameters,
    derivatives,
    parameter_kinds,
    parameter_legs,
    parameter_names,
    readings,
)
from ..robot.tolerances import Tolerances
from .registration import fit_frame, rigid_fit_rows
from .tracker import MeasurementNoise

#: Fewest poses an identification takes: each leg's 11 parameters are seen only through its
#: own reading at each pose, so every leg needs more readings than that.
MIN_POSES = 12
#: Default threshold of a flagged reading's studentized residual.
OUTLIER_THRESHOLD = 4.0
#: Default rule of identifiability: a scaled combination with a smaller singular value stays
#: nominal (the data know it less well than its tolerance).
MIN_SINGULAR = 1.0


@dataclass(frozen=True)
class Combination:
    """A combination of parameters the data do not determine, kept at its nominal value.

    Attributes:
        direction: (66,) unit vector in the scaled deviations (tolerance units).
        singular_value: its singular value S_i: the data determine it to 1 / S_i tolerance
            standard deviations.
        terms: ((name, coefficient), ...) its largest terms, in physical units' names.
    """

    direction: np.ndarray
    singular_value: float
    terms: tuple

    def words(self) -> str:
        """The combination as text, e.g. "0.71 crank_angles_deg[2] - 0.70 pivot_offsets_m[2].y
        (S = 0.3)"."""
        text = ""
        for k, (name, c) in enumerate(self.terms):
            sign = "-" if c < 0 else ("+" if k else "")
            text += f" {sign} {abs(c):.2f} {name}" if k else f"{sign}{abs(c):.2f} {name}"
        return f"{text} (S = {self.singular_value:.3g})"


@dataclass(frozen=True)
class Outlier:
    """A reading flagged as an outlier: pose (row of the measurements), leg, its residual in
    rad and its studentized residual."""

    pose: int
    leg: int
    residual_rad: float
    studentized: float


@dataclass(frozen=True)
class Identification:
    """What :func:`identify` found.

    Attributes:
        nominal, identified: :class:`~stewart_drake.robot.legs.LegParameters` before and after.
        deviation: (66,) identified minus nominal, units of the deviation vector
            (:mod:`~stewart_drake.robot.legs`).
        std: (66,) each entry's standard deviation from the residuals (0 for a parameter that
            stays nominal by the rule), same units.
        covariance: (66, 66) of the identified deviations, same units.
        scale: (66,) the tolerances' standard deviations the analysis scales by.
        singular_values: of the scaled, whitened Jacobian at the nominal robot (where the rule
            is applied), descending.
        fixed: the :class:`Combination` s kept nominal (they span ``fixed_basis``).
        fixed_basis: (k, 66) orthonormal rows spanning the combinations kept nominal.
        outliers: the :class:`Outlier` s flagged (on the poses used).
        used: (N,) bool, the poses the identification used (all unless outliers were dropped).
        rms_before_rad, rms_after_rad: RMS of the readings' residuals (model minus read) with
            the nominal and the identified robot, over the poses used, rad.
        chi2_reduced: sum of the whitened residuals' squares over their degrees of freedom
            (about 1 when the noise is as stated).
        dof: readings used minus parameters identified.
        nfev: residual evaluations of ``least_squares``.
        frames_covariance: (66, 66) the part of ``covariance`` that the frames' error of
            registered poses makes (zeros without one), same units.
    """

    nominal: LegParameters
    identified: LegParameters
    deviation: np.ndarray
    std: np.ndarray
    covariance: np.ndarray
    scale: np.ndarray
    singular_values: np.ndarray
    fixed: tuple
    fixed_basis: np.ndarray
    outliers: tuple
    used: np.ndarray
    rms_before_rad: float
    rms_after_rad: float
    chi2_reduced: float
    dof: int
    nfev: int
    frames_covariance: np.ndarray | None = None

    @property
    def identified_mask(self) -> np.ndarray:
        """(66,) bool: the parameters with a nonzero tolerance (those the fit may move)."""
        return self.scale > 0

    def prior_covariance(self) -> np.ndarray:
        """(66, 66) what is left of the tolerances' covariance in the fixed combinations (what
        keeping them nominal may cost), same units as :attr:`covariance`."""
        V = self.fixed_basis
        return (self.scale[:, None] * (V.T @ V)) * self.scale[None, :]


def check_measurements(poses, q) -> tuple[np.ndarray, np.ndarray]:
    """(poses (N, 6), readings (N, 6)) checked for :func:`identify`.

    Raises:
        InvalidConfigError: not (N, 6) each, not finite, of different lengths, or fewer than
            :data:`MIN_POSES` poses.
    """
    poses = as_poses("measured poses", poses).reshape(-1, 6)
    q = as_array("encoder readings", q, last=6).reshape(-1, 6)
    if len(q) != len(poses):
        raise InvalidConfigError(f"{len(poses)} poses but {len(q)} rows of readings")
    if len(poses) < MIN_POSES:
        raise InvalidConfigError(
            f"{len(poses)} poses are too few to identify the parameters: each leg's 11 are "
            f"seen only through its own reading, so at least {MIN_POSES} poses are needed (60 "
            f"or more for a useful accuracy, docs/calibration.md)"
        )
    return poses, q


def reading_covariances(
    geometry: StewartGeometry,
    legs: LegParameters,
    poses,
    noise: MeasurementNoise,
    pose_covariances=None,
) -> np.ndarray:
    """(N, 6, 6) Sigma_k, each pose's readings' covariance (module docstring), rad^2, at the
    robot ``legs``; ``pose_covariances`` (N, 6, 6), [rad, m]^2 of a small rotation in B and a
    shift, in place of the tracker's isotropic noise (registered poses)."""
    G = derivatives(geometry, legs, poses).pose
    if pose_covariances is None:
        sig = np.array([noise.rotation_rad] * 3 + [noise.translation_m] * 3) ** 2
        poses_part = np.einsum("nik,k,njk->nij", G, sig, G)
    else:
        poses_part = np.einsum("nik,nkl,njl->nij", G, pose_covariances, G)
    return poses_part + noise.quantization_rms_rad**2 * np.eye(6)


def whitening(
    geometry: StewartGeometry,
    legs: LegParameters,
    poses,
    noise: MeasurementNoise,
    pose_covariances=None,
):
    """(N, 6, 6) L_k^-1 of each pose's readings' covariance Sigma_k = L_k L_k^T
    (:func:`reading_covariances`)."""
    Sigma = reading_covariances(geometry, legs, poses, noise, pose_covariances)
    return np.linalg.inv(np.linalg.cholesky(Sigma))


def _residuals(geometry, legs, poses, q) -> np.ndarray:
    """(N, 6) model minus reading, wrapped to [-pi, pi), rad."""
    return wrap_angle(readings(geometry, legs, poses) - q)


def singular_values(J: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(S descending, V^T) of the tall matrix J (m, n), from the eigenvalues of J^T J (n, n):
    LAPACK's SVD of the tall matrix waits on BLAS threads on a busy machine, the small
    symmetric problem does not. Singular values below about 1e-8 S_max are not resolved (an
    exact gauge shows as such a value, far below the rule's threshold)."""
    w, V = np.linalg.eigh(J.T @ J)
    order = np.argsort(w)[::-1]
    return np.sqrt(np.clip(w[order], 0.0, None)), V[:, order].T


def _fixed_combinations(Vt, S, min_singular, names) -> tuple:
    """The :class:`Combination` s that span the rows of Vt whose singular values S are below
    ``min_singular``, written so that each reads: reduced row echelon form with column pivoting
    (each combination leads with a parameter the others do not hold), normalized; the span, and
    so what is kept nominal, is the same. Each one's singular value is |J_s v| / |v| (from S and
    Vt)."""
    import scipy.linalg

    fixed = Vt[S < min_singular]
    if not len(fixed):
        return ()
    _, _, pivots = scipy.linalg.qr(fixed, pivoting=True)
    lead = np.sort(pivots[: len(fixed)])
    rows = np.linalg.solve(fixed[:, lead], fixed)  # identity on the leading columns
    out = []
    for v in rows:
        v = v / np.linalg.norm(v)
        v = v if v[np.argmax(np.abs(v))] > 0 else -v
        order = np.argsort(-np.abs(v))
        terms = tuple((names[j], float(v[j])) for j in order[:4] if abs(v[j]) >= 0.15)
        gain = float(np.linalg.norm(S * (Vt @ v)))
        out.append(Combination(direction=v, singular_value=gain, terms=terms))
    return tuple(sorted(out, key=lambda c: c.singular_value))


def identify(
    geometry: StewartGeometry,
    poses,
    q,
    noise: MeasurementNoise,
    tolerances: Tolerances | None = None,
    min_singular: float = MIN_SINGULAR,
    outlier_threshold: float = OUTLIER_THRESHOLD,
    robust: bool = False,
    drop_outliers: bool = False,
    pose_covariances=None,
    frames=None,
) -> Identification:
    """Identify the robot's per-leg parameters from measured poses and readings.

    Args:
        geometry: the nominal robot.
        poses: (N, 6) the platform's poses as the tracker measured them, [rad, m].
        q: (N, 6) the encoders' readings there, rad (any whole turn: residuals are wrapped).
        noise: what the measurements carry (:class:`~.tracker.MeasurementNoise`).
        tolerances: the robot's tolerances, the scale of each parameter (default
            :class:`~stewart_drake.robot.tolerances.Tolerances`); a zero half-width keeps that
            parameter nominal.
        min_singular: the identifiability rule's threshold (module docstring), > 0.
        outlier_threshold: a reading with a larger studentized residual is flagged.
        robust: the soft-L1 loss (scale 3 whitened units) instead of least squares.
        drop_outliers: identify again without the poses holding a flagged reading.
        pose_covariances: (N, 6, 6) each pose's noise, [rad, m]^2 (a small rotation in B and a
            shift), in place of ``noise``'s isotropic one (registered poses: module docstring).
        frames: (J (N, 6, k), C (k, k)): an error e common to every pose, of covariance C, that
            moves pose k by J_k e (the registration's frames), carried to the covariance.
    Returns:
        :class:`Identification`.
    Raises:
        InvalidConfigError: the measurements as :func:`check_measurements` says, a threshold
            out of range.
        UnreachablePoseError: a measured pose the nominal robot cannot reach (not this robot's
            poses, or the wrong units).
    Source: the textbook identification of a parallel robot from external pose measurements
        (least squares on the inverse kinematics' residuals, an SVD of the scaled Jacobian).
    """
    poses, q = check_measurements(poses, q)
    extra = _check_registered(len(poses), pose_covariances, frames)
    tolerances = Tolerances() if tolerances is None else tolerances
    min_singular = as_number("min_singular", min_singular, 0.0, lo_open=True)
    outlier_threshold = as_number("outlier_threshold", outlier_threshold, 0.0, lo_open=True)
    used = np.ones(len(poses), dtype=bool)
    result = _identify_once(
        geometry, poses, q, noise, tolerances, min_singular, robust, used, outlier_threshold, extra
    )
    if drop_outliers and result.outliers:
        for o in result.outliers:
            used[o.pose] = False
        if used.sum() < MIN_POSES:
            raise InvalidConfigError(
                f"dropping the {int((~used).sum())} poses with outliers leaves {int(used.sum())}, "
                f"fewer than {MIN_POSES}: measure again, or identify without --drop-outliers"
            )
        result = _identify_once(
            geometry,
            poses,
            q,
            noise,
            tolerances,
            min_singular,
            robust,
            used,
            outlier_threshold,
            extra,
        )
    return result


def _check_registered(n: int, pose_covariances, frames) -> tuple:
    """(pose_covariances (n, 6, 6) or None, frames (J (n, 6, k), C (k, k)) or None), checked.

    Raises:
        InvalidConfigError: a shape other than these, not finite, a covariance not symmetric
            positive semi-definite.
    """
    if pose_covariances is not None:
        pose_covariances = as_array("pose_covariances", pose_covariances, shape=(n, 6, 6))
        _check_covariance("pose_covariances", pose_covariances)
    if frames is not None:
        J = as_array("frames' pose derivatives", frames[0])
        if J.ndim != 3 or J.shape[:2] != (n, 6):
            raise InvalidConfigError(f"the frames' pose derivatives must be ({n}, 6, k)")
        C = as_array("frames' covariance", frames[1], shape=(J.shape[2],) * 2)
        _check_covariance("the frames' covariance", C[None])
        frames = (J, C)
    return pose_covariances, frames


def _check_covariance(name: str, C: np.ndarray) -> None:
    """Raises InvalidConfigError unless each C[k] is symmetric positive semi-definite."""
    scale = max(float(np.abs(C).max()), 1e-300)
    if np.abs(C - np.swapaxes(C, 1, 2)).max() > 1e-9 * scale or (
        np.linalg.eigvalsh(C).min() < -1e-9 * scale
    ):
        raise InvalidConfigError(f"{name} must be symmetric positive semi-definite")


def _frames_covariance(W, G, frames, used, Jb, N_inv, basis, scale) -> np.ndarray:
    """(66, 66) K C K^T of the module docstring: K = N^-1 Jb^T (W G J) the identified
    combinations' derivative with respect to the frames' error, mapped to the parameters."""
    if frames is None:
        return np.zeros((len(scale), len(scale)))
    J, C = frames[0][used], frames[1]
    D = np.einsum("nij,njk,nkl->nil", W, G, J).reshape(-1, J.shape[2])
    K = basis @ (N_inv @ (Jb.T @ D))
    return scale[:, None] * (K @ C @ K.T) * scale[None, :]


def _identify_once(
    geometry, poses, q, noise, tolerances, min_singular, robust, used, outlier_threshold, extra
) -> Identification:
    """One identification on the poses ``used`` (see :func:`identify`)."""
    nominal = LegParameters.nominal(geometry)
    x, y = poses[used], q[used]
    pose_covariances, frames = extra
    Sigma = reading_covariances(
        geometry, nominal, x, noise, None if pose_covariances is None else pose_covariances[used]
    )
    W = np.linalg.inv(np.linalg.cholesky(Sigma))
    scale = tolerances.stds()
    active = scale > 0
    names = parameter_names()

    def jac_scaled(legs):
        J = derivatives(geometry, legs, x).parameters  # (N, 6, 66)
        return np.einsum("nij,njk->nik", W, J).reshape(-1, N_PARAMETERS) * scale

    S0, Vt0 = singular_values(jac_scaled(nominal)[:, active])
    basis = np.zeros((N_PARAMETERS, int(np.sum(S0 >= min_singular))))
    basis[active] = Vt0[S0 >= min_singular].T  # identified combinations, scaled units

    def fun(z):
        legs = nominal.shifted(scale * (basis @ z))
        r = _residuals(geometry, legs, x, y)
        return np.einsum("nij,nj->ni", W, r).ravel()

    def jac(z):
        return jac_scaled(nominal.shifted(scale * (basis @ z))) @ basis

    # MINPACK's Levenberg-Marquardt for squares; the trust region with LSMR for the robust
    # loss (its dense solver's SVDs of the tall Jacobian wait on BLAS threads on a busy machine).
    options = (
        dict(method="trf", loss="soft_l1", f_scale=3.0, tr_solver="lsmr")
        if robust
        else dict(method="lm")
    )
    try:
        fit = least_squares(
            fun,
            np.zeros(basis.shape[1]),
            jac=jac,
            x_scale=1.0,
            xtol=1e-12,
            ftol=1e-12,
            gtol=1e-12,
            **options,
        )
    except UnreachablePoseError as err:  # the fit left every robot near the drawing
        worst = np.abs(_residuals(geometry, nominal, x, y)).max(axis=0)
        raise InvalidConfigError(
            f"the readings fit no robot near the drawing: explaining them moved leg {err.leg} "
            f"so far that it could not reach a measured pose; the nominal robot misses the "
            f"readings by up to {', '.join(f'q{i} {v:.3g}' for i, v in enumerate(worst))} rad: "
            f"check the readings' columns, units and encoder zeros (zero_counts)"
        ) from None
    delta = scale * (basis @ fit.x)
    identified = nominal.shifted(delta)
    # The covariance and the leverages at the solution, in the combinations identified.
    Jb = jac_scaled(identified) @ basis
    r_w = fun(fit.x)
    m, k = r_w.size, basis.shape[1]
    dof = max(m - k, 1)
    chi2 = float(r_w @ r_w) / dof
    N_inv = np.linalg.inv(Jb.T @ Jb)  # k x k, well conditioned: only S >= min_singular
    cov_scaled = chi2 * basis @ N_inv @ basis.T
    covariance = scale[:, None] * cov_scaled * scale[None, :]
    Vt_full = np.zeros((len(S0), N_PARAMETERS))
    Vt_full[:, active] = Vt0
    # Each reading's residual against its own deviation, Sigma_jj less what the fit took of it.
    at_solution = derivatives(geometry, identified, x)
    Jr = (at_solution.parameters * scale).reshape(-1, N_PARAMETERS) @ basis
    frames_part = _frames_covariance(W, at_solution.pose, frames, used, Jb, N_inv, basis, scale)
    covariance = covariance + frames_part
    var = np.diagonal(Sigma, axis1=1, axis2=2).ravel() - np.einsum("mi,ij,mj->m", Jr, N_inv, Jr)
    raw = _residuals(geometry, identified, x, y)
    studentized = raw.ravel() / np.sqrt(chi2 * np.clip(var, 1e-30, None))
    rows = np.flatnonzero(used)
    flagged = np.flatnonzero(np.abs(studentized) > outlier_threshold)
    outliers = tuple(
        Outlier(int(rows[j // 6]), j % 6, float(raw.ravel()[j]), float(studentized[j]))
        for j in map(int, flagged)
    )
    before = _residuals(geometry, nominal, x, y)
    return Identification(
        nominal=nominal,
        identified=identified,
        deviation=delta,
        std=np.sqrt(np.clip(np.diag(covariance), 0.0, None)),
        covariance=covariance,
        scale=scale,
        singular_values=S0,
        fixed=_fixed_combinations(Vt_full, S0, min_singular, names),
        fixed_basis=Vt_full[S0 < min_singular],
        outliers=outliers,
        used=used.copy(),
        rms_before_rad=float(np.sqrt(np.mean(before**2))),
        rms_after_rad=float(np.sqrt(np.mean(raw**2))),
        chi2_reduced=chi2,
        dof=dof,
        nfev=int(fit.nfev),
        frames_covariance=frames_part,
    )


def predicted_rms(
    geometry: StewartGeometry, ident: Identification, poses, noise: MeasurementNoise
) -> float:
    """The RMS error of the identified robot's predicted readings at poses (N, 6) that the
    identification's own covariance predicts, rad: the parameters' covariance (with what the
    fixed combinations may hold, :meth:`Identification.prior_covariance`) mapped through the
    readings' derivatives, and the readings' quantization."""
    J = derivatives(geometry, ident.identified, poses).parameters
    C = ident.covariance + ident.prior_covariance()
    var = np.einsum("nik,kl,nil->ni", J, C, J)
    return float(np.sqrt(np.mean(var) + noise.quantization_rms_rad**2))


def kinds_and_legs() -> tuple[tuple[str, ...], np.ndarray]:
    """(the kind of each parameter, the leg of each), for reports."""
    return parameter_kinds(), parameter_legs()


#: The chi-square (6 degrees of freedom) beyond which a rigid motion of the pivots or of the
#: platform joints is refused as a robot's: 0.1 % of robots within their tolerances exceed it
#: (``scipy.stats.chi2.ppf(0.999, 6)``).
RIGID_MOTION_CHI2 = 22.458
#: Where each set of joints is in the deviation vector: (frame, its first entry).
_JOINT_SETS = (("base", 0), ("platform", 18))


@dataclass(frozen=True)
class RigidMotion:
    """How far the identified pivots (``frame`` "base", in B) or platform joints ("platform",
    in E) moved together, as one rigid body, from the drawing.

    Attributes:
        frame: "base" or "platform".
        angle_rad: the rigid motion's rotation angle, rad.
        shift_m: its translation's norm at the joints' centroid, m.
        chi2: its Mahalanobis distance squared (6 degrees of freedom) against the spread that
            the tolerances and the identification's uncertainty give such a motion.
    """

    frame: str
    angle_rad: float
    shift_m: float
    chi2: float

    @property
    def beyond(self) -> bool:
        """Whether no robot within its tolerances moves so (:data:`RIGID_MOTION_CHI2`)."""
        return self.chi2 > RIGID_MOTION_CHI2


def rigid_motions(geometry: StewartGeometry, ident: Identification) -> tuple:
    """The :class:`RigidMotion` of the base's pivots and of the platform's joints that the
    identification found: the rigid fit of the identified joints to the nominal ones
    (:func:`~.registration.fit_frame`), and its chi-square against its covariance L (T + C) L^T,
    T the tolerances' (each coordinate's standard deviation squared), C the identification's,
    L the fit's derivative with respect to the joints' deviations. Poses measured in another
    frame than B (a tracker turned or shifted) move every pivot so; a marker off the platform
    frame moves every platform joint so.
    """
    out = []
    for frame, start in _JOINT_SETS:
        nominal = geometry.P_B if frame == "base" else geometry.p_E
        block = slice(start, start + 18)
        d = ident.deviation[block].reshape(6, 3)
        X, _, _ = fit_frame(nominal + d, nominal)
        e = np.concatenate(
            [Rotation.from_matrix(X.rotation().matrix()).as_rotvec(), X.translation()]
        )
        L = rigid_fit_rows(nominal)  # (6, 18): e = L d to first order
        C = np.diag(ident.scale[block] ** 2) + ident.covariance[block, block]
        cov = L @ C @ L.T
        chi2 = float(e @ np.linalg.lstsq(cov, e, rcond=None)[0]) if np.any(cov) else 0.0
        centroid = nominal.mean(axis=0)
        shift = X.multiply(centroid) - centroid
        out.append(
            RigidMotion(frame, float(np.linalg.norm(e[:3])), float(np.linalg.norm(shift)), chi2)
        )
    return tuple(out)
