"""A robot's design: the reference robot is one design exactly, random designs within the bounds
build a plant in Drake (SDF, collision geometry) and in MuJoCo (MJCF) closed at home, a design
that cannot close is refused naming the variable, and the motor catalogue agrees with its
datasheet page."""

import math
import re
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
from conftest import extra_missing

from stewart_drake.base.errors import InvalidConfigError, InvalidGeometryError
from stewart_drake.design.variables import (
    DESIGN_BOUNDS,
    Design,
    random_design,
    reference_design,
)
from stewart_drake.plant.clearance import ClearanceModel
from stewart_drake.plant.closed_chain import loop_closure_errors
from stewart_drake.plant.plant import make_plant, platform_pose
from stewart_drake.robot.geometry import reference_geometry
from stewart_drake.robot.kinematics import X_HOME, ik, leg_reach_ratio
from stewart_drake.robot.motor_catalogue import (
    MOTOR_CATALOGUE,
    REFERENCE_MOTOR,
    catalogue_motor,
)
from stewart_drake.robot.servo import ServoModel
from stewart_drake.run.scenario import dump_scenario
from stewart_drake.run.scenario_io import load_scenario

DOC = Path(__file__).resolve().parent.parent / "docs" / "motor_catalogue.md"


def _closing_designs(n: int, seed: int) -> list[Design]:
    """``n`` designs drawn within the bounds, each rod length then drawn where every leg closes
    and the geometry's own checks (joint limits at home) pass."""
    rng = np.random.default_rng(seed)
    designs = []
    while len(designs) < n:
        d = random_design(rng, motor=str(rng.choice(list(MOTOR_CATALOGUE))))
        lo, hi = d.rod_length_range()
        lo, hi = max(lo, DESIGN_BOUNDS["rod_length"][0]), min(hi, DESIGN_BOUNDS["rod_length"][1])
        if lo >= hi:
            continue
        d.rod_length = float(rng.uniform(lo, hi))
        try:
            d.geometry()
        except InvalidGeometryError:
            continue  # a joint limit at home; refused by the geometry (named there)
        designs.append(d)
    return designs


def test_the_reference_robot_is_a_design_exactly():
    design = reference_design()
    assert design.geometry() == reference_geometry()
    assert design.servo() == ServoModel()
    assert design.motor == REFERENCE_MOTOR


@pytest.mark.parametrize("design", _closing_designs(3, seed=7), ids=lambda d: d.motor)
def test_designs_within_the_bounds_build_a_drake_plant_closed_at_home(design):
    geometry = design.geometry()
    # The SDF (with collision geometry) parsed by Drake, assembled at home: loops closed and the
    # platform where the design puts it, read back from Drake's plant.
    plant, context, handles, _, _ = make_plant(geometry, contact=True)
    assert loop_closure_errors(plant, context, handles).max() < 1e-9
    np.testing.assert_allclose(platform_pose(plant, context, handles)[0], X_HOME, atol=1e-9)
    # The cranks' pivots are home_height under the home pose.
    assert X_HOME[5] - geometry.pivot_z == pytest.approx(design.home_height)
    # The collision geometry: Drake's SceneGraph finds a closest pair of parts at home.
    contact = ClearanceModel(geometry).closest(X_HOME)
    assert np.isfinite(contact.distance)


def test_designs_within_the_bounds_build_a_mujoco_model_closed_at_home():
    if extra_missing("mujoco"):
        pytest.skip(extra_missing("mujoco"))
    import mujoco

    from stewart_drake.plant import mjcf

    for design in _closing_designs(2, seed=11):
        geometry = design.geometry()
        model = mjcf.load_model(geometry, servo=design.servo())
        data = mujoco.MjData(model)
        theta = mjcf.assemble(model, data, geometry, X_HOME)
        assert mjcf.loop_closure_errors(model, data).max() < 1e-9
        np.testing.assert_allclose(mjcf.platform_pose(model, data), X_HOME, atol=1e-9)
        np.testing.assert_allclose(theta, ik(geometry, X_HOME), atol=1e-12)


def test_the_closing_rod_lengths_agree_with_the_geometrys_reach_check():
    # Two computations: the design's distances from each platform joint to its crank tip's
    # circle, and paper eq. 6's |L| / sqrt(M^2 + N^2) (the geometry's own reach check), just
    # inside and just outside each end of the range.
    for design in _closing_designs(3, seed=5):
        lo, hi = design.rod_length_range()
        g = design.geometry()
        for s, closes in (
            (lo * (1 + 1e-6), True),
            (lo * (1 - 1e-6), False),
            (hi * (1 - 1e-6), True),
            (hi * (1 + 1e-6), False),
        ):
            legs = SimpleNamespace(
                P_B=g.P_B,
                p_E=g.p_E,
                d_B=g.d_B,
                w_B=g.w_B,
                crank_lengths=g.crank_lengths,
                rod_lengths=np.full(6, s),
            )
            assert bool(np.all(np.abs(leg_reach_ratio(legs, X_HOME)) <= 1)) == closes, (s, lo)


