"""The host's part of the servos' own position loop: the reference's crank angles streamed as goal
positions, one a period (``controller: !ServoPositionDriver``, with ``bus.position_loop``).

Each servo runs its firmware's Position Control Mode at its own rate on its own encoder
(:class:`~stewart_drake.station.bus.position_mode.ServoPositionLoop`); the host closes no loop.
Each period :class:`CrankGoalStreamer` takes the reference's pose, rate and acceleration at its
sample, carries the pose forward to when the servos will have reached the goal it sends
(second order: ``x + v L + a L^2 / 2``), turns it into crank angles by the closed-form inverse
kinematics (compiled: :func:`~.kernels.crank_reference`), and pairs each angle with the
Profile Velocity that reaches it in one period from the previous goal. Ours, not the paper's
(the paper closes an LQI on the host; docs/paper_notes.md).

This module must not use ``from __future__ import annotations``: Drake's YAML loader reads
:class:`ServoPositionDriver`'s field types.
"""

from dataclasses import dataclass
from typing import ClassVar

import numpy as np
from pydrake.systems.framework import BasicVector, LeafSystem

from ...base.checks import as_number
from ...base.errors import InvalidConfigError
from ...robot.kinematics import ik
from ...robot.single_pose import leg_constants
from ..contract import ControllerContext, ControllerDriver
from .kernels import crank_reference


class CrankGoalStreamer(LeafSystem):
    """The reference's crank angles as the servos' goals, one a period.

    Input port: ``x_d`` (18,): the reference's pose [rad, m], rate and acceleration at the
        sample (the controller contract's).
    Output ports: ``crank_goal`` (12,): the cranks' goal angles (6) rad, the robot's angles
        (the bus adds its encoders' zero errors), and their Profile Velocities (6) rad/s;
        ``T`` (6,): zero, N m (the contract's port; the servos' firmware makes the torque).

    Args:
        geometry: the robot (:class:`~stewart_drake.robot.geometry.StewartGeometry`).
        period_s: the control period h, s.  offset_s: the sample's offset in the period, s.
        lead_s: how far past the reference's time at the sample each goal is taken, s: to
            when the servos will have reached it.
        x_initial, x_dot_initial: (6,) the pose and rate at t = 0: the goal held before the
            first sample.
    Raises:
        InvalidConfigError: a period or lead that is not positive and finite.
        UnreachablePoseError: no inverse kinematics at ``x_initial`` (the first goal).
    """

    def __init__(self, geometry, period_s, offset_s, lead_s, x_initial, x_dot_initial=None):
        super().__init__()
        as_number("period_s", period_s, 0.0, 1.0, lo_open=True)
        as_number("lead_s", lead_s, 0.0, 1.0)
        self.geometry = geometry
        self.period_s, self.lead_s = float(period_s), float(lead_s)
        self._legs = np.array(leg_constants(geometry))
        self._legs.setflags(write=False)  # as the kernel was compiled for
        self._theta, self._omega = np.empty(6), np.empty(6)
        x0 = np.asarray(x_initial, dtype=float)
        v0 = np.zeros(6) if x_dot_initial is None else np.asarray(x_dot_initial, dtype=float)
        x_d0 = np.concatenate([x0, v0, np.zeros(6)])
        theta_now = self._angles(x_d0, 0.0).copy()
        theta_goal = self._angles(x_d0, self.period_s)
        initial = np.concatenate([theta_goal, np.abs(theta_goal - theta_now) / self.period_s])
        self.DeclareVectorInputPort("x_d", 18)
        self._state = self.DeclareDiscreteState(BasicVector(initial))
        self.DeclareStateOutputPort("crank_goal", self._state)
        self.DeclareVectorOutputPort("T", 6, lambda context, out: out.SetFromVector(np.zeros(6)))
        self.DeclarePeriodicDiscreteUpdateEvent(self.period_s, offset_s, self._Update)

    def _angles(self, x_d, lead) -> np.ndarray:
        """(6,) crank angles, rad, of the reference ``x_d`` (18,) carried ``lead`` s forward;
        by the compiled IK (a few microseconds: the loop's CPU a period is what bounds it)."""
        theta, omega = self._theta, self._omega
        if not crank_reference(self._legs, x_d, lead, theta, omega) and not np.all(
            np.isfinite(theta)
        ):
            x = x_d[:6] + x_d[6:12] * lead + 0.5 * x_d[12:] * lead * lead
            ik(self.geometry, x[None, :])  # the checked inverse kinematics names the leg
        return theta

    def _Update(self, context, discrete_state):
        x_d = self.get_input_port(0).Eval(context)
        theta = self._angles(x_d, self.lead_s)
        held = discrete_state.get_mutable_vector(self._state).get_mutable_value()
        held[6:] = np.abs(theta - held[:6]) / self.period_s
        held[:6] = theta


@dataclass
class ServoPositionDriver(ControllerDriver):
    """The servos' own position loop as a scenario's controller: the host streams the reference's
    crank angles (:class:`CrankGoalStreamer`) and each servo's firmware follows them; the loop's
    gains are the bus's (``bus.position_loop``, required with this controller).

    Attributes:
        extra_lead_s: lead beyond the bus's timing, s (>= 0): the servos reach a goal one
            control period after the driver writes it, the write coming the computation delay
            after the sample; their loops' own lag behind the profile is this.
    """

    extra_lead_s: float = 0.0

    takes_omega: ClassVar[bool] = False
    run_suffix: ClassVar[str] = "_position"
    short_name: ClassVar[str] = ""
    #: Its ``crank_goal`` drives the servos' goals: the bus must run their position loop.
    streams_goals: ClassVar[bool] = True

    def validate(
        self, control_period_s: float, delay_periods: int = 0, prefix: str = "controller."
    ) -> "ServoPositionDriver":
        """Check the option; returns self.

        Raises:
            InvalidConfigError: names the option (``prefix`` + its name).
        """
        as_number(f"{prefix}extra_lead_s", self.extra_lead_s, 0.0, 1.0)
        if delay_periods > 4:
            raise InvalidConfigError(
                f"a computation delay of {delay_periods} periods: the goals would lead the "
                "reference by more than the servos' loops follow"
            )
        return self

    def lead_s(self, context: ControllerContext) -> float:
        """How far past the reference at the sample a goal is taken, s: the goal written the
        computation delay's periods after the sample (at the period's start, the sample being
        half a plant step in), reached one period later, plus ``extra_lead_s``; the reference
        at the sample is already half a plant step ahead of it."""
        h, d, h_p = context.period_s, context.delay_periods, context.plant_time_step_s
        return max(0.0, (d + 1) * h - h_p + self.extra_lead_s)

    def make(self, context: ControllerContext):
        """The :class:`CrankGoalStreamer` for the Diagram ``context`` describes."""
        return CrankGoalStreamer(
            context.geometry,
            context.period_s,
            context.offset_s,
            self.lead_s(context),
            context.x_initial,
            context.x_dot_initial,
        )

    def summary(self) -> dict:
        """The settings a run's results carry (plain JSON values)."""
        return {"extra_lead_s": self.extra_lead_s}


__all__ = ["CrankGoalStreamer", "ServoPositionDriver"]
