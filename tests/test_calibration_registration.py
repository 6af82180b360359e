"""The tracker's frames registered to the robot's from fiducials: the weighted rigid fit and its
covariance (against Monte Carlo), the conversion of marker poses in the tracker's frame to
platform poses in the base frame (against Drake's RigidTransform), REG.yaml's reader on good
and hostile files. Fast unit tests only (tools/mutation.py runs them against every mutant of
calibration/registration.py); the identification of registered poses and the command are
tests/test_calibration_registered.py's."""

import re

import numpy as np
import pytest
from pydrake.math import RigidTransform, RollPitchYaw, RotationMatrix
from scipy.spatial.transform import Rotation

from stewart_drake.base.errors import InvalidConfigError, MissingFileError
from stewart_drake.calibration import files, tracker
from stewart_drake.calibration import registration as rg
from stewart_drake.calibration import registration_file as rf
from stewart_drake.robot.geometry import StewartGeometry
from stewart_drake.robot.kinematics import rotation_rpy

GEOMETRY = StewartGeometry()
NOISE = tracker.MeasurementNoise(5e-6, 20e-6)
SETUP = tracker.emulated_setup(GEOMETRY)
POSES_BP = np.array(
    [
        [0.1, -0.05, 0.2, 0.01, -0.02, 0.3],
        [0.0, 0.0, 0.0, 0.0, 0.0, 0.3],
        [-0.2, 0.1, -0.1, 0.05, 0.03, 0.25],
    ]
)


def _exp(e) -> RigidTransform:
    """The small motion (Exp(e_rot), e_trans) of a 6-vector [rotation vector, translation]."""
    return RigidTransform(RotationMatrix(Rotation.from_rotvec(e[:3]).as_matrix()), e[3:])


def _log(X: RigidTransform) -> np.ndarray:
    return np.concatenate(
        [Rotation.from_matrix(X.rotation().matrix()).as_rotvec(), X.translation()]
    )


def _kabsch(a, b, w):
    """(R, t) of the weighted rigid fit a ~ R b + t, written out (the SVD of the weighted
    cross-covariance, its reflection removed)."""
    ca, cb = w @ a / w.sum(), w @ b / w.sum()
    U, _, Vt = np.linalg.svd(((b - cb) * w[:, None]).T @ (a - ca))
    R = Vt.T @ np.diag([1.0, 1.0, np.sign(np.linalg.det(Vt.T @ U.T))]) @ U.T
    return R, ca - R @ cb


def _central(f, n: int, h: float) -> np.ndarray:
    """(m, n) the Jacobian of f (n,) -> (m,) at 0 by central differences of step h."""
    return np.column_stack([(f(h * u) - f(-h * u)) / (2 * h) for u in np.eye(n)])


def _fit_normal_matrix(X, p_A, p_B, w):
    """(6, 6) J^T W J of the residuals p_A - X Exp(e) p_B (w per point, on each axis), J by
    central differences in e, the error of X in B."""

    def residuals(e):
        return (p_A - (X @ _exp(e)).multiply(p_B.T).T).ravel()

    J = _central(residuals, 6, 1e-6)
    return J.T @ (np.repeat(w, 3)[:, None] * J)


def _assert_covariance(stated, expected, tol):
    """Each entry of a covariance within ``tol`` of the other, in units of the product of the
    two standard deviations (a correlation's units: the rotation's, the translation's and the
    cross block each in its own), and each standard deviation within ``tol``, relative."""
    s = np.sqrt(np.diag(expected))
    np.testing.assert_allclose(np.sqrt(np.diag(stated)), s, rtol=tol, atol=0)
    np.testing.assert_allclose(stated / np.outer(s, s), expected / np.outer(s, s), atol=tol)


def _whitened_moment(errors, cov):
    """(6, 6) the second moment about 0 of errors (K, 6) whitened by ``cov``: the identity when
    ``cov`` is their covariance and they have no bias, block by block, without units."""
    z = np.linalg.solve(np.linalg.cholesky(cov), errors.T).T
    return z.T @ z / len(z)


def test_the_weighted_fit_recovers_a_known_frame_with_the_covariance_it_states():
    X_AB = RigidTransform(RollPitchYaw(0.1, -0.2, 0.52), [1.0, 0.2, 0.1])
    p_B = np.array(
        [[0.22, 0, -0.08], [0, 0.22, -0.08], [-0.22, 0, -0.06], [0, -0.2, -0.08], [0.1, 0.1, 0.0]]
    )
    sigma = np.array([2e-6, 2e-6, 4e-6, 2e-6, 8e-6])  # one point worse: its weight says so
    rng = np.random.default_rng(0)
    errors, d2 = [], []
    for _ in range(2000):
        p_A = X_AB.multiply(p_B.T).T + rng.normal(0.0, 1.0, p_B.shape) * sigma[:, None]
        X, cov, rms = rg.fit_frame(p_A, p_B, sigma**-2.0)
        e = _log(X.inverse() @ X_AB)  # true X_AB = X Exp(e)
        errors.append(e)
        d2.append(e @ np.linalg.solve(cov, e))
    errors = np.array(errors)
    # The stated covariance is the scatter's, entry by entry, to Monte Carlo's precision: the
    # errors whitened by it have the identity for second moment (the cross block too, in
    # consistent units; sampling error about 0.03).
    scatter = np.cov(errors.T)
    np.testing.assert_allclose(np.sqrt(np.diag(scatter)), np.sqrt(np.diag(cov)), rtol=0.06)
    np.testing.assert_allclose(_whitened_moment(errors, cov), np.eye(6), atol=0.1)
    assert np.abs(cov[:3, 3:]).max() > 0.3 * np.sqrt(cov[0, 0] * cov[3, 3])  # a cross block
    assert np.mean(d2) == pytest.approx(6.0, rel=0.1)  # chi-square of 6 degrees of freedom
    assert np.max(np.abs(errors.mean(axis=0)) / np.sqrt(np.diag(cov))) < 0.1  # unbiased
    assert 1e-6 < rms < 1e-5 and np.sqrt(cov[0, 0]) < 2e-5


