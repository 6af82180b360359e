"""Result files written atomically: a reader never sees a half-written file, even after Ctrl-C."""

from __future__ import annotations

import os
import tempfile
from pathlib import Path

import numpy as np


def atomic_write(path: Path, write) -> None:
    """Call write(binary file) on a temporary file next to ``path``, then os.replace it."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
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


def save_npz(path: Path, arrays: dict) -> Path:
    """``np.savez_compressed`` of ``arrays`` into ``path``, atomically; returns the path."""
    atomic_write(path, lambda f: np.savez_compressed(f, **arrays))
    return Path(path)
