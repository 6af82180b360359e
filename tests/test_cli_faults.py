"""Issue 8: bad CLI input ends in one line and a non-zero exit; outputs are written atomically."""

import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from stewart_drake.fileio import atomic_write, save_npz
from stewart_drake.interfaces import cli

REPO = Path(__file__).resolve().parent.parent


def _one_line_error(capsys, argv, code=2):
    """Run the CLI in-process; the exit code and its only stderr line."""
    try:
        rc = cli.main(argv)
    except SystemExit as exit_:                     # argparse's own errors
        rc = exit_.code
    err = capsys.readouterr().err
    assert rc == code, err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in err, err
    return lines[0]


@pytest.mark.parametrize("argv, expected", [
    (["run", "--duration", "-1"], "--duration: must be > 0, got -1"),
    (["run", "--duration", "nan"], "--duration: must be > 0, got nan"),
    (["run", "--omega-q", "abc"], "--omega-q: expected a number, got 'abc'"),
    (["run", "--tuner", "fuzzy"], "invalid choice: 'fuzzy'"),
    (["collect", "--jobs", "-2"], "--jobs: must be >= 0, got -2"),
    (["evaluate", "--jobs", "-1"], "--jobs: must be >= 0, got -1"),
    (["collect", "--duration", "0"], "--duration: must be > 0, got 0"),
    (["collect", "--seed", "1.5"], "--seed: expected an integer, got '1.5'"),
    (["workspace", "--resolution", "1"], "--resolution: must be >= 2, got 1"),
    (["workspace", "--jobs", "many"], "--jobs: expected an integer, got 'many'"),
    (["train", "--mode", "best"], "invalid choice: 'best'"),
    (["nonsense"], "invalid choice: 'nonsense'"),
])
def test_bad_arguments_give_one_line_and_exit_2(capsys, argv, expected):
    line = _one_line_error(capsys, argv)
    assert expected in line and line.startswith("stewart-drake")


def test_bad_values_found_after_parsing_give_one_line(capsys, tmp_path):
    out = ["--out", str(tmp_path / "r")]
    assert "unknown trajectory 'circle'; choose one of" in _one_line_error(
        capsys, ["run", "--trajectory", "circle", "--no-progress"] + out)
    assert "omega_Q must be a finite number in [0.001, 1000], got 5000.0" in _one_line_error(
        capsys, ["run", "--omega-q", "5000", "--no-progress"] + out)
    assert f"no ANN tuner weights at {tmp_path / 'w.npz'}" in _one_line_error(
        capsys, ["run", "--tuner", "ann", "--tuner-weights", str(tmp_path / "w.npz")] + out)
    assert "no collected runs in" in _one_line_error(
        capsys, ["train", "--data", str(tmp_path / "nothing"), "--out", str(tmp_path / "w.npz")])
    assert "duration_s (1e-06 s) must cover at least two log periods (0.002 s)" in \
        _one_line_error(capsys, ["run", "--duration", "1e-6"] + out)   # not "0 mrad RMS"
    assert "--tuner-weights needs --tuner ann" in _one_line_error(
        capsys, ["run", "--tuner-weights", str(REPO / "stewart_drake/data/ann_tuner.npz")] + out)
    assert not (tmp_path / "r").exists()                  # refused before anything was written


@pytest.mark.parametrize("argv", [["run"], ["collect"], ["workspace"], ["train"], ["sdf"]])
def test_unwritable_output_is_refused_before_any_work(capsys, tmp_path, argv):
    blocker = tmp_path / "a_file"
    blocker.write_text("not a folder")
    line = _one_line_error(capsys, argv + ["--out", str(blocker / "sub" / "out.x")])
    assert f"cannot write to {blocker}" in line and "is a file; choose another output" in line


