"""The scenario as a schema: its YAML form, the value types it mirrors, and every bad setting
refused by the name of its field before anything is built."""

from pathlib import Path

import pytest
from pydrake.common.yaml import yaml_load_typed

from stewart_drake.base.errors import (
    InvalidConfigError,
    InvalidGeometryError,
    MissingFileError,
)
from stewart_drake.control.tuning import AnnTunerDriver
from stewart_drake.robot.geometry import StewartGeometry
from stewart_drake.run.plan import make_plan
from stewart_drake.run.scenario import NamedReference, Robot, Scenario, dump_scenario
from stewart_drake.run.scenario_io import load_scenario
from stewart_drake.station.guard import GuardConfig
from stewart_drake.station.station import SensorNoise

SCENARIOS = Path(__file__).resolve().parent.parent / "scenarios"


def test_a_dump_names_only_the_drake_settings_it_changes():
    """Drake adds and removes fields of its config structs between releases (1.58 dropped
    SimulatorConfig.publish_every_time_step): a dump names only the ones that differ from the
    running Drake's defaults and the two the robot needs, so it loads on every supported Drake."""
    from pydrake.common.yaml import yaml_load

    scenario = Scenario()
    scenario.simulator.target_realtime_rate = 1.0
    scenario.plant.penetration_allowance = 2e-3
    text = dump_scenario(scenario)
    data = yaml_load(data=text)
    assert data["plant"] == {
        "time_step": 1e-3,
        "use_sampled_output_ports": False,
        "discrete_contact_approximation": "sap",
        "penetration_allowance": 2e-3,
    }
    assert data["simulator"] == {"target_realtime_rate": 1.0} and "visualization" not in data
    back = load_scenario_text(text)
    assert back.simulator.target_realtime_rate == 1.0 and back.plant.penetration_allowance == 2e-3
    assert back.visualization.publish_period == scenario.visualization.publish_period
    for path in sorted(SCENARIOS.glob("*.yaml")):
        if path.name.endswith("_requirements.yaml"):  # a design task, not a scenario
            continue
        data = yaml_load(data=path.read_text())
        assert set(data["plant"]) == {
            "time_step",
            "discrete_contact_approximation",
            "use_sampled_output_ports",
        }, path
        assert "simulator" not in data and "visualization" not in data, path


def test_paper_ideal_is_the_default_scenario():
    assert dump_scenario(load_scenario("paper_ideal")) == dump_scenario(Scenario())


def test_robot_mirrors_the_geometry_both_ways():
    g = StewartGeometry(rod_length=0.41, pivot_angles_deg=(-12, 12, 108, 132, 228, 252))
    robot = Robot.from_value(g)
    assert robot.rod_length == 0.41 and isinstance(robot.pivot_angles_deg, list)
    assert robot.build() == g
    assert make_plan(Scenario(robot=robot)).geometry == g


@pytest.mark.parametrize(
    "form, value, left_out",
    [
        ("Robot", "StewartGeometry", ("motor_reflected_inertia",)),
        ("Motors", "ServoModel", ()),
        ("LqiScalesConfig", "LqiScales", ()),
    ],
)
def test_the_yaml_forms_mirror_their_value_types_field_for_field(form, value, left_out):
    """Robot, Motors and LqiScalesConfig are written out in source: the same fields in the same
    order, a list of floats where the value type has a tuple, the same defaults."""
    import dataclasses
    import typing

    from stewart_drake.control.lqi.driver import LqiScales, LqiScalesConfig
    from stewart_drake.robot.servo import ServoModel
    from stewart_drake.run import scenario as sc
    from stewart_drake.station.hardware import Motors

    kinds = {
        "Robot": sc.Robot,
        "Motors": Motors,
        "LqiScalesConfig": LqiScalesConfig,
        "StewartGeometry": StewartGeometry,
        "ServoModel": ServoModel,
        "LqiScales": LqiScales,
    }
    form, value = kinds[form], kinds[value]
    mine, theirs = typing.get_type_hints(form), typing.get_type_hints(value)
    names = [f.name for f in dataclasses.fields(value) if f.name not in left_out]
    assert [f.name for f in dataclasses.fields(form)] == names
    default_form, default_value = form(), value()
    for name in names:
        tuple_field = theirs[name] is tuple or typing.get_origin(theirs[name]) is tuple
        assert mine[name] == _form_type(theirs[name]), name
        expected = getattr(default_value, name)
        assert getattr(default_form, name) == (list(expected) if tuple_field else expected), name
    built = default_form.build()
    assert isinstance(built, value) and form.from_value(built) == default_form


