"""See it: Meshcat replays of a run as one standalone HTML file.

:func:`record_html` simulates a :class:`~stewart_drake.run.scenario.Scenario`
(no visualizer in the loop, so the run is as fast and as exact as ``run_experiment``), then
plays the logged plant states through a visualization-only copy of the robot at ``fps`` frames
per second into a Meshcat animation, with the reference as a translucent ghost of the platform
(:func:`add_reference_ghost`), and saves ``Meshcat.StaticHtml()``: the viewer's JavaScript and
the scene are inlined, so the file opens in any browser with no server (about 2.2 MB of viewer
plus ~2 kB per frame). Pictures of the Diagram are :mod:`~.diagrams`'.
"""

from __future__ import annotations

import shutil
import time
from pathlib import Path

import numpy as np

from ..base.errors import InvalidConfigError
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

    Each frame shows the state nearest its time on a fresh plant of ``geometry`` (role
    illustration); parts closer than ``clearance_m`` (:mod:`~stewart_drake.plant.clearance`) get
    a marker, red touching, orange close (at most :data:`CONTACT_MARKERS`); the ghost
    (:func:`add_reference_ghost`) is at ``x_d``, and a sphere :data:`ERROR_MARKER_HEIGHT_M`
    above it shows the error (:func:`error_colour`); docs/pictures.md, "Replay in 3-D".

    Args:
        meshcat: a pydrake ``Meshcat``.
        geometry: the :class:`~.geometry.StewartGeometry` that was simulated.
        t: (N,) log times, s.
        states: (N, nq + nv) or (N, nq) plant states of that geometry's plant, rods as bodies
            or as distance constraints (drawn with the rods' shapes from crank tip to platform
            joint, :func:`~stewart_drake.plant.closed_chain.rod_bodies_positions`).
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
    from pydrake.systems.framework import DiagramBuilder

    from ..plant.clearance import clearance_model
    from ..plant.plant import add_stewart_plant

    builder = DiagramBuilder()
    plant, scene_graph, _ = add_stewart_plant(builder, geometry)
    nq = plant.num_positions()
    states, x_d = _checked_log(geometry, nq, t, states, x_d, error)
    frame_times, idx = frame_indices(t, fps)
    visualizer = _replay_visualizer(builder, scene_graph, meshcat, fps)
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
            colour = _mark_reference(animation, k, ghost, marker, x_d[i], error, i, colour)
    visualizer.StopRecording()
    visualizer.PublishRecording()
    return len(frame_times)


def _checked_log(geometry, nq: int, t, states, x_d, error):
    """(states (N, >= nq) of the plant with rods as bodies, x_d (N, >= 6) or None) of
    :func:`record_states`' arguments, states of a plant with rods as distance constraints
    redrawn with rods (:func:`~stewart_drake.plant.closed_chain.rod_bodies_positions`).

    Raises:
        InvalidConfigError: states, x_d or error do not fit the plant and t.
    """
    from ..plant.closed_chain import rod_bodies_positions
    from ..plant.plant import DISTANCE_NQ, DISTANCE_NV

    states = np.atleast_2d(np.asarray(states, dtype=float))
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
    return states, x_d


def _replay_visualizer(builder, scene_graph, meshcat, fps: float):
    """A ``MeshcatVisualizer`` of the illustration role under :data:`REPLAY_PREFIX`, publishing
    ``fps`` frames per s, added to ``builder``."""
    from pydrake.geometry import MeshcatVisualizer, MeshcatVisualizerParams, Role

    params = MeshcatVisualizerParams()
    params.role = Role.kIllustration
    params.publish_period = 1.0 / fps  # the recording's frames per second
    params.prefix = REPLAY_PREFIX
    return MeshcatVisualizer.AddToBuilder(builder, scene_graph, meshcat, params)


def _mark_reference(animation, frame: int, ghost: str, marker, x_d, error, i: int, colour):
    """Frame ``frame`` of the animation: the ghost at the reference pose ``x_d`` and, with a
    ``marker`` (else None), the error marker above it in the colour of log sample i's error
    (``error``: (errors (N,) m, tolerance m)); returns the marker's colour now (only changes
    of ``colour`` are recorded)."""
    from pydrake.math import RigidTransform

    X_WE = ghost_transform(x_d)
    animation.SetTransform(frame, ghost, X_WE)
    if marker is None:
        return colour
    p = X_WE.translation() + np.array([0.0, 0.0, ERROR_MARKER_HEIGHT_M])
    animation.SetTransform(frame, marker, RigidTransform(p))
    new = error_colour(float(error[0][i]), float(error[1]))
    if new != colour:  # only changes are recorded
        animation.SetProperty(frame, marker + "/<object>", "color", list(new))
    return new


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
    from ..plant.closed_chain import states_without_play
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
    # The replay's plant is the SDF's: a plant with gear play is drawn by its cranks' angles.
    states = states_without_play(sd.plant, sd.handles, result.state)
    record_states(meshcat, sd.plan.plant_geometry, result.t_state, states, fps, x_d=x_d)
    return result, write_static_html(meshcat, path)
