"""Learning from every cycle: the numpy pieces against independent computations, the Drake
system in the closed loop of the robot as built, its bound, payload error and encoder noise."""

import numpy as np
import pytest

from stewart_drake.base.errors import InvalidConfigError
from stewart_drake.control import ilc
from stewart_drake.control.ilc import IlcDriver
from stewart_drake.organ_motion.fidelity import rms_translation_rotation
from stewart_drake.robot import kinematics
from stewart_drake.robot.geometry import X_HOME
from stewart_drake.run.plan import make_plan
from stewart_drake.run.result import collect_result
from stewart_drake.run.scenario import OrganMotionReference
from stewart_drake.run.scenario_io import load_scenario
from stewart_drake.run.simulate import advance, build_simulator
from stewart_drake.station import guard


def test_the_q_filter_has_zero_phase_and_wraps_around_the_cycle():
    M, dt = 1000, 0.004  # a 4 s cycle
    ba = ilc.q_filter(20.0, dt)
    t = np.arange(M) * dt
    slow = np.sin(2 * np.pi * 2.0 * t + 0.3)[:, None]  # 2 Hz: passes, no lag
    fast = np.sin(2 * np.pi * 60.0 * t)[:, None]  # 60 Hz: removed
    out = ilc.periodic_filtfilt(ba, slow + fast)
    assert np.abs(out - slow).max() < 0.02  # also at both ends (wrapped)
    assert np.abs(np.fft.rfft(out[:, 0])[240]) < 0.02 * np.abs(np.fft.rfft(fast[:, 0])[240])
    assert ilc.q_filter(200.0, dt) is None  # at or above Nyquist: no filter


def test_resampling_to_phase_and_the_lead():
    phase = (np.arange(37) + 0.5) / 37  # 37 records of an odd cycle
    values = np.sin(2 * np.pi * phase)[:, None]
    out = ilc.resample_to_phase(phase, values, 100, shift=0.1)
    grid = np.arange(100) / 100
    assert np.abs(out[:, 0] - np.sin(2 * np.pi * (grid + 0.1))).max() < 5e-3


def test_repeatability_weights_what_repeats():
    rng = np.random.default_rng(0)
    r = np.sin(np.linspace(0, 2 * np.pi, 500))[:, None] * np.ones(6)
    noise = lambda: rng.standard_normal((500, 6))  # noqa: E731
    w = ilc.repeatability(r + 0.1 * noise(), 0.7 * r + 0.1 * noise())
    assert np.all(w > 0.9)  # scale does not matter
    w = ilc.repeatability(0.1 * noise(), 0.1 * noise())
    assert np.all(w < 0.2)
    assert np.all(ilc.repeatability(r, -r) == 0)  # opposite: nothing learned
    snr1 = ilc.repeatability(r + noise() * np.sqrt(0.5), r + noise() * np.sqrt(0.5))
    f = ilc.REPEATABILITY_FLOOR  # |r|^2 / (|r|^2 + |n|^2) = 0.5,
    assert np.allclose(snr1, (0.5 - f) / (1 - f), atol=0.1)  # above the floor


def test_learning_converges_on_a_lagging_loop():
    """The update law on a numpy model of a closed loop that lags 8 ms and overshoots 20 % at
    5 Hz: the error of a repeated cycle falls geometrically (series ILC, Bristow et al.)."""
    M, dt = 1000, 0.004
    f = np.fft.rfftfreq(M, dt)
    s = 2j * np.pi * f
    wn, zeta = 2 * np.pi * 6.0, 0.35
    T = wn**2 / (s**2 + 2 * zeta * wn * s + wn**2) * np.exp(-s * 0.002)

    def loop(r):
        return np.fft.irfft(np.fft.rfft(r, axis=0) * T[:, None], n=M, axis=0)

    t = np.arange(M) * dt
    x_d = (0.0075 - 0.015 * np.cos(np.pi * t / 4) ** 6)[:, None] * np.ones((1, 6))
    learned, ba = np.zeros((M, 6)), ilc.q_filter(25.0, dt)
    errors = []
    for _ in range(8):
        e = loop(x_d + learned) - x_d
        errors.append(np.sqrt(np.mean(e**2)))
        lead = ilc.resample_to_phase((np.arange(M)) / M, e, M, shift=0.008 / (M * dt))
        learned = ilc.learn(learned, lead, 0.8, ba)
    assert errors[-1] < 0.02 * errors[0]
    assert all(b < a for a, b in zip(errors, errors[1:]))


def test_the_measured_error_is_the_pose_error(geometry):
    x_d = (
        X_HOME
        + np.array([0.01, -0.02, 0.005, 0.003, -0.002, 0.004]) * np.linspace(0, 1, 5)[:, None]
    )
    dx = np.array([2e-5, -1e-5, 3e-5, 4e-6, -6e-6, 2e-6])
    theta = kinematics.ik(geometry, x_d + dx)
    assert np.allclose(ilc.cycle_error(geometry, theta, x_d, "pose"), dx, atol=1e-12)
    e_theta = ilc.cycle_error(geometry, theta, x_d, "motor_angle")
    assert np.allclose(ilc._to_pose(geometry, x_d, e_theta), dx, rtol=1e-3, atol=1e-10)


