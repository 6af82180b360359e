"""See it: Meshcat replays of a run as one standalone HTML file, and pictures of the Diagram.

Replay: :func:`record_html` simulates a :class:`~stewart_drake.simulation.scenario.Scenario` (no visualizer in the
loop, so the run is as fast and as exact as ``run_experiment``), then plays the logged plant
states through a visualization-only copy of the robot at ``fps`` frames per second into a Meshcat
animation, and saves ``Meshcat.StaticHtml()``: the viewer's JavaScript and the scene are inlined,
so the file opens in any browser with no server (about 2.2 MB of viewer plus ~2 kB per frame).

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

from ..errors import InvalidConfigError, RenderToolMissingError
from ..fileio import atomic_write

#: Replay frame rate, frames per s: smooth to the eye, ~2 kB per frame in the HTML.
REPLAY_FPS = 30.0
#: Meshcat path under which the replay's geometry lives ("/drake/stewart/...").
REPLAY_PREFIX = "stewart"
#: Default camera position and target in world, m: the robot from the front-left, slightly above.
CAMERA_POSITION = (0.45, -0.45, 0.45)
CAMERA_TARGET = (0.0, 0.0, 0.15)
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


def record_states(meshcat, geometry, t, states, fps: float = REPLAY_FPS) -> int:
    """Record logged plant states as a Meshcat animation (illustration geometry only).

    A fresh plant of ``geometry`` (same joint order as the simulated one) with a
    ``MeshcatVisualizer`` of role illustration (no proximity, contact or inertia visuals) is set
    to the state nearest to each frame time and published into the recording, which is then
    published to ``meshcat``; the camera is aimed at the robot.

    Args:
        meshcat: a pydrake ``Meshcat``.
        geometry: the :class:`~.geometry.StewartGeometry` that was simulated.
        t: (N,) log times, s.
        states: (N, nq + nv) or (N, nq) plant states of that geometry's plant.
        fps: frames per s of the animation.
    Returns:
        the number of frames recorded.
    Raises:
        InvalidConfigError: states do not fit the plant, or bad ``fps``.
    """
    from pydrake.geometry import MeshcatVisualizer, MeshcatVisualizerParams, Role
    from pydrake.systems.framework import DiagramBuilder

    from ..model.plant import add_stewart_plant

    builder = DiagramBuilder()
    plant, scene_graph, _ = add_stewart_plant(builder, geometry)
    states = np.atleast_2d(np.asarray(states, dtype=float))
    nq = plant.num_positions()
    if states.shape[0] != np.size(t) or states.shape[1] < nq:
        raise InvalidConfigError(
            f"states must be (N, >= {nq}) with N = len(t) = {np.size(t)}, got {states.shape}: "
            f"pass the plant state log of the same geometry")
    frame_times, idx = frame_indices(t, fps)
    params = MeshcatVisualizerParams()
    params.role = Role.kIllustration
    params.publish_period = 1.0 / fps           # the recording's frames per second
    params.prefix = REPLAY_PREFIX
    visualizer = MeshcatVisualizer.AddToBuilder(builder, scene_graph, meshcat, params)
    diagram = builder.Build()
    context = diagram.CreateDefaultContext()
    plant_context = plant.GetMyMutableContextFromRoot(context)
    meshcat.SetCameraPose(np.array(CAMERA_POSITION), np.array(CAMERA_TARGET))
    meshcat.SetProperty("/Axes", "visible", False)    # the world triad would hide the base
    visualizer.StartRecording()
    for k, i in enumerate(idx):
        # Meshcat files a transform under frame floor(time * fps); k / fps can land a hair below
        # k and overwrite frame k - 1, so stamp a quarter frame late (round or floor give k).
        context.SetTime((k + 0.25) / fps)
        plant.SetPositions(plant_context, states[i, :nq])
        diagram.ForcedPublish(context)
    visualizer.StopRecording()
    visualizer.PublishRecording()
    return len(frame_times)


def write_static_html(meshcat, path: str | Path) -> Path:
    """Save ``meshcat.StaticHtml()`` (viewer JS + scene + animation inlined) atomically."""
    html = meshcat.StaticHtml()
    path = Path(path)
    atomic_write(path, lambda f: f.write(html.encode("utf-8")))
    return path


def record_html(config=None, path: str | Path = "results/replay.html", progress: bool = False,
                fps: float = REPLAY_FPS, meshcat=None, *, reference=None, controller=None):
    """Simulate a scenario and write its Meshcat replay as a standalone HTML file.

    The run is advanced through the same guard as ``run_experiment``: a diverging run stops with
    :class:`~stewart_drake.errors.SimulationDivergedError` and its logs saved, and no HTML.

    Args:
        config: a :class:`~stewart_drake.simulation.scenario.Scenario` (default: the paper's
            experiment, 10 s). reference, controller: as ``run_experiment``.
        path: the .html to write (folders are created).
        progress: show a progress bar while simulating.
        fps: replay frames per s (the 10 s paper run at 30 fps is about 3 MB).
        meshcat: a Meshcat to record into (default: a new one, local server on a free port).
    Returns:
        (RunResult, Path of the html): the same result ``run_experiment(config)`` gives.
    Raises:
        UnreachablePoseError, JointLimitError, SingularPoseError: the reference is refused
            (before simulating). SimulationDivergedError: the guard stopped the run.
    """
    from pydrake.geometry import Meshcat

    from ..simulation import guard
    from ..studies.experiments import advance, build_simulator, collect_result

    sd, simulator = build_simulator(config, reference=reference, controller=controller)
    wall0 = time.perf_counter()
    guard.advance(sd, simulator,
                  lambda: advance(simulator, sd.scenario.duration_s, progress))
    wall = time.perf_counter() - wall0
    context = simulator.get_context()
    result = collect_result(sd, context, wall)
    log = sd.loggers["state"].FindLog(context)
    meshcat = meshcat if meshcat is not None else Meshcat()
    record_states(meshcat, sd.scenario.plant_geometry(), log.sample_times(), log.data().T, fps)
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


def control_loop_dot(diagram) -> str:
    """A picture of the control loop: one box per system of the top-level Diagram (loggers left
    out), the station collapsed to the ports in use, each edge labelled with the signal's name
    and size. Built from ``Diagram.connection_map()``, so it is always the wiring that runs.

    Returns:
        DOT text (left to right).
    """
    edges, used = [], {}
    for (dst, i), (src, j) in diagram.connection_map().items():
        if type(dst).__name__ == "VectorLogSink":
            continue
        out, inp = src.get_output_port(j), dst.get_input_port(i)
        used.setdefault(src.get_name(), (src, set(), set()))[2].add(out.get_name())
        used.setdefault(dst.get_name(), (dst, set(), set()))[1].add(inp.get_name())
        size = f" ({out.size()})" if out.get_data_type().name == "kVectorValued" else ""
        edges.append(f'  "{src.get_name()}":"out_{out.get_name()}" -> '
                     f'"{dst.get_name()}":"in_{inp.get_name()}" [label="{out.get_name()}{size}", '
                     f'fontsize=9];')
    lines = ["digraph control_loop {", "  rankdir=LR;", '  node [shape=none, fontsize=10];']
    for name in sorted(used):
        system, inputs, outputs = used[name]
        rows = max(len(inputs), len(outputs), 1)
        ins, outs = sorted(inputs), sorted(outputs)
        cells = "".join(
            "<TR>"
            + (f'<TD PORT="in_{ins[k]}" BORDER="1">{ins[k]}</TD>' if k < len(ins)
               else '<TD BORDER="0"></TD>')
            + (f'<TD PORT="out_{outs[k]}" BORDER="1">{outs[k]}</TD>' if k < len(outs)
               else '<TD BORDER="0"></TD>')
            + "</TR>" for k in range(rows))
        color = ' BGCOLOR="#dbe9f6"' if name == "station" else ""
        lines.append(f'  "{name}" [label=<<TABLE BORDER="0" CELLSPACING="0"><TR><TD BORDER="1" '
                     f'COLSPAN="2"{color}><B>{name}</B><BR/>{type(system).__name__}</TD></TR>'
                     f"{cells}</TABLE>>];")
    return "\n".join(lines + sorted(edges) + ["}", ""])


def diagram_dots() -> dict[str, str]:
    """Graphviz sources of the Diagram pictures, normalized (:func:`normalize_dot`).

    Returns:
        {name: DOT text}: ``control_loop`` (:func:`control_loop_dot` of the fixed-weight LQI
        loop: the station collapsed to the ports in use), ``diagram_fixed`` and ``diagram_ann``
        (Drake's picture of the whole closed loop, one level deep, with fixed weights and with
        the ANN tuner), ``station`` (the robot's Diagram inside), ``lqi_controller``,
        ``density_features``, ``ann_tuner`` and ``crank_pd`` (the controller systems and their
        ports: each follows the controller contract, so either plugs into the same Diagram).
    """
    from ..simulation.diagram import make_stewart_diagram
    from ..simulation.scenario import AnnTunerDriver, PdDriver, Scenario

    fixed = make_stewart_diagram(Scenario())
    ann = make_stewart_diagram(Scenario(tuner=AnnTunerDriver()))
    pd = make_stewart_diagram(Scenario(controller=PdDriver()))
    raw = {"control_loop": control_loop_dot(fixed.diagram),
           "diagram_fixed": fixed.diagram.GetGraphvizString(max_depth=1),
           "diagram_ann": ann.diagram.GetGraphvizString(max_depth=1),
           "station": fixed.station.GetGraphvizString(max_depth=1),
           "lqi_controller": fixed.controller.GetGraphvizString(),
           "density_features": ann.features.GetGraphvizString(),
           "ann_tuner": ann.tuner.GetGraphvizString(),
           "crank_pd": pd.controller.GetGraphvizString()}
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
            "render the .svg pictures; the .dot sources were written")
    svg = subprocess.run([exe, "-Tsvg"], input=dot, capture_output=True, text=True,
                         check=True).stdout
    stamp = _HASH_COMMENT.format(dot_hash(dot))
    head, sep, rest = svg.partition("?>\n")            # after the XML declaration
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
