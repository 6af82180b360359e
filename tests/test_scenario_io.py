"""Scenario files: shipped names load and round-trip, --set overrides are typed and named, a file
that does not fit the schema is refused naming the field."""

import pickle
from pathlib import Path

import numpy as np
import pytest
from conftest import HANG_S
from pydrake.common.yaml import yaml_dump_typed, yaml_load_typed

from stewart_drake.base.errors import InvalidConfigError, MissingFileError
from stewart_drake.run.scenario import (
    CsvReference,
    PdDriver,
    Robot,
    Scenario,
    dump_scenario,
)
from stewart_drake.run.scenario_io import apply_override, load_scenario, shipped_scenarios

SCENARIOS = Path(__file__).resolve().parent.parent / "scenarios"


@pytest.mark.parametrize(
    "path",
    sorted(p for p in SCENARIOS.glob("*.yaml") if not p.name.endswith("_requirements.yaml")),
    ids=lambda p: p.stem,
)
def test_every_shipped_scenario_round_trips_unchanged(path):
    text = path.read_text()
    body = "".join(line for line in text.splitlines(keepends=True) if not line.startswith("#"))
    scenario = load_scenario(path)
    assert dump_scenario(scenario) == body  # the file is a dump
    again = yaml_load_typed(schema=Scenario, data=yaml_dump_typed(scenario))
    assert dump_scenario(again) == body
    assert dump_scenario(pickle.loads(pickle.dumps(scenario))) == body  # workers get the same
    assert path.stem in shipped_scenarios()


def test_overrides_are_typed_and_named():
    s = load_scenario(
        "paper_ideal",
        ["controller.omega_Q=10", "duration_s=2", "guard.max_tracking_error=[0.1, 0.02]"],
    )
    assert s.controller.omega_Q == 10.0 and isinstance(s.controller.omega_Q, float)
    assert s.duration_s == 2.0 and s.guard.max_tracking_error == [0.1, 0.02]
    apply_override(s, "controller=!PdDriver {bandwidth_hz: 15}")
    assert isinstance(s.controller, PdDriver) and s.controller.bandwidth_hz == 15.0
    apply_override(s, "reference=!CsvReference {path: run.csv}")
    assert s.reference == CsvReference("run.csv")
    with pytest.raises(InvalidConfigError, match=r"'omegaQ' is not a field of LqiDriver"):
        apply_override(Scenario(), "controller.omegaQ=10")
    with pytest.raises(InvalidConfigError, match=r"--set duration_s=ten"):
        apply_override(Scenario(), "duration_s=ten")
    with pytest.raises(InvalidConfigError, match="key=value"):
        apply_override(Scenario(), "duration_s")
    with pytest.raises(InvalidConfigError, match=r"controller.omega_Q must be a finite number"):
        load_scenario("paper_ideal", ["controller.omega_Q=-1"])


def test_a_yaml_file_that_does_not_fit_the_schema_names_the_field(tmp_path):
    bad = tmp_path / "bad.yaml"
    bad.write_text("duration_s: 3\ncontroller: {omega_Q: 2, gain: 5}\n")
    with pytest.raises(
        InvalidConfigError,
        match=r"bad.yaml is not a valid scenario file: it does "
        r"not fit .*\['gain'\]",
    ):
        load_scenario(bad)
    with pytest.raises(MissingFileError, match="shipped: .*paper_ideal"):
        load_scenario("paper_nowhere")
    good = tmp_path / "good.yaml"
    good.write_text("duration_s: 3\ncontroller: !PdDriver {bandwidth_hz: 12}\n")
    s = load_scenario(good)
    assert s.duration_s == 3.0 and s.controller == PdDriver(bandwidth_hz=12.0)
    assert s.robot == Robot()  # unspecified fields keep their defaults


def test_the_run_options_apply_in_place_and_validate(tmp_path):
    from stewart_drake.control.tuning import AnnTunerDriver, RatioTunerDriver
    from stewart_drake.run.scenario_io import apply_run_options

    csv = tmp_path / "ref.csv"
    t = np.linspace(0.0, 2.5, 26)
    rows = np.column_stack([t, np.zeros((26, 5)), np.full(26, 0.30)])
    np.savetxt(csv, rows, delimiter=",", header="t,phi,theta,psi,X,Y,Z", comments="")
    scenario = apply_run_options(
        load_scenario("paper_hardware"),
        trajectory_file=str(csv),
        controller="lqi",
        omega_Q=10.0,
        tuner="ratio",
        divergence_dir=tmp_path / "diverged",
    )
    assert scenario.duration_s == 2.5  # the file's own length
    assert isinstance(scenario.reference, CsvReference) and scenario.reference.path == str(csv)
    assert scenario.controller.omega() == (10.0, 1.0)
    assert scenario.controller.schedule_period_s == 0.02  # the scenario's LQI options
    assert isinstance(scenario.tuner, RatioTunerDriver)
    assert scenario.guard.divergence_dir == str(tmp_path / "diverged")
    weights = tmp_path / "mine.npz"
    weights.write_bytes(b"")  # exists: taken as what `train` last wrote
    ann = apply_run_options(
        load_scenario("paper_ideal"), duration_s=1.0, tuner="ann", default_ann_weights=weights
    )
    assert ann.tuner == AnnTunerDriver(weights=str(weights)) and ann.duration_s == 1.0
    assert ann.controller.gain_transfer == "none"  # the paper's gain switching
    pd = apply_run_options(load_scenario("paper_ideal"), controller="pd", tuner="none")
    assert isinstance(pd.controller, PdDriver) and pd.tuner is None


