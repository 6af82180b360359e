"""Make the example inputs `stewart-drake examples` copies (stewart_drake/data/examples/): a
tracker's marker exports, a fiducial registration, a registration motion's export, the robot's
encoder log, recorded traces and a depth camera's file, all synthetic and seeded, and their
README.md.

    python tools/make_examples.py            # rewrite stewart_drake/data/examples/
    python tools/make_examples.py --check    # exit 1 if the shipped files are not what it makes

The measured motions are the case of tests/test_verify.py, made by the same arithmetic with the
same seeds: the library's breathing with a 2 deg tilt that the phantom followed 60 ms late, seen
for 40 s at 100 Hz with 0.12 mm RMS of the tracker's own error, exported on the tracker's clock
(it started 121.456 s before the motion's clock: --clock-offset=-121.456). `--check` compares
the numbers of each file with what it would write (to 1e-9 of each value: another numpy may
round a last digit differently), and the registration's and README's text exactly.
"""

from __future__ import annotations

import argparse
import re
import sys
import tempfile
from pathlib import Path

import numpy as np
from scipy.interpolate import CubicSpline

from stewart_drake.calibration import files, tracker
from stewart_drake.calibration.join import write_encoder_log
from stewart_drake.organ_motion.examples import EXAMPLES, FOLDER
from stewart_drake.references.organ.library import make_motion
from stewart_drake.robot.kinematics import ik
from stewart_drake.run.plan import robot_geometry
from stewart_drake.run.scenario_io import load_scenario
from stewart_drake.station.bus.servos import SurrogateServoConfig

#: The phantom's motion and the marker exports' setting (tests/test_verify.py's).
REFERENCE = make_motion("breathing", {"tilt": "2deg"})
CLOCK_START_MS, REFERENCE_START_S = 123456.0, 2.0
CLOCK_OFFSET_S = REFERENCE_START_S - CLOCK_START_MS / 1e3
LATENCY_S, NOISE_RMS_M = 0.060, 0.12e-3
#: Where the aligned tracker's origin is in the base frame, m.
ALIGNED_ORIGIN_M = np.array([0.4, -1.2, 0.9])
#: The depth camera's setting (tests/test_verify_interact.py's, without its gap).
DEPTH_DELAY_S, DEPTH_OFFSET_MM, DEPTH_NOISE_MM = 5.45, 412.3, 0.6
#: The camera's distance to the surrogate platform, mm.
SURROGATE_OFFSET_MM = 388.7
#: The encoder log's surrogate carriage: the breathing through a correlation model of this
#: amplitude ratio and lead, s.
CARRIAGE_RATIO, CARRIAGE_LEAD_S = 0.5, 0.4


def setup():
    """The emulated tracker 1 m and 30 deg from the base, its marker 50 mm off the platform."""
    return tracker.emulated_setup(robot_geometry(load_scenario("phantom_hardware")))


def phantom_run(seconds=40.0, rate_hz=100.0):
    """(t (n,) s on the tracker's clock, (n, 6) the platform's true poses in B)."""
    t = CLOCK_START_MS / 1e3 + np.arange(int(round(seconds * rate_hz))) / rate_hz
    return t, REFERENCE.evaluate(t + CLOCK_OFFSET_S - LATENCY_S)[0]


def tracker_view(x_BP, seed=0, aligned=False):
    """(n, 3) the marker's positions in the tracker's frame with NOISE_RMS_M of 3-D error."""
    rng = np.random.default_rng(seed)
    if aligned:
        x = np.array(x_BP, dtype=float)
        x[:, 3:] += ALIGNED_ORIGIN_M
    else:
        x = setup().tracker_poses(x_BP)
    x[:, 3:] += rng.normal(0.0, NOISE_RMS_M / np.sqrt(3.0), x[:, 3:].shape)
    return x[:, 3:]


