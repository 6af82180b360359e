"""analysis/error_budget from closed-loop runs: the budget's shares against the runs they come
from, the encoders' pose carrying the floor, a payload the controller does not know, and
``analyze --budget`` at the command line. The floor, the table and the shares without a closed
loop are tests/test_error_budget_table.py's."""

import numpy as np
import pytest

from stewart_drake.analysis.error_budget import (
    SOURCES,
    error_budget,
)
from stewart_drake.references.organ.breathing import Breathing
from stewart_drake.run.scenario_io import load_scenario


@pytest.fixture(scope="module")
def short_budget():
    """A 2 s breath, 3 of them, the first not measured, on paper_bus with a payload it does not
    know (the model's row runs)."""
    scenario = load_scenario("paper_bus", ["payload_scale=1.2"])
    lines = []
    budget = error_budget(scenario, Breathing(period_s=2.0), say=lines.append)
    return budget, lines


def test_each_share_is_what_taking_the_source_away_removed(short_budget):
    budget, lines = short_budget
    assert budget.window_s == (2.0, 10.0)
    # every source the scenario has was run once, backlash (none on the XM430) was not
    ran = [line for line in lines if "without its" in line]
    assert [line.split("without its ")[1].split(" ...")[0] for line in ran] == [
        "encoders",
        "period and delay",
        "current loop",
        "friction",
        "model",
    ]
    np.testing.assert_array_equal(budget.rows["backlash"], 0.0)
    assert "backlash" not in budget.without
    for name, without in budget.without.items():
        want = np.sqrt(np.maximum(budget.total**2 - without**2, 0.0))
        np.testing.assert_allclose(budget.rows[name], want, rtol=1e-12)
    assert list(budget.rows) == list(SOURCES)


def test_the_encoder_pose_carries_the_floor(short_budget):
    budget, _ = short_budget
    # what the robot reads carries the counts the true pose does not, and is of the floor's size:
    # not at least the floor on every axis, because the loop closes on those same counts (an
    # axis that hardly moves in 8 s, Y here, samples few of a count's phases: 0.6 of the sum
    # below at the 5 ms period); and, on the axes breathing moves (X, Z), about the true error
    # and the floor as independent parts (within a third)
    assert np.all(budget.encoder_pose > budget.total)
    assert np.all(
        (budget.encoder_pose > 0.5 * budget.floor) & (budget.encoder_pose < 3 * budget.floor)
    )
    moving = [3, 5]
    np.testing.assert_allclose(
        budget.encoder_pose[moving], np.hypot(budget.total, budget.floor)[moving], rtol=0.35
    )


def test_a_payload_the_controller_does_not_know_has_a_share(short_budget):
    budget, _ = short_budget
    assert np.max(budget.rows["model"]) > 0.0


def test_analyze_gives_the_servos_budget_at_the_command_line(tmp_path, capsys):
    """A controller other than the LQI: analyze says the margins are the LQI's and gives the
    budget, as a table and as files."""
    import json

    from stewart_drake.cli import main as cli

    out = tmp_path / "an"
    code = cli.main(
        ["analyze", "--scenario", "paper_bus", "--param", "period=2s", "--out", str(out)]
    )
    printed = capsys.readouterr().out
    assert code == 0
    assert "the loop's margins are the LQI's" in printed
    assert "error budget of breathing at [0, 0, 0, 0, 0, 0.3]" in printed
    assert "| **encoder pose** (what the robot reads) |" in printed
    # the crank servo's robust margins (tests/test_servo_margins.py holds their figures)
    assert "stable for a plant gain (true / believed torque per command) of 0.12 to 2.87" in printed
    assert "with 6 ms more delay, 0.12 to 2.18" in printed
    assert "  holds what a shipped servo must: gain 0.5 to 2 with 6 ms more delay" in printed
    record = json.loads((out / "budget.json").read_text())
    assert record["motion"] == "breathing" and len(record["total"]) == 6
    assert record["crank_servo_margins"][0].startswith("the crank servo's loop (f_c 2.5 Hz")
