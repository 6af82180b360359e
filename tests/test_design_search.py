"""The design search: a candidate's evaluation against independent checks, and the optimizer's
seed, resume and binding constraint."""

import dataclasses
import json
import os
import re
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from conftest import HANG_S

from stewart_drake.design.design_search import (
    SEARCH_VARIABLES,
    design_from_vector,
    search,
    vector_of,
)
from stewart_drake.design.margins import MARGINS, design_geometry, evaluate
from stewart_drake.design.requirements import (
    DesignRequirements,
    RequiredWorkspace,
    load_requirements,
)
from stewart_drake.design.task_samples import task_samples, tilted_box_poses
from stewart_drake.design.variables import Design, reference_design
from stewart_drake.plant import admissible
from stewart_drake.plant.clearance import ClearanceModel
from stewart_drake.references.trajectories import NamedReference
from stewart_drake.robot import limits
from stewart_drake.robot.kinematics import rotation_rpy
from stewart_drake.robot.motor_catalogue import REFERENCE_MOTOR, catalogue_motor

ROOT = Path(__file__).resolve().parents[1]
REQUIREMENTS = ROOT / "scenarios" / "design_requirements.yaml"


@pytest.fixture(scope="module")
def task():
    return task_samples(load_requirements(REQUIREMENTS))


def _paper_only(payload_kg: float, workspace=None) -> DesignRequirements:
    return DesignRequirements(
        motions=[NamedReference(name="paper")], workspace=workspace, payload_kg=payload_kg
    ).validate()


def test_the_required_workspace_is_the_box_grid_with_each_point_tilted_by_the_cone():
    poses = tilted_box_poses([0.03, 0.03, 0.02], 15.0, [0.0, 0.0, 0.3])
    assert poses.shape == (27 * 9, 6)
    z = rotation_rpy(poses[:, :3])[:, :, 2]  # the platform's normal in the base frame
    tilt = np.degrees(np.arccos(np.clip(z[:, 2], -1, 1)))
    assert np.sum(np.isclose(tilt, 0.0, atol=1e-9)) == 27
    assert np.allclose(tilt[tilt > 1e-6], 15.0, atol=1e-9)
    # The eight tilts of a point lean toward eight evenly spread azimuths.
    azimuths = np.degrees(np.arctan2(z[1:9, 1], z[1:9, 0])) % 360
    assert np.allclose(np.diff(np.sort(azimuths)), 45.0, atol=1e-9)
    assert np.allclose(poses[:, 3:].min(axis=0), [-0.015, -0.015, 0.29])
    assert np.allclose(poses[:, 3:].max(axis=0), [0.015, 0.015, 0.31])


def test_a_design_maps_to_a_search_point_and_back(task):
    reference = reference_design()
    again = design_from_vector(vector_of(reference), reference.motor)
    assert again.motor == reference.motor
    for name in SEARCH_VARIABLES:
        assert getattr(again, name) == pytest.approx(getattr(reference, name), rel=1e-12)
    rng = np.random.default_rng(3)
    built = 0
    for u in rng.uniform(size=(40, 8)):
        design = design_from_vector(u, REFERENCE_MOTOR)
        lo, hi = design.rod_length_range()
        if lo <= hi and 0.15 <= lo and hi <= 0.5:
            assert lo - 1e-12 <= design.rod_length <= hi + 1e-12
            design.geometry()  # every point whose other variables allow a rod builds
            built += 1
    assert built >= 10


