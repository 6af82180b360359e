"""A real browser (headless Chromium, software WebGL) shows the robot in the replay HTML."""

import importlib.util
from pathlib import Path

import pytest

from stewart_drake.run.scenario import Scenario
from stewart_drake.viz.visualize import record_html, write_static_html

_TOOL = Path(__file__).resolve().parent.parent / "tools" / "screenshot_replay.py"
_spec = importlib.util.spec_from_file_location("screenshot_replay", _TOOL)
screenshot_replay = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(screenshot_replay)

pytestmark = [
    pytest.mark.slow,
    pytest.mark.skipif(
        screenshot_replay.find_chromium() is None, reason="needs Chromium (apt install chromium)"
    ),
]


def test_chromium_screenshot_of_the_replay_shows_the_robot(tmp_path):
    from pydrake.geometry import Meshcat

    _, html = record_html(Scenario(duration_s=1.0), tmp_path / "replay.html")
    shot = screenshot_replay.screenshot(html, tmp_path / "replay.png")
    robot = screenshot_replay.robot_pixel_fractions(shot)
    # Negative control: the same viewer with an empty scene has none of the robot's colors.
    meshcat = Meshcat()
    meshcat.SetProperty("/Axes", "visible", False)  # as record_states does
    empty = write_static_html(meshcat, tmp_path / "empty.html")
    blank = screenshot_replay.robot_pixel_fractions(
        screenshot_replay.screenshot(empty, tmp_path / "empty.png")
    )
    assert max(blank.values()) < 1e-4, blank
    # At 1280x800 the platform disc, crank arms and ball joints each cover > 0.05 % of the image
    # (measured: ~0.2 %, 0.15 %, 0.1 %).
    assert min(robot.values()) > 5e-4, robot
