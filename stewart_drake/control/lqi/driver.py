"""The LQI as a scenario's choice (``controller: !LqiDriver``): its options and their scales,
checked (:meth:`LqiDriver.validate`) and built (:meth:`LqiDriver.make`) here, the one place.

Drake's YAML loader (``yaml_load_typed``) reads the fields' annotations, so this module must not
use ``from __future__ import annotations``.
"""

import dataclasses
from dataclasses import dataclass, field
from typing import ClassVar

import numpy as np

from ...base.checks import as_array, as_number, check_multiple
from ...base.errors import InvalidConfigError
from ...base.mirrors import ValueMirror
from ..contract import ControllerContext, ControllerDriver
from .controller import LqiDiagram
from .gain import LQI_OMEGA_MAX, LQI_OMEGA_MIN

#: How the gain is re-solved at a re-schedule (see :class:`~.controller.LqiController`).
RICCATI_MODES = ("warm", "track", "cold")
GAIN_TRANSFER_MODES = ("integral", "feedback", "none")
#: Largest computation delay the LQI compensates, control periods: its model has 6 (3 + d)
#: states, and a run's cost grows about as their cube (0.26x real time at 20, 0.02x at 40 on
#: one core of the reference machine).
MAX_COMPENSATED_DELAY = 20


@dataclass(frozen=True)
class LqiScales:
    """Normalization of the LQI cost (Bryson's rule); SI units.

    Attributes:
        pose: (6,) acceptable pose error [rad, rad, rad, m, m, m].
        rate: (6,) acceptable rate error [rad/s x3, m/s x3].
        integral: (6,) acceptable integral of the pose error [rad s x3, m s x3].
        torque: acceptable motor torque, N m (same for the six motors).
    """

    pose: tuple = (1e-3, 1e-3, 1e-3, 1e-3, 1e-3, 1e-3)
    rate: tuple = (1.0, 1.0, 1.0, 0.1, 0.1, 0.1)
    integral: tuple = (2e-5, 2e-5, 2e-5, 2e-5, 2e-5, 2e-5)
    torque: float = 0.3

    def __post_init__(self):
        for name in ("pose", "rate", "integral"):
            v = as_array(f"LqiScales.{name}", getattr(self, name), shape=(6,))
            # 1/s^2 must stay finite and > 0: scales within 1e-100 .. 1e100.
            if np.any(v < 1e-100) or np.any(v > 1e100):
                raise InvalidConfigError(
                    f"LqiScales.{name} needs 6 values in [1e-100, 1e100], got {v}"
                )
            object.__setattr__(self, name, tuple(float(c) for c in v))
        object.__setattr__(
            self, "torque", as_number("LqiScales.torque [N m]", self.torque, 1e-100, 1e100)
        )

    def Q_unit(self, delay_periods: int = 0) -> np.ndarray:
        """(18 + 6 d, 18 + 6 d) state weight at omega_Q = 1. The d delayed torques of
        :func:`~.gain.error_model` get 1e-6 of the torque weight: almost free, but not zero, so the
        diagonal scaling of the Riccati solve stays defined."""
        s = np.concatenate(
            [self.pose, self.rate, self.integral, np.full(6 * delay_periods, self.torque * 1e3)]
        )
        return np.diag(1.0 / s**2)

    def R_unit(self) -> np.ndarray:
        """(6, 6) torque weight at omega_R = 1."""
        return np.eye(6) / self.torque**2


@dataclass
class LqiScalesConfig(ValueMirror):
    """The YAML form of :class:`LqiScales` (a scenario's ``controller.scales``): the same fields,
    units and defaults, lists for its tuples; :meth:`build` gives the :class:`LqiScales`."""

    value_class = LqiScales

    pose: list[float] = field(default_factory=lambda: list(LqiScales.pose))
    rate: list[float] = field(default_factory=lambda: list(LqiScales.rate))
    integral: list[float] = field(default_factory=lambda: list(LqiScales.integral))
    torque: float = LqiScales.torque


