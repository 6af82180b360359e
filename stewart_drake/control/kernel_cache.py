"""numba's disk cache for the LQI's compiled code: how the kernels are compiled
(:func:`njit_cached`), their uncompiled form (:func:`interpreted`), and whether importing
:mod:`.lqi.kernels` will compile, decided from the cache without importing it (importing it is
what compiles).

numba keeps one index file per compiled function, ``<module>.<function>-<line>.py<XY>.nbi``, in
the first cache folder it can write: ``NUMBA_CACHE_DIR`` (a sub-folder per source folder), else
``__pycache__`` beside the source, else the user's cache folder, else (:func:`njit_cached` sets
it) a folder in the temporary directory. An index is valid when numba's version wrote it, its
stamp is the digest of the source file as it is now, and it holds an entry compiled for this
machine's CPU. The same cache is bypassed when the sources the kernels freeze in have changed
(:func:`sources_digest`). This module imports numba only when a function here needs it.
"""

from __future__ import annotations

import glob
import hashlib
import inspect
import os
import pickle
import sys
import tempfile
import types
from pathlib import Path
from typing import Any

#: The kernels' module files (in :mod:`.lqi`), with the functions :func:`.lqi.kernels.warm_up`
#: calls in each; the others are compiled into them.
ENTRY_POINTS = {"step.py": ("step", "act", "filter_rate"), "reschedule.py": ("warm_gain",)}
KERNEL_FILES = tuple(Path(__file__).with_name("lqi") / name for name in ENTRY_POINTS)

#: :func:`sources_digest` of the sources the kernels were last compiled against.
DEPENDENCIES_DIGEST = "f781ee6ad8def75f"


def sources_digest() -> str:
    """SHA-256 (16 hex digits) of what the compiled code takes from other files: the source of
    :func:`~stewart_drake.robot.kinematics.ik_scalar` and all of :mod:`.lqi.layout` (the index
    constants, which numba freezes into the machine code). numba's cache notices a change of a
    kernels' file itself (:data:`KERNEL_FILES`) only, so the cache is used only while this digest
    is :data:`DEPENDENCIES_DIGEST` (a test holds them equal: change one, update the other)."""
    from ..robot.kinematics import ik_scalar
    from .lqi import layout

    digest = hashlib.sha256(inspect.getsource(ik_scalar).encode())
    digest.update(Path(layout.__file__).read_bytes())
    return digest.hexdigest()[:16]


def use_cache() -> bool:
    """Whether the kernels may use numba's disk cache (:data:`DEPENDENCIES_DIGEST` holds)."""
    try:
        return sources_digest() == DEPENDENCIES_DIGEST
    except (OSError, TypeError):  # sources not shipped: compile every time
        return False


def fallback_cache_dir() -> str:
    """A per-user folder in the temporary directory for numba's cache."""
    user = os.environ.get("USER") or str(os.getuid() if hasattr(os, "getuid") else "user")
    return os.path.join(tempfile.gettempdir(), f"stewart-drake-numba-cache-{user}")


def njit_cached(function, cache: bool = True):
    """``numba.njit(cache=True)(function)``, with the cache where numba can write; without the
    cache when ``cache`` is false (:func:`use_cache`, which a kernels' module asks once).

    numba refuses to cache (RuntimeError at decoration) when neither ``NUMBA_CACHE_DIR``, the
    source's ``__pycache__`` nor the user's cache folder is writable: the cache then goes to
    :func:`fallback_cache_dir`, and if even that fails the function compiles in every process.
    """
    import numba

    if not cache:
        return numba.njit(function)
    try:
        return numba.njit(cache=True)(function)
    except RuntimeError:
        pass
    config: Any = numba.config  # its settings are module attributes numba sets at import
    if not config.CACHE_DIR:
        config.CACHE_DIR = fallback_cache_dir()
        try:
            return numba.njit(cache=True)(function)
        except RuntimeError:
            config.CACHE_DIR = ""
    return numba.njit(function)


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


