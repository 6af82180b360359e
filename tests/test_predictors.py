"""The field's predictors beside the plain regression (wLMS, MULIN, the Kalman filter on a
breathing model) and what every predictor is wrapped in (the bound on the displacement and the
shrinkage): each against a computation written out here, never against its own figures;
causality; the fallback to no prediction. Fast unit tests only."""

import math

import numpy as np
import pytest

from stewart_drake.base.errors import InvalidConfigError
from stewart_drake.references import predictors
from stewart_drake.references.prediction import (
    ENVELOPE_MARGIN,
    PREDICTORS,
    OnlinePredictor,
    PredictorSettings,
)
from stewart_drake.references.predictors import (
    HarmonicKalmanModel,
    MulinModel,
    WaveletLMSModel,
    filter_period,
)


def _ar2(n, seed=0):
    """(n, 2) two AR(2) processes (a damped 4 s oscillation at 25 Hz, driven by white noise),
    in m."""
    rng = np.random.default_rng(seed)
    r, theta = 0.995, 2 * np.pi * 0.04 / 4.0
    a1, a2 = 2 * r * math.cos(theta), -(r**2)
    y = np.zeros((n, 2))
    e = 1e-4 * rng.normal(size=(n, 2))
    for i in range(2, n):
        y[i] = a1 * y[i - 1] + a2 * y[i - 2] + e[i]
    return y


# --- wLMS ---------------------------------------------------------------------------------


def _haar_written_out(y, J):
    """The causal a trous Haar transform by its recursion, c_j(n) = (c_(j-1)(n) +
    c_(j-1)(n - 2^(j-1))) / 2 (the first sample repeated before the start): (J + 1, N, m), the
    details W_1..W_J and the rest c_J."""
    c = [np.asarray(y, dtype=float)]
    for j in range(1, J + 1):
        step = 2 ** (j - 1)
        prev = c[-1]
        shifted = np.concatenate([np.repeat(prev[:1], step, axis=0), prev[:-step]])
        c.append(0.5 * (prev + shifted))
    return np.array([c[j - 1] - c[j] for j in range(1, J + 1)] + [c[J]])


def _wlms_features(y, J, a):
    """(N, m, a (J + 1)) the wLMS regression vectors written out from the transform."""
    coeff = _haar_written_out(y, J)
    N, m = y.shape
    pad = 2**J * a + 1

    def at(band, n):
        return band[max(n, 0)] if n >= 0 else band[0]

    rows = np.zeros((N, m, a * (J + 1)))
    for n in range(N):
        col = 0
        for j in range(1, J + 1):
            for i in range(a):
                rows[n, :, col] = at(coeff[j - 1], n - 2**j * i) if n - 2**j * i >= 0 else 0.0
                col += 1
        for i in range(a):
            rows[n, :, col] = at(coeff[J], n - 2**J * i) - y[n]
            col += 1
    assert pad > 0
    return rows


def test_wlms_features_are_the_a_trous_haar_transform():
    """The regression vector of every sample (once its scales have filled) is the causal a
    trous Haar transform written out by its recursion: the details at strides 2^j and the
    smooth rest relative to the newest sample."""
    y = _ar2(200)
    settings = PredictorSettings(wlms_scales=3, wlms_depth=2, wlms_window_s=0.2)
    model = WaveletLMSModel(0.04, 2, 2, settings)
    expected = _wlms_features(y, 3, 2)
    for n, v in enumerate(y):
        model.update(v)
        if n >= model.span:
            np.testing.assert_allclose(model._B[-1], expected[n], rtol=0, atol=1e-15)
    assert np.abs(expected[-1]).max() > 1e-5


