"""Issue 8: bad settings are refused by name; a failed gain solve never yields a NaN gain."""

import numpy as np
import pytest
from pydrake.systems.analysis import Simulator

from stewart_drake.control import lqi as lqi
from stewart_drake.control.lqi import LqiController, error_model, lqi_gain
from stewart_drake.simulation.diagram import StewartConfig
from stewart_drake.errors import (InvalidConfigError, InvalidGeometryError, MissingFileError, RiccatiSolveError, SingularPoseError)
from stewart_drake.studies.experiments import format_metrics, run_experiment
from stewart_drake.model.geometry import X_HOME, StewartGeometry
from stewart_drake.model.statics import holding_torques
from stewart_drake.simulation.guard import GuardConfig


# -- configuration --------------------------------------------------------------------------------

@pytest.mark.parametrize("fields, message", [
    ({"control_period_s": 1.5e-3}, r"control_period_s \(0.0015 s\) must be a whole multiple of "
                                   r"plant_time_step_s \(0.001 s\); the nearest valid value is "
                                   r"0.002 s"),
    ({"schedule_period_s": 0.0125}, r"schedule_period_s \(0.0125 s\) must be a whole multiple of "
                                    r"control_period_s"),
    ({"log_period_s": 2.5e-3}, r"log_period_s \(0.0025 s\) must be a whole multiple of "
                               r"plant_time_step_s"),
    ({"tuner": "ann", "tuner_period_s": 0.0205}, r"tuner_period_s .* whole multiple of "
                                                 r"control_period_s"),
    ({"guard": GuardConfig(check_period_s=0.0105)}, r"guard.check_period_s .* whole multiple"),
    ({"duration_s": -1.0}, r"duration_s must be a finite number in \(0, inf\], got -1.0"),
    ({"duration_s": "10"}, r"duration_s must be a number, got '10' \(a string\)"),
    ({"plant_time_step_s": float("nan")}, r"plant_time_step_s must be a finite number"),
    ({"omega_Q": float("nan")}, r"omega_Q must be a finite number in \[0.001, 1000\]"),
    ({"omega_R": 1e4}, r"omega_R must be a finite number in \[0.001, 1000\], got 10000.0"),
    ({"omega_R": True}, r"omega_R must be one number"),
    ({"feedforward": "pid"}, r"feedforward must be 'gravity', 'inverse_dynamics' or 'none'"),
    ({"feature_window": 0}, r"feature_window must be an integer >= 1"),
    ({"trajectory": "spiral"}, r"unknown trajectory 'spiral'; choose one of \[.*'helix'.*'paper'"),
    ({"trajectory": 3.0}, r"trajectory must be a name or an object with evaluate"),
    ({"guard": {"max_closure_error_m": 1}}, r"guard must be a GuardConfig"),
])
def test_bad_settings_are_refused_by_name(fields, message):
    with pytest.raises(InvalidConfigError, match=message):
        StewartConfig(**fields)


@pytest.mark.parametrize("fields, message", [
    ({"max_closure_error_m": 0.0}, r"max_closure_error_m must be a finite number in \(0, inf\]"),
    ({"max_tracking_error": (0.2,)}, r"max_tracking_error must be \(rad, m\)"),
    ({"max_tracking_error": (0.2, float("inf"))}, r"max_tracking_error\[1\] must be a finite"),
    ({"cond_threshold": 0.5}, r"cond_threshold must be a finite number in \(1, inf\]"),
    ({"divergence_dir": ""}, r"divergence_dir must be a folder path"),
])
def test_bad_guard_settings_are_refused(fields, message):
    with pytest.raises(InvalidConfigError, match=message):
        GuardConfig(**fields)


def test_missing_tuner_weights_are_refused_before_building(tmp_path):
    with pytest.raises(MissingFileError, match="no ANN tuner weights at .*w.npz") as info:
        StewartConfig(tuner="ann", tuner_weights=str(tmp_path / "w.npz"))
    assert isinstance(info.value, FileNotFoundError)


@pytest.mark.parametrize("fields, message", [
    ({"rod_length": 0.9}, r"leg \d cannot close at the home pose .* change the rod or crank"),
    ({"rod_length": 0.25}, r"leg \d cannot close at the home pose"),
    ({"crank_length": -0.11}, r"crank_length must be a finite number in \(0, inf\], got -0.11"),
    ({"base_radius": 0.0}, r"base_radius must be a finite number in \(0, inf\]"),
    ({"rod_length": float("inf")}, r"rod_length must be a finite number"),
    ({"pivot_z": float("nan")}, r"pivot_z must be a finite number"),
    ({"platform_mass": 0.0}, r"platform_mass must be a finite number in \(0, inf\]"),
    ({"rod_mass": "heavy"}, r"rod_mass must be a number, got .heavy. \(a string\)"),
    ({"platform_inertia": (0.001, 0.001, 0.006)}, r"platform_inertia = \[0.001, 0.001, 0.006\] "
                                                  r"kg m\^2 fails the triangle inequality"),
    ({"rod_inertia": (0.0016, 0.0016, 0.0)}, r"rod_inertia needs 3 positive moments"),
    ({"crank_inertia": (1e-6, float("nan"), 6e-5)}, r"crank_inertia has a non-finite value"),
    ({"pivot_angles_deg": (0.0,) * 5}, r"pivot_angles_deg must have shape \(6,\)"),
    ({"motor_angle_min_deg": 10.0}, r"the home pose violates the motor_angle limit"),
])
def test_bad_geometry_is_refused_by_name(fields, message):
    with pytest.raises(InvalidGeometryError, match=message):
        StewartGeometry(**fields)


