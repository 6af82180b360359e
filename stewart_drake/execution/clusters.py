"""The cluster backends of the runner protocol (:mod:`~.runners`): Ray and Dask.

:class:`RayRunner` (extra ``[ray]``) runs jobs as Ray tasks, :class:`DaskRunner` (extra
``[dask]``) as Dask distributed tasks; both keep the protocol of :mod:`~.runners` (results as
jobs complete, failures as records, lost workers retried, cancellation by signal). A cluster's
address is checked before any work: its form (:func:`parse_address`), then that something
answers there in time (:func:`probe_address`). :func:`make_runner` builds any runner, local or
on a cluster, from the CLI's ``--runner`` options.
"""

from __future__ import annotations

import contextlib
import os
import threading
import time

from ..base.errors import InvalidConfigError
from .runners import (
    AUTO_RECYCLE,
    DEFAULT_RECYCLE,
    DEFAULT_RETRIES,
    RUNNERS,
    JobFailure,
    PoolRunner,
    ProcessRunner,
    SerialRunner,
    WorkerLost,
    call_job,
    resolve_recycle,
)

#: Seconds to wait for a Ray cluster's or a Dask scheduler's address to accept a connection
#: (``--connect-timeout``: at most :data:`MAX_CONNECT_TIMEOUT_S`).
DEFAULT_CONNECT_TIMEOUT_S = 5.0
MAX_CONNECT_TIMEOUT_S = 600.0
#: Seconds Ray may take to join a cluster whose address answered (its handshake; measured 20 s
#: on a busy 2-core machine).
RAY_JOIN_TIMEOUT_S = 60.0


def _import_extra(module: str, extra: str):
    import importlib

    try:
        return importlib.import_module(module)
    except ImportError:
        raise InvalidConfigError(
            f"--runner {extra} needs the {extra} extra: pip install 'stewart-drake[{extra}]'"
        ) from None


def parse_address(option: str, address: str, schemes: tuple) -> tuple[str, str, int]:
    """(scheme or "", host, port) of a cluster address ``[scheme://]host:port``.

    Raises:
        InvalidConfigError: no host, no port or a port outside 1..65535, a scheme not in
            ``schemes``, or other characters; names the option and the expected form.
    """
    import re

    form = f"[{'|'.join(schemes)}://]host:port"
    match = re.fullmatch(
        r"(?:(?P<scheme>[A-Za-z]+)://)?(?P<host>\[[0-9A-Fa-f:.]+\]|[\w.-]+)"
        r":(?P<port>\d+)/?",
        str(address).strip(),
    )
    if match is None:
        raise InvalidConfigError(
            f"{option} {address!r} is not an address of the form {form}"
            + (" (or auto, local)" if "ray" in schemes else "")
        )
    scheme = (match["scheme"] or "").lower()
    if scheme and scheme not in schemes:
        raise InvalidConfigError(
            f"{option} {address!r}: the scheme {scheme!r} is not one of "
            f"{', '.join(schemes)} ({form})"
        )
    port = int(match["port"])
    if not 1 <= port <= 65535:
        raise InvalidConfigError(f"{option} {address!r}: the port {port} is not in 1..65535")
    return scheme, match["host"].strip("[]"), port


def _connect_timeout(value) -> float:
    """``value`` as a connect timeout, s, in (0, :data:`MAX_CONNECT_TIMEOUT_S`].

    Raises:
        InvalidConfigError: not a number in that range.
    """
    from ..base.checks import as_number

    return as_number("--connect-timeout", value, 0.0, MAX_CONNECT_TIMEOUT_S, lo_open=True)


def probe_address(option: str, host: str, port: int, timeout_s: float) -> None:
    """Make sure something accepts TCP connections at ``host:port`` within ``timeout_s``.

    Interruptible (Ctrl-C, SIGTERM) and bounded, unlike the cluster clients' own retry loops.
    Raises:
        InvalidConfigError: nothing answers in time (refused, unreachable, unknown host).
    """
    import socket

    try:
        with socket.create_connection((host, port), timeout=timeout_s):
            pass
    except OSError as err:
        why = "no answer" if isinstance(err, TimeoutError) else (err.strerror or str(err))
        raise InvalidConfigError(
            f"{option} {host}:{port}: nothing accepts a connection there within {timeout_s:g} s "
            f"({why}); start the cluster first, check the address, or raise "
            f"--connect-timeout"
        ) from None