@pytest.mark.parametrize("window_s, steps", [(0.6, 3), (0.2, 1)])
def test_wlms_with_a_full_step_is_the_least_squares_fit_of_its_window(window_s, steps):
    """With mu = 1 each step's weights are the least-squares solution (minimum norm when the
    window holds fewer pairs than features) over the newest M pairs, written out here with
    numpy's lstsq on an AR(2) process: 15 pairs for 8 features, or 5 (fewer than the
    features)."""
    y = _ar2(300)
    dt = 0.04
    settings = PredictorSettings(wlms_scales=3, wlms_depth=2, wlms_window_s=window_s, wlms_mu=1.0)
    model = WaveletLMSModel(dt, steps, 2, settings)
    out = np.array([model.update(v) for v in y])
    X = _wlms_features(y, 3, 2)
    M = round(window_s / dt)
    for n in (150, 299):
        for k in range(1, steps + 1):
            for a in range(2):
                js = n - k - np.arange(M)
                A = X[js, a]
                s = y[js + k, a] - y[js, a]
                w = np.linalg.lstsq(A, s, rcond=None)[0]
                expected = y[n, a] + X[n, a] @ w
                assert out[n, k - 1, a] == pytest.approx(expected, rel=1e-7, abs=1e-12)


def test_wlms_predicts_an_ar_process_as_its_own_coefficients_do():
    """On a long AR(2) process, wLMS's one-step prediction error is within 20 % of the
    process's own innovation (the least any predictor can do), and far below holding the
    newest sample's."""
    y = _ar2(6000, seed=3)[:, :1]
    model = WaveletLMSModel(0.04, 1, 1, PredictorSettings(wlms_window_s=2.0, wlms_mu=0.05))
    out = np.array([model.update(v) for v in y])[:, 0, 0]
    e = out[1000:-1] - y[1001:, 0]
    held = y[1000:-1, 0] - y[1001:, 0]
    rms, innovation = np.sqrt(np.mean(e**2)), 1e-4
    assert innovation < rms < 1.2 * innovation
    assert rms < 0.5 * np.sqrt(np.mean(held**2))


# --- MULIN --------------------------------------------------------------------------------


@pytest.mark.parametrize("order", [0, 1, 2])
def test_mulin_extrapolates_a_polynomial_of_its_degree_exactly(order):
    """MULIN of order r is the polynomial of degree r + 1 through y_n, y_(n-k), ...: a
    polynomial of that degree (numpy's polyval) is predicted exactly k = 1..4 samples ahead
    once its smoothing has settled (smoothing far shorter than a step), one of a degree more
    is not."""
    dt = 0.1
    t = np.arange(0.0, 10.0, dt)
    coef = [0.002, -0.01, 0.03, 0.05][-(order + 2) :]
    y = np.polyval(coef, t)[:, None]
    model = MulinModel(dt, 4, 1, PredictorSettings(mulin_order=order, mulin_smoothing_s=1e-4))
    out = np.array([model.update(v) for v in y])
    n = np.arange(30, 90)
    for k in range(1, 5):
        np.testing.assert_allclose(out[n, k - 1, 0], np.polyval(coef, t[n] + k * dt), rtol=1e-9)
    higher = np.polyval([0.001] + coef, t)[:, None]
    model = MulinModel(dt, 4, 1, PredictorSettings(mulin_order=order, mulin_smoothing_s=1e-4))
    off = np.array([model.update(v) for v in higher])[60, 3, 0] - np.polyval(
        [0.001] + coef, t[60] + 0.4
    )
    assert abs(off) > 1e-6


def test_mulin_smooths_its_extrapolated_error_exponentially():
    """The extrapolated error is smoothed: e <- e + alpha (raw - e), alpha = 1 - exp(-dt / tau),
    written out on order 0 (raw = y_n - y_(n-k))."""
    rng = np.random.default_rng(4)
    y = np.cumsum(rng.normal(size=(50, 1)), axis=0) * 1e-3
    dt, tau = 0.2, 0.5
    model = MulinModel(dt, 2, 1, PredictorSettings(mulin_order=0, mulin_smoothing_s=tau))
    alpha = 1 - math.exp(-dt / tau)
    e = np.zeros(2)
    for n, v in enumerate(y):
        out = model.update(v)
        raw = np.array([y[n, 0] - y[max(n - k, 0), 0] for k in (1, 2)])
        e = e + alpha * (raw - e)
        np.testing.assert_allclose(out[:, 0], y[n, 0] + e, rtol=0, atol=1e-15)


