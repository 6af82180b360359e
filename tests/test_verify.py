"""``stewart-drake verify``: a motion measured on a phantom judged against its reference, the
frames never fitted to the motion judged. A marker export (semicolons, decimal commas, ms, a frame
column, a closing line of zeros) 60 ms late with 0.12 mm RMS of its own error, on the tracker's
clock: in the base frame's axes (its offsets removed and said), in a tracker's frame 1 m and
30 deg from the base with the marker 50 mm off the platform (refused as turned without a
registration; judged through fiducials or through a registration motion measured once); a 6-DoF
marker; the robot's encoder log beside the tracker's view; the clocks' relation not known; and
the hostile files, each one line, exit 2. The battery of wrong motions is
tests/test_verify_discrimination.py."""

import importlib.util
import json
import re
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from stewart_drake.base.errors import InvalidConfigError
from stewart_drake.calibration import files, tracker
from stewart_drake.calibration.join import write_encoder_log
from stewart_drake.cli.main import main
from stewart_drake.references.organ.library import make_motion
from stewart_drake.robot.kinematics import ik
from stewart_drake.run.plan import robot_geometry
from stewart_drake.run.scenario_io import load_scenario
from stewart_drake.verification.measured_motion import MeasuredMotion, read_measured
from stewart_drake.verification.verify import verify

_TOOL = Path(__file__).resolve().parent.parent / "tools" / "make_examples.py"
_SPEC = importlib.util.spec_from_file_location("make_examples", _TOOL)
make_examples = importlib.util.module_from_spec(_SPEC)
_SPEC.loader.exec_module(make_examples)

#: The phantom's motion: the library's breathing with a 2 deg tilt, so that the marker's
#: offset from the platform's origin moves it (50 mm x 2 deg = 1.7 mm).
PARAMS = ["--param", "tilt=2deg"]
REFERENCE = make_motion("breathing", {"tilt": "2deg"})
#: The tracker's clock at its first sample, ms (it started long before the phantom), and where
#: the phantom's motion was then, s of the reference's clock.
CLOCK_START_MS, REFERENCE_START_S = 123456.0, 2.0
#: The tracker's clock + this = the reference's, s (what a user who knows the relation gives).
CLOCK_OFFSET_S = REFERENCE_START_S - CLOCK_START_MS / 1e3
LATENCY_S, NOISE_RMS_M = 0.060, 0.12e-3
SETUP = tracker.emulated_setup(robot_geometry(load_scenario("phantom_hardware")))
MARKER_COLUMNS = "-,t [ms],X [mm],Y [mm],Z [mm]"
#: The axes a marker of positions only measures.
SEEN_XYZ = np.array([False] * 3 + [True] * 3)


def phantom_run(seconds=40.0, rate_hz=100.0, seed=0):
    """(t (n,) s on the tracker's clock, (n, 6) the platform's true poses in B): the phantom
    following REFERENCE LATENCY_S late."""
    t = CLOCK_START_MS / 1e3 + np.arange(int(round(seconds * rate_hz))) / rate_hz
    return t, REFERENCE.evaluate(t + CLOCK_OFFSET_S - LATENCY_S)[0]


#: Where a tracker whose axes are the base frame's has its origin, in the base frame, m.
ALIGNED_ORIGIN_M = np.array([0.4, -1.2, 0.9])


def tracker_view(x_BP, seed=0, rotations=False, aligned=False):
    """(n, 6) the marker's poses in the tracker's frame T with NOISE_RMS_M of 3-D error (NaN
    rotations unless ``rotations``, then 50 urad per axis): SETUP's tracker, or with
    ``aligned`` one whose axes are the base frame's, its origin at -ALIGNED_ORIGIN_M, the marker
    at the platform's origin."""
    rng = np.random.default_rng(seed)
    if aligned:
        x = np.array(x_BP, dtype=float)
        x[:, 3:] += ALIGNED_ORIGIN_M
    else:
        x = SETUP.tracker_poses(x_BP)
    x[:, 3:] += rng.normal(0.0, NOISE_RMS_M / np.sqrt(3.0), x[:, 3:].shape)
    if rotations:
        x[:, :3] += rng.normal(0.0, 50e-6, x[:, :3].shape)
    else:
        x[:, :3] = np.nan
    return x