def test_the_fit_is_the_weighted_kabsch_fit_with_its_normal_matrix_s_inverse_for_covariance():
    """The frame fitted is the weighted Kabsch fit written out; the covariance stated is
    (J^T W J)^-1, J the residuals' Jacobian in the error e (true X_AB = X_AB Exp(e), e in B) by
    central differences, each block in its own units. Without weights, the same J^T J's inverse
    times the residuals' sum of squares over their 3 n - 6 degrees of freedom; rms their RMS."""
    X_AB = RigidTransform(RollPitchYaw(0.1, -0.2, 0.52), [1.0, 0.2, 0.1])
    p_B = np.array(
        [[0.22, 0, -0.08], [0, 0.22, -0.08], [-0.22, 0, -0.06], [0, -0.2, -0.08], [0.1, 0.1, 0.0]]
    )
    sigma = np.array([2e-6, 2e-6, 4e-6, 2e-6, 8e-6])
    p_A = X_AB.multiply(p_B.T).T + np.random.default_rng(7).normal(0.0, 1.0, p_B.shape) * 3e-6
    for w in (sigma**-2.0, None):
        X, cov, rms = rg.fit_frame(p_A, p_B, w)
        weights = np.ones(5) if w is None else w
        R, t = _kabsch(p_A, p_B, weights)
        np.testing.assert_allclose(X.rotation().matrix(), R, rtol=0, atol=1e-12)
        np.testing.assert_allclose(X.translation(), t, rtol=0, atol=1e-12)
        residual = p_A - X.multiply(p_B.T).T
        assert rms == pytest.approx(np.sqrt(np.mean(np.sum(residual**2, axis=1))), rel=1e-12)
        expected = np.linalg.inv(_fit_normal_matrix(X, p_A, p_B, weights))
        if w is None:
            expected *= np.sum(residual**2) / (3 * 5 - 6)
        _assert_covariance(cov, expected, 1e-6)


def test_the_fit_refuses_what_fixes_no_frame():
    """Points not (n, 3) (each named), weights not one per point or not > 0; and points that
    lie on one line once weighted (the fourth point off the line weighs 1e-8 of the others)."""
    rng = np.random.default_rng(8)
    b = rng.uniform(-0.2, 0.2, (4, 3))
    with pytest.raises(InvalidConfigError, match="points_a"):
        rg.fit_frame(rng.random((3, 4)), rng.random((3, 4)))
    with pytest.raises(InvalidConfigError, match="points_b"):
        rg.fit_frame(rng.random((4, 3)), rng.random((3, 4)))
    with pytest.raises(InvalidConfigError, match="weights"):
        rg.fit_frame(b, b, np.ones(5))
    with pytest.raises(InvalidConfigError, match="weight must be > 0"):
        rg.fit_frame(b, b, [1.0, 1.0, 0.0, 1.0])
    line = np.array([[-0.1, 0, 0], [0, 0, 0], [0.1, 0, 0], [0, 0.1, 0]])
    assert rg.fit_frame(line, line)[2] == 0.0
    with pytest.raises(InvalidConfigError, match="lie on one line"):
        rg.fit_frame(line, line, [1.0, 1.0, 1.0, 1e-8])


def test_the_spread_off_a_line_is_the_ratio_of_the_weighted_cloud_s_axes():
    """line_spread: sqrt of the weighted covariance's second eigenvalue over its first, written
    out for clouds whose covariance is diagonal: a 2 x 1 rectangle (0.5) anywhere in space; three
    points on a line and one off it, plainly (sqrt(0.375)) and with the fourth weighing eps;
    points on a line, one point, one point twice: 0."""
    rectangle = np.array([[2.0, 1, 0], [-2, 1, 0], [2, -1, 0], [-2, -1, 0]]) + [5.0, -3.0, 7.0]
    assert rg.line_spread(rectangle) == pytest.approx(0.5, rel=1e-12)
    cloud = np.array([[-1.0, 0, 0], [0, 0, 0], [1, 0, 0], [0, 1, 0]])
    assert rg.line_spread(cloud) == pytest.approx(np.sqrt(0.375), rel=1e-12)
    eps = 3e-4
    m = eps / (3 + eps)  # the weighted mean's y
    yy, xx = (3 * m**2 + eps * (1 - m) ** 2) / (3 + eps), 2 / (3 + eps)
    spread = rg.line_spread(cloud, [1.0, 1.0, 1.0, eps])
    assert spread == pytest.approx(np.sqrt(yy / xx), rel=1e-9)
    assert rg.line_spread(cloud[:3]) == 0.0 and rg.line_spread(cloud[:1]) == 0.0
    assert rg.line_spread(np.array([[1.0, 2, 3], [1, 2, 3]])) == 0.0


def test_the_rows_of_the_rigid_fit_are_its_derivative():
    """rigid_fit_rows: the small rigid motion the fit gives to points displaced by d, e = L d,
    against fit_frame's by central differences (weighted and not)."""
    b = SETUP.base_B
    for w in (np.array([1.0, 2.0, 0.5, 4.0]) * 1e10, None):
        L = rg.rigid_fit_rows(b, w)

        def motion(d, w=w):
            return _log(rg.fit_frame(b + d.reshape(-1, 3), b, w)[0])

        np.testing.assert_allclose(L, _central(motion, b.size, 1e-7), rtol=0, atol=1e-6)
        assert L.shape == (6, 12) and np.abs(L).max() > 1.0


def test_the_unweighted_fit_takes_the_noise_from_its_residuals():
    X_AB = RigidTransform(RollPitchYaw(0.3, 0.2, -1.0), [-0.5, 2.0, 0.3])
    p_B = np.random.default_rng(1).uniform(-0.2, 0.2, (30, 3))
    p_A = X_AB.multiply(p_B.T).T + np.random.default_rng(2).normal(0.0, 1e-5, p_B.shape)
    X, cov, _ = rg.fit_frame(p_A, p_B)
    _, cov_known, _ = rg.fit_frame(p_A, p_B, np.full(30, 1e10))
    assert np.sqrt(cov[3, 3] / cov_known[3, 3]) == pytest.approx(1.0, rel=0.2)
    assert np.linalg.norm(_log(X.inverse() @ X_AB)[:3]) < 5 * np.sqrt(np.trace(cov[:3, :3]))
    exact, zero, rms = rg.fit_frame(X_AB.multiply(p_B.T).T, p_B)
    assert rms < 1e-14 and np.abs(exact.GetAsMatrix4() - X_AB.GetAsMatrix4()).max() < 1e-13


