"""A servo as it is, where the controller's model stops: its drive (the supply voltage, the PWM
duty, the winding's resistance and back-EMF, the current loop's lag and limit, the firmware's
position loop) and its gear train's friction, compiled with numba: the bus emulator's servos as
they are (:class:`~stewart_drake.live.plant_backend.RealisticServos`) and the bench on which
real servos are identified (:mod:`stewart_drake.actuator`) run these functions.

Conventions, at the output shaft, SI: ``v`` the shaft's rate (rad/s), ``tau_m`` the motor's
torque through the gears, ``tau_e`` the load's torque on the shaft (gravity on a bench), both
N m in the shaft's sense. The motor is a DC motor seen at the shaft: ``tau_m = k i`` and a
back-EMF ``k v`` (``k`` in N m/A = V s/rad, the motor's constant times the gear ratio, without
the gears' losses: those are the friction's, below), so that a PWM duty ``d`` in [-1, 1] of the
supply ``V`` drives ``i = (d V - k v) / R`` (the winding's inductance left out: its time
constant, well under a millisecond, is below the current loop's).

The friction is a budget ``tau_fm``, the largest torque the gear train can hold against the
motion (:func:`friction_budget`), applied as the torque that would stop the shaft within one
step, clipped to ``[-tau_fm, tau_fm]`` (:func:`stopping_friction`): a shaft at rest stays at
rest until the other torques exceed the budget, with no regularisation. The budget is the six
models of M. Duclusaud, G. Passault, V. Padois and O. Ly, "Extended Friction Models for the
Physics Simulation of Servo Actuators", ICRA 2025 (arXiv 2410.08650), written here from their
equations: with ``S = exp(-|v / v_s|^alpha)`` (1 at rest, 0 when sliding fast),

- M1: ``K_c + K_v |v|``; M2: M1 + ``S K_cs`` (static friction above the sliding one);
- M3: M1 + ``K_l |tau_m - tau_e|``; M4: M2 + ``(K_l + S K_ls) |tau_m - tau_e|`` (friction grows
  with the torque the gears carry);
- M5: M2 + ``|K_le tau_e - K_lm tau_m| + S |K_les tau_e - K_lms tau_m|`` (the load's and the
  motor's torques weighed apart: a train driven from the motor is not the one backdriven);
- M6: M5 + ``S K_qe tau_e^2`` while the motor drives against the load (opposite signs, the
  motor's larger) or ``S K_qm tau_m^2`` while the load drives the motor back.

Every model is one vector of :data:`FRICTION_NAMES` (a model's unused terms zero):
:data:`MODEL_CLASSES` names each model's terms. :data:`reference` holds the functions
uncompiled (their ``py_func``).
"""

from __future__ import annotations

import math

import numpy as np

from ...base.compiled import interpreted, njit_cached

#: The friction budget's terms, in the order of a friction vector (N m, N m s/rad, rad/s, or no
#: unit for the load terms, a share of a torque; the quadratic terms per N m).
FRICTION_NAMES = (
    "coulomb_Nm",  # K_c
    "viscous_Nm_s_per_rad",  # K_v
    "stribeck_Nm",  # K_cs
    "stribeck_rad_s",  # v_s
    "stribeck_alpha",  # alpha
    "load",  # K_l
    "load_stribeck",  # K_ls
    "load_motor",  # K_lm
    "load_external",  # K_le
    "load_motor_stribeck",  # K_lms
    "load_external_stribeck",  # K_les
    "quad_motor_per_Nm",  # K_qm
    "quad_external_per_Nm",  # K_qe
)
FRICTION = {name: k for k, name in enumerate(FRICTION_NAMES)}
_STRIBECK = ("stribeck_Nm", "stribeck_rad_s", "stribeck_alpha")
_DIRECTIONAL = ("load_motor", "load_external", "load_motor_stribeck", "load_external_stribeck")
#: The terms each model of Duclusaud et al. (2025) uses; the others are zero.
MODEL_CLASSES: dict[str, tuple[str, ...]] = {
    "m1": ("coulomb_Nm", "viscous_Nm_s_per_rad"),
    "m2": ("coulomb_Nm", "viscous_Nm_s_per_rad", *_STRIBECK),
    "m3": ("coulomb_Nm", "viscous_Nm_s_per_rad", "load"),
    "m4": ("coulomb_Nm", "viscous_Nm_s_per_rad", *_STRIBECK, "load", "load_stribeck"),
    "m5": ("coulomb_Nm", "viscous_Nm_s_per_rad", *_STRIBECK, *_DIRECTIONAL),
    "m6": (
        "coulomb_Nm",
        "viscous_Nm_s_per_rad",
        *_STRIBECK,
        *_DIRECTIONAL,
        "quad_motor_per_Nm",
        "quad_external_per_Nm",
    ),
}