#: A tracker's marker export written as tools/make_examples.py writes the shipped examples of
#: this case (a quoted header without units, semicolons, decimal commas, CRLF, ms, a closing
#: line of zeros): ``write_marker_export(path, t_s, xyz_m)`` -> path.
write_marker_export = make_examples.write_marker_export


def run_verify(tmp_path, *options):
    """``verify breathing --param tilt=2deg`` with ``options`` in process: (exit code, the JSON
    of the first measured file)."""
    out = tmp_path / "out"
    code = main(["verify", "breathing", *PARAMS, "--out", str(out), *options])
    reports = sorted(out.glob("verify_*.json"))
    return code, [json.loads(p.read_text()) for p in reports]


def export_options(export) -> list:
    """The options of an export: the file, its columns, the clocks' relation, a tolerance of
    0.2 mm."""
    return [
        "--measured",
        str(export),
        "--measured-columns",
        MARKER_COLUMNS,
        f"--clock-offset={CLOCK_OFFSET_S!r}",
        "--tolerance",
        "0.2mm,0.1deg",
    ]


@pytest.fixture(scope="module")
def export(tmp_path_factory):
    """The marker export in SETUP's tracker frame: 40 s at 100 Hz, positions only."""
    t, x = phantom_run()
    return write_marker_export(
        tmp_path_factory.mktemp("verify") / "markers.csv", t, tracker_view(x)[:, 3:]
    )


@pytest.fixture(scope="module")
def aligned_export(tmp_path_factory):
    """The same motion seen by a tracker whose axes are the base's, its marker at the
    platform's origin."""
    t, x = phantom_run()
    return write_marker_export(
        tmp_path_factory.mktemp("verify") / "aligned.csv", t, tracker_view(x, aligned=True)[:, 3:]
    )


@pytest.fixture(scope="module")
def fiducials_reg(tmp_path_factory):
    """SETUP's tracker registered from fiducials measured at 2 um (REG.yaml)."""
    return files.write_registration(
        tmp_path_factory.mktemp("reg") / "REG.yaml",
        SETUP.fiducials(tracker.MeasurementNoise(5e-6, 20e-6), seed=1),
    )


def _check_acceptance(figures):
    assert figures["latency_s"] == pytest.approx(LATENCY_S, abs=0.010)
    assert figures["fidelity"]["rms_translation_m"] == pytest.approx(NOISE_RMS_M, rel=0.15)
    assert figures["clock_offset_s"] == pytest.approx(CLOCK_OFFSET_S)


