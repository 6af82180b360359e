"""Runners: how a study's independent jobs are executed, and the protocol every backend keeps.

The protocol
------------
``runner.map(fn, jobs, progress=None)`` takes a picklable module-level function ``fn`` and a
mapping ``{job_id: job}`` (str ids, picklable jobs; the studies build each job's config in one
function, e.g. ``evaluation.case_config``) and yields ``(job_id, outcome)`` **as jobs
complete**, not in order. ``outcome`` is ``fn(job)``, or a :class:`JobFailure` when the job
produced none:

- ``kind="error"``: ``fn`` raised. The record carries the exception itself (every
  :class:`~stewart_drake.base.errors.StewartError` pickles), its type name, message and
  traceback, and the bytes of the file it names (``err.path``: a divergence dump travels back
  from any machine). Not retried: a refusal is deterministic.
- ``kind="lost"``: the worker died under the job on each of ``1 + retries`` attempts (a local
  pool charges every job in flight when one of its workers dies, and restarts).

Each job is yielded exactly once; ``progress(job_id, outcome)``, if given, is called before each
yield. SIGINT, SIGTERM, SIGHUP and SIGQUIT received while ``map`` runs in the main thread stop
submitting, cancel what is pending, end the workers and raise :class:`Interrupted` (a
KeyboardInterrupt that names the signal); a signal the process ignores stays ignored.

Backends: :class:`SerialRunner` (this process), :class:`ProcessRunner` (local processes, the
default, recycled after ``recycle`` jobs), and :class:`~.clusters.RayRunner` (extra ``[ray]``)
and :class:`~.clusters.DaskRunner` (extra ``[dask]``), which loop over their pools as
:class:`PoolRunner` does; :func:`~.clusters.make_runner` builds one from the CLI's ``--runner``
options. Why each rule, and the workers' lifetime: docs/evaluation.md, "Studies: runners,
resume, nothing lost".
"""

from __future__ import annotations

import contextlib
import ctypes
import functools
import os
import pickle
import signal
import threading
import traceback
from collections import Counter, deque
from dataclasses import dataclass, field
from pathlib import Path

from ..base.errors import InvalidConfigError

#: Names of the backends, for ``--runner``.
RUNNERS = ("processes", "serial", "ray", "dask")
#: Jobs a worker process runs before it is replaced, on a Drake that cannot free a Diagram with
#: a Python LeafSystem (drake 1.51 keeps every run's: about 2 MB per 0.5 s run of
#: paper_hardware, 21 MB per 10 s run), so this bounds a worker's growth to ~420 MB; a
#: replacement costs a fresh interpreter and pydrake import (~1.5 s).
DEFAULT_RECYCLE = 20
#: ``recycle`` that lets the runner choose (:func:`default_recycle`): never on a Drake that frees
#: a run's Diagram, else every :data:`DEFAULT_RECYCLE` jobs.
AUTO_RECYCLE = "auto"
#: Attempts after the first for a job whose worker died.
DEFAULT_RETRIES = 2
#: The signals a terminal or a job control sends to end a command: Ctrl-C, ``kill``, a closed
#: terminal, Ctrl-\. Every command handles them alike (exit status 128 + the signal), and a
#: session on the robot ends with its torque off whichever arrives.
TERMINAL_SIGNALS = ("SIGINT", "SIGTERM", "SIGHUP", "SIGQUIT")
#: Their numbers on this platform: each cancels a running ``map`` and ends a command.
CANCEL_SIGNALS = tuple(getattr(signal, n) for n in TERMINAL_SIGNALS if hasattr(signal, n))


@dataclass
class JobFailure:
    """A job that gave no result (see the module docstring); picklable.

    Attributes:
        job_id: the job's key.  kind: "error" (``fn`` raised) or "lost" (its worker died).
        error_type: the exception's class name.  message: its text.  traceback: where.
        attempts: how many times the job was started.
        error: the exception object (None if it would not pickle, or for "lost").
        files: {path on the worker: bytes} of the file the error names (a divergence dump).
    """

    job_id: str
    kind: str
    error_type: str
    message: str
    traceback: str = ""
    attempts: int = 1
    error: BaseException | None = None
    files: dict = field(default_factory=dict)

    def __str__(self) -> str:
        return f"{self.error_type}: {self.message}"

    @classmethod
    def from_exception(cls, job_id: str, err: BaseException) -> JobFailure:
        """The record of ``err`` raised by a job, with the file it names read and removed."""
        files = {}
        path = getattr(err, "path", None)
        if isinstance(path, (str, os.PathLike)) and os.path.isfile(path):
            files[str(path)] = Path(path).read_bytes()
            os.remove(path)
        try:
            pickle.loads(pickle.dumps(err))
            kept = err
        except Exception:  # noqa: BLE001 - a foreign exception that will not travel
            kept = None
        return cls(
            job_id,
            "error",
            type(err).__name__,
            str(err),
            "".join(traceback.format_exception(err, limit=-6)),
            error=kept,
            files=files,
        )


