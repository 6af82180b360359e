"""The package's one lag search (:mod:`stewart_drake.base.lag`) against numbers found here another
way: pure delays of a sine and of an irregular breath built into the signals (the measured the
motion evaluated at t - L, never interpolated), the residual's least on a fine grid written out in
numpy, the Cramer-Rao bound of a delay in white noise, and IntERAct's own findOptimalShift
(tests/interact_method.py). Unit tests of a fraction of a second each."""

import math

import numpy as np
import pytest
from interact_method import optimal_shift

from stewart_drake.base.errors import InvalidConfigError
from stewart_drake.base.lag import best_shift, inner_mask, signal_lag

#: A robot's control period and a 30 s window, as the encoders' relative latency judges.
H = 0.01
T = np.arange(0.0, 30.0, H)
#: The delays put in: none, sub-sample either way, several samples, near the search's edge.
DELAYS_S = (0.0, 0.0037, -0.0021, 0.0125, -0.0213, 0.2468, -0.4011)


def sine(t):
    """A 10 mm, 4 s breath, m."""
    return 0.01 * np.sin(2 * np.pi * t / 4.0)


def breath(t):
    """An irregular breath as IntERAct's traces hold them, m: Lujan's cos^4 shape (10 mm, end
    of exhale flat) with its period wandering between 3.6 and 4.4 s and a heartbeat's ripple."""
    phase = 2 * np.pi * (t / 4.0 + 0.08 * np.sin(2 * np.pi * t / 23.0))  # 3.67-4.38 s a breath
    return 0.01 * np.cos(phase / 2) ** 4 + 0.3e-3 * np.sin(2 * np.pi * t / 0.9)


def crlb_s(t, motion, sigma, offsets):
    """The Cramer-Rao bound on a delay's standard deviation, s, of a motion sampled at t in white
    noise of ``sigma``: sigma / sqrt(sum of the motion's squared rate), the rate less its mean
    when a constant offset is estimated with it (the Fisher information's Schur complement)."""
    rate = np.gradient(motion(t), t)
    rate = rate - rate.mean() if offsets else rate
    return sigma / math.sqrt(float(np.sum(rate * rate)))


@pytest.mark.parametrize("motion", [sine, breath], ids=["sine", "breath"])
@pytest.mark.parametrize("delay_s", DELAYS_S)
def test_a_pure_delay_is_found_to_a_hundredth_of_a_sample(motion, delay_s):
    lag, rms = signal_lag(T, motion(T - delay_s), motion(T), 0.5)
    assert abs(lag - delay_s) < 0.01 * H, (lag, delay_s)
    # What is left is the command's interpolation between samples, microns at most.
    assert rms < 5e-6


def held(t, command, tau_s):
    """A servo's reading at the times t (a period H apart, from the first) of a command held a
    period at a time: each held value approached by a first-order lag of ``tau_s``, exactly."""
    x, out = 0.0, np.empty(t.size)
    decay = math.exp(-H / tau_s)
    for k, c in enumerate(command):
        out[k] = x
        x = c + (x - c) * decay
    return out


def test_a_held_command_s_lag_does_not_move_with_where_the_samples_fall():
    # A robot holds each command for a control period, so what its encoders read moves in steps
    # locked to the command's sample times. Put the command's samples a fraction of a period
    # later (their times and values both) and the lag must move by that fraction, no more:
    # within 1 us (0.25 us measured). Against a linear interpolant of the command it moved by
    # 5.4 us here, and by up to 0.47 ms on an emulated robot's encoder log.
    y = held(T, breath(T), 0.015)
    lag0, _ = signal_lag(T, y, breath(T), 0.5, offsets=True)
    assert 0.015 < lag0 < 0.025  # about the lag's tau plus half a period held
    for fraction in (0.13, 0.31, 0.5, 0.77):
        shifted = T + fraction * H
        lag, _ = signal_lag(shifted, y, breath(shifted), 0.5, offsets=True)
        assert abs(lag - fraction * H - lag0) < 1e-6, (fraction, lag, lag0)


