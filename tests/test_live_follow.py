"""The live follower (references/live_stream.py): fed a recorded stream's samples at their
arrival times it gives the offline follower's reference, between arrivals as at them; it fills
a few lost samples causally and refuses what a stream cannot be, naming the sample."""

import numpy as np
import pytest

from stewart_drake.base.errors import InvalidConfigError, LiveSourceError
from stewart_drake.references.live_stream import MAX_GAP_S, LiveFollower
from stewart_drake.references.organ.library import make_motion
from stewart_drake.references.prediction import PredictorSettings
from stewart_drake.references.stream import Stream, follow, stream_of

SETTINGS = PredictorSettings(history_s=2.0, min_record_s=2.0)


def _utime(t) -> int:
    return int(round(t * 1e6))


@pytest.mark.parametrize("predictor", ["linear", "none"])
def test_fed_on_time_the_live_follower_is_the_offline_follower(predictor):
    """Irregular breathing 0.2 s late at 25 Hz for 30 s: at three random instants between
    each arrival and the next, pose, rate and acceleration equal the offline follower's to
    1e-12 (m, m/s, m/s^2), across the predictor's switch from held to predicted."""
    stream = stream_of(make_motion("irregular_breathing", {"seed": "3"}), 0.2, 25.0, 30.0)
    offline = follow(stream, predictor, SETTINGS)
    live = LiveFollower(0.2, 25.0, predictor, SETTINGS)
    rng = np.random.default_rng(0)
    worst = 0.0
    for i, (t, y) in enumerate(zip(stream.t, stream.poses)):
        live.receive(stream.arrival[i], i, _utime(t), y)
        nxt = stream.arrival[i] + stream.dt
        for now in [stream.arrival[i], *np.sort(rng.uniform(stream.arrival[i], nxt, 3))]:
            got = live.evaluate(now)
            want = [q[0] for q in offline.evaluate(np.array([now]))]
            worst = max(worst, *(float(np.max(np.abs(a - b))) for a, b in zip(got, want)))
    assert worst < 1e-12, worst
    if predictor == "linear":
        assert len(offline.switches) >= 1 and live.using[3]  # the switch was crossed
        assert live.used_samples > 0.5 * live.received
    assert live.received == stream.t.size and live.filled == 0


def test_lost_samples_are_filled_on_the_line_between_the_two_known():
    """Samples 5 and 6 lost: when 7 arrives they are filled in on the straight line from 4 to
    7 (known then: nothing later is used), and the follower goes on as if they had come."""
    t = np.arange(0.0, 2.0, 0.04)
    poses = np.zeros((t.size, 6))
    poses[:, 3] = 0.01 * t
    live = LiveFollower(0.2, 25.0, "none")
    for i in (0, 1, 2, 3, 4, 7, 8):
        live.receive(t[i] + 0.2, i, _utime(t[i]), poses[i])
    assert (live.received, live.filled) == (7, 2)
    full = follow(Stream(t[:9], poses[:9], 0.2), "none")
    now = t[8] + 0.2 + 0.03
    np.testing.assert_allclose(
        live.evaluate(now)[0], full.evaluate(np.array([now]))[0][0], atol=1e-15
    )


