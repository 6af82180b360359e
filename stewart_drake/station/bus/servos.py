"""The servos on the bus: each model's spec, torque <-> current, and the bus's settings.

A model (:class:`ServoSpec`, :data:`SERVO_SPECS`) is what the bus sees of an X-series servo: its
Model Number, its current unit (or none: the XL430-W250 has no Current Control Mode) and its
stall figures. Torque <-> current: the servo's torque constant at the horn, ``K_t = stall torque
/ stall current`` at 12 V from the e-Manual's specification table (XM540-W270: 10.6 N m at 4.4 A,
2.409 N m/A as the e-Manual prints it; XM430-W350: 4.1 N m at 2.3 A, 1.783 N m/A). The relation
is the e-Manual's linear one at stall; its performance graphs show the torque per ampere falling
somewhat at low currents (friction of the 350 : 1 gear train), which a torque controller meets as
friction. Figures and sources: docs/motor_catalogue.md, docs/hardware_bus.md.

A scenario's ``bus`` (:class:`DynamixelBusConfig`) gives the arguments of
:class:`~.driver.DynamixelBus` (:meth:`~.driver.DynamixelBus.from_config` makes the bus, not
opened) and the loop's deadline policy; :func:`check_bus_settings` checks them without the
vendor's library or a port. Drake's YAML loader reads :class:`DynamixelBusConfig`'s field
annotations: this module must not use ``from __future__ import annotations``.
"""

import math
from dataclasses import dataclass, field
from operator import attrgetter

import numpy as np

from ...base.checks import as_number, check_int
from ...base.errors import InvalidConfigError, StewartError
from ...robot.motor_catalogue import catalogue_motor
from ..hardware import Encoders, Estimator, Hardware, Motors
from ..surrogate.linear_stage import LinearStage
from . import protocol as p
from .position_mode import ServoPositionLoop


@dataclass(frozen=True)
class ServoSpec:
    """One model as the bus sees it.

    Attributes:
        name: the catalogue key (:data:`~stewart_drake.robot.motor_catalogue.MOTOR_CATALOGUE`).
        model_number: what PING returns (Model Number, address 0).
        current_unit_A: one unit of Goal/Present Current, A; None: no Current Control Mode.
        current_limit_max: the Current Limit's largest value (its factory default), units.
        stall_current_A: the current at the catalogue's peak torque, A: the e-Manual's stall
            current at 12 V (X series); twice the continuous current at 24 V (DYNAMIXEL-P, whose
            peak the catalogue estimates as twice the continuous torque).
        source: the e-Manual page.
        table: the family's :class:`~.protocol.ControlTable`.
        counts_per_rev: Present Position counts a turn of the horn.
        velocity_unit_rad_s: one unit of Present Velocity, rad/s.
        position_range: (min, max) counts the Position Limits may take.
        zero_count: the count a crank at its zero reads by default (mid-range).
        baud_rates: the rates the family takes, bps.
    """

    name: str
    model_number: int
    current_unit_A: float | None
    current_limit_max: int
    stall_current_A: float
    source: str
    table: p.ControlTable = p.X_SERIES
    counts_per_rev: int = p.COUNTS_PER_REV
    velocity_unit_rad_s: float = p.VELOCITY_UNIT_RAD_S
    position_range: tuple[int, int] = (0, 4095)
    zero_count: int = 2048
    baud_rates: tuple = ()

    @property
    def rad_per_count(self) -> float:
        """One encoder count, rad."""
        return 2 * math.pi / self.counts_per_rev

    @property
    def amps_per_unit(self) -> float:
        """One unit of Goal/Present Current, A.

        Raises:
            InvalidConfigError: a model without Current Control Mode.
        """
        if self.current_unit_A is None:
            servo_spec(self.name)  # raises, saying why
        return float(self.current_unit_A or 0.0)

    @property
    def stall_torque_Nm(self) -> float:
        """The stall torque at 12 V, N m at the horn (the motor catalogue's peak torque)."""
        return catalogue_motor(self.name).servo.peak_torque_Nm

    @property
    def torque_constant_Nm_per_A(self) -> float:
        """K_t = stall torque / stall current, N m/A at the horn."""
        return self.stall_torque_Nm / self.stall_current_A


