"""The predictors of a streamed motion and the reference that follows it: causality, the
regression against a direct least-squares fit, the fallback to no prediction, the follower's
smoothness and the refusals."""

import numpy as np
import pytest

from stewart_drake.base.errors import InvalidConfigError
from stewart_drake.references.organ.library import make_motion
from stewart_drake.references.prediction import (
    LinearModel,
    OnlinePredictor,
    PredictorSettings,
    check_predictor,
)
from stewart_drake.references.stream import PAST_NODES, Stream, follow, stream_of


def _rms(e):
    return float(np.sqrt(np.mean(np.sum(np.asarray(e) ** 2, axis=-1))))


@pytest.fixture(scope="module")
def breathing_stream():
    """60 s of the library's breathing (15 mm on X, 4 s) at 25 Hz, 0.2 s late."""
    return stream_of(make_motion("breathing", {}), 0.2, 25.0, 60.0), make_motion("breathing", {})


def test_nothing_before_an_arrival_depends_on_it(breathing_stream):
    """Causality: change every sample taken after t_c; the followed reference before t_c + the
    latency is unchanged to the bit, and after it differs."""
    stream, _ = breathing_stream
    t_c = 30.0
    changed = stream.poses.copy()
    later = stream.t > t_c
    changed[later, 3] += 0.003 * np.sin(np.arange(np.count_nonzero(later)))
    a = follow(stream)
    b = follow(Stream(stream.t, changed, stream.latency_s, stream.name))
    t = np.arange(0.0, 60.0, 0.001)
    first_changed = stream.t[later][0] + stream.latency_s
    before = t < first_changed
    for xa, xb in zip(a.evaluate(t), b.evaluate(t)):
        assert np.array_equal(xa[before], xb[before])
    assert np.max(np.abs(a.evaluate(t)[0][~before] - b.evaluate(t)[0][~before])) > 1e-3


def test_linear_model_is_the_weighted_ridge_fit():
    """The streamed regression's prediction equals the exponentially weighted ridge least-squares
    fit written out directly (numpy's lstsq on the stacked, weighted pairs)."""
    rng = np.random.default_rng(1)
    y = np.cumsum(rng.normal(size=(80, 1)), axis=0) * 1e-3
    dt, k_ahead = 0.1, 2
    settings = PredictorSettings(history_s=0.3, memory_s=2.0, ridge=1e-3)
    model = LinearModel(dt, 3, 1, settings)
    out = np.array([model.update(v) for v in y])
    p, lam = model.p, np.exp(-dt / settings.memory_s)
    i = len(y) - 1
    padded = np.concatenate([np.repeat(y[:1], p, 0), y])

    def features(j):
        return np.array([padded[j + p, 0] - padded[j + p - l, 0] for l in range(1, p + 1)])

    js = np.arange(0, i - k_ahead + 1)
    X = np.array([features(j) for j in js])
    Y = y[js + k_ahead, 0] - y[js, 0]
    w = lam ** ((i - k_ahead - js) / 2)
    R = (X * w[:, None] ** 2).T @ X
    delta = settings.ridge * np.trace(R) / p + 1e-30
    A = np.vstack([X * w[:, None], np.sqrt(delta) * np.eye(p)])
    b = np.concatenate([Y * w, np.zeros(p)])
    weights = np.linalg.lstsq(A, b, rcond=None)[0]
    expected = y[i, 0] + features(i) @ weights
    assert out[i, k_ahead - 1, 0] == pytest.approx(expected, rel=1e-9, abs=1e-15)


def test_every_prediction_is_the_weighted_ridge_fit_of_its_step():
    """At every sample and every step ahead, on two axes: the streamed regression (one matrix
    factorised per axis and sample, reused by each step ahead k samples later) equals the
    exponentially weighted ridge fit of the pairs completed so far, written out per step."""
    rng = np.random.default_rng(2)
    y = np.cumsum(rng.normal(size=(60, 2)), axis=0) * 1e-3
    dt, steps = 0.1, 4
    settings = PredictorSettings(history_s=0.4, memory_s=1.5, ridge=1e-2)
    model = LinearModel(dt, steps, 2, settings)
    out = np.array([model.update(v) for v in y])  # (N, K, m)
    p, lam = model.p, np.exp(-dt / settings.memory_s)
    padded = np.concatenate([np.repeat(y[:1], p, 0), y])
    expected = np.empty_like(out)
    for i in range(len(y)):
        for a in range(2):
            x_i = padded[i + p, a] - padded[i + p - np.arange(1, p + 1), a]
            for k in range(1, steps + 1):
                js = np.arange(0, i - k + 1)
                if js.size == 0:
                    expected[i, k - 1, a] = y[i, a]
                    continue
                X = padded[js + p, a, None] - padded[js[:, None] + p - np.arange(1, p + 1), a]
                w = lam ** (i - k - js)
                R = (X * w[:, None]).T @ X
                r = (X * w[:, None]).T @ (y[js + k, a] - y[js, a])
                delta = settings.ridge * np.trace(R) / p + 1e-30
                expected[i, k - 1, a] = y[i, a] + x_i @ np.linalg.solve(R + delta * np.eye(p), r)
    np.testing.assert_allclose(out, expected, rtol=0, atol=1e-14)
    assert np.max(np.abs(out - y[:, None, :])) > 1e-3  # it predicts displacements