def test_base_poses_are_drake_s_composition_and_tracker_poses_their_inverse():
    reg = rg.Registration(SETUP.X_TB, SETUP.X_PM, np.zeros((6, 6)), np.zeros((6, 6)), 0.0, 0.0)
    x_TM = reg.tracker_poses(POSES_BP)
    for x, seen in zip(POSES_BP, x_TM):
        X_TM = SETUP.X_TB @ RigidTransform(RollPitchYaw(x[:3]), x[3:]) @ SETUP.X_PM
        np.testing.assert_allclose(seen[:3], RollPitchYaw(X_TM.rotation()).vector(), atol=1e-14)
        np.testing.assert_allclose(seen[3:], X_TM.translation(), atol=1e-14)
    np.testing.assert_allclose(reg.base_poses(x_TM), POSES_BP, atol=1e-14)
    assert reg.base_poses(x_TM[0]).shape == (1, 6)
    with pytest.raises(InvalidConfigError, match="not mm"):
        reg.base_poses([0, 0, 0, 0, 0, 1e4])


def test_the_pose_jacobians_are_how_the_frames_errors_move_the_converted_poses():
    e = np.random.default_rng(3).normal(0.0, 1e-6, 12)
    # Frames off by e: the true X_TB is X_TB Exp(e_B), the true X_PM is Exp(e_M) X_PM.
    wrong = rg.Registration(
        SETUP.X_TB @ _exp(e[:6]).inverse(),
        _exp(e[6:]).inverse() @ SETUP.X_PM,
        np.zeros((6, 6)),
        np.zeros((6, 6)),
        0.0,
        0.0,
    )
    converted = wrong.base_poses(SETUP.tracker_poses(POSES_BP))
    J = wrong.pose_jacobians(converted)
    for x, xc, Jk in zip(POSES_BP, converted, J):
        turn = Rotation.from_matrix(rotation_rpy(x[:3]) @ rotation_rpy(xc[:3]).T).as_rotvec()
        moved = np.concatenate([turn, x[3:] - xc[3:]])
        np.testing.assert_allclose(moved, Jk @ e, rtol=0, atol=1e-11)  # first order in 1e-6


def test_the_pose_covariances_are_the_marker_noise_moved_to_the_platform_frame():
    """Against Monte Carlo of the tracker's noise (the converted poses' errors whitened by the
    stated covariance: the identity, every block in consistent units) and exactly against the
    conversion's Jacobian by central differences (a small rotation of the marker in T, a shift)."""
    reg = SETUP.registration()
    x_TM = SETUP.tracker_poses(POSES_BP)
    rng = np.random.default_rng(4)
    noisy = np.array([tracker.noisy_poses(x_TM, NOISE, rng) for _ in range(3000)])  # (K, N, 6)
    predicted = reg.pose_covariances(POSES_BP, NOISE.rotation_rad, NOISE.translation_m)
    for k, x in enumerate(POSES_BP):
        xc = reg.base_poses(noisy[:, k])
        turn = Rotation.from_matrix(rotation_rpy(xc[:, :3]) @ rotation_rpy(x[:3]).T).as_rotvec()
        errors = np.column_stack([turn, xc[:, 3:] - x[3:]])
        np.testing.assert_allclose(_whitened_moment(errors, predicted[k]), np.eye(6), atol=0.1)
    # The lever arm: the 50 mm marker adds its rotation noise to the positions' 5 um.
    assert np.sqrt(predicted[0, 3, 3]) > NOISE.translation_m * 1.0001
    rotation, shift = 3e-5, 7e-6
    predicted = reg.pose_covariances(POSES_BP, rotation, shift)
    for k, x in enumerate(x_TM):
        X_TM = RigidTransform(RollPitchYaw(x[:3]), x[3:])

        def moved(d, X_TM=X_TM, k=k):
            R = RotationMatrix(Rotation.from_rotvec(d[:3]).as_matrix()) @ X_TM.rotation()
            seen = np.concatenate([RollPitchYaw(R).vector(), X_TM.translation() + d[3:]])
            xc = reg.base_poses(seen)[0]
            R_turn = rotation_rpy(xc[:3]) @ rotation_rpy(POSES_BP[k, :3]).T
            return np.concatenate([Rotation.from_matrix(R_turn).as_rotvec(), xc[3:]])

        J = _central(moved, 6, 1e-6)
        expected = J @ np.diag([rotation**2] * 3 + [shift**2] * 3) @ J.T
        _assert_covariance(predicted[k], expected, 1e-6)


def test_an_emulated_setup_s_fiducials_register_its_frames_within_their_covariance():
    errors, covs = [], []
    for seed in range(400):
        reg = rg.register(SETUP.fiducials(NOISE, seed))
        errors.append(
            np.concatenate(
                [_log(reg.X_TB.inverse() @ SETUP.X_TB), _log(SETUP.X_PM @ reg.X_PM.inverse())]
            )
        )
        covs.append(reg.frames_covariance())
    errors, mean_cov = np.array(errors), np.mean(covs, axis=0)
    ratio = np.sqrt(np.diag(np.cov(errors.T)) / np.diag(mean_cov))
    # The covariance stated is the scatter's, or up to a fifth larger where the residuals of a
    # few points seemed noisier than point_sigma_m (it then follows them).
    assert np.all((ratio > 0.8) & (ratio < 1.05)), ratio
    # No bias: the mean error is within 4 standard errors of 0 on every axis (a frame turned or
    # moved wrongly is off by many); the two blocks' correlations are the stated ones.
    assert np.all(np.abs(errors.mean(axis=0)) < 4 * np.sqrt(np.diag(mean_cov) / len(errors)))
    for block in (slice(0, 6), slice(6, 12)):
        z = _whitened_moment(errors[:, block], mean_cov[block, block])
        np.testing.assert_allclose(z, np.diag(np.diag(z)), atol=0.2)
    assert reg.base_points == 4 and reg.platform_points == 4
    assert 0.5e-6 < reg.rms_base_m < 5e-6 and "from 4 fiducials" in reg.words()


