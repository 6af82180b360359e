"""The runner protocol (jobs/runners.py) on the local backends: results as they complete,
failures as typed records, retries of a dead worker, recycling, cancellation, no orphans."""

import os
import pickle
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import numpy as np
import psutil
import pytest
from conftest import HANG_S, wait_for

from stewart_drake.base.errors import JointLimitError, SimulationDivergedError
from stewart_drake.execution.clusters import make_runner
from stewart_drake.execution.runners import (
    DEFAULT_RECYCLE,
    Interrupted,
    JobFailure,
    ProcessRunner,
    SerialRunner,
    call_job,
)

REPO = Path(__file__).resolve().parent.parent


def square(x):
    return x * x


def refuse(job):
    if job == "bad":
        raise JointLimitError(1, "crank_joint", -4.8e-4, t=0.644)
    return job


def diverge(folder):
    path = Path(folder) / "diverged_x.npz"
    np.savez(path, t=np.arange(3.0))
    raise SimulationDivergedError("tracking error too large", 0.5, str(path))


def die_once(marker):
    """Kills its worker on the first attempt (no marker yet), returns the pid on the next."""
    if not os.path.exists(marker):
        Path(marker).write_text("died")
        os._exit(1)
    return os.getpid()


def always_die(_):
    os._exit(1)


def pid_after(seconds):
    time.sleep(seconds)
    return os.getpid()


@pytest.mark.parametrize("runner", [SerialRunner(), ProcessRunner(2)], ids=["serial", "processes"])
def test_every_job_yields_once_with_its_id_and_a_failure_is_a_typed_record(runner):
    jobs = {"a": 3, "b": "bad", "c": 5}
    out = dict(runner.map(refuse, jobs))
    assert out.keys() == jobs.keys() and out["a"] == 3 and out["c"] == 5
    failure = out["b"]
    assert isinstance(failure, JobFailure) and failure.kind == "error" and failure.attempts == 1
    assert isinstance(failure.error, JointLimitError) and failure.error.leg == 1
    assert failure.error_type == "JointLimitError" and "0.0275 deg" in str(failure)
    assert "refuse" in failure.traceback
    assert pickle.loads(pickle.dumps(failure)).error.margin == -4.8e-4


def test_results_arrive_as_they_complete_and_progress_sees_each():
    seen = []
    order = [
        k
        for k, _ in ProcessRunner(2).map(
            pid_after, {"slow": 1.5, "fast": 0.0}, progress=lambda k, o: seen.append(k)
        )
    ]
    assert order == seen == ["fast", "slow"]


def test_a_divergence_dump_travels_back_with_the_failure(tmp_path):
    ((_, failure),) = ProcessRunner(1).map(diverge, {"d": str(tmp_path)})
    assert failure.error_type == "SimulationDivergedError"
    ((path, data),) = failure.files.items()
    assert path == str(tmp_path / "diverged_x.npz") and not Path(path).exists()  # moved
    assert data[:2] == b"PK"  # the .npz


def test_a_dead_worker_is_retried_then_recorded_as_lost(tmp_path):
    out = dict(ProcessRunner(1, retries=1).map(die_once, {"once": str(tmp_path / "m")}))
    assert isinstance(out["once"], int)  # the second attempt finished
    out = dict(ProcessRunner(2, retries=1).map(always_die, {"x": 0, "y": 1}))
    assert {k: (o.kind, o.attempts) for k, o in out.items()} == {"x": ("lost", 2), "y": ("lost", 2)}


def test_workers_are_recycled_after_n_jobs():
    pids = [p for _, p in ProcessRunner(1, recycle=2).map(pid_after, dict.fromkeys("abcde", 0))]
    assert len(set(pids)) == 3 and os.getpid() not in pids


@pytest.mark.parametrize(
    "signum", [signal.SIGTERM, signal.SIGHUP, signal.SIGINT], ids=lambda s: signal.Signals(s).name
)
def test_a_signal_during_map_ends_the_workers_and_keeps_what_finished(signum):
    # A signal the shell left at its default (under `nohup`, SIGHUP arrives ignored and stays so:
    # the next test), restored afterwards.
    inherited = signal.signal(
        signum, signal.SIG_DFL if signum != signal.SIGINT else signal.default_int_handler
    )
    try:
        _signal_during_map(signum)
    finally:
        signal.signal(signum, inherited)


def _is_resource_tracker(process) -> bool:
    """multiprocessing's resource tracker: started by the first spawn of the test session and
    kept for the whole session by design, not a worker."""
    try:
        return "resource_tracker" in " ".join(process.cmdline())
    except psutil.Error:
        return False