# -- Ray ------------------------------------------------------------------------------------------


class _RayPool:
    def __init__(self, ray, remote, capacity: int, started: bool):
        self.ray, self.remote, self.capacity, self.started = ray, remote, capacity, started

    def submit(self, *args):
        return self.remote.remote(*args)

    def wait(self, handles, timeout):
        return self.ray.wait(handles, num_returns=1, timeout=timeout)[0]

    def outcome(self, ref):
        exc = self.ray.exceptions
        try:
            return self.ray.get(ref)
        except exc.RayTaskError as err:  # call_job raised: the job never ran (e.g. an import)
            cause = err.as_instanceof_cause() if hasattr(err, "as_instanceof_cause") else err
            return JobFailure.from_exception("", cause)
        except exc.RayError as err:  # worker or node died, task cancelled, OOM
            raise WorkerLost(f"{type(err).__name__}: {str(err).splitlines()[0]}") from None

    def recover(self):
        pass

    def close(self, pending):
        for ref in pending:
            with contextlib.suppress(Exception):
                self.ray.cancel(ref, force=True)
        if self.started:
            self.ray.shutdown()


class RayRunner(PoolRunner):
    """Jobs as Ray tasks (``pip install 'stewart-drake[ray]'``).

    Args:
        n_workers: CPUs of the local cluster started when there is no ``address`` and Ray is
            not initialized yet (0: all cores); ignored when joining a cluster.
        address: a running cluster ("auto", "ray://host:10001", "host:6379"), or None.
        retries: attempts after the first for jobs whose worker died (Ray's own task retries
            are off so that every backend counts alike).
        recycle: tasks per Ray worker process before it is replaced (``max_calls``; None or
            0: never). :data:`AUTO_RECYCLE` is :data:`DEFAULT_RECYCLE` here: a cluster's
            nodes may run another Drake than this process.
        connect_timeout_s: seconds for the address to accept a connection (:meth:`probe`).
    Workers must import stewart_drake (install it on every node). A cluster this runner
    started is shut down when ``map`` ends; one it joined is left running. Joining is bounded:
    the address must answer within ``connect_timeout_s`` and Ray must join within
    :data:`RAY_JOIN_TIMEOUT_S`, while Ctrl-C, SIGTERM and SIGHUP end the wait.
    Raises:
        InvalidConfigError: an address that is not "auto", "local" or ``[ray://]host:port``.
    """

    #: Addresses Ray resolves itself (the cluster of this machine; a new local one).
    NAMED_ADDRESSES = ("auto", "local")

    def __init__(
        self,
        n_workers: int = 0,
        address: str | None = None,
        retries: int = DEFAULT_RETRIES,
        recycle: int | str | None = DEFAULT_RECYCLE,
        connect_timeout_s: float = DEFAULT_CONNECT_TIMEOUT_S,
    ):
        self.n_workers = n_workers
        self.address = address
        self.retries = retries
        self.recycle = DEFAULT_RECYCLE if recycle == AUTO_RECYCLE else resolve_recycle(recycle)
        self.connect_timeout_s = _connect_timeout(connect_timeout_s)
        self._target = (
            None
            if not address or address in self.NAMED_ADDRESSES
            else parse_address("--address", address, ("ray",))
        )

    def probe(self) -> None:
        """Refuse an address nothing answers at within ``connect_timeout_s``
        (:func:`probe_address`); "auto", "local" and no address are Ray's to resolve."""
        if self._target is not None:
            probe_address("--address", *self._target[1:], self.connect_timeout_s)

    def _join(self, ray) -> None:
        """``ray.init(address=...)`` in a helper thread: Ray's handshake waits in C++, where the
        main thread would neither see a signal nor time out."""
        self.probe()
        box = {}

        def join():
            try:
                ray.init(address=self.address, log_to_driver=False)
            except BaseException as err:  # noqa: BLE001 - reported by the main thread
                box["error"] = err

        thread = threading.Thread(target=join, daemon=True, name="ray-join")
        thread.start()
        deadline = time.monotonic() + RAY_JOIN_TIMEOUT_S
        while thread.is_alive() and time.monotonic() < deadline:
            thread.join(0.2)
        if thread.is_alive():
            raise InvalidConfigError(
                f"--address {self.address}: it answers, but no Ray cluster "
                f"joined within {RAY_JOIN_TIMEOUT_S:g} s; check the address "
                f"(the head's GCS port, 6379, or ray://host:10001)"
            )
        if "error" in box:
            err = box["error"]
            first = (str(err).strip().splitlines() or [""])[0]
            raise InvalidConfigError(
                f"--address {self.address}: Ray cannot join it ({type(err).__name__}: {first:.200})"
            ) from None

    def _open(self):
        ray = _import_extra("ray", "ray")
        started = not ray.is_initialized()
        if started:
            if self.address:
                self._join(ray)
            else:
                # "local": a cluster of our own even when another one runs on this machine
                # (Ray would join that one and refuse num_cpus).
                ray.init(
                    address="local",
                    num_cpus=self.n_workers or os.cpu_count(),
                    include_dashboard=False,
                    log_to_driver=False,
                )
        cpus = int(ray.cluster_resources().get("CPU", 1))
        self.n_workers = cpus
        remote = ray.remote(num_cpus=1, max_retries=0, max_calls=self.recycle or 0)(call_job)
        return _RayPool(ray, remote, capacity=2 * cpus, started=started)


