"""numba's disk cache for the package's compiled code: how a kernel is compiled
(:func:`njit_cached`) and its uncompiled form (:func:`interpreted`).

The LQI's control step (:mod:`stewart_drake.control.lqi`, whose cache
:mod:`stewart_drake.control.kernel_cache` also inspects) and the reference validator's per-pose
arithmetic (:mod:`stewart_drake.robot.path_kernels`) are compiled this way. numba keeps one
index file per compiled function in the first cache folder it can write: ``NUMBA_CACHE_DIR``,
else ``__pycache__`` beside the source, else the user's cache folder, else (:func:`njit_cached`
sets it) a folder in the temporary directory, made private to the user.

numba's index and data files are pickles, and unpickling runs whatever a pickle names. Two
defences keep the cache from running what this tool did not write:

- A cache folder another user can write in (a folder of the shared temporary directory planted
  before ours, a ``__pycache__`` open to all) is never used (:func:`cache_folder_problem`): the
  code compiles in every process, said once.
- Every index and data file is signed as it is written: an HMAC-SHA256 of its bytes and its
  name, keyed by a secret of this user's (:func:`cache_key`: 32 random bytes in a file of mode
  0600 in the user's configuration folder, outside every cache, made on first use), appended
  to the file. A file is unpickled only once its signature is checked; one without a valid
  signature (a ``__pycache__`` that came inside a downloaded archive or repository, a file
  copied in from another machine or account, one numba wrote without this module, one cut
  short or of random bytes) is removed unread and the code compiles again, said once. numba
  itself still reads a signed file (pickle ignores the bytes after its end).

What this does not defend: the same user. Whoever runs code as this user can read the key and
sign a pickle of their own (they could as well edit this package or ``~/.bashrc``), so the key
is no boundary between two programs of one account; it marks the files this user's
stewart-drake wrote, and keeps out files from elsewhere. A damaged entry (a truncated write, a
full disk, random bytes) fails its signature, or, if signed, whatever unpickling it raises is
caught: either way it is discarded and compiled again instead of failing every later run. This
module imports numba only when a function here needs it.

A compilation is seconds to a minute that shows nothing else: while a command runs
(:func:`announce_compiles`), the first compilation of each module's kernels is said in one line
before it starts (the LQI's step says so itself before its import,
:func:`~stewart_drake.execution.options.say_if_compiling`).
"""

from __future__ import annotations

import contextlib
import functools
import hashlib
import hmac
import io
import os
import pickle
import secrets
import stat
import sys
import tempfile
import types
from collections.abc import Callable, Iterator
from typing import Any

#: What reading a damaged cache file may raise: any exception. Unpickling runs the opcodes it
#: finds, so damaged bytes raise nearly anything (pickle's errors, EOFError, OverflowError,
#: RecursionError, struct.error, UnicodeDecodeError, a missing module or attribute, MemoryError
#: ...); a list of them misses some. KeyboardInterrupt and SystemExit are not Exceptions and
#: pass.
DAMAGED_CACHE_ERRORS: tuple[type[BaseException], ...] = (Exception,)
#: What ends a signed cache file: this marker, then the 32 bytes of its HMAC-SHA256.
SIGNATURE_MARKER = b"stewart-drake-mac1"
_TAG_BYTES = 32
#: Bytes of the key that signs the cache's files.
KEY_BYTES = 32
_SAID: set = set()


def _say_once(key, line: str) -> None:
    """``line`` on stderr, once per process for ``key``."""
    if key not in _SAID:
        _SAID.add(key)
        print(f"stewart-drake: {line}", file=sys.stderr, flush=True)


#: Who is told the module whose kernels numba starts compiling, while a command runs; None: no
#: one.
_announce: Callable[[str], None] | None = None
#: The modules (or packages: a prefix) whose compilation was said, in this process.
_announced: set = set()
_listening = False


@contextlib.contextmanager
def announce_compiles(say: Callable[[str], None]) -> Iterator[None]:
    """While the block runs, call ``say(module)`` just before numba starts compiling the first
    kernel of ``module`` (its ``__name__``; once a module, a process): a command says so in
    one line (:func:`~stewart_drake.execution.options.compile_note`). A kernel loaded from the
    cache says nothing. Numba is not imported here: the one listener is registered when a
    kernel is first decorated (:func:`njit_cached`)."""
    global _announce
    previous, _announce = _announce, say
    try:
        yield
    finally:
        _announce = previous


