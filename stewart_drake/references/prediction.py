"""Predictors of a motion known only as it arrives: each axis's position a few samples ahead of
the newest, adapted online, with its uncertainty from its recent residuals and a fallback to no
prediction whenever it is doing worse.

A predictor reads one sample at a time (:meth:`OnlinePredictor.update`) and returns the
positions it expects 1..K samples later; it never sees a sample before it has arrived, and the
pairs it learns from are only those whose outcome has arrived (a pair for k samples ahead is
learned k samples after its input). :data:`PREDICTORS` names them:

- ``none``: the newest sample, held (no prediction).
- ``linear``: adaptive linear regression (the predictors of Ernst et al. 2013 and Krauss et al.
  2011 of which this is the plainest): for each axis and each k, the displacement k samples
  ahead as a linear function of the displacements of the newest sample from the ``history_s``
  before it, fitted by exponentially weighted ridge least squares (the normal equations' sums
  decay with time constant ``memory_s``; every step ahead shares the features, so one matrix
  per axis is factorised at each sample, :class:`LinearModel`).
- ``wlms``: the wavelet-based multiscale regression of Ernst et al. 2007
  (:class:`~.predictors.WaveletLMSModel`).
- ``mulin``: the multi-step linear extrapolation of the error of no prediction of Ernst &
  Schweikard 2008 (:class:`~.predictors.MulinModel`).
- ``kalman``: a Kalman filter on a breathing model, a baseline and the harmonics of the period
  the motion shows (:class:`~.predictors.HarmonicKalmanModel`).
- ``rnn``: a small recurrent network trained online by UORO, after Pohl et al. 2021
  (:class:`~.predictors.RecurrentModel`).

:class:`OnlinePredictor` wraps each model with what keeps its predictions from doing harm,
applied in this order:

1. the **outliers** (``outlier_k``; off unless set), to the sample as it arrives: a sample
   further from the position put forward for it one sample earlier than ``outlier_k`` times
   the mean such distance lately (per axis, each distance counted at most that far) and than
   :data:`OUTLIER_STEPS` times the largest step between samples the motion has lately made (the
   bound's) is taken as a glitch of the tracker (a reflection, a marker swap): the position put
   forward stands in for it on that axis, for the model and for the curve the follower draws
   through its samples (``OnlinePredictor.sample``), at most :data:`MAX_REJECTED_RUN`
   samples in a row (a step the motion truly makes is taken after them); counted;
2. the **envelope**, to the positions predicted: every prediction is clipped to the motion's
   recent range (its samples of the last ``envelope_s``, or all so far), widened by
   :data:`ENVELOPE_MARGIN` of it (a prediction never asks for more than the motion has lately
   done: a peak is not made larger than the motion makes it);
3. the **bound** on the displacement (``bound_s``): the displacement predicted k samples ahead
   is at most, widened by the same margin, the largest displacement over k samples the motion
   itself has made lately (a peak hold forgotten with time constant ``bound_s``), so a noisy
   sample or a step in the samples is not extrapolated beyond what the motion does;
4. the **shrinkage** (``shrink``): per axis and k, the displacement is multiplied by the gain
   g in [0, 1] that would have served best over the completed pairs of the last ``gain_s``
   (least squares of the outcome's displacement on the predicted one, exponentially weighted),
   so a model whose predicted displacements are partly noise is followed only that part of
   the way;
5. the **record** that decides, per axis, whether its predictions are used: the exponentially
   weighted mean squared error at every k of what is put forward and of no prediction over the
   last ``record_s``; the model is taken up on an axis once its record there is below
   (1 - ``record_margin``) times no prediction's (and has ``min_record_s`` of residuals), and
   dropped (a fallback, counted) as soon as it is no longer below no prediction's: the
   hysteresis keeps a model that merely ties with no prediction from switching at every
   sample, and a model that stops paying is dropped at once. On an axis at rest (no
   prediction's record within :data:`QUIET_RMS`) a model whose record is no worse is taken up
   as well: there it moves the reference by less than that, and it is then in use when the
   motion starts again, instead of a switch (:data:`~.stream.SWITCH_S`) after its record has
   shown it pays (a motion that rests between excursions is otherwise followed without
   prediction on the first second of each). Where it is not used the newest sample is held.
   The same record gives the uncertainty: the RMS residual of what is used. The record starts
   once the model's first predictions mean something (its ``warm``: a regression fitted on a
   few samples predicts wildly, and would weigh on the record long after).

The bound and the shrinkage are ours; the literature's predictors are usually run on the
samples as they come, and the study that chose them is in docs/organ_motion.md ("Choosing the
predictor").
"""

