"""The organ-motion library and recorded traces: the models' own formulas, derivatives that
agree with finite differences, units, axes, gaps, refusals and scaling by the one validator."""

import math

import numpy as np
import pytest
from conftest import write_trace

from stewart_drake.base.errors import InvalidConfigError, MotorLimitError
from stewart_drake.control.ilc import IlcDriver
from stewart_drake.organ_motion.reproduction import scale_to_fit
from stewart_drake.references.motion import reference_cycles
from stewart_drake.references.organ.breathing import (
    Breathing,
    HysteresisBreathing,
    IrregularBreathing,
)
from stewart_drake.references.organ.combinators import ScaledReference, common_period
from stewart_drake.references.organ.core import axis_index
from stewart_drake.references.organ.heartbeat import Heartbeat
from stewart_drake.references.organ.library import make_motion
from stewart_drake.references.samples import CubicSplineTrajectory
from stewart_drake.references.traces import TraceTrajectory, load_trace
from stewart_drake.references.trajectories import make_trajectory
from stewart_drake.robot.geometry import X_HOME
from stewart_drake.run.plan import make_plan
from stewart_drake.run.scenario import (
    OrganMotionReference,
    Scenario,
    TraceReference,
    dump_scenario,
)
from stewart_drake.run.scenario_io import load_scenario

MOTIONS = [
    Breathing(),
    Breathing(shape_n=1, tilt_rad=0.02, phase_rad=0.3),
    Heartbeat(),
    make_motion("breathing_heartbeat"),
    IrregularBreathing(),
    IrregularBreathing(shape_n=2, seed=3),
    HysteresisBreathing(),
]


@pytest.mark.parametrize("motion", MOTIONS, ids=lambda m: f"{m.name}")
def test_rate_and_acceleration_are_the_derivatives_of_the_pose(motion):
    t = np.linspace(0.01, 30.0, 3001)
    if isinstance(motion, IrregularBreathing):  # also right at the cycle boundaries
        t = np.sort(np.concatenate([t, motion.cycles(30.0)[0][1:-1]]))
    h = 1e-5
    x, v, a = motion.evaluate(t)
    xp, vp, _ = motion.evaluate(t + h)
    xm, vm, _ = motion.evaluate(t - h)
    assert np.abs((xp - xm) / (2 * h) - v).max() < 1e-6 * max(1.0, np.abs(v).max())
    assert np.abs((vp - vm) / (2 * h) - a).max() < 1e-4 * max(1.0, np.abs(a).max())
    assert np.abs(xp - xm).max() < 2 * h * np.abs(v).max() + 1e-12  # no jump anywhere


def test_breathing_is_lujans_formula():
    b, tau, n, phi = 0.015, 4.0, 3, math.pi / 2
    m = Breathing(amplitude_m=b, period_s=tau, shape_n=n, phase_rad=phi, direction="Z")
    t = np.linspace(0.0, 8.0, 801)
    z0 = X_HOME[5] + b / 2  # end-exhale, where the motion rests
    expected = z0 - b * np.cos(np.pi * t / tau - phi) ** (2 * n)
    x = m.evaluate(t)[0]
    assert np.allclose(x[:, 5], expected, atol=1e-15)
    assert np.allclose(np.delete(x, 5, axis=1), np.delete(X_HOME, 5))
    assert np.ptp(x[:, 5]) == pytest.approx(b, rel=1e-9)


def test_default_directions_follow_the_patient_frame():
    assert Breathing().direction == (1.0, 0.0, 0.0)  # SI -> platform X
    assert Heartbeat().direction == (0.0, 1.0, 0.0)  # LR -> platform Y
    assert axis_index("AP") == (5, 1.0)
    assert axis_index("-rot_LR") == (1, -1.0)
    with pytest.raises(InvalidConfigError, match="unknown axis 'up'"):
        axis_index("up")


def test_tilt_follows_the_breathing_shape():
    m = Breathing(tilt_rad=math.radians(2), tilt_axis="pitch")
    x = m.evaluate(np.linspace(0, 4, 401))[0]
    assert np.ptp(x[:, 1]) == pytest.approx(math.radians(2), rel=1e-9)
    assert np.allclose(x[:, 1] / x[:, 1].max(), (x[:, 3] - X_HOME[3]) / x[:, 3].max())


