"""The external surrogate's stage as a seventh servo on the robot's bus: a DYNAMIXEL turning the
stage whose carriage carries the chest marker, driven in the cranks' period.

:class:`~..bus.servos.SurrogateServoConfig` (a scenario's ``bus.surrogate``) says which servo it is
and the stage it turns (:class:`~stewart_drake.station.surrogate.linear_stage.LinearStage`, the part
the Diagram's stage is too); :class:`SurrogateDrive` is its controller on the loop's computer, as
the cranks' controllers are: each period it turns the carriage's commanded position, rate and
acceleration (the session gives them on the run's clock) and the last reading of the servo's encoder
into a torque at the horn, which the driver sends as the seventh row of the period's one sync write
of Goal Current (:meth:`~..bus.driver.DynamixelBus.write_torques`); the servo's encoder comes back
as the seventh status of the period's one sync read. Like the cranks it is in Current Control Mode
(a sync write writes one address for all its servos: the cranks' Goal Current).

The carriage's position ``s`` (m, 0 at mid-travel) from the servo's Present Position:
``s = (counts - zero_counts) * lead_m_per_rev / counts_per_rev * direction`` (4096 a turn on
the X series).

The controller (:meth:`SurrogateDrive.torque`), in the horn's angle theta = 2 pi s / lead: tau = J
a_c + b v_c + c tanh(v_c / v_eps) + K_p (theta_c - theta_p) + K_d (v_c - v_m), where J is the
rotor's reflected inertia plus the carriage's mass through the transmission (m (lead / 2 pi)^2:
:meth:`~stewart_drake.station.surrogate.linear_stage.LinearStage.inertia_at_horn_kg_m2`), b and c
the servo's viscous and dry friction (the motor catalogue's figures), theta_p the reading predicted
one period on (theta_m + h v_m: the torque acts a period after the reading it came from, as the
cranks' do), K_p = J w^2 and K_d = 2 J w with w = 2 pi ``bandwidth_hz`` (a critically damped double
integrator). The dry friction's feed-forward fades through a commanded reversal over v_eps =
max(|alpha_c| h, v_min): the rate the command itself changes by in one period (the commanded rate is
exact, not measured, so the fade need only keep the torque from stepping inside the period of the
reversal), v_min a tenth of an encoder count a period. A fade of one count a period (0.15 rad/s)
left the friction under-compensated over a breath's slow turns on a belt, where the horn turns
slower for the same carriage speed: the carriage lagged its command by 1.3-1.7 ms on IntERAct's
pairs (0.1-0.2 ms on a 50 mm lead). The torque is in the carriage's sense (positive drives ``s``
up). The weight of a vertical carriage (m g lead / 2 pi: 37 mN m for 0.3 kg on the default belt's 80
mm a turn, 0.9 % of the servo's stall torque) is left to the position loop.

The stage is the cited part by default (the catalogue's XM430-W350-T on a GT2 belt over a
40-tooth pulley: 80 mm a turn, 61.3 mm/s at no load). A command may ask for
:data:`~..bus.servos.SPEED_MARGIN` (80 %) of the no-load speed, 49.1 mm/s, which
:func:`check_surrogate_path` holds a path to before anything is powered, with the travel
(100 mm). docs/robot.md, "The surrogate on the bus".

The stage's settings, :class:`~..bus.servos.SurrogateServoConfig`, are with the bus's in
:mod:`.servos` (Drake's YAML loader reads them there).
"""

import math

import numpy as np

from ...base.errors import InvalidConfigError
from ..bus.servos import SPEED_MARGIN, SurrogateServoConfig


def check_surrogate_path(config: SurrogateServoConfig, s, v, what: str = "the surrogate") -> None:
    """Refuse a carriage command outside the stage's travel or faster than it can follow,
    before anything is powered.

    Args:
        config: the stage. s, v: (n,) commanded positions, m, and rates, m/s, at sampled times.
        what: how the messages name the command.
    Raises:
        InvalidConfigError: not finite, out of the travel or over the speed (each named with
            its figure and the limit).
    """
    s, v = np.asarray(s, dtype=float), np.asarray(v, dtype=float)
    if not (np.all(np.isfinite(s)) and np.all(np.isfinite(v))):
        raise InvalidConfigError(f"{what}: the commanded carriage position is not finite")
    stage = config.stage
    half = 0.5 * stage.travel_m
    if s.size and np.max(np.abs(s)) > half:
        raise InvalidConfigError(
            f"{what} asks the carriage for {1e3 * s[np.argmax(np.abs(s))]:+.1f} mm, outside the "
            f"stage's travel of +-{1e3 * half:g} mm (bus.surrogate.stage.travel_m)"
        )
    top = config.max_speed_m_s()
    if v.size and np.max(np.abs(v)) > top:
        raise InvalidConfigError(
            f"{what} asks the carriage for {1e3 * np.max(np.abs(v)):.1f} mm/s, over the "
            f"{1e3 * top:.1f} mm/s the stage allows ({100 * SPEED_MARGIN:g} % of the "
            f"{stage.motor}'s no-load speed at {1e3 * stage.lead_m_per_rev:g} mm a turn): a "
            "longer bus.surrogate.stage.lead_m_per_rev, or a slower trace"
        )


