"""A run's plan: every derived value computed once, from the scenario's own numbers, validated once,
and what the station builds from it read back from Drake."""

import numpy as np
import pytest

from stewart_drake.references.data_collection import data_collection_trajectory
from stewart_drake.robot import limits
from stewart_drake.robot.kinematics import X_HOME
from stewart_drake.run import simulate as experiments
from stewart_drake.run.diagram import controller_context, held_station
from stewart_drake.run.plan import RunPlan, check_reference, checked_plan, make_plan
from stewart_drake.run.scenario import DataCollectionReference, Scenario
from stewart_drake.run.scenario_io import load_scenario


@pytest.mark.parametrize("torque_limit", [None, 0.5, 5.0])
def test_the_plan_derives_the_robot_as_built_from_the_scenario_s_numbers(torque_limit):
    scenario = load_scenario(
        "paper_hardware", [f"torque_limit_Nm={torque_limit or 'null'}", "payload_scale=1.5"]
    )
    motors = scenario.hardware.motors
    plan = make_plan(scenario, with_reference=False)
    # The rotor seen at the crank: rotor inertia x gear ratio^2 (2.5e-4 kg m^2 here).
    assert plan.geometry.motor_reflected_inertia == pytest.approx(
        motors.rotor_inertia * motors.gear_ratio**2, rel=1e-15
    )
    assert plan.servo.peak_torque_Nm == motors.peak_torque_Nm
    # The lower of the scenario's limit and the motors' peak torque (0.702 N m).
    expected = min(v for v in (torque_limit, motors.peak_torque_Nm) if v is not None)
    assert plan.torque_limit_Nm == expected
    assert plan.motor_limits.peak_torque_Nm == expected
    assert plan.motor_limits.margin == scenario.guard.effort_margin
    assert plan.motor_limits.max_speed_rad_s == motors.no_load_speed_rad_s
    # The payload is on the simulated platform only: the controller believes in the robot.
    assert plan.plant_geometry.platform_mass == pytest.approx(1.5 * plan.geometry.platform_mass)
    np.testing.assert_allclose(
        plan.plant_geometry.platform_inertia, 1.5 * np.array(plan.geometry.platform_inertia)
    )
    assert plan.delay_periods == scenario.hardware.computation_delay_periods == 1
    assert plan.sample_offset_s == 0.5 * scenario.plant.time_step
    assert plan.reference is None


def test_the_ideal_robot_has_no_servo_no_limit_and_no_delay():
    plan = make_plan(Scenario())
    assert (plan.servo, plan.torque_limit_Nm, plan.delay_periods) == (None, None, 0)
    assert plan.geometry.motor_reflected_inertia == 0.0
    assert plan.encoder_count_at_tip == (1e-6, 1e-5)
    np.testing.assert_allclose(plan.reference.evaluate(0.0)[0], X_HOME, atol=1e-12)


def test_one_encoder_count_at_the_crank_tip():
    plan = make_plan(load_scenario("paper_hardware"), with_reference=False)
    counts = plan.scenario.hardware.encoders.counts_per_rev
    tip = 2 * np.pi / counts * plan.geometry.crank_length
    assert plan.encoder_count_at_tip == pytest.approx(
        (tip, tip / plan.geometry.platform_radius), rel=1e-15
    )


def test_the_station_applies_the_plan_s_torque_limit():
    # Read back from what Drake built: a command above the limit comes out at the limit.
    scenario = load_scenario(
        "paper_hardware", ["torque_limit_Nm=0.5", "hardware.motors.current_time_constant_s=0"]
    )
    plan = make_plan(scenario, with_reference=False)
    station, _, context = held_station(plan, T=np.full(6, 1.0))
    applied = station.GetOutputPort("motor_torque_applied").Eval(context)
    np.testing.assert_allclose(applied, plan.torque_limit_Nm)
    assert station.plan is plan


def test_a_data_collection_reference_is_made_for_the_plan_s_robot_and_limit():
    scenario = load_scenario("paper_hardware", ["duration_s=1.5"])
    scenario.reference = DataCollectionReference(seed=3)
    plan = make_plan(scenario)
    direct = data_collection_trajectory(
        3, plan.geometry, duration_s=1.5, torque_limit_Nm=plan.torque_limit_Nm
    )
    t = np.linspace(0.0, 1.5, 9)
    for a, b in zip(plan.reference.evaluate(t), direct.evaluate(t)):
        np.testing.assert_array_equal(a, b)