@pytest.mark.parametrize("noise_m", [0.0, 1e-5])
def test_register_states_each_frame_s_covariance_from_its_fiducials_and_the_marker(noise_m):
    """Fiducials read exactly (noise 0) or five times noisier than point_sigma_m says (2 um):
    each frame is the Kabsch fit of its fiducials (X_PM = X_TP^-1 X_TM, the marker turned);
    cov_B the fit's (J^T W J)^-1, scaled by the residuals' reduced chi-square when above 1
    (sum r^2 / (sigma^2 (3 n - 6))); cov_M the platform fit's the same way plus the marker's
    measurement noise (3e-5 rad, 7e-6 m per axis) carried by central differences of X_PM."""
    base = SETUP.X_TB.multiply(SETUP.base_B.T).T
    X_TM = SETUP.X_TB @ RigidTransform(RollPitchYaw(POSES_BP[0, :3]), POSES_BP[0, 3:])
    X_TP, X_TM = X_TM, X_TM @ SETUP.X_PM
    platform = X_TP.multiply(SETUP.platform_P.T).T
    rng = np.random.default_rng(9)
    marker = np.concatenate([RollPitchYaw(X_TM.rotation()).vector(), X_TM.translation()])
    fiducials = rg.Fiducials(
        SETUP.base_B,
        base + rng.normal(0.0, noise_m, base.shape),
        SETUP.platform_P,
        platform + rng.normal(0.0, noise_m, platform.shape),
        marker,
        2e-6,
        (3e-5, 7e-6),
    )
    reg = rg.register(fiducials)
    sigma, n = 2e-6, len(SETUP.base_B)
    covs, residuals = [], []
    for seen, known, X in (
        (fiducials.base_T, SETUP.base_B, reg.X_TB),
        (fiducials.platform_T, SETUP.platform_P, RigidTransform(X_TM) @ reg.X_PM.inverse()),
    ):
        R, t = _kabsch(seen, known, np.ones(n))
        np.testing.assert_allclose(X.GetAsMatrix4()[:3], np.column_stack([R, t]), atol=1e-12)
        residual = seen - X.multiply(known.T).T
        residuals.append(residual)
        chi2 = np.sum(residual**2) / (sigma**2 * (3 * n - 6))
        covs.append(
            np.linalg.inv(_fit_normal_matrix(X, seen, known, np.full(n, sigma**-2)))
            * max(1.0, chi2)
        )
        assert (chi2 > 5) == (noise_m > 0)
    X_TP_fit = RigidTransform(X_TM) @ reg.X_PM.inverse()

    def marker_moved(d):
        X = RigidTransform(
            RotationMatrix(Rotation.from_rotvec(d[:3]).as_matrix()) @ X_TM.rotation(),
            X_TM.translation() + d[3:],
        )
        return _log(X_TP_fit.inverse() @ X @ reg.X_PM.inverse())  # e_M: Exp(e_M) X_PM

    J = _central(marker_moved, 6, 1e-6)
    marker_cov = J @ np.diag([3e-5**2] * 3 + [7e-6**2] * 3) @ J.T
    _assert_covariance(reg.cov_B, covs[0], 1e-6)
    _assert_covariance(reg.cov_M, covs[1] + marker_cov, 1e-6)
    np.testing.assert_allclose(reg.X_PM.GetAsMatrix4(), SETUP.X_PM.GetAsMatrix4(), atol=1e-4)
    assert (reg.base_points, reg.platform_points) == (n, n)
    for rms, residual in zip((reg.rms_base_m, reg.rms_platform_m), residuals):
        assert rms == pytest.approx(np.sqrt(np.mean(np.sum(residual**2, axis=1))), rel=1e-9)


def test_a_registration_without_platform_points_has_the_marker_for_platform_frame():
    """Base fiducials only: X_PM is the identity with a zero (6, 6) covariance and no platform
    residual; the base's frame, covariance and residual are its fit's. A fit refused names the
    source, REG.yaml unless told."""
    fiducials = rg.Fiducials(SETUP.base_B, SETUP.fiducials(NOISE, 1).base_T, point_sigma_m=1e-5)
    reg = rg.register(fiducials)
    X, cov, rms = rg.fit_frame(fiducials.base_T, SETUP.base_B, np.full(4, 1e10))
    assert reg.X_PM.IsExactlyIdentity() and reg.cov_M.shape == (6, 6) and not reg.cov_M.any()
    np.testing.assert_allclose(reg.X_TB.GetAsMatrix4(), X.GetAsMatrix4(), rtol=0, atol=1e-15)
    assert reg.rms_base_m == pytest.approx(rms, rel=1e-12) and reg.rms_platform_m == 0.0
    _assert_covariance(reg.cov_B, cov, 1e-9)  # the noise below the 10 um stated: unscaled
    assert (reg.base_points, reg.platform_points) == (4, 0)
    assert reg.frames_covariance()[6:].sum() == 0 and reg.frames_covariance().shape == (12, 12)
    line = rg.Fiducials(np.outer([0.0, 0.1, 0.2], [1.0, 1.0, 1.0]), np.zeros((3, 3)))
    with pytest.raises(InvalidConfigError, match="^REG.yaml: base_points: the 3 points lie"):
        rg.register(line)
    R, t = _kabsch(np.eye(3), SETUP.base_B[:3], np.ones(3))  # points that are not the drawing's
    far = np.sqrt(np.mean(np.sum((np.eye(3) - SETUP.base_B[:3] @ R.T - t) ** 2, axis=1)))
    said = rf"^x.yaml: base_points: the fiducials fit no rigid motion \({far * 1e3:.3g} mm RMS"
    with pytest.raises(InvalidConfigError, match=said + r" off it, over 5 mm\)"):
        rg.register(rg.Fiducials(SETUP.base_B[:3], np.eye(3)), "x.yaml")


def test_the_registration_s_words_give_its_frames_and_their_standard_deviations():
    """The printed line: each frame's roll, pitch, yaw (rad) and position (m) to 6 digits, and
    its standard deviation per axis, the root of the mean of its covariance's rotation and
    translation diagonals, in urad and um (3 digits); the fits' RMS residuals in um; every
    digit a float holds with ``exact``."""
    reg = rg.register(SETUP.fiducials(NOISE, 2))
    number = r"(-?[\d.e+-]+)"
    frame = (
        rf"rpy_rad \[{number}, {number}, {number}\], xyz_m \[{number}, {number}, {number}\] "
        rf"\(\+- {number} urad, {number} um per axis\)"
    )
    said = re.fullmatch(
        rf"X_TB {frame} from 4 fiducials \({number} um RMS\); "
        rf"X_PM {frame} from 4 fiducials \({number} um RMS\)",
        reg.words(),
    )
    assert said, reg.words()
    values = [float(v) for v in said.groups()]
    assert said.group(1) == f"{RollPitchYaw(reg.X_TB.rotation()).vector()[0]:.6g}"  # 6 digits
    for X, cov, rms, part in (
        (reg.X_TB, reg.cov_B, reg.rms_base_m, values[:9]),
        (reg.X_PM, reg.cov_M, reg.rms_platform_m, values[9:]),
    ):
        pose = np.concatenate([RollPitchYaw(X.rotation()).vector(), X.translation()])
        np.testing.assert_allclose(part[:6], pose, rtol=1e-5, atol=1e-9)
        sd = np.sqrt([np.mean(np.diag(cov)[:3]), np.mean(np.diag(cov)[3:])]) * 1e6
        np.testing.assert_allclose(part[6:8], sd, rtol=5e-3)
        assert part[8] == pytest.approx(rms * 1e6, rel=5e-3)
    assert 1.0 < values[6] < 100.0 and 0.1 < values[7] < 10.0  # urad and um, not rad or m
    exact = rg.transform_words(reg.X_TB, reg.cov_B, exact=True)
    rpy = [float(v) for v in re.search(r"rpy_rad \[(.*?)\]", exact).group(1).split(", ")]
    assert rpy == RollPitchYaw(reg.X_TB.rotation()).vector().tolist()
    only = rg.Registration(reg.X_TB, RigidTransform(), reg.cov_B, np.zeros((6, 6)), 1e-6, 0.0, 4)
    assert only.words().endswith(
        "(1 um RMS); the marker is the platform frame (no platform_points)"
    )