def write_marker_export(path, t_s, xyz_m):
    """A tracker's marker export at ``path``: a quoted header ``"Frame";"Timestamp";"x";"y";
    "z"``, ``;``-separated, decimal commas, CRLF, ``t_s`` (n,) s written in ms on the tracker's
    own clock, ``xyz_m`` (n, 3) m written in mm to the micron, a closing line of zeros; returns
    the path."""

    def comma(v):
        return f"{v:.3f}".replace(".", ",")

    lines = ['"Frame";"Timestamp";"x";"y";"z"']
    lines += [
        ";".join([str(k + 1), comma(t * 1e3)] + [comma(v * 1e3) for v in p])
        for k, (t, p) in enumerate(zip(t_s, xyz_m))
    ]
    lines.append("0;0;0;0;0")
    Path(path).write_bytes(("\r\n".join(lines) + "\r\n").encode())
    return Path(path)


def registration_run(seconds=40.0, rate_hz=100.0, seed=7, noise_m=50e-6):
    """(t, (n, 3)): the registration motion as the turned tracker saw it, 60 ms late."""
    t = 500.0 + np.arange(int(seconds * rate_hz)) / rate_hz
    x = make_motion("registration").evaluate(t - 500.0 + 0.5 - LATENCY_S)[0]
    seen = setup().tracker_poses(x)[:, 3:]
    return t, seen + np.random.default_rng(seed).normal(0.0, noise_m / np.sqrt(3), seen.shape)


def write_encoders(path, seconds=12.0):
    """The robot's encoder log: 0.5 s of lead-in (no t_path), then ``seconds`` of the breathing
    15 ms late, 17-bit readings with the encoders' zero errors, on the robot computer's clock;
    with a surrogate's servo on the bus, its carriage (``s``, read, and ``s_cmd``, commanded)
    following the breathing through the correlation model ratio 0.5 and lead 0.4 s
    (``--surrogate model --surrogate-param ratio=0.5 lead=0.4s``: half the breath's X, the only
    axis it moves along, 0.4 s ahead), 15 ms late too, read in the servo's counts."""
    geometry = robot_geometry(load_scenario("phantom_hardware"))
    t_path = np.arange(0.0, seconds, 0.01)
    x = REFERENCE.evaluate(t_path - 0.015)[0]
    q = tracker.quantize(ik(geometry, x) + geometry.encoder_offsets, 2**17)
    count = SurrogateServoConfig().metres_per_count
    s_cmd = CARRIAGE_RATIO * REFERENCE.evaluate(t_path + CARRIAGE_LEAD_S)[0][:, 3]
    s_cmd -= 0.5 * (s_cmd.max() + s_cmd.min())  # about the stage's mid-travel
    s = CARRIAGE_RATIO * REFERENCE.evaluate(t_path + CARRIAGE_LEAD_S - 0.015)[0][:, 3]
    s = np.round((s - 0.5 * (s.max() + s.min())) / count) * count
    n, lead = len(t_path), 50

    def held(v):
        return np.concatenate([np.repeat(v[:1], lead, axis=0), v])

    write_encoder_log(
        path,
        1.7e9 + np.arange(n + lead) * 0.01,
        np.arange(n + lead) * 0.01,
        np.concatenate([np.full(lead, np.nan), t_path]),
        held(q),
        surrogate=(held(s), held(s_cmd)),
    )


def irregular_breath(t, seed=3):
    """(SI, amplitude (n,)): breaths of 3.6-4.4 s and 8-12 mm peak to peak on SI (Lujan's
    cos^4, a rest at exhale), drawn per breath, growing to full size over the first 10 s."""
    rng = np.random.default_rng(seed)
    periods = rng.uniform(3.6, 4.4, 64)
    amplitudes = rng.uniform(8.0, 12.0, 64)
    starts = np.concatenate([[0.0], np.cumsum(periods)])
    k = np.searchsorted(starts, t, side="right") - 1
    u = (t - starts[k]) / periods[k]
    envelope = np.minimum(t / 10.0, 1.0)
    return envelope * amplitudes[k] * np.cos(np.pi * u - np.pi / 2) ** 4, u, k, starts, periods


