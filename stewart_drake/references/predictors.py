"""The respiratory-motion predictors of the field beside the plain regression of
:mod:`~.prediction`: the wavelet-based multiscale regression (:class:`WaveletLMSModel`, wLMS),
the multi-step linear extrapolation of the error of no prediction (:class:`MulinModel`, MULIN),
and a Kalman filter on a breathing model, a baseline and the harmonics of a period it measures
(:class:`HarmonicKalmanModel`), and a small recurrent network trained online by unbiased online
recurrent optimisation (:class:`RecurrentModel`, UORO).

Each reads one sample at a time and returns the positions it expects 1..K samples later,
``update(y)`` -> (K, m), from the samples up to ``y`` only; ``warm`` is the number of samples
after which its predictions mean something (the record of :class:`~.prediction.OnlinePredictor`
starts once those predictions' outcomes arrive). :class:`~.prediction.OnlinePredictor` wraps
each with the envelope, the bound on the displacement, the shrinkage and the record that falls
back to no prediction (:mod:`~.prediction`). Every axis is predicted apart from the others.
"""

import math

import numpy as np

from ..base.signals import PERIOD_POWER_SHARE, dominant_period
from .trace_cleaning import noise_estimate

#: The periods :func:`filter_period` looks for, s: a heartbeat (0.5 s, 120 bpm) to a slow
#: breath (12 s).
PERIOD_RANGE_S = (0.5, 12.0)
#: Harmonics at or above this fraction of the Nyquist frequency are left out of the model.
NYQUIST_SHARE = 0.8


def _ring_push(ring: np.ndarray, value) -> None:
    """Shift ``ring`` (L, ...) one row up and put ``value`` last (the newest last)."""
    ring[:-1] = ring[1:]
    ring[-1] = value


def _take_sample(model, y) -> np.ndarray:
    """Push sample ``y`` (m,) onto ``model._y``, the samples' history (the first sample
    repeated before the stream's start, so that a history reads a motion at rest there), and
    count it in ``model._n``; returns ``y`` as floats."""
    y = np.asarray(y, dtype=float)
    if model._n == 0:
        model._y[:] = y
    model._n += 1
    _ring_push(model._y, y)
    return y