def test_registered_poses_are_converted_with_their_noise_and_the_frames_error():
    reg = SETUP.registration()
    x_TM = SETUP.tracker_poses(POSES_BP)
    got = rg.register_poses(reg, x_TM, 3e-5, 7e-6)
    np.testing.assert_allclose(got.poses, POSES_BP, atol=1e-14)
    np.testing.assert_array_equal(got.pose_covariances, reg.pose_covariances(got.poses, 3e-5, 7e-6))
    np.testing.assert_array_equal(got.frames[0], reg.pose_jacobians(got.poses))
    np.testing.assert_array_equal(got.frames[1], reg.frames_covariance())


def test_a_registration_file_reads_back_the_frames_its_fiducials_give(tmp_path):
    fiducials = SETUP.fiducials(NOISE, 0)
    path = files.write_registration(tmp_path / "reg.yaml", fiducials)
    reg, direct = rf.read_registration(path), rg.register(fiducials)
    assert np.abs(reg.X_TB.GetAsMatrix4() - direct.X_TB.GetAsMatrix4()).max() == 0
    assert np.abs(reg.X_PM.GetAsMatrix4() - direct.X_PM.GetAsMatrix4()).max() == 0
    np.testing.assert_array_equal(reg.cov_M, direct.cov_M)
    # Without platform points the marker is the platform frame, exactly.
    text = "base_points:\n" + "".join(
        f"  - {{base_m: {b.tolist()}, tracker_m: {t.tolist()}}}\n"
        for b, t in zip(fiducials.base_B, fiducials.base_T)
    )
    (tmp_path / "base.yaml").write_text(text)
    only = rf.read_registration(tmp_path / "base.yaml")
    assert only.X_PM.IsExactlyIdentity() and not only.cov_M.any() and only.platform_points == 0
    assert np.abs(only.X_TB.GetAsMatrix4() - direct.X_TB.GetAsMatrix4()).max() == 0


_GOOD_BASE = (
    "base_points:\n"
    "  - {base_m: [0.2, 0, 0], tracker_m: [1.2, 0, 0]}\n"
    "  - {base_m: [0, 0.2, 0], tracker_m: [1, 0.2, 0]}\n"
    "  - {base_m: [-0.2, 0, 0], tracker_m: [0.8, 0, 0]}\n"
)
_PLATFORM = (
    "platform_points:\n"
    "  marker_in_tracker: {rpy_rad: [0, 0, 0], xyz_m: [1, 0, 0.3]}\n"
    "  points:\n"
    "    - {platform_m: [0.1, 0, 0], tracker_m: [1.1, 0, 0.3]}\n"
    "    - {platform_m: [0, 0.1, 0], tracker_m: [1, 0.1, 0.3]}\n"
    "    - {platform_m: [-0.1, 0, 0], tracker_m: [0.9, 0, 0.3]}\n"
)


def _two_points():
    return "\n".join(_GOOD_BASE.splitlines()[:3]) + "\n"


#: A file of frames fitted to a registration motion, good.
_FRAMES = (
    "motion_frames:\n  tracker_base: {rpy_rad: [0, 0, 0], xyz_m: [1, 0, 0]}\n"
    "  platform_marker: {rpy_rad: [0, 0, 0], xyz_m: [0, 0, 0]}\n  rms_m: 1.0e-5\n"
)

