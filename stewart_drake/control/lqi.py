"""LQI regulator of paper section III as a Drake LeafSystem, with online gain re-scheduling.

Error model (paper eqs. 19-25). Per pose coordinate the error is a double integrator driven by the
motor torques through B(x) = M_x(x)^-1 tau(x) (tau = J^T, eq. 18 corrected; M_x the task-space
inertia of platform, cranks and rods); gravity is the constant disturbance d of eq. 19 and is
cancelled by a virtual-work feed-forward. With the integral of the pose error z (eq. 23) the
state is e = [e_x (6), e_x_dot (6), z (6)] (block order; the paper interleaves e_x and e_x_dot).
Sampled at h with zero-order hold, the double integrator has the closed form

    e_x+     = e_x + h e_x_dot + h^2/2 B u
    e_x_dot+ = e_x_dot + h B u
    z+       = z + h e_x               (the controller's own rectangle-rule integrator)

so no matrix exponential is needed. Gains come from Drake's DiscreteAlgebraicRiccatiEquation
(eqs. 31-32, with eq. 32's missing "B^T P A" restored) and the law is u = T_ff - K_p e_bar - K_I z
(eq. 34).

Weights (departure from eq. 27, docs/paper_notes.md): Q = omega_Q I and R = omega_R I on errors in
SI units make the torque far too cheap relative to a 1 mm error, so the gains cannot hold the
platform. We apply eq. 27 to *normalized* errors and torques (Bryson's rule):
Q = omega_Q diag(1/s_e^2, 1/s_v^2, 1/s_z^2), R = omega_R diag(1/s_T^2), with the scales of
:class:`LqiScales` (1 mrad / 1 mm of pose error by default). omega_Q and omega_R in {0.1, 1, 10}
then span soft to stiff controllers that all hold the platform.
"""

import dataclasses
import typing
import warnings
from dataclasses import dataclass, field
from typing import ClassVar

import numpy as np
from pydrake.math import DiscreteAlgebraicRiccatiEquation
from pydrake.systems.framework import Diagram, DiagramBuilder, LeafSystem
from pydrake.systems.primitives import Demultiplexer, Multiplexer

from ..base.checks import as_array, as_number, check_multiple
from ..base.errors import (
    InvalidConfigError,
    NotStabilizableError,
    RiccatiSolveError,
    SimulationDivergedError,
    SingularPoseError,
    UnreachablePoseError,
)
from ..base.mirrors import ValueMirror
from ..robot import kinematics, statics
from ..robot.geometry import X_HOME, StewartGeometry
from . import lqi_step
from .contract import LQI_STATUS_NAMES, ControllerContext, ControllerDriver
from .lqi_step import LqiStatus

