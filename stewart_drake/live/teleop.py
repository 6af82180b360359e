"""Drive the robot live: the closed loop at real time in Meshcat, the reference set by sliders.

:func:`run_teleop` builds the scenario's closed loop (:func:`~stewart_drake.run.diagram.
make_stewart_diagram`) with a live reference instead of a precomputed one: the pose sliders
(:class:`PoseSliders`: "roll [rad]", "pitch [rad]", "yaw [rad]", "x [m]", "y [m]", "z [m]"; keys
Q/E, W/S, A/D, J/L, I/K, U/O, as Drake's ``MeshcatPoseSliders``) give a target pose,
:class:`~stewart_drake.run.reference.TeleopReference` filters it into a pose
the robot can follow (rate-limited, and stopped at the boundary of the admissible workspace),
and Drake's ``Simulator`` runs the whole at a target real-time rate while Meshcat shows the
robot and, as a translucent ghost of the platform, the reference (:class:`ReferenceGhost`).
:class:`TeleopDisplay` shows, as it changes, the tracking error of the real platform and
its margins (by default the torque margin of the holding torques against the motors' peak
torque and the clearance between the robot's parts; ``margins`` is the hook for other figures).
The reference stops where two parts would come closer than ``guard.min_clearance_m``.

The Meshcat panel's gauges are sliders named "<figure> (reading)" whose values the display
writes back every refresh (dragging them does nothing). The pose sliders span the admissible
workspace around the start pose along each axis (:func:`slider_limits`).
The panel's button "pause / resume" (key P) stops the simulated time and starts it again.
The run ends after ``duration_s`` or at Ctrl-C, and reports the real-time rate it kept.
"""

from __future__ import annotations

import dataclasses
import functools
import signal
import time
from collections.abc import Callable
from typing import TYPE_CHECKING

import numpy as np
from pydrake.systems.framework import LeafSystem

from ..robot.kinematics import X_HOME
from ..robot.statics import holding_torques
from ..run.plan import make_plan

if TYPE_CHECKING:  # for the annotations only: build_teleop imports these when it runs
    from pydrake.geometry import Meshcat
    from pydrake.systems.analysis import Simulator
    from pydrake.systems.framework import Diagram

    from ..run.diagram import StewartDiagram
    from ..run.reference import TeleopReference

#: Slider range around the start pose: [roll, pitch, yaw] rad, [x, y, z] m, when the workspace
#: is not swept (``slider_limits`` searches up to twice as far in each direction).
SLIDER_RANGE = np.array([0.25, 0.25, 0.35, 0.04, 0.04, 0.03])
#: Poses tried per direction and axis by :func:`slider_limits`.
SLIDER_SWEEP_POINTS = 40
#: Suffix of the gauges' names: they show a reading, they are not inputs.
READING = " (reading)"
#: The pose sliders' names, with their units: roll, pitch, yaw [rad], then x, y, z [m].
POSE_SLIDERS = ("roll [rad]", "pitch [rad]", "yaw [rad]", "x [m]", "y [m]", "z [m]")
#: Their keys (decrease, increase), as Drake's ``MeshcatPoseSliders``.
POSE_KEYS = (
    ("KeyQ", "KeyE"),
    ("KeyS", "KeyW"),
    ("KeyA", "KeyD"),
    ("KeyJ", "KeyL"),
    ("KeyK", "KeyI"),
    ("KeyU", "KeyO"),
)
#: Slider steps: 5 mrad, 1 mm.
SLIDER_STEP = np.array([0.005, 0.005, 0.005, 0.001, 0.001, 0.001])
#: The Meshcat button that pauses the simulated time and resumes it (key P).
PAUSE_BUTTON = "pause / resume"
#: How often the display is refreshed, s.
DISPLAY_PERIOD_S = 0.1


