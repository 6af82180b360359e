"""Result files written atomically, and read back as valid files or one typed error.

Writing: a reader never sees a half-written file, even after Ctrl-C (:func:`atomic_write`).
Reading: :class:`CheckedNpz` and :func:`read_json` turn whatever a damaged file raises inside
numpy, zipfile, zlib or json (BadZipFile, EOFError, KeyError, JSONDecodeError, ValueError ...)
into a :class:`~stewart_drake.errors.CorruptFileError` naming the file and what is wrong. The
bytes are read first, so an ``OSError`` is always a real failure to read (permissions, a
vanished file), never a symptom of the content.
"""

from __future__ import annotations

import io
import json
import os
import re
import socket
import tempfile
import time
from pathlib import Path

import numpy as np

from .errors import CorruptFileError


#: The temporaries of :func:`atomic_write`: ``.<name>.<host>-<pid>.<random>.tmp``, hidden, named
#: by the writer so that :func:`remove_stale_temporaries` can tell a dead writer's from a live one.
_TEMPORARY = re.compile(r"^\.(?P<name>.+)\.(?P<host>\w*)-(?P<pid>\d+)\.\w+\.tmp$")
#: A temporary of the older form ``.<name>.<random>.tmp`` is stale after this long, s.
_LEGACY_STALE_S = 3600.0


def _writer() -> str:
    return f"{re.sub(r'[^A-Za-z0-9_]', '_', socket.gethostname())}-{os.getpid()}"