# --- the period and the Kalman filter ------------------------------------------------------


@pytest.mark.parametrize("rate", [25.0, 5.0])
def test_the_period_of_a_breath(rate):
    """The period of a 3.7 s sine and of a 4.3 s breath shaped as cos^4 (its harmonics
    included) over 20 s, at 25 and 5 Hz: within 1 %. White noise, a drift, rest, and a period
    beyond the range looked for (a 0.3 s tremor) or half the samples' span (a 14 s wave): none."""
    dt = 1.0 / rate
    t = np.arange(0.0, 20.0, dt)
    assert filter_period(np.sin(2 * np.pi * t / 3.7), dt) == pytest.approx(3.7, rel=0.01)
    breath = np.cos(np.pi * t / 4.3) ** 4
    assert filter_period(breath, dt) == pytest.approx(4.3, rel=0.01)
    noise = np.random.default_rng(0).normal(size=t.size)
    assert math.isnan(filter_period(noise, dt))
    assert math.isnan(filter_period(0.01 * t, dt))
    assert math.isnan(filter_period(np.zeros_like(t), dt))
    assert math.isnan(filter_period(np.sin(2 * np.pi * t / 14.0), dt))
    if rate > 2 / 0.3:
        assert math.isnan(filter_period(np.sin(2 * np.pi * t / 0.3), dt))
    # Within the range, the edges are kept: 0.5 s at 25 Hz, 10 s (half of 20 s) at both rates.
    if rate == 25.0:
        assert filter_period(np.sin(2 * np.pi * t / 0.52), dt) == pytest.approx(0.52, rel=0.01)
    assert filter_period(np.sin(2 * np.pi * t / 9.8), dt) == pytest.approx(9.8, rel=0.02)


def _kalman_written_out(y, dt, omega, H, settings, K):
    """The textbook Kalman filter (covariance update P = (I - K h) P) of the model
    HarmonicKalmanModel's docstring defines, one axis, written out with dense matrices: started
    once half the window has arrived (state [first sample, 0, ...], covariance (4 std)^2 I, run
    through those samples), its noises measured on the newest window every second from then
    on. Returns (N, K) the predictions 1..K ahead after each sample, h F^k x (matrix powers),
    NaN before the start."""
    n = 1 + 2 * H
    F = np.eye(n)
    for h in range(1, H + 1):
        c, s = math.cos(h * omega * dt), math.sin(h * omega * dt)
        F[2 * h - 1 : 2 * h + 1, 2 * h - 1 : 2 * h + 1] = [[c, -s], [s, c]]
    hv = np.zeros(n)
    hv[0] = 1.0
    hv[1::2] = 1.0
    W = round(settings.kalman_window_s / dt)
    warm, every = W // 2, round(1.0 / dt)

    def noises(window):
        scale = float(np.std(window))
        Q = np.diag([(settings.kalman_q_level * scale) ** 2 * dt]
                    + [(settings.kalman_q * scale) ** 2 * dt] * (2 * H))  # fmt: skip
        R = max(predictors.noise_estimate(window) ** 2, (settings.kalman_r_floor * scale) ** 2)
        return Q, R

    def step(x, P, v, Q, R):
        x = F @ x
        P = F @ P @ F.T + Q
        gain = P @ hv / (hv @ P @ hv + R)
        return x + gain * (v - hv @ x), (np.eye(n) - np.outer(gain, hv)) @ P

    out = np.full((len(y), K), np.nan)
    x = P = Q = R = None
    for i in range(len(y)):
        if x is not None:
            x, P = step(x, P, y[i], Q, R)
        if i + 1 >= warm and (i + 1 - warm) % every == 0:
            window = y[max(0, i + 1 - W) : i + 1]
            Q, R = noises(window)
            if x is None:
                x = np.zeros(n)
                x[0] = window[0]
                P = np.eye(n) * (4.0 * np.std(window)) ** 2
                for v in window:
                    x, P = step(x, P, v, Q, R)
        if x is not None:
            out[i] = [hv @ np.linalg.matrix_power(F, k) @ x for k in range(1, K + 1)]
    return out


