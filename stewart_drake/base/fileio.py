"""Result files written atomically, and read back as valid files or one typed error.

Writing: a reader never sees a half-written file, even after Ctrl-C (:func:`atomic_write`), and
only regular files are ever replaced: a device node, a FIFO or a socket where an output is due
is refused by name (:func:`check_replaceable`), never renamed over; nor is a file the running
command reads (:func:`inputs_kept`: the same path, a link to it, a hard link).
Reading: every file the tool reads goes through :func:`read_checked` (a regular file, its size
bounded before a byte is read: a FIFO cannot block the reader, a sparse 100 GB file cannot
exhaust the memory). :func:`read_json` and :class:`~.npz.CheckedNpz` (an ``.npz`` archive)
then turn whatever a damaged file raises inside numpy, zipfile, zlib or json (BadZipFile,
EOFError, KeyError, JSONDecodeError, ValueError ...) into a
:class:`~stewart_drake.base.errors.CorruptFileError` naming the file and what is wrong. The bytes
are read first, so an ``OSError`` is always a real failure to read (permissions, a vanished
file), never a symptom of the content.
"""

from __future__ import annotations

import contextlib
import json
import os
import re
import socket
import stat
import tempfile
from pathlib import Path

import numpy as np

from .checks import available_memory_bytes, check_memory, format_bytes
from .errors import CorruptFileError, InvalidConfigError

#: The temporaries of :func:`atomic_write`: ``.<name>.<host>-<pid>.<random>.tmp``, hidden, named
#: by the writer so that :func:`remove_stale_temporaries` can tell a dead writer's from a live one
#: (``<random>``: the 8 characters of ``tempfile.mkstemp``).
_TEMPORARY = re.compile(r"^\.(?P<name>.+)\.(?P<host>\w*)-(?P<pid>\d+)\.[a-z0-9_]{8}\.tmp$")
#: Largest JSON document read (a manifest, an evaluation row, rows.json), bytes.
MAX_JSON_BYTES = 256e6


def describe_mode(mode: int) -> str:
    """What a file of ``st_mode`` ``mode`` is, for messages: "a folder", "a FIFO (named pipe)"."""
    for test, name in (
        (stat.S_ISDIR, "a folder"),
        (stat.S_ISCHR, "a character device"),
        (stat.S_ISBLK, "a block device"),
        (stat.S_ISFIFO, "a FIFO (named pipe)"),
        (stat.S_ISSOCK, "a socket"),
        (stat.S_ISREG, "a regular file"),
    ):
        if test(mode):
            return name
    return "not a regular file"


def _name_limits(folder: Path) -> tuple[int, int]:
    """(the longest name, the longest path) in bytes the file system of ``folder`` (or of the
    nearest folder above it that exists) takes; POSIX's 255 and 4096 where it does not say."""
    folder = Path(os.path.abspath(folder))
    while not folder.exists() and folder.parent != folder:
        folder = folder.parent
    limits = []
    for name, default in (("PC_NAME_MAX", 255), ("PC_PATH_MAX", 4096)):
        try:
            limits.append(int(os.pathconf(folder, name)))
        except (OSError, ValueError, AttributeError):  # not POSIX, or no limit said
            limits.append(default)
    return limits[0], limits[1]


def check_name(path, what: str | None = None) -> None:
    """Refuse an output whose name (or whole path) is longer than its file system takes, counted
    with the temporary it is written through (:func:`atomic_write`: ``.<name>.<host>-<pid>.
    <8 characters>.tmp``, 15 bytes and the writer's name longer): said before any work, not
    after it as an ``OSError`` of the write.

    Raises:
        InvalidConfigError: the name's length in bytes, the longest this output may have, and
            what to change.
    """
    path = Path(path)
    name_max, path_max = _name_limits(path.parent)
    extra = len(os.fsencode(f"..{_writer()}.")) + 8 + len(".tmp")
    name = len(os.fsencode(path.name))
    whole = len(os.fsencode(os.path.abspath(path)))
    if name + extra > name_max:
        raise InvalidConfigError(
            f"{what or path}: its name is {name} bytes long; the file system takes names of "
            f"at most {name_max} bytes, and the temporary it is written through adds {extra}: "
            f"give a name of at most {name_max - extra} bytes (of a report named after an "
            "input file, a shorter name of that file)"
        )
    if whole + extra > path_max:
        raise InvalidConfigError(
            f"{what or path}: its path is {whole} bytes long, with the temporary it is written "
            f"through {whole + extra}, over the {path_max} the system takes: choose a shorter "
            "--out"
        )


