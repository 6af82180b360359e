"""Scenarios: what a run is, as typed dataclasses with their YAML form and their validation.

A :class:`Scenario` is the schema of a run: the robot (:class:`Robot`), Drake's plant, simulator
and visualization settings, the reference, the controller, the tuner, the periods, the robot as
built, the sensor noise, the tool disturbance, the guard, the learner, the servo bus and LCM. It
is read with ``pydrake.common.yaml.yaml_load_typed`` and written with ``yaml_dump_typed``
(:func:`dump_scenario`); files, shipped names and ``--set`` overrides are :mod:`~.scenario_io`'s,
and the values a run derives from a scenario are computed once, by :func:`~.plan.make_plan`.

Choices are tagged unions (``controller: !PdDriver {bandwidth_hz: 20}``), each choice one class
beside what it builds, checking its own fields: the controllers (``LqiDriver`` in
:mod:`~stewart_drake.control.lqi`, ``CrankServoDriver`` in :mod:`~stewart_drake.control.servo`,
``PdDriver``, ``UserController``), the tuners
(:mod:`~stewart_drake.control.tuning`), the references, the learner (``IlcDriver``,
:mod:`~stewart_drake.control.ilc`) and the guard (``GuardConfig``, :mod:`~.guard`); a new choice
is one class added to its union (:data:`ControllerChoice`, :data:`ReferenceChoice`,
:data:`~stewart_drake.control.tuning.TunerChoice`). Sections that configure a thing live beside
it (:class:`~stewart_drake.station.hardware.Hardware`,
:class:`~stewart_drake.station.bus.servos.DynamixelBusConfig`,
:mod:`~stewart_drake.station.station`).

The classes are plain mutable dataclasses with concrete field types (this module must not use
``from __future__ import annotations``: Drake's YAML loader builds each with its defaults, then
sets fields), so validation is a separate step: :meth:`Scenario.validate` names the field to fix.
:class:`Robot`, :class:`~stewart_drake.station.hardware.Motors` and
:class:`~stewart_drake.control.lqi.driver.LqiScalesConfig` are the YAML forms of frozen value
types (same names, units and defaults; lists for tuples), ``build()`` giving the value back
(:class:`~stewart_drake.base.mirrors.ValueMirror`). Where each part lives: docs/scenarios.md.
"""

import dataclasses
import typing
from dataclasses import dataclass, field
from pathlib import Path

from pydrake.common.yaml import yaml_dump_typed, yaml_load, yaml_load_typed
from pydrake.multibody.plant import MultibodyPlantConfig
from pydrake.systems.analysis import SimulatorConfig
from pydrake.visualization import VisualizationConfig

from ..base.checks import as_number, check_multiple
from ..base.errors import (
    InvalidConfigError,
    InvalidGeometryError,
)
from ..base.mirrors import ValueMirror
from ..control.contract import UserController
from ..control.feedforward_tuning import FeedforwardTuning
from ..control.ilc import IlcDriver
from ..control.lqi.driver import LqiDriver
from ..control.lqi.driver import (
    LqiScalesConfig as LqiScalesConfig,  # re-exported: controller.scales
)
from ..control.pd import PdDriver
from ..control.servo.driver import CrankServoDriver
from ..control.servo.goal_stream import ServoPositionDriver
from ..control.tuning import AnnTunerDriver, TunerChoice
from ..plant.sdf import check_rod_model
from ..references.data_collection import DataCollectionReference
from ..references.motion import ReferenceConfig as ReferenceConfig  # re-exported: the choices' base
from ..references.organ.library import OrganMotionReference
from ..references.samples import CsvReference
from ..references.traces import TraceReference
from ..references.trajectories import NamedReference, SineReference
from ..robot.geometry import TEMPERATURE_RANGE_C, StewartGeometry
from ..robot.statics import FEEDFORWARD_MODES
from ..robot.tolerances import RobotTolerances
from ..station.bus.emulator_config import EmulatorConfig
from ..station.bus.servos import DynamixelBusConfig
from ..station.guard import GuardConfig
from ..station.hardware import Hardware
from ..station.lcm_publish import LcmConfig
from ..station.station import SensorNoise, ToolDisturbance
from ..station.surrogate.axis import SurrogateAxis
from .drake_configs import MIN_REALTIME_RATE as MIN_REALTIME_RATE  # re-exported: live
from .drake_configs import validate_plant_config, validate_simulator_config

