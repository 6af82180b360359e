"""`stewart-drake reproduce` as a user runs it: a library motion, a recorded trace (30 Hz, mm and
deg, a gap), a trace beyond the motors, scaling to fit, learning, phantom files as they come; its
report's figure and its replay. The fidelity measures themselves are tests/test_fidelity.py's."""

import json
import math

import numpy as np
import pytest
from conftest import write_trace

from stewart_drake.cli import main as cli
from stewart_drake.organ_motion import fidelity as fd
from stewart_drake.organ_motion import fidelity_figure as fr
from stewart_drake.organ_motion import reproduction
from stewart_drake.references.organ.library import OrganMotionReference
from stewart_drake.robot.geometry import X_HOME


def _run(capsys, argv, code=0):
    rc = cli.main(argv + ["--no-progress"])
    out, err = capsys.readouterr()
    assert rc == code, (out, err)
    return out, err


def test_reproduce_a_library_motion_writes_its_report(tmp_path, capsys):
    one_breath = "reproduce breathing --param period=1s --cycles 1".split()
    out, _ = _run(capsys, one_breath + ["--param", "amplitude=6mm", "--out", str(tmp_path)])
    # The verdict names what it compares: the robot's true pose against the motion asked for.
    judged = "the robot's true pose against the reference (breathing)"
    assert f"PASS: {judged}, RMS error per axis" in out and "wrote" in out
    md = (tmp_path / "reproduce_breathing.md").read_text()
    assert f"**PASS: {judged}, RMS error per axis within 0.1 mm | 0.1 deg" in md
    assert "Belcher et al." in md and "breathing 1" in md and "reproduce_breathing.png" in md
    figures = json.loads((tmp_path / "reproduce_breathing.json").read_text())
    assert figures["fidelity"]["window_s"] == pytest.approx([1.0, 2.0], abs=2e-3)
    assert 1e-6 < figures["fidelity"]["rms"][3] < 1e-4
    assert (tmp_path / "reproduce_breathing.png").stat().st_size > 20_000
    out, _ = _run(capsys, one_breath + ["--tolerance", "1um,1urad", "--out", str(tmp_path)], code=2)
    assert f"FAIL: {judged}, RMS error per axis beyond" in out


def test_a_recorded_trace_round_trip(tmp_path, capsys):
    """A trace written in mm and deg at 30 Hz with a gap is imported, reproduced, reported."""
    t = np.arange(0.0, 3.0, 1 / 30)
    shape = np.cos(np.pi * t / 1.0) ** 4  # 1 s breaths
    trace = write_trace(
        tmp_path / "patient.csv",
        t,
        {"SI [mm]": 8 * shape, "AP [mm]": 2 * np.roll(shape, 2), "rot_LR [deg]": 0.3 * shape},
        gap=(1.3, 1.5),
    )
    out, _ = _run(
        capsys, ["reproduce", str(trace), "--lowpass-hz", "8", "--out", str(tmp_path / "out")]
    )
    md = (tmp_path / "out" / "reproduce_patient.md").read_text()
    figures = json.loads((tmp_path / "out" / "reproduce_patient.json").read_text())
    fid = figures["fidelity"]
    assert fid["moving"] == ["theta", "X", "Z"]
    assert fid["p2p"][3] == pytest.approx(0.008, rel=0.03)  # mm -> m
    assert fid["p2p"][1] == pytest.approx(math.radians(0.3), rel=0.03)  # deg -> rad
    assert fid["window_s"][1] == pytest.approx(t[-1], abs=2e-3)
    assert fid["rms"][3] < 1e-4 and "PASS" in md