@pytest.mark.parametrize("delay_s", [0.0037, -0.0213, 0.2468])
def test_a_delay_with_an_offset_and_encoder_noise_is_found_to_a_hundredth_of_a_sample(delay_s):
    rng = np.random.default_rng(7)
    sigma = 5e-6  # a few encoder counts, m
    measured = breath(T - delay_s) + 2e-3 + sigma * rng.standard_normal(T.size)
    lag, rms = signal_lag(T, measured, breath(T), 0.5, offsets=True)
    bound = crlb_s(T[50:-50], breath, sigma, True)
    assert 5 * bound < 0.01 * H  # the test's premise: the noise leaves a hundredth reachable
    assert abs(lag - delay_s) < 0.01 * H, (lag, delay_s)
    assert 0.8 * sigma < rms < 1.2 * sigma  # the noise, the offset removed


def test_a_camera_s_noise_spreads_the_lag_as_the_cramer_rao_bound_says():
    sigma, delay_s = 0.2e-3, 0.0813  # a depth camera's 0.2 mm
    lags = []
    for seed in range(24):
        rng = np.random.default_rng(seed)
        measured = sine(T - delay_s) + sigma * rng.standard_normal(T.size)
        lags.append(signal_lag(T, measured, sine(T), 0.5, offsets=True)[0])
    bound = crlb_s(T[50:-50], sine, sigma, True)
    spread = float(np.std(lags))
    assert 0.6 * bound < spread < 1.5 * bound, (spread, bound)
    assert abs(float(np.mean(lags)) - delay_s) < 4 * bound / math.sqrt(len(lags))


def test_unevenly_sampled_times_are_taken_at_their_own_times():
    rng = np.random.default_rng(3)
    t = T + rng.uniform(-0.3, 0.3, T.size) * H  # a camera's frames, jittering
    for delay_s in (0.0037, -0.2468):
        lag, _ = signal_lag(t, breath(t - delay_s), breath(t), 0.5)
        assert abs(lag - delay_s) < 0.01 * H, (lag, delay_s)


def test_columns_count_alike_and_an_offset_is_removed_only_when_asked():
    delay_s = 0.0173
    c = np.column_stack([sine(T), 0.5 * breath(T)])
    m = np.column_stack([sine(T - delay_s), 0.5 * breath(T - delay_s)]) + [1e-3, -2e-3]
    lag, rms = signal_lag(T, m, c, 0.5, offsets=True)
    assert abs(lag - delay_s) < 0.01 * H and rms < 5e-6
    _, kept = signal_lag(T, m, c, 0.5)  # the offsets kept: they are the residual
    assert kept == pytest.approx(math.hypot(1e-3, 2e-3), rel=1e-2)


def _residual(t, y, c, lags):
    """RMS(y(t_k) - c(t_k - L)) over the samples 0.5 s inside either end, each L, written out."""
    inner = (t >= t[0] + 0.5) & (t <= t[-1] - 0.5)
    return np.array(
        [np.sqrt(np.mean((y[inner] - np.interp(t[inner] - L, t, c)) ** 2)) for L in lags]
    )


def test_a_periodic_motion_s_other_minima_within_the_search_are_not_taken():
    # A 4 s breath with a strong 0.6 s component: the residual dips every 0.6 s.
    def motion(t):
        return 0.004 * np.sin(2 * np.pi * t / 4.0) + 0.006 * np.sin(2 * np.pi * t / 0.6 + 0.4)

    delay_s = 0.3123
    y, c = motion(T - delay_s), motion(T)
    lags = np.arange(-0.5, 0.5 + 1e-9, 1e-3)
    r = _residual(T, y, c, lags)
    # The premise, on the written-out residual: a local minimum near 0 (the one a descent from
    # no lag would stop in) other than the true one.
    dips = [k for k in range(1, len(r) - 1) if r[k] < r[k - 1] and r[k] < r[k + 1]]
    wrong = [lags[k] for k in dips if abs(lags[k] - delay_s) > 0.1]
    assert any(abs(w) < 0.35 for w in wrong), wrong
    lag, _ = signal_lag(T, y, c, 0.5)
    assert abs(lag - delay_s) < 0.01 * H, lag


