"""The crank servo as a scenario's choice (``controller: !CrankServoDriver``): its options,
checked (:meth:`CrankServoDriver.validate`) and built (:meth:`CrankServoDriver.make`) here, the
one place.

Drake's YAML loader (``yaml_load_typed``) reads the fields' annotations, so this module must not
use ``from __future__ import annotations``.
"""

from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from ...base.checks import as_number, check_multiple
from ...base.errors import InvalidConfigError
from ..contract import ControllerContext, ControllerDriver
from .design import KT_RANGE, MAX_DELAY_PERIODS, MAX_LOAD_SHARE, design_loop

#: The friction estimate's upper bound as a share of the motors' peak torque.
FRICTION_MAX_SHARE = 0.5


@dataclass
class CrankServoDriver(ControllerDriver):
    """The crank servo (:mod:`~stewart_drake.control.servo`) as a scenario's controller: the
    controller for the robot on its servo bus, where each crank's dry friction and encoder, not
    the chain's dynamics, limit the motion (docs/robot.md, "The controller on the bus"). Ours,
    not the paper's: its gains come from the same Riccati equation (Drake's DARE) on each crank's
    model in acceleration units rather than the pose's.

    Attributes:
        bandwidth_hz: the feedback's closed-loop bandwidth f_c, Hz (2 pi f_c h <= 1).
        observer_bandwidth_hz: the estimator's, Hz (2 pi f h <= 1): higher follows the cranks
            more closely and passes more of the encoders' counts into the torque.
        integral_ratio: the integral's corner sits at f_c / integral_ratio (> 0).
        friction_scale: the Coulomb friction believed at the start as a share of the servo's
            (the motor catalogue's, docs/motor_catalogue.md; 0: none believed), in [0, 5].
        friction_rate_rad_s: the crank rate over which the friction's sign is smoothed, rad/s
            (tanh(v / rate)).
        friction_direction_hz: near rest, a share of the friction is fed forward the way the
            crank must go to close its angle error: v = omega_d - 2 pi f e_theta, Hz (0: the
            reference's rate alone; a crank that stops short then stays until the integral frees
            it).
        friction_direction_share: that share, in [0, 1]; the rest follows the reference's rate.
            Below 1 a crank at rest is pushed with less than the friction it has even when the
            friction believed is too large (by up to 1 / share), which would otherwise start a
            relay's oscillation.
        friction_adaptation_s: tau_F, s: how fast the friction believed follows the feedback's
            torque along the motion (0: held at the start's).
        disturbance_feedback: share of the estimated disturbance taken off the command at once,
            in [0, 1] (0: the integral removes it).
        schedule_period_s: re-compute the chain's joint-space inertia at the reference this
            often, s (a whole multiple of the control period).
        friction_load_share: K_l, the friction believed a newton metre of each crank's
            feed-forward torque: gears lose a share of the torque they carry (Duclusaud et
            al.'s M3 to M5 classes; 1 - eta, 0.29 for the XM430-W350-T by its e-Manual's stall
            and no-load figures), in [0, 0.9]; 0: none (the Coulomb friction alone).
        friction_Nm: each crank's Coulomb friction believed at the start, N m (6 values: its
            servo's commissioning, docs/servo_bench.md); null: ``friction_scale`` x the
            catalogue's for all six.
        torque_constant_scale: each servo's torque per command as a share of the catalogue's
            (6 values in [0.5, 2]: its commissioning's motor constant over the catalogue's);
            null: the catalogue's for all six.
    """

    bandwidth_hz: float = 3.0
    observer_bandwidth_hz: float = 15.0
    integral_ratio: float = 3.0
    friction_scale: float = 1.0
    friction_rate_rad_s: float = 2e-3
    friction_adaptation_s: float = 2.0
    disturbance_feedback: float = 0.0
    schedule_period_s: float = 0.1
    friction_direction_hz: float = 3.0
    friction_direction_share: float = 1.0
    friction_load_share: float = 0.0
    friction_Nm: list[float] | None = None
    torque_constant_scale: list[float] | None = None

    #: No weights omega: no input for a tuner.
    takes_omega: ClassVar[bool] = False
    run_suffix: ClassVar[str] = "_servo"
    short_name: ClassVar[str] = "servo"

    def validate(
        self, control_period_s: float, delay_periods: int = 0, prefix: str = "controller."
    ) -> "CrankServoDriver":
        """Check every option for a controller of period ``control_period_s`` (s) on a robot
        with ``delay_periods`` of computation delay; returns self.

        Raises:
            InvalidConfigError: names the option (``prefix`` + its name) and what to change.
        """
        for name in ("bandwidth_hz", "observer_bandwidth_hz", "integral_ratio"):
            as_number(f"{prefix}{name}", getattr(self, name), 0.0, lo_open=True)
        as_number(f"{prefix}friction_scale", self.friction_scale, 0.0, 5.0)
        as_number(f"{prefix}friction_rate_rad_s", self.friction_rate_rad_s, 0.0, 10.0, lo_open=True)
        as_number(f"{prefix}friction_direction_hz", self.friction_direction_hz, 0.0, 1e3)
        as_number(f"{prefix}friction_direction_share", self.friction_direction_share, 0.0, 1.0)
        as_number(f"{prefix}friction_adaptation_s", self.friction_adaptation_s, 0.0, 1e4)
        as_number(f"{prefix}disturbance_feedback", self.disturbance_feedback, 0.0, 1.0)
        as_number(f"{prefix}friction_load_share", self.friction_load_share, 0.0, MAX_LOAD_SHARE)
        for name, lo, hi in (("friction_Nm", 0.0, 5.0), ("torque_constant_scale", *KT_RANGE)):
            values = getattr(self, name)
            if values is not None and (
                np.shape(values) != (6,) or not all(lo <= float(v) <= hi for v in values)
            ):
                raise InvalidConfigError(
                    f"{prefix}{name} must be 6 numbers in [{lo:g}, {hi:g}], one a crank (its "
                    f"servo's commissioning), or null; got {values!r:.80}"
                )
        check_multiple(
            f"{prefix}schedule_period_s",
            self.schedule_period_s,
            "control_period_s",
            control_period_s,
        )
        if delay_periods > MAX_DELAY_PERIODS:
            raise InvalidConfigError(
                f"a computation delay of {delay_periods} periods is more than the crank "
                f"servo carries ({MAX_DELAY_PERIODS}): lengthen control_period_s"
            )
        try:
            design_loop(
                control_period_s,
                delay_periods,
                self.bandwidth_hz,
                self.observer_bandwidth_hz,
                self.integral_ratio,
            )
        except InvalidConfigError as err:
            raise InvalidConfigError(f"{prefix}{err}") from None
        return self

    @property
    def commissioned(self) -> bool:
        """Whether the scenario gives any of each servo's commissioning (``friction_Nm``,
        ``torque_constant_scale``, a ``friction_load_share`` above 0); False: the catalogue's
        figures alone, which servos as they are leave outside the crank servo's bounds on some
        draws (docs/robot.md, "A commissioned paper_bus")."""
        return (
            self.friction_Nm is not None
            or self.torque_constant_scale is not None
            or self.friction_load_share > 0.0
        )

    def make(self, context: ControllerContext):
        """The crank servo for the Diagram that ``context`` describes: designed for its period
        and delay, the servo's friction (``context.servo``; none on the ideal robot) believed at
        ``friction_scale``, the friction's direction read where the torque will act."""
        from .controller import CrankServoController

        h, d = context.period_s, context.delay_periods
        loop = design_loop(h, d, self.bandwidth_hz, self.observer_bandwidth_hz, self.integral_ratio)
        servo = context.servo
        coulomb = 0.0 if servo is None else servo.coulomb_friction_Nm
        viscous = 0.0 if servo is None else servo.viscous_damping
        peak = None if servo is None else servo.peak_torque_Nm
        limit = context.torque_limit_Nm
        bound = min(v for v in (peak, limit, np.inf) if v is not None)
        friction_max = FRICTION_MAX_SHARE * bound if np.isfinite(bound) else 5.0 * coulomb
        friction = (
            np.full(6, min(self.friction_scale * coulomb, friction_max))
            if self.friction_Nm is None
            else np.minimum(np.asarray(self.friction_Nm, dtype=float), friction_max)
        )
        # The torque computed at the sample acts over one period d periods on (the simulated
        # station's delay line and the bus's driver write at a period's start; with no delay,
        # from the next plant step): its middle, from the reference's own instant (the sample
        # plus half a plant step, led again by half a plant step).
        h_p = context.plant_time_step_s
        lead = (d + 0.5) * h - h_p if d > 0 else 0.5 * h
        return CrankServoController(
            context.geometry,
            loop,
            offset_s=context.offset_s,
            lead_s=max(lead, 0.0),
            x_initial=context.x_initial,
            x_dot_initial=context.x_dot_initial,
            torque_limit_Nm=limit,
            friction_Nm=friction,
            viscous=viscous,
            friction_load_share=self.friction_load_share,
            torque_constant_scale=self.torque_constant_scale,
            friction_rate_rad_s=self.friction_rate_rad_s,
            friction_adaptation_s=self.friction_adaptation_s,
            friction_max_Nm=friction_max,
            disturbance_feedback=self.disturbance_feedback,
            friction_direction_hz=self.friction_direction_hz,
            friction_direction_share=self.friction_direction_share,
            schedule_period_s=self.schedule_period_s,
        )

    def summary(self) -> dict:
        """The settings a run's results carry (plain JSON values)."""
        return {
            "bandwidth_hz": self.bandwidth_hz,
            "observer_bandwidth_hz": self.observer_bandwidth_hz,
            "friction_scale": self.friction_scale,
        }
