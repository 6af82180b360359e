"""The LQI's work of one control period, stage by stage, compiled with numba: the one source.

:class:`~.controller.LqiController` calls :func:`step` (and :func:`act`, :func:`filter_rate`)
every control period, over two arrays that Drake owns, the controller's input vector ``u`` and
its discrete state ``state``, and the constants the controller builds once (named in
:mod:`.layout`):

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
  case, in place of some sixty numpy and Python calls.

Written as loops over the (6,)-sized arrays, where a numpy call costs more than its arithmetic.
The reference is the same code run by Python: :data:`reference` holds every function here as its
numba ``py_func``, calling the others' ``py_func`` in turn (never compiled), so the compiled and
the interpreted step are equal by construction; a test holds their results equal on random
poses, weights, saturation and delay cases, and ``LqiController(..., compiled=False)`` runs it.

Importing this module compiles nothing: :mod:`.kernels` compiles (or loads from numba's disk
cache) what the controller calls, with the types it passes
(:func:`~stewart_drake.control.kernel_cache.njit_cached`).
"""

from __future__ import annotations

import math

import numpy as np

from ...robot.path_kernels import fk_newton, lu_solve6
from ...robot.single_pose import ik_scalar
from ..kernel_cache import interpreted, njit_cached, use_cache
from .layout import (
    ALPHA,
    ANTI_WINDUP,
    COUNTER,
    E_BAR,
    ESTIMATOR,
    FK_JUMP,
    FRICTION,
    FRICTION_RATE,
    GAIN_CHANGED,
    GOVERNED,
    GOVERNED_STEPS,
    GOVERNOR_BOUND,
    HOLD,
    INTEGRAL_NORM,
    J_INV,
    K_OLD,
    K_PART,
    NEED_GOVERNOR,
    NEED_NEWTON,
    NEED_SCHEDULE,
    NONFINITE_SAMPLE,
    OMEGA,
    OMEGA_Q,
    OMEGA_R,
    PENDING,
    POSE_IN,
    SATURATED_STEPS,
    SCHEDULE_POSE,
    STATUS,
    STEPS_PER_SCHEDULE,
    T_APPLIED,
    T_FF,
    T_PART,
    TORQUE_LIMIT,
    TRANSFER,
    TRANSFER_INTEGRAL,
    TRANSFER_NONE,
    WINDOW,
    WINDOW_ROW,
    X_D,
    X_HAT,
    H,
    Z,
)

_CACHE = use_cache()


def _njit(function):
    """:func:`~stewart_drake.control.kernel_cache.njit_cached`, cached while the sources this
    module inlines are those it was compiled against."""
    return njit_cached(function, _CACHE)


#: The closed-form IK of :func:`~stewart_drake.robot.single_pose.ik_scalar`, compiled as written.
ik_compiled = _njit(ik_scalar)


@_njit
def part(array, bounds, k):
    """The view of part ``k`` (an index of :data:`~.layout.PARTS`) of ``u`` or of the state."""
    return array[bounds[k, 0] : bounds[k, 1]]


# -- sums in one order ----------------------------------------------------------------------------
# The two reductions whose results feed back into the loop are written as loops: compiled and
# interpreted, they sum in one order and give the same bits. (BLAS sums a product in another
# order; on the robot as built a last-bit difference in the estimate or the torque can become
# another encoder count, and the runs part ways.)


@_njit
def matvec(A, v):
    """A v for A (m, n), v (n,): each row summed left to right."""
    out = np.zeros(A.shape[0])
    for i in range(A.shape[0]):
        acc = 0.0
        for j in range(A.shape[1]):
            acc += A[i, j] * v[j]
        out[i] = acc
    return out


@_njit
def solve6(A, b):
    """(x, True) with A x = b for A (6, 6), b (6,), by LU with partial pivoting (LAPACK's
    dgesv, :func:`~stewart_drake.robot.path_kernels.lu_solve6` on copies); (b, False) when a
    pivot is exactly zero, where dgesv reports a singular matrix."""
    x = b.copy()
    if not lu_solve6(A.copy(), x):
        return b, False
    return x, True


# -- estimate -------------------------------------------------------------------------------------