def announced(module: str) -> None:
    """Mark ``module`` (a module or a package: its modules too) as said: its compilation is
    announced elsewhere (:func:`~stewart_drake.execution.options.say_if_compiling`)."""
    _announced.add(module)


#: The package whose kernels are said: numba's own helpers compile inside them, unsaid.
_PACKAGE = __name__.split(".")[0]


def _on_compile(module: str) -> None:
    """numba starts compiling a kernel of ``module``: say so, the first time for it (a module
    of this package; numba's own helpers compile as parts of its kernels)."""
    say = _announce
    if say is None or not module.startswith(_PACKAGE + "."):
        return
    if any(module == m or module.startswith(m + ".") for m in _announced):
        return
    _announced.add(module)
    say(module)


def _listen() -> None:
    """Register, once, numba's listener of its "numba:compile" events (sent only when a kernel
    is compiled, not when it is loaded from the cache), calling :func:`_on_compile`."""
    global _listening
    if _listening:
        return
    from numba.core import event

    class _Compiling(event.Listener):
        def on_start(self, event):
            dispatcher = event.data.get("dispatcher") if isinstance(event.data, dict) else None
            module = getattr(getattr(dispatcher, "py_func", None), "__module__", None)
            if module:
                _on_compile(module)

        def on_end(self, event):
            pass

    event.register("numba:compile", _Compiling())
    _listening = True


def fallback_cache_dir() -> str:
    """A per-user folder in the temporary directory for numba's cache."""
    user = os.environ.get("USER") or str(os.getuid() if hasattr(os, "getuid") else "user")
    return os.path.join(tempfile.gettempdir(), f"stewart-drake-numba-cache-{user}")


def cache_folder_problem(folder, root=None) -> str | None:
    """Why numba's cache in ``folder`` could hold another user's pickles, or None when it is
    safe: ``folder`` and each folder between it and ``root`` (the cache's top, e.g.
    ``NUMBA_CACHE_DIR``; None: ``folder`` alone) must be a folder (not a symbolic link, but for
    a ``root`` the user chose, which may be a link; :func:`fallback_cache_dir`, in the shared
    temporary directory, may not), owned by this user, that no one else may write in. Where
    the system has no user ids (Windows), only the kind is checked."""
    folder = os.path.abspath(folder)
    top = os.path.abspath(root) if root else folder
    follow = root is not None and top != os.path.abspath(fallback_cache_dir())
    chain = [folder]
    while chain[-1] != top and os.path.dirname(chain[-1]) != chain[-1]:
        if not chain[-1].startswith(top + os.sep):
            break
        chain.append(os.path.dirname(chain[-1]))
    for path in chain:
        try:
            st = os.stat(path) if path == top and follow else os.lstat(path)
        except OSError as err:
            return f"{path} cannot be examined ({err.strerror or err})"
        if stat.S_ISLNK(st.st_mode):
            return f"{path} is a symbolic link"
        if not stat.S_ISDIR(st.st_mode):
            return f"{path} is not a folder"
        if hasattr(os, "getuid") and st.st_uid != os.getuid():
            return f"{path} belongs to user id {st.st_uid}, not to you ({os.getuid()})"
        if hasattr(os, "getuid") and st.st_mode & 0o022:
            return f"others may write in {path} (mode {stat.S_IMODE(st.st_mode):o})"
    return None


def _private_folder(path: str) -> None:
    """Make ``path`` readable and writable by this user alone, if it does not exist (its
    parent, the temporary directory, exists); an existing one is judged by
    :func:`cache_folder_problem`."""
    try:
        os.mkdir(path, 0o700)
    except OSError:
        pass


def key_folders() -> list[str]:
    """Where the key that signs numba's cache is kept, in order of choice: the user's
    configuration folder (``XDG_CONFIG_HOME``, else ``~/.config``), their cache folder
    (``XDG_CACHE_HOME``, else ``~/.cache``), each under ``stewart-drake``, else a folder of the
    temporary directory made private to the user (as :func:`fallback_cache_dir`)."""
    home = os.path.expanduser("~")
    folders = []
    for variable, default in (("XDG_CONFIG_HOME", ".config"), ("XDG_CACHE_HOME", ".cache")):
        base = os.environ.get(variable) or (os.path.join(home, default) if home != "~" else "")
        if base and os.path.isabs(base):
            folders.append(os.path.join(base, "stewart-drake"))
    return folders + [fallback_cache_dir() + "-key"]


