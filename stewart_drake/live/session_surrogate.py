"""The surrogate's part of a session on the robot (:func:`~.session.run_on_robot` with a
surrogate's trace): the trace checked against the stage before the port is opened, the
carriage's command on the run's clock (with the platform's lag matched, when the bus asks for
it), and the pair's relative latency from the encoders at the end, judged.

**The relative latency from the encoders.**
Each axis is judged against its own reference on the reference's own clock, the one clock of
both references (the encoder log's ``t_path``: the Diagram's time of each control period
warped by the run's start and end ramps, the clock ``verify --surrogate`` reads the log on):

- the **lag** L of an axis is the shift delta that minimises the RMS difference between what
  its encoders measured, y(t_k), and its reference shifted later by delta, c(t_k - delta), less
  their mean difference (a constant offset, as the Diagram's pair report removes it) (the
  reference joined between its logged samples by a cubic spline; delta searched in
  [-``max_lag_s``, +``max_lag_s``], every shift on the samples' step at once by FFT, then refined
  by a bounded scalar minimisation to 1 us: :func:`stewart_drake.base.lag.signal_lag`,
  IntERAct's RMSE alignment, Kaczynska et al. 2026, in continuous shifts). L > 0: the axis moves
  after its reference.
- the platform's y and c: its pose from the crank encoders (forward kinematics) and the
  reference's pose, along the **principal direction** of the reference's translations over the
  judged window (:func:`~stewart_drake.base.signals.principal_direction`, as the Diagram's pair
  report and lag matching take it), m; the surrogate's: the carriage's position from its servo's
  encoder (``s``) and its reference on the run's clock (``s_ref``: its trace where the
  platform's reference is, before any delay lag matching gave its command), m. So a delay given
  to the carriage's command to match the platform's lag
  (:mod:`~stewart_drake.station.surrogate.lag_matching`) is part of the surrogate's lag, and judged,
  not assumed; the servo's own lag behind the command it was given (``s_cmd``) is reported
  beside it.
- the **relative latency** is L_platform - L_surrogate, s, the one relative latency
  (:func:`~stewart_drake.base.pair_figures.relative_latency`, the Diagram's pair report's too):
  **positive when the platform (the
  internal target) follows its command later than the surrogate follows its own**, the sign
  ``verify --surrogate`` and IntERAct's analysis use (``shift6D - shift1D``,
  RMSEAlignMethod.m); its verdict holds it to ``tolerance_s`` (one control period by default: the
  acceptance of the emulated pair).

The window judged: the periods from the end of the homing lead-in on (``t >= t_from``), less
``max_lag_s`` at each end so that every shift compares the same samples. An axis whose command
moves less than 20 encoder counts' worth over the window has no lag to measure (NaN, said).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import cast

import numpy as np

from ..base.errors import InvalidConfigError
from ..base.lag import inner_mask, signal_lag
from ..base.pair_figures import LAG_SEARCH_S, relative_latency
from ..base.signals import direction_words
from ..base.verdicts import verdict as verdict_word
from ..base.verdicts import within


def check_surrogate_trace(scenario, surrogate) -> None:
    """Refuse, before the port is opened, a surrogate's trace without a surrogate's servo on
    the bus, shorter than the run, or outside the stage's travel or speed.

    Raises:
        InvalidConfigError: names what and by how much.
    """
    from ..station.surrogate.bus_servo import check_surrogate_path

    config = scenario.bus.surrogate
    if config is None:
        raise InvalidConfigError(
            "--surrogate drives the surrogate's servo on the bus: the scenario's bus has no "
            "surrogate section (bus.surrogate: its id, model, lead and travel; docs/robot.md)"
        )
    if surrogate.duration_s < scenario.duration_s - 1e-9:
        raise InvalidConfigError(
            f"--surrogate {surrogate.path} lasts {surrogate.duration_s:g} s, the run "
            f"{scenario.duration_s:g} s: give --duration {surrogate.duration_s:g} or less"
        )
    t = np.arange(0.0, scenario.duration_s, 0.5 * scenario.control_period_s)
    s, v, _ = surrogate.evaluate(t)
    check_surrogate_path(config, s, v, f"--surrogate {surrogate.path}")


def command_surrogate(driver, surrogate, homed, scenario) -> None:
    """Give the driver's surrogate its command on the run's clock from where its carriage was read
    (:class:`~stewart_drake.station.surrogate.carriage.SurrogateCommand`, sampled on the control
    period's grid over the run's ``duration_s``), the whole path, lead-in included, checked
    against the stage first.

    Raises:
        InvalidConfigError: the carriage rests outside the travel, or the lead-in is too fast.
    """
    from ..station.surrogate.bus_servo import check_surrogate_path
    from ..station.surrogate.carriage import SurrogateCommand

    drive, period_s = driver.surrogate, scenario.control_period_s
    command = SurrogateCommand(surrogate, homed, drive.held[0])
    s, v, _ = command.evaluate(np.arange(0.0, homed.duration_s, 0.5 * period_s))
    check_surrogate_path(drive.config, s, v, "the surrogate's lead-in and trace")
    drive.command = command.sampled(period_s, scenario.duration_s)
    #: The carriage's reference on the run's clock, before any lag matching's delay: what
    #: the run's relative latency judges the carriage against.
    drive.reference = command
    if drive.config.match_platform_lag:
        drive.lag_match = lag_match(homed, period_s, scenario.duration_s)


def lag_match(homed, period_s: float, t_end: float):
    """The platform's lag estimator (:class:`~..station.surrogate.lag_matching.PlatformLagMatch`)
    on its reference sampled every period to ``t_end``, along the principal direction of its
    translations after the lead-in (:func:`~stewart_drake.base.signals.principal_direction`:
    the direction the run's relative latency judges, and the Diagram's lag matching follows)."""
    from ..base.signals import principal_direction
    from ..station.surrogate.lag_matching import PlatformLagMatch

    t = np.arange(int(np.ceil(t_end / period_s)) + 1) * period_s
    x, v, _ = homed.evaluate(t)
    after = t >= homed.home_s
    moving = x[after] if np.count_nonzero(after) > 1 else x
    u = principal_direction(moving)
    r, r_dot = x[:, 3:6] @ u, v[:, 3:6] @ u
    if not np.ptp(moving[:, 3:6] @ u) > 0:  # a reference that holds still has no lag to learn
        r, r_dot = np.zeros_like(r), np.zeros_like(r_dot)
    return PlatformLagMatch(period_s, r, r_dot, u)


def relative_latency_of_run(driver, homed, t, carriage):
    """The relative latency of the run's periods after the homing lead-in, from the
    encoders, held to one control period; on the reference's own clock (the warped clock of
    its start and end ramps, :meth:`~..references.homing.HomingReference.reference_time`, the
    encoder log's ``t_path``), as ``verify --surrogate`` measures it on the log: each period at
    the reference's time it was asked, the periods after the path ends (its time held) left
    out."""
    t = np.asarray(t, dtype=float)
    tau = homed.reference_time(t)
    after = np.flatnonzero(t >= homed.home_s)
    after = after[np.diff(tau[after], prepend=-np.inf) > 0]  # tau never falls
    s_m, s_c, s_ref, delays = (np.asarray(v, dtype=float)[after] for v in carriage)
    return judged_relative_latency(
        tau[after],
        np.asarray(driver.pose_readings(), dtype=float)[after],
        homed.evaluate(t[after])[0],
        s_m,
        s_c,
        s_reference=s_ref,
        delays_s=delays if driver.surrogate.lag_match is not None else None,
        tolerance_s=driver.period_s,
        s_count_m=driver.surrogate.config.metres_per_count,
        # A crank's count moves the platform by about its crank's length times the count.
        x_count_m=0.01 * driver.quantum_rad,
    )


#: The longest lag searched, s: the pair's (:data:`~stewart_drake.base.pair_figures.LAG_SEARCH_S`).
MAX_LAG_S = LAG_SEARCH_S
#: Fewest samples a window must hold.
MIN_SAMPLES = 20


def axis_lag(t, measured, commanded, max_lag_s: float = MAX_LAG_S, still_below: float = 0.0):
    """The lag of one axis (module docstring), s: the shift delta minimising
    RMS(measured(t_k) - commanded(t_k - delta)) over the inner samples.

    Args:
        t: (n,) sample times, s, increasing. measured, commanded: (n,) the axis measured and
            commanded at them (same unit).
        max_lag_s: the search's half-width, s.
        still_below: a command whose peak to peak is at most this has no lag (NaN).
    Returns:
        (lag s, NaN for a still command; the RMS residual at it, the axis's unit).
    Raises:
        InvalidConfigError: shapes that differ, times not increasing, a value not finite, fewer
            than :data:`MIN_SAMPLES` samples inside the search's margins.
    """
    t, y, c = (np.asarray(v, dtype=float) for v in (t, measured, commanded))
    if t.ndim != 1 or y.shape != t.shape or c.shape != t.shape:
        raise InvalidConfigError(
            f"the times, measured and commanded samples must be (n,) alike, got {t.shape}, "
            f"{y.shape}, {c.shape}"
        )
    # The package's one lag search: every shift by FFT on the samples' step, then to 1 us.
    return signal_lag(
        t, y, c, max_lag_s, offsets=True, still_below=still_below, min_samples=MIN_SAMPLES
    )


@dataclass(frozen=True)
class RelativeLatency:
    """The platform's and the surrogate's lags and their difference (module docstring).

    Attributes:
        relative_s: L_platform - L_surrogate, s (> 0: the platform lags); NaN when an axis
            is still.
        surrogate_lag_s, platform_lag_s: each axis's lag against its own command, s.
        platform_axis: the direction the platform is judged along, in words ("X", "Y", "Z" or
            its components: :func:`~stewart_drake.base.signals.direction_words`).
        surrogate_rms_m, platform_rms_m: the RMS residual at each lag, m.
        tolerance_s: the verdict's bound on |relative_s|, s. samples: samples judged.
        servo_lag_s: the carriage's lag behind the command it was given (``s_cmd``), s;
            NaN when judged against that command itself.
        matching_delay_s: the mean delay lag matching gave the carriage's command over the
            window, s (NaN: none was given).
        platform_direction: (3,) the unit direction the platform is judged along: the principal
            direction of its reference's translations over the window.
    """

    relative_s: float
    surrogate_lag_s: float
    platform_lag_s: float
    platform_axis: str
    surrogate_rms_m: float
    platform_rms_m: float
    tolerance_s: float
    samples: int
    servo_lag_s: float = math.nan
    matching_delay_s: float = math.nan
    platform_direction: tuple = (0.0, 0.0, 1.0)

    @property
    def passed(self) -> bool:
        """|relative_s| <= tolerance_s (False when it is NaN)."""
        return within(self.relative_s, self.tolerance_s)

    def line(self) -> str:
        """The verdict in one line, naming what it compares."""
        against = "s_ref, its trace" if self.servo_lag_s == self.servo_lag_s else "s_cmd"
        what = (
            "relative latency, platform after surrogate (each axis's lag behind its own "
            f"reference on the reference's clock, from its encoders: the carriage's s against "
            f"{against}"
            f", the platform's {self.platform_axis} against the reference's)"
        )
        matched = ""
        if self.matching_delay_s == self.matching_delay_s:
            matched = (
                f"; its command delayed {1e3 * self.matching_delay_s:+.1f} ms on average by lag "
                f"matching, its servo {1e3 * self.servo_lag_s:+.1f} ms behind that command"
            )
        lags = (
            f"surrogate {1e3 * self.surrogate_lag_s:+.1f} ms (RMS {1e6 * self.surrogate_rms_m:.0f}"
            f" um{matched}), platform {1e3 * self.platform_lag_s:+.1f} ms (RMS "
            f"{1e6 * self.platform_rms_m:.0f} um) over {self.samples} periods"
        )
        bound = f"|relative| <= {1e3 * self.tolerance_s:g} ms (one control period)"
        if self.relative_s != self.relative_s:
            still = [
                n
                for n, lag in (
                    ("the surrogate", self.surrogate_lag_s),
                    ("the platform", self.platform_lag_s),
                )
                if lag != lag
            ]
            return f"{what}: not measured, {' and '.join(still)} did not move; FAIL: {bound}"
        verdict = verdict_word(self.passed)
        # Two decimals: a figure at the bound reads on its side of it (-10.04 ms, not -10.0).
        return f"{what}: {1e3 * self.relative_s:+.2f} ms ({lags}); {verdict}: {bound}"


def _samples(what: str, shape: tuple, *values) -> list[np.ndarray]:
    """``values`` as float arrays, each of ``shape``.

    Raises:
        InvalidConfigError: "``what`` must be ``shape``", with the shapes given.
    """
    arrays = [np.asarray(v, dtype=float) for v in values]
    if any(a.shape != shape for a in arrays):
        raise InvalidConfigError(
            f"{what} must be {shape}, got {' and '.join(str(a.shape) for a in arrays)}"
        )
    return arrays


def judged_relative_latency(
    t,
    x_measured,
    x_commanded,
    s_measured,
    s_commanded,
    tolerance_s: float,
    t_from: float = -math.inf,
    max_lag_s: float = MAX_LAG_S,
    s_count_m: float = 0.0,
    x_count_m: float = 0.0,
    s_reference=None,
    delays_s=None,
) -> RelativeLatency:
    """The relative latency of a run from its encoders, judged (:class:`RelativeLatency`).

    Args:
        t: (n,) the periods' run times, s. x_measured, x_commanded: (n, 6) the platform's
            pose from its encoders and the reference's, rad and m. s_measured, s_commanded:
            (n,) the carriage's position read and commanded, m.
        s_reference: (n,) the carriage's reference on the run's clock (before lag matching's
            delay), m: the surrogate's lag is judged against it, and its servo's lag behind
            ``s_commanded`` reported beside; None: judged against ``s_commanded``.
        delays_s: (n,) the delay lag matching gave the carriage's command each period, s
            (its mean over the window is reported); None: none.
        tolerance_s: the verdict's bound, s (one control period). t_from: the window's start
            (the end of the homing lead-in), s.
        s_count_m, x_count_m: one encoder count of each axis, m: a command moving less than
            20 of them is still (no lag).
    Raises:
        InvalidConfigError: as :func:`axis_lag`'s; shapes that differ; tolerance not > 0.
    """
    t = np.asarray(t, dtype=float)
    x_m, x_c = _samples("the poses", (t.size, 6), x_measured, x_commanded)
    if not 0 < tolerance_s < math.inf:
        raise InvalidConfigError(f"tolerance_s must be > 0 s, got {tolerance_s}")
    window = t >= t_from
    t_w = t[window]
    s_m, s_c = _samples("the surrogate's samples", t.shape, s_measured, s_commanded)
    still = 20 * s_count_m
    servo_lag, s_judged = math.nan, s_c
    if s_reference is not None:
        (s_judged,) = _samples("the surrogate's reference", t.shape, s_reference)
        servo_lag, _ = axis_lag(t_w, s_m[window], s_c[window], max_lag_s, still_below=still)
    # The one relative latency (base.pair_figures, the Diagram's pair report's too): the
    # platform's lag along the principal direction of its reference's translations over the
    # window, the one lag matching uses too.
    pair = relative_latency(
        t_w,
        x_c[window],
        x_m[window],
        s_judged[window],
        s_m[window],
        max_lag_s,
        still_internal=20 * x_count_m,
        still_external=still,
        min_samples=MIN_SAMPLES,
    )
    u = cast(tuple, pair.direction)  # poses given: a direction found, never None
    delay = math.nan
    if delays_s is not None:
        (d,) = _samples("the delays", t.shape, delays_s)
        judged = d[window][inner_mask(t_w, max_lag_s)]  # the samples the lags compared
        if np.any(np.isfinite(judged)):
            delay = float(np.nanmean(judged))
    return RelativeLatency(
        relative_s=pair.relative_s,
        surrogate_lag_s=pair.external_lag_s,
        platform_lag_s=pair.internal_lag_s,
        platform_axis=direction_words(np.array(u)),
        platform_direction=u,
        surrogate_rms_m=pair.external_rms_m,
        platform_rms_m=pair.internal_rms_m,
        tolerance_s=float(tolerance_s),
        samples=pair.samples,
        servo_lag_s=float(servo_lag),
        matching_delay_s=delay,
    )


__all__ = [
    "RelativeLatency",
    "axis_lag",
    "check_surrogate_trace",
    "command_surrogate",
    "judged_relative_latency",
    "lag_match",
    "relative_latency_of_run",
]
