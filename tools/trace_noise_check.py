"""How much a trace's measurement noise costs without learning, with the samples joined through
every one (``--smoothing none``) and without their noise (the default): the issue's check of
docs/organ_motion.md, "Read without their noise and seams".

    python tools/trace_noise_check.py "PATH/TO/Lung/Trace 1-Large AP motion.txt" [--out DIR]

Takes the trace's first ``--seconds`` (120 s), writes it as it is and with ``--noise-mm``
(0.1 mm) of white noise added to its three translation columns (seeded), and reproduces each
both ways with ``stewart-drake reproduce`` on its default scenario (``phantom_hardware``), without
learning. Prints the four runs' RMS translation and rotation errors and peaks over the window
the report measures, read from the reports' JSON, and whether the noisy trace joined without
its noise stays within 20 % of the clean trace's error. Four 120 s runs: about 4 CPU-minutes.
"""

import argparse
import json
import sys
from pathlib import Path

import numpy as np

from stewart_drake.base.fileio import read_checked
from stewart_drake.cli.main import main as cli


def _excerpts(path: Path, seconds: float, noise_mm: float, folder: Path) -> dict:
    """{label: file} of the trace's first ``seconds``, clean and with the noise added."""
    text = read_checked(path, "trace", 50e6, "give an IntERAct 6-D trace").decode()
    rows = np.array([[float(v) for v in line.split()] for line in text.splitlines() if line])
    rows = rows[rows[:, 0] <= seconds]
    noisy = rows.copy()
    rng = np.random.default_rng(0)
    noisy[:, 1:4] += rng.normal(0.0, noise_mm, (len(rows), 3))  # LR SI AP, mm
    files = {}
    for label, table in (("clean", rows), (f"+{noise_mm:g} mm noise", noisy)):
        out = folder / f"{path.stem}_{'clean' if table is rows else 'noisy'}.txt"
        np.savetxt(out, table, fmt="%.6g")
        files[label] = out
    return files


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("trace", type=Path, help="an IntERAct 6-D trace (7 columns)")
    parser.add_argument("--seconds", type=float, default=120.0)
    parser.add_argument("--noise-mm", type=float, default=0.1)
    parser.add_argument("--out", type=Path, default=Path("results/trace_noise_check"))
    args = parser.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)
    figures = {}
    for label, path in _excerpts(args.trace, args.seconds, args.noise_mm, args.out).items():
        for smoothing in ("none", "auto"):
            report = args.out / f"{path.stem}_{smoothing}"
            argv = ["reproduce", str(path), "--smoothing", smoothing, "--out", str(report)]
            if cli(argv + ["--no-progress"]) != 0:
                return 1
            (data,) = [
                json.loads(read_checked(p, "reproduce report", 50e6)) for p in report.glob("*.json")
            ]
            f = data["fidelity"]
            figures[label, smoothing] = f["rms_translation_m"]
            joined = "through every sample" if smoothing == "none" else "without noise"
            print(
                f"{label:>16} | {joined}: {f['rms_translation_m'] * 1e6:.2f} um, "
                f"{f['rms_rotation_rad'] * 1e6:.1f} urad, "
                f"peak {f['peak_translation_m'] * 1e6:.1f} um"
            )
    clean, noisy = figures["clean", "auto"], figures[f"+{args.noise_mm:g} mm noise", "auto"]
    ratio = noisy / clean
    verdict = "within" if abs(ratio - 1.0) <= 0.2 else "NOT within"
    print(f"noisy / clean, joined without noise: {ratio:.3f} ({verdict} 20 %)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