def _signal_during_map(signum):
    got = []

    def on_result(job_id, outcome):
        got.append(job_id)
        os.kill(os.getpid(), signum)  # as `kill <pid>` would, after one result

    before = {p.pid for p in psutil.Process().children(recursive=True)}
    handlers = {s: signal.getsignal(s) for s in (signal.SIGINT, signal.SIGTERM, signal.SIGHUP)}
    with pytest.raises(Interrupted) as info:
        for _ in ProcessRunner(2).map(
            pid_after, {"a": 0.0, "b": 30.0, "c": 30.0}, progress=on_result
        ):
            pass
    assert info.value.signum == signum and got == ["a"]
    time.sleep(0.5)
    left = [
        p
        for p in psutil.Process().children(recursive=True)
        if p.pid not in before
        and p.status() != psutil.STATUS_ZOMBIE
        and not _is_resource_tracker(p)
    ]
    assert left == []
    assert {s: signal.getsignal(s) for s in handlers} == handlers  # restored


def wrapped_interrupt(job):
    """A job a signal interrupted inside compiled code: numba's dispatcher hands back a
    SystemError whose cause is the handler's Interrupted."""
    if job == "compiled":
        try:
            raise Interrupted(signal.SIGTERM)
        except Interrupted as err:
            raise SystemError("<numba dispatcher> returned a result with an exception set") from err
    return job


def test_an_interrupt_wrapped_by_compiled_code_stops_a_serial_map_not_records_a_failure():
    got = []
    with pytest.raises(Interrupted) as info:
        for job_id, outcome in SerialRunner().map(
            wrapped_interrupt, {"a": "done", "b": "compiled", "c": "never"}
        ):
            got.append((job_id, outcome))
    assert info.value.signum == signal.SIGTERM and got == [("a", "done")]
    # Any other error stays the job's record.
    assert isinstance(call_job(refuse, "b", "bad"), JobFailure)


def test_a_signal_ignored_by_the_process_stays_ignored():
    """`nohup stewart-drake collect &`: a hangup must not cancel the study."""
    old = signal.signal(signal.SIGHUP, signal.SIG_IGN)
    try:
        seen = []
        out = dict(
            SerialRunner().map(
                square,
                {"a": 2, "b": 3},
                progress=lambda k, o: (
                    seen.append(signal.getsignal(signal.SIGHUP)),
                    os.kill(os.getpid(), signal.SIGHUP),
                ),
            )
        )
        assert out == {"a": 4, "b": 9} and seen == [signal.SIG_IGN] * 2
    finally:
        signal.signal(signal.SIGHUP, old)


@pytest.mark.system
def test_workers_die_with_their_parent(tmp_path):
    """kill -9 of the parent (no cleanup can run): PR_SET_PDEATHSIG ends its workers."""
    script = textwrap.dedent(f"""
        import os, sys
        sys.path.insert(0, {str(Path(__file__).parent)!r})
        from test_runners import pid_after
        from stewart_drake.execution.runners import ProcessRunner
        for _ in ProcessRunner(2).map(pid_after, {{"a": {2 * HANG_S}, "b": {2 * HANG_S}}}):
            pass
    """)
    parent = subprocess.Popen([sys.executable, "-c", script], cwd=REPO)

    def started():
        return [
            p
            for p in psutil.Process(parent.pid).children()
            if "multiprocessing" in " ".join(p.cmdline())
            and "resource_tracker" not in " ".join(p.cmdline())
        ]

    try:
        wait_for(lambda: len(started()) >= 2, HANG_S, "two workers starting", poll_s=0.2)
        workers = started()
        parent.kill()
        parent.wait()
        # At once on a quiet machine; an orphan would live on (its job outlasts the guard).
        gone, alive = psutil.wait_procs(workers, timeout=HANG_S)
        assert alive == []
    finally:
        parent.kill()


def test_local_workers_are_recycled_only_where_drake_cannot_free_a_run():
    from stewart_drake.base.errors import InvalidConfigError
    from stewart_drake.execution.clusters import RayRunner
    from stewart_drake.execution.runners import drake_frees_diagrams

    expected = None if drake_frees_diagrams() else DEFAULT_RECYCLE
    assert ProcessRunner(1).recycle == expected
    assert make_runner("processes", 1).recycle == expected
    assert ProcessRunner(1, recycle=0).recycle is None
    assert ProcessRunner(1, recycle=3).recycle == 3
    assert RayRunner(1, recycle="auto").recycle == DEFAULT_RECYCLE  # nodes: another Drake
    with pytest.raises(InvalidConfigError, match="recycle must be"):
        ProcessRunner(1, recycle="sometimes")


def test_make_runner_refuses_options_of_another_backend():
    from stewart_drake.base.errors import InvalidConfigError

    assert isinstance(make_runner("serial"), SerialRunner)
    assert make_runner("processes", 3).n_workers == 3
    with pytest.raises(InvalidConfigError, match="--address is the Ray cluster's"):
        make_runner("processes", address="auto")
    with pytest.raises(InvalidConfigError, match="--scheduler is the Dask scheduler's"):
        make_runner("ray", scheduler="tcp://x:8786")
