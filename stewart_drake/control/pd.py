"""Baseline controllers behind the LQI's ports, for the evaluation.

:class:`CrankPdController` is what a rotary Stewart platform ships with: an independent-joint PD
loop per motor around the crank angle, on top of the same virtual-work gravity feed-forward as
the LQI. It follows the controller contract (:mod:`~stewart_drake.control.contract`) with the
ports ``x``, ``x_d``, ``T_ff``; ``T``, ``status``, ``e_bar``
so :func:`~stewart_drake.run.diagram.make_stewart_diagram` swaps one for the other.
"""

from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from ..base.checks import as_number
from ..base.errors import InvalidConfigError, UnreachablePoseError
from ..robot import kinematics, statics
from ..robot.geometry import X_HOME, StewartGeometry
from ..robot.statics import crank_inertia_matrix
from .contract import ControllerContext, ControllerDriver, PoseTorqueController


@dataclass
class PdDriver(ControllerDriver):
    """The crank-space PD baseline with gravity feed-forward as a scenario's controller
    (``controller: !PdDriver``; :class:`CrankPdController`): its options, checked and built here.

    Attributes:
        bandwidth_hz: natural frequency of every mode of the closed loop, Hz; at most what the
            sampling carries, 2 pi f h <= 0.5.
        damping: damping ratio zeta (1: critical).
        schedule_period_s: re-schedule the inertia-shaped gains from the reference pose this
            often, s.
    """

    bandwidth_hz: float = 20.0
    damping: float = 1.0
    schedule_period_s: float = 0.01

    #: The PD has no weights: no ``omega`` input for a tuner.
    takes_omega: ClassVar[bool] = False
    run_suffix: ClassVar[str] = "_pd"
    short_name: ClassVar[str] = "pd"

    def validate(
        self, control_period_s: float, delay_periods: int = 0, prefix: str = "controller."
    ) -> "PdDriver":
        """Check the options for a controller of period ``control_period_s`` (s); returns self
        (the PD ignores a computation delay).

        Raises:
            InvalidConfigError: names the option and what to change.
        """
        for name in ("bandwidth_hz", "damping", "schedule_period_s"):
            as_number(f"{prefix}{name}", getattr(self, name), 0.0, lo_open=True)
        w_n = 2 * np.pi * self.bandwidth_hz
        if w_n * control_period_s > 0.5:
            raise InvalidConfigError(
                f"{prefix}bandwidth_hz = {self.bandwidth_hz:g} Hz is too high for a "
                f"{control_period_s:g} s period (2 pi f h = {w_n * control_period_s:.2f} > 0.5); "
                f"lower it or the period"
            )
        return self

    def make(self, context: ControllerContext) -> "CrankPdController":
        """The PD for the Diagram that ``context`` describes."""
        return CrankPdController(
            context.geometry,
            self,
            period_s=context.period_s,
            offset_s=context.offset_s,
            x_initial=context.x_initial,
        )