def atomic_write(path: Path, write) -> None:
    """Call write(binary file) on a temporary file next to ``path``, then os.replace it.

    The temporary is ``.<name>.<host>-<pid>.<random>.tmp``; an exception (Ctrl-C included)
    removes it, a kill that Python cannot see (SIGKILL, SIGTERM outside a study) leaves it for
    :func:`remove_stale_temporaries`.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.{_writer()}.",
                               suffix=".tmp")
    try:
        with os.fdopen(fd, "wb") as f:
            write(f)
        umask = os.umask(0)
        os.umask(umask)
        os.chmod(tmp, 0o666 & ~umask)                # mkstemp makes 0600; keep the usual mode
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.remove(tmp)
        raise


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except (PermissionError, OverflowError):
        return True                                   # another user's process, or not a pid
    return True


def remove_stale_temporaries(folder, depth: int = 1) -> list[Path]:
    """Delete the temporaries :func:`atomic_write` left in ``folder`` (and its sub-folders down
    to ``depth``) when its process was killed mid-write: those of a process of this host that
    no longer runs, and those of the older unnamed form after an hour. A live writer's file
    (another command writing there now) and another host's (a shared disk) are left alone.

    Returns:
        the paths removed (none when the folder does not exist).
    """
    folder, host = Path(folder), _writer().rsplit("-", 1)[0]
    patterns = [".*.tmp"] + ["/".join(["*"] * k + [".*.tmp"]) for k in range(1, depth + 1)]
    removed = []
    for pattern in patterns:
        for path in folder.glob(pattern):
            match = _TEMPORARY.match(path.name)
            try:
                if match:
                    stale = match["host"] == host and not _alive(int(match["pid"]))
                else:
                    stale = time.time() - path.stat().st_mtime > _LEGACY_STALE_S
                if stale and path.is_file():
                    path.unlink()
                    removed.append(path)
            except FileNotFoundError:                 # its writer renamed or removed it
                continue
    return removed


def save_npz(path: Path, arrays: dict) -> Path:
    """``np.savez_compressed`` of ``arrays`` into ``path``, atomically; returns the path."""
    atomic_write(path, lambda f: np.savez_compressed(f, **arrays))
    return Path(path)


def _describe(err: BaseException) -> str:
    text = str(err).strip().splitlines()
    return f"{type(err).__name__}: {text[0]:.160}" if text else type(err).__name__


def read_json(path, kind: str, remedy: str = ""):
    """The JSON document in ``path``.

    Raises:
        CorruptFileError: not UTF-8 or not JSON (truncated, random bytes, empty).
        OSError: the file cannot be read.
    """
    raw = Path(path).read_bytes()
    try:
        return json.loads(raw.decode("utf-8"))
    except (UnicodeDecodeError, ValueError, RecursionError) as err:
        problem = "it is empty" if not raw.strip() else f"not JSON ({_describe(err)})"
        raise CorruptFileError(path, kind, problem, remedy) from None


class CheckedNpz:
    """Every array of an ``.npz`` archive (``allow_pickle=False``), with typed accessors.

    Args:
        path: the file.  kind: what it should be, for messages ("ANN tuner weights file").
        remedy: what the user can do about a bad one (appended to every message).
    Raises:
        CorruptFileError: the bytes are not an ``.npz`` archive whose every entry numpy can
            read without pickle (empty, truncated, random bytes, a bad CRC, an object array, a
            single ``.npy`` array, an entry too large to hold).
        OSError: the file cannot be read.
    """

    def __init__(self, path, kind: str, remedy: str = ""):
        self.path, self.kind, self.remedy = Path(path), kind, remedy
        raw = self.path.read_bytes()
        if not raw:
            raise self.corrupt("it is empty")
        try:
            data = np.load(io.BytesIO(raw), allow_pickle=False)
            if not isinstance(data, np.lib.npyio.NpzFile):
                raise self.corrupt("it holds one .npy array, not an .npz archive")
            with data:
                self.arrays = {name: data[name] for name in data.files}
        except CorruptFileError:
            raise
        except Exception as err:                  # noqa: BLE001 - bytes in memory: any failure
            raise self.corrupt(f"not a readable .npz archive ({_describe(err)})") from None

    def corrupt(self, problem: str) -> CorruptFileError:
        """The error to raise for this file."""
        return CorruptFileError(self.path, self.kind, problem, self.remedy)

    def __contains__(self, name: str) -> bool:
        return name in self.arrays

    def _entry(self, name: str) -> np.ndarray:
        if name not in self.arrays:
            raise self.corrupt(f"the entry {name!r} is missing")
        return self.arrays[name]

    def array(self, name: str) -> np.ndarray:
        """Entry ``name`` as a float64 array (numbers only; shape and finiteness are the
        caller's to check)."""
        a = self._entry(name)
        if a.dtype.kind not in "biuf":
            raise self.corrupt(f"the entry {name!r} holds {a.dtype} values, not numbers")
        return a.astype(np.float64)

    def number(self, name: str) -> float:
        """Entry ``name`` as one float (a 0-d or 1-element numeric array)."""
        a = self.array(name)
        if a.size != 1:
            raise self.corrupt(f"the entry {name!r} must be one number, has shape {a.shape}")
        return float(a.reshape(()))

    def integer(self, name: str) -> int:
        """Entry ``name`` as one integer."""
        v = self.number(name)
        if not (np.isfinite(v) and v == int(v)):
            raise self.corrupt(f"the entry {name!r} must be an integer, got {v!r}")
        return int(v)

    def text(self, name: str) -> str:
        """Entry ``name`` as one string (a 0-d unicode array)."""
        a = self._entry(name)
        if a.dtype.kind != "U" or a.size != 1:
            raise self.corrupt(f"the entry {name!r} must be one string, has {a.dtype} "
                               f"shape {a.shape}")
        return str(a.reshape(()))

    def json(self, name: str, kind: type = dict):
        """Entry ``name`` (a string) parsed as JSON, which must be a ``kind``."""
        text = self.text(name)
        try:
            value = json.loads(text)
        except (ValueError, RecursionError) as err:
            raise self.corrupt(f"the entry {name!r} is not JSON ({_describe(err)})") from None
        if not isinstance(value, kind):
            raise self.corrupt(f"the entry {name!r} must be a JSON {kind.__name__}, got "
                               f"{type(value).__name__}")
        return value