def check_replaceable(path, what: str | None = None) -> None:
    """Refuse to write over ``path`` unless it is absent or a regular file (symlinks followed)
    that is none of the running command's inputs (:func:`inputs_kept`), and a name its file
    system cannot hold (:func:`check_name`).

    Args:
        path: the output.  what: how the message names it (default the path), e.g.
            "--out /tmp/x".
    Raises:
        InvalidConfigError: ``path`` is a device node, a FIFO, a socket or a folder; the tool
            replaces only regular files, so the message says to choose another output. Or
            ``path`` is the same file as an input of the command (:func:`check_not_an_input`).
            Or its name, or its path, is too long (:func:`check_name`).
    """
    check_name(path, what)
    try:
        mode = os.stat(path).st_mode
    except (FileNotFoundError, NotADirectoryError):
        mode = None
    if mode is not None and not stat.S_ISREG(mode):
        raise InvalidConfigError(
            f"{what or path} is {describe_mode(mode)}, not a regular file: "
            f"stewart-drake replaces only regular files; choose another "
            f"output"
        )
    check_not_an_input(path, what)


#: The inputs of the command running, (how a message names it, path, whether it is a folder
#: whose every file is read), while :func:`inputs_kept` holds them; empty otherwise.
_INPUTS: list[tuple[str, str, bool]] = []
#: How many :func:`inputs_kept` blocks are open: :func:`note_input` adds only inside one.
_KEEPING: list[int] = [0]


@contextlib.contextmanager
def inputs_kept(named=()):
    """While the block runs, refuse every output that is the same file as one of the command's
    inputs: ``named``, (how a message names it, path) pairs (a folder stands for every file
    under it), and those :func:`note_input` adds meanwhile. Every output goes through
    :func:`check_replaceable` (:func:`atomic_write` calls it), so a command never writes over
    what it reads: ``calibrate --join A B --out A`` is refused. The command line
    (:func:`stewart_drake.cli.main.main`) holds one around each command.

    Args:
        named: iterable of (str, path-like); a path of None is skipped.
    """
    before = list(_INPUTS)
    _KEEPING[0] += 1
    try:
        for what, path in named:
            note_input(what, path)
        yield
    finally:
        _KEEPING[0] -= 1
        _INPUTS[:] = before


def note_input(what: str, path) -> None:
    """Add ``path`` (named ``what`` in messages, e.g. "--scenario my.yaml") to the inputs an
    open :func:`inputs_kept` block keeps; outside one, do nothing."""
    if path is None or not str(path) or not _KEEPING[0]:
        return
    _INPUTS.append((what, str(path), os.path.isdir(path)))


def same_file(a, b) -> bool:
    """Whether paths ``a`` and ``b`` name one file: the same inode (a link, a hard link, a
    path through a linked folder) when both exist, else the same path once links and ``..``
    are resolved."""
    try:
        sa, sb = os.stat(a), os.stat(b)
    except (OSError, ValueError):
        return os.path.realpath(a) == os.path.realpath(b)
    return (sa.st_dev, sa.st_ino) == (sb.st_dev, sb.st_ino)


def _in_folder(path, folder) -> bool:
    """Whether the existing file ``path`` is under ``folder``, by its resolved path or, for a
    file of several hard links, by its inode."""
    try:
        info = os.stat(path)
    except (OSError, ValueError):
        return False
    real, top = os.path.realpath(path), os.path.realpath(folder)
    if real.startswith(top.rstrip(os.sep) + os.sep):
        return True
    if info.st_nlink < 2:
        return False
    for root, _, files in os.walk(top):
        for name in files:
            try:
                other = os.stat(os.path.join(root, name))
            except OSError:
                continue
            if (other.st_dev, other.st_ino) == (info.st_dev, info.st_ino):
                return True
    return False


def check_not_an_input(path, what: str | None = None) -> None:
    """Refuse ``path`` as an output when it is the same file (:func:`same_file`) as an input
    the open :func:`inputs_kept` block keeps, or an existing file in an input folder.

    Raises:
        InvalidConfigError: names the output (``what``, default the path) and the input.
    """
    for name, source, folder in _INPUTS:
        if folder and not _in_folder(path, source):
            continue
        if not folder and not same_file(path, source):
            continue
        how = "a file of" if folder else "the same file as"
        shown = name if str(source) in name else f"{name} ({source})"
        raise InvalidConfigError(
            f"{what or path} is {how} {shown}, which this command reads: stewart-drake never "
            f"writes over its own input; choose another output"
        )