def test_an_export_on_the_base_axes_passes_its_offsets_removed_and_said(
    tmp_path, aligned_export, capsys
):
    code, (figures,) = run_verify(tmp_path, *export_options(aligned_export))
    out, err = capsys.readouterr()
    assert code == 0, out
    _check_acceptance(figures)
    # The verdict names what it compared; the JSON's passed is it.
    assert figures["passed"] is True and figures["verdict"]["passed"] is True
    line = figures["verdict"]["line"]
    assert line.startswith("PASS: aligned.csv (X, Y, Z; each axis's offset removed) against")
    latency_ms = float(re.search(r"; latency ([\d.]+) ms within 500 ms;", line).group(1))
    # The tracker's origin, removed and not judged, is said on the verdict line: it is larger
    # than the tolerance.
    assert line.endswith(
        "; a constant removed and not judged, larger than the tolerance: X +400 mm, Y -1200 mm, "
        "Z +900 mm (each measured axis's mean error, with --frame axes: a tracker's origin, a "
        "phantom set down off its place, or a localisation error; --frame base or "
        "--registration judges it)"
    )
    assert latency_ms == pytest.approx(LATENCY_S * 1e3, abs=10.0)
    assert out.splitlines()[0] == line
    # The offsets removed are the tracker's origin, to the noise's mean over ~3600 samples.
    removed = np.array(figures["offsets_removed"][3:])
    assert np.max(np.abs(removed - ALIGNED_ORIGIN_M)) < 10e-6
    assert figures["offsets_removed"][:3] == [0.0, 0.0, 0.0]
    assert figures["frame"]["how"] == "axes" and figures["frame"]["removes_offsets"]
    removed_words = " ".join(figures["removed"])
    assert "X +400 mm, Y -1200 mm, Z +900 mm" in removed_words
    assert "a constant offset of the whole phantom is not judged" in removed_words
    assert figures["measured"]["not_measured"] == ["phi", "theta", "psi"]
    fid = figures["fidelity"]
    assert fid["measured"] == ["X", "Y", "Z"] and np.isnan(fid["rms_rotation_rad"])
    assert fid["gamma"][0]["pass_rate"] == 1.0 and len(fid["cycles"]["starts"]) >= 8
    assert figures["startup"]["window_s"][1] == pytest.approx(4.0)  # the first breath
    md = (tmp_path / "out" / "verify_breathing_aligned.md").read_text()
    assert "rotation not measured" in md and "all zeros after the last sample" in md
    assert "| theta | 2 deg | not measured |" in md
    assert "Not measured, so not judged: phi, theta, psi." in md
    assert "What this check can see" in md and "this check fails a scale" in md
    # Progress on stderr before the work: each file read, then judged.
    assert "verify: reading" in err and "verify: aligning and judging aligned.csv" in err


def test_a_window_far_from_zero_is_printed_with_every_digit(tmp_path, aligned_export, capsys):
    """Judged three days into the reference's clock (a tracker's clock since it booted, the
    clocks' relation given): the windows of the verdict and of the figures show every digit
    before the point ("t = 259204-259240 s"), where 4 significant digits once printed both
    ends alike, "t = 2.592e+05-2.592e+05 s"."""
    options = export_options(aligned_export)
    options[options.index(f"--clock-offset={CLOCK_OFFSET_S!r}")] = (
        f"--clock-offset={CLOCK_OFFSET_S + 259_200!r}"
    )
    code, (figures,) = run_verify(tmp_path, *options)
    out = capsys.readouterr().out
    windows = re.findall(r"over t = (\d+(?:\.\d+)?)-(\d+(?:\.\d+)?) s", out)
    assert code == 0 and len(windows) == 2 and "e+05" not in out, out
    w0, w1 = figures["fidelity"]["window_s"]
    assert all(float(a) == pytest.approx(w0, abs=0.01) for a, _ in windows)
    assert all(float(b) == pytest.approx(w1, abs=0.01) for _, b in windows)
    assert 259_200 < w0 < w1 - 10


def test_a_tracker_turned_from_the_base_fails_without_a_registration_naming_the_turn(
    tmp_path, export, capsys
):
    code, (figures,) = run_verify(tmp_path, *export_options(export))
    out = capsys.readouterr().out
    assert code == 2 and figures["passed"] is False
    (cause,) = figures["verdict"]["causes"]
    assert "the measured motion is turned" in cause and "--registration" in cause
    # The turn named is the tracker's 30 deg less what a motion along one line cannot show.
    turned = float(cause.split("turned ")[1].split(" deg")[0])
    assert 20.0 < turned < 31.0
    assert out.startswith("FAIL: markers.csv (X, Y, Z; each axis's offset removed)")


def test_the_turned_tracker_registered_by_fiducials_passes_nothing_fitted(
    tmp_path, export, fiducials_reg
):
    code, (figures,) = run_verify(
        tmp_path, *export_options(export), "--registration", str(fiducials_reg)
    )
    assert code == 0, figures["verdict"]["line"]
    _check_acceptance(figures)
    assert figures["frame"]["how"] == "registration"
    assert figures["offsets_removed"] == [0.0] * 6
    assert "nothing fitted and no offset removed" in " ".join(figures["removed"])
    assert "registered to the base frame" in figures["verdict"]["compared"]