def test_a_feasible_design_passes_checks_path_validator_and_the_admissible_set(task):
    """The evaluation's verdict against code it does not share: ``check``'s path validator
    (1 kHz samples, clearance every mm of motion) on each motion, and the one admissible set
    on the workspace's held poses."""
    design = dataclasses.replace(reference_design(), motor="XM540-W270-T")
    task = dataclasses.replace(task, resolution=(np.inf, np.inf))  # its 12-bit encoders fail
    e = evaluate(design, task)
    assert e.feasible, e.margins
    geometry = design_geometry(design, task.payload_kg)
    motor = catalogue_motor(design.motor).servo
    motor_limits = limits.MotorLimits(
        motor.peak_torque_Nm, motor.no_load_speed_rad_s, task.torque_share, motor
    )
    reference = NamedReference(name="paper").make(geometry, 10.0, None)
    t = np.arange(0.0, 10.0, 1e-3)
    x, xd, xdd = reference.evaluate(t)
    report = limits.validate_trajectory(
        geometry,
        t,
        x,
        x_dot=xd,
        x_ddot=xdd,
        clearance=ClearanceModel(geometry),
        motor_limits=motor_limits,
    )
    assert report.ok and report.feasible
    assert report.peak_torque == pytest.approx(
        e.figures["per_motion"]["paper"]["peak_torque_Nm"], rel=5e-3
    )
    assert report.peak_speed == pytest.approx(
        e.figures["per_motion"]["paper"]["peak_speed_rad_s"], rel=5e-3
    )
    assert report.min_clearance >= e.figures["min_clearance_m"] - 3e-3
    held = admissible.classify(geometry, task.workspace_x, motor_limits=motor_limits)
    assert held["admissible"].all()
    assert held["max_torque"].max() == pytest.approx(e.figures["holding_torque_Nm"], rel=1e-12)


def test_a_design_over_its_motors_fails_the_torque_margin_as_check_refuses_it():
    task = task_samples(_paper_only(payload_kg=3.0))
    e = evaluate(reference_design(), task)
    assert e.margins["torque"] < 0 and not e.feasible
    assert e.binding[0] in ("torque", "continuous_torque")
    geometry = design_geometry(reference_design(), 3.0)
    motor = catalogue_motor(REFERENCE_MOTOR).servo
    t = np.arange(0.0, 10.0, 1e-3)
    x, xd, xdd = NamedReference(name="paper").make(geometry, 10.0, None).evaluate(t)
    report = limits.validate_trajectory(
        geometry,
        t,
        x,
        x_dot=xd,
        x_ddot=xdd,
        motor_limits=limits.MotorLimits(
            motor.peak_torque_Nm, motor.no_load_speed_rad_s, 0.9, motor
        ),
    )
    assert not report.feasible
    assert 1.0 - report.peak_torque / report.torque_limit == pytest.approx(
        e.margins["torque"], abs=5e-3
    )


def test_the_payload_adds_its_weight_to_the_holding_torque(task):
    """0.5 kg at the platform's centre of mass: the holding torque at home grows by the share
    of 0.5 kg g the legs carry, by virtual work: sum_i T_i dtheta_i = m g dZ for a heave."""
    from stewart_drake.robot.kinematics import X_HOME, jacobian
    from stewart_drake.robot.statics import holding_torques

    g0 = design_geometry(reference_design(), 0.0)
    g1 = design_geometry(reference_design(), 0.5)
    dT = holding_torques(g1, X_HOME) - holding_torques(g0, X_HOME)
    J = jacobian(g1, X_HOME)  # dtheta/dx
    # Virtual work of the added weight along a heave dZ: T . (J e_Z) = 0.5 g.
    assert float(dT @ J[:, 5]) == pytest.approx(0.5 * g1.gravity, rel=1e-9)


def test_every_margin_is_reported_and_the_binding_one_is_the_smallest(task):
    lazy = evaluate(reference_design(), task)
    e = evaluate(reference_design(), task, lazy=False)
    assert not lazy.feasible and "clearance" not in lazy.margins  # it misses one already
    assert lazy.binding[0] == "continuous_torque"  # 1.5 kg held take 0.37 N m > 0.351
    # Met only within 80 % of the continuous torque: a motor never runs at its rating all day.
    f = e.figures
    assert e.margins["continuous_torque"] == pytest.approx(
        1.0 - f["rms_torque_Nm"] / (0.8 * f["motor_continuous_Nm"]), rel=1e-12
    )
    assert set(e.margins) == set(MARGINS)
    assert {k: e.margins[k] for k in lazy.margins} == lazy.margins
    name, margin = e.binding
    assert margin == min(e.margins.values()) and e.margins[name] == margin


