"""Studies that survive. Every finished result is on disk as it arrives, the same
command resumes with only what is missing, a folder of other settings is refused by name,
SIGTERM leaves no process behind, and kill -9 of a worker loses only its cases."""

import json
import os
import signal
import subprocess
import sys
from pathlib import Path

import numpy as np
import psutil
import pytest
from conftest import HANG_S, wait_for

from stewart_drake.base.errors import IncompleteResultsError, ResultsMismatchError
from stewart_drake.cli.main import main
from stewart_drake.evaluation import evaluation
from stewart_drake.execution.runners import Interrupted, SerialRunner
from stewart_drake.tuner.collection import collect, load_records

REPO = Path(__file__).resolve().parent.parent
CLI = [sys.executable, "-m", "stewart_drake.cli.main"]


class StopAfter(SerialRunner):
    """A serial runner that is sent SIGTERM after ``n`` results (what `kill <pid>` does)."""

    def __init__(self, n):
        self.n, self.ran = n, []

    def map(self, fn, jobs, progress=None):
        for k, (job_id, outcome) in enumerate(super().map(fn, jobs)):
            self.ran.append(job_id)
            yield job_id, outcome
            if k + 1 == self.n:
                raise Interrupted(signal.SIGTERM)


def test_an_interrupted_collect_resumes_and_train_refuses_it_until_then(tmp_path, capsys):
    out = tmp_path / "collect"
    first = StopAfter(4)
    with pytest.raises(Interrupted):
        collect(out, duration_s=0.2, runner=first, progress=False)
    manifest = json.loads((out / "manifest.json").read_text())
    assert not manifest["complete"] and len(manifest["jobs"]) == 4
    assert len(list(out.glob("run_*.npz"))) == 4
    with pytest.raises(IncompleteResultsError, match="holds 4 of 9 runs"):
        load_records(out)
    assert main(["train", "--data", str(out), "--out", str(tmp_path / "w.npz")]) == 2
    assert "did not finish" in capsys.readouterr().err
    kept = {p.name: p.stat().st_mtime_ns for p in out.glob("run_*.npz")}

    second = StopAfter(99)
    manifest = collect(out, duration_s=0.2, runner=second, progress=False)
    assert sorted(second.ran) == sorted(set(manifest["jobs"]) - set(first.ran))  # only those
    assert manifest["complete"] and (manifest["ran"], manifest["reused"]) == (5, 4)
    assert {n: (out / n).stat().st_mtime_ns for n in kept} == kept  # untouched
    assert len(load_records(out)) == 9

    with pytest.raises(ResultsMismatchError, match="seed 0 there, 1 here"):
        collect(out, seed=1, duration_s=0.2, runner=SerialRunner(), progress=False)
    # A run file of another collection in the folder (what a failed save used to leave):
    path = out / manifest["runs"][3]["file"]
    with np.load(path) as data:
        arrays = dict(data)
    arrays["settings_hash"] = np.array("0123456789abcdef")
    np.savez_compressed(path, **arrays)
    with pytest.raises(ResultsMismatchError, match=f"{path.name} is not of the settings"):
        load_records(out)


