"""Faults before and during a run end in a typed error, and the data is not lost."""

import numpy as np
import pytest

from stewart_drake.base.errors import (
    JointLimitError,
    SimulationDivergedError,
    SingularPoseError,
    StewartError,
    UnreachablePoseError,
)
from stewart_drake.control.contract import LQI_STATUS_NAMES
from stewart_drake.plant.closed_chain import assemble
from stewart_drake.references.trajectories import SineTrajectory, paper_manoeuvre
from stewart_drake.robot import kinematics, limits
from stewart_drake.robot.geometry import StewartGeometry
from stewart_drake.run.plan import check_reference, make_plan
from stewart_drake.run.scenario import Robot, Scenario
from stewart_drake.run.simulate import build_simulator, run_experiment
from stewart_drake.station import guard
from stewart_drake.station.guard import GuardConfig

HEAVE_TO_DEAD_POINT = SineTrajectory(
    amplitude=(0, 0, 0, 0, 0, 0.117), frequency_hz=(0, 0, 0, 0, 0, 0.25), name="heave"
)


def _config(tmp_path, duration_s=0.3, **guard_fields):
    return Scenario(
        duration_s=duration_s,
        guard=GuardConfig(divergence_dir=str(tmp_path / "diverged"), **guard_fields),
    )


def _load(path):
    with np.load(path, allow_pickle=False) as data:
        return {k: data[k] for k in data.files}


def _check_saved(err, tmp_path, t_fault):
    """The file named in the error holds the logs up to the fault and the last state."""
    assert err.path is not None and str(tmp_path / "diverged") in err.path
    assert err.path in str(err)
    saved = _load(err.path)
    for key in (
        "t",
        "x",
        "T",
        "status",
        "state",
        "state_last",
        "t_last",
        "reason",
        "scenario",
        "T_applied_last",
        "integral",
    ):
        assert key in saved, key
    t = saved["t"]
    assert saved["x"].shape == (t.size, 12) and saved["T"].shape == (t.size, 6)
    assert saved["status"].shape == (t.size, len(LQI_STATUS_NAMES))
    assert t[0] == 0.0 and t[-1] <= float(saved["t_last"]) + 1e-12
    assert float(saved["t_last"]) == pytest.approx(err.t)
    assert t_fault <= err.t <= t_fault + 0.011  # caught within one check period
    assert t.size >= int(t_fault / 1e-3)  # nothing before the fault is lost
    assert saved["state_last"].shape == saved["state"].shape[1:]
    assert str(saved["reason"]) in str(err)
    assert "name: paper" in str(saved["scenario"]) and "controller:" in str(saved["scenario"])
    return saved


def test_nan_torque_stops_the_run_and_saves_the_logs(tmp_path, feedforward_fault):
    calls = {"n": 0}

    def faulty(T_ff):  # the 101st control step (t = 0.1005 s)
        calls["n"] += 1
        return np.full(6, np.nan) if calls["n"] > 100 else T_ff

    feedforward_fault(faulty)
    with pytest.raises(SimulationDivergedError, match="motor torques are not finite") as info:
        run_experiment(_config(tmp_path))
    saved = _check_saved(info.value, tmp_path, 0.1)
    # The update of t = 0.1005 s makes the NaN torque; Drake refuses it at the plant's update of
    # 0.101 s, before the plant uses it, and the guard names it.
    assert info.value.t == pytest.approx(0.101)
    assert np.all(np.isnan(saved["T_last"]))
    # The loggers publish at 0.101 s before the plant's update: the last row is the fault
    # itself, everything before it is finite, and the plant never used the NaN.
    assert saved["t"][-1] == pytest.approx(0.101) and np.all(np.isnan(saved["T"][-1]))
    assert np.all(np.isfinite(saved["T"][:-1])) and np.all(np.isfinite(saved["x"]))
    assert np.all(np.isfinite(saved["state_last"]))