@_njit
def estimate(legs, h, alpha, fk_jump, theta, x_hat, J_inv):
    """Pose and rate from the encoders by one Newton chord step, in place in ``x_hat``.

    From x_0 = x + h v (the last estimate advanced by its rate) the step is
    x = x_0 - J_inv wrap(ik(x_0) - (theta - o)), J_inv the inverse Jacobian of the last
    re-schedule, o the encoders' zero errors the controller believes; the rate is the backward
    difference low-passed, v+ = v + alpha ((x - x_prev) / h - v).

    Args:
        legs: (6, LEG_SIZE) leg constants
            (:func:`~stewart_drake.robot.single_pose.leg_constants`; the encoder's zero error
            in their last column). h: period, s. alpha: rate filter weight. fk_jump: largest
            correction accepted (rad or m).
        theta: (6,) motor angles as the encoders read them, rad. x_hat: (12,) [x, v], updated.
        J_inv: (6, 6) inverse Jacobian.
    Returns:
        False (``x_hat`` untouched) when a correction exceeds ``fk_jump`` or is not finite:
        a jump or a stale Jacobian, for a full Newton solve instead.
    Source: FK by Newton on paper eq. 6 (ours: the paper reads the pose from its ADAMS model).
    """
    x0 = np.empty(6)
    for i in range(6):
        x0[i] = x_hat[i] + h * x_hat[6 + i]
    theta0 = ik_compiled(legs, x0)
    r = np.empty(6)
    for j in range(6):
        r[j] = (theta0[j] - (theta[j] - legs[j, 16]) + math.pi) % (2 * math.pi) - math.pi
    dx = matvec(J_inv, r)
    total, largest = 0.0, 0.0
    for i in range(6):
        total += dx[i]
        largest = max(largest, abs(dx[i]))
    if not (largest <= fk_jump and math.isfinite(total)):
        return False
    for i in range(6):
        x = x0[i] - dx[i]
        x_hat[6 + i] += alpha * ((x - x_hat[i]) / h - x_hat[6 + i])
        x_hat[i] = x
    return True


@_njit
def newton(legs, mode, tol, max_iterations, x0, theta, x):
    """The full Newton solve of a period whose chord step :func:`estimate` refused: the pose x
    (6,) whose IK gives the encoders' reading theta, from x0, in place
    (:func:`~stewart_drake.robot.path_kernels.fk_newton`: the steps of
    :meth:`~stewart_drake.control.estimator.PoseEstimator.estimate`); then :func:`filter_rate`.
    Returns whether it converged (x is the last iterate either way, as the estimator's)."""
    J = np.empty((6, 6))
    return fk_newton(legs, mode, tol, max_iterations, x0, theta, x, J)


@_njit
def filter_rate(h, alpha, x, x_hat):
    """Set ``x_hat`` to the pose x (6,) and the low-passed difference rate (see
    :func:`estimate`): the end of an estimate found by a full Newton solve."""
    for i in range(6):
        x_hat[6 + i] += alpha * ((x[i] - x_hat[i]) / h - x_hat[6 + i])
        x_hat[i] = x[i]


# -- re-schedule and govern: what is due ----------------------------------------------------------


@_njit
def schedule_due(c, counter, omega, status):
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


@_njit
def _max_abs(v):
    """max |v_i|, NaN if any entry is NaN (as numpy's max)."""
    largest = 0.0
    for value in v:
        if math.isnan(value):
            return math.nan
        largest = max(largest, abs(value))
    return largest


@_njit
def governor_needed(bound, T_ff):
    """The reference's feed-forward T_ff (6,) exceeds ``bound`` (a fraction of the torque
    limit, inf without a governor) and is finite: a pose the motors cannot hold."""
    return bound < _max_abs(T_ff) < math.inf