def test_a_diverged_run_gives_one_line_naming_the_saved_file(capsys, tmp_path, monkeypatch, feedforward_fault):
    feedforward_fault(lambda T_ff: np.full(6, np.inf))
    line = _one_line_error(capsys, ["run", "--duration", "0.1", "--no-progress",
                                    "--out", str(tmp_path)])
    # inf - inf = NaN in the pending torques reaches the plant after the computation delay,
    # where Drake refuses the NaN actuation: the guard names the torques
    assert re.search(r"simulation diverged at t = 0\.00\d s: the motor torques are not finite",
                     line)
    saved = sorted((tmp_path / "diverged").glob("diverged_paper_*.npz"))
    assert len(saved) == 1 and str(saved[0]) in line
    assert not (tmp_path / "run_paper.npz").exists()      # no result file, no plot of a NaN


def test_no_traceback_from_the_installed_command_line(tmp_path):
    proc = subprocess.run([sys.executable, "-m", "stewart_drake.interfaces.cli", "run", "--duration", "-3"],
                          cwd=REPO, capture_output=True, text=True, timeout=120)
    assert proc.returncode == 2
    assert proc.stderr.strip().splitlines() == [
        "stewart-drake run: error: argument --duration: must be > 0, got -3 "
        "(see stewart-drake run --help)"]


# -- atomic writes --------------------------------------------------------------------------------

@pytest.mark.parametrize("interruption", [OSError(28, "No space left on device"),
                                          KeyboardInterrupt()])
def test_an_interrupted_write_leaves_the_old_file_and_no_partial_one(tmp_path, interruption):
    path = tmp_path / "result.npz"
    save_npz(path, {"t": np.arange(3.0)})
    before = path.read_bytes()

    def writer(f):
        f.write(b"PK\x03\x04 half of a zip")             # some bytes reach the disk, then...
        raise interruption

    with pytest.raises(type(interruption)):
        atomic_write(path, writer)
    assert path.read_bytes() == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["result.npz"]   # no temporary left
    with np.load(path) as data:
        assert data["t"].tolist() == [0.0, 1.0, 2.0]


def test_an_interrupted_save_of_the_tuner_keeps_the_old_weights(tmp_path, monkeypatch):
    from stewart_drake.control import tuner

    model = tuner.load_tuner()
    path = tmp_path / "ann_tuner.npz"
    tuner.save_tuner(model, path)
    before = path.read_bytes()

    def savez_then_ctrl_c(f, **arrays):
        f.write(b"partial")
        raise KeyboardInterrupt

    monkeypatch.setattr(tuner.np, "savez", savez_then_ctrl_c)
    with pytest.raises(KeyboardInterrupt):
        tuner.save_tuner(model, path)
    assert path.read_bytes() == before and len(list(tmp_path.iterdir())) == 1


def test_sdf_command_writes_atomically(tmp_path, monkeypatch, capsys):
    from stewart_drake.model import plant

    out = tmp_path / "robot.sdf"
    assert cli.main(["sdf", "--out", str(out)]) == 0
    good = out.read_text()
    assert good == plant.write_sdf()

    def broken():
        raise OSError(5, "Input/output error")

    monkeypatch.setattr(plant, "write_sdf", broken)
    assert "Input/output error" in _one_line_error(capsys, ["sdf", "--out", str(out)], code=1)
    assert out.read_text() == good


# -- issue 16: every output path is checked before the work ----------------------------------------

@pytest.mark.parametrize("argv", [["run"], ["collect"], ["evaluate"], ["workspace"], ["train"],
                                  ["sdf"], ["mjcf"], ["diagrams"], ["scenario"]])
def test_an_empty_out_is_refused(capsys, argv):
    assert "--out is empty: give a" in _one_line_error(capsys, argv + ["--out", ""])


@pytest.mark.parametrize("argv", [["train"], ["sdf"], ["mjcf"], ["scenario"]])
def test_a_folder_where_a_file_is_due_is_refused(capsys, tmp_path, argv):
    line = _one_line_error(capsys, argv + ["--out", str(tmp_path)])
    assert f"--out {tmp_path} is a folder: give a file name" in line