# -- the controller: omega input and Riccati failures ---------------------------------------------

def _controller_alone(omega, duration_s=0.05):
    """An LqiController simulated alone at home, x = x_d, with ``omega`` on its port."""
    controller = LqiController(StewartGeometry(), period_s=1e-3, schedule_period_s=1e-2)
    simulator = Simulator(controller)
    context = simulator.get_mutable_context()
    controller.get_x_input_port().FixValue(context, np.concatenate([X_HOME, np.zeros(6)]))
    controller.get_x_d_input_port().FixValue(context, np.concatenate([X_HOME, np.zeros(12)]))
    controller.get_T_ff_input_port().FixValue(context, holding_torques(StewartGeometry(), X_HOME))
    controller.get_omega_input_port().FixValue(context, np.asarray(omega, dtype=float))
    simulator.AdvanceTo(duration_s)
    status = controller.GetOutputPort("status").Eval(context)
    K = context.get_discrete_state(2).get_value().reshape(6, 18)
    T = controller.GetOutputPort("T").Eval(context)
    return controller, status, K, T


@pytest.mark.parametrize("omega", [(np.nan, 1.0), (1.0, np.inf), (1e5, 1.0), (1.0, 0.0)])
def test_a_bad_omega_on_the_port_keeps_the_last_gain(omega):
    with pytest.warns(RuntimeWarning, match="gain re-schedule failed .*omega_"):
        controller, status, K, T = _controller_alone(omega)
    assert np.all(np.isfinite(K)) and np.all(np.isfinite(T))
    np.testing.assert_array_equal(K, controller.K_initial)
    assert status[0:2].tolist() == [1.0, 1.0]           # still the weights of that gain
    assert status[2] == 1                               # only the initial solve succeeded
    assert status[3] == 50                              # every one of the 50 steps retried
    np.testing.assert_allclose(T, holding_torques(StewartGeometry(), X_HOME))


def test_a_failed_solve_keeps_the_last_good_gain_and_counts(monkeypatch):
    good = {}
    original = LqiController.gain
    calls = {"n": 0}

    def flaky(self, x, omega_Q=1.0, omega_R=1.0, K_start=None):
        calls["n"] += 1
        if calls["n"] > 3:
            raise RiccatiSolveError("forced failure")
        K = original(self, x, omega_Q, omega_R) * (1.0 + 0.01 * calls["n"])   # each one differs
        good["last"] = K
        return K

    monkeypatch.setattr(LqiController, "gain", flaky)
    with pytest.warns(RuntimeWarning, match="forced failure.*keeping the last good gain"):
        controller, status, K, T = _controller_alone((1.0, 1.0), duration_s=0.1)
    np.testing.assert_array_equal(K, good["last"])
    assert not np.array_equal(K, controller.K_initial)
    assert status[2] == 1 + 3 and status[3] == 10 - 3    # 10 schedules: 3 solved, 7 failed
    assert np.all(np.isfinite(T))


def test_failures_in_a_closed_loop_run_are_reported(monkeypatch, tmp_path):
    original = LqiController.gain
    calls = {"n": 0}

    def every_other(self, x, omega_Q=1.0, omega_R=1.0, K_start=None):
        calls["n"] += 1
        if calls["n"] % 2 == 0:
            raise RiccatiSolveError("forced failure")
        return original(self, x, omega_Q, omega_R, K_start=K_start)

    monkeypatch.setattr(LqiController, "gain", every_other)
    with pytest.warns(RuntimeWarning):
        result = run_experiment(StewartConfig(duration_s=0.2, guard=GuardConfig(
            divergence_dir=tmp_path)))
    # 0.2 s / 10 ms: 20 or 21 schedules (t = 0.2 s included or not), every other one failed;
    # gain_solves also counts the solve at build time (lqi_gain, not gain()).
    failures = result.metrics["gain_failures"]
    assert failures == int(result.status[-1, 3]) == calls["n"] // 2 and failures >= 10
    assert result.metrics["gain_solves"] + failures == calls["n"] + 1
    assert f"({failures} failed, last good gain kept)" in format_metrics(result.metrics)
    assert result.metrics["finite"] and max(result.metrics["rms_error"]) < 1e-3


def test_no_stabilizing_solution_is_a_riccati_error():
    A, B = error_model(np.zeros((6, 6)), 1e-3)          # B = 0: no torque moves anything
    with pytest.raises(RiccatiSolveError, match="DiscreteAlgebraicRiccatiEquation failed"):
        lqi_gain(A, B, np.eye(18), np.eye(6))
    A, B = error_model(np.eye(6), 1e-3)
    with pytest.raises(RiccatiSolveError):
        lqi_gain(A, B, np.eye(18), -np.eye(6))           # R not positive definite


def test_a_singular_input_matrix_is_a_typed_error(monkeypatch):
    from stewart_drake.model import statics

    monkeypatch.setattr(statics, "task_inertia", lambda g, x, theta=None: np.zeros((6, 6)))
    with pytest.raises(SingularPoseError, match="B_c = inf is not finite"):
        lqi.input_matrix(StewartGeometry(), X_HOME)


def test_error_messages_say_what_to_change():
    with pytest.raises(InvalidConfigError) as info:
        StewartConfig(schedule_period_s=0.0153)
    assert "the nearest valid value is 0.015 s" in str(info.value)