@pytest.mark.parametrize(
    "options, message",
    [
        ({"tuner_weights": "w.npz"}, "--tuner-weights needs --tuner ann or --tuner ratio"),
        ({"trajectory": "paper", "trajectory_file": "r.csv"}, "--trajectory or --trajectory-file"),
        ({"duration_s": -1.0}, "duration_s must be"),
    ],
)
def test_bad_run_options_are_refused_by_name(options, message):
    from stewart_drake.run.scenario_io import apply_run_options

    with pytest.raises(InvalidConfigError, match=message):
        apply_run_options(load_scenario("paper_ideal"), **options)


def _merge_bomb(levels: int = 27) -> str:
    """A few hundred bytes of YAML merge keys that expand to 10 x 2^levels keys."""
    lines = ["m0: &m0 {" + ", ".join(f"k{i}: 1" for i in range(10)) + "}"]
    lines += [f"m{i}: &m{i} {{<<: [*m{i - 1}, *m{i - 1}]}}" for i in range(1, levels + 1)]
    return "\n".join(lines) + "\n"


def test_a_merge_key_bomb_is_refused_before_it_expands(tmp_path):
    from conftest import run_within

    path = tmp_path / "bomb.yaml"
    path.write_text(_merge_bomb())
    assert path.stat().st_size < 1000
    # Counted on the composed graph, once per node: far below a second, where expanding never
    # would end; the guard against a hang fails the test if it does.
    with pytest.raises(InvalidConfigError, match=r"bomb.yaml: its anchors and merge keys expand"):
        run_within(HANG_S, load_scenario, path)
    with pytest.raises(InvalidConfigError, match=r"--set controller: its anchors and merge keys"):
        run_within(
            HANG_S,
            load_scenario,
            "paper_ideal",
            ["controller=" + "{" + _merge_bomb().replace("\n", ", ") + "}"],
        )


def test_an_override_longer_than_a_scenario_file_is_refused():
    with pytest.raises(InvalidConfigError, match="over the bound of a scenario file"):
        load_scenario("paper_ideal", ["duration_s=" + "1" * 300_000])


def test_the_expanded_size_counts_every_use_of_an_anchor(tmp_path):
    import yaml

    from stewart_drake.run.scenario_io import _expanded_nodes

    # m0: 1 + 10 x (key, value) = 21; each mI: 1 + "<<" + a list of two uses of mI-1; the root:
    # 1 + three keys + m0 + m1 + m2 = 1 + 3 + 21 + 45 + 93.
    assert _expanded_nodes(yaml.compose(_merge_bomb(2))) == 163
    path = tmp_path / "anchors.yaml"
    path.write_text("guard: &g {check_period_s: 0.02}\n")
    assert load_scenario(path).guard.check_period_s == 0.02


def test_a_section_may_carry_its_own_class_s_tag(tmp_path):
    path = tmp_path / "tagged.yaml"
    path.write_text(
        "learning: !IlcDriver {gain: 0.5}\n"
        "hardware: !Hardware\n  computation_delay_periods: 2\n  motors: !Motors {gear_ratio: 5.0}\n"
    )
    scenario = load_scenario(path)
    assert scenario.learning.gain == 0.5 and scenario.learning.q_cutoff_hz == 25.0
    assert scenario.hardware.computation_delay_periods == 2
    assert scenario.hardware.motors.gear_ratio == 5.0
    path.write_text("hardware: !PdDriver {}\n")
    with pytest.raises(InvalidConfigError, match=r"a tag \(!Name\) that is not its section's own"):
        load_scenario(path)
    # learning is a choice of two learners: a tag among them, another refused naming them
    path.write_text("learning: !FeedforwardTuning {stretch_s: 3.0}\n")
    assert load_scenario(path).learning.stretch_s == 3.0
    path.write_text("learning: !PdDriver {}\n")
    with pytest.raises(InvalidConfigError, match="FeedforwardTuning"):
        load_scenario(path)


def test_a_scenario_that_is_not_a_path_or_a_name_is_refused():
    with pytest.raises(MissingFileError, match="a scenario is a .yaml path or a shipped name"):
        load_scenario(None)