class SurrogateDrive:
    """The surrogate's position loop on the loop's computer (module docstring), for
    :class:`~..bus.station.DynamixelDriver`.

    Args:
        config: the stage. period_s: the control period, s.
    Attributes:
        command: ``command(t) -> (s, v, a)`` the carriage's position m, rate m/s and
            acceleration m/s^2 at the run's time t (floats); None: hold where it was first read.
        lag_match: None, or a
            :class:`~stewart_drake.station.surrogate.lag_matching.PlatformLagMatch`: the
            command is then taken at ``t - lag_match.delay_s``, the platform's lag estimated
            from its encoders (:meth:`platform_reading`), so that the carriage is as late on
            its trace as the platform is on its own.
        held: (s m, v m/s) of the last reading.
    """

    def __init__(self, config: SurrogateServoConfig, period_s: float):
        self.config, self.period_s = config, float(period_s)
        servo = config.stage.catalogue.servo
        self.J = config.stage.inertia_at_horn_kg_m2()
        self.viscous, self.coulomb = servo.viscous_damping, servo.coulomb_friction_Nm
        w = 2 * math.pi * config.bandwidth_hz
        self.kp, self.kd = self.J * w * w, 2.0 * self.J * w
        #: The least rate over which the dry friction's feed-forward fades (a tenth of a count a
        #: period), rad/s.
        counts = config.stage.catalogue.encoder_counts_per_rev
        self.v_eps = 0.1 * 2 * math.pi / counts / self.period_s
        self.command = None
        #: The carriage's reference on the run's clock before any delay (an object with
        #: ``evaluate(t) -> (s, v, a)``; the session sets it with ``command``), or None.
        self.reference = None
        self.lag_match = None
        self.held = (math.nan, math.nan)
        self._hold = math.nan

    def reading(self, s_m: float, v_m_s: float) -> None:
        """Hold a reading of the carriage (the first one is where a missing command holds)."""
        self.held = (float(s_m), float(v_m_s))
        if self._hold != self._hold:
            self._hold = float(s_m)

    def platform_reading(self, t: float, pose) -> None:
        """The platform's pose measured for run time ``t`` (s; (6,) rad and m), for lag
        matching (nothing without it)."""
        if self.lag_match is not None:
            self.lag_match.update(t, pose)

    @property
    def delay_s(self) -> float:
        """The delay the command is taken with, s (0 without lag matching)."""
        return self.lag_match.delay_s if self.lag_match is not None else 0.0

    def commanded(self, t: float) -> tuple[float, float, float]:
        """(s m, v m/s, a m/s^2) commanded at run time ``t``: the command at ``t`` less the
        lag matching's delay."""
        if self.command is None:
            return self._hold, 0.0, 0.0
        s, v, a = self.command(t - self.delay_s)
        return float(s), float(v), float(a)

    def torque(self, t: float) -> tuple[float, float]:
        """(the horn's torque for the period starting at ``t``, N m; the position commanded,
        m) from the held reading (one period old); (0, NaN) while nothing was read."""
        s_m, v_m = self.held
        if s_m != s_m:
            return 0.0, math.nan
        s_c, v_c, a_c = self.commanded(t)
        r = self.config.metres_per_rad
        theta_m, w_m = s_m / r, v_m / r
        theta_c, w_c, alpha_c = s_c / r, v_c / r, a_c / r
        theta_p = theta_m + self.period_s * w_m
        tau = (
            self.J * alpha_c
            + self.viscous * w_c
            + self.coulomb * math.tanh(w_c / max(abs(alpha_c) * self.period_s, self.v_eps))
            + self.kp * (theta_c - theta_p)
            + self.kd * (w_c - w_m)
        )
        return tau, s_c


def surrogate_settings(surrogate: SurrogateServoConfig, spec, ids, settings: dict):
    """The surrogate's servo on the cranks' bus, after them: (its ServoSpec, its Current Limit
    in the table's units, its settings), the settings the cranks' ``settings`` with its own
    Current Limit and its factory position range (multi-turn in Current Control Mode: the limits
    do not apply). Its model must be of the cranks' series (``spec``): one sync read and write
    serve every servo.

    Raises:
        InvalidConfigError: a surrogate out of range, or a servo of another series.
    """
    from ..bus.position_mode import GAIN_NAMES as POSITION_GAIN_NAMES
    from ..bus.protocol import CURRENT_CONTROL_MODE
    from ..bus.servos import servo_spec

    table = spec.table
    surrogate.validate(ids, None, prefix="surrogate.")
    s_spec = servo_spec(surrogate.model)
    if s_spec.table != table:
        raise InvalidConfigError(
            f"surrogate.stage.motor {s_spec.name} keeps its items at other addresses "
            f"than the cranks' {spec.name}: one sync read and write serve every "
            f"servo of the bus; give the stage a servo of the {table.family} series"
        )
    units = s_spec.current_limit_max
    if surrogate.current_limit_A is not None:
        units = min(units, int(surrogate.current_limit_A / s_spec.amps_per_unit))
    own = {k: v for k, v in settings.items() if k not in POSITION_GAIN_NAMES}
    return (
        s_spec,
        int(units),
        own
        | {
            # the cranks' servos may run their own position loop; the stage is torque-driven
            "Operating Mode": (table.operating_mode, CURRENT_CONTROL_MODE),
            "Current Limit": (table.current_limit, int(units)),
            "Min Position Limit": (table.min_position_limit, s_spec.position_range[0]),
            "Max Position Limit": (table.max_position_limit, s_spec.position_range[1]),
        },
    )