def test_a_plan_is_made_once_and_overridden_without_validating_again(monkeypatch):
    plan = make_plan(Scenario(duration_s=0.05))
    assert make_plan(plan) is plan
    calls = []
    monkeypatch.setattr(Scenario, "validate", lambda self: calls.append(1) or self)
    home = make_plan(plan, reference="home")
    assert isinstance(home, RunPlan) and home.geometry is plan.geometry
    np.testing.assert_allclose(home.reference.evaluate(0.3)[0], X_HOME, atol=1e-12)
    assert calls == []


def test_a_run_validates_its_scenario_once(monkeypatch):
    calls = []
    validate = Scenario.validate

    def counting(self):
        calls.append(1)
        return validate(self)

    scenario = Scenario(duration_s=0.02)  # a dataclass validates when constructed
    monkeypatch.setattr(Scenario, "validate", counting)
    sd, simulator = experiments.build_simulator(scenario)
    simulator.AdvanceTo(0.02)
    assert len(calls) == 1
    assert sd.plan.scenario.duration_s == 0.02


def test_each_controller_context_has_its_own_pose_estimator():
    plan = make_plan(load_scenario("paper_hardware"), with_reference=False)
    a, b = (controller_context(plan, X_HOME, np.zeros(6)) for _ in range(2))
    assert a.pose_estimator is not None and a.pose_estimator is not b.pose_estimator
    assert (a.torque_limit_Nm, a.delay_periods, a.offset_s) == (
        plan.torque_limit_Nm,
        1,
        plan.sample_offset_s,
    )
    ideal = controller_context(make_plan(Scenario()), X_HOME, np.zeros(6))
    assert ideal.pose_estimator is None


def test_the_reference_check_uses_the_simulated_robot():
    # The paper manoeuvre's report on the plan equals the one on the scenario (planned there).
    scenario = load_scenario("paper_hardware", ["duration_s=2"])
    a = check_reference(scenario, raise_refused=False)
    b = check_reference(make_plan(scenario), raise_refused=False)
    assert a.ok and b.ok and a.max_cond == b.max_cond


def test_a_checked_plan_keeps_its_report_and_is_not_checked_again(monkeypatch):
    from stewart_drake.run import plan as plans

    plan = checked_plan(Scenario(duration_s=0.05))
    assert plan.report is not None and plan.report.ok and plan.report.series == {}
    for name in ("check_run_memory", "check_reference_shown"):
        monkeypatch.setattr(plans, name, lambda *a, **k: pytest.fail("checked again"))
    assert checked_plan(plan) is plan
    sd, simulator = experiments.build_simulator(plan)
    assert sd.plan is plan
    # Another reference is checked again: its plan carries no report of the old one.
    assert make_plan(plan, reference="home").report is None


def test_the_run_starts_where_the_reference_starts():
    sd, simulator = experiments.build_simulator(Scenario(duration_s=0.05))
    x0, x_dot0, _ = sd.trajectory.evaluate(0.0)
    np.testing.assert_array_equal(sd.x_initial, x0)
    np.testing.assert_array_equal(sd.x_dot_initial, x_dot0)
    state = sd.station.GetOutputPort("platform_state").Eval(
        sd.station.GetMyContextFromRoot(simulator.get_context())
    )
    np.testing.assert_allclose(state, np.concatenate([x0, x_dot0]), atol=1e-9)


def _same_robot(a, b) -> bool:
    import dataclasses

    return all(
        np.array_equal(np.asarray(getattr(a, f.name)), np.asarray(getattr(b, f.name)))
        for f in dataclasses.fields(a)
    )


@pytest.mark.parametrize("name", ["paper_hardware", "paper_bus", "paper_ideal"])
def test_the_robot_s_geometry_without_a_run_is_the_plan_s(name):
    """robot_geometry is the plan's believed robot (the bus's servos' reflected inertia on
    paper_bus), not the plant's (a robot drawn from tolerances is the plan's plant_geometry)."""
    from stewart_drake.run.plan import robot_geometry

    plan = make_plan(load_scenario(name), with_reference=False)
    assert _same_robot(robot_geometry(load_scenario(name)), plan.geometry)
    if name != "paper_bus":  # robot_tolerances is simulated, never on the bus
        drawn = load_scenario(name, ["robot_tolerances={seed: 3}"])
        built = make_plan(drawn, with_reference=False)
        assert _same_robot(robot_geometry(drawn), built.geometry)
        assert not _same_robot(robot_geometry(drawn), built.plant_geometry)


