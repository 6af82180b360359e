"""The crank servo's control period, compiled with numba: :func:`step`, one call per period.

What one period does (the design: :mod:`.design`; the controller: :mod:`.controller`):

1. the reference's crank angles and rates, now (for the feedback) and at the time the torque
   will act (for the friction's feed-forward): the closed-form IK and the Jacobian
   (:func:`~stewart_drake.robot.path_kernels.ik_angles`,
   :func:`~stewart_drake.robot.path_kernels.jacobian_at`) of the reference pose, carried
   forward by its rate and acceleration for the later one;
2. per crank, the current estimator: the encoder's angle (less its zero error) corrects the
   predicted [theta, omega, delta];
3. the feedback acceleration a = -K [z, e_theta, e_omega, pending], optionally less the
   estimated disturbance, and its torque M a (M the chain's joint-space inertia at the
   reference, re-scheduled by the controller);
4. the torque: the reference's feed-forward + the friction the controller believes, (F_i +
   K_l |T_ff,i|) [(1 - s) tanh(omega_d,i / r) + s tanh(v_i / r)] (F_i Coulomb's, K_l the
   share of the torque the gears carry that they lose, on the feed-forward's torque: Duclusaud
   et al.'s M3 class, docs/servo_bench.md; r the friction rate), a share s in the
   direction v_i = omega_d,i(t + lead) - k_c e_theta,i the crank must go to close its error,
   the rest in the reference's sense, both where the torque will act (a crank at rest is pushed
   with s F_i at most: less than the friction it has if it has more than s of what is believed,
   so the push cannot start a relay's oscillation), + the viscous friction + the feedback's
   torque; divided by each servo's torque per command as a share of the catalogue's (its
   commissioning's; 1 when none was measured) and clipped to the motors' limit;
5. integral (stopped while a crank's torque is clipped: anti-windup), the friction estimate's
   adaptation (while the reference moves the crank, F_i moves by h / tau_F times the friction
   the feed-forward misses, :func:`friction_error`: the part of the feedback torque that flips
   with the motion's sense, fitted apart from a steady one, which a payload's weight is), the
   estimator's prediction with the command that acts over the next period, and the pending
   commands shifted.

Loops over the (6,)-sized arrays, where a numpy call would cost more than its arithmetic.
Compiled on first import (or loaded from numba's disk cache), so that no control period pays
for it; :data:`reference` holds the same functions uncompiled (their ``py_func``), the same code
by construction.
"""

from __future__ import annotations

import math

import numpy as np

from ...base.compiled import interpreted
from ...robot import path_kernels
from ...robot.path_kernels import ik_angles, jacobian_at
from ...robot.single_pose import LEG_SIZE

#: Entries of the constants array ``c`` of :func:`step`, in order.
CONSTANTS = (
    "h",  # control period, s
    "lead",  # from the sample to the middle of the period its torque acts in, s
    "friction_rate",  # the smoothed sign's rate, rad/s
    "k_c",  # the friction direction's gain on the angle error, 1/s
    "adapt",  # 1 / tau_F, 1/s (0: the friction estimate is held)
    "adapt_min_rate",  # the reference's crank rate above which it adapts, rad/s
    "friction_min",  # bounds of the friction estimate, N m
    "friction_max",
    "viscous",  # viscous friction, N m s/rad
    "limit",  # the motors' torque limit, N m (inf: none)
    "delay",  # d, pending commands
    "dob",  # weight of the estimated disturbance in the command (0: integral action only)
    "memory",  # the friction regression's forgetting factor a period, exp(-h / tau_m)
    "share",  # the share of the friction fed in the sense that closes the angle error
    "load_share",  # the gears' friction a newton metre of the feed-forward's torque, K_l
)
(
    H,
    LEAD,
    FRICTION_RATE,
    K_C,
    ADAPT,
    ADAPT_MIN_RATE,
    FRICTION_MIN,
    FRICTION_MAX,
    VISCOUS,
    LIMIT,
    DELAY,
    DOB,
    MEMORY,
    SHARE,
    LOAD_SHARE,
) = range(len(CONSTANTS))

#: The state vector's parts, (start, size) for a delay d (:func:`layout`): the predicted
#: [theta, omega, delta] of each crank (18), the integrals z (6), the pending commands (6 d,
#: crank-major, oldest first), the friction estimates (6), the torque command (6), the pose
#: error (6) and the counters (:data:`STATUS`).
STATUS = ("steps", "saturated_steps", "reference_failures")


def layout(d: int) -> dict:
    """{part: slice} of the state vector for a delay of ``d`` periods (module docstring)."""
    sizes = (
        ("x_bar", 18),
        ("z", 6),
        ("pending", 6 * d),
        ("friction", 6),
        ("friction_sums", 24),
        ("T", 6),
        ("e_bar", 6),
        ("status", len(STATUS)),
    )
    out, k = {}, 0
    for name, size in sizes:
        out[name] = slice(k, k + size)
        k += size
    out["size"] = slice(0, k)
    return out


