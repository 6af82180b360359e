"""The robot as built, as a scenario gives it: the ``hardware`` section (:class:`Hardware`:
encoders, servos, the rate estimator, the computation delay), read by the station
(:class:`~.station.StewartStation`: the torque pipe, the encoders) and the plan
(:func:`~stewart_drake.run.plan.make_plan`: the servo, the limits, the pose estimator).

Drake's YAML loader builds each class with its defaults and then sets fields (a Scenario's
``hardware``), so they are plain mutable dataclasses with concrete field types, and this
module must not use ``from __future__ import annotations``. :class:`Motors` is the YAML form of
the frozen :class:`~stewart_drake.robot.servo.ServoModel` (same names, units and defaults),
with ``build()`` to get it back (:class:`~stewart_drake.base.mirrors.ValueMirror`).
"""

from dataclasses import dataclass, field

import numpy as np

from ..base.checks import MAX_SEED, as_number
from ..base.checks import check_int as _check_int
from ..base.errors import InvalidConfigError, StewartError
from ..base.mirrors import ValueMirror
from ..robot.servo import MAX_BACKLASH_RAD, ServoModel

_SERVO = ServoModel()


@dataclass
class Motors(ValueMirror):
    """The servo at each crank: every field of :class:`~stewart_drake.robot.servo.ServoModel`, same
    names, units and defaults (at the output shaft: gear ratio, rotor inertia kg m^2, peak torque
    N m, current-loop time constant s, viscous N m s/rad and Coulomb N m friction, friction
    regularization N m s/rad, no-load speed rad/s, the gear's play ``backlash_rad`` rad, 0 by
    default); defaults: maxon EC 45 flat 50 W + a 4.3:1 planetary gearhead (docs/hardware.md).
    ``build()`` gives the servo."""

    value_class = ServoModel

    name: str = _SERVO.name
    gear_ratio: float = _SERVO.gear_ratio
    rotor_inertia: float = _SERVO.rotor_inertia
    peak_torque_Nm: float = _SERVO.peak_torque_Nm
    current_time_constant_s: float = _SERVO.current_time_constant_s
    viscous_damping: float = _SERVO.viscous_damping
    coulomb_friction_Nm: float = _SERVO.coulomb_friction_Nm
    friction_damping: float = _SERVO.friction_damping
    no_load_speed_rad_s: float = _SERVO.no_load_speed_rad_s
    backlash_rad: float = _SERVO.backlash_rad


@dataclass
class Encoders:
    """Absolute encoders on the six crank shafts, read at the control period. Encoder i reads
    theta_i + o_i, o_i its zero error (the robot's ``encoder_offsets_rad``, a property of the
    robot as built: :class:`~stewart_drake.robot.geometry.StewartGeometry`), then its noise,
    then whole counts (:class:`~.station.StewartStation`).

    Attributes:
        counts_per_rev: counts per crank revolution (default 2^17, a 17-bit absolute encoder on
            the output shaft, RLS AksIM-2 class); the quantum is 2 pi / counts_per_rev rad.
        noise_counts: standard deviation of white Gaussian noise added before quantization,
            counts (0: quantization only).
        seed: seed of that noise (Drake RandomSource), 0 .. 2^32 - 1.
    """

    counts_per_rev: int = 2**17
    noise_counts: float = 0.0
    seed: int = 0

    @property
    def quantum_rad(self) -> float:
        """One count, rad."""
        return 2 * np.pi / self.counts_per_rev


@dataclass
class Estimator:
    """Pose and rate from the encoders (:class:`~stewart_drake.control.estimator.FkEstimator`).

    Attributes:
        rate_cutoff_hz: corner of the first-order low-pass on the differentiated FK pose, Hz.
        fk_tolerance_counts: Newton stops when every motor angle of the estimate is within this
            many counts of the measurement.
    """

    rate_cutoff_hz: float = 100.0
    fk_tolerance_counts: float = 0.01


@dataclass
class Hardware:
    """The robot as built: encoders, servos, the controller computer's delay.

    Attributes:
        encoders: the only position measurement (:class:`Encoders`).
        motors: the servo at each crank (:class:`Motors`).
        estimator: FK pose and rate estimation from the encoders (:class:`Estimator`).
        computation_delay_periods: control periods between the measurement and the torque it
            produces (0: none).
    """

    encoders: Encoders = field(default_factory=Encoders)
    motors: Motors = field(default_factory=Motors)
    estimator: Estimator = field(default_factory=Estimator)
    computation_delay_periods: int = 1

    def validate(self, control_period_s: float) -> None:
        """Check every field (``hardware.<path>``) for a controller of period
        ``control_period_s``.

        Raises:
            InvalidConfigError: names the field.
        """
        for name, kind in (("encoders", Encoders), ("motors", Motors), ("estimator", Estimator)):
            if not isinstance(getattr(self, name), kind):
                raise InvalidConfigError(
                    f"hardware.{name} must be a {kind.__name__}, got "
                    f"{type(getattr(self, name)).__name__}"
                )
        _check_int("hardware.encoders.counts_per_rev", self.encoders.counts_per_rev, 16, 2**40)
        as_number("hardware.encoders.noise_counts", self.encoders.noise_counts, 0.0, 1e6)
        _check_int("hardware.encoders.seed", self.encoders.seed, 0, MAX_SEED)
        as_number("hardware.motors.backlash_rad", self.motors.backlash_rad, 0.0, MAX_BACKLASH_RAD)
        if self.motors.backlash_rad > 0 and not self.motors.rotor_inertia > 0:
            raise InvalidConfigError(
                "hardware.motors.backlash_rad > 0 needs hardware.motors.rotor_inertia > 0: the "
                "rotor turns inside the play on its own inertia"
            )
        try:
            self.motors.build()
        except (StewartError, TypeError) as err:
            raise InvalidConfigError(f"hardware.motors: {err}") from None
        as_number(
            "hardware.estimator.rate_cutoff_hz",
            self.estimator.rate_cutoff_hz,
            0.0,
            0.5 / control_period_s,
            lo_open=True,
        )
        as_number(
            "hardware.estimator.fk_tolerance_counts",
            self.estimator.fk_tolerance_counts,
            0.0,
            1.0,
            lo_open=True,
        )
        _check_int("hardware.computation_delay_periods", self.computation_delay_periods, 0, 100)
