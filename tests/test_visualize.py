"""See it: the Meshcat replay is a standalone HTML of the run; the Diagram pictures are current."""

import re
from pathlib import Path

import numpy as np
import pytest
from meshcat_html import read_meshcat_commands
from pydrake.math import RollPitchYaw

from stewart_drake.cli.main import main
from stewart_drake.references.trajectories import paper_manoeuvre
from stewart_drake.run.diagram import make_stewart_diagram
from stewart_drake.run.scenario import Scenario
from stewart_drake.viz import diagrams, visualize

#: The committed pictures (``stewart-drake diagrams`` from the repository's root rewrites them).
DIAGRAMS = Path(__file__).resolve().parent.parent / "diagrams"
from stewart_drake.base.errors import InvalidConfigError, RenderToolMissingError
from stewart_drake.run.plan import make_plan
from stewart_drake.run.result import load_result

DURATION = 0.3


@pytest.fixture(scope="module")
def replay(tmp_path_factory):
    out = tmp_path_factory.mktemp("replay")
    html = out / "replay.html"
    code = main(
        [
            "run",
            "--duration",
            str(DURATION),
            "--html",
            str(html),
            "--out",
            str(out),
            "--no-progress",
        ]
    )
    assert code == 0
    text = html.read_text()
    return {
        "html": html,
        "text": text,
        "commands": read_meshcat_commands(text),
        "result": load_result(out / "run_paper.npz"),
    }


def test_frame_indices_pick_the_nearest_logged_sample():
    t = np.arange(1001) * 1e-3  # 1 kHz log over 1 s
    frame_times, idx = visualize.frame_indices(t, 30.0)
    assert len(frame_times) == 31 and frame_times[-1] == pytest.approx(1.0)
    np.testing.assert_array_equal(idx, np.round(np.arange(31) / 30 * 1e3).astype(int))
    frame_times, idx = visualize.frame_indices(np.array([0.0, 0.1, 0.25]), 10.0)
    np.testing.assert_allclose(frame_times, [0.0, 0.1, 0.2])
    np.testing.assert_array_equal(idx, [0, 1, 2])  # 0.2 is nearer 0.25 than 0.1
    with pytest.raises(InvalidConfigError, match="fps"):
        visualize.frame_indices(t, 0.0)
    with pytest.raises(InvalidConfigError, match="no logged samples"):
        visualize.frame_indices(np.array([]), 30.0)


def test_replay_html_is_standalone_and_small(replay):
    text, size = replay["text"], replay["html"].stat().st_size
    # The viewer (~2.2 MB of three.js + meshcat) is inlined; 10 frames add a few tens of kB.
    assert 2.0e6 < size < 2.6e6, size
    assert "MeshCat.Viewer" in text and "<script src" not in text.replace(" ", "")
    # Scene and animation come from data: URIs; nothing is fetched, nothing connects to a server.
    assert text.count('fetch("data:application/octet-binary;base64,') == len(replay["commands"])
    assert not re.findall(r'fetch\("(?!data:)', text)
    viewer_script = text.rsplit("<script>", 1)[1]
    assert "new MeshCat.Viewer" in viewer_script and "connect(" not in viewer_script
    assert "http://localhost" not in text
    types = [c["type"] for c in replay["commands"]]
    assert types.count("set_animation") == 1 and "set_object" in types


def test_replay_shows_only_the_illustration_geometry(replay):
    from stewart_drake.robot.parts import robot_parts

    objects = sorted(
        c["path"].split("rotary_stewart/", 1)[1]
        for c in replay["commands"]
        if c["type"] == "set_object" and "rotary_stewart/" in c["path"]
    )
    expected = sorted(f"{p.link}/{p.name}" for p in robot_parts())
    assert [o.split("/", 1)[0] + "/" + o.rsplit("/", 1)[1] for o in objects] == expected
    markers = [
        c["path"]
        for c in replay["commands"]
        if c["type"] == "set_object" and "rotary_stewart/" not in c["path"]
    ]
    ghost = [f"{visualize.GHOST_PATH}/{p.name}" for p in robot_parts() if p.link == "platform"]
    assert sorted(markers) == sorted(
        [f"/drake/{visualize.REPLAY_PREFIX}_contacts/{j}" for j in range(visualize.CONTACT_MARKERS)]
        + ghost  # the reference's ghost: the platform's parts
    )
    assert all(
        c["path"].startswith(f"/drake/{visualize.REPLAY_PREFIX}/")
        for c in replay["commands"]
        if c["type"] == "set_object" and "rotary_stewart/" in c["path"]
    )
    # The paper run keeps every pair of parts apart: the contact markers never show.
    (animation,) = [c for c in replay["commands"] if c["type"] == "set_animation"]
    assert not [a for a in animation["animations"] if "_contacts" in a["path"]]


