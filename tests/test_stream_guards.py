"""What keeps a stream predictor from doing harm on the inputs real trackers give: the samples'
outliers taken out (and nothing else), a step the motion truly makes taken after at most
MAX_REJECTED_RUN samples, the recent envelope, the settings refused, and the follower's
figures against the true motion with and without the guards. Fast unit tests."""

import re

import numpy as np
import pytest

from stewart_drake.base.errors import InvalidConfigError
from stewart_drake.organ_motion.streaming import MEASURE_STEP_S, stream_figures
from stewart_drake.references.organ.library import make_motion
from stewart_drake.references.prediction import (
    MAX_REJECTED_RUN,
    OnlinePredictor,
    PredictorSettings,
)
from stewart_drake.references.stream import follow, stream_of
from stewart_drake.studies.stream_sources import StreamForm

RATE_HZ = 25.0


def _fed(poses, settings, steps=6):
    """(the samples as followed (N, 6), the predictor) after feeding ``poses``."""
    p = OnlinePredictor("linear", 1 / RATE_HZ, steps, 6, settings)
    out = []
    for y in poses:
        p.raw_update(y)
        out.append(p.sample.copy())
    return np.array(out), p


def test_outliers_are_taken_out_and_nothing_else():
    """Breathing at 25 Hz with 30 samples off by 3 mm on each translation (from 12 s, 40
    samples apart): exactly those samples' translations are replaced, by positions within
    0.1 mm of the true motion there; no other sample, and no rotation, is touched."""
    stream = stream_of(make_motion("breathing", {}), 0.2, RATE_HZ, 60.0)
    poses = stream.poses.copy()
    hit = np.arange(300, 1500, 40)[:30]
    signs = np.where(np.arange(hit.size)[:, None] % 2 == 0, 1.0, -1.0) * [1.0, -1.0, 1.0]
    poses[hit, 3:] += 3e-3 * signs
    followed, p = _fed(poses, PredictorSettings(outlier_k=4.0))
    replaced = followed != poses
    rows, axes = np.nonzero(replaced)
    assert set(rows.tolist()) == set(hit.tolist())
    assert set(axes.tolist()) == {3, 4, 5}
    assert p.rejected == int(replaced.sum()) == 3 * hit.size
    assert np.max(np.abs(followed[hit, 3:] - stream.poses[hit, 3:])) < 1e-4
    assert np.max(np.abs(followed[hit, 3:] - stream.poses[hit, 3:])) > 0  # a prediction


def test_without_the_setting_no_sample_is_replaced():
    stream = stream_of(make_motion("breathing", {}), 0.2, RATE_HZ, 30.0)
    poses = stream.poses.copy()
    poses[400, 3] += 3e-3
    followed, p = _fed(poses, PredictorSettings())
    np.testing.assert_array_equal(followed, poses)
    assert p.rejected == 0


@pytest.mark.parametrize("seed", [3, 12])
def test_an_irregular_motion_is_its_own_not_an_outlier(seed):
    """Irregular breathing (amplitude and period varying 30 % from cycle to cycle), exact
    samples: no sample is taken out, although its breaths surprise the predictor."""
    motion = make_motion(
        "irregular_breathing", {"seed": seed, "amplitude_cv": 0.3, "period_cv": 0.3}
    )
    poses = stream_of(motion, 0.2, RATE_HZ, 120.0).poses
    followed, p = _fed(poses, PredictorSettings(outlier_k=4.0))
    assert p.rejected == 0
    np.testing.assert_array_equal(followed, poses)


def test_a_step_the_motion_makes_is_taken_after_the_longest_run():
    """Breathing that steps by 5 mm on X at sample 800 and stays there: at most
    MAX_REJECTED_RUN samples in a row are replaced, then every sample is taken as it is."""
    stream = stream_of(make_motion("breathing", {}), 0.2, RATE_HZ, 60.0)
    poses = stream.poses.copy()
    poses[800:, 3] += 5e-3
    followed, p = _fed(poses, PredictorSettings(outlier_k=4.0))
    replaced = np.flatnonzero((followed != poses).any(axis=1))
    assert MAX_REJECTED_RUN == 2
    assert replaced.tolist() == [800, 801]
    np.testing.assert_array_equal(followed[802:], poses[802:])


class _Overshooting:
    """A model that asks for 5 cm more than the newest sample at every step ahead."""

    warm = 0

    def update(self, y):
        return np.repeat(np.asarray(y)[None, :], 6, axis=0) + 0.05