def friction_vector(values: dict) -> np.ndarray:
    """(len(FRICTION_NAMES),) from ``{name: value}`` (names of :data:`FRICTION_NAMES`; the
    others zero, the Stribeck shape 1 rad/s and 1 when not given, so that a model without it
    divides by nothing)."""
    f = np.zeros(len(FRICTION_NAMES))
    f[FRICTION["stribeck_rad_s"]] = 1.0
    f[FRICTION["stribeck_alpha"]] = 1.0
    for name, value in values.items():
        f[FRICTION[name]] = float(value)
    return f


def _njit(function):
    return njit_cached(function, error_model="numpy")


@_njit
def friction_budget(f, v, tau_m, tau_e):
    """The gear train's friction budget tau_fm, N m (module docstring), for friction vector
    ``f`` (:data:`FRICTION_NAMES`) at shaft rate ``v`` rad/s with the motor's torque ``tau_m``
    and the load's ``tau_e``, N m."""
    s = math.exp(-(abs(v / f[3]) ** f[4]))
    carried = abs(tau_m - tau_e)
    budget = f[0] + f[1] * abs(v) + s * f[2] + (f[5] + s * f[6]) * carried
    budget += abs(f[8] * tau_e - f[7] * tau_m) + s * abs(f[10] * tau_e - f[9] * tau_m)
    if tau_e * tau_m < 0.0:  # the motor and the load against each other
        if abs(tau_e) < abs(tau_m):  # the motor drives
            budget += s * f[12] * tau_e * tau_e
        elif abs(tau_e) > abs(tau_m):  # the load drives the motor back
            budget += s * f[11] * tau_m * tau_m
    return budget


@_njit
def stopping_friction(inertia, h, v, tau_net, budget):
    """The friction torque over a step ``h`` s of a shaft of ``inertia`` kg m^2 at rate ``v``
    under the other torques ``tau_net`` N m: the torque that stops it within the step (``-(J
    v / h + tau_net)``), clipped to ``[-budget, budget]``."""
    stop = inertia * v / h + tau_net
    return -math.copysign(min(abs(stop), budget), stop)


@_njit
def pwm_current(duty, v, supply_V, k, R):
    """The winding's current, A, at PWM ``duty`` of ``supply_V`` with the shaft at ``v``:
    ``(d V - k v) / R``."""
    return (duty * supply_V - k * v) / R


@_njit
def limited_duty(duty, v, supply_V, k, R, current_limit_A, duty_max):
    """``duty`` kept, where the supply allows it, to a current within ``current_limit_A`` (the
    firmware bounds the duty, not the current: at speed the back-EMF can hold the current past
    the limit, and the supply wins), then within ``[-duty_max, duty_max]``."""
    centre, span = k * v / supply_V, R * current_limit_A / supply_V
    duty = min(max(duty, centre - span), centre + span)
    return min(max(duty, -duty_max), duty_max)


@_njit
def position_duty(goal_rad, read_rad, kp_raw, counts_per_rev, divisor, pwm_full):
    """The firmware position loop's P term as a duty: ``kp_raw / divisor`` PWM units per count of
    error (the encoder read in whole counts), over ``pwm_full`` units (100 %)."""
    counts = counts_per_rev / (2.0 * math.pi)
    error = math.floor(goal_rad * counts + 0.5) - math.floor(read_rad * counts + 0.5)
    return kp_raw / divisor * error / pwm_full


@_njit
def current_step(i, target_A, h, time_constant_s, v, supply_V, k, R, current_limit_A):
    """The current after a step ``h`` of a current loop of ``time_constant_s`` (first order)
    towards ``target_A``, the target within ``current_limit_A`` and the result within what the
    supply drives at ``v`` (``[(-V - k v) / R, (V - k v) / R]``), A."""
    target = min(max(target_A, -current_limit_A), current_limit_A)
    if time_constant_s > 0.0:
        i = i + (1.0 - math.exp(-h / time_constant_s)) * (target - i)
    else:
        i = target
    lo, hi = (-supply_V - k * v) / R, (supply_V - k * v) / R
    return min(max(i, lo), hi)


