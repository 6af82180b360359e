"""The crank servo's design: one crank's loop in acceleration units, its feedback gain from
Drake's DARE and its current estimator by pole placement.

Why one crank and acceleration units. On the servo bus the motion of a phantom is slow next to
the control period, and what holds the platform back is each crank's dry friction and encoder,
not the coupling of the chain, which the inverse-dynamics feed-forward carries. The controller
therefore commands an *acceleration* a (6,) of the cranks and applies the torque M_theta(x_d) a
(M_theta = J^-T M_x J^-1 the chain's joint-space inertia at the reference pose,
:func:`~stewart_drake.robot.statics.crank_inertia_matrix`): seen through M_theta every crank is
the same unit-inertia double integrator,

    theta_dd = a + delta

with delta the acceleration nothing models (a payload, friction the feed-forward missed), so one
gain and one estimator serve all six cranks. Sampled at the control period h with the command
held (zero-order hold) and acting ``delay_periods`` periods after the sample it came from
(the bus writes a torque at the start of the next period: d = 1):

    theta+ = theta + h omega + h^2/2 (a_act + delta),   omega+ = omega + h (a_act + delta)

**Feedback** (:func:`feedback_gain`): the linear-quadratic regulator of the error
[z, theta - theta_d, omega - omega_d, the d commands still pending], z the integral of the angle
error (integral action: a constant delta leaves no steady error), with Bryson's weights set by
one closed-loop bandwidth f_c: 1 on the angle error, 1/omega_c^2 on the rate error,
(omega_c / ``integral_ratio``)^2 on z and 1/omega_c^4 on a (for a double integrator, Q = diag(1,
0) and R = 1/omega_c^4 place the poles at omega_c with damping 0.707: Franklin, Powell and
Workman, *Digital Control of Dynamic Systems*, 3rd ed., 1998, section 9.3). The pending commands
cost 1e-9: nearly free, known. Solved by Drake's ``DiscreteAlgebraicRiccatiEquation``.

**Estimator** (:func:`estimator_gain`): the current estimator of Franklin, Powell and Workman
(section 8.2.3: the measurement of period k corrects the prediction before the command of period
k is computed), on the state [theta, omega, delta] (delta as a constant: their section 8.5,
"disturbance estimation"), its three error poles at the s-plane Butterworth pattern of radius
omega_o = 2 pi ``observer_bandwidth_hz`` mapped by z = exp(s h). It reads the angle only: at
4096 counts a turn and 10 ms a count is 0.15 rad/s of rate, more than a breathing phantom's
cranks turn, and the servos' Present Velocity is as coarse (0.024 rad/s); the estimator's model
carries the rate between counts.

Design choices and figures: docs/robot.md, "The controller on the bus".
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from pydrake.math import DiscreteAlgebraicRiccatiEquation

from ...base.checks import as_number, check_int
from ...base.errors import InvalidConfigError, RiccatiSolveError

#: Weight of each pending command in the LQR's cost: nearly free (they are known, not chosen),
#: but not zero, so that Q stays positive semidefinite with every state detectable.
PENDING_WEIGHT = 1e-9
#: Largest computation delay the design carries, periods (a state per period).
MAX_DELAY_PERIODS = 20
#: The largest bandwidth the sampling carries: 2 pi f h at most this (for the feedback and the
#: estimator alike; beyond it the zero-order hold's phase eats the margin).
MAX_OMEGA_H = 1.0

#: The largest share of a torque the gears may be believed to lose (an efficiency of 0.1).
MAX_LOAD_SHARE = 0.9
#: Each servo's torque per command within these factors of the catalogue's: the catalogue's
#: K_t is the e-Manual's stall ratio, within +-10 % unit to unit, and a commissioning that finds
#: more than a factor of 2 has found a different motor.
KT_RANGE = (0.5, 2.0)


def crank_model(h: float) -> tuple[np.ndarray, np.ndarray]:
    """(Phi (3, 3), Gamma (3,)) of one crank's [theta, omega, delta] over one period h, s, under
    a held acceleration: theta+ = theta + h omega + h^2/2 (a + delta), omega+ = omega + h (a +
    delta), delta+ = delta (exact: the double integrator's zero-order hold)."""
    Phi = np.array([[1.0, h, 0.5 * h * h], [0.0, 1.0, h], [0.0, 0.0, 1.0]])
    Gamma = np.array([0.5 * h * h, h, 0.0])
    return Phi, Gamma


def error_model(h: float, delay_periods: int) -> tuple[np.ndarray, np.ndarray]:
    """(A (3 + d, 3 + d), B (3 + d, 1)) of the regulated error [z, e_theta, e_omega, p_1 ..
    p_d] over one period h: z+ = z + h e_theta (the controller's rectangle rule), the crank's
    double integrator driven by p_1 (the command that acts now; the new one with d = 0), and the
    pending commands shifting, the new one entering last."""
    d = check_int("delay_periods", delay_periods, 0, MAX_DELAY_PERIODS)
    n = 3 + d
    A, B = np.zeros((n, n)), np.zeros((n, 1))
    A[0, 0], A[0, 1] = 1.0, h
    A[1, 1], A[1, 2], A[2, 2] = 1.0, h, 1.0
    drive = np.array([0.5 * h * h, h])
    if d == 0:
        B[1:3, 0] = drive
    else:
        A[1:3, 3] = drive
        for j in range(d - 1):
            A[3 + j, 4 + j] = 1.0
        B[n - 1, 0] = 1.0
    return A, B


def feedback_gain(
    h: float, delay_periods: int, bandwidth_hz: float, integral_ratio: float
) -> np.ndarray:
    """K (3 + d,): the command a = -K [z, e_theta, e_omega, p_1 .. p_d] minimising the sum over
    periods of e_theta^2 + e_omega^2 / omega_c^2 + z^2 (omega_c / integral_ratio)^2 +
    a^2 / omega_c^4 (the module docstring), omega_c = 2 pi ``bandwidth_hz``, s^-1.

    Raises:
        InvalidConfigError: a bandwidth the sampling does not carry (2 pi f h > 1), a
            non-positive ratio. RiccatiSolveError: Drake's solve failed.
    """
    w = _omega(h, bandwidth_hz, "bandwidth_hz")
    ratio = as_number("integral_ratio", integral_ratio, 0.0, lo_open=True)
    A, B = error_model(h, delay_periods)
    Q = np.diag([(w / ratio) ** 2, 1.0, w**-2] + [PENDING_WEIGHT] * (A.shape[0] - 3))
    R = np.array([[w**-4]])
    try:
        P = DiscreteAlgebraicRiccatiEquation(A, B, Q, R)
    except (RuntimeError, ValueError) as err:
        raise RiccatiSolveError(f"the crank servo's DARE failed: {err}") from None
    return np.linalg.solve(R + B.T @ P @ B, B.T @ P @ A)[0]


def estimator_gain(h: float, observer_bandwidth_hz: float) -> np.ndarray:
    """L (3,): the current estimator's gain, x_hat = x_bar + L (theta_read - theta_bar), whose
    prediction error x_bar+ - x+ = Phi (I - L C) (x_bar - x) has its poles at z = exp(s h), s on
    the Butterworth circle of radius 2 pi ``observer_bandwidth_hz`` (-1, -1/2 +- j sqrt(3)/2).

    Raises:
        InvalidConfigError: a bandwidth the sampling does not carry (2 pi f h > 1).
    """
    w = _omega(h, observer_bandwidth_hz, "observer_bandwidth_hz")
    Phi, _ = crank_model(h)
    s = w * np.array([-1.0, complex(-0.5, 0.5 * math.sqrt(3)), complex(-0.5, -0.5 * math.sqrt(3))])
    # eig(Phi - Phi L C) = eig(Phi - G C) with G = Phi L: the predictor's pole placement.
    G = ackermann_observer(Phi, np.array([1.0, 0.0, 0.0]), np.exp(s * h))
    return np.linalg.solve(Phi, G)


def ackermann_observer(Phi: np.ndarray, C: np.ndarray, poles) -> np.ndarray:
    """G (n,) with eig(Phi - G C) = ``poles``, for one output C (n,): Ackermann's formula on the
    dual, G = p(Phi) O^-1 e_n, p the polynomial with those roots and O = [C; C Phi; ...; C
    Phi^(n-1)] the observability matrix (Franklin, Powell and Workman, section 8.2.1, eq. 8.38).

    Raises:
        InvalidConfigError: (Phi, C) not observable.
    """
    n = Phi.shape[0]
    O = np.vstack([C @ np.linalg.matrix_power(Phi, k) for k in range(n)])
    if np.linalg.matrix_rank(O) < n:
        raise InvalidConfigError("the crank's angle does not observe its model's state")
    coefficients = np.real(np.poly(poles))  # p(z) = z^n + c_1 z^(n-1) + ... + c_n
    p_Phi = sum(c * np.linalg.matrix_power(Phi, n - k) for k, c in enumerate(coefficients))
    e_n = np.zeros(n)
    e_n[-1] = 1.0
    return p_Phi @ np.linalg.solve(O, e_n)


def _omega(h: float, f_hz: float, name: str) -> float:
    h = as_number("period_s", h, 0.0, lo_open=True)
    w = 2 * math.pi * as_number(name, f_hz, 0.0, lo_open=True)
    if w * h > MAX_OMEGA_H:
        raise InvalidConfigError(
            f"{name} = {f_hz:g} Hz is too high for a {h:g} s control period (2 pi f h = "
            f"{w * h:.2f} > {MAX_OMEGA_H:g}): at most {MAX_OMEGA_H / (2 * math.pi * h):.3g} Hz; "
            f"lower it or shorten control_period_s"
        )
    return w


@dataclass(frozen=True)
class CrankLoop:
    """The designed loop of one crank (:func:`design_loop`): the gains every crank shares.

    Attributes:
        h: control period, s. delay_periods: d, periods from a sample to its torque acting.
        bandwidth_hz, observer_bandwidth_hz: what the gains were designed for, Hz.
        K: (3 + d,) feedback gain on [z, e_theta, e_omega, p_1 .. p_d] (:func:`feedback_gain`).
        L: (3,) the current estimator's gain (:func:`estimator_gain`).
        Phi, Gamma: the crank's [theta, omega, delta] model over one period (:func:`crank_model`).
    """

    h: float
    delay_periods: int
    bandwidth_hz: float
    observer_bandwidth_hz: float
    K: np.ndarray
    L: np.ndarray
    Phi: np.ndarray
    Gamma: np.ndarray

    def closed_loop(self) -> np.ndarray:
        """The loop's state matrix over one period, the estimator in it: state [theta, omega,
        z, p_1 .. p_d, theta_bar, omega_bar, delta_bar] about a reference at rest with delta
        = 0 (the command from the corrected estimate; :func:`closed_loop_poles`)."""
        d, h = self.delay_periods, self.h
        Phi, Gam, L = self.Phi, self.Gamma, self.L
        n = 3 + d + 3
        T = np.zeros((n, n))
        # x_hat = x_bar + L (theta - theta_bar): as rows over [theta, ..., x_bar]
        i_bar = 3 + d
        xhat = np.zeros((3, n))
        xhat[:, i_bar : i_bar + 3] = np.eye(3) - np.outer(L, [1.0, 0.0, 0.0])
        xhat[:, 0] += L
        # a = -K [z, theta_hat, omega_hat, p]
        a = -self.K[0] * _unit(n, 2) - self.K[1] * xhat[0] - self.K[2] * xhat[1]
        for j in range(d):
            a = a - self.K[3 + j] * _unit(n, 3 + j)
        act = a if d == 0 else _unit(n, 3)
        # the plant (delta = 0)
        T[0] = _unit(n, 0) + h * _unit(n, 1) + 0.5 * h * h * act
        T[1] = _unit(n, 1) + h * act
        T[2] = _unit(n, 2) + h * xhat[0]
        for j in range(d):
            T[3 + j] = _unit(n, 4 + j) if j < d - 1 else a
        # the estimator's prediction from x_hat with the command that acts
        T[i_bar : i_bar + 3] = Phi @ xhat + np.outer(Gam, act)
        return T


def _unit(n: int, k: int) -> np.ndarray:
    e = np.zeros(n)
    e[k] = 1.0
    return e


def design_loop(
    h: float,
    delay_periods: int,
    bandwidth_hz: float,
    observer_bandwidth_hz: float,
    integral_ratio: float,
) -> CrankLoop:
    """One crank's loop for a control period h (s) and d ``delay_periods``: the feedback gain
    and the estimator (module docstring).

    Raises:
        InvalidConfigError: a bandwidth the sampling does not carry, a bad delay or ratio.
        RiccatiSolveError: the Riccati solve failed.
    """
    K = feedback_gain(h, delay_periods, bandwidth_hz, integral_ratio)
    L = estimator_gain(h, observer_bandwidth_hz)
    Phi, Gamma = crank_model(h)
    for a in (K, L, Phi, Gamma):
        a.setflags(write=False)
    return CrankLoop(
        float(h),
        int(delay_periods),
        float(bandwidth_hz),
        float(observer_bandwidth_hz),
        K,
        L,
        Phi,
        Gamma,
    )


def closed_loop_poles(loop: CrankLoop) -> np.ndarray:
    """The eigenvalues of :meth:`CrankLoop.closed_loop`: inside the unit circle when the loop
    with its estimator is stable (the separation principle makes them the regulator's and the
    estimator's, which a test checks)."""
    return np.linalg.eigvals(loop.closed_loop())