def write_traces(folder, seconds=120.0):
    """trace.txt (7 columns, 5 Hz), surrogate.txt (2 columns, 5 Hz) and depth.csv (the
    camera's AP, about 32 Hz on its own clock)."""
    t = np.round(np.arange(0.0, seconds + 1e-9, 0.2), 1)
    si, *_ = irregular_breath(t)
    ap, *_ = irregular_breath(t - 0.25)  # the AP motion lags SI: a loop, not a line
    ap = 0.4 * np.where(t >= 0.25, ap, 0.0)
    lr = 0.15 * si
    rot_lr = 0.02 * si  # deg: the tumour tilts with the breath
    rows = [
        f"{a:.1f} {b:.2f} {c:.2f} {d:.2f} {e:.3f} 0.000 0.000"
        for a, b, c, d, e in zip(t, lr, si, ap, rot_lr)
    ]
    (folder / "trace.txt").write_text("\n".join(rows) + "\n")
    # The chest's surface: a smaller motion that leads the tumour by 0.2 s, 50 um of noise.
    chest, *_ = irregular_breath(t + 0.2)
    chest = 0.45 * chest + np.random.default_rng(5).normal(0.0, 0.05, len(t))
    (folder / "surrogate.txt").write_text(
        "\n".join(f"{a:.1f} {b:.2f}" for a, b in zip(t, chest)) + "\n"
    )
    # The depth camera on the phantom that followed trace.txt's AP (joined smoothly), its own
    # clock from 0, the phantom starting 5.45 s after it, steps of 26.5-36.5 ms.
    rng = np.random.default_rng(0)
    steps = rng.uniform(0.0265, 0.0365, int((seconds + 10) / 0.0315))
    t_cam = np.concatenate([[0.0], np.cumsum(steps)])
    t_cam = t_cam[t_cam < seconds + DEPTH_DELAY_S]
    spline = CubicSpline(t, ap)
    seen = spline(np.clip(t_cam - DEPTH_DELAY_S, 0.0, seconds))
    depth = DEPTH_OFFSET_MM + seen + rng.normal(0.0, DEPTH_NOISE_MM, len(t_cam))
    lines = ["t [s],depth [mm]"] + [f"{a:.4f},{b:.2f}" for a, b in zip(t_cam, depth)]
    (folder / "depth.csv").write_text("\n".join(lines) + "\n")
    # The same camera on the surrogate platform, which followed surrogate.txt (as written) in
    # sync with the phantom: the pair's relative latency is 0.
    chest_seen = CubicSpline(t, np.round(chest, 2))(np.clip(t_cam - DEPTH_DELAY_S, 0.0, seconds))
    noise = np.random.default_rng(6).normal(0.0, DEPTH_NOISE_MM, len(t_cam))
    lines = ["t [s],depth [mm]"] + [
        f"{a:.4f},{b:.2f}" for a, b in zip(t_cam, SURROGATE_OFFSET_MM + chest_seen + noise)
    ]
    (folder / "depth_surrogate.csv").write_text("\n".join(lines) + "\n")


def write_patient(path, seconds=20.0):
    """A header CSV at 30 Hz: SI 15 mm and AP 3.6 mm peak to peak, rot_LR 1 deg, a 4 s
    breath."""
    t = np.arange(int(round(seconds * 30))) / 30.0
    c = np.cos(2 * np.pi * t / 4.0)
    lines = ["time [s],SI [mm],AP [mm],rot_LR [deg]"] + [
        f"{a:.3f},{7.5 * b:.2f},{1.8 * b:.2f},{0.5 * b:.2f}" for a, b in zip(t, c)
    ]
    Path(path).write_text("\n".join(lines) + "\n")


def write_servo_bench(path, seconds=6.0):
    """A bench log (:mod:`stewart_drake.actuator.bench_log`) of the shipped XL330-M288-T model
    swinging 0.49 kg at 0.1 m in its own position mode at kp 400, 7.4 V, a sine of growing
    frequency (BAM's "sin_time_square" kind) sampled at 200 Hz, the encoder in whole counts."""
    from stewart_drake.actuator.bench import replay
    from stewart_drake.actuator.bench_log import BenchLog, write_bench_log
    from stewart_drake.actuator.model_file import read_model

    model, _ = read_model("XL330-M288-T")
    t = np.arange(int(round(seconds * 200)) + 1) / 200.0
    goal = np.sin(0.5 * np.pi * t * t) * np.minimum(1.0, t / 1.5)
    on = np.ones(t.size, bool)
    blank = BenchLog("", 0.49, 0.1, 0.0, 400.0, 7.4, "xl330", "sin_time_square", t, goal, t * 0, on)
    count = 2 * np.pi / 4096
    q = np.round(replay(model, blank) / count) * count
    log = BenchLog("", 0.49, 0.1, 0.0, 400.0, 7.4, "xl330", "sin_time_square", t, goal, q, on)
    write_bench_log(path, log)


