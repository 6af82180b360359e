"""analysis/error_budget without its closed loops: the encoders' floor against a Monte Carlo of
the encoders themselves (counts drawn on each crank, the pose found by forward kinematics), the
budget's table as a user reads it (units under their headers, the dominant source), each
"without" run taking away its source and only it (the simulations stood in for), the shares in
quadrature, the refusals before any simulation. The budget from real closed-loop runs is
tests/test_error_budget.py's."""

import numpy as np
import pytest

from stewart_drake.analysis.error_budget import (
    SOURCES,
    axis_rms,
    error_budget,
    quantization_floor,
    source_share,
)
from stewart_drake.base.errors import InvalidConfigError
from stewart_drake.references.organ.breathing import Breathing
from stewart_drake.robot import kinematics
from stewart_drake.robot.forward_kinematics import fk
from stewart_drake.robot.geometry import X_HOME
from stewart_drake.run.plan import make_plan
from stewart_drake.run.scenario_io import load_scenario


@pytest.mark.parametrize("pose", [X_HOME, X_HOME + [0.1, -0.05, 0.2, 0.02, -0.01, -0.02]])
def test_the_floor_is_what_uniform_counts_give_through_forward_kinematics(pose):
    """Each crank off its true angle by a uniform fraction of a count in [-1/2, 1/2], 4000
    draws, the pose by forward kinematics: its standard deviation per axis is the floor to 5 %
    (the Monte Carlo's own spread is 2 %)."""
    scenario = load_scenario("paper_bus", [])
    floor = quantization_floor(scenario, pose)
    geometry = make_plan(scenario, with_reference=False).geometry
    q = 2 * np.pi / 4096
    theta = kinematics.ik(geometry, pose)
    rng = np.random.default_rng(11)
    poses = np.array(
        [fk(geometry, theta + rng.uniform(-0.5, 0.5, 6) * q, x0=pose)[0] for _ in range(4000)]
    )
    np.testing.assert_allclose(poses.std(axis=0), floor, rtol=0.05)


def test_the_ideal_robot_has_no_floor_to_budget():
    with pytest.raises(InvalidConfigError, match="ideal robot"):
        quantization_floor(load_scenario("paper_ideal", []))
    with pytest.raises(InvalidConfigError, match="ideal robot"):
        error_budget(load_scenario("paper_ideal", []), "breathing")


def test_a_window_outside_the_span_is_refused():
    with pytest.raises(InvalidConfigError, match="skip_s"):
        error_budget(load_scenario("paper_bus", []), "breathing", duration_s=4.0, skip_s=5.0)


def test_the_budget_table_reads_as_a_user_reads_it():
    """A budget made by hand: the header names urad for the rotations and um for the
    translations, each figure is a millionth of its SI value to 3 digits, the encoders' row is
    theirs, and what dominates is the largest share, the period where it is the period."""
    from stewart_drake.analysis.error_budget import ErrorBudget

    rows = {name: np.zeros(6) for name in SOURCES}
    rows["encoders"] = np.array([3e-4, 2e-4, 1e-4, 5e-5, 4e-5, 1e-5])
    rows["period and delay"] = np.array([1e-4, 1e-4, 1e-4, 8e-5, 6e-5, 2e-5])
    budget = ErrorBudget(
        floor=np.full(6, 1.34e-4),
        total=np.array([4e-4, 3e-4, 2e-4, 1.1e-4, 9e-5, 2.5e-5]),
        encoder_pose=np.array([5e-4, 4e-4, 3e-4, 1.8e-4, 1.5e-4, 3e-5]),
        rows=rows,
        without={},
        window_s=(2.0, 10.0),
    )
    lines = budget.lines()
    assert lines[0] == (
        "| | phi [urad] | theta [urad] | psi [urad] | X [um] | Y [um] | Z [um] | what lowers it |"
    )
    assert (
        lines[2]
        == "| **true pose**, every source (simulated) | 400 | 300 | 200 | 110 | 90 | 25 |  |"
    )
    assert lines[3] == (
        f"| share of encoders | 300 | 200 | 100 | 50 | 40 | 10 | {SOURCES['encoders']} |"
    )
    assert lines[4] == (
        f"| share of period and delay | 100 | 100 | 100 | 80 | 60 | 20 | "
        f"{SOURCES['period and delay']} |"
    )
    assert (
        "| encoders' floor (what they can know) | 134 | 134 | 134 | 134 | 134 | 134 |  |" in lines
    )
    assert (
        "| **encoder pose** (what the robot reads) | 500 | 400 | 300 | 180 | 150 | 30 |  |" in lines
    )
    assert lines[-1] == "Dominant: period and delay in translation, encoders in rotation."