@functools.cache
def drake_frees_diagrams() -> bool:
    """Whether this process's Drake frees a Diagram with a Python ``LeafSystem`` once nothing
    refers to it: a one-time probe (a Diagram of one such system, built, dropped, collected).

    drake 1.51 cannot (the system's callbacks, held in C++, refer back to it: drake#22515);
    drake 1.58 can. Our closed loop is then freed too (a test holds it to that), so a worker's
    memory no longer grows with the runs it has done (docs/performance.md).
    """
    import gc
    import weakref

    from pydrake.systems.framework import BasicVector, DiagramBuilder, LeafSystem

    class _Probe(LeafSystem):
        def __init__(self):
            super().__init__()
            self.DeclareVectorOutputPort("y", 1, self._calc)

        def _calc(self, context, out: BasicVector):
            out.SetAtIndex(0, 0.0)

    builder = DiagramBuilder()
    builder.AddSystem(_Probe())
    diagram = weakref.ref(builder.Build())
    del builder
    gc.collect()
    return diagram() is None


def default_recycle() -> int | None:
    """Jobs per local worker before it is replaced when not told: None (never) where Drake frees
    a run's Diagram (:func:`drake_frees_diagrams`), else :data:`DEFAULT_RECYCLE`."""
    return None if drake_frees_diagrams() else DEFAULT_RECYCLE


def resolve_recycle(recycle: int | str | None) -> int | None:
    """``recycle`` with :data:`AUTO_RECYCLE` resolved (:func:`default_recycle`) and 0 as None."""
    if recycle == AUTO_RECYCLE:
        return default_recycle()
    if isinstance(recycle, str) or (recycle is not None and recycle < 0):
        raise InvalidConfigError(
            f"recycle must be a number of jobs >= 0, None or {AUTO_RECYCLE!r}, got {recycle!r}"
        )
    return recycle or None


class Interrupted(KeyboardInterrupt):
    """A ``map`` (or a command) stopped by a signal; ``signum`` says which (exit status
    128 + signum)."""

    def __init__(self, signum: int):
        self.signum = int(signum)
        super().__init__(f"interrupted by {signal.Signals(signum).name}")

    def __reduce__(self):
        return type(self), (self.signum,)


def interrupt_in(err: BaseException) -> KeyboardInterrupt | None:
    """The KeyboardInterrupt (Ctrl-C, or :class:`Interrupted` for SIGTERM and SIGHUP) that
    ``err`` wraps, searched down its chain of causes and contexts (at most 20 links), or None.
    A signal whose handler raises while compiled code runs comes back wrapped in another error:
    numba's dispatcher returns a SystemError ("returned a result with an exception set") whose
    cause is the interrupt."""
    link: BaseException | None = err
    for _ in range(20):
        if link is None:
            return None
        if isinstance(link, KeyboardInterrupt):
            return link
        link = link.__cause__ or link.__context__
    return None


#: The signals the command's handlers raised while it runs, first first (the command clears
#: it as it starts and ends): a raise that code swallowed ("Exception ignored" from a callback
#: inside numba's compiler) is still known here, so nothing powers a robot after it.
_RAISED: list[int] = []


def raise_interrupted(signum, frame):
    """A signal handler: raise :class:`Interrupted` for ``signum`` (SIGTERM, SIGHUP, SIGQUIT),
    noted in :func:`interrupt_raised`."""
    _RAISED.append(int(signum))
    raise Interrupted(signum)


def raise_keyboard_interrupt(signum, frame):
    """SIGINT's handler while the command runs: Python's own (a KeyboardInterrupt), noted in
    :func:`interrupt_raised`."""
    _RAISED.append(int(signum))
    raise KeyboardInterrupt


def interrupt_raised() -> int | None:
    """The first signal the command's handlers raised (:func:`raise_interrupted`,
    :func:`raise_keyboard_interrupt`) since :func:`forget_interrupts`, or None."""
    return _RAISED[0] if _RAISED else None


def forget_interrupts() -> None:
    """Clear what :func:`interrupt_raised` knows (the command does, as it starts and ends)."""
    _RAISED.clear()


