"""Load a Meshcat replay in a real (headless) browser and save what it shows as a PNG.

    python tools/screenshot_replay.py           # 10 s paper run -> docs/replay_screenshot.png
    python tools/screenshot_replay.py --html results/replay.html --out shot.png

Needs Chromium (Debian: `apt install chromium`); WebGL runs on the SwiftShader software
rasterizer, so no GPU or display is used. Prints one line per figure, e.g.
``robot_pixels green 0.0031 orange 0.0009 blue 0.0008 (shot.png, 1280x800)``: the fractions of
the image in the platform's green, the cranks' orange and the ball joints' blue (sdf.write_sdf
colors), which is how the slow test decides that the robot, not a blank page, is on screen.
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from stewart_drake.viz.visualize import find_chromium

REPO = Path(__file__).resolve().parent.parent


def screenshot(
    html: str | Path,
    png: str | Path,
    size=(1280, 800),
    budget_ms: int = 5000,
    chromium: str | None = None,
    timeout_s: float = 180.0,
) -> Path:
    """Open ``html`` (file://) in headless Chromium and write a ``size`` screenshot to ``png``.

    ``budget_ms`` of virtual time let the viewer load and the animation play before the shot.
    Raises:
        RenderToolMissingError: no Chromium on PATH.
        RuntimeError: Chromium wrote no PNG (its stderr tail is in the message).
    """
    from stewart_drake.base.errors import RenderToolMissingError

    exe = chromium or find_chromium()
    if exe is None:
        raise RenderToolMissingError(
            "no Chromium on PATH: install it (Debian: `apt install chromium`) to screenshot a "
            "replay"
        )
    png = Path(png).resolve()
    png.parent.mkdir(parents=True, exist_ok=True)
    png.unlink(missing_ok=True)
    with tempfile.TemporaryDirectory(prefix="chromium-profile-") as profile:
        cmd = [
            exe,
            "--headless",
            "--no-sandbox",
            "--disable-gpu",
            "--disable-quic",
            "--no-first-run",
            "--disable-background-networking",
            "--disable-component-update",
            "--disable-sync",
            "--use-angle=swiftshader",
            "--enable-unsafe-swiftshader",
            f"--user-data-dir={profile}",
            f"--screenshot={png}",
            f"--window-size={size[0]},{size[1]}",
            f"--virtual-time-budget={budget_ms}",
            Path(html).resolve().as_uri(),
        ]
        proc = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout_s)
    if not png.exists():
        raise RuntimeError(
            f"Chromium wrote no screenshot (exit {proc.returncode}): {proc.stderr[-1500:]}"
        )
    return png


def robot_pixel_fractions(png: str | Path) -> dict:
    """Fractions of the image's pixels in the robot's colors (sdf.write_sdf diffuse colors).

    Returns:
        {"green": platform disc, "orange": crank arms, "blue": ball joints}, each in [0, 1].
    """
    import matplotlib.image as mpimg

    rgb = mpimg.imread(str(png))[..., :3].astype(float)
    r, g, b = rgb[..., 0], rgb[..., 1], rgb[..., 2]
    return {
        "green": float(np.mean((g - r > 0.2) & (g - b > 0.15))),
        "orange": float(np.mean((r - b > 0.4) & (r > 0.6) & (g > 0.25) & (g < r - 0.15))),
        "blue": float(np.mean((b - r > 0.3) & (b - g > 0.2))),
    }


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--html",
        default=None,
        help="replay to load (default: record the paper run into a temp file)",
    )
    parser.add_argument("--duration", type=float, default=10.0, help="s to record if no --html")
    parser.add_argument("--out", default=str(REPO / "docs" / "replay_screenshot.png"))
    parser.add_argument("--budget-ms", type=int, default=5000, help="virtual time before the shot")
    args = parser.parse_args(argv)
    sys.path.insert(0, str(REPO))
    with tempfile.TemporaryDirectory() as tmp:
        html = args.html
        if html is None:
            from stewart_drake.run.scenario import Scenario
            from stewart_drake.viz.visualize import record_html

            t0 = time.perf_counter()
            _, html = record_html(Scenario(duration_s=args.duration), Path(tmp) / "replay.html")
            print(
                f"replay_html_bytes {html.stat().st_size} ({args.duration:g} s run, "
                f"{time.perf_counter() - t0:.1f} s wall)"
            )
        t0 = time.perf_counter()
        png = screenshot(html, args.out, budget_ms=args.budget_ms)
        wall = time.perf_counter() - t0
    fr = robot_pixel_fractions(png)
    print(
        f"robot_pixels green {fr['green']:.4f} orange {fr['orange']:.4f} blue {fr['blue']:.4f} "
        f"({png}, {png.stat().st_size} bytes, {wall:.1f} s in Chromium)"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
