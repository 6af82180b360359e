"""A servo on its bench, simulated: the servo's firmware closing its own position loop on a
pendulum, as the bench's logs record a real one (:mod:`.bench_log`), with the drive and the
friction of :mod:`stewart_drake.station.bus.servo_physics`.

:func:`replay` runs a :class:`BenchModel` on a log's goal positions, the firmware's loop
closed on the simulated shaft (not on the logged one), and returns the simulated positions at the
log's times; :func:`errors` compares them with what the real servo did (mean absolute and RMS
error, rad), as Duclusaud et al. (ICRA 2025) judge a model: a rollout of the whole log, never
reset to the measurement.

The pendulum: ``J q'' = tau_m + tau_e + tau_f`` with ``J`` the pendulum's inertia plus the
servo's ``armature`` (its rotor seen at the shaft), ``tau_e = -(m + m_arm / 2) g l sin(q +
q_offset)`` (the arm hangs down at ``q = -q_offset``: the bench's zero is off by that), the motor's
torque from the firmware's duty (:func:`~stewart_drake.station.bus.servo_physics.position_duty`,
bounded for the current limit, then by the supply), the friction the stopping torque clipped to
the budget. Semi-implicit Euler at :data:`STEP_S`, landing on every logged time; the goal is the
log's, linear between samples, the torque off where the log says so
(:func:`~stewart_drake.station.bus.servo_physics.pendulum_rollout`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ..base.errors import InvalidConfigError
from ..station.bus import servo_physics as physics
from ..station.bus.servo_physics import FRICTION_NAMES, MODEL_CLASSES, friction_vector
from .bench_log import BenchLog

#: The simulation's step, s (the firmware's loop runs at least this often).
STEP_S = 1e-3
#: The drive's parameters, in the order of a drive vector.
DRIVE_NAMES = ("k_Nm_per_A", "resistance_ohm", "armature_kg_m2", "q_offset_rad")


@dataclass(frozen=True)
class BenchServo:
    """What the bench needs of a servo's firmware and datasheet.

    Attributes:
        name: the model.  counts_per_rev: the encoder's counts a turn of the shaft.
        p_divisor: the position P gain's divisor: the firmware's output is ``kp / p_divisor``
            PWM units per count of error.  pwm_full: the PWM units of a 100 % duty.
        duty_max: the PWM Limit as a share of ``pwm_full``.  current_limit_A: the firmware's.
        stall_torque_Nm, no_load_speed_rad_s: the datasheet's, at the shaft (for the bounds of an
            identification).
        source: where each figure comes from.
    """

    name: str
    counts_per_rev: int
    p_divisor: float
    pwm_full: float
    duty_max: float
    current_limit_A: float
    stall_torque_Nm: float
    no_load_speed_rad_s: float
    source: str


#: The servos the bench knows.
BENCH_SERVOS = {
    "XL330-M288-T": BenchServo(
        "XL330-M288-T",
        4096,
        256.0,
        885.0,
        1.0,
        1.75,
        0.52,
        103 * 2 * math.pi / 60,
        "ROBOTIS e-Manual, XL330-M288-T (https://emanual.robotis.com/docs/en/dxl/x/xl330-m288/): "
        "4096 counts a turn, PWM Limit 885 (100 %), Current Limit 1750 mA, stall torque 0.52 N m "
        "and no-load speed 103 rpm at 5 V. The P gain's divisor: the e-Manual gives KPP = "
        "KPP(TBL) / 128; Duclusaud et al.'s measurements of the XL330 found 256 (Rhoban/bam, "
        "bam/dynamixel/actuator.py), which gives the datasheet's torque constant "
        "(0.52 N m / 1.47 A = 0.35 N m/A) where 128 would halve it",
    )
}


def bench_servo(name: str) -> BenchServo:
    """The bench's figures of servo ``name``: :data:`BENCH_SERVOS`'s, or, for a servo of the
    bus with Current Control Mode (:data:`~stewart_drake.station.bus.servos.SERVO_SPECS`), its
    bus table's and the motor catalogue's, for logs in Current Control Mode (its position loop's
    gains are not known to the bench: the e-Manual's 128 and 885 are taken).

    Raises:
        InvalidConfigError: a servo the bench does not know (the known ones listed).
    """
    from ..robot.motor_catalogue import catalogue_motor
    from ..station.bus.servos import SERVO_SPECS

    if name in BENCH_SERVOS:
        return BENCH_SERVOS[name]
    spec = SERVO_SPECS.get(name)
    if spec is None or spec.current_unit_A is None:
        known = [*BENCH_SERVOS, *(n for n, s in SERVO_SPECS.items() if s.current_unit_A)]
        raise InvalidConfigError(
            f"--servo {name!r}: the bench knows {', '.join(known)}; its firmware's gains "
            "and limits are needed to simulate another"
        )
    servo = catalogue_motor(name).servo
    return BenchServo(
        name,
        spec.counts_per_rev,
        128.0,
        885.0,
        1.0,
        spec.current_limit_max * spec.current_unit_A,
        servo.peak_torque_Nm,
        servo.no_load_speed_rad_s,
        f"the bus's table ({spec.source}) and the motor catalogue (docs/motor_catalogue.md)",
    )


@dataclass(frozen=True)
class BenchModel:
    """A servo's model as identified on its bench: its drive and its friction.

    Attributes:
        servo: a :data:`BENCH_SERVOS` key.  model_class: "m1" .. "m6"
            (:data:`~stewart_drake.station.bus.servo_physics.MODEL_CLASSES`).
        k_Nm_per_A: the motor's constant at the shaft (torque per ampere, back-EMF per rad/s).
        resistance_ohm: the winding's (and drive's) resistance.  armature_kg_m2: the rotor's
            inertia at the shaft.  q_offset_rad: the bench's zero error.
        friction: {name: value} of the model class's terms (the others zero).
        current_time_constant_s: the current loop's lag (Current Control Mode; a log in the
            servo's position mode drives the motor by PWM and does not show it), s.
    """

    servo: str
    model_class: str
    k_Nm_per_A: float
    resistance_ohm: float
    armature_kg_m2: float
    q_offset_rad: float = 0.0
    friction: dict = field(default_factory=dict)
    current_time_constant_s: float = 0.0

    def __post_init__(self):
        bench_servo(self.servo)
        if self.model_class not in MODEL_CLASSES:
            raise InvalidConfigError(
                f"model class {self.model_class!r} is not one of {', '.join(MODEL_CLASSES)}"
            )
        extra = sorted(set(self.friction) - set(MODEL_CLASSES[self.model_class]))
        if extra:
            raise InvalidConfigError(
                f"{self.model_class} has no friction term {', '.join(extra)} (its terms: "
                f"{', '.join(MODEL_CLASSES[self.model_class])})"
            )
        for name in ("k_Nm_per_A", "resistance_ohm", "armature_kg_m2"):
            if not (math.isfinite(getattr(self, name)) and getattr(self, name) > 0):
                raise InvalidConfigError(f"{name} must be > 0, got {getattr(self, name)!r}")
        for name, value in self.friction.items():
            if not (math.isfinite(value) and value >= 0):
                raise InvalidConfigError(f"friction {name} must be >= 0, got {value!r}")
        lag = self.current_time_constant_s
        if not (math.isfinite(lag) and lag >= 0):
            raise InvalidConfigError(f"current_time_constant_s must be >= 0, got {lag!r}")

    def drive_vector(self) -> np.ndarray:
        """(5,) :data:`DRIVE_NAMES` and the current loop's lag."""
        return np.array(
            [
                self.k_Nm_per_A,
                self.resistance_ohm,
                self.armature_kg_m2,
                self.q_offset_rad,
                self.current_time_constant_s,
            ]
        )

    def friction_vector(self) -> np.ndarray:
        """(len(FRICTION_NAMES),) the budget's terms."""
        return friction_vector(self.friction)