def test_the_kalman_filter_is_the_textbook_filter_of_its_model(monkeypatch):
    """Given the period (its estimate replaced by the true one), the filter's predictions at
    every sample equal the textbook Kalman filter of the model its docstring defines, written
    out with dense matrices, on a noisy two-harmonic breath at 5 Hz; before its start it holds
    the newest sample."""
    dt, period, K = 0.2, 4.0, 5
    monkeypatch.setattr(predictors, "filter_period", lambda x, dt: period)
    t = np.arange(0.0, 40.0, dt)
    rng = np.random.default_rng(1)
    y = 0.004 * np.sin(2 * np.pi * t / period) + 0.001 * np.cos(4 * np.pi * t / period + 0.3)
    y = y + 0.002 + 2e-4 * rng.normal(size=t.size)
    settings = PredictorSettings(kalman_harmonics=2, kalman_window_s=10.0)
    model = HarmonicKalmanModel(dt, K, 1, settings)
    out = np.array([model.update([v]) for v in y])[:, :, 0]
    expected = _kalman_written_out(y, dt, 2 * np.pi / period, 2, settings, K)
    started = np.isfinite(expected[:, 0])
    assert np.argmax(started) == model.warm - 1 == 24
    np.testing.assert_allclose(out[started], expected[started], rtol=0, atol=1e-12)
    np.testing.assert_array_equal(out[~started], np.repeat(y[~started, None], K, axis=1))
    assert np.abs(out[started] - y[started, None]).max() > 1e-3  # it predicts


def test_the_kalman_filter_predicts_a_sine_as_its_closed_form():
    """A pure sine on a baseline at 25 Hz (period 3.3 s, measured by the filter itself): after
    30 s the prediction k = 1..10 samples ahead is the sine's own closed form c + A sin(omega
    (t + k dt) + phi) to 0.5 % of the amplitude, where holding the newest sample is off by up to
    70 %."""
    dt, K = 0.04, 10
    A, omega, phi, c = 0.005, 2 * np.pi / 3.3, 0.7, 0.21
    t = np.arange(0.0, 60.0, dt)
    y = c + A * np.sin(omega * t + phi)
    model = HarmonicKalmanModel(dt, K, 1, PredictorSettings())
    out = np.array([model.update([v]) for v in y])[:, :, 0]
    later = t >= 30.0
    k = np.arange(1, K + 1)
    closed = c + A * np.sin(omega * (t[later, None] + k * dt) + phi)
    error = np.abs(out[later] - closed).max()
    assert 0 < error < 5e-3 * A
    assert np.abs(y[later, None] - closed).max() > 0.5 * A


# --- every predictor: causality and the fallback -------------------------------------------


def _noisy_breath(n=400, dt=0.2, seed=2):
    """(n, 6) a 4 s breath of 10 mm on X with 0.3 mm of white noise on every axis, at 5 Hz."""
    t = np.arange(n) * dt
    rng = np.random.default_rng(seed)
    y = 3e-4 * rng.normal(size=(n, 6))
    y[:, 3] += 0.005 * np.cos(np.pi * t / 4.0) ** 4 + 0.21
    return y


@pytest.mark.parametrize("name", PREDICTORS)
def test_no_prediction_reads_a_sample_before_it_arrived(name):
    """Change one sample (the 300th of 400): everything each predictor put forward before it,
    its choice and its uncertainty included, is unchanged to the bit; after it, the positions
    differ (but for no prediction's, which are the samples themselves)."""
    y = _noisy_breath()
    changed = y.copy()
    changed[300] += 0.002

    def run(samples):
        p = OnlinePredictor(name, 0.2, 5, 6, PredictorSettings(kalman_window_s=20.0))
        rows = []
        for v in samples:
            out = p.raw_update(v)
            rows.append((out, p.using.copy(), p.sigma.copy()))
        return rows

    a, b = run(y), run(changed)
    for i in range(300):
        for x, z in zip(a[i], b[i]):
            assert np.array_equal(x, z, equal_nan=True), i
    assert any(not np.array_equal(a[i][0], b[i][0]) for i in range(300, 400))