def write_reference(path, seconds=8.0):
    """The project's CSV (t,phi,theta,psi,X,Y,Z; s, rad, m) of the library's breathing with a
    2 deg tilt, at 50 Hz."""
    t = np.arange(int(round(seconds * 50)) + 1) / 50.0
    x = REFERENCE.evaluate(t)[0]
    lines = ["t,phi,theta,psi,X,Y,Z"] + [
        ",".join([f"{a:.2f}"] + [f"{v:.9f}" for v in row]) for a, row in zip(t, x)
    ]
    Path(path).write_text("\n".join(lines) + "\n")


README_HEAD = """# Example inputs

Copied into a folder of yours by `stewart-drake examples [DIR]` (default: the current folder);
every command block of README.md and docs/*.md runs as written in a folder holding them
(tests/test_docs_commands.py). All synthetic, seeded and made by `python tools/make_examples.py`
(`--check` says whether these are what it makes); none is anyone's measurement.

| file | what it is, and what a command shows on it |
|---|---|
"""

README_TAIL = """
How they were made (tools/make_examples.py, the case of tests/test_verify.py):

- **The marker exports** (`markers.csv`, `markers_turned.csv`, `reg_markers.csv`): the platform's
  true poses, the library's motion 60 ms late, seen by the tracker with 0.12 mm RMS of 3-D noise
  (50 um for the registration motion), written as an optical tracker exports them: a quoted
  header without units (hence `--measured-columns '-,t [ms],X [mm],Y [mm],Z [mm]'`), a frame
  counter, semicolons, decimal commas, CRLF, ms on the tracker's clock, which started
  121.456 s before the motion's (`--clock-offset=-121.456`), a closing line of zeros. The aligned
  tracker's origin is (-0.4, 1.2, -0.9) m in the base frame; the turned tracker is
  `stewart_drake.calibration.tracker.emulated_setup` of the `phantom_hardware` robot, and
  `REG.yaml` its fiducials measured with 2 um of noise, the marker's pose the mean of 100 samples
  of 5 um and 20 urad (`fiducials(MeasurementNoise(5e-6, 20e-6), seed=1)`). With them `verify`
  PASSes `markers.csv` (a latency of 59.98 ms, the noise as the error), FAILs
  `markers_turned.csv` without a registration ("the measured motion is turned 26.9 deg from the
  reference's") and PASSes it through `REG.yaml` or through the registration that `calibrate
  --register reg_markers.csv` fits.
- **The encoder log** (`run_encoders.csv`): 12 s of the breathing 15 ms late after 0.5 s of
  lead-in, the readings the inverse kinematics of `phantom_hardware`'s robot plus its encoders'
  zero errors, quantized to 2^17 counts a turn; a surrogate's servo on the bus, its carriage
  commanded (`s_cmd`) half the breath's X 0.4 s ahead (the correlation model `ratio=0.5
  lead=0.4s`) and read (`s`) 15 ms late in the servo's counts of 19.5 um: `verify breathing
  --param tilt=2deg --surrogate model --surrogate-param ratio=0.5 lead=0.4s` with the log for
  both measurements PASSes the pair, their relative latency within a ms of 0.
- **The traces** (`trace.txt`, `surrogate.txt`): breaths of 3.6-4.4 s and 8-12 mm on SI drawn
  per breath (seed 3), growing over the first 10 s, AP 0.4 of it and 0.25 s behind, LR 0.15 of
  it, rot_LR 0.02 deg a mm; the surrogate 0.45 of the breath 0.2 s ahead, with 50 um of noise.
  Written as the motion phantom's files are: no header, spaces, 5 Hz.
- **The depth camera** (`depth.csv`): trace.txt's AP joined by a cubic spline, seen from the
  camera's clock 5.45 s after it started, steps of 26.5-36.5 ms, an offset of 412.3 mm and
  0.6 mm of noise (a RealSense's, as in IntERAct's laboratory runs): `verify trace.txt --measured
  depth.csv --measured-map depth=AP --tolerance 1mm,1deg` PASSes it; the default 0.1 mm is below
  the camera's own noise. `depth_surrogate.csv`: the same camera's times and noise (seed 6) on
  the surrogate platform, which followed surrogate.txt (a cubic spline through it as written) in
  sync with the phantom, 388.7 mm away: `verify trace.txt --surrogate surrogate.txt` with both
  files PASSes the pair, their relative latency within a few ms of 0.
- **patient.csv**: cosines of 4 s, SI 15 mm, AP 3.6 mm and rot_LR 1 deg peak to peak, 30 Hz.
- **ref.csv**: the library's breathing with a 2 deg tilt, 8 s (two breaths) at 50 Hz.
- **servo_bench.json**: the shipped XL330-M288-T model (identified on a real one's bench logs,
  docs/servo_bench.md) replayed on a sine whose frequency grows (sin(pi t^2 / 2), its amplitude
  ramped over 1.5 s), kp 400, 7.4 V, 6 s at 200 Hz, the angles in the encoder's whole counts:
  `servo replay servo_bench.json --model XL330-M288-T` gives it back within a count (0.4 mrad).
"""


