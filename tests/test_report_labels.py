"""A reproduction's report says how the run learned: a feed-forward run and a held model are not
"no learning", the model file is named in the .md, the .json and the figure, the figure's title
wraps a long name instead of running off both ends; ``reproduce`` applies a scenario's
``learning.learned_from`` as ``run`` does."""

import json
from types import SimpleNamespace

import numpy as np
import pytest
from conftest import write_trace

from stewart_drake.base.errors import InvalidConfigError, StewartError
from stewart_drake.cli.main import main
from stewart_drake.cli.registry import build_parser
from stewart_drake.control import feedforward_basis as ff
from stewart_drake.control.feedforward_tuning import FeedforwardTuning
from stewart_drake.organ_motion.command import _feedforward_choice
from stewart_drake.organ_motion.fidelity import fidelity
from stewart_drake.organ_motion.fidelity_figure import TITLE_POINTS, report_title
from stewart_drake.organ_motion.fidelity_report import report_markdown, write_report
from stewart_drake.organ_motion.reproduction import Reproduction, learning_words
from stewart_drake.run.scenario_io import load_scenario

TOL = (1e-4, np.radians(0.1))


def _rep(name: str, learning: str = "", learned_from: str = "", learn_cycles: int = 0):
    """A reproduction of 4 s of 0.25 Hz breathing on Z tracked 20 um off, without a run."""
    t = np.arange(0.0, 4.0, 0.01)
    x_d = np.zeros((t.size, 18))
    x_d[:, 5] = 0.3 + 0.005 * np.sin(2 * np.pi * 0.25 * t)
    x = x_d[:, :12].copy()
    x[:, 5] += 2e-5
    result = SimpleNamespace(t=t, x=x, x_d=x_d, config_summary={"controller": "LQI"})
    return Reproduction(
        name=name,
        reference=None,
        scale=1.0,
        result=result,
        cycle_starts=np.zeros(0),
        learn_cycles=learn_cycles,
        fidelity=fidelity(t, x, x_d, (0.4, 4.0)),
        learning=learning,
        learned_from=learned_from,
    )


def test_learning_words_name_each_way_a_run_learns():
    assert learning_words(None) == "no learning"
    assert learning_words(None, 3) == "learning from 3 cycles, then held"
    assert learning_words(FeedforwardTuning()) == "feed-forward learned over the run"
    started = FeedforwardTuning(learned_from="/data/m/model.npz")
    assert learning_words(started) == "feed-forward started from model.npz, learning over the run"
    held = FeedforwardTuning(learned_from="/data/m/model.npz", learn=False)
    assert learning_words(held) == "feed-forward model.npz held, not learning"


def test_the_report_names_the_held_model_in_its_first_line_md_json_and_figure(tmp_path):
    model = "/data/commissioning/liver_model.npz"
    held = learning_words(FeedforwardTuning(learned_from=model, learn=False))
    rep = _rep("liver", held, model)
    text = report_markdown(rep, TOL)
    run_line = next(line for line in text.splitlines() if line.startswith("Run:"))
    assert "liver_model.npz held, not learning" in run_line and "no learning" not in run_line
    assert f"Feed-forward model: {model}." in text
    md, png, js = write_report(rep, tmp_path, TOL)
    figures = json.loads(js.read_text())
    assert figures["learned_from"] == model and figures["learning"] == held
    assert "liver_model.npz" in report_title(rep, "PASS")
    # a run without learning still says so
    plain = report_markdown(_rep("liver"), TOL)
    assert ", no learning);" in plain and "Feed-forward model" not in plain


def test_the_report_gives_the_start_up_and_the_encoders_resolution_beside_the_figures(tmp_path):
    """The measured window leaves out the start-up: the report and its .json give it (RMS and
    peak), and the encoders' resolution at the reference's poses (a robot at home, 17 bits:
    5.9 um / 33.8 urad), beside the measured figures; a robot that reads its angles exactly
    has no such line."""
    import dataclasses

    from stewart_drake.organ_motion.reproduction import _startup
    from stewart_drake.robot.geometry import X_HOME, reference_geometry

    rep = _rep("breathing")
    rep.result.x_d[:, :6] += np.asarray(X_HOME) - np.array([0, 0, 0, 0, 0, 0.3])
    rep.result.x[:, :6] += np.asarray(X_HOME) - np.array([0, 0, 0, 0, 0, 0.3])
    rep.result.x[:40, 3] += 1e-4  # the first 0.4 s, before the window: 0.1 mm off on X
    rep = dataclasses.replace(
        rep,
        startup=_startup(rep.result, rep.fidelity["window_s"]),
        geometry=reference_geometry(),
        encoder_quantum_rad=2 * np.pi / 2**17,
    )
    assert rep.startup["rms_translation_m"] == pytest.approx(np.hypot(1e-4, 2e-5), rel=1e-9)
    text = report_markdown(rep, TOL)
    assert "Start-up, not in the figures above or below (t = 0-0.4 s): RMS 102 um" in text
    line = next(x for x in text.splitlines() if x.startswith("Encoders' resolution"))
    assert "at these poses: 5.9" in line and " um / 33." in line
    figures = json.loads(write_report(rep, tmp_path, TOL)[2].read_text())
    assert figures["startup"]["peak_translation_m"] == pytest.approx(np.hypot(1e-4, 2e-5))
    assert figures["encoder_resolution_m_rad"][0] == pytest.approx(5.9e-6, rel=0.02)
    exact = report_markdown(dataclasses.replace(rep, encoder_quantum_rad=0.0), TOL)
    assert "Encoders' resolution" not in exact