def test_heartbeat_amplitude_is_peak_to_peak_and_rate_in_bpm():
    m = Heartbeat(amplitude_m=0.003, rate_bpm=90, harmonics=(1.0, 0.4))
    t = np.linspace(0.0, 2.0, 20001)
    y = m.evaluate(t)[0][:, 4]
    assert np.ptp(y) == pytest.approx(0.003, rel=1e-4)
    assert m.frequency_hz == pytest.approx(1.5)
    assert np.allclose(m.evaluate(t + 60 / 90)[0], m.evaluate(t)[0], atol=1e-12)


def test_the_sum_repeats_after_the_common_period():
    m = make_motion("breathing_heartbeat")
    assert m.repeat_period_s == pytest.approx(20.0)  # 5 breaths, 24 beats
    assert m.frequencies_hz() == {"breathing": 0.25, "cardiac": 1.2}
    t = np.linspace(0, 20, 2001)
    assert np.allclose(m.evaluate(t + 20.0)[0], m.evaluate(t)[0], atol=1e-12)
    assert not np.allclose(m.evaluate(t + 4.0)[0], m.evaluate(t)[0], atol=1e-6)
    assert common_period([4.1, 60 / 72]) is None
    starts, scale = m.cycles(45.0)
    assert np.allclose(starts, [0, 20, 40, 60]) and np.allclose(scale, 1)


def test_irregular_breathing_cycles_vary_and_are_seeded():
    m = IrregularBreathing(seed=7)
    starts, scale = m.cycles(60.0)
    periods = np.diff(starts)
    assert starts[0] == 0 and starts[-2] < 60.0 <= starts[-1]
    assert periods.std() > 0.03 * m.period_s and scale.std() > 0.05
    assert np.allclose(starts, IrregularBreathing(seed=7).cycles(60.0)[0])
    assert not np.allclose(
        periods, np.diff(IrregularBreathing(seed=8).cycles(60.0)[0])[: len(periods)]
    )
    # each cycle reaches its own depth from the same end-exhale position
    x = m.evaluate(np.linspace(0.0, starts[-1], 60001))[0][:, 3] - X_HOME[3]
    t = np.linspace(0.0, starts[-1], 60001)
    for k in range(len(periods)):
        inside = (t >= starts[k]) & (t < starts[k + 1])
        assert x[inside].max() == pytest.approx(m.amplitude_m / 2, abs=1e-9)
        assert x[inside].max() - x[inside].min() == pytest.approx(m.cycle_amplitudes[k], rel=1e-3)


def test_hysteresis_inhale_and_exhale_paths_differ():
    m = HysteresisBreathing()
    assert 0.0015 < m.loop_width_m() < 0.003  # Seppenwoolde: 1-5 mm
    assert HysteresisBreathing(lag=0.0).loop_width_m() < 1e-9
    assert HysteresisBreathing(lag=0.1).loop_width_m() > m.loop_width_m()


def test_make_motion_takes_units_and_names_what_is_wrong():
    m = make_motion(
        "breathing",
        {"amplitude": "20mm", "period": "5 s", "direction": "-Z", "tilt": "2deg", "shape": "2"},
    )
    assert (m.amplitude_m, m.period_s, m.shape_n) == (pytest.approx(0.02), 5.0, 2)
    assert m.direction == (0.0, 0.0, -1.0) and m.tilt_rad == pytest.approx(math.radians(2))
    assert make_motion("breathing", {"amplitude_m": 0.01}).amplitude_m == 0.01
    bh = make_motion("breathing_heartbeat", {"heart_rate": "1.5Hz", "heart_amplitude": "3mm"})
    assert bh.parts[1].rate_bpm == pytest.approx(90) and bh.parts[1].amplitude_m == 0.003
    bh = make_motion("breathing_heartbeat", {"heart_harmonics": "1,0.3", "shape": "1"})
    assert bh.parts[1].harmonics == (1.0, 0.3) and bh.parts[0].shape_n == 1
    with pytest.raises(InvalidConfigError, match="is not a number list"):
        make_motion("breathing_heartbeat", {"heart_harmonics": "1,a"})
    with pytest.raises(InvalidConfigError, match="has no parameter 'depth'.*amplitude"):
        make_motion("breathing", {"depth": "1mm"})
    with pytest.raises(InvalidConfigError, match="unknown unit 'furlong'"):
        make_motion("breathing", {"amplitude": "1furlong"})
    with pytest.raises(InvalidConfigError, match="unknown motion 'cough'"):
        make_motion("cough")
    with pytest.raises(InvalidConfigError, match="shape_n"):
        make_motion("breathing", {"shape_n": "1.5"})


