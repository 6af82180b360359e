"""Identification of the per-leg parameters from poses measured by a tracker and the encoders'
readings there: a maximum a posteriori estimate with the tolerances as its prior (whitened
residuals of the readings and one prior row per parameter, ``scipy.optimize.least_squares``),
its uncertainty (the posterior's Gaussian approximation, with a registration's frames' error
carried as K C_e K^T), the combinations the data hardly see, and the outliers it drops round
after round. The method, its equations and why: docs/calibration.md, "How the identification
works". What the estimate is worth (predicted accuracy, a held-out check, rigid motions):
:mod:`~.validation`."""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
from scipy.optimize import least_squares

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
from .tracker import MeasurementNoise

#: Fewest poses an identification takes: each leg's 11 parameters are seen only through its
#: own reading at each pose, so every leg needs more readings than that.
MIN_POSES = 12
#: Default threshold of a flagged reading's studentized residual.
OUTLIER_THRESHOLD = 4.0
#: Default threshold of the singular values (of the whitened, scaled Jacobian over the noise
#: scale) below which a combination is named as known mostly from its tolerance.
MIN_SINGULAR = 1.0
#: Most rounds of dropping the poses that hold an outlier and identifying again.
MAX_ROUNDS = 10
#: A parameter identified beyond this many of its tolerance's standard deviations is named:
#: the drawing is probably wrong there, or the poses are not in the base frame.
BEYOND_TOLERANCE = 3.0
#: Most refits of the noise scale, and the relative change of s^2 that asks for one.
_SCALE_FITS, _SCALE_TOL = 6, 0.02
#: A Gaussian's standard deviation over its median absolute value.
_MAD = 1.4826