def _form_type(hint):
    """The YAML form's type of a value type's field type: a list where it has a tuple (of
    floats, or of tuples: a list of lists), an optional one optional."""
    import functools
    import operator
    import types
    import typing

    origin = typing.get_origin(hint)
    if hint is tuple or origin is tuple:
        items = [arg for arg in typing.get_args(hint) if arg is not Ellipsis]
        nested = bool(items) and (items[0] is tuple or typing.get_origin(items[0]) is tuple)
        return list[_form_type(items[0])] if nested else list[float]
    if origin in (types.UnionType, typing.Union):
        return functools.reduce(operator.or_, [_form_type(arg) for arg in typing.get_args(hint)])
    return hint


NAN = float("nan")


@pytest.mark.parametrize(
    "path, value, message",
    [
        (
            "control_period_s",
            1.5e-3,
            r"control_period_s \(0.0015 s\) must be a whole multiple of "
            r"plant.time_step \(0.001 s\); the nearest valid value is "
            r"0.002 s",
        ),
        (
            "controller.schedule_period_s",
            0.0125,
            r"controller.schedule_period_s \(0.0125 s\) must be "
            r"a whole multiple of control_period_s",
        ),
        (
            "log_period_s",
            2.5e-3,
            r"log_period_s \(0.0025 s\) must be a whole multiple of "
            r"plant.time_step",
        ),
        (
            "tuner",
            AnnTunerDriver(period_s=0.0205),
            r"tuner.period_s .* whole multiple of "
            r"control_period_s",
        ),
        ("guard.check_period_s", 0.0105, r"guard.check_period_s .* whole multiple"),
        ("duration_s", -1.0, r"duration_s must be a finite number in \(0, inf\], got -1.0"),
        ("duration_s", "10", r"duration_s must be a number, got '10' \(a string\)"),
        ("duration_s", 1e-6, r"duration_s \(1e-06 s\) must cover at least two log periods"),
        ("plant.time_step", NAN, r"plant.time_step must be a finite number"),
        ("plant.discrete_contact_approximation", "tamsi", r"does not enforce the ball constraints"),
        (
            "controller.omega_Q",
            NAN,
            r"controller.omega_Q must be a finite number in \[0.001, 1000\]",
        ),
        (
            "controller.omega_R",
            1e4,
            r"controller.omega_R must be a finite number in \[0.001, 1000\], "
            r"got 10000.0",
        ),
        ("controller.omega_R", True, r"controller.omega_R must be one number"),
        (
            "controller.riccati",
            "hot",
            r"controller.riccati must be one of \('warm', 'track', 'cold'\)",
        ),
        ("controller.scales", "x", r"controller.scales must be an LqiScalesConfig, got str"),
        (
            "feedforward",
            "pid",
            r"feedforward must be one of \('gravity', 'inverse_dynamics', 'none'\)",
        ),
        (
            "tuner",
            AnnTunerDriver(feature_window=0),
            r"tuner.feature_window must be an integer in "
            r"\[1, 100000\]",
        ),
        (
            "reference",
            NamedReference("spiral"),
            r"unknown trajectory 'spiral'; choose one of "
            r"\[.*'helix'.*'paper'",
        ),
        ("reference", 3.0, r"reference must be a NamedReference, CsvReference"),
        ("guard", {"max_closure_error_m": 1}, r"guard must be a GuardConfig, got dict \(a dict"),
        ("robot", {"rod_length": 0.4}, r"robot must be a Robot, got dict"),
        (
            "sensor_noise",
            SensorNoise(seed=2**32),
            r"sensor_noise.seed must be an integer in "
            r"\[0, 4294967295\], got 4294967296",
        ),
        ("sensor_noise", SensorNoise(std=[0.1] * 7), r"sensor_noise.std needs 12 finite values"),
        ("payload_scale", 0.0, r"payload_scale must be a finite number in \[0.1, 10\]"),
        (
            "controller",
            "lqi",
            r"controller must be an LqiDriver, CrankServoDriver, ServoPositionDriver, PdDriver or "
            r"UserController",
        ),
        ("rod_model", "springs", r"rod_model must be one of \('bodies', 'distance'\)"),
    ],
)
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