def _writer() -> str:
    return f"{re.sub(r'[^A-Za-z0-9_]', '_', socket.gethostname())}-{os.getpid()}"


def atomic_write(path: Path, write) -> None:
    """Call write(binary file) on a temporary file next to ``path``, then os.replace it.

    The temporary is ``.<name>.<host>-<pid>.<random>.tmp``; an exception (Ctrl-C included)
    removes it, a kill that Python cannot see (SIGKILL) leaves it for
    :func:`remove_stale_temporaries`.

    Raises:
        InvalidConfigError: ``path`` is a device node, a FIFO, a socket or a folder
            (:func:`check_replaceable`), before anything is written.
        OSError: the write failed (a full disk, permissions); its ``filename`` is ``path``.
    """
    path = Path(path)
    check_replaceable(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.{_writer()}.", suffix=".tmp")
    try:
        with os.fdopen(fd, "wb") as f:
            write(f)
        umask = os.umask(0)
        os.umask(umask)
        os.chmod(tmp, 0o666 & ~umask)  # mkstemp makes 0600; keep the usual mode
        os.replace(tmp, path)
    except OSError as err:
        if os.path.exists(tmp):
            os.remove(tmp)
        if err.errno is not None and err.filename in (None, tmp):  # a full disk names none
            raise type(err)(err.errno, err.strerror or str(err), str(path)) from None
        raise
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
        return True  # another user's process, or not a pid
    return True


def remove_stale_temporaries(folder, depth: int = 1) -> list[Path]:
    """Delete the temporaries :func:`atomic_write` left in ``folder`` (and its sub-folders down
    to ``depth``) when its process was killed mid-write: regular files named by the writer's
    pattern ``.<name>.<host>-<pid>.<random>.tmp`` whose writer, a process of this host, no
    longer runs. Nothing else is touched: a live writer's file (another command writing there
    now), another host's (a shared disk), and every file of another name (a user's
    ``.notes.tmp``, however old).

    Returns:
        the paths removed (none when the folder does not exist).
    """
    folder, host = Path(folder), _writer().rsplit("-", 1)[0]
    patterns = [".*.tmp"] + ["/".join(["*"] * k + [".*.tmp"]) for k in range(1, depth + 1)]
    removed = []
    for pattern in patterns:
        for path in folder.glob(pattern):
            match = _TEMPORARY.match(path.name)
            if not match or match["host"] != host or _alive(int(match["pid"])):
                continue
            try:
                if stat.S_ISREG(path.lstat().st_mode):
                    path.unlink()
                    removed.append(path)
            except FileNotFoundError:  # its writer renamed or removed it
                continue
    return removed


def save_npz(path: Path, arrays: dict) -> Path:
    """``np.savez_compressed`` of ``arrays`` into ``path``, atomically; returns the path."""
    atomic_write(path, lambda f: np.savez_compressed(f, **arrays))
    return Path(path)


def _describe(err: BaseException) -> str:
    text = str(err).strip().splitlines()
    return f"{type(err).__name__}: {text[0]:.160}" if text else type(err).__name__


def read_checked(path, kind: str, max_bytes: float, remedy: str = "") -> bytes:
    """The bytes of ``path``, read only once it is known to be a regular file of a bounded size.

    The path is checked before it is opened (a device is never opened, a socket cannot be),
    opened without blocking (a FIFO put there meanwhile would wait for a writer forever) and
    checked again on the open descriptor, so it cannot be swapped between the check and the
    read.

    Args:
        path: the file.  kind: what it should be, for messages ("scenario file").
        max_bytes: the largest such file, bytes; a larger one is refused unread.
        remedy: what the user can do about a bad one.
    Raises:
        CorruptFileError: a folder, a device node, a FIFO or a socket, or larger than
            ``max_bytes`` (a sparse file included).
        InvalidConfigError: more bytes than the machine has memory available.
        OSError: the file cannot be opened or read (missing, permissions).
    """

    def refuse(mode):
        return CorruptFileError(
            path, kind, f"it is {describe_mode(mode)}, not a regular file", remedy
        )

    mode = os.stat(path).st_mode  # a device is not even opened, a socket cannot be
    if not stat.S_ISREG(mode):
        raise refuse(mode)
    fd = os.open(path, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0))
    info = os.fstat(fd)  # what was opened, if it changed since the stat
    if not stat.S_ISREG(info.st_mode):
        os.close(fd)
        raise refuse(info.st_mode)
    with os.fdopen(fd, "rb") as f:
        if info.st_size > max_bytes:
            raise CorruptFileError(
                path,
                kind,
                f"it holds {format_bytes(info.st_size)}, over "
                f"the bound of {format_bytes(max_bytes)} for this "
                f"kind of file",
                remedy,
            )
        check_memory(f"reading {path}", info.st_size, "free some memory")
        return f.read()


