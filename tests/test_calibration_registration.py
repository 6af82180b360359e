"""The tracker's frames registered to the robot's from fiducials: the weighted rigid fit and its
covariance (against Monte Carlo), the conversion of marker poses in the tracker's frame to
platform poses in the base frame (against Drake's RigidTransform), REG.yaml's reader on good
and hostile files. Fast unit tests only (tools/mutation.py runs them against every mutant of
calibration/registration.py); the identification of registered poses and the command are
tests/test_calibration_registered.py's."""

import numpy as np
import pytest
from pydrake.math import RigidTransform, RollPitchYaw, RotationMatrix
from scipy.spatial.transform import Rotation

from stewart_drake.base.errors import InvalidConfigError, MissingFileError
from stewart_drake.calibration import files, tracker
from stewart_drake.calibration import registration as rg
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
    # The stated covariance is the scatter's, entry by entry, to Monte Carlo's precision.
    scatter = np.cov(errors.T)
    np.testing.assert_allclose(np.sqrt(np.diag(scatter)), np.sqrt(np.diag(cov)), rtol=0.06)
    assert np.max(np.abs(scatter - cov)) < 0.1 * np.max(np.abs(cov))
    assert np.mean(d2) == pytest.approx(6.0, rel=0.1)  # chi-square of 6 degrees of freedom
    assert np.max(np.abs(errors.mean(axis=0)) / np.sqrt(np.diag(cov))) < 0.1  # unbiased
    assert 1e-6 < rms < 1e-5 and np.sqrt(cov[0, 0]) < 2e-5


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
    reg = SETUP.registration()
    x_TM = SETUP.tracker_poses(POSES_BP)
    rng = np.random.default_rng(4)
    noisy = np.array([tracker.noisy_poses(x_TM, NOISE, rng) for _ in range(3000)])  # (K, N, 6)
    predicted = reg.pose_covariances(POSES_BP, NOISE.rotation_rad, NOISE.translation_m)
    for k, x in enumerate(POSES_BP):
        xc = reg.base_poses(noisy[:, k])
        turn = Rotation.from_matrix(rotation_rpy(xc[:, :3]) @ rotation_rpy(x[:3]).T).as_rotvec()
        scatter = np.cov(np.column_stack([turn, xc[:, 3:] - x[3:]]).T)
        assert np.max(np.abs(scatter - predicted[k])) < 0.08 * np.max(np.abs(predicted[k]))
    # The lever arm: the 50 mm marker adds its rotation noise to the positions' 5 um.
    assert np.sqrt(predicted[0, 3, 3]) > NOISE.translation_m * 1.0001


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
    assert reg.base_points == 4 and reg.platform_points == 4
    assert 0.5e-6 < reg.rms_base_m < 5e-6 and "from 4 fiducials" in reg.words()


def test_a_registration_file_reads_back_the_frames_its_fiducials_give(tmp_path):
    fiducials = SETUP.fiducials(NOISE, 0)
    path = files.write_registration(tmp_path / "reg.yaml", fiducials)
    reg, direct = rg.read_registration(path), rg.register(fiducials)
    assert np.abs(reg.X_TB.GetAsMatrix4() - direct.X_TB.GetAsMatrix4()).max() == 0
    assert np.abs(reg.X_PM.GetAsMatrix4() - direct.X_PM.GetAsMatrix4()).max() == 0
    np.testing.assert_array_equal(reg.cov_M, direct.cov_M)
    # Without platform points the marker is the platform frame, exactly.
    text = "base_points:\n" + "".join(
        f"  - {{base_m: {b.tolist()}, tracker_m: {t.tolist()}}}\n"
        for b, t in zip(fiducials.base_B, fiducials.base_T)
    )
    (tmp_path / "base.yaml").write_text(text)
    only = rg.read_registration(tmp_path / "base.yaml")
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
        "unknown key 'trackr_m'",
    ),
    "unknown top key": (_GOOD_BASE + "units: mm\n", "the file: unknown key 'units'"),
    "no base points": ("point_sigma_m: 2.0e-6\n", "missing base_points"),
    "a list": ("- 1\n- 2\n", "the file: expected a mapping"),
    "a mapping of points": ("base_points: {a: 1}\n", "base_points: expected a list"),
    "sigma zero": (_GOOD_BASE + "point_sigma_m: 0\n", "point_sigma_m: must be > 0"),
    "sigma huge": (
        _GOOD_BASE + "point_sigma_m: 0.5\n",
        r"point_sigma_m: expected a finite number in \[0, 0.001\]",
    ),
    "mismatched": (_GOOD_BASE.replace("[0.8, 0, 0]", "[0.9, 0, 0]"), "fit no rigid motion"),
    "twice": (_GOOD_BASE + "base_points: []\n", "appears twice"),
    "not yaml": ("base_points: [\n", "not YAML"),
    "empty": ("  \n", "it is empty"),
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
        rg.read_registration(path)
    assert "\n" not in str(err.value) and str(path) in str(err.value)


def test_the_good_files_of_the_hostile_cases_are_read(tmp_path):
    (tmp_path / "reg.yaml").write_text(_GOOD_BASE + _PLATFORM)
    reg = rg.read_registration(tmp_path / "reg.yaml")
    np.testing.assert_allclose(reg.X_TB.translation(), [1, 0, 0], atol=1e-12)
    np.testing.assert_allclose(reg.X_PM.GetAsMatrix4(), np.eye(4), atol=1e-12)


def test_a_large_missing_or_unreadable_registration_file_is_refused(tmp_path):
    big = tmp_path / "big.yaml"
    big.write_text(_GOOD_BASE + "#" * int(rg.MAX_REGISTRATION_BYTES) + "\n")
    with pytest.raises(InvalidConfigError, match="over the bound"):
        rg.read_registration(big)
    with pytest.raises(MissingFileError, match="no registration file"):
        rg.read_registration(tmp_path / "none.yaml")
    with pytest.raises(InvalidConfigError, match="a folder"):
        rg.read_registration(tmp_path)
    (tmp_path / "bin.yaml").write_bytes(b"base_points: \xff\xfe\n")
    with pytest.raises(InvalidConfigError, match="not UTF-8"):
        rg.read_registration(tmp_path / "bin.yaml")
    # Anchors that would expand to billions of nodes are refused before they expand.
    bomb = "a: &a [1, 1, 1, 1, 1, 1, 1, 1, 1]\n" + "".join(
        f"{c}: &{c} [{', '.join(['*' + p] * 9)}]\n" for p, c in zip("abcdefgh", "bcdefghi")
    )
    (tmp_path / "bomb.yaml").write_text(bomb)
    with pytest.raises(InvalidConfigError, match="expand"):
        rg.read_registration(tmp_path / "bomb.yaml")


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