def test_a_design_applied_to_a_scenario_round_trips_through_its_file(tmp_path):
    design = _closing_designs(1, seed=3)[0]
    design.motor = "XM430-W350-T"
    scenario = design.apply_to(load_scenario("paper_hardware"))
    dump_scenario(scenario, tmp_path / "design.yaml")
    back = load_scenario(tmp_path / "design.yaml")
    assert back.robot.build() == design.geometry()
    assert back.hardware.motors.build() == catalogue_motor("XM430-W350-T").servo
    assert back.hardware.encoders.counts_per_rev == 4096
    # The reference design leaves the robot as built unchanged.
    reference = load_scenario("paper_hardware")
    assert dump_scenario(reference_design().apply_to(load_scenario("paper_hardware"))) == (
        dump_scenario(reference)
    )


def test_a_design_that_cannot_close_at_home_is_refused_naming_the_rod_length():
    design = reference_design()
    lo, hi = design.rod_length_range()
    assert lo < 0.404 < hi
    design.rod_length = 0.16  # a short rod cannot span the 0.37 m home height
    with pytest.raises(InvalidGeometryError, match=r"design\.rod_length = 0\.16 m cannot close"):
        design.geometry()
    with pytest.raises(InvalidGeometryError, match=rf"\[{lo:.4g}, {hi:.4g}\] m"):
        design.geometry()


def test_values_outside_the_bounds_and_unknown_motors_are_refused_by_name():
    with pytest.raises(
        InvalidConfigError, match=r"design\.crank_length = 0\.5 m .*\[0\.03, 0\.15\]"
    ):
        Design(crank_length=0.5).geometry()
    with pytest.raises(InvalidConfigError, match=r"design\.home_height must be a number"):
        Design(home_height="high").geometry()
    with pytest.raises(InvalidConfigError, match=r"design\.motor 'MX-28' is not in the catalogue"):
        Design(motor="MX-28").servo()


def test_the_maxon_entry_is_the_servo_models_defaults_and_peak_torques_are_as_documented():
    maxon = catalogue_motor(REFERENCE_MOTOR)
    assert maxon.servo == ServoModel()
    assert maxon.servo.peak_torque_Nm == pytest.approx(2 * 2.52 * 36.0e-3 * 4.3 * 0.90)
    assert maxon.continuous_torque_Nm == pytest.approx(maxon.servo.peak_torque_Nm / 2)
    xm540 = catalogue_motor("XM540-W270-T")
    assert xm540.servo.peak_torque_Nm == 10.6  # the stall torque at 12 V
    assert xm540.continuous_torque_Nm == pytest.approx(10.6 / 5)
    assert xm540.servo.no_load_speed_rad_s == pytest.approx(30 * 2 * math.pi / 60)
    assert xm540.servo.reflected_inertia == pytest.approx(5e-7 * 272.5**2)


def _doc_rows() -> dict:
    """{name: cells} of the catalogue table of docs/motor_catalogue.md."""
    rows = {}
    for line in DOC.read_text().splitlines():
        m = re.match(r"\| `([^`]+)` \|(.*)\|$", line)
        if m:
            rows[m.group(1)] = [c.strip() for c in m.group(2).split("|")]
    return rows


def _first_number(cell: str) -> float:
    return float(re.match(r"[\d.e+-]+", cell).group(0))


def test_every_catalogue_motor_has_its_row_and_sources_in_the_doc_and_the_figures_agree():
    rows, text = _doc_rows(), DOC.read_text()
    assert set(rows) == set(MOTOR_CATALOGUE)
    for name, motor in MOTOR_CATALOGUE.items():
        peak, cont, speed, ratio, inertia, counts, mass, price = rows[name]
        s = motor.servo
        assert _first_number(peak) == pytest.approx(s.peak_torque_Nm, rel=1e-3)
        assert _first_number(cont) == pytest.approx(motor.continuous_torque_Nm, rel=1e-3)
        rad_s = float(speed.split("/")[1])
        assert rad_s == pytest.approx(s.no_load_speed_rad_s, rel=5e-3)
        assert _first_number(ratio) == s.gear_ratio
        reflected = float(inertia.split(";")[1])
        assert reflected == pytest.approx(s.reflected_inertia, rel=5e-3)
        assert int(counts) == motor.encoder_counts_per_rev
        assert _first_number(mass) == pytest.approx(motor.mass_kg * 1e3)
        assert _first_number(price) == motor.price_usd
        # A source for every motor: its name again below the table, beside a URL.
        sources = text.split("## Sources", 1)[1]
        if name != REFERENCE_MOTOR:
            assert re.search(rf"`{re.escape(name)}`: <https://[^>]+>", sources), name
    assert "<https://online.flippingbook.com/" in text  # the maxon catalogue page
