"""Closed-loop confirmation of a design: the reference design's scenario is the hardware scenario
exactly, the payload is platform mass in the plant Drake builds, the LQI's torque scale follows
the motor's peak, a run of the reference design is a run of the base scenario, a Dynamixel
design's effort is measured against its own motor, and what the robot cannot do is a row."""

import dataclasses
import re

import numpy as np
import pytest

from stewart_drake.base.errors import InvalidConfigError, InvalidGeometryError
from stewart_drake.control.pd import PdDriver
from stewart_drake.control.tuning import AnnTunerDriver, WeightSchedule
from stewart_drake.design.design_confirm import (
    MAX_PERIODIC_S,
    TABLE_HEADER,
    confirm,
    confirmation_table,
    design_scenario,
    torque_scale_Nm,
)
from stewart_drake.design.requirements import DesignRequirements, load_requirements
from stewart_drake.design.variables import Design, reference_design
from stewart_drake.organ_motion.fidelity import fidelity
from stewart_drake.references.organ.library import OrganMotionReference
from stewart_drake.references.samples import CsvReference
from stewart_drake.references.trajectories import NamedReference
from stewart_drake.robot.motor_catalogue import REFERENCE_MOTOR, catalogue_motor
from stewart_drake.run.diagram import make_stewart_diagram
from stewart_drake.run.scenario import use_paper_tuner
from stewart_drake.run.scenario_io import load_scenario
from stewart_drake.run.simulate import run_experiment

REQUIREMENTS = "scenarios/design_requirements.yaml"


def _no_payload() -> DesignRequirements:
    return dataclasses.replace(load_requirements(REQUIREMENTS), payload_kg=0.0)


def test_the_reference_design_builds_the_hardware_scenario_exactly():
    base = load_scenario("paper_hardware")
    s = design_scenario(reference_design(), _no_payload(), NamedReference("paper"))
    assert s.robot == base.robot
    assert s.hardware == base.hardware  # motors, encoders, estimator, delay
    assert s.controller == base.controller  # the torque scale: 0.3 N m exactly
    assert s.tuner is None and s.reference == NamedReference("paper")
    assert s.duration_s == base.duration_s == 10.0  # the paper's experiment
    # breathing 4 s + a 72 bpm heartbeat repeats after 5 breaths, 24 beats
    breathing = load_requirements(REQUIREMENTS).motions[1]
    assert design_scenario(reference_design(), _no_payload(), breathing).duration_s == 20.0
    assert MAX_PERIODIC_S == 20.0


def test_a_motion_with_an_end_runs_to_its_end(tmp_path):
    t = np.linspace(0.0, 3.0, 31)
    rows = np.column_stack([t, np.zeros((31, 5)), 0.30 + 1e-3 * np.sin(t)])
    csv = tmp_path / "path.csv"
    np.savetxt(csv, rows, delimiter=",", header="t,phi,theta,psi,X,Y,Z", comments="")
    s = design_scenario(reference_design(), _no_payload(), CsvReference(str(csv)))
    assert s.duration_s == pytest.approx(3.0)
    for asked, runs in ((1.0, 1.0), (9.0, 3.0)):  # never past the motion's end
        s = design_scenario(
            reference_design(), _no_payload(), CsvReference(str(csv)), duration_s=asked
        )
        assert s.duration_s == pytest.approx(runs)


def test_the_payload_is_platform_mass_in_the_plant_drake_builds():
    req = load_requirements(REQUIREMENTS)
    assert req.payload_kg == 0.5
    base = make_stewart_diagram(load_scenario("paper_hardware")).plant.GetBodyByName("platform")
    s = design_scenario(Design(motor="XM540-W270-T"), req, req.motions[0])
    sd = make_stewart_diagram(s)
    body = sd.plant.GetBodyByName("platform")
    assert body.default_mass() == pytest.approx(1.5, abs=1e-12)  # 1.0 kg + the 0.5 kg payload
    # a point mass at the platform's centre of mass: the COM stays at the frame's origin and the
    # rotational inertia about it does not change
    np.testing.assert_allclose(body.default_com(), [0.0, 0.0, 0.0], atol=1e-15)
    np.testing.assert_allclose(
        body.default_rotational_inertia().CopyToFullMatrix3(),
        base.default_rotational_inertia().CopyToFullMatrix3(),
        atol=1e-15,
    )
    assert sd.controller.geometry.platform_mass == pytest.approx(1.5)  # the controller knows it
    assert s.payload_scale == 1.0