from dataclasses import dataclass
from typing import Any

import numpy as np

from ..base.checks import check_int
from ..base.errors import InvalidConfigError
from .predictors import HarmonicKalmanModel, MulinModel, RecurrentModel, WaveletLMSModel

#: The predictors by name; the first is no prediction.
PREDICTORS = ("none", "linear", "wlms", "mulin", "kalman", "rnn")
#: The predictor ``reproduce --stream`` uses unless told: the selection study's choice on the
#: library's motions and IntERAct's traces (docs/organ_motion.md, "Choosing the predictor").
DEFAULT_PREDICTOR = "linear"
#: The widening of the motion's recent range that a prediction may reach, a fraction of it.
ENVELOPE_MARGIN = 0.1
#: The most displacements the regression reads, whatever the stream's rate: it factorises a
#: matrix of this size per axis at every sample (64: 2.56 s at 25 Hz one sample apart; a longer
#: history, or a faster stream, reads every second sample or more).
MAX_LAGS = 64
#: The most samples in a row an axis may have taken as outliers; the next is taken as it is.
MAX_REJECTED_RUN = 2
#: A sample is an outlier only beyond this many times the largest step between samples the
#: motion has lately made.
OUTLIER_STEPS = 1.1
#: The least distance from the position put forward that may make a sample an outlier, in the
#: axis's unit (m or rad): 10 um or 10 urad, below any tracker's glitch.
OUTLIER_FLOOR = 1e-5
#: An axis is at rest for the record when no prediction's RMS residual there is within this, in
#: the axis's unit (m or rad): 1 um or 1 urad, below any tracker's noise (tens of um) and the
#: robot's resolution (an encoder count of a 110 mm crank is 0.17 mm at its end).
QUIET_RMS = 1e-6