class CrankPdController(PoseTorqueController):
    """Crank-space PD + gravity feed-forward: T = T_ff + K_p (theta_d - theta) + K_d (w_d - w).

    theta = IK(x) and w = J(x) x_dot are the crank angles and rates of the measured pose (J the
    Jacobian d theta / d x); theta_d, w_d those of the reference. The gains place every mode of
    the linearized chain at ``bandwidth_hz`` with damping ``damping``:
    K_p = (2 pi f)^2 M_theta, K_d = 2 zeta (2 pi f) M_theta, with M_theta the joint-space inertia
    (:func:`crank_inertia_matrix`) at the reference pose, re-scheduled every
    ``schedule_period_s`` like the LQI's gains. Gains fixed at home diverge on the paper
    manoeuvre: at phi = -0.52 rad, Z = 0.25 m one mode's inertia is 24 times smaller than at home,
    its frequency five times higher, and the derivative term no longer fits the 1 ms sampling.
    There is no integral action: a payload the feed-forward does not know leaves a steady error,
    which is what the comparison should show.

    Ports: inputs ``x`` (12), ``x_d`` (18), ``T_ff`` (6) (no ``omega``: it has no weights);
    outputs ``T`` (6), ``e_bar`` (6) and ``status`` = [inertia re-schedules, failures (IK or
    singular inertia)] (``status_names``).

    Args:
        geometry: the robot the controller believes in.
        driver: the gains' bandwidth, damping and re-schedule period (:class:`PdDriver`);
            default ``PdDriver()``.
        period_s: control period, s. offset_s: sample offset in [0, period_s), s.
        x_initial: initial pose (for the initial torque).
    Raises:
        InvalidConfigError: a non-positive period, a bad option of the driver (named
            ``driver.<option>``: a bandwidth the sampling cannot carry, 2 pi f h > 0.5).
    """

    def __init__(
        self,
        geometry: StewartGeometry,
        driver: PdDriver | None = None,
        *,
        period_s: float = 1e-3,
        offset_s: float = 0.0,
        x_initial=None,
    ):
        super().__init__(omega=False)
        self.status_names = ("inertia_reschedules", "failures")
        if not (np.isfinite(period_s) and period_s > 0):
            raise InvalidConfigError(f"period_s must be a finite number > 0, got {period_s}")
        if not (0 <= offset_s < period_s):
            raise InvalidConfigError(f"offset_s must be in [0, period_s), got {offset_s}")
        driver = (driver or PdDriver()).validate(period_s, prefix="driver.")
        self.driver = driver
        w_n = 2 * np.pi * driver.bandwidth_hz
        damping, schedule_period_s = driver.damping, driver.schedule_period_s
        self.geometry = geometry
        self._kp, self._kd = w_n**2, 2 * damping * w_n
        self.steps_per_schedule = max(1, int(round(schedule_period_s / period_s)))
        x0 = X_HOME if x_initial is None else np.asarray(x_initial, dtype=float)
        M = crank_inertia_matrix(geometry, x0)
        #: Gains at the initial pose, (6, 6) each (the running ones are in the discrete state).
        self.K_p, self.K_d = self._kp * M, self._kd * M
        self._u_index = self.DeclareDiscreteState(statics.holding_torques(geometry, x0))
        self._s_index = self.DeclareDiscreteState(2)
        self._e_index = self.DeclareDiscreteState(6)
        self._M_index = self.DeclareDiscreteState(M.reshape(-1))  # M_theta of the gains
        self._k_index = self.DeclareDiscreteState(1)  # step counter
        self.DeclareStateOutputPort("T", self._u_index)
        self.DeclareStateOutputPort("status", self._s_index)
        self.DeclareStateOutputPort("e_bar", self._e_index)
        self.DeclarePeriodicDiscreteUpdateEvent(
            period_sec=period_s, offset_sec=float(offset_s), update=self._Update
        )

    def crank_states(self, x) -> tuple[np.ndarray, np.ndarray]:
        """(theta (6,) rad, w (6,) rad/s) of the cranks for a pose and rate x (12,)."""
        theta = kinematics.ik(self.geometry, x[:6])
        return theta, kinematics.jacobian(self.geometry, x[:6], theta) @ x[6:12]

    def _Update(self, context, discrete_state):
        x = self._x.Eval(context)
        ref = self._x_d.Eval(context)
        T = self._T_ff.Eval(context).copy()
        status = context.get_discrete_state(self._s_index).get_value().copy()
        M = context.get_discrete_state(self._M_index).get_value().reshape(6, 6)
        k = int(context.get_discrete_state(self._k_index).get_value()[0])
        try:
            if k % self.steps_per_schedule == 0:
                M = crank_inertia_matrix(self.geometry, ref[:6])
                status[0] += 1
                discrete_state.set_value(self._M_index, M.reshape(-1))
            theta, w = self.crank_states(x)
            theta_d, w_d = self.crank_states(ref[:12])
            T += M @ (self._kp * (theta_d - theta) + self._kd * (w_d - w))
        except (UnreachablePoseError, np.linalg.LinAlgError):
            status[1] += 1  # keep the last gains / the feed-forward; the guard sees the pose
        discrete_state.set_value(self._k_index, [k + 1])
        discrete_state.set_value(self._u_index, T)
        discrete_state.set_value(self._s_index, status)
        discrete_state.set_value(self._e_index, x[:6] - ref[:6])
