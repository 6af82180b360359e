"""The servo model against real servos: a DYNAMIXEL XL330-M288-T's bench logs, 0.49 kg swung in
its own position mode at three gains along four motions (Duclusaud et al., ICRA 2025; the BAM
data, Apache-2.0, not shipped: ``../shared/data/bam`` beside the repository, or
``STEWART_DRAKE_BAM=PATH``; without it these tests skip, saying so).

Our split: the shipped model (``stewart_drake/data/servos/XL330-M288-T_m6.json``) was identified
on the eight logs at kp 100 and 400; the four at kp 200 are held out of it, each motion once, at
a gain it never saw. The reference is BAM's own M6, its parameters as BAM published them, its
error measured by BAM's own code where it installs (``better-actuator-models``, Python 3.12;
elsewhere its figure as BAM's code printed it on these logs)."""

import json
import math
import os
from pathlib import Path

import numpy as np
import pytest

from stewart_drake.actuator.bench import BenchModel, errors, replay
from stewart_drake.actuator.bench_log import read_bench_log
from stewart_drake.actuator.model_file import read_model

REPO = Path(__file__).resolve().parent.parent
BAM = Path(os.environ.get("STEWART_DRAKE_BAM", REPO.parent / "shared" / "data" / "bam"))
SHIPPED = REPO / "stewart_drake" / "data" / "servos" / "XL330-M288-T_m6.json"
pytestmark = pytest.mark.skipif(
    not (BAM / "xl330_logs").is_dir(),
    reason=f"the real servos' bench logs are not at {BAM} (set STEWART_DRAKE_BAM=PATH to the BAM "
    "data: xl330_logs/ and params/)",
)
HELD_OUT_KP = 200
#: BAM's M6 on these twelve logs, mean absolute error, rad, as its own ``python -m bam.mae``
#: printed it (better-actuator-models 1.0.2, its logs resampled at 5 ms by ``bam.process``):
#: what the comparison uses where BAM does not install.
BAM_M6_ALL_RAD, BAM_M6_HELD_OUT_RAD = 0.05742, 0.06180


@pytest.fixture(scope="module")
def logs():
    return [read_bench_log(p) for p in sorted((BAM / "xl330_logs").glob("*.json"))]


def _split(logs):
    return [g for g in logs if g.kp != HELD_OUT_KP], [g for g in logs if g.kp == HELD_OUT_KP]


def _mean_mae(model, logs) -> float:
    return float(np.mean([errors(replay(model, log), log)["mae_rad"] for log in logs]))


def test_the_shipped_model_was_identified_on_the_split_it_says(logs):
    """The file names the eight logs at kp 100 and 400, and replays them as it says it did."""
    model, seen = read_model(SHIPPED)
    train, held = _split(logs)
    assert sorted(seen) == sorted(g.name for g in train) and len(held) == 4
    recorded = json.loads(SHIPPED.read_text())["mae_rad"]
    assert _mean_mae(model, train) == pytest.approx(recorded, rel=1e-9)
    assert {g.trajectory for g in held} == {g.trajectory for g in train}  # each motion held out


def test_the_held_out_logs_are_replayed_within_the_measured_error(logs):
    """On the four held-out logs the model's mean absolute error is 34.9 mrad (measured), held
    to 25-45: a model a fifth stiffer, or with the friction of the datasheet's Coulomb guess
    alone, is outside."""
    model, _ = read_model(SHIPPED)
    _, held = _split(logs)
    mae = _mean_mae(model, held)
    assert 0.025 < mae < 0.045, mae
    stiff = BenchModel(
        model.servo,
        model.model_class,
        1.2 * model.k_Nm_per_A,
        model.resistance_ohm,
        model.armature_kg_m2,
        model.q_offset_rad,
        model.friction,
    )
    assert _mean_mae(stiff, held) > 0.045
    coulomb = BenchModel(
        model.servo, "m1", model.k_Nm_per_A, model.resistance_ohm, model.armature_kg_m2,
        model.q_offset_rad, {"coulomb_Nm": 0.05 * 0.52},
    )  # fmt: skip
    assert _mean_mae(coulomb, held) > 0.045


def _bam_params(name: str) -> dict:
    return json.loads((BAM / "params" / "xl330" / f"{name}.json").read_text())


