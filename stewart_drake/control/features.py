"""Density features of the tracking error and of the motor torques (paper eqs. 35-36).

Eq. 35 as printed, rho_e(t) = (m + 1) e(t) / sum_{i=n-m}^{n} e(t_i), divides by a *signed* window
sum: a tracking error that oscillates around zero makes that sum cross zero and rho_e jump to
+-infinity (eq. 36 likewise for torques that change sign). We use the well-posed variant

    rho(t) = |x(t)| / (mean_{i=n-m..n} |x(t_i)| + eps)
           = (m + 1) |x(t)| / (sum_{i=n-m..n} |x(t_i)| + (m + 1) eps)

per channel (docs/paper_notes.md, "Eqs. 35-36"). It keeps the paper's meaning (about 1 for a
steady signal, up to m + 1 for a spike above the recent average) and is finite and bounded,
0 <= rho <= m + 1, for every finite input. :func:`density_features` (numpy, used for the data
set) and :class:`DensityFeatures` (the Drake system) compute the numbers with one function
(``_rho``), so the closed loop and the data set cannot disagree.

Non-finite inputs (NaN, +-inf) are an error, never clamped: they mean the simulation or the log
already diverged, and a clamped feature would hide that.
"""

from __future__ import annotations

import math

import numpy as np
from pydrake.systems.framework import LeafSystem

from ..base.checks import as_array, as_number, check_int
from ..base.errors import InvalidConfigError, SimulationDivergedError

N_CHANNELS = 6  # six pose errors, six motor torques
N_FEATURES = 2 * N_CHANNELS  # rho = [rho_e (6,), rho_T (6,)]
DEFAULT_WINDOW = 50  # m + 1 samples
DEFAULT_EPS = 1e-9


def _check_window_eps(window: int, eps: float) -> None:
    check_int("window (m + 1 samples)", window, 1)
    # eps > 0 keeps eq. 35 defined when the window is all zeros.
    as_number("eps (> 0, the floor of eq. 35's denominator)", eps, 0.0, lo_open=True)


def _signals(name: str, x) -> np.ndarray:
    """Finite float samples; density features need them: drop or fix a diverged run."""
    return as_array(f"{name} (density features need finite samples)", x)


def _rho(window: np.ndarray, n_valid, eps: float) -> np.ndarray:
    """Core of eqs. 35-36 (well-posed variant): the one place the numbers are computed.

    Args:
        window: (..., m + 1, C) samples, oldest first, current last; samples before the first
            valid one are zeros.
        n_valid: valid samples at the end of each window (1..m+1), scalar or (...,).
        eps: > 0, added to the mean of |x|.
    Returns:
        (..., C) |x(t)| / (mean of |x| over the valid samples + eps).
    """
    a = np.abs(window)
    n = np.asarray(n_valid, dtype=float)[..., None, None]
    # Sum of |x| / n rather than sum / n: cannot overflow for finite |x| (each term <= max / n).
    mean_abs = np.sum(a / n, axis=-2)
    return a[..., -1, :] / (mean_abs + eps)


def density_features(e_window, T_window, eps: float = DEFAULT_EPS, n_valid=None) -> np.ndarray:
    """Density features rho = [rho_e, rho_T] of windows of pose errors and torques.

    Args:
        e_window: (..., m + 1, 6) pose errors e_bar [rad, rad, rad, m, m, m], oldest sample
            first, the current sample e_bar(t) last.
        T_window: (..., m + 1, 6) motor torques T, N m, same ordering and length.
        eps: > 0, in the units of each signal: added to the window mean of |x| so that an
            all-zero window gives rho = 0 (dimensionless output, so eps sets the smallest signal
            that counts as "not zero").
        n_valid: how many samples at the end of each window are real (1..m+1), the rest being
            zero padding at the start of a run; None means all of them. Scalar or (...,).
    Returns:
        (..., 12) rho = [rho_e (6,), rho_T (6,)], dimensionless, 0 <= rho <= m + 1;
        rho_x = |x(t)| / (mean of |x| over the last n_valid samples + eps).
    Raises:
        InvalidConfigError (a ValueError): a non-finite sample (names the array and index),
            mismatched shapes, eps <= 0 or n_valid outside 1..m+1.
    Source: paper eqs. 35-36, with |.| and eps so the denominator cannot cross zero
        (docs/paper_notes.md).
    """
    e_window = _signals("e_window", e_window)
    T_window = _signals("T_window", T_window)
    if e_window.ndim < 2 or e_window.shape[-1] != N_CHANNELS or e_window.shape != T_window.shape:
        raise InvalidConfigError(
            f"e_window and T_window must both be (..., m + 1, 6), got "
            f"{e_window.shape} and {T_window.shape}"
        )
    length = e_window.shape[-2]
    _check_window_eps(length, eps)
    n = length if n_valid is None else as_array("n_valid", n_valid)
    if np.any(n < 1) or np.any(n > length):
        raise InvalidConfigError(f"n_valid must be in 1..{length} (the window length), got {n}")
    return np.concatenate([_rho(e_window, n, eps), _rho(T_window, n, eps)], axis=-1)