def test_replay_marks_the_parts_that_touch(tmp_path):
    """A path into the pose where the hub plate and rod 0 overlap: the marker appears (orange
    while the parts are closer than the margin, red once they touch), between the parts."""
    from pydrake.geometry import Meshcat

    from stewart_drake.plant.closed_chain import assembled_positions
    from stewart_drake.plant.plant import make_plant
    from stewart_drake.robot.geometry import StewartGeometry
    from stewart_drake.robot.kinematics import X_HOME

    overlap = np.array([0.2102, 0.2411, -0.2047, -0.0222, 0.0979, 0.2157])
    t = np.linspace(0.0, 1.0, 31)
    x = X_HOME + t[:, None] * (overlap - X_HOME)
    plant, _, handles, _, _ = make_plant()
    states = assembled_positions(plant, handles, x)
    meshcat = Meshcat()
    visualize.record_states(meshcat, StewartGeometry(), t, states, fps=30.0)
    html = visualize.write_static_html(meshcat, tmp_path / "touch.html")
    (animation,) = [
        c for c in read_meshcat_commands(html.read_text()) if c["type"] == "set_animation"
    ]
    tracks = {
        a["path"]: {tr["name"]: tr["keys"] for tr in a["clip"]["tracks"]}
        for a in animation["animations"]
    }
    marker = f"/drake/{visualize.REPLAY_PREFIX}_contacts/0"
    visible = tracks[marker][".visible"]
    colours = tracks[marker + "/<object>"][".color"]
    assert visible[0]["value"] is True and 0 < visible[0]["time"] < 30
    assert colours[0]["value"][:3] == [1.0, 0.6, 0.0]  # near first
    assert colours[-1]["value"][:3] == [1.0, 0.0, 0.0]  # then touching
    # The marker sits between the rod and the hub plate's rim (r ~ 0.125 m, z ~ 0).
    end = np.array(tracks[marker][".position"][-1]["value"])
    assert abs(end[2]) < 0.02 and 0.11 < np.hypot(end[0], end[1]) < 0.14


