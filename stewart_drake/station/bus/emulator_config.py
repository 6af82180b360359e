"""The servos behind the bus emulator as a built robot's are: a scenario's ``emulator`` section
(:class:`EmulatorConfig`) and the servo set it draws (:meth:`EmulatorConfig.draw`,
:class:`EmulatedServos`), never the controller's own model.

``servos: realistic`` (``robot --emulate``'s default): every departure left ``null`` is drawn
from ``seed`` within what the catalogue and the e-Manual leave uncertain (the ranges below, each
with its source); ``servos: ideal`` (``--emulate ideal``): the controller's own model, as the
emulator was, every departure off unless given. A departure given (``--set
emulator.kt_scale=0.7``) applies in either, alone in ``ideal``.

What a drawn servo is (at the output shaft; :mod:`.servo_physics` runs it): a DC motor of
constant ``k = K_t / eta`` (N m/A and V s/rad; ``K_t`` the bus's stall ratio, ``eta`` the gear
train's efficiency, below) times ``kt_scale``, a winding of ``R = V / I_stall`` on the family's
supply ``V``; a current loop of the catalogue's lag times ``current_lag_scale``; a friction budget
of Duclusaud et al.'s (ICRA 2025) directional class: ``K_c`` and ``K_cs`` each 1 % of the stall
torque (their XL330, MX-64 and MX-106 hold 1.5 to 2 % together, at rest), a Stribeck speed of 2
rad/s and exponent 2 (theirs: 1.5 to 2.9 rad/s), ``1 - eta`` of the motor's torque lost where the
gears carry it plus a tenth more at rest (theirs: 0.20 to 0.31, and up to 0.2), all but the load
terms times ``friction_scale``; the catalogue's viscous friction times ``friction_scale``.
``eta`` is what the e-Manual's figures imply where they hold at one voltage: ``K_t`` over the
back-EMF constant of the no-load speed (0.71 for the XM430-W350-T); for the DYNAMIXEL-P, whose
no-load speed is not a back-EMF's, 0.7 (a planetary train's; an estimate).

Drake's YAML loader reads this dataclass's field annotations: this module must not use
``from __future__ import annotations``.
"""

import math
from dataclasses import dataclass, field, fields, replace

import numpy as np

from ...base.checks import MAX_SEED, as_number, check_int
from ...base.errors import InvalidConfigError
from ...robot.motor_catalogue import catalogue_motor
from .protocol import SUPPLY_V
from .servo_physics import FRICTION, friction_vector
from .servos import ServoSpec

#: A servo's motor constant about its model's, unit to unit: +-10 % (each servo its own).
KT_SPREAD = 0.10
#: The catalogue's rotor inertia "uncertain by a factor of about 2": drawn log-uniform, one
#: for all six (one model, one rotor).
ROTOR_INERTIA_RANGE = (0.5, 2.0)
#: The catalogue's friction (its 5 % guess, and the budget here) within a factor of 2 either
#: way, log-uniform, one for the model, then +-20 % servo to servo.
FRICTION_RANGE, FRICTION_SPREAD = (0.5, 2.0), 0.2
#: The catalogue's current-loop lag (1 ms, "not published") within a factor of 2.
CURRENT_LAG_RANGE = (0.5, 2.0)
#: The platform's mass (and payload) about the drawing's: machined and bought parts, +-3 %.
MASS_SPREAD = 0.03
#: The gear play drawn as a share of the e-Manual's largest: X series 15 arcmin (0.25 deg),
#: DYNAMIXEL-P "below 0.1 deg".
BACKLASH_SHARE = (0.25, 1.0)
BACKLASH_MAX_RAD = {"X": math.radians(0.25), "P": math.radians(0.1)}
#: The encoders' transition noise, counts RMS: the X series' ams AS5045 (e-Manual: the
#: XM430's encoder), 0.03 deg RMS in its slow mode (datasheet, "Transition noise") = 0.34 counts
#: of 4096; the DYNAMIXEL-P's counts its motor's turns (2048 a turn): one count of the output's
#: 526,374 (an estimate: 12 urad, below everything else).
ENCODER_NOISE_COUNTS = {"X": 0.34, "P": 1.0}
#: The encoder's integral non-linearity, its first harmonic a turn of what it reads: the AS5045's
#: +-0.5 deg with the magnet centred (datasheet), drawn up to it, servo by servo; the
#: DYNAMIXEL-P's on its motor shaft, divided by the gear ratio at the output (none drawn here).
INL_MAX_COUNTS = {"X": 0.5 / (360 / 4096), "P": 0.0}
#: The robot above the temperature its lengths were measured at, K (a warm room, warm
#: motors), drawn uniform.
TEMPERATURE_RISE_RANGE_K = (0.0, 5.0)
#: What moves the emulator's plant (:attr:`EmulatorConfig.clock`).
CLOCKS = ("wall", "loop")
#: The DYNAMIXEL-P's gear train efficiency (not published; a planetary train's, estimated).
P_EFFICIENCY = 0.7
#: Each servo's Return Delay Time as it leaves the factory: 250 x 2 us (e-Manual, "Return
#: Delay Time(9)").
FACTORY_RETURN_DELAY_US = 500.0
#: The motor constant's fall with the winding's (magnets') temperature, per K (NdFeB), and the
#: copper's resistance's rise, per K.
KT_PER_K, RESISTANCE_PER_K = -0.0012, 0.0039
SERVOS = ("realistic", "ideal")


