"""``reproduce --stream``: a recorded trace streamed late, followed with prediction and run on the
robot as built, measured against the true motion; and its refusals, before any work."""

import json

import numpy as np
import pytest
from conftest import write_trace

from stewart_drake.cli import main as cli
from stewart_drake.references.prediction import DEFAULT_PREDICTOR, PREDICTORS


def _run(capsys, argv, code=0):
    rc = cli.main(argv + ["--no-progress"])
    out, err = capsys.readouterr()
    assert rc == code, (out, err)
    return out, err


def _breathing_trace(path):
    """40 s of a 10 mm, 4 s breath on SI at 10 Hz, with a slow drift: a recorded trace."""
    t = np.arange(0.0, 40.0, 0.1)
    si = 5.0 * np.cos(2 * np.pi * t / 4.0) + 0.02 * t
    return write_trace(path, t, {"SI [mm]": si})


def test_a_trace_streamed_late_is_followed_better_with_prediction(tmp_path, capsys):
    """0.2 s late: the robot, against the true motion, is within 0.6 of the error of the reference
    followed without prediction, and within 50 um of the followed reference itself; the report
    says the latency assumed."""
    trace = _breathing_trace(tmp_path / "breath.csv")
    out, _ = _run(capsys, ["reproduce", str(trace), "--stream", "0.2", "--out", str(tmp_path)])
    assert "streamed 0.2 s late at 10 Hz, predictor linear" in out
    report = json.loads((tmp_path / "reproduce_breath_stream.json").read_text())
    without = report["without"]["rms_translation_m"]
    assert without > 1e-3  # about 0.3 s of a 10 mm breath
    assert report["robot"]["rms_translation_m"] < 0.6 * without
    assert abs(report["robot"]["rms_translation_m"] - report["with"]["rms_translation_m"]) < 5e-5
    assert report["horizon"]["rms_translation_m"] < report["horizon"]["none_translation_m"]
    assert (
        report["horizon"]["ratio"] < 0.6
        and report["horizon"]["nrmse"] < 0.6 * (report["horizon"]["nrmse_none"])
    )
    assert "(a) the prediction 0.2 s ahead, at the samples" in out
    assert "(b) the followed reference against the true motion" in out
    assert report["latency_s"] == 0.2 and report["predictor"] == "linear"
    assert (tmp_path / "reproduce_breath_stream.png").stat().st_size > 10_000
    # The robot's own fidelity beside it, named after the stream (no space in any name).
    own = tmp_path / "reproduce_breath_stream_robot.md"
    assert own.exists() and f"the robot's own fidelity, {own.name})" in out
    assert not [f.name for f in tmp_path.iterdir() if " " in f.name]


@pytest.mark.parametrize(
    "extra, message",
    [
        (["--stream", "0"], "latency must be in (0, 10] s"),
        (["--stream", "nan"], "latency must be in (0, 10] s"),
        (["--stream", "-0.2"], "latency must be in (0, 10] s"),
        (["--stream-rate", "10"], "--stream-rate is for --stream"),
        (["--stream", "0.2", "--feedforward"], "it takes no learning"),
    ],
)
def test_bad_stream_options_are_refused_in_one_line(tmp_path, capsys, extra, message):
    trace = _breathing_trace(tmp_path / "breath.csv")
    _, err = _run(capsys, ["reproduce", str(trace), *extra, "--out", str(tmp_path / "o")], code=2)
    assert message in err
    assert len(err.strip().splitlines()) == 1
    assert not (tmp_path / "o").exists()


def test_unknown_predictor_and_short_stream_refused(tmp_path, capsys):
    trace = _breathing_trace(tmp_path / "breath.csv")
    with pytest.raises(SystemExit) as exit_:
        cli.main(["reproduce", str(trace), "--stream", "0.2", "--predictor", "lstm"])
    assert exit_.value.code == 2
    assert "invalid choice: 'lstm'" in capsys.readouterr().err
    t = np.arange(0.0, 3.0, 0.1)
    short = write_trace(tmp_path / "short.csv", t, {"SI [mm]": np.sin(t)})
    _, err = _run(capsys, ["reproduce", str(short), "--stream", "0.2", "--out", str(tmp_path)], 2)
    assert "the linear predictor needs" in err


def test_the_command_names_the_predictors():
    """The command lists its predictors without importing numpy: the same as the library's."""
    import argparse

    from stewart_drake.organ_motion.command import _add_stream_arguments

    parser = argparse.ArgumentParser()
    _add_stream_arguments(parser)
    action = next(a for a in parser._actions if a.dest == "predictor")
    assert tuple(action.choices) == PREDICTORS and action.default == DEFAULT_PREDICTOR