def test_a_long_name_in_the_figure_title_wraps_within_the_figure():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    name = "patient_0042_liver_fraction_03_" + "x" * 150 + "_marker_export_2026-11-23"
    rep = _rep(name, learning_words(FeedforwardTuning(learned_from=f"/m/{name}.npz")))
    title = report_title(rep, "PASS: translation 20 um RMS")
    assert len(title.splitlines()) > 2
    assert title.replace("\n", "").startswith(name) and f"{name}.npz" in title.replace("\n", "")
    fig = plt.figure(figsize=(10, 8))
    text = fig.suptitle(title, fontsize=TITLE_POINTS)
    fig.canvas.draw()
    box = text.get_window_extent()
    width = fig.get_window_extent().width
    plt.close(fig)
    assert box.x0 >= 0 and box.x1 <= width  # neither end cut


def _args(*argv):
    return build_parser().parse_args(["reproduce", "breathing", *argv])


def test_reproduce_takes_a_scenarios_learned_model_and_flags_override_it(tmp_path):
    path = ff.save_learned(tmp_path / "m.npz", np.zeros((ff.basis_size(), 6)))
    scenario = load_scenario(
        "paper_hardware", [f"learning=!FeedforwardTuning {{learned_from: {path}, learn: false}}"]
    )
    chosen = _feedforward_choice(_args(), scenario)
    assert chosen is not None and chosen.learned_from == str(path) and not chosen.learn
    assert _feedforward_choice(_args("--feedforward"), scenario).learn  # the flag learns on
    with pytest.raises(InvalidConfigError, match="choose one"):
        _feedforward_choice(_args("--learn-cycles", "2"), scenario)
    # a FeedforwardTuning without a model stays settings for --feedforward, as documented
    settings = load_scenario("paper_hardware", ["learning=!FeedforwardTuning {stretch_s: 4.0}"])
    assert _feedforward_choice(_args(), settings) is None
    bad = load_scenario(
        "paper_hardware", [f"learning=!FeedforwardTuning {{learned_from: {tmp_path / 'no.npz'}}}"]
    )
    with pytest.raises((StewartError, FileNotFoundError), match="no.npz"):  # before the run
        _feedforward_choice(_args(), bad)


def test_a_reproduce_run_on_a_scenarios_held_model_says_so(tmp_path, capsys):
    """A few seconds of a trace on a scenario holding a learned model (zeros): the learner
    runs (its line in the report), the first line says the model is held and names it."""
    model = ff.save_learned(tmp_path / "held_model.npz", np.zeros((ff.basis_size(), 6)))
    t = np.arange(0.0, 3.0, 0.01)
    trace = write_trace(tmp_path / "short.csv", t, {"SI [mm]": 2.0 * np.sin(np.pi * t)})
    out = tmp_path / "out"
    argv = ["reproduce", str(trace), "--scenario", "paper_hardware", "--out", str(out)]
    argv += ["--set", f"learning=!FeedforwardTuning {{learned_from: {model}, learn: false}}"]
    assert main(argv + ["--no-progress", "--tolerance", "1mm,1deg"]) == 0
    md = (out / "reproduce_short.md").read_text()
    run_line = next(line for line in md.splitlines() if line.startswith("Run:"))
    assert "feed-forward held_model.npz held, not learning" in run_line
    assert f"Feed-forward model: {model}." in md
    assert "Learner (feed-forward as a function of the reference)" in md
    assert "centred: its mean removed (X " in md  # the trace's line says what was removed
    figures = json.loads((out / "reproduce_short.json").read_text())
    assert figures["learned_from"] == str(model)