def _tiny_search(task, folder, seed=0, maxiter=2):
    return search(
        task,
        REFERENCE_MOTOR,
        "peak_torque",
        folder,
        seed=seed,
        popsize=2,
        maxiter=maxiter,
        progress=False,
    )


def test_the_same_seed_gives_the_same_design_and_another_seed_another(task, tmp_path):
    a = _tiny_search(task, tmp_path / "a")
    b = _tiny_search(task, tmp_path / "b")
    c = _tiny_search(task, tmp_path / "c", seed=1)
    assert a.evaluations == b.evaluations == 16 * 3
    assert dataclasses.asdict(a.best.design) == dataclasses.asdict(b.best.design)
    assert a.generations == b.generations
    assert c.generations != a.generations
    # Run again in its folder: every generation read back, the same answer.
    again = _tiny_search(task, tmp_path / "a")
    assert again.reused == again.evaluations == a.evaluations
    assert again.compute_s == pytest.approx(a.compute_s, rel=1e-12) and a.compute_s > 0
    assert dataclasses.asdict(again.best.design) == dataclasses.asdict(a.best.design)


@pytest.mark.system
def test_a_search_killed_and_run_again_continues_and_finds_the_same_design(task, tmp_path):
    folder = tmp_path / "killed"
    code = (
        "from stewart_drake.design.requirements import load_requirements\n"
        "from stewart_drake.design.design_search import search\n"
        "from stewart_drake.design.task_samples import task_samples\n"
        f"task = task_samples(load_requirements({str(REQUIREMENTS)!r}))\n"
        f"search(task, {REFERENCE_MOTOR!r}, 'peak_torque', {str(folder)!r}, seed=0, popsize=2,"
        " maxiter=6, progress=False)\n"
    )
    proc = subprocess.Popen([sys.executable, "-c", code], cwd=ROOT)
    manifest = folder / "manifest.json"
    deadline = time.monotonic() + HANG_S
    try:
        while time.monotonic() < deadline and proc.poll() is None:
            try:
                if len(json.loads(manifest.read_text())["jobs"]) >= 2:
                    break
            except (OSError, ValueError, KeyError):
                pass
            time.sleep(0.2)
        assert proc.poll() is None, "the search ended before it could be killed"
        os.kill(proc.pid, signal.SIGKILL)
    finally:
        proc.kill()
        proc.wait(timeout=HANG_S)
    resumed = search(
        task, REFERENCE_MOTOR, "peak_torque", folder, seed=0, popsize=2, maxiter=6, progress=False
    )
    whole = search(
        task,
        REFERENCE_MOTOR,
        "peak_torque",
        tmp_path / "whole",
        seed=0,
        popsize=2,
        maxiter=6,
        progress=False,
    )
    assert 32 <= resumed.reused < resumed.evaluations == whole.evaluations
    assert dataclasses.asdict(resumed.best.design) == dataclasses.asdict(whole.best.design)
    assert resumed.generations == whole.generations


def test_a_task_no_design_can_meet_ends_with_its_binding_constraint(tmp_path):
    impossible = _paper_only(
        payload_kg=0.0,
        workspace=RequiredWorkspace(box_m=[0.4, 0.4, 0.3], tilt_deg=45.0),
    )
    task = task_samples(impossible)
    result = search(
        task, REFERENCE_MOTOR, "peak_torque", tmp_path, seed=0, popsize=2, maxiter=2, progress=False
    )
    assert not result.feasible
    name, margin = result.best.binding
    assert name == "reach" and margin < 0


