"""The figures of a closed-loop run, defined once: tracking, effort, the feedback torque, step and
frequency responses, and the tuner study's cost.

Every study reads its numbers here: ``run_experiment`` (:func:`compute_metrics`), the evaluation
grid (:func:`normalized_rms`, :func:`feedback_effort`, :func:`settling_time`,
:func:`frequency_response`, :func:`bandwidth_hz`), the tuner study (:func:`sample_costs`,
:func:`window_means`). A result is any object with the arrays of
:class:`~stewart_drake.run.result.RunResult` (``t``, ``x``, ``x_d``, ``T``, ...); SI
units throughout.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..base.errors import InvalidConfigError
from ..base.measures import peak_per_axis, rms_per_axis
from ..robot.kinematics import AXIS_NAMES, AXIS_UNITS
from ..robot.statics import holding_torques

#: Settling band of the step responses, as a fraction of the step.
SETTLING_BAND = 0.02
#: The study cost's scales: 1 mrad | 1 mm of pose error, 0.3 N m of feedback torque (the LQI's
#: default scales, :class:`~stewart_drake.control.lqi.driver.LqiScales`).
ERROR_SCALE, TORQUE_SCALE = 1e-3, 0.3


# -- a run's figures -------------------------------------------------------------------------------


def compute_metrics(
    result, wall_s: float | None = None, window_start_s: float | None = None
) -> dict:
    """Figures of a run.

    Returns:
        dict: ``rms_error`` and ``peak_error`` per axis (rad and m) over t >= window_start_s
        (default: the second half of the run, i.e. [5, 10] s for the paper's 10 s), ``peak_torque``
        (6,) N m, ``sum_T2_dt`` N^2 m^2 s, ``max_closure_m``, ``status`` (the controller's
        status at the end, by name), and for a controller that reports them ``gain_solves`` and
        ``gain_failures``; ``realtime_factor`` (if wall_s).
    Raises:
        InvalidConfigError: fewer than 2 samples in the window (nothing to average: simulate
            longer than one log period).
    """
    t = result.t
    start = t[-1] / 2 if window_start_s is None else window_start_s
    i0 = int(np.searchsorted(t, start - 1e-9))  # the logs' times increase
    if t.size - i0 < 2:
        raise InvalidConfigError(
            f"a run of {t[-1]:g} s has {t.size - i0} logged sample(s) "
            f"after t = {start:g} s: too short for metrics; simulate longer"
        )
    # Axis by axis, in float64: a long run's intermediates are one column at a time.
    rms, peak = [], []
    for k in range(6):
        e = np.subtract(result.x[i0:, k], result.x_d[i0:, k], dtype=float)
        rms.append(float(rms_per_axis(e)))
        peak.append(float(peak_per_axis(e)))
    metrics = {
        "window_s": [float(start), float(t[-1])],
        "rms_error": rms,
        "peak_error": peak,
        "peak_torque": np.abs(result.T).max(axis=0).tolist(),
        "sum_T2_dt": effort(result.t, result.T),
        "max_closure_m": float(result.closure.max()),
        "status": {name: float(v) for name, v in zip(result.status_names, result.status[-1])},
        "finite": bool(np.all(np.isfinite(result.x)) and np.all(np.isfinite(result.T))),
    }
    for name in ("gain_solves", "gain_failures"):
        if name in metrics["status"]:
            metrics[name] = int(metrics["status"][name])
    if wall_s is not None:
        metrics["wall_s"] = float(wall_s)
        metrics["realtime_factor"] = float(t[-1] / wall_s) if wall_s > 0 else float("inf")
    return metrics


def tracking_error(result) -> np.ndarray:
    """(N, 6) x - x_d of the true pose (from the plant state, free of sensor noise), rad and m."""
    return result.x[:, :6] - result.x_d[:, :6]


def effort(t, T) -> float:
    """Sum T^2 dt of torques T (N, 6) logged at times t (N,), N^2 m^2 s (rectangle rule, the
    first sample weighted 0)."""
    dt = np.diff(t, prepend=t[0])
    T = np.asarray(T)
    return float(sum(np.dot(dt, np.square(T[:, k], dtype=float)) for k in range(T.shape[1])))


def normalized_rms(rms, pose_scales) -> float:
    """sqrt(mean_i (rms_i / s_i)^2): one tracking figure from the RMS error per axis (6,), with
    the LQI's error scales ``pose_scales`` (6,) (1 mrad, 1 mm by default), so angles and
    positions count alike."""
    return float(np.sqrt(np.mean((np.asarray(rms) / np.asarray(pose_scales)) ** 2)))


def feedback_torque(result, geometry) -> np.ndarray:
    """(N, 6) what the controller adds to holding the platform up, N m: the applied torques
    minus the static holding torques of the reference pose
    (:func:`~stewart_drake.robot.statics.holding_torques` of the robot the controller believes
    in). Gravity's share is the same for every controller, so efforts are compared on this."""
    return result.T - holding_torques(geometry, result.x_d[:, :6])


def feedback_effort(result, geometry) -> float:
    """Sum (T - T_hold)^2 dt, N^2 m^2 s: the effort of :func:`feedback_torque`."""
    return effort(result.t, feedback_torque(result, geometry))


# -- step and frequency responses ------------------------------------------------------------------


def settling_time(t, error, size: float, t_step: float, band: float = SETTLING_BAND):
    """Time after ``t_step`` from which |error| stays within band * |size|, s (None if never).

    Args:
        t: (N,) s. error: (N,) x - x_d on the stepped axis (rad or m). size: the step.
    """
    t = np.asarray(t)
    after = t >= t_step
    outside = after & (np.abs(error) > band * abs(size))
    if not np.any(after):
        return None
    if not np.any(outside):
        return 0.0
    last = int(np.flatnonzero(outside)[-1])
    if last == len(t) - 1:
        return None  # still outside at the end of the run
    return float(t[last + 1] - t_step)


def overshoot(error, size: float) -> float:
    """The largest excursion of ``error`` (N,) past the target in the step's direction, as a
    fraction of |size| (0 when it never overshoots)."""
    return float(max(0.0, np.max(np.sign(size) * error) / abs(size)))


def frequency_response(t, y, chirp, cycles_per_segment: float = 2.0):
    """Gain and phase of y against a sine sweep, segment by segment.

    Each segment spans ``cycles_per_segment`` cycles of the sweep; on it y - offset is fitted by
    least squares with A(t) (a sin(phase) + b cos(phase)) + c, A the sweep's envelope
    (:meth:`~stewart_drake.references.trajectories.ChirpTrajectory.envelope`), and the gain is
    |a + i b| and the phase arg(a + i b) (y ~ gain A sin(phase of the sweep + phase)).

    Args:
        t: (N,) s. y: (N,) the swept axis of the pose. chirp: the
            :class:`~stewart_drake.references.trajectories.ChirpTrajectory`.
    Returns:
        (f (K,) Hz, gain (K,), phase (K,) rad, unwrapped from segment to segment: negative when
        y lags the sweep). The first segment is dropped (the start transient), so f starts one
        segment into the sweep (2.4 Hz for the 1 -> 50 Hz sweep of 8 s): report ``f[0]``, not
        the sweep's nominal start.
    """
    t = np.asarray(t)
    y = np.asarray(y) - chirp.offset[chirp.axis]
    m = t <= chirp.duration_s
    t, y = t[m], y[m]
    ph = chirp.phase(t)
    seg = np.floor(ph / (2 * np.pi * cycles_per_segment)).astype(int)
    f, gain, phase = [], [], []
    for k in np.unique(seg)[1:]:  # the first segment holds the start transient
        sel = seg == k
        if sel.sum() < 8:
            continue
        A = chirp.envelope(t[sel])[0]
        basis = np.stack([A * np.sin(ph[sel]), A * np.cos(ph[sel]), np.ones(sel.sum())], axis=1)
        (a, b, _), *_ = np.linalg.lstsq(basis, y[sel], rcond=None)
        f.append(float(np.mean(chirp.frequency(t[sel]))))
        gain.append(float(np.hypot(a, b)))
        phase.append(float(np.arctan2(b, a)))
    return np.array(f), np.array(gain), np.unwrap(np.array(phase))


#: What a -3 dB bandwidth is relative to the frequencies measured (:class:`Bandwidth`).
BANDWIDTH_CROSSING = "crossing"
BANDWIDTH_BELOW, BANDWIDTH_ABOVE = "below the sweep", "above the sweep"


@dataclass(frozen=True)
class Bandwidth:
    """A -3 dB bandwidth as a sweep measures it.

    Attributes:
        hz: the frequency where the gain first falls below -3 dB, log-interpolated between the
            last point above and the first below, Hz; None when the sweep holds no such pair.
        where: :data:`BANDWIDTH_CROSSING` (``hz`` is the bandwidth), :data:`BANDWIDTH_BELOW`
            (the gain is already below -3 dB at the first frequency: the bandwidth, if any, is
            lower than the sweep), :data:`BANDWIDTH_ABOVE` (the gain never falls below -3 dB:
            the bandwidth is higher than the sweep).
        f_min, f_max: the sweep's first and last frequency, Hz (NaN for an empty sweep).
    """

    hz: float | None
    where: str
    f_min: float
    f_max: float

    def text(self, digits: int = 3) -> str:
        """ "36.3", "< 2.43 (below the sweep)" or "> 49.4 (above the sweep)"."""
        if self.where == BANDWIDTH_CROSSING:
            return f"{self.hz:.{digits}g}"
        if self.where == BANDWIDTH_BELOW:
            return f"< {self.f_min:.{digits}g} ({BANDWIDTH_BELOW})"
        return f"> {self.f_max:.{digits}g} ({BANDWIDTH_ABOVE})"


def bandwidth_hz(f, gain) -> Bandwidth:
    """The -3 dB bandwidth (gain 1/sqrt 2) of a frequency response: the lowest frequency where
    the gain falls below it, log-interpolated between the last point above and the first below.

    It never names a frequency the sweep did not bracket: a gain already below -3 dB at the
    sweep's first frequency is "below the sweep", a gain that never falls below it is "above the
    sweep" (:class:`Bandwidth`).

    Args:
        f: (K,) increasing frequencies, Hz. gain: (K,) |y / y_d| (linear, not dB).
    """
    f, gain = np.asarray(f, dtype=float), np.asarray(gain, dtype=float)
    f_min, f_max = (float(f[0]), float(f[-1])) if len(f) else (np.nan, np.nan)
    below = np.flatnonzero(~(gain >= 1 / np.sqrt(2)))  # a NaN gain counts as below
    if len(below) == 0:
        return Bandwidth(None, BANDWIDTH_ABOVE, f_min, f_max)
    k = int(below[0])
    if k == 0:
        return Bandwidth(None, BANDWIDTH_BELOW, f_min, f_max)
    g0, g1 = np.log(gain[k - 1]), np.log(max(gain[k], 1e-300))
    w = (np.log(1 / np.sqrt(2)) - g0) / (g1 - g0)
    hz = float(np.exp(np.log(f[k - 1]) + w * (np.log(f[k]) - np.log(f[k - 1]))))
    return Bandwidth(hz, BANDWIDTH_CROSSING, f_min, f_max)


# -- the tuner study's cost ------------------------------------------------------------------------


def sample_costs(result, geometry) -> tuple[np.ndarray, np.ndarray]:
    """(e2 (N,), u2 (N,)): per sample, the squared tracking error and the squared
    :func:`feedback_torque`, each normalized by its scale (:data:`ERROR_SCALE`,
    :data:`TORQUE_SCALE`) and summed over the axes; the tuner study's cost at lambda is
    J = mean(e2 + lambda u2)."""
    e = tracking_error(result) / ERROR_SCALE
    u = feedback_torque(result, geometry) / TORQUE_SCALE
    return (e**2).sum(axis=1), (u**2).sum(axis=1)


def window_means(
    t: np.ndarray, values: np.ndarray, duration_s: float, window_s: float
) -> np.ndarray:
    """(n_windows,) mean of values (N,) over each ``window_s`` window of [0, duration_s)."""
    n = int(round(duration_s / window_s))
    index = np.minimum((t / window_s + 1e-9).astype(int), n - 1)
    sums = np.bincount(index, weights=values, minlength=n)
    counts = np.maximum(np.bincount(index, minlength=n), 1)
    return sums / counts


def format_metrics(metrics: dict, whose: str = "") -> str:
    """Human-readable summary (mrad / mm / N m) of :func:`~.metrics.compute_metrics`'s dict;
    ``whose``: whose pose the error is of, said in the first line (a robot's session measures
    the pose its encoders read, not the platform's)."""
    w0, w1 = metrics["window_s"]
    of = f" of {whose}" if whose else ""
    lines = [f"RMS tracking error{of} over t in [{w0:g}, {w1:g}] s:"]
    for axis, unit, v, p in zip(
        AXIS_NAMES, AXIS_UNITS, metrics["rms_error"], metrics["peak_error"]
    ):
        lines.append(f"  {axis:>5}: {1e3 * v:10.3g} {unit} RMS  (peak {1e3 * p:.3g} {unit})")
    lines.append(
        "peak |T| per motor [N m]: " + " ".join(f"{v:.3f}" for v in metrics["peak_torque"])
    )
    lines.append(f"sum T^2 dt: {metrics['sum_T2_dt']:.4g} N^2 m^2 s")
    lines.append(f"max loop-closure error: {metrics['max_closure_m']:.3g} m")
    status = dict(metrics.get("status", {}))
    if "gain_solves" in status:
        lines.append(
            f"gain re-schedules: {int(status.pop('gain_solves'))} "
            f"({int(status.pop('gain_failures', 0))} failed, last good gain kept)"
        )
    counts = {k: v for k, v in status.items() if k not in ("omega_Q", "omega_R", "integral_norm")}
    if counts:
        lines.append(
            "controller status: "
            + ", ".join(f"{k.replace('_', ' ')} {v:g}" for k, v in counts.items())
        )
    if "first_contact" in metrics:
        c = metrics["first_contact"]
        lines.append(
            "contact between parts: none"
            if c is None
            else f"first contact between parts: {c['parts'][0]} and {c['parts'][1]} at "
            f"t = {c['t']:.4g} s ({c['force_N']:.3g} N)"
        )
    if "realtime_factor" in metrics:
        lines.append(
            f"real-time factor: {metrics['realtime_factor']:.2f} "
            f"({metrics['window_s'][1]:.1f} s sim / {metrics['wall_s']:.2f} s wall)"
        )
    if "temperature_note" in metrics:  # a run warmer or colder than its robot's calibration
        lines.append(metrics["temperature_note"])
    return "\n".join(lines)