def registration_run(seconds=40.0, rate_hz=100.0, seed=7, noise_m=50e-6):
    """(t, (n, 3) positions): the library's registration motion as SETUP's tracker saw it,
    0.5 s of the motion's clock after the tracker's 500 s, 60 ms late."""
    t = 500.0 + np.arange(int(seconds * rate_hz)) / rate_hz
    x = make_motion("registration").evaluate(t - 500.0 + 0.5 - LATENCY_S)[0]
    seen = SETUP.tracker_poses(x)[:, 3:]
    return t, seen + np.random.default_rng(seed).normal(0.0, noise_m / np.sqrt(3), seen.shape)


def test_a_registration_motion_registers_the_tracker_once_and_later_runs_are_judged_in_it(
    tmp_path, export, capsys
):
    from pydrake.math import RollPitchYaw

    from stewart_drake.calibration.registration_file import read_fiducials, read_registration

    t, seen = registration_run()
    reg_csv = write_marker_export(tmp_path / "reg.csv", t, seen)
    reg = tmp_path / "REG.yaml"
    code = main(
        ["calibrate", "--register", str(reg_csv), "--measured-columns", MARKER_COLUMNS]
        + ["--out", str(reg)]
    )
    out = capsys.readouterr().out
    assert code == 0, out
    assert "This run is not judged" in out and "PASS" not in out and "FAIL" not in out
    assert sorted(p.name for p in tmp_path.iterdir()) == ["REG.yaml", "reg.csv"]
    # The frames written are the tracker's, to what 40 s of 50 um noise give.
    got = read_registration(reg)
    dR = (got.X_TB.rotation().inverse() @ SETUP.X_TB.rotation()).ToAngleAxis().angle()
    assert dR < 1e-3
    assert np.linalg.norm(got.X_TB.translation() - SETUP.X_TB.translation()) < 1e-3
    assert np.linalg.norm(got.X_PM.translation() - SETUP.X_PM.translation()) < 0.3e-3
    assert np.linalg.norm(SETUP.X_PM.translation()) == pytest.approx(0.05)
    assert "fitted to a registration motion" in got.words()
    assert np.allclose(RollPitchYaw(got.X_PM.rotation()).vector(), 0.0)  # no rotations seen
    # Later runs are judged in it: the turned tracker's export passes, nothing fitted.
    code, (figures,) = run_verify(tmp_path, *export_options(export), "--registration", str(reg))
    assert code == 0, figures["verdict"]["line"]
    _check_acceptance(figures)
    # calibrate identifies the kinematics a motion registration takes as true: it refuses it.
    with pytest.raises(InvalidConfigError, match="motion_frames: frames fitted to a registr"):
        read_fiducials(reg)


def test_a_run_of_another_motion_does_not_register_the_tracker_and_writes_nothing(
    tmp_path, export, capsys
):
    # A breathing's run given as the registration motion's: the marker stays millimetres from
    # the registration motion however the frames are fitted. (A motion that leaves the frames
    # undetermined, the breathing as the reference, is refused by the fit:
    # tests/test_registration_motion.py.)
    reg = tmp_path / "REG.yaml"
    code = main(
        ["calibrate", "--register", str(export), "--measured-columns", MARKER_COLUMNS]
        + ["--out", str(reg)]
    )
    err = capsys.readouterr().err.splitlines()[-1]
    assert code == 2 and not reg.exists()
    assert "mm RMS from registration" in err and "not this motion" in err, err