@pytest.mark.parametrize("name", ["mulin", "wlms", "kalman", "linear"])
def test_a_predictor_worse_than_none_is_not_used(name):
    """On white noise about a still position every predictor's record is held against no
    prediction's; MULIN (extrapolating the noise) is worse than holding the newest sample and
    falls back to it exactly; the others, where they learn to pull towards the mean, may be
    used, but never while their record is the worse. Without the shrinkage, which would hide
    the model's own record behind a gain near 0."""
    rng = np.random.default_rng(7)
    y = np.zeros((600, 6))
    y[:, 3] = 1e-3 * rng.normal(size=600)
    settings = PredictorSettings(shrink=False, bound_s=None)
    p = OnlinePredictor(name, 0.2, 5, 6, settings)
    for v in y:
        out = p.update(v)
        if p._se[0, :, 3].sum() >= p._se[1, :, 3].sum():  # the record: holding is no worse
            assert not p.using[3]
        if not p.using[3]:
            np.testing.assert_array_equal(out[:, 3], np.full(5, v[3]))
    if name == "mulin":
        assert p._se[0, :, 3].sum() > 1.5 * p._se[1, :, 3].sum() and not p.using[3]


# --- the bound and the shrinkage -----------------------------------------------------------


class _Scripted:
    """A model whose predictions are given: row i of ``rows`` (N, K, m) at its i-th sample."""

    warm = 0

    def __init__(self, rows):
        self.rows, self.i = rows, 0

    def update(self, y):
        self.i += 1
        return self.rows[self.i - 1].copy()


def test_the_bound_is_the_largest_recent_displacement_widened():
    """The displacement put forward k samples ahead is at most, widened by the envelope's
    margin, the largest |y_j - y_(j-k)| so far, each weighed exp(-(n - j) dt / bound_s): written
    out as that maximum over the samples (not the predictor's recursion); within it the
    model's own positions pass unchanged. A still axis predicts no displacement."""
    dt, K, bound_s = 0.2, 3, 2.0
    t = np.arange(120) * dt
    y = np.column_stack([0.004 * np.sin(2 * np.pi * t / 5.0), np.zeros_like(t)])
    y[60:, 0] += 0.003  # a step in the samples
    k = np.arange(1, K + 1)
    rows = np.repeat(y[:, None, :], K, axis=1)
    rows[:, :, 0] += 0.02 * np.sin(3 * t)[:, None] * k  # overshooting, either way
    rows[:, :, 1] += 1e-3
    settings = PredictorSettings(shrink=False, bound_s=bound_s)
    p = OnlinePredictor("linear", dt, K, 2, settings)
    p.model = _Scripted(rows)
    lam = math.exp(-dt / bound_s)
    for n, v in enumerate(y):
        out = p.raw_update(v)
        low, high = y[: n + 1].min(axis=0), y[: n + 1].max(axis=0)
        margin = ENVELOPE_MARGIN * (high - low)
        inside = np.clip(rows[n], low - margin, high + margin)
        for kk in k:
            js = np.arange(kk, n + 1)
            moved = np.abs(y[js] - y[js - kk]) * lam ** (n - js)[:, None]
            reach = (1 + ENVELOPE_MARGIN) * (moved.max(axis=0) if js.size else np.zeros(2))
            expected = v + np.clip(inside[kk - 1] - v, -reach, reach)
            np.testing.assert_allclose(out[kk - 1], expected, rtol=0, atol=1e-15)
    assert p.clipped > 100
    assert np.abs(out[:, 0] - y[-1, 0]).max() > 1e-3  # it still predicts