def test_the_encoders_resolution_agrees_with_the_forward_kinematics_of_half_a_count(task):
    """The first-order pose error of half a count at every crank against the exact one: the
    forward kinematics of the perturbed motor angles, at the pose and sign pattern found worst."""
    from stewart_drake.design.margins import _SIGNS, encoder_resolution
    from stewart_drake.robot.forward_kinematics import fk
    from stewart_drake.robot.kinematics import ik, jacobian

    geometry = design_geometry(reference_design(), task.payload_kg)
    x = np.concatenate([task.x, task.workspace_x])
    counts = 4096
    translation, rotation = encoder_resolution(geometry, x, counts)
    dx = np.einsum("nij,sj->nsi", np.linalg.inv(jacobian(geometry, x)), _SIGNS) * np.pi / counts
    n, s = np.unravel_index(np.argmax(np.linalg.norm(dx[..., 3:], axis=-1)), dx.shape[:2])
    theta = ik(geometry, x[n]) + _SIGNS[s] * np.pi / counts
    exact = fk(geometry, theta, x0=x[n])[0] - x[n]
    assert np.linalg.norm(exact[3:]) == pytest.approx(translation, rel=0.02)
    assert 1e-4 < translation < 1e-3 and 1e-3 < rotation < 1e-2  # 12 bits: 0.56 mm, 3.7 mrad
    # Resolution scales as one over the counts.
    assert encoder_resolution(geometry, x, 2**17)[0] == pytest.approx(translation / 32, rel=1e-9)


def _requirements_file(tmp_path, text: str) -> Path:
    path = tmp_path / "requirements.yaml"
    path.write_text(text)
    return path


def test_the_design_command_writes_a_scenario_every_command_takes(tmp_path, capsys):
    """The reference geometry meets this task with the XM540 (no resolution asked): the first
    generation holds it, so a one-generation search finds a design; its scenario file loads as
    any scenario, with the design's robot and the payload on its platform."""
    from stewart_drake.cli import main as cli
    from stewart_drake.run.scenario_io import load_scenario

    path = _requirements_file(
        tmp_path,
        "motions:\n  - !NamedReference {name: paper}\npayload_kg: 0.5\n",
    )
    out = tmp_path / "out"
    one_generation = "--generations 1 --popsize 2 --no-cheapest --no-confirm --runner serial"
    argv = ["design", str(path), "--out", str(out), "--motor", "XM540-W270-T"]
    code = cli.main(argv + one_generation.split() + ["--no-progress"])
    assert code == 0
    document = json.loads((out / "designs.json").read_text())
    best = document["chosen"]["objective"]
    assert best["design"]["motor"] == "XM540-W270-T"
    assert all(m >= 0 for m in best["margins"].values())
    scenario = load_scenario(str(out / "design_objective.yaml"))
    from stewart_drake.design.variables import Design

    geometry = Design(**best["design"]).geometry()
    assert scenario.robot.platform_mass == pytest.approx(geometry.platform_mass + 0.5)
    assert scenario.robot.crank_length == pytest.approx(geometry.crank_length)
    assert scenario.hardware.motors.peak_torque_Nm == pytest.approx(10.6)
    report = (out / "design.md").read_text()
    assert "XM540-W270-T" in report and "## Margins" in report
    # The paper's LQI at 1 ms (the base's) takes 0.66 ms of delay in roll (analyze's table,
    # docs/analysis.md): with 6 ms more it holds no gain, on this design as on the reference.
    for role in ("reference", "objective"):
        assert document["robustness"][role]["holds"] is False
        assert document["robustness"][role]["delayed_gains"] == [None, None]
    assert "**The objective design is not recommended as it is: its loop does NOT hold" in report
    captured = capsys.readouterr()
    assert "design's loop: does NOT hold gain 0.5 to 2 with 6 ms more delay" in captured.out
    # Without bars, the search still says how long it may take before it starts.
    said = re.search(
        r"the search: 32 candidates a motor \(XM540-W270-T first\), ([\d.]+) s a "
        r"candidate at most on 1 worker\(s\): up to (\d+) (s|min) a motor",
        captured.err,
    )
    assert said, captured.err
    each, total, unit = float(said[1]), float(said[2]), said[3]
    assert total * (60 if unit == "min" else 1) == pytest.approx(32 * each, rel=0.5, abs=1)
    for png in ("front.png", "designs.png", "margins.png"):
        assert (out / png).stat().st_size > 10_000