def slider_limits(admissible, x0, span=None, points: int = SLIDER_SWEEP_POINTS):
    """Lower and upper slider limits, (6,) each [rad, m]: along each axis of the pose from
    ``x0`` (the others held), the farthest pose up to ``span`` (default 5 x
    :data:`SLIDER_RANGE`) in each direction that ``admissible`` accepts with every pose before
    it; ``x0`` itself where none is. One call of ``admissible`` on 12 x ``points`` poses.

    Args:
        admissible: ``admissible(x (N, 6)) -> (N,) bool`` (the teleop reference's).
        x0: (6,) the start pose. span: (6,) how far to search. points: poses per direction.
    """
    x0 = np.asarray(x0, dtype=float)
    span = 5 * SLIDER_RANGE if span is None else np.asarray(span, dtype=float)
    fractions = np.arange(1, points + 1) / points
    trials = []
    for axis in range(6):
        for sign in (-1.0, 1.0):
            x = np.tile(x0, (points, 1))
            x[:, axis] += sign * fractions * span[axis]
            trials.append(x)
    ok = np.asarray(admissible(np.concatenate(trials)), dtype=bool).reshape(12, points)
    reach = np.array([fractions[: int(np.argmin(np.append(row, False)))][-1:].sum() for row in ok])
    reach = reach.reshape(6, 2) * span[:, None]
    return x0 - reach[:, 0], x0 + reach[:, 1]


def torque_margins(geometry, peak_torque_Nm: float | None) -> Callable[[np.ndarray], dict]:
    """The default ``margins`` of :class:`TeleopDisplay`: the motors' peak torque minus the
    largest holding torque of the pose (statics, N m); none without a torque limit."""

    def margins(x: np.ndarray) -> dict:
        if peak_torque_Nm is None:
            return {}
        try:
            T = holding_torques(geometry, x)
        except ValueError:  # a pose the statics refuse: no margin at all
            return {"T margin [N m]": 0.0}
        return {"T margin [N m]": float(peak_torque_Nm - np.abs(T).max())}

    return margins


def robot_margins(geometry, peak_torque_Nm: float | None, clearance) -> Callable:
    """The default ``margins`` of :class:`TeleopDisplay`: :func:`torque_margins` and the
    clearance between the robot's closest parts, mm (capped at 20), from ``clearance`` (a
    :class:`~stewart_drake.plant.clearance.ClearanceModel`)."""
    torque = torque_margins(geometry, peak_torque_Nm)

    def margins(x: np.ndarray) -> dict:
        out = torque(x)
        try:
            out["clearance [mm]"] = 1e3 * clearance.closest(x).distance
        except ValueError:  # a pose no leg closes at: no clearance at all
            out["clearance [mm]"] = 0.0
        return out

    return margins


class PoseSliders(LeafSystem):
    """Six Meshcat sliders named with their units (:data:`POSE_SLIDERS`) whose values make the
    output port ``pose`` (a ``RigidTransform``: roll-pitch-yaw [rad], then x, y, z [m]), read
    when the port is evaluated. Drake's ``MeshcatPoseSliders`` does the same but names its
    sliders "roll" .. "z" with no units and takes no names.

    Args:
        meshcat: the Meshcat of the run. initial: (6,) the start pose [rad, m].
        lower, upper, step: (6,) the sliders' limits and steps [rad, m].
    """

    def __init__(self, meshcat, initial, lower, upper, step):
        from pydrake.common.value import AbstractValue
        from pydrake.math import RigidTransform

        super().__init__()
        self.meshcat = meshcat
        for name, lo, hi, dx, x, (down, up) in zip(
            POSE_SLIDERS, lower, upper, step, initial, POSE_KEYS, strict=True
        ):
            meshcat.AddSlider(name, float(lo), float(hi), float(dx), float(x), down, up)
        self.DeclareAbstractOutputPort(
            "pose", lambda: AbstractValue.Make(RigidTransform()), self._CalcPose
        )

    def values(self) -> np.ndarray:
        """(6,) the sliders' values now [rad, m]."""
        return np.array([self.meshcat.GetSliderValue(name) for name in POSE_SLIDERS])

    def _CalcPose(self, context, output):
        from pydrake.math import RigidTransform, RollPitchYaw

        x = self.values()
        output.set_value(RigidTransform(RollPitchYaw(x[:3]), x[3:]))