# -- Dask -----------------------------------------------------------------------------------------


class _DaskPool:
    def __init__(self, distributed, client, cluster, capacity: int):
        self.distributed, self.client, self.cluster = distributed, client, cluster
        self.capacity = capacity

    def submit(self, *args):
        return self.client.submit(call_job, *args, pure=False)

    def wait(self, handles, timeout):
        try:
            return self.distributed.wait(
                handles, timeout=timeout, return_when="FIRST_COMPLETED"
            ).done
        except TimeoutError:
            return set()

    def outcome(self, future):
        if future.status == "error":
            err = future.exception()
            if isinstance(err, self.distributed.KilledWorker):
                raise WorkerLost(f"KilledWorker: {err}")
            return JobFailure.from_exception("", err)  # call_job raised: the job never ran
        if future.status == "cancelled":
            raise WorkerLost("the task was cancelled (its worker or the scheduler went away)")
        return future.result()

    def recover(self):
        pass

    def close(self, pending):
        with contextlib.suppress(Exception):
            if pending:
                self.client.cancel(pending, force=True)
        self.client.close()
        if self.cluster is not None:
            self.cluster.close()


class DaskRunner(PoolRunner):
    """Jobs as Dask distributed tasks (``pip install 'stewart-drake[dask]'``).

    Args:
        n_workers: worker processes (one thread each) of the local cluster started when there
            is no ``scheduler`` (0: one per core).
        scheduler: address of a running scheduler ("tcp://host:8786"), or None.
        retries: attempts after the first for jobs whose worker died (on top of the
            scheduler's own ``allowed-failures``).
        connect_timeout_s: seconds for the scheduler to accept a connection (:meth:`probe`),
            and Dask's own connect timeout.
    Workers must import stewart_drake. Memory: recycle Dask workers with their own
    ``--lifetime`` options. A local cluster this runner started is closed when ``map`` ends.
    Raises:
        InvalidConfigError: a scheduler address that is not ``[tcp|tls|ws|wss://]host:port``.
    """

    def __init__(
        self,
        n_workers: int = 0,
        scheduler: str | None = None,
        retries: int = DEFAULT_RETRIES,
        connect_timeout_s: float = DEFAULT_CONNECT_TIMEOUT_S,
    ):
        self.n_workers = n_workers
        self.scheduler = scheduler
        self.retries = retries
        self.connect_timeout_s = _connect_timeout(connect_timeout_s)
        self._target = (
            parse_address("--scheduler", scheduler, ("tcp", "tls", "ws", "wss"))
            if scheduler
            else None
        )

    def probe(self) -> None:
        """Refuse a scheduler nothing answers at within ``connect_timeout_s``."""
        if self._target is not None:
            probe_address("--scheduler", *self._target[1:], self.connect_timeout_s)

    def _join(self, distributed):
        """``distributed.Client(scheduler)`` in a helper thread, given ``connect_timeout_s`` for
        the connection and as long again for the handshake: a peer that accepts and never
        answers would otherwise hold the main thread for minutes (the client's timeout bounds
        the connect, not the handshake), where it sees no signal either."""
        self.probe()
        box: dict = {}

        def join():
            try:
                box["client"] = distributed.Client(self.scheduler, timeout=self.connect_timeout_s)
            except BaseException as err:  # noqa: BLE001 - reported by the main thread
                box["error"] = err

        thread = threading.Thread(target=join, daemon=True, name="dask-join")
        thread.start()
        deadline = time.monotonic() + 2 * self.connect_timeout_s + 1.0
        while thread.is_alive() and time.monotonic() < deadline:
            thread.join(0.2)
        if thread.is_alive() or "error" in box:
            err = box.get("error")
            why = "" if err is None else f" ({' '.join(str(err).split())[:200]})"
            raise InvalidConfigError(
                f"--scheduler {self.scheduler}: it accepts a connection, but no Dask scheduler "
                f"answered within {2 * self.connect_timeout_s + 1.0:g} s{why}"
            )
        return box["client"]

    def _open(self):
        distributed = _import_extra("distributed", "dask")
        cluster = None
        if self.scheduler:
            client = self._join(distributed)
        else:
            cluster = distributed.LocalCluster(
                n_workers=self.n_workers or os.cpu_count(),
                threads_per_worker=1,
                processes=True,
                dashboard_address=None,
            )
            client = distributed.Client(cluster)
        self.n_workers = max(1, sum(client.nthreads().values()))
        return _DaskPool(distributed, client, cluster, capacity=2 * self.n_workers)