def test_nan_state_stops_the_run(tmp_path):
    sd, simulator = build_simulator(_config(tmp_path))
    simulator.AdvanceTo(0.1005)  # between plant updates: the next step is the controller's
    plant_context = sd.plant.GetMyMutableContextFromRoot(simulator.get_mutable_context())
    state = plant_context.get_mutable_discrete_state_vector()
    k = state.size() - 1  # a rod's angular rate
    state.SetAtIndex(k, np.nan)
    with pytest.raises(
        SimulationDivergedError, match=f"plant state is not finite \\(entry {k}"
    ) as info:
        guard.advance(sd, simulator, lambda: simulator.AdvanceTo(0.3))
    saved = _check_saved(info.value, tmp_path, 0.1)
    assert np.isnan(saved["state_last"][k])
    # The plant state is logged every 10 ms (state_log_period_s): all of it before the fault.
    assert np.allclose(np.diff(saved["t_state"]), 0.01) and saved["t_state"][-1] == 0.1
    assert np.all(np.isfinite(saved["state"]))


def _trips_at_0_1_s(sd, simulator, tmp_path, match: str) -> None:
    """Advancing from 0.1 s to 0.3 s raises a divergence that ``match`` describes, the logs of
    0.1 s saved with it."""
    with pytest.raises(SimulationDivergedError, match=match) as info:
        guard.advance(sd, simulator, lambda: simulator.AdvanceTo(0.3))
    _check_saved(info.value, tmp_path, 0.1)


def test_broken_loop_trips_the_closure_bound(tmp_path):
    # SAP pulls a broken loop back within a few steps: check every step to see the 5 mm.
    sd, simulator = build_simulator(_config(tmp_path, check_period_s=1e-3))
    simulator.AdvanceTo(0.1)
    plant_context = sd.plant.GetMyMutableContextFromRoot(simulator.get_mutable_context())
    X_WE = sd.plant.GetFreeBodyPose(plant_context, sd.handles.platform)
    X_WE.set_translation(X_WE.translation() + [0.0, 0.0, 0.005])  # 5 mm off its six rods
    sd.plant.SetFreeBodyPose(plant_context, sd.handles.platform, X_WE)
    bound = r"loop-closure error .* exceeds GuardConfig.max_closure_error_m = 0.001 m"
    _trips_at_0_1_s(sd, simulator, tmp_path, bound)


def test_a_lost_platform_trips_the_tracking_bound(tmp_path):
    sd, simulator = build_simulator(_config(tmp_path, check_period_s=1e-3))
    simulator.AdvanceTo(0.1)
    plant_context = sd.plant.GetMyMutableContextFromRoot(simulator.get_mutable_context())
    x = paper_manoeuvre().evaluate(0.1)[0] + [0.3, 0, 0, 0, 0, 0]  # 0.3 rad of roll off
    assemble(sd.plant, plant_context, sd.handles, x)  # loops closed: only phi
    bound = r"\|phi - phi_d\| = 0.\d+ rad exceeds GuardConfig.max_tracking_error = 0.2 rad"
    _trips_at_0_1_s(sd, simulator, tmp_path, bound)


def test_another_drake_failure_keeps_its_type_and_saves_the_logs(tmp_path, feedforward_fault):
    def broken(T_ff):
        raise RuntimeError("actuator driver fault")

    sd, simulator = build_simulator(_config(tmp_path))
    simulator.AdvanceTo(0.05)
    feedforward_fault(broken)
    with pytest.raises(RuntimeError, match="actuator driver fault") as info:
        guard.advance(sd, simulator, lambda: simulator.AdvanceTo(0.3))
    assert not isinstance(info.value, StewartError)  # a bug is not relabelled "diverged"
    note = " ".join(getattr(info.value, "__notes__", []))
    path = note.split("saved in ")[-1]
    saved = _load(path)
    assert saved["t"][-1] == pytest.approx(0.05) and "actuator driver fault" in str(saved["reason"])


def test_a_closure_bound_below_the_solver_compliance_trips_at_the_first_check(tmp_path):
    """SAP closes the loops to ~1e-7 m along the paper run; a 1e-9 m bound cannot hold."""
    with pytest.raises(
        SimulationDivergedError,
        match=r"loop-closure error \d.* m at rod \d "
        r"exceeds GuardConfig.max_closure_error_m = 1e-09 m",
    ) as info:
        run_experiment(_config(tmp_path, max_closure_error_m=1e-9))
    assert info.value.t <= 0.011
    saved = _load(info.value.path)
    assert saved["t"].size >= 1 and np.all(np.isfinite(saved["x"]))


def test_a_normal_run_is_checked_and_writes_nothing(tmp_path):
    result = run_experiment(_config(tmp_path, duration_s=0.2))
    assert result.metrics["finite"]
    assert not (tmp_path / "diverged").exists()


