"""The motion phantoms' library (sawtooth, sharkfin, baseline drift, transient and persistent
excursions, breath-hold): C2 everywhere, the rounded corners included, parameters read back,
refusals typed, and a library motion laid on a recorded trace."""

import math

import numpy as np
import pytest
from conftest import write_trace

from stewart_drake.base.errors import InvalidConfigError
from stewart_drake.cli import main as cli
from stewart_drake.references.organ.breathing import BreathHold, Breathing
from stewart_drake.references.organ.combinators import LayeredReference, MotionSum, layered
from stewart_drake.references.organ.excursions import (
    BaselineDrift,
    PersistentExcursion,
    TransientExcursion,
)
from stewart_drake.references.organ.library import (
    LIBRARY,
    OrganMotionReference,
    make_motion,
    split_parameters,
)
from stewart_drake.references.organ.waveforms import Sawtooth, Sharkfin
from stewart_drake.references.traces import load_trace
from stewart_drake.robot.geometry import X_HOME
from stewart_drake.run.plan import make_plan
from stewart_drake.run.scenario import Scenario, TraceReference, dump_scenario
from stewart_drake.run.scenario_io import load_scenario


def _corners(m) -> np.ndarray:
    """Where ``m`` joins two pieces (the ends of its blends and steps), s, over [0, 40]."""
    if isinstance(m, (Sawtooth, Sharkfin)):
        h, T = 0.5 * m.rounding_s, m.period_s
        t_in = m.inhale_fraction * T
        points = [k * T + c for k in range(11) for c in (-h, h, t_in - h, t_in + h)]
    elif isinstance(m, BaselineDrift):
        t0, r, D = m.drift_start_s, m.drift_rounding_s, m.drift_duration_s
        points = [t0, t0 + r] if m.drift_period_s else [t0, t0 + r, t0 + D - r, t0 + D]
    elif isinstance(m, TransientExcursion):
        t0, r, D = m.excursion_start_s, m.excursion_rise_s, m.excursion_duration_s
        points = [t0, t0 + r, t0 + D - r, t0 + D]
    elif isinstance(m, PersistentExcursion):
        points = [m.shift_start_s, m.shift_start_s + m.shift_rise_s]
    else:  # a breath-hold
        ta, r = m.hold_starts_s, m.hold_ramp_s
        points = [ta, ta + r, ta + r + m.hold_s, ta + 2 * r + m.hold_s]
    points = np.asarray(points, dtype=float)
    return points[(points > 1e-3) & (points < 40.0)]


def _largest_jumps(m, points, delta=1e-7) -> tuple[float, float, float]:
    """The largest change of pose, rate and acceleration across ``points`` (from delta before to
    delta after)."""
    before, after = m.evaluate(points - delta), m.evaluate(points + delta)
    return tuple(float(np.abs(b - a).max()) for a, b in zip(before, after))


PHANTOM = [
    Sawtooth(),
    Sawtooth(inhale_fraction=0.6, rounding_s=0.05, direction="-AP"),
    Sharkfin(),
    Sharkfin(inhale_fraction=0.2, inhale_tau_s=0.1, exhale_tau_s=2.0, rounding_s=0.1),
    BaselineDrift(drift_start_s=3.0, drift_duration_s=20.0),
    BaselineDrift(drift_period_s=12.0, drift_start_s=1.0, drift_direction="LR"),
    TransientExcursion(),
    PersistentExcursion(shift_m=-0.004, shift_direction="AP"),
    BreathHold(hold_s=5.0),
    BreathHold(hold_phase=0.3, hold_cycle=2, hold_s=3.0, hold_ramp_s=0.8, shape_n=1),
]


@pytest.mark.parametrize("motion", PHANTOM, ids=lambda m: m.name)
def test_pose_rate_and_acceleration_agree_with_finite_differences_of_the_pose(motion):
    corners = _corners(motion)
    t = np.sort(np.concatenate([np.linspace(0.013, 40.0, 4001), corners]))
    h = 1e-6
    x, v, a = motion.evaluate(t)
    xp, vp, _ = motion.evaluate(t + h)
    xm, vm, _ = motion.evaluate(t - h)
    v_scale, a_scale = np.abs(v).max(), np.abs(a).max()
    assert v_scale > 0 and a_scale > 0
    assert np.abs((xp - xm) / (2 * h) - v).max() < 1e-5 * v_scale
    assert np.abs((vp - vm) / (2 * h) - a).max() < 1e-4 * a_scale
    # the acceleration is also the pose's second difference, corners included
    h = 1e-4
    xp, xm = motion.evaluate(t + h)[0], motion.evaluate(t - h)[0]
    assert np.abs((xp - 2 * x + xm) / h**2 - a).max() < 1e-2 * a_scale


