"""estimator.py: the pose from exact encoder angles by Newton's FK, the rate's low-pass, the
chord step, and the FkEstimator system's output. (Quantized encoders along a manoeuvre:
test_hardware.py.)"""

import math

import numpy as np
import pytest

from stewart_drake.base.errors import InvalidConfigError
from stewart_drake.control.estimator import FkEstimator, PoseEstimator
from stewart_drake.robot import kinematics
from stewart_drake.robot.geometry import X_HOME

QUANTUM = 2 * np.pi / 2**40  # "exact sensing" (docs/hardware_figures.md)
H = 1e-3


@pytest.fixture(scope="module")
def estimator(geometry):
    return PoseEstimator(geometry, H, QUANTUM, max_iterations=8)


def test_fk_recovers_the_pose_from_exact_encoder_angles(geometry, estimator, random_poses):
    """Started 5 mm / 30 mrad off (a warm start far worse than a control period's), Newton
    lands on the pose whose IK gives the angles, to well below one encoder count."""
    rng = np.random.default_rng(7)
    for x in random_poses[:30]:
        theta = kinematics.ik(geometry, x)
        start = x + rng.uniform(-1, 1, 6) * [0.03, 0.03, 0.03, 5e-3, 5e-3, 5e-3]
        x_hat, steps, converged = estimator.estimate(theta, start)
        assert converged and steps <= 8
        np.testing.assert_allclose(x_hat, x, rtol=0, atol=1e-11)
        residual = kinematics.wrap_angle(kinematics.ik(geometry, x_hat) - theta)
        assert np.abs(residual).max() <= 0.01 * QUANTUM
        # angles a whole turn away are the same encoder reading
        x_turn, _, converged = estimator.estimate(theta + 2 * np.pi, start)
        assert converged and np.abs(x_turn - x_hat).max() < 1e-11


def test_update_low_passes_the_difference_of_the_estimates(geometry, random_poses):
    cutoff = 50.0
    est = PoseEstimator(geometry, H, QUANTUM, rate_cutoff_hz=cutoff)
    alpha = 1 - math.exp(-2 * math.pi * cutoff * H)
    assert est.alpha == pytest.approx(alpha, rel=1e-15)
    x_prev, v_prev = X_HOME, np.full(6, 0.01)
    x_new = X_HOME + np.array([1e-4, -2e-4, 3e-4, 1e-5, 2e-5, -1e-5])
    x, v = est.update(kinematics.ik(geometry, x_new), x_prev, v_prev)
    np.testing.assert_allclose(x, x_new, atol=1e-10)
    np.testing.assert_allclose(v, v_prev + alpha * ((x_new - X_HOME) / H - v_prev), atol=1e-8)


def test_the_chord_step_agrees_with_the_full_newton_near_the_last_estimate(geometry, estimator):
    x_prev = X_HOME + np.array([0.05, -0.02, 0.1, 0.01, 0.0, -0.01])
    v_prev = np.array([0.2, 0.1, -0.1, 0.02, 0.01, 0.0])
    x_true = x_prev + H * v_prev + np.array([2e-5, -1e-5, 1e-5, 3e-6, -2e-6, 1e-6])
    J_inv = np.linalg.inv(kinematics.jacobian(geometry, x_prev))
    x, v = estimator.track(kinematics.ik(geometry, x_true), x_prev, v_prev, J_inv)
    np.testing.assert_allclose(x, x_true, atol=1e-8)
    np.testing.assert_allclose(v, v_prev + estimator.alpha * ((x - x_prev) / H - v_prev), atol=1e-8)


def test_the_system_outputs_the_estimate_of_its_input(geometry, estimator):
    x_true = X_HOME + np.array([0.01, 0.02, -0.01, 2e-3, -1e-3, 1e-3])
    system = FkEstimator(estimator, offset_s=5e-4, x_initial=X_HOME)
    context = system.CreateDefaultContext()
    system.get_input_port(0).FixValue(context, kinematics.ik(geometry, x_true))
    out = system.get_output_port(0).Eval(context)
    np.testing.assert_allclose(out[:6], x_true, atol=1e-9)
    np.testing.assert_allclose(out[6:], estimator.alpha * (x_true - X_HOME) / H, atol=1e-8)


@pytest.mark.parametrize(
    "argument", ["period_s", "quantum_rad", "rate_cutoff_hz", "tolerance_counts"]
)
def test_a_non_positive_setting_is_refused_by_name(geometry, argument):
    settings = {
        "period_s": H,
        "quantum_rad": QUANTUM,
        "rate_cutoff_hz": 100.0,
        "tolerance_counts": 0.01,
    }
    settings[argument] = 0.0
    with pytest.raises(InvalidConfigError, match=rf"^{argument} must be a finite number in \(0"):
        PoseEstimator(geometry, **settings)
