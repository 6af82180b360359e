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

SETTINGS = PredictorSettings(min_record_s=2.0)


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
    ],
    ids=[
        "nan",
        "five",
        "text",
        "repeated",
        "out-of-order",
        "same-utime",
        "spacing",
        "spacing-long",
        "numbering-jump",
        "gap",
    ],
)
def test_what_a_stream_cannot_be_is_refused_naming_the_sample(samples, message):
    live = LiveFollower(0.2, 25.0, name="BREATH")
    with pytest.raises(LiveSourceError, match=f"^BREATH: {message}"):
        for k, (seq, utime, pose) in enumerate(samples):
            live.receive(0.1 * k, seq, utime, np.zeros(6) if pose is None else pose)
    assert MAX_GAP_S < 1.16


def test_bad_settings_are_refused():
    for latency in (0.0, float("nan"), -1.0):
        with pytest.raises(InvalidConfigError, match="latency"):
            LiveFollower(latency, 25.0)
    for rate in (0.0, float("inf"), 2000.0):
        with pytest.raises(InvalidConfigError, match="rate"):
            LiveFollower(0.2, rate)
    with pytest.raises(InvalidConfigError, match="unknown predictor"):
        LiveFollower(0.2, 25.0, "lstm")
    assert LiveFollower(0.2, 25.0).evaluate(1.0) is None  # nothing arrived
