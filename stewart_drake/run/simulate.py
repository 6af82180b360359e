"""Closed-loop runs: build a checked run, simulate it through its guard, read its result.

``run_experiment(scenario)`` returns a :class:`~.result.RunResult` (arrays + metrics,
:func:`~.metrics.compute_metrics`): the plan is made and checked once
(:func:`~.plan.checked_plan`: the scenario, the run's memory, the reference), the Diagram built
from it
(:func:`~.diagram.build_diagram`), simulated (:func:`simulate`) and read
(:mod:`~.result`, which also saves and loads results). The pictures and the printed summary
are made apart, from a result (:mod:`~stewart_drake.paper.run_report`: ``plot_fig7``;
:func:`~.metrics.format_metrics`).
"""

from __future__ import annotations

import dataclasses
import time
from pathlib import Path

from pydrake.systems.analysis import ApplySimulatorConfig, Simulator

from ..station import guard
from .diagram import StewartDiagram, build_diagram
from .plan import RunPlan, checked_plan
from .result import RunLogs, RunResult, finish_result, read_run, release_reference
from .scenario import Scenario

#: Where ``stewart-drake train`` writes the tuner and ``run --tuner ann`` looks first.
DEFAULT_TUNER_OUT = Path("results") / "tuner" / "ann_tuner.npz"


def advance(simulator: Simulator, t_end: float, progress: bool, desc: str = "simulating"):
    """``simulator.AdvanceTo(t_end)`` (s), in 200 chunks behind a tqdm bar when ``progress``:
    the bar shows the simulator's time against ``t_end``, never beyond it (a total rounded
    below ``t_end``, or chunks summed past it by a rounding, made tqdm warn that it clamps)."""
    if not progress:
        simulator.AdvanceTo(t_end)
        return
    from tqdm import tqdm

    chunk = max(t_end / 200, 1e-3)
    t = simulator.get_context().get_time()
    with tqdm(
        total=t_end,
        initial=min(t, t_end),
        desc=desc,
        unit="sim s",
        bar_format=("{l_bar}{bar}| {n:.2f}/{total:.2f} sim s [{elapsed}<{remaining}]"),
    ) as bar:
        while t < t_end - 1e-12:
            t_next = min(t + chunk, t_end)
            simulator.AdvanceTo(t_next)
            bar.n = t_next  # the simulator's time itself: no sum of chunks to round past t_end
            bar.update(0)
            t = t_next


def simulated_robot(scenario):
    """``scenario`` as a simulation runs it: a scenario or plan that drives the servo bus (its
    ``bus`` section, e.g. ``paper_bus``) gives the robot the bus drives, simulated with the
    bus's servos and encoders (:func:`~.plan.as_built`: what a plan on the bus already holds),
    on the simulated station, its bus left closed: ``stewart-drake robot`` drives the bus. Any
    other scenario, plan, or None: itself."""
    from ..station.station import StewartStation
    from .plan import as_built

    if isinstance(scenario, Scenario) and scenario.bus is not None:
        return dataclasses.replace(as_built(scenario), bus=None)
    if isinstance(scenario, RunPlan) and scenario.scenario.bus is not None:
        return dataclasses.replace(
            scenario,
            scenario=dataclasses.replace(as_built(scenario.scenario), bus=None),
            station_factory=StewartStation,
        )
    return scenario