def readme() -> str:
    rows = "".join(f"| `{name}` | {what} |\n" for name, what in EXAMPLES.items())
    return README_HEAD + rows + README_TAIL


def make(folder: Path) -> None:
    """Write every example and README.md into ``folder``."""
    folder.mkdir(parents=True, exist_ok=True)
    t, x = phantom_run()
    write_marker_export(folder / "markers.csv", t, tracker_view(x, aligned=True))
    write_marker_export(folder / "markers_turned.csv", t, tracker_view(x))
    files.write_registration(
        folder / "REG.yaml", setup().fiducials(tracker.MeasurementNoise(5e-6, 20e-6), seed=1)
    )
    write_marker_export(folder / "reg_markers.csv", *registration_run())
    write_encoders(folder / "run_encoders.csv")
    write_traces(folder)
    write_patient(folder / "patient.csv")
    write_reference(folder / "ref.csv")
    write_servo_bench(folder / "servo_bench.json")
    (folder / "README.md").write_text(readme())
    made = {p.name for p in folder.iterdir()}
    assert made == set(EXAMPLES) | {"README.md"}, made ^ (set(EXAMPLES) | {"README.md"})


_NUMBER = re.compile(r"-?\d+(?:[.,]\d+)?(?:e[-+]?\d+)?|nan")


def differences(made: Path, shipped: Path) -> list[str]:
    """The files of ``shipped`` that differ from ``made``'s: their text apart from the numbers,
    or a number by more than 1e-9 of it."""
    found = []
    for path in sorted(made.iterdir()):
        other = shipped / path.name
        if not other.is_file():
            found.append(f"{path.name}: not shipped")
            continue
        a, b = path.read_text(), other.read_text()
        if a == b:
            continue
        if _NUMBER.sub("#", a) != _NUMBER.sub("#", b):
            found.append(f"{path.name}: its text differs")
            continue
        x = np.array([float(v.replace(",", ".")) for v in _NUMBER.findall(a)])
        y = np.array([float(v.replace(",", ".")) for v in _NUMBER.findall(b)])
        close = np.isclose(x, y, rtol=1e-9, atol=1e-9, equal_nan=True)
        if not close.all():
            found.append(f"{path.name}: {np.count_nonzero(~close)} numbers differ")
    extra = {p.name for p in shipped.iterdir()} - {p.name for p in made.iterdir()}
    found += [f"{name}: shipped, not made" for name in sorted(extra)]
    return found


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--check", action="store_true", help="compare the shipped files with what it makes"
    )
    parser.add_argument("--out", type=Path, default=FOLDER, help="where to write them")
    args = parser.parse_args(argv)
    if not args.check:
        make(args.out)
        for path in sorted(args.out.iterdir()):
            print(f"{path.name}: {path.stat().st_size / 1e3:.0f} kB")
        return 0
    with tempfile.TemporaryDirectory() as tmp:
        make(Path(tmp))
        found = differences(Path(tmp), args.out)
    for line in found:
        print(line)
    return 1 if found else 0


if __name__ == "__main__":
    sys.exit(main())
