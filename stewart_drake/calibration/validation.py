"""What an identification is worth: the accuracy of the readings its covariance predicts (and
the nominal robot's, from the tolerances), a held-out check on the user's own poses
(:func:`cross_validate`), and the rigid motions of the pivots or the platform joints that say
the poses were probably not the platform frame's in the base frame (:func:`rigid_motions`)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from ..base.checks import check_int
from ..robot.geometry import StewartGeometry
from ..robot.legs import LegParameters, derivatives
from ..robot.tolerances import Tolerances
from .identify import (
    MIN_POSES,
    Identification,
    _residuals,
    check_measurements,
    identify,
    reading_covariances,
)
from .registration import fit_frame, rigid_fit_rows
from .tracker import MeasurementNoise

#: Folds of the held-out check.
FOLDS = 5


def predicted_rms(
    geometry: StewartGeometry,
    ident: Identification,
    poses,
    noise: MeasurementNoise,
    covariance=None,
) -> float:
    """The RMS error of the identified robot's predicted readings at poses (N, 6) that the
    identification's own covariance predicts, rad: the parameters' covariance (the tolerances'
    prior included; or ``covariance`` (66, 66), e.g. :meth:`Identification.design_covariance`)
    mapped through the readings' derivatives, and the readings' quantization."""
    J = derivatives(geometry, ident.identified, poses).parameters
    C = ident.covariance if covariance is None else covariance
    var = np.einsum("nik,kl,nil->ni", J, C, J)
    return float(np.sqrt(np.mean(var) + noise.quantization_rms_rad**2))


def nominal_rms(
    geometry: StewartGeometry, tolerances: Tolerances, poses, noise: MeasurementNoise
) -> float:
    """The RMS error of the nominal robot's predicted readings at poses (N, 6) that the
    tolerances give (their variances mapped through the readings' derivatives, and the
    quantization), rad: what an identification starts from."""
    J = derivatives(geometry, LegParameters.nominal(geometry), poses).parameters
    var = np.einsum("nik,k,nik->ni", J, tolerances.stds() ** 2, J)
    return float(np.sqrt(np.mean(var) + noise.quantization_rms_rad**2))


@dataclass(frozen=True)
class HeldOut:
    """The held-out check of :func:`cross_validate`; RMS over every held-out reading, rad.

    Attributes:
        folds: how many.  poses: the poses checked (those the identification used).
        rms_rad: each fold's readings predicted from the others' identification, against
            the readings.
        predicted_rad: what those identifications' covariances and the measurements' own
            noise (each held-out pose's Sigma_k times the fold's noise scale squared) predict
            for ``rms_rad``.
        noise_rad: the measurements' own noise's part of ``predicted_rad``.
    """

    folds: int
    poses: int
    rms_rad: float
    predicted_rad: float
    noise_rad: float


def cross_validate(
    geometry: StewartGeometry,
    poses,
    q,
    noise: MeasurementNoise,
    ident: Identification,
    folds: int = FOLDS,
    tolerances: Tolerances | None = None,
    pose_covariances=None,
) -> HeldOut | None:
    """A k-fold check of an identification on its own measurements: the poses it used (in
    their order, pose j in fold j mod k), each fold's readings predicted by the robot
    identified (as ``ident`` was: its loss, the tolerances, no further outliers dropped) from
    the other folds' poses.

    Args:
        geometry, poses (N, 6), q (N, 6), noise, tolerances, pose_covariances (N, 6, 6): what
            ``ident`` was identified from (:func:`identify`; the frames' error is left out: it
            is the same in the held-out poses as in the others, and the parameters absorb it).
        ident: the identification checked (its ``used`` poses are the ones split).
        folds: k, 2 .. 20.
    Returns:
        :class:`HeldOut`, or None when the poses used are too few for each fold's
        identification to keep :data:`MIN_POSES`.
    Raises:
        InvalidConfigError: folds out of range; as :func:`identify`.
    """
    folds = check_int("folds", folds, 2, 20)
    poses, q = check_measurements(poses, q)
    rows = np.flatnonzero(ident.used)
    if len(rows) - -(-len(rows) // folds) < MIN_POSES:
        return None
    err2, var, own = [], [], []
    for f in range(folds):
        test = rows[f::folds]
        train = np.setdiff1d(rows, test)
        covs = None if pose_covariances is None else np.asarray(pose_covariances)
        part = identify(
            geometry,
            poses[train],
            q[train],
            noise,
            tolerances,
            robust=ident.robust,
            drop_outliers=False,
            pose_covariances=None if covs is None else covs[train],
        )
        x = poses[test]
        r = _residuals(geometry, part.identified, x, q[test])
        J = derivatives(geometry, part.identified, x).parameters
        Sigma = reading_covariances(
            geometry, part.nominal, x, noise, None if covs is None else covs[test]
        )
        noise_var = part.chi2_reduced * np.diagonal(Sigma, axis1=1, axis2=2)
        err2.append(r**2)
        own.append(noise_var)
        var.append(np.einsum("nik,kl,nil->ni", J, part.covariance, J) + noise_var)
    return HeldOut(
        folds=folds,
        poses=len(rows),
        rms_rad=float(np.sqrt(np.mean(np.concatenate(err2)))),
        predicted_rad=float(np.sqrt(np.mean(np.concatenate(var)))),
        noise_rad=float(np.sqrt(np.mean(np.concatenate(own)))),
    )


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
        shift = X.rotation().matrix() @ centroid + X.translation() - centroid
        out.append(
            RigidMotion(frame, float(np.linalg.norm(e[:3])), float(np.linalg.norm(shift)), chi2)
        )
    return tuple(out)
