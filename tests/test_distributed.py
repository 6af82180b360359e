"""Ray and Dask backends give exactly the local backend's results, on local clusters of 2 CPUs
(the default tier's: two short runs on a cluster the runner starts and ends itself; the slow
tier's: the evaluation on clusters started once per module); skipped only when their extra is
not installed."""

import json

import numpy as np
import pytest
from conftest import HANG_S, needs_extra, run_within

from stewart_drake.evaluation.evaluation import evaluate
from stewart_drake.execution.clusters import DaskRunner, RayRunner
from stewart_drake.execution.runners import JobFailure, ProcessRunner, SerialRunner
from stewart_drake.tuner.collection import _collect_job, collection_jobs

#: Row fields that measure the machine, not the run.
TIMING = ("wall_s", "realtime_factor")


#: Two of the collection's nine runs (0.2 s each), its weights' extremes.
JOBS = ("q0.1_r0.1", "q10_r10")


def _records(runner):
    """The collection's :data:`JOBS` mapped over ``runner``: {job: its record}."""
    _, jobs = collection_jobs(duration_s=0.2)
    return dict(runner.map(_collect_job, {k: jobs[k] for k in JOBS}))


def _rows(base, runner):
    """evaluate --quick --controllers pd into ``base``: its rows by case."""
    report = evaluate(
        base / "docs",
        base / "evaluation",
        runner=runner,
        progress=False,
        quick=True,
        controllers=("pd",),
    )
    return {
        json.dumps(r["case"], sort_keys=True): {k: v for k, v in r.items() if k not in TIMING}
        for r in report["rows"]
    }


@pytest.fixture(scope="module")
def local():
    return _records(SerialRunner())


@pytest.fixture(scope="module")
def local_rows(tmp_path_factory):
    return _rows(tmp_path_factory.mktemp("local_rows"), ProcessRunner(2))


@pytest.fixture(scope="module")
def ray_runner():
    import ray

    ray.init(address="local", num_cpus=2, include_dashboard=False, log_to_driver=False)
    yield RayRunner()
    ray.shutdown()


@pytest.fixture(scope="module")
def dask_runner():
    import distributed

    with distributed.LocalCluster(
        n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None
    ) as cluster:
        yield DaskRunner(scheduler=cluster.scheduler_address)


# The extra is checked by the mark, before the local study or the cluster starts.
@pytest.mark.parametrize(
    "backend", [pytest.param(b, marks=needs_extra(b), id=b) for b in ("ray", "dask")]
)
def test_backend_gives_the_local_results(backend, local):
    """Two runs of the collection on a 2-CPU cluster the runner starts and shuts down itself,
    sample for sample as in this process (the evaluation's rows, with the runs lost
    everywhere, are the slow tier's: test_backend_gives_the_local_rows)."""
    runner = {"ray": RayRunner, "dask": DaskRunner}[backend](2)
    records = _records(runner)
    assert runner.n_workers == 2
    assert sorted(records) == sorted(local) == sorted(JOBS)
    for job, theirs in local.items():
        assert not isinstance(records[job], JobFailure), records[job]
        assert not isinstance(theirs, JobFailure), theirs
        for key in ("omega_Q", "omega_R", "t", "rho", "cost_e", "cost_u"):
            np.testing.assert_array_equal(records[job][key], theirs[key], err_msg=key)


@pytest.mark.slow
@pytest.mark.parametrize(
    "backend", [pytest.param(b, marks=needs_extra(b), id=b) for b in ("ray", "dask")]
)
def test_backend_gives_the_local_rows(backend, request, local_rows, tmp_path):
    runner = request.getfixturevalue(f"{backend}_runner")
    rows = _rows(tmp_path, runner)
    assert len(rows) == 10 + 7  # pd: scenarios and conditions
    assert _comparable(rows) == _comparable(local_rows)
    # the 5 N push needs more torque than the servos have (docs/hardware.md): lost everywhere
    assert {r["case"]["condition"] for r in rows.values() if "error" in r} == {"push 5 N"}


def _comparable(rows: dict) -> dict:
    """Rows without what names a time or a place: a lost run's dump file, its traceback."""
    out = {}
    for key, row in rows.items():
        row = dict(row)
        if "error" in row:
            row["error"] = row["error"].split("; data up to then saved in")[0]
            row.pop("traceback", None)
        out[key] = row
    return out


@needs_extra("dask")
def test_a_scheduler_that_accepts_and_never_answers_is_given_up_on(tmp_path):
    """A peer that accepts the connection and says nothing: refused after the connect timeout
    for the connection and as much again for the handshake, not after minutes."""
    import socket
    import threading

    from stewart_drake.base.errors import InvalidConfigError
    from stewart_drake.execution.clusters import make_runner

    server = socket.socket()
    server.bind(("127.0.0.1", 0))
    server.listen(8)
    held = []
    stop = threading.Event()

    def accept_and_hold():
        server.settimeout(0.2)
        while not stop.is_set():
            try:
                held.append(server.accept()[0])
            except OSError:
                continue

    threading.Thread(target=accept_and_hold, daemon=True).start()
    port = server.getsockname()[1]
    try:
        runner = make_runner("dask", scheduler=f"tcp://127.0.0.1:{port}", connect_timeout_s=1.0)
        with pytest.raises(InvalidConfigError, match="it accepts a connection, but no Dask"):
            # Given up after about 3 s; a hang fails the test.
            run_within(HANG_S, lambda: list(runner.map(str, {"a": 1})))
    finally:
        stop.set()
        for conn in held:
            conn.close()
        server.close()