def crank_servo_settings(model: BenchModel) -> dict | None:
    """What the crank servo takes of one servo's identified model (a scenario's ``controller:
    !CrankServoDriver``, that servo's crank; docs/robot.md, "A commissioned paper_bus"), or None
    for a servo the bus does not drive: its torque per ampere while the motor drives, as a share
    of the bus's catalogue K_t (k (1 - K_l) / K_t: the gears lose K_l of what the motor gives);
    its Coulomb friction believed, N m: the static budget K_c + K_cs, the crank servo's one
    Coulomb term (a crank breathing turns at a tenth of the Stribeck speed or less, where the
    Stribeck term has hardly fallen; and the search tells the budget, not its split: an
    emulated robot's six servos came out 2 to 32 % low in K_c + K_cs / 2, on which its rotor
    x0.5 edge missed its bounds, 193 um true X against 133 um on the budget: docs/robot.md,
    "A commissioned paper_bus"); and the gears' load share K_l (M5 and M6: the motor's,
    ``load_motor``; M3 and M4: ``load``; 0 for M1 and M2)."""
    from ..station.bus.servos import SERVO_SPECS

    spec = SERVO_SPECS.get(model.servo)
    if spec is None:
        return None
    f = model.friction
    share = f.get("load_motor", f.get("load", 0.0))
    return {
        "torque_constant_scale": model.k_Nm_per_A * (1.0 - share) / spec.torque_constant_Nm_per_A,
        "friction_Nm": f.get("coulomb_Nm", 0.0) + f.get("stribeck_Nm", 0.0),
        "friction_load_share": share,
    }