def test_the_system_refuses_bad_settings(geometry):
    with pytest.raises(InvalidConfigError, match="whole multiple"):
        ilc.IterativeLearningController(
            geometry, IlcDriver(sample_period_s=0.0025), 1e-3, 5e-4, [0, 1, 2]
        )
    with pytest.raises(InvalidConfigError, match="increasing"):
        ilc.IterativeLearningController(geometry, IlcDriver(), 1e-3, 5e-4, [0, 2, 1])
    with pytest.raises(InvalidConfigError, match="shorter than four records"):
        ilc.IterativeLearningController(geometry, IlcDriver(), 1e-3, 5e-4, [0, 0.01, 1])
    with pytest.raises(InvalidConfigError, match="gain must be below 2"):
        ilc.IterativeLearningController(geometry, IlcDriver(gain=2.0), 1e-3, 5e-4, [0, 1, 2])


def _learn(cycles, motion="breathing", params=None, **changes):
    """A run of the robot as built learning from every cycle; per-cycle true RMS errors (m,
    rad) and the learner's status at the end of each cycle."""
    scenario = load_scenario("paper_hardware")
    scenario.reference = OrganMotionReference(
        motion, params or {"period": "0.6s", "amplitude": "4mm"}
    )
    learning = changes.pop("learning", {})
    for key, value in changes.items():
        *path, leaf = key.split(".")
        target = scenario
        for p in path:
            target = getattr(target, p)
        setattr(target, leaf, value)
    reference = make_plan(scenario).reference
    starts = reference.cycles(1e3)[0][: cycles + 1]
    scenario.duration_s = float(starts[-1])
    scenario.learning = IlcDriver(**learning)
    sd, simulator = build_simulator(scenario)
    assert sd.learner is not None and sd.learner.M == round(0.6 / 0.004)
    guard.advance(sd, simulator, lambda: advance(simulator, scenario.duration_s, False))
    r = collect_result(sd, simulator.get_context(), 1.0)
    status = sd.loggers["ilc_status"].FindLog(simulator.get_context()).data().T
    final = sd.learner.GetOutputPort("ilc_status").Eval(
        sd.learner.GetMyContextFromRoot(simulator.get_context())
    )
    e = r.x[:, :6] - r.x_d[:, :6]
    true, ends = [], []
    for a, b in zip(starts[:-1], starts[1:]):
        true.append(rms_translation_rotation(e[(r.t >= a) & (r.t < b)]))
        k = int(np.searchsorted(r.t_state, b)) + 1  # just after its end (logged with the state)
        ends.append(dict(zip(ilc.ILC_STATUS_NAMES, status[k] if k < len(status) else final)))
    return np.array(true), ends, r


def test_learning_removes_most_of_the_error_of_a_repeated_breath():
    true, ends, r = _learn(6)
    assert ends[-1]["learned_cycles"] == 6 and ends[-1]["rollbacks"] == 0
    # the true (plant) error of the last cycle against the first, without correction
    assert true[-1][0] < 0.15 * true[0][0], true[:, 0]
    assert true[0][0] > 50e-6  # a breath of 0.6 s lags the loop
    # what the learner measured from the encoders agrees with the truth within a count
    assert abs(ends[0]["E_trans_m"] - true[0][0]) < 5e-6


def test_learning_with_a_heavier_payload_and_noisy_encoders_converges_or_stops():
    true, ends, _ = _learn(6, payload_scale=1.2, **{"hardware.encoders.noise_counts": 1.0})
    last = ends[-1]
    assert last["stopped"] or true[-1][0] < 0.3 * true[0][0], (true, last)
    floor_m = load_scenario("paper_hardware").hardware.encoders.quantum_rad * 0.11
    for j in range(1, len(ends)):  # every corrected cycle within the bound,
        over = ends[j]["E_trans_m"] > 1.2 * ends[j - 1]["E_trans_m"] + floor_m + 1e-12
        assert not over or ends[j]["rollbacks"] > ends[j - 1]["rollbacks"]  # or rolled back


def test_a_learner_past_its_stability_is_rolled_back_by_its_bound():
    true, ends, _ = _learn(
        4, learning=dict(gain=1.9, q_cutoff_hz=500.0, lead_s=0.0, gain_decay_cycles=0.0)
    )
    assert ends[1]["rollbacks"] == 1 and ends[1]["gain"] == pytest.approx(0.95)
    assert ends[1]["E_trans_m"] > 1.2 * ends[0]["E_trans_m"]  # the cycle that tripped it
    # the cycle after the rollback runs with the best correction (none): the first's error
    assert true[2][0] == pytest.approx(true[0][0], rel=0.1)


def test_the_rollback_count_never_passes_its_limit():
    """An unstable learner (gain 1.9, no decay) allowed no rollback: its first cycle over the
    bound (the second) stops learning with the best correction (none) held, instead of counting
    a rollback past the limit; the cycles after run as the first did."""
    true, ends, _ = _learn(
        5,
        learning=dict(
            gain=1.9, q_cutoff_hz=500.0, lead_s=0.0, gain_decay_cycles=0.0, max_rollbacks=0
        ),
    )
    assert [e["rollbacks"] for e in ends] == [0.0] * 5
    assert [e["stopped"] for e in ends] == [0.0, 1.0, 1.0, 1.0, 1.0]
    assert ends[-1]["learned_cycles"] == 1.0
    assert true[-1][0] == pytest.approx(true[0][0], rel=0.1)  # held: no correction