def test_the_design_command_names_the_binding_constraint_of_a_task_nothing_meets(tmp_path, capsys):
    """One line names the binding constraint; with the progress shown, every stage after the
    search's bar is said before it starts (the best design's every margin, the report and its
    plots: once a minute that showed nothing after the bar's end)."""
    from stewart_drake.cli import main as cli

    path = _requirements_file(
        tmp_path,
        "motions: []\nworkspace: {box_m: [0.4, 0.4, 0.3], tilt_deg: 45.0}\n",
    )
    argv = ["design", str(path), "--out", str(tmp_path / "out"), "--generations", "1"]
    code = cli.main([*argv, "--popsize", "2", "--no-cheapest", "--runner", "serial"])
    lines = [ln for ln in re.split(r"[\r\n]", capsys.readouterr().err) if ln.strip()]
    assert code == 1
    said = [ln for ln in lines if ln.startswith("stewart-drake design: ")]
    bar = max(k for k, ln in enumerate(lines) if ln.startswith(f"design {REFERENCE_MOTOR}:"))
    assert [lines.index(ln) > bar for ln in said] == [False, False, True, True, True, True], lines
    assert said[0] == "stewart-drake design: evaluating the reference robot on the task"
    # How long the search may take, before its bar: popsize 2 x 8 variables x 2 generations.
    assert said[1].startswith("stewart-drake design: the search: 32 candidates a motor (")
    assert said[2].startswith(f"stewart-drake design: {REFERENCE_MOTOR}: evaluating every margin")
    assert said[3].startswith("stewart-drake design: what each design's loop survives")
    assert said[4].startswith("stewart-drake design: writing the report, its plots")
    assert "binding constraint reach" in said[5]  # the one line of the verdict, last
    assert "Binding constraint: reach" in (tmp_path / "out" / "design.md").read_text()


def test_rod_ends_that_the_design_puts_too_close_fail_clearance_as_check_refuses_them(task):
    """Two rod ends 14.5 deg apart on a 52 mm ring overlap at every pose: the distance is fixed
    by the design, so the evaluation, the admissible set and check's validator all refuse it."""
    design = Design(
        crank_length=0.082,
        rod_length=0.4164,
        base_radius=0.1189,
        base_pair_spacing_deg=39.8,
        platform_radius=0.05174,
        platform_pair_spacing_deg=14.53,
        crank_direction_deg=108.3,
        home_height=0.4087,
    )
    e = evaluate(design, task, lazy=False)
    gap = 2 * 0.05174 * np.sin(np.radians(14.53 / 2)) - 2 * design.geometry().rod_end_radius
    assert e.figures["design_clearance_m"] == pytest.approx(gap, abs=1e-6) and gap < 0
    assert e.margins["clearance"] < -1.0 and not e.feasible
    geometry = design_geometry(design, task.payload_kg)
    assert not admissible.classify(geometry, task.workspace_x)["clear"].any()
    t = np.arange(0.0, 1.0, 1e-2)
    report = limits.validate_trajectory(
        geometry, t, task.x[:100], clearance=ClearanceModel(geometry)
    )
    assert report.first_interference is not None
    assert report.first_interference[3] == pytest.approx(gap, abs=1e-6)