def test_a_trace_beyond_the_motors_is_refused_naming_the_motor_and_the_time(tmp_path, capsys):
    t = np.arange(0.0, 2.0, 1 / 30)
    trace = write_trace(tmp_path / "fast.csv", t, {"Z [mm]": 12 * np.sin(2 * np.pi * 6 * t)})
    _, err = _run(capsys, ["reproduce", str(trace), "--out", str(tmp_path / "out")], code=2)
    lines = err.strip().splitlines()
    assert len(lines) == 1
    assert "motor" in lines[0] and "would need" in lines[0] and "at t = " in lines[0]
    assert not (tmp_path / "out" / "reproduce_fast.md").exists()


def test_scale_to_fit_says_by_how_much(tmp_path, capsys):
    t = np.arange(0.0, 1.0, 1 / 100)
    trace = write_trace(tmp_path / "fast.csv", t, {"Z [mm]": 12 * np.sin(2 * np.pi * 6 * t)})
    rc = cli.main(
        [
            "reproduce",
            str(trace),
            "--scale-to-fit",
            "--tolerance",
            "1m,1rad",
            "--out",
            str(tmp_path / "out"),
            "--no-progress",
        ]
    )
    out, err = capsys.readouterr()
    assert rc == 0, err
    scale = float(out.split("scaled by ")[1].split()[0])
    assert 0.2 < scale < 1.0
    figures = json.loads((tmp_path / "out" / "reproduce_fast.json").read_text())
    assert figures["scale"] == pytest.approx(scale, abs=1e-3)
    assert figures["fidelity"]["p2p"][5] == pytest.approx(0.024 * scale, rel=0.02)


def test_reproduce_learns_on_request(tmp_path, capsys):
    out, _ = _run(
        capsys,
        [
            "reproduce",
            "breathing",
            "--scenario",  # the LQI without feed-forwards, whose cycles learning cuts to 0.3
            "paper_hardware",
            "--param",
            "period=0.6s",
            "--param",
            "amplitude=4mm",
            "--learn-cycles",
            "3",
            "--cycles",
            "1",
            "--out",
            str(tmp_path),
        ],
    )
    md = (tmp_path / "reproduce_breathing.md").read_text()
    assert "Learner: learned from 3 cycles, 0 rollback(s)" in md
    cycles = json.loads((tmp_path / "reproduce_breathing.json").read_text())["fidelity"]
    per_cycle = cycles["cycles"]["rms_translation_m"]
    assert len(per_cycle) == 4 and per_cycle[-1] < 0.3 * per_cycle[0]


@pytest.mark.parametrize(
    "argv, expected",
    [
        (["reproduce", "cough"], "unknown motion 'cough'"),
        (["reproduce", "breathing", "--param", "depth=3mm"], "has no parameter 'depth'"),
        (["reproduce", "breathing", "--param", "amplitude"], "--param takes KEY=VALUE"),
        (
            ["reproduce", "breathing", "--map", "SI=X"],
            "--centre-on, --max-gap, --smoothing, --seam-blend are for a trace file",
        ),
        (["reproduce", "breathing", "--tolerance", "0.1mm"], "one length and one angle"),
        (["reproduce", "missing.csv"], "no trace at"),
    ],
)
def test_bad_reproduce_arguments_give_one_line(tmp_path, capsys, argv, expected):
    _, err = _run(capsys, argv + ["--out", str(tmp_path)], code=2)
    assert len(err.strip().splitlines()) == 1 and expected in err