@pytest.mark.parametrize(
    "samples, message",
    [
        ([(0, 0, [0, 0, 0, 0, 0, np.nan])], "sample 0 is not 6 finite numbers"),
        ([(0, 0, [0.0] * 5)], r"sample 0 is not 6 finite numbers: \[0, 0, 0, 0, 0\]"),
        ([(0, 0, "pose")], "sample 0 is not 6 finite numbers: \\['pose'\\]"),
        (
            [(0, 0, None), (0, 40_000, None)],
            "sample 0 .* after sample 0 .*: out of order or repeated",
        ),
        ([(0, 0, None), (2, 80_000, None), (1, 40_000, None)], "sample 1 .*: out of order"),
        ([(0, 0, None), (1, 0, None)], "sample 1 .*: out of order or repeated"),
        ([(0, 0, None), (1, 100_000, None)], "sample 1: the samples are 100 ms apart, not the 40"),
        ([(0, 0, None), (1, 2_500_000, None)], "sample 1: the samples are 2.5 s apart, not the 40"),
        (
            [(0, 0, None), (101, 40_000, None)],
            r"sample 101 \(utime 40000\) is 40 ms after sample 0 \(utime 0\) on the source's "
            r"clock, but 101 samples after it: 4.04 s at the stream's rate \(25 Hz\); the "
            r"source's numbering or its clock jumped",
        ),
        ([(0, 0, None), (30, 1_200_000, None)], r"sample 30: samples 1..29 are missing \(1.16 s"),
        (
            [(0, 0, list(range(10)))],
            r"sample 0 is not 6 finite numbers: \[0, 1, 2, 3, 4, 5, 6, 7\]$",
        ),
        ([(0, 0, "x" * 100)], r"sample 0 is not 6 finite numbers: \['x{79}\]$"),
        (
            [(0, 0, None), (1, 100_000, None)],
            r"sample 1: the samples are 100 ms apart, not the 40 ms of the stream's rate "
            r"\(25 Hz\)$",
        ),
        ([(0, 0, None), (1, 40_000, None)], "sample 1 arrived at 0.1 s, before the previous one$"),
    ],
    ids=(
        "nan five text repeated out-of-order same-utime spacing spacing-long numbering-jump gap "
        "ten long-text spacing-in-words arrived-earlier"
    ).split(),
)
def test_what_a_stream_cannot_be_is_refused_naming_the_sample(samples, message):
    live = LiveFollower(0.2, 25.0, name="BREATH")
    with pytest.raises(LiveSourceError, match=f"^BREATH: {message}"):
        for k, (seq, utime, pose) in enumerate(samples):
            now = 0.1 * k if "arrived" not in message else 0.2 - 0.1 * k
            live.receive(now, seq, utime, np.zeros(6) if pose is None else pose)
    assert MAX_GAP_S < 1.16


def test_the_limits_of_a_stream_are_its_own():
    """At 16 Hz (62.5 ms) two samples 93.75 ms or 31.25 ms apart are exactly SPACING_TOLERANCE
    (a half) off the rate: taken; 93.751 ms is refused. At 20 Hz 10 missing samples are 0.5 s,
    MAX_GAP_S: filled; 11 are refused. Two samples may arrive at the same instant, and a pose
    may come as a (1, 6) array."""
    live = LiveFollower(0.2, 16.0, "none")
    for seq, utime in ((0, 0), (1, 93_750), (2, 125_000)):
        live.receive(0.2, seq, utime, np.zeros((1, 6)))
    assert live.received == 3 and live.last_arrival == 0.2
    with pytest.raises(LiveSourceError, match="93.75 ms apart"):
        live.receive(0.3, 3, 218_751, np.zeros(6))
    live = LiveFollower(0.2, 20.0, "none")
    live.receive(0.0, 0, 0, np.zeros(6))
    live.receive(1.0, 11, 550_000, np.zeros(6))
    assert live.filled == 10 and live.last_arrival == 1.0
    with pytest.raises(LiveSourceError, match=r"samples 12..22 are missing \(0.55 s"):
        live.receive(2.0, 23, 1_150_000, np.zeros(6))


def test_the_reference_goes_on_from_what_it_followed_when_lost_samples_are_filled():
    """When a sample arrives after lost ones, the reference at that instant is still the one it
    was following (the filled-in samples arrive with it: the blend starts from the curve
    followed before, not from theirs), so it has no step there."""
    stream = stream_of(make_motion("breathing", {}), 0.2, 25.0, 12.0)
    live = LiveFollower(0.2, 25.0, "none")
    for i in (*range(200), 203):
        now = stream.arrival[i]
        before = live.evaluate(now)
        live.receive(now, i, _utime(stream.t[i]), stream.poses[i])
        if i > 0:
            np.testing.assert_allclose(live.evaluate(now)[0], before[0], rtol=0, atol=1e-12)
    assert live.filled == 3