def call_job(fn, job_id: str, job):
    """Run one job (in the worker): its result, or the :class:`JobFailure` of what it raised.

    Raises:
        KeyboardInterrupt: Ctrl-C, or :class:`Interrupted`, while the job ran; also when it
            comes back wrapped in another error (:func:`interrupt_in`: a signal inside compiled
            code), so that it stops the map as any interrupt does instead of being recorded as
            the job's failure.
    """
    try:
        return fn(job)
    except Exception as err:  # noqa: BLE001 - a failure is a record, never a lost grid
        interrupt = interrupt_in(err)
        if interrupt is not None:
            raise interrupt from err
        return JobFailure.from_exception(job_id, err)


@contextlib.contextmanager
def _cancel_on_signals():
    """While inside: SIGINT, SIGTERM, SIGHUP, SIGQUIT raise :class:`Interrupted` (main thread
    only)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return

    # A signal the process was started ignoring stays ignored: `nohup` (SIGHUP), a background
    # job of a script (SIGINT).
    old = {
        s: signal.signal(s, raise_interrupted)
        for s in CANCEL_SIGNALS
        if signal.getsignal(s) is not signal.SIG_IGN
    }
    try:
        yield
    finally:
        for s, handler in old.items():
            signal.signal(s, handler)


@contextlib.contextmanager
def _signals_ignored():
    """Cleanup that a second Ctrl-C or SIGTERM must not cut short (it would orphan workers)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    old = {s: signal.signal(s, signal.SIG_IGN) for s in CANCEL_SIGNALS}
    try:
        yield
    finally:
        for s, handler in old.items():
            signal.signal(s, handler)


class SerialRunner:
    """Runs jobs one after the other in this process (tests, debugging, notebooks)."""

    n_workers = 1

    def map(self, fn, jobs, progress=None):
        """See the module docstring; jobs run in their given order."""
        with _cancel_on_signals():
            for job_id, job in dict(jobs).items():
                outcome = call_job(fn, job_id, job)
                if progress is not None:
                    progress(job_id, outcome)
                yield job_id, outcome


class WorkerLost(Exception):
    """Raised by a pool's ``submit`` or ``outcome`` (:class:`PoolRunner`) when the job's worker
    died or the pool broke; the message says how."""


class PoolRunner:
    """The protocol's loop over a pool of workers; backends supply ``_open`` -> a pool with
    ``capacity`` (jobs in flight), ``submit(fn, job_id, job)`` (runs ``call_job`` of them; raises
    :class:`WorkerLost` if the pool broke), ``wait(handles, timeout)`` -> done handles,
    ``outcome(handle)`` (raises :class:`WorkerLost`), ``recover()`` (after a loss) and
    ``close(pending)`` (cancel and end what is pending)."""

    n_workers: int = 1
    retries: int = DEFAULT_RETRIES

    def _open(self):
        raise NotImplementedError

    def map(self, fn, jobs, progress=None):
        """See the module docstring."""
        jobs = dict(jobs)
        queue, attempts, inflight = deque(jobs), Counter(), {}
        pool = None
        with _cancel_on_signals():
            try:
                pool = self._open()
                while queue or inflight:
                    pool.recover()
                    while queue and len(inflight) < pool.capacity:
                        try:
                            handle = pool.submit(fn, queue[0], jobs[queue[0]])
                        except WorkerLost:  # the pool broke since recover(): not an attempt
                            break
                        job_id = queue.popleft()
                        attempts[job_id] += 1
                        inflight[handle] = job_id
                    if not inflight:
                        continue
                    for handle in pool.wait(list(inflight), timeout=0.5):
                        job_id = inflight.pop(handle)
                        try:
                            outcome = pool.outcome(handle)
                        except WorkerLost as lost:
                            if attempts[job_id] <= self.retries:
                                queue.appendleft(job_id)
                                continue
                            outcome = JobFailure(job_id, "lost", "WorkerLost", str(lost))
                        if isinstance(outcome, JobFailure):
                            outcome.job_id, outcome.attempts = job_id, attempts[job_id]
                        if progress is not None:
                            progress(job_id, outcome)
                        yield job_id, outcome
            finally:
                if pool is not None:
                    with _signals_ignored():
                        pool.close(list(inflight))


# -- local processes ------------------------------------------------------------------------------


def _die_with_parent(parent_pid: int) -> None:
    """Make this worker end when ``parent_pid`` does: PR_SET_PDEATHSIG on Linux, else a thread
    that polls the parent's pid."""
    try:
        if ctypes.CDLL(None, use_errno=True).prctl(1, int(signal.SIGKILL)) != 0:  # PDEATHSIG
            raise OSError(ctypes.get_errno(), "prctl")
    except (OSError, AttributeError):

        def watch():
            while os.getppid() == parent_pid:
                threading.Event().wait(1.0)
            os._exit(1)

        threading.Thread(target=watch, daemon=True, name="parent-watch").start()
    if os.getppid() != parent_pid:  # the parent died before the signal was set
        os._exit(1)