#: BAM's parameters' names as ours (its model file's keys, our friction terms).
_TERMS = {
    "friction_base": "coulomb_Nm",
    "friction_viscous": "viscous_Nm_s_per_rad",
    "friction_stribeck": "stribeck_Nm",
    "dtheta_stribeck": "stribeck_rad_s",
    "alpha": "stribeck_alpha",
    "load_friction_base": "load",
    "load_friction_stribeck": "load_stribeck",
    "load_friction_motor": "load_motor",
    "load_friction_external": "load_external",
    "load_friction_motor_stribeck": "load_motor_stribeck",
    "load_friction_external_stribeck": "load_external_stribeck",
    "load_friction_motor_quad": "quad_motor_per_Nm",
    "load_friction_external_quad": "quad_external_per_Nm",
}


def _ours_with_bams(name: str) -> BenchModel:
    p = _bam_params(name)
    friction = {_TERMS[k]: v for k, v in p.items() if k in _TERMS}
    return BenchModel("XL330-M288-T", name, p["kt"], p["R"], p["armature"], p["q_offset"], friction)


def _bams_own_mae(logs, name: str) -> dict[str, float]:
    """{log name: BAM's model ``name``'s mean absolute error by BAM's own simulator}, the log
    resampled at 5 ms as ``bam.process`` does (linear between samples); skips where BAM does not
    install (it needs Python 3.12)."""
    bam_model = pytest.importorskip("bam.model", reason="better-actuator-models (Python 3.12)")
    from bam import simulate

    model = bam_model.load_model(str(BAM / "params" / "xl330" / f"{name}.json"))
    out = {}
    for log in logs:
        t = np.arange(0.0, log.t[-1], 0.005)
        q = np.interp(t, log.t, log.q)
        goal = np.interp(t, log.t, log.goal)
        frame = np.clip(np.searchsorted(log.t, t, side="right") - 1, 0, log.t.size - 2)
        a = (t - log.t[frame]) / (log.t[frame + 1] - log.t[frame])
        on = log.enabled[frame] + a * (log.enabled[frame + 1].astype(float) - log.enabled[frame])
        entries = [
            {"position": qi, "goal_position": gi, "torque_enable": bool(e > 0.5), "speed": 0.0}
            for qi, gi, e in zip(q, goal, on)
        ]
        data = {"dt": 0.005, "mass": log.mass_kg, "length": log.length_m, "arm_mass": 0.0}
        data.update(kp=log.kp, vin=7.4, entries=entries)
        sim = simulate.Simulator(model)
        positions, _, _ = sim.rollout_log(data, simulate_control=True)
        out[log.name] = float(np.mean(np.abs(np.array(positions) - q)))
    return out


def test_ours_is_no_worse_than_bams_m6_on_the_held_out_logs_and_on_all(logs):
    """BAM's M6 as published, measured by BAM's own code (or its printed figure where it does not
    install), against our M6 identified on the other eight: ours is lower on the held-out four
    (34.9 against 61.8 mrad measured) and on all twelve (26.9 against 57.4)."""
    model, _ = read_model(SHIPPED)
    _, held = _split(logs)
    try:
        theirs = _bams_own_mae(logs, "m6")
        bam_all = float(np.mean(list(theirs.values())))
        bam_held = float(np.mean([theirs[g.name] for g in held]))
    except pytest.skip.Exception:
        bam_all, bam_held = BAM_M6_ALL_RAD, BAM_M6_HELD_OUT_RAD
    assert _mean_mae(model, held) <= bam_held
    assert _mean_mae(model, logs) <= bam_all


@pytest.mark.parametrize("name", ["m1", "m6"])
def test_our_physics_with_bams_parameters_gives_bams_own_figure(logs, name):
    """Our drive, friction and firmware loop, written from the paper's equations, run with BAM's
    published parameters: each log's error within 30 % of what BAM's own code gives it, the mean
    within 5 % (measured: 70.6 against 68.4 mrad for M1, 58.3 against 57.5 for M6; the two differ
    in the step, 1 ms against 5 ms, the encoder read in counts and the supply measured, and the
    logs that drop the pendulum into a free swing differ most, up to 28 %: where the release
    falls within a step moves the whole swing); without BAM, the mean against its printed
    figure."""
    ours = {g.name: errors(replay(_ours_with_bams(name), g), g)["mae_rad"] for g in logs}
    try:
        theirs = _bams_own_mae(logs, name)
    except pytest.skip.Exception:
        printed = {"m1": 0.06841, "m6": BAM_M6_ALL_RAD}[name]
        assert np.mean(list(ours.values())) == pytest.approx(printed, rel=0.05)
        return
    for log_name, value in theirs.items():
        assert ours[log_name] == pytest.approx(value, rel=0.3), log_name
    assert np.mean(list(ours.values())) == pytest.approx(np.mean(list(theirs.values())), rel=0.05)
    assert math.isfinite(sum(ours.values()))