@pytest.mark.parametrize("name", ["paper_hardware", "paper_bus", "paper_ideal"])
def test_the_robot_s_motor_limits_and_reference_without_a_run_are_the_plan_s(name):
    """robot_motor_limits is the plan's motor_limits (its peak torque the plan's torque limit:
    the bus's current limit on paper_bus), run_reference the plan's reference, sample for
    sample."""
    from stewart_drake.run.plan import robot_motor_limits, run_reference

    scenario = load_scenario(name, ["torque_limit_Nm=0.5"])
    plan = make_plan(scenario)
    assert robot_motor_limits(scenario) == plan.motor_limits
    assert robot_motor_limits(scenario).peak_torque_Nm == plan.torque_limit_Nm
    t = np.linspace(0.0, plan.duration_s, 101)
    for ours, its in zip(run_reference(scenario).evaluate(t), plan.reference.evaluate(t)):
        np.testing.assert_array_equal(ours, its)


def _report_fields(report):
    from dataclasses import fields

    return {f.name: getattr(report, f.name) for f in fields(report) if f.name != "series"}


def _same(a, b) -> bool:
    if isinstance(a, dict):
        return a.keys() == b.keys() and all(_same(a[k], b[k]) for k in a)
    if isinstance(a, np.ndarray | float):
        return np.array_equal(a, b, equal_nan=True)
    return str(a) == str(b)


def test_a_reference_checked_in_stretches_gives_the_report_of_one_check(monkeypatch):
    """The check runs in stretches of VALIDATE_CHUNK_SAMPLES so that its memory does not grow
    with the run: 997-sample stretches over the paper's first 4 s (five stretches, the last
    short), with motors too weak for it (every refusal reported), give every figure, time, leg
    and motor of the check in one go, and the same sample-by-sample series."""
    from stewart_drake.run import plan as trajectories

    scenario = load_scenario(
        "paper_hardware", ["hardware.motors.peak_torque_Nm=0.4", "duration_s=4"]
    )
    monkeypatch.setattr(trajectories, "VALIDATE_CHUNK_SAMPLES", 10**9)
    whole = check_reference(scenario, raise_refused=False)
    assert not whole.ok and whole.first_effort_violation is not None
    monkeypatch.setattr(trajectories, "VALIDATE_CHUNK_SAMPLES", 997)
    parts = check_reference(scenario, raise_refused=False)
    clearance = ("min_clearance", "min_clearance_t", "clearance_t", "clearance")
    mine, theirs = (
        {k: v for k, v in _report_fields(r).items() if k not in clearance + ("clearance_profile",)}
        for r in (parts, whole)
    )
    assert _same(mine, theirs)
    mine, theirs = (
        {k: v for k, v in r.series.items() if k not in clearance} for r in (parts, whole)
    )
    assert _same(mine, theirs) and parts.series["t"].size == 4_001
    # The clearance is measured wherever a part has moved its resolution since the last measure,
    # counted afresh in each stretch: each check is within the resolution of the path's true
    # smallest clearance, so the two within it of each other.
    resolution = limits.DEFAULT_CLEARANCE_RESOLUTION_M
    assert abs(parts.min_clearance - whole.min_clearance) <= resolution
    # The stretches' clearance profiles joined: one profile from the first sample to the last,
    # its measures the series' (each stretch's first and last pose among them).
    t_p, c_p, res = parts.clearance_profile
    assert res == resolution and t_p[0] == 0.0 and t_p[-1] == pytest.approx(4.0)
    assert np.all(np.diff(t_p) > 0) and t_p.size > whole.clearance_profile[0].size
    np.testing.assert_array_equal(t_p, parts.series["clearance_t"])
    np.testing.assert_array_equal(c_p, parts.series["clearance"])
    lean = check_reference(scenario, raise_refused=False, keep_series=False)
    assert lean.series == {} and lean.summary() == parts.summary()
    np.testing.assert_array_equal(lean.clearance_profile[1], c_p)  # kept without the series


def test_a_refusal_in_a_later_stretch_names_the_same_time(monkeypatch):
    from stewart_drake.base.errors import StewartError
    from stewart_drake.references.samples import CubicSplineTrajectory
    from stewart_drake.run import plan as trajectories

    t = np.linspace(0.0, 10.0, 101)
    poses = np.tile([0.0, 0.0, 0.0, 0.0, 0.0, 0.30], (101, 1))
    poses[:, 3] = np.where(t > 7.0, 0.1 * (t - 7.0), 0.0)  # a crank joint's cone at 8.958 s
    reference = CubicSplineTrajectory(t, poses, name="away")
    scenario = load_scenario("paper_hardware", ["guard.allow_infeasible=true"])
    messages = []
    for chunk in (10**9, 997):
        monkeypatch.setattr(trajectories, "VALIDATE_CHUNK_SAMPLES", chunk)
        with pytest.raises(StewartError) as info:
            check_reference(scenario, reference)
        messages.append(str(info.value))
    # The earliest refusal, whichever check finds it: a crank joint's cone, before the pose
    # goes out of reach at 9.056 s.
    assert messages[0] == messages[1] and "t = 8.958 s" in messages[0], messages