#: How a run's bus is named when its servos were the emulator's: the start of an encoder log's
#: bus line (the session writes it; verify's reader and record tell an emulated run by it).
EMULATED_BUS = "emulated: "


@dataclass
class EmulatorConfig:
    """What the bus emulator puts behind the bus (module docstring). ``null``: drawn from
    ``seed`` with ``servos: realistic``, none with ``servos: ideal``.

    Attributes:
        servos: "realistic" or "ideal".  seed: the draw's, 0 .. 2^32 - 1.
        kt_scale: every servo's motor constant over the model's (drawn: each its own).
        rotor_inertia_scale: the rotors' inertia over the catalogue's.
        friction_scale: the friction budget's and the viscous friction over this module's.
        mass_scale: the platform's mass and inertia over the drawing's.
        current_lag_scale: the current loop's lag over the catalogue's.
        backlash_rad: each gear train's play at the output, rad.
        encoder_noise_counts: transition noise, counts RMS.
        encoder_nonlinearity_counts: the encoders' first-harmonic non-linearity, counts (each
            servo's phase drawn).
        temperature_rise_K: the robot (its lengths, its windings) above its lengths' temperature.
        return_delay_us: each servo's Return Delay Time as the emulator's control table starts
            it (null: the factory's 500 us; the driver may write its own).
        latency_timer_ms: the USB adapter's latency timer (1 ms as docs/robot.md sets it; the
            adapter's factory setting is 16).
        reply_jitter_us: the host's and the adapter's scheduling, added to each packet's time,
            uniform in [0, it].
        crc_error_rate, timeout_rate: the share of status packets sent corrupt, or not at all.
        clock: what moves the emulator's plant: "wall" (default), the wall clock, as servos
            are (its model must keep real time: one that falls behind says how far, its
            figures then the emulator's); "loop", the control loop's commands, one control
            period each, the model first carried to each command's instant under the commands
            before it (:class:`~.emulator.BusEmulator`'s ``catch_up``): the motion immune to
            the machine's speed, the loop's timing kept to the period (what a servo's 1 ms
            firmware needs on a machine that cannot run it in real time).
    """

    servos: str = "realistic"
    seed: int = 0
    kt_scale: float | None = None
    rotor_inertia_scale: float | None = None
    friction_scale: float | None = None
    mass_scale: float | None = None
    current_lag_scale: float | None = None
    backlash_rad: float | None = None
    encoder_noise_counts: float | None = None
    encoder_nonlinearity_counts: float | None = None
    temperature_rise_K: float | None = None
    return_delay_us: float | None = None
    latency_timer_ms: float | None = None
    reply_jitter_us: float | None = None
    crc_error_rate: float = 0.0
    timeout_rate: float = 0.0
    clock: str = "wall"

    def validate(self, prefix: str = "emulator.") -> None:
        """Check every field (named ``prefix + name``).

        Raises:
            InvalidConfigError: the first field out of range, named.
        """
        if self.servos not in SERVOS:
            raise InvalidConfigError(
                f"{prefix}servos must be one of {', '.join(SERVOS)}, got {self.servos!r}"
            )
        check_int(f"{prefix}seed", self.seed, 0, MAX_SEED)
        if self.clock not in CLOCKS:
            raise InvalidConfigError(
                f"{prefix}clock must be one of {', '.join(CLOCKS)}, got {self.clock!r}"
            )
        ranges = {
            "kt_scale": (0.2, 5.0),
            "rotor_inertia_scale": (0.1, 10.0),
            "friction_scale": (0.0, 10.0),
            "mass_scale": (0.5, 2.0),
            "current_lag_scale": (0.0, 20.0),
            "backlash_rad": (0.0, 0.1),
            "encoder_noise_counts": (0.0, 100.0),
            "encoder_nonlinearity_counts": (0.0, 100.0),
            "temperature_rise_K": (-30.0, 60.0),
            "return_delay_us": (0.0, 510.0),
            "latency_timer_ms": (0.0, 255.0),
            "reply_jitter_us": (0.0, 1e5),
            "crc_error_rate": (0.0, 1.0),
            "timeout_rate": (0.0, 1.0),
        }
        for name, (lo, hi) in ranges.items():
            value = getattr(self, name)
            if value is not None:
                as_number(f"{prefix}{name}", value, lo, hi)

    def given(self) -> dict:
        """{name: value} of the departures set (not null), beside ``servos`` and ``seed``."""
        skip = {"servos", "seed", "crc_error_rate", "timeout_rate"}
        out = {f.name: getattr(self, f.name) for f in fields(self) if f.name not in skip}
        out = {k: v for k, v in out.items() if v is not None}
        out.update({k: getattr(self, k) for k in ("crc_error_rate", "timeout_rate")})
        return {k: v for k, v in out.items() if v}

    def draw(self, spec: ServoSpec, n: int = 6) -> "EmulatedServos":
        """The servo set of ``n`` servos of model ``spec`` this section makes (module
        docstring): the given departures as given, the others drawn from ``seed``
        (``realistic``) or none (``ideal``).

        Raises:
            InvalidConfigError: as :meth:`validate`; a model the motor catalogue lacks.
        """
        self.validate()
        rng = np.random.default_rng(self.seed)
        real = self.servos == "realistic"
        family = spec.table.family
        servo = catalogue_motor(spec.name).servo

        def pick(value, draw, ideal):
            """The given value, else a draw (realistic) or the ideal's; drawn either way, so
            that one field set leaves the others' draws as they were."""
            drawn = draw()
            if value is not None:
                return value
            return drawn if real else ideal

        def log_uniform(lo, hi, size=None):
            return np.exp(rng.uniform(math.log(lo), math.log(hi), size))

        kt_each = np.ones(n) * pick(
            self.kt_scale, lambda: rng.uniform(1 - KT_SPREAD, 1 + KT_SPREAD, n), 1.0
        )
        rotor = float(pick(self.rotor_inertia_scale, lambda: log_uniform(*ROTOR_INERTIA_RANGE), 1))
        friction_model = log_uniform(*FRICTION_RANGE)
        friction_each = rng.uniform(1 - FRICTION_SPREAD, 1 + FRICTION_SPREAD, n)
        friction = np.full(n, self.friction_scale) if self.friction_scale is not None else (
            friction_model * friction_each if real else np.ones(n)
        )  # fmt: skip
        mass = float(
            pick(self.mass_scale, lambda: rng.uniform(1 - MASS_SPREAD, 1 + MASS_SPREAD), 1)
        )
        lag = float(pick(self.current_lag_scale, lambda: log_uniform(*CURRENT_LAG_RANGE), 0.0))
        backlash_max = BACKLASH_MAX_RAD[family]
        backlash = float(
            pick(self.backlash_rad, lambda: backlash_max * rng.uniform(*BACKLASH_SHARE), 0.0)
        )
        noise = self.encoder_noise_counts
        if noise is None:
            noise = ENCODER_NOISE_COUNTS[family] if real else 0.0
        inl_each = rng.uniform(0.0, 1.0, n) * INL_MAX_COUNTS[family]
        inl = np.full(n, self.encoder_nonlinearity_counts) if (
            self.encoder_nonlinearity_counts is not None
        ) else (inl_each if real else np.zeros(n))  # fmt: skip
        phase = rng.uniform(0.0, 2 * math.pi, n)
        warm = float(
            pick(self.temperature_rise_K, lambda: rng.uniform(*TEMPERATURE_RISE_RANGE_K), 0)
        )
        supply = SUPPLY_V[family]
        if family == "X":
            efficiency = spec.torque_constant_Nm_per_A / (supply / servo.no_load_speed_rad_s)
        else:
            efficiency = P_EFFICIENCY
        k_model = spec.torque_constant_Nm_per_A / (efficiency if real else 1.0)
        k = k_model * kt_each * (1 + KT_PER_K * warm)
        resistance = np.full(n, supply / spec.stall_current_A) * (1 + RESISTANCE_PER_K * warm)
        stall = servo.peak_torque_Nm
        budgets = np.empty((n, len(FRICTION)))
        for i in range(n):
            if real:
                terms = {
                    "coulomb_Nm": 0.01 * stall * friction[i],
                    "stribeck_Nm": 0.01 * stall * friction[i],
                    "stribeck_rad_s": 2.0,
                    "stribeck_alpha": 2.0,
                    "load_motor": max(0.0, 1.0 - efficiency),
                    "load_motor_stribeck": 0.1,
                }
            else:
                terms = {"coulomb_Nm": servo.coulomb_friction_Nm * friction[i]}
            budgets[i] = friction_vector(terms)
        return EmulatedServos(
            model=spec.name,
            family=family,
            realistic=real,
            kt_scale=kt_each,
            friction_scale=np.asarray(friction, dtype=float),
            k_Nm_per_A=k,
            resistance_ohm=resistance,
            supply_V=supply if real else math.inf,
            current_limit_A=spec.current_limit_max * spec.amps_per_unit,
            current_time_constant_s=servo.current_time_constant_s * lag,
            friction=budgets,
            viscous_scale=float(np.mean(friction)),
            rotor_inertia_scale=rotor,
            mass_scale=mass,
            backlash_rad=backlash,
            encoder_noise_counts=float(noise),
            inl_counts=np.asarray(inl, dtype=float),
            inl_phase=phase,
            temperature_rise_K=warm,
            return_delay_us=_given(self.return_delay_us, FACTORY_RETURN_DELAY_US if real else 0.0),
            latency_timer_ms=_given(self.latency_timer_ms, 1.0 if real else 0.0),
            reply_jitter_us=_given(self.reply_jitter_us, 100.0 if real else 0.0),
            crc_error_rate=self.crc_error_rate,
            timeout_rate=self.timeout_rate,
            seed=self.seed,
        )