HOSTILE = {
    "two points": (_two_points(), "base_points: 2 points: a frame needs at least 3"),
    "collinear": (
        _GOOD_BASE.replace(
            "[0, 0.2, 0], tracker_m: [1, 0.2, 0]", "[0.1, 0, 0], tracker_m: [1.1, 0, 0]"
        ),
        "base_points: the 3 points lie on one line",
    ),
    "NaN": (
        _GOOD_BASE.replace("[1.2, 0, 0]", "[.nan, 0, 0]"),
        r"base_points\[0\].tracker_m\[0\]: expected a finite",
    ),
    "nan": (_GOOD_BASE.replace("[1.2, 0, 0]", "[nan, 0, 0]"), "got 'nan'"),
    "inf": (_GOOD_BASE.replace("[1.2, 0, 0]", "[1e400, 0, 0]"), "finite number"),
    "far": (_GOOD_BASE.replace("[1.2, 0, 0]", "[1200, 0, 0]"), r"in \[-100, 100\] m"),
    "text": (_GOOD_BASE.replace("[1.2, 0, 0]", "['1.2', 0, 0]"), "got '1.2'"),
    "two numbers": (
        _GOOD_BASE.replace("[1.2, 0, 0]", "[1.2, 0]"),
        r"base_points\[0\].tracker_m: expected 3 numbers",
    ),
    "unknown key": (
        _GOOD_BASE.replace("tracker_m: [1.2", "trackr_m: [1.2"),
        r"base_points\[0\]: unknown key 'trackr_m' \(known: base_m, tracker_m\)",
    ),
    "unknown top key": (_GOOD_BASE + "units: mm\n", "the file: unknown key 'units'"),
    "a key not text": (_GOOD_BASE + "? [1, 2]\n: 3\n", "the file: unknown key a key that is not"),
    "a long key": (_GOOD_BASE + "x" * 60 + ": 1\n", r"the file: unknown key 'x{39} \(known"),
    "no base points": (
        "point_sigma_m: 2.0e-6\n",
        "the file: missing base_points; write base_points: ",
    ),
    "a list": (
        "- 1\n- 2\n",
        "the file: expected a mapping of base_points, platform_points, point_sigma_m$",
    ),
    "one point": (
        "\n".join(_GOOD_BASE.splitlines()[:2]) + "\n",
        "base_points: 1 point: a frame needs at least 3",
    ),
    "base_m two numbers": (
        _GOOD_BASE.replace("[0.2, 0, 0]", "[0.2, 0]"),
        r"base_points\[0\].base_m: expected 3 numbers \[x, y, z\] in m, got 2",
    ),
    "base_m far": (
        _GOOD_BASE.replace("[0.2, 0, 0]", "[1000, 0, 0]"),
        r"base_points\[0\].base_m\[0\]: expected a finite number in \[-100, 100\] m, got '1000'",
    ),
    "base_m not a list": (
        _GOOD_BASE.replace("[0.2, 0, 0]", "0.2"),
        r"base_points\[0\].base_m: expected a list",
    ),
    "sigma a list": (
        _GOOD_BASE + "point_sigma_m: [1]\n",
        r"point_sigma_m: expected a finite number in \[0, 0.001\] m, got a list or mapping",
    ),
    "sigma long text": (_GOOD_BASE + "point_sigma_m: " + "x" * 60 + "\n", r"got 'x{39}$"),
    "marker far": (
        _GOOD_BASE + _PLATFORM.replace("xyz_m: [1, 0, 0.3]", "xyz_m: [1000, 0, 0.3]"),
        r"platform_points.marker_in_tracker.xyz_m\[0\]: expected a finite number in "
        r"\[-100, 100\] m, got '1000'",
    ),
    "marker rotation noise": (
        _GOOD_BASE + _PLATFORM.replace("0.3]}", "0.3], rotation_sigma_rad: 0.5}", 1),
        r"platform_points.marker_in_tracker.rotation_sigma_rad: expected a finite number in "
        r"\[0, 0.01\] rad, got '0.5'",
    ),
    "marker translation noise": (
        _GOOD_BASE + _PLATFORM.replace("0.3]}", "0.3], translation_sigma_m: 0.5}", 1),
        r"platform_points.marker_in_tracker.translation_sigma_m: expected a finite number in "
        r"\[0, 0.001\] m, got '0.5'",
    ),
    "marker unknown key": (
        _GOOD_BASE + _PLATFORM.replace("rpy_rad:", "rpy:"),
        "platform_points.marker_in_tracker: unknown key 'rpy'",
    ),
    "marker without its pose": (
        _GOOD_BASE + _PLATFORM.replace("{rpy_rad: [0, 0, 0], xyz_m: [1, 0, 0.3]}", "{}"),
        "platform_points.marker_in_tracker: missing rpy_rad, xyz_m; write base_points:",
    ),
    "platform two points": (
        _GOOD_BASE + "\n".join(_PLATFORM.splitlines()[:5]) + "\n",
        "platform_points.points: 2 points: a frame needs at least 3",
    ),
    "a mapping of points": ("base_points: {a: 1}\n", "base_points: expected a list"),
    "sigma zero": (_GOOD_BASE + "point_sigma_m: 0\n", "point_sigma_m: must be at least 1e-09 m"),
    "sigma tiny": (
        _GOOD_BASE + "point_sigma_m: 1.0e-300\n",
        "point_sigma_m: must be at least 1e-09 m .*, got 1e-300",
    ),
    "points a micrometre apart": (
        "base_points:\n"
        "  - {base_m: [0, 0, 0], tracker_m: [1, 0, 0]}\n"
        "  - {base_m: [1.0e-6, 0, 0], tracker_m: [1.000001, 0, 0]}\n"
        "  - {base_m: [0, 1.0e-6, 0], tracker_m: [1, 1.0e-6, 0]}\n",
        r"base_points: the fiducials are 0.000\d+ mm RMS from their centre, too close to fix a "
        r"frame: its rotation is known to \+- [\d.e+]+ mrad only",
    ),
    "motion frames unknown key": (
        "motion_frames:\n  tracker_base: {rpy_rad: [0, 0, 0], xyz_m: [1, 0, 0]}\n"
        "  platform_marker: {rpy_rad: [0, 0, 0], xyz_m: [0, 0, 0]}\n  rms_m: 1.0e-5\n"
        "  colour: red\n",
        "motion_frames: unknown key 'colour'",
    ),
    "motion frames rms": (
        "motion_frames:\n  tracker_base: {rpy_rad: [0, 0, 0], xyz_m: [1, 0, 0]}\n"
        "  platform_marker: {rpy_rad: [0, 0, 0], xyz_m: [0, 0, 0]}\n  rms_m: 0.5\n",
        r"motion_frames.rms_m: expected a finite number in \[0, 0.005\] m",
    ),
    "motion frame turned 7 rad": (
        _FRAMES.replace("tracker_base: {rpy_rad: [0, 0, 0]", "tracker_base: {rpy_rad: [0, 0, 7]"),
        r"motion_frames.tracker_base.rpy_rad\[2\]: expected a finite number in \[-6.28319, "
        r"6.28319\] rad, got '7'",
    ),
    "motion frame 200 m away": (
        _FRAMES.replace("xyz_m: [0, 0, 0]", "xyz_m: [0, 0, 200]"),
        r"motion_frames.platform_marker.xyz_m\[2\]: expected a finite number in \[-100, 100\] m",
    ),
    "motion frame rotation sigma": (
        _FRAMES.replace("xyz_m: [1, 0, 0]}", "xyz_m: [1, 0, 0], rotation_sigma_rad: 0.5}"),
        r"motion_frames.tracker_base.rotation_sigma_rad: expected a finite number in \[0, 0.01\] "
        r"rad, got '0.5'",
    ),
    "motion frame translation sigma": (
        _FRAMES.replace("xyz_m: [0, 0, 0]}", "xyz_m: [0, 0, 0], translation_sigma_m: 0.01}"),
        r"motion_frames.platform_marker.translation_sigma_m: expected a finite number in \[0, "
        r"0.001\] m, got '0.01'",
    ),
    "motion frame missing": (
        _FRAMES.replace("  platform_marker: {rpy_rad: [0, 0, 0], xyz_m: [0, 0, 0]}\n", ""),
        r"motion_frames: missing platform_marker; write motion_frames: \{tracker_base: .* as "
        r"calibrate --register writes it",
    ),
    "motion frame without its pose": (
        _FRAMES.replace("{rpy_rad: [0, 0, 0], xyz_m: [0, 0, 0]}", "{xyz_m: [0, 0, 0]}"),
        r"motion_frames.platform_marker: missing rpy_rad; write motion_frames:",
    ),
    "motion frame unknown key": (
        _FRAMES.replace("tracker_base: {rpy_rad:", "tracker_base: {rpy:"),
        r"motion_frames.tracker_base: unknown key 'rpy' \(known: rpy_rad, xyz_m, "
        r"rotation_sigma_rad, translation_sigma_m\)",
    ),
    "motion frames source a list": (
        _FRAMES + "  source: [1, 2]\n",
        "motion_frames.source: expected a text of at most 1000 characters",
    ),
    "motion frames beside points": (
        _GOOD_BASE + "motion_frames:\n  tracker_base: {rpy_rad: [0, 0, 0], xyz_m: [1, 0, 0]}\n"
        "  platform_marker: {rpy_rad: [0, 0, 0], xyz_m: [0, 0, 0]}\n  rms_m: 1.0e-5\n",
        "the file: unknown key 'base_points'",
    ),
    "sigma huge": (
        _GOOD_BASE + "point_sigma_m: 0.5\n",
        r"point_sigma_m: expected a finite number in \[0, 0.001\] m, got '0.5'",
    ),
    "mismatched": (_GOOD_BASE.replace("[0.8, 0, 0]", "[0.9, 0, 0]"), "fit no rigid motion"),
    "twice": (_GOOD_BASE + "base_points: []\n", "appears twice"),
    "not yaml": ("base_points: [\n", "not YAML"),
    "empty": ("  \n", "it is empty.* write base_points: "),
    "python tag": (
        _GOOD_BASE.replace("[1.2, 0, 0]", "[!!python/object:os.system 1, 0, 0]"),
        "got '1'",
    ),
    "platform without marker": (
        _GOOD_BASE + "platform_points:\n  points: []\n",
        "platform_points: missing marker_in_tracker",
    ),
    "marker in degrees": (
        _GOOD_BASE + _PLATFORM.replace("rpy_rad: [0, 0, 0]", "rpy_rad: [0, 0, 30]"),
        r"marker_in_tracker.rpy_rad\[2\]: expected a finite number in \[-6.28319, 6.28319\] rad",
    ),
    "platform collinear": (
        _GOOD_BASE
        + _PLATFORM.replace(
            "[0, 0.1, 0], tracker_m: [1, 0.1, 0.3]", "[0.05, 0, 0], tracker_m: [1.05, 0, 0.3]"
        ),
        "platform_points.points: the 3 points lie on one line",
    ),
}