def test_the_shrinkage_is_the_least_squares_gain_of_the_completed_pairs():
    """Per axis and k the displacement put forward is g d, g the weighted least-squares gain of
    the outcome's displacement on the model's over the pairs completed so far (weights
    exp(-(n - j) dt / gain_s)), clipped to [0, 1]: written out as sums over the pairs. Axes: a
    model that predicts twice the displacement that comes (g -> 1/2), one that predicts it
    (g = 1), one that predicts it reversed (g = 0, the newest sample held)."""
    dt, K, gain_s = 0.1, 2, 3.0
    t = np.arange(150) * dt
    y = np.column_stack([0.01 * np.sin(t)] * 3)
    k = np.arange(1, K + 1)
    future = 0.01 * np.sin(t[:, None] + k * dt)  # (N, K)
    d = future - y[:, :1]
    rows = np.stack([y[:, :1] + 2 * d, y[:, :1] + d, y[:, :1] - d], axis=-1)  # (N, K, 3)
    settings = PredictorSettings(shrink=True, bound_s=None, gain_s=gain_s)
    p = OnlinePredictor("linear", dt, K, 3, settings)
    p.model = _Scripted(rows)
    p._warm = 0  # the scripted model's predictions count from the first
    lam = math.exp(-dt / gain_s)
    for n, v in enumerate(y):
        out = p.raw_update(v)
        low, high = y[: n + 1].min(axis=0), y[: n + 1].max(axis=0)
        margin = ENVELOPE_MARGIN * (high - low)
        for kk in k:
            js = np.arange(kk, n + 1)  # pairs made at j - k, completed at j <= n
            dd = np.clip(rows[js - kk, kk - 1], low - margin, high + margin) - y[js - kk]
            # The clip at each pair's own time: the envelope then.
            for idx, j in enumerate(js):
                lo_j, hi_j = y[: j - kk + 1].min(axis=0), y[: j - kk + 1].max(axis=0)
                m_j = ENVELOPE_MARGIN * (hi_j - lo_j)
                dd[idx] = np.clip(rows[j - kk, kk - 1], lo_j - m_j, hi_j + m_j) - y[j - kk]
            w = lam ** (n - js)[:, None]
            sxx, sxy = (w * dd * dd).sum(axis=0), (w * dd * (y[js] - y[js - kk])).sum(axis=0)
            g = np.clip(np.divide(sxy, sxx, out=np.zeros(3), where=sxx > 0), 0, 1)
            inside = np.clip(rows[n, kk - 1], low - margin, high + margin)
            np.testing.assert_allclose(out[kk - 1], v + g * (inside - v), rtol=1e-9, atol=1e-15)
    assert p.gain[:, 0] == pytest.approx([0.5, 0.5], abs=0.05)
    assert p.gain[:, 1] == pytest.approx([1.0, 1.0]) and not p.gain[:, 2].any()


def test_the_settings_of_the_predictors_are_checked():
    """Each new setting refused out of its range, naming it."""
    for change, words in [
        ({"wlms_mu": 0.0}, r"wlms_mu must be a finite number in \(0, 1\]"),
        ({"wlms_mu": 1.5}, "wlms_mu"),
        ({"bound_s": 0.0}, "bound_s must be a finite number > 0"),
        ({"gain_s": float("nan")}, "gain_s"),
        ({"wlms_scales": 0}, "wlms_scales must be an integer >= 1, got 0"),
        ({"mulin_order": -1}, "mulin_order must be an integer >= 0"),
        ({"kalman_harmonics": 2.0}, "kalman_harmonics must be an integer"),
        ({"shrink": 1}, "shrink must be True or False"),
        ({"kalman_window_s": -1.0}, "kalman_window_s"),
    ]:
        with pytest.raises(InvalidConfigError, match=words):
            PredictorSettings(**change)
    assert PredictorSettings(bound_s=None).bound_s is None


def test_the_settings_at_their_edges():
    """Each count at its least taken (1; MULIN's order 0), a bool or an infinity refused as a
    number, and a setting after one left None still checked."""
    least = {"wlms_scales": 1, "wlms_depth": 1, "mulin_order": 0, "kalman_harmonics": 1}
    s = PredictorSettings(**least, rnn_units=1, wlms_mu=1.0, record_margin=0.0, ridge=0.0)
    assert (s.wlms_depth, s.kalman_harmonics, s.rnn_units, s.mulin_order) == (1, 1, 1, 0)
    for change, words in [
        ({"history_s": True}, "history_s must be a finite number > 0, got True"),
        ({"history_s": math.inf}, "history_s must be a finite number > 0, got inf"),
        ({"bound_s": None, "envelope_s": 0.0}, "envelope_s must be a finite number > 0"),
        ({"record_margin": 1.0}, r"record_margin must be a finite number in \[0, 1\)"),
        ({"ridge": -1e-12}, "ridge must be a finite number >= 0"),
    ]:
        with pytest.raises(InvalidConfigError, match=words):
            PredictorSettings(**change)