def test_guard_checks_closure_and_tracking_at_its_period(tmp_path, monkeypatch):
    times = []
    original = guard.DivergenceGuard.check

    def counted(self, context):
        times.append(context.get_time())
        return original(self, context)

    monkeypatch.setattr(guard.DivergenceGuard, "check", counted)
    sd, simulator = build_simulator(_config(tmp_path, duration_s=0.2, check_period_s=0.02))
    simulator.AdvanceTo(0.2)
    # one Python call per check period (a periodic event), none in between
    np.testing.assert_allclose(times, np.arange(0.0, 0.2001, 0.02), atol=1e-12)


# -- the reference, before anything is simulated --------------------------------------------------


def test_reference_beyond_the_motor_range_names_time_leg_and_limit():
    config = Scenario(
        robot=Robot.from_value(StewartGeometry(motor_angle_min_deg=-60.0)), duration_s=10.0
    )
    with pytest.raises(JointLimitError, match=r"leg \d leaves its motor_angle limit") as info:
        check_reference(config)
    err = info.value
    t = np.arange(0.0, 10.0005, 1e-3)
    theta = kinematics.ik(make_plan(config).geometry, paper_manoeuvre().evaluate(t)[0])
    first = int(np.argmax(np.any(np.rad2deg(theta) < -60.0, axis=1)))
    assert err.t == pytest.approx(t[first])
    assert np.rad2deg(theta[first, err.leg]) < -60.0
    assert err.limit == "motor_angle" and err.margin < 0
    assert "motor_angle_min_deg" in str(err)


def test_heave_to_the_dead_point_is_refused_although_cond_is_moderate():
    """The known gap of cond(J): all six legs reach the dead point together."""
    config = Scenario(duration_s=2.0)
    t = np.arange(0.0, 2.0005, 1e-3)
    x = HEAVE_TO_DEAD_POINT.evaluate(t)[0]
    geometry = make_plan(config).geometry
    cond, inv = kinematics.singularity_measures(geometry, x)
    assert cond.max() < 45.0 and np.abs(kinematics.leg_reach_ratio(geometry, x)).max() < 1
    with pytest.raises(SingularPoseError, match=r"1/sigma_max\(J\) = 0.00\d+ < 0.01") as info:
        check_reference(config, HEAVE_TO_DEAD_POINT)
    first = int(np.argmax(inv < limits.DEFAULT_MIN_SIGMA_MIN_INV))
    assert info.value.measure == "sigma_min_inv" and info.value.t == pytest.approx(t[first])
    assert info.value.pose[5] > 0.415
    # Without the second measure the path passes: that is the gap it closes.
    report = limits.validate_trajectory(make_plan(config).geometry, t, x, min_sigma_min_inv=0.0)
    assert report.ok


def test_cond_threshold_refuses_the_paper_path_where_cond_first_exceeds_it():
    config = Scenario(duration_s=10.0, guard=GuardConfig(cond_threshold=60.0))
    with pytest.raises(SingularPoseError, match=r"cond\(J\) = 60.\d+ > 60") as info:
        check_reference(config)
    t = np.arange(0.0, 10.0005, 1e-3)
    geometry = make_plan(config).geometry
    cond, _ = kinematics.singularity_measures(geometry, paper_manoeuvre().evaluate(t)[0])
    assert info.value.t == pytest.approx(t[int(np.argmax(cond > 60.0))])
    assert check_reference(Scenario(duration_s=10.0)).max_cond == pytest.approx(77.69, abs=0.01)


def test_unreachable_reference_fails_before_any_simulation(tmp_path):
    too_high = SineTrajectory(amplitude=(0, 0, 0, 0, 0, 0.2), frequency_hz=(0, 0, 0, 0, 0, 1.0))
    # Nearly singular just before it is out of reach: the earliest refusal is raised.
    with pytest.raises((UnreachablePoseError, SingularPoseError)) as info:
        run_experiment(
            Scenario(duration_s=1.0, guard=GuardConfig(divergence_dir=str(tmp_path / "d"))),
            reference=too_high,
        )
    assert 0.0 < info.value.t < 0.25
    assert not (tmp_path / "d").exists()


# -- the clearance the reference keeps, as the guard reads it ------------------------------------