class WaveletLMSModel:
    """Wavelet-based multiscale autoregression (wLMS) of each axis, k = 1..K samples ahead.

    After Ernst, Schlaefer & Schweikard, "Prediction of respiratory motion with wavelet-based
    multiscale autoregression", MICCAI 2007 (LNCS 4792, 668), compared with the field's other
    predictors by Ernst et al., Phys. Med. Biol. 58, 3911 (2013). The signal is split by the
    causal a trous Haar transform into J detail scales and a smooth rest:
    c_0 = y, c_j(n) = (c_(j-1)(n) + c_(j-1)(n - 2^(j-1))) / 2 (the mean of the 2^j newest
    samples), W_j = c_(j-1) - c_j, so y(n) = sum_j W_j(n) + c_J(n). The regression vector of
    sample n reads each scale at its own stride: B(n) = [W_j(n - 2^j i), i < a (j = 1..J);
    c_J(n - 2^J i) - y(n), i < a]; the displacement k samples ahead is w_k^T B(n). At every
    sample the weights move towards the least-squares solution over the newest M completed pairs
    (Moore-Penrose, the minimum-norm one when M < the features): w_k <- (1 - mu) w_k + mu
    B_k^+ s_k, B_k's rows B(n - k - i) and s_k's y(n - i) - y(n - k - i), i < M.

    Ours, where the paper's text was not available to check it: the depth a is the same on
    every scale (the paper's a_j differ per scale), and the regression is of the displacement
    from the newest sample (the smooth rest read relative to it; the paper regresses the
    position itself), so that an axis's offset (Z at home, 0.2 m) does not weigh in the least
    squares.

    Args:
        dt: the sample step, s. steps: K. axes: m. settings: its ``wlms_*`` fields
            (:class:`~.prediction.PredictorSettings`).
    """

    def __init__(self, dt: float, steps: int, axes: int, settings):
        self.K, self.m = int(steps), int(axes)
        self.J = max(1, int(settings.wlms_scales))
        self.a = max(1, int(settings.wlms_depth))
        self.M = max(1, int(round(settings.wlms_window_s / dt)))
        self.mu = float(settings.wlms_mu)
        self.span = 2**self.J * (self.a - 1) + 2**self.J  # samples one regression vector reads
        self.P = self.a * (self.J + 1)
        self.warm = self.span + self.K + self.M
        self._y = np.zeros((self.span + self.K + self.M + 1, self.m))
        self._B = np.zeros((self.K + self.M, self.m, self.P))  # newest last
        self._w = np.zeros((self.K, self.m, self.P))
        self._n = 0

    def features(self) -> np.ndarray:
        """(m, P) the regression vector of the newest sample, from the samples held."""
        y = self._y[-self.span :]  # (span, m), newest last
        # c_j at lag l: the mean of the 2^j samples ending l samples before the newest.
        out = []
        for j in range(1, self.J + 1):
            for i in range(self.a):
                lag = 2**j * i
                fine = y[len(y) - lag - 2 ** (j - 1) : len(y) - lag].mean(axis=0)
                coarse = y[len(y) - lag - 2**j : len(y) - lag].mean(axis=0)
                out.append(fine - coarse)
        for i in range(self.a):
            lag = 2**self.J * i
            out.append(y[len(y) - lag - 2**self.J : len(y) - lag].mean(axis=0) - y[-1])
        return np.stack(out, axis=-1)

    def update(self, y: np.ndarray) -> np.ndarray:
        """Read sample ``y`` (m,); return (K, m) its expected values 1..K samples later."""
        y = _take_sample(self, y)
        _ring_push(self._B, self.features())
        k = np.arange(1, self.K + 1)
        i = np.arange(self.M)
        # Pairs of step k: features of sample n - k - i, outcome at n - i (i < M), all arrived.
        ready = self._n - 1 - k - (self.M - 1) >= 0  # (K,): M pairs of step k complete
        if ready.any():
            rows = self._B[self.K + self.M - 1 - k[:, None] - i[None, :]]  # (K, M, m, P)
            newest = len(self._y) - 1
            target = self._y[newest - i][None, :, :] - self._y[newest - k[:, None] - i[None, :]]
            B = np.moveaxis(rows, 2, 1)  # (K, m, M, P)
            s = np.moveaxis(target, 2, 1)  # (K, m, M)
            w_ls = (np.linalg.pinv(B, rcond=1e-10) @ s[..., None])[..., 0]  # (K, m, P)
            self._w[ready] += self.mu * (w_ls[ready] - self._w[ready])
        return y[None, :] + np.einsum("kmp,mp->km", self._w, self._B[-1])


class MulinModel:
    """Multi-step linear extrapolation of the error of no prediction (MULIN), k = 1..K samples
    ahead.

    After Ernst & Schweikard, "Predicting respiratory motion signals for image-guided
    radiotherapy using multi-step linear methods (MULIN)", Int. J. CARS 3, 85 (2008): the error
    that holding the newest sample makes k samples ahead, e_n = y_n - y_(n-k), is itself
    extrapolated from its own past by backward differences of order r, and added to the newest
    sample; of order 0 (e = e_n) that is the line through y_(n-k) and y_n, of order r the
    polynomial of degree r + 1 through y_n, y_(n-k), ..., y_(n-(r+1)k) read k samples ahead:
    y_n + sum_(i=0..r+1) (-1)^i C(r + 2, i + 1) y_(n-ik) - y_n. The extrapolated error is
    smoothed exponentially over ``mulin_smoothing_s`` (the paper smooths and scales it; its
    scaling is here the shrinkage :class:`~.prediction.OnlinePredictor` learns, and the form of
    the smoothing is ours: the paper's text was not available to check it).

    Args:
        dt: the sample step, s. steps: K. axes: m. settings: its ``mulin_*`` fields.
    """

    def __init__(self, dt: float, steps: int, axes: int, settings):
        self.K, self.m = int(steps), int(axes)
        self.r = max(0, int(settings.mulin_order))
        self.alpha = float(1.0 - np.exp(-dt / settings.mulin_smoothing_s))
        self.warm = (self.r + 1) * self.K
        i = np.arange(self.r + 2)
        self.coef = np.array(
            [(-1) ** j * math.comb(self.r + 2, j + 1) for j in range(self.r + 2)], dtype=np.float64
        )
        self._lags = np.arange(1, self.K + 1)[:, None] * i[None, :]  # (K, r + 2): i k
        self._y = np.zeros(((self.r + 1) * self.K + 1, self.m))
        self._e = np.zeros((self.K, self.m))
        self._n = 0

    def update(self, y: np.ndarray) -> np.ndarray:
        """Read sample ``y`` (m,); return (K, m) its expected values 1..K samples later."""
        y = _take_sample(self, y)
        past = self._y[len(self._y) - 1 - self._lags]  # (K, r + 2, m): y_(n - i k)
        raw = np.einsum("i,kim->km", self.coef, past) - y[None, :]
        self._e += self.alpha * (raw - self._e)
        return y[None, :] + self._e


