"""``stewart-drake verify`` on a single-axis sensor, held against IntERAct's own alignment
(tests/interact_method.py, reimplemented from their MATLAB): a commanded 6-D trace in the
phantom's 7-column format at 5 Hz, a depth camera's file (its own clock, ~32 ms steps with 5 ms
of jitter and one 1.3 s gap, an offset of its own, 0.6 mm of noise), the robot 5.45 s after the
camera started. verify judges the depth on its one axis, names the five it did not measure, and
its delay and RMS error agree with their method (0.1 s, 15 %) and with the truth. With the
surrogate (``verify --surrogate``), the relative latency of the 6-DoF platform against the 1-DoF
one agrees with their ``RMSEAlignMethod.m`` (``shift6D - shift1D``) on the example pair seen by
one camera, and on their runs to 0.05 s on at least 12 of 21 (all 21 when measured). On IntERAct's
published laboratory runs (21, not shipped: their licence is not ours) with
``STEWART_DRAKE_INTERACT=PATH`` (a folder holding ``Figure 5 - Table 2``)."""

import json
import os

import numpy as np
import pytest
from interact_method import (
    MAX_GAP_S,
    TRACE_COLUMN,
    camera_file,
    laboratory_pairs,
    laboratory_runs,
    optimal_shift,
    read_columns,
    relative_latency,
)

from stewart_drake.cli.main import main
from stewart_drake.references.traces import load_trace
from stewart_drake.verification.measured_motion import read_measured
from stewart_drake.verification.pair_judgement import verify_pair

DELAY_S, OFFSET_MM, NOISE_MM = 5.45, 12.3, 0.6


def ap_motion(t):
    """A 4.2 s breath on AP growing to 10 mm peak to peak over its first 30 s (cos^4: a rest at
    exhale), mm: the "gradual start" of IntERAct's laboratory traces, which also tells one
    breath from the next."""
    return 10.0 * np.minimum(t / 30.0, 1.0) * (0.5 - np.cos(np.pi * t / 4.2 - np.pi / 2) ** 4)