def test_the_reference_s_clearance_profile_bounds_the_clearance_between_its_measures():
    """The check's clearance profile (kept without the series) promises that between two
    measured poses the parts are at least the smaller measure less the resolution apart: the
    clearance measured at every control sample of the paper's manoeuvre (its first 2 s) keeps
    that promise, and the profile measured far fewer poses than there are samples."""
    from stewart_drake.plant.clearance import clearance_model

    plan = make_plan(Scenario(duration_s=2.0))
    report = check_reference(plan, keep_series=False)
    t_p, c_p, resolution = report.clearance_profile
    assert not report.series and resolution == limits.DEFAULT_CLEARANCE_RESOLUTION_M
    assert 2 < len(t_p) < 0.5 * 2.0 / plan.control_period_s
    assert t_p[0] == 0.0 and t_p[-1] == pytest.approx(2.0)
    assert np.min(c_p) == pytest.approx(report.min_clearance)
    t = np.arange(0.0, 2.0 + 1e-9, plan.control_period_s)
    measured, _ = clearance_model(plan.plant_geometry).sweep(
        plan.reference.evaluate(t)[0], max_distance=report.clearance_threshold + 0.02
    )
    j = np.clip(np.searchsorted(t_p, t), 1, len(t_p) - 1)
    promised = np.minimum(c_p[j - 1], c_p[j]) - resolution
    assert np.all(measured >= promised - 1e-9)
    assert np.min(measured - promised) < 2 * resolution  # a bound, not a gap a mile wide


def test_the_guard_lets_a_part_stray_by_half_the_clearance_the_reference_keeps_there(
    tmp_path, monkeypatch
):
    """The guard's allowed stray follows the profile (half the smaller measure about t, less
    the resolution), never below what guard.min_clearance_m allows, and falls back to that
    floor outside what was checked, where a measure is NaN, or without a profile; a run through
    it asks SceneGraph only at every tenth check where the profile leaves room (the paper run
    strays micrometres), and at every check without one when nothing is left by the floor."""
    from stewart_drake.plant.clearance import ClearanceModel
    from stewart_drake.run.plan import checked_plan

    checks, asked = [], []
    check, overlaps = guard.DivergenceGuard.check, ClearanceModel.overlaps

    def counted_check(self, context):
        checks.append(round(context.get_time() / self.config.check_period_s))
        return check(self, context)

    def counted_overlaps(self, q):
        asked.append(checks[-1])
        return overlaps(self, q)

    monkeypatch.setattr(guard.DivergenceGuard, "check", counted_check)
    monkeypatch.setattr(ClearanceModel, "overlaps", counted_overlaps)
    scenario = _config(tmp_path, duration_s=0.5)
    plan = checked_plan(scenario)
    t_p, c_p, resolution = plan.report.clearance_profile
    floor = 0.5 * (scenario.guard.min_clearance_m - limits.DEFAULT_CLEARANCE_RESOLUTION_M)
    sd, simulator = build_simulator(plan)
    g = sd.guard
    for t in (0.0, 0.123, 0.25, t_p[-1]):
        j = min(max(int(np.searchsorted(t_p, t)), 1), len(t_p) - 1)
        c = c_p[0] if t == 0.0 else min(c_p[j - 1], c_p[j])
        assert g.stray_allowed(t) == pytest.approx(max(0.5 * (c - resolution), floor))
    assert g.stray_allowed(t_p[-1] + 0.1) == floor and g.stray_allowed(-1.0) == floor
    assert g.stray_allowed(0.25) > 2 * floor  # the paper's manoeuvre keeps far more than 3 mm
    g._profile = (t_p, np.full_like(c_p, np.nan), resolution)
    assert g.stray_allowed(0.25) == floor  # an unmeasured (NaN) clearance: the floor
    # With no floor at all (as if guard.min_clearance_m left nothing), the profile alone
    # spares SceneGraph between the tenth checks; without it every check asks.
    g._profile, g._stray_m = (t_p, c_p, resolution), 0.0
    simulator.AdvanceTo(0.25)
    assert len(checks) >= 25
    assert asked == [k for k in checks if k % guard.INTERFERENCE_EVERY == 0]
    g._profile, before = None, len(checks)
    simulator.AdvanceTo(0.5)
    assert asked[-(len(checks) - before) :] == checks[before:]