def test_a_6dof_marker_is_measured_in_rotation_too_and_a_constant_error_stays_with_base():
    t, x = phantom_run(seconds=20.0, rate_hz=120.0)
    seen = tracker_view(x, seed=2, rotations=True)
    measured = MeasuredMotion("m.csv", "tracker", t, seen, np.ones(6, bool), "test")
    ver = verify(
        REFERENCE, measured, clock_offset_s=CLOCK_OFFSET_S, registration=SETUP.registration()
    )
    assert ver.latency_s == pytest.approx(LATENCY_S, abs=0.005)
    assert ver.fidelity["rms_translation_m"] == pytest.approx(NOISE_RMS_M, rel=0.15)
    assert ver.fidelity["rms_rotation_rad"] == pytest.approx(50e-6 * np.sqrt(3), rel=0.15)
    assert ver.judgement.passed
    # Poses already in the base frame, with a true constant error of 0.3 mm on Y: "base" keeps
    # it in the figures and fails naming it; "axes" removes it (and says how much).
    in_base = x.copy()
    in_base[:, 4] += 0.3e-3
    kept = verify(
        REFERENCE,
        MeasuredMotion("b.csv", "tracker", t, in_base, np.ones(6, bool)),
        clock_offset_s=CLOCK_OFFSET_S,
        frame="base",
    )
    removed = verify(
        REFERENCE,
        MeasuredMotion("b.csv", "tracker", t, in_base, np.ones(6, bool)),
        clock_offset_s=CLOCK_OFFSET_S,
    )
    assert kept.fidelity["rms"][4] == pytest.approx(0.3e-3, rel=0.01)
    assert not kept.judgement.passed
    assert kept.judgement.causes == [
        "a constant offset of Y +0.3 mm (the phantom set down off its place or tilted, or a "
        "registration out of date)"
    ]
    assert removed.fidelity["rms"][4] < 1e-6 and removed.judgement.passed
    assert removed.offsets[4] == pytest.approx(0.3e-3, rel=1e-6)
    assert kept.latency_s == pytest.approx(LATENCY_S, abs=1e-4)


def test_without_the_clocks_relation_the_whole_shift_is_the_latency_not_judged():
    t, x = phantom_run(seconds=20.0)
    seen = tracker_view(x, seed=3, aligned=True)
    ver = verify(REFERENCE, MeasuredMotion("m.csv", "tracker", t, seen, SEEN_XYZ))
    # The shift is found wherever the tracker's clock starts (here 123 s before the motion's
    # clock), modulo the 4 s period of a motion that repeats; it all goes to the latency.
    assert ver.clock_offset_s == 0.0 and ver.clock == "not known"
    assert (ver.latency_s - (LATENCY_S - CLOCK_OFFSET_S)) % 4.0 == pytest.approx(0.0, abs=0.005)
    assert "The clocks' relation was not given" in ver.removed[0]
    assert ver.fidelity["rms_translation_m"] == pytest.approx(NOISE_RMS_M, rel=0.15)
    # A latency of 121 s passes: without the clocks' relation it is not judged, and said.
    assert ver.judgement.passed and not ver.judgement.latency_judged
    assert "latency not judged (the clocks' relation not given)" in ver.judgement.line


def test_the_encoder_log_and_the_tracker_side_by_side(tmp_path, export, fiducials_reg, capsys):
    """A robot run's encoder log (lead-in without t_path, readings with the encoders' zero
    errors, 17-bit counts) of a platform 15 ms late, beside the tracker's export."""
    scenario = load_scenario("phantom_hardware")
    geometry = robot_geometry(scenario)
    t_path = np.arange(0.0, 30.0, 0.01)
    x = REFERENCE.evaluate(t_path - 0.015)[0]
    q = tracker.quantize(ik(geometry, x) + geometry.encoder_offsets, 2**17)
    lead = np.full(50, np.nan)
    log = write_encoder_log(
        tmp_path / "run_encoders.csv",
        1.7e9 + np.arange(len(t_path) + 50) * 0.01,
        np.arange(len(t_path) + 50) * 0.01,
        np.concatenate([lead, t_path]),
        np.vstack([np.repeat(q[:1], 50, axis=0), q]),
    )
    code, reports = run_verify(
        tmp_path,
        "--measured",
        str(log),
        *export_options(export),
        "--registration",
        str(fiducials_reg),
    )
    printed = capsys.readouterr().out
    assert code == 0, printed
    markers, encoders = reports  # sorted by name: verify_breathing_markers, _run_encoders
    assert encoders["measured"]["kind"] == "encoders" and encoders["clock_offset_s"] == 0.0
    assert encoders["latency_s"] == pytest.approx(0.015, abs=0.002)
    assert encoders["fidelity"]["rms_translation_m"] < 10e-6
    assert encoders["fidelity"]["measured"] == ["phi", "theta", "psi", "X", "Y", "Z"]
    assert encoders["frame"]["how"] == "encoders"
    _check_acceptance(markers)
    assert "side by side:" in printed and "| run_encoders.csv | encoders | PASS |" in printed