class TeleopDisplay(LeafSystem):
    """Shows the tracking error and the margins in Meshcat, every ``period_s`` (a publish
    event: nothing between).

    Input ports: ``x`` (12,) the platform's true pose and rate; ``x_d`` (18,) the reference.
    Each figure is a gauge of the Meshcat panel (a slider the display sets, named
    "<figure> (reading)"; names short enough for the panel): "error [mm]" (the tracking
    error, largest of |X - X_d|, |Y - Y_d|, |Z - Z_d|), "error [mrad]" (largest of the
    angles), "limited" (1 while the reference stops short of the sliders at the boundary of
    the admissible workspace, from the optional input port ``limited`` (1,)), and one per entry
    of ``margins(x)``.

    Args:
        meshcat: the Meshcat of the run. margins: ``margins(x (6,)) -> {name: value}``, the
            figures to show besides the tracking error (see :func:`torque_margins`).
        ranges: {name: (min, max)} of the gauges (default: 0 .. 10 mm, 0 .. 20 mrad, and
            0 .. 1 for a margin not named there).
        period_s: refresh period, s.
    """

    def __init__(
        self,
        meshcat,
        margins: Callable[[np.ndarray], dict],
        ranges=None,
        period_s: float = DISPLAY_PERIOD_S,
    ):
        super().__init__()
        self.meshcat, self.margins = meshcat, margins
        self.ranges = {"error [mm]": (0.0, 10.0), "error [mrad]": (0.0, 20.0), **(ranges or {})}
        self._x = self.DeclareVectorInputPort("x", 12)
        self._x_d = self.DeclareVectorInputPort("x_d", 18)
        self._limited = self.DeclareVectorInputPort("limited", 1)
        self.DeclarePeriodicPublishEvent(period_sec=period_s, offset_sec=0.0, publish=self._Publish)

    def figures(self, context) -> dict:
        """{name: value} of the display now (the tracking error and the margins)."""
        x, x_d = np.asarray(self._x.Eval(context)), np.asarray(self._x_d.Eval(context))
        e = np.abs(x[:6] - x_d[:6])
        return {
            "error [mm]": 1e3 * float(e[3:].max()),
            "error [mrad]": 1e3 * float(e[:3].max()),
            **(
                {"limited": float(np.asarray(self._limited.Eval(context))[0])}
                if self._limited.HasValue(context)
                else {}
            ),
            **self.margins(x[:6]),
        }

    def _Publish(self, context):
        names = set(self.meshcat.GetSliderNames())
        for figure, value in self.figures(context).items():
            lo, hi = self.ranges.get(figure, (0.0, 1.0))
            name = figure + READING
            if name not in names:
                self.meshcat.AddSlider(name, lo, hi, (hi - lo) / 10000, lo)
            self.meshcat.SetSliderValue(name, float(np.clip(value, lo, hi)))


class ReferenceGhost(LeafSystem):
    """Places the reference's ghost at the input ``x_d`` (18,) every ``period_s`` (a publish
    event, visualization only); the constructor draws it with
    :func:`~stewart_drake.viz.visualize.add_reference_ghost`.

    Args:
        meshcat: the Meshcat of the run. geometry: the robot drawn. period_s: s.
    """

    def __init__(self, meshcat, geometry, period_s: float = 1.0 / 30):
        from ..viz.visualize import add_reference_ghost

        super().__init__()
        self.meshcat = meshcat
        self.path = add_reference_ghost(meshcat, geometry)
        self._x_d = self.DeclareVectorInputPort("x_d", 18)
        self.DeclarePeriodicPublishEvent(period_sec=period_s, offset_sec=0.0, publish=self._Publish)

    def _Publish(self, context):
        from ..viz.visualize import ghost_transform

        self.meshcat.SetTransform(self.path, ghost_transform(self._x_d.Eval(context)))


@dataclasses.dataclass
class TeleopRun:
    """What :func:`build_teleop` built: ``diagram`` (sliders + closed loop + display),
    ``loop`` (the :class:`~stewart_drake.run.diagram.StewartDiagram` inside),
    ``sliders``, ``reference`` (the :class:`~stewart_drake.run.reference.TeleopReference`),
    ``display``, ``ghost`` (the :class:`ReferenceGhost`), ``simulator`` (initialized, at the
    target real-time rate) and ``meshcat`` (with the :data:`PAUSE_BUTTON`)."""

    diagram: Diagram
    loop: StewartDiagram
    sliders: PoseSliders
    reference: TeleopReference
    display: TeleopDisplay
    ghost: ReferenceGhost
    simulator: Simulator
    meshcat: Meshcat

    def paused(self) -> bool:
        """Whether the :data:`PAUSE_BUTTON` has been clicked an odd number of times."""
        return self.meshcat.GetButtonClicks(PAUSE_BUTTON) % 2 == 1