@pytest.mark.parametrize("motion", PHANTOM, ids=lambda m: m.name)
def test_nothing_jumps_where_the_pieces_meet(motion):
    corners = _corners(motion)
    assert corners.size >= 2
    _, v, a = motion.evaluate(np.linspace(0.0, 40.0, 40001))
    dx, dv, da = _largest_jumps(motion, corners)
    assert dx < 1e-6 * np.abs(v).max()  # 2e-7 s at the top speed: no step
    assert dv < 1e-5 * max(np.abs(a).max(), 1e-3)
    assert da < 1e-4 * max(np.abs(a).max(), 1e-3)


def test_the_jump_check_sees_a_raw_corner():
    """The same check on the ramps without their rounding: the rate jumps at the corner."""
    saw = Sawtooth(rounding_s=0.2)
    t_in = saw.inhale_fraction * saw.period_s
    inhale, exhale = saw._branches()
    raw = np.array([t_in - 1e-7, t_in + 1e-7])
    rate = np.where(raw < t_in, inhale(raw)[1], exhale(raw)[1])
    assert abs(rate[1] - rate[0]) > 1.0  # /s of the unit stroke: a corner
    dx, dv, da = _largest_jumps(saw, np.array([t_in]))
    assert dv < 1e-6 and da < 1e-5  # |a| 2e-7 s: no step


@pytest.mark.parametrize("cls", [Sawtooth, Sharkfin])
def test_waveform_amplitude_period_and_inhale_read_back(cls):
    m = cls(amplitude_m=0.012, period_s=5.0, inhale_fraction=0.4, direction="Z")
    t = np.linspace(0.0, 10.0, 200001)
    z = m.evaluate(t)[0][:, 5] - X_HOME[5]
    assert np.ptp(z) == pytest.approx(0.012, rel=1e-6)
    assert 0.5 * (z.max() + z.min()) == pytest.approx(0.0, abs=1e-9)  # centred mid-range
    assert np.allclose(m.evaluate(t + 5.0)[0], m.evaluate(t)[0], atol=1e-12)
    assert m.repeat_period_s == 5.0 and m.frequencies_hz() == {"breathing": 0.2}
    # end-exhale (+) near the cycle's start, end-inhale (-) near 0.4 of it
    one = t < 5.0
    assert abs(t[one][np.argmax(z[one])] - 0.0) < 0.15 or t[one][np.argmax(z[one])] > 4.85
    assert t[one][np.argmin(z[one])] == pytest.approx(2.0, abs=0.15)
    starts, scale = m.cycles(12.0)
    assert np.allclose(starts, [0, 5, 10, 15]) and np.allclose(scale, 1)


def test_sawtooth_ramps_are_straight_between_the_rounded_corners():
    m = Sawtooth(amplitude_m=0.015, period_s=4.0, inhale_fraction=0.3, rounding_s=0.2)
    low, span = m._range
    inhale = np.linspace(0.15, 1.05, 50)  # clear of the corners at 0 and 1.2 s
    exhale = np.linspace(1.35, 3.85, 50)
    for t, speed in ((inhale, -0.015 / 1.2 / span), (exhale, 0.015 / 2.8 / span)):
        _, v, a = m.evaluate(t)
        assert np.allclose(v[:, 3], speed, rtol=1e-12) and np.abs(a).max() < 1e-12
    assert low == pytest.approx(0.016, abs=1e-3) and 1 - low - span == pytest.approx(
        0.016, abs=1e-3
    )
    # the rounded path is at most 5/64 rounding_s times the change of speed inside the corner
    assert 0.8 < low / (5 / 64 * 0.2 * (1 / 1.2 + 1 / 2.8)) < 1.0


def test_sharkfin_inhale_and_exhale_are_exponentials_of_their_time_constants():
    m = Sharkfin(inhale_tau_s=0.3, exhale_tau_s=0.7, rounding_s=0.2)
    inhale = np.linspace(0.15, 1.05, 40)
    exhale = np.linspace(1.35, 3.85, 40)
    for t, tau in ((inhale, 0.3), (exhale, 0.7)):
        _, v, a = m.evaluate(t)
        assert np.allclose(a[:, 3] / v[:, 3], -1.0 / tau, rtol=1e-9)  # y''/y' of exp(-t/tau)
    _, v, a = m.evaluate(np.linspace(0.0, 4.0, 40001))
    assert np.abs(a[:, 3]).max() == pytest.approx(0.42, abs=0.01)  # the docstring's figure
    # the rounded corners are cut inside: the motion turns back twice a cycle, no more
    assert np.count_nonzero(np.diff(np.sign(v[:, 3])) != 0) == 2