@pytest.mark.parametrize("argv, option, sub", [
    (["run", "--duration", "0.1"], "--out", "diverged"),
    (["collect", "--duration", "0.1"], "--out", "diverged"),
    (["evaluate", "--quick", "--controllers", "pd"], "--out", "rows"),
    (["evaluate", "--quick", "--controllers", "pd"], "--docs", None),
    (["run", "--duration", "0.1"], "--html", None),
])
def test_every_output_of_a_command_is_checked_before_the_work(capsys, tmp_path, monkeypatch,
                                                               argv, option, sub):
    from stewart_drake.studies import collection, evaluation, experiments

    for module, name in ((experiments, "build_simulator"), (collection, "collection_jobs"),
                         (evaluation, "cases")):
        monkeypatch.setattr(module, name, lambda *a, **k: pytest.fail("work started"))
    out = tmp_path / "out"
    blocker = out / sub if sub else tmp_path / "a_file"
    blocker.parent.mkdir(exist_ok=True)
    blocker.write_text("a file where a folder or a file's folder is due")
    target = {"--out": out, "--docs": blocker / "docs", "--html": blocker / "replay.html"}
    args = argv + ["--no-progress", "--out", str(out)]
    if option != "--out":
        args += [option, str(target[option])]
    before = sorted(tmp_path.rglob("*"))
    line = _one_line_error(capsys, args)
    assert f"cannot write to {blocker}" in line and f"{blocker} is a file" in line
    assert line.endswith(f"choose another output with {option}")
    assert sorted(tmp_path.rglob("*")) == before                  # nothing written


def test_a_divergence_folder_that_cannot_be_written_keeps_the_divergence(tmp_path, monkeypatch, feedforward_fault):
    from stewart_drake.errors import SimulationDivergedError
    from stewart_drake.simulation.scenario import GuardConfig, Scenario
    from stewart_drake.studies.experiments import run_experiment

    feedforward_fault(lambda T_ff: np.full(6, np.inf))
    blocker = tmp_path / "diverged"
    blocker.write_text("a file in the folder's place")
    scenario = Scenario(duration_s=0.1, guard=GuardConfig(divergence_dir=str(blocker)))
    with pytest.raises(SimulationDivergedError, match=rf"the motor torques are not finite.* \(the "
                       rf"logs could not be saved in {blocker}: File exists; set "
                       rf"guard.divergence_dir") as info:
        run_experiment(scenario)
    assert info.value.path is None and blocker.read_text() == "a file in the folder's place"


def test_collect_keeps_divergences_under_its_out_folder(tmp_path, monkeypatch, feedforward_fault):
    from stewart_drake.studies.collection import collect
    from stewart_drake.studies.runners import SerialRunner

    monkeypatch.chdir(tmp_path)
    feedforward_fault(lambda T_ff: np.full(6, np.inf))
    manifest = collect(tmp_path / "out", duration_s=0.1, runner=SerialRunner(), progress=False)
    assert all(run["lost"] for run in manifest["runs"])
    assert len(list((tmp_path / "out" / "diverged").glob("diverged_*.npz"))) == 9
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out"]   # nothing in the current folder


# -- issue 16: sizes are bounded before anything is allocated -------------------------------------

@pytest.mark.parametrize("argv, expected", [
    (["run", "--duration", "1e5"], "a run of 100000 s logged every 0.001 s: about 400 GB of "
                                   "memory needed, more than the 8 GB available"),
    (["run", "--duration", "1e9"], "a run of 1e+09 s logged"),
    (["run", "--duration", "1e300"], "a run of 1e+300 s logged every 0.001 s: about 4e+306 "
                                     "bytes of memory needed"),
    (["run", "--duration", "1e5", "--html", "replay.html"], "about 400 GB of memory needed"),
    (["collect", "--duration", "1e6", "--jobs", "3"], "3 runs at once, each of 1e+06 s logged "
                                                      "every 0.001 s: about 12 TB of memory"),
    (["workspace", "--resolution", "100000"], "a workspace sweep at resolution 100000 (2e+15 "
                                              "poses): about 400 PB of memory needed"),
])
def test_a_request_beyond_the_machine_s_memory_is_refused_in_one_line(
        capsys, tmp_path, monkeypatch, argv, expected):
    from stewart_drake import checks

    monkeypatch.setattr(checks, "available_memory_bytes", lambda: 8e9)
    monkeypatch.chdir(tmp_path)
    line = _one_line_error(capsys, argv + ["--no-progress", "--out", "out"])
    assert expected in line
    assert not any(tmp_path.iterdir())                   # refused before anything was written