_EMANUAL = "https://emanual.robotis.com/docs/en/dxl/x/"
_EMANUAL_P = "https://emanual.robotis.com/docs/en/dxl/p/"
#: Baud rates the X series takes (e-Manual, "Baud Rate(8)"), bps.
BAUD_RATES = (9600, 57600, 115200, 1_000_000, 2_000_000, 3_000_000, 4_000_000, 4_500_000)
#: And the DYNAMIXEL-P series (e-Manual, P series "Baud Rate(8)": up to 10.5 Mbps).
P_BAUD_RATES = BAUD_RATES + (6_000_000, 10_500_000)


def _x_spec(name: str, model_number: int, unit_A: float | None, limit_units: int, stall_A: float):
    """An X-series model: its table, its current unit and limit, its stall current at 12 V, and
    its encoder's counts a turn the motor catalogue's (one source for both)."""
    return ServoSpec(
        name,
        model_number,
        unit_A,
        limit_units,
        stall_A,
        _EMANUAL + name.lower().rsplit("-", 1)[0] + "/",
        counts_per_rev=catalogue_motor(name).encoder_counts_per_rev,
        baud_rates=BAUD_RATES if unit_A is not None else (),
    )


def _p_spec(name: str, model_number: int, limit_mA: int, continuous_A: float):
    """A DYNAMIXEL-P model: its table, 1 mA current units, 0.01 rpm velocity units, its
    encoder's counts a turn (the motor catalogue's: one source for both), Position Limits
    within a turn either side of 0 (zero at 0)."""
    counts = catalogue_motor(name).encoder_counts_per_rev
    half = counts // 2
    return ServoSpec(
        name,
        model_number,
        1e-3,
        limit_mA,
        2.0 * continuous_A,
        _EMANUAL_P + name.lower() + "/",
        table=p.P_SERIES,
        counts_per_rev=counts,
        velocity_unit_rad_s=0.01 * 2 * math.pi / 60,
        position_range=(-half, half),
        zero_count=0,
        baud_rates=P_BAUD_RATES,
    )


#: The servos' model on a bus that names none: the reference robot's (docs/motor_catalogue.md).
DEFAULT_MODEL = "XM430-W350-T"
#: The Temperature Limit written to every servo unless configured, deg C (at most 80).
DEFAULT_TEMPERATURE_LIMIT_C = 70
#: The servos' bus watchdog unless configured, s: the torque goes off when no command reaches
#: them for this long.
DEFAULT_WATCHDOG_S = 0.1

#: The models the bus knows; stall figures at 12 V (e-Manual "Specifications"); the
#: DYNAMIXEL-P's continuous figures at 24 V (:func:`_p_spec`).
SERVO_SPECS: dict[str, ServoSpec] = {
    s.name: s
    for s in (
        _x_spec("XM430-W350-T", 1020, 2.69e-3, 1193, 2.3),
        _x_spec("XM540-W270-T", 1120, 2.69e-3, 2047, 4.4),
        _x_spec("XL430-W250-T", 1060, None, 0, 1.4),
        _p_spec("PM42-010-S260-R", 2100, 1461, 0.6),
        _p_spec("PH42-020-S300-R", 2000, 4500, 1.5),
    )
}


def servo_spec(name: str, *, torque_control: bool = True) -> ServoSpec:
    """The bus description of model ``name``.

    Raises:
        InvalidConfigError: an unknown model (lists the known ones), or, with
            ``torque_control``, a model without Current Control Mode (the XL430-W250).
    """
    if name not in SERVO_SPECS:
        raise InvalidConfigError(
            f"servo model {name!r} is not one the bus knows; choose one of "
            f"{', '.join(SERVO_SPECS)} (docs/hardware_bus.md)"
        )
    spec = SERVO_SPECS[name]
    if torque_control and spec.current_unit_A is None:
        raise InvalidConfigError(
            f"{name} has no Current Control Mode (no current sensing: {spec.source}), so the "
            f"controllers' motor torques cannot be sent to it; use one of "
            + ", ".join(n for n, m in SERVO_SPECS.items() if m.current_unit_A is not None)
        )
    return spec