def _usable(folder: str) -> bool:
    """Whether numba could use ``folder`` for its cache: it, or the nearest folder above it that
    exists, is writable (numba creates the rest)."""
    path = Path(folder)
    while not path.exists() and path.parent != path:
        path = path.parent
    return path.is_dir() and os.access(path, os.W_OK | os.X_OK)


def cache_folder(source: Path = KERNEL_FILES[0]) -> str | None:
    """The folder numba caches ``source``'s functions in, by its own order of choice (None: none
    is writable, and every process compiles)."""
    import numba
    from numba.core.caching import _CacheLocator

    def sub(root: str) -> str:
        return os.path.join(root, _CacheLocator.get_suitable_cache_subpath(str(source)))

    chosen = getattr(numba.config, "CACHE_DIR", "")  # NUMBA_CACHE_DIR, or njit_cached's fallback
    if chosen:
        return sub(chosen)
    candidates = [str(source.parent / "__pycache__")]
    try:
        from numba.misc.appdirs import AppDirs

        candidates.append(sub(AppDirs(appname="numba", appauthor=False).user_cache_dir))
    except ImportError:  # another numba layout: the fallback below still applies
        pass
    candidates.append(sub(fallback_cache_dir()))
    return next((c for c in candidates if _usable(c)), None)


def _host_cpu() -> tuple[str, str]:
    """The CPU name and features numba compiles for (its codegen's ``magic_tuple``, less the
    triple)."""
    import numba
    from numba.core import codegen

    name = getattr(numba.config, "CPU_NAME", None) or codegen.ll.get_host_cpu_name()
    features = getattr(numba.config, "CPU_FEATURES", None)
    return name, features if features is not None else codegen.get_host_cpu_features()


def _valid_index(path: str, stamps: tuple, cpu: tuple[str, str]) -> bool:
    """Whether numba's index file ``path`` is this source's (its stamp one of ``stamps``), of
    this numba, and holds an entry compiled for ``cpu``."""
    import numba

    try:
        with open(path, "rb") as f:
            if pickle.load(f) != numba.__version__:
                return False
            saved, overloads = pickle.loads(f.read())
    except (OSError, EOFError, ValueError, TypeError, pickle.UnpicklingError, AttributeError):
        return False  # a damaged or foreign index: numba compiles again too
    if saved not in stamps:
        return False
    return any(tuple(key[1][1:]) == cpu for key in overloads)


def will_compile(source: Path | None = None, entries=None) -> bool:
    """Whether importing the kernels compiles them: the cache is bypassed (:func:`use_cache`),
    numba has no writable cache folder, or that folder has no valid index
    (:func:`_valid_index`) for one of the entry points.

    Args:
        source: one kernels' file (None: every file of :data:`KERNEL_FILES`).
        entries: its entry points' names (None: those :data:`ENTRY_POINTS` gives its name).

    Reads a few small files and imports numba; compiles nothing.
    """
    if not use_cache():
        return True
    sources = KERNEL_FILES if source is None else (Path(source),)
    cpu = _host_cpu()
    abi = f"py{sys.version_info[0]}{sys.version_info[1]}{getattr(sys, 'abiflags', '')}"
    for path in sources:
        folder = cache_folder(path)
        if folder is None:
            return True
        try:
            st = os.stat(path)
            # numba's stamp: the file's digest (numba >= 0.61), or its mtime and size before
            stamps = (hashlib.sha256(Path(path).read_bytes()).digest(), (st.st_mtime, st.st_size))
        except OSError:
            return True
        for name in entries if source is not None and entries else ENTRY_POINTS[path.name]:
            pattern = os.path.join(glob.escape(folder), f"{path.stem}.{name}-*.{abi}.nbi")
            if not any(_valid_index(p, stamps, cpu) for p in glob.glob(pattern)):
                return True
    return False