def _write_export(path, seconds=20.0, drop=None, columns=3):
    t, x = phantom_run(seconds=seconds)
    xyz = tracker_view(x)[:, 3:]
    if drop is not None:
        xyz[drop, 1] = np.nan
    write_marker_export(path, t, xyz)
    if columns == 2:  # a tracker that exported two axes
        text = path.read_text().splitlines()
        path.write_text("\n".join(";".join(line.split(";")[:4]) for line in text) + "\n")
    return path


@pytest.mark.parametrize(
    "case, expected",
    [
        ("short", "lasts 2.99 s, shorter than one cycle of breathing (4 s)"),
        ("nan", "line 101: Y is missing or NaN"),
        ("columns", "a trace has a time column and 1 to 6 axes, got 0 axes"),
        ("fit", "--frame fit is gone: a frame fitted to the motion judged absorbs"),
        ("one axis registered", "this file measures X, Y: judge it without --registration"),
        ("no overlap", "no overlap"),
        ("registration", "base_points: 2 points: a frame needs at least 3"),
        ("clock", "the clock offset must be a number within +-1e+10 s"),
        ("long name", "bytes long; the file system takes names of at most 255 bytes"),
    ],
)
def test_a_hostile_measured_file_is_one_line_and_exit_2(tmp_path, capsys, case, expected):
    path = tmp_path / "m.csv"
    if case == "long name":  # a 240-character name: its report's name is longer than 255
        path = tmp_path / ("m" * 236 + ".csv")
        _write_export(path)
    columns = MARKER_COLUMNS
    offset = CLOCK_OFFSET_S
    if case == "short":
        _write_export(path, seconds=3.0)
    elif case == "nan":
        _write_export(path, drop=99)
    elif case == "columns":
        _write_export(path, columns=2)
        columns = "-,t [ms],-,-"
    elif case in ("fit", "one axis registered"):
        _write_export(path, columns=2)
        columns = "-,t [ms],X [mm],Y [mm]"
    elif case == "no overlap":
        _write_export(path)
        offset = -1e5
    elif case == "clock":
        _write_export(path)
        offset = 1e300
    options = ["--measured", str(path), "--measured-columns", columns, f"--clock-offset={offset}"]
    if case == "registration":  # REG.yaml naming 2 points: refused before any file is read
        reg = tmp_path / "REG.yaml"
        reg.write_text(
            "base_points:\n  - {base_m: [0, 0, 0], tracker_m: [1, 0, 0]}\n"
            "  - {base_m: [0.1, 0, 0], tracker_m: [1.1, 0, 0]}\n"
        )
        options += ["--registration", str(reg)]
    if case == "fit":
        options += ["--frame", "fit"]
    if case == "one axis registered":
        options += [
            "--registration",
            str(
                files.write_registration(
                    tmp_path / "REG.yaml",
                    SETUP.fiducials(tracker.MeasurementNoise(5e-6, 20e-6), seed=1),
                )
            ),
        ]
    code, reports = run_verify(tmp_path, *options)
    err = capsys.readouterr().err
    assert code == 2 and not reports
    # One line of refusal, last; before it only the progress lines of the work begun.
    *progress, refusal = err.strip("\n").split("\n")
    assert refusal.startswith("stewart-drake verify: ") and expected in refusal
    assert all(line.startswith("verify: ") for line in progress)
    if case == "long name":  # refused before the file is read, not after the judgement
        assert progress == [], progress