def test_the_accuracy_asked_refuses_the_xm430s_floor_and_takes_the_pm42s():
    """scenarios/phantom_requirements.yaml asks 0.1 mm and 0.5 mrad RMS per axis: the encoders'
    floor may take half. The reference geometry's floor over the task, against one computed here
    with the Jacobian by central differences of the inverse kinematics: the XM430's 4096 counts
    a turn miss it (about 0.13 mm of X at home), the PM42-010's 526,374 meet it."""
    from stewart_drake.robot.kinematics import ik

    requirements = load_requirements(ROOT / "scenarios" / "phantom_requirements.yaml")
    task = task_samples(requirements)
    assert task.floor == pytest.approx((0.5e-4, 2.5e-4), rel=1e-12)
    geometry = design_geometry(reference_design(), task.payload_kg)
    x = np.concatenate([task.x, task.workspace_x])

    def floor_here(counts: int) -> tuple:
        h = 1e-7
        J = np.empty((len(x), 6, 6))
        for k in range(6):
            dx = np.zeros(6)
            dx[k] = h
            J[:, :, k] = (ik(geometry, x + dx) - ik(geometry, x - dx)) / (2 * h)
        q = 2 * np.pi / counts
        rms = np.sqrt(np.sum(np.linalg.inv(J) ** 2, axis=-1) * q * q / 12)
        return rms[:, 3:].max(), rms[:, :3].max()

    results = {}
    for motor in ("XM430-W350-T", "PM42-010-S260-R"):
        e = evaluate(dataclasses.replace(reference_design(), motor=motor), task, lazy=False)
        counts = catalogue_motor(motor).encoder_counts_per_rev
        m, rad = floor_here(counts)
        assert e.figures["floor_m"] == pytest.approx(m, rel=1e-5)
        assert e.figures["floor_rad"] == pytest.approx(rad, rel=1e-5)
        margin = min(1 - m / task.floor[0], 1 - rad / task.floor[1])
        assert e.margins["accuracy"] == pytest.approx(margin, rel=1e-4, abs=1e-6)
        results[motor] = e
    xm, pm = results["XM430-W350-T"], results["PM42-010-S260-R"]
    assert 1.3e-4 < xm.figures["floor_m"] < 2.0e-4  # 0.13 mm at home, more at the box's edge
    assert xm.margins["accuracy"] < -1.5 and not xm.feasible
    assert 0.5e-6 < pm.figures["floor_m"] < 2.0e-6 and pm.margins["accuracy"] > 0.95


def test_the_cheapest_motor_search_skips_a_motor_the_robot_cannot_drive_by_torque(monkeypatch):
    """The XL430-W250-T senses no current: `robot` refuses it, so the search never recommends
    it, and says so; the next motor up is searched first."""
    from types import SimpleNamespace

    from stewart_drake.design import design_search
    from stewart_drake.robot.motor_catalogue import MOTOR_CATALOGUE

    assert "no Current Control Mode" in design_search.torque_refusal("XL430-W250-T")
    assert design_search.torque_refusal("XM430-W350-T") == ""
    assert design_search.torque_refusal("maxon-EC45flat-50W-GP42C-4.3") == ""  # not on the bus
    searched = []

    def search(task, motor, *args):
        searched.append(motor)
        return SimpleNamespace(motor=motor, feasible=len(searched) == 2)

    monkeypatch.setattr(design_search, "search", search)
    said = []
    results = design_search.cheapest_motor(None, say=said.append)
    cheapest = sorted(MOTOR_CATALOGUE, key=lambda m: MOTOR_CATALOGUE[m].price_usd)
    assert cheapest[0] == "XL430-W250-T" and searched == cheapest[1:3]
    assert [r.motor for r in results] == searched
    assert said == [
        "design: XL430-W250-T skipped: no Current Control Mode (no current sensing), so the "
        "robot's controllers cannot send it a torque and `robot` refuses it"
    ]


def test_design_announces_how_long_its_searches_may_take():
    from types import SimpleNamespace

    from stewart_drake.design.design_search import SEARCH_VARIABLES
    from stewart_drake.design.design_study import _length_words
    from stewart_drake.robot.motor_catalogue import MOTOR_CATALOGUE

    n = 8 * len(SEARCH_VARIABLES) * 31
    others = len(MOTOR_CATALOGUE) - 1  # the XL430-W250-T is never searched
    line = _length_words(0.6, 8, 30, True, "XM430-W350-T", SimpleNamespace(n_workers=2))
    one = n * 0.6 / 2 / 60
    assert line == (
        f"the search: {n} candidates a motor (XM430-W350-T first, then up to {others} more from "
        f"the cheapest up), 0.6 s a candidate at most on 2 worker(s): up to {one:.0f} min a "
        f"motor, {(1 + others) * one:.0f} min in all (a bar per motor)"
    )
    alone = _length_words(0.6, 8, 30, False, "XM430-W350-T", None)
    assert "then up to" not in alone and f"{n * 0.6 / 60:.0f} min in all" in alone
