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
    assert (full.control_period_s, hw.computation_delay_periods) == (0.005, 1)  # paper_bus's
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
        assert variant.control_period_s == 0.005


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


def _stand_in(monkeypatch, figures):
    """error_budget with its simulations stood in: each run returns ``figures(k, scenario)``
    (its k-th call), and the scenarios and lines said are kept."""
    from stewart_drake.analysis import error_budget as module

    runs = []

    def fake(scenario, reference, skip):
        runs.append((scenario, reference, skip))
        return figures(len(runs) - 1, scenario)

    monkeypatch.setattr(module, "_errors", fake)
    return runs


def test_the_budget_holds_each_run_where_its_source_is(monkeypatch):
    """Every figure of the ErrorBudget from the runs that made it: the total and the encoder pose
    from the run with every source, each row sqrt(total^2 - without^2) of its own run, a
    source the scenario lacks (backlash: paper_bus has none) zeros and no run, the floor at the
    motion's centre, the window, the assumptions, and one line said before each run."""
    centre = X_HOME + np.array([0.0, 0.0, 0.0, 0.0, 0.0, 0.01])
    total = np.array([4e-4, 3e-4, 2e-4, 1.2e-4, 1.0e-4, 3e-5])

    def figures(k, scenario):
        if k == 0:
            return total, 2 * total, centre
        return total * (0.5 + 0.1 * k), np.zeros(6), np.zeros(6)  # run k: its own share

    runs = _stand_in(monkeypatch, figures)
    lines = []
    scenario = load_scenario("paper_bus", ["payload_scale=1.2"])
    budget = error_budget(scenario, "breathing", duration_s=4.0, skip_s=1.0, say=lines.append)
    ran = ["encoders", "period and delay", "current loop", "friction", "model"]
    assert len(runs) == 6 and all(skip == 1.0 for _, _, skip in runs)
    assert lines == [
        "simulating 4 s of the motion, every source ...",
        *(f"simulating 4 s of the motion, without its {name} ..." for name in ran),
    ]
    np.testing.assert_array_equal(budget.total, total)
    np.testing.assert_array_equal(budget.encoder_pose, 2 * total)
    assert list(budget.rows) == list(SOURCES) and sorted(budget.without) == sorted(ran)
    for k, name in enumerate(ran, start=1):
        without = total * (0.5 + 0.1 * k)
        np.testing.assert_array_equal(budget.without[name], without)
        np.testing.assert_allclose(budget.rows[name], total * np.sqrt(1 - (0.5 + 0.1 * k) ** 2))
    np.testing.assert_array_equal(budget.rows["backlash"], np.zeros(6))
    np.testing.assert_allclose(budget.floor, quantization_floor(scenario, centre), rtol=1e-12)
    assert not np.allclose(budget.floor, quantization_floor(scenario))  # not at home
    assert budget.window_s == (1.0, 4.0)
    assert budget.assumptions == {
        "centre": centre.tolist(),
        "control_period_s": 0.005,
        "delay_periods": 1,
        "counts_per_rev": 4096,
        "controller": "CrankServoDriver",
    }
    full = runs[0][0]
    assert full.bus is None and full.duration_s == 4.0 and full.learning is None
    reference = runs[0][1]  # the library's breathing, made on the robot: one for every run
    assert all(r is reference for _, r, _ in runs) and hasattr(reference, "evaluate")
    assert all(run.learning is None and run.bus is None for run, _, _ in runs)
    period = runs[2][0]  # without the period and delay: its logs at the 1 ms period too
    assert (period.log_period_s, period.state_log_period_s) == (1e-3, 1e-2)


@pytest.mark.parametrize(
    "reference, span, skip",
    [
        (Breathing(period_s=2.0), 10.0, 2.0),
        (Breathing(period_s=0.8), 4.0, 0.8),
        ("a still pose", 20.0, 4.0),
    ],
)
def test_without_a_span_the_budget_takes_five_periods_and_skips_the_first(
    monkeypatch, reference, span, skip
):
    """Five of the motion's periods, the first not measured; a reference with no period: 20 s,
    the first 4 not measured."""
    from types import SimpleNamespace

    if isinstance(reference, str):
        reference = SimpleNamespace(evaluate=None)  # an object with evaluate(t), no period
    runs = _stand_in(monkeypatch, lambda k, s: (np.full(6, 1e-4), np.full(6, 1e-4), X_HOME))
    budget = error_budget(load_scenario("paper_bus", []), reference)
    assert budget.window_s == (skip, span)
    assert runs[0][0].duration_s == span and runs[0][2] == skip


