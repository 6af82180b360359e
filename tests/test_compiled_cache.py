"""numba's disk cache as another user, a downloaded tree or a damaged disk leaves it: a cache
folder others may write in is never loaded from (its planted pickles never run), a file this
user's stewart-drake did not sign is never unpickled (a pickle planted in a private folder never
runs), a damaged entry (cut short, random bytes) is discarded and compiled again; each said in
one line, the command's results unchanged, and the entries it wrote loaded by the next run
without compiling. Through the command (`check`, whose reference validator is compiled), each
with a cache folder of its own and the key in a configuration folder of the suite's."""

import os
import pickle
import random
import shutil
import subprocess
import sys
from pathlib import Path

import numba
import pytest
from conftest import HANG_S

pytestmark = pytest.mark.system

_SCRIPT = Path(sys.executable).with_name("stewart-drake")


def _check(cache: Path, out: Path, config: Path) -> subprocess.CompletedProcess:
    """``stewart-drake check paper`` with numba's cache in ``cache`` and the key that signs it
    in ``config`` (the user's configuration folder); a hang fails it."""
    env = {**os.environ, "NUMBA_CACHE_DIR": str(cache), "XDG_CONFIG_HOME": str(config)}
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
    """A private cache folder filled by one run of `check`, that run, and the configuration
    folder holding the key that signed it."""
    cache, config = tmp_path_factory.mktemp("cache"), tmp_path_factory.mktemp("config")
    os.chmod(cache, 0o700)
    first = _check(cache, tmp_path_factory.mktemp("out"), config)
    assert first.returncode == 0, first.stderr
    assert list(cache.rglob("*.nbi")) and list(cache.rglob("*.nbc"))
    key = config / "stewart-drake" / "numba-cache.key"
    assert key.stat().st_size == 32 and oct(key.stat().st_mode & 0o777) == oct(0o600)
    return cache, first, config


def _private_copy(warm, tmp_path) -> Path:
    """A copy of the warm cache in a private folder of the test's own."""
    cache = tmp_path / "cache"
    shutil.copytree(warm[0], cache)
    os.chmod(cache, 0o700)
    return cache


def _entries(cache: Path) -> dict:
    """{cache file: (inode, mtime)}: a file numba wrote again shows as changed."""
    return {p: (p.stat().st_ino, p.stat().st_mtime_ns) for p in sorted(cache.rglob("*.nb[ic]"))}


def test_a_cache_folder_others_may_write_in_is_never_loaded_from(warm, tmp_path):
    cache, first, config = warm
    planted = tmp_path / "planted"
    planted.mkdir()
    for index in cache.rglob("*.nbi"):  # every entry the command will look for, planted
        target = planted / index.relative_to(cache)
        target.parent.mkdir(parents=True, exist_ok=True)
        with open(target, "wb") as f:
            pickle.dump(numba.__version__, f)  # numba reads the rest only for its own version
            f.write(pickle.dumps(_Payload(tmp_path / "payload_ran")))
    os.chmod(planted, 0o777)  # a folder of the shared temporary directory, made by another
    run = _check(planted, tmp_path / "out", config)
    assert not (tmp_path / "payload_ran").exists()
    assert run.returncode == 0, run.stderr
    said = [line for line in run.stderr.splitlines() if "not safe to load" in line]
    assert len(said) == 1 and f"others may write in {planted} (mode 777)" in said[0], run.stderr
    assert "set NUMBA_CACHE_DIR to a folder of your own" in said[0]
    assert _figures(run) == _figures(first)