def density_features_series(
    e, T, window: int = DEFAULT_WINDOW, eps: float = DEFAULT_EPS
) -> np.ndarray:
    """Density features at every sample of a time series, as :class:`DensityFeatures` gives them.

    Sample k uses the samples max(0, k - m)..k (a shorter window during the first m samples of a
    run), exactly like the Drake system sampling the same signals at the same period.

    Args:
        e: (N, 6) pose errors e_bar [rad, rad, rad, m, m, m], one row per feature period.
        T: (N, 6) motor torques, N m.
        window: m + 1, samples per window.
        eps: see :func:`density_features`.
    Returns:
        (N, 12) rho = [rho_e, rho_T] per sample, dimensionless.
    Raises:
        InvalidConfigError (a ValueError): non-finite samples, shapes other than (N, 6),
            window < 1 or eps <= 0.
    Source: paper eqs. 35-36 (well-posed variant, docs/paper_notes.md).
    """
    e = _signals("e", e)
    T = _signals("T", T)
    if e.ndim != 2 or e.shape[1] != N_CHANNELS or e.shape != T.shape:
        raise InvalidConfigError(f"e and T must both be (N, 6), got {e.shape} and {T.shape}")
    _check_window_eps(window, eps)
    pad = np.zeros((window - 1, N_CHANNELS))
    view = np.lib.stride_tricks.sliding_window_view
    # (N, 6, window) -> (N, window, 6): same layout as the system's buffer, zeros first.
    e_win = view(np.vstack([pad, e]), window, axis=0).swapaxes(-1, -2)
    T_win = view(np.vstack([pad, T]), window, axis=0).swapaxes(-1, -2)
    n_valid = np.minimum(np.arange(1, len(e) + 1), window)
    return density_features(e_win, T_win, eps, n_valid)


