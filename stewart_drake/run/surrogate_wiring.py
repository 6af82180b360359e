"""The external surrogate's stage in the run's Diagram, beside the platform on the same clock
(:func:`add_surrogate`; a scenario's ``surrogate``): what
:func:`~stewart_drake.run.diagram.build_diagram` adds when the scenario has one."""

from __future__ import annotations

import numpy as np
from pydrake.systems.framework import OutputPort

from ..base.errors import InvalidConfigError
from ..base.signals import principal_direction
from ..station.surrogate.stage import SurrogatePorts, add_surrogate_stage
from .plan import RunPlan
from .run_logs import SignalLog


def add_surrogate(builder, plan: RunPlan, trajectory, meshcat, loggers: dict, platform=None):
    """With the scenario's ``surrogate``, its stage beside the platform on the same clock: the
    external signal made once from the run's reference (recorded, or through the correlation
    model), sampled at the controller's instants (the platform's period and offset), the stage
    added (:func:`~stewart_drake.station.surrogate.stage.add_surrogate_stage`; with
    ``match_platform_lag`` its goal as late as the platform is on its reference, measured from
    ``platform``, the station's pose of the platform: the plant's, read as it is at the
    sample, where the robot reads its encoders; not the controller's estimate, which is held
    from the previous period and would read as one period more late) and logged as
    "surrogate" (5: [p m, v m/s, p_d m, v_d m/s, a_d m/s^2], float64, every log period).
    Returns (the stage's ports or None, the signal or None).

    Raises:
        InvalidConfigError: a live reference (no motion known in advance to correlate with), a
            signal the stage cannot follow (:meth:`~stewart_drake.station.surrogate.stage.
            SurrogateStage.check_signal`).
    """
    axis = plan.scenario.surrogate
    if axis is None:
        return None, None
    if trajectory is None:
        raise InvalidConfigError(
            "the surrogate follows a signal known in advance; a live reference has none: set "
            "surrogate: null"
        )
    h, offset, duration = plan.control_period_s, plan.sample_offset_s, plan.duration_s
    signal = axis.signal(trajectory, duration)
    samples = axis.samples(signal, duration, h, offset)
    match = None
    if axis.match_platform_lag and platform is not None:
        from ..station.surrogate.lag_matching import PlatformLagMatch

        # Along the internal motion's principal direction, as the pair's report measures
        # the target's delay (base.pair_figures.relative_latency).
        x, v, _ = trajectory.evaluate(samples[0])
        u = signal.direction
        if u is None:  # not known: the principal direction of the samples
            u = principal_direction(x)
        match = PlatformLagMatch(h, x[:, 3:6] @ u, v[:, 3:6] @ u, u, t0=float(samples[0][0]))
    ports = add_surrogate_stage(
        builder,
        axis.stage,
        samples,
        h,
        offset,
        plan.plant_time_step_s,
        meshcat,
        lag_match=match,
        platform_state=platform,
    )
    log = SignalLog.add(
        builder,
        "log_surrogate",
        {"surrogate": (_concatenated(builder, ports), np.float64)},
        plan.log_period_s,
        duration,
    )
    loggers["surrogate"] = log.logger("surrogate")
    return ports, signal


def _concatenated(builder, ports: SurrogatePorts) -> OutputPort:
    """[state (2,), goal (3,)] of the stage as one port."""
    from pydrake.systems.primitives import Multiplexer

    mux = builder.AddNamedSystem("surrogate_log_mux", Multiplexer([2, 3]))
    builder.Connect(ports.state, mux.get_input_port(0))
    builder.Connect(ports.goal, mux.get_input_port(1))
    return mux.get_output_port()


__all__ = ["add_surrogate"]