def filter_period(x: np.ndarray, dt: float, period_range_s=PERIOD_RANGE_S) -> float:
    """The period the Kalman filter's model holds for the motion ``x`` (n,) sampled every
    ``dt`` s: its dominant period (:func:`~stewart_drake.base.signals.dominant_period`, the
    strongest spectral peak) when the motion counts as periodic
    (:data:`~stewart_drake.base.signals.PERIOD_POWER_SHARE`) and the period lies in
    ``period_range_s`` (and within half the samples' span), s; NaN when the motion shows no
    such period (at rest, noise, a drift)."""
    x = np.asarray(x, dtype=float)
    period, share = dominant_period(np.arange(x.size) * dt, x)
    top = min(period_range_s[1], 0.5 * x.size * dt)
    if share >= PERIOD_POWER_SHARE and period_range_s[0] <= period <= top:
        return float(period)
    return float("nan")


class HarmonicKalmanModel:
    """A Kalman filter on a breathing model: per axis a baseline and H harmonics of a period
    the motion itself shows, predicted k = 1..K samples ahead in closed form.

    The model is the dynamic linear model with a Fourier-form seasonal component (West &
    Harrison, "Bayesian Forecasting and Dynamic Models", 2nd ed., Springer 1997, ch. 8): state
    [c, p_1, q_1, ..., p_H, q_H], the baseline c a random walk, each harmonic's (p_h, q_h)
    turned by h omega dt at every sample (a harmonic oscillator) and free to drift in amplitude
    and phase; the sample y = c + sum_h p_h + noise. The prediction k samples ahead is
    c + sum_h (p_h cos(h omega k dt) - q_h sin(h omega k dt)). A Kalman filter of respiratory
    motion: Sharp et al., Phys. Med. Biol. 49, 425 (2004); its baseline, frequency and pattern
    followed in real time: Ruan et al., Phys. Med. Biol. 54, 4777 (2009). The filter is the
    textbook one (Joseph form of the covariance update).

    Ours: omega is not in the filter's state but measured, every second, as the period of the
    newest ``kalman_window_s`` of the axis (:func:`filter_period`), first once half the window
    has arrived (the filter then starts on that half, as if run through it); the process noise
    is ``kalman_q`` (harmonics) and ``kalman_q_level`` (baseline) per square root of a second
    times the axis's standard deviation over the window, the sample noise the noise that
    :func:`~.trace_cleaning.noise_estimate` finds in the window (at least ``kalman_r_floor`` of
    the standard deviation); harmonics at or above :data:`NYQUIST_SHARE` of the Nyquist
    frequency are left out. An axis whose motion shows no period predicts its baseline, the
    filtered level.

    Args:
        dt: the sample step, s. steps: K. axes: m. settings: its ``kalman_*`` fields.
    """

    def __init__(self, dt: float, steps: int, axes: int, settings):
        self.dt, self.K, self.m = float(dt), int(steps), int(axes)
        self.H = max(1, int(settings.kalman_harmonics))
        self.n = 1 + 2 * self.H
        self.q, self.q_level = float(settings.kalman_q), float(settings.kalman_q_level)
        self.r_floor = float(settings.kalman_r_floor)
        self.W = max(16, int(round(settings.kalman_window_s / self.dt)))
        self.warm = self.W // 2
        self.every = max(1, int(round(1.0 / self.dt)))
        self._y = np.zeros((self.W, self.m))
        self._n = 0
        self.omega = np.full(self.m, np.nan)  # rad/s, per axis
        self.started = np.zeros(self.m, dtype=bool)
        self.x = np.zeros((self.m, self.n))
        self.P = np.zeros((self.m, self.n, self.n))
        self._F = np.tile(np.eye(self.n), (self.m, 1, 1))
        self._h = np.zeros((self.m, self.n))
        self._h[:, 0] = 1.0
        self._Q = np.zeros((self.m, self.n, self.n))
        self._on = np.zeros((self.m, self.n), dtype=bool)  # the states in the model
        self._R = np.zeros(self.m)
        self._harmonic = np.arange(1, self.H + 1)
        self._k = np.arange(1, self.K + 1)

    # --- the model's matrices -------------------------------------------------------------
    def _set_model(self, axes: np.ndarray, window: np.ndarray) -> None:
        """F, h, Q and R of ``axes`` (bool (m,)) from their omega and ``window`` (L, m)."""
        for a in np.flatnonzero(axes):
            scale = float(np.std(window[:, a]))
            F = np.eye(self.n)
            h = np.zeros(self.n)
            h[0] = 1.0
            on = np.zeros(self.n, dtype=bool)
            on[0] = True
            q = np.zeros(self.n)
            q[0] = (self.q_level * scale) ** 2 * self.dt
            if np.isfinite(self.omega[a]):
                for j, hh in enumerate(self._harmonic):
                    angle = hh * self.omega[a] * self.dt
                    if angle >= NYQUIST_SHARE * math.pi:
                        break
                    c, s = math.cos(angle), math.sin(angle)
                    F[1 + 2 * j : 3 + 2 * j, 1 + 2 * j : 3 + 2 * j] = [[c, -s], [s, c]]
                    h[1 + 2 * j] = 1.0
                    on[1 + 2 * j : 3 + 2 * j] = True
                    q[1 + 2 * j : 3 + 2 * j] = (self.q * scale) ** 2 * self.dt
            self._F[a], self._h[a], self._Q[a], self._on[a] = F, h, np.diag(q), on
            noise = noise_estimate(window[:, a])
            self._R[a] = max(noise**2, (self.r_floor * scale) ** 2, 1e-30)
            # Harmonics left out keep no state.
            self.x[a, ~on] = 0.0
            self.P[a][~on, :] = 0.0
            self.P[a][:, ~on] = 0.0

    def _step(self, axes: np.ndarray, y: np.ndarray) -> None:
        """One prediction and update of the filters of ``axes`` (int indices) with ``y``."""
        F, h, P, x = self._F[axes], self._h[axes], self.P[axes], self.x[axes]
        x = np.einsum("aij,aj->ai", F, x)
        P = F @ P @ np.swapaxes(F, 1, 2) + self._Q[axes]
        S = np.einsum("ai,aij,aj->a", h, P, h) + self._R[axes]
        gain = np.einsum("aij,aj->ai", P, h) / S[:, None]
        x = x + gain * (y[axes] - np.einsum("ai,ai->a", h, x))[:, None]
        ikh = np.eye(self.n)[None] - gain[:, :, None] * h[:, None, :]
        P = ikh @ P @ np.swapaxes(ikh, 1, 2) + self._R[axes][:, None, None] * (
            gain[:, :, None] * gain[:, None, :]
        )
        self.x[axes], self.P[axes] = x, P

    def _start(self, axes: np.ndarray, window: np.ndarray) -> None:
        """Start the filters of ``axes`` (bool (m,)) on ``window`` (L, m), oldest first."""
        self._set_model(axes, window)
        idx = np.flatnonzero(axes)
        scale = np.std(window[:, idx], axis=0) + 1e-12
        self.x[idx] = 0.0
        self.x[idx, 0] = window[0, idx]
        self.P[idx] = np.eye(self.n)[None] * ((4.0 * scale) ** 2)[:, None, None]
        on = self._on[idx]
        self.P[idx] *= on[:, :, None] & on[:, None, :]
        for row in window:
            self._step(idx, row)
        self.started[idx] = True

    # --- the stream -----------------------------------------------------------------------
    def update(self, y: np.ndarray) -> np.ndarray:
        """Read sample ``y`` (m,); return (K, m) its expected values 1..K samples later."""
        y = np.asarray(y, dtype=float)
        self._n += 1
        _ring_push(self._y, y)
        live = np.flatnonzero(self.started)
        if live.size:
            self._step(live, y)
        n = self._n
        if n >= self.warm and (n - self.warm) % self.every == 0:
            window = self._y[-min(n, self.W) :]
            periods = np.array([filter_period(window[:, a], self.dt) for a in range(self.m)])
            found = np.isfinite(periods)
            self.omega = np.where(found, 2 * np.pi / np.where(found, periods, 1.0), self.omega)
            new = ~self.started & (np.ptp(window, axis=0) > 0)
            if new.any():
                self._start(new, window)
            old = self.started & ~new
            if old.any():
                self._set_model(old, window)
        return self.predict(y)

    def predict(self, y: np.ndarray) -> np.ndarray:
        """(K, m) the filters' positions 1..K samples ahead (the newest sample ``y`` (m,) on
        the axes not yet started)."""
        omega = np.where(np.isfinite(self.omega), self.omega, 0.0)
        step = (omega * self.dt)[None, :, None]
        angle = self._k[:, None, None] * self._harmonic[None, None, :] * step  # (K, m, H)
        p, q = self.x[:, 1::2], self.x[:, 2::2]  # (m, H)
        ahead = self.x[None, :, 0] + np.sum(p * np.cos(angle) - q * np.sin(angle), axis=-1)
        return np.where(self.started[None, :], ahead, y[None, :])