def test_a_cycle_away_is_outside_the_search():
    # Periodic every 1 s, 0.1 s late: within +-0.45 s the one match is 0.1 s, not -0.9 or 1.1.
    def motion(t):
        return 0.005 * np.sin(2 * np.pi * t) + 0.002 * np.sin(4 * np.pi * t + 1.0)

    lag, _ = signal_lag(T, motion(T - 0.1), motion(T), 0.45)
    assert abs(lag - 0.1) < 0.01 * H
    # A lag beyond the search is held at its edge, never matched a cycle off.
    edge, _ = signal_lag(T, motion(T - 0.3), motion(T), 0.2)
    assert edge == pytest.approx(0.2, abs=1e-5)


@pytest.mark.parametrize("delay_s", [0.2468, -0.0213])
def test_the_lag_is_interact_s_find_optimal_shift(delay_s):
    # IntERAct's method, an independent program (its grid of shifts and of amplitude offsets),
    # here on a 1 ms grid of shifts and in mm as theirs: the same lag within its grid.
    y = breath(T - delay_s) + 1.5e-3
    theirs, _, _ = optimal_shift(T, 1e3 * breath(T), T, 1e3 * y, lo=-0.5, hi=0.5, step=1e-3)
    lag, _ = signal_lag(T, y, breath(T), 0.5, offsets=True)
    assert abs(lag - theirs) <= 0.5e-3 + 1e-9, (lag, theirs)


def test_a_still_command_has_no_lag():
    still = np.full(T.size, 0.3)
    lag, rms = signal_lag(T, sine(T), still, 0.5)
    assert math.isnan(lag) and math.isnan(rms)
    # Still below a bound: a command of a few counts' jitter is still too; one above it moves.
    jitter = 0.3 + 1e-6 * np.sign(np.sin(T))
    assert math.isnan(signal_lag(T, sine(T), jitter, 0.5, still_below=2e-5)[0])
    assert not math.isnan(signal_lag(T, sine(T - 0.01), sine(T), 0.5, still_below=2e-5)[0])


def _args(**change):
    args = dict(t=T, measured=sine(T - 0.01), commanded=sine(T), max_lag_s=0.5)
    args.update(change)
    return args


@pytest.mark.parametrize(
    "change, words",
    [
        (dict(measured=sine(T)[:-1]), r"\(n,\) alike"),
        (dict(commanded=np.column_stack([sine(T), sine(T)])), r"\(n,\) alike"),
        (dict(t=T.reshape(-1, 1)), r"\(n,\) alike"),
        (dict(measured=np.zeros((T.size, 2, 2)), commanded=np.zeros((T.size, 2, 2))), "alike"),
        (dict(measured=np.where(T == T[7], np.nan, sine(T))), "not finite"),
        (dict(commanded=np.where(T == T[9], np.inf, sine(T))), "not finite"),
        (dict(t=np.where(T == T[5], np.nan, T)), "not finite"),
        (dict(t=T[::-1].copy()), "must increase"),
        (dict(t=np.r_[T[:10], T[9:-1]]), "must increase"),
        (dict(max_lag_s=0.0), "max_lag_s must be > 0"),
        (dict(max_lag_s=-0.1), "max_lag_s must be > 0"),
        (dict(max_lag_s=math.inf), "max_lag_s must be > 0"),
        (dict(max_lag_s=math.nan), "max_lag_s must be > 0"),
        (dict(max_lag_s=14.95), "too short"),
        (dict(t=T[:3], measured=sine(T[:3]), commanded=sine(T[:3])), "too short"),
        (dict(t=T[:0], measured=sine(T[:0]), commanded=sine(T[:0])), "too short"),
    ],
)
def test_wrong_samples_are_refused(change, words):
    with pytest.raises(InvalidConfigError, match=words):
        signal_lag(**_args(**change))