def torque_to_current_units(tau_Nm, spec: ServoSpec, direction=1):
    """Goal Current (units, rounded to integers) for output torque ``tau_Nm`` (N m at the crank,
    in the crank's sense; ``direction`` -1 for a servo mounted the other way)."""
    unit = spec.amps_per_unit
    return np.rint(np.asarray(tau_Nm) * direction / spec.torque_constant_Nm_per_A / unit).astype(
        np.int64
    )


def current_units_to_torque(units, spec: ServoSpec, direction=1):
    """Output torque, N m in the crank's sense, for a (Goal or Present) Current in units."""
    unit = spec.amps_per_unit
    return np.asarray(units) * unit * spec.torque_constant_Nm_per_A * direction


@dataclass(frozen=True)
class BusSettings:
    """The settings of a bus, checked (:func:`check_bus_settings`): ``spec`` the model's
    :class:`ServoSpec`, ``ids`` (list), ``zero_counts`` and ``directions`` (n,)
    arrays, ``current_limit_units`` and ``watchdog_units`` the raw values written,
    ``position_limits_counts`` (min, max)."""

    spec: ServoSpec
    ids: list
    zero_counts: np.ndarray
    directions: np.ndarray
    current_limit_units: int
    watchdog_units: int
    position_limits_counts: tuple[int, int]


def check_bus_settings(
    baud_rate,
    ids,
    model: str = DEFAULT_MODEL,
    zero_counts=None,
    directions=None,
    current_limit_A: float | None = None,
    temperature_limit_C: int = DEFAULT_TEMPERATURE_LIMIT_C,
    position_limits_counts=None,
    watchdog_s: float = DEFAULT_WATCHDOG_S,
    reply_timeout_s: float | None = None,
    prefix: str = "",
) -> BusSettings:
    """Check the arguments of :class:`~.driver.DynamixelBus` (same names and meanings) without the
    vendor's library or a port; ``prefix`` goes before every name in a message (a scenario's
    ``"bus."``).

    Raises:
        InvalidConfigError: the first argument out of range, named.
    """
    try:
        spec = servo_spec(model)
    except InvalidConfigError as err:
        raise InvalidConfigError(f"{prefix}model: {err}") from None
    try:
        ids = [int(i) for i in ids]
    except (TypeError, ValueError):
        ids = []
    if not ids or len(set(ids)) != len(ids) or not all(0 <= i <= p.MAX_ID for i in ids):
        raise InvalidConfigError(f"{prefix}ids {ids} must be distinct integers in 0..{p.MAX_ID}")
    n = len(ids)
    if baud_rate not in spec.baud_rates:
        raise InvalidConfigError(
            f"{prefix}baud_rate {baud_rate} is not a rate {model} takes; choose one of "
            f"{spec.baud_rates}"
        )
    zero = np.full(n, spec.zero_count) if zero_counts is None else np.asarray(zero_counts)
    sign = np.ones(n) if directions is None else np.asarray(directions, dtype=float)
    if zero.shape != (n,) or sign.shape != (n,) or not np.all(np.abs(sign) == 1):
        raise InvalidConfigError(
            f"{prefix}zero_counts and {prefix}directions must have one entry per id ({n}); "
            f"directions +1 or -1"
        )
    limit_units = spec.current_limit_max
    if current_limit_A is not None:
        if not _finite(current_limit_A):
            raise InvalidConfigError(
                f"{prefix}current_limit_A {current_limit_A} must be a finite number of A"
            )
        limit_units = math.floor(current_limit_A / spec.amps_per_unit)
        if not 0 < limit_units <= spec.current_limit_max:
            raise InvalidConfigError(
                f"{prefix}current_limit_A {current_limit_A} must be in (0, "
                f"{spec.current_limit_max * spec.amps_per_unit:.3g}] A for {model}"
            )
    if not 0 < temperature_limit_C <= 80:
        raise InvalidConfigError(
            f"{prefix}temperature_limit_C {temperature_limit_C} must be in (0, 80] deg C"
        )
    if position_limits_counts is None:
        position_limits_counts = spec.position_range
    lo, hi = (int(c) for c in position_limits_counts)
    bottom, top = spec.position_range
    if not bottom <= lo < hi <= top:
        raise InvalidConfigError(
            f"{prefix}position_limits_counts {position_limits_counts} must be "
            f"{bottom} <= min < max <= {top} for {model}"
        )
    watchdog_units = round(watchdog_s / p.WATCHDOG_UNIT_S) if _finite(watchdog_s) else 0
    if not (1 <= watchdog_units <= 127 and math.isclose(watchdog_units * 0.02, watchdog_s)):
        raise InvalidConfigError(
            f"{prefix}watchdog_s {watchdog_s} must be a multiple of 0.02 s in 0.02..2.54"
        )
    if reply_timeout_s is not None and not 0 < reply_timeout_s <= 5:
        raise InvalidConfigError(f"{prefix}reply_timeout_s {reply_timeout_s} must be in (0, 5] s")
    return BusSettings(spec, ids, zero, sign, int(limit_units), int(watchdog_units), (lo, hi))