_GEOMETRY = StewartGeometry()


@dataclass
class Robot(ValueMirror):
    """The robot: every field of :class:`~stewart_drake.robot.geometry.StewartGeometry`, same
    names, units and defaults (docs/reference_geometry.md, Table I; meanings there), lists for
    its tuples, but the motors' reflected inertia, which the scenario's ``hardware.motors`` sets;
    ``build()`` gives the geometry (validated there). The per-leg fields (``pivot_offsets_m``
    ... ``encoder_offsets_rad``, docs/robot.md) are null for the robot as drawn, and a dump
    leaves a null field out. Its lengths hold at ``lengths_at_c`` (degrees C); a run at another
    temperature (the scenario's ``temperature_c``) scales them by ``rod_expansion_per_k`` and
    ``frame_expansion_per_k`` (docs/robot.md, "Temperature")."""

    value_class = StewartGeometry

    base_radius: float = _GEOMETRY.base_radius
    pivot_z: float = _GEOMETRY.pivot_z
    pivot_angles_deg: list[float] = field(default_factory=lambda: list(_GEOMETRY.pivot_angles_deg))
    platform_radius: float = _GEOMETRY.platform_radius
    platform_angles_deg: list[float] = field(
        default_factory=lambda: list(_GEOMETRY.platform_angles_deg)
    )
    crank_angles_deg: list[float] = field(default_factory=lambda: list(_GEOMETRY.crank_angles_deg))
    crank_length: float = _GEOMETRY.crank_length
    rod_length: float = _GEOMETRY.rod_length
    rod_mass: float = _GEOMETRY.rod_mass
    rod_inertia: list[float] = field(default_factory=lambda: list(_GEOMETRY.rod_inertia))
    crank_mass: float = _GEOMETRY.crank_mass
    crank_inertia: list[float] = field(default_factory=lambda: list(_GEOMETRY.crank_inertia))
    platform_mass: float = _GEOMETRY.platform_mass
    platform_inertia: list[float] = field(default_factory=lambda: list(_GEOMETRY.platform_inertia))
    base_mass: float = _GEOMETRY.base_mass
    base_inertia: list[float] = field(default_factory=lambda: list(_GEOMETRY.base_inertia))
    base_plate_radius: float = _GEOMETRY.base_plate_radius
    rod_radius: float = _GEOMETRY.rod_radius
    rod_end_radius: float = _GEOMETRY.rod_end_radius
    platform_plate_radius: float = _GEOMETRY.platform_plate_radius
    gravity: float = _GEOMETRY.gravity
    motor_angle_min_deg: float = _GEOMETRY.motor_angle_min_deg
    motor_angle_max_deg: float = _GEOMETRY.motor_angle_max_deg
    crank_joint_cone_deg: float = _GEOMETRY.crank_joint_cone_deg
    platform_joint_cone_deg: float = _GEOMETRY.platform_joint_cone_deg
    lengths_at_c: float = _GEOMETRY.lengths_at_c
    rod_expansion_per_k: float = _GEOMETRY.rod_expansion_per_k
    frame_expansion_per_k: float = _GEOMETRY.frame_expansion_per_k
    pivot_offsets_m: list[list[float]] | None = None
    platform_offsets_m: list[list[float]] | None = None
    crank_lengths_m: list[float] | None = None
    rod_lengths_m: list[float] | None = None
    shaft_tilts_rad: list[float] | None = None
    encoder_offsets_rad: list[float] | None = None


# -- references ------------------------------------------------------------------------------------

