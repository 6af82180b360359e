"""fileio.py: results written atomically, files read back whole or refused with one typed error
naming the file (special files and hostile archives: test_untrusted_input.py)."""

import os
import subprocess
import sys

import numpy as np
import pytest

from stewart_drake.base.errors import CorruptFileError
from stewart_drake.base.fileio import (
    _writer,
    atomic_write,
    read_json,
    remove_stale_temporaries,
    save_npz,
)
from stewart_drake.base.npz import CheckedNpz


def test_a_writer_that_raises_leaves_the_old_file_and_no_temporary(tmp_path):
    path = tmp_path / "result.json"
    atomic_write(path, lambda f: f.write(b'{"old": 1}'))

    def half_then_fail(f):
        f.write(b'{"new": ')
        raise KeyboardInterrupt  # Ctrl-C mid-write

    with pytest.raises(KeyboardInterrupt):
        atomic_write(path, half_then_fail)
    assert path.read_bytes() == b'{"old": 1}'
    assert sorted(p.name for p in tmp_path.iterdir()) == ["result.json"]
    atomic_write(path, lambda f: f.write(b'{"new": 2}'))
    assert read_json(path, "result") == {"new": 2}


def test_the_written_file_has_the_usual_mode_not_mkstemp_s(tmp_path):
    umask = os.umask(0o022)
    try:
        atomic_write(tmp_path / "a.txt", lambda f: f.write(b"x"))
    finally:
        os.umask(umask)
    assert (tmp_path / "a.txt").stat().st_mode & 0o777 == 0o644


def test_an_os_error_of_the_write_names_the_output_not_the_temporary(tmp_path):
    def full_disk(f):
        raise OSError(28, "No space left on device")

    with pytest.raises(OSError) as info:
        atomic_write(tmp_path / "out.npz", full_disk)
    assert info.value.filename == str(tmp_path / "out.npz") and info.value.errno == 28
    assert list(tmp_path.iterdir()) == []


def test_stale_temporaries_of_a_dead_writer_go_and_nothing_else(tmp_path):
    dead = subprocess.run(
        [sys.executable, "-c", "import os; print(os.getpid())"],
        capture_output=True,
        text=True,
        check=True,
    ).stdout.strip()
    host = _writer().rsplit("-", 1)[0]
    stale = tmp_path / f".run.npz.{host}-{dead}.abcd1234.tmp"
    live = tmp_path / f".run.npz.{host}-{os.getpid()}.abcd1234.tmp"
    other_host = tmp_path / f".run.npz.elsewhere{host}-{dead}.abcd1234.tmp"
    users = tmp_path / ".notes.tmp"
    for p in (stale, live, other_host, users):
        p.write_bytes(b"x")
    assert remove_stale_temporaries(tmp_path) == [stale]
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(
        p.name for p in (live, other_host, users)
    )
    assert remove_stale_temporaries(tmp_path / "absent") == []


def test_an_npz_round_trip_through_the_typed_accessors(tmp_path):
    path = save_npz(
        tmp_path / "w.npz",
        {
            "W": np.arange(6.0).reshape(2, 3),
            "n": np.array(7),
            "name": np.array("paper"),
            "meta": np.array('{"a": 1}'),
        },
    )
    npz = CheckedNpz(path, "weights file", remedy="train again")
    np.testing.assert_array_equal(npz.array("W"), [[0, 1, 2], [3, 4, 5]])
    assert npz.integer("n") == 7 and npz.number("n") == 7.0 and "W" in npz and "x" not in npz
    assert npz.text("name") == "paper" and npz.json("meta") == {"a": 1}
    with pytest.raises(
        CorruptFileError,
        match=r"w.npz is not a valid weights file: the entry "
        r"'x' is missing; train again$",
    ):
        npz.array("x")
    with pytest.raises(CorruptFileError, match="'W' must be one number, has shape"):
        npz.number("W")
    with pytest.raises(CorruptFileError, match="'name' holds <U5 values, not numbers"):
        npz.array("name")
    with pytest.raises(CorruptFileError, match="'meta' must be a JSON list, got dict"):
        npz.json("meta", list)


@pytest.mark.parametrize(
    "data, problem",
    [
        (b"", "it is empty"),
        (b"  \n", "it is empty"),
        (b'{"a": [1, 2', "not JSON"),
        (b"\xff\xfe{}", "not JSON"),
    ],
)
def test_a_damaged_json_is_one_typed_error_naming_the_file(tmp_path, data, problem):
    path = tmp_path / "rows.json"
    path.write_bytes(data)
    with pytest.raises(CorruptFileError, match=problem) as info:
        read_json(path, "rows file")
    assert info.value.path == str(path) and info.value.kind == "rows file"
