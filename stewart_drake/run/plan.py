"""A run's plan: every value a validated scenario implies, computed once, then only read.

A :class:`~.scenario.Scenario` says what a run is (the robot, its motors, the reference, the
controller, the periods); :func:`make_plan` says how it is built. It validates the scenario (the
one place a run's scenario is validated) and derives, once, what the station, the Diagram, the
reference check and the simulator need: the robot the controller believes in and the one that is
simulated, the servo, the torque and motor limits, the computation delay, the sample offset, the
reference object and the controller's factory. Everything below the plan (the station, the
guard, the learner) receives these values and never reads the scenario again.

    plan = make_plan(load_scenario("paper_hardware"))
    sd = make_stewart_diagram(plan)          # or build_simulator(plan), run_experiment(plan)
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from ..control.contract import ControllerContext, resolve_controller
from ..control.estimator import PoseEstimator
from ..robot.geometry import StewartGeometry
from ..robot.limits import MotorLimits, TrajectoryReport
from ..robot.servo import ServoModel
from .scenario import Scenario


@dataclass(frozen=True)
class RunPlan:
    """The values a validated scenario implies (:func:`make_plan`); SI units.

    Attributes:
        scenario: the validated scenario the plan was made from (read it, do not change it:
            the values below are not recomputed); on the servo bus with ``hardware: null``,
            with the robot built with the bus's servos (:meth:`~.scenario.Scenario.as_built`).
        geometry: the robot the controller believes in: ``robot`` with, on the robot as built,
            the motors' reflected inertia (rotor inertia x gear ratio^2).
        plant_geometry: the robot that is simulated: ``geometry`` with ``payload_scale`` on the
            platform's mass and inertia.
        servo: the servo of ``hardware.motors`` (None on the ideal robot).
        torque_limit_Nm: the saturation in force, N m: the lowest of ``torque_limit_Nm``, with
            hardware the servo's peak torque, and on the servo bus ``K_t`` times its current
            limit (None: unlimited).
        motor_limits: what a reference may ask of the motors: that limit, the servo's no-load
            speed at the crank, its friction and ``guard.effort_margin``.
        delay_periods: control periods between a measurement and its torque (0 on the ideal
            robot).
        plant_time_step_s, control_period_s, log_period_s, duration_s: the run's step, periods
            and length, s.
        sample_offset_s: when the controllers sample within their period, s: half a plant step
            after each plant update, when the plant already holds the next step's configuration
            (its reference leads by the same half step; the controller contract, "Sampling").
        encoder_count_at_tip: (m, rad) one encoder count at the crank tip, as a translation
            and as a rotation of the platform; (1e-6 m, 1e-5 rad) on the ideal robot, which
            reads exact angles (the learner's additive floor).
        reference: the reference object (:class:`~.motion.Reference`: ``evaluate(t)``), or
            None for a plan made without one (a live reference, or only the robot's values).
        controller_factory: ``f(ControllerContext) -> System``, the run's controller.
    """

    scenario: Scenario
    geometry: StewartGeometry
    plant_geometry: StewartGeometry
    servo: ServoModel | None
    torque_limit_Nm: float | None
    motor_limits: MotorLimits
    delay_periods: int
    plant_time_step_s: float
    control_period_s: float
    log_period_s: float
    duration_s: float
    sample_offset_s: float
    encoder_count_at_tip: tuple[float, float]
    reference: Any  # a motion.Reference, or None
    controller_factory: Callable

    def add_plant(self, builder):
        """The robot as simulated, a MultibodyPlant named "plant" with its SceneGraph, added to
        ``builder``: :func:`~stewart_drake.plant.plant.add_stewart_plant` with ``plant_geometry``,
        ``servo`` and the scenario's plant settings, contact and rod model. Returns (plant,
        scene_graph, handles)."""
        from ..plant.plant import add_stewart_plant

        scenario = self.scenario
        plant, scene_graph, handles = add_stewart_plant(
            builder,
            self.plant_geometry,
            plant_config=scenario.plant,
            servo=self.servo,
            contact=scenario.contact,
            rod_model=scenario.rod_model,
        )
        plant.set_name("plant")
        return plant, scene_graph, handles

    def controller_context(self, x0, x_dot0) -> ControllerContext:
        """What the run tells its controller's factory, starting at pose x0 (6,) [rad, m] moving
        at x_dot0 (6,) [rad/s, m/s]: on the robot as built a new encoders' pose estimator, with
        a network tuner its features' window. A new context (and estimator) each call."""
        hw, h = self.scenario.hardware, self.control_period_s
        pose_estimator = (
            None
            if hw is None
            else PoseEstimator(
                self.geometry,
                h,
                hw.encoders.quantum_rad,
                x0,
                rate_cutoff_hz=hw.estimator.rate_cutoff_hz,
                tolerance_counts=hw.estimator.fk_tolerance_counts,
            )
        )
        tuner = self.scenario.tuner
        return ControllerContext(
            geometry=self.geometry,
            period_s=h,
            offset_s=self.sample_offset_s,
            plant_time_step_s=self.plant_time_step_s,
            x_initial=x0,
            x_dot_initial=x_dot0,
            torque_limit_Nm=self.torque_limit_Nm,
            delay_periods=self.delay_periods,
            pose_estimator=pose_estimator,
            feature_window=None if tuner is None else tuner.density_window(),
        )


def make_plan(
    scenario: Scenario | RunPlan | None = None,
    *,
    reference=None,
    controller=None,
    with_reference: bool = True,
) -> RunPlan:
    """Validate ``scenario`` and derive every value of its run (:class:`RunPlan`).

    Args:
        scenario: the run (default: ``Scenario()``, the paper's experiment on the ideal robot),
            validated here; or a plan, not validated again: returned as it is, or with the
            reference or controller given here (or its reference made, if it has none).
        reference: a reference overriding ``scenario.reference``: an object with
            ``evaluate(t)``, a Drake ``Trajectory``, a CSV path or a name
            (:func:`~.trajectories.as_trajectory`).
        controller: a controller factory or registered name overriding ``scenario.controller``
            (:mod:`~stewart_drake.control.contract`).
        with_reference: False for a plan without a reference object (a live reference, or when
            only the robot's values are needed: nothing is read or sampled).
    Returns:
        the :class:`RunPlan`.
    Raises:
        InvalidConfigError, InvalidGeometryError, MissingFileError: the scenario does not
            validate (the message names the field), or a controller name is not registered.
    """
    from ..references.trajectories import as_trajectory

    plan = (
        scenario
        if isinstance(scenario, RunPlan)
        else _robot_plan((scenario if scenario is not None else Scenario()).validate())
    )
    changes: dict[str, Any] = {}
    if reference is not None:
        changes["reference"] = as_trajectory(reference)
    elif with_reference and plan.reference is None:
        changes["reference"] = as_trajectory(
            plan.scenario.reference.make(plan.geometry, plan.duration_s, plan.torque_limit_Nm)
        )
    if controller is not None:
        changes["controller_factory"] = (
            resolve_controller(controller) if isinstance(controller, str) else controller
        )
    return dataclasses.replace(plan, **changes) if changes else plan


def _robot_plan(scenario: Scenario) -> RunPlan:
    """The plan of a validated ``scenario`` without its reference object (on the servo bus,
    of the robot built with its servos: :meth:`~.scenario.Scenario.as_built`)."""
    scenario = scenario.as_built()
    geometry = scenario.robot.build()
    servo = None if scenario.hardware is None else scenario.hardware.motors.build()
    if servo is not None:
        geometry = geometry.replace(motor_reflected_inertia=servo.reflected_inertia)
    plant_geometry = geometry
    if scenario.payload_scale != 1.0:
        k = scenario.payload_scale
        plant_geometry = geometry.replace(
            platform_mass=geometry.platform_mass * k,
            platform_inertia=tuple(k * v for v in geometry.platform_inertia),
        )
    limits = [
        v
        for v in (
            scenario.torque_limit_Nm,
            None if servo is None else servo.peak_torque_Nm,
            None if scenario.bus is None else scenario.bus.torque_limit_Nm(),
        )
        if v is not None
    ]
    torque_limit = min(limits) if limits else None
    h_plant = scenario.plant.time_step
    tip = (
        (1e-6, 1e-5)
        if scenario.hardware is None
        else (
            scenario.hardware.encoders.quantum_rad * geometry.crank_length,
            scenario.hardware.encoders.quantum_rad
            * geometry.crank_length
            / geometry.platform_radius,
        )
    )
    return RunPlan(
        scenario=scenario,
        geometry=geometry,
        plant_geometry=plant_geometry,
        servo=servo,
        torque_limit_Nm=torque_limit,
        motor_limits=MotorLimits(
            torque_limit,
            None if servo is None else servo.no_load_speed_rad_s,
            scenario.guard.effort_margin,
            servo,
        ),
        delay_periods=0
        if scenario.hardware is None
        else scenario.hardware.computation_delay_periods,
        plant_time_step_s=h_plant,
        control_period_s=scenario.control_period_s,
        log_period_s=scenario.log_period_s,
        duration_s=scenario.duration_s,
        sample_offset_s=0.5 * h_plant,
        encoder_count_at_tip=tip,
        reference=None,
        controller_factory=scenario.controller.resolve(),
    )


def check_reference(
    plan: Scenario | RunPlan,
    trajectory=None,
    raise_refused: bool = True,
    progress=None,
    keep_series: bool = True,
) -> TrajectoryReport:
    """Refuse a reference the robot of ``plan`` cannot follow, before anything is simulated:
    :func:`~.guard.check_path` with the plan's robot as simulated (payload included), duration,
    control period, guard bounds and motor limits.

    Args:
        plan: a :class:`RunPlan` or a scenario (planned here).
        trajectory: the reference object (default: the plan's).
        raise_refused: False reports every refusal in the report instead of raising the first.
        progress, keep_series: as :func:`~.trajectories.validate`.
    Returns:
        the :class:`~stewart_drake.robot.limits.TrajectoryReport`.
    Raises:
        as :func:`~.guard.check_path`.
    """
    from ..station.guard import check_path

    plan = make_plan(plan, with_reference=trajectory is None)
    trajectory = plan.reference if trajectory is None else trajectory
    return check_path(
        trajectory,
        plan.plant_geometry,
        plan.duration_s,
        plan.control_period_s,
        plan.scenario.guard,
        plan.motor_limits,
        raise_refused=raise_refused,
        progress=progress,
        keep_series=keep_series,
    )