def teleop_scenario(scenario):
    """The scenario for a live run: the visual geometry only, published at 30 Hz (the collision
    and inertia views cost real time), logs every 0.1 s (a long session must not fill the
    memory), the reference's own settings unused."""
    from pydrake.visualization import VisualizationConfig

    scenario = dataclasses.replace(scenario, log_period_s=0.1)
    scenario.visualization = VisualizationConfig(
        publish_period=1.0 / 30,
        publish_proximity=False,
        publish_contacts=False,
        publish_inertia=False,
        enable_alpha_sliders=False,
    )
    return scenario.validate()


def build_teleop(
    scenario,
    meshcat,
    realtime_rate: float = 1.0,
    margins=None,
    limits=None,
    x_initial=X_HOME,
    bus=None,
) -> TeleopRun:
    """The live closed loop of ``scenario`` in ``meshcat`` (module docstring), ready to run.

    Args:
        scenario: the robot and its controller (:func:`teleop_scenario` is applied).
        meshcat: a pydrake ``Meshcat``. realtime_rate: the Simulator's target real-time rate.
        margins: the display's hook (default :func:`robot_margins`: the torque margin of the
            scenario's motors and the clearance between the parts).
        limits: the reference's :class:`~stewart_drake.run.reference.ReferenceFilterLimits`.
        x_initial: (6,) the start pose [rad, m] (home).
        bus: on the robot (a scenario with ``bus``), the opened and configured
            :class:`~stewart_drake.station.bus.driver.DynamixelBus` the station drives
            (it reads the servos once here); the caller enables the torque.
    Raises:
        InvalidConfigError: a bad scenario or setting; UnreachablePoseError: x_initial.
    """
    from pydrake.systems.analysis import Simulator
    from pydrake.systems.framework import DiagramBuilder

    from ..plant.clearance import clearance_model
    from ..run.diagram import make_stewart_diagram
    from ..viz.visualize import CAMERA_POSITION, CAMERA_TARGET

    scenario = teleop_scenario(scenario)
    meshcat.SetCameraPose(np.array(CAMERA_POSITION), np.array(CAMERA_TARGET))
    meshcat.SetProperty("/Axes", "visible", False)  # the world triad would hide the base
    plan = make_plan(scenario, with_reference=False)
    geometry, peak = plan.geometry, plan.torque_limit_Nm
    x0 = np.asarray(x_initial, dtype=float)
    clearance = clearance_model(plan.plant_geometry)
    reference = _teleop_reference(scenario, plan, x0, limits, clearance)
    loop = make_stewart_diagram(plan, meshcat, reference_system=reference)
    builder = DiagramBuilder()
    builder.AddSystem(loop.diagram)
    lower, upper = slider_limits(reference.admissible, x0)
    sliders = PoseSliders(meshcat, x0, lower, upper, SLIDER_STEP)
    builder.AddNamedSystem("sliders", sliders)
    builder.Connect(sliders.get_output_port(), loop.diagram.GetInputPort("target"))
    display = TeleopDisplay(
        meshcat,
        margins or robot_margins(geometry, peak, clearance),
        ranges={
            "T margin [N m]": (0.0, peak or 1.0),
            "clearance [mm]": (0.0, 20.0),
            "limited": (0.0, 1.0),
        },
    )
    ghost = ReferenceGhost(meshcat, plan.plant_geometry)
    _add_views(builder, loop, display, ghost)
    diagram = builder.Build()
    diagram.set_name("teleop")
    simulator = Simulator(diagram)
    simulator.set_target_realtime_rate(realtime_rate)
    context = simulator.get_mutable_context()
    loop.initialize(context)
    if bus is not None:
        loop.station.use_bus(bus)  # type: ignore[union-attr]
    loop.station.assemble(context, x0)
    simulator.Initialize()
    meshcat.AddButton(PAUSE_BUTTON, "KeyP")  # (re)starts its count: running
    return TeleopRun(diagram, loop, sliders, reference, display, ghost, simulator, meshcat)


def _teleop_reference(scenario, plan, x0, limits, clearance) -> TeleopReference:
    """The live reference from ``x0`` on the robot of ``plan`` (``scenario``'s), stopped at the
    boundary of the admissible poses as the scenario's guard judges them (its thresholds, the
    motors' peak torque and ``clearance``, a
    :class:`~stewart_drake.plant.clearance.ClearanceModel`)."""
    from ..run.reference import TeleopReference, guarded_admissible

    return TeleopReference(
        plan.geometry,
        x0,
        scenario.control_period_s,
        limits,
        admissible=guarded_admissible(plan, clearance),
    )


