"""numba's disk cache for the LQI's compiled code: how the kernels are compiled
(:func:`njit_cached`) and their uncompiled form (:func:`interpreted`), both of
:mod:`stewart_drake.base.compiled`, and whether importing :mod:`.lqi.kernels` will compile,
decided from the cache without importing it (importing it is what compiles).

numba keeps one index file per compiled function, ``<module>.<function>-<line>.py<XY>.nbi``, in
the first cache folder it can write: ``NUMBA_CACHE_DIR`` (a sub-folder per source folder), else
``__pycache__`` beside the source, else the user's cache folder, else (:func:`njit_cached` sets
it) a folder in the temporary directory. An index is valid when this user's stewart-drake signed
it (:mod:`stewart_drake.base.compiled`), numba's version wrote it, its stamp is the digest of the
source file as it is now, and it holds an entry compiled for this machine's CPU. The same cache
is bypassed when the sources the kernels freeze in have changed (:func:`sources_digest`). This
module imports numba only when a function here needs it.
"""

from __future__ import annotations

import glob
import hashlib
import inspect
import os
import sys
from pathlib import Path

# How the kernels are compiled, and their uncompiled form: the package's one convention, in base
# (the robot's validator compiles its kernels the same way), named here for the LQI's modules.
from ..base.compiled import cache_folder_problem, load_signed_index
from ..base.compiled import fallback_cache_dir as fallback_cache_dir
from ..base.compiled import interpreted as interpreted
from ..base.compiled import njit_cached as njit_cached

#: The kernels' module files (in :mod:`.lqi`), with the functions :func:`.lqi.kernels.warm_up`
#: calls in each; the others are compiled into them.
ENTRY_POINTS = {
    "step.py": ("step", "act", "filter_rate", "newton"),
    "reschedule.py": ("warm_gain",),
}
KERNEL_FILES = tuple(Path(__file__).with_name("lqi") / name for name in ENTRY_POINTS)

#: :func:`sources_digest` of the sources the kernels were last compiled against.
DEPENDENCIES_DIGEST = "62c1a9208b30027f"


def sources_digest() -> str:
    """SHA-256 (16 hex digits) of what the compiled code takes from other files: the source of
    :func:`~stewart_drake.robot.single_pose.ik_scalar`, all of :mod:`.lqi.layout` (the index
    constants, which numba freezes into the machine code) and all of
    :mod:`~stewart_drake.robot.path_kernels` (:func:`~stewart_drake.robot.path_kernels.lu_solve6`,
    :func:`~stewart_drake.robot.path_kernels.fk_newton`). numba's cache notices a change of a
    kernels' file itself (:data:`KERNEL_FILES`) only, so the cache is used only while this digest
    is :data:`DEPENDENCIES_DIGEST` (a test holds them equal: change one, update the other)."""
    from ..robot import path_kernels
    from ..robot.single_pose import ik_scalar
    from .lqi import layout

    digest = hashlib.sha256(inspect.getsource(ik_scalar).encode())
    digest.update(Path(layout.__file__).read_bytes())
    digest.update(Path(path_kernels.__file__).read_bytes())
    return digest.hexdigest()[:16]


def use_cache() -> bool:
    """Whether the kernels may use numba's disk cache (:data:`DEPENDENCIES_DIGEST` holds)."""
    try:
        return sources_digest() == DEPENDENCIES_DIGEST
    except (OSError, TypeError):  # sources not shipped: compile every time
        return False


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
    """Whether numba's index file ``path`` is one this user's stewart-drake signed
    (:func:`~stewart_drake.base.compiled.load_signed_index`: nothing is unpickled before), of
    this numba, this source's (its stamp one of ``stamps``), and holds an entry compiled for
    ``cpu``."""
    import numba

    index = load_signed_index(path)
    if index is None:
        return False  # missing, unsigned or damaged: numba compiles again too
    version, saved, overloads = index
    if version != numba.__version__ or saved not in stamps:
        return False
    return any(tuple(key[1][1:]) == cpu for key in overloads)


def will_compile(source: Path | None = None, entries=None) -> bool:
    """Whether importing the kernels compiles them: the cache is bypassed (:func:`use_cache`),
    numba has no writable cache folder or none safe to load from
    (:func:`~stewart_drake.base.compiled.cache_folder_problem`), or that folder has no valid index
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
    import numba

    for path in sources:
        folder = cache_folder(path)
        # an index is a pickle: read only from a folder that is safe to load from
        chosen = getattr(numba.config, "CACHE_DIR", "")
        if folder is None or cache_folder_problem(folder, chosen or None):
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
