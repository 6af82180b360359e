"""The controller contract: what any controller of the Diagram declares, and what it is given.

A controller is a Drake system (a ``LeafSystem``, or a ``Diagram`` exporting the ports, as
:class:`~stewart_drake.control.lqi.controller.LqiDiagram` does) made by a **factory**
``factory(context) -> System`` that receives a :class:`ControllerContext`.
:func:`~stewart_drake.run.diagram.make_stewart_diagram` connects its ports **by name**;
only ``x_d`` and ``T`` are required, every other port is connected when the controller declares
it.

Input ports (vectors, SI units):
    ``x_d`` (18,): required; reference pose [phi, theta, psi, X, Y, Z] (rad, m), its rate and
        acceleration, evaluated at the sample time plus half a plant step.
    ``x`` (12,): pose estimate and rate: on the ideal robot the station's ``platform_state``
        (plus sensor noise).
    ``motor_angle`` (6,) rad, ``motor_rate`` (6,) rad/s, ``motor_torque_applied`` (6,) N m:
        the station's outputs of those names.
    ``T_ff`` (6,): feed-forward motor torques along the reference, N m
        (``Scenario.feedforward``).
    ``omega`` (2,): [omega_Q, omega_R] of paper eq. 27, the scenario's or the tuner's.
Output ports:
    ``T`` (6,): required; motor torque command, N m, held between updates.
    ``status`` (k,): numbers for the metrics, named by the controller's ``status_names`` (a
        tuple of k str; the LQI's are :data:`LQI_STATUS_NAMES`).
    ``e_bar`` (6,): the pose error the last update acted on (the tuner's density features).
    ``integral`` (6,): integral states (the LQI's z, eq. 23), logged.
    ``crank_goal`` (12,): the cranks' goal angles rad and Profile Velocities rad/s streamed to
        servos running their own position loop (a bus with ``position_loop``; ``T`` is then not
        written).
    ``feature_window`` (12 w + 2,): with a tuner, the last w samples of [e_bar,
        motor_torque_applied] as a ring buffer [rows (w x 12, oldest at ``head``), n_valid,
        head], w = ``context.feature_window``.

Sampling: a periodic discrete update of period ``context.period_s`` and offset
``context.offset_s`` = half a plant step. With ``learning`` the ``x_d`` a controller reads
includes the learner's correction (:class:`LearnerContext`,
:class:`~stewart_drake.control.ilc.IterativeLearningController`). A scenario's
``UserController`` names a factory given to :func:`register_controller`, or an entry point of
the group :data:`ENTRY_POINT_GROUP` opted into by name (:func:`use_entry_point_controllers`);
any other name is refused (:func:`resolve_controller`). Why the offset, what a tuner and a
learner change, and how names are resolved: docs/station.md, "The controller contract".
"""

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any, ClassVar, Self

import numpy as np
from pydrake.systems.framework import Diagram, LeafSystem

from ..base.checks import as_number
from ..base.errors import InvalidConfigError
from ..robot.geometry import StewartGeometry

#: Ports the Diagram knows how to connect, with their sizes (``status`` has any size).
INPUT_PORTS = {
    "x_d": 18,
    "x": 12,
    "motor_angle": 6,
    "motor_rate": 6,
    "T_ff": 6,
    "omega": 2,
    "motor_torque_applied": 6,
}
OUTPUT_PORTS = {
    "T": 6,
    "status": None,
    "e_bar": 6,
    "integral": 6,
    "feature_window": None,
    "crank_goal": 12,
}
REQUIRED_INPUTS = ("x_d",)
REQUIRED_OUTPUTS = ("T",)
#: ``status`` entries of the LQI (and of controllers that report the same figures).
LQI_STATUS_NAMES = (
    "omega_Q",
    "omega_R",
    "gain_solves",
    "gain_failures",
    "integral_norm",
    "saturated_steps",
    "governed_steps",
)