def test_replay_animation_follows_the_logged_run(replay):
    (animation,) = [c for c in replay["commands"] if c["type"] == "set_animation"]
    tracks = {a["path"].rsplit("/", 1)[1]: a["clip"] for a in animation["animations"]}
    assert {f"crank_{i}" for i in range(6)} | {f"rod_{i}" for i in range(6)} | {"platform"} <= set(
        tracks
    )
    n_frames = int(DURATION * visualize.REPLAY_FPS) + 1
    clip = tracks["platform"]
    assert clip["fps"] == visualize.REPLAY_FPS
    position, quaternion = (
        {t["name"]: t["keys"] for t in clip["tracks"]}[k] for k in (".position", ".quaternion")
    )
    assert [k["time"] for k in position] == list(range(n_frames))  # no frame lost or doubled
    result = replay["result"]
    # Each frame shows the plant state logged nearest its time (every state_log_period_s); the
    # pose log (float32, every log period) holds the same instant to 7 digits.
    for k in (0, n_frames // 2, n_frames - 1):
        i = int(np.argmin(np.abs(result.t_state - k / visualize.REPLAY_FPS)))
        j = int(np.argmin(np.abs(result.t - result.t_state[i])))
        np.testing.assert_allclose(position[k]["value"], result.x[j, 3:6], atol=1e-7)
        q = RollPitchYaw(result.x[j, :3].astype(float)).ToQuaternion()
        q_xyzw = np.array([q.x(), q.y(), q.z(), q.w()])
        q_rec = np.array(quaternion[k]["value"])
        assert min(np.abs(q_rec - q_xyzw).max(), np.abs(q_rec + q_xyzw).max()) < 1e-6
    # The platform really moves in the replay (paper eqs. 37-38: Z rises from 0.30 m).
    assert position[-1]["value"][2] - position[0]["value"][2] > 1e-3


def test_replay_draws_the_reference_as_a_ghost_at_x_d(replay):
    (animation,) = [c for c in replay["commands"] if c["type"] == "set_animation"]
    (ghost,) = [a["clip"] for a in animation["animations"] if a["path"] == visualize.GHOST_PATH]
    tracks = {t["name"]: t["keys"] for t in ghost["tracks"]}
    result = replay["result"]
    _, idx = visualize.frame_indices(result.t_state, visualize.REPLAY_FPS)
    assert [k["time"] for k in tracks[".position"]] == list(range(len(idx)))
    for k in (0, len(idx) // 2, len(idx) - 1):
        x_d = paper_manoeuvre().evaluate(result.t_state[idx[k] : idx[k] + 1])[0][0]
        X = visualize.ghost_transform(x_d)
        np.testing.assert_allclose(tracks[".position"][k]["value"], X.translation(), atol=1e-9)
        q = X.rotation().ToQuaternion()
        q_xyzw = np.array([q.x(), q.y(), q.z(), q.w()])
        q_rec = np.array(tracks[".quaternion"][k]["value"])
        assert min(np.abs(q_rec - q_xyzw).max(), np.abs(q_rec + q_xyzw).max()) < 1e-9
    # The reference moves (paper eqs. 37-38), and the ghost with it.
    assert tracks[".position"][-1]["value"][2] - tracks[".position"][0]["value"][2] > 1e-3
    plates = [
        c["object"]["materials"][0]
        for c in replay["commands"]
        if c["type"] == "set_object" and c["path"] == f"{visualize.GHOST_PATH}/plate"
    ]
    assert len(plates) == 1 and plates[0]["transparent"] and plates[0]["opacity"] < 0.5


def test_replay_starts_looking_down_at_the_robot_from_the_front(replay):
    """The HTML's own camera commands (Meshcat's y-up camera frame: world (x, y, z) is
    (x, z, -y)) put the camera at CAMERA_POSITION looking at CAMERA_TARGET, and that is above
    the platform, from the front, looking down by more than 30 degrees."""
    camera = [
        c["value"]
        for c in replay["commands"]
        if c["type"] == "set_property" and c["path"] == "/Cameras/default/rotated/<object>"
    ]
    target = [c["value"] for c in replay["commands"] if c["type"] == "set_target"]
    (x, z, minus_y), (tx, tz, minus_ty) = camera[-1], target[-1]
    np.testing.assert_allclose([x, -minus_y, z], visualize.CAMERA_POSITION, atol=1e-12)
    np.testing.assert_allclose([tx, -minus_ty, tz], visualize.CAMERA_TARGET, atol=1e-12)
    view = np.subtract(visualize.CAMERA_TARGET, visualize.CAMERA_POSITION)
    assert np.degrees(np.arcsin(-view[2] / np.linalg.norm(view))) > 30  # looking down
    assert z > replay["result"].x[:, 5].max() + 0.1 and x > abs(-minus_y)  # above, from +X


def test_the_replay_meshcat_serves_only_this_machine_off_the_live_ports(capsys):
    meshcat = visualize.offline_meshcat()
    assert meshcat.web_url() == f"http://localhost:{meshcat.port()}"
    assert not 7000 <= meshcat.port() <= 7999  # an ephemeral port, not one teleop would take
    with pytest.raises(SystemExit):
        main(["run", "--help"])
    assert "opens a web port on localhost while it records, unused" in " ".join(
        capsys.readouterr().out.split()
    )


def test_record_states_refuses_states_of_another_shape():
    from pydrake.geometry import Meshcat

    with pytest.raises(InvalidConfigError, match="same geometry"):
        visualize.record_states(
            Meshcat(), make_plan(Scenario()).geometry, np.arange(3) * 1e-3, np.zeros((3, 5))
        )


def test_a_diverging_replay_stops_at_the_guard_and_saves_the_whole_scenario(
    tmp_path, monkeypatch, feedforward_fault
):
    """The HTML replay advances through the guard, and the saved file
    explains the divergence: the whole scenario (it loads back equal) and the torque applied."""
    from stewart_drake.base.errors import SimulationDivergedError
    from stewart_drake.run.scenario import PdDriver, _scenario_from_yaml, dump_scenario
    from stewart_drake.station.guard import GuardConfig

    feedforward_fault(lambda T_ff: np.full(6, np.inf))
    scenario = Scenario(
        duration_s=0.2,
        torque_limit_Nm=0.7,
        payload_scale=1.5,
        guard=GuardConfig(divergence_dir=str(tmp_path / "diverged")),
    )
    with pytest.raises(SimulationDivergedError, match="the motor torques are not finite") as info:
        visualize.record_html(scenario, tmp_path / "replay.html")
    assert not (tmp_path / "replay.html").exists()
    with np.load(info.value.path, allow_pickle=False) as saved:
        back = _scenario_from_yaml(str(saved["scenario"]))
        applied, commanded = saved["T_applied_last"], saved["T_last"]
    assert dump_scenario(back) == dump_scenario(scenario) and not isinstance(
        back.controller, PdDriver
    )
    assert (back.torque_limit_Nm, back.payload_scale) == (0.7, 1.5)
    assert np.all(np.isinf(commanded)) and np.all(applied == 0.7)  # the limit clipped it


def test_committed_diagram_pictures_are_current():
    dots = diagrams.diagram_dots()
    assert {"control_loop", "diagram_fixed", "diagram_ann", "station", "lqi_controller"} <= set(
        dots
    )
    for name, dot in dots.items():
        dot_path = DIAGRAMS / f"{name}.dot"
        svg_path = dot_path.with_suffix(".svg")
        hint = "run `stewart-drake diagrams` (with Graphviz installed) and commit diagrams/"
        assert dot_path.exists() and dot_path.read_text() == dot, f"{dot_path} is stale: {hint}"
        assert svg_path.exists(), f"{svg_path} is missing: {hint}"
        assert diagrams.svg_dot_hash(svg_path.read_text()) == diagrams.dot_hash(dot), (
            f"{svg_path} was rendered from another .dot: {hint}"
        )


def test_diagram_dot_is_the_same_in_every_build_and_shows_every_connection():
    first, second = (make_stewart_diagram(Scenario()).diagram for _ in range(2))
    raw = [d.GetGraphvizString(max_depth=1) for d in (first, second)]
    assert raw[0] != raw[1]  # Drake's system ids differ ...
    dots = [diagrams.normalize_dot(r) for r in raw]
    assert dots[0] == dots[1]  # ... the normalized text does not
    # every connection, and the exported input (tool_wrench, fixed in the Context) to the station
    assert dots[0].count(" -> ") == len(first.connection_map()) + first.num_input_ports()
    for name in ("station", "controller", "reference", "feedforward", "omega", "log_signals"):
        assert f"name={name}" in dots[0]


def test_control_loop_picture_shows_the_ports_in_use_only():
    sd = make_stewart_diagram(Scenario())
    dot = diagrams.control_loop_dot(sd.diagram)
    assert '"controller":"out_T" -> "station":"in_motor_torque" [label="T (6)"' in dot
    assert '"station":"out_platform_state" -> "controller":"in_x"' in dot
    assert '"inputs":"out_tool_wrench" -> "station":"in_tool_wrench"' in dot  # exported
    assert "log_" not in dot  # loggers left out
    assert "motor_rate" not in dot  # a station port the LQI does not use
    connections = sd.diagram.connection_map()
    logged = [dst for (dst, _) in connections if diagrams.is_log(dst, connections)]
    assert len(logged) >= 5  # the signals and the plant state go to the logs
    assert dot.count(" -> ") == len(connections) - len(logged) + 1


def test_pictures_draw_the_default_scenario_and_label_the_ideal_one():
    """`run` defaults to the robot as built: the pictures without a suffix show its encoders
    feeding the LQI; the ideal robot's pictures say so in their caption."""
    dots = diagrams.diagram_dots()
    loop, ideal = dots["control_loop"], dots["control_loop_ideal"]
    assert '"station":"out_motor_angle" -> "controller":"in_motor_angle"' in loop
    assert "platform_state" not in loop and "paper_hardware" in loop
    assert '"station":"out_platform_state" -> "controller":"in_x"' in ideal
    assert "the ideal robot (paper_ideal)" in ideal and "paper_hardware" not in ideal
    for name in ("encoders", "computation_delay", "current_loop", "torque_limit"):
        assert f'"{name}" [label=' in dots["station"], name
        assert f'"{name}" [label=' not in dots["station_ideal"], name
    assert "paper_hardware" in dots["diagram_fixed"] and "paper_hardware" in dots["diagram_ann"]


def test_the_station_picture_leaves_out_the_ports_nobody_connects():
    """Drake releases add ports to the MultibodyPlant (1.58 added surface_speeds and
    surface_displacements): the station picture draws only the ports in use, so it is the same
    on every supported Drake."""
    sd = make_stewart_diagram(Scenario())
    dot = diagrams.wiring_dot(sd.station)
    plant = sd.station.plant
    connected = {
        src.get_output_port(j).get_name()
        for (_, _), (src, j) in sd.station.connection_map().items()
        if src is plant
    }
    unused = {plant.get_output_port(k).get_name() for k in range(plant.num_output_ports())}
    unused -= connected | {"state"}
    assert unused and not any(f"out_{name}" in dot for name in unused)
    assert all(f'"out_{name}"' in dot for name in connected)


def test_svg_rendering_needs_graphviz_and_says_so(monkeypatch):
    monkeypatch.setattr(diagrams.shutil, "which", lambda name: None)
    with pytest.raises(RenderToolMissingError, match="install graphviz"):
        diagrams.render_svg("digraph { a -> b }")


def test_diagrams_cli_writes_the_dot_sources(tmp_path):
    assert main(["diagrams", "--dot-only", "--out", str(tmp_path)]) == 0
    for name in ("diagram_fixed", "diagram_ann", "lqi_controller"):
        assert (tmp_path / f"{name}.dot").read_text() == (DIAGRAMS / f"{name}.dot").read_text()
    assert not list(tmp_path.glob("*.svg"))
