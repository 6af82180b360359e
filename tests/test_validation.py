"""The LQI's failures: a bad omega on its port, a failed gain solve, an unsolvable Riccati
equation never yield a NaN gain, and are reported with what to change. (Bad scenario settings
refused by name: test_scenario.py.)"""

import numpy as np
import pytest
from pydrake.systems.analysis import Simulator

from stewart_drake.base.errors import (
    InvalidConfigError,
    RiccatiSolveError,
    SingularPoseError,
)
from stewart_drake.control.lqi import gain
from stewart_drake.control.lqi.controller import LqiController, LqiDiagram
from stewart_drake.control.lqi.gain import error_model, lqi_gain
from stewart_drake.robot.geometry import X_HOME, StewartGeometry
from stewart_drake.robot.statics import holding_torques
from stewart_drake.run.metrics import format_metrics
from stewart_drake.run.scenario import LqiDriver, Scenario
from stewart_drake.run.simulate import run_experiment
from stewart_drake.station.guard import GuardConfig

# -- the controller: omega input and Riccati failures ---------------------------------------------


def _controller_alone(omega, duration_s=0.05):
    """An LQI (its Diagram with the contract's ports) simulated alone at home, x = x_d, with
    ``omega`` on its port."""
    controller = LqiDiagram(StewartGeometry(), LqiDriver(schedule_period_s=1e-2), period_s=1e-3)
    simulator = Simulator(controller)
    context = simulator.get_mutable_context()
    controller.get_x_input_port().FixValue(context, np.concatenate([X_HOME, np.zeros(6)]))
    controller.get_x_d_input_port().FixValue(context, np.concatenate([X_HOME, np.zeros(12)]))
    controller.get_T_ff_input_port().FixValue(context, holding_torques(StewartGeometry(), X_HOME))
    controller.get_omega_input_port().FixValue(context, np.asarray(omega, dtype=float))
    simulator.AdvanceTo(duration_s)
    status = controller.GetOutputPort("status").Eval(context)
    K = controller.gain_in_use(context)
    T = controller.GetOutputPort("T").Eval(context)
    return controller.lqi, status, K, T


@pytest.mark.parametrize("omega", [(np.nan, 1.0), (1.0, np.inf), (1e5, 1.0), (1.0, 0.0)])
def test_a_bad_omega_on_the_port_keeps_the_last_gain(omega):
    with pytest.warns(RuntimeWarning, match="gain re-schedule failed .*omega_"):
        controller, status, K, T = _controller_alone(omega)
    assert np.all(np.isfinite(K)) and np.all(np.isfinite(T))
    np.testing.assert_array_equal(K, controller.K_initial)
    assert status[0:2].tolist() == [1.0, 1.0]  # still the weights of that gain
    assert status[2] == 1  # only the initial solve succeeded
    assert status[3] == 50  # every one of the 50 steps retried
    np.testing.assert_allclose(T, holding_torques(StewartGeometry(), X_HOME))


def test_a_failed_solve_keeps_the_last_good_gain_and_counts(monkeypatch):
    good = {}
    original = LqiController._gain
    calls = {"n": 0}

    def flaky(self, x, omega_Q=1.0, omega_R=1.0, K_start=None):
        calls["n"] += 1
        if calls["n"] > 3:
            raise RiccatiSolveError("forced failure")
        K, J = original(self, x, omega_Q, omega_R, None)
        K = K * (1.0 + 0.01 * calls["n"])  # each one differs
        good["last"] = K
        return K, J

    monkeypatch.setattr(LqiController, "_gain", flaky)
    with pytest.warns(RuntimeWarning, match="forced failure.*keeping the last good gain"):
        controller, status, K, T = _controller_alone((1.0, 1.0), duration_s=0.1)
    np.testing.assert_array_equal(K, good["last"])
    assert not np.array_equal(K, controller.K_initial)
    assert status[2] == 1 + 3 and status[3] == 10 - 3  # 10 schedules: 3 solved, 7 failed
    assert np.all(np.isfinite(T))


def test_failures_in_a_closed_loop_run_are_reported(monkeypatch, tmp_path):
    original = LqiController._gain
    calls = {"n": 0}

    def every_other(self, x, omega_Q=1.0, omega_R=1.0, K_start=None):
        calls["n"] += 1
        if calls["n"] % 2 == 0:
            raise RiccatiSolveError("forced failure")
        return original(self, x, omega_Q, omega_R, K_start)

    monkeypatch.setattr(LqiController, "_gain", every_other)
    with pytest.warns(RuntimeWarning):
        result = run_experiment(
            Scenario(duration_s=0.2, guard=GuardConfig(divergence_dir=str(tmp_path)))
        )
    # 0.2 s / 10 ms: 20 or 21 schedules (t = 0.2 s included or not), every other one failed;
    # gain_solves also counts the solve at build time (lqi_gain, not gain()).
    failures = result.metrics["gain_failures"]
    assert (
        failures
        == int(result.status[-1, result.status_names.index("gain_failures")])
        == calls["n"] // 2
        and failures >= 10
    )
    assert result.metrics["gain_solves"] + failures == calls["n"] + 1
    assert f"({failures} failed, last good gain kept)" in format_metrics(result.metrics)
    assert result.metrics["finite"] and max(result.metrics["rms_error"]) < 1e-3


def test_no_stabilizing_solution_is_a_riccati_error():
    A, B = error_model(np.zeros((6, 6)), 1e-3)  # B = 0: no torque moves anything
    with pytest.raises(RiccatiSolveError, match="DiscreteAlgebraicRiccatiEquation failed"):
        lqi_gain(A, B, np.eye(18), np.eye(6))
    A, B = error_model(np.eye(6), 1e-3)
    with pytest.raises(RiccatiSolveError):
        lqi_gain(A, B, np.eye(18), -np.eye(6))  # R not positive definite


def test_a_singular_input_matrix_is_a_typed_error(monkeypatch):
    from stewart_drake.robot import statics

    monkeypatch.setattr(statics, "task_inertia", lambda g, x, theta=None: np.zeros((6, 6)))
    with pytest.raises(SingularPoseError, match="B_c = inf is not finite"):
        gain.input_matrix(StewartGeometry(), X_HOME)


def test_error_messages_say_what_to_change():
    with pytest.raises(InvalidConfigError) as info:
        Scenario(controller=LqiDriver(schedule_period_s=0.0153))
    assert "the nearest valid value is 0.015 s" in str(info.value)
