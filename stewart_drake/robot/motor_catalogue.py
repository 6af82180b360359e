"""A small catalogue of real servos and gearmotors a design may put at the cranks.

Each entry is a :class:`CatalogueMotor`: the :class:`~.servo.ServoModel` the plant and the station
take (at the output shaft), plus what a designer compares motors by: continuous torque, encoder
resolution, mass and price. The figures and their sources (datasheet pages, and for each figure a
vendor does not publish the estimate and its basis) are in docs/motor_catalogue.md; a test checks
that every entry is listed there.

Dynamixel X servos (ROBOTIS e-Manual, at the recommended 12.0 V): peak torque = the stall torque;
continuous torque = 1/5 of it (the e-Manual's guidance for stable motion, not a thermal rating);
no-load speed at the horn; encoder 4096 counts per output turn (12-bit magnetic encoder on the
output shaft). Rotor inertia, friction and the current loop's lag are **not published**: the
rotor inertia is that of a coreless motor of the size the case holds (maxon's catalogue), the
dry friction 5 % of the stall torque and the viscous friction as much again at the no-load speed,
the current loop 1 ms (the firmware's control cycle is not published; docs/motor_catalogue.md).

DYNAMIXEL-P servos (ROBOTIS e-Manual, at 24 V): continuous torque and current, no-load speed,
gear ratio and resolution as the specification table gives them; the encoder counts its
motor's turns (2048 or 2000 a motor turn times the gear ratio: 526,374 to 1,003,846 counts an
output turn), so the gear's play (< 0.1 deg, the table) is on the crank's side of it. Not
published: the stall torque (the performance graph's largest, estimated here as twice the
continuous torque), the rotor's inertia (the case's coreless or BLDC maxon motor) and the
friction (5 % of the peak, as the X series'); docs/motor_catalogue.md.

The maxon entry is the reference robot's servo, :class:`~.servo.ServoModel`'s defaults exactly.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from ..base.errors import InvalidConfigError
from .servo import EC45_FLAT_50W_24V, GEAR_RATIO, ServoModel

#: Dynamixel's dry friction (output), a fraction of the stall torque: not published (estimate).
DYNAMIXEL_COULOMB_FRACTION = 0.05
#: Dynamixel's current (torque) loop lag, s: not published (estimate).
DYNAMIXEL_CURRENT_TIME_CONSTANT_S = 1e-3
#: Continuous torque as a fraction of the stall torque (ROBOTIS e-Manual's guidance).
DYNAMIXEL_CONTINUOUS_FRACTION = 0.2
#: One g cm^2 in kg m^2.
G_CM2 = 1e-7
#: DYNAMIXEL-P's peak torque as a multiple of its continuous torque: not published (estimate).
DYNAMIXEL_P_PEAK_FACTOR = 2.0


@dataclass(frozen=True)
class CatalogueMotor:
    """One motor of the catalogue; SI units.

    Attributes:
        name: the catalogue key (the vendor's part number), as a design names it.
        servo: the :class:`~.servo.ServoModel` at the output shaft (peak torque N m, no-load
            speed rad/s, gear ratio, rotor inertia kg m^2, friction, current-loop lag).
        continuous_torque_Nm: torque the motor may give indefinitely, N m at the output.
        encoder_counts_per_rev: position counts per output turn.
        mass_kg: one motor (with its gearhead), kg.
        price_usd: one motor (with its gearhead; the maxon's drive not included), US dollars.
    """

    name: str
    servo: ServoModel
    continuous_torque_Nm: float
    encoder_counts_per_rev: int
    mass_kg: float
    price_usd: float


def _robotis(
    label: str,
    name: str,
    peak_torque_Nm: float,
    continuous_torque_Nm: float,
    no_load_rpm: float,
    gear_ratio: float,
    counts_per_rev: int,
    rotor_inertia_g_cm2: float,
    mass_g: float,
    price_usd: float,
) -> CatalogueMotor:
    """A ROBOTIS servo (``label``: its family and voltage) from its figures: the dry friction
    :data:`DYNAMIXEL_COULOMB_FRACTION` of the peak torque and the viscous as much again at the
    no-load speed, the current loop :data:`DYNAMIXEL_CURRENT_TIME_CONSTANT_S` (estimates: the
    module docstring)."""
    no_load = no_load_rpm * 2 * math.pi / 60
    coulomb = DYNAMIXEL_COULOMB_FRACTION * peak_torque_Nm
    return CatalogueMotor(
        name=name,
        servo=ServoModel(
            name=f"ROBOTIS {label}",
            gear_ratio=gear_ratio,
            rotor_inertia=rotor_inertia_g_cm2 * G_CM2,
            peak_torque_Nm=peak_torque_Nm,
            current_time_constant_s=DYNAMIXEL_CURRENT_TIME_CONSTANT_S,
            viscous_damping=coulomb / no_load,
            coulomb_friction_Nm=coulomb,
            no_load_speed_rad_s=no_load,
        ),
        continuous_torque_Nm=continuous_torque_Nm,
        encoder_counts_per_rev=counts_per_rev,
        mass_kg=mass_g * 1e-3,
        price_usd=price_usd,
    )


def _dynamixel(name, stall_torque_Nm, no_load_rpm, gear_ratio, rotor_g_cm2, mass_g, price_usd):
    """A Dynamixel X servo from its datasheet figures at 12 V: its stall torque the peak, a
    fifth of it continuous, 4096 counts a turn (derivations: module docstring)."""
    continuous = DYNAMIXEL_CONTINUOUS_FRACTION * stall_torque_Nm
    return _robotis(
        f"Dynamixel {name} (12 V)", name, stall_torque_Nm, continuous, no_load_rpm, gear_ratio,
        4096, rotor_g_cm2, mass_g, price_usd,
    )  # fmt: skip


def _dynamixel_p(name, continuous_Nm, no_load_rpm, gear_ratio, counts, rotor_g_cm2, mass_g, usd):
    """A DYNAMIXEL-P servo from its datasheet figures at 24 V: its peak torque
    :data:`DYNAMIXEL_P_PEAK_FACTOR` times the continuous (module docstring)."""
    peak = DYNAMIXEL_P_PEAK_FACTOR * continuous_Nm
    return _robotis(
        f"DYNAMIXEL-P {name} (24 V)", name, peak, continuous_Nm, no_load_rpm, gear_ratio,
        counts, rotor_g_cm2, mass_g, usd,
    )  # fmt: skip


_EC45 = EC45_FLAT_50W_24V

#: {name: motor}, cheapest first. Sources and estimates: docs/motor_catalogue.md.
MOTOR_CATALOGUE: dict[str, CatalogueMotor] = {
    m.name: m
    for m in (
        _dynamixel("XL430-W250-T", 1.5, 61.0, 258.5, 1.0, 57.2, 50.0),
        _dynamixel("XH430-W350-T", 3.4, 30.0, 353.5, 1.0, 82.0, 250.0),
        _dynamixel("XM430-W350-T", 4.1, 46.0, 353.5, 1.0, 82.0, 290.0),
        _dynamixel("XM540-W270-T", 10.6, 30.0, 272.5, 5.0, 165.0, 495.0),
        CatalogueMotor(
            name="maxon-EC45flat-50W-GP42C-4.3",
            servo=ServoModel(),
            # The winding's nominal (max. continuous) torque through the gearhead.
            continuous_torque_Nm=_EC45["torque_constant"]
            * _EC45["nominal_current"]
            * GEAR_RATIO
            * 0.90,
            # The scenario's default encoder: 17 bits absolute on the crank.
            encoder_counts_per_rev=2**17,
            mass_kg=0.110 + 0.260,
            price_usd=600.0,
        ),
        _dynamixel_p("PM42-010-S260-R", 1.7, 28.0, 257.019, 526_374, 2.0, 270.0, 1400.0),
        _dynamixel_p("PH42-020-S300-R", 5.1, 32.7, 303.75, 607_500, 3.0, 340.0, 1900.0),
        _dynamixel_p("PH54-100-S500-R", 25.3, 33.3, 501.923, 1_003_846, 24.0, 740.0, 2900.0),
    )
}

#: The reference robot's motor (:class:`~.servo.ServoModel`'s defaults).
REFERENCE_MOTOR = "maxon-EC45flat-50W-GP42C-4.3"


def catalogue_motor(name: str) -> CatalogueMotor:
    """The catalogue's motor ``name``.

    Raises:
        InvalidConfigError: no such motor (lists the names).
    """
    if not isinstance(name, str) or name not in MOTOR_CATALOGUE:
        raise InvalidConfigError(
            f"motor {name!r} is not in the catalogue; choose one of "
            f"{', '.join(MOTOR_CATALOGUE)} (docs/motor_catalogue.md)"
        )
    return MOTOR_CATALOGUE[name]
