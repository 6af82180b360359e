"""Bad settings are refused by name; a failed gain solve never yields a NaN gain."""

import numpy as np
import pytest
from pydrake.systems.analysis import Simulator

from stewart_drake.control import lqi as lqi
from stewart_drake.control.lqi import LqiController, LqiDiagram, error_model, lqi_gain
from stewart_drake.control.tuning import AnnTunerDriver
from stewart_drake.errors import (
    InvalidConfigError,
    InvalidGeometryError,
    MissingFileError,
    RiccatiSolveError,
    SingularPoseError,
)
from stewart_drake.model.geometry import X_HOME, StewartGeometry
from stewart_drake.model.statics import holding_torques
from stewart_drake.simulation.guard import GuardConfig
from stewart_drake.simulation.scenario import LqiDriver, NamedReference, Scenario, SensorNoise
from stewart_drake.studies.experiments import format_metrics, run_experiment

# -- configuration --------------------------------------------------------------------------------

NAN = float("nan")


@pytest.mark.parametrize("path, value, message", [
    ("control_period_s", 1.5e-3, r"control_period_s \(0.0015 s\) must be a whole multiple of "
                                 r"plant.time_step \(0.001 s\); the nearest valid value is "
                                 r"0.002 s"),
    ("controller.schedule_period_s", 0.0125, r"controller.schedule_period_s \(0.0125 s\) must be "
                                             r"a whole multiple of control_period_s"),
    ("log_period_s", 2.5e-3, r"log_period_s \(0.0025 s\) must be a whole multiple of "
                             r"plant.time_step"),
    ("tuner", AnnTunerDriver(period_s=0.0205), r"tuner.period_s .* whole multiple of "
                                               r"control_period_s"),
    ("guard.check_period_s", 0.0105, r"guard.check_period_s .* whole multiple"),
    ("duration_s", -1.0, r"duration_s must be a finite number in \(0, inf\], got -1.0"),
    ("duration_s", "10", r"duration_s must be a number, got '10' \(a string\)"),
    ("duration_s", 1e-6, r"duration_s \(1e-06 s\) must cover at least two log periods"),
    ("plant.time_step", NAN, r"plant.time_step must be a finite number"),
    ("plant.discrete_contact_approximation", "tamsi", r"does not enforce the ball constraints"),
    ("controller.omega_Q", NAN, r"controller.omega_Q must be a finite number in \[0.001, 1000\]"),
    ("controller.omega_R", 1e4, r"controller.omega_R must be a finite number in \[0.001, 1000\], "
                                r"got 10000.0"),
    ("controller.omega_R", True, r"controller.omega_R must be one number"),
    ("controller.riccati", "hot", r"controller.riccati must be one of \('warm', 'track', 'cold'\)"),
    ("controller.scales", "x", r"controller.scales must be an LqiScalesConfig, got str"),
    ("feedforward", "pid", r"feedforward must be one of \('gravity', 'inverse_dynamics', 'none'\)"),
    ("tuner", AnnTunerDriver(feature_window=0), r"tuner.feature_window must be an integer in "
                                                r"\[1, 100000\]"),
    ("reference", NamedReference("spiral"), r"unknown trajectory 'spiral'; choose one of "
                                            r"\[.*'helix'.*'paper'"),
    ("reference", 3.0, r"reference must be a NamedReference, CsvReference"),
    ("guard", {"max_closure_error_m": 1}, r"guard must be a GuardConfig, got dict \(a dict"),
    ("robot", {"rod_length": 0.4}, r"robot must be a Robot, got dict"),
    ("sensor_noise", SensorNoise(seed=2**32), r"sensor_noise.seed must be an integer in "
                                              r"\[0, 4294967295\], got 4294967296"),
    ("sensor_noise", SensorNoise(std=[0.1] * 7), r"sensor_noise.std needs 12 finite values"),
    ("payload_scale", 0.0, r"payload_scale must be a finite number in \[0.1, 10\]"),
    ("controller", "lqi", r"controller must be an LqiDriver, PdDriver or UserController"),
])
def test_bad_settings_are_refused_by_name(path, value, message):
    scenario = Scenario()
    *parents, leaf = path.split(".")
    target = scenario
    for name in parents:
        target = getattr(target, name)
    setattr(target, leaf, value)
    with pytest.raises(InvalidConfigError, match=message):
        scenario.validate()


def test_a_bad_robot_is_refused_with_the_field_of_the_geometry():
    scenario = Scenario()
    scenario.robot.rod_length = 0.9
    with pytest.raises(InvalidGeometryError, match=r"robot: leg \d cannot close at the home pose"):
        scenario.validate()


@pytest.mark.parametrize("fields, message", [
    ({"max_closure_error_m": 0.0}, r"max_closure_error_m must be a finite number in \(0, inf\]"),
    ({"max_tracking_error": (0.2,)}, r"max_tracking_error must be \[rad, m\]"),
    ({"max_tracking_error": (0.2, float("inf"))}, r"max_tracking_error\[1\] must be a finite"),
    ({"cond_threshold": 0.5}, r"cond_threshold must be a finite number in \(1, inf\]"),
    ({"divergence_dir": ""}, r"divergence_dir must be a folder path"),
])
def test_bad_guard_settings_are_refused(fields, message):
    with pytest.raises(InvalidConfigError, match=message):
        GuardConfig(**fields)


def test_missing_tuner_weights_are_refused_before_building(tmp_path):
    with pytest.raises(MissingFileError, match="no ANN tuner weights at .*w.npz") as info:
        Scenario(tuner=AnnTunerDriver(weights=str(tmp_path / "w.npz")))
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
    assert status[0:2].tolist() == [1.0, 1.0]           # still the weights of that gain
    assert status[2] == 1                               # only the initial solve succeeded
    assert status[3] == 50                              # every one of the 50 steps retried
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
        K = K * (1.0 + 0.01 * calls["n"])                                      # each one differs
        good["last"] = K
        return K, J

    monkeypatch.setattr(LqiController, "_gain", flaky)
    with pytest.warns(RuntimeWarning, match="forced failure.*keeping the last good gain"):
        controller, status, K, T = _controller_alone((1.0, 1.0), duration_s=0.1)
    np.testing.assert_array_equal(K, good["last"])
    assert not np.array_equal(K, controller.K_initial)
    assert status[2] == 1 + 3 and status[3] == 10 - 3    # 10 schedules: 3 solved, 7 failed
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
        result = run_experiment(Scenario(duration_s=0.2, guard=GuardConfig(
            divergence_dir=str(tmp_path))))
    # 0.2 s / 10 ms: 20 or 21 schedules (t = 0.2 s included or not), every other one failed;
    # gain_solves also counts the solve at build time (lqi_gain, not gain()).
    failures = result.metrics["gain_failures"]
    assert failures == int(result.status[-1, result.status_names.index("gain_failures")]) \
        == calls["n"] // 2 and failures >= 10
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
        Scenario(controller=LqiDriver(schedule_period_s=0.0153))
    assert "the nearest valid value is 0.015 s" in str(info.value)