# -- the CLI's choice -----------------------------------------------------------------------------


def make_runner(
    kind: str = "processes",
    jobs: int = 0,
    address: str | None = None,
    scheduler: str | None = None,
    retries: int = DEFAULT_RETRIES,
    recycle: int | str | None = AUTO_RECYCLE,
    connect_timeout_s: float = DEFAULT_CONNECT_TIMEOUT_S,
):
    """The runner of the CLI's ``--runner KIND --jobs N [--address A] [--scheduler S]``; an
    address is checked here, before any work: its form, then that it answers within
    ``connect_timeout_s``.

    Args:
        kind: one of :data:`RUNNERS`. jobs: workers (0: one per core; a local cluster's size
            for ray and dask). address: Ray cluster (ray only). scheduler: Dask scheduler
            (dask only). retries, recycle: see :class:`~.runners.ProcessRunner` and
            :class:`RayRunner` (recycle 0 or None: never; Dask ignores it). connect_timeout_s:
            see :class:`RayRunner`.
    Raises:
        InvalidConfigError: an unknown kind, an option of another backend, a negative count,
            a malformed address, or an address where nothing answers in time.
    """
    if kind not in RUNNERS:
        raise InvalidConfigError(f"unknown runner {kind!r}; choose one of {RUNNERS}")
    if address and kind != "ray":
        raise InvalidConfigError("--address is the Ray cluster's: use it with --runner ray")
    if scheduler and kind != "dask":
        raise InvalidConfigError("--scheduler is the Dask scheduler's: use it with --runner dask")
    if jobs < 0 or retries < 0:
        raise InvalidConfigError(f"--jobs and --retries must be >= 0, got {jobs}, {retries}")
    if kind == "serial":
        return SerialRunner()
    _connect_timeout(connect_timeout_s)
    if kind in ("ray", "dask"):
        runner = (
            RayRunner(jobs, address, retries, recycle, connect_timeout_s)
            if kind == "ray"
            else DaskRunner(jobs, scheduler, retries, connect_timeout_s)
        )
        runner.probe()
        return runner
    return ProcessRunner(jobs, retries, recycle)
