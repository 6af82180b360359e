"""What a scenario's loop survives of what the catalogue does not know: one answer for every
controller we ship (:func:`loop_robustness`), stated by ``analyze`` and required by ``design``.

The requirement and the scan are :mod:`stewart_drake.control.robustness`' (plant gain 0.5 to 2,
with 6 ms more delay for a loop the host closes); each loop's exact sampled model is its own:

* the paper's LQI (:func:`lqi_robust_range`): its linear closed loop at the pose
  (:func:`~.loop_analysis.loop_models`: the plant as simulated, the LQI as designed), the
  torque reaching the mechanics ``g`` times the command and the extra delay as whole control
  periods, rounded up (the linear model's delay is a shift register of periods);
* the crank servo: :func:`stewart_drake.control.servo.margins.robust_range`;
* the servos' own position loop: :func:`stewart_drake.station.bus.position_margins.
  position_robust_range` (the bus's delay is outside it).
"""

from __future__ import annotations

import math

import numpy as np

from ..base.errors import InvalidConfigError
from ..control.robustness import EXTRA_DELAY_S, RobustRange, lqi_spectral_radius, stable_gain_range
from ..run.plan import RunPlan, make_plan
from ..run.scenario import Scenario


def lqi_robust_range(scenario: Scenario | RunPlan, x0=None) -> RobustRange:
    """What the scenario's LQI survives at pose x0 (default home): its stable plant gains with
    the design's delay and with :data:`~stewart_drake.control.robustness.EXTRA_DELAY_S` more
    (whole periods, rounded up), and in ``notes`` the whole periods of extra delay it survives
    at gain 1.

    Raises:
        InvalidConfigError: as :func:`~.loop_analysis.loop_models` (not an LQI, or a plant step
            other than the control period).
    """
    from ..control.linear_model import plant_model
    from ..control.lqi.driver import LqiDriver
    from .loop_analysis import loop_models

    plan = scenario if isinstance(scenario, RunPlan) else make_plan(scenario, with_reference=False)
    models = loop_models(plan, x0)
    lqi = plan.scenario.controller
    assert isinstance(lqi, LqiDriver)  # loop_models refuses another
    servo, h = plan.servo, models.h
    plants: dict = {}

    def plant_of_delay(extra: int):
        if extra not in plants:
            plants[extra] = plant_model(
                plan.plant_geometry,
                models.x0,
                h,
                delay_periods=plan.delay_periods + extra,
                viscous_damping=0.0 if servo is None else servo.viscous_damping,
                current_time_constant_s=0.0 if servo is None else servo.current_time_constant_s,
            )
        return plants[extra]

    def range_with(extra: int) -> tuple[float, float]:
        return stable_gain_range(
            lambda g: lqi_spectral_radius(models, plant_of_delay, g, extra) < 1.0, steps=120
        )

    extra_periods = math.ceil(EXTRA_DELAY_S / h - 1e-9)
    survived = 0
    while survived < extra_periods and (
        lqi_spectral_radius(models, plant_of_delay, 1.0, survived + 1) < 1.0
    ):
        survived += 1
    return RobustRange(
        loop=(
            f"the LQI's loop (omega_Q {lqi.omega_Q:g}, omega_R {lqi.omega_R:g}, "
            f"{1e3 * h:g} ms, {plan.delay_periods} "
            "period(s) of delay designed for)"
        ),
        gains=range_with(0),
        delayed_gains=range_with(extra_periods),
        extra_delay_s=extra_periods * h,
        notes=(
            "delay it takes beyond the design's at gain 1: "
            + (
                f"{survived} whole period(s), {1e3 * survived * h:g} ms"
                if survived < extra_periods
                else f"at least {1e3 * extra_periods * h:g} ms"
            ),
        ),
    )


def loop_robustness(scenario: Scenario, x0=None) -> RobustRange | None:
    """What ``scenario``'s loop survives (module docstring), or None for a controller that has
    no such model here (a crank PD, an LQI whose weights a tuner drives).

    Raises:
        InvalidConfigError: a scenario whose loop cannot be modelled as it is configured
            (:func:`lqi_robust_range`).
    """
    from ..control.lqi.driver import LqiDriver
    from ..control.servo.driver import CrankServoDriver
    from ..control.servo.margins import robust_range
    from ..station.bus.position_margins import position_robust_range

    controller = scenario.controller
    if scenario.bus is not None and scenario.bus.position_loop is not None:
        return position_robust_range(*position_loop_model(scenario))
    if isinstance(controller, CrankServoDriver):
        return robust_range(crank_servo_loop(scenario))
    if isinstance(controller, LqiDriver) and scenario.tuner is None:
        return lqi_robust_range(scenario, x0)
    return None


def crank_servo_loop(scenario: Scenario):
    """The crank servo's loop as ``scenario`` configures it
    (:class:`~stewart_drake.control.servo.design.CrankLoop`, on its period and computation
    delay)."""
    from ..control.servo.design import design_loop
    from ..control.servo.driver import CrankServoDriver
    from ..run.plan import as_built

    servo = scenario.controller
    if not isinstance(servo, CrankServoDriver):
        raise InvalidConfigError(
            "the crank servo's loop needs controller: !CrankServoDriver, got "
            f"{type(servo).__name__}"
        )
    hardware = as_built(scenario).hardware
    h, d = scenario.control_period_s, 0 if hardware is None else hardware.computation_delay_periods
    return design_loop(h, d, servo.bandwidth_hz, servo.observer_bandwidth_hz, servo.integral_ratio)


def position_loop_model(scenario: Scenario) -> tuple:
    """The servos' own position loop as ``scenario``'s bus writes it: (its gains in SI
    (:class:`~stewart_drake.station.bus.servo_firmware.PositionGains`), the crank's inertia
    kg m^2, the motor's K_t N m/A, its winding's resistance ohm), what
    :mod:`stewart_drake.station.bus.position_margins` takes."""
    from ..station.bus.position_mode import crank_inertia
    from ..station.bus.protocol import SUPPLY_V
    from ..station.bus.servo_firmware import table_position_gains
    from ..station.bus.servos import servo_spec

    bus = scenario.bus
    if bus is None or bus.position_loop is None:
        raise InvalidConfigError("the servos' own position loop needs bus.position_loop")
    spec = servo_spec(bus.model, torque_control=False)
    inertia = crank_inertia(scenario.robot.build(), spec.name)
    supply = SUPPLY_V[spec.table.family]
    gains = table_position_gains(bus.position_loop.raw_gains(spec, inertia), spec, supply)
    return gains, inertia, spec.torque_constant_Nm_per_A, supply / spec.stall_current_A


def robust_lines(r: RobustRange) -> list[str]:
    """The range as ``analyze`` prints it for a loop without lines of its own (the LQI's)."""
    (lo0, hi0), (lo, hi) = r.gains, r.delayed_gains
    return [
        f"{r.loop}:",
        f"  stable for a plant gain (true / believed torque per command) of {lo0:.2f} to "
        f"{hi0:.2f}; with {1e3 * r.extra_delay_s:g} ms more delay, "
        + ("unstable at gain 1" if np.isnan(lo) else f"{lo:.2f} to {hi:.2f}"),
        *(f"  {note}" for note in r.notes),
        f"  {r.verdict()}",
    ]


__all__ = [
    "crank_servo_loop",
    "lqi_robust_range",
    "loop_robustness",
    "position_loop_model",
    "robust_lines",
]