def test_baseline_drift_reaches_its_total_at_its_rate():
    m = BaselineDrift(drift_m=0.004, drift_duration_s=30.0, drift_start_s=5.0)
    x, v, _ = m.evaluate(np.array([0.0, 5.0, 20.0, 35.0, 100.0]))
    assert np.allclose(x[:, 3] - X_HOME[3], [0, 0, 0.004 * (15 - 1) / 28, 0.004, 0.004])
    assert v[2, 3] == pytest.approx(0.004 / 28.0, rel=1e-12)  # drift_m / (duration - rounding)
    assert np.allclose(v[[0, 3, 4]], 0.0)
    sine = BaselineDrift(drift_m=0.002, drift_period_s=20.0, drift_rounding_s=2.0)
    t = np.linspace(2.0, 42.0, 40001)
    x = sine.evaluate(t)[0][:, 3] - X_HOME[3]
    assert np.ptp(x) == pytest.approx(0.002, rel=1e-6) and x.min() > -1e-12
    assert np.allclose(sine.evaluate(t + 20.0)[0], sine.evaluate(t)[0], atol=1e-15)
    with pytest.raises(InvalidConfigError, match="does not repeat"):
        sine.cycles(60.0)


def test_transient_excursion_goes_and_comes_back_persistent_one_stays():
    m = TransientExcursion(
        excursion_m=0.005, excursion_start_s=2.0, excursion_duration_s=10.0, excursion_rise_s=2.0
    )
    t = np.array([0.0, 2.0, 3.0, 4.0, 8.0, 10.0, 12.0, 30.0])
    d = m.evaluate(t)[0][:, 3] - X_HOME[3]
    assert np.allclose(d, [0, 0, 0.0025, 0.005, 0.005, 0.005, 0, 0], atol=1e-15)
    assert np.abs(m.evaluate(np.linspace(0, 20, 20001))[1]).max() == pytest.approx(
        1.875 * 0.005 / 2.0, rel=1e-6
    )
    p = PersistentExcursion(shift_m=-0.003, shift_start_s=1.0, shift_rise_s=4.0)
    d = p.evaluate(np.array([0.5, 3.0, 5.0, 1e4]))[0][:, 3] - X_HOME[3]
    assert np.allclose(d, [0.0, -0.0015, -0.003, -0.003], atol=1e-15)


def test_breath_hold_stops_at_its_phase_for_its_time_then_resumes():
    m = BreathHold(hold_cycle=1, hold_phase=0.5, hold_s=6.0, hold_ramp_s=0.5)
    b = Breathing()
    ta = m.hold_starts_s
    assert ta == pytest.approx(5.75)
    before = np.linspace(0.0, ta, 200)
    assert np.allclose(m.evaluate(before)[0], b.evaluate(before)[0], atol=1e-15)
    still = np.linspace(ta + 0.5, ta + 6.5, 200)
    x, v, a = m.evaluate(still)
    assert np.allclose(x, b.evaluate(6.0)[0], atol=1e-15)  # held at end-inhale (t = 6 s)
    assert np.abs(v).max() < 1e-15 and np.abs(a).max() < 1e-15
    assert x[0, 3] - X_HOME[3] == pytest.approx(-0.0075)
    after = np.linspace(ta + 7.0, 40.0, 300)
    for got, want in zip(m.evaluate(after), b.evaluate(after - 6.5)):
        assert np.allclose(got, want, atol=1e-12)  # hold_s + ramp behind
    starts, scale = m.cycles(20.0)
    assert np.allclose(starts, [0.0, 4.0, 14.5, 18.5, 22.5]) and np.allclose(scale, 1)
    assert m.repeat_period_s is None and m.frequencies_hz() == {"breathing": 0.25}