def test_a_damaged_cache_is_discarded_and_compiled_again(warm, tmp_path):
    first, config = warm[1], warm[2]
    cache = _private_copy(warm, tmp_path)
    for entry in sorted(cache.rglob("*.nb[ic]")):  # a write cut short: half of each file
        data = entry.read_bytes()
        entry.write_bytes(data[: len(data) // 2])
    run = _check(cache, tmp_path / "out", config)
    assert run.returncode == 0, run.stderr
    assert "Traceback" not in run.stderr
    damaged = [line for line in run.stderr.splitlines() if "was damaged" in line]
    assert len(damaged) == 1 and "it was removed and the code compiles again" in damaged[0]
    assert _figures(run) == _figures(first)
    written = _entries(cache)
    again = _check(cache, tmp_path / "again", config)  # the entries written anew load cleanly
    assert again.returncode == 0 and "damaged" not in again.stderr, again.stderr
    assert _figures(again) == _figures(first)
    assert _entries(cache) == written  # loaded, not compiled and written again


@pytest.mark.parametrize("seeds", [(5, 15, 20)])
def test_random_bytes_in_every_cache_file_are_discarded(warm, tmp_path, seeds):
    """Random bytes in each index and data file (numba's own reader raised OverflowError on
    one, as a traceback): one line, the same figures, for each seed."""
    first, config = warm[1], warm[2]
    for seed in seeds:
        cache = _private_copy(warm, tmp_path / str(seed))
        draw = random.Random(seed)
        for entry in sorted(cache.rglob("*.nb[ic]")):
            entry.write_bytes(draw.randbytes(entry.stat().st_size))
        run = _check(cache, tmp_path / str(seed) / "out", config)
        assert run.returncode == 0 and "Traceback" not in run.stderr, (seed, run.stderr)
        said = [line for line in run.stderr.splitlines() if "was damaged" in line]
        assert len(said) == 1, (seed, run.stderr)
        assert _figures(run) == _figures(first)


def test_a_pickle_planted_in_a_private_cache_never_runs(warm, tmp_path):
    """A cache folder of the user's own (a __pycache__ that came in a downloaded tree) whose
    every index and data file is a pickle that would create a file: none is unpickled, one
    line says so, the figures are the same; the entries written instead are signed and load on
    the next run without compiling."""
    first, config = warm[1], warm[2]
    cache = _private_copy(warm, tmp_path)
    marker = tmp_path / "payload_ran"
    for entry in cache.rglob("*.nb[ic]"):
        payload = pickle.dumps(_Payload(marker))
        if entry.suffix == ".nbi":  # numba's index: its version, then the rest
            payload = pickle.dumps(numba.__version__) + payload
        entry.write_bytes(payload)
    run = _check(cache, tmp_path / "out", config)
    assert not marker.exists()
    assert run.returncode == 0 and "Traceback" not in run.stderr, run.stderr
    said = [line for line in run.stderr.splitlines() if "stewart-drake: numba" in line]
    assert len(said) == 1 and "not written by stewart-drake for you (no valid signature)" in said[0]
    assert _figures(run) == _figures(first)
    written = _entries(cache)
    again = _check(cache, tmp_path / "again", config)
    assert again.returncode == 0 and "numba" not in again.stderr, again.stderr
    assert _entries(cache) == written and not marker.exists()
    assert _figures(again) == _figures(first)


def test_an_unsigned_index_is_never_unpickled_to_say_whether_the_step_compiles(tmp_path):
    """The compile note reads numba's index before numba does: a planted one is not run."""
    from stewart_drake.control import kernel_cache

    marker = tmp_path / "payload_ran"
    index = tmp_path / "step.step-1.py311.nbi"
    index.write_bytes(pickle.dumps(numba.__version__) + pickle.dumps(_Payload(marker)))
    assert kernel_cache._valid_index(str(index), (), ("cpu", "")) is False
    assert not marker.exists()


@pytest.mark.parametrize("seed", [0, 43, 45, 102, 802])
def test_whatever_unpickling_a_signed_file_raises_is_a_discard(tmp_path, seed, capsys, monkeypatch):
    """Random payloads, signed as if this tool had written them: pickle raises
    UnpicklingError, OverflowError, ValueError, UnicodeDecodeError or MemoryError (seeds 0, 43,
    45, 102, 802); each is discarded, said once, never raised."""
    from numba.core.caching import IndexDataCacheFile

    from stewart_drake.base import compiled

    monkeypatch.setattr(compiled, "_SAID", set())
    key = compiled.cache_key()[0]
    assert key is not None
    files = compiled._recovering(IndexDataCacheFile)(str(tmp_path), "f-1.py311", "stamp")
    junk = random.Random(seed).randbytes(2000)
    index, data = Path(files._index_path), Path(files._data_path(files._data_name(1)))
    index.write_bytes(compiled.signed(key, str(index), pickle.dumps(numba.__version__) + junk))
    data.write_bytes(compiled.signed(key, str(data), junk))
    assert files._load_index() == {} and files._load_data(data.name) is None
    assert not index.exists() and not data.exists()
    said = capsys.readouterr().err.strip().splitlines()
    assert len(said) == 1 and "was damaged" in said[0], said


def test_the_key_is_the_user_s_alone(tmp_path):
    """Made on first use, mode 0600, whole; refused when others may read it or it is a link."""
    from stewart_drake.base import compiled

    folder = tmp_path / "config" / "stewart-drake"
    key = compiled._make_key(str(folder))
    path = folder / "numba-cache.key"
    assert len(key) == 32 and path.read_bytes() == key
    assert oct(path.stat().st_mode & 0o777) == oct(0o600)
    assert compiled._make_key(str(folder)) == key  # kept, not made again
    os.chmod(path, 0o644)
    with pytest.raises(ValueError, match="others may read or write"):
        compiled._make_key(str(folder))
    os.chmod(path, 0o600)
    (tmp_path / "elsewhere").symlink_to(path)
    with pytest.raises(OSError):
        compiled._read_key(str(tmp_path / "elsewhere"))
    os.chmod(folder, 0o777)
    with pytest.raises(ValueError, match="others may write in"):
        compiled._make_key(str(folder))


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