def test_linear_predicts_breathing_far_better_than_none(breathing_stream):
    """On the library's breathing 0.2 s late the followed reference is within a fifth of the
    error of following without prediction (after the record's first 10 s)."""
    stream, truth = breathing_stream
    t = np.arange(10.0, 60.0, 0.01)
    x_true = truth.evaluate(t)[0][:, 3:]
    none = _rms(follow(stream, "none").evaluate(t)[0][:, 3:] - x_true)
    linear = _rms(follow(stream, "linear").evaluate(t)[0][:, 3:] - x_true)
    assert none > 1e-3  # 0.2-0.3 s of a 15 mm breath
    assert linear < 0.2 * none


def test_no_worse_than_none_on_white_noise():
    """White noise: the regression learns to pull towards the mean, which beats holding the
    newest sample; the follower is no worse than without prediction."""
    rng = np.random.default_rng(0)
    t = np.arange(0.0, 120.0, 0.04)
    poses = np.zeros((t.size, 6))
    poses[:, 3] = 1e-3 * rng.normal(size=t.size)
    stream = Stream(t, poses, 0.2, "noise")
    grid = np.arange(0.0, 120.0, 0.01)
    truth = np.interp(grid, t, poses[:, 3])  # the motion between samples, as any will do
    followed = {name: follow(stream, name) for name in ("none", "linear")}
    err = {n: _rms((f.evaluate(grid)[0][:, 3] - truth)[:, None]) for n, f in followed.items()}
    assert err["linear"] <= err["none"]


class _Biased:
    """A model that predicts 1 mm too high on X: worse than holding the newest sample."""

    p = 2

    def update(self, y):
        out = np.repeat(np.asarray(y, dtype=float)[None, :], 3, axis=0)
        out[:, 3] += 1e-3
        return out


def test_falls_back_to_none_when_the_model_does_worse():
    """A model worse than no prediction is used only until its record says so (min_record_s):
    from then on the newest sample is held, exactly, and the model is off on that axis."""
    predictor = OnlinePredictor("linear", 0.1, 3, 6, PredictorSettings(min_record_s=1.0))
    predictor.model = _Biased()
    predictor._warm = 0
    t = np.arange(0.0, 20.0, 0.1)
    outputs = []
    for v in np.sin(t):
        y = np.array([0, 0, 0, 0.01 * v, 0, 0])
        outputs.append(predictor.update(y)[:, 3] - y[3])
    outputs = np.array(outputs)
    assert not predictor.using[3]
    assert np.array_equal(outputs[-150:], np.zeros((150, 3)))
    assert predictor.sigma[0, 3] == pytest.approx(
        np.sqrt(np.mean(np.diff(0.01 * np.sin(t))[-100:] ** 2)), rel=0.3
    )


def test_follower_is_c2(breathing_stream):
    """The followed reference's rate and acceleration are the derivatives of its pose (central
    differences at 10 us), blends between arrivals included."""
    stream, _ = breathing_stream
    f = follow(stream)
    t = np.linspace(20.0, 22.0, 997)
    h = 1e-5
    x, v, a = f.evaluate(t)
    xp, vp, _ = f.evaluate(t + h)
    xm, vm, _ = f.evaluate(t - h)
    np.testing.assert_allclose(v, (xp - xm) / (2 * h), atol=1e-6)
    np.testing.assert_allclose(a, (vp - vm) / (2 * h), atol=1e-3)
    assert np.max(np.abs(v[:, 3])) > 5e-3  # it moves


def test_uncertainty_is_the_recent_residual(breathing_stream):
    """sigma at the step ahead nearest the latency is the RMS of the residuals there: the true
    error of the used predictions over the last 10 s is within a factor 2 of it."""
    stream, _ = breathing_stream
    f = follow(stream)
    k = int(round(stream.latency_s / stream.dt))
    used = f.nodes[:, PAST_NODES + k, 3]  # the position k samples ahead
    err = used[:-k] - stream.poses[k:, 3]
    i = stream.t.size - 1 - k
    recent = err[i - 250 : i]
    assert f.sigma[i, k - 1, 3] == pytest.approx(np.sqrt(np.mean(recent**2)), rel=1.0)


@pytest.mark.parametrize("latency", [0.0, -0.1, float("nan"), float("inf"), "soon"])
def test_bad_latency_refused(latency):
    with pytest.raises(InvalidConfigError, match="latency"):
        stream_of(make_motion("breathing", {}), latency, 25.0, 10.0)