# --- the recurrent network ---------------------------------------------------------------


def test_uoro_estimates_the_networks_jacobian_without_bias():
    """UORO's s~ theta~^T is an unbiased estimate of d state / d parameters: over 4000 draws of
    its random signs, on a network of 3 units and 2 inputs run 4 steps without learning, the
    mean estimate equals the Jacobian of the state after those steps (central finite
    differences of the state on each of W_a, W_b, b) within 4 standard errors of the mean, on
    every element; one draw alone is far from it."""
    from stewart_drake.references.predictors import RecurrentModel

    settings = PredictorSettings(rnn_units=3, rnn_history_s=0.2)
    model = RecurrentModel(0.1, 1, 1, settings)
    rng = np.random.default_rng(11)
    model.Wa, model.Wb, model.b = (
        rng.normal(size=(3, 3)),
        rng.normal(size=(3, 2)),
        rng.normal(size=3),
    )
    model.rate = 0.0  # no learning: the parameters stay where the Jacobian is taken
    inputs = rng.normal(size=(4, 2))

    def state_after(Wa, Wb, b):
        s = np.zeros(3)
        for u in inputs:
            s = np.tanh(Wa @ s + Wb @ u + b)
        return s

    theta = np.concatenate([model.Wa.ravel(), model.Wb.ravel(), model.b])
    exact = np.zeros((3, theta.size))
    for i in range(theta.size):
        h = np.zeros(theta.size)
        h[i] = 1e-6
        up, down = theta + h, theta - h
        exact[:, i] = (
            state_after(up[:9].reshape(3, 3), up[9:15].reshape(3, 2), up[15:])
            - state_after(down[:9].reshape(3, 3), down[9:15].reshape(3, 2), down[15:])
        ) / 2e-6
    draws = []
    for seed in range(4000):
        model._rng = np.random.default_rng(seed)
        model.s, model.s_tilde = np.zeros(3), np.zeros(3)
        model.theta_tilde = np.zeros(theta.size)
        for u in inputs:
            model._train(u, np.zeros(1))
        draws.append(np.outer(model.s_tilde, model.theta_tilde))
    draws = np.array(draws)
    mean, se = draws.mean(axis=0), draws.std(axis=0) / np.sqrt(len(draws))
    assert np.all(np.abs(mean - exact) <= 4 * se + 1e-9)
    assert np.abs(draws[0] - exact).max() > 0.3 * np.abs(exact).max()
    np.testing.assert_allclose(model.s, state_after(model.Wa, model.Wb, model.b), atol=1e-15)


def test_the_recurrent_network_learns_a_breath():
    """On a 4 s breath at 25 Hz, the network trained online for a minute predicts 0.36 s ahead
    with less than 0.6 of the error of holding the newest sample; and two runs are the same
    to the bit (its random signs are seeded)."""
    dt, K = 0.04, 9
    t = np.arange(0.0, 120.0, dt)
    y = np.zeros((t.size, 6))
    y[:, 3] = 0.01 * np.cos(np.pi * t / 4) ** 4
    runs = []
    for _ in range(2):
        p = OnlinePredictor("rnn", dt, K, 6)
        runs.append(np.array([p.raw_update(v) for v in y]))
    np.testing.assert_array_equal(runs[0], runs[1])
    half = t.size // 2
    e = runs[0][half:-K, K - 1, 3] - y[half + K :, 3]
    held = y[half:-K, 3] - y[half + K :, 3]
    assert 0 < np.sqrt(np.mean(e**2)) < 0.6 * np.sqrt(np.mean(held**2))