ReferenceChoice = (
    NamedReference
    | CsvReference
    | SineReference
    | DataCollectionReference
    | OrganMotionReference
    | TraceReference
)
ControllerChoice = LqiDriver | CrankServoDriver | ServoPositionDriver | PdDriver | UserController
#: The learners a scenario may choose: from every cycle, or as a function of the reference.
LearningChoice = IlcDriver | FeedforwardTuning


def _choices(union) -> tuple:
    """The classes of a tagged union (``A | B`` -> (A, B))."""
    return typing.get_args(union)


def named_controllers() -> dict:
    """{short name: class} of the controller choices a command can pick by name with their
    defaults (``run --controller``, the evaluation grid), read from :data:`ControllerChoice`."""
    return {kind.short_name: kind for kind in _choices(ControllerChoice) if kind.short_name}


def choice_classes() -> dict:
    """{field: its choice classes} of every tagged union of the scenario (``controller``,
    ``reference``, ``tuner``) and the learner's ``learning``: what dispatching on a choice's
    type would test (``tools/code_shape.py`` counts such tests)."""
    return {
        "controller": _choices(ControllerChoice),
        "reference": _choices(ReferenceChoice),
        "tuner": _choices(TunerChoice),
        "learning": _choices(LearningChoice),
    }


def _default_plant() -> MultibodyPlantConfig:
    # Unsampled output ports: the plant's update is then a discrete update of its state alone,
    # not an unrestricted one that also copies the step's sample (contact results, forces) into
    # an abstract state: the station steps about 1.25 times faster and a closed loop is the
    # same to the bit (the state output is live either way; docs/plant_speed.md).
    return MultibodyPlantConfig(
        time_step=1e-3, discrete_contact_approximation="sap", use_sampled_output_ports=False
    )