class RecurrentModel:
    """A small recurrent neural network trained online by unbiased online recurrent optimisation
    (UORO), all axes at once, predicting each axis's displacement k = 1..K samples ahead.

    After Pohl et al., "Prediction of the position of external markers using a recurrent neural
    network trained with unbiased online recurrent optimization for safe lung cancer
    radiotherapy" (arXiv:2106.01100, 2021; Comput. Methods Programs Biomed., 2022), with UORO as
    Tallec & Ollivier give it ("Unbiased online recurrent optimization", ICLR 2018, algorithm
    1). The network: s_n = tanh(W_a s_(n-1) + W_b u_n + b), q units, read out o_n = W_c s_n +
    c; its input u_n the displacements of the newest sample from the L before it, per axis,
    each over the axis's scale (the exponentially weighted RMS displacement over one sample
    step, forgotten over ``memory_s``: ours, so that rad and m weigh alike); its output the
    displacements 1..K samples ahead in the same scale. The gradient of the squared error
    with respect to the state's parameters is UORO's rank-one unbiased estimate
    (s~ theta~^T of dstate/dparameters, its random signs from a generator seeded at 0, so that a
    run is reproducible), clipped to ``rnn_clip`` in norm, and a step of ``rnn_rate`` taken
    at every sample (plain stochastic gradient descent, as Pohl et al.).

    A pair is learned once its K outcomes have arrived: the network is trained on the samples
    K behind the newest, and predicts by running its trained state on over the K newest
    inputs with the newest weights.

    Args:
        dt: the sample step, s. steps: K. axes: m. settings: its ``rnn_*`` fields and
            ``memory_s``.
    """

    def __init__(self, dt: float, steps: int, axes: int, settings):
        self.K, self.m = int(steps), int(axes)
        self.L = max(1, int(round(settings.rnn_history_s / dt)))
        self.q = int(settings.rnn_units)
        self.rate, self.clip = float(settings.rnn_rate), float(settings.rnn_clip)
        self.warm = self.L + 2 * self.K
        self._lam = float(np.exp(-dt / settings.memory_s))
        rng = np.random.default_rng(0)
        self._rng = rng
        n_in, n_out = self.m * self.L, self.m * self.K
        # Small initial weights, as Pohl et al.'s (Gaussian); the readout at zero: the network
        # starts by predicting no displacement.
        self.Wa = rng.normal(0.0, 1.0 / math.sqrt(self.q), (self.q, self.q)) * 0.5
        self.Wb = rng.normal(0.0, 1.0 / math.sqrt(n_in), (self.q, n_in))
        self.b = np.zeros(self.q)
        self.Wc = np.zeros((n_out, self.q))
        self.c = np.zeros(n_out)
        self.s = np.zeros(self.q)  # the trained state, K samples behind
        self.s_tilde = np.zeros(self.q)
        self.theta_tilde = np.zeros(self.q * self.q + self.q * n_in + self.q)
        self._y = np.zeros((self.L + self.K + 1, self.m))  # newest last
        self._u = np.zeros((self.K + 1, n_in))  # the inputs of the newest K + 1 samples
        self._scale2 = np.zeros(self.m)  # weighted mean squared one-step displacement
        self._weight = 0.0
        self._scales = np.ones((self.K + 1, self.m))
        self._n = 0

    def _input(self) -> np.ndarray:
        """(m L,) the newest sample's input: its displacement from each of the L before it,
        over the axis's scale."""
        y = self._y
        d = (y[-1][None, :] - y[-2 : -2 - self.L : -1]) / self._scales[-1][None, :]
        return d.T.reshape(-1)

    def transition(self, s: np.ndarray, u: np.ndarray) -> np.ndarray:
        """The next state from state ``s`` (q,) and input ``u`` (m L,)."""
        return np.tanh(self.Wa @ s + self.Wb @ u + self.b)

    def _train(self, u: np.ndarray, target: np.ndarray) -> None:
        """One UORO step of the trained state on input ``u``, output ``target`` (m K,)."""
        s_old = self.s
        s_new = self.transition(s_old, u)
        D = 1.0 - s_new**2
        # UORO: s~ theta~^T stays an unbiased estimate of dstate/dparameters.
        nu = self._rng.choice((-1.0, 1.0), size=self.q)
        forward = D * (self.Wa @ self.s_tilde)  # (dF/ds) s~
        nd = nu * D
        backward = np.concatenate([np.outer(nd, s_old).ravel(), np.outer(nd, u).ravel(), nd])
        eps = 1e-12
        rho0 = math.sqrt((np.linalg.norm(self.theta_tilde) + eps) / (np.linalg.norm(forward) + eps))
        rho1 = math.sqrt((np.linalg.norm(backward) + eps) / (np.linalg.norm(nu) + eps))
        self.s_tilde = rho0 * forward + rho1 * nu
        self.theta_tilde = self.theta_tilde / rho0 + backward / rho1
        self.s = s_new
        # The gradient of 0.5 |o - target|^2.
        e = self.Wc @ s_new + self.c - target
        g_state = float((self.Wc.T @ e) @ self.s_tilde) * self.theta_tilde
        g_Wc, g_c = np.outer(e, s_new), e
        norm = math.sqrt(float(g_state @ g_state) + float(np.sum(g_Wc**2)) + float(e @ e))
        step = self.rate * (min(1.0, self.clip / norm) if norm > 0 else 1.0)
        qq, qi = self.q * self.q, self.q * u.size
        self.Wa -= step * g_state[:qq].reshape(self.q, self.q)
        self.Wb -= step * g_state[qq : qq + qi].reshape(self.q, u.size)
        self.b -= step * g_state[qq + qi :]
        self.Wc -= step * g_Wc
        self.c -= step * g_c

    def update(self, y: np.ndarray) -> np.ndarray:
        """Read sample ``y`` (m,); return (K, m) its expected values 1..K samples later."""
        y = _take_sample(self, y)
        step = self._y[-1] - self._y[-2]
        self._scale2 = self._lam * self._scale2 + step * step
        self._weight = self._lam * self._weight + 1.0
        scale = np.sqrt(self._scale2 / self._weight)
        _ring_push(self._scales, np.where(scale > 0, scale, 1.0))
        _ring_push(self._u, self._input())
        if self._n > self.L + self.K:
            # The sample K behind the newest: its input, and its K outcomes, all arrived.
            base = self._y[-1 - self.K]
            target = (self._y[-self.K :] - base[None, :]) / self._scales[0][None, :]
            self._train(self._u[0], target.reshape(-1))
        s = self.s
        for u in self._u[1:]:
            s = self.transition(s, u)
        out = (self.Wc @ s + self.c).reshape(self.K, self.m)
        return y[None, :] + out * self._scales[-1][None, :]


__all__ = [
    "PERIOD_RANGE_S",
    "NYQUIST_SHARE",
    "WaveletLMSModel",
    "MulinModel",
    "filter_period",
    "HarmonicKalmanModel",
    "RecurrentModel",
]