def test_reproduce_takes_a_phantom_trace_as_it_comes(tmp_path, capsys):
    """A 7-column phantom file (.txt, spaces, no header) and a ';'-separated decimal-comma
    marker file are reproduced with no editing; the report says how each was read."""
    t = np.arange(0.0, 12.0, 0.2)
    phantom = tmp_path / "Lung trace.txt"
    rows = np.column_stack(
        [t, 0.3 * np.sin(t), 4.0 * np.sin(np.pi * t / 2), np.cos(t), 0.5 * np.sin(t), 0 * t, 0 * t]
    )
    phantom.write_text("\n".join(" ".join(f"{v:.5g}" for v in r) for r in rows))
    marker = tmp_path / "marker.csv"
    marker.write_text(
        "t [s];SI [mm]\n" + "".join(f"{a:.2f};{3 * math.sin(a):.4f}\n".replace(".", ",") for a in t)
    )
    for path, layout in (
        (phantom, "phantom format, no header, separated by spaces"),
        (marker, "header, separated by semicolons, decimal commas"),
    ):
        out = tmp_path / path.stem
        code = cli.main(
            ["reproduce", str(path), "--duration", "1", "--no-progress", "--out", str(out)]
        )
        printed = capsys.readouterr()
        assert code == 0, printed.err
        md = (out / f"reproduce_{path.stem}.md").read_text()
        assert f"Trace: {path.name} ({layout}): " in md, md[:600]
        assert "**PASS" in md


def test_the_report_figure_gives_each_error_its_axis_and_tolerance_and_keeps_peaks(
    tmp_path, monkeypatch
):
    import matplotlib.pyplot as plt

    from stewart_drake.run.scenario_io import load_scenario

    t = np.arange(1_000_003) * 1e-3
    y = np.zeros_like(t)
    y[777_777] = 5.0  # one spike in a long run
    tt, yy = fr._thinned(t, y, peaks=True)
    assert tt.size <= fr.PLOT_POINTS + 1 and yy.max() == 5.0  # the peak is kept
    assert fr._thinned(t, y)[0].size <= fr.PLOT_POINTS + 1

    from stewart_drake.run.scenario import dump_scenario

    scenario = load_scenario("paper_hardware")
    scenario.reference = OrganMotionReference("breathing", {"period": "1s"})
    given = dump_scenario(scenario)
    rep = reproduction.reproduce(scenario, learn_cycles=1, eval_cycles=1)
    # The run's duration and learner are on the plan's copy; the caller's scenario is unchanged
    # (it was changed in place: its duration_s and learning were the run's).
    assert dump_scenario(scenario) == given
    assert rep.plan.scenario.duration_s == pytest.approx(2.0) and rep.learn_cycles == 1
    assert rep.plan.scenario.learning.learn_cycles == 1 and scenario.learning is None
    # The run is run_experiment's: its result carries the learner's record, a row per state
    # sample and the state at the end.
    assert rep.learner is rep.result.learner_status
    assert rep.learner.shape[0] == rep.result.t_state.size + 1
    figures = []
    monkeypatch.setattr(plt, "close", figures.append)
    fr.plot_report(rep, tmp_path / "r.png", (0.1e-3, math.radians(0.1)))
    (fig,) = figures
    by_label = {ax.get_ylabel(): ax for ax in fig.axes}
    for label, tolerance in (
        ("translation\nerror [um]", 100.0),
        ("rotation\nerror [urad]", 1e6 * math.radians(0.1)),
    ):
        lines = by_label[label].get_lines()
        assert any(np.allclose(ln.get_ydata(), tolerance) for ln in lines), label


