"""A 1-DoF linear stage on paper: a catalogue servo turning a transmission (a toothed belt, a
lead screw) that moves a carriage; the external surrogate's stage, one part for both of its
controllers (the Diagram's axis, :mod:`stewart_drake.station.surrogate.stage`, and the servo
bus's seventh servo, :mod:`stewart_drake.station.surrogate.bus_servo`).

:class:`LinearStage` holds what the part is: the servo, the carriage's travel per turn of the
servo's horn, the stroke, the carriage's mass and the transmission's efficiency. What follows
from the motor catalogue (:mod:`.motor_catalogue`) is derived, never set apart: the no-load
speed, the continuous force and one encoder count at the carriage, the servo's reflected rotor
inertia and viscous friction through the transmission.

The default is a cited part: a ROBOTIS Dynamixel XM430-W350-T (the catalogue's fastest X servo
with Current Control Mode: 46 rpm, 4.1 N m stall, 0.82 N m continuous, 4096 counts a turn;
docs/motor_catalogue.md) on a GT2 timing belt (2 mm tooth pitch) over a 40-tooth pulley, 80 mm
of travel a turn: 61.3 mm/s at no load, 58 N continuous at an efficiency of 0.9, 19.5 um a
count. The travel (100 mm: IntERAct's respiratory traces span at most 56 mm), the carriage's
mass (0.3 kg: a carriage with a 3D-printed block) and the efficiency (toothed belts are quoted at
0.9-0.98: the low end) are estimates. docs/surrogate.md, "The stage".

Drake's YAML loader reads :class:`LinearStage`'s field annotations (a scenario's
``surrogate.stage`` and ``bus.surrogate.stage``): this module must not use
``from __future__ import annotations``.
"""

import math
from dataclasses import dataclass

from ...base.checks import as_number
from ...base.errors import InvalidConfigError
from ...robot.motor_catalogue import CatalogueMotor, catalogue_motor

#: The servo of the default stage (docs/motor_catalogue.md gives its datasheet's figures).
DEFAULT_MOTOR = "XM430-W350-T"
#: GT2 timing belt's tooth pitch, m (Gates' 2 mm GT profile).
GT2_PITCH_M = 2e-3
#: Teeth of the default pulley: 40 x 2 mm = 80 mm of belt a turn, so that the XM430-W350's 46 rpm
#: give 61.3 mm/s, above every respiratory trace of IntERAct's LARK and LIGHT SABR sets but one
#: (LIGHT SABR "1.Mean_Motion_resp": 53 mm/s in its first 30 s, 66 mm/s at 101 s, as the trace
#: reader's spline has it; 61 mm/s between its raw 5 Hz samples there).
PULLEY_TEETH = 40
#: Travel of the carriage per turn of the horn on the default belt and pulley, m.
DEFAULT_LEAD_M_PER_REV = PULLEY_TEETH * GT2_PITCH_M
#: Belt drive's efficiency: not published for this part; toothed belts are quoted at 0.9-0.98,
#: the low end taken (estimate).
BELT_EFFICIENCY = 0.9
#: Travel of the default stage, m: IntERAct's respiratory traces span at most 56 mm.
DEFAULT_TRAVEL_M = 0.1
#: The carriage and the surrogate block on it, kg (estimate: a 3D-printed block on a carriage).
DEFAULT_CARRIAGE_KG = 0.3


@dataclass
class LinearStage:
    """The stage's mechanical part; SI units. Defaults: the cited belt stage (module docstring).

    Attributes:
        motor: the servo, a key of :data:`~stewart_drake.robot.motor_catalogue.MOTOR_CATALOGUE`.
        lead_m_per_rev: the carriage's travel per turn of the servo's horn, m (a belt: the
            pulley's teeth times the belt's pitch; a screw: its lead).
        travel_m: the carriage's whole stroke, m, centred on its zero (``s`` in
            +-travel_m / 2).
        carriage_mass_kg: the carriage and what it carries (the surrogate's block, a marker), kg.
        efficiency: the transmission's, in (0, 1]: the force at the carriage is the horn's
            torque times it over ``lead_m_per_rev / 2 pi``.
    """

    motor: str = DEFAULT_MOTOR
    lead_m_per_rev: float = DEFAULT_LEAD_M_PER_REV
    travel_m: float = DEFAULT_TRAVEL_M
    carriage_mass_kg: float = DEFAULT_CARRIAGE_KG
    efficiency: float = BELT_EFFICIENCY

    def check(self, prefix: str = "stage.") -> "LinearStage":
        """Check every field, each named ``prefix + field`` in a message.

        Raises:
            InvalidConfigError: a motor the catalogue does not have, or a field out of range
                (lead in (0, 0.5] m, travel in (0, 1] m, mass in [0, 50] kg, efficiency in
                (0, 1]).
        """
        try:
            catalogue_motor(self.motor)
        except InvalidConfigError as err:
            raise InvalidConfigError(f"{prefix}motor: {err}") from None
        as_number(prefix + "lead_m_per_rev", self.lead_m_per_rev, 0.0, 0.5, lo_open=True)
        as_number(prefix + "travel_m", self.travel_m, 0.0, 1.0, lo_open=True)
        as_number(prefix + "carriage_mass_kg", self.carriage_mass_kg, 0.0, 50.0)
        as_number(prefix + "efficiency", self.efficiency, 0.0, 1.0, lo_open=True)
        return self

    # -- derived from the catalogue -----------------------------------------------------------
    @property
    def catalogue(self) -> CatalogueMotor:
        """The servo's catalogue entry (raises InvalidConfigError for an unknown motor)."""
        return catalogue_motor(self.motor)

    @property
    def metres_per_rad(self) -> float:
        """The carriage's travel per radian of the horn, m/rad: lead / 2 pi."""
        return self.lead_m_per_rev / (2 * math.pi)

    @property
    def metres_per_count(self) -> float:
        """One count of the servo's encoder as the carriage's travel, m: lead / counts a turn."""
        return self.lead_m_per_rev / self.catalogue.encoder_counts_per_rev

    @property
    def no_load_speed_m_s(self) -> float:
        """The servo's no-load speed at the carriage, m/s."""
        return self.catalogue.servo.no_load_speed_rad_s * self.metres_per_rad

    @property
    def continuous_force_N(self) -> float:
        """The servo's continuous torque at the carriage through the transmission's
        efficiency, N."""
        return self.catalogue.continuous_torque_Nm * self.efficiency / self.metres_per_rad

    def inertia_at_horn_kg_m2(self) -> float:
        """J at the horn: the rotor's inertia through its gearhead (J_rotor N^2) plus the
        carriage's mass through the transmission (m (lead / 2 pi)^2), kg m^2."""
        servo = self.catalogue.servo
        return (
            servo.rotor_inertia * servo.gear_ratio**2
            + self.carriage_mass_kg * self.metres_per_rad**2
        )

    def moving_mass_kg(self) -> float:
        """The same inertia at the carriage, kg: J at the horn / (lead / 2 pi)^2 (the carriage
        plus the rotor's reflected inertia, 77 kg of it for the default part)."""
        return self.inertia_at_horn_kg_m2() / self.metres_per_rad**2

    def viscous_N_s_per_m(self) -> float:
        """The servo's viscous friction at the carriage, N s/m: b_horn / (lead / 2 pi)^2."""
        return self.catalogue.servo.viscous_damping / self.metres_per_rad**2