@dataclass
class Scenario:
    """Everything that defines one closed-loop run; SI units. Defaults: the paper's experiment
    (eqs. 37-38, 10 s) on the ideal robot (``paper_ideal``; the CLI's: ``paper_hardware``), LQI
    with omega_Q = omega_R = 1. Design of each section: docs/scenarios.md, "The sections".

    Attributes:
        robot: the geometry and inertias (:class:`Robot`).
        plant: Drake's ``MultibodyPlantConfig``; ``time_step`` > 0 and a SAP approximation
            ("sap", "lagged", "similar"); ``use_sampled_output_ports`` false by default.
        simulator, visualization: Drake's ``SimulatorConfig``, ``VisualizationConfig``.
        reference: the path x_d(t): :class:`NamedReference`, :class:`CsvReference`,
            :class:`SineReference`, :class:`DataCollectionReference`,
            :class:`OrganMotionReference` or :class:`TraceReference`.
        feedforward: "gravity" (virtual work), "inverse_dynamics" or "none".
        controller: :class:`LqiDriver`, :class:`CrankServoDriver`, :class:`PdDriver` or
            :class:`UserController`.
        tuner: None (fixed weights), or a choice of :mod:`~stewart_drake.control.tuning`.
        duration_s: simulated time, s. control_period_s: controller period h, s (whole steps).
        log_period_s, state_log_period_s: periods of the signal logs and of the plant's full
            state log (replays, loop closure), s (whole multiples of the plant step).
        sensor_noise: None, or noise on the measured pose and rate (:class:`SensorNoise`).
        robot_as_built: None, or the robot simulated (:class:`Robot`) when it differs from
            ``robot``, which the controller still believes in (docs/calibration.md).
        robot_tolerances: None, or the robot as built drawn about ``robot``
            (:class:`~stewart_drake.robot.tolerances.RobotTolerances`; not with robot_as_built).
        temperature_c: None, or the robot's temperature during the run, degrees C: the robot
            that moves (``robot_as_built``, the drawn one, or ``robot``) holds its lengths at
            it, each scaled from its own ``lengths_at_c`` (docs/robot.md, "Temperature").
            None: every robot at its own ``lengths_at_c``, nothing scaled.
        compensate_temperature: with ``temperature_c``, whether the controller is told it:
            true, its robot (``robot``) is scaled to ``temperature_c`` too; false, it keeps
            ``robot``'s lengths as they were measured (what a warm day costs, uncompensated).
        payload_scale: the simulated platform's mass and inertia over the robot's.
        torque_limit_Nm: torque saturation, N m, or None (with hardware, at most the peak).
        guard: checks before and during the run (:class:`GuardConfig`).
        hardware: None for the ideal robot, or :class:`Hardware` (encoders, servos, delay).
        disturbance: None, or a wrench on the tool tip (:class:`ToolDisturbance`).
        contact: simulate contact between the robot's parts (:mod:`~stewart_drake.robot.parts`).
        rod_model: "bodies" or "distance" (:data:`~stewart_drake.plant.sdf.ROD_MODELS`).
        learning: None, :class:`IlcDriver` or :class:`FeedforwardTuning`.
        bus: None, or the real robot's servos (:class:`DynamixelBusConfig`).
        lcm: None, or LCM channels for status and commands (:class:`LcmConfig`).
        surrogate: None, or the external surrogate's stage beside the platform and the signal
            it follows (:class:`~stewart_drake.station.surrogate.axis.SurrogateAxis`,
            docs/surrogate.md).
        emulator: the servos behind the bus emulator (``robot --emulate``), as a built robot's
            depart from the controller's model
            (:class:`~stewart_drake.station.bus.emulator_config.EmulatorConfig`).
    Raises:
        InvalidConfigError: (``validate``, by every builder and at construction) a field out
            of range, a period not a whole multiple of the one it runs on, a wrong type; named
            by its path (e.g. ``controller.omega_Q``).
        InvalidGeometryError: the robot cannot be built (names the field). MissingFileError: a
            tuner weights file or a CSV reference that does not exist.
    """

    robot: Robot = field(default_factory=Robot)
    plant: MultibodyPlantConfig = field(default_factory=_default_plant)
    simulator: SimulatorConfig = field(default_factory=SimulatorConfig)
    visualization: VisualizationConfig = field(default_factory=VisualizationConfig)
    reference: ReferenceChoice = field(default_factory=NamedReference)
    feedforward: str = "gravity"
    controller: ControllerChoice = field(default_factory=LqiDriver)
    tuner: TunerChoice | None = None
    duration_s: float = 10.0
    control_period_s: float = 1e-3
    log_period_s: float = 1e-3
    state_log_period_s: float = 1e-2
    sensor_noise: SensorNoise | None = None
    robot_as_built: Robot | None = None
    robot_tolerances: RobotTolerances | None = None
    temperature_c: float | None = None
    compensate_temperature: bool = True
    payload_scale: float = 1.0
    torque_limit_Nm: float | None = None
    guard: GuardConfig = field(default_factory=GuardConfig)
    hardware: Hardware | None = None
    disturbance: ToolDisturbance | None = None
    contact: bool = False
    rod_model: str = "bodies"
    learning: LearningChoice | None = None
    bus: DynamixelBusConfig | None = None
    lcm: LcmConfig | None = None
    surrogate: SurrogateAxis | None = None
    emulator: EmulatorConfig = field(default_factory=EmulatorConfig)

    def __post_init__(self):
        self.validate()

    def use_controller(
        self, controller: ControllerChoice, tuner: TunerChoice | None = None
    ) -> "Scenario":
        """Run this scenario with ``controller`` and ``tuner`` (None: fixed weights; the
        paper's ANN tuner comes with its gain switching, :func:`use_paper_tuner`): the one way
        the studies put a controller on a base scenario. Changes the scenario in place and
        returns it (not validated)."""
        self.controller, self.tuner = controller, None
        if isinstance(tuner, AnnTunerDriver):
            return use_paper_tuner(self, tuner)
        self.tuner = tuner
        return self

    def lqi(self, **changes) -> LqiDriver:
        """This scenario's LQI with ``changes`` (e.g. ``omega_Q=10``): its own options when its
        controller is an LqiDriver, the defaults otherwise. The scenario is not changed."""
        base = self.controller if isinstance(self.controller, LqiDriver) else LqiDriver()
        return dataclasses.replace(base, **changes)

    # -- validation --------------------------------------------------------------------------
    def validate(self) -> "Scenario":
        """Check every field before anything is built; returns self.

        Raises:
            InvalidConfigError, InvalidGeometryError, MissingFileError: see the class docstring.
        """
        self._validate_types()
        for name in ("robot", "robot_as_built"):
            robot = getattr(self, name)
            if robot is None:
                continue
            try:
                robot.build()
            except InvalidGeometryError as err:
                raise InvalidGeometryError(f"{name}: {err}") from None
            except TypeError as err:
                raise InvalidConfigError(f"{name}: {err}") from None
        if self.robot_tolerances is not None:
            if self.robot_as_built is not None:
                raise InvalidConfigError(
                    "robot_as_built and robot_tolerances both give the robot as built: set one "
                    "of them to null"
                )
            try:
                self.robot_tolerances.as_built(self.robot.build())
            except InvalidGeometryError as err:
                raise InvalidGeometryError(f"robot_tolerances: {err}") from None
        self._validate_temperature()
        self._validate_periods()
        if self.hardware is not None:
            self.hardware.validate(self.control_period_s)
            if self.sensor_noise is not None:
                raise InvalidConfigError(
                    "sensor_noise is the ideal pose sensor's; on the robot "
                    "as built the encoders are noisy: set "
                    "hardware.encoders.noise_counts instead"
                )
        self.controller.validate(
            self.control_period_s,
            0 if self.hardware is None else self.hardware.computation_delay_periods,
        )
        self.reference.validate()
        if self.surrogate is not None:
            self.surrogate.validate(self.control_period_s)
        if self.feedforward not in FEEDFORWARD_MODES:
            raise InvalidConfigError(
                f"feedforward must be one of {FEEDFORWARD_MODES}, got {self.feedforward!r}"
            )
        if self.tuner is not None:
            self.tuner.validate(self.controller, self.control_period_s)
        if self.sensor_noise is not None:
            self.sensor_noise.validate()
        as_number("payload_scale", self.payload_scale, 0.1, 10.0)
        if not isinstance(self.contact, bool):
            raise InvalidConfigError(f"contact must be true or false, got {self.contact!r}")
        check_rod_model(self.rod_model)
        if self.contact and self.rod_model != "bodies":
            raise InvalidConfigError(
                f"contact needs the rods' collision geometry: set rod_model to 'bodies' "
                f"(got {self.rod_model!r})"
            )
        if self.torque_limit_Nm is not None:
            as_number("torque_limit_Nm", self.torque_limit_Nm, lo=0.0, lo_open=True)
        self.guard.validate()
        check_multiple(
            "guard.check_period_s",
            self.guard.check_period_s,
            "plant.time_step",
            self.plant.time_step,
        )
        if self.disturbance is not None:
            self.disturbance.validate()
        if self.learning is not None:
            self.learning.validate(self.control_period_s)
        if self.bus is not None:
            self.bus.validate(self.control_period_s, self.hardware)
            for name in ("disturbance", "contact", "robot_as_built", "robot_tolerances"):
                if getattr(self, name):
                    raise InvalidConfigError(
                        f"{name} is simulated; on the servo bus the real robot meets the real "
                        f"world: set {name} to {'false' if name == 'contact' else 'null'}"
                    )
        position_loop = self.bus is not None and self.bus.position_loop is not None
        if position_loop != getattr(self.controller, "streams_goals", False):
            raise InvalidConfigError(
                "bus.position_loop runs the servos' own position loop and its controller streams "
                "them goals: set both (controller: !ServoPositionDriver) or neither; got "
                f"controller {type(self.controller).__name__} and bus.position_loop "
                f"{'set' if position_loop else 'null'}"
            )
        loop = None if self.bus is None else self.bus.position_loop
        if self.bus is not None and loop is not None:  # the gains the bus writes fit its table
            from ..station.bus.position_mode import crank_inertia
            from ..station.bus.servos import servo_spec

            spec = servo_spec(self.bus.model, torque_control=False)
            loop.raw_gains(spec, crank_inertia(self.robot.build(), spec.name))
        if self.lcm is not None:
            self.lcm.validate(self.plant.time_step)
        self.emulator.validate()
        return self

    #: The fields that hold a choice or a section, and the classes each may hold.
    _FIELD_TYPES = {
        "robot": (Robot,),
        "plant": (MultibodyPlantConfig,),
        "simulator": (SimulatorConfig,),
        "visualization": (VisualizationConfig,),
        "guard": (GuardConfig,),
        "controller": _choices(ControllerChoice),
        "reference": _choices(ReferenceChoice),
        "tuner": (type(None),) + _choices(TunerChoice),
        "sensor_noise": (type(None), SensorNoise),
        "robot_as_built": (type(None), Robot),
        "robot_tolerances": (type(None), RobotTolerances),
        "hardware": (type(None), Hardware),
        "disturbance": (type(None), ToolDisturbance),
        "learning": (type(None),) + _choices(LearningChoice),
        "bus": (type(None), DynamixelBusConfig),
        "lcm": (type(None), LcmConfig),
        "surrogate": (type(None), SurrogateAxis),
        "emulator": (EmulatorConfig,),
    }

    def _validate_types(self) -> None:
        """Each section and choice is of a class its field takes (a dict, say, is not)."""
        for name, kinds in self._FIELD_TYPES.items():
            value = getattr(self, name)
            if isinstance(value, kinds):
                continue
            names = [k.__name__ for k in kinds if k is not type(None)]
            listed = ", ".join(names[:-1]) + (" or " if len(names) > 1 else "") + names[-1]
            article = "an" if listed[0] in "AEIOU" or listed.startswith("Lqi") else "a"
            raise InvalidConfigError(
                f"{name} must be {'None or ' if type(None) in kinds else ''}{article} {listed}, "
                f"got {type(value).__name__}"
                + (
                    " (a dict: load it with load_scenario, or build the dataclass with "
                    f"{names[0]}(**d))"
                    if isinstance(value, dict)
                    else ""
                )
            )

    def _validate_temperature(self) -> None:
        """``temperature_c`` None or a number in the geometry's range, every robot closing at
        home at it; ``compensate_temperature`` a bool."""
        if not isinstance(self.compensate_temperature, bool):
            raise InvalidConfigError(
                f"compensate_temperature must be true or false, got {self.compensate_temperature!r}"
            )
        if self.temperature_c is None:
            return
        as_number("temperature_c", self.temperature_c, *TEMPERATURE_RANGE_C)
        for name in ("robot", "robot_as_built"):
            robot = getattr(self, name)
            if robot is None:
                continue
            try:
                robot.build().at_temperature(self.temperature_c)
            except InvalidGeometryError as err:
                raise InvalidGeometryError(
                    f"{name} at temperature_c = {self.temperature_c:g} C: {err}"
                ) from None

    def _validate_periods(self) -> None:
        """The run's durations and periods, and Drake's plant and simulator settings."""
        for name in ("duration_s", "control_period_s", "log_period_s", "state_log_period_s"):
            as_number(name, getattr(self, name), lo=0.0, lo_open=True)
        h = as_number("plant.time_step", self.plant.time_step, lo=0.0, lo_open=True)
        if self.plant.discrete_contact_approximation not in ("sap", "lagged", "similar"):
            raise InvalidConfigError(
                f"plant.discrete_contact_approximation "
                f"{self.plant.discrete_contact_approximation!r} does not enforce the ball "
                f"constraints that close the loops; use 'sap', 'lagged' or 'similar'"
            )
        validate_plant_config(self.plant)
        validate_simulator_config(self.simulator)
        check_multiple("control_period_s", self.control_period_s, "plant.time_step", h)
        check_multiple("log_period_s", self.log_period_s, "plant.time_step", h)
        check_multiple("state_log_period_s", self.state_log_period_s, "plant.time_step", h)
        if self.duration_s < 2 * self.log_period_s:
            raise InvalidConfigError(
                f"duration_s ({self.duration_s:g} s) must cover at least two log periods "
                f"({2 * self.log_period_s:g} s): a shorter run has no second sample to measure"
            )

    # -- pickling through YAML (Drake's config structs do not pickle) -------------------------
    def __reduce__(self):
        return (_scenario_from_yaml, (dump_scenario(self),))