def _worker_init(parent_pid: int) -> None:
    """Initializer of a local worker: the terminal's keys (Ctrl-C, Ctrl-\\), sent to the whole
    foreground group, are the parent's to handle (it ends the workers)."""
    for name in ("SIGINT", "SIGQUIT"):
        if hasattr(signal, name):
            signal.signal(getattr(signal, name), signal.SIG_IGN)
    _die_with_parent(parent_pid)


class _LocalPool:
    def __init__(self, n_workers: int, recycle: int | None, start_method: str):
        from multiprocessing import get_context

        self.capacity = n_workers
        self._args = dict(
            max_workers=n_workers,
            mp_context=get_context(start_method),
            max_tasks_per_child=recycle,
            initializer=_worker_init,
            initargs=(os.getpid(),),
        )
        self._broken = False
        self.executor = self._new()

    def _new(self):
        from concurrent.futures import ProcessPoolExecutor

        return ProcessPoolExecutor(**self._args)

    def submit(self, *args):
        from concurrent.futures.process import BrokenProcessPool

        try:
            return self.executor.submit(call_job, *args)
        except BrokenProcessPool:
            self._broken = True
            raise WorkerLost("the pool broke") from None

    def wait(self, handles, timeout):
        from concurrent.futures import FIRST_COMPLETED, wait

        return wait(handles, timeout=timeout, return_when=FIRST_COMPLETED).done

    def outcome(self, future):
        from concurrent.futures.process import BrokenProcessPool

        try:
            return future.result()
        except BrokenProcessPool as err:
            self._broken = True
            raise WorkerLost(f"a worker process died ({err})") from None

    def recover(self):
        if self._broken:
            self._terminate()
            self.executor, self._broken = self._new(), False

    def close(self, pending):
        if pending:
            self._terminate()
        else:
            self.executor.shutdown(wait=True)

    def _terminate(self):
        processes = list((getattr(self.executor, "_processes", None) or {}).values())
        results = getattr(self.executor, "_result_queue", None)  # shutdown forgets it
        self.executor.shutdown(wait=False, cancel_futures=True)
        for p in processes:
            p.terminate()
        for p in processes:
            p.join(2.0)
            if p.is_alive():
                p.kill()
                p.join()
        # A worker killed while it sent a result leaves half a message in the result pipe; the
        # executor's thread then waits for the rest forever, and the interpreter for that thread
        # at exit. With every worker gone, closing our write end turns that wait into an EOF.
        writer = getattr(results, "_writer", None)
        if writer is not None:
            with contextlib.suppress(OSError):
                writer.close()


class ProcessRunner(PoolRunner):
    """Jobs over local worker processes (the default runner).

    Args:
        n_workers: processes (0: one per core).
        retries: attempts after the first for jobs whose worker died.
        recycle: jobs per worker before it is replaced (bounds leaked memory; None or 0:
            never; :data:`AUTO_RECYCLE`: never where this Drake frees a run's Diagram, else
            :data:`DEFAULT_RECYCLE`, :func:`default_recycle`). The workers run this
            interpreter, hence its Drake.
        start_method: "spawn" (default: a fresh interpreter, safe with Drake's threads) or
            "forkserver".
    Workers ignore SIGINT (the parent ends them on Ctrl-C, SIGTERM, SIGHUP) and are killed when
    the parent dies (PR_SET_PDEATHSIG), so none is left orphaned.
    """

    def __init__(
        self,
        n_workers: int = 0,
        retries: int = DEFAULT_RETRIES,
        recycle: int | str | None = AUTO_RECYCLE,
        start_method: str = "spawn",
    ):
        self.n_workers = n_workers or os.cpu_count() or 1
        self.retries = retries
        self.recycle = resolve_recycle(recycle)
        self.start_method = start_method

    def _open(self):
        return _LocalPool(self.n_workers, self.recycle, self.start_method)


def map_outcomes(runner, fn, jobs: dict, progress: bool = True, desc: str = "", unit: str = "job"):
    """{job id: fn(job), or the failure's text} of every job of ``jobs`` ({id: job}) run by
    ``runner`` (default two local processes, each job in a fresh one), with a tqdm bar when
    ``progress``: a study that keeps going when one job fails and reports it in its table."""
    runner = runner or ProcessRunner(n_workers=2, recycle=1)
    items = runner.map(fn, jobs)
    if progress:
        from tqdm import tqdm

        items = tqdm(items, total=len(jobs), desc=desc, unit=unit)
    return {
        job_id: str(outcome) if isinstance(outcome, JobFailure) else outcome
        for job_id, outcome in items
    }