@dataclass
class LqiDriver(ControllerDriver):
    """The LQI of paper section III as a scenario's controller (``controller: !LqiDriver``):
    its options, checked (:meth:`validate`) and built (:meth:`make`) here, the one place. The
    options marked "ours" are not in the paper; why each, and what it measured:
    docs/paper_notes.md (re-scheduling, switching gains, torque limit, friction feed-forward).

    Attributes:
        omega_Q, omega_R: weights of eq. 27 on normalized errors and torques, in
            [:data:`~.gain.LQI_OMEGA_MIN`, :data:`~.gain.LQI_OMEGA_MAX`] (only their ratio
            matters): the constant on the controller's ``omega`` input; a tuner replaces them.
        schedule_period_s: re-solve the Riccati gain from the measured pose this often, s (a
            whole multiple of the control period; a change of omega re-solves at once). Ours.
        riccati: "warm" refines the last gain by Newton's method to convergence
            (:func:`~.reschedule.newton_gain`, the cold solve as fallback); "track" takes one Newton
            step per re-schedule; "cold" calls Drake's DARE each time.
        scales: normalization of Q and R (Bryson's rule, :class:`LqiScalesConfig`).
        anti_windup: stop integrating z while a command is clipped at the motors' limit
            (clamping); acts only when the motors have a limit. Ours.
        delay_compensation: augment the error model with the torques still in the pipe when the
            robot has a computation delay (:func:`~.gain.error_model`); false ignores the delay.
        reference_governor: with a torque limit, follow the nearest pose the motors can hold
            (:meth:`~.controller.LqiController.govern`) while the reference's own feed-forward
            exceeds :data:`~.gain.GOVERNOR_MARGIN` of the limit (docs/hardware.md). Ours.
        schedule_pose: re-schedule the input matrix B(x) from the measured pose; false keeps the
            start pose's, as a plain LQI (the gain then changes only with omega). Ours.
        gain_transfer: what carries over when the gain changes: "integral" keeps the integral
            torque, K_I,new z_new = K_I,old z_old; "feedback" keeps the whole feedback,
            K_I,new z_new = K_old e - K_rest,new e_rest; "none" keeps z, as the paper does.
        friction_compensation_Nm: Coulomb friction the controller believes each motor has, at
            the crank, N m (0: none, the paper scenarios'), fed forward as
            ``friction_compensation_Nm * tanh(theta_dot_d / friction_rate_rad_s)`` per motor,
            theta_dot_d = J x_dot_d (:func:`~.step.friction_feedforward`); needs the encoders'
            estimator. Ours.
        friction_rate_rad_s: crank rate, rad/s, of the smoothed sign above (> 0).
    """

    omega_Q: float = 1.0
    omega_R: float = 1.0
    schedule_period_s: float = 0.01
    riccati: str = "warm"
    scales: LqiScalesConfig = field(default_factory=LqiScalesConfig)
    anti_windup: bool = True
    delay_compensation: bool = True
    reference_governor: bool = True
    schedule_pose: bool = True
    gain_transfer: str = "integral"
    friction_compensation_Nm: float = 0.0
    friction_rate_rad_s: float = 3e-4

    #: The controller has the ``omega`` input a tuner drives.
    takes_omega: ClassVar[bool] = True
    short_name: ClassVar[str] = "lqi"

    def validate(
        self,
        control_period_s: float,
        delay_periods: int = 0,
        prefix: str = "controller.",
        delay_name: str = "hardware.computation_delay_periods",
    ) -> "LqiDriver":
        """Check every option for a controller of period ``control_period_s`` (s) on a robot
        with ``delay_periods`` of computation delay (a setting named ``delay_name``); returns
        self.

        Raises:
            InvalidConfigError: names the option (``prefix`` + its name) and what to change.
        """
        for name in ("omega_Q", "omega_R"):
            as_number(f"{prefix}{name}", getattr(self, name), LQI_OMEGA_MIN, LQI_OMEGA_MAX)
        check_multiple(
            f"{prefix}schedule_period_s",
            self.schedule_period_s,
            "control_period_s",
            control_period_s,
        )
        for name, modes in (("riccati", RICCATI_MODES), ("gain_transfer", GAIN_TRANSFER_MODES)):
            if getattr(self, name) not in modes:
                raise InvalidConfigError(
                    f"{prefix}{name} must be one of {modes}, got {getattr(self, name)!r}"
                )
        for name in ("anti_windup", "delay_compensation", "reference_governor", "schedule_pose"):
            if not isinstance(getattr(self, name), bool):
                raise InvalidConfigError(
                    f"{prefix}{name} must be true or false, got {getattr(self, name)!r}"
                )
        as_number(f"{prefix}friction_compensation_Nm", self.friction_compensation_Nm, 0.0, 10.0)
        as_number(f"{prefix}friction_rate_rad_s", self.friction_rate_rad_s, 0.0, lo_open=True)
        if not isinstance(self.scales, LqiScalesConfig):
            raise InvalidConfigError(
                f"{prefix}scales must be an LqiScalesConfig, got {type(self.scales).__name__}"
            )
        try:
            self.scales.build()
        except (InvalidConfigError, TypeError) as err:
            raise InvalidConfigError(f"{prefix}scales: {err}") from None
        if self.delay_compensation and delay_periods > MAX_COMPENSATED_DELAY:
            raise InvalidConfigError(
                f"{delay_name} = {delay_periods} with the LQI's delay compensation gives a "
                f"model of 6 x (3 + {delay_periods}) = "
                f"{6 * (3 + delay_periods)} states whose Riccati equation is re-solved every "
                f"schedule period (thousands of times slower than real time); at most "
                f"{MAX_COMPENSATED_DELAY} periods are compensated: set "
                f"{prefix}delay_compensation: false, or lengthen control_period_s"
            )
        return self

    def make(self, context: ControllerContext, compiled: bool = True) -> LqiDiagram:
        """The LQI with the controller contract's ports for the Diagram that ``context``
        describes; ``compiled=False`` runs its uncompiled step (:data:`~.step.reference`: the
        same code, slower)."""
        return LqiDiagram(
            context.geometry,
            self,
            period_s=context.period_s,
            offset_s=context.offset_s,
            x_initial=context.x_initial,
            x_dot_initial=context.x_dot_initial,
            torque_limit_Nm=context.torque_limit_Nm,
            delay_periods=context.delay_periods,
            estimator=context.pose_estimator,
            feature_window=context.feature_window,
            compiled=compiled,
        )

    def omega(self) -> tuple:
        """(omega_Q, omega_R): the constant on the ``omega`` input when no tuner drives it."""
        return (self.omega_Q, self.omega_R)

    def with_weights(self, **weights) -> "LqiDriver":
        """A copy with these ``omega_Q`` and ``omega_R`` (either or both)."""
        return dataclasses.replace(self, **weights)

    def summary(self) -> dict:
        """The settings a run's results carry (plain JSON values)."""
        return {
            "omega_Q": self.omega_Q,
            "omega_R": self.omega_R,
            "schedule_period_s": self.schedule_period_s,
        }