def _write_6dof(path, t_s, poses, quaternion: bool, order="wxyz"):
    """A 6-DoF marker's export with a header: t [s], X, Y, Z [m], then roll, pitch, yaw [rad]
    or the unit quaternion's columns in ``order`` (scalar ``w`` first or last), full precision."""
    xyz = [f"{a} [m]" for a in "XYZ"]
    if quaternion:
        q = Rotation.from_euler("ZYX", poses[:, 2::-1]).as_quat()  # x, y, z, w
        q *= np.where(np.arange(len(q)) % 2 == 0, 1.0, -1.0)[:, None]  # q and -q: one rotation
        cols = {c: q[:, "xyzw".index(c)] for c in order}
        header = ["t [s]", *xyz, *(f"q{c}" for c in order)]
        values = np.column_stack([t_s, poses[:, 3:], *(cols[c] for c in order)])
    else:
        header = ["t [s]", *xyz, "phi [rad]", "theta [rad]", "psi [rad]"]
        values = np.column_stack([t_s, poses[:, 3:], poses[:, :3]])
    lines = [",".join(header)] + [",".join(repr(float(v)) for v in row) for row in values]
    path.write_text("\n".join(lines) + "\n")
    return path


def test_a_quaternion_export_reads_as_the_same_rotations_and_is_judged_alike(tmp_path):
    # A tracker turned so that the marker's yaw in its frame hovers about pi (psi wraps there
    # as the platform tilts), exported as roll/pitch/yaw and as quaternions (scalar first, or
    # last; the sign flipping sample to sample, as some trackers write it): the same poses,
    # yaw unwrapped, the same verdict.
    t, x = phantom_run(seconds=12.0, rate_hz=50.0)
    seen = tracker_view(x, seed=4, rotations=True)
    turn = Rotation.from_rotvec([0.0, 0.0, np.pi - np.mean(seen[:, 2])])
    R = turn * Rotation.from_euler("ZYX", seen[:, 2::-1])
    seen = np.column_stack([np.unwrap(R.as_euler("ZYX")[:, ::-1], axis=0), turn.apply(seen[:, 3:])])
    rpy = read_measured(_write_6dof(tmp_path / "rpy.csv", t, seen, False))
    assert np.min(seen[:, 2]) < np.pi < np.max(seen[:, 2])  # the case is the one named
    for order in ("wxyz", "xyzw"):
        quat = read_measured(_write_6dof(tmp_path / f"q_{order}.csv", t, seen, True, order))
        assert quat.rotations_measured and quat.measured.all()
        # Roll, pitch and yaw as written, yaw unwrapped in time (2 pi off at most as a whole).
        turns = np.round((quat.poses[0, 2] - seen[0, 2]) / (2 * np.pi))
        moved = quat.poses - np.array([0, 0, 2 * np.pi * turns, 0, 0, 0])
        assert np.max(np.abs(moved - rpy.poses)) < 1e-9
    # The tracker's true frame: SETUP's, turned by ``turn`` after it.
    from pydrake.math import RigidTransform, RotationMatrix

    frame = SETUP.registration()
    turned = RigidTransform(RotationMatrix(turn.as_matrix()), np.zeros(3)) @ frame.X_TB
    reg = type(frame)(turned, frame.X_PM, frame.cov_B, frame.cov_M, 0.0, 0.0)
    a = verify(REFERENCE, rpy, clock_offset_s=CLOCK_OFFSET_S, registration=reg)
    b = verify(REFERENCE, quat, clock_offset_s=CLOCK_OFFSET_S, registration=reg)
    assert b.latency_s == pytest.approx(a.latency_s, abs=1e-9)
    for key in ("rms_translation_m", "rms_rotation_rad"):
        assert b.fidelity[key] == pytest.approx(a.fidelity[key], rel=1e-6)
    assert a.latency_s == pytest.approx(LATENCY_S, abs=0.005)
    assert a.fidelity["rms_rotation_rad"] == pytest.approx(50e-6 * np.sqrt(3), rel=0.2)