def test_the_memory_estimates_admit_what_runs_and_track_the_machine(monkeypatch):
    from stewart_drake import checks
    from stewart_drake.errors import InvalidConfigError
    from stewart_drake.simulation.scenario import Scenario
    from stewart_drake.studies.experiments import check_run_memory, run_memory_bytes

    available = checks.available_memory_bytes()
    assert available is None or available > 1e8
    assert 3e7 < run_memory_bytes(Scenario()) < 1e8         # 10 s at 1 ms: tens of MB
    monkeypatch.setattr(checks, "available_memory_bytes", lambda: 1e8)
    check_run_memory(Scenario())
    with pytest.raises(InvalidConfigError, match="3 runs at once, each of 10 s"):
        check_run_memory(Scenario(), runs_at_once=3)
    monkeypatch.setattr(checks, "available_memory_bytes", lambda: None)   # unknown: no check
    check_run_memory(Scenario(duration_s=1e300))


def test_a_temporary_left_by_sigterm_is_removed_at_the_next_start(tmp_path, capsys):
    """Issue 16: SIGTERM outside a study kills Python before atomic_write can clean up; the
    next command writing there removes what the dead writer left, and only that."""
    import os
    import signal
    import time

    out = tmp_path / "sdf"
    writer = subprocess.Popen([sys.executable, "-c", (
        "import time; from pathlib import Path; from stewart_drake.fileio import atomic_write\n"
        "def slow(f):\n    f.write(b'half a file'); f.flush(); print('writing', flush=True); "
        "time.sleep(60)\n"
        f"atomic_write(Path({str(out / 'robot.sdf')!r}), slow)")],
        stdout=subprocess.PIPE, text=True, env=dict(os.environ, PYTHONPATH=os.pathsep.join(
            [str(REPO)] + os.environ.get("PYTHONPATH", "").split(os.pathsep))))
    assert writer.stdout.readline() == "writing\n"
    writer.send_signal(signal.SIGTERM)
    assert writer.wait(timeout=30) == -signal.SIGTERM
    left = [p.name for p in out.iterdir()]
    assert len(left) == 1 and left[0].startswith(".robot.sdf.") and left[0].endswith(".tmp")
    live = out / f".robot.sdf.{left[0].split('.')[3].rsplit('-', 1)[0]}-{os.getpid()}.x1.tmp"
    live.write_bytes(b"another command writing here now")
    old_form, fresh_old_form = out / ".a.npz.k2j3h4_a.tmp", out / ".b.npz.k2j3h4_b.tmp"
    for path in (old_form, fresh_old_form):
        path.write_bytes(b"")
    os.utime(old_form, (time.time() - 7200,) * 2)
    assert cli.main(["sdf", "--out", str(out / "robot.sdf")]) == 0
    assert sorted(p.name for p in out.iterdir()) == sorted(
        ["robot.sdf", live.name, fresh_old_form.name])


def test_a_pd_run_reports_its_own_status_not_gain_re_schedules(tmp_path, capsys):
    """Issue 16: the summary printed 'gain re-schedules' (an LQI figure) for a PD run."""
    assert cli.main(["run", "--controller", "pd", "--duration", "0.1", "--no-progress",
                     "--out", str(tmp_path)]) == 0
    out = capsys.readouterr().out
    assert "controller status: inertia reschedules 10, failures 0" in out
    assert "gain" not in out and "omega" not in out