@pytest.mark.parametrize(
    "fields, message",
    [
        (
            {"max_closure_error_m": 0.0},
            r"max_closure_error_m must be a finite number in \(0, inf\]",
        ),
        ({"max_tracking_error": (0.2,)}, r"max_tracking_error must be \[rad, m\]"),
        ({"max_tracking_error": (0.2, float("inf"))}, r"max_tracking_error\[1\] must be a finite"),
        ({"cond_threshold": 0.5}, r"cond_threshold must be a finite number in \(1, inf\]"),
        ({"divergence_dir": ""}, r"divergence_dir must be a folder path"),
    ],
)
def test_bad_guard_settings_are_refused(fields, message):
    with pytest.raises(InvalidConfigError, match=message):
        GuardConfig(**fields)


def test_missing_tuner_weights_are_refused_before_building(tmp_path):
    with pytest.raises(MissingFileError, match="no ANN tuner weights at .*w.npz") as info:
        Scenario(tuner=AnnTunerDriver(weights=str(tmp_path / "w.npz")))
    assert isinstance(info.value, FileNotFoundError)


@pytest.mark.parametrize(
    "fields, message",
    [
        ({"rod_length": 0.9}, r"leg \d cannot close at the home pose .* change the rod or crank"),
        ({"rod_length": 0.25}, r"leg \d cannot close at the home pose"),
        ({"crank_length": -0.11}, r"crank_length must be a finite number in \(0, 100\], got -0.11"),
        ({"base_radius": 0.0}, r"base_radius must be a finite number in \(0, 100\]"),
        ({"rod_length": float("inf")}, r"rod_length must be a finite number"),
        ({"pivot_z": float("nan")}, r"pivot_z must be a finite number"),
        ({"platform_mass": 0.0}, r"platform_mass must be a finite number in \(0, 100000\]"),
        ({"rod_mass": "heavy"}, r"rod_mass must be a number, got .heavy. \(a string\)"),
        (
            {"platform_inertia": (0.001, 0.001, 0.006)},
            r"platform_inertia = \[0.001, 0.001, 0.006\] "
            r"kg m\^2 fails the triangle inequality",
        ),
        ({"rod_inertia": (0.0016, 0.0016, 0.0)}, r"rod_inertia needs 3 positive moments"),
        ({"crank_inertia": (1e-6, float("nan"), 6e-5)}, r"crank_inertia has a non-finite value"),
        ({"pivot_angles_deg": (0.0,) * 5}, r"pivot_angles_deg must have shape \(6,\)"),
        ({"motor_angle_min_deg": 10.0}, r"the home pose violates the motor_angle limit"),
    ],
)
def test_bad_geometry_is_refused_by_name(fields, message):
    with pytest.raises(InvalidGeometryError, match=message):
        StewartGeometry(**fields)


def load_scenario_text(text):
    return yaml_load_typed(schema=Scenario, data=text, allow_schema_with_no_yaml=True)


def test_an_absurd_disturbance_or_q_filter_is_refused_before_simulating():
    from stewart_drake.control.ilc import IlcDriver
    from stewart_drake.station.station import ToolDisturbance

    with pytest.raises(InvalidConfigError, match=r"disturbance.magnitude must be .* \[0, 10000\]"):
        Scenario(disturbance=ToolDisturbance("push", 1e300, [1.0, 0.0, 0.0]))
    with pytest.raises(InvalidConfigError, match=r"learning.q_cutoff_hz must be .* \[0.1,"):
        Scenario(learning=IlcDriver(q_cutoff_hz=1e-300))
    Scenario(disturbance=ToolDisturbance("push", 1e4, [1.0, 0.0, 0.0]))  # the bound itself


def test_rods_as_distance_constraints_are_read_from_yaml_and_refuse_contact():
    """The rods have no collision geometry as constraints: contact would miss them."""
    scenario = load_scenario("paper_ideal", ["rod_model=distance"])
    assert scenario.rod_model == "distance"
    with pytest.raises(InvalidConfigError, match="contact needs the rods' collision geometry"):
        load_scenario("paper_ideal", ["rod_model=distance", "contact=true"])