@dataclass(frozen=True)
class ControllerContext:
    """What the Diagram tells a controller factory.

    Attributes:
        geometry: the robot the controller believes in
            (:class:`~stewart_drake.robot.geometry.StewartGeometry`; a payload it does not know
            is not in it).
        period_s: control period h, s.
        offset_s: sample offset within the period, s (half a plant step; see the module
            docstring).
        plant_time_step_s: the plant's step, s.
        x_initial: (6,) pose at t = 0 [rad, m] (the reference's start).
        x_dot_initial: (6,) its rate [rad/s, m/s].
        torque_limit_Nm: the motors' torque limit, N m (None: unlimited).
        delay_periods: control periods between a measurement and the torque computed from it
            (the robot's computation delay; 0 on the ideal robot).
        pose_estimator: on the robot as built, the
            :class:`~stewart_drake.control.estimator.PoseEstimator` from its encoders (a
            controller with a ``motor_angle`` input may estimate the pose itself with it; one
            with an ``x`` input gets the estimate from an FK estimator system); None on the
            ideal robot.
        feature_window: with a tuner, the samples w of the density features' window (a
            controller may buffer them on a ``feature_window`` output); None without one.
        servo: on the robot as built, the motors' :class:`~stewart_drake.robot.servo.ServoModel`
            (their friction, inertia and peak torque, for a controller that compensates them);
            None on the ideal robot.
    """

    geometry: StewartGeometry
    period_s: float
    offset_s: float
    plant_time_step_s: float
    x_initial: np.ndarray
    x_dot_initial: np.ndarray | None = None
    torque_limit_Nm: float | None = None
    delay_periods: int = 0
    # A PoseEstimator or None; Any, as estimator.py imports this module (through the LQI).
    pose_estimator: Any = None
    feature_window: int | None = None
    # A ServoModel or None; Any, as robot.servo is a lower layer but kept out of the signature.
    servo: Any = None


@dataclass(frozen=True)
class LearnerContext:
    """What the Diagram tells the learner of a scenario's ``learning``: each learning choice
    builds its system from it (``driver.make_learner(context)``), as a controller factory does
    from a :class:`ControllerContext`.

    Attributes:
        geometry: the robot the controller believes in.
        reference: the reference object (``evaluate(t)``) the run tracks.
        period_s: control period, s. offset_s: sample offset within the period, s.
        duration_s: the run's length, s.
        floor: (m, rad) one encoder count at the crank tip as a translation and as a platform
            rotation (the learner's additive floor of its monitored bound).
        cycles: ``cycles(period_s) -> (starts (K + 1,) s, scale (K,))``, the cycles of the
            reference over the run (``period_s`` > 0: of that period from t = 0), for a
            learner that learns from every cycle.
        encoder_quantum_rad: one encoder count, rad (0: the angles are read exactly).
    """

    geometry: StewartGeometry
    reference: Any
    period_s: float
    offset_s: float
    duration_s: float
    floor: tuple[float, float]
    cycles: Callable
    encoder_quantum_rad: float = 0.0


class ControllerDriver:
    """Base of a scenario's controller choices (:class:`~.lqi.driver.LqiDriver`,
    :class:`~.pd.PdDriver`, :class:`UserController`): each is a dataclass that checks its own
    options (``validate``) and builds its controller (``make``), the one place it does. A new
    controller is one such class in the scenario's ``controller`` union.
    """

    #: Whether the controller has the ``omega`` input a tuner drives (None: known once built).
    takes_omega: ClassVar[bool | None] = None
    #: How a run's result files mark the controller (``run_<reference>...<suffix>``).
    run_suffix: ClassVar[str] = ""
    #: Whether its ``crank_goal`` drives the servos' own position loop (``bus.position_loop``).
    streams_goals: ClassVar[bool] = False
    #: The choice's name where a command picks it with its defaults (``run --controller NAME``,
    #: the evaluation grid); "" for a choice that needs options to mean anything.
    short_name: ClassVar[str] = ""

    def validate(
        self, control_period_s: float, delay_periods: int = 0, prefix: str = "controller."
    ):
        """Check the options for a controller of period ``control_period_s`` (s) on a robot with
        ``delay_periods`` of computation delay; returns self.

        Raises:
            InvalidConfigError: names the option (``prefix`` + its name).
        """
        raise NotImplementedError

    def make(self, context: ControllerContext):
        """The controller system for the Diagram that ``context`` describes (the contract)."""
        raise NotImplementedError

    def resolve(self) -> Callable:
        """The factory ``f(ControllerContext) -> System`` of this choice, resolved now (a name
        that is not registered is refused here)."""
        return self.make

    def omega(self) -> tuple:
        """(omega_Q, omega_R): the constant on an ``omega`` input when no tuner drives it."""
        return (1.0, 1.0)

    def with_weights(self, **weights) -> Self:
        """A copy with constant weights ``omega_Q``, ``omega_R`` (the LQI's).

        Raises:
            InvalidConfigError: the controller has no such weights.
        """
        raise InvalidConfigError(
            f"omega_Q and omega_R are weights of the LQI controller; the "
            f"controller is a {type(self).__name__}"
        )

    def summary(self) -> dict:
        """Settings a run's results carry besides the controller's name (plain JSON values)."""
        return {}