@pytest.mark.parametrize("case", sorted(HOSTILE))
def test_a_hostile_registration_file_is_refused_in_one_line_naming_the_field(tmp_path, case):
    text, message = HOSTILE[case]
    path = tmp_path / "reg.yaml"
    path.write_text(text)
    with pytest.raises(InvalidConfigError, match=message) as err:
        rf.read_registration(path)
    assert "\n" not in str(err.value) and str(path) in str(err.value)


def test_frames_fitted_to_a_motion_are_read_as_written(tmp_path):
    """motion_frames_yaml's file read back: the frames (to the digits YAML keeps), each
    sigma squared on its covariance's diagonal (rotation then translation), the fit's RMS,
    and its source in words (or that none was given); without the sigmas, zero covariance."""
    from pydrake.math import RigidTransform, RollPitchYaw

    X_TB = RigidTransform(RollPitchYaw(0.1, -0.2, 0.3), [1.0, -0.5, 0.25])
    X_PM = RigidTransform(RollPitchYaw(-0.05, 0.0, 0.02), [0.01, 0.02, 0.03])
    text = rf.motion_frames_yaml(X_TB, X_PM, (1e-3, 2e-4), (3e-3, 4e-4), 5e-5, "a run")
    (tmp_path / "reg.yaml").write_text(text)
    reg = rf.read_registration(tmp_path / "reg.yaml")
    np.testing.assert_allclose(reg.X_TB.GetAsMatrix4(), X_TB.GetAsMatrix4(), atol=1e-12)
    np.testing.assert_allclose(reg.X_PM.GetAsMatrix4(), X_PM.GetAsMatrix4(), atol=1e-12)
    np.testing.assert_allclose(np.diag(reg.cov_B), [1e-6] * 3 + [4e-8] * 3, rtol=1e-12)
    np.testing.assert_allclose(np.diag(reg.cov_M), [9e-6] * 3 + [1.6e-7] * 3, rtol=1e-12)
    assert not np.any(reg.cov_B - np.diag(np.diag(reg.cov_B)))
    assert reg.rms_base_m == 5e-5 and reg.rms_platform_m == 0.0
    assert reg.source == "fitted to a registration motion (a run)"
    (tmp_path / "bare.yaml").write_text(_FRAMES)
    bare = rf.read_registration(tmp_path / "bare.yaml")
    assert bare.source == "fitted to a registration motion (no source given)"
    assert not bare.cov_B.any() and not bare.cov_M.any() and bare.rms_base_m == 1e-5
    np.testing.assert_allclose(bare.X_TB.translation(), [1, 0, 0], atol=0)


def test_the_file_of_fitted_frames_reads_as_a_person_would_write_it():
    """Its head says what it is and where it goes (verify --registration; calibrate needs
    fiducials), then the frames in the order written (the base, then the marker), each pose a
    line of three numbers, each sigma named; a calibration refuses it, saying why."""
    from pydrake.math import RigidTransform, RollPitchYaw

    X = RigidTransform(RollPitchYaw(0.0, 0.0, 0.5), [1.0, -0.5, 0.25])
    text = rf.motion_frames_yaml(X, RigidTransform(), (1e-3, 2e-4), (3e-3, 4e-4), 5e-5, "a run")
    lines = text.splitlines()
    assert lines[:3] == [
        "# The tracker's frames fitted to a registration motion (stewart-drake calibrate "
        "--register):",
        "# X_TB the base in the tracker's frame, X_PM the marker on the platform. Give this "
        "file to",
        "# verify --registration; calibrate's identification needs fiducials instead.",
    ]
    assert lines[3:] == [
        "motion_frames:",
        "  tracker_base:",
        "    rpy_rad: [0.0, 0.0, 0.5]",
        "    xyz_m: [1.0, -0.5, 0.25]",
        "    rotation_sigma_rad: 0.001",
        "    translation_sigma_m: 0.0002",
        "  platform_marker:",
        "    rpy_rad: [0.0, 0.0, 0.0]",
        "    xyz_m: [0.0, 0.0, 0.0]",
        "    rotation_sigma_rad: 0.003",
        "    translation_sigma_m: 0.0004",
        "  rms_m: 5.0e-05",
        "  source: a run",
    ]