def test_each_without_run_takes_away_its_source_and_only_it(monkeypatch):
    """The simulations the budget runs, caught before they run: without the encoders, 2^30
    counts; without the period and delay, 1 ms and none; without the current loop, no lag;
    without friction, none in the servo and none believed; without the model, the payload the
    controller believes; every other field as the full run's."""
    from stewart_drake.analysis import error_budget as module

    seen = {}

    def fake(scenario, reference, skip):
        seen[len(seen)] = scenario
        return np.full(6, 1e-4), np.full(6, 2e-4), np.array([0, 0, 0, 0, 0, 0.3])

    monkeypatch.setattr(module, "_errors", fake)
    scenario = load_scenario("paper_bus", ["payload_scale=1.2"])
    module.error_budget(scenario, "breathing", duration_s=4.0, skip_s=1.0)
    full, encoders, period, current, friction, model = (seen[k] for k in range(6))
    hw = full.hardware
    assert (full.control_period_s, hw.computation_delay_periods) == (0.01, 1)
    assert encoders.hardware.encoders.counts_per_rev == 2**30
    assert (period.control_period_s, period.hardware.computation_delay_periods) == (1e-3, 0)
    assert period.hardware.encoders == hw.encoders
    assert (
        current.hardware.motors.current_time_constant_s == 0.0 < hw.motors.current_time_constant_s
    )
    assert friction.hardware.motors.coulomb_friction_Nm == 0.0
    assert friction.hardware.motors.viscous_damping == 0.0
    assert friction.controller.friction_scale == 0.0 < full.controller.friction_scale
    assert model.payload_scale == 1.0 and full.payload_scale == 1.2
    for variant in (encoders, current, friction, model):
        assert variant.control_period_s == 0.01


def test_a_share_is_what_taking_the_source_away_removed_in_quadrature():
    """3-4-5 in quadrature; nothing where taking it away made it worse; a run that measured
    nothing (NaN) shares nothing to give."""
    total = np.array([5.0, 5.0, 1.0, 0.0, 2.0, np.nan])
    without = np.array([3.0, 4.0, 2.0, 0.0, 2.0, 1.0])
    share = source_share(total, without)
    np.testing.assert_allclose(share[:5], [4.0, 3.0, 0.0, 0.0, 0.0], rtol=0, atol=1e-15)
    assert np.isnan(share[5])


def test_the_rms_is_per_axis_over_the_rows():
    e = np.zeros((4, 6))
    e[:, 0] = [3.0, -3.0, 3.0, -3.0]  # a square wave of 3: RMS 3
    e[:, 4] = [1.0, 1.0, 1.0, 5.0]  # sqrt((3 + 25) / 4) = sqrt(7)
    np.testing.assert_allclose(axis_rms(e), [3.0, 0, 0, 0, np.sqrt(7.0), 0], rtol=1e-15, atol=0)
    assert np.isnan(axis_rms(np.empty((0, 6)))).all()


def test_a_budget_longer_than_its_bound_is_refused_before_any_simulation(monkeypatch):
    """A breath of an hour would simulate five hours, seven times: refused in one line with what
    to change, before a simulation starts."""
    from stewart_drake.analysis import error_budget as eb
    from stewart_drake.run import simulate

    def never(*args, **kw):
        raise AssertionError("simulated")

    monkeypatch.setattr(simulate, "run_experiment", never)
    hour = Breathing(period_s=3600.0)
    with pytest.raises(InvalidConfigError, match=r"would simulate 18000 s of the motion \(five"):
        error_budget(load_scenario("paper_bus", []), hour)
    with pytest.raises(InvalidConfigError, match="--param period="):
        error_budget(load_scenario("paper_bus", []), "breathing", duration_s=eb.MAX_SPAN_S + 1)