def test_the_lqi_torque_scale_is_the_same_share_of_each_motors_peak():
    base = load_scenario("paper_hardware")
    peak_ref = catalogue_motor(REFERENCE_MOTOR).servo.peak_torque_Nm
    assert peak_ref == pytest.approx(0.7022, abs=1e-4)
    assert torque_scale_Nm(peak_ref, base) == 0.3
    s = design_scenario(Design(motor="XM540-W270-T"), _no_payload(), NamedReference("paper"))
    assert s.hardware.motors.peak_torque_Nm == 10.6
    assert s.hardware.encoders.counts_per_rev == 4096
    assert s.controller.scales.torque == pytest.approx(0.3 * 10.6 / 0.7021728, rel=1e-12)
    assert s.controller.scales.torque == pytest.approx(4.5288, abs=1e-4)
    assert s.controller.scales.pose == base.controller.scales.pose  # the rest the base's
    assert s.controller.scales.rate == base.controller.scales.rate
    assert s.controller.omega_Q == base.controller.omega_Q
    # the controller Drake runs is built with that scale: R = I / torque^2
    sd = make_stewart_diagram(s)
    np.testing.assert_allclose(sd.controller.lqi._R1, np.eye(6) / 4.5288**2, rtol=1e-4)


def test_a_network_tuner_is_kept_only_on_the_robot_it_was_trained_on():
    base = use_paper_tuner(load_scenario("paper_hardware"), AnnTunerDriver())
    ref = design_scenario(reference_design(), _no_payload(), NamedReference(), base)
    assert isinstance(ref.tuner, AnnTunerDriver)
    other = design_scenario(Design(motor="XL430-W250-T"), _no_payload(), NamedReference(), base)
    assert other.tuner is None
    assert other.controller.omega_Q == base.controller.omega_Q  # the fixed weights
    scheduled = load_scenario("paper_hardware")
    scheduled.tuner = WeightSchedule()
    s = design_scenario(Design(motor="XL430-W250-T"), _no_payload(), NamedReference(), scheduled)
    assert isinstance(s.tuner, WeightSchedule)


def test_bad_input_is_refused_before_anything_runs():
    req = _no_payload()
    paper = NamedReference()
    with pytest.raises(InvalidConfigError, match="needs hardware"):
        design_scenario(reference_design(), req, paper, "paper_ideal")
    pd = load_scenario("paper_hardware")
    pd.controller = PdDriver()
    with pytest.raises(InvalidConfigError, match="LqiDriver"):
        design_scenario(reference_design(), req, paper, pd)
    with pytest.raises(InvalidConfigError, match="duration_s"):
        design_scenario(reference_design(), req, paper, duration_s=-1.0)
    with pytest.raises(InvalidConfigError, match="reference choice"):
        design_scenario(reference_design(), req, "paper")
    with pytest.raises(InvalidConfigError, match="design.motor"):
        design_scenario(Design(motor="nema17"), req, paper)
    with pytest.raises(InvalidGeometryError, match="rod_length"):
        confirm(Design(rod_length=0.2), req)  # cannot close at home: before any run


def test_the_reference_design_runs_as_the_base_scenario_does():
    """The same system, two ways: the confirmation's figures equal those of the base scenario
    run directly (deterministic: no encoder noise)."""
    rows = confirm(reference_design(), _no_payload(), duration_s=1.5)
    assert [r["label"] for r in rows] == ["paper", "breathing_heartbeat"]
    row = rows[0]
    assert row["completed"] and row["reason"] is None and row["duration_s"] == 1.5
    base = load_scenario("paper_hardware")
    base.duration_s = 1.5
    direct = run_experiment(base)
    f = fidelity(direct.t, direct.x, direct.x_d)
    assert row["rms_translation_um"] == pytest.approx(1e6 * f["rms_translation_m"], rel=1e-9)
    assert row["rms_rotation_urad"] == pytest.approx(1e6 * f["rms_rotation_rad"], rel=1e-9)
    assert row["peak_translation_um"] == pytest.approx(1e6 * f["peak_translation_m"], rel=1e-9)
    assert row["peak_torque_Nm"] == pytest.approx(float(np.abs(direct.T).max()), rel=1e-9)
    # the paper manoeuvre on the reference robot: tens of um, well within the motor's peak
    assert 1.0 < row["rms_translation_um"] < 100.0
    assert 0.3 < row["peak_torque_fraction"] < 1.0
    assert row["peak_speed_rad_s"] == pytest.approx(1.9, abs=0.3)  # the manoeuvre's cranks
    assert row["peak_speed_fraction"] == pytest.approx(row["peak_speed_rad_s"] / 152.2089, rel=1e-5)
    assert rows[1]["completed"] and rows[1]["peak_speed_rad_s"] < 0.2  # breathing is slow