def decode_text(raw: bytes, path, kind: str, remedy: str = "", encoding: str = "utf-8") -> str:
    """``raw`` as text (``encoding``: "utf-8", or "utf-8-sig" to drop a byte-order mark).

    Raises:
        CorruptFileError: not UTF-8 text, naming ``path`` as a ``kind``, the reason and the
            byte, and saying ``remedy``.
    """
    try:
        return raw.decode(encoding)
    except UnicodeDecodeError as err:
        raise CorruptFileError(
            path, kind, f"not UTF-8 text ({err.reason} at byte {err.start})", remedy
        ) from None


#: Memory a YAML document (a scenario, design requirements) takes to compose and load per byte
#: of its text, bytes: PyYAML's events and nodes, then Drake's typed load (about 40 measured).
YAML_BYTES_PER_BYTE = 64.0
#: Memory json.loads takes per byte of a document, beyond the bytes (objects, floats, strings:
#: 9-12 measured on a run's rows and a design generation).
JSON_BYTES_PER_BYTE = 16.0


def check_parse_memory(
    path, kind: str, raw: bytes, bytes_per_row: float = 0.0, bytes_per_byte: float = 0.0
) -> int:
    """Refuse, before it is parsed, a file whose parse would need more memory than this process
    has: ``raw`` (its bytes, already read) costs ``bytes_per_row`` per line and
    ``bytes_per_byte`` per byte beyond itself (each reader states what its parse measured).
    Every reader of a file the user names calls this between :func:`read_checked` and its
    parse, so that a long file is refused in one line instead of ending in a MemoryError or
    swapping for minutes.

    Returns:
        the file's lines (its newlines, and a last line without one).
    Raises:
        InvalidConfigError: one line: the estimate, the memory available
            (:func:`~.checks.available_memory_bytes`: the machine, a cgroup, ``ulimit -v``) and
            the size of such a file that would fit.
    """
    rows = raw.count(b"\n") + (1 if raw and not raw.endswith(b"\n") else 0)
    need = rows * bytes_per_row + len(raw) * bytes_per_byte
    available = available_memory_bytes()
    if available is not None and need > available:
        per_byte = need / max(len(raw), 1)
        fits = f"{format_bytes(available / per_byte)}"
        if bytes_per_row:
            fits += f" (about {int(available / (need / rows)):,} lines)"
        raise InvalidConfigError(
            f"{path}: reading this {kind} of {format_bytes(len(raw))} ({rows:,} lines) needs "
            f"about {format_bytes(need)} of memory, more than the {format_bytes(available)} "
            f"available; one of up to about {fits} fits here: split it into shorter files, "
            "or free some memory"
        )
    return rows


def read_json(path, kind: str, remedy: str = "", max_bytes: float = MAX_JSON_BYTES):
    """The JSON document in ``path`` (:func:`read_checked`, at most ``max_bytes``).

    Raises:
        CorruptFileError: not a regular file, too large, not UTF-8 or not JSON (truncated,
            random bytes, empty).
        OSError: the file cannot be read.
    """
    raw = read_checked(path, kind, max_bytes, remedy)
    check_parse_memory(path, kind, raw, bytes_per_byte=JSON_BYTES_PER_BYTE)
    try:
        return json.loads(raw.decode("utf-8"))
    except (UnicodeDecodeError, ValueError, RecursionError) as err:
        problem = "it is empty" if not raw.strip() else f"not JSON ({_describe(err)})"
        raise CorruptFileError(path, kind, problem, remedy) from None


def write_between_markers(doc: Path, markers: tuple[str, str], block: str) -> Path:
    """Replace the text of ``doc`` from ``markers[0]`` to ``markers[1]`` (both included) by
    ``block`` (which starts and ends with them), or append ``block`` when they are absent; the
    rest of the file is kept. For the generated tables of the docs."""
    doc = Path(doc)
    text = doc.read_text(encoding="utf-8") if doc.exists() else ""
    if markers[0] in text and markers[1] in text:
        a = text.index(markers[0])
        b = text.index(markers[1]) + len(markers[1])
        text = text[:a] + block + text[b:]
    else:
        text = text + ("\n" if text else "") + block + "\n"
    atomic_write(doc, lambda f: f.write(text.encode("utf-8")))
    return doc
