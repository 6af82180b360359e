"""Results that persist and resume: one study's folder, a file per finished job, a manifest.

A :class:`ResultStore` claims a folder for one study (``collect``, ``evaluate``) and one set of
settings, identified by :func:`settings_hash`, and locks it (:data:`LOCK`, ``fcntl.flock``): a
second study writing there at the same time is refused naming the first
(:class:`~stewart_drake.base.errors.FolderInUseError`); the kernel releases the lock when its holder
ends, however it ends. Each finished job is written atomically the
moment it arrives (``put``) and the manifest is rewritten with it, so an interruption, a killed
worker or a failed report loses nothing that finished. Running the same command again runs only
the jobs whose file is missing (:func:`run_jobs`); a folder of other settings, or of another
study, is refused by name (:class:`~stewart_drake.base.errors.ResultsMismatchError`).

``manifest.json``::

    {"study": "collect", "format": 2, "settings": {...}, "settings_hash": "3f2a...",
     "complete": false,
     "jobs": {"<job_id>": {"status": "done", "file": "run_q1_r1.npz", ...},
              "<job_id>": {"status": "lost", "error": "WorkerLost: ...", "attempts": 3}},
     ...study fields written at the end (``finish``)}
"""

from __future__ import annotations

import hashlib
import json
import os
import socket
import time
from pathlib import Path
from typing import Any

from ..base.errors import (
    CorruptFileError,
    FolderInUseError,
    IncompleteResultsError,
    ResultsMismatchError,
    SimulationDivergedError,
)
from ..base.fileio import atomic_write, check_replaceable, read_json
from .runners import JobFailure

MANIFEST = "manifest.json"
#: The lock file of a study folder; it holds who locked it last ("`evaluate` study, pid ...").
LOCK = ".stewart-drake.lock"
#: Study folders this process holds locked: {real path: open lock file}.
_HELD: dict = {}
#: Layout version of the folder; 2 = one file per job and a settings hash.
FORMAT = 2


def settings_hash(settings: dict) -> str:
    """16 hex digits of the SHA-256 of ``settings`` as canonical JSON (sorted keys)."""
    text = json.dumps(settings, sort_keys=True, separators=(",", ":"), default=str)
    return hashlib.sha256(text.encode()).hexdigest()[:16]


def file_digest(path) -> str:
    """16 hex digits of the SHA-256 of a file's bytes (settings that are files: tuner weights,
    read through :func:`~stewart_drake.base.fileio.read_checked`, at most 64 MB)."""
    from ..base.fileio import read_checked

    return hashlib.sha256(read_checked(path, "settings file", 64e6)).hexdigest()[:16]