def log_arrays(log: BenchLog, servo: BenchServo) -> tuple:
    """The arrays :func:`~stewart_drake.station.bus.servo_physics.pendulum_rollout` takes for
    ``log`` on ``servo``: (t, goal, enabled, bench, servo constants)."""
    bench = np.array([log.inertia_kg_m2, log.gravity_Nm, log.supply_V, log.kp])
    mode = physics.CURRENT_MODE if log.mode == "current" else physics.POSITION_MODE
    constants = np.array(
        [
            servo.counts_per_rev,
            servo.p_divisor,
            servo.pwm_full,
            servo.duty_max,
            servo.current_limit_A,
            mode,
        ],
        dtype=float,
    )
    return log.t, log.goal, log.enabled, bench, constants


def replay(model: BenchModel, log: BenchLog, step_s: float = STEP_S) -> np.ndarray:
    """(n,) the simulated shaft angle at the log's times, rad, ``model`` driven by the log's
    goals from its first angle
    (:func:`~stewart_drake.station.bus.servo_physics.pendulum_rollout`)."""
    q = np.empty(log.t.size)
    q[0] = log.q[0]
    t, goal, enabled, bench, servo = log_arrays(log, bench_servo(model.servo))
    drive, f = model.drive_vector(), model.friction_vector()
    physics.pendulum_rollout(t, goal, enabled, bench, servo, drive, f, step_s, q)
    return q


def errors(simulated: np.ndarray, log: BenchLog) -> dict:
    """{"mae_rad", "rms_rad", "peak_rad"}: the simulated angles against the logged ones, over
    every sample (the mean absolute error is Duclusaud et al.'s figure)."""
    e = np.asarray(simulated, dtype=float) - log.q
    return {
        "mae_rad": float(np.mean(np.abs(e))),
        "rms_rad": float(np.sqrt(np.mean(e * e))),
        "peak_rad": float(np.max(np.abs(e))),
    }


__all__ = [
    "BENCH_SERVOS",
    "BenchModel",
    "BenchServo",
    "DRIVE_NAMES",
    "FRICTION_NAMES",
    "STEP_S",
    "bench_servo",
    "errors",
    "log_arrays",
    "replay",
]