@_njit
def observe(c, legs, u, state, bounds):
    """Estimate (with an estimator) and say which stages need Python this period.

    Args:
        c: the constants (``StepConstants``). legs: (6, LEG_SIZE) leg constants.
        u: the input vector, state: the state (updated), bounds: their layout
            (:meth:`~.layout.LqiLayout.bounds`).
    Returns:
        bit flags: :data:`NEED_NEWTON`, :data:`NEED_SCHEDULE`, :data:`NEED_GOVERNOR`.
    """
    flags = 0
    if c[ESTIMATOR] != 0.0 and not estimate(
        legs,
        c[H],
        c[ALPHA],
        c[FK_JUMP],
        part(u, bounds, POSE_IN),
        part(state, bounds, X_HAT),
        part(state, bounds, J_INV).reshape((6, 6)),
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


@_njit
def push_window(window, e_bar, T):
    """Buffer one sample [e_bar (6), T (6)] of the density features (eqs. 35-36) in the ring
    ``window`` = [rows (w x 12), n_valid, head]; False (nothing written) if it is not finite."""
    total = 0.0
    for i in range(6):
        total += e_bar[i] + T[i]
    if not math.isfinite(total):
        return False
    w = (window.size - 2) // WINDOW_ROW
    head = int(window[-1])
    for i in range(6):
        window[WINDOW_ROW * head + i] = e_bar[i]
        window[WINDOW_ROW * head + 6 + i] = T[i]
    window[-2] = min(window[-2] + 1.0, w)
    window[-1] = (head + 1) % w
    return True


@_njit
def error_state(x, ref, z, pending):
    """e = [e_x (6), e_x_dot (6), z (6), pending (6 d)]: x (12,) - ref[:12] and the integral
    (eqs. 23-25, block order; the pending torques of the delay-augmented model after them)."""
    e = np.empty(18 + pending.size)
    for i in range(12):
        e[i] = x[i] - ref[i]
    for i in range(6):
        e[12 + i] = z[i]
    for i in range(pending.size):
        e[18 + i] = pending[i]
    return e


@_njit
def transfer_gain(mode, K_old, K, e, z):
    """Carry the integral action ("integral", K_I z_new = K_I,old z) or the whole feedback
    ("feedback", K_I z_new = K_old e - (K e - K_I z)) over a gain change, in z (6,) and
    e[12:18]. False (z kept: a torque step rather than no control) when K_I is singular.
    Ours: the paper switches gains as they come."""
    K_I = np.ascontiguousarray(K[:, 12:18])
    if mode == TRANSFER_INTEGRAL:
        target = matvec(K_old[:, 12:18], z)
    else:
        target = matvec(K_old, e) - (matvec(K, e) - matvec(K_I, z))
    z_new, ok = solve6(K_I, target)
    if not ok:
        return False
    for i in range(6):
        z[i] = z_new[i]
        e[12 + i] = z_new[i]
    return True


@_njit
def friction_feedforward(friction, rate, J_inv, x_d_rate, T_ff):
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


@_njit
def feedback(K, e, T_ff, T):
    """The LQI law T = T_ff - K e (paper eq. 34), K (6, n), e (n,), into T (6,)."""
    Ke = matvec(K, e)
    for i in range(6):
        T[i] = T_ff[i] - Ke[i]


@_njit
def saturate(limit, T):
    """Clip T (6,) to +-limit when a finite command exceeds it; True if it did. A non-finite T
    is not clipped: it reaches the guard, which names it."""
    if limit < _max_abs(T) < math.inf:
        for i in range(6):
            T[i] = min(max(T[i], -limit), limit)
        return True
    return False


@_njit
def push_pending(pending, T, T_ff):
    """The feedback torque just commanded becomes the newest of the d pending (6 d,), the
    oldest drops out (the delay-augmented model of :func:`~.gain.error_model`)."""
    for i in range(pending.size - 1, 5, -1):
        pending[i] = pending[i - 6]
    for i in range(6):
        pending[i] = T[i] - T_ff[i]


@_njit
def integrate(h, e, z):
    """z+ = z + h e_x (paper eq. 23, rectangle rule): z (6,) from e[12:18] and e[:6]."""
    for i in range(6):
        z[i] = e[12 + i] + h * e[i]


@_njit
def act(c, u, state, bounds, mode):
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
            for i in range(24):
                hold[i] = 0.0
            for i in range(6):
                hold[i] = ref[i]
                hold[18 + i] = T_ff[i]
    if c[FRICTION] > 0.0:
        J_inv = part(state, bounds, J_INV)
        T_ff = friction_feedforward(
            c[FRICTION], c[FRICTION_RATE], J_inv.reshape((6, 6)), ref[6:12], T_ff
        )
    x = part(state, bounds, X_HAT) if c[ESTIMATOR] != 0.0 else part(u, bounds, POSE_IN)
    K = part(state, bounds, K_PART)
    K = K.reshape((6, K.size // 6))
    pending = part(state, bounds, PENDING)
    e = error_state(x, ref, z, pending)
    if mode & GAIN_CHANGED and c[TRANSFER] != TRANSFER_NONE:
        K_old = part(state, bounds, K_OLD)
        transfer_gain(c[TRANSFER], K_old.reshape((6, K_old.size // 6)), K, e, z)
    feedback(K, e, T_ff, T)
    saturated = saturate(c[TORQUE_LIMIT], T)
    if saturated:
        status[SATURATED_STEPS] += 1.0
    if pending.size:
        push_pending(pending, T, T_ff)
    if not (saturated and c[ANTI_WINDUP] != 0.0):  # clamping: z holds while saturated
        integrate(c[H], e, z)
    norm = 0.0
    for i in range(6):
        norm += z[i] * z[i]
    status[INTEGRAL_NORM] = math.sqrt(norm)
    for i in range(6):
        e_bar[i] = e[i]
    return flags


@_njit
def step(c, legs, u, state, bounds):
    """:func:`observe`, then :func:`act` when no stage needs Python: one call per period in the
    common case. Arguments as theirs.

    Returns:
        (observe's flags, act's flags); act has not run when the first is not 0.
    """
    need = observe(c, legs, u, state, bounds)
    if need:
        return need, 0
    return 0, act(c, u, state, bounds, 0)


#: Every function above as the Python numba compiles (its ``py_func``), calling the others'
#: ``py_func``: the uncompiled step, equal to the compiled one by construction.
reference = interpreted(globals())