def use_paper_tuner(scenario: Scenario, tuner: AnnTunerDriver) -> Scenario:
    """Give ``scenario`` the paper's ANN ``tuner`` and, for an LQI, the paper's gain switching
    (``gain_transfer = "none"``; see :class:`AnnTunerDriver`). Returns the scenario (changed in
    place)."""
    scenario.tuner = tuner
    if isinstance(scenario.controller, LqiDriver):
        scenario.controller = dataclasses.replace(scenario.controller, gain_transfer="none")
    return scenario


def _scenario_from_yaml(text: str) -> Scenario:
    return yaml_load_typed(schema=Scenario, data=text, allow_schema_with_no_yaml=True)


#: Drake's config structs in a Scenario, and the fields of each that a dump always writes (the
#: ones the robot needs whatever Drake's defaults are).
_DRAKE_SECTIONS = {
    "plant": (
        MultibodyPlantConfig,
        ("time_step", "discrete_contact_approximation", "use_sampled_output_ports"),
    ),
    "simulator": (SimulatorConfig, ()),
    "visualization": (VisualizationConfig, ()),
}


def _top_level_blocks(text: str) -> dict:
    """{key: its lines} of a YAML mapping as ``yaml_dump_typed`` writes it (a key at column 0,
    its nested lines indented below it), in order."""
    blocks: dict = {}
    key = None
    for line in text.splitlines(keepends=True):
        if line[:1] not in (" ", "") and ":" in line:
            key = line.split(":", 1)[0]
            blocks[key] = ""
        blocks[key] += line
    return blocks


