"""The error budget of servos as they are (stewart_drake/live/emulated_budget.py): whole sessions of
the phantom on the realistic bus emulator, one with every departure its seed draws and one
without each source, read against what the gears' play is known to do there."""

import numpy as np
import pytest
from conftest import require_extra

require_extra("robot")

from stewart_drake.references.organ.library import OrganMotionReference  # noqa: E402
from stewart_drake.run.plan import run_reference  # noqa: E402
from stewart_drake.run.scenario_io import load_scenario  # noqa: E402


@pytest.mark.slow
def test_the_phantoms_budget_finds_the_play_its_encoders_cannot_see(monkeypatch, tmp_path):
    """phantom_bus (its servos' own loop, realistic seed 0), 4 s of breathing, two sources. The
    PM42's encoder is on the motor, inside the gears' play: the platform sags by the play along
    Z where the encoders read the cranks where the motors put them (docs/robot.md: Z 63 um true
    against 1.7 um read). Without the play the true Z falls under half of what it is with it;
    the play's share of Z is over 40 um and dominates the translation; the encoder pose reads Z
    under 10 um, as the table says."""
    from stewart_drake.live import emulated_budget as eb

    sources = {name: eb.SOURCES[name] for name in ("backlash", "encoder noise")}
    monkeypatch.setattr(eb, "SOURCES", sources)
    scenario = load_scenario("phantom_bus")
    scenario.reference = OrganMotionReference(motion="breathing")
    scenario.duration_s = 4.0
    scenario.guard.divergence_dir = str(tmp_path / "diverged")
    scenario.validate()
    x0 = run_reference(scenario).evaluate(np.array([0.0]))[0][0]
    said = []
    budget = eb.emulated_budget(scenario, x0, say=said.append)
    assert [s.split(" (")[0] for s in said[1:]] == [
        "without its backlash",
        "without its encoder noise",
    ]
    z = 5
    assert 40e-6 < budget.total[z] < 120e-6, budget.total
    assert budget.without["backlash"][z] < 0.5 * budget.total[z]
    assert budget.rows["backlash"][z] > 40e-6
    assert budget.dominant()[0] == "backlash"
    assert budget.encoder_pose[z] < 10e-6, (budget.total, budget.without, budget.encoder_pose)
    assert budget.measured == "emulated" and "(emulated)" in budget.lines()[2]
    assert set(budget.rows) == {"backlash", "encoder noise"}