N_E = 18  # error-model states [e_x, e_x_dot, z]
#: How the gain is re-solved at a re-schedule (see :class:`LqiController`).
RICCATI_MODES = ("warm", "track", "cold")
GAIN_TRANSFER_MODES = ("integral", "feedback", "none")
#: The reference governor takes over when the reference's feed-forward exceeds this fraction of
#: the torque limit, and keeps the holding torques of the pose it follows within it. The rest of
#: the limit is the headroom a motor at its bound keeps for feedback: it must exceed the motor's
#: Coulomb friction (0.018 N m on paper_hardware) for the motor to lift its crank back
#: (docs/hardware.md measures margins from 0.85 to 0.95). Ours: the paper has no torque limit.
GOVERNOR_MARGIN = 0.9
#: Relative size of the last term at which the Stein series of :func:`lqi_gain_warm` stops.
STEIN_TOL = 1e-16
#: The weights omega_Q, omega_R the LQI accepts (eq. 27; only their ratio sets the gain).
LQI_OMEGA_MIN, LQI_OMEGA_MAX = 1e-3, 1e3
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
        :func:`error_model` get 1e-6 of the torque weight: almost free, but not zero, so the
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
    its options, checked (:meth:`validate`) and built (:meth:`make`) here, the one place.

    Attributes:
        omega_Q, omega_R: weights of eq. 27 on normalized errors and torques, in
            [:data:`LQI_OMEGA_MIN`, :data:`LQI_OMEGA_MAX`] (only their ratio matters): the
            constant on the controller's ``omega`` input; a tuner replaces them.
        schedule_period_s: re-solve the Riccati gain from the measured pose this often, s (a
            whole multiple of the control period; a change of omega re-solves at once). Ours.
        riccati: how the gain is re-solved: "warm" refines the last gain by Newton's method
            (:func:`lqi_gain_warm`) to convergence, falling back to the cold solve if that
            fails; "track" takes one Newton step per re-schedule (every iterate stabilizes, the
            gain converges over successive re-schedules); "cold" calls Drake's DARE each time.
        scales: normalization of Q and R (Bryson's rule, :class:`LqiScalesConfig`).
        anti_windup: stop integrating z while a command is clipped at the motors' limit
            (clamping); acts only when the motors have a limit. Ours: the paper has none.
        delay_compensation: augment the error model with the torques still in the pipe when the
            robot has a computation delay (:func:`error_model`); false ignores the delay.
        reference_governor: with a torque limit, do not follow a reference whose own
            feed-forward exceeds :data:`GOVERNOR_MARGIN` of the limit (a pose the motors cannot
            hold): follow the nearest pose they can hold (:meth:`LqiController.govern`) until
            the reference is back within reach. Anti-windup alone cannot keep such a platform:
            past that pose gravity wins and it falls (docs/hardware.md). Ours.
        schedule_pose: re-schedule the input matrix B(x) from the measured pose; false keeps the
            start pose's, as a plain LQI (the gain then changes only with omega). Ours.
        gain_transfer: what carries over when the gain changes (new weights, a new pose):
            "integral" keeps the integral torque, K_I,new z_new = K_I,old z_old, so what the
            integrator learned (friction, model error) stays and only the proportional part
            follows the new gain; "feedback" keeps the whole feedback, K_I,new z_new = K_old e -
            K_rest,new e_rest (no torque step); "none" keeps z, a torque step, as the paper
            does. The three compared: docs/paper_notes.md.
        friction_compensation_Nm: Coulomb friction the controller believes each motor has, at
            the crank, N m (0: none, the paper scenarios'): the feed-forward then carries
            ``friction_compensation_Nm * tanh(theta_dot_d / friction_rate_rad_s)`` per motor,
            theta_dot_d = J x_dot_d the reference's crank rates
            (:func:`~.lqi_step.friction_feedforward`). Needs the encoders' estimator (the robot
            as built). On breathing it lowers the translation error (9.2 to 5.3 um at 17-bit
            encoders) and, with 2^19 counts or more, the rotation (15-17 to 6-8 urad), but not
            the 17-bit rotation floor, which is the encoders' (docs/organ_motion.md, "The
            rotation floor"). Ours: the paper's motors have no friction.
        friction_rate_rad_s: crank rate, rad/s, of the smoothed sign above (> 0); 3e-4 (33 um/s
            at a crank tip) measured best of 1e-4 to 1e-2 on breathing at 2^17 to 2^23 counts.
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
        as_number(f"{prefix}schedule_period_s", self.schedule_period_s, 0.0, lo_open=True)
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

    def make(self, context: ControllerContext, compiled: bool = True) -> "LqiDiagram":
        """The LQI with the controller contract's ports for the Diagram that ``context``
        describes; ``compiled=False`` runs its numpy reference step (same numbers, slower)."""
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


def error_model(B_c: np.ndarray, h: float, delay_periods: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """Discrete error model (A, B) at sample time h for continuous input matrix B_c (6, 6).

    Args:
        B_c: (6, 6) input matrix. h: sample time, s.
        delay_periods: d >= 0 periods between a sample and the torque it computes: the state is
            augmented with the d torques already commanded but not yet acting (newest first),
            e = [e_x, e_x_dot, z, u_{k-1}, ..., u_{k-d}], and e+ = A e + B u_k with the oldest
            acting on the error dynamics (ours: the paper has no delay).
    Returns:
        A (n, n), B (n, 6) of e+ = A e + B u, n = 18 + 6 d, e = [e_x, e_x_dot, z, ...]; paper
        eqs. 21-25 with an exact zero-order hold of the double integrators.
    Raises:
        InvalidConfigError: B_c not a finite (6, 6) array, h not in (0, 1] s (a slower
            controller cannot hold the platform; the bound also keeps h^2 B_c finite), d < 0.
    """
    B_c = as_array("input matrix B_c", B_c, shape=(6, 6))
    h = as_number("sample time h [s]", h, 0.0, 1.0, lo_open=True)
    if (
        isinstance(delay_periods, bool)
        or not isinstance(delay_periods, (int, np.integer))
        or delay_periods < 0
    ):
        raise InvalidConfigError(f"delay_periods must be an integer >= 0, got {delay_periods!r}")
    I = np.eye(6)
    A = np.zeros((N_E, N_E))
    A[0:6, 0:6] = I
    A[0:6, 6:12] = h * I
    A[6:12, 6:12] = I
    A[12:18, 0:6] = h * I
    A[12:18, 12:18] = I
    B = np.zeros((N_E, 6))
    B[0:6] = 0.5 * h * h * B_c
    B[6:12] = h * B_c
    d = int(delay_periods)
    if d == 0:
        return A, B
    n = N_E + 6 * d
    A_d, B_d = np.zeros((n, n)), np.zeros((n, 6))
    A_d[:N_E, :N_E] = A
    A_d[:N_E, n - 6 :] = B  # u_{k-d} acts now
    for j in range(d - 1):  # the history shifts by one
        A_d[N_E + 6 * (j + 1) : N_E + 6 * (j + 2), N_E + 6 * j : N_E + 6 * (j + 1)] = np.eye(6)
    B_d[N_E : N_E + 6] = np.eye(6)  # u_k is the newest
    return A_d, B_d


def input_matrix(geometry: StewartGeometry, x, theta=None) -> np.ndarray:
    """B_c(x) = M_x(x)^-1 tau(x): pose acceleration per unit motor torque, (6, 6).

    Args:
        x: (6,) pose [rad, m]; theta: optional (6,) motor angles of x.
    Returns:
        (6, 6) finite, (rad/s^2 or m/s^2) per N m.
    Raises:
        UnreachablePoseError, SingularPoseError, InvalidConfigError: see kinematics.jacobian.
    Source: paper eq. 22 sets b = tau (unit inertia); dividing by the task inertia M_x, with the
    legs' inertia (:func:`statics.task_inertia`), is ours (docs/paper_notes.md); tau = J^T (eq. 18
    corrected).
    """
    tau = kinematics.tau(geometry, x, theta)  # validates x and theta
    theta = kinematics.ik(geometry, x) if theta is None else theta
    try:
        B_c = np.linalg.solve(statics.task_inertia(geometry, x, theta), tau)
    except np.linalg.LinAlgError:
        B_c = np.full((6, 6), np.inf)
    if not np.isfinite(B_c).all():
        raise SingularPoseError("B_c", np.inf, np.inf, pose=np.ravel(x))
    return B_c


def input_matrix_single(geometry: StewartGeometry, x) -> tuple[np.ndarray, np.ndarray]:
    """:func:`input_matrix` of ONE pose by the single-pose kernels (about 5 times faster), and
    the Jacobian it used: the per-step path of the gain re-scheduling.

    Args:
        x: (6,) finite pose [rad, m] (not validated: the controller's own estimate).
    Returns:
        (B_c (6, 6), J (6, 6)).
    Raises:
        SingularPoseError: B_c not finite (a singular or unreachable pose).
    """
    _, cache = kinematics.ik_single(geometry, x)
    J = kinematics.jacobian_single(geometry, cache)
    try:
        B_c = np.linalg.solve(statics.task_inertia_single(geometry, cache, J), J.T)
    except np.linalg.LinAlgError:
        B_c = np.full((6, 6), np.inf)
    if not np.isfinite(B_c).all():
        raise SingularPoseError("B_c", np.inf, np.inf, pose=np.ravel(x))
    return B_c, J


def body_constants(geometry: StewartGeometry) -> np.ndarray:
    """The robot as the compiled B(x) reads it (:data:`~.lqi_kernels.BODY`): crank and rod
    length, s^2 - a^2, the platform's principal inertia (3) and mass, the crank shaft's inertia
    (crank about its shaft + the motor's reflected inertia, as
    :func:`~stewart_drake.robot.statics.task_inertia`), the rod's mass and transverse inertia.
    SI units."""
    g = geometry
    a = g.crank_length
    shaft = g.crank_inertia[1] + g.crank_mass * (0.5 * a) ** 2 + g.motor_reflected_inertia
    return np.array(
        [
            a,
            g.rod_length,
            g.rod_length**2 - a * a,
            *g.platform_inertia,
            g.platform_mass,
            shaft,
            g.rod_mass,
            g.rod_inertia[0],
        ],
        dtype=float,
    )


def hautus_checks(A: np.ndarray, B: np.ndarray, C: np.ndarray, tol: float = 1e-9) -> dict:
    """Stabilizability of (A, B) and detectability of (A, C) by the Hautus test (eqs. 28-29).

    Every eigenvalue with |lambda| >= 1 (here all are 1: chains of integrators) must satisfy
    rank [lambda I - A, B] = n and rank [lambda I - A; C] = n.
    Returns:
        dict with ``stabilizable``, ``detectable`` (bool) and the minimum ranks found.
    Raises:
        InvalidConfigError: A not (n, n), B not (n, m), C not (p, n), or non-finite entries.
    """
    A = as_array("A", A)
    n = A.shape[0] if A.ndim == 2 else -1
    if A.shape != (n, n) or n < 1:
        raise InvalidConfigError(f"A must be square (n, n), got {A.shape}")
    B, C = as_array("B", B), as_array("C", C)
    if B.ndim != 2 or B.shape[0] != n or C.ndim != 2 or C.shape[1] != n:
        raise InvalidConfigError(f"B must be ({n}, m) and C (p, {n}); got {B.shape} and {C.shape}")
    tol = as_number("tol", tol, 0.0)
    try:
        eigs = np.linalg.eigvals(A)
        unstable = np.unique(np.round(eigs[np.abs(eigs) >= 1 - 1e-9], 9))
        rank_ab, rank_ac = n, n
        for lam in unstable:
            M = lam * np.eye(n) - A
            rank_ab = min(rank_ab, np.linalg.matrix_rank(np.hstack([M, B]), tol))
            rank_ac = min(rank_ac, np.linalg.matrix_rank(np.vstack([M, C]), tol))
    except np.linalg.LinAlgError as err:
        raise InvalidConfigError(f"Hautus test failed numerically ({err}); scale A, B, C") from None
    return {
        "stabilizable": rank_ab == n,
        "detectable": rank_ac == n,
        "rank_AB": int(rank_ab),
        "rank_AC": int(rank_ac),
        "n": n,
    }


def balance(A, B, Q, R):
    """Diagonal scaling e = D_x e~, u = D_u u~ with D = diag(Q)^-1/2, diag(R)^-1/2 of the
    Riccati problem (A, B, Q, R) (the compiled Newton step, :func:`~.lqi_kernels.newton_gain`,
    scales the same way).

    The LQI's Q spans 1 (rates, 1/(1 rad/s)^2) to 2.5e9 (integrals, 1/(2e-5)^2): unscaled, the
    Riccati solution has cond(P) ~ 4e9 and the gains carry ~1e-8 relative rounding error; scaled,
    cond(P) ~ 400. Returns (A~, B~, Q~, R~, d_x, d_u).
    """
    qd, rd = np.diag(Q).copy(), np.diag(R).copy()
    d_x = 1.0 / np.sqrt(qd) if np.all(qd > 0) else np.ones(len(qd))
    d_u = 1.0 / np.sqrt(rd) if np.all(rd > 0) else np.ones(len(rd))
    return (
        A * (1 / d_x).reshape(-1, 1) * d_x.reshape(1, -1),
        B * (1 / d_x).reshape(-1, 1) * d_u.reshape(1, -1),
        Q * d_x.reshape(-1, 1) * d_x.reshape(1, -1),
        R * d_u.reshape(-1, 1) * d_u.reshape(1, -1),
        d_x,
        d_u,
    )


def _check_finite(**arrays) -> None:
    for name, M in arrays.items():
        if not np.all(np.isfinite(M)):
            raise RiccatiSolveError(f"{name} has non-finite entries; no gain computed")


def lqi_gain(A: np.ndarray, B: np.ndarray, Q: np.ndarray, R: np.ndarray) -> np.ndarray:
    """Optimal gain K = (R + B^T P B)^-1 B^T P A (eqs. 31-32); u = -K e.

    Solved on the diagonally scaled problem (:func:`balance`) with Drake's
    DiscreteAlgebraicRiccatiEquation, then scaled back: the same gain, better conditioned.

    Args:
        A: (n, n), B: (n, m), Q: (n, n) symmetric >= 0, R: (m, m) symmetric > 0.
    Returns:
        (m, n) finite gain K with spectral radius of A - B K < 1.
    Raises:
        RiccatiSolveError: Drake's solver failed, or the result is not finite or not stabilizing.
        InvalidConfigError: shapes that do not match (n, n), (n, m), (n, n), (m, m).
    """
    _check_finite(A=A, B=B, Q=Q, R=R)
    n, m = np.shape(B) if np.ndim(B) == 2 else (-1, -1)
    if (np.shape(A), np.shape(Q), np.shape(R)) != ((n, n), (n, n), (m, m)) or min(n, m) < 1:
        raise InvalidConfigError(
            f"lqi_gain needs A (n, n), B (n, m), Q (n, n), R (m, m); got "
            f"{np.shape(A)}, {np.shape(B)}, {np.shape(Q)}, {np.shape(R)}"
        )
    Ab, Bb, Qb, Rb, d_x, d_u = balance(A, B, Q, R)
    try:
        P = DiscreteAlgebraicRiccatiEquation(Ab, Bb, Qb, Rb)
    except (RuntimeError, ValueError, SystemExit) as err:
        # pydrake reports a failed precondition (e.g. (A, B) not stabilizable) as SystemExit.
        raise RiccatiSolveError(f"DiscreteAlgebraicRiccatiEquation failed: {err}") from None
    try:
        K = d_u[:, None] * np.linalg.solve(Rb + Bb.T @ P @ Bb, Bb.T @ P @ Ab) / d_x[None, :]
    except np.linalg.LinAlgError as err:
        raise RiccatiSolveError(
            f"R + B^T P B is singular ({err}); make R positive definite"
        ) from None
    if not np.all(np.isfinite(K)):
        raise RiccatiSolveError("Riccati gain is not finite")
    try:
        rho = np.max(np.abs(np.linalg.eigvals(A - B @ K)))
    except np.linalg.LinAlgError:
        rho = np.nan
    if not rho < 1.0:
        raise RiccatiSolveError(
            f"Riccati gain does not stabilize the model (spectral radius {rho:.6g})"
        )
    return K


def lqi_gain_warm(
    A: np.ndarray,
    B: np.ndarray,
    Q: np.ndarray,
    R: np.ndarray,
    K_start,
    tol: float = 1e-4,
    max_iter: int = 8,
) -> tuple[np.ndarray, int]:
    """The gain of :func:`lqi_gain` by Newton's method (Hewer's algorithm) from a nearby gain.

    Each iteration solves one Stein equation P = A_c^T P A_c + Q + K^T R K for A_c = A - B K
    (compiled squared Smith iteration, :func:`~.lqi_kernels.stein`: about 0.05 ms on 24 states,
    a sixth of Drake's RealDiscreteLyapunovEquation and of scipy's, to 1e-12 of them;
    benchmarks/realtime.py --riccati) and sets K = (R + B^T P B)^-1 B^T P A. From any
    stabilizing K_start the iterates stay stabilizing and
    converge quadratically to the Riccati gain, so a gain from the previous re-schedule (a pose
    a few ms away) is refined in two iterations, about half the cost of a cold DARE. Newton's
    quadratic convergence makes the last step size an estimate of the previous iterate's error
    squared: the loop stops once the relative step is below ``tol`` (1e-4 gives at most 5e-9
    relative to the cold solve along the paper manoeuvre, in 2.05 iterations on average; tested).
    It iterates on the diagonally scaled problem (:func:`balance`), without which the Stein
    solves' rounding (cond(P) ~ 4e9) alone would leave ~5e-8.

    Args:
        A (n, n), B (n, m), Q (n, n), R (m, m): as :func:`lqi_gain`. K_start: (m, n) stabilizing.
    Returns:
        (K (m, n), iterations).
    Raises:
        RiccatiSolveError: K_start does not stabilize (A, B), a Stein solution is not positive
            definite, or no convergence in ``max_iter`` iterations; the caller falls back to the
            cold :func:`lqi_gain`.
    Source: G. A. Hewer, IEEE TAC 16(4), 1971; paper eqs. 31-32.
    """
    K = np.asarray(K_start, dtype=float)
    _check_finite(A=A, B=B, Q=Q, R=R, K_start=K)
    K, iterations = _compiled_stages().newton_gain(
        *(np.ascontiguousarray(M, dtype=float) for M in (A, B, Q, R, K)),
        float(tol),
        int(max_iter),
        STEIN_TOL,
    )
    if iterations == -1:
        raise RiccatiSolveError(
            "warm start does not stabilize the model (the Stein equation's series diverges)"
        )
    if iterations < 0:
        raise RiccatiSolveError(f"Newton iteration did not converge in {max_iter} iterations")
    return K, iterations


def project_onto_torque_bound(d, T, G, bound: float) -> tuple[np.ndarray, np.ndarray]:
    """The step s nearest to d with |T + G s| <= bound for every motor: the Euclidean projection
    onto the linearized torque bound (a small QP, by an active set).

    A motor joins the active set when the current step would overload it, on the side it would
    cross; it leaves when its Lagrange multiplier turns negative (the bound pulls the step
    instead of pushing it). At most one side of a motor can be active (bound > 0), so the
    active rows stay independent for a non-singular G.

    Args:
        d: (6,) the step wanted [rad, m]. T: (6,) torques at s = 0, N m. G: (6, 6) d T / d x.
        bound: N m, > 0.
    Returns:
        (s (6,), C (k, 6)): the step, and the active bounds' rows (sign times the rows of G),
        whose null space is the tangent the step can still move along.
    Raises:
        numpy.linalg.LinAlgError: dependent active rows (a singular G).
    """
    predicted = T + G @ d
    side = np.sign(predicted)
    active = np.abs(predicted) > bound
    s, C = d, G[:0]
    for _ in range(12):  # each pass adds or releases one motor
        if active.any():
            C = side[active, None] * G[active]
            lam = np.linalg.solve(C @ C.T, C @ d - (bound - side[active] * T[active]))
            if lam.min() < 0.0:
                active[np.flatnonzero(active)[np.argmin(lam)]] = False
                continue
            s = d - C.T @ lam
        else:
            s, C = d, G[:0]
        predicted = T + G @ s
        over = ~active & (np.abs(predicted) > bound * (1 + 1e-9))
        if not over.any():
            break
        k = int(np.argmax(np.where(over, np.abs(predicted), -np.inf)))
        active[k], side[k] = True, np.sign(predicted[k])
    return s, C


class LqiController(LeafSystem):
    """LQI torque controller of the platform pose, re-scheduled online (paper section III): the
    system that computes. :class:`LqiDiagram` gives it the controller contract's named ports
    (:mod:`~stewart_drake.control.contract`); the Diagram uses that.

    Input port ``u``: the input vector of :class:`~.lqi_step.LqiLayout` (``layout``),
    [pose_in, x_d, T_ff, omega, T_applied]:
        ``x`` (12,): pose estimate and rate [phi, theta, psi, X, Y, Z, their rates], rad, m, /s;
            with an estimator instead ``motor_angle`` (6,), the encoders, rad.
        ``x_d`` (18,): reference pose, rate and acceleration (same units, /s^2 for the last 6).
        ``T_ff`` (6,): feed-forward motor torques, N m (:mod:`~stewart_drake.run.reference`).
        ``omega`` (2,): [omega_Q, omega_R] > 0 (the ANN tuner drives it; else a constant).
        ``motor_torque_applied`` (6,): with ``feature_window``, the torques the motors apply, N m.
    Output port ``state``: the whole state (``layout``), whose first parts :class:`LqiDiagram`
    exports as:
        ``T`` (6,): motor torques, N m, sampled at ``offset_s`` after each plant step and held;
            within +-torque_limit_Nm when the controller knows the motors' limit.
        ``integral`` (6,): the integral states z of eq. 23 [rad s, m s].
        ``status`` (7,): [omega_Q, omega_R in use, gain solves, failed solves, |z|, saturated
            steps, governed steps] (``status_names`` = :data:`~.contract.LQI_STATUS_NAMES`).
        ``e_bar`` (6,): the pose error x - x_d the last update acted on (for the density features,
            so they see exactly the controller's error at the controller's instants).
        ``x_hat`` (12,): with an estimator, its pose and rate estimate.
        ``feature_window`` (12 w + 2,): with ``feature_window`` = w, the last w samples of
            [e_bar, motor_torque_applied] for :class:`~.features.DensityFeatures` (ring buffer
            [rows, n_valid, head]), sampled at the controller's instants: the features then cost
            no callback of their own per period.
    Discrete state: one vector, named part by part (:class:`~.lqi_step.LqiLayout`, ``LqiStatus``;
    no bare indices): the exported parts above, then the steps since the last solve, the gain K
    and the previous one (6 n each, row-major 6 x n, n = 18 + 6 d; :meth:`gain_in_use`), the d
    feedback torques commanded but not yet acting (6 d), the governor's last reference within
    reach (24), the estimator's J^-1 (36).

    Each control period runs one Python callback: it reads ``u`` and the state (one port, one
    vector) and calls the stages of :mod:`.lqi_step` (estimate, re-schedule, govern, feedback,
    saturate, integrate), compiled (:mod:`.lqi_kernels`, the default) or in numpy
    (``compiled=False``, the reference); only the gain re-solve (every schedule period), the
    governor (out of reach) and a refused chord step run in Python.

    Args:
        geometry: the robot (for B(x)).
        driver: the options (:class:`LqiDriver`: re-scheduling, Riccati mode, scales,
            anti-windup, governor, gain transfer; its weights are the Diagram's, on ``omega``);
            default ``LqiDriver()``.
        period_s: control period h, s (paper: 1 ms).
        offset_s: time of the sample within the period. The Diagram uses half a plant step, so
            the controller reads the state the plant just produced and its torque acts from the
            next plant step on: the zero-order-hold model above is then exact, with no extra
            step of delay (offset 0 would read the state one plant step old).
        x_initial: pose of the first gain (default home). x_dot_initial: its rate (the
            estimator's start; default at rest).
        torque_limit_Nm: the motors' torque limit, N m, or None: commands are clipped to it (the
            driver's anti-windup and reference governor act only with a limit).
        delay_periods: control periods between a sample and its torque acting (the computation
            delay); with ``driver.delay_compensation`` the error model carries the pending
            torques (:func:`error_model`).
        estimator: None to read the pose and rate on the ``x`` input; or a
            :class:`~stewart_drake.control.estimator.PoseEstimator`: the controller then reads
            the encoders on a ``motor_angle`` input (6, rad) and estimates the pose and rate in
            its own update (one Newton chord step per period with the Jacobian of the last
            re-schedule, :meth:`~.estimator.PoseEstimator.track`), exported as ``x_hat`` (12).
        feature_window: None, or the samples w of the density features' window (eqs. 35-36)
            the controller buffers for them (the Diagram sets it when it has a tuner).
        compiled: run the compiled stages (:mod:`.lqi_kernels`); False runs the numpy
            reference (:mod:`.lqi_step`), the same numbers to 1e-12 and about 10 times slower.
    Raises:
        InvalidConfigError: a bad period, offset, limit, delay or window, or a bad option of the
            driver (named ``driver.<option>``).
        RiccatiSolveError: no gain at the start pose.
        NotStabilizableError: the error model fails the Hautus test at the start pose
            (eqs. 28-29).
    """

    def __init__(
        self,
        geometry: StewartGeometry,
        driver: LqiDriver | None = None,
        *,
        period_s: float = 1e-3,
        offset_s: float = 0.0,
        x_initial=None,
        x_dot_initial=None,
        torque_limit_Nm: float | None = None,
        delay_periods: int = 0,
        estimator=None,
        feature_window: int | None = None,
        compiled: bool = True,
    ):
        super().__init__()
        self.status_names = LQI_STATUS_NAMES
        self.geometry = geometry
        self.estimator = estimator
        self._configure(
            driver or LqiDriver(),
            period_s,
            offset_s,
            torque_limit_Nm,
            delay_periods,
            feature_window,
        )
        x0 = X_HOME if x_initial is None else np.asarray(x_initial, dtype=float)
        self.x_initial = x0.copy()
        K0 = self._initial_gain(x0)
        #: Newton iterations and cold solves so far (diagnostics, not state: a benchmark reads
        #: them after a run; they do not affect the simulation).
        self.solve_stats = {"warm": 0, "warm_iterations": 0, "cold": 0}
        T0 = statics.holding_torques(geometry, x0)
        self.layout = lqi_step.LqiLayout.build(
            self.n, self.delay, self.governor, estimator is not None, feature_window
        )
        self.feature_window = feature_window
        self._u = self.DeclareVectorInputPort("u", self.layout.u_size)
        self._state_index = self.DeclareDiscreteState(
            self._initial_state(
                x0,
                np.zeros(6) if x_dot_initial is None else np.asarray(x_dot_initial, dtype=float),
                T0,
                K0,
            )
        )
        self.DeclareStateOutputPort("state", self._state_index)
        self.DeclarePeriodicDiscreteUpdateEvent(
            period_sec=self.h, offset_sec=float(offset_s), update=self._Update
        )
        self._load_constants(compiled)

    def _configure(
        self, driver: LqiDriver, period_s, offset_s, torque_limit_Nm, delay_periods, feature_window
    ) -> None:
        """Check the settings and keep what the stages read: the period, the driver's options,
        the limit, the delay and the unit weights Q_1, R_1."""
        if not (np.isfinite(period_s) and period_s > 0):
            raise InvalidConfigError(f"control period must be > 0 s, got {period_s}")
        if not (0 <= offset_s < period_s):
            raise InvalidConfigError(f"offset_s must be in [0, period_s), got {offset_s}")
        if feature_window is not None and (
            isinstance(feature_window, bool)
            or not isinstance(feature_window, (int, np.integer))
            or feature_window < 1
        ):
            raise InvalidConfigError(
                f"feature_window must be None or an integer >= 1, got {feature_window!r}"
            )
        self.driver = driver.validate(
            period_s, delay_periods, prefix="driver.", delay_name="delay_periods"
        )
        self.h = float(period_s)
        self.steps_per_schedule = int(round(driver.schedule_period_s / period_s))
        self.scales = driver.scales.build()
        self.riccati = driver.riccati
        self.torque_limit = (
            None
            if torque_limit_Nm is None
            else as_number("torque_limit_Nm", torque_limit_Nm, 0.0, lo_open=True)
        )
        self.anti_windup = driver.anti_windup
        self.governor = driver.reference_governor and self.torque_limit is not None
        error_model(np.eye(6), self.h, delay_periods)  # checks delay_periods
        self.delay = int(delay_periods) if driver.delay_compensation else 0
        self.n = N_E + 6 * self.delay
        self._governor_bound = (
            GOVERNOR_MARGIN * self.torque_limit
            if self.governor and self.torque_limit is not None
            else np.inf
        )
        self._Q1, self._R1 = self.scales.Q_unit(self.delay), self.scales.R_unit()
        self.schedule_pose = driver.schedule_pose
        self.gain_transfer = driver.gain_transfer
        self.friction = float(driver.friction_compensation_Nm)
        if self.friction > 0.0 and self.estimator is None:
            raise InvalidConfigError(
                "driver.friction_compensation_Nm needs the encoders' estimator (crank rates from "
                "its Jacobian): set it to 0 on the ideal robot, or give the robot hardware"
            )

    def _initial_gain(self, x0) -> np.ndarray:
        """K at the start pose and unit weights, after the Hautus test of the error model there
        (eqs. 28-29)."""
        A, B = error_model(input_matrix(self.geometry, x0), self.h, self.delay)
        self.hautus = hautus_checks(A, B, np.sqrt(self._Q1))
        if not (self.hautus["stabilizable"] and self.hautus["detectable"]):
            raise NotStabilizableError(self.hautus, x0)
        K0 = lqi_gain(A, B, self._Q1, self._R1)
        self.K_initial = K0
        return K0

    def _load_constants(self, compiled: bool) -> None:
        """What the stages need and never change (configuration, not state), read-only as the
        compiled stages were compiled for (lqi_kernels.warm_up)."""
        self.compiled = bool(compiled)
        self._stages = _compiled_stages() if self.compiled else lqi_step
        self._constants = self._step_constants()
        self._bounds = self.layout.bounds()
        self._legs = np.zeros((6, 9)) if self.estimator is None else self.estimator.legs.copy()
        self._legs.setflags(write=False)
        self._gain_legs = np.array(kinematics.leg_constants(self.geometry)[0])
        self._body = body_constants(self.geometry)
        for constant in (self._gain_legs, self._body):
            constant.setflags(write=False)

    def _initial_state(self, x0, v0, T0, K0) -> np.ndarray:
        """The state at t = 0: holding torques, weights 1 and one solve (K_initial) so far, the
        estimate at x0 moving at v0, K = K_old = K0, and a counter that makes the first update
        re-solve at the measured pose."""
        lay = self.layout
        state = np.zeros(lay.state_size)
        state[lay.T] = T0
        status = LqiStatus(state[lay.status])
        status.omega_Q = status.omega_R = status.gain_solves = 1.0
        state[lay.counter] = self.steps_per_schedule
        state[lay.K] = state[lay.K_old] = K0.reshape(-1)
        if self.governor:
            state[lay.hold] = np.concatenate([x0, np.zeros(12), T0])
        if self.estimator is not None:
            state[lay.x_hat] = np.concatenate([x0, v0])
            state[lay.J_inv] = np.linalg.inv(kinematics.ik_jacobian(self.geometry, x0)[1]).reshape(
                -1
            )
        return state

    def _step_constants(self) -> np.ndarray:
        """The constants of the stages (``lqi_step.StepConstants``) as the array they read."""
        c = lqi_step.StepConstants(np.zeros(len(lqi_step.StepConstants.get_fields())))
        c.h = self.h
        c.torque_limit = np.inf if self.torque_limit is None else self.torque_limit
        c.governor_bound = self._governor_bound
        c.steps_per_schedule = self.steps_per_schedule
        c.schedule_pose = float(self.schedule_pose)
        c.anti_windup = float(self.anti_windup)
        c.transfer = lqi_step.TRANSFER_CODES[self.gain_transfer]
        if self.estimator is not None:
            c.estimator = 1.0
            c.alpha = self.estimator.alpha
            c.crank_length, c.leg_c = self.estimator.crank_length, self.estimator.leg_c
            c.fk_jump = self.estimator.chord_step_max
            c.friction = self.friction
            c.friction_rate = self.driver.friction_rate_rad_s
        constants = c[:]
        constants.setflags(write=False)
        return constants

    # -- gain ----------------------------------------------------------------------------------
    def _check_weights(self, omega_Q: float, omega_R: float) -> tuple[float, float]:
        return (
            as_number("omega_Q", omega_Q, LQI_OMEGA_MIN, LQI_OMEGA_MAX),
            as_number("omega_R", omega_R, LQI_OMEGA_MIN, LQI_OMEGA_MAX),
        )

    def gain(self, x, omega_Q: float = 1.0, omega_R: float = 1.0, K_start=None) -> np.ndarray:
        """(6, n) LQI gain K = [K_p | K_I (| K_u)] at pose x for weights omega_Q, omega_R (eq. 33);
        n = 18, + 6 per period of delay (the gain on the pending torques).

        Args:
            K_start: optional (6, 18) nearby stabilizing gain: the gain is then refined from it
                by :func:`lqi_gain_warm` (same K to < 1e-8 relative), with the cold DARE as the
                fallback.
        Raises:
            InvalidConfigError: weights not in [1e-3, 1e3]; RiccatiSolveError: see lqi_gain.
        """
        x = as_array("pose x", x, shape=(6,))
        kinematics.ik(self.geometry, x)  # a typed error for a bad or unreachable pose
        return self._gain(x, omega_Q, omega_R, K_start)[0]

    def _gain(self, x, omega_Q, omega_R, K_start):
        """(K, J^-1): the gain of :meth:`gain` and the inverse Jacobian at x it used.

        From a start gain, one compiled call (:func:`~.lqi_kernels.warm_gain`: B(x), the error
        model and Newton's method, the same numbers as :func:`input_matrix_single`,
        :func:`error_model` and :func:`lqi_gain_warm`), about a fifth of their cost in numpy
        (benchmarks/realtime.py --riccati); the cold DARE is the fallback.
        """
        omega_Q, omega_R = self._check_weights(omega_Q, omega_R)
        x = np.ascontiguousarray(x, dtype=float)
        Q, R = omega_Q * self._Q1, omega_R * self._R1
        if K_start is not None:
            one_step = self.riccati == "track"
            K, J_inv, iterations = _compiled_stages().warm_gain(
                self._gain_legs,
                self._body,
                x,
                self.h,
                self.delay,
                Q,
                R,
                np.ascontiguousarray(K_start, dtype=float),
                np.inf if one_step else 1e-4,
                1 if one_step else 8,
                STEIN_TOL,
            )
            if iterations > 0:
                self.solve_stats["warm"] += 1
                self.solve_stats["warm_iterations"] += iterations
                return K, J_inv
            # a singular pose is named by input_matrix_single below; a failed Newton iteration
            # falls back to the cold solve
        B_c, J = input_matrix_single(self.geometry, x)
        A, B = error_model(B_c, self.h, self.delay)
        self.solve_stats["cold"] += 1
        return lqi_gain(A, B, Q, R), np.linalg.inv(J)

    def govern(self, hold, ref) -> np.ndarray:
        """The reference the governor follows when ``ref`` is out of reach: the pose nearest to
        ``ref[:6]`` (Euclidean in rad and m) whose holding torques are within
        :data:`GOVERNOR_MARGIN` of the limit, moving with the part of the reference's rate that
        keeps them there.

        One step of sequential quadratic programming per control period, from the last governed
        pose ``hold[:6]`` (so the governed reference moves continuously: started from ``ref``
        each time, the set of motors at the bound can switch and the reference jump by
        centimetres): the step towards ``ref`` projected exactly onto the motors' bound
        linearized at that pose by finite differences (one batched statics call;
        :func:`project_onto_torque_bound`). The reference moves little in a period, so one step
        is within 6 um | 2 urad and 3e-7 N m of three along the paper manoeuvre, at 0.6 ms
        instead of 1.1 ms.

        The projection is exact, onto every motor's bound at once: a step projected only onto
        the motors the full step would overload can push another one to the limit itself, and a
        motor at the limit keeps no headroom for feedback (docs/hardware.md). The rate and
        acceleration are those of the reference projected onto the tangent of the active bounds
        (the derivative of the projection, curvature neglected), so the pose and the rate the
        LQI tracks agree. On the paper manoeuvre's extreme with a 0.35 N m limit the nearest
        such pose shifts Y and Z by up to 19 and 13 mm rather than giving up a fifth of a radian
        of roll. Ours: the paper has no torque limit.

        Args:
            hold: (24,) the last governed reference (followed at rest if no pose is found).
            ref: (18,) the reference out of reach.
        Returns:
            (24,) [pose (6), rate (6), acceleration (6), the pose's holding torques (6)].
        """
        bound, eps = GOVERNOR_MARGIN * self.torque_limit, 1e-6  # type: ignore[operator]
        x = hold[:6] if np.any(hold[18:]) else ref[:6]
        try:
            T = statics.holding_torques(
                self.geometry, x + np.vstack([np.zeros(6), eps * np.eye(6)])
            )
            G = ((T[1:] - T[0]) / eps).T  # d T / d x, (6, 6)
            step, C = project_onto_torque_bound(ref[:6] - x, T[0], G, bound)
            x = x + step
            T0 = statics.holding_torques(self.geometry, x)
            tangent = np.eye(6) - C.T @ np.linalg.solve(C @ C.T, C) if len(C) else np.eye(6)
        except (UnreachablePoseError, SingularPoseError, InvalidConfigError, np.linalg.LinAlgError):
            T0 = np.full(6, np.inf)
        if not np.abs(T0).max() <= self.torque_limit:
            return np.concatenate([hold[:6], np.zeros(12), hold[18:]])
        return np.concatenate([x, tangent @ ref[6:12], tangent @ ref[12:18], T0])

    def inputs(self, context) -> np.ndarray:
        """The input vector ``u`` of this period (``layout``), read once: the one place the
        controller reads its ports, so a test can inject a fault there."""
        return typing.cast(np.ndarray, self._u.Eval(context))

    # -- update --------------------------------------------------------------------------------
    def gain_in_use(self, context) -> np.ndarray:
        """(6, n) the gain K the controller's state holds in ``context`` (its own context)."""
        state = context.get_discrete_state(self._state_index).get_value()
        return state[self.layout.K].reshape(6, self.n).copy()

    def state_part(self, context, name: str) -> np.ndarray:
        """A copy of the named part of the state (:class:`~.lqi_step.LqiLayout`, e.g. "z",
        "status") in ``context`` (the controller's own)."""
        state = context.get_discrete_state(self._state_index).get_value()
        return state[getattr(self.layout, name)].copy()

    def _Update(self, context, discrete_state):
        # One port in, the stages (compiled) on the state Drake owns (discrete_state holds the
        # current values, updated in place), and Python only for the rare stages.
        u = self.inputs(context)
        state = discrete_state.get_mutable_value(self._state_index)
        need, flags = self._stages.step(self._constants, self._legs, u, state, self._bounds)
        if need:
            flags = self._stages.act(
                self._constants,
                u,
                state,
                self._bounds,
                self._python_stages(context, need, u, state),
            )
        if flags & lqi_step.NONFINITE_SAMPLE:
            lay = self.layout
            sample = np.concatenate([state[lay.e_bar], u[lay.T_applied]])
            raise SimulationDivergedError(
                f"non-finite {'e_bar' if not np.all(np.isfinite(sample[:6])) else 'T'} = "
                f"{np.array2string(sample, precision=4)} ([e_bar, T]) at the density features' "
                f"window (features are not computed from diverged signals)",
                t=context.get_time(),
            )

    # -- the stages that run in Python -------------------------------------------------------
    def _python_stages(self, context, need: int, u, state) -> int:
        """Estimate by full Newton, re-schedule, govern, as ``need`` says; returns the mode
        flags :func:`~.lqi_step.act` needs (GAIN_CHANGED, GOVERNED)."""
        lay, mode = self.layout, 0
        if need & lqi_step.NEED_NEWTON:
            self._estimate_by_newton(u[lay.pose_in], state[lay.x_hat])
        x = u[lay.pose_in] if self.estimator is None else state[lay.x_hat]
        if need & lqi_step.NEED_SCHEDULE and self._reschedule(context, x, u[lay.omega], state):
            mode |= lqi_step.GAIN_CHANGED
        if need & lqi_step.NEED_GOVERNOR:
            state[lay.hold] = self.govern(state[lay.hold], u[lay.x_d])
            mode |= lqi_step.GOVERNED
        return mode

    def _estimate_by_newton(self, theta, x_hat) -> None:
        """Estimate: the full Newton solve when the chord step is refused (a jump, a stale
        Jacobian; :meth:`~.estimator.PoseEstimator.estimate`), then the rate filter."""
        x0 = x_hat[:6] + self.h * x_hat[6:]
        x = self.estimator.estimate(np.asarray(theta, dtype=float), x0)[0]
        self._stages.filter_rate(self.h, self.estimator.alpha, x, x_hat)

    def _reschedule(self, context, x, omega, state) -> bool:
        """Re-schedule: re-solve the gain at the estimated pose for the weights on the port
        (eqs. 31-33, :meth:`_gain`), keeping the previous gain for the gain transfer and the
        Jacobian's inverse for the estimator. A failed solve keeps the last good gain (with a
        warning, then every hundredth). True if the gain changed."""
        lay = self.layout
        status, K = LqiStatus(state[lay.status]), state[lay.K].reshape(6, self.n)
        try:
            K_new, J_inv = self._gain(
                np.array(x[:6]) if self.schedule_pose else self.x_initial,
                omega[0],
                omega[1],
                K_start=K if self.riccati != "cold" else None,
            )
        except (
            RiccatiSolveError,
            InvalidConfigError,
            UnreachablePoseError,
            SingularPoseError,
            np.linalg.LinAlgError,
        ) as err:
            status.gain_failures += 1
            if status.gain_failures == 1 or status.gain_failures % 100 == 0:
                warnings.warn(
                    f"t = {context.get_time():.4f} s: gain re-schedule failed ({err}); "
                    f"keeping the last good gain ({int(status.gain_failures)} failures "
                    f"so far)",
                    RuntimeWarning,
                    stacklevel=1,
                )
            return False
        status.omega_Q, status.omega_R = omega
        status.gain_solves += 1
        state[lay.K_old] = state[lay.K]
        K[:] = K_new
        if self.estimator is not None:
            state[lay.J_inv] = J_inv.reshape(-1)
        return True


class LqiDiagram(Diagram):
    """:class:`LqiController` with the controller contract's named ports: a ``Multiplexer``
    gathers them into its input vector and a ``Demultiplexer`` splits its state into outputs
    (C++ systems: the controller's Python update reads one port and writes one vector).

    Input ports: ``x`` (12,) or with an estimator ``motor_angle`` (6,); ``x_d`` (18,); ``T_ff``
    (6,); ``omega`` (2,); with a feature window ``motor_torque_applied`` (6,).
    Output ports: ``T`` (6,), ``integral`` (6,), ``status`` (7,), ``e_bar`` (6,), with an
    estimator ``x_hat`` (12,), with a feature window ``feature_window`` (12 w + 2,).
    Units and meanings: :class:`LqiController`.

    Args:
        as :class:`LqiController` (geometry, the :class:`LqiDriver`, then keywords).
    Attributes:
        lqi: the :class:`LqiController` inside (gains, governor, settings).
        status_names: :data:`~.contract.LQI_STATUS_NAMES`.
    """

    def __init__(self, geometry: StewartGeometry, driver: LqiDriver | None = None, **settings):
        super().__init__()
        builder = DiagramBuilder()
        self.lqi = LqiController(geometry, driver, **settings)
        builder.AddNamedSystem("lqi", self.lqi)
        self.status_names = LQI_STATUS_NAMES
        lay = self.lqi.layout
        names = (
            "x" if self.lqi.estimator is None else "motor_angle",
            "x_d",
            "T_ff",
            "omega",
            "motor_torque_applied",
        )
        sizes = [getattr(lay, p).stop - getattr(lay, p).start for p in lqi_step.PARTS[:5]]
        inputs = [(name, size) for name, size in zip(names, sizes) if size]
        mux = builder.AddNamedSystem("inputs", Multiplexer([size for _, size in inputs]))
        for k, (name, _) in enumerate(inputs):
            builder.ExportInput(mux.get_input_port(k), name)
        builder.Connect(mux.get_output_port(), self.lqi.get_input_port())
        parts = [
            (port, getattr(lay, p))
            for p, port in lqi_step.EXPORTED.items()
            if getattr(lay, p).stop > getattr(lay, p).start
        ]
        exported = parts[-1][1].stop
        sizes = [sl.stop - sl.start for _, sl in parts] + [lay.state_size - exported]
        demux = builder.AddNamedSystem("outputs", Demultiplexer(sizes))
        builder.Connect(self.lqi.get_output_port(), demux.get_input_port())
        for k, (port, _) in enumerate(parts):
            builder.ExportOutput(demux.get_output_port(k), port)
        builder.BuildInto(self)

    @property
    def n(self) -> int:
        """Columns of the gain, 18 + 6 d."""
        return self.lqi.n

    @property
    def geometry(self) -> StewartGeometry:
        """The robot the controller believes in."""
        return self.lqi.geometry

    def lqi_context(self, context):
        """The :class:`LqiController`'s context inside this Diagram's ``context``."""
        return self.GetSubsystemContext(self.lqi, context)

    def gain_in_use(self, context) -> np.ndarray:
        """(6, n) the gain in use in this Diagram's ``context``
        (:meth:`LqiController.gain_in_use`)."""
        return self.lqi.gain_in_use(self.lqi_context(context))

    def get_x_input_port(self):
        return self.GetInputPort("x")

    def get_x_d_input_port(self):
        return self.GetInputPort("x_d")

    def get_T_ff_input_port(self):
        return self.GetInputPort("T_ff")

    def get_omega_input_port(self):
        return self.GetInputPort("omega")


def _compiled_stages():
    """The compiled stages (:mod:`.lqi_kernels`), imported when a controller first needs them
    (numba's import and the first compilation are paid by runs, not by ``import lqi``)."""
    from . import lqi_kernels

    return lqi_kernels
