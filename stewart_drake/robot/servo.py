"""The servo at each crank: a brushless motor behind a planetary gearhead, its drive and its
friction.

:class:`ServoModel` holds what the plant and the station need, at the **output shaft** (the crank):
peak torque, reflected rotor inertia, current-loop lag, viscous and Coulomb friction. Its defaults
are one real servo of the class desktop surgical and hexapod platforms use (docs/hardware.md):

* motor: maxon EC 45 flat, 43.5 mm, brushless, 50 W, 24 V winding (maxon catalogue, motor data
  at nominal voltage): torque constant 36.0 mNm/A, nominal (max. continuous) current 2.52 A,
  nominal torque 91.1 mNm, rotor inertia 135 g cm^2, terminal resistance 0.942 Ohm and inductance
  0.363 mH phase to phase, no-load current 238 mA at 6250 rpm;
* gearhead: one planetary stage, 4.3 : 1, efficiency 0.90 (maxon GP 42 C class);
* drive: current limited to twice the nominal current (the usual short-term overload setting).

Derived (each formula in docs/hardware.md): peak output torque 2 x 2.52 A x 36.0 mNm/A x 4.3 x
0.90 = 0.702 N m; reflected inertia 135 g cm^2 x 4.3^2 = 2.50e-4 kg m^2; current-loop time
constant L/R = 0.385 ms (the winding's, an upper bound for the current loop of the drive); the
no-load friction 36.0 mNm/A x 0.238 A = 8.57 mNm at 654 rad/s split half Coulomb, half viscous
(an assumption: the datasheet gives only the sum), reflected to the output: Coulomb 4.28 mNm x 4.3
= 18.4 mN m, viscous (4.28 mNm / 654 rad/s) x 4.3^2 = 1.21e-4 N m s/rad; no-load speed at the
crank 654 rad/s / 4.3 = 152 rad/s.
"""

from __future__ import annotations

from dataclasses import dataclass

from ..base.checks import as_number
from ..base.errors import InvalidConfigError

#: Motor and gearhead data (SI) the defaults are derived from; docs/hardware.md cites each.
EC45_FLAT_50W_24V = {
    "torque_constant": 36.0e-3,
    "nominal_current": 2.52,
    "rotor_inertia": 135e-7,
    "terminal_resistance": 0.942,
    "terminal_inductance": 0.363e-3,
    "no_load_current": 0.238,
    "no_load_speed": 6250 * 2 * 3.141592653589793 / 60,
}
GEAR_RATIO, GEAR_EFFICIENCY, CURRENT_LIMIT_FACTOR = 4.3, 0.90, 2.0
#: Largest gear play a scenario may give, rad (5.7 deg: ten times a Dynamixel's, six times a
#: standard planetary gearhead's; docs/hardware.md).
MAX_BACKLASH_RAD = 0.1
_m = EC45_FLAT_50W_24V
_friction_motor = _m["torque_constant"] * _m["no_load_current"]  # 8.57 mN m at no load


@dataclass(frozen=True)
class ServoModel:
    """One crank's servo at its output shaft; SI units.

    Attributes:
        name: what it is (for reports).
        gear_ratio: motor turns per crank turn.
        rotor_inertia: the motor's rotor inertia, kg m^2 (reflected: times gear_ratio^2).
        peak_torque_Nm: largest output torque the drive delivers (current limit), N m.
        current_time_constant_s: first-order lag of the current (torque) loop, s.
        viscous_damping: viscous friction at the output, N m s/rad (Drake joint damping).
        coulomb_friction_Nm: dry friction at the output, N m (0: none).
        friction_damping: the dry friction's regularization, N m s/rad: below the friction
            torque a joint creeps at (net torque) / friction_damping (Drake's SAP solves it
            implicitly, see :func:`~stewart_drake.plant.plant.add_stewart_plant`).
        no_load_speed_rad_s: the motor's no-load speed through the gearbox, rad/s at the crank
            (6250 rpm / 4.3 = 152 rad/s): the fastest a reference may turn a crank (less a
            margin, :class:`~stewart_drake.robot.limits.MotorLimits`).
        backlash_rad: the gearhead's play at the output shaft, rad, in [0,
            :data:`MAX_BACKLASH_RAD`]: the angle the crank turns, the rotor held, between the two
            flanks (a datasheet's "backlash"); 0: a rigid gear, the plant built without it
            (:mod:`~stewart_drake.plant.backlash`).
    Raises:
        InvalidConfigError: a value that is not finite, negative (or zero for gear_ratio, peak
            torque, friction_damping; above the bound for backlash_rad), naming the field.
    Source: module docstring and docs/hardware.md.
    """

    name: str = "maxon EC 45 flat 50 W (24 V) + planetary gearhead 4.3:1"
    gear_ratio: float = GEAR_RATIO
    rotor_inertia: float = _m["rotor_inertia"]
    peak_torque_Nm: float = (
        CURRENT_LIMIT_FACTOR
        * _m["nominal_current"]
        * _m["torque_constant"]
        * GEAR_RATIO
        * GEAR_EFFICIENCY
    )
    current_time_constant_s: float = _m["terminal_inductance"] / _m["terminal_resistance"]
    viscous_damping: float = 0.5 * _friction_motor / _m["no_load_speed"] * GEAR_RATIO**2
    coulomb_friction_Nm: float = 0.5 * _friction_motor * GEAR_RATIO
    friction_damping: float = 1e4
    no_load_speed_rad_s: float = _m["no_load_speed"] / GEAR_RATIO
    backlash_rad: float = 0.0

    def __post_init__(self):
        for name, positive in (
            ("gear_ratio", True),
            ("rotor_inertia", False),
            ("peak_torque_Nm", True),
            ("current_time_constant_s", False),
            ("viscous_damping", False),
            ("coulomb_friction_Nm", False),
            ("friction_damping", True),
            ("no_load_speed_rad_s", True),
        ):
            object.__setattr__(
                self, name, as_number(f"servo.{name}", getattr(self, name), 0.0, lo_open=positive)
            )
        object.__setattr__(
            self,
            "backlash_rad",
            as_number("servo.backlash_rad", self.backlash_rad, 0.0, MAX_BACKLASH_RAD),
        )
        if not isinstance(self.name, str):
            raise InvalidConfigError(f"servo.name must be a string, got {self.name!r}")

    @property
    def reflected_inertia(self) -> float:
        """Rotor inertia seen at the crank, rotor_inertia x gear_ratio^2, kg m^2."""
        return self.rotor_inertia * self.gear_ratio**2