def write_run(folder, seed=0, seconds=120.0):
    """(the 7-column trace, the camera's file, (t_in, y_in), (t_out, y_out)): the commanded
    trace at 5 Hz, quantised to 0.1 mm as IntERAct's are, and the camera's depth (``t [s],depth
    [mm]``) 5.45 s late on its own clock."""
    rng = np.random.default_rng(seed)
    t_in = np.arange(0.0, seconds, 0.2)
    y_in = np.round(ap_motion(t_in), 1)
    trace = folder / "commanded.txt"
    rows = [f"{t:.1f} 0 0 {y:.1f} 0 0 0" for t, y in zip(t_in, y_in)]
    trace.write_text("\n".join(rows) + "\n")
    steps = rng.uniform(0.0265, 0.0365, int((seconds + 10) / 0.0315))
    steps[len(steps) // 2] = 1.34  # the camera's hiccup, as in two of IntERAct's runs
    t_out = np.concatenate([[0.0], np.cumsum(steps)])
    t_out = t_out[t_out < seconds + DELAY_S]
    y_out = (
        OFFSET_MM
        + np.interp(t_out - DELAY_S, t_in, y_in, left=y_in[0], right=y_in[-1])
        + rng.normal(0.0, NOISE_MM, len(t_out))
    )
    camera = folder / "camera.csv"
    lines = ["t [s],depth [mm]"] + [f"{float(t)!r},{float(y)!r}" for t, y in zip(t_out, y_out)]
    camera.write_text("\n".join(lines) + "\n")
    return trace, camera, (t_in, y_in), (t_out, y_out)


def verify_depth(tmp_path, trace, camera, *options):
    """``verify TRACE --measured CAMERA --measured-map depth=AP`` in process: (exit code, JSON)."""
    out = tmp_path / "out"
    code = main(
        ["verify", str(trace), "--measured", str(camera), "--measured-map", "depth=AP"]
        + [
            "--measured-max-gap",
            str(MAX_GAP_S),
            "--tolerance",
            "1mm,1deg",
            "--out",
            str(out),
            *options,
        ]
    )
    (report,) = sorted(out.glob("verify_*.json"))
    return code, json.loads(report.read_text())


def test_a_depth_camera_is_judged_on_its_axis_as_interact_aligns_it(tmp_path, capsys):
    trace, camera, (t_in, y_in), (t_out, y_out) = write_run(tmp_path)
    code, figures = verify_depth(tmp_path, trace, camera)
    out = capsys.readouterr().out
    assert code == 0, out
    assert figures["measured"]["axes"] == ["Z"]
    assert figures["measured"]["not_measured"] == ["phi", "theta", "psi", "X", "Y"]
    assert out.startswith("PASS: camera.csv (Z; each axis's offset removed) against commanded")
    delay, rms = -figures["shift_s"], figures["fidelity"]["rms"][5] * 1e3
    # Their method, on the same files' numbers.
    their_delay, their_offset, their_rmse = optimal_shift(t_in, y_in, t_out, y_out)
    assert delay == pytest.approx(their_delay, abs=0.1)
    assert rms == pytest.approx(their_rmse, rel=0.15)
    assert their_offset == pytest.approx(OFFSET_MM, abs=0.05)
    # And the truth: the delay, the camera's noise as the error.
    assert delay == pytest.approx(DELAY_S, abs=0.01)
    assert rms == pytest.approx(NOISE_MM, rel=0.08)
    # Judged at its own samples: an interpolation between two noisy samples would halve part
    # of their noise (the figure 11 % lower on IntERAct's runs).
    assert "each is judged at its own time, nothing resampled" in " ".join(figures["removed"])


def test_the_cameras_gap_is_refused_unless_a_longer_gap_is_allowed(tmp_path, capsys):
    trace, camera, _, _ = write_run(tmp_path)
    code = main(
        ["verify", str(trace), "--measured", str(camera), "--measured-map", "depth=AP"]
        + ["--out", str(tmp_path / "out")]
    )
    err = capsys.readouterr().err.strip().splitlines()[-1]
    assert code == 2
    assert "the measured samples stop for 1.34 s after t = " in err and "--measured-max-gap" in err


def test_a_depth_camera_on_a_phantom_at_rest_fails(tmp_path):
    trace, camera, _, (t_out, _) = write_run(tmp_path)
    rng = np.random.default_rng(3)
    still = OFFSET_MM + rng.normal(0.0, NOISE_MM, len(t_out))
    lines = ["t [s],depth [mm]"] + [f"{float(t)!r},{float(y)!r}" for t, y in zip(t_out, still)]
    camera.write_text("\n".join(lines) + "\n")
    code, figures = verify_depth(tmp_path, trace, camera)
    assert code == 2 and figures["passed"] is False
    # "Did not move" is judged against the reference's motion, not the tolerance: the camera's
    # noise is more than a tenth of it, and is named as such.
    causes = figures["verdict"]["causes"]
    assert any("did not move" in c or "or noise" in c for c in causes), causes


INTERACT = os.environ.get("STEWART_DRAKE_INTERACT", "")


@pytest.mark.skipif(
    not INTERACT,
    reason="IntERAct's laboratory runs are not shipped (their licence is not ours): "
    "STEWART_DRAKE_INTERACT=PATH to a folder holding 'Figure 5 - Table 2' runs this test",
)
@pytest.mark.parametrize("k", range(21))
def test_interacts_laboratory_runs_agree_with_their_method(tmp_path, k):
    runs = laboratory_runs(INTERACT)
    if k >= len(runs):
        pytest.skip(f"{len(runs)} runs found under {INTERACT}")
    label, trace, time_file, depth_file = runs[k]
    t_out, y_out = read_columns(time_file), read_columns(depth_file)
    data = read_columns(trace)
    camera = tmp_path / "camera.csv"
    lines = ["t [s],depth [mm]"] + [f"{float(t)!r},{float(y)!r}" for t, y in zip(t_out, y_out)]
    camera.write_text("\n".join(lines) + "\n")
    code, figures = verify_depth(tmp_path, trace, camera)
    their_delay, _, their_rmse = optimal_shift(data[:, 0], data[:, TRACE_COLUMN], t_out, y_out)
    assert -figures["shift_s"] == pytest.approx(their_delay, abs=0.1), label
    assert figures["fidelity"]["rms"][5] * 1e3 == pytest.approx(their_rmse, rel=0.15), label


def test_the_relative_latency_agrees_with_their_method_on_a_pair(tmp_path):
    """The example pair (trace.txt, surrogate.txt) seen by one camera, the internal platform
    0.12 s later than the surrogate: verify's relative latency, their ``shift6D - shift1D`` (at
    RMSEAlignMethod.m's 0.01 s steps) and the truth agree."""
    from stewart_drake.organ_motion.examples import FOLDER

    rng = np.random.default_rng(8)
    t = np.concatenate([[0.0], np.cumsum(rng.uniform(0.0265, 0.0365, 3800))])
    depths = []
    for path, column, delay in (
        (FOLDER / "trace.txt", 3, 5.57),
        (FOLDER / "surrogate.txt", 1, 5.45),
    ):
        data = np.loadtxt(path)
        u = np.clip(t - delay, data[0, 0], data[-1, 0])
        depth = np.interp(u, data[:, 0], data[:, column]) + rng.normal(0.0, 0.3, len(t))
        np.savetxt(tmp_path / f"depth_{column}.txt", depth)
        depths.append(tmp_path / f"depth_{column}.txt")
    np.savetxt(tmp_path / "time.txt", t)
    files = (FOLDER / "trace.txt", FOLDER / "surrogate.txt", tmp_path / "time.txt", *depths)
    theirs, _, _ = relative_latency(*files, step=0.01)
    internal = camera_file(tmp_path / "internal.csv", files[2], files[3])
    surrogate = camera_file(tmp_path / "surrogate.csv", files[2], files[4])
    pair = verify_pair(
        load_trace(files[0]),
        load_trace(files[1]),
        read_measured(internal, axis_map={"depth": "AP"}),
        read_measured(surrogate, axis_map={"depth": "SI"}),
        tolerance=(1e-3, 0.02),
    )
    assert theirs == pytest.approx(0.12, abs=0.015)
    assert pair.relative_latency_s == pytest.approx(theirs, abs=0.02)
    assert pair.relative_latency_s == pytest.approx(0.12, abs=0.01)
    assert not pair.judgement.passed  # 0.12 s is beyond the 0.1 s bound


@pytest.mark.slow
@pytest.mark.skipif(
    not INTERACT,
    reason="IntERAct's laboratory runs are not shipped (their licence is not ours): "
    "STEWART_DRAKE_INTERACT=PATH to a folder holding 'Figure 5 - Table 2' runs this test",
)
def test_interacts_relative_latencies_agree_with_their_method(tmp_path):
    """Each of their 21 runs judged by verify_pair on the camera's two depths (verify's own
    clock search) and by their RMSEAlignMethod.m (0.05 s steps, as IntERAct_data_analysis.m
    searches): within 0.05 s on at least 12 (the issue's acceptance), within 0.1 s on all."""
    pairs = laboratory_pairs(INTERACT)
    if not pairs:  # a folder of IntERAct's traces only, as the robot's tests read
        pytest.skip(f"no laboratory runs under {INTERACT} ('Figure 5 - Table 2')")
    assert len(pairs) == 21, [p[0] for p in pairs]
    differences = []
    for k, (label, trace, resp, time_file, depth_6d, depth_1d) in enumerate(pairs):
        internal = camera_file(tmp_path / f"{k}_6d.csv", time_file, depth_6d)
        surrogate = camera_file(tmp_path / f"{k}_1d.csv", time_file, depth_1d)
        pair = verify_pair(
            load_trace(trace),
            load_trace(resp),
            read_measured(internal, axis_map={"depth": "AP"}),
            read_measured(surrogate, axis_map={"depth": "SI"}),
            tolerance=(1e-3, 0.02),
            max_gap_s=MAX_GAP_S,
        )
        theirs, s6, s1 = relative_latency(trace, resp, time_file, depth_6d, depth_1d)
        assert -pair.internal_shift_s == pytest.approx(s6, abs=0.1), label
        assert -pair.surrogate_shift_s == pytest.approx(s1, abs=0.1), label
        assert pair.judgement.meaningful, (label, pair.judgement.line)
        differences.append(abs(pair.relative_latency_s - theirs))
    assert max(differences) <= 0.1, differences
    assert sum(d <= 0.05 + 1e-9 for d in differences) >= 12, differences