def _read_key(path: str) -> bytes:
    """The key in ``path``: a regular file (not a link) of :data:`KEY_BYTES` bytes, this user's,
    that no one else may read or write.

    Raises:
        OSError: missing or unreadable.  ValueError: not such a file (says why).
    """
    fd = os.open(path, os.O_RDONLY | getattr(os, "O_NOFOLLOW", 0) | getattr(os, "O_NONBLOCK", 0))
    with os.fdopen(fd, "rb") as f:
        info = os.fstat(f.fileno())
        if not stat.S_ISREG(info.st_mode):
            raise ValueError(f"{path} is not a regular file")
        if hasattr(os, "getuid") and info.st_uid != os.getuid():
            raise ValueError(f"{path} belongs to user id {info.st_uid}, not to you")
        if hasattr(os, "getuid") and info.st_mode & 0o077:
            raise ValueError(
                f"others may read or write {path} (mode {stat.S_IMODE(info.st_mode):o}): remove "
                "it, a new one is made"
            )
        key = f.read(KEY_BYTES + 1)
    if len(key) != KEY_BYTES:
        raise ValueError(f"{path} does not hold a key of {KEY_BYTES} bytes: remove it")
    return key


def _make_key(folder: str) -> bytes:
    """The key in ``folder``/numba-cache.key, made there (mode 0600, whole or not at all: two
    processes making it at once keep one) if it is not; ``folder`` is made private to the user
    and must be safe (:func:`cache_folder_problem`).

    Raises:
        OSError, ValueError: no key can be kept there (says why).
    """
    os.makedirs(folder, mode=0o700, exist_ok=True)
    problem = cache_folder_problem(folder)
    if problem is not None:
        raise ValueError(problem)
    path = os.path.join(folder, "numba-cache.key")
    try:
        return _read_key(path)
    except FileNotFoundError:
        pass
    fd, tmp = tempfile.mkstemp(dir=folder, prefix=".numba-cache.key.")  # mode 0600
    try:
        with os.fdopen(fd, "wb") as f:
            f.write(secrets.token_bytes(KEY_BYTES))
        try:
            os.link(tmp, path)  # never replaces a key another process made meanwhile
        except FileExistsError:
            pass
    finally:
        os.remove(tmp)
    return _read_key(path)


@functools.cache
def cache_key() -> tuple[bytes | None, str]:
    """(the key that signs numba's cache files, "") or (None, why no key can be kept), once per
    process: the first of :func:`key_folders` where a key is, or can be made."""
    problems = []
    for folder in key_folders():
        try:
            return _make_key(folder), ""
        except (OSError, ValueError) as err:
            problems.append(f"{folder}: {getattr(err, 'strerror', None) or err}")
    return None, "; ".join(problems)


def _tag(key: bytes, path: str, payload: bytes) -> bytes:
    """HMAC-SHA256 of a cache file's ``payload`` and its name (not its folder: a cache copied
    or moved by its user stays valid)."""
    name = os.path.basename(path).encode("utf-8", "surrogateescape")
    message = b"stewart-drake numba cache\0" + name + b"\0" + payload
    return hmac.new(key, message, hashlib.sha256).digest()


def signed(key: bytes, path: str, payload: bytes) -> bytes:
    """``payload`` (the bytes numba writes at ``path``) with its signature appended."""
    return payload + SIGNATURE_MARKER + _tag(key, path, payload)


def verified(key: bytes, path: str, raw: bytes) -> bytes | None:
    """The payload of ``raw``, the bytes read at ``path``, when its signature is valid, else
    None (none, another key's, or bytes changed since)."""
    end = len(SIGNATURE_MARKER) + _TAG_BYTES
    if len(raw) < end or raw[-end:-_TAG_BYTES] != SIGNATURE_MARKER:
        return None
    payload = raw[:-end]
    return payload if hmac.compare_digest(raw[-_TAG_BYTES:], _tag(key, path, payload)) else None


def load_signed_index(path) -> tuple | None:
    """(numba's version, the source's stamp, the overloads) of numba's index file ``path``,
    or None when it is missing, unsigned (:func:`verified`) or damaged; nothing is unpickled
    before its signature is checked."""
    key, _ = cache_key()
    if key is None:
        return None
    try:
        with open(path, "rb") as f:
            payload = verified(key, str(path), f.read())
        if payload is None:
            return None
        stream = io.BytesIO(payload)
        version = pickle.load(stream)
        stamp, overloads = pickle.loads(stream.read())
        return version, stamp, overloads
    except DAMAGED_CACHE_ERRORS:
        return None