def build_simulator(
    scenario: Scenario | RunPlan | None = None,
    meshcat=None,
    *,
    reference=None,
    controller=None,
    progress: bool = False,
    report=None,
    controller_logs: bool = True,
    on_checked=None,
):
    """(StewartDiagram, Simulator) with the loops assembled at x_d(0) moving at x_dot_d(0), guarded.

    The run's memory is checked first, then the reference (:func:`~.plan.checked_plan`; the
    plan keeps the check's report); ``sd.guard``, the
    Diagram's :class:`guard.DivergenceGuard`, checks the run as it goes (advance with
    :func:`guard.advance` to get the logs saved when it trips). ``scenario.simulator`` is
    applied.

    Args:
        scenario, meshcat, reference, controller, controller_logs: as
            :func:`~stewart_drake.run.diagram.make_stewart_diagram`.
        progress: show a bar while a long reference is checked
            (:func:`~.plan.check_reference_shown`).
        report: the check's report when the caller has already checked this plan's reference
            (it is then not checked again).
        on_checked: called (no arguments) once the checks pass, before the Diagram is built.
    Raises:
        UnreachablePoseError, JointLimitError, SingularPoseError: the reference leaves the
            workspace, a joint range or nears a singularity (first time, leg or measure),
            checked before anything is simulated. InvalidConfigError: a bad scenario field, or
            a run that needs more memory than the machine has
            (:func:`~.memory.check_run_memory`), or an ``lcm.url`` on which nothing published
            arrives (:func:`~stewart_drake.station.lcm_publish.make_lcm`).
    """
    plan = checked_plan(
        simulated_robot(scenario),
        reference=reference,
        controller=controller,
        progress=progress,
        report=report,
    )
    lcm = None
    if plan.scenario.lcm is not None:  # a dead URL is a refusal: before the Diagram is built
        from ..station.lcm_publish import make_lcm

        lcm = make_lcm(plan.scenario.lcm.url)
    if on_checked is not None:
        on_checked()
    sd = build_diagram(plan, meshcat, controller_logs=controller_logs, lcm=lcm)
    simulator = Simulator(sd.diagram)
    ApplySimulatorConfig(plan.scenario.simulator, simulator)
    context = simulator.get_mutable_context()
    sd.initialize(context)
    # Start on the reference, moving with it: a platform at rest under a reference that already
    # moves (eqs. 37-38 start at phi_dot = 2 pi/6 rad/s) makes a torque spike that is not
    # tracking (1.7 N m against 0.41 N m afterwards).
    sd.station.assemble(context, sd.x_initial, sd.x_dot_initial)
    simulator.Initialize()
    return sd, simulator


def run_experiment(
    scenario: Scenario | RunPlan | None = None,
    progress: bool = False,
    meshcat=None,
    *,
    reference=None,
    controller=None,
    on_checked=None,
    report=None,
    controller_logs: bool = True,
    desc: str = "simulating",
) -> RunResult:
    """Simulate one closed-loop run and collect its logs and metrics: every run of the package
    that simulates (the paper's, a reproduction, a study's job) comes here.

    Args:
        scenario: the run, a scenario or a :class:`~stewart_drake.run.plan.RunPlan`
            (default: the paper's experiment on the ideal robot, 10 s).
        progress: show a tqdm progress bar.
        meshcat: optional Meshcat to visualize the run.
        reference: optional reference object overriding ``scenario.reference`` (an object with
            ``evaluate(t)``, a Drake ``Trajectory``, a CSV path or a name).
        controller: optional controller factory or registered name (the controller contract,
            :mod:`~stewart_drake.control.contract`) overriding ``scenario.controller``.
        on_checked: called (no arguments) once the run's checks pass, before the Diagram is
            built: the command line says there what the next seconds do.
        report: the reference's check when the caller has made it (not checked again).
        controller_logs: False to log neither the controller's integral nor its error estimate
            (a long reproduction is lighter without them).
        desc: the progress bar's label.
    Returns:
        :class:`~.result.RunResult` (with a learner's record when the scenario learns).
    Raises:
        UnreachablePoseError, JointLimitError, SingularPoseError before simulating (see
        :func:`build_simulator`); SimulationDivergedError when the guard stops the run (the
        logs up to then are saved, the path is in the error).
    """
    sd, simulator = build_simulator(
        scenario,
        meshcat,
        reference=reference,
        controller=controller,
        progress=progress,
        report=report,
        controller_logs=controller_logs,
        on_checked=on_checked,
    )
    logs, wall = simulate(sd, simulator, progress, desc)
    release_reference(sd)
    return finish_result(logs, wall)


def simulate(
    sd: StewartDiagram, simulator: Simulator, progress: bool = False, desc: str = "simulating"
) -> tuple[RunLogs, float]:
    """Advance a built run to its end through the guard (:func:`guard.advance`) and read it
    (:func:`~.result.read_run`). Returns (logs, wall time of the simulation, s)."""
    wall0 = time.perf_counter()
    guard.advance(sd, simulator, lambda: advance(simulator, sd.plan.duration_s, progress, desc))
    wall = time.perf_counter() - wall0
    return read_run(sd, simulator.get_context()), wall