def test_a_shorter_least_window_is_taken_when_asked():
    t = np.arange(0.0, 1.12, H)  # 12 samples inside +-0.5 s margins: refused, unless 8 will do
    with pytest.raises(InvalidConfigError, match="at least 20"):
        signal_lag(t, sine(t - 0.01), sine(t), 0.5)
    assert signal_lag(t, sine(t - 0.01), sine(t), 0.5, min_samples=8)[0] == pytest.approx(
        0.01, abs=1e-4
    )


# -- the search on a reference given as a function of time (verify's clock) ---------------------


def _seen(times):
    return np.column_stack([breath(times)])


def test_a_camera_s_frames_against_a_continuous_reference_give_its_shift():
    # verify's form: the measured at a camera's uneven times, the reference any function of
    # time; the shift d puts the measured time + d on the reference's clock (d = -lag).
    rng = np.random.default_rng(11)
    t = np.sort(rng.uniform(5.0, 35.0, 1800))  # 60 frames a second, jittering
    for d_true in (0.4271, -1.1034):
        y = breath(t + d_true).reshape(-1, 1)
        d = best_shift(t, y, np.ones(1), _seen, (-1.5, 1.5), 0.02, True)
        assert abs(d - d_true) < 1e-4, (d, d_true)


def test_the_search_stays_within_its_shifts_and_refuses_a_wrong_range():
    t = np.arange(5.0, 35.0, H)
    y = breath(t + 0.9).reshape(-1, 1)
    assert best_shift(t, y, np.ones(1), _seen, (-0.5, 0.5), H, True) == pytest.approx(0.5, abs=1e-5)
    assert best_shift(t, y, np.ones(1), _seen, (0.3, 0.3), H, True) == 0.3
    for shifts, step, words in [
        ((0.5, -0.5), H, "lo <= hi"),
        ((math.nan, 0.5), H, "finite"),
        ((-0.5, math.inf), H, "finite"),
        ((-0.5, 0.5), 0.0, "step must be > 0"),
        ((-0.5, 0.5), math.nan, "step must be > 0"),
        ((-0.5, 0.5), math.inf, "step must be > 0"),
    ]:
        with pytest.raises(InvalidConfigError, match=words):
            best_shift(t, y, np.ones(1), _seen, shifts, step, True)
    with pytest.raises(InvalidConfigError, match="2 samples"):
        best_shift(t[:1], y[:1], np.ones(1), _seen, (-0.5, 0.5), H, True)
    assert -0.5 <= best_shift(t[:2], y[:2], np.ones(1), _seen, (-0.5, 0.5), H, True) <= 0.5


def test_the_samples_compared_are_those_a_margin_from_either_end():
    """Times 0..10 s and a search of 2 s: 2 to 8 s, both ends included; none of no samples."""
    t = np.arange(11.0)
    np.testing.assert_array_equal(t[inner_mask(t, 2.0)], np.arange(2.0, 9.0))
    assert inner_mask(np.array([]), 1.0).size == 0


def test_the_fewest_samples_a_lag_is_measured_on():
    """Two samples inside the margins are enough where min_samples is 2 (or less); one is
    refused naming the two; columns each still, at different levels, have no lag."""
    t = np.arange(6.0)
    c = np.sin(t)
    assert math.isfinite(signal_lag(t, np.sin(t - 0.1), c, 1.5, min_samples=2)[0])  # 2 and 3 s
    with pytest.raises(InvalidConfigError, match=r"1 samples .* \(at least 2\)"):
        signal_lag(t[:5], np.sin(t[:5] - 0.1), c[:5], 2.0, min_samples=1)  # 0-4 s: 2 s alone
    still = np.column_stack([np.ones(6), 2.0 * np.ones(6)])
    assert all(map(math.isnan, signal_lag(t, still, still, 1.5, min_samples=2)))