@dataclass(frozen=True)
class PredictorSettings:
    """The settings of the predictors, in seconds so that they mean the same at any sample rate
    (each predictor reads its own; the record, the bound and the shrinkage serve them all).

    Attributes:
        history_s: the past the linear regression reads, s (``round(history_s / dt)``
            displacements, at least 2; beyond :data:`MAX_LAGS`, every second sample or more:
            :meth:`lag_stride`).
        memory_s: time constant of the forgetting of the regression's sums, s.
        ridge: the ridge, relative to the mean of the diagonal of the regression's sums.
        record_s: time constant of the residuals' record (the fallback and the uncertainty), s.
        min_record_s: residuals needed before the model may be used, s.
        gain_s: time constant of the sums the shrinkage's gain is fitted on, s.
        bound_s: time constant of the forgetting of the largest recent displacement that bounds
            the predicted one, s; None: no bound.
        envelope_s: the past whose range (widened) holds every prediction, s; None: the whole
            run so far.
        record_margin: the hysteresis of the record, in [0, 1): the share by which the model's
            record must beat no prediction's before it is taken up.
        outlier_k: how many times its recent mean distance a sample must be from the position
            put forward for it to be taken as an outlier; None: none is.
        shrink: whether the predicted displacement is shrunk by its fitted gain.
        wlms_scales: wLMS's detail scales J (the coarsest reads 2^J samples).
        wlms_depth: wLMS's values read per scale, a.
        wlms_window_s: wLMS's least squares window, s (``round(wlms_window_s / dt)`` pairs).
        wlms_mu: wLMS's step towards each window's solution, in (0, 1].
        mulin_order: MULIN's order r (0: a line, r: a polynomial of degree r + 1).
        mulin_smoothing_s: time constant of MULIN's smoothing of its extrapolated error, s.
        kalman_harmonics: the harmonics of the period the Kalman filter's model holds, H.
        kalman_q: process noise of each harmonic's amplitude, per square root of a second,
            relative to the axis's standard deviation.
        kalman_q_level: the same of the baseline.
        kalman_r_floor: least sample noise the filter assumes, relative to the axis's standard
            deviation.
        kalman_window_s: the newest samples the period and the noise are measured on, s.
        rnn_units: the recurrent network's units, q.
        rnn_history_s: the past its input reads, s (``round(rnn_history_s / dt)``
            displacements, at least 1).
        rnn_rate: its learning rate (a step of stochastic gradient descent per sample).
        rnn_clip: the largest norm of its gradient step.
    Raises:
        InvalidConfigError: a value not finite and > 0 (``ridge`` >= 0; ``wlms_mu`` in (0, 1];
            the counts integers >= 1, ``mulin_order`` >= 0; ``bound_s`` None or > 0).
    """

    # The defaults: history, the record needed before use, the hysteresis, the envelope's window and
    # the outliers (off) are the choice across sources, each left out in turn (docs/organ_motion.md,
    # "Chosen across sources", studies/stream_selection.py); memory and ridge the earlier
    # tuning on the library's motions (memory 30-120 s within 0.005 of the mean ratio; a ridge of
    # 1e-6 beat 1e-3 by 0.05); the bound and the shrinkage "Choosing the predictor"'s. The other
    # models' settings were not tuned (one setting each, from their papers or ours).
    history_s: float = 4.0
    memory_s: float = 30.0
    ridge: float = 1e-6
    record_s: float = 10.0
    min_record_s: float = 2.0
    gain_s: float = 30.0
    bound_s: float | None = 20.0
    envelope_s: float | None = 120.0
    record_margin: float = 0.1
    outlier_k: float | None = None
    shrink: bool = True
    wlms_scales: int = 3
    wlms_depth: int = 2
    wlms_window_s: float = 0.5
    wlms_mu: float = 0.3
    mulin_order: int = 1
    mulin_smoothing_s: float = 0.1
    kalman_harmonics: int = 3
    kalman_q: float = 0.3
    kalman_q_level: float = 0.1
    kalman_r_floor: float = 1e-3
    kalman_window_s: float = 20.0
    rnn_units: int = 16
    rnn_history_s: float = 1.0
    rnn_rate: float = 0.02
    rnn_clip: float = 2.0

    def __post_init__(self):
        positive = (
            "history_s", "memory_s", "record_s", "min_record_s", "gain_s", "wlms_window_s",
            "mulin_smoothing_s", "kalman_q", "kalman_q_level", "kalman_r_floor",
            "kalman_window_s", "rnn_history_s", "rnn_rate", "rnn_clip",
        )  # fmt: skip
        optional = ("bound_s", "envelope_s", "outlier_k")
        for name in positive + ("ridge", "wlms_mu", "record_margin") + optional:
            v = getattr(self, name)
            if name in optional and v is None:
                continue
            ok = isinstance(v, (int, float)) and not isinstance(v, bool) and np.isfinite(v)
            if name == "ridge":
                ok, words = ok and v >= 0, ">= 0"
            elif name == "wlms_mu":
                ok, words = ok and 0 < v <= 1, "in (0, 1]"
            elif name == "record_margin":
                ok, words = ok and 0 <= v < 1, "in [0, 1)"
            else:
                ok, words = ok and v > 0, "> 0"
            if not ok:
                raise InvalidConfigError(
                    f"predictor setting {name} must be a finite number {words}, got {v!r}"
                )
        for name, low in (
            ("wlms_scales", 1), ("wlms_depth", 1), ("mulin_order", 0), ("kalman_harmonics", 1),
            ("rnn_units", 1),
        ):  # fmt: skip
            check_int(f"predictor setting {name}", getattr(self, name), low)
        if not isinstance(self.shrink, bool):
            raise InvalidConfigError(
                f"predictor setting shrink must be True or False, got {self.shrink!r}"
            )

    def lag_stride(self, dt: float) -> int:
        """Samples between the displacements the regression reads at a sample step ``dt`` (s):
        1 unless ``history_s`` holds more than :data:`MAX_LAGS` samples, then the fewest that
        keep their count within it (a faster stream reads the same history, more coarsely)."""
        return max(1, -(-int(round(self.history_s / dt)) // MAX_LAGS))

    def lags(self, dt: float) -> int:
        """Displacements the regression reads at a sample step ``dt`` (s): ``history_s`` in
        steps of :meth:`lag_stride` samples, at least 2 and at most :data:`MAX_LAGS`."""
        stride = self.lag_stride(dt)
        return min(MAX_LAGS, max(2, int(round(self.history_s / (dt * stride)))))

    def samples_needed(self, dt: float, steps: int) -> int:
        """Samples a stream needs before the model can be used at all: its history, the
        steps ahead it predicts and ``min_record_s`` of residuals."""
        history = self.lags(dt) * self.lag_stride(dt)
        return history + steps + max(1, int(round(self.min_record_s / dt)))


def check_predictor(name: str) -> str:
    """``name`` when it is one of :data:`PREDICTORS`.

    Raises:
        InvalidConfigError: an unknown predictor, naming the known ones.
    """
    if name not in PREDICTORS:
        raise InvalidConfigError(
            f"unknown predictor {name!r}: choose one of {', '.join(PREDICTORS)}"
        )
    return name


class HoldModel:
    """No prediction: the newest sample at every step ahead."""

    warm = 0

    def __init__(self, steps: int, axes: int):
        self.steps, self.axes = int(steps), int(axes)

    def update(self, y: np.ndarray) -> np.ndarray:
        """(K, m) the newest sample ``y`` (m,) repeated."""
        return np.repeat(np.asarray(y, dtype=float)[None, :], self.steps, axis=0)


class LinearModel:
    """Adaptive linear regression of each axis k = 1..K samples ahead (module docstring).

    Features of sample i: x_i = [y_i - y_{i-s}, y_i - y_{i-2s}, ..., y_i - y_{i-ps}] per axis, s
    the stride (:meth:`PredictorSettings.lag_stride`, 1 unless the history holds more than
    :data:`MAX_LAGS` samples; the first sample repeated before the stream's start); target of
    the pair for k: y_{j+k} - y_j, learned at sample j + k. Sums R_k = sum lambda^(i-j) x_j
    x_j^T and r_k = sum lambda^(i-j) x_j (y_{j+k} - y_j), lambda = exp(-dt / memory_s); weights
    w_k = (R_k + delta I)^-1 r_k with delta = ridge x mean(diag R_k) (plus 1e-30: a motion at
    rest predicts no displacement).

    Every step ahead reads the same features, so R_k at sample i is the sum S_n = sum_(j <= n)
    lambda^(n-j) x_j x_j^T of one recursion, k samples old (n = i - k): each sample adds one
    outer product per axis and factorises one matrix per axis (the inverse of its Cholesky
    factor: LAPACK's ``dpotrf`` and ``dtrtri``, through scipy), which every step ahead reuses for
    the K samples after it. A sample costs O(m p^3 / 3) for the factor and O(K m p^2) for
    the weights, against O(K m p^3) for a solve per axis and step.

    Args:
        dt: the sample step, s (> 0). steps: K. axes: m. settings: :class:`PredictorSettings`.
    """

    def __init__(self, dt: float, steps: int, axes: int, settings: PredictorSettings):
        self.p, self.K, self.m = settings.lags(dt), int(steps), int(axes)
        self.stride = settings.lag_stride(dt)
        self.warm = self.p * self.stride + self.K  # its first pairs complete
        self.lam = float(np.exp(-dt / settings.memory_s))
        self.ridge = float(settings.ridge)
        # The newest samples, newest last: the history read and the steps ahead learned.
        self._y = np.zeros((self.p * self.stride + self.K + 1, self.m))
        self._x = np.zeros((self.K + 1, self.m, self.p))  # features of the newest K + 1
        self._S = np.zeros((self.m, self.p, self.p))  # S_n of the newest sample
        # F_n, (S_n + delta_n I)^-1 = F_n^T F_n (F_n lower triangular) per axis of the newest
        # K + 1 samples, in a ring: sample n in slot n mod (K + 1); _Ft its transposes (a view).
        self._F = np.zeros((self.K + 1, self.m, self.p, self.p))
        self._Ft = np.swapaxes(self._F, -1, -2)
        self._r = np.zeros((self.K, self.m, self.p))
        self._n = 0
        self._eye = np.eye(self.p)
        from scipy.linalg import lapack  # here: importing it costs 0.1 ms at every sample

        self._lapack = lapack

    def update(self, y: np.ndarray) -> np.ndarray:
        """Read sample ``y`` (m,); return (K, m) its expected values 1..K samples later."""
        lapack = self._lapack
        y = np.asarray(y, dtype=float)
        if self._n == 0:
            self._y[:] = y  # the first sample repeated before the stream's start
        self._y[:-1] = self._y[1:]
        self._y[-1] = y
        i = self._n  # this sample's index
        self._n += 1
        s = self.stride
        x = (y[None, :] - self._y[-1 - s : -1 - s * (self.p + 1) : -s]).T  # (m, p): y_i - y_{i-ls}
        self._x[:-1] = self._x[1:]
        self._x[-1] = x
        # The pairs that have just completed: input k samples ago, outcome now.
        k = np.arange(1, self.K + 1)
        ready = (i - k) >= 0
        xk = self._x[-1 - k] * ready[:, None, None]  # (K, m, p)
        target = (y[None, :] - self._y[-1 - k]) * ready[:, None]  # (K, m)
        self._r = self.lam * self._r + xk * target[..., None]
        # S_i, and the inverse Cholesky factor of S_i + delta_i I into the ring.
        self._S *= self.lam
        self._S += x[:, :, None] * x[:, None, :]
        delta = self.ridge * np.trace(self._S, axis1=1, axis2=2) / self.p + 1e-30
        normal = self._S + delta[:, None, None] * self._eye
        factor = np.empty_like(normal)
        for a in range(self.m):
            c, info = lapack.dpotrf(normal[a], lower=1, clean=1)
            if info == 0:
                factor[a], info = lapack.dtrtri(c, lower=1, overwrite_c=1)
            if info != 0:  # not positive definite to rounding: no prediction on the axis
                factor[a] = 0.0
        self._F[i % (self.K + 1)] = factor
        # w_k = (R_k + delta I)^-1 r_k = F^T F r_k, F from the ring by slot (r_k put in sample
        # i - k's).
        order = (i - k) % (self.K + 1)
        r = np.zeros((self.K + 1, self.m, self.p, 1))
        r[order, ..., 0] = self._r
        w = (self._Ft @ (self._F @ r))[order, ..., 0]  # (K, m, p)
        return y[None, :] + np.einsum("kmp,mp->km", w, x)


#: The models by name (:data:`PREDICTORS`), each built as ``model(dt, steps, axes, settings)``.
#: The models by name, each built (dt, steps, axes, settings) with ``warm`` and ``update(y)``.
MODELS: dict[str, Any] = {
    "none": lambda dt, steps, axes, settings: HoldModel(steps, axes),
    "linear": LinearModel,
    "wlms": WaveletLMSModel,
    "mulin": MulinModel,
    "kalman": HarmonicKalmanModel,
    "rnn": RecurrentModel,
}


class OnlinePredictor:
    """A predictor (:data:`PREDICTORS`) with its envelope, its bound, its shrinkage and its
    record of residuals: the fallback to no prediction and the uncertainty (module docstring).

    Args:
        name: one of :data:`PREDICTORS`. dt: the sample step, s. steps: K, the samples ahead
            predicted. axes: m. settings: :class:`PredictorSettings` (default the shipped).
    Attributes:
        using: (m,) bool, whether the model's predictions are used on each axis now.
        sigma: (K, m) RMS residual of what is used, per step ahead (rad or m; NaN before any).
        gain: (K, m) the shrinkage's gain now, in [0, 1] (1 without shrinkage).
        clipped: predicted positions moved by the envelope or the bound (count).
        fallbacks: the times an axis's model was dropped for no prediction (count).
        rejected: samples' axes taken as outliers (count).
        sample: (m,) the newest sample as followed: the outliers' axes replaced.
    Raises:
        InvalidConfigError: an unknown predictor; dt or steps not > 0.
    """

    def __init__(
        self, name: str, dt: float, steps: int, axes: int, settings: PredictorSettings | None = None
    ):
        check_predictor(name)
        if not (np.isfinite(dt) and dt > 0 and steps >= 1):
            raise InvalidConfigError(
                f"a predictor needs dt > 0 s and steps >= 1, got {dt}, {steps}"
            )
        self.name, self.dt, self.K, self.m = name, float(dt), int(steps), int(axes)
        self.settings = settings or PredictorSettings()
        self.model = MODELS[name](self.dt, self.K, self.m, self.settings)
        self._mu = float(np.exp(-self.dt / self.settings.record_s))
        self._min_n = max(1, int(round(self.settings.min_record_s / self.dt)))
        self._past = np.zeros((self.K + 1, self.K, self.m))  # the newest K + 1 put forward
        self._past_d = np.zeros((self.K + 1, self.K, self.m))  # their bounded displacements
        self._y = np.zeros((self.K + 1, self.m))  # the newest K + 1 samples
        self._se = np.zeros((2, self.K, self.m))  # weighted squared residuals: model, none
        self._w = np.zeros(self.K)  # their weights
        self._count = np.zeros(self.K, dtype=int)
        self._k = np.arange(1, self.K + 1)
        self._residual = np.zeros((2, self.K, self.m))
        self._n = 0
        # The record starts when the model's predictions mean something.
        self._warm = int(self.model.warm)
        self._low: np.ndarray | None = None
        self._high: np.ndarray | None = None
        self.clipped = 0
        self.fallbacks = 0
        self.rejected = 0
        self.sample = np.zeros(self.m)
        self._distance = np.zeros(self.m)  # weighted sum of the distances from what was put forward
        self._distance_w = 0.0
        self._run = np.zeros(self.m, dtype=int)
        self.using = np.zeros(self.m, dtype=bool)
        # The recent envelope: the range of each block of about a second, the newest blocks kept.
        envelope_s = self.settings.envelope_s
        self._block = max(1, int(round(1.0 / self.dt)))
        blocks = (
            0 if envelope_s is None else max(1, int(np.ceil(envelope_s / (self._block * self.dt))))
        )
        self._blocks_low = np.full((blocks, self.m), np.inf)
        self._blocks_high = np.full((blocks, self.m), -np.inf)
        self._in_block = 0
        self.sigma = np.full((self.K, self.m), np.nan)
        # The bound: the largest displacement over k samples, held and forgotten.
        bound_s = self.settings.bound_s
        self._hold = None if bound_s is None else float(np.exp(-self.dt / bound_s))
        self._largest = np.zeros((self.K, self.m))
        # The shrinkage: sums of d^2 and d (outcome's displacement), weighted.
        self._lam_g = float(np.exp(-self.dt / self.settings.gain_s))
        self._sxx = np.zeros((self.K, self.m))
        self._sxy = np.zeros((self.K, self.m))
        self.gain = (
            np.ones((self.K, self.m)) if not self.settings.shrink else np.zeros((self.K, self.m))
        )

    def update(self, y) -> np.ndarray:
        """Read sample ``y`` (m,) [rad or m]; return (K, m) the positions used 1..K samples
        later: the model's on the axes where its record is better than no prediction's, the
        newest sample held on the others."""
        predicted = self.raw_update(y)
        return np.where(self.using[None, :], predicted, np.asarray(y, dtype=float)[None, :])

    def raw_update(self, y) -> np.ndarray:
        """As :meth:`update`, but (K, m) the model's positions on every axis (within the
        envelope and the bound, shrunk), whatever the record chose (``using`` says that)."""
        y = self._cleaned(np.asarray(y, dtype=float).reshape(self.m))
        self.sample = y
        self._n += 1
        self._y[:-1] = self._y[1:]
        self._y[-1] = y
        self._record(y)
        self._learn_gain(y)
        raw = self.model.update(y)
        bounded = self._bounded(raw, y)
        displacement = bounded - y[None, :]
        self.clipped += int(np.count_nonzero(bounded != raw))
        predicted = y[None, :] + self.gain * displacement if self.settings.shrink else bounded
        self._past_d[:-1] = self._past_d[1:]
        self._past_d[-1] = displacement
        self._past[:-1] = self._past[1:]
        self._past[-1] = predicted
        return predicted

    def _bounded(self, predicted: np.ndarray, y: np.ndarray) -> np.ndarray:
        """``predicted`` (K, m) clipped to the recent range of the samples, widened by
        :data:`ENVELOPE_MARGIN` of it, and its displacement from ``y`` to the largest recent
        displacement over as many samples, widened alike."""
        kept = self._blocks_low.size > 0
        if self._low is None or self._high is None:
            self._low, self._high = y.copy(), y.copy()
        elif kept and self._in_block == 0:  # a block starts: the one finished joins the kept
            self._blocks_low = np.roll(self._blocks_low, -1, axis=0)
            self._blocks_high = np.roll(self._blocks_high, -1, axis=0)
            self._blocks_low[-1], self._blocks_high[-1] = self._low, self._high
            self._low, self._high = y.copy(), y.copy()
        np.minimum(self._low, y, out=self._low)
        np.maximum(self._high, y, out=self._high)
        low, high = self._low, self._high
        if kept:
            self._in_block = (self._in_block + 1) % self._block
            low = np.minimum(low, self._blocks_low.min(axis=0))
            high = np.maximum(high, self._blocks_high.max(axis=0))
        margin = ENVELOPE_MARGIN * (high - low)
        bounded = np.clip(predicted, low - margin, high + margin)
        if self._hold is not None:
            k = self._k
            ready = (self._n - 1 - k) >= 0
            moved = np.abs(y[None, :] - self._y[-1 - k]) * ready[:, None]  # (K, m)
            self._largest = np.maximum(self._hold * self._largest, moved)
            reach = (1.0 + ENVELOPE_MARGIN) * self._largest
            bounded = y[None, :] + np.clip(bounded - y[None, :], -reach, reach)
        return bounded

    def _cleaned(self, y: np.ndarray) -> np.ndarray:
        """``y`` with the axes it is an outlier on (module docstring, 1) replaced by the
        position put forward for it a sample ago."""
        k = self.settings.outlier_k
        if k is None or self.name == "none" or self._count[0] < self._min_n:
            return y
        expected = self._past[-1, 0]
        distance = np.abs(y - expected)
        scale = np.maximum(self._distance / max(self._distance_w, 1e-300), OUTLIER_FLOOR)
        # Beyond the largest step between samples the motion has lately made, too: a surprise
        # within a step (a breath unlike the last) is the motion's own.
        reach = OUTLIER_STEPS * self._largest[0]
        far = (distance > k * scale) & (distance > reach)
        out = far & (self._run < MAX_REJECTED_RUN) & (self._distance_w > 0)
        self._distance = self._mu * self._distance + np.minimum(distance, k * scale)
        self._distance_w = self._mu * self._distance_w + 1.0
        self._run = np.where(out, self._run + 1, 0)
        self.rejected += int(np.count_nonzero(out))
        return np.where(out, expected, y)

    def _learn_gain(self, y: np.ndarray) -> None:
        """The pairs completed at ``y``: the bounded displacement predicted k samples ago
        against the displacement that came, into the shrinkage's sums; then its gain."""
        if not self.settings.shrink:
            return
        k = self._k
        ready = ((self._n - 1 - k) >= self._warm)[:, None]
        d = self._past_d[-k, k - 1]  # (K, m)
        outcome = y[None, :] - self._y[-1 - k]
        self._sxx = self._lam_g * self._sxx + ready * d * d
        self._sxy = self._lam_g * self._sxy + ready * d * outcome
        with np.errstate(invalid="ignore", divide="ignore"):
            g = np.where(self._sxx > 0, self._sxy / self._sxx, 0.0)
        self.gain = np.clip(g, 0.0, 1.0)

    def _record(self, y: np.ndarray) -> None:
        """The residuals of the predictions made k samples ago (k = 1..K) at ``y``, into the
        record; then the choice per axis and the uncertainty."""
        k = self._k
        ready = (self._n - 1 - k) >= self._warm
        residual = self._residual
        residual[0] = self._past[-k, k - 1]  # (K, m): the model's, made k samples ago
        residual[1] = self._y[-1 - k]  # the newest sample then, held
        residual -= y
        residual *= residual
        residual *= ready[None, :, None]
        self._se *= self._mu
        self._se += residual
        self._w = self._mu * self._w + ready
        self._count += ready
        if self.name == "none" or self._count[-1] < self._min_n:
            self.using[:] = False
        else:
            model, none = self._se[0].sum(axis=0), self._se[1].sum(axis=0)
            margin = np.where(self.using, 1.0, 1.0 - self.settings.record_margin)
            quiet = none <= QUIET_RMS**2 * self._w.sum()  # at rest: the tie taken up
            using = (model < margin * none) | (quiet & (model <= none))
            self.fallbacks += int(np.count_nonzero(self.using & ~using))
            self.using = using
        with np.errstate(invalid="ignore", divide="ignore"):
            mse = self._se / self._w[None, :, None]
        self.sigma = np.sqrt(np.where(self.using[None, :], mse[0], mse[1]))


__all__ = [
    "PREDICTORS",
    "DEFAULT_PREDICTOR",
    "ENVELOPE_MARGIN",
    "MAX_LAGS",
    "MAX_REJECTED_RUN",
    "OUTLIER_FLOOR",
    "QUIET_RMS",
    "PredictorSettings",
    "check_predictor",
    "HoldModel",
    "LinearModel",
    "MODELS",
    "OnlinePredictor",
]