def _finite(value) -> bool:
    """Whether ``value`` is a finite real number (not NaN, not inf, not a string)."""
    try:
        return math.isfinite(value)
    except TypeError:
        return False


#: Control periods a loop on the servo bus may run at, s: 100 Hz to 1 kHz.
BUS_CONTROL_PERIODS_S = (1e-3, 1e-2)


#: The share of the servo's no-load speed a surrogate's command may ask for: above it the
#: drive's voltage leaves too little current to follow (the catalogue's linear speed-torque line).
SPEED_MARGIN = 0.8


@dataclass
class SurrogateServoConfig:
    """The surrogate's servo on the robot's bus (a scenario's ``bus.surrogate``; None: no
    surrogate, the bus as before): what is the bus's (the servo's id, its zero and sense, its
    Current Limit, its position loop) and the stage it turns, the part the Diagram's
    ``surrogate.stage`` is too (:class:`~stewart_drake.station.surrogate.linear_stage.LinearStage`:
    by default the catalogue's XM430-W350-T on a GT2 belt, 80 mm a turn; its figures and sources
    there).

    Attributes:
        id: the servo's id, distinct from the cranks' (0..252).
        stage: the part: its servo (a bus model with Current Control Mode that the motor
            catalogue has: ``XM430-W350-T``, ``XM540-W270-T``), travel per turn, stroke and
            carriage mass.
        zero_counts: the servo's Present Position with the carriage at mid-travel, counts
            (multi-turn, a signed 32-bit count).
        direction: +1, or -1 when the counts grow as the carriage goes down ``s``.
        current_limit_A: its Current Limit, A (None: the model's maximum).
        bandwidth_hz: the position loop's bandwidth, Hz (below a tenth of the control rate).
        match_platform_lag: delay the carriage's command by the platform's lag behind its own
            reference, estimated each period from the crank encoders
            (:mod:`~stewart_drake.station.surrogate.lag_matching`), so that the two motions
            keep their recorded timing; False: the carriage follows its trace on the run's
            clock as is.
    """

    id: int = 7
    stage: LinearStage = field(default_factory=LinearStage)
    zero_counts: int = 2048
    direction: int = 1
    current_limit_A: float | None = None
    bandwidth_hz: float = 5.0
    match_platform_lag: bool = True

    def validate(
        self, crank_ids, control_period_s: float | None, prefix: str = "bus.surrogate."
    ) -> None:
        """Check every field (named ``prefix + name``; the stage's ``prefix + "stage." +
        name``) against the cranks' ids and the control period, s (None: the bandwidth only
        > 0).

        Raises:
            InvalidConfigError: the first field out of range, named.
        """
        servo_id = check_int(f"{prefix}id", self.id, 0, p.MAX_ID)
        if servo_id in [int(i) for i in crank_ids]:
            raise InvalidConfigError(
                f"{prefix}id {servo_id} is a crank's ({list(crank_ids)}): give the surrogate's "
                "servo an id of its own"
            )
        if not isinstance(self.stage, LinearStage):
            raise InvalidConfigError(
                f"{prefix}stage must be a LinearStage, got {type(self.stage).__name__}"
            )
        try:
            spec = servo_spec(self.stage.motor)
        except StewartError as err:
            raise InvalidConfigError(f"{prefix}stage.motor: {err}") from None
        self.stage.check(f"{prefix}stage.")
        check_int(f"{prefix}zero_counts", self.zero_counts, -(2**31), 2**31 - 1)
        if self.direction not in (1, -1) or isinstance(self.direction, bool):
            raise InvalidConfigError(f"{prefix}direction must be +1 or -1, got {self.direction!r}")
        if self.current_limit_A is not None:
            top = spec.current_limit_max * spec.amps_per_unit
            as_number(f"{prefix}current_limit_A", self.current_limit_A, 0.0, top, lo_open=True)
        top_hz = None if control_period_s is None else 0.1 / control_period_s
        as_number(f"{prefix}bandwidth_hz", self.bandwidth_hz, 0.0, top_hz, lo_open=True)
        if not isinstance(self.match_platform_lag, bool):
            raise InvalidConfigError(
                f"{prefix}match_platform_lag must be true or false, got {self.match_platform_lag!r}"
            )

    @classmethod
    def beside(cls, model: str) -> "SurrogateServoConfig":
        """The default surrogate for a bus of cranks of ``model``: the default stage (the X
        series' XM430-W350-T on an 80 mm belt) beside X-series cranks; beside DYNAMIXEL-P
        cranks, whose packets address other items, a PM42-010-S260-R on a 120 mm belt (a
        40-tooth GT2 pulley of 3 mm pitch: its 28 rpm at 80 % is 44.8 mm/s), counting about
        zero. What ``robot --emulate`` emulates when the scenario's bus has no surrogate."""
        if servo_spec(model, torque_control=False).table.family == "X":
            return cls()
        stage = LinearStage(motor="PM42-010-S260-R", lead_m_per_rev=0.12)
        return cls(stage=stage, zero_counts=0)

    # --- the stage's figures as the bus uses them --------------------------------------------

    def goal_current_units(self, s_spec: ServoSpec, limit_units: int, tau) -> int:
        """Its servo's Goal Current, in its table's units, for ``tau`` N m at the horn in the
        carriage's sense: the direction applied, clipped to ``limit_units``.

        Raises:
            InvalidConfigError: ``tau`` not finite (nothing is sent).
        """
        if not math.isfinite(tau):
            raise InvalidConfigError(f"the surrogate's torque must be finite, got {tau}")
        units = tau * self.direction / s_spec.torque_constant_Nm_per_A / s_spec.amps_per_unit
        return min(max(round(units), -limit_units), limit_units)

    @property
    def model(self) -> str:
        """The servo's model on the bus: the stage's motor."""
        return self.stage.motor

    @property
    def metres_per_count(self) -> float:
        """One encoder count of the servo as carriage travel, m (the stage's)."""
        return self.stage.metres_per_count

    @property
    def metres_per_rad(self) -> float:
        """Carriage travel per radian of the horn, m/rad (the stage's lead / 2 pi)."""
        return self.stage.metres_per_rad

    def max_speed_m_s(self) -> float:
        """The fastest a command may move the carriage, m/s: :data:`SPEED_MARGIN` of the
        stage's no-load speed (49.1 mm/s for the default belt)."""
        return SPEED_MARGIN * self.stage.no_load_speed_m_s

    def counts_to_m(self, counts):
        """Carriage position, m, for Present Position ``counts``."""
        return (np.asarray(counts, dtype=float) - self.zero_counts) * (
            self.metres_per_count * self.direction
        )

    def m_to_counts(self, s_m):
        """Present Position (counts, rounded) with the carriage at ``s_m``; inverse of
        :meth:`counts_to_m`."""
        return np.rint(
            np.asarray(s_m, dtype=float) * self.direction / self.metres_per_count + self.zero_counts
        ).astype(np.int64)