#: The attribute :func:`njit_cached` sets on every function it compiles.
KERNEL_MARK = "_stewart_drake_kernel"


def njit_cached(function, cache: bool = True, **options):
    """``numba.njit(cache=True, **options)(function)``, with the cache in a folder that is safe
    to load from (:func:`cache_folder_problem`) and damaged entries compiled again; without the
    cache when ``cache`` is false (the LQI's kernels ask
    :func:`~stewart_drake.control.kernel_cache.use_cache` once) or when no safe folder is found
    (said once on stderr, with what to do). ``options``: numba's own
    (``error_model="numpy"``: a division by zero gives inf or NaN, as numpy's, not an error).

    numba refuses to cache (RuntimeError at decoration) when neither ``NUMBA_CACHE_DIR``, the
    source's ``__pycache__`` nor the user's cache folder is writable: the cache then goes to
    :func:`fallback_cache_dir`, made private to the user, and if even that fails the function
    compiles in every process.

    The function is marked (:data:`KERNEL_MARK`) before it is compiled: with
    ``NUMBA_DISABLE_JIT`` numba returns it as it is, and :func:`interpreted` still finds it.
    """
    import numba

    setattr(function, KERNEL_MARK, True)

    _listen()
    if not cache:
        return numba.njit(**options)(function)
    config: Any = numba.config  # its settings are module attributes numba sets at import
    try:
        dispatcher = numba.njit(cache=True, **options)(function)
    except RuntimeError:
        if config.CACHE_DIR:
            return numba.njit(**options)(function)
        config.CACHE_DIR = fallback_cache_dir()
        _private_folder(config.CACHE_DIR)
        try:
            dispatcher = numba.njit(cache=True, **options)(function)
        except RuntimeError:
            config.CACHE_DIR = ""
            return numba.njit(**options)(function)
    folder = getattr(getattr(dispatcher, "_cache", None), "_cache_path", None)
    if folder is None:  # NUMBA_DISABLE_JIT: the function itself, nothing cached
        return dispatcher
    problem = cache_folder_problem(folder, config.CACHE_DIR or None)
    if problem is not None:
        _say_once(
            ("unsafe", problem),  # one line for every folder of one unsafe root
            f"numba's cache folder {folder} is not safe to load compiled code from: {problem}; "
            "compiling without a disk cache (every run compiles again): set NUMBA_CACHE_DIR to "
            "a folder of your own that no one else may write in",
        )
        return numba.njit(**options)(function)
    key, why = cache_key()
    if key is None:
        _say_once(
            ("no key",),
            f"no key to sign numba's cache can be kept ({why}); compiling without a disk cache "
            "(every run compiles again): set XDG_CONFIG_HOME to a folder of your own",
        )
        return numba.njit(**options)(function)
    cache_file = dispatcher._cache._cache_file
    cache_file.__class__ = _recovering(type(cache_file))  # type: ignore[arg-type]
    return dispatcher


@functools.cache
def _recovering(base: type) -> type:
    """numba's cache file class ``base`` (its ``IndexDataCacheFile``), whose files are signed as
    they are written (:func:`signed`) and read only when their signature holds
    (:func:`verified`): a file that is unsigned, of another key or damaged is removed unread and
    the code compiles again, and whatever unpickling a signed file raises does the same."""

    class _RecoveringCacheFile(base):
        def _discard(self, path: str, why: str) -> None:
            try:
                os.remove(path)
            except OSError:
                pass
            _say_once(
                ("discarded",),  # one line, whichever files follow
                f"numba's cache file {path} was damaged or not written by stewart-drake for "
                f"you ({why}): it was removed and the code compiles again (so is any other "
                "such file, unread)",
            )

        def _payload(self, path: str) -> bytes | None:
            """The verified payload of ``path``, or None (the file discarded).

            Raises:
                OSError: the file cannot be read (missing: numba's own handling follows).
            """
            with open(path, "rb") as f:
                raw = f.read()
            payload = verified(cache_key()[0] or b"", path, raw)
            if payload is None:
                self._discard(path, "no valid signature")
            return payload

        def _load_index(self):
            try:
                payload = self._payload(self._index_path)
            except FileNotFoundError:
                return {}
            except OSError as err:
                self._discard(self._index_path, type(err).__name__)
                return {}
            if payload is None:
                return {}
            try:
                stream = io.BytesIO(payload)
                if pickle.load(stream) != self._version:  # another numba's: it is rewritten
                    return {}
                stamp, overloads = pickle.loads(stream.read())
            except DAMAGED_CACHE_ERRORS as err:
                self._discard(self._index_path, type(err).__name__)
                return {}
            return overloads if stamp == self._source_stamp else {}

        def _load_data(self, name):
            path = self._data_path(name)
            payload = self._payload(path)  # an OSError: numba's load() returns None
            if payload is None:
                return None
            try:
                return pickle.loads(payload)
            except DAMAGED_CACHE_ERRORS as err:
                self._discard(path, type(err).__name__)
                return None

        def _save_index(self, overloads):
            payload = pickle.dumps(self._version, protocol=-1)
            self._write_signed(
                self._index_path, payload + self._dump((self._source_stamp, overloads))
            )

        def _save_data(self, name, data):
            self._write_signed(self._data_path(name), self._dump(data))

        def _write_signed(self, path: str, payload: bytes) -> None:
            with self._open_for_write(path) as f:
                f.write(signed(cache_key()[0] or b"", path, payload))

    _RecoveringCacheFile.__name__ = _RecoveringCacheFile.__qualname__ = "_RecoveringCacheFile"
    return _RecoveringCacheFile