@pytest.mark.parametrize(
    "header, row, expected",
    [
        ("t [s],X [m],Y [m],Z [m],qx,qy,qz", "0.1,0,0,0,0,0,0", "one column each of qw (or q0)"),
        ("t [s],X [m],Y [m],Z [m],qw,qx,qy,qz", "0.1,0,0,0,0.5,0,0,0", "has norm 0.5"),
        ("t [s],X [m],Y [m],Z [m],qw,qx,qy,qz", "0.1,0,0,0,,0,0,0", "is missing or not a number"),
        (
            "t [s],X [m],Y [m],Z [m],q0,qx,qy,qz,psi [deg]",
            "0.1,0,0,0,1,0,0,0,0",
            "both a quaternion and roll, pitch or yaw",
        ),
    ],
)
def test_a_hostile_quaternion_is_refused_naming_its_line(tmp_path, header, row, expected):
    good = ",".join(["0"] + row.split(",")[1:4] + ["1", "0", "0", "0"][: len(row.split(",")) - 4])
    rows = [row.replace("0.1", f"{k / 10:g}", 1) for k in range(1, 6)]
    rows[0] = good if "norm" in expected or "missing" in expected else rows[0]
    path = tmp_path / "q.csv"
    path.write_text("\n".join([header, *rows]) + "\n")
    with pytest.raises(InvalidConfigError, match=expected.replace("(", r"\(").replace(")", r"\)")):
        read_measured(path)


def test_a_run_logged_a_period_short_of_two_breaths_is_judged_over_its_second():
    # robot breathing --duration 8 logs until 7.975 s: its second breath counts, cut to the log
    # (a cycle missed by up to 2 % of it at either end); one missed by more is refused.
    t = np.arange(0.0, 7.975, 0.005)
    x = REFERENCE.evaluate(t - 0.010)[0]
    ver = verify(REFERENCE, MeasuredMotion("r_encoders.csv", "encoders", t, x, np.ones(6, bool)))
    assert ver.fidelity["window_s"] == pytest.approx((4.0, 7.96), abs=1e-6)  # 10 ms late
    assert ver.judgement.passed and ver.latency_s == pytest.approx(0.010, abs=1e-4)
    short = t < 7.8
    with pytest.raises(InvalidConfigError, match="not one whole cycle"):
        verify(
            REFERENCE,
            MeasuredMotion("r_encoders.csv", "encoders", t[short], x[short], np.ones(6, bool)),
        )


def test_a_paused_export_is_refused_naming_the_option_and_judged_in_segments_with_it(
    tmp_path, capsys
):
    # 40 s at 100 Hz with no sample from 15 s to 27 s of the run: an imaging arc's pause.
    t, x = phantom_run()
    keep = ~((t - t[0] > 15.0) & (t - t[0] < 27.0))
    export = write_marker_export(
        tmp_path / "paused.csv", t[keep], tracker_view(x, aligned=True)[keep, 3:]
    )
    options = export_options(export)
    code, reports = run_verify(tmp_path, *options)
    err = capsys.readouterr().err
    assert code == 2 and reports == [] and "stop for 12.01 s after t = 138.446 s of the file" in err
    assert "give --measured-pauses to judge the stretches either side" in err
    code, (figures,) = run_verify(tmp_path, *options, "--measured-pauses")
    assert code == 0, capsys.readouterr().out
    line = figures["verdict"]["line"]
    assert (
        line.startswith("PASS")
        and "judged in 2 segments across a pause (12.01 s after t = 138.446 s of the file)" in line
    )
    # A pair and a registration take no pause, refused before any work.
    assert 2 == main(
        [
            "verify",
            "breathing",
            *PARAMS,
            "--out",
            str(tmp_path / "p"),
            *options,
            "--measured-pauses",
            "--surrogate",
            str(export),
            "--measured-surrogate",
            str(export),
        ]
    )
    assert "--measured-pauses judges one motion in segments" in capsys.readouterr().err
    assert 2 == main(
        [
            "verify",
            "breathing",
            *PARAMS,
            "--out",
            str(tmp_path / "r"),
            "--measured",
            str(export),
            "--measured-pauses",
            "--save-registration",
            str(tmp_path / "r.yaml"),
        ]
    )
    # A registration is calibrate's (calibrate --register, which takes no pause): said so.
    assert "--save-registration moved to calibrate" in capsys.readouterr().err
    assert not (tmp_path / "r.yaml").exists()
