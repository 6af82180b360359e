"""numba's disk cache as another user or a damaged disk leaves it: a cache folder others may write
in is never loaded from (its planted pickles never run), a damaged entry is discarded and
compiled again; both said in one line, the command's results unchanged. Through the command
(`check`, whose reference validator is compiled), each with a cache folder of its own."""

import os
import pickle
import subprocess
import sys
from pathlib import Path

import numba
import pytest
from conftest import HANG_S

pytestmark = pytest.mark.system

_SCRIPT = Path(sys.executable).with_name("stewart-drake")


def _check(cache: Path, out: Path) -> subprocess.CompletedProcess:
    """``stewart-drake check paper`` with numba's cache in ``cache``; a hang fails it."""
    env = {**os.environ, "NUMBA_CACHE_DIR": str(cache)}
    return subprocess.run(
        [str(_SCRIPT), "check", "paper", "--out", str(out)],
        env=env,
        capture_output=True,
        text=True,
        timeout=HANG_S,
    )


def _figures(run: subprocess.CompletedProcess) -> list:
    """The check's report, less the line naming its figure's file."""
    return [line for line in run.stdout.splitlines() if not line.startswith("wrote ")]


class _Payload:
    """A pickle that, loaded, creates a file: what a planted cache entry could do."""

    def __init__(self, marker: Path):
        self.marker = marker

    def __reduce__(self):
        return (Path.touch, (self.marker,))


@pytest.fixture(scope="module")
def warm(tmp_path_factory):
    """A private cache folder filled by one run of `check`, and that run."""
    cache = tmp_path_factory.mktemp("cache")
    os.chmod(cache, 0o700)
    first = _check(cache, tmp_path_factory.mktemp("out"))
    assert first.returncode == 0, first.stderr
    assert list(cache.rglob("*.nbi")) and list(cache.rglob("*.nbc"))
    return cache, first


def test_a_cache_folder_others_may_write_in_is_never_loaded_from(warm, tmp_path):
    cache, first = warm
    planted = tmp_path / "planted"
    planted.mkdir()
    for index in cache.rglob("*.nbi"):  # every entry the command will look for, planted
        target = planted / index.relative_to(cache)
        target.parent.mkdir(parents=True, exist_ok=True)
        with open(target, "wb") as f:
            pickle.dump(numba.__version__, f)  # numba reads the rest only for its own version
            f.write(pickle.dumps(_Payload(tmp_path / "payload_ran")))
    os.chmod(planted, 0o777)  # a folder of the shared temporary directory, made by another
    run = _check(planted, tmp_path / "out")
    assert not (tmp_path / "payload_ran").exists()
    assert run.returncode == 0, run.stderr
    said = [line for line in run.stderr.splitlines() if "not safe to load" in line]
    assert len(said) == 1 and f"others may write in {planted} (mode 777)" in said[0], run.stderr
    assert "set NUMBA_CACHE_DIR to a folder of your own" in said[0]
    assert _figures(run) == _figures(first)


def test_a_damaged_cache_is_discarded_and_compiled_again(warm, tmp_path):
    cache, first = warm
    for entry in sorted(cache.rglob("*.nb[ic]")):  # a write cut short: half of each file
        data = entry.read_bytes()
        entry.write_bytes(data[: len(data) // 2])
    run = _check(cache, tmp_path / "out")
    assert run.returncode == 0, run.stderr
    assert "Traceback" not in run.stderr
    damaged = [line for line in run.stderr.splitlines() if "was damaged" in line]
    assert damaged and all("it was removed and the code compiles again" in d for d in damaged)
    assert _figures(run) == _figures(first)
    again = _check(cache, tmp_path / "again")  # the entries written anew load cleanly
    assert again.returncode == 0 and "damaged" not in again.stderr, again.stderr
    assert _figures(again) == _figures(first)


def test_the_fallback_folder_is_made_private_and_refused_when_another_made_it(
    tmp_path, monkeypatch
):
    """Where neither the source tree nor the user's cache folder can be written, the cache goes
    to the temporary directory: made there for this user alone, refused where someone made the
    name first (any mode others may write in, or a link)."""
    from stewart_drake.base import compiled

    monkeypatch.setattr("tempfile.tempdir", str(tmp_path))
    fallback = compiled.fallback_cache_dir()
    assert Path(fallback).parent == tmp_path
    compiled._private_folder(fallback)
    assert compiled.cache_folder_problem(fallback, fallback) is None
    assert oct(os.stat(fallback).st_mode & 0o777) == oct(0o700 & ~_umask())
    os.chmod(fallback, 0o777)
    assert compiled.cache_folder_problem(fallback, fallback) == (
        f"others may write in {fallback} (mode 777)"
    )
    os.rmdir(fallback)
    os.symlink(tmp_path, fallback)  # another user's link to a folder that seems fine
    assert compiled.cache_folder_problem(fallback, fallback) == f"{fallback} is a symbolic link"
    chosen = tmp_path / "chosen"  # NUMBA_CACHE_DIR may be the user's own link
    chosen.symlink_to(tmp_path)
    assert compiled.cache_folder_problem(chosen / "robot_x", chosen) == (
        f"{chosen / 'robot_x'} cannot be examined (No such file or directory)"
    )
    (tmp_path / "robot_x").mkdir(mode=0o700)
    assert compiled.cache_folder_problem(chosen / "robot_x", chosen) is None


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask
