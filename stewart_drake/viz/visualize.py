"""See it: Meshcat replays of a run as one standalone HTML file, and pictures of the Diagram.

Replay: :func:`record_html` simulates a :class:`~stewart_drake.run.scenario.Scenario`
(no visualizer in the loop, so the run is as fast and as exact as ``run_experiment``), then
plays the logged plant states through a visualization-only copy of the robot at ``fps`` frames
per second into a Meshcat animation, with the reference as a translucent ghost of the platform
(:func:`add_reference_ghost`), and saves ``Meshcat.StaticHtml()``: the viewer's JavaScript and
the scene are inlined, so the file opens in any browser with no server (about 2.2 MB of viewer
plus ~2 kB per frame).

Diagram pictures: :func:`diagram_dots` returns the Graphviz source of the full Diagram (fixed
weights and ANN tuner) and of the controller systems, with Drake's process-dependent system ids
renumbered so the text is the same in every process; :func:`write_diagrams` stores ``<name>.dot``
and renders ``<name>.svg`` with Graphviz ``dot``, stamping the SVG with the SHA-256 of its .dot
(:func:`svg_dot_hash`) so a stale picture is detected without Graphviz.
"""

from __future__ import annotations

import hashlib
import re
import shutil
import subprocess
import time
from pathlib import Path

import numpy as np

from ..base.errors import InvalidConfigError, RenderToolMissingError
from ..base.fileio import atomic_write
from ..robot.limits import DEFAULT_MIN_CLEARANCE_M

#: Replay frame rate, frames per s: smooth to the eye, ~2 kB per frame in the HTML.
REPLAY_FPS = 30.0
#: Meshcat path under which the replay's geometry lives ("/drake/stewart/...").
REPLAY_PREFIX = "stewart"
#: Camera position and target in world, m, of the live views and of the replay's first frame:
#: from the front (+X, a little to -Y), 40 degrees above, 0.57 m from a point between base and
#: platform, so the platform's top, all six legs and the base are in view.
CAMERA_POSITION = (0.36, -0.24, 0.55)
CAMERA_TARGET = (0.0, 0.0, 0.18)
#: Meshcat path of the reference's ghost: a translucent copy of the platform drawn at x_d.
GHOST_PATH = "/drake/reference_ghost"
#: The ghost's colour (RGBA): light blue, mostly transparent, unlike any part of the robot.
GHOST_RGBA = (0.3, 0.6, 1.0, 0.35)
#: Where ``stewart-drake diagrams`` writes by default: ``diagrams/`` in the current folder (from
#: the repository's root, the committed pictures).
DIAGRAMS_DIR = Path("diagrams")
_HASH_COMMENT = "<!-- dot-sha256: {} -->"
#: Browsers that can show a Meshcat page headless (tools/screenshot_replay.py,
#: tools/chromium_cdp.py).
CHROMIUM_NAMES = ("chromium", "chromium-browser", "google-chrome", "google-chrome-stable")


def find_chromium() -> str | None:
    """Path of a Chromium-family browser on PATH (:data:`CHROMIUM_NAMES`), or None."""
    for name in CHROMIUM_NAMES:
        path = shutil.which(name)
        if path:
            return path
    return None


def frame_indices(t: np.ndarray, fps: float) -> tuple[np.ndarray, np.ndarray]:
    """Frames at ``fps`` over the logged times ``t`` and, for each, the nearest log sample.

    Args:
        t: (N,) increasing log times, s.
        fps: frames per s, > 0.
    Returns:
        (frame_times (F,) s = k / fps for k = 0 .. floor(t[-1] * fps), indices (F,) into t).
    Raises:
        InvalidConfigError: fps not > 0, or fewer than one logged sample.
    """
    t = np.asarray(t, dtype=float)
    if not (np.isfinite(fps) and fps > 0):
        raise InvalidConfigError(f"fps must be a finite number > 0, got {fps}")
    if t.size == 0:
        raise InvalidConfigError("no logged samples to replay: simulate for longer than 0 s")
    frame_times = np.arange(int(np.floor(t[-1] * fps + 1e-9)) + 1) / fps
    idx = np.clip(np.searchsorted(t, frame_times), 0, t.size - 1)
    before = np.clip(idx - 1, 0, t.size - 1)
    idx = np.where(np.abs(t[before] - frame_times) <= np.abs(t[idx] - frame_times), before, idx)
    return frame_times, idx


def add_reference_ghost(meshcat, geometry, path: str = GHOST_PATH) -> str:
    """Draw the reference's ghost in ``meshcat``: every part of the platform (plate, studs,
    tool; :func:`~stewart_drake.robot.parts.robot_parts`) in :data:`GHOST_RGBA`, under ``path``
    at the home pose; :func:`ghost_transform` places it.

    Args:
        meshcat: a pydrake ``Meshcat``. geometry: the
            :class:`~stewart_drake.robot.geometry.StewartGeometry` drawn.
    Returns:
        ``path``.
    """
    from pydrake.geometry import Box, Capsule, Cylinder, Rgba, Sphere
    from pydrake.math import RigidTransform, RotationMatrix

    from ..robot.kinematics import X_HOME
    from ..robot.parts import robot_parts

    shapes = {"box": Box, "capsule": Capsule, "cylinder": Cylinder, "sphere": Sphere}
    for part in robot_parts(geometry):
        if part.link == "platform":
            child = f"{path}/{part.name}"
            meshcat.SetObject(child, shapes[part.shape](*part.size), Rgba(*GHOST_RGBA))
            X_EG = RigidTransform(RotationMatrix(part.R_LG), part.p_LG.tolist())
            meshcat.SetTransform(child, X_EG)
    meshcat.SetTransform(path, ghost_transform(X_HOME))
    return path


def ghost_transform(x_d):
    """X_WE, the ``RigidTransform`` of the platform frame at the reference pose ``x_d`` ((6,)
    or longer: its first six [rad, m])."""
    from ..plant.plant import pose_to_transform

    return pose_to_transform(np.asarray(x_d, dtype=float)[:6])


def _mark_contacts(animation, frame: int, markers: list, shown: list, close: list) -> None:
    """Frame ``frame`` of the animation: marker j between the closest points of the j-th
    closest pair of ``close`` (red touching, orange near), hidden without one; ``shown`` keeps
    what each marker shows (only changes are recorded)."""
    from pydrake.math import RigidTransform

    for j, (path, colours) in enumerate(markers):
        contact = close[j] if j < len(close) else None
        kind = None if contact is None else ("touch" if contact.distance <= 0 else "near")
        if contact is not None:  # kind is not None
            animation.SetTransform(frame, path, RigidTransform(0.5 * (contact.p_WA + contact.p_WB)))
        if kind != shown[j]:
            animation.SetProperty(frame, path, "visible", kind is not None)
            if kind is not None:
                animation.SetProperty(frame, path + "/<object>", "color", colours[kind])
            shown[j] = kind


def record_states(
    meshcat,
    geometry,
    t,
    states,
    fps: float = REPLAY_FPS,
    clearance_m: float = DEFAULT_MIN_CLEARANCE_M,
    x_d=None,
    error=None,
) -> int:
    """Record logged plant states as a Meshcat animation (illustration geometry), with markers
    where two parts touch and, given ``x_d``, the reference's ghost (and given ``error``, a
    marker above it coloured by the tracking error).

    A fresh plant of ``geometry`` (same joint order as the simulated one) with a
    ``MeshcatVisualizer`` of role illustration (no proximity or inertia visuals) is set to the
    state nearest to each frame time and published into the recording, which is then published
    to ``meshcat``; the camera is aimed at the robot. At every frame the parts closer than
    ``clearance_m`` (:mod:`~stewart_drake.plant.clearance`) get a marker between their closest
    points, red where they touch or overlap, orange where they are only close (at most
    :data:`CONTACT_MARKERS` at a time, the closest pairs). With ``x_d`` the reference's ghost
    (:func:`add_reference_ghost`) is at ``x_d`` of the same log sample in every frame; with
    ``error`` too, a sphere :data:`ERROR_MARKER_HEIGHT_M` above the ghost shows that sample's
    error against the tolerance (:func:`error_colour`).

    Args:
        meshcat: a pydrake ``Meshcat``.
        geometry: the :class:`~.geometry.StewartGeometry` that was simulated.
        t: (N,) log times, s.
        states: (N, nq + nv) or (N, nq) plant states of that geometry's plant, rods as bodies
            or as distance constraints (drawn with the rods' shapes from crank tip to platform
            joint, :func:`~stewart_drake.plant.plant.rod_bodies_positions`).
        fps: frames per s of the animation.
        clearance_m: parts closer than this are marked, m.
        x_d: (N, >= 6) the reference logged with ``states`` [rad, m], or None (no ghost).
        error: ((N,) translation error at the same samples, m; tolerance, m), or None (no
            marker; needs ``x_d``).
    Returns:
        the number of frames recorded.
    Raises:
        InvalidConfigError: states, x_d or error do not fit the plant and t, or bad ``fps``.
    """
    # Long for its docstring; the per-frame markers are _mark_contacts.
    from pydrake.geometry import MeshcatVisualizer, MeshcatVisualizerParams, Role
    from pydrake.systems.framework import DiagramBuilder

    from ..plant.clearance import clearance_model
    from ..plant.plant import DISTANCE_NQ, DISTANCE_NV, add_stewart_plant, rod_bodies_positions

    builder = DiagramBuilder()
    plant, scene_graph, _ = add_stewart_plant(builder, geometry)
    states = np.atleast_2d(np.asarray(states, dtype=float))
    nq = plant.num_positions()
    if states.shape[1] in (DISTANCE_NQ, DISTANCE_NQ + DISTANCE_NV):  # rods as constraints
        states = rod_bodies_positions(geometry, states)
    if states.shape[0] != np.size(t) or states.shape[1] < nq:
        raise InvalidConfigError(
            f"states must be (N, >= {nq}) with N = len(t) = {np.size(t)}, got {states.shape}: "
            f"pass the plant state log of the same geometry"
        )
    if x_d is not None:
        x_d = np.atleast_2d(np.asarray(x_d, dtype=float))
        if x_d.shape[0] != np.size(t) or x_d.shape[1] < 6:
            raise InvalidConfigError(
                f"x_d must be (N, >= 6) with N = len(t) = {np.size(t)}, got {x_d.shape}: pass "
                f"the reference logged with the states"
            )
    if error is not None and np.shape(error[0]) != (np.size(t),):
        raise InvalidConfigError(
            f"error must be (N,) with N = len(t) = {np.size(t)}, got {np.shape(error[0])}"
        )
    frame_times, idx = frame_indices(t, fps)
    params = MeshcatVisualizerParams()
    params.role = Role.kIllustration
    params.publish_period = 1.0 / fps  # the recording's frames per second
    params.prefix = REPLAY_PREFIX
    visualizer = MeshcatVisualizer.AddToBuilder(builder, scene_graph, meshcat, params)
    diagram = builder.Build()
    context = diagram.CreateDefaultContext()
    plant_context = plant.GetMyMutableContextFromRoot(context)
    meshcat.SetCameraPose(np.array(CAMERA_POSITION), np.array(CAMERA_TARGET))
    meshcat.SetProperty("/Axes", "visible", False)  # the world triad would hide the base
    markers = _contact_markers(meshcat)
    ghost = add_reference_ghost(meshcat, geometry) if x_d is not None else None
    marker = _error_marker(meshcat) if error is not None and ghost is not None else None
    colour = None
    model = clearance_model(geometry)
    visualizer.StartRecording()
    animation = visualizer.get_mutable_recording()
    shown = [None] * len(markers)
    for k, i in enumerate(idx):
        # Meshcat files a transform under frame floor(time * fps); k / fps can land a hair below
        # k and overwrite frame k - 1, so stamp a quarter frame late (round or floor give k).
        context.SetTime((k + 0.25) / fps)
        plant.SetPositions(plant_context, states[i, :nq])
        diagram.ForcedPublish(context)
        _mark_contacts(
            animation, k, markers, shown, model.contacts(None, clearance_m, q=states[i, :nq])
        )
        if ghost is not None:
            X_WE = ghost_transform(x_d[i])
            animation.SetTransform(k, ghost, X_WE)
        if marker is not None:
            from pydrake.math import RigidTransform

            p = X_WE.translation() + np.array([0.0, 0.0, ERROR_MARKER_HEIGHT_M])
            animation.SetTransform(k, marker, RigidTransform(p))
            new = error_colour(float(error[0][i]), float(error[1]))
            if new != colour:  # only changes are recorded
                animation.SetProperty(k, marker + "/<object>", "color", list(new))
                colour = new
    visualizer.StopRecording()
    visualizer.PublishRecording()
    return len(frame_times)


#: Meshcat path of the tracking error's marker, and its height above the reference's ghost, m.
ERROR_MARKER_PATH = "/drake/tracking_error"
ERROR_MARKER_HEIGHT_M = 0.06
#: The error marker's colours (RGBA): within half the tolerance, within it, beyond it.
ERROR_COLOURS = (
    (0.1, 0.75, 0.2, 0.9),
    (1.0, 0.75, 0.0, 0.9),
    (0.9, 0.1, 0.1, 0.9),
)


def error_colour(error_m: float, tolerance_m: float) -> tuple:
    """The error marker's colour (:data:`ERROR_COLOURS`): green for an error at most half the
    tolerance, amber up to the tolerance, red beyond it (and for an error that is not finite)."""
    if error_m <= 0.5 * tolerance_m:
        return ERROR_COLOURS[0]
    return ERROR_COLOURS[1] if error_m <= tolerance_m else ERROR_COLOURS[2]


def _error_marker(meshcat) -> str:
    """The tracking error's marker (a 6 mm sphere), drawn green; returns its path."""
    from pydrake.geometry import Rgba, Sphere

    meshcat.SetObject(ERROR_MARKER_PATH, Sphere(0.006), Rgba(*ERROR_COLOURS[0]))
    return ERROR_MARKER_PATH


#: How many pairs of close parts a replay marks at once (the closest ones).
CONTACT_MARKERS = 4


def _contact_markers(meshcat) -> list:
    """The replay's contact markers, hidden: [(Meshcat path, {"touch": rgba, "near": rgba})]."""
    from pydrake.geometry import Rgba, Sphere

    colours = {"touch": [1.0, 0.0, 0.0, 0.9], "near": [1.0, 0.6, 0.0, 0.9]}
    out = []
    for j in range(CONTACT_MARKERS):
        path = f"/drake/{REPLAY_PREFIX}_contacts/{j}"
        meshcat.SetObject(path, Sphere(0.008), Rgba(*colours["touch"]))
        meshcat.SetProperty(path, "visible", False)
        out.append((path, colours))
    return out


def offline_meshcat():
    """A ``Meshcat`` to record a replay into, its web server (Drake's Meshcat always runs one:
    ``MeshcatParams`` has no option without it, in 1.51 as in 1.58) bound to this machine only
    and to a free ephemeral port (not the 7000.. ports a live ``teleop`` takes); nothing
    connects to it, and it closes with the Meshcat."""
    from pydrake.geometry import Meshcat, MeshcatParams

    return Meshcat(MeshcatParams(host="localhost", port=0))


def write_static_html(meshcat, path: str | Path, caption: str = "") -> Path:
    """Save ``meshcat.StaticHtml()`` (viewer JS + scene + animation inlined) atomically, with
    ``caption`` (plain text, escaped; lines kept) in a box over the top left of the view."""
    import html as html_text

    html = meshcat.StaticHtml()
    if caption:
        box = (
            '<div id="stewart-caption" style="position:fixed;top:8px;left:8px;z-index:10;'
            "max-width:46em;padding:6px 9px;background:rgba(255,255,255,0.85);"
            'font:12px sans-serif;white-space:pre-line;pointer-events:none">'
            f"{html_text.escape(caption)}</div>"
        )
        html = html.replace("<body>", "<body>\n" + box, 1)
    path = Path(path)
    atomic_write(path, lambda f: f.write(html.encode("utf-8")))
    return path


def record_html(
    config=None,
    path: str | Path = "results/replay.html",
    progress: bool = False,
    fps: float = REPLAY_FPS,
    meshcat=None,
    *,
    reference=None,
    controller=None,
):
    """Simulate a scenario and write its Meshcat replay as a standalone HTML file.

    The run is advanced through the same guard as ``run_experiment``: a diverging run stops with
    :class:`~stewart_drake.base.errors.SimulationDivergedError` and its logs saved, and no HTML.

    Args:
        config: a :class:`~stewart_drake.run.scenario.Scenario` (default: the paper's
            experiment, 10 s). reference, controller: as ``run_experiment``.
        path: the .html to write (folders are created).
        progress: show a progress bar while simulating.
        fps: replay frames per s (the 10 s paper run at 30 fps is about 3 MB).
        meshcat: a Meshcat to record into (default: :func:`offline_meshcat`).
    Returns:
        (RunResult, Path of the html): the same result ``run_experiment(config)`` gives.
    Raises:
        UnreachablePoseError, JointLimitError, SingularPoseError: the reference is refused
            (before simulating). SimulationDivergedError: the guard stopped the run.
    """
    from ..run.result import collect_result
    from ..run.simulate import advance, build_simulator
    from ..station import guard

    sd, simulator = build_simulator(config, reference=reference, controller=controller)
    wall0 = time.perf_counter()
    guard.advance(sd, simulator, lambda: advance(simulator, sd.scenario.duration_s, progress))
    wall = time.perf_counter() - wall0
    context = simulator.get_context()
    result = collect_result(sd, context, wall)
    meshcat = meshcat if meshcat is not None else offline_meshcat()
    x_d = np.concatenate(sd.trajectory.evaluate(result.t_state), axis=1)
    record_states(meshcat, sd.plan.plant_geometry, result.t_state, result.state, fps, x_d=x_d)
    return result, write_static_html(meshcat, path)


# -- pictures of the Diagram --------------------------------------------------------------------


def normalize_dot(dot: str) -> str:
    """The same Graphviz text for the same Diagram, whatever ran before in the process.

    Drake numbers systems with a process-wide counter (``s123``, ``_123``, ``cluster123...``)
    and lists edges in the order of its connection map, keyed by memory address. Systems are
    renumbered by first appearance (the node list comes first, in the order they were added),
    then each run of consecutive edge lines is sorted.
    """
    ids: dict[str, str] = {}

    def renumber(match: re.Match) -> str:
        return match.group(1) + ids.setdefault(match.group(2), str(len(ids)))

    lines = re.sub(r"(digraph _|clusters?|\bs)(\d+)", renumber, dot).split("\n")
    out, edges = [], []
    for line in lines + [""]:
        if " -> " in line:
            edges.append(line)
            continue
        out += sorted(edges)
        edges = []
        out.append(line)
    return "\n".join(out[:-1])


def _html_node(name: str, kind: str, inputs, outputs, color: str = "") -> str:
    """A Graphviz node: a title cell, then the input ports left and the output ports right."""
    ins, outs = sorted(inputs), sorted(outputs)
    cells = "".join(
        "<TR>"
        + (
            f'<TD PORT="in_{ins[k]}" BORDER="1">{ins[k]}</TD>'
            if k < len(ins)
            else '<TD BORDER="0"></TD>'
        )
        + (
            f'<TD PORT="out_{outs[k]}" BORDER="1">{outs[k]}</TD>'
            if k < len(outs)
            else '<TD BORDER="0"></TD>'
        )
        + "</TR>"
        for k in range(max(len(ins), len(outs), 1))
    )
    color = f' BGCOLOR="{color}"' if color else ""
    return (
        f'  "{name}" [label=<<TABLE BORDER="0" CELLSPACING="0"><TR><TD BORDER="1" '
        f'COLSPAN="2"{color}><B>{name}</B><BR/>{kind}</TD></TR>{cells}</TABLE>>];'
    )


def wiring_dot(diagram, title: str = "", highlight: tuple = ("station",)) -> str:
    """A picture of a Diagram's wiring: one box per subsystem (loggers left out) with only the
    ports in use, each edge labelled with the signal's name and size, and the Diagram's own
    exported ports as the boxes ``inputs`` and ``outputs``. Built from ``connection_map()`` and
    the exported ports' locators, so it is always the wiring that runs, and it leaves out the
    ports nobody connects (a Drake release that adds ports to the plant draws the same picture).

    Args:
        diagram: a built Drake ``Diagram``.
        title: a caption drawn above the picture ("" for none).
        highlight: names of subsystems drawn shaded (the station in a closed loop).
    Returns:
        DOT text (left to right).
    """
    from pydrake.systems.framework import InputPortIndex, OutputPortIndex

    def vector_size(port) -> str:
        return f" ({port.size()})" if port.get_data_type().name == "kVectorValued" else ""

    edges: list = []
    used: dict = {}

    def edge(src, out_name, dst, in_name, label):
        used.setdefault(src[0], (src[1], set(), set()))[2].add(out_name)
        used.setdefault(dst[0], (dst[1], set(), set()))[1].add(in_name)
        edges.append(
            f'  "{src[0]}":"out_{out_name}" -> "{dst[0]}":"in_{in_name}" '
            f'[label="{label}", fontsize=9];'
        )

    for (dst, i), (src, j) in diagram.connection_map().items():
        if type(dst).__name__ in ("VectorLogSink", "SignalLog"):
            continue
        out, inp = src.get_output_port(j), dst.get_input_port(i)
        edge(
            (src.get_name(), type(src).__name__),
            out.get_name(),
            (dst.get_name(), type(dst).__name__),
            inp.get_name(),
            out.get_name() + vector_size(out),
        )
    for i in range(diagram.num_input_ports()):
        port = diagram.get_input_port(i)
        for dst, j in diagram.GetInputPortLocators(InputPortIndex(i)):
            edge(
                ("inputs", "exported"),
                port.get_name(),
                (dst.get_name(), type(dst).__name__),
                dst.get_input_port(j).get_name(),
                port.get_name() + vector_size(port),
            )
    for i in range(diagram.num_output_ports()):
        port = diagram.get_output_port(i)
        src, j = diagram.get_output_port_locator(OutputPortIndex(i))
        edge(
            (src.get_name(), type(src).__name__),
            src.get_output_port(j).get_name(),
            ("outputs", "exported"),
            port.get_name(),
            port.get_name() + vector_size(port),
        )
    lines = [
        f"digraph {_dot_id(diagram.get_name())} {{",
        "  rankdir=LR;",
        "  node [shape=none, fontsize=10];",
    ]
    if title:
        lines.append(f'  labelloc=t; fontsize=12; label="{title}";')
    for name in sorted(used):
        kind, inputs, outputs = used[name]
        lines.append(
            _html_node(
                name,
                kind,
                inputs,
                outputs,
                "#dbe9f6"
                if name in highlight
                else "#eeeeee"
                if name in ("inputs", "outputs")
                else "",
            )
        )
    return "\n".join(lines + sorted(edges) + ["}", ""])


def _dot_id(name: str) -> str:
    return re.sub(r"\W", "_", name) or "diagram"


def control_loop_dot(diagram, title: str = "") -> str:
    """The control loop: :func:`wiring_dot` of the whole closed-loop Diagram, the station drawn
    with the ports in use only.

    Returns:
        DOT text (left to right).
    """
    return wiring_dot(diagram, title)


def titled(dot: str, title: str) -> str:
    """A Drake ``GetGraphvizString`` picture with ``title`` as its caption."""
    head, sep, rest = dot.partition("\n")
    return f'{head}{sep}labelloc=t\nfontsize=12\nlabel="{title}"\n{rest}'


#: The captions of the pictures of the two shipped robots (DOT "\\n" breaks the line).
HARDWARE_CAPTION = (
    "the robot as built (paper_hardware, the default of stewart-drake run)\\n"
    "station: encoders, computation delay, servos with current loop, friction "
    "and torque limit; the LQI estimates the pose from the encoders (FK)"
)
IDEAL_CAPTION = (
    "the ideal robot (paper_ideal)\\nthe controller reads the exact pose; ideal "
    "torque sources, no friction, no delay"
)


def diagram_dots() -> dict[str, str]:
    """Graphviz sources of the Diagram pictures, normalized (:func:`normalize_dot`).

    Every picture is built from the default scenario of ``stewart-drake run``, the robot as
    built (``paper_hardware``), but the ones whose name ends in ``_ideal`` (``paper_ideal``).

    Returns:
        {name: DOT text}: ``control_loop`` and ``control_loop_ideal`` (:func:`control_loop_dot`
        of the fixed-weight LQI loop: the station with the ports in use), ``station`` and
        ``station_ideal`` (:func:`wiring_dot` of the robot's Diagram inside), ``diagram_fixed``
        and ``diagram_ann`` (Drake's picture of the whole closed loop, one level deep, with fixed
        weights and with the ANN tuner), ``lqi_controller``, ``density_features``,
        ``ann_tuner`` and ``crank_pd`` (the controller systems and their ports: each follows
        the controller contract, so either plugs into the same Diagram).
    """
    from ..control.tuning import AnnTunerDriver
    from ..run.diagram import make_stewart_diagram
    from ..run.scenario import PdDriver, use_paper_tuner
    from ..run.scenario_io import DEFAULT_SCENARIO, load_scenario

    def scenario(name=DEFAULT_SCENARIO):
        return load_scenario(name)

    fixed = make_stewart_diagram(scenario())
    ideal = make_stewart_diagram(scenario("paper_ideal"))
    ann = make_stewart_diagram(use_paper_tuner(scenario(), AnnTunerDriver()))
    pd = scenario()
    pd.controller = PdDriver()
    pd = make_stewart_diagram(pd)
    raw = {
        "control_loop": control_loop_dot(
            fixed.diagram, f"closed loop with the LQI: {HARDWARE_CAPTION}"
        ),
        "control_loop_ideal": control_loop_dot(
            ideal.diagram, f"closed loop with the LQI: {IDEAL_CAPTION}"
        ),
        "station": wiring_dot(
            fixed.station, f"inside the station: {HARDWARE_CAPTION}", highlight=()
        ),
        "station_ideal": wiring_dot(
            ideal.station, f"inside the station: {IDEAL_CAPTION}", highlight=()
        ),
        "diagram_fixed": titled(
            fixed.diagram.GetGraphvizString(max_depth=1), f"fixed weights: {HARDWARE_CAPTION}"
        ),
        "diagram_ann": titled(
            ann.diagram.GetGraphvizString(max_depth=1), f"the paper's ANN tuner: {HARDWARE_CAPTION}"
        ),
        "lqi_controller": fixed.controller.GetGraphvizString(),
        # With the paper's tuner the loop has both (StewartDiagram types them optional).
        "density_features": ann.features.GetGraphvizString(),  # type: ignore[union-attr]
        "ann_tuner": ann.tuner.GetGraphvizString(),  # type: ignore[union-attr]
        "crank_pd": pd.controller.GetGraphvizString(),
    }
    return {name: normalize_dot(dot) for name, dot in raw.items()}


def dot_hash(dot: str) -> str:
    """SHA-256 hex digest of a DOT text (UTF-8)."""
    return hashlib.sha256(dot.encode("utf-8")).hexdigest()


def svg_dot_hash(svg: str) -> str | None:
    """The DOT hash stamped into an SVG by :func:`write_diagrams`, or None if there is none."""
    match = re.search(r"<!-- dot-sha256: ([0-9a-f]{64}) -->", svg)
    return match.group(1) if match else None


def render_svg(dot: str, dot_executable: str | None = None) -> str:
    """SVG text of ``dot`` rendered by Graphviz, stamped with ``<!-- dot-sha256: ... -->``.

    Raises:
        RenderToolMissingError: Graphviz ``dot`` is not on PATH.
    """
    exe = dot_executable or shutil.which("dot")
    if exe is None:
        raise RenderToolMissingError(
            "Graphviz `dot` is not on PATH: install graphviz (e.g. `apt install graphviz`) to "
            "render the .svg pictures; the .dot sources were written"
        )
    svg = subprocess.run(
        [exe, "-Tsvg"], input=dot, capture_output=True, text=True, check=True
    ).stdout
    stamp = _HASH_COMMENT.format(dot_hash(dot))
    head, sep, rest = svg.partition("?>\n")  # after the XML declaration
    return head + sep + stamp + "\n" + rest if sep else stamp + "\n" + svg


def write_diagrams(out_dir: str | Path = DIAGRAMS_DIR, render: bool = True) -> list[Path]:
    """Write ``<name>.dot`` for each of :func:`diagram_dots` and, if ``render``, ``<name>.svg``.

    Returns:
        the paths written.
    Raises:
        RenderToolMissingError: ``render`` and no Graphviz ``dot`` (the .dot files are written).
    """
    out = Path(out_dir)
    dots = diagram_dots()
    written = []
    for name, dot in dots.items():
        path = out / f"{name}.dot"
        atomic_write(path, lambda f, d=dot: f.write(d.encode("utf-8")))
        written.append(path)
    if render:
        for name, dot in dots.items():
            svg = render_svg(dot)
            path = out / f"{name}.svg"
            atomic_write(path, lambda f, s=svg: f.write(s.encode("utf-8")))
            written.append(path)
    return written