#: Factories registered by name (:func:`register_controller`).
CONTROLLER_REGISTRY: dict[str, Callable[..., LeafSystem]] = {}
#: Entry-point group of installed controller factories (``name = "package.module:factory"``);
#: one is loaded only when the user names it (:func:`use_entry_point_controllers`).
ENTRY_POINT_GROUP = "stewart_drake.controllers"


def register_controller(name: str, factory: Callable[..., LeafSystem]) -> None:
    """Make ``factory(context, **parameters) -> LeafSystem`` available to scenarios by ``name``.

    Raises:
        InvalidConfigError: ``name`` is empty or ``factory`` is not callable.
    """
    if not isinstance(name, str) or not name:
        raise InvalidConfigError(f"a controller name must be a non-empty string, got {name!r}")
    if not callable(factory):
        raise InvalidConfigError(f"the factory registered as {name!r} is not callable")
    CONTROLLER_REGISTRY[name] = factory


def _registered() -> str:
    return ", ".join(sorted(CONTROLLER_REGISTRY)) or "none"


def resolve_controller(name: str) -> Callable[..., LeafSystem]:
    """The factory registered as ``name`` (:func:`register_controller`,
    :func:`use_entry_point_controllers`); nothing is imported or called here.

    Raises:
        InvalidConfigError: ``name`` is not registered (a ``"module:attribute"`` path included);
            the message lists the registered names and how to register one.
    """
    if isinstance(name, str) and name in CONTROLLER_REGISTRY:
        return CONTROLLER_REGISTRY[name]
    path = (
        " is an import path, and a scenario never imports code; it"
        if isinstance(name, str) and ":" in name
        else ""
    )
    raise InvalidConfigError(
        f"controller factory {name!r}{path} is not a registered controller (registered: "
        f"{_registered()}): call register_controller({name!r}, factory) in the Python code "
        f"that runs the scenario, or install the factory as an entry point of the group "
        f"{ENTRY_POINT_GROUP!r} and opt into it with --plugin NAME"
    )


@dataclass
class UserController(ControllerDriver):
    """A controller of the user's as a scenario's controller (``controller: !UserController``):
    ``factory`` names a callable ``factory(context, **parameters) -> LeafSystem`` following this
    contract that Python code the user ran registered (:func:`register_controller`), or an
    installed entry point the user opted into (:func:`use_entry_point_controllers`, ``--plugin
    NAME``). Loading the scenario imports and calls nothing: an unknown name is refused when the
    run is built (:meth:`resolve`), listing the registered ones.

    Attributes:
        factory: the registered name. parameters: keyword arguments of the factory (numbers).
    """

    factory: str = ""
    parameters: dict[str, float] = field(default_factory=dict)

    def validate(
        self, control_period_s: float, delay_periods: int = 0, prefix: str = "controller."
    ) -> "UserController":
        if not isinstance(self.factory, str) or not self.factory:
            raise InvalidConfigError(
                f"{prefix}factory must name a registered controller "
                f"(register_controller, or --plugin NAME)"
            )
        for key, value in self.parameters.items():
            as_number(f"{prefix}parameters.{key}", value)
        return self

    def resolve(self) -> Callable:
        registered = resolve_controller(self.factory)

        def make(context):
            try:
                return registered(context, **self.parameters)
            except SystemExit as err:  # would end the caller without a word
                raise InvalidConfigError(
                    f"the controller factory {self.factory!r} raised SystemExit({err.code!r}) "
                    f"instead of returning a controller: fix the plug-in"
                ) from None

        return make

    def make(self, context: ControllerContext):
        return self.resolve()(context)


