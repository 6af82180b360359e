"""The LQI's work of one control period, stage by stage, in numpy: the reference implementation.

:class:`~.lqi.LqiController` runs the same stages compiled (:mod:`.lqi_kernels`, numba), which a
test holds equal to these (the same bits, in fact) on random poses, weights, saturation and
delay cases; this module is the one to read. Both export :func:`step`, :func:`observe` and
:func:`act` with the same signature, over two arrays that Drake owns, the controller's input
vector ``u`` and its discrete state ``state``, and the constants the controller builds once:

* ``observe`` estimates the pose from the encoders (one Newton chord step and a rate filter) and
  says which stages need Python this period: a full Newton solve when the chord step is refused,
  a gain re-solve (every schedule period, or at once when omega changes: eqs. 31-33), the
  reference governor (a feed-forward the motors cannot hold);
* ``act`` adds the motors' Coulomb friction to the feed-forward (when asked: off in the paper
  scenarios), forms the error state (eqs. 23-25), carries the integral over a gain change, applies
  the law u = T_ff - K e (eq. 34), clips to the motors' limit, records the pending torques of
  the computation delay, integrates z (eq. 23, with anti-windup) and buffers the density
  features' samples (eqs. 35-36);
* ``step`` is observe, then act when no stage needs Python: one call per period in the common
  case.

Named state, no bare indices. :class:`LqiLayout` names every part of ``u`` and ``state``
(index slices); the status part is named by :data:`~.contract.LQI_STATUS_NAMES` (``LqiStatus``,
a Drake ``namedview``), the constants by ``StepConstants`` (a ``namedview``). The compiled
stages cannot take Python objects: they receive the constants as one float array and the
layout as an int array of (start, stop) rows, :meth:`LqiLayout.bounds`, read through
:func:`part` with the index constants below.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from pydrake.common.containers import namedview

from ..robot.kinematics import ik_scalar
from .contract import LQI_STATUS_NAMES

#: The status group, by name (``status.gain_solves += 1``).
LqiStatus = namedview("LqiStatus", LQI_STATUS_NAMES)
OMEGA_Q, OMEGA_R, GAIN_SOLVES, GAIN_FAILURES, INTEGRAL_NORM, SATURATED_STEPS, GOVERNED_STEPS = (
    range(len(LQI_STATUS_NAMES))
)

#: The constants of the step, by name; ``governor_bound`` and ``torque_limit`` are inf when
#: there is none, ``transfer`` a code of :data:`TRANSFER_CODES`, the flags 0.0 or 1.0;
#: ``friction`` (N m, 0: none) and ``friction_rate`` (rad/s) the Coulomb feed-forward's.
StepConstants = namedview(
    "StepConstants",
    (
        "h",
        "alpha",
        "torque_limit",
        "governor_bound",
        "steps_per_schedule",
        "schedule_pose",
        "anti_windup",
        "transfer",
        "estimator",
        "crank_length",
        "leg_c",
        "fk_jump",
        "friction",
        "friction_rate",
    ),
)
(
    H,
    ALPHA,
    TORQUE_LIMIT,
    GOVERNOR_BOUND,
    STEPS_PER_SCHEDULE,
    SCHEDULE_POSE,
    ANTI_WINDUP,
    TRANSFER,
    ESTIMATOR,
    CRANK_LENGTH,
    LEG_C,
    FK_JUMP,
    FRICTION,
    FRICTION_RATE,
) = range(len(StepConstants.get_fields()))
#: gain_transfer modes (see LqiController) as the codes the compiled stages compare.
TRANSFER_CODES = {"none": 0.0, "integral": 1.0, "feedback": 2.0}
TRANSFER_NONE, TRANSFER_INTEGRAL, TRANSFER_FEEDBACK = 0.0, 1.0, 2.0

#: observe() says which stages need Python this period (bit flags).
NEED_NEWTON, NEED_SCHEDULE, NEED_GOVERNOR = 1, 2, 4
#: act() is told what Python did (bit flags) ...
GAIN_CHANGED, GOVERNED = 1, 2
#: ... and answers with this flag when the features' sample was not finite.
NONFINITE_SAMPLE = 1

#: The named parts of the input vector ``u`` and of the state, in order (:class:`LqiLayout`).
PARTS = (
    "pose_in",
    "x_d",
    "T_ff",
    "omega",
    "T_applied",
    "T",
    "z",
    "status",
    "e_bar",
    "x_hat",
    "window",
    "counter",
    "K",
    "K_old",
    "pending",
    "hold",
    "J_inv",
)
(
    POSE_IN,
    X_D,
    T_FF,
    OMEGA,
    T_APPLIED,
    T_PART,
    Z,
    STATUS,
    E_BAR,
    X_HAT,
    WINDOW,
    COUNTER,
    K_PART,
    K_OLD,
    PENDING,
    HOLD,
    J_INV,
) = range(len(PARTS))
#: The parts of the state the controller's Diagram exports, in order: state output ports.
EXPORTED = {
    "T": "T",
    "z": "integral",
    "status": "status",
    "e_bar": "e_bar",
    "x_hat": "x_hat",
    "window": "feature_window",
}
#: Columns of a window row: [e_bar (6), T (6)].
WINDOW_ROW = 12


@dataclass(frozen=True)
class LqiLayout:
    """Where each named part of the LQI's input vector ``u`` and of its state lies: index slices,
    no bare numbers. An absent part (no estimator, no delay, ...) is an empty slice.

    Input vector ``u``:
        pose_in: (12,) the ``x`` input [pose, rate], or with an estimator (6,) ``motor_angle``.
        x_d (18,): the reference [pose, rate, acceleration]. T_ff (6,): feed-forward, N m.
        omega (2,): [omega_Q, omega_R] on the port.
        T_applied (6,): with a feature window, the torques the motors apply, N m.
    State (the exported parts first, in :data:`EXPORTED` order):
        T (6,): the torque command, N m. z (6,): the integral states (eq. 23).
        status (7,): ``LqiStatus``. e_bar (6,): the pose error the last update acted on.
        x_hat (12,): with an estimator, its estimate. window (12 w + 2,): with a feature window,
            the ring buffer [rows [e_bar, T], n_valid, head].
        counter (1,): control periods since the last gain re-solve.
        K, K_old (6 n,): the gain in use and the one before the last re-solve, row-major (6, n),
            n = 18 + 6 d. pending (6 d,): feedback torques commanded but not yet acting, newest
            first. hold (24,): with a governor, its last reference within reach [pose, rate,
            acc, T_ff]. J_inv (36,): with an estimator, its inverse Jacobian, row-major.
    """

    pose_in: slice
    x_d: slice
    T_ff: slice
    omega: slice
    T_applied: slice
    T: slice
    z: slice
    status: slice
    e_bar: slice
    x_hat: slice
    window: slice
    counter: slice
    K: slice
    K_old: slice
    pending: slice
    hold: slice
    J_inv: slice

    @classmethod
    def build(
        cls, n: int, delay_periods: int, governor: bool, estimator: bool, window: int | None
    ) -> LqiLayout:
        """The layout for n gain columns, d periods of delay, with or without a governor, an
        estimator and a feature window of ``window`` samples."""
        inputs = (6 if estimator else 12, 18, 6, 2, 6 if window else 0)
        state = (
            6,
            6,
            len(LQI_STATUS_NAMES),
            6,
            12 if estimator else 0,
            WINDOW_ROW * window + 2 if window else 0,
            1,
            6 * n,
            6 * n,
            6 * delay_periods,
            24 if governor else 0,
            36 if estimator else 0,
        )
        slices = []
        for sizes in (inputs, state):
            stops = np.cumsum(sizes)
            slices += [slice(int(stop - size), int(stop)) for size, stop in zip(sizes, stops)]
        return cls(*slices)

    @property
    def u_size(self) -> int:
        return self.T_applied.stop

    @property
    def state_size(self) -> int:
        return self.J_inv.stop

    def bounds(self) -> np.ndarray:
        """(17, 2) int64 [start, stop) of each part in :data:`PARTS` order, for the compiled
        stages (which cannot read a dataclass)."""
        return np.array(
            [[getattr(self, p).start, getattr(self, p).stop] for p in PARTS], dtype=np.int64
        )


def part(array: np.ndarray, bounds: np.ndarray, k: int) -> np.ndarray:
    """The view of part ``k`` (an index of :data:`PARTS`) of ``u`` or of the state."""
    return array[bounds[k, 0] : bounds[k, 1]]


# -- sums in one order ----------------------------------------------------------------------------
# The two reductions whose results feed back into the loop are written once, as loops, and the
# compiled stages compile these very functions: both implementations then produce the same
# bits. (BLAS sums a product in another order; on the robot as built a last-bit difference in
# the estimate or the torque can become another encoder count, and the runs part ways.)


def matvec(A, v):
    """A v for A (m, n), v (n,): each row summed left to right."""
    out = np.zeros(A.shape[0])
    for i in range(A.shape[0]):
        acc = 0.0
        for j in range(A.shape[1]):
            acc += A[i, j] * v[j]
        out[i] = acc
    return out


def solve6(A, b):
    """(x, True) with A x = b for A (6, 6), b (6,), by LU with partial pivoting (LAPACK's
    dgesv); (b, False) when a pivot is exactly zero, where dgesv reports a singular matrix."""
    M = A.copy()
    x = b.copy()
    for k in range(6):
        p = k
        for i in range(k + 1, 6):
            if abs(M[i, k]) > abs(M[p, k]):
                p = i
        if M[p, k] == 0.0:
            return b, False
        if p != k:
            for j in range(6):
                M[k, j], M[p, j] = M[p, j], M[k, j]
            x[k], x[p] = x[p], x[k]
        for i in range(k + 1, 6):
            f = M[i, k] / M[k, k]
            for j in range(k + 1, 6):
                M[i, j] -= f * M[k, j]
            x[i] -= f * x[k]
    for k in range(5, -1, -1):
        acc = x[k]
        for j in range(k + 1, 6):
            acc -= M[k, j] * x[j]
        x[k] = acc / M[k, k]
    return x, True


# -- estimate -------------------------------------------------------------------------------------


def estimate(legs, crank_length, leg_c, h, alpha, fk_jump, theta, x_hat, J_inv) -> bool:
    """Pose and rate from the encoders by one Newton chord step, in place in ``x_hat``.

    From x_0 = x + h v (the last estimate advanced by its rate) the step is
    x = x_0 - J_inv wrap(ik(x_0) - theta), J_inv the inverse Jacobian of the last re-schedule;
    the rate is the backward difference low-passed, v+ = v + alpha ((x - x_prev) / h - v).

    Args:
        legs: (6, 9) leg constants, crank_length, leg_c = s^2 - a^2
            (:func:`~stewart_drake.robot.kinematics.leg_constants`). h: period, s. alpha: rate
            filter weight. fk_jump: largest correction accepted (rad or m).
        theta: (6,) measured motor angles, rad. x_hat: (12,) [x, v], updated.
        J_inv: (6, 6) inverse Jacobian.
    Returns:
        False (``x_hat`` untouched) when a correction exceeds ``fk_jump`` or is not finite:
        a jump or a stale Jacobian, for a full Newton solve instead.
    Source: FK by Newton on paper eq. 6 (ours: the paper reads the pose from its ADAMS model).
    """
    x_prev, v_prev = x_hat[:6].copy(), x_hat[6:].copy()
    x0 = x_prev + h * v_prev
    theta0 = np.array(ik_scalar((legs, crank_length, leg_c), x0))
    dx = matvec(J_inv, (theta0 - theta + math.pi) % (2 * math.pi) - math.pi)
    if not (np.abs(dx).max() <= fk_jump and math.isfinite(dx.sum())):
        return False
    x_hat[:6] = x0 - dx
    x_hat[6:] = v_prev + alpha * ((x_hat[:6] - x_prev) / h - v_prev)
    return True


def filter_rate(h, alpha, x, x_hat) -> None:
    """Set ``x_hat`` to the pose x (6,) and the low-passed difference rate (see
    :func:`estimate`): the end of an estimate found by a full Newton solve."""
    x_prev, v_prev = x_hat[:6].copy(), x_hat[6:].copy()
    x_hat[:6] = x
    x_hat[6:] = v_prev + alpha * ((x - x_prev) / h - v_prev)


# -- re-schedule and govern: what is due ----------------------------------------------------------


def schedule_due(c, counter, omega, status) -> bool:
    """A gain re-solve is due: a schedule period has passed (with pose scheduling), or the
    weights on the port differ from those in use (eqs. 27, 31-33). Advances ``counter`` (1,),
    which restarts with a re-solve."""
    due = (
        (counter[0] >= c[STEPS_PER_SCHEDULE] and c[SCHEDULE_POSE] != 0.0)
        or omega[0] != status[OMEGA_Q]
        or omega[1] != status[OMEGA_R]
    )
    counter[0] = 1.0 if due else counter[0] + 1.0
    return due


def governor_needed(bound, T_ff) -> bool:
    """The reference's feed-forward T_ff (6,) exceeds ``bound`` (a fraction of the torque
    limit, inf without a governor) and is finite: a pose the motors cannot hold."""
    return bound < np.abs(T_ff).max() < math.inf


def observe(c, legs, u, state, bounds) -> int:
    """Estimate (with an estimator) and say which stages need Python this period.

    Args:
        c: the constants (``StepConstants``). legs: (6, 9) leg constants.
        u: the input vector, state: the state (updated), bounds: their layout
            (:meth:`LqiLayout.bounds`).
    Returns:
        bit flags: :data:`NEED_NEWTON`, :data:`NEED_SCHEDULE`, :data:`NEED_GOVERNOR`.
    """
    flags = 0
    if c[ESTIMATOR] != 0.0 and not estimate(
        legs,
        c[CRANK_LENGTH],
        c[LEG_C],
        c[H],
        c[ALPHA],
        c[FK_JUMP],
        part(u, bounds, POSE_IN),
        part(state, bounds, X_HAT),
        part(state, bounds, J_INV).reshape(6, 6),
    ):
        flags |= NEED_NEWTON
    if schedule_due(
        c, part(state, bounds, COUNTER), part(u, bounds, OMEGA), part(state, bounds, STATUS)
    ):
        flags |= NEED_SCHEDULE
    if governor_needed(c[GOVERNOR_BOUND], part(u, bounds, T_FF)):
        flags |= NEED_GOVERNOR
    return flags


# -- act ------------------------------------------------------------------------------------------


def push_window(window, e_bar, T) -> bool:
    """Buffer one sample [e_bar (6), T (6)] of the density features (eqs. 35-36) in the ring
    ``window`` = [rows (w x 12), n_valid, head]; False (nothing written) if it is not finite."""
    if not math.isfinite(e_bar.sum() + T.sum()):
        return False
    w = (window.size - 2) // WINDOW_ROW
    head = int(window[-1])
    row = window[WINDOW_ROW * head : WINDOW_ROW * (head + 1)]
    row[:6], row[6:] = e_bar, T
    window[-2] = min(window[-2] + 1.0, w)
    window[-1] = (head + 1) % w
    return True


def error_state(x, ref, z, pending) -> np.ndarray:
    """e = [e_x (6), e_x_dot (6), z (6), pending (6 d)]: x (12,) - ref[:12] and the integral
    (eqs. 23-25, block order; the pending torques of the delay-augmented model after them)."""
    return np.concatenate([x - ref[:12], z, pending])


def transfer_gain(mode, K_old, K, e, z) -> bool:
    """Carry the integral action ("integral", K_I z_new = K_I,old z) or the whole feedback
    ("feedback", K_I z_new = K_old e - (K e - K_I z)) over a gain change, in z (6,) and
    e[12:18]. False (z kept: a torque step rather than no control) when K_I is singular.
    Ours: the paper switches gains as they come."""
    K_I = K[:, 12:18]
    if mode == TRANSFER_INTEGRAL:
        target = matvec(K_old[:, 12:18], z)
    else:
        target = matvec(K_old, e) - (matvec(K, e) - matvec(K_I, z))
    z_new, ok = solve6(np.ascontiguousarray(K_I), target)
    if not ok:
        return False
    z[:] = z_new
    e[12:18] = z_new
    return True


def friction_feedforward(friction, rate, J_inv, x_d_rate, T_ff) -> np.ndarray:
    """T_ff + friction tanh(theta_dot_d / rate): the reference's feed-forward (6,) plus the
    Coulomb friction its motor rates theta_dot_d = J x_dot_d meet, with a smoothed sign.

    Args:
        friction: N m at each crank, > 0. rate: rad/s, the crank rate at which the smoothed sign
            reaches tanh(1) = 0.76 of it. J_inv: (6, 6) the estimator's inverse Jacobian (the
            last re-schedule's). x_d_rate: (6,) the reference's rate [rad/s, m/s]. T_ff: (6,).
    Returns:
        a new (6,) array; T_ff itself when J_inv is singular (no compensation this period).
    Ours: the paper's motors have no friction.
    """
    theta_dot, ok = solve6(J_inv, x_d_rate.copy())
    if not ok:
        return T_ff
    out = np.zeros(6)
    for i in range(6):
        out[i] = T_ff[i] + friction * math.tanh(theta_dot[i] / rate)
    return out


def feedback(K, e, T_ff, T) -> None:
    """The LQI law T = T_ff - K e (paper eq. 34), K (6, n), e (n,), into T (6,)."""
    T[:] = T_ff - matvec(K, e)


def saturate(limit, T) -> bool:
    """Clip T (6,) to +-limit when a finite command exceeds it; True if it did. A non-finite T
    is not clipped: it reaches the guard, which names it."""
    if limit < np.abs(T).max() < math.inf:
        np.clip(T, -limit, limit, out=T)
        return True
    return False


def push_pending(pending, T, T_ff) -> None:
    """The feedback torque just commanded becomes the newest of the d pending (6 d,), the
    oldest drops out (the delay-augmented model of :func:`~.lqi.error_model`)."""
    pending[6:] = pending[:-6].copy()
    pending[:6] = T - T_ff


def integrate(h, e, z) -> None:
    """z+ = z + h e_x (paper eq. 23, rectangle rule): z (6,) from e[12:18] and e[:6]."""
    z[:] = e[12:18] + h * e[:6]


def act(c, u, state, bounds, mode) -> int:
    """The law, from the error to the torque and the integral, in place in ``state``; with
    ``friction`` the feed-forward carries the Coulomb friction of the reference's motor rates
    (:func:`friction_feedforward`), which the pending torques then leave out.

    Args:
        c: the constants. u, state, bounds: as :func:`observe`.
        mode: bit flags of what Python did this period: GAIN_CHANGED (K_old holds the gain
            before), GOVERNED (the reference and its feed-forward are the governor's ``hold``).
    Returns:
        bit flags: :data:`NONFINITE_SAMPLE` (the features' sample was not finite).
    """
    flags = 0
    status, z, T = part(state, bounds, STATUS), part(state, bounds, Z), part(state, bounds, T_PART)
    e_bar, window = part(state, bounds, E_BAR), part(state, bounds, WINDOW)
    if window.size and not push_window(window, e_bar, part(u, bounds, T_APPLIED)):
        flags |= NONFINITE_SAMPLE
    ref, T_ff = part(u, bounds, X_D), part(u, bounds, T_FF)
    if c[GOVERNOR_BOUND] < math.inf:
        hold = part(state, bounds, HOLD)
        if mode & GOVERNED:
            ref, T_ff = hold[:18], hold[18:]
            status[GOVERNED_STEPS] += 1.0
        else:  # the last reference within reach, at rest
            hold[:6], hold[6:18], hold[18:] = ref[:6], 0.0, T_ff
    if c[FRICTION] > 0.0:
        J_inv = part(state, bounds, J_INV).reshape(6, 6)
        T_ff = friction_feedforward(c[FRICTION], c[FRICTION_RATE], J_inv, ref[6:12], T_ff)
    x = part(state, bounds, X_HAT) if c[ESTIMATOR] != 0.0 else part(u, bounds, POSE_IN)
    K = part(state, bounds, K_PART).reshape(6, -1)
    pending = part(state, bounds, PENDING)
    e = error_state(x, ref, z, pending)
    if mode & GAIN_CHANGED and c[TRANSFER] != TRANSFER_NONE:
        transfer_gain(c[TRANSFER], part(state, bounds, K_OLD).reshape(6, -1), K, e, z)
    feedback(K, e, T_ff, T)
    saturated = saturate(c[TORQUE_LIMIT], T)
    if saturated:
        status[SATURATED_STEPS] += 1.0
    if pending.size:
        push_pending(pending, T, T_ff)
    if not (saturated and c[ANTI_WINDUP] != 0.0):  # clamping: z holds while saturated
        integrate(c[H], e, z)
    status[INTEGRAL_NORM] = np.linalg.norm(z)
    e_bar[:] = e[:6]
    return flags


def step(c, legs, u, state, bounds) -> tuple[int, int]:
    """:func:`observe`, then :func:`act` when no stage needs Python: one call per period in the
    common case. Arguments as theirs.

    Returns:
        (observe's flags, act's flags); act has not run when the first is not 0.
    """
    need = observe(c, legs, u, state, bounds)
    if need:
        return need, 0
    return 0, act(c, u, state, bounds, 0)