def test_evaluate_keeps_its_rows_and_the_last_report_when_every_case_fails(
    tmp_path, monkeypatch, capsys, feedforward_fault
):
    monkeypatch.chdir(tmp_path)  # the guard's default folder is relative
    feedforward_fault(lambda T_ff: np.full(6, np.inf))
    out = tmp_path / "out"
    quick_lqi = dict(runner=SerialRunner(), progress=False, quick=True, controllers=("lqi_1_1",))
    with pytest.raises(IncompleteResultsError, match="cases failed"):
        evaluation.evaluate(tmp_path / "docs", out, **quick_lqi)
    assert not (tmp_path / "docs").exists()  # no report of failures only
    rows = sorted((out / "rows").glob("*.json"))
    n = 10 + 7 + 5  # nominal scenarios, conditions, encoder resolutions (hardware base)
    assert len(rows) == n  # on disk before the report
    row = json.loads(rows[0].read_text())
    assert row["error"].startswith("SimulationDivergedError: simulation diverged at t = 0.00")
    dumps = sorted((out / "diverged").glob("diverged_*.npz"))
    assert len(dumps) == n and str(dumps[0].parent) in row["error"]
    assert not (tmp_path / "results").exists()  # under --out, not the current folder

    monkeypatch.setattr(evaluation, "run_case", lambda case, **_: pytest.fail("ran again"))
    (tmp_path / "docs").mkdir()
    (tmp_path / "docs" / "results.md").write_text("the last good report")
    with pytest.raises(IncompleteResultsError, match=rf"all {n} cases failed \(first: Simulat"):
        evaluation.evaluate(tmp_path / "docs", out, **quick_lqi)
    assert (tmp_path / "docs" / "results.md").read_text() == "the last good report"
    assert len(json.loads((out / "rows.json").read_text())["rows"]) == n
    argv = ["evaluate", "--no-tuner-study", "--out", str(out), "--docs", str(tmp_path / "docs")]
    argv += ["--controllers", "lqi_1_1", "--no-progress"]
    assert main(argv + ["--quick"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "the report in" in err[0] and "was not replaced" in err[0]
    assert main(argv) == 2  # not --quick
    assert (
        "holds evaluate results of other settings (quick True there, False here"
        in capsys.readouterr().err
    )


# -- the command line as a user (or CI, or systemd) drives it -------------------------------------


def _start(argv, tmp_path):
    env = dict(
        os.environ,
        PYTHONPATH=os.pathsep.join(
            [str(REPO)] + [p for p in os.environ.get("PYTHONPATH", "").split(os.pathsep) if p]
        ),
    )
    return subprocess.Popen(
        CLI + argv, cwd=tmp_path, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True
    )


def _wait_for_results(proc, out: Path, n: int):
    """Block until ``n`` jobs are done in ``out``'s manifest (a hang fails the test after
    :data:`conftest.HANG_S`); the workers then."""

    def done():
        assert proc.poll() is None, proc.communicate()
        try:
            jobs = json.loads((out / "manifest.json").read_text())["jobs"]
        except (OSError, ValueError):
            jobs = {}
        return sum(v["status"] == "done" for v in jobs.values()) >= n

    wait_for(done, HANG_S, f"{n} finished jobs in {out}", poll_s=0.1)
    return [
        p
        for p in psutil.Process(proc.pid).children(recursive=True)
        if "spawn_main" in " ".join(p.cmdline())
    ]


@pytest.mark.system
@pytest.mark.parametrize(
    "argv",
    [
        # Runs of 0.5 s: after the first result, seven are still to run when SIGTERM comes.
        pytest.param(["collect", "--duration", "0.5"], id="collect"),
        # The same mechanism (the runner under a study's store) through the other study.
        pytest.param(
            ["evaluate", "--quick", "--no-tuner-study", "--controllers", "lqi_1_1"]
            + ["--docs", "docs"],
            id="evaluate",
            marks=pytest.mark.slow,
        ),
    ],
)
def test_sigterm_to_the_main_process_leaves_no_process_and_keeps_what_finished(tmp_path, argv):
    out = tmp_path / "out"
    proc = _start(argv + ["--out", str(out), "--jobs", "2", "--no-progress"], tmp_path)
    workers = _wait_for_results(proc, out, 1)
    everything = psutil.Process(proc.pid).children(recursive=True)  # workers, resource tracker
    assert len(workers) == 2
    proc.send_signal(signal.SIGTERM)
    # A second or two on a quiet machine, awaited as events: a process still running after the
    # guard against a hang fails the test. Popen reaps its child: its exit code stays.
    _, err = proc.communicate(timeout=HANG_S)
    gone, alive = psutil.wait_procs(everything, timeout=HANG_S)
    assert alive == []
    assert proc.returncode == 128 + signal.SIGTERM
    assert "interrupted by SIGTERM; finished results are kept in" in err and "Traceback" not in err
    manifest = json.loads((out / "manifest.json").read_text())
    assert not manifest["complete"]
    done = [v["file"] for v in manifest["jobs"].values() if v["status"] == "done"]
    assert done and all((out / f).exists() for f in done)


#: Each study a worker is killed in: its command, its jobs, and (with ``out``) how many results
#: it reads back once complete.
STUDIES = {
    # Nine runs of 0.5 s: after two results, seven are still to run when the worker is killed.
    "collect": (["collect", "--duration", "0.5"], 9, lambda out: len(load_records(out))),
    "evaluate": (
        ["evaluate", "--quick", "--no-tuner-study", "--controllers", "pd", "--docs", "docs"],
        10 + 7,  # pd: the nominal scenarios and the conditions (no encoders)
        lambda out: len(json.loads((out / "rows.json").read_text())["rows"]),
    ),
}


@pytest.mark.system
@pytest.mark.parametrize("study", ["collect", pytest.param("evaluate", marks=pytest.mark.slow)])
def test_kill_9_of_a_worker_loses_only_its_cases_and_the_rerun_runs_only_those(
    tmp_path, monkeypatch, capsys, study
):
    """The same mechanism in both studies (the runner under a study's store): the default
    tier's is the collection's, the shorter."""
    command, n, read_back = STUDIES[study]
    out = tmp_path / "out"
    argv = command + ["--out", str(out), "--retries", "0", "--no-progress"]
    proc = _start(argv + ["--jobs", "2"], tmp_path)
    workers = _wait_for_results(proc, out, 2)
    workers[0].kill()
    _, err = proc.communicate(timeout=HANG_S)
    assert proc.returncode == 2 and "have no result" in err, err
    jobs = json.loads((out / "manifest.json").read_text())["jobs"]
    lost = sorted(k for k, v in jobs.items() if v["status"] == "lost")
    done = {
        v["file"]: (out / v["file"]).stat().st_mtime_ns
        for v in jobs.values()
        if v["status"] == "done"
    }
    assert 1 <= len(lost) <= 2 and len(done) + len(lost) == n  # in flight on the broken pool
    assert all("a worker process died" in jobs[k]["error"] for k in lost)

    # The rerun, in this process and serially (the runner is no setting of the results), in
    # the killed command's folder (--docs docs is relative).
    monkeypatch.chdir(tmp_path)
    assert main(argv + ["--runner", "serial"]) == 0
    # One line says it (collect: "9 runs, ... (2 run now, 7 found on disk)"; evaluate: "17 runs
    # (1 run now in ... s wall, 16 found on disk; ...)").
    (said,) = [line for line in capsys.readouterr().out.splitlines() if " run now" in line]
    assert said.startswith(f"{n} runs"), said
    assert f"({len(lost)} run now" in said and f"{len(done)} found on disk" in said, said
    manifest = json.loads((out / "manifest.json").read_text())
    assert manifest["complete"] and all(v["status"] == "done" for v in manifest["jobs"].values())
    assert {f: (out / f).stat().st_mtime_ns for f in done} == done  # not run again
    assert read_back(out) == n