def test_the_budgets_json_holds_every_figure_in_si_units():
    from stewart_drake.analysis.error_budget import ErrorBudget

    rows = {"encoders": np.array([1e-4, 0, 0, 2e-5, 0, 0]), "friction": np.full(6, np.nan)}
    budget = ErrorBudget(
        floor=np.full(6, 1.3e-4),
        total=np.arange(6) * 1e-5,
        encoder_pose=np.arange(6) * 2e-5,
        rows=rows,
        without={"encoders": np.ones(6) * 3e-5},
        window_s=(2.0, 10.0),
        assumptions={"control_period_s": 0.01},
        measured="emulated",
    )
    record = budget.record()
    assert record["floor"] == [1.3e-4] * 6
    assert record["total"] == [0.0, 1e-5, 2e-5, 3.0000000000000004e-05, 4e-5, 5e-5]
    assert record["encoder_pose"] == [k * 2e-5 for k in range(6)]
    assert record["rows"]["encoders"] == [1e-4, 0.0, 0.0, 2e-5, 0.0, 0.0]
    assert np.isnan(record["rows"]["friction"]).all()
    assert record["without"] == {"encoders": [3e-5] * 6}
    assert record["window_s"] == [2.0, 10.0]
    assert record["assumptions"] == {"control_period_s": 0.01} and record["measured"] == "emulated"
    assert list(record) == [
        "floor", "total", "encoder_pose", "rows", "without", "window_s", "assumptions", "measured"
    ]  # fmt: skip


def test_what_dominates_is_the_largest_share_by_its_norm_and_a_row_not_measured_never():
    """Translations (X, Y, Z) and rotations judged apart, each by its norm: a row with one large
    axis against one with two middling; a NaN row (its run did not end) is said not measured
    and dominates nothing, even where every other row is zero."""
    from stewart_drake.analysis.error_budget import ErrorBudget

    rows = {
        "backlash": np.full(6, np.nan),
        "encoders": np.array([0.0, 0.0, 5.15e-4, 1.5e-4, 0.0, 0.0]),  # X alone: 1.5e-4
        "friction": np.array([3e-4, 3e-4, 3e-4, 3e-5, 3e-5, 0.0]),  # rotation norm 5.2e-4
        "current loop": np.array([0.0, 0.0, 0.0, 0.0, 0.0, 1e-4]),  # Z alone: 1e-4
    }
    budget = ErrorBudget(
        floor=np.zeros(6), total=np.ones(6), encoder_pose=np.ones(6), rows=rows, without={},
        window_s=(0.0, 1.0), assumptions={"backlash": "its run stalled"},
    )  # fmt: skip
    assert budget.dominant() == ("encoders", "friction")
    lines = budget.lines()
    assert "Not measured, backlash: its run stalled." in lines
    assert "| share of backlash | - | - | - | - | - | - | a gear without play |" in lines
    assert lines[-1] == "Dominant: encoders in translation, friction in rotation."
    assert lines[-3] == ""  # the table, a blank line, then the words
    only_nan = ErrorBudget(
        floor=np.zeros(6), total=np.ones(6), encoder_pose=np.ones(6),
        rows={"backlash": np.full(6, np.nan), "encoders": np.zeros(6)}, without={},
        window_s=(0.0, 1.0),
    )  # fmt: skip
    assert only_nan.dominant() == ("encoders", "encoders")
    assert "Not measured, backlash: its run did not end." in only_nan.lines()


def test_without_friction_each_controller_believes_none_and_another_is_kept():
    from dataclasses import dataclass

    from stewart_drake.analysis.error_budget import _believing_no_friction

    @dataclass(frozen=True)
    class Lqi:
        friction_compensation_Nm: float = 0.3

    @dataclass(frozen=True)
    class Servo:
        friction_scale: float = 1.0

    @dataclass(frozen=True)
    class Other:
        gain: float = 2.0

    assert _believing_no_friction(Lqi()) == Lqi(0.0)
    assert _believing_no_friction(Servo()) == Servo(0.0)
    other = Other()
    assert _believing_no_friction(other) is other


