"""The crank servo as a Drake system: :class:`CrankServoController`, one compiled step a control
period (:mod:`.kernels`) over gains designed once (:mod:`.design`), the chain's joint-space
inertia re-scheduled from the reference every ``schedule_period_s``.
"""

from __future__ import annotations

import math

import numpy as np
from pydrake.systems.framework import LeafSystem

from ...base.checks import as_number
from ...base.errors import InvalidConfigError
from ...robot import kinematics, path_kernels, statics
from ...robot.geometry import X_HOME, StewartGeometry
from ...robot.single_pose import leg_constants
from .design import KT_RANGE, MAX_LOAD_SHARE, CrankLoop

#: The friction fit's memory, s: longer than a breath's half (a fit needs both senses of motion).
FRICTION_MEMORY_S = 4.0
#: The crank rate above which the friction is learned, as a multiple of the smoothed sign's
#: rate: a crank that turns slower (a crank the motion hardly turns) keeps what it believes, its
#: fit of the sign too poor (on the emulator such cranks learned friction up to the bound and
#: dithered the platform's roll and yaw by 1 mrad).
ADAPT_RATE_SHARE = 10.0
#: The friction learned stays within these factors of the friction believed at the start.
FRICTION_RANGE = (0.5, 2.0)
#: What the ``status`` output holds, in order.
SERVO_STATUS_NAMES = (
    "saturated_steps",
    "reference_failures",
    "friction_mean_Nm",
    "inertia_reschedules",
)


def _kernels():
    """:mod:`.kernels`, compiled (or loaded from numba's cache) when a controller is first
    built, not when this module is imported."""
    from . import kernels

    return kernels