class _Scripted:
    """An OnlinePredictor whose record's choice on each axis is given, sample by sample."""

    def __init__(self, using):
        self.rows, self.i, self.clipped = using, 0, 0

    def raw_update(self, y):
        self.using, self.sigma = self.rows[self.i], np.zeros((1, 6))
        self.sample = np.asarray(y, dtype=float)
        self.i += 1
        return np.repeat(np.asarray(y)[None, :], 1, axis=0)


def test_the_weights_move_as_the_record_chooses_once_a_move_has_ended():
    """Samples every 0.5 s whose record switches each axis as written: u moves at the arrival
    where the choice differs from where u is heading, once the 1 s move before has ended; the
    moves in force at a time are those under way, after those that ended folded into one per
    axis (their sum)."""
    using = np.zeros((8, 6), dtype=bool)
    using[1:, 0] = True  # on at 0.5 s
    using[[1, 4, 5], 1] = True  # on at 0.5; off at 1.5 (the end of the move); on 2.5; off 3.5
    using[2, 2] = True  # on at 1.0; off at 2.0
    live = LiveFollower(0.2, 2.0, "none")
    live._model = _Scripted(using)
    for i in range(8):
        live.receive(0.5 * i, i, 500_000 * i, np.zeros(6))
    long_ago = -1e9
    assert live.switches(3.5).tolist() == [
        [long_ago, 0, 1.0], [long_ago, 1, 1.0], [3.5, 1, -1.0]
    ]  # the move from 2.5 ended at 3.5 exactly  # fmt: skip
    assert live.switches(4.6).tolist() == [[long_ago, 0, 1.0]]
    assert live.using.tolist() == [True, False, False, False, False, False]


def test_before_any_sample_nothing_is_used():
    live = LiveFollower(0.2, 25.0, "linear")
    assert live.predictor == "linear" and live.last_arrival is None
    assert live.using.dtype == bool and live.using.shape == (6,) and not live.using.any()
    assert live.sigma.shape == (live.steps, 6) and np.isnan(live.sigma).all()


def test_bad_settings_are_refused():
    for latency in (0.0, float("nan"), -1.0):
        with pytest.raises(InvalidConfigError, match="latency"):
            LiveFollower(latency, 25.0)
    for rate in (0.0, float("inf"), 2000.0, 1000.5, "25"):
        with pytest.raises(InvalidConfigError, match="rate"):
            LiveFollower(0.2, rate)
    assert LiveFollower(0.2, 0.5).dt == 2.0 and LiveFollower(0.2, 1000).dt == 1e-3
    for lag, blend in ((-0.1, 0.1), (1.0, 0.1), (1.5, 0.1), (float("nan"), 0.1), (0.0, 0.0)):
        with pytest.raises(InvalidConfigError, match=r"loop_lag_s must be in \[0, 1\) s and"):
            LiveFollower(0.2, 25.0, loop_lag_s=lag, blend_s=blend)
    assert LiveFollower(0.2, 25.0, loop_lag_s=0.0).loop_lag_s == 0.0
    with pytest.raises(InvalidConfigError, match="unknown predictor"):
        LiveFollower(0.2, 25.0, "lstm")
    assert LiveFollower(0.2, 25.0).evaluate(1.0) is None  # nothing arrived