def test_a_dynamixel_design_runs_and_is_measured_against_its_own_motor():
    req = _no_payload()
    req.motions = req.motions[:1]
    (row,) = confirm(Design(motor="XL430-W250-T"), req, duration_s=1.0)
    assert row["completed"] and row["motor"] == "XL430-W250-T"
    assert row["motor_peak_Nm"] == 1.5 and row["motor_continuous_Nm"] == pytest.approx(0.3)
    assert row["motor_no_load_rad_s"] == pytest.approx(61.0 * 2 * np.pi / 60)
    assert row["peak_torque_fraction"] == pytest.approx(row["peak_torque_Nm"] / 1.5, rel=1e-12)
    assert row["rms_torque_fraction"] == pytest.approx(row["rms_torque_Nm"] / 0.3, rel=1e-12)
    assert 0.0 < row["peak_torque_Nm"] <= 1.5 + 1e-6  # never past the motor's peak
    assert row["torque_scale_Nm"] == pytest.approx(0.3 * 1.5 / 0.7021728, rel=1e-12)
    line = confirmation_table([row]).splitlines()[2]
    assert f"| {row['peak_torque_Nm']:.3g} ({100 * row['peak_torque_fraction']:.0f}%) |" in line
    assert line.count("|") == TABLE_HEADER.count("|")


def test_a_motion_the_motors_cannot_make_is_a_row_with_the_reason():
    """20 kg on the platform: holding it needs more than the motors' peak, so the reference is
    refused before the run, and the row says so."""
    req = DesignRequirements(
        motions=[OrganMotionReference("breathing")], payload_kg=20.0
    ).validate()
    (row,) = confirm(reference_design(), req, duration_s=0.5)
    assert row["completed"] is False
    assert row["reason"].startswith("MotorLimitError")
    assert "rms_translation_um" not in row and row["label"] == "breathing"


def test_motions_run_in_a_worker_process_as_in_this_one():
    """Through a local process pool the rows are those of the serial run (the same system), and
    a refusal raised in a worker comes back as a row naming it. One worker runs both motions:
    a second would prove nothing more and costs its own start (Python, Drake, the package)."""
    from stewart_drake.execution.runners import ProcessRunner
    from stewart_drake.references.trajectories import SineReference

    out_of_reach = SineReference(offset=[0, 0, 0, 0, 0, 0.7])  # 0.7 m up: no leg reaches
    req = DesignRequirements(motions=[NamedReference("paper"), out_of_reach]).validate()
    pooled = confirm(reference_design(), req, runner=ProcessRunner(1), duration_s=0.5)
    (serial,) = confirm(
        reference_design(), dataclasses.replace(req, motions=req.motions[:1]), duration_s=0.5
    )
    assert [r["label"] for r in pooled] == ["paper", "sine"]
    assert pooled[0]["completed"]
    for key in ("rms_translation_um", "rms_rotation_urad", "peak_torque_Nm", "peak_speed_rad_s"):
        assert pooled[0][key] == serial[key]
    assert pooled[1]["completed"] is False
    assert pooled[1]["reason"].startswith("UnreachablePoseError")


@pytest.mark.slow
def test_the_reference_robot_makes_the_acceptance_motions_with_the_payload():
    """The acceptance set on the reference robot with its 0.5 kg payload (30 s simulated): both
    motions made, tracking within tens of um, the motors below their peak; holding 1.5 kg takes
    0.374 N m a motor at home, above the maxon's 0.351 N m continuous torque, and so does the
    RMS torque."""
    rows = confirm(reference_design(), load_requirements(REQUIREMENTS))
    paper, breathing = rows
    assert paper["completed"] and breathing["completed"]
    assert (paper["duration_s"], breathing["duration_s"]) == (10.0, 20.0)
    assert 5.0 < paper["rms_translation_um"] < 40.0 and paper["rms_rotation_urad"] < 80.0
    assert 10.0 < breathing["rms_translation_um"] < 100.0
    for row in rows:
        assert 0.5 < row["peak_torque_fraction"] < 1.0
        assert 1.0 < row["rms_torque_fraction"] < 1.5


def test_a_guard_trip_is_a_row(tmp_path):
    """A guard that allows 0.1 um and 0.1 urad of error stops the run at its first check: the
    row names the trip."""
    base = load_scenario("paper_hardware")
    base.guard.max_tracking_error = [1e-7, 1e-7]
    base.guard.divergence_dir = str(tmp_path)
    req = DesignRequirements(motions=[NamedReference("paper")]).validate()
    (row,) = confirm(reference_design(), req, base, duration_s=0.5)
    assert row["completed"] is False
    assert row["reason"].startswith("SimulationDivergedError")
    assert "max_tracking_error" in row["reason"] and "rms_translation_um" not in row
    table = confirmation_table([row]).splitlines()
    assert table[0] == TABLE_HEADER and len(table) == 3
    assert table[2].startswith("| paper | 0.5 | not made: SimulationDivergedError")
    cells = [len(re.split(r"(?<!\\)\|", line)) for line in table]  # | escaped in a reason
    assert cells[0] == cells[1] == cells[2] == 10
    assert r"\|phi - phi_d\|" in table[2]