class CrankServoController(LeafSystem):
    """The crank servo of the servo bus (:mod:`~stewart_drake.control.servo`): per crank, the
    reference's feed-forward, the Coulomb friction the controller believes (adapted online) and
    a linear-quadratic feedback with integral action on a current estimator of the crank's
    angle, rate and disturbance, through the chain's joint-space inertia.

    Input ports: ``x_d`` (18,) the reference pose, rate, acceleration [rad, m, /s, /s^2];
        ``motor_angle`` (6,) the encoders' crank angles, rad (their zero errors included, which
        ``geometry.encoder_offsets`` takes back); ``T_ff`` (6,) the reference's feed-forward
        torques, N m (the scenario's ``feedforward``: ``inverse_dynamics`` carries the inertia
        the feedback would otherwise have to find).
    Output ports: ``T`` (6,) the motor torques, N m, held (within +-``torque_limit_Nm``);
        ``integral`` (6,) the integrals z of the crank-angle errors, rad s; ``e_bar`` (6,) the
        pose error the encoders read, J^-1 (theta - theta_d) at the reference [rad, m];
        ``status`` (:data:`SERVO_STATUS_NAMES`).

    Args:
        geometry: the robot the controller believes in.
        loop: the designed loop (:func:`~.design.design_loop`), its period and delay those of
            the Diagram.
        offset_s: the sample's offset in the period, s.
        lead_s: from the reference's sample to the middle of the period the torque acts in, s:
            where the friction's direction is read.
        x_initial, x_dot_initial: (6,) the pose and rate at t = 0 (default home, at rest).
        torque_limit_Nm: the motors' limit (None: none).
        friction_Nm: (6,) the Coulomb friction believed at the start, N m. viscous: N m s/rad.
        friction_load_share: K_l, the friction believed a newton metre of each crank's
            feed-forward torque, in [0, ``MAX_LOAD_SHARE``] (:mod:`.kernels`, stage 4; 0:
            none).
        torque_constant_scale: (6,) each servo's torque per command as a share of the
            catalogue's, within ``KT_RANGE`` (its commissioning's; None: 1): the torque is
            divided by it.
        friction_rate_rad_s: the smoothed sign's crank rate, rad/s.
        friction_adaptation_s: tau_F, s (0: the friction held).
        friction_max_Nm: the estimate's upper bound, N m (and within :data:`FRICTION_RANGE` of
            ``friction_Nm`` when it is given).
        friction_direction_hz: f, Hz: ``friction_direction_share`` of the friction is fed in
            the sense of omega_d(t + lead) - 2 pi f e_theta (default f the loop's bandwidth), the
            rest in the reference's (:mod:`.kernels`, stage 4).
        disturbance_feedback: share of the estimated disturbance taken off the command (0: the
            integral alone removes it).
        schedule_period_s: how often M_theta is re-computed at the reference, s.
        compiled: run :mod:`.kernels`' compiled step (False: its ``py_func``, the same code).
    Raises:
        InvalidConfigError: a bad setting. UnreachablePoseError: x_initial is not a pose.
    """

    def __init__(
        self,
        geometry: StewartGeometry,
        loop: CrankLoop,
        *,
        offset_s: float = 0.0,
        lead_s: float = 0.0,
        x_initial=None,
        x_dot_initial=None,
        torque_limit_Nm: float | None = None,
        friction_Nm=None,
        viscous: float = 0.0,
        friction_load_share: float = 0.0,
        torque_constant_scale=None,
        friction_rate_rad_s: float = 2e-3,
        friction_adaptation_s: float = 2.0,
        friction_max_Nm: float = 1.0,
        friction_direction_hz: float | None = None,
        friction_direction_share: float = 1.0,
        disturbance_feedback: float = 0.0,
        schedule_period_s: float = 0.1,
        compiled: bool = True,
    ):
        super().__init__()
        self.status_names = SERVO_STATUS_NAMES
        self.geometry, self.loop = geometry, loop
        h, d = loop.h, loop.delay_periods
        if not 0.0 <= offset_s < h:
            raise InvalidConfigError(f"offset_s must be in [0, {h:g}) s, got {offset_s}")
        k = _kernels()
        self._step = k.step if compiled else k.reference.step
        self._parts = k.layout(d)
        c = np.zeros(len(k.CONSTANTS))
        c[k.H], c[k.LEAD] = h, as_number("lead_s", lead_s, 0.0, 1.0)
        c[k.FRICTION_RATE] = as_number(
            "friction_rate_rad_s", friction_rate_rad_s, 0.0, lo_open=True
        )
        c[k.K_C] = (
            2
            * math.pi
            * (
                loop.bandwidth_hz
                if friction_direction_hz is None
                else as_number("friction_direction_hz", friction_direction_hz, 0.0)
            )
        )
        tau_F = as_number("friction_adaptation_s", friction_adaptation_s, 0.0)
        c[k.ADAPT] = 0.0 if tau_F == 0.0 else 1.0 / tau_F
        c[k.ADAPT_MIN_RATE] = ADAPT_RATE_SHARE * c[k.FRICTION_RATE]
        c[k.FRICTION_MIN] = 0.0
        c[k.FRICTION_MAX] = as_number("friction_max_Nm", friction_max_Nm, 0.0)
        c[k.VISCOUS] = as_number("viscous", viscous, 0.0)
        c[k.LIMIT] = (
            math.inf
            if torque_limit_Nm is None
            else as_number("torque_limit_Nm", torque_limit_Nm, 0.0, lo_open=True)
        )
        c[k.DELAY] = d
        c[k.SHARE] = as_number("friction_direction_share", friction_direction_share, 0.0, 1.0)
        c[k.MEMORY] = math.exp(-h / max(FRICTION_MEMORY_S, h))
        c[k.DOB] = as_number("disturbance_feedback", disturbance_feedback, 0.0, 1.0)
        c[k.LOAD_SHARE] = as_number("friction_load_share", friction_load_share, 0.0, MAX_LOAD_SHARE)
        # a copy (np.array), made read-only below: the caller's array is not frozen
        kt = np.ones(6) if torque_constant_scale is None else np.array(torque_constant_scale, float)
        if kt.shape != (6,) or not np.all((kt >= KT_RANGE[0]) & (kt <= KT_RANGE[1])):
            raise InvalidConfigError(
                f"torque_constant_scale must be 6 values in [{KT_RANGE[0]:g}, {KT_RANGE[1]:g}] "
                f"(each servo's torque per command over the catalogue's), got {kt}"
            )
        kt.setflags(write=False)
        self._kt = kt
        self._legs = np.array(leg_constants(geometry))
        self._legs.setflags(write=False)
        #: The robot's constants as :func:`~stewart_drake.robot.path_kernels.joint_inertia`
        #: reads them (the inertia's re-schedule, compiled).
        self._inertia_constants = statics.kernel_constants(geometry)
        self._gains = tuple(np.ascontiguousarray(a) for a in (loop.K, loop.L, loop.Phi, loop.Gamma))
        self.steps_per_schedule = max(
            1, int(round(as_number("schedule_period_s", schedule_period_s, 0.0, lo_open=True) / h))
        )
        x0 = X_HOME if x_initial is None else np.asarray(x_initial, dtype=float)
        v0 = np.zeros(6) if x_dot_initial is None else np.asarray(x_dot_initial, dtype=float)
        friction = np.zeros(6) if friction_Nm is None else np.asarray(friction_Nm, dtype=float)
        if friction.shape != (6,) or not np.all((friction >= 0) & (friction <= c[k.FRICTION_MAX])):
            raise InvalidConfigError(
                f"friction_Nm must be 6 values in [0, friction_max_Nm = {c[k.FRICTION_MAX]:g}] "
                f"N m, got {friction}"
            )
        if np.any(friction > 0.0):  # the estimate stays within a factor of 2 of the start's
            c[k.FRICTION_MIN] = FRICTION_RANGE[0] * float(np.min(friction))
            c[k.FRICTION_MAX] = min(c[k.FRICTION_MAX], FRICTION_RANGE[1] * float(np.max(friction)))
        c.setflags(write=False)
        self._c = c
        self._x_d = self.DeclareVectorInputPort("x_d", 18)
        self._theta = self.DeclareVectorInputPort("motor_angle", 6)
        self._T_ff = self.DeclareVectorInputPort("T_ff", 6)
        self._state = self.DeclareDiscreteState(self.initial_state(x0, v0, friction))
        #: M_theta, J^-1 and the re-schedules so far, in the context (73,).
        self._inertia_state = self.DeclareDiscreteState(np.append(self._inertia(x0), 0.0))
        parts = self._parts
        for name, part in (("T", "T"), ("integral", "z"), ("e_bar", "e_bar")):
            self.DeclareVectorOutputPort(
                name,
                6,
                self._part_output(parts[part]),
                prerequisites_of_calc={self.discrete_state_ticket(self._state)},
            )
        self.DeclareVectorOutputPort(
            "status",
            len(SERVO_STATUS_NAMES),
            self._CalcStatus,
            prerequisites_of_calc={self.discrete_state_ticket(self._state)},
        )
        self.DeclarePeriodicDiscreteUpdateEvent(h, float(offset_s), self._Update)

    def initial_state(self, x0, v0, friction) -> np.ndarray:
        """The state at t = 0: the estimator at the cranks of pose x0 moving at v0, nothing
        integrated or pending, the friction believed, the torque holding x0."""
        p = self._parts
        state = np.zeros(p["size"].stop)
        theta = kinematics.ik(self.geometry, x0)
        omega = kinematics.jacobian(self.geometry, x0, theta) @ v0
        x_bar = state[p["x_bar"]].reshape(6, 3)
        x_bar[:, 0], x_bar[:, 1] = theta, omega
        state[p["friction"]] = friction
        state[p["T"]] = statics.holding_torques(self.geometry, x0, theta)
        return state

    def _inertia(self, x) -> np.ndarray:
        """(72,) [M_theta (6, 6) kg m^2, J^-1 (6, 6)] at pose x, rows first.

        Raises:
            UnreachablePoseError: x is not a pose of the robot.
        """
        theta = kinematics.ik(self.geometry, x)
        J = kinematics.jacobian(self.geometry, x, theta)
        J_inv = np.linalg.inv(J)
        M = J_inv.T @ statics.task_inertia(self.geometry, x, theta) @ J_inv
        return np.concatenate([M.ravel(), J_inv.ravel()])

    def _part_output(self, part: slice):
        def calc(context, output):
            output.SetFromVector(context.get_discrete_state(self._state).value()[part])

        return calc

    def _CalcStatus(self, context, output):
        state = context.get_discrete_state(self._state).value()
        s = state[self._parts["status"]]
        schedules = context.get_discrete_state(self._inertia_state).value()[72]
        friction_mean = state[self._parts["friction"]].sum() / 6.0  # not np.mean: its overhead
        output.SetFromVector([s[1], s[2], friction_mean, schedules])

    def _Update(self, context, discrete_state):
        x_d = self._x_d.Eval(context)
        state = discrete_state.get_mutable_vector(self._state).get_mutable_value()
        state[:] = context.get_discrete_state(self._state).value()
        inertia = discrete_state.get_mutable_vector(self._inertia_state).get_mutable_value()
        inertia[:] = context.get_discrete_state(self._inertia_state).value()
        steps = int(state[self._parts["status"]][0])
        if steps % self.steps_per_schedule == 0 and steps > 0:
            M, J_inv = np.empty((6, 6)), np.empty((6, 6))
            legs, body = self._inertia_constants
            if path_kernels.joint_inertia(legs, body, x_d[:6], M, J_inv):
                inertia[:36], inertia[36:72] = M.ravel(), J_inv.ravel()
                inertia[72] += 1.0
            # else: the last kept; the step counts the reference's failure
        K, L, Phi, Gam = self._gains
        self._step(
            self._c,
            K,
            L,
            Phi,
            Gam,
            self._legs,
            inertia[:36].reshape(6, 6),
            inertia[36:72].reshape(6, 6),
            x_d,
            self._theta.Eval(context),
            self._T_ff.Eval(context),
            self._kt,
            state,
        )

    @property
    def constants(self) -> dict[str, float]:
        """{name: value} of what the compiled step runs with (:data:`.kernels.CONSTANTS`: the
        period, the lead, the friction's rate, bounds and adaptation, the torque limit, the
        delay, ...), SI units: the settings as the controller took them, to read back."""
        return dict(zip(_kernels().CONSTANTS, map(float, self._c)))

    def friction_estimate(self, context) -> np.ndarray:
        """(6,) the Coulomb friction the controller believes now, N m (this system's context)."""
        return context.get_discrete_state(self._state).value()[self._parts["friction"]].copy()