def test_a_source_that_stalls_leaves_the_reference_where_two_steps_took_it():
    """Breathing sampled with 10 um of noise, then silence: until the sample timeout ends the
    run, the reference holds where the held curve stood two sample steps past the newest
    sample (never the cubic's extrapolation: 22 mm after 0.5 s), at rest; before the silence,
    as on time."""
    from stewart_drake.references.stream import HELD_STEPS

    rng = np.random.default_rng(4)
    t = np.arange(0.0, 6.0, 0.04)
    poses = make_motion("breathing").evaluate(t)[0]
    poses[:, 3:] += rng.normal(0.0, 10e-6, (t.size, 3))
    live = LiveFollower(0.2, 25.0, "none")
    for i, ti in enumerate(t):
        live.receive(ti + 0.2, i, _utime(ti), poses[i])
    last = t[-1] + 0.2
    # Where the held curve reads HELD_STEPS steps past the newest sample, from its own cubic
    # through the last four samples (not-a-knot, as the follower joins them): written out here.
    from scipy.interpolate import CubicSpline

    tau = (np.arange(4) - 3) * 0.04
    held_at = CubicSpline(tau, poses[-4:], axis=0)(HELD_STEPS * 0.04)
    for wait in (0.2, 0.35, 0.5):  # the follower's sample timeout is 0.5 s
        x, v, a = live.evaluate(last + wait)
        np.testing.assert_allclose(x, held_at, rtol=0, atol=1e-12)
        assert not np.any(v) and not np.any(a)
    # The reference there is within a few tenths of a millimetre of the newest sample, as the
    # breathing moved over two steps and a half (its speed at most 25 mm/s), not 22 mm off.
    assert 0.0 < np.max(np.abs(held_at - poses[-1])[3:]) < 2.5 * 0.04 * 0.025


def test_live_and_offline_shape_the_same_reference_for_the_same_arrivals():
    """The library's breathing at 5 Hz with 0.1 mm of noise, 0.2 s late, on the robot as built
    (its prediction asks a motor for more torque than a reference may use): the live follower
    fed each sample at its arrival and shaped period by period by the Shaper (as the robot's
    live reference does) gives, at every period, the pose, rate and acceleration that the
    offline shaping of the offline follower gives, to 1e-12; both shaped it, as many periods
    and by as much. The live shaper starts at rest at the first sample (where the offline
    reference is until it arrives)."""
    from dataclasses import replace

    from stewart_drake.run.plan import make_plan
    from stewart_drake.run.scenario_io import load_scenario
    from stewart_drake.run.shaping import Shaper, shape_followed, shaping_limits

    duration = 10.0
    rng = np.random.default_rng(1)
    t = np.arange(0.0, duration + 1e-9, 0.2)
    poses = np.asarray(make_motion("breathing", {}).evaluate(t)[0]).copy()
    poses[:, 3:] += rng.normal(0.0, 100e-6, (t.size, 3))
    stream = Stream(t, poses, 0.2, "noisy breathing")
    plan = make_plan(
        replace(load_scenario("phantom_hardware"), duration_s=duration), with_reference=False
    )
    limits = replace(shaping_limits(plan), period_s=0.002)
    offline = shape_followed(follow(stream, "linear", SETTINGS), limits, duration)
    live, shaper = LiveFollower(0.2, 5.0, "linear", SETTINGS), Shaper(limits)
    state = shaper.initial_state(poses[0])
    worst, i = 0.0, 0
    for k in range(int(duration / limits.period_s)):
        now = k * limits.period_s
        while i < t.size and stream.arrival[i] <= now:
            live.receive(stream.arrival[i], i, _utime(t[i]), poses[i])
            i += 1
        given, _ = shaper.step(state, now, live.evaluate(now))
        want = np.concatenate([q[0] for q in offline.evaluate(np.array([now]))])
        worst = max(worst, float(np.max(np.abs(given - want))))
    assert worst < 1e-12, worst
    mine, theirs = shaper.record_of(state), offline.record
    assert theirs.scaled >= 1 and mine.scaled == theirs.scaled and mine.shaped == theirs.shaped
    assert mine.departure_m == pytest.approx(theirs.departure_m, rel=1e-9, abs=1e-15)