@pytest.mark.parametrize(
    "make, match",
    [
        (lambda: Sawtooth(rounding_s=1.5), r"rounding_s must be at most .*\(1.2 s\)"),
        (lambda: Sawtooth(rounding_s=0.0), r"rounding_s must be a finite number in \(0"),
        (lambda: Sharkfin(inhale_fraction=1.2), r"inhale_fraction must be .* \[0.05, 0.95\]"),
        (lambda: Sharkfin(exhale_tau_s=-1.0), "exhale_tau_s must be a finite number"),
        (lambda: Sharkfin(direction="pitch"), "must be a translation axis"),
        (lambda: BaselineDrift(drift_rounding_s=40.0), "at most half the drift's duration"),
        (
            lambda: BaselineDrift(drift_period_s=10.0, drift_rounding_s=6.0),
            "at most half the drift's period",
        ),
        (lambda: TransientExcursion(excursion_rise_s=6.0), "at most half excursion_duration"),
        (lambda: TransientExcursion(excursion_m=2.0), r"excursion_m must be .* \[-1, 1\]"),
        (lambda: PersistentExcursion(shift_direction=(0, 0, 0)), "not be the zero vector"),
        (lambda: PersistentExcursion(shift_rise_s=0.0), "shift_rise_s must be"),
        (lambda: BreathHold(hold_phase=1.0), r"hold_phase must be in \[0, 1\)"),
        (lambda: BreathHold(hold_cycle=1.5), "hold_cycle must be an integer"),
        (lambda: BreathHold(hold_cycle=0, hold_phase=0.0), "before t = 0"),
        (lambda: BreathHold(hold_ramp_s=5.0), r"hold_ramp_s must be .* \(0, 4\]"),
        (lambda: make_motion("sharkfin", {"rounding": "1furlong"}), "unknown unit 'furlong'"),
        (lambda: make_motion("breath_hold", {"breath": "2s"}), "has no parameter 'breath'"),
    ],
)
def test_bad_parameters_are_refused_with_a_typed_error(make, match):
    with pytest.raises(InvalidConfigError, match=match):
        make()


def test_make_motion_builds_the_phantoms_motions_with_units():
    m = make_motion("breath_hold", {"hold": "15s", "hold_ramp": "300ms", "hold_phase": "0"})
    assert (m.hold_s, m.hold_ramp_s, m.hold_phase) == (15.0, pytest.approx(0.3), 0.0)
    m = make_motion("sharkfin", {"exhale_tau": "1s", "rounding": "250ms", "period": "5s"})
    assert (m.exhale_tau_s, m.rounding_s, m.period_s) == (1.0, 0.25, 5.0)
    m = make_motion("baseline_drift", {"drift": "-2mm", "drift_period": "1min"})
    assert (m.drift_m, m.drift_period_s) == (pytest.approx(-0.002), 60.0)
    phantoms = "sawtooth sharkfin baseline_drift transient_excursion persistent_excursion"
    assert set(LIBRARY) >= set(phantoms.split()) | {"breath_hold"}


# -- laying a library motion on another motion or on a trace -----------------------------------


def test_a_drift_on_a_trace_is_the_trace_plus_the_drift(tmp_path):
    t = np.arange(0.0, 30.0, 0.04)
    path = write_trace(
        tmp_path / "patient.csv", t, {"SI [mm]": 6 * np.cos(np.pi * t / 4) ** 4, "AP [mm]": t * 0}
    )
    trace = load_trace(path)
    drift = BaselineDrift(drift_m=0.003, drift_duration_s=20.0, drift_direction="SI")
    both = layered(trace, [drift])
    assert isinstance(both, LayeredReference) and both.name == "patient+baseline_drift"
    assert both.end_time == trace.end_time and both.centre == trace.centre
    for got, a, b in zip(both.evaluate(t), trace.evaluate(t), drift.displacement(t)):
        assert np.allclose(got, a + b, atol=1e-15)
    x = both.evaluate(t)[0]
    assert x[-1, 3] - trace.evaluate(t[-1])[0][3] == pytest.approx(0.003)
    assert both.evaluate(5.0)[0].shape == (6,)  # one time: one pose
    # the same through a scenario, its YAML and the plan
    s = Scenario(reference=TraceReference(path=str(path), add={"baseline_drift": {"drift": "3mm"}}))
    dump_scenario(s, tmp_path / "s.yaml")
    back = load_scenario(tmp_path / "s.yaml")
    assert back.reference.add == {"baseline_drift": {"drift": "3mm"}}
    assert back.reference.label == "patient+baseline_drift"
    ref = make_plan(back).reference
    assert np.allclose(
        ref.evaluate(t)[0],
        trace.evaluate(t)[0] + BaselineDrift(drift_m=0.003).displacement(t)[0],
    )
    with pytest.raises(InvalidConfigError, match="unknown motion 'cough'"):
        TraceReference(path=str(path), add={"cough": {}}).validate()