def _add_views(builder, loop: StewartDiagram, display: TeleopDisplay, ghost: ReferenceGhost):
    """Add the display and the reference's ghost to ``builder``, fed by the closed loop's
    outputs."""
    builder.AddNamedSystem("display", display)
    builder.Connect(loop.diagram.GetOutputPort("platform_state"), display.GetInputPort("x"))
    builder.Connect(loop.diagram.GetOutputPort("x_d"), display.GetInputPort("x_d"))
    builder.Connect(loop.diagram.GetOutputPort("limited"), display.GetInputPort("limited"))
    builder.AddNamedSystem("ghost", ghost)
    builder.Connect(loop.diagram.GetOutputPort("x_d"), ghost.GetInputPort("x_d"))


def run_teleop(
    run: TeleopRun,
    duration_s: float | None = None,
    chunk_s: float = 0.1,
    report: Callable[[str], None] | None = print,
) -> dict:
    """Advance ``run`` in real time until ``duration_s`` (None: until Ctrl-C), guarded.

    Between chunks of ``chunk_s`` simulated s the :data:`PAUSE_BUTTON` is read: while paused
    the simulated time stands still (the loop sleeps ``chunk_s`` between reads) and, resumed,
    it goes on at real time from there (the pause is not caught up). ``duration_s`` counts
    simulated time, so a paused run waits for the button or Ctrl-C.

    Returns:
        {"sim_s": simulated s, "wall_s": wall s while running, "paused_s": wall s paused,
        "realtime_rate": sim_s / wall_s, "worst_rate": the lowest rate over any 10 s of running
        (the whole run if shorter)}, and "interrupted_by": the signal's number when Ctrl-C,
        SIGTERM or SIGHUP ended it.
    Raises:
        SimulationDivergedError: the guard stopped the run (the logs are saved).
    """
    from ..station import guard

    simulator = run.simulator
    simulator.ResetStatistics()  # pace from now: a pause before must not be caught up
    t_start, wall_start = simulator.get_context().get_time(), time.perf_counter()
    marks = [(wall_start, t_start)]
    interrupted_by, paused_s = None, 0.0
    try:
        while duration_s is None or simulator.get_context().get_time() < t_start + duration_s:
            if run.paused():
                pause_start = time.perf_counter()
                while run.paused():
                    time.sleep(chunk_s)
                paused_s += time.perf_counter() - pause_start
                simulator.ResetStatistics()  # resume at real time from here
            t_next = simulator.get_context().get_time() + chunk_s
            if duration_s is not None:
                t_next = min(t_next, t_start + duration_s)
            guard.advance(run.loop, simulator, functools.partial(simulator.AdvanceTo, t_next))
            marks.append((time.perf_counter() - paused_s, simulator.get_context().get_time()))
    except KeyboardInterrupt as err:  # Ctrl-C, or SIGTERM / SIGHUP through the CLI's handler
        interrupted_by = int(getattr(err, "signum", signal.SIGINT))
    wall = np.array([m[0] for m in marks]) - wall_start
    sim = np.array([m[1] for m in marks]) - t_start
    rates = [
        (sim[j] - sim[i]) / (wall[j] - wall[i])
        for i in range(len(marks))
        for j in (int(np.searchsorted(wall, wall[i] + 10.0)),)
        if j < len(marks) and wall[j] > wall[i]
    ]
    total = {
        "sim_s": float(sim[-1]),
        "wall_s": float(wall[-1]),
        "paused_s": float(paused_s),
        "realtime_rate": float(sim[-1] / wall[-1]) if wall[-1] > 0 else 0.0,
    }
    total["worst_rate"] = float(min(rates)) if rates else total["realtime_rate"]
    if interrupted_by is not None:
        total["interrupted_by"] = interrupted_by
    if report is not None:
        report(
            f"realtime_rate {total['realtime_rate']:.3f} over {total['sim_s']:.1f} s simulated "
            f"in {total['wall_s']:.1f} s wall (lowest over 10 s: {total['worst_rate']:.3f})"
            + (f"; paused {paused_s:.1f} s" if paused_s > 0 else "")
        )
    return total