@dataclass(frozen=True)
class Combination:
    """A combination of parameters the data know less well than its tolerance: the prior holds
    it near nominal, and its uncertainty is about its tolerance's.

    Attributes:
        direction: (66,) unit vector in the scaled deviations (tolerance units).
        singular_value: its singular value S_i: the data alone would determine it to 1 / S_i
            tolerance standard deviations.
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
    """A reading flagged as an outlier.

    Attributes:
        pose: its row of the measurements.  leg: its encoder.
        residual_rad: model minus reading, rad.  studentized: over the robust scale.
        round: the round after whose fit its pose was dropped (1 the first), when
            :attr:`Identification.used` says it was; else the last round.
    """

    pose: int
    leg: int
    residual_rad: float
    studentized: float
    round: int = 1


@dataclass(frozen=True)
class Identification:
    """What :func:`identify` found.

    Attributes:
        nominal, identified: :class:`~stewart_drake.robot.legs.LegParameters` before and after.
        deviation: (66,) identified minus nominal, units of the deviation vector
            (:mod:`~stewart_drake.robot.legs`).
        std: (66,) each entry's standard deviation (0 for a parameter of zero tolerance),
            same units.
        covariance: (66, 66) of the identified deviations, the tolerances' prior and the
            frames' error included, same units.
        scale: (66,) the tolerances' standard deviations (the prior's).
        singular_values: of the whitened, scaled Jacobian over the noise scale at the estimate,
            descending: what the data tell of each combination beside the prior's 1.
        weak: the :class:`Combination` s with a singular value below ``min_singular``.
        outliers: the :class:`Outlier` s flagged against the last fit, over every pose (a
            dropped pose's readings judged as predictions).
        used: (N,) bool, the poses of the last round (all unless outliers were dropped).
        rounds: how many times the parameters were identified (1 without outliers dropped).
        rms_before_rad, rms_after_rad: RMS of the readings' residuals (model minus read) with
            the nominal and the identified robot, over the poses used, rad.
        chi2_reduced: sum of the whitened residuals' squares over their degrees of freedom,
            with the noise as stated (about 1 when it is; the noise scale squared).
        dof: readings used minus the parameters' effective number (p_eff, module docstring).
        nfev: residual evaluations of ``least_squares``, over every fit.
        frames_covariance: (66, 66) the part of ``covariance`` that the frames' error of
            registered poses makes (zeros without one), same units.
        information: (66, 66) J^T J of the poses used at the stated noise, in scaled units
            (zero for a parameter of zero tolerance): what the poses tell, whatever the
            residuals say of the noise.
        robust: whether the soft-L1 loss was used.
    """

    nominal: LegParameters
    identified: LegParameters
    deviation: np.ndarray
    std: np.ndarray
    covariance: np.ndarray
    scale: np.ndarray
    singular_values: np.ndarray
    weak: tuple
    outliers: tuple
    used: np.ndarray
    rounds: int
    rms_before_rad: float
    rms_after_rad: float
    chi2_reduced: float
    dof: float
    nfev: int
    frames_covariance: np.ndarray
    information: np.ndarray
    robust: bool = False

    @property
    def identified_mask(self) -> np.ndarray:
        """(66,) bool: the parameters with a nonzero tolerance (those the fit may move)."""
        return self.scale > 0

    @property
    def noise_scale(self) -> float:
        """The residuals' noise over the stated noise, sqrt(chi2/dof)."""
        return float(np.sqrt(self.chi2_reduced))

    def design_covariance(self) -> np.ndarray:
        """(66, 66) the covariance the poses used give with the noise as stated, the
        tolerances' prior included (not scaled by the residuals, no frames' error), units of
        :attr:`covariance`: what the pose set itself identifies."""
        active = self.scale > 0
        C = np.zeros((N_PARAMETERS, N_PARAMETERS))
        A = self.information[np.ix_(active, active)] + np.eye(int(active.sum()))
        C[np.ix_(active, active)] = np.linalg.inv(A)
        return self.scale[:, None] * C * self.scale[None, :]

    @property
    def dropped(self) -> np.ndarray:
        """(k,) the rows of the poses dropped for their outliers, ascending."""
        return np.flatnonzero(~self.used)

    def beyond_tolerance(self, factor: float = BEYOND_TOLERANCE) -> tuple:
        """((index, deviation over its tolerance's standard deviation), ...) of the parameters
        identified beyond ``factor`` standard deviations of their tolerance, largest first."""
        ratio = np.divide(
            self.deviation, self.scale, out=np.zeros_like(self.deviation), where=self.scale > 0
        )
        beyond = np.flatnonzero(np.abs(ratio) > factor)
        return tuple((int(k), float(ratio[k])) for k in beyond[np.argsort(-np.abs(ratio[beyond]))])


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


def _weak_combinations(Vt, S, min_singular, names) -> tuple:
    """The :class:`Combination` s that span the rows of Vt whose singular values S are below
    ``min_singular``, written so that each reads: reduced row echelon form with column pivoting
    (each combination leads with a parameter the others do not hold), normalized; the span is
    the same. Each one's singular value is |J_s v| / |v| (from S and Vt)."""
    import scipy.linalg

    weak = Vt[S < min_singular]
    if not len(weak):
        return ()
    _, _, pivots = scipy.linalg.qr(weak, pivoting=True)
    lead = np.sort(pivots[: len(weak)])
    rows = np.linalg.solve(weak[:, lead], weak)  # identity on the leading columns
    out = []
    for v in rows:
        v = v / np.linalg.norm(v)
        v = v if v[np.argmax(np.abs(v))] > 0 else -v
        order = np.argsort(-np.abs(v))
        terms = tuple((names[j], float(v[j])) for j in order[:4] if abs(v[j]) >= 0.15)
        gain = float(np.linalg.norm(S * (Vt @ v)))
        out.append(Combination(direction=v, singular_value=gain, terms=terms))
    return tuple(sorted(out, key=lambda c: c.singular_value))


class _Problem:
    """The measurements and what every fit of them shares: the nominal robot, each pose's
    readings' covariance and whitening (at the nominal robot), the prior's scale."""

    def __init__(self, geometry, poses, q, noise, tolerances, pose_covariances, frames):
        self.geometry, self.poses, self.q, self.frames = geometry, poses, q, frames
        self.nominal = LegParameters.nominal(geometry)
        self.Sigma = reading_covariances(geometry, self.nominal, poses, noise, pose_covariances)
        self.W = np.linalg.inv(np.linalg.cholesky(self.Sigma))
        self.scale = tolerances.stds()
        self.active = self.scale > 0

    def delta(self, z) -> np.ndarray:
        """(66,) the deviations of the scaled ones z (n active,)."""
        out = np.zeros(N_PARAMETERS)
        out[self.active] = self.scale[self.active] * z
        return out

    def legs(self, z) -> LegParameters:
        return self.nominal.shifted(self.delta(z))

    def rows(self, legs, used) -> np.ndarray:
        """(6 N_used, n) the whitened, scaled Jacobian of the poses ``used``."""
        J = derivatives(self.geometry, legs, self.poses[used]).parameters[..., self.active]
        n = int(self.active.sum())
        return np.einsum("nij,njk->nik", self.W[used], J).reshape(-1, n) * self.scale[self.active]

    def whitened(self, z, used) -> np.ndarray:
        """(6 N_used,) the whitened residuals of the robot z at the poses ``used``."""
        r = _residuals(self.geometry, self.legs(z), self.poses[used], self.q[used])
        return np.einsum("nij,nj->ni", self.W[used], r).ravel()


@dataclass(frozen=True)
class _Fit:
    """One fit: z (n,), the noise scale s^2 it weighed with, chi2/dof, the whitened Jacobian
    J (m, n) and C (n, n) at z, the effective number of parameters, residual evaluations."""

    z: np.ndarray
    s2: float
    chi2: float
    J: np.ndarray
    C: np.ndarray
    p_eff: float
    nfev: int


#: The soft-L1 loss's scale, whitened units: a residual of 3 standard deviations is where it
#: turns from the square to the absolute value.
_SOFT_L1_SCALE = 3.0
#: Most reweighting rounds of the robust fit, and the largest change of a weight that ends it.
_IRLS_ROUNDS, _IRLS_TOL = 100, 1e-6


def _solve(problem: _Problem, used, robust: bool, z0, s2: float):
    """(z, nfev): the estimate (module docstring) on the poses ``used`` with noise scale s2;
    with ``robust``, the soft-L1 loss's minimum by iteratively reweighted least squares (each
    residual weighted by 1 / sqrt(1 + (r / 3)^2), its loss's derivative over its own)."""
    n, s = int(problem.active.sum()), np.sqrt(s2)
    weight = np.ones(6 * int(used.sum()))

    def fun(z):
        return np.concatenate([weight * problem.whitened(z, used) / s, z])

    def jac(z):
        return np.vstack([weight[:, None] * problem.rows(problem.legs(z), used) / s, np.eye(n)])

    z, nfev = z0, 0
    for _ in range(_IRLS_ROUNDS if robust else 1):
        z, k = _least_squares(problem, used, fun, jac, z)
        nfev += k
        if not robust:
            break
        r = problem.whitened(z, used) / s
        new = (1.0 + (r / _SOFT_L1_SCALE) ** 2) ** -0.25  # the square root of the weight
        if np.max(np.abs(new**2 - weight**2)) <= _IRLS_TOL:
            break
        weight = new
    return z, nfev


def _least_squares(problem: _Problem, used, fun, jac, z0):
    """(z, nfev) of MINPACK's Levenberg-Marquardt on ``fun`` from z0.

    Raises:
        InvalidConfigError: the fit left every robot near the drawing (the readings').
    """
    try:
        fit = least_squares(
            fun, z0, jac=jac, method="lm", x_scale=1.0, xtol=1e-12, ftol=1e-12, gtol=1e-12
        )
    except UnreachablePoseError as err:
        x, y = problem.poses[used], problem.q[used]
        worst = np.abs(_residuals(problem.geometry, problem.nominal, x, y)).max(axis=0)
        raise InvalidConfigError(
            f"the readings fit no robot near the drawing: explaining them moved leg {err.leg} "
            f"so far that it could not reach a measured pose; the nominal robot misses the "
            f"readings by up to {', '.join(f'q{i} {v:.3g}' for i, v in enumerate(worst))} rad: "
            f"check the readings' columns, units and encoder zeros (zero_counts)"
        ) from None
    return fit.x, int(fit.nfev)


def _fit(problem: _Problem, used, robust: bool, z0) -> _Fit:
    """The estimate on the poses ``used`` with the noise scale estimated with it, at least 1
    (module docstring): refits while s^2 moves by more than :data:`_SCALE_TOL`."""
    n = int(problem.active.sum())
    z, s2, nfev = z0, 1.0, 0
    for _ in range(_SCALE_FITS):
        z, k = _solve(problem, used, robust, z, s2)
        nfev += k
        J = problem.rows(problem.legs(z), used)
        C = np.linalg.inv(J.T @ J / s2 + np.eye(n))
        p_eff = n - float(np.trace(C))
        r_w = problem.whitened(z, used)
        chi2 = float(r_w @ r_w) / max(r_w.size - p_eff, 1.0)
        # With the soft-L1 loss, the scale the blunders do not move: the median's.
        level = (_MAD * float(np.median(np.abs(r_w)))) ** 2 if robust else chi2
        # Never below the stated noise: residuals quieter than it (readings averaged, a few
        # poses the parameters can follow) would narrow the +- values below what it promises.
        level = max(level, 1.0)
        if abs(level - s2) <= _SCALE_TOL * s2:
            break
        s2 = level
    C = np.linalg.inv(J.T @ J / s2 + np.eye(n))
    return _Fit(z, s2, chi2, J, C, n - float(np.trace(C)), nfev)


def _flag(problem: _Problem, fit: _Fit, used, threshold: float, round_: int) -> tuple:
    """The :class:`Outlier` s of a fit (module docstring), over every pose: those ``used`` by
    the fit studentized by their variance less what the fit absorbed, the others (dropped) as
    predictions, by their variance plus the fit's."""
    legs = problem.legs(fit.z)
    x, y = problem.poses, problem.q
    J = derivatives(problem.geometry, legs, x).parameters[..., problem.active]
    Jr = J.reshape(-1, J.shape[-1]) * problem.scale[problem.active]
    h = np.einsum("mi,ij,mj->m", Jr, fit.C, Jr) / fit.s2
    sigma = np.diagonal(problem.Sigma, axis1=1, axis2=2).ravel()
    raw = _residuals(problem.geometry, legs, x, y).ravel()
    fitted = np.repeat(used, 6)
    u = raw / np.sqrt(np.where(fitted, np.clip(sigma - h, 1e-3 * sigma, None), sigma + h))
    spread = max(_MAD * float(np.median(np.abs(u[fitted]))), 1e-12)
    t = u / spread
    return tuple(
        Outlier(j // 6, j % 6, float(raw[j]), float(t[j]), round_)
        for j in map(int, np.flatnonzero(np.abs(t) > threshold))
    )


def identify(
    geometry: StewartGeometry,
    poses,
    q,
    noise: MeasurementNoise,
    tolerances: Tolerances | None = None,
    min_singular: float = MIN_SINGULAR,
    outlier_threshold: float = OUTLIER_THRESHOLD,
    robust: bool = False,
    drop_outliers: bool = True,
    pose_covariances=None,
    frames=None,
) -> Identification:
    """Identify the robot's per-leg parameters from measured poses and readings, with the
    tolerances as the prior (module docstring).

    Args:
        geometry: the nominal robot.
        poses: (N, 6) the platform's poses as the tracker measured them, [rad, m].
        q: (N, 6) the encoders' readings there, rad (any whole turn: residuals are wrapped).
        noise: what the measurements carry (:class:`~.tracker.MeasurementNoise`).
        tolerances: the robot's tolerances, the prior of each parameter (default
            :class:`~stewart_drake.robot.tolerances.Tolerances`); a zero half-width keeps that
            parameter nominal.
        min_singular: the singular value below which a combination is named weak, > 0.
        outlier_threshold: a reading with a larger studentized residual is flagged, > 0.
        robust: the soft-L1 loss (scale 3 whitened units) on the residuals.
        drop_outliers: drop the poses holding a flagged reading and identify again, until none
            is flagged (at most :data:`MAX_ROUNDS` rounds).
        pose_covariances: (N, 6, 6) each pose's noise, [rad, m]^2 (a small rotation in B and a
            shift), in place of ``noise``'s isotropic one (registered poses: module docstring).
        frames: (J (N, 6, k), C (k, k)): an error e common to every pose, of covariance C, that
            moves pose k by J_k e (the registration's frames), carried to the covariance.
    Returns:
        :class:`Identification`.
    Raises:
        InvalidConfigError: the measurements as :func:`check_measurements` says, a threshold
            out of range, dropping the outliers' poses leaves fewer than :data:`MIN_POSES`,
            readings no robot near the drawing explains.
        UnreachablePoseError: a measured pose the nominal robot cannot reach (not this robot's
            poses, or the wrong units).
    Source: the identification of a parallel robot from external pose measurements (least
        squares on the inverse kinematics' residuals), regularized by the tolerances as a
        Gaussian prior (a maximum a posteriori estimate, its Laplace covariance).
    """
    poses, q = check_measurements(poses, q)
    pose_covariances, frames = _check_registered(len(poses), pose_covariances, frames)
    tolerances = Tolerances() if tolerances is None else tolerances
    min_singular = as_number("min_singular", min_singular, 0.0, lo_open=True)
    outlier_threshold = as_number("outlier_threshold", outlier_threshold, 0.0, lo_open=True)
    problem = _Problem(geometry, poses, q, noise, tolerances, pose_covariances, frames)
    used = np.ones(len(poses), dtype=bool)
    z = np.zeros(int(problem.active.sum()))
    dropped_in = np.zeros(len(poses), dtype=int)  # the round that last dropped each pose
    nfev = 0
    for round_ in range(1, MAX_ROUNDS + 1):
        fit = _fit(problem, used, robust, z)
        nfev += fit.nfev
        found = _flag(problem, fit, used, outlier_threshold, round_)
        keep = np.ones(len(poses), dtype=bool)
        keep[[o.pose for o in found]] = False
        if not drop_outliers or np.array_equal(keep, used) or round_ == MAX_ROUNDS:
            break
        # A pose flagged against this fit is dropped; one dropped before and not flagged now
        # is taken back: a blunder's pull on the first fit flags good poses too.
        dropped_in[used & ~keep] = round_
        used = keep
        if used.sum() < MIN_POSES:
            raise InvalidConfigError(
                f"dropping the {int((~used).sum())} poses with outliers leaves "
                f"{int(used.sum())}, fewer than {MIN_POSES}: check the measurements (their "
                f"units, the frames), or identify with --no-drop-outliers to see them all"
            )
        z = fit.z
    outliers = tuple(
        replace(o, round=int(dropped_in[o.pose])) if not used[o.pose] else o for o in found
    )
    return _identification(problem, fit, used, round_, outliers, min_singular, nfev, robust)


def _identification(problem, fit, used, rounds, outliers, min_singular, nfev, robust):
    """The :class:`Identification` of the last round's fit."""
    scale, active = problem.scale, problem.active
    legs = problem.legs(fit.z)
    cov = np.zeros((N_PARAMETERS, N_PARAMETERS))
    cov[np.ix_(active, active)] = fit.C
    covariance = scale[:, None] * cov * scale[None, :]
    frames_part = _frames_covariance(problem, fit, legs, used)
    covariance = covariance + frames_part
    S, Vt = singular_values(fit.J / np.sqrt(fit.s2))
    Vt_full = np.zeros((len(S), N_PARAMETERS))
    Vt_full[:, active] = Vt
    information = np.zeros((N_PARAMETERS, N_PARAMETERS))
    information[np.ix_(active, active)] = fit.J.T @ fit.J
    x, y = problem.poses[used], problem.q[used]
    before = _residuals(problem.geometry, problem.nominal, x, y)
    after = _residuals(problem.geometry, legs, x, y)
    return Identification(
        nominal=problem.nominal,
        identified=legs,
        deviation=problem.delta(fit.z),
        std=np.sqrt(np.clip(np.diag(covariance), 0.0, None)),
        covariance=covariance,
        scale=scale,
        singular_values=S,
        weak=_weak_combinations(Vt_full, S, min_singular, parameter_names()),
        outliers=outliers,
        used=used.copy(),
        rounds=rounds,
        rms_before_rad=float(np.sqrt(np.mean(before**2))),
        rms_after_rad=float(np.sqrt(np.mean(after**2))),
        chi2_reduced=fit.chi2,
        dof=after.size - fit.p_eff,
        nfev=nfev,
        frames_covariance=frames_part,
        information=information,
        robust=robust,
    )


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


def _frames_covariance(problem: _Problem, fit: _Fit, legs, used) -> np.ndarray:
    """(66, 66) K C_e K^T of the module docstring, K = C J^T D / s^2 mapped to the
    parameters."""
    if problem.frames is None:
        return np.zeros((N_PARAMETERS, N_PARAMETERS))
    Je, Ce = problem.frames[0][used], problem.frames[1]
    G = derivatives(problem.geometry, legs, problem.poses[used]).pose
    D = np.einsum("nij,njk,nkl->nil", problem.W[used], G, Je).reshape(-1, Je.shape[2])
    K = np.zeros((N_PARAMETERS, Je.shape[2]))
    K[problem.active] = fit.C @ (fit.J.T @ D) / fit.s2
    K *= problem.scale[:, None]
    return K @ Ce @ K.T


def kinds_and_legs() -> tuple[tuple[str, ...], np.ndarray]:
    """(the kind of each parameter, the leg of each), for reports."""
    return parameter_kinds(), parameter_legs()