def test_the_prediction_stays_within_the_recent_envelope():
    """Breathing of 15 mm for 40 s, then of 1.5 mm (its centre the same), predicted 5 cm too
    far: with a 10 s envelope, from 60 s on the highest position put forward is the top of the
    samples' range of the last 11 s (the blocks of a second kept and the one under way) plus a
    tenth of that range, within 1e-12 m; with the whole run's range, the 15 mm breaths' top
    plus a tenth of 15 mm."""
    t = np.arange(0.0, 80.0, 1 / RATE_HZ)
    z = np.where(t < 40.0, 7.5e-3, 0.75e-3) * np.sin(2 * np.pi * t / 4.0)
    poses = np.zeros((t.size, 6))
    poses[:, 5] = z
    for envelope_s in (10.0, None):
        settings = PredictorSettings(envelope_s=envelope_s, bound_s=None, shrink=False)
        p = OnlinePredictor("linear", 1 / RATE_HZ, 6, 6, settings)
        p.model = _Overshooting()
        for i, y in enumerate(poses):
            ahead = p.raw_update(y)
            if t[i] >= 60.0:
                recent = z[max(0, i - int(11 * RATE_HZ)) : i + 1] if envelope_s else z[: i + 1]
                top = recent.max() + 0.1 * np.ptp(recent)
                assert ahead[:, 5] == pytest.approx(np.full(6, top), abs=1e-12)
        if envelope_s is None:
            assert top == pytest.approx(7.5e-3 * 1.2, rel=1e-3)
        else:
            assert top == pytest.approx(0.75e-3 * 1.2, rel=1e-3)


@pytest.mark.parametrize(
    "change, words",
    [
        ({"outlier_k": 0.0}, "outlier_k must be a finite number > 0"),
        ({"record_margin": 1.0}, "record_margin must be a finite number in [0, 1)"),
        ({"record_margin": -0.1}, "record_margin must be a finite number in [0, 1)"),
        ({"envelope_s": 0.0}, "envelope_s must be a finite number > 0"),
        ({"envelope_s": float("nan")}, "envelope_s must be a finite number > 0"),
    ],
)
def test_bad_guard_settings_are_refused(change, words):
    with pytest.raises(InvalidConfigError, match=re.escape(words)):
        PredictorSettings(**change)


def _ratio(motion, form, settings):
    end = 120.0
    t = np.arange(0.0, end, MEASURE_STEP_S)
    truth = np.asarray(motion.evaluate(t)[0])
    stream = form.apply(stream_of(motion, 0.2, form.rate_hz, end))
    none = stream_figures(truth, follow(stream, "none").evaluate(t)[0])
    f = follow(stream, "linear", settings)
    mine = stream_figures(truth, f.evaluate(t)[0])
    return mine["rms_translation_m"] / none["rms_translation_m"], f


def test_outliers_taken_out_halve_the_followed_error():
    """Breathing streamed 0.2 s late at 25 Hz with 1 % of its samples 3 mm off (each axis), by
    the regression with 2 s of history: the followed reference against the true motion, over no
    prediction's, is 0.2-0.3 with the outliers taken out and 0.4-0.55 without (measured 0.224
    and 0.449), the first at most 0.6 times the second; the samples replaced are the outliers'
    (about 36 samples' 3 axes, fewer where an offset is within a step)."""
    motion = make_motion("breathing", {})
    form = StreamForm(rate_hz=RATE_HZ, outlier_share=0.01, seed=3)
    guarded, f = _ratio(motion, form, PredictorSettings(history_s=2.0, outlier_k=4.0))
    plain, _ = _ratio(motion, form, PredictorSettings(history_s=2.0))
    assert 0.2 < guarded < 0.3 and 0.4 < plain < 0.55 and guarded < 0.6 * plain
    assert 40 <= f.rejected <= 3 * 40


def test_a_stream_too_large_to_follow_is_refused_before_any_work(monkeypatch):
    """1 kHz for 10 s, 0.2 s late, on a machine with 1 GB free: refused in one line naming the
    samples, the rate, the steps ahead and what to change (the follower would hold about
    1.4 GB: 10,001 arrivals of 204 steps ahead); 25 Hz for 120 s (about 30 MB) is followed."""
    from stewart_drake.base import checks

    monkeypatch.setattr(checks, "available_memory_bytes", lambda: 1e9)
    fast = stream_of(make_motion("breathing", {}), 0.2, 1000.0, 10.0)
    with pytest.raises(InvalidConfigError) as err:
        follow(fast, "linear")
    words = str(err.value)
    assert words.startswith("following breathing's 10001 samples at 1000 Hz, 204 steps ahead: ")
    assert "more than the" in words and words.endswith(
        "lower the stream's rate (--stream-rate) or shorten the run (--duration)"
    )
    slow = stream_of(make_motion("breathing", {}), 0.2, RATE_HZ, 120.0)
    assert follow(slow, "none").stream is slow
