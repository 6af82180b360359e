"""numba's disk cache for the package's compiled code: how a kernel is compiled
(:func:`njit_cached`) and its uncompiled form (:func:`interpreted`).

The LQI's control step (:mod:`stewart_drake.control.lqi`, whose cache
:mod:`stewart_drake.control.kernel_cache` also inspects) and the reference validator's per-pose
arithmetic (:mod:`stewart_drake.robot.path_kernels`) are compiled this way. numba keeps one
index file per compiled function in the first cache folder it can write: ``NUMBA_CACHE_DIR``,
else ``__pycache__`` beside the source, else the user's cache folder, else (:func:`njit_cached`
sets it) a folder in the temporary directory, made private to the user.

numba's index and data files are pickles, and unpickling runs whatever a pickle names: a cache
folder another user can write in (a folder of the shared temporary directory planted before
ours, a ``__pycache__`` open to all) would let them run code as this user. So the folder is used
only when it is this user's own and no one else may write in it (:func:`cache_folder_problem`);
else the code compiles in every process, and says so once. A damaged entry (a truncated write,
a full disk) is discarded and compiled again, and said once, instead of failing every later
run. This module imports numba only when a function here needs
it.

A compilation is seconds to a minute that shows nothing else: while a command runs
(:func:`announce_compiles`), the first compilation of each module's kernels is said in one line
before it starts (the LQI's step says so itself before its import,
:func:`~stewart_drake.execution.options.say_if_compiling`).
"""

from __future__ import annotations

import contextlib
import functools
import os
import pickle
import stat
import sys
import tempfile
import types
from collections.abc import Callable, Iterator
from typing import Any

#: What a damaged numba cache file raises when read (pickle's errors, a truncated stream, a
#: payload naming what no longer exists).
DAMAGED_CACHE_ERRORS = (
    pickle.UnpicklingError,
    EOFError,
    ValueError,
    TypeError,
    AttributeError,
    ImportError,
    IndexError,
    KeyError,
    MemoryError,
)
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
    """
    import numba

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
    cache_file = dispatcher._cache._cache_file
    cache_file.__class__ = _recovering(type(cache_file))  # type: ignore[arg-type]
    return dispatcher


@functools.cache
def _recovering(base: type) -> type:
    """numba's cache file class ``base`` (its ``IndexDataCacheFile``), whose reads discard a
    damaged index or data file and compile again instead of raising."""

    class _RecoveringCacheFile(base):
        def _discard(self, path: str, err: BaseException) -> None:
            try:
                os.remove(path)
            except OSError:
                pass
            _say_once(
                ("damaged", path),
                f"numba's cache file {path} was damaged ({type(err).__name__}); it was removed "
                "and the code compiles again",
            )

        def _load_index(self):
            try:
                return super()._load_index()
            except DAMAGED_CACHE_ERRORS as err:
                self._discard(self._index_path, err)
                return {}

        def _load_data(self, name):
            try:
                return super()._load_data(name)
            except DAMAGED_CACHE_ERRORS as err:
                self._discard(self._data_path(name), err)
                return None

    _RecoveringCacheFile.__name__ = _RecoveringCacheFile.__qualname__ = "_RecoveringCacheFile"
    return _RecoveringCacheFile


def interpreted(namespace: dict) -> types.SimpleNamespace:
    """The compiled functions of a module's ``namespace`` (its ``globals()``) as the Python they
    were compiled from: each one's numba ``py_func``, run with the module's other compiled
    functions as theirs too, so that nothing it calls is compiled. The compiled and the
    interpreted form are the same code by construction (``f.__code__ is
    compiled.py_func.__code__``); a test holds their results equal. A function taken from
    another module (an ``ik_scalar`` compiled here) is its own ``py_func`` as it is.

    Returns:
        a namespace with one attribute per compiled function, of the same name.
    """
    plain = dict(namespace)
    compiled = {k: v for k, v in namespace.items() if callable(getattr(v, "py_func", None))}
    for name, dispatcher in compiled.items():
        f = dispatcher.py_func
        plain[name] = (
            types.FunctionType(f.__code__, plain, f.__name__, f.__defaults__, f.__closure__)
            if f.__globals__ is namespace
            else f
        )
    return types.SimpleNamespace(**{name: plain[name] for name in compiled})