def lock_folder(folder, study: str) -> None:
    """Hold ``folder``'s study lock (``fcntl.flock`` of :data:`LOCK`) for this process until
    :func:`unlock_folder` or its end; already held by this process: nothing to do (one process
    runs its studies one after the other).

    Raises:
        FolderInUseError: another process holds it; the message says who (the lock file's
            line: study, pid, host, since when).
    """
    try:
        import fcntl
    except ImportError:  # no flock (Windows): the folder stays unlocked
        return
    folder = Path(folder)
    key = os.path.realpath(folder)
    if key in _HELD:
        return
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / LOCK
    for _ in range(10):  # the holder removes the file as it lets go: lock the file that is there
        check_replaceable(path)
        f = open(path, "a+", encoding="utf-8")
        try:
            fcntl.flock(f, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            f.seek(0)
            holder = " ".join(f.read(300).split())
            f.close()
            raise FolderInUseError(folder, holder) from None
        try:
            if os.path.samestat(os.fstat(f.fileno()), os.stat(path)):
                break
        except FileNotFoundError:
            pass
        f.close()
    else:
        raise FolderInUseError(folder, "another process that keeps taking and releasing it")
    f.seek(0)
    f.truncate()
    f.write(
        f"`{study}` study, pid {os.getpid()} on {socket.gethostname()}, since "
        f"{time.strftime('%Y-%m-%d %H:%M:%S')}\n"
    )
    f.flush()
    _HELD[key] = f


def unlock_folder(folder) -> None:
    """Release ``folder``'s study lock if this process holds it, removing the lock file (no
    stale file is left to read as a lock; a process waiting on the removed file locks the new
    one, :func:`lock_folder`)."""
    f = _HELD.pop(os.path.realpath(Path(folder)), None)
    if f is not None:
        try:
            os.unlink(Path(folder) / LOCK)
        except OSError:
            pass  # gone already, or a read-only folder: the lock is released all the same
        f.close()


#: What a job's entry in a manifest may record (:meth:`ResultStore.mark` uses a JobFailure's kind).
JOB_STATUSES = ("done", "lost", "error")
#: A damaged manifest cannot be repaired by deleting it alone: the folder's result files would
#: then be refused as results without a manifest.
_REMEDY = "delete the folder (or choose another --out) and run the command again"


def read_manifest(folder: Path) -> dict | None:
    """The manifest of ``folder``, None if there is none.

    A manifest of the current layout (with ``study`` and ``settings_hash``) is checked entry by
    entry: ``jobs`` maps ids to records with a known ``status`` and, when done, a ``file``.
    An older layout is returned as it is (:class:`ResultStore` refuses it by name).

    Raises:
        CorruptFileError: not JSON (truncated, random bytes, empty), not a JSON object, or an
            incomplete record (names the entry).
        OSError: the file cannot be read.
    """
    path = Path(folder) / MANIFEST
    if not path.exists():
        return None
    manifest = read_json(path, "stewart-drake manifest", _REMEDY)
    if not isinstance(manifest, dict):
        raise CorruptFileError(
            path,
            "stewart-drake manifest",
            f"a JSON {type(manifest).__name__}, not an object",
            _REMEDY,
        )
    if "study" in manifest or "settings_hash" in manifest:
        check_manifest(path, manifest)
    return manifest


def check_manifest(path: Path, manifest: dict) -> None:
    """Refuse a manifest of the current layout with a missing or mistyped entry.

    Raises:
        CorruptFileError: names the first entry that is wrong.
    """

    def bad(problem):
        return CorruptFileError(path, "stewart-drake manifest", problem, _REMEDY)

    for key, kind in (
        ("study", str),
        ("settings_hash", str),
        ("settings", dict),
        ("jobs", dict),
        ("complete", bool),
    ):
        if not isinstance(manifest.get(key), kind):
            raise bad(
                f"{key!r} must be a JSON {kind.__name__}, got {type(manifest.get(key)).__name__}"
                if key in manifest
                else f"the entry {key!r} is missing"
            )
    if settings_hash(manifest["settings"]) != manifest["settings_hash"]:
        raise bad(
            f"its settings_hash {manifest['settings_hash']!r} is not the hash of its "
            f"settings ({settings_hash(manifest['settings'])!r}): one was edited"
        )
    owner: dict[Any, str] = {}
    for job_id, job in manifest["jobs"].items():
        if not isinstance(job, dict) or job.get("status") not in JOB_STATUSES:
            raise bad(f"job {job_id!r} has no status of {JOB_STATUSES}")
        name = job.get("file")
        if job["status"] == "done" and not (
            isinstance(name, str)
            and name
            and not Path(name).is_absolute()
            and ".." not in Path(name).parts
        ):
            raise bad(f"job {job_id!r} is done but names no file in the folder")
        if job["status"] == "done":
            if name in owner:
                raise bad(
                    f"jobs {owner[name]!r} and {job_id!r} both name the file {name!r} "
                    f"(each job has a file of its own)"
                )
            owner[name] = job_id


def _difference(old: dict, new: dict) -> str:
    """'seed 0 there, 1 here; trajectory differs' for the settings that differ."""
    parts = []
    for k in sorted(k for k in set(old) | set(new) if old.get(k) != new.get(k)):
        a, b = old.get(k), new.get(k)
        scalar = not isinstance(a, (dict, list)) and not isinstance(b, (dict, list))
        parts.append(f"{k} {a!r:.40} there, {b!r:.40} here" if scalar else f"{k} differs")
    return "; ".join(parts)


class ResultStore:
    """One study's results in ``folder`` (see the module docstring).

    Args:
        folder: the study's ``--out``.  study: "collect" or "evaluate".
        settings: JSON-able dict of everything that decides the results (not the runner).
        pattern: glob of the study's result files; a folder holding such files but no manifest
            is refused (an older layout, or a manifest deleted by hand).
    Raises:
        ResultsMismatchError: the folder holds another study's results, or results of other
            settings (the message names the settings that differ).
        FolderInUseError: another process's study is writing the folder (:func:`lock_folder`);
            this store holds the lock until :meth:`finish` or :meth:`close`.
        CorruptFileError: a damaged manifest (:func:`read_manifest`).
    """

    def __init__(self, folder, study: str, settings: dict, pattern: str):
        self.folder = Path(folder)
        self.study = study
        settings = json.loads(json.dumps(settings, default=str))  # as the manifest holds it
        self.settings = settings
        self.hash = settings_hash(settings)
        lock_folder(self.folder, study)
        try:
            self._claim(pattern)
        except BaseException:
            self.close()
            raise

    def close(self) -> None:
        """Release the folder's lock (:meth:`finish` does); the store's files stay."""
        unlock_folder(self.folder)

    def _claim(self, pattern: str) -> None:
        study, settings = self.study, self.settings
        old = read_manifest(self.folder)
        if old is None:
            if any(self.folder.glob(pattern)):
                raise ResultsMismatchError(
                    f"{self.folder} holds {pattern} files without a {MANIFEST} (an older "
                    f"stewart-drake, or the manifest was removed): choose another --out or "
                    f"delete them"
                )
            old = {}
        elif "study" not in old or "settings_hash" not in old:
            raise ResultsMismatchError(
                f"{self.folder} holds results of an older stewart-drake (no settings hash in "
                f"its {MANIFEST}): choose another --out or delete the folder"
            )
        elif old["study"] != study:
            raise ResultsMismatchError(
                f"{self.folder} holds results of `stewart-drake {old['study']}`, not of "
                f"`{study}`: choose another --out"
            )
        elif old.get("settings_hash") != self.hash:
            raise ResultsMismatchError(
                f"{self.folder} holds {study} results of other settings "
                f"({_difference(old.get('settings', {}), settings)}): run with those settings "
                f"to finish them, or choose another --out (or delete the folder)"
            )
        done = {
            k: v
            for k, v in old.get("jobs", {}).items()
            if v.get("status") == "done" and (self.folder / v["file"]).exists()
        }
        self.manifest: dict[str, Any] = {
            "study": study,
            "format": FORMAT,
            "settings": settings,
            "settings_hash": self.hash,
            "complete": False,
            "jobs": done,
        }
        self._save()  # claim the folder before any work

    def _save(self) -> None:
        text = json.dumps(self.manifest, indent=1, default=float).encode()
        atomic_write(self.folder / MANIFEST, lambda f: f.write(text))

    def done(self) -> set:
        """Ids of the jobs whose result is on disk."""
        return {k for k, v in self.manifest["jobs"].items() if v["status"] == "done"}

    def put(self, job_id: str, name: str, write, **meta) -> Path:
        """Write a finished job's file atomically (``write(binary file)``), then record it.

        Args:
            name: file name under the folder (sub-folders allowed).
            meta: JSON-able facts kept in the manifest beside it (times, figures).
        """
        path = self.folder / name
        atomic_write(path, write)
        self.manifest["jobs"][job_id] = {"status": "done", "file": name, **meta}
        self._save()
        return path

    def put_json(self, job_id: str, name: str, value, **meta) -> Path:
        """:meth:`put` of a JSON document."""
        text = json.dumps(value, indent=1, default=float).encode()
        return self.put(job_id, name, lambda f: f.write(text), **meta)

    def load_json(self, job_id: str):
        """The JSON document a job's :meth:`put_json` wrote.

        Raises:
            CorruptFileError: the file is not JSON (names it; delete it and run again to redo
                that job).
        """
        return read_json(
            self.folder / self.manifest["jobs"][job_id]["file"],
            f"{self.study} result",
            "delete it and run the same command again to redo that job",
        )

    def mark(self, failure: JobFailure) -> None:
        """Record a job with no result (lost or failed); it runs again next time."""
        self.manifest["jobs"][failure.job_id] = {
            "status": failure.kind,
            "error": str(failure),
            "attempts": failure.attempts,
        }
        self._save()

    def keep_files(self, failure: JobFailure) -> list[Path]:
        """Write the files a failure carried back (divergence dumps) under ``diverged/`` and
        point its message (and error's ``path``) at them; returns the paths written."""
        written = []
        for old, data in failure.files.items():
            path = self.folder / "diverged" / Path(old).name
            atomic_write(path, lambda f, data=data: f.write(data))
            failure.message = failure.message.replace(old, str(path))
            if isinstance(failure.error, SimulationDivergedError) and failure.error.path == old:
                failure.error = SimulationDivergedError(
                    failure.error.message, failure.error.t, str(path)
                )
            written.append(path)
        return written

    def finish(self, complete: bool, **fields) -> dict:
        """Write the study's closing fields and whether every job is on disk, and release the
        folder's lock; the manifest."""
        self.manifest.update(fields)
        self.manifest["complete"] = bool(complete)
        self._save()
        self.close()
        return self.manifest


def run_jobs(
    store: ResultStore,
    runner,
    fn,
    jobs: dict,
    save,
    progress: bool = True,
    desc: str = "jobs",
    what: str = "jobs",
) -> dict:
    """Run the jobs of ``jobs`` whose result is not in ``store``, storing each as it arrives.

    Args:
        store: the study's folder.  runner: any runner of :mod:`.runners`.
        fn: the job function.  jobs: {job_id: job}.
        save: ``save(job_id, outcome)`` stores a result (or a ``kind="error"`` failure, as the
            study decides) through ``store``; lost jobs are recorded here.
        progress: show a tqdm bar (counting the jobs found on disk).
        desc, what: the bar's label and the noun of the error message.
    Returns:
        dict: ``ran`` (ids run now), ``reused`` (ids found on disk), ``wall_s`` of this call.
    Raises:
        IncompleteResultsError: some jobs have no result on disk at the end (lost, or failed
            and not stored by ``save``); the message names the first and says to rerun.
        Interrupted: a signal stopped the runner; everything finished is on disk.
    """
    from tqdm import tqdm

    todo = {k: v for k, v in jobs.items() if k not in store.done()}
    reused = [k for k in jobs if k not in todo]
    wall0 = time.perf_counter()
    with tqdm(
        total=len(jobs), initial=len(reused), desc=desc, unit="run", disable=not progress
    ) as bar:
        for job_id, outcome in runner.map(fn, todo):
            if isinstance(outcome, JobFailure):
                store.keep_files(outcome)
                if outcome.kind == "lost":
                    store.mark(outcome)
                    bar.update()
                    continue
            save(job_id, outcome)
            bar.update()
    wall = time.perf_counter() - wall0
    missing = [k for k in jobs if k not in store.done()]
    if missing:
        first = store.manifest["jobs"].get(missing[0], {}).get("error", "not run")
        raise IncompleteResultsError(
            f"{len(missing)} of {len(jobs)} {what} have no result ({missing[0]}: "
            f"{first.splitlines()[0]:.200}); the {len(jobs) - len(missing)} finished are in "
            f"{store.folder}: run the same command again to run only the missing ones"
        )
    return {"ran": list(todo), "reused": reused, "wall_s": wall}