#: :func:`~stewart_drake.robot.path_kernels.source_digest` of the source these kernels compile
#: in, as their numba cache was written (a test holds it current).
PATH_KERNELS_DIGEST = "3d946829dba818d4"
#: numba, numpy's error model, cached while :data:`PATH_KERNELS_DIGEST` holds.
_njit = path_kernels.compiled_against(PATH_KERNELS_DIGEST)


@_njit
def crank_reference(legs, x_d, ahead, theta, omega):
    """The reference's crank angles and rates ``ahead`` s after its sample, in place in theta
    (6,) rad and omega (6,) rad/s: theta = IK(x), omega = J(x) v at x = x_d + v_d s + a_d s^2/2,
    v = v_d + a_d s (x_d (18,) [pose, rate, acceleration], s = ``ahead``). Returns whether every
    leg closed (and the rates are finite)."""
    x, v = np.empty(6), np.empty(6)
    for k in range(6):
        x[k] = x_d[k] + x_d[6 + k] * ahead + 0.5 * x_d[12 + k] * ahead * ahead
        v[k] = x_d[6 + k] + x_d[12 + k] * ahead
    R, E = np.empty((3, 3)), np.empty((3, 3))
    r, q, J = np.empty((6, 3)), np.empty((6, 3)), np.empty((6, 6))
    ik_angles(legs, x, R, E, r, q, theta)
    for i in range(6):
        if not math.isfinite(theta[i]):
            return False
    jacobian_at(legs, theta, E, r, q, J)
    ok = True
    for i in range(6):
        s = 0.0
        for k in range(6):
            s += J[i, k] * v[k]
        omega[i] = s
        ok = ok and math.isfinite(s)
    return ok


@_njit
def friction_error(state, k, memory, tau_fb, omega):
    """The friction the feed-forward misses at one crank, N m: the least-squares fit
    tau_fb = dF sign(omega) + b over the moving periods, exponentially forgotten (``memory`` a
    period), so that a steady torque b (a payload the feed-forward misses, which the integral
    carries) is not taken for friction; the four running sums in ``state[k : k + 4]`` (n, sum
    of signs, sum of torques, sum of torque x sign), updated here. Returns dF (0 until both
    senses of motion are in the fit)."""
    s = 1.0 if omega > 0.0 else -1.0
    state[k] = memory * state[k] + 1.0
    state[k + 1] = memory * state[k + 1] + s
    state[k + 2] = memory * state[k + 2] + tau_fb
    state[k + 3] = memory * state[k + 3] + tau_fb * s
    n, ss = state[k], state[k + 1]
    det = n * n - ss * ss
    if det <= 0.01 * n * n:  # (nearly) one sense only: the sign and the offset not apart
        return 0.0
    return (n * state[k + 3] - ss * state[k + 2]) / det