def test_an_excursion_on_breathing_is_a_sum_about_the_breathing_s_centre():
    ref = OrganMotionReference(
        "breathing",
        {"amplitude": "10mm"},
        add={"transient_excursion": {"excursion": "4mm", "excursion_direction": "AP"}},
    )
    ref.validate()
    motion = ref.make(None, 10.0, None)
    assert isinstance(motion, MotionSum) and ref.label == "breathing+transient_excursion"
    t = np.linspace(0.0, 20.0, 2001)
    b = Breathing(amplitude_m=0.01).evaluate(t)
    e = TransientExcursion(excursion_m=0.004, excursion_direction="AP").displacement(t)
    for got, x, d in zip(motion.evaluate(t), b, e):
        assert np.allclose(got, x + d, atol=1e-15)
    assert np.allclose(motion.cycles(12.0)[0], [0, 4, 8, 12])  # the breathing's


def test_split_parameters_sends_each_key_to_the_motion_that_has_it():
    shares = split_parameters(
        ["breathing", "baseline_drift", "heartbeat"],
        {"drift": "3mm", "period": "5s", "heartbeat.amplitude": "2mm", "rate": "60bpm"},
    )
    assert shares == [{"period": "5s"}, {"drift": "3mm"}, {"amplitude": "2mm", "rate": "60bpm"}]
    with pytest.raises(InvalidConfigError, match="both have it; .* breathing.amplitude="):
        split_parameters(["breathing", "heartbeat"], {"amplitude": "1mm"})
    with pytest.raises(InvalidConfigError, match="none of breathing, heartbeat has it"):
        split_parameters(["breathing", "heartbeat"], {"drift": "1mm"})
    with pytest.raises(InvalidConfigError, match="'sharkfin' is not among the motions"):
        split_parameters(["breathing"], {"sharkfin.amplitude": "1mm"})


def test_reproduce_add_lays_motions_on_a_trace_or_a_library_motion(tmp_path, monkeypatch, capsys):
    """`reproduce --add` builds the layered reference (the run itself is replaced here)."""
    seen = []

    def fake_reproduce(scenario, **kwargs):
        seen.append(scenario.reference)
        raise InvalidConfigError("captured")

    monkeypatch.setattr("stewart_drake.organ_motion.reproduction.reproduce", fake_reproduce)
    t = np.arange(0.0, 12.0, 0.05)
    path = write_trace(tmp_path / "p.csv", t, {"SI [mm]": 5 * np.sin(np.pi * t / 2)})
    out = str(tmp_path / "out")
    argv = ["reproduce", str(path), "--add", "baseline_drift", "--param", "drift=2mm"]
    assert cli.main(argv + ["--out", out, "--no-progress"]) == 2
    assert seen[-1].add == {"baseline_drift": {"drift": "2mm"}}
    argv = ["reproduce", "breathing", "--add", "persistent_excursion", "--add", "heartbeat"]
    argv += ["--param", "shift=3mm", "--param", "breathing.amplitude=8mm", "--param", "rate=60"]
    assert cli.main(argv + ["--out", out, "--no-progress"]) == 2
    ref = seen[-1]
    assert ref.parameters == {"amplitude": "8mm"}
    assert ref.add == {"persistent_excursion": {"shift": "3mm"}, "heartbeat": {"rate": "60"}}
    motion = make_plan(Scenario(reference=ref)).reference
    assert [p.name for p in motion.parts] == ["breathing", "persistent_excursion", "heartbeat"]
    capsys.readouterr()
    for argv, expected in (
        (["reproduce", str(path), "--param", "drift=2mm"], "of one added with --add on a trace"),
        (["reproduce", "breathing", "--add", "heartbeat", "--param", "amplitude=1mm"], "both"),
        (
            ["reproduce", "breathing", "--add", "heartbeat", "--add", "heartbeat"],
            "each motion once",
        ),
    ):
        assert cli.main(argv + ["--out", out, "--no-progress"]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and expected in err[0], err


def test_breath_hold_default_cycle_lengths():
    m = BreathHold()
    starts, _ = m.cycles(40.0)
    assert np.allclose(np.diff(starts)[:3], [4.0, 4.0 + 20.0 + 0.5, 4.0])
    assert math.isclose(m.evaluate(14.0)[0][3] - X_HOME[3], -0.0075, abs_tol=1e-15)