#: The firmware modes a bench rollout runs: the servo's own position loop (its PWM from the P
#: term), or its current loop following a Goal Current (Current Control Mode).
POSITION_MODE, CURRENT_MODE = 3.0, 0.0


@_njit
def pendulum_rollout(t, goal, enabled, bench, servo, drive, f, h, q_out):
    """A servo swinging a pendulum (a bench, :mod:`stewart_drake.actuator.bench`): the shaft's
    angle at each time ``t`` (n,) into ``q_out`` (n,), from ``q_out[0]`` at rest. ``J q'' =
    tau_m + tau_e + tau_f``: the pendulum's inertia plus the rotor's, gravity ``-G sin(q +
    q_offset)``, the motor's torque ``k i``, the friction the stopping torque clipped to the
    budget; semi-implicit Euler at ``h``, landing on every time of ``t``. In the servo's own
    position mode the current is the firmware's duty's (:func:`position_duty`, bounded by
    :func:`limited_duty`) through the winding; in Current Control Mode the current follows the
    goal through the current loop (:func:`current_step`).

    Args:
        goal (n,): the goal position, rad, linear between samples, or the Goal Current, A, each
            held until the next (by the mode).
        enabled (n,) bool: the torque's state.  bench: (4,) [pendulum inertia kg m^2, G N m,
            supply V, kp].  servo: (6,) [counts a turn, P divisor, PWM units of 100 %,
            largest duty, current limit A, mode (:data:`POSITION_MODE`, :data:`CURRENT_MODE`)].
            drive: (5,) [k N m/A, R ohm, armature kg m^2, q_offset rad, current lag s].
            f: the friction vector.  h: the step, s.
    """
    k, R, armature, offset, lag = drive[0], drive[1], drive[2], drive[3], drive[4]
    inertia = bench[0] + armature
    current_mode = servo[5] == CURRENT_MODE
    q, v, i = q_out[0], 0.0, 0.0
    now = t[0]
    seg = 0
    n = t.size
    for j in range(1, n):
        while now < t[j] - 1e-12:
            while seg + 2 < n and t[seg + 1] <= now:
                seg += 1
            if current_mode:  # each Goal Current held until the next is written
                g = goal[seg]
            else:  # a goal position's trajectory, sampled
                a = min(max((now - t[seg]) / (t[seg + 1] - t[seg]), 0.0), 1.0)
                g = goal[seg] + a * (goal[seg + 1] - goal[seg])
            step = min(h, t[j] - now)
            tau_m = 0.0
            if not enabled[seg]:
                i = 0.0
            elif current_mode:
                i = current_step(i, g, step, lag, v, bench[2], k, R, servo[4])
                tau_m = k * i
            else:
                duty = position_duty(g, q, bench[3], servo[0], servo[1], servo[2])
                duty = limited_duty(duty, v, bench[2], k, R, servo[4], servo[3])
                tau_m = k * pwm_current(duty, v, bench[2], k, R)
            tau_e = -bench[1] * math.sin(q + offset)
            budget = friction_budget(f, v, tau_m, tau_e)
            net = tau_m + tau_e
            net += stopping_friction(inertia, step, v, net, budget)
            v += step * net / inertia
            q += step * v
            now += step
        q_out[j] = q


def warm_up() -> None:
    """Compile (or load from the cache) every function with the types its callers pass."""
    f = friction_vector({})
    friction_budget(f, 0.1, 0.2, -0.1)  # a drawn servo's own (writeable) vector
    f.setflags(write=False)
    friction_budget(f, 0.1, 0.2, -0.1)
    stopping_friction(0.01, 1e-3, 0.1, 0.2, 0.05)
    pwm_current(0.5, 0.1, 12.0, 2.0, 5.0)
    limited_duty(0.5, 0.1, 12.0, 2.0, 5.0, 1.0, 1.0)
    position_duty(0.1, 0.0, 400.0, 4096.0, 256.0, 885.0)
    current_step(0.0, 1.0, 1e-3, 1e-3, 0.1, 12.0, 2.0, 5.0, 2.0)
    t, q = np.linspace(0.0, 0.01, 3), np.zeros(3)
    f = friction_vector({})
    pendulum_rollout(
        t, np.zeros(3), np.ones(3, bool), np.ones(4), np.ones(6), np.ones(5), f, 1e-3, q
    )


#: Every function above as the Python numba compiles (its ``py_func``): the uncompiled form.
reference = interpreted(globals())