def _python_of(value, jit_off: bool):
    """The Python a kernel was compiled from (numba's ``py_func``); with ``NUMBA_DISABLE_JIT``
    the marked function itself (with the JIT on, a marked plain function is one compiled under
    another name, ``ik_compiled = _njit(ik_scalar)``, and not a kernel of its own); None for
    anything else. ``jit_off``: numba's ``config.DISABLE_JIT``, read once by the caller."""
    f = getattr(value, "py_func", None)
    if callable(f):
        return f
    marked = callable(value) and getattr(value, KERNEL_MARK, False)
    return value if marked and jit_off else None


def interpreted(namespace: dict) -> types.SimpleNamespace:
    """The compiled functions of a module's ``namespace`` (its ``globals()``) as the Python they
    were compiled from: each one's numba ``py_func``, run with the module's other compiled
    functions as theirs too, so that nothing it calls is compiled. The compiled and the
    interpreted form are the same code by construction (``f.__code__ is
    compiled.py_func.__code__``); a test holds their results equal. A function taken from
    another module (an ``ik_scalar`` compiled here) is its own ``py_func`` as it is. With
    ``NUMBA_DISABLE_JIT`` nothing is compiled: the functions :func:`njit_cached` marked are
    taken as they are (so a comparison of the two forms runs, on the same Python twice).

    Returns:
        a namespace with one attribute per compiled function, of the same name.
    """
    plain = dict(namespace)
    import numba

    jit_off = bool(getattr(numba.config, "DISABLE_JIT", False))
    compiled = {k: f for k, v in namespace.items() if (f := _python_of(v, jit_off)) is not None}
    for name, f in compiled.items():
        plain[name] = (
            types.FunctionType(f.__code__, plain, f.__name__, f.__defaults__, f.__closure__)
            if f.__globals__ is namespace
            else f
        )
    return types.SimpleNamespace(**{name: plain[name] for name in compiled})


def kernel_versions(package: str = _PACKAGE) -> dict[str, int]:
    """{``module.function``: how many versions numba holds} of every compiled function of the
    loaded modules of ``package``. numba keeps one machine-code version a function per
    argument type (a read-only array is another type), compiled or loaded from the cache the
    first time it meets that type: what a warm-up did not meet, a control period pays for.
    Read before a loop starts and after it (:func:`versions_added`)."""
    counts: dict[str, int] = {}
    for name, module in list(sys.modules.items()):
        if module is None or not (name == package or name.startswith(package + ".")):
            continue
        for attribute, value in list(vars(module).items()):
            py_func = getattr(value, "py_func", None)
            signatures = getattr(value, "signatures", None)
            if py_func is None or signatures is None or py_func.__module__ != name:
                continue
            counts[f"{name}.{attribute}"] = len(signatures)
    return counts


def versions_added(before: dict[str, int], after: dict[str, int] | None = None) -> list[str]:
    """The compiled functions of ``after`` (default :func:`kernel_versions` now) that hold more
    versions than in ``before`` (or are new), sorted by name: what was compiled or loaded
    between the two readings."""
    after = kernel_versions() if after is None else after
    return sorted(name for name, n in after.items() if n > before.get(name, 0))
