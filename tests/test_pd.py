"""pd.py: the crank PD's closed-form gains place every mode of the linearized chain where its
docstring says, and one update applies T_ff + K_p (theta_d - theta) + K_d (w_d - w)."""

import numpy as np
import pytest

from stewart_drake.base.errors import InvalidConfigError
from stewart_drake.control.pd import CrankPdController, PdDriver
from stewart_drake.robot import kinematics, statics
from stewart_drake.robot.geometry import X_HOME


@pytest.mark.parametrize("bandwidth_hz, damping", [(20.0, 1.0), (15.0, 0.5), (30.0, 0.7)])
def test_every_mode_of_the_linearized_chain_has_the_bandwidth_and_damping(
    geometry, bandwidth_hz, damping
):
    """M_theta theta'' = -K_p theta - K_d theta': each of the 12 poles has |s| = 2 pi f and
    Re s = -zeta 2 pi f (a double pole at -2 pi f when critically damped)."""
    x0 = X_HOME + np.array([0.2, -0.1, 0.3, 0.02, -0.01, 0.01])
    pd = CrankPdController(
        geometry, PdDriver(bandwidth_hz=bandwidth_hz, damping=damping), x_initial=x0
    )
    M = statics.crank_inertia_matrix(geometry, x0)
    w_n = 2 * np.pi * bandwidth_hz
    np.testing.assert_allclose(pd.K_p, w_n**2 * M, rtol=1e-14)
    A = np.block(
        [[np.zeros((6, 6)), np.eye(6)], [-np.linalg.solve(M, pd.K_p), -np.linalg.solve(M, pd.K_d)]]
    )
    s = np.linalg.eigvals(A)
    # 1e-6: a double root (zeta = 1) splits by about sqrt(eps) in the eigenvalue solver
    np.testing.assert_allclose(np.abs(s), w_n, rtol=1e-6)
    np.testing.assert_allclose(s.real, -damping * w_n, rtol=1e-6)


def test_one_update_applies_the_pd_law_on_the_crank_states(geometry):
    pd = CrankPdController(geometry, PdDriver(bandwidth_hz=10.0, damping=0.8))
    context = pd.CreateDefaultContext()
    rng = np.random.default_rng(3)
    x = np.concatenate(
        [
            X_HOME + rng.uniform(-1, 1, 6) * [0.02, 0.02, 0.02, 2e-3, 2e-3, 2e-3],
            rng.normal(size=6) * 0.1,
        ]
    )
    ref = np.concatenate([X_HOME, np.zeros(6), np.zeros(6)])
    T_ff = statics.holding_torques(geometry, X_HOME)
    pd.get_x_input_port().FixValue(context, x)
    pd.get_x_d_input_port().FixValue(context, ref)
    pd.get_T_ff_input_port().FixValue(context, T_ff)
    assert pd.get_omega_input_port() is None  # no weights, no omega port
    update = pd.EvalUniquePeriodicDiscreteUpdate(context)
    T = update.get_vector(0).CopyToVector()
    theta = kinematics.ik(geometry, x[:6])
    w = kinematics.jacobian(geometry, x[:6]) @ x[6:]
    M = statics.crank_inertia_matrix(geometry, X_HOME)
    w_n = 2 * np.pi * 10.0
    expected = T_ff + M @ (
        w_n**2 * (kinematics.ik(geometry, X_HOME) - theta) + 2 * 0.8 * w_n * (0.0 - w)
    )
    np.testing.assert_allclose(T, expected, rtol=1e-10, atol=1e-12)
    np.testing.assert_array_equal(update.get_vector(1).CopyToVector(), [1, 0])  # one schedule
    np.testing.assert_allclose(update.get_vector(2).CopyToVector(), x[:6] - X_HOME)


def test_a_bandwidth_the_sampling_cannot_carry_is_refused():
    assert PdDriver(bandwidth_hz=79.0).validate(1e-3) is not None  # 2 pi 79 1e-3 = 0.496
    with pytest.raises(
        InvalidConfigError,
        match=r"driver.bandwidth_hz = 80 Hz is too high for "
        r"a 0.001 s period \(2 pi f h = 0.50 > 0.5\)",
    ):
        PdDriver(bandwidth_hz=80.0).validate(1e-3, prefix="driver.")
    with pytest.raises(
        InvalidConfigError,
        match=r"controller.damping must be a finite number "
        r"in \(0, inf\]",
    ):
        PdDriver(damping=0.0).validate(1e-3)
