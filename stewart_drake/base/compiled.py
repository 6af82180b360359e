"""numba's disk cache for the package's compiled code: how a kernel is compiled
(:func:`njit_cached`) and its uncompiled form (:func:`interpreted`).

The LQI's control step (:mod:`stewart_drake.control.lqi`, whose cache
:mod:`stewart_drake.control.kernel_cache` also inspects) and the reference validator's per-pose
arithmetic (:mod:`stewart_drake.robot.path_kernels`) are compiled this way. numba keeps one
index file per compiled function in the first cache folder it can write: ``NUMBA_CACHE_DIR``,
else ``__pycache__`` beside the source, else the user's cache folder, else (:func:`njit_cached`
sets it) a folder in the temporary directory. This module imports numba only when a function
here needs it.
"""

from __future__ import annotations

import os
import tempfile
import types
from typing import Any


def fallback_cache_dir() -> str:
    """A per-user folder in the temporary directory for numba's cache."""
    user = os.environ.get("USER") or str(os.getuid() if hasattr(os, "getuid") else "user")
    return os.path.join(tempfile.gettempdir(), f"stewart-drake-numba-cache-{user}")


def njit_cached(function, cache: bool = True, **options):
    """``numba.njit(cache=True, **options)(function)``, with the cache where numba can write;
    without the cache when ``cache`` is false (the LQI's kernels ask
    :func:`~stewart_drake.control.kernel_cache.use_cache` once). ``options``: numba's own
    (``error_model="numpy"``: a division by zero gives inf or NaN, as numpy's, not an error).

    numba refuses to cache (RuntimeError at decoration) when neither ``NUMBA_CACHE_DIR``, the
    source's ``__pycache__`` nor the user's cache folder is writable: the cache then goes to
    :func:`fallback_cache_dir`, and if even that fails the function compiles in every process.
    """
    import numba

    if not cache:
        return numba.njit(**options)(function)
    try:
        return numba.njit(cache=True, **options)(function)
    except RuntimeError:
        pass
    config: Any = numba.config  # its settings are module attributes numba sets at import
    if not config.CACHE_DIR:
        config.CACHE_DIR = fallback_cache_dir()
        try:
            return numba.njit(cache=True, **options)(function)
        except RuntimeError:
            config.CACHE_DIR = ""
    return numba.njit(**options)(function)


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