@dataclass
class DynamixelBusConfig:
    """The robot's servos on a DYNAMIXEL bus: the station drives them instead of a simulated
    plant (:class:`~.station.HardwareStation`; docs/hardware_bus.md). The arguments of
    :class:`~stewart_drake.station.bus.driver.DynamixelBus`, same names, units and
    defaults, and the loop's deadline policy.

    Attributes:
        port: the serial port ("/dev/ttyUSB0", or a bus emulator's pty).
        baud_rate: bps, the servos' setting (one of the driver's ``BAUD_RATES``).
        ids: the six servo ids, in the cranks' order (reference_geometry.md's legs).
        model: the servos' model, a ``SERVO_SPECS`` key with Current Control Mode.
        zero_counts: Present Position of each servo at its crank's zero angle, counts (6).
        directions: +1, or -1 for a servo whose counts grow against its crank's angle (6).
        current_limit_A: the servos' Current Limit, A (None: the model's maximum); the
            torque limit of the run is at most ``K_t`` times it.
        temperature_limit_C: deg C, in (0, 80].
        position_limits_counts: (min, max) written to the servos (Position Control Mode only).
        watchdog_s: the servos' bus watchdog, s (a multiple of 20 ms in 0.02..2.54).
        reply_timeout_s: the least wait for a status packet, s (None: the SDK's, about 34 ms).
        read_retries: a period's sync read sent again this many times (0..10) after a corrupt
            reply before the run ends (a bus's noise; each retry counted in the run's timing);
            a missing reply ends it at once.
        max_deadline_misses: the run stops (``DeadlineMissError``, torque off) at the first
            period missed beyond this many (0: at the first miss).
        surrogate: the external surrogate's stage as a seventh servo on this bus
            (:class:`SurrogateServoConfig`: its id and the stage it turns);
            None (default): no surrogate, six servos.
        position_loop: the servos' own position loop (:class:`~.position_mode.
            ServoPositionLoop`; its controller streams goals); None (default): Current Control
            Mode, the host's current loop.

    The robot as built is then the one with these servos: ``hardware: null`` is derived from
    the bus (:meth:`hardware`); a ``hardware`` given must agree with it (its motors named after
    ``model``, the servos' 4096-count encoders, one period of computation delay), or the
    scenario is refused (:meth:`validate`).
    """

    port: str = "/dev/ttyUSB0"
    baud_rate: int = 1_000_000
    ids: list[int] = field(default_factory=lambda: [1, 2, 3, 4, 5, 6])
    model: str = DEFAULT_MODEL
    zero_counts: list[int] = field(default_factory=lambda: [2048] * 6)
    directions: list[int] = field(default_factory=lambda: [1] * 6)
    current_limit_A: float | None = None
    temperature_limit_C: int = DEFAULT_TEMPERATURE_LIMIT_C
    position_limits_counts: list[int] = field(default_factory=lambda: [0, 4095])
    watchdog_s: float = DEFAULT_WATCHDOG_S
    reply_timeout_s: float | None = None
    read_retries: int = 1
    max_deadline_misses: int = 10
    surrogate: SurrogateServoConfig | None = None
    position_loop: ServoPositionLoop | None = None

    def _settings(self):
        return check_bus_settings(
            self.baud_rate,
            self.ids,
            self.model,
            self.zero_counts,
            self.directions,
            self.current_limit_A,
            self.temperature_limit_C,
            self.position_limits_counts,
            self.watchdog_s,
            self.reply_timeout_s,
            prefix="bus.",
        )

    def validate(self, control_period_s: float, hardware: "Hardware | None") -> None:
        """Check every field (``bus.<name>``), the control period (1 to 10 ms) and that
        ``hardware``, if given, is the robot built with these servos.

        Raises:
            InvalidConfigError: names the field.
        """
        if not isinstance(self.port, str) or not self.port:
            raise InvalidConfigError(f"bus.port must be a serial port path, got {self.port!r}")
        if len(self.ids) != 6:
            raise InvalidConfigError(f"bus.ids must name the six servos, got {self.ids!r}")
        if len(self.position_limits_counts) != 2:
            raise InvalidConfigError(
                f"bus.position_limits_counts must be [min, max], got {self.position_limits_counts}"
            )
        self._settings()
        check_int("bus.max_deadline_misses", self.max_deadline_misses, 0, 10**9)
        check_int("bus.read_retries", self.read_retries, 0, 10)
        lo, hi = BUS_CONTROL_PERIODS_S
        if not lo - 1e-12 <= control_period_s <= hi + 1e-12:
            raise InvalidConfigError(
                f"control_period_s {control_period_s:g} s: a loop on the servo bus runs at "
                f"{lo:g} to {hi:g} s"
            )
        if self.position_loop is not None:
            self.position_loop.validate(servo_spec(self.model, torque_control=False))
        if self.surrogate is not None:
            if not isinstance(self.surrogate, SurrogateServoConfig):
                raise InvalidConfigError(
                    "bus.surrogate must be None or a SurrogateServoConfig, got "
                    f"{type(self.surrogate).__name__}"
                )
            self.surrogate.validate(self.ids, control_period_s)
            cranks = servo_spec(self.model, torque_control=False).table
            if servo_spec(self.surrogate.model, torque_control=False).table != cranks:
                raise InvalidConfigError(
                    f"bus.surrogate.stage.motor {self.surrogate.model} keeps its items at "
                    f"other addresses than the cranks' {self.model} (one sync read and write "
                    f"serve every servo of the bus): give the stage a servo of the "
                    f"{cranks.family} series"
                )
        expected = self.hardware(control_period_s)
        if hardware is None:
            return
        for name in ("motors.name", "encoders.counts_per_rev", "computation_delay_periods"):
            got, want = attrgetter(name)(hardware), attrgetter(name)(expected)
            if got != want:
                raise InvalidConfigError(
                    f"hardware.{name} is {got!r} but the servos of bus.model {self.model} make "
                    f"it {want!r}: set it so, or hardware: null to derive the robot from the bus"
                )

    def hardware(self, control_period_s: float = 1e-3) -> "Hardware":
        """The robot as built with these servos: their catalogue model (friction, gear,
        reflected inertia, peak torque; docs/motor_catalogue.md), their encoders (4096 counts a
        turn on the X series, 526,374 on the PM42-010) without added noise, one control period
        of delay between a measurement and its torque (the driver writes the torque computed
        from a period's reading at the start of the next period,
        :class:`~.bus.station.DynamixelDriver`), and the encoders' rate filter at its default
        corner or, for a long ``control_period_s``, at the Nyquist frequency
        0.5 / control_period_s.

        Raises:
            InvalidConfigError: a model the motor catalogue does not have.
        """
        try:
            servo = catalogue_motor(self.model).servo
        except (StewartError, KeyError) as err:
            raise InvalidConfigError(f"bus.model: {err}") from None
        return Hardware(
            encoders=Encoders(
                counts_per_rev=servo_spec(self.model, torque_control=False).counts_per_rev
            ),
            motors=Motors.from_value(servo),
            estimator=Estimator(
                rate_cutoff_hz=min(Estimator().rate_cutoff_hz, 0.5 / control_period_s)
            ),
            computation_delay_periods=1,
        )

    def torque_limit_Nm(self) -> float | None:
        """``current_limit_A`` as a torque at the crank, N m (None without one)."""
        if self.current_limit_A is None:
            return None
        return self.current_limit_A * servo_spec(self.model).torque_constant_Nm_per_A
