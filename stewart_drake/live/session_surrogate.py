"""The surrogate's part of a session on the robot (:func:`~.session.run_on_robot` with a
surrogate's trace): the trace checked against the stage before the port is opened, the
carriage's command on the run's clock (with the platform's lag matched, when the bus asks for
it), and the pair's relative latency from the encoders at the end.
"""

from __future__ import annotations

import numpy as np

from ..base.errors import InvalidConfigError


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
    encoders, held to one control period."""
    from ..station.surrogate.encoder_relative_latency import relative_latency

    x_c = homed.evaluate(t)[0]
    return relative_latency(
        t,
        driver.pose_readings(),
        x_c,
        carriage[0],
        carriage[1],
        s_reference=carriage[2],
        delays_s=carriage[3] if driver.surrogate.lag_match is not None else None,
        tolerance_s=driver.period_s,
        t_from=homed.home_s,
        s_count_m=driver.surrogate.config.metres_per_count,
        # A crank's count moves the platform by about its crank's length times the count.
        x_count_m=0.01 * driver.quantum_rad,
    )


__all__ = ["check_surrogate_trace", "command_surrogate", "lag_match", "relative_latency_of_run"]