def use_entry_point_controllers(names) -> list[str]:
    """Register the installed entry points named ``names`` of :data:`ENTRY_POINT_GROUP`
    (``importlib.metadata``), each under its own name: the opt-in that makes a package's
    controller available to scenarios. Only the named entry points are imported.

    Args:
        names: entry-point names (``stewart-drake run --plugin NAME``).
    Returns:
        the names registered.
    Raises:
        InvalidConfigError: no installed entry point of that name (the message lists those
            installed), or one that cannot be imported or is not callable.
    """
    from importlib.metadata import entry_points

    installed = {ep.name: ep for ep in entry_points(group=ENTRY_POINT_GROUP)}
    for name in names:
        if name not in installed:
            raise InvalidConfigError(
                f"--plugin {name}: no installed entry point of that name in the group "
                f"{ENTRY_POINT_GROUP!r} (installed: {', '.join(sorted(installed)) or 'none'})"
            )
        try:
            factory = installed[name].load()
        # the user's package may raise anything, SystemExit too (it would end the command
        # without a word)
        except (Exception, SystemExit) as err:  # noqa: BLE001
            raise InvalidConfigError(
                f"--plugin {name}: the entry point {installed[name].value} "
                f"cannot be loaded ({type(err).__name__}: {err})"
            ) from None
        register_controller(name, factory)
    return list(names)


def check_controller(system) -> None:
    """Check a controller against the contract before it is wired.

    Raises:
        InvalidConfigError: not a LeafSystem or Diagram, a required port missing, a known port of
            the wrong size, an input port the Diagram cannot connect, or ``status`` without
            ``status_names`` of its size; the message names the port.
    """
    if not isinstance(system, (LeafSystem, Diagram)):
        raise InvalidConfigError(
            f"a controller factory must return a pydrake LeafSystem (or a "
            f"Diagram), got {type(system).__name__}"
        )
    name = system.get_name() or type(system).__name__
    inputs = {
        system.get_input_port(i).get_name(): system.get_input_port(i)
        for i in range(system.num_input_ports())
    }
    outputs = {
        system.get_output_port(i).get_name(): system.get_output_port(i)
        for i in range(system.num_output_ports())
    }
    for required in REQUIRED_INPUTS:
        if required not in inputs:
            raise InvalidConfigError(
                f"controller {name} has no input port {required!r} "
                f"(required by the contract, control/contract.py)"
            )
    for required in REQUIRED_OUTPUTS:
        if required not in outputs:
            raise InvalidConfigError(
                f"controller {name} has no output port {required!r} "
                f"(required by the contract, control/contract.py)"
            )
    for port_name, port in inputs.items():
        if port_name not in INPUT_PORTS:
            raise InvalidConfigError(
                f"controller {name} declares input port {port_name!r}, which the Diagram cannot "
                f"connect; the contract's inputs are {sorted(INPUT_PORTS)}"
            )
        if port.size() != INPUT_PORTS[port_name]:
            raise InvalidConfigError(
                f"controller {name}: input port {port_name!r} has size "
                f"{port.size()}, the contract says {INPUT_PORTS[port_name]}"
            )
    for port_name, size in OUTPUT_PORTS.items():
        if port_name in outputs and size is not None and outputs[port_name].size() != size:
            raise InvalidConfigError(
                f"controller {name}: output port {port_name!r} has size "
                f"{outputs[port_name].size()}, the contract says {size}"
            )
    if "status" in outputs:
        names = getattr(system, "status_names", None)
        if names is None or len(tuple(names)) != outputs["status"].size():
            raise InvalidConfigError(
                f"controller {name} has a status output of size {outputs['status'].size()}; "
                f"give it a status_names attribute naming each entry"
            )


class PoseTorqueController(LeafSystem):
    """Base class of the package's pose controllers: declares the input ports ``x`` (12) (unless
    ``pose_input`` is false: a controller that estimates the pose from ``motor_angle`` itself),
    ``x_d`` (18), ``T_ff`` (6) and ``omega`` (2) of the contract (module docstring).

    A subclass declares the outputs ``T`` (6) and, if it has them, ``status`` (with
    ``status_names``), ``e_bar`` (6) and ``integral`` (6).
    """

    def __init__(self, omega: bool = True, pose_input: bool = True):
        super().__init__()
        self._x = self.DeclareVectorInputPort("x", 12) if pose_input else None
        self._x_d = self.DeclareVectorInputPort("x_d", 18)
        self._T_ff = self.DeclareVectorInputPort("T_ff", 6)
        self._omega = self.DeclareVectorInputPort("omega", 2) if omega else None

    def get_x_input_port(self):
        return self._x

    def get_x_d_input_port(self):
        return self._x_d

    def get_T_ff_input_port(self):
        return self._T_ff

    def get_omega_input_port(self):
        return self._omega