def test_the_floor_defaults_to_home():
    scenario = load_scenario("paper_bus", [])
    np.testing.assert_array_equal(
        quantization_floor(scenario), quantization_floor(scenario, X_HOME)
    )


def test_one_runs_errors_are_the_true_and_the_encoder_poses_over_the_window(monkeypatch):
    """``_errors`` on a run stood in: the poses after ``skip`` only (the rows before are far
    off); the true pose's RMS error; the encoder pose of cranks on whole counts is the true
    pose, and of cranks 0.4 count past them the pose of the whole counts (rounded back); the
    motion's centre is the reference's mean over the window."""
    import dataclasses
    from types import SimpleNamespace

    from stewart_drake.analysis import error_budget as module
    from stewart_drake.run import simulate

    plan = make_plan(load_scenario("paper_bus", []), with_reference=False)
    scenario = dataclasses.replace(plan.scenario, bus=None)  # as error_budget passes it
    geometry = plan.geometry
    q = 2 * np.pi / 4096
    t = np.arange(8) * 0.01
    x_d = np.tile(X_HOME, (8, 1))
    x_d[:, 5] += np.linspace(0.0, 0.01, 8)
    counts = np.round(kinematics.ik(geometry, x_d) / q)  # whole counts near the reference
    on_counts = np.array([fk(geometry, c * q, x0=x)[0] for c, x in zip(counts, x_d)])
    late = np.array([fk(geometry, (c + 0.4) * q, x0=x)[0] for c, x in zip(counts, x_d)])
    x_true = np.where((np.arange(8) % 2 == 0)[:, None], on_counts, late)
    x_true[:3] += 0.05  # before the window: never counted
    result = SimpleNamespace(
        t=t, x=np.hstack([x_true, np.zeros((8, 6))]), x_d=np.hstack([x_d, np.zeros((8, 12))])
    )
    monkeypatch.setattr(simulate, "run_experiment", lambda scenario, reference: result)
    total, encoders, centre = module._errors(scenario, None, 0.03)
    kept = slice(3, None)
    np.testing.assert_allclose(
        total, np.sqrt(np.mean((x_true[kept] - x_d[kept]) ** 2, axis=0)), rtol=1e-12
    )
    np.testing.assert_allclose(
        encoders, np.sqrt(np.mean((on_counts[kept] - x_d[kept]) ** 2, axis=0)), rtol=1e-6,
        atol=1e-12,
    )  # fmt: skip
    assert not np.allclose(total, encoders)  # the late cranks' 0.4 count is what they hide
    np.testing.assert_allclose(centre, x_d[kept].mean(axis=0), rtol=1e-15)


def test_the_window_and_the_span_are_taken_at_their_edges(monkeypatch):
    """A window from 0 and a span of exactly MAX_SPAN_S are taken; a window that starts at the
    span's end is refused; a span past the bound names the seven runs it would take, and the
    five periods only when the span was the default."""
    from stewart_drake.analysis import error_budget as eb

    _stand_in(monkeypatch, lambda k, s: (np.full(6, 1e-4), np.full(6, 1e-4), X_HOME))
    scenario = load_scenario("paper_bus", [])
    assert error_budget(scenario, "breathing", duration_s=4.0, skip_s=0.0).window_s == (0.0, 4.0)
    long = error_budget(scenario, "breathing", duration_s=eb.MAX_SPAN_S, skip_s=1.0)
    assert long.window_s == (1.0, eb.MAX_SPAN_S)
    with pytest.raises(InvalidConfigError, match="skip_s"):
        error_budget(scenario, "breathing", duration_s=4.0, skip_s=4.0)
    with pytest.raises(InvalidConfigError) as refused:
        error_budget(scenario, "breathing", duration_s=eb.MAX_SPAN_S + 1)
    words = str(refused.value)
    assert f"would simulate {eb.MAX_SPAN_S + 1:g} s of the motion up to 7 times" in words
    assert "five of its periods" not in words