def _drake_section(name: str, value) -> str:
    """The ``name:`` block of a Drake config struct: the fields that differ from this Drake's
    defaults, plus the ones the robot needs (:data:`_DRAKE_SECTIONS`); "" when none."""
    kind, always = _DRAKE_SECTIONS[name]
    changed = yaml_load(data=yaml_dump_typed(value, defaults=kind())) or {}
    keep = set(changed) | set(always)
    lines = [
        block for key, block in _top_level_blocks(yaml_dump_typed(value)).items() if key in keep
    ]
    return (
        f"{name}:\n"
        + "".join(
            "  " + line if line.strip() else line
            for block in lines
            for line in block.splitlines(True)
        )
        if lines
        else ""
    )


def dump_scenario(scenario: Scenario, path=None) -> str:
    """The scenario as YAML text (``yaml_dump_typed``); also written to ``path`` if given.

    Every field of ours is written; of Drake's config structs (``plant``, ``simulator``,
    ``visualization``) only the fields that differ from the running Drake's defaults, and the
    plant's ``time_step``, ``discrete_contact_approximation`` and ``use_sampled_output_ports``
    (ours differs from Drake's default: a dump must say which it is). Drake adds, renames and
    removes fields of these structs between releases (``SimulatorConfig.publish_every_time_step``
    is gone in 1.58), so a full dump would load only on the Drake that wrote it; this one loads on
    every supported Drake unless the user changed a field that one of them lacks.
    """
    blocks = _top_level_blocks(yaml_dump_typed(scenario))
    for name in _DRAKE_SECTIONS:
        blocks[name] = _drake_section(name, getattr(scenario, name))
    text = "".join(blocks.values())
    if path is not None:
        from ..base.fileio import atomic_write

        atomic_write(Path(path), lambda f: f.write(text.encode()))
    return text