def test_a_long_run_s_figure_zooms_at_full_rate_on_its_largest_error(tmp_path, monkeypatch):
    """120 s of logs with one 0.2 mm spike at t = 83.4 s: the figure adds a 10 s zoom centred on
    it, drawn at full rate (every sample of those 10 s)."""
    from types import SimpleNamespace

    import matplotlib.pyplot as plt

    t = np.arange(0.0, 120.0, 1e-3)
    x_d = np.tile(X_HOME, (t.size, 1))
    x_d[:, 3] += 5e-3 * np.sin(2 * np.pi * t / 4)
    x = x_d.copy()
    x[:, 3] += 2e-6 * np.sin(2 * np.pi * 37 * t)
    spike = int(round(83.4 / 1e-3))
    x[spike, 3] += 2e-4
    fid = fd.fidelity(t, x, x_d, (4.0, 120.0))
    rep = SimpleNamespace(
        name="long",
        fidelity=fid,
        result=SimpleNamespace(t=t, x=x, x_d=x_d),
        learn_cycles=0,
    )
    figures = []
    monkeypatch.setattr(plt, "close", figures.append)
    fr.plot_report(rep, tmp_path / "long.png", (0.1e-3, math.radians(0.1)))
    (fig,) = figures
    (zoom,) = [ax for ax in fig.axes if ax.get_ylabel() == "zoom: translation\nerror [um]"]
    # Each translation axis's error is drawn (the tolerance is per axis); the spike is on X.
    (line,) = [ln for ln in zoom.get_lines() if ln.get_label() == "|X error|"]
    assert {ln.get_label() for ln in zoom.get_lines()} >= {"|Y error|", "|Z error|"}
    ts = np.asarray(line.get_xdata())
    assert ts[0] == pytest.approx(78.4, abs=2e-3) and ts[-1] == pytest.approx(88.4, abs=2e-3)
    assert ts.size == pytest.approx(10_001, abs=2)  # full rate
    assert max(line.get_ydata()) == pytest.approx(200.0, rel=0.02)  # the spike, in um


def test_reproduce_writes_its_replay_with_the_reference_s_ghost_and_the_error(tmp_path, capsys):
    """``reproduce --html``: the robot from the run's plant-state log (every 10 ms), the
    reference's ghost at the trace's pose in every frame, and the error marker coloured against
    the tolerance."""
    from meshcat_html import read_meshcat_commands

    from stewart_drake.viz import visualize

    t = np.arange(0.0, 4.0, 0.04)
    trace = tmp_path / "short trace.txt"
    rows = np.column_stack([t, 0 * t, 3.0 * np.sin(np.pi * t / 2), 0 * t, 0 * t, 0 * t, 0 * t])
    trace.write_text("\n".join(" ".join(f"{v:.5g}" for v in r) for r in rows))
    html = tmp_path / "replay.html"
    out, _ = _run(
        capsys,
        ["reproduce", str(trace), "--duration", "2", "--out", str(tmp_path), "--html", str(html)],
    )
    assert f"wrote {html}" in out
    text = html.read_text()
    assert "blue ghost: the reference" in text
    assert "PASS: the robot&#x27;s true pose against the reference (short trace), RMS" in text
    (animation,) = [c for c in read_meshcat_commands(text) if c["type"] == "set_animation"]
    clips = {a["path"]: a["clip"] for a in animation["animations"]}
    ghost = {k["name"]: k["keys"] for k in clips[visualize.GHOST_PATH]["tracks"]}
    n_frames = int(2.0 * visualize.REPLAY_FPS) + 1
    assert [k["time"] for k in ghost[".position"]] == list(range(n_frames))
    # The trace's SI (platform X, 3 mm amplitude) moves the ghost: 2 s is half a period.
    x = np.array([k["value"][0] for k in ghost[".position"]])
    assert 2e-3 < np.ptp(x) < 7e-3
    marker = {k["name"]: k["keys"] for k in clips[visualize.ERROR_MARKER_PATH]["tracks"]}
    np.testing.assert_allclose(
        [k["value"][2] for k in marker[".position"]],
        [k["value"][2] + visualize.ERROR_MARKER_HEIGHT_M for k in ghost[".position"]],
        atol=1e-12,
    )
    # Its colour changes with the error (recorded where it changes), one of the three.
    (track,) = clips[visualize.ERROR_MARKER_PATH + "/<object>"]["tracks"]
    assert track["name"] == ".color" and track["keys"][0]["time"] == 0
    for key in track["keys"]:
        assert any(np.allclose(key["value"], rgba) for rgba in visualize.ERROR_COLOURS)
    assert visualize.error_colour(40e-6, 1e-4) == visualize.ERROR_COLOURS[0]
    assert visualize.error_colour(60e-6, 1e-4) == visualize.ERROR_COLOURS[1]
    assert visualize.error_colour(math.nan, 1e-4) == visualize.ERROR_COLOURS[2]
