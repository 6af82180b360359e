"""Linear models of the robot and of the LQI at a pose, in the controller's discrete time.

Built from the closed chain's own quantities at a pose x0 at rest (Drake's ``Linearize`` cannot
take this plant, docs/analysis.md, "The model"): the task-space inertia M_x
(:func:`~stewart_drake.robot.statics.task_inertia`), the Jacobian J = d theta / d x and the
gravity stiffness H = d T_hold / d x (central differences of
:func:`~stewart_drake.robot.statics.holding_torques`). In task coordinates, with T the motor
torques' deviation from the holding torques of x0 and b the motors' viscous friction,

    M_x x_ddot = J^T (T - H x - b J x_dot)

Three pieces, each a :class:`DiscreteModel` (numpy A, B, C, D at the period h; ``to_drake()``
gives a Drake ``LinearSystem``, ``to_control()`` a python-control ``StateSpace`` with the
[analysis] extra):

* :func:`plant_model`: torque command -> pose and rate, with the computation delay (d periods)
  and the drive's current loop (:func:`~stewart_drake.station.station.current_loop`'s
  formulas) in front of the mechanics;
* :func:`lqi_model`: the LQI's own linear form at that pose (eq. 34 with the gain it solves
  there, the integral state z, its pending torques, the gravity feed-forward linearized, H x_d,
  and on the robot as built the encoders' rate filter);
* :func:`closed_loop`: the two joined, with the reference [x_d, x_d_dot] as input and a
  task-force injection f at the plant input (T_in = T_ctrl + J^-T f) to open the loop there.

Left out (why: docs/analysis.md): Coulomb friction, the encoders' quantization, the
velocity-product (Coriolis) terms and the torque limit.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from ..base.checks import as_array, as_number
from ..base.errors import InvalidConfigError, MissingExtraError
from ..robot import kinematics, statics
from ..robot.geometry import StewartGeometry
from .lqi.driver import LqiDriver
from .lqi.gain import error_model, input_matrix, lqi_gain

#: How the plant's mechanics are discretized (:func:`plant_model`).
INTEGRATORS = ("sap", "zoh")
#: Step of the central differences of the holding torques (rad | m).
GRAVITY_STEP = 1e-6


@dataclass(frozen=True)
class DiscreteModel:
    """x+ = A x + B u, y = C x + D u at period ``h``; SI units.

    Attributes:
        A (n, n), B (n, m), C (p, n), D (p, m): the matrices. h: the period, s.
        inputs, outputs, states: a name per column of B, row of C, row of A (e.g. "T2", "Z").
    """

    A: np.ndarray
    B: np.ndarray
    C: np.ndarray
    D: np.ndarray
    h: float
    inputs: tuple
    outputs: tuple
    states: tuple

    def to_drake(self):
        """This model as a Drake discrete ``LinearSystem`` (time_period = h)."""
        from pydrake.systems.primitives import LinearSystem

        return LinearSystem(A=self.A, B=self.B, C=self.C, D=self.D, time_period=self.h)

    def to_control(self):
        """This model as a python-control discrete ``StateSpace`` (dt = h), names kept.

        Raises:
            MissingExtraError: python-control is not installed (the [analysis] extra).
        """
        try:
            import control
        except ImportError:
            raise MissingExtraError(
                "python-control is not installed: pip install 'stewart-drake[analysis]' "
                "(the Drake form, to_drake(), needs nothing more)"
            ) from None
        return control.ss(
            self.A,
            self.B,
            self.C,
            self.D,
            self.h,
            inputs=list(self.inputs),
            outputs=list(self.outputs),
            states=list(self.states),
        )

    def frequency_response(self, f_hz) -> np.ndarray:
        """(K, p, m) complex C (zI - A)^-1 B + D at z = exp(i 2 pi f h) for f (K,) Hz."""
        f = np.atleast_1d(np.asarray(f_hz, dtype=float))
        n = self.A.shape[0]
        out = np.empty((len(f), self.C.shape[0], self.B.shape[1]), dtype=complex)
        for k, fk in enumerate(f):
            z = np.exp(2j * np.pi * fk * self.h)
            out[k] = self.C @ np.linalg.solve(z * np.eye(n) - self.A, self.B) + self.D
        return out


def _names(prefix: str, n: int = 6) -> tuple:
    return tuple(f"{prefix}{k}" for k in range(n))


#: Pose coordinate names, the rows of a pose (rad, rad, rad, m, m, m).
AXES = kinematics.AXIS_NAMES


def gravity_stiffness(geometry: StewartGeometry, x0) -> np.ndarray:
    """H = d T_hold / d x at pose x0, (6, 6) N m per (rad | m): how the holding torques change
    with the pose (central differences of :func:`~stewart_drake.robot.statics.holding_torques`,
    step :data:`GRAVITY_STEP`)."""
    x0 = as_array("pose x0", x0, shape=(6,))
    e = GRAVITY_STEP * np.eye(6)
    T = statics.holding_torques(geometry, np.vstack([x0 + e, x0 - e]))
    return ((T[:6] - T[6:]) / (2 * GRAVITY_STEP)).T


def plant_model(
    geometry: StewartGeometry,
    x0,
    h: float,
    *,
    delay_periods: int = 0,
    viscous_damping: float = 0.0,
    current_time_constant_s: float = 0.0,
    integrator: str = "sap",
) -> DiscreteModel:
    """The robot at pose x0 at rest, from motor torques to pose and rate, at period h.

    States: pose x (6) and rate v (6) deviations, then the current loop's torque (6, with a
    current loop), then the d torque commands still in the pipe (6 d, newest first). Input: the
    command T (6, N m, deviation from the holding torques of x0), applied d periods later
    through the current loop. Outputs: x (6, rad | m) and v (6, rad/s | m/s), no feed-through
    (a torque acts over the next period).

    Args:
        geometry: the robot (with the motors' reflected inertia in it, as the plan gives it).
        x0: (6,) pose [rad, m]. h: period, s (the plant's time step = the control period).
        delay_periods: d >= 0, the computation delay in periods.
        viscous_damping: the motors' viscous friction at the crank, N m s/rad (b).
        current_time_constant_s: the drive's current-loop lag, s (0: none); discretized as the
            station does it, the torque averaged over each step.
        integrator: "sap" steps the mechanics as Drake's SAP solver does (v+ = v + h a(v+),
            x+ = x + h v+, damping implicit, gravity at the start of the step: the plant the
            simulations run); "zoh" samples the continuous robot exactly (zero-order hold; the
            LQI's own design model when b = H = 0). They differ by half a period of position
            lag: 3.6 deg at 20 Hz with h = 1 ms.
    Raises:
        InvalidConfigError: a bad pose, period, delay, friction or integrator;
        UnreachablePoseError, SingularPoseError: x0 cannot be linearized.
    """
    x0 = as_array("pose x0", x0, shape=(6,))
    h = as_number("period h [s]", h, 0.0, 1.0, lo_open=True)
    b = as_number("viscous_damping [N m s/rad]", viscous_damping, 0.0)
    tau = as_number("current_time_constant_s", current_time_constant_s, 0.0)
    if integrator not in INTEGRATORS:
        raise InvalidConfigError(f"integrator must be one of {INTEGRATORS}, got {integrator!r}")
    error_model(np.eye(6), h, delay_periods)  # checks delay_periods
    A_m, B_m = _mechanics(geometry, x0, h, b, integrator)
    A, B, n_lag = _drive_path(A_m, B_m, h, tau, int(delay_periods))
    n, d = len(A), int(delay_periods)
    C = np.hstack([np.eye(12), np.zeros((12, n - 12))])
    states = (
        tuple(f"x_{a}" for a in AXES)
        + tuple(f"v_{a}" for a in AXES)
        + (_names("T_lag") if n_lag else ())
        + tuple(f"T_pipe{j}_{k}" for j in range(d) for k in range(6))
    )
    return DiscreteModel(
        A,
        B,
        C,
        np.zeros((12, 6)),
        h,
        _names("T"),
        tuple(AXES) + tuple(f"{a}_dot" for a in AXES),
        states,
    )


def _mechanics(geometry, x0, h: float, b: float, integrator: str):
    """(A_m (12, 12), B_m (12, 6)): the robot's mechanics at x0 from a torque (deviation, N m)
    to pose and rate, at period h, discretized as :func:`plant_model`'s ``integrator`` says."""
    theta = kinematics.ik(geometry, x0)
    J = kinematics.jacobian(geometry, x0, theta)
    M = statics.task_inertia(geometry, x0, theta)
    H = gravity_stiffness(geometry, x0)
    Minv = np.linalg.inv(M)
    B_c = Minv @ J.T  # acceleration per N m
    K_g = B_c @ H  # acceleration per (rad | m) of pose, the gravity stiffness
    D_v = Minv @ (b * J.T @ J)  # acceleration per (rad/s | m/s), the viscous friction
    I, Z = np.eye(6), np.zeros((6, 6))
    if integrator == "sap":
        W = np.linalg.inv(I + h * D_v)
        A_m = np.block([[I - h * h * W @ K_g, h * W], [-h * W @ K_g, W]])
        B_m = np.vstack([h * h * W @ B_c, h * W @ B_c])
    else:
        from scipy.linalg import expm

        F = np.zeros((18, 18))
        F[:12, :12] = np.block([[Z, I], [-K_g, -D_v]])
        F[6:12, 12:] = B_c
        E = expm(F * h)
        A_m, B_m = E[:12, :12], E[:12, 12:]
    return A_m, B_m


def _drive_path(A_m, B_m, h: float, tau: float, d: int):
    """(A (n, n), B (n, 6), n_lag): the mechanics (:func:`_mechanics`) behind the drive's
    current loop (lag ``tau`` s, 0: none; its 6 states, n_lag) and the d periods of the
    computation delay (a shift register of 6 d states), states ordered as
    :func:`plant_model` says."""
    I = np.eye(6)
    # the torque that reaches the mechanics: T_m = C_in s + D_in T, s the pipe's states
    n_lag = 6 if tau > 0 else 0
    n = 12 + n_lag + 6 * d
    A, B = np.zeros((n, n)), np.zeros((n, 6))
    A[:12, :12] = A_m
    # the delayed command (the pipe's oldest, or T itself without delay)
    C_del, D_del = np.zeros((6, n)), np.zeros((6, 6))
    if d:
        C_del[:, n - 6 :] = I
        B[12 + n_lag : 12 + n_lag + 6] = I
        for j in range(d - 1):
            r = 12 + n_lag + 6 * (j + 1)
            A[r : r + 6, r - 6 : r] = I
    else:
        D_del = I
    if n_lag:
        a = float(np.exp(-h / tau))
        c = tau / h * (1 - a)
        A[12:18] += (1 - a) * C_del
        A[12:18, 12:18] += a * I
        B[12:18] += (1 - a) * D_del
        C_in = c * np.hstack([np.zeros((6, 12)), I, np.zeros((6, 6 * d))]) + (1 - c) * C_del
        D_in = (1 - c) * D_del
    else:
        C_in, D_in = C_del, D_del
    A[:12] += B_m @ C_in
    B[:12] += B_m @ D_in
    return A, B, n_lag


def lqi_design(
    geometry: StewartGeometry, x0, h: float, driver: LqiDriver | None = None, delay_periods=0
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The LQI's design at pose x0: its error model and gain, as the controller solves them.

    Args:
        driver: the LQI's options (weights omega_Q, omega_R and scales; default ``LqiDriver()``).
        delay_periods: the robot's computation delay; compensated when
            ``driver.delay_compensation``.
    Returns:
        (A (n, n), B (n, 6), K (6, n)): e+ = A e + B u, u = -K e, e = [e_x, e_x_dot, z, the
        pending torques (6 d)], n = 18 + 6 d (:func:`~.lqi.gain.error_model`,
        :func:`~.lqi.gain.lqi_gain`).
    """
    driver = (driver or LqiDriver()).validate(h, delay_periods)
    d = int(delay_periods) if driver.delay_compensation else 0
    scales = driver.scales.build()
    A, B = error_model(input_matrix(geometry, x0), h, d)
    K = lqi_gain(A, B, driver.omega_Q * scales.Q_unit(d), driver.omega_R * scales.R_unit())
    return A, B, K


def lqi_model(
    geometry: StewartGeometry,
    x0,
    h: float,
    driver: LqiDriver | None = None,
    *,
    delay_periods: int = 0,
    rate_cutoff_hz: float | None = None,
) -> DiscreteModel:
    """The LQI's linear form at pose x0 (gain held at its value there), at period h.

    Inputs: the measured pose x (6) and rate v (6), the reference pose x_d (6) and rate
    x_d_dot (6). Output: the torque command T (6, N m, deviation from the holding torques of
    x0): T = H x_d - K [x - x_d, v - x_d_dot, z, pending] (eq. 34 with the gravity
    feed-forward T_hold(x_d) linearized). States: z (6), z+ = z + h (x - x_d); the pending
    feedback torques (6 d, with delay compensation); with ``rate_cutoff_hz`` (the robot as
    built) the estimator's last pose and rate (12): it then ignores the rate input and uses
    v = v_prev + alpha ((x - x_prev) / h - v_prev), alpha = 1 - exp(-2 pi f_c h), as
    :class:`~.estimator.PoseEstimator` does (the forward kinematics is exact: x is the pose).

    Raises:
        InvalidConfigError, RiccatiSolveError: as :func:`lqi_design`.
    """
    x0 = as_array("pose x0", x0, shape=(6,))
    driver = (driver or LqiDriver()).validate(h, delay_periods)
    _, _, K = lqi_design(geometry, x0, h, driver, delay_periods)
    d = (K.shape[1] - 18) // 6
    H = gravity_stiffness(geometry, x0)
    K_p, K_v, K_I, K_u = K[:, :6], K[:, 6:12], K[:, 12:18], K[:, 18:]
    I = np.eye(6)
    est = 12 if rate_cutoff_hz is not None else 0
    n = 6 + 6 * d + est
    A, B, C, D = np.zeros((n, n)), np.zeros((n, 24)), np.zeros((6, n)), np.zeros((6, 24))
    # the rate the law uses: v (input) or the estimator's v_hat = (1-alpha) v_prev + alpha (x -
    # x_prev) / h, as rows over [state | inputs]
    v_state, v_in = np.zeros((6, n)), np.zeros((6, 24))
    if est:
        f_c = as_number("rate_cutoff_hz", rate_cutoff_hz, 0.0, 0.5 / h, lo_open=True)
        alpha = 1.0 - np.exp(-2 * np.pi * f_c * h)
        xp, vp = 6 + 6 * d, 12 + 6 * d
        v_state[:, xp : xp + 6] = -alpha / h * I
        v_state[:, vp : vp + 6] = (1 - alpha) * I
        v_in[:, :6] = alpha / h * I
    else:
        v_in[:, 6:12] = I
    # T_fb = -K_p (x - x_d) - K_v (v - x_d_dot) - K_I z - K_u pending
    C_fb, D_fb = np.zeros((6, n)), np.zeros((6, 24))
    D_fb[:, :6], D_fb[:, 12:18], D_fb[:, 18:24] = -K_p, K_p, K_v
    C_fb -= K_v @ v_state
    D_fb -= K_v @ v_in
    C_fb[:, :6] -= K_I
    if d:
        C_fb[:, 6 : 6 + 6 * d] -= K_u
    C[:], D[:] = C_fb, D_fb
    D[:, 12:18] += H
    # z+ = z + h (x - x_d)
    A[:6, :6] = I
    B[:6, :6], B[:6, 12:18] = h * I, -h * I
    if d:  # the newest pending is this period's feedback torque; the rest shift
        A[6:12], B[6:12] = C_fb, D_fb
        for j in range(d - 1):
            A[12 + 6 * j : 18 + 6 * j, 6 + 6 * j : 12 + 6 * j] = I
    if est:
        B[xp : xp + 6, :6] = I
        A[vp : vp + 6], B[vp : vp + 6] = v_state, v_in
    states = (
        tuple(f"z_{a}" for a in AXES)
        + tuple(f"pending{j}_{k}" for j in range(d) for k in range(6))
        + (tuple(f"x_prev_{a}" for a in AXES) + tuple(f"v_prev_{a}" for a in AXES) if est else ())
    )
    inputs = (
        tuple(AXES)
        + tuple(f"{a}_dot" for a in AXES)
        + tuple(f"{a}_d" for a in AXES)
        + tuple(f"{a}_d_dot" for a in AXES)
    )
    return DiscreteModel(A, B, C, D, h, inputs, _names("T"), states)


def closed_loop(plant: DiscreteModel, controller: DiscreteModel, J) -> DiscreteModel:
    """The plant and the controller joined: the controller reads the plant's pose and rate, its
    torque drives the plant, plus a task-force injection at the plant input.

    Args:
        plant: :func:`plant_model` (input T (6), outputs x, v (12)).
        controller: :func:`lqi_model` (inputs x, v, x_d, x_d_dot (24), output T (6)).
        J: (6, 6) the Jacobian d theta / d x at the pose (tau = J^T maps torques to task forces).
    Returns:
        inputs [x_d (6), x_d_dot (6), f (6)]: the reference and a task-force injection
        (N | N m) added at the plant input (T_in = T + J^-T f); outputs [x (6), v (6), f_c (6)]
        with f_c = J^T T the controller's task force. States: the plant's, then the
        controller's. Opening axis i of the loop is then f_i in, -f_c,i out
        (:func:`open_loop`, :func:`loop_at_a_time` give the loop itself).
    """
    J = as_array("Jacobian J", J, shape=(6, 6))
    Ap, Bp, Cp = plant.A, plant.B, plant.C
    Ak, Bk, Ck, Dk = controller.A, controller.B, controller.C, controller.D
    Dky, Dkr = Dk[:, :12], Dk[:, 12:]
    Bky, Bkr = Bk[:, :12], Bk[:, 12:]
    JinvT = np.linalg.inv(J.T)
    n_k = Ak.shape[0]
    A = np.block([[Ap + Bp @ Dky @ Cp, Bp @ Ck], [Bky @ Cp, Ak]])
    B = np.block([[Bp @ Dkr, Bp @ JinvT], [Bkr, np.zeros((n_k, 6))]])
    C = np.block([[Cp, np.zeros((12, n_k))], [J.T @ Dky @ Cp, J.T @ Ck]])
    D = np.block([[np.zeros((12, 18))], [J.T @ Dkr, np.zeros((6, 6))]])
    return DiscreteModel(
        A,
        B,
        C,
        D,
        plant.h,
        controller.inputs[12:] + tuple(f"f_{a}" for a in AXES),
        plant.outputs + tuple(f"f_c_{a}" for a in AXES),
        plant.states + controller.states,
    )


def open_loop(plant: DiscreteModel, controller: DiscreteModel, J) -> DiscreteModel:
    """The loop opened at the plant input, in task forces: w (6, N | N m) enters the plant as
    J^-T w, the controller reads its pose and rate (reference zero) and the output is
    -J^T T (6): L(z) with the negative-feedback convention, so the loop closes with w = -y.
    States: the plant's, then the controller's; no feed-through.

    Args:
        as :func:`closed_loop`.
    """
    J = as_array("Jacobian J", J, shape=(6, 6))
    Ap, Bp, Cp = plant.A, plant.B, plant.C
    Ak, Bk, Ck, Dk = controller.A, controller.B, controller.C, controller.D
    n_k = Ak.shape[0]
    A = np.block([[Ap, np.zeros((Ap.shape[0], n_k))], [Bk[:, :12] @ Cp, Ak]])
    B = np.vstack([Bp @ np.linalg.inv(J.T), np.zeros((n_k, 6))])
    C = -J.T @ np.hstack([Dk[:, :12] @ Cp, Ck])
    return DiscreteModel(
        A,
        B,
        C,
        np.zeros((6, 6)),
        plant.h,
        tuple(f"f_{a}" for a in AXES),
        tuple(f"-f_c_{a}" for a in AXES),
        plant.states + controller.states,
    )


def loop_at_a_time(loop: DiscreteModel, axis: int) -> DiscreteModel:
    """The single-input single-output loop of one axis with the five others closed: the loop
    transfer a control engineer breaks at one input while the rest stay in service.

    Args:
        loop: :func:`open_loop` (6 inputs, 6 outputs, no feed-through). axis: 0..5
            (phi, theta, psi, X, Y, Z).
    """
    if isinstance(axis, bool) or not isinstance(axis, (int, np.integer)) or not 0 <= axis < 6:
        raise InvalidConfigError(f"axis must be an integer in 0..5, got {axis!r}")
    rest = [k for k in range(6) if k != axis]
    A = loop.A - loop.B[:, rest] @ loop.C[rest]
    return dataclasses.replace(
        loop,
        A=A,
        B=loop.B[:, [axis]],
        C=loop.C[[axis]],
        D=np.zeros((1, 1)),
        inputs=(loop.inputs[axis],),
        outputs=(loop.outputs[axis],),
    )