@_njit
def step(c, K, L, Phi, Gam, legs, M, J_inv, x_d, theta_read, T_ff, kt, state):
    """One control period (module docstring) over the controller's ``state`` (its layout:
    :func:`layout`), in place: the torque command is ``state``'s "T" part.

    Args:
        c: the constants (:data:`CONSTANTS`). K: (3 + d,) feedback gain. L: (3,) estimator
            gain. Phi (3, 3), Gam (3,): the crank's model over a period. legs: (6, LEG_SIZE)
            the robot's leg constants (the encoders' zero errors last). M: (6, 6) joint-space
            inertia, kg m^2. J_inv: (6, 6) d x / d theta at the reference, for the pose error.
        x_d: (18,) reference pose, rate, acceleration at the sample. theta_read: (6,) encoder
            angles, rad. T_ff: (6,) the reference's feed-forward torques, N m. kt: (6,) each
            servo's torque per command as a share of the catalogue's (no unit).
    Returns:
        whether the reference's IK closed (if not, the torque and the state are kept).
    """
    d = int(c[DELAY])
    h = c[H]
    i_z, i_p = 18, 24
    i_f = i_p + 6 * d
    i_r = i_f + 6
    i_t = i_r + 24
    i_e = i_t + 6
    i_s = i_e + 6
    th0, w0 = np.empty(6), np.empty(6)
    thl, wl = np.empty(6), np.empty(6)
    state[i_s] += 1.0
    if not (
        crank_reference(legs, x_d, 0.0, th0, w0) and crank_reference(legs, x_d, c[LEAD], thl, wl)
    ):
        state[i_s + 2] += 1.0
        return False
    n_k = K.size
    acc = np.empty(6)
    x_hat = np.empty((6, 3))
    y = np.empty(6)
    for i in range(6):
        y[i] = theta_read[i] - legs[i, LEG_SIZE - 1]
        nu = y[i] - state[3 * i]
        for k in range(3):
            x_hat[i, k] = state[3 * i + k] + L[k] * nu
        e_th = x_hat[i, 0] - th0[i]
        e_w = x_hat[i, 1] - w0[i]
        a = -(K[0] * state[i_z + i] + K[1] * e_th + K[2] * e_w)
        for j in range(n_k - 3):
            a -= K[3 + j] * state[i_p + d * i + j]
        acc[i] = a - c[DOB] * x_hat[i, 2]
    saturated = False
    limit = c[LIMIT]
    for i in range(6):
        tau_fb = 0.0
        for j in range(6):
            tau_fb += M[i, j] * acc[j]
        e_th = x_hat[i, 0] - th0[i]
        v = wl[i] - c[K_C] * e_th
        F = state[i_f + i]
        sense = (1.0 - c[SHARE]) * math.tanh(wl[i] / c[FRICTION_RATE])
        sense += c[SHARE] * math.tanh(v / c[FRICTION_RATE])
        T = T_ff[i] + (F + c[LOAD_SHARE] * abs(T_ff[i])) * sense + c[VISCOUS] * wl[i]
        T = (T + tau_fb) / kt[i]
        clipped = False
        if T > limit:
            T, clipped = limit, True
        elif T < -limit:
            T, clipped = -limit, True
        saturated = saturated or clipped
        state[i_t + i] = T
        if not clipped:
            state[i_z + i] += h * e_th
        if c[ADAPT] > 0.0 and abs(wl[i]) > c[ADAPT_MIN_RATE]:
            F += c[ADAPT] * h * friction_error(state, i_r + 4 * i, c[MEMORY], tau_fb, wl[i])
            state[i_f + i] = min(max(F, c[FRICTION_MIN]), c[FRICTION_MAX])
        _predict(state, i, d, i_p, acc[i], Phi, Gam, x_hat)
    if saturated:
        state[i_s + 1] += 1.0
    for i in range(6):
        s = 0.0
        for j in range(6):
            s += J_inv[i, j] * (y[j] - th0[j])
        state[i_e + i] = s
    return True


@_njit
def _predict(state, i, d, i_p, acc_i, Phi, Gam, x_hat):
    """Crank ``i``'s estimator prediction over the next period, with the command that acts
    over it (``d`` periods late: the oldest of its delay line, which then takes ``acc_i``), in
    ``state`` (:func:`step`'s)."""
    act = acc_i if d == 0 else state[i_p + d * i]
    for k in range(3):
        s = Gam[k] * act
        for m in range(3):
            s += Phi[k, m] * x_hat[i, m]
        state[3 * i + k] = s
    for j in range(d - 1):
        state[i_p + d * i + j] = state[i_p + d * i + j + 1]
    if d > 0:
        state[i_p + d * i + d - 1] = acc_i


def warm_up() -> None:
    """Compile (or load from the cache) :func:`step` with the types the controller passes."""
    legs = np.zeros((6, LEG_SIZE))
    legs.setflags(write=False)
    c = np.zeros(len(CONSTANTS))
    c[FRICTION_RATE], c[DELAY], c[LIMIT] = 1e-3, 1.0, math.inf
    # The gains read-only, as design.design_loop makes them: numba compiles (or loads) one
    # version per argument type, read-only included, and a version first met in a control
    # period stalls it.
    K, L, Gam = np.zeros(4), np.zeros(3), np.zeros(3)
    Phi, M, J = np.eye(3), np.eye(6), np.eye(6)
    for a in (c, K, L, Phi, Gam):
        a.setflags(write=False)
    kt = np.ones(6)
    kt.setflags(write=False)
    state = np.zeros(layout(1)["size"].stop)
    step(c, K, L, Phi, Gam, legs, M, J, np.zeros(18), np.zeros(6), np.zeros(6), kt, state)
    # The servos' own loop's goals (goal_stream.CrankGoalStreamer), called from Python.
    crank_reference(legs, np.zeros(18), 0.01, np.empty(6), np.empty(6))
    # The inertia's re-schedule, which the controller calls every few periods with the robot's
    # read-only constants (statics.kernel_constants); zero legs close no leg: it returns False.
    body = np.zeros(len(path_kernels.BODY))
    body.setflags(write=False)
    x = np.array([0.0, 0.0, 0.0, 0.0, 0.0, 0.3])
    path_kernels.joint_inertia(legs, body, x, np.empty((6, 6)), np.empty((6, 6)))


#: Every function above as the Python numba compiles (its ``py_func``): the uncompiled form.
reference = interpreted(globals())

warm_up()