class DensityFeatures(LeafSystem):
    """Density of the tracking error and of the motor torques (paper eqs. 35-36).

    Input ports (sampling, the default):
        ``e_bar`` (6,): pose error [rad, rad, rad, m, m, m].
        ``T`` (6,): motor torques, N m.
    Input port (``buffered=True``):
        ``feature_window`` (12 window + 2,): the same samples, buffered by the controller at its
            instants (contract port ``feature_window``: rows [e_bar, T], n_valid, head).
    Output port:
        ``rho`` (12,) = [rho_e (6,), rho_T (6,)], dimensionless, of the samples taken so far.
    Discrete state (sampling only): a ring buffer (window x 12) of [e_bar, T] rows and
    [n_valid, head] (2,). rho is :func:`density_features` of the last min(k + 1, window)
    samples, computed when read and cached; no direct feedthrough. Eq. 35 divides by a signed
    window sum that can cross zero; we divide by the window mean of |.| plus ``eps`` instead
    (docs/paper_notes.md, "Eqs. 35-36", with the two ways of sampling).

    Args:
        window: m + 1, samples per window (50).
        period_s: sampling period, s (1 ms, the control period).
        eps: see :func:`density_features`.
        offset_s: time of the first sample, s, in [0, period_s) (the Diagram: the controller's).
        buffered: read the controller's ``feature_window`` instead of sampling.
    Raises:
        InvalidConfigError: window < 1, period_s <= 0, eps <= 0 or offset_s outside [0, period_s).
        SimulationDivergedError: (during simulation, sampling) a non-finite input sample, not
            clamped: the loop has diverged (a buffering controller raises it itself).
    """

    def __init__(
        self,
        window: int = DEFAULT_WINDOW,
        period_s: float = 1e-3,
        eps: float = DEFAULT_EPS,
        offset_s: float = 0.0,
        buffered: bool = False,
    ):
        super().__init__()
        _check_window_eps(window, eps)
        if not (np.isfinite(period_s) and period_s > 0):
            raise InvalidConfigError(f"period_s must be > 0 s, got {period_s}")
        if not (np.isfinite(offset_s) and 0 <= offset_s < period_s):
            raise InvalidConfigError(f"offset_s must be in [0, period_s), got {offset_s}")
        self.window = int(window)
        self.period_s = float(period_s)
        self.eps = float(eps)
        self.buffered = bool(buffered)
        if self.buffered:
            self._e = self._T = None
            self._window_in = self.DeclareVectorInputPort(
                "feature_window", self.window * N_FEATURES + 2
            )
            self._rho = self.DeclareVectorOutputPort(
                "rho",
                N_FEATURES,
                self._CalcRho,
                prerequisites_of_calc={self.all_input_ports_ticket()},
            )
            return
        self._e = self.DeclareVectorInputPort("e_bar", N_CHANNELS)
        self._T = self.DeclareVectorInputPort("T", N_CHANNELS)
        self._buf = self.DeclareDiscreteState(self.window * N_FEATURES)
        self._n_index = self.DeclareDiscreteState(2)  # n_valid, head
        self._rho = self.DeclareVectorOutputPort(
            "rho", N_FEATURES, self._CalcRho, prerequisites_of_calc={self.xd_ticket()}
        )
        self.DeclarePeriodicDiscreteUpdateEvent(
            period_sec=self.period_s, offset_sec=float(offset_s), update=self._Update
        )

    def get_e_bar_input_port(self):
        return self._e

    def get_T_input_port(self):
        return self._T

    def get_rho_output_port(self):
        return self._rho

    def _Update(self, context, discrete_state):
        e, T = self._e.Eval(context), self._T.Eval(context)
        if not math.isfinite(e.sum() + T.sum()):  # one reduction: the common case is fast
            sample = np.concatenate([e, T])
            name = "e_bar" if not np.all(np.isfinite(e)) else "T"
            raise SimulationDivergedError(
                f"non-finite {name} = {np.array2string(sample, precision=4)} ([e_bar, T]) at "
                f"the DensityFeatures input (features are not computed from diverged signals)",
                t=context.get_time(),
            )
        counters = discrete_state.get_mutable_value(self._n_index)  # in place: no copies
        head = int(counters[1])
        row = discrete_state.get_mutable_value(self._buf)[
            head * N_FEATURES : (head + 1) * N_FEATURES
        ]
        row[:N_CHANNELS], row[N_CHANNELS:] = e, T
        counters[0] = min(counters[0] + 1, self.window)
        counters[1] = (head + 1) % self.window

    def _CalcRho(self, context, output) -> None:
        if self.buffered:
            window = np.asarray(self._window_in.Eval(context))
            buffer, (n, head) = window[:-2], window[-2:]
        else:
            buffer = context.get_discrete_state(self._buf).get_value()
            n, head = context.get_discrete_state(self._n_index).get_value()
        output.SetFromVector(ring_features(buffer, n, head, self.eps))


def ring_features(buffer, n_valid, head, eps: float = DEFAULT_EPS) -> np.ndarray:
    """rho (12,) of a ring buffer of finite [e_bar, T] rows (window * 12,) whose oldest row is
    ``head`` and last ``n_valid`` rows are samples (zeros before the first sample): the numbers
    of :func:`density_features` (the same ``_rho``), without its checks of the inputs (the
    buffer's writer refuses a non-finite sample)."""
    if n_valid == 0:  # nothing sampled yet
        return np.zeros(N_FEATURES)
    rows = np.roll(np.asarray(buffer).reshape(-1, N_FEATURES), -int(head), axis=0)  # oldest first
    return _rho(rows, n_valid, eps)