def _given(value, otherwise: float) -> float:
    return float(otherwise if value is None else value)


@dataclass(frozen=True)
class EmulatedServos:
    """A drawn servo set (:meth:`EmulatorConfig.draw`); arrays one entry a servo, SI units at
    the output shaft.

    Attributes:
        model, family: the servos' model and control-table family ("X", "P").
        realistic: drawn as a built robot's (else the controller's model).
        kt_scale, friction_scale: (n,) each servo's motor constant and friction over the model's.
        k_Nm_per_A: (n,) motor constants (torque per ampere, back-EMF per rad/s).
        resistance_ohm: (n,).  supply_V: the supply (inf: no voltage limit).
        current_limit_A: the model's largest Current Limit.
        current_time_constant_s: the current loop's lag (0: none).
        friction: (n, len(FRICTION_NAMES)) each servo's friction budget terms.
        viscous_scale: the plant's viscous friction over the catalogue's.
        rotor_inertia_scale, mass_scale: the plant's over the catalogue's and drawing's.
        backlash_rad: the gear play, rad.  temperature_rise_K: the robot above its lengths'.
        encoder_noise_counts: RMS.  inl_counts, inl_phase: (n,) the first harmonic's amplitude,
            counts, and phase, rad.
        return_delay_us, latency_timer_ms, reply_jitter_us, crc_error_rate, timeout_rate: the
            bus's (:class:`EmulatorConfig`).
        seed: the draw's, which also seeds the encoders' noise and the bus's jitter.
    """

    model: str
    family: str
    realistic: bool
    kt_scale: np.ndarray
    friction_scale: np.ndarray
    k_Nm_per_A: np.ndarray
    resistance_ohm: np.ndarray
    supply_V: float
    current_limit_A: float
    current_time_constant_s: float
    friction: np.ndarray
    viscous_scale: float
    rotor_inertia_scale: float
    mass_scale: float
    backlash_rad: float
    encoder_noise_counts: float
    inl_counts: np.ndarray
    inl_phase: np.ndarray
    temperature_rise_K: float
    return_delay_us: float
    latency_timer_ms: float
    reply_jitter_us: float
    crc_error_rate: float
    timeout_rate: float
    seed: int = field(default=0)

    def summary(self) -> str:
        """One line: what the emulator's servos are, for the run's output."""
        if not self.realistic and not self.departs():
            return "ideal servos (the controller's own model)"
        k = self.k_Nm_per_A
        return (
            f"{'realistic' if self.realistic else 'ideal'} servos (seed {self.seed}): k "
            f"{k.min():.3g}-{k.max():.3g} N m/A, rotor x{self.rotor_inertia_scale:.2f}, "
            f"Coulomb {self.friction[:, FRICTION['coulomb_Nm']].mean():.3g} N m, load share "
            f"{self.friction[:, FRICTION['load_motor']].mean():.2f}, current lag "
            f"{1e3 * self.current_time_constant_s:.2g} ms, play "
            f"{1e3 * self.backlash_rad:.2g} mrad, mass x{self.mass_scale:.3f}, "
            f"+{self.temperature_rise_K:.1f} K, encoder noise {self.encoder_noise_counts:g} "
            f"counts, non-linearity up to {self.inl_counts.max():.2g} counts; bus: return delay "
            f"{self.return_delay_us:g} us (as the table starts), latency timer "
            f"{self.latency_timer_ms:g} ms, jitter {self.reply_jitter_us:g} us"
        )

    def one(self, i: int) -> "EmulatedServos":
        """The set's servo ``i`` (0-based) alone, as drawn among its ``n``: a set of one, for the
        bench that commissions it before it goes into the robot.

        Raises:
            InvalidConfigError: ``i`` not one of the set's.
        """
        n = len(self.k_Nm_per_A)
        if not 0 <= i < n:
            raise InvalidConfigError(f"servo {i + 1} of a set of {n}: choose 1 to {n}")
        each = ("kt_scale", "friction_scale", "k_Nm_per_A", "resistance_ohm", "friction",
                "inl_counts", "inl_phase")  # fmt: skip
        return replace(self, **{name: getattr(self, name)[i : i + 1] for name in each})

    def departs(self) -> bool:
        """Whether anything here departs from the controller's model."""
        return bool(
            np.any(self.kt_scale != 1)
            or np.any(self.friction_scale != 1)
            or self.current_time_constant_s > 0
            or self.backlash_rad > 0
            or self.encoder_noise_counts > 0
            or np.any(self.inl_counts > 0)
            or self.return_delay_us > 0
            or self.latency_timer_ms > 0
            or self.reply_jitter_us > 0
            or self.rotor_inertia_scale != 1
            or self.mass_scale != 1
            or self.temperature_rise_K != 0
            or self.crc_error_rate > 0
            or self.timeout_rate > 0
        )
