"""A servo's drive and friction identified from its bench logs: the :class:`~.bench.BenchModel` of
one model class whose replay of every log (:func:`~.bench.replay`: the firmware's loop closed on
the simulated shaft, the whole log, never reset to the measurement) departs least from what the
real servo did, in mean absolute error over the logs (Duclusaud et al., ICRA 2025, identify their
models this way, with CMA-ES).

The search: scipy's differential evolution (a seeded, bounded global search; the error is not
smooth where the shaft sticks and slips, which rules out a gradient), over the motor's constant,
the resistance, the rotor's inertia at the shaft, the bench's zero error and the class's friction
terms (:data:`~stewart_drake.station.bus.servo_physics.MODEL_CLASSES`), each within
:func:`bounds`, and, where a log drove the servo in Current Control Mode, the current loop's lag.
What the logs cannot tell apart stays unidentified: the P divisor and the torque constant scale
together (:data:`~.bench.BENCH_SERVOS` gives the divisor); a log in position mode drives the
motor by its PWM, so the current loop's lag does not show in it; and in Current Control Mode
the winding's resistance shows only where the supply bounds the current (fast motion).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from ..base.checks import check_int
from ..base.errors import InvalidConfigError
from ..station.bus import servo_physics as physics
from ..station.bus.servo_physics import MODEL_CLASSES, friction_vector
from .bench import BenchModel, BenchServo, bench_servo, log_arrays
from .bench_log import BenchLog

#: The drive's terms a search moves, before the friction's.
DRIVE_TERMS = ("k_Nm_per_A", "resistance_ohm", "armature_kg_m2", "q_offset_rad")


def bounds(
    servo: BenchServo, model_class: str, with_lag: bool = False
) -> dict[str, tuple[float, float]]:
    """{term: (low, high)} of a search of ``model_class`` on ``servo`` (``with_lag``: the
    current loop's lag too, 0 to 10 ms, for logs in Current Control Mode): the motor's constant
    within a factor of 4 of the datasheet's stall torque over its current limit (either side),
    the resistance 0.3 to 20 ohm, the rotor 1e-5 to 0.05 kg m^2 at the shaft, the bench's zero
    within 0.1 rad; friction torques up to 40 % of the stall torque, the viscous term up to the
    stall torque over the no-load speed, load shares up to 1, the Stribeck speed 0.01 to 5 rad/s
    and its exponent 0.5 to 10 (Duclusaud et al.'s ranges), the quadratic terms up to 0.05 per
    N m."""
    k0 = servo.stall_torque_Nm / servo.current_limit_A
    torque = 0.4 * servo.stall_torque_Nm
    ranges = {
        "k_Nm_per_A": (k0 / 4, 4 * k0),
        "resistance_ohm": (0.3, 20.0),
        "armature_kg_m2": (1e-5, 0.05),
        "q_offset_rad": (-0.1, 0.1),
        "current_time_constant_s": (0.0, 0.01),
        "coulomb_Nm": (0.0, torque),
        "viscous_Nm_s_per_rad": (0.0, servo.stall_torque_Nm / servo.no_load_speed_rad_s),
        "stribeck_Nm": (0.0, torque),
        "stribeck_rad_s": (0.01, 5.0),
        "stribeck_alpha": (0.5, 10.0),
        "quad_motor_per_Nm": (0.0, 0.05),
        "quad_external_per_Nm": (0.0, 0.05),
    }
    lag = ("current_time_constant_s",) if with_lag else ()
    terms = DRIVE_TERMS + lag + MODEL_CLASSES[model_class]
    return {name: ranges.get(name, (0.0, 1.0)) for name in terms}


def model_of(
    servo: str, model_class: str, x: Sequence[float], with_lag: bool = False
) -> BenchModel:
    """The :class:`~.bench.BenchModel` of a search's vector ``x`` (:data:`DRIVE_TERMS`, the
    current loop's lag ``with_lag``, then the class's friction terms)."""
    terms = MODEL_CLASSES[model_class]
    k, R, armature, offset = (float(v) for v in x[:4])
    n = 5 if with_lag else 4
    lag = float(x[4]) if with_lag else 0.0
    friction = {name: float(v) for name, v in zip(terms, x[n:])}
    return BenchModel(servo, model_class, k, R, armature, offset, friction, lag)


@dataclass(frozen=True)
class Identified:
    """An identification's result.

    Attributes:
        model: the model found.  mae_rad: its mean over the logs of each log's mean absolute
            error, rad.  evaluations: how many replays of the logs the search ran.
        logs: the logs' names, in order.
        settled: whether the search had settled (:func:`has_settled`); False: its best error
            was still falling, and the model may be far from the servo's (more generations).
        generations: the generations the search ran.
    """

    model: BenchModel
    mae_rad: float
    evaluations: int
    logs: tuple[str, ...]
    settled: bool = True
    generations: int = 0


#: A search has settled when its best error fell, over its last :func:`settling_window`
#: generations, by less than this share of itself...
SETTLED_SHARE = 0.01
#: ... or by less than this share of an encoder count (a replay cannot be told better than the
#: log's own resolution; an emulated XM430's search still fell 5 % over its last 40 of 400
#: generations at 0.57 mrad, 0.03 mrad, with its figures within 3 % of the servo's). scipy's own
#: test (the population's errors within ``tol`` of their mean) is not it: at 1e-6 no search here
#: meets it, and a looser ``tol`` would stop the search where it is.
SETTLED_COUNTS = 0.1


def settling_window(generations: int) -> int:
    """The generations over which a search's settling is judged: a tenth of the search, at
    least 10."""
    return max(10, generations // 10)


def has_settled(best_mae: Sequence[float], count_rad: float = 0.0) -> bool:
    """Whether a search whose best error (rad) after each generation was ``best_mae`` had
    settled: its fall over the last :func:`settling_window` generations under
    :data:`SETTLED_SHARE` of itself or :data:`SETTLED_COUNTS` of an encoder count
    (``count_rad``); False for a search no longer than its window."""
    window = settling_window(len(best_mae))
    if len(best_mae) <= window:
        return False
    before, after = best_mae[-1 - window], best_mae[-1]
    return bool(before - after <= max(SETTLED_SHARE * before, SETTLED_COUNTS * count_rad))


def _checked(logs, servo: str, model_class: str, generations: int) -> tuple:
    """(the servo's :class:`~.bench.BenchServo`, the generations) once :func:`identify`'s
    arguments are checked (its Raises)."""
    spec = bench_servo(servo)
    if model_class not in MODEL_CLASSES:
        raise InvalidConfigError(
            f"--model-class {model_class!r}: choose one of {', '.join(MODEL_CLASSES)}"
        )
    if not logs:
        raise InvalidConfigError("identify needs at least one bench log")
    return spec, check_int("generations", generations, 1)


def identify(
    logs: Sequence[BenchLog],
    servo: str,
    model_class: str = "m6",
    seed: int = 0,
    generations: int = 150,
    progress: Callable[[int, float], None] | None = None,
) -> Identified:
    """The :class:`~.bench.BenchModel` of ``model_class`` that replays ``logs`` best (module
    docstring).

    Args:
        logs: checked bench logs (:func:`~.bench_log.read_bench_log`) of the one servo.
        servo: a :data:`~.bench.BENCH_SERVOS` key.  model_class: "m1" .. "m6".
        seed: the search's seed (the same logs and seed give the same model).
        generations: the search's generations at most (each ``15 x`` the terms' count replays).
        progress: ``f(generation, best mean absolute error rad)`` after each generation.
    Raises:
        InvalidConfigError: no log, an unknown servo or model class, generations < 1.
    """
    from scipy.optimize import differential_evolution

    spec, generations = _checked(logs, servo, model_class, generations)
    with_lag = any(log.mode == "current" for log in logs)
    n = 5 if with_lag else 4
    arrays = [log_arrays(log, spec) for log in logs]
    measured = [log.q for log in logs]
    outs = [np.empty(log.t.size) for log in logs]
    terms = MODEL_CLASSES[model_class]
    f = friction_vector({})
    slots = np.array([physics.FRICTION[name] for name in terms], dtype=np.int64)
    count = [0]

    def objective(x) -> float:
        count[0] += 1
        f[slots] = x[n:]
        drive = np.zeros(5)
        drive[:n] = x[:n]
        total = 0.0
        for (t, goal, enabled, bench, constants), q, out in zip(arrays, measured, outs):
            out[0] = q[0]
            physics.pendulum_rollout(t, goal, enabled, bench, constants, drive, f, 1e-3, out)
            e = np.mean(np.abs(out - q))
            total += e if math.isfinite(e) else 10.0
        return total / len(arrays)

    best: list[float] = []

    def callback(xk, convergence=None) -> None:
        best.append(objective(xk))
        if progress is not None:
            progress(len(best), best[-1])

    ranges = list(bounds(spec, model_class, with_lag).values())
    result = differential_evolution(
        objective,
        ranges,
        seed=seed,
        maxiter=generations,
        popsize=15,
        tol=1e-6,
        mutation=(0.5, 1.0),
        recombination=0.7,
        polish=False,
        init="sobol",
        callback=callback,
    )
    model = model_of(servo, model_class, result.x, with_lag)
    return Identified(
        model,
        float(result.fun),
        count[0],
        tuple(log.name for log in logs),
        settled=has_settled(best, 2 * math.pi / spec.counts_per_rev),
        generations=len(best),
    )
