"""Drive `stewart-drake teleop`'s live Meshcat from headless Chromium and save what it shows.

    python tools/screenshot_teleop.py                    # -> docs/teleop_screenshot.png
    python tools/screenshot_teleop.py --out shot.png

The robot as built runs at real time; the page's own slider controls (as a user's mouse would)
tilt and lift the platform, and the shot is taken 1.2 s after the last move, with the gauges
(tracking error, torque margin, clearance between the parts) and Meshcat's real-time strip.
Needs Chromium (Debian: `apt install chromium`). Prints one line, e.g.
``teleop_screenshot docs/teleop_screenshot.png realtime_rate 1.000 (6.2 s simulated)``.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import chromium_cdp  # tools/, beside this script (on sys.path when run)
from pydrake.geometry import Meshcat

from stewart_drake.live.teleop import build_teleop, run_teleop
from stewart_drake.run.scenario_io import load_scenario

REPO = Path(__file__).resolve().parent.parent

#: The slider moves, (name, value) in the panel's units (rad, m), one every 1.2 s.
MOVES = (("roll [rad]", 0.15), ("y [m]", 0.02), ("z [m]", 0.315), ("pitch [rad]", -0.12))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default=str(REPO / "docs" / "teleop_screenshot.png"))
    args = parser.parse_args()
    meshcat = Meshcat()
    run = build_teleop(load_scenario("paper_hardware"), meshcat, realtime_rate=1.0)
    simulated = run_teleop(run, 1.0, report=None)["sim_s"]
    rates = []
    with chromium_cdp.HeadlessChromium(meshcat.web_url()) as browser:
        browser.wait_for("typeof viewer !== 'undefined' && 'z [m]' in viewer.gui_controllers", 60)
        for name, value in MOVES:
            browser.evaluate(f"viewer.gui_controllers['{name}'].setValue({value}); null")
            stats = run_teleop(run, 1.2, report=None)
            simulated += stats["sim_s"]
            rates.append(stats["realtime_rate"])
        browser.evaluate("viewer.gui.open(); null")  # the panel, as a user opens it
        shot = browser.screenshot(Path(args.out))
    print(f"teleop_screenshot {shot} realtime_rate {min(rates):.3f} ({simulated:.1f} s simulated)")


if __name__ == "__main__":
    main()
