"""The predictors of a streamed motion and the reference that follows it: causality, the
regression against a direct least-squares fit, the record (the fallback to no prediction and
the uncertainty) and the followed curves against the same written out here, the figures users
read against the true motion delayed, the follower's smoothness and the refusals. Fast unit
tests only (tools/mutation.py runs them against every mutant of references/prediction.py and
references/stream.py)."""

from dataclasses import replace

import numpy as np
import pytest

from stewart_drake.base.errors import InvalidConfigError
from stewart_drake.references import prediction
from stewart_drake.references.organ.library import make_motion
from stewart_drake.references.prediction import (
    LinearModel,
    OnlinePredictor,
    PredictorSettings,
    check_predictor,
)
from stewart_drake.references.stream import PAST_NODES, Stream, follow, stream_of

#: The settings these tests' figures are written for: 0.5 s of history (12 samples at 25 Hz),
#: no hysteresis, the whole run's envelope (the shipped ones are the selection's choice: the
#: mechanics tested here are the same under them).
PLAIN = PredictorSettings(history_s=0.5, record_margin=0.0, envelope_s=None, min_record_s=5.0)


def _rms(e):
    return float(np.sqrt(np.mean(np.sum(np.asarray(e) ** 2, axis=-1))))


def _record_written_out(predicted, y, warm, min_n, mu, margin=0.0):
    """The predictor's record written out as weighted sums (not its recursion): the predictions
    ``predicted`` (N, K, m) made at each sample of ``y`` (N, m); the residual of the prediction
    k ahead made at sample j - k counts at sample j when j - k >= ``warm``, weighted mu^(i - j)
    at sample i. Returns (using (N, m), sigma (N, K, m)): the model chosen where it has
    ``min_n`` residuals k = K ahead and its summed weighted squares are below the held
    sample's, times 1 - ``margin`` where it was not chosen at the sample before (the
    hysteresis), or not above them where the held sample's weighted mean square over the steps
    ahead is within (1 um)^2 (at rest); sigma the weighted RMS residual of what is chosen (NaN
    before any)."""
    N, K, m = predicted.shape
    r2 = np.zeros((2, N, K, m))
    ready = np.zeros((N, K))
    for k in range(1, K + 1):
        j = np.arange(warm + k, N)
        r2[0, j, k - 1] = (predicted[j - k, k - 1] - y[j]) ** 2
        r2[1, j, k - 1] = (y[j - k] - y[j]) ** 2
        ready[j, k - 1] = 1.0
    i = np.arange(N)
    W = np.tril(mu ** (i[:, None] - i[None, :]).astype(float))  # (N, N) mu^(i - j), j <= i
    se = np.einsum("ij,sjkm->sikm", W, r2)
    w = W @ ready  # (N, K)
    count = np.cumsum(ready[:, -1])
    model, none = se[0].sum(axis=1), se[1].sum(axis=1)  # (N, m)
    using = np.zeros(model.shape, dtype=bool)
    for j in range(N):
        before = using[j - 1] if j else np.zeros(model.shape[1], dtype=bool)
        better = model[j] < np.where(before, 1.0, 1.0 - margin) * none[j]
        at_rest = (none[j] <= 1e-12 * w[j].sum()) & (model[j] <= none[j])
        using[j] = (count[j] >= min_n) & (better | at_rest)
    with np.errstate(invalid="ignore"):
        mse = se / w[None, :, :, None]
    return using, np.sqrt(np.where(using[:, None, :], mse[0], mse[1]))