def test_the_commands_list_every_motion_of_the_library_in_its_order():
    """The motion arguments' help (reproduce, verify, robot) is written out, not read from the
    library: building the parser reads no numpy."""
    from stewart_drake.execution.options import LIBRARY_MOTIONS
    from stewart_drake.references.organ.library import LIBRARY

    assert LIBRARY_MOTIONS == tuple(LIBRARY)


def test_scenario_references_and_learning_round_trip_through_yaml(tmp_path):
    s = Scenario(
        reference=OrganMotionReference(
            "breathing_heartbeat", {"amplitude": "12mm", "heart_rate": "60bpm"}
        ),
        learning=IlcDriver(gain=0.5, learn_cycles=3),
    )
    path = tmp_path / "s.yaml"
    dump_scenario(s, path)
    back = load_scenario(path)
    assert back.reference == s.reference and back.learning == s.learning
    motion = make_plan(back).reference
    assert motion.parts[0].amplitude_m == pytest.approx(0.012)
    with pytest.raises(InvalidConfigError, match="learning.gain"):
        load_scenario(path, ["learning.gain=2.5"])
    with pytest.raises(InvalidConfigError, match="has no parameter"):
        load_scenario(path, ["reference.parameters={bogus: 1mm}"])


# -- traces ------------------------------------------------------------------------------------


def test_the_projects_own_csv_is_read_as_before(tmp_path):
    path = tmp_path / "ref.csv"
    rows = ["t,phi,theta,psi,X,Y,Z"] + [f"{k * 0.1},0,0,0,0,0,{0.3 + 0.001 * k}" for k in range(5)]
    path.write_text("\n".join(rows) + "\n")
    ref = load_trace(path)
    assert isinstance(ref, CubicSplineTrajectory) and not isinstance(ref, TraceTrajectory)
    assert ref.evaluate(0.2)[0][5] == pytest.approx(0.302)


def test_cycles_of_a_trace_are_found_where_its_motion_peaks(tmp_path):
    motion = IrregularBreathing(seed=2)
    t = np.arange(0.0, 40.0, 1 / 25)
    path = write_trace(tmp_path / "irr.csv", t, {"X [m]": motion.evaluate(t)[0][:, 3] - X_HOME[3]})
    starts, scale = reference_cycles(load_trace(path), 40.0)
    true = motion.cycles(40.0)[0]
    inhale = true[:-1] + 0.5 * np.diff(true)  # end-inhale: mid-cycle of the model
    inhale = inhale[inhale < 39.5]
    assert len(starts) >= len(inhale) - 1
    assert np.abs(starts[:, None] - inhale[None, :]).min(axis=1).max() < 0.05
    with pytest.raises(InvalidConfigError, match="does not repeat"):
        reference_cycles(make_trajectory("home"), 10.0)


def test_scale_to_fit_shrinks_a_motion_the_motors_cannot_follow_until_it_passes():
    from stewart_drake.run.plan import check_reference

    scenario = load_scenario("paper_hardware")
    scenario.duration_s = 1.0
    fast = Heartbeat(amplitude_m=0.02, rate_bpm=360, harmonics=(1.0,), direction="Z")
    with pytest.raises(MotorLimitError, match=r"motor \d would need .* at t = "):
        check_reference(scenario, fast)
    scaled, scale = scale_to_fit(scenario, fast, tol=0.01)
    assert 0.05 < scale < 1.0
    assert check_reference(scenario, scaled, raise_refused=False).ok
    assert not check_reference(
        scenario, ScaledReference(fast, min(1.0, scale + 0.03)), raise_refused=False
    ).ok
    x = scaled.evaluate(np.linspace(0, 1, 10001))[0]
    assert np.ptp(x[:, 5]) == pytest.approx(scale * 0.02, rel=1e-3)
    assert scale_to_fit(scenario, Breathing())[1] == 1.0


def test_a_trace_reference_in_a_scenario_checks_its_file(tmp_path):
    with pytest.raises(Exception, match="no trace at"):
        Scenario(reference=TraceReference(path=str(tmp_path / "none.csv")))
    t = np.arange(0.0, 3.0, 0.05)
    path = write_trace(tmp_path / "z.csv", t, {"AP [mm]": np.sin(2 * np.pi * t)})
    s = Scenario(reference=TraceReference(path=str(path), scale=0.5))
    ref = make_plan(s).reference
    assert np.ptp(ref.evaluate(t)[0][:, 5]) == pytest.approx(
        0.5 * np.ptp(load_trace(path).evaluate(t)[0][:, 5])
    )