def test_a_calibration_refuses_frames_fitted_to_a_motion(tmp_path):
    """calibrate identifies the kinematics a motion's frames take as true: it reads fiducials
    only, and says so; a fiducial's noise exactly at its least (1 nm) is read, and a source of
    exactly 1000 characters (1001 refused)."""
    (tmp_path / "reg.yaml").write_text(_FRAMES)
    with pytest.raises(InvalidConfigError) as err:
        rf.read_fiducials(tmp_path / "reg.yaml")
    assert str(err.value).endswith(
        "motion_frames: frames fitted to a registration motion take the robot's kinematics as "
        "true, which a calibration identifies: register the tracker with fiducials "
        "(base_points) for calibrate"
    )
    (tmp_path / "long.yaml").write_text(_FRAMES + "  source: " + "s" * rf.MAX_SOURCE_CHARS + "\n")
    assert rf.read_registration(tmp_path / "long.yaml").source.endswith("(" + "s" * 1000 + ")")
    (tmp_path / "over.yaml").write_text(_FRAMES + "  source: " + "s" * 1001 + "\n")
    with pytest.raises(InvalidConfigError, match="at most 1000 characters"):
        rf.read_registration(tmp_path / "over.yaml")
    (tmp_path / "least.yaml").write_text(_GOOD_BASE + "point_sigma_m: 1.0e-9\n")
    assert rf.read_fiducials(tmp_path / "least.yaml").point_sigma_m == 1e-9


def test_the_good_files_of_the_hostile_cases_are_read(tmp_path):
    (tmp_path / "reg.yaml").write_text(_GOOD_BASE + _PLATFORM)
    reg = rf.read_registration(tmp_path / "reg.yaml")
    np.testing.assert_allclose(reg.X_TB.translation(), [1, 0, 0], atol=1e-12)
    np.testing.assert_allclose(reg.X_PM.GetAsMatrix4(), np.eye(4), atol=1e-12)
    # The noises a file gives are those read: the fiducials' (at its bound), the marker's.
    noise = "0.3], rotation_sigma_rad: 3.0e-5, translation_sigma_m: 7.0e-6}"
    text = _PLATFORM.replace("0.3]}", noise, 1)
    (tmp_path / "noise.yaml").write_text(_GOOD_BASE + "point_sigma_m: 0.001\n" + text)
    fiducials = rf.read_fiducials(tmp_path / "noise.yaml")
    assert fiducials.point_sigma_m == 0.001 and fiducials.marker_sigma == (3e-5, 7e-6)
    (tmp_path / "base.yaml").write_text(_GOOD_BASE + "point_sigma_m: 1.0e-5\n")
    assert rf.read_fiducials(tmp_path / "base.yaml").point_sigma_m == 1e-5


def test_a_large_missing_or_unreadable_registration_file_is_refused(tmp_path):
    big = tmp_path / "big.yaml"
    big.write_text(_GOOD_BASE + "#" * int(rf.MAX_REGISTRATION_BYTES) + "\n")
    with pytest.raises(InvalidConfigError, match="over the bound"):
        rf.read_registration(big)
    with pytest.raises(MissingFileError, match="no registration file"):
        rf.read_registration(tmp_path / "none.yaml")
    with pytest.raises(InvalidConfigError, match="a folder"):
        rf.read_registration(tmp_path)
    (tmp_path / "bin.yaml").write_bytes(b"base_points: \xff\xfe\n")
    with pytest.raises(InvalidConfigError, match="not UTF-8"):
        rf.read_registration(tmp_path / "bin.yaml")
    # Anchors that would expand to billions of nodes are refused before they expand.
    bomb = "a: &a [1, 1, 1, 1, 1, 1, 1, 1, 1]\n" + "".join(
        f"{c}: &{c} [{', '.join(['*' + p] * 9)}]\n" for p, c in zip("abcdefgh", "bcdefghi")
    )
    (tmp_path / "bomb.yaml").write_text(bomb)
    with pytest.raises(InvalidConfigError, match="expand"):
        rf.read_registration(tmp_path / "bomb.yaml")


def test_the_emulated_tracker_follows_its_marker_in_its_own_frame():
    t = np.linspace(0.0, 2.0, 201)
    x = np.tile(POSES_BP[0], (len(t), 1))
    x[:, 3] += 0.01 * t
    quiet = tracker.MeasurementNoise(0.0, 0.0)
    times, seen = tracker.track(t, x, quiet, 0, setup=SETUP)
    _, plain = tracker.track(t, x, quiet, 0)
    np.testing.assert_allclose(seen, SETUP.tracker_poses(plain), atol=1e-15)
    np.testing.assert_allclose(SETUP.registration().base_poses(seen), plain, atol=1e-14)
    assert len(times) == 100


def test_fiducials_measured_in_a_mirrored_frame_are_refused_where_they_can_tell():
    """Six fiducials off one plane, measured by a tracker whose x axis is reversed (a
    left-handed frame): a reflection fits them to their noise, any rotation to centimetres,
    and the fit is refused. As written (right-handed) they pass; on one plane the two cannot be
    told apart (the plane turned over), and they pass too."""
    rng = np.random.default_rng(7)
    p_B = np.array([[0.1, 0, 0], [0, 0.1, 0], [-0.1, 0, 0], [0, -0.1, 0], [0, 0, 0.08],
                    [0.05, 0.05, 0.12]])  # fmt: skip
    R = RotationMatrix(RollPitchYaw(0.3, -0.2, 1.1)).matrix()
    p_A = p_B @ R.T + [0.5, -0.2, 1.0] + rng.normal(0, 20e-6, p_B.shape)
    X, _, rms = rg.fit_frame(p_A, p_B)
    assert rms < 40e-6
    mirrored = p_A * [-1.0, 1.0, 1.0]
    with pytest.raises(InvalidConfigError, match="fit a mirrored frame") as err:
        rg.fit_frame(mirrored, p_B)
    assert "left-handed" in str(err.value)
    flat = p_B[:4]
    rg.fit_frame((flat @ R.T + [0.5, -0.2, 1.0]) * [-1.0, 1.0, 1.0], flat)