def _clipped_written_out(predicted, y, block=None, blocks=None):
    """``predicted`` (N, K, m) clipped to the range of ``y`` (N, m) up to each sample, widened
    by a tenth of it; and how many positions that moved. With ``blocks``: the range of the
    samples from the start of the ``blocks``-th block of ``block`` samples before the one
    sample i is in."""
    if blocks is None:
        low, high = np.minimum.accumulate(y), np.maximum.accumulate(y)
    else:
        first = [max(0, (i // block - blocks) * block) for i in range(len(y))]
        low = np.array([y[f : i + 1].min(axis=0) for i, f in enumerate(first)])
        high = np.array([y[f : i + 1].max(axis=0) for i, f in enumerate(first)])
    margin = 0.1 * (high - low)
    out = np.clip(predicted, (low - margin)[:, None, :], (high + margin)[:, None, :])
    return out, int(np.count_nonzero(out != predicted))


def _smoothstep(x):
    x = np.clip(x, 0.0, 1.0)
    return 10 * x**3 - 15 * x**4 + 6 * x**5


def _followed_written_out(f, t):
    """(M, 6) the pose of the followed reference ``f`` at times ``t`` (M,), written out from its
    arrays: in [a_i, a_i+1) (a: the arrivals) the curves of arrivals i - 1 and i blended by the
    quintic smoothstep over the sample step, each a not-a-knot cubic (scipy) through its nodes:
    the predicted one read at t + loop lag - t_i (held at its last node beyond it), the held one
    (the past nodes and the newest) a latency and a step later. Each axis weighs the predicted
    curve by u, moved by the smoothstep over 1 s from each arrival where the record's choice
    differs from where u is heading, once the move before has ended. The first sample before
    the first arrival."""
    from scipy.interpolate import CubicSpline

    s, dt = f.stream, f.stream.dt
    tau = (np.arange(f.nodes.shape[1]) - PAST_NODES) * dt
    moves = []
    for axis in range(6):
        heading, free = False, -np.inf
        for a, use in zip(s.arrival, f.using[:, axis]):
            if use != heading and a >= free:
                heading, free = use, a + 1.0
                moves.append((a, axis, 1.0 if use else -1.0))
    i = np.searchsorted(s.arrival, t, side="right") - 1
    x = np.empty((t.size, 6))
    for m, (tm, im) in enumerate(zip(t, i)):
        if im < 0:
            x[m] = s.poses[0]
            continue
        p, h = [], []
        for j in (max(im - 1, 0), im):
            ahead = tm + f.loop_lag_s - s.t[j]
            p.append(CubicSpline(tau, f.nodes[j])(min(ahead, tau[-1])))
            held = CubicSpline(tau[: PAST_NODES + 1], f.nodes[j, : PAST_NODES + 1])
            h.append(held(ahead - s.latency_s - dt))
        w = _smoothstep((tm - s.arrival[im]) / dt) if im > 0 else 1.0
        u = np.zeros(6)
        for a, axis, direction in moves:
            u[axis] += direction * _smoothstep(tm - a)
        p_m, h_m = p[0] + w * (p[1] - p[0]), h[0] + w * (h[1] - h[0])
        x[m] = h_m + u * (p_m - h_m)
    return x


class _Scripted:
    """A model whose predictions are given: row i of ``rows`` (N, K, m) at its i-th sample."""

    def __init__(self, rows):
        self.rows, self.i = rows, 0

    def update(self, y):
        self.i += 1
        return self.rows[self.i - 1].copy()


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


@pytest.mark.parametrize(("steps", "max_lags", "stride"), [(1, 64, 1), (4, 64, 1), (2, 3, 2)])
def test_every_prediction_is_the_weighted_ridge_fit_of_its_step(
    steps, max_lags, stride, monkeypatch
):
    """At every sample and every step ahead, on two axes: the streamed regression (one matrix
    factorised per axis and sample, reused by each step ahead k samples later) equals the
    exponentially weighted ridge fit of the pairs completed so far, written out per step; one
    step ahead (the fewest) or four; and with a history longer than the most displacements read
    (6 samples, at most 3 read: every second sample, y_i - y_{i-2l})."""
    monkeypatch.setattr(prediction, "MAX_LAGS", max_lags)
    rng = np.random.default_rng(2)
    y = np.cumsum(rng.normal(size=(60, 2)), axis=0) * 1e-3
    dt = 0.1
    settings = PredictorSettings(history_s=0.4 if stride == 1 else 0.6, memory_s=1.5, ridge=1e-2)
    model = LinearModel(dt, steps, 2, settings)
    assert (model.p, model.stride) == ((4, 1) if stride == 1 else (3, 2))
    out = np.array([model.update(v) for v in y])  # (N, K, m)
    p, lam = model.p, np.exp(-dt / settings.memory_s)
    lags = stride * np.arange(1, p + 1)
    pad = p * stride
    padded = np.concatenate([np.repeat(y[:1], pad, 0), y])
    expected = np.empty_like(out)
    for i in range(len(y)):
        for a in range(2):
            x_i = padded[i + pad, a] - padded[i + pad - lags, a]
            for k in range(1, steps + 1):
                js = np.arange(0, i - k + 1)
                if js.size == 0:
                    expected[i, k - 1, a] = y[i, a]
                    continue
                X = padded[js + pad, a, None] - padded[js[:, None] + pad - lags, a]
                w = lam ** (i - k - js)
                R = (X * w[:, None]).T @ X
                r = (X * w[:, None]).T @ (y[js + k, a] - y[js, a])
                delta = settings.ridge * np.trace(R) / p + 1e-30
                expected[i, k - 1, a] = y[i, a] + x_i @ np.linalg.solve(R + delta * np.eye(p), r)
    np.testing.assert_allclose(out, expected, rtol=0, atol=1e-14)
    assert np.max(np.abs(out - y[:, None, :])) > 1e-3  # it predicts displacements


def test_linear_predicts_breathing_far_better_than_none(breathing_stream):
    """On the library's breathing 0.2 s late (after the record's first 10 s): without prediction
    the followed reference is the motion a latency and a sample step late, less the loop's lag
    (its error that of the motion delayed so, to 1e-4); with the regression on 2 s of history,
    the error is 0.5 % to 5 % of that (1.9 % measured; the shipped 4 s, 5.2 % over this first
    minute: it has twice the weights to learn)."""
    from stewart_drake.references.stream import LOOP_LAG_S

    stream, truth = breathing_stream
    t = np.arange(10.0, 60.0, 0.01)
    x_true = truth.evaluate(t)[0][:, 3:]
    none = _rms(follow(stream, "none").evaluate(t)[0][:, 3:] - x_true)
    linear = _rms(
        follow(stream, "linear", PredictorSettings(history_s=2.0)).evaluate(t)[0][:, 3:] - x_true
    )
    late = truth.evaluate(t - (stream.latency_s + stream.dt - LOOP_LAG_S))[0][:, 3:]
    assert none == pytest.approx(_rms(late - x_true), rel=1e-4)
    assert 0.005 * none < linear < 0.05 * none


def test_no_worse_than_none_on_white_noise():
    """White noise: the regression learns to pull towards the mean, which beats holding the
    newest sample: the follower's error is near that of following the mean itself (the RMS of
    the motion, the least any predictor of white noise can expect), and well below that of
    following without prediction."""
    rng = np.random.default_rng(0)
    t = np.arange(0.0, 120.0, 0.04)
    poses = np.zeros((t.size, 6))
    poses[:, 3] = 1e-3 * rng.normal(size=t.size)
    stream = Stream(t, poses, 0.2, "noise")
    grid = np.arange(0.0, 120.0, 0.01)
    truth = np.interp(grid, t, poses[:, 3])  # the motion between samples, as any will do
    followed = {name: follow(stream, name) for name in ("none", "linear")}
    err = {n: _rms((f.evaluate(grid)[0][:, 3] - truth)[:, None]) for n, f in followed.items()}
    mean = _rms(truth[:, None])  # the error of following the mean, 0
    assert 0.95 * mean < err["linear"] < 1.25 * mean
    assert err["none"] > 1.5 * err["linear"]
    assert followed["linear"].using[-1, 3] and not followed["none"].using.any()


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


@pytest.mark.parametrize(
    "K, min_record_s, margin, envelope_s",
    [(3, 0.1, 0.0, None), (3, 1.0, 0.0, None), (1, 0.5, 0.0, None), (3, 0.1, 0.6, 2.0),
     (2, 0.5, 0.3, 0.7)],
)  # fmt: skip
def test_the_record_chooses_and_measures_as_its_weighted_sums_say(
    K, min_record_s, margin, envelope_s
):
    """Given a model's predictions, at every sample: the positions returned (the model's clipped
    to the range so far plus a tenth, on the axes where its record is better; the newest sample
    on the others), which axes use it, and sigma, the weighted RMS residual of what is used,
    equal the record written out as sums (not the predictor's recursion). Axes: a model better
    than holding the newest sample, one worse by a bias, one at rest (equal records of zero:
    taken up, it moves nothing), one whose predictions overshoot and are clipped. The record
    starts once the model's first pairs are complete (history 2 samples + K), and the model is
    chosen only after
    min_record_s of residuals K ahead (1, 10 or 5 samples). K = 1 is the fewest steps ahead.
    With a hysteresis (``record_margin``) the model is taken up only once its record beats the
    held sample's by that share, and dropped (a fallback, counted) as soon as it does not beat
    it; with ``envelope_s`` the range is that of the blocks of a second (10 samples) kept.
    Without the bound and the shrinkage (tests/test_predictors.py writes them out)."""
    dt = 0.1
    settings = PredictorSettings(
        history_s=0.2,
        record_s=2.0,
        min_record_s=min_record_s,
        shrink=False,
        bound_s=None,
        record_margin=margin,
        envelope_s=envelope_s,
    )
    t = np.arange(80) * dt
    y = np.column_stack([0.01 * np.sin(t), 0.01 * np.cos(t), np.zeros_like(t), 0.01 * np.sin(t)])
    k = np.arange(1, K + 1)[None, :, None]
    future = np.column_stack([0.01 * np.sin(t[:, None] + k[..., 0] * dt)])  # (N, K)
    rows = np.repeat(y[:, None, :], K, axis=1)
    rows[:, :, 0] = future + 1e-5 * np.sin(7 * t)[:, None]  # nearly the truth
    rows[:, :, 1] += 5e-3 * k[..., 0]  # biased
    rows[:, :, 3] += 0.05  # beyond the motion's range
    predictor = OnlinePredictor("linear", dt, K, 4, settings)
    assert predictor.sigma.shape == (K, 4) and np.all(np.isnan(predictor.sigma))
    assert predictor.using.dtype == bool and not predictor.using.any()  # before any sample
    predictor.model = _Scripted(rows)
    blocks = None if envelope_s is None else int(np.ceil(envelope_s / 1.0))
    clipped, moved = _clipped_written_out(rows, y, 10, blocks)
    min_n = max(1, round(min_record_s / dt))
    using, sigma = _record_written_out(clipped, y, 2 + K, min_n, np.exp(-dt / 2.0), margin)
    for i, v in enumerate(y):
        out = predictor.update(v)
        np.testing.assert_array_equal(predictor.using, using[i], err_msg=f"sample {i}")
        np.testing.assert_allclose(predictor.sigma, sigma[i], rtol=1e-12, atol=0, equal_nan=True)
        np.testing.assert_array_equal(out, np.where(using[i], clipped[i], v))
    assert predictor.clipped == moved > 0
    assert predictor.fallbacks == int(np.count_nonzero(using[:-1] & ~using[1:]))
    first = int(np.argmax(using[:, 0]))  # when the better model is first chosen
    assert using[-1].tolist() == [True, False, True, False]
    if margin == 0.0:
        assert first == 2 + 2 * K - 1 + min_n
    assert np.isnan(sigma[2 + K]).all() and np.isfinite(sigma[2 + K + 1, 0]).all()


@pytest.mark.parametrize(("rms", "taken_up"), [(0.9e-6, True), (1.1e-6, False)])
def test_a_model_that_ties_with_no_prediction_is_taken_up_only_at_rest(rms, taken_up):
    """A model whose predictions are exactly no prediction's (the newest sample held) on a
    motion of tiny steps: taken up where no prediction's RMS residual is within 1 um (at rest,
    where it moves nothing and is in use when the motion starts), not where it is above, with
    or without the hysteresis. The residual of the held sample k ahead is k times the step, so
    the step is set for the record's RMS over k = 1..K (weights equal once the record is
    long) to be ``rms``."""
    dt, K, N = 0.1, 3, 200
    step = rms / np.sqrt(np.mean(np.arange(1, K + 1) ** 2))
    y = (step * np.arange(N))[:, None]
    for margin in (0.0, 0.1):
        settings = PredictorSettings(
            history_s=0.2, record_s=2.0, min_record_s=0.5, shrink=False, bound_s=None,
            envelope_s=None, record_margin=margin,
        )  # fmt: skip
        predictor = OnlinePredictor("linear", dt, K, 1, settings)
        predictor.model = _Scripted(np.repeat(y[:, None, :], K, axis=1))
        for v in y:
            predictor.update(v)
        assert bool(predictor.using[0]) is taken_up
        assert predictor.sigma[:, 0] == pytest.approx(step * np.arange(1, K + 1), rel=1e-9)


def test_no_prediction_holds_the_newest_sample_with_its_record_from_the_start():
    """The predictor "none": every step ahead is the newest sample, never chosen as a
    prediction, and sigma is the weighted RMS of the held sample's residuals from the first
    pair on (no warm-up)."""
    dt, K = 0.1, 2
    y = 0.01 * np.column_stack([np.sin(np.arange(30) * dt), np.zeros(30)])
    predictor = OnlinePredictor("none", dt, K, 2, PredictorSettings(record_s=1.0))
    raw = np.array([predictor.raw_update(v) for v in y])
    np.testing.assert_array_equal(raw, np.repeat(y[:, None, :], K, axis=1))
    _, sigma = _record_written_out(raw, y, 0, 1, np.exp(-dt / 1.0))
    np.testing.assert_allclose(predictor.sigma, sigma[-1], rtol=1e-12, atol=0)
    assert not predictor.using.any() and predictor.clipped == 0 and np.isfinite(sigma[1, 0, 0])


class _NotPositiveDefinite:
    """LAPACK's Cholesky reporting a matrix not positive definite (info 1)."""

    @staticmethod
    def dpotrf(a, lower, clean):
        return np.zeros_like(a), 1

    @staticmethod
    def dtrtri(c, lower, overwrite_c):
        raise AssertionError("not called when the factorisation failed")


def test_an_axis_whose_sums_do_not_factorise_is_not_predicted():
    """When the normal equations are not positive definite to rounding, the axis predicts no
    displacement: the newest sample at every step ahead."""
    model = LinearModel(0.1, 3, 2, PredictorSettings(history_s=0.2))
    model._lapack = _NotPositiveDefinite()
    for v in np.linspace(0.0, 0.01, 20):
        out = model.update([v, -v])
    np.testing.assert_array_equal(out, np.repeat([[0.01, -0.01]], 3, axis=0))


def test_the_settings_in_samples():
    """History, records and the samples a stream needs, in samples at a step, as the settings'
    docstring defines them."""
    s = PredictorSettings(history_s=0.5)
    assert s.lags(0.01) == 50 and s.lags(0.04) == 12 and s.lags(1.0) == 2  # at least 2
    assert PredictorSettings(history_s=0.1).lags(0.04) == 2  # round(2.5) = 2
    assert PredictorSettings(history_s=2.0).lags(1 / 30) == 60
    # At most MAX_LAGS (64): 200 samples read every 4th (the fewest strides within 64), 50.
    assert PredictorSettings(history_s=2.0).lag_stride(0.01) == 4
    assert PredictorSettings(history_s=2.0).lags(0.01) == 50
    assert PredictorSettings(history_s=0.64).lags(0.01) == 64  # 64 samples: all of them
    assert PredictorSettings(history_s=0.64).lag_stride(0.01) == 1
    assert PredictorSettings(history_s=0.7).lag_stride(0.01) == 2  # 70: every second, 35
    assert PredictorSettings(history_s=0.7).lags(0.01) == 35
    assert (
        PredictorSettings(history_s=4.0, min_record_s=5.0).samples_needed(0.04, 5)
        == 2 * 50 + 5 + 125
    )
    assert PredictorSettings(history_s=4.0).samples_needed(0.04, 5) == 2 * 50 + 5 + 50  # 2 s
    assert s.samples_needed(0.04, 8) == 12 + 8 + 50  # the shipped 2 s of record
    assert replace(PLAIN, min_record_s=0.01).samples_needed(0.04, 8) == 12 + 8 + 1
    assert PredictorSettings(ridge=0.0).ridge == 0.0  # no ridge is allowed
    with pytest.raises(InvalidConfigError, match=r"ridge must be a finite number >= 0, got -1e-09"):
        PredictorSettings(ridge=-1e-9)
    with pytest.raises(InvalidConfigError, match=r"memory_s must be a finite number > 0, got 0.0"):
        PredictorSettings(memory_s=0.0)


@pytest.mark.parametrize("predictor", ["linear", "none"])
def test_the_followed_pose_is_its_curves_written_out(breathing_stream, predictor):
    """At 340 random instants over the minute (the first arrivals, the model's switch on X at
    6.4 s and its 1 s move included), the followed pose equals its curves written out from the
    follower's nodes and record (scipy's splines, the smoothstep): the predicted curve where
    the record chose it, the held one a latency and a step behind where it did not."""
    stream, _ = breathing_stream
    settings = PredictorSettings(memory_s=20.0)
    f = follow(stream, predictor, settings)
    rng = np.random.default_rng(5)
    t = np.sort(
        np.concatenate(
            [rng.uniform(0.0, 60.0, 240), rng.uniform(6.3, 7.5, 60), rng.uniform(0.1, 0.5, 40)]
        )
    )
    np.testing.assert_allclose(f.evaluate(t)[0], _followed_written_out(f, t), rtol=0, atol=1e-12)
    assert f.using.dtype == bool and f.using[:, 3].any() == (predictor == "linear")
    assert f.predictor == predictor and f.settings is settings


@pytest.mark.parametrize("predictor", ["linear", "none"])
def test_a_motion_moving_from_its_first_sample_is_followed_from_its_first_arrivals(predictor):
    """A motion already moving at its first sample (the library's start smoothly): over its
    first arrivals the followed pose is its curves written out, and its rate and acceleration
    the derivatives of its pose (central differences at 10 us)."""
    t = np.arange(0.0, 8.0, 0.04)
    poses = np.zeros((t.size, 6))
    poses[:, 3] = 0.005 * np.sin(1.5 * t + 1.0)
    poses[:, 1] = 0.02 * np.cos(1.1 * t)
    f = follow(Stream(t, poses, 0.2, "moving"), predictor, PredictorSettings(min_record_s=1.0))
    instants = np.sort(np.random.default_rng(6).uniform(0.0, 0.6, 60))
    np.testing.assert_allclose(
        f.evaluate(instants)[0], _followed_written_out(f, instants), rtol=0, atol=1e-12
    )
    grid, h = np.linspace(0.21, 0.6, 97), 1e-5
    x, v, a = f.evaluate(grid)
    xp, vp, _ = f.evaluate(grid + h)
    xm, vm, _ = f.evaluate(grid - h)
    np.testing.assert_allclose(v, (xp - xm) / (2 * h), rtol=0, atol=1e-8)
    np.testing.assert_allclose(a, (vp - vm) / (2 * h), rtol=0, atol=2e-4)
    assert np.abs(v[:, 3]).max() > 1e-3


def test_the_followed_reference_at_rest_before_and_held_after_its_nodes(breathing_stream):
    """Before the first sample arrives: the first sample, at rest. Long after the last one
    (the predicted curve's last node passed): the predicted axis holds its last node, at rest
    (the robot is not sent on along the cubic). A time of any shape gives poses of its shape."""
    stream, _ = breathing_stream
    f = follow(stream)
    x, v, a = f.evaluate(np.array([0.0, 0.1, stream.latency_s - 1e-9]))
    np.testing.assert_array_equal(x, np.repeat(stream.poses[:1], 3, axis=0))
    assert not v.any() and not a.any()
    late = stream.arrival[-1] + 0.5  # 0.7 s after the last sample: its nodes end at K steps
    x, v, a = f.evaluate(late)
    assert x.shape == v.shape == a.shape == (6,) and f.using[-1, 3]
    assert x[3] == pytest.approx(f.nodes[-1, -1, 3], abs=1e-15)
    assert abs(v[3]) < 1e-15 and abs(a[3]) < 1e-12
    np.testing.assert_allclose(f.at_horizon(1.0), f.nodes[:, -1], rtol=0, atol=1e-15)
    assert f.evaluate(np.full((2, 3), 30.0))[0].shape == (2, 3, 6)


@pytest.mark.parametrize("switch_s", [1.0, 0.5])
def test_follower_is_c2(breathing_stream, monkeypatch, switch_s):
    """The followed reference's rate and acceleration are the derivatives of its pose (central
    differences at 10 us), blends between arrivals included, and through the model's switch on
    X at 6.4 s, the weights' move lasting 1 s (the shipped SWITCH_S) or 0.5 s."""
    from stewart_drake.references import stream as stream_module

    monkeypatch.setattr(stream_module, "SWITCH_S", switch_s)
    stream, _ = breathing_stream
    f = follow(stream, "linear", PLAIN)
    # X's switch; the axes at rest are taken up at the same arrival (their records tie at 0).
    assert [s for s in f.switches.tolist() if s[1] == 3.0] == [[6.36, 3.0, 1.0]]
    assert sorted(f.switches.tolist()) == [[6.36, float(a), 1.0] for a in range(6)]
    h = 1e-5
    for t in (np.linspace(20.0, 22.0, 997), np.linspace(6.2, 7.6, 997), np.linspace(0.2, 0.6, 97)):
        x, v, a = f.evaluate(t)
        xp, vp, _ = f.evaluate(t + h)
        xm, vm, _ = f.evaluate(t - h)
        np.testing.assert_allclose(v, (xp - xm) / (2 * h), rtol=0, atol=1e-8)
        np.testing.assert_allclose(a, (vp - vm) / (2 * h), rtol=0, atol=2e-4)
        assert np.max(np.abs(v[:, 3])) > 1e-4  # it moves
    # The smoothstep 10 s^3 - 15 s^4 + 6 s^5 at s = 1/4, 1/2, 1 of the move.
    u, du, ddu = f.weights(6.36 + switch_s * np.array([0.25, 0.5, 1.0]))
    np.testing.assert_allclose(u[:, 3], [0.103515625, 0.5, 1.0], rtol=1e-12)
    np.testing.assert_allclose(du[:, 3], np.array([1.0546875, 1.875, 0.0]) / switch_s, atol=1e-12)
    np.testing.assert_allclose(ddu[:, 3], np.array([5.625, 0.0, 0.0]) / switch_s**2, atol=1e-9)
    # The axes at rest move with X (their records tie at 0 from the same arrival).
    np.testing.assert_allclose(u, np.repeat(u[:, 3:4], 6, axis=1), rtol=0, atol=0)


def test_uncertainty_is_the_weighted_rms_of_the_residuals_used(breathing_stream):
    """On the library's breathing, at every arrival and step ahead: sigma, and the axes whose
    predictions are used, are the record written out on the follower's own predictions (the
    nodes ahead of the newest sample): the exponentially weighted (10 s) RMS residual of what
    is used, from the end of the regression's first pairs (12 samples of history + K) and once
    5 s (125 samples) of residuals K ahead are in. Only X moves; it is predicted at the end, and
    the axes at rest are taken up (a tie at rest)."""
    stream, _ = breathing_stream
    f = follow(stream, "linear", PLAIN)
    K = f.sigma.shape[1]
    ahead = f.nodes[:, PAST_NODES + 1 :]
    using, sigma = _record_written_out(ahead, stream.poses, 12 + K, 125, np.exp(-0.04 / 10.0))
    np.testing.assert_array_equal(f.using, using)
    np.testing.assert_allclose(f.sigma, sigma, rtol=1e-9, atol=0, equal_nan=True)
    assert using[-1].tolist() == [True] * 6  # X, and the axes at rest (their records tie at 0)
    assert 1e-6 < sigma[-1, K - 1, 3] < 1e-3


@pytest.mark.parametrize("latency", [0.0, -0.1, float("nan"), float("inf"), "soon"])
def test_bad_latency_refused(latency):
    with pytest.raises(InvalidConfigError, match="latency"):
        stream_of(make_motion("breathing", {}), latency, 25.0, 10.0)


def test_unknown_predictor_and_short_stream_refused(breathing_stream):
    """A stream shorter than the predictor needs is refused naming both lengths: at 25 Hz and
    0.2 s late, K = 9 steps ahead, 12 samples of history and 5 s (125 samples) of record: 146
    samples, 5.8 s. No prediction needs 3 samples."""
    stream, _ = breathing_stream
    with pytest.raises(InvalidConfigError, match="unknown predictor 'lstm'.*none, linear"):
        check_predictor("lstm")
    assert (
        follow(Stream(stream.t[:146], stream.poses[:146], 0.2, "b"), "linear", PLAIN).sigma.shape[1]
        == 9
    )
    short = Stream(stream.t[:145], stream.poses[:145], 0.2, "short")
    message = r"^the stream of short has 145 samples \(5.76 s\): the linear predictor needs 146 "
    with pytest.raises(InvalidConfigError, match=message + r"\(5.8 s at 25 Hz\) before it can"):
        follow(short, "linear", PLAIN)
    assert follow(short, "none").end_time == pytest.approx(stream.t[144])
    assert follow(Stream(stream.t[:3], stream.poses[:3], 0.2, "three"), "none").end_time == 0.08
    with pytest.raises(InvalidConfigError, match="has 2 samples .* needs 3"):
        follow(Stream(stream.t[:2], stream.poses[:2], 0.2, "two"), "none")


def test_the_steps_ahead_cover_the_latency_the_lag_a_step_and_the_blend():
    """K = ceil((latency + loop lag + a step + the blend) / step) + 1: the follower's curve
    reaches past where it is read until the next arrival's is blended in."""
    from stewart_drake.references.stream import follower_steps

    assert follower_steps(0.2, 0.04, 5e-5, 0.04) == 9  # 7.00125 -> 8, + 1
    assert follower_steps(0.2, 0.04, 0.0, 0.04) == 8  # exactly 7 -> 7, + 1
    assert follower_steps(0.05, 0.01, 0.0, 0.005) == 8  # 6.5 -> 7, + 1


@pytest.mark.parametrize(
    "change, words",
    [
        ({"loop_lag_s": -1e-3}, "loop_lag_s must be in"),
        ({"loop_lag_s": 1.0}, "loop_lag_s must be in"),
        ({"loop_lag_s": 1.5}, "loop_lag_s must be in"),
        ({"loop_lag_s": float("nan")}, "loop_lag_s must be in"),
        ({"blend_s": float("nan")}, "loop_lag_s must be in"),
        ({"blend_s": 0.0}, "blend_s must be > 0 s, got 0.0"),
        ({"blend_s": -0.1}, "blend_s must be > 0"),
    ],
)
def test_the_follower_refuses_a_bad_lag_or_blend(breathing_stream, change, words):
    with pytest.raises(InvalidConfigError, match=words):
        follow(breathing_stream[0], "none", **change)


def test_the_follower_takes_no_loop_lag(breathing_stream):
    """A loop lag of 0 is allowed: the predicted curve is read at the arrival's own time."""
    stream, _ = breathing_stream
    f = follow(stream, "linear", loop_lag_s=0.0)
    t = np.array([30.0, 45.5])
    np.testing.assert_allclose(f.evaluate(t)[0], _followed_written_out(f, t), rtol=0, atol=1e-12)


def test_a_stream_of_a_motion_is_its_samples_from_0_s(breathing_stream):
    """A library motion streamed: its samples every 1 / rate from 0 s to the duration, taken
    from the motion itself, named after it; the rate in (0, 1000] Hz, at least 3 samples,
    and the latency in (0, 10] s."""
    from stewart_drake.references.stream import check_latency

    motion = make_motion("breathing", {})
    s = stream_of(motion, 0.2, 25.0, 2.0)
    np.testing.assert_array_equal(s.t, np.arange(51) * 0.04)
    np.testing.assert_array_equal(s.poses, motion.evaluate(s.t)[0])
    assert s.name == "breathing" and s.latency_s == 0.2 and s.dt == pytest.approx(0.04)
    assert stream_of(make_motion("breathing", {}), 0.2, 1000.0, 0.002).t.size == 3
    assert stream_of(make_motion("breathing", {}), 0.2, 0.5, 4.0).t.tolist() == [0.0, 2.0, 4.0]

    class Unnamed:
        def evaluate(self, t):
            return (np.zeros(np.shape(t) + (6,)),)

    assert stream_of(Unnamed(), 0.2, 25.0, 1.0).name == "stream"
    for rate in (0.0, 1000.5, 2000.0, float("nan")):
        with pytest.raises(InvalidConfigError, match=r"rate must be in \(0, 1000\] Hz"):
            stream_of(motion, 0.2, rate, 10.0)
    with pytest.raises(InvalidConfigError, match="has 2 samples: at least 3"):
        stream_of(motion, 0.2, 25.0, 0.05)
    assert check_latency(10.0) == 10.0 and check_latency("0.2") == 0.2
    with pytest.raises(InvalidConfigError, match=r"in \(0, 10\] s, got 10.5"):
        check_latency(10.5)


def test_the_weights_move_once_a_move_has_ended():
    """Each axis's weight moves towards the record's choice at the arrival where it differs
    from where the weight is heading, and not again until the move has ended (1 s here): a
    choice that flickers meanwhile is ignored; one that holds past the end is followed, at the
    first arrival after it (or at its end exactly)."""
    from stewart_drake.references.stream import _switches

    arrival = np.arange(8) * 0.5  # 0, 0.5, ..., 3.5 s
    using = np.zeros((8, 6), dtype=bool)
    using[1:, 0] = True  # on at 0.5 s, for good
    # On at 0.5; off from 1.0: followed at 1.5, the move's end; on at 2.0 (moving) and 2.5: at
    # 2.5; off from 3.0: at 3.5.
    using[[1, 4, 5], 1] = True
    using[2, 2] = True  # on at 1.0 s; off from 1.5 (moving): at 2.0
    moves = _switches(arrival, using, 1.0).tolist()
    assert moves == [[0.5, 0, 1.0], [0.5, 1, 1.0], [1.5, 1, -1.0], [2.5, 1, 1.0], [3.5, 1, -1.0],
                     [1.0, 2, 1.0], [2.0, 2, -1.0]]  # fmt: skip
    assert _switches(arrival, np.zeros((8, 6), dtype=bool), 1.0).shape == (0, 3)


def test_online_predictor_refuses_bad_settings():
    with pytest.raises(InvalidConfigError, match="memory_s"):
        PredictorSettings(memory_s=0.0)
    with pytest.raises(InvalidConfigError, match="dt > 0"):
        OnlinePredictor("linear", 0.0, 3, 6)


def test_the_two_measures_a_at_the_samples_and_b_end_to_end():
    """(a) is the prediction the latency (and the loop's lag) after each sample against the
    newest sample held, written out here from the follower's arrays: the not-a-knot cubic
    through each arrival's nodes (scipy) read at the horizon, used where the record written out
    chooses it; over the whole 40 s, the 2 s of residuals before the model may be used
    included. (b) the followed reference, whose no-prediction lags a sample step more: the
    true motion delayed by the latency and a step (less the loop's lag) is its error. With no
    predictor (a) is exactly 1."""
    from scipy.interpolate import CubicSpline

    from stewart_drake.organ_motion.streaming import follow_motion
    from stewart_drake.references.stream import LOOP_LAG_S

    motion = make_motion("breathing", {})
    settings = replace(PLAIN, min_record_s=2.0)
    r = follow_motion(motion, 0.2, duration_s=40.0, settings=settings)
    h, followed = r["horizon"], r["followed"]
    horizon, dt = 0.2 + LOOP_LAG_S, 0.04
    t, y = followed.stream.t, followed.stream.poses
    n = followed.nodes.shape[1]
    K = n - PAST_NODES - 1
    tau = (np.arange(n) - PAST_NODES) * dt
    model = CubicSpline(tau, np.moveaxis(followed.nodes, 1, 0), axis=0)(horizon)  # (N, 6)
    mu = np.exp(-dt / 10.0)
    using, _ = _record_written_out(followed.nodes[:, PAST_NODES + 1 :], y, 12 + K, 50, mu)
    used = np.where(using, model, y)
    keep = t + horizon <= 40.0
    truth = motion.evaluate(t[keep] + horizon)[0][:, 3:]
    held, predicted = _rms(y[keep, 3:] - truth), _rms(used[keep, 3:] - truth)
    assert h["none_translation_m"] == pytest.approx(held, rel=1e-12)
    assert h["model_translation_m"] == pytest.approx(_rms(model[keep, 3:] - truth), rel=1e-9)
    assert h["rms_translation_m"] == pytest.approx(predicted, rel=1e-9)
    assert h["ratio"] == pytest.approx(predicted / held, rel=1e-9)
    assert h["samples"] == int(np.count_nonzero(keep))
    # The model's first choice: the pairs of 12 + K samples, then 2 s (50 samples) K ahead.
    assert np.argmax(using[:, 3]) == 12 + 2 * K + 49 and 0.25 < h["ratio"] < 0.4
    # (b) without prediction: the motion a latency, a step and less the loop's lag late.
    grid = np.arange(0.0, 40.0, 0.01)
    late = motion.evaluate(grid - (0.2 + dt - LOOP_LAG_S))[0][:, 3:]
    lag_error = _rms(late - motion.evaluate(grid)[0][:, 3:])
    assert r["without"]["rms_translation_m"] == pytest.approx(lag_error, rel=1e-4)
    assert r["without"]["rms_translation_m"] > h["none_translation_m"]  # a step more of lag
    assert r["ratio_translation"] == pytest.approx(
        r["with"]["rms_translation_m"] / r["without"]["rms_translation_m"], rel=1e-12
    )
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