def test_unknown_predictor_and_short_stream_refused(breathing_stream):
    stream, _ = breathing_stream
    with pytest.raises(InvalidConfigError, match="unknown predictor 'lstm'.*none, linear"):
        check_predictor("lstm")
    short = Stream(stream.t[:40], stream.poses[:40], 0.2, "short")
    with pytest.raises(InvalidConfigError, match=r"has 40 samples .* needs \d+"):
        follow(short, "linear")
    assert follow(short, "none").end_time == pytest.approx(stream.t[39])


def test_online_predictor_refuses_bad_settings():
    with pytest.raises(InvalidConfigError, match="memory_s"):
        PredictorSettings(memory_s=0.0)
    with pytest.raises(InvalidConfigError, match="dt > 0"):
        OnlinePredictor("linear", 0.0, 3, 6)


def test_the_two_measures_a_at_the_samples_and_b_end_to_end():
    """(a) is the prediction the latency (and the loop's lag) after each sample against the
    newest sample held, written out here; (b) the followed reference, whose no-prediction lags
    a sample step more, so its error without prediction is the larger. With no predictor (a)
    is exactly 1."""
    from stewart_drake.organ_motion.streaming import follow_motion
    from stewart_drake.references.stream import LOOP_LAG_S

    motion = make_motion("breathing", {})
    settings = PredictorSettings(min_record_s=2.0)
    r = follow_motion(motion, 0.2, duration_s=40.0, settings=settings)
    h, followed = r["horizon"], r["followed"]
    horizon = 0.2 + LOOP_LAG_S
    t = followed.stream.t
    keep = t + horizon <= 40.0
    truth = motion.evaluate(t[keep] + horizon)[0][:, 3:]
    held = followed.stream.poses[keep, 3:]
    assert h["none_translation_m"] == pytest.approx(_rms(held - truth), rel=1e-12)
    used = np.where(followed.using, followed.at_horizon(horizon), followed.stream.poses)[keep]
    assert h["rms_translation_m"] == pytest.approx(_rms(used[:, 3:] - truth), rel=1e-12)
    assert h["samples"] == int(np.count_nonzero(keep))
    assert h["ratio"] == pytest.approx(h["rms_translation_m"] / h["none_translation_m"])
    assert h["ratio"] < 0.5 and r["ratio_translation"] < 0.6
    assert r["without"]["rms_translation_m"] > h["none_translation_m"]  # a step more of lag
    none = follow_motion(motion, 0.2, "none", duration_s=40.0, settings=settings)["horizon"]
    assert none["ratio"] == 1.0 and none["nrmse"] == none["nrmse_none"] > 0.3


def test_the_warm_up_ends_where_the_prediction_is_first_followed(breathing_stream):
    """prediction_start is the warm-up's end: before it the linear follower is the follower
    without prediction, and a switch later it is no longer; none and a motion at rest have
    none."""
    from stewart_drake.organ_motion.streaming import prediction_start
    from stewart_drake.references.stream import SWITCH_S

    stream, _ = breathing_stream
    linear, none = follow(stream, "linear"), follow(stream, "none")
    first = prediction_start(linear)
    assert first is not None and 5.0 < first < 10.0  # at least min_record_s of residuals
    t = np.arange(0.0, 30.0, 0.001)
    gap = np.abs(linear.evaluate(t)[0][:, 3] - none.evaluate(t)[0][:, 3])
    assert gap[t < first].max() < 1e-12 and gap[t > first + SWITCH_S].max() > 1e-4
    assert prediction_start(none) is None
    still = Stream(stream.t, np.zeros_like(stream.poses), 0.2, "still")
    assert prediction_start(follow(still, "linear")) is None


def test_the_figures_after_the_warm_up_are_those_of_the_samples_after_it():
    """after_warm_up: the RMS per axis of the logged pose against the true motion from the
    warm-up's end (+ SWITCH_S) to the window's end; None when the warm-up ends before the
    window, or no prediction was followed."""
    from types import SimpleNamespace

    from stewart_drake.organ_motion.streaming import after_warm_up
    from stewart_drake.references.stream import SWITCH_S

    t = np.arange(0.0, 20.0, 0.001)
    x_d = np.zeros((t.size, 18), np.float32)
    x = np.zeros((t.size, 12), np.float32)
    x[:, 3] = np.where(t < 6.0, 2e-3, 1e-5)  # 2 mm before the prediction, 10 um after
    x[:, 1] = 3e-5
    judged = SimpleNamespace(
        fidelity={"window_s": [4.0, 19.999]}, result=SimpleNamespace(t=t, x=x, x_d=x_d)
    )
    later = after_warm_up(judged, 6.0 - SWITCH_S)
    assert later["window_s"] == pytest.approx([6.0, 19.999], abs=1e-9)
    assert later["rms"] == pytest.approx([0, 3e-5, 0, 1e-5, 0, 0], rel=1e-6, abs=1e-12)
    assert after_warm_up(judged, 3.0 - SWITCH_S) is None  # before the window
    assert after_warm_up(judged, None) is None
