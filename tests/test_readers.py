"""Every file a user names is read through base/fileio.py (an .npz archive through base/npz.py,
on fileio's read_checked), and what that reader refuses.

The scan below lists every call in the package that opens or loads a file and fails on one
outside the checked reader (:data:`CHECKED_READER`) that is not in :data:`ALLOWED`, so the next
loader cannot go around the
checked reader (a FIFO that blocks it, a small archive that asks for terabytes, a pickle).
"""

import ast
import math
import os
import threading
import zipfile
from pathlib import Path

import numpy as np
import pytest
from conftest import HANG_S

import stewart_drake
from stewart_drake.base.errors import CorruptFileError
from stewart_drake.base.npz import CheckedNpz
from stewart_drake.control.feedforward_basis import (
    LAGS_S,
    LEARNED_FORMAT,
    basis_size,
    load_learned,
    save_learned,
)

PACKAGE = Path(stewart_drake.__file__).parent

#: Names that read a file when called, by the last part of the called name (``np.load``,
#: ``numpy.load``, ``Path(...).read_text`` ...), or by the whole dotted name where the last part
#: alone is too common (``pickle.load``).
READERS_BY_ATTRIBUTE = {
    "read_text",
    "read_bytes",
    "loadtxt",
    "genfromtxt",
    "fromfile",
    "memmap",
    "loadmat",
    "safe_load",
    "full_load",
    "unsafe_load",
    "load_all",
    "from_xml_path",
    "open",  # builtin open, os.open, io.open, Path.open, zipfile/tarfile.open ...
    "ZipFile",
    "TarFile",
}
#: Modules whose ``load``/``loads`` reads a file or unpickles (a method of our own named
#: ``load``, e.g. ``TaskSamples.load``, reads through fileio and is scanned where it is defined).
LOADER_MODULES = {
    "np",
    "numpy",
    "json",
    "pickle",
    "cloudpickle",
    "dill",
    "joblib",
    "marshal",
    "shelve",
    "torch",
    "yaml",
}
#: ``loads`` of these modules parses a string already read, not a file.
STRING_PARSERS = {"json.loads"}

#: Calls outside fileio.py that do not read a file a user names: (path under the package, the
#: enclosing function, the called name). Each says why.
ALLOWED = {
    # The machine's memory, from the kernel's own files (/proc/meminfo, the cgroup's limit).
    ("base/checks.py", "available_memory_bytes", "open"),
    # What this process maps, against its address-space limit (/proc/self/statm).
    ("base/checks.py", "_address_space_room", "open"),
    # Our own source files, hashed for numba's cache key.
    ("control/kernel_cache.py", "sources_digest", "Path(...).read_bytes"),
    ("control/kernel_cache.py", "will_compile", "Path(...).read_bytes"),
    ("robot/path_kernels.py", "source_digest", "Path(...).read_bytes"),
    # The kernel's run-queue time of the loop's own thread (/proc/thread-self/schedstat).
    ("station/bus/timing.py", "_RunQueueClock.__init__", "os.open"),
    # The kernel's PM QoS device (/dev/cpu_dma_latency): a request written and held, the
    # latency in force read back as 4 bytes.
    ("live/realtime.py", "idle_latency_in_force", "os.open"),
    ("live/realtime.py", "RealtimeLoop._ask_idle_latency", "os.open"),
    # numba's own cache files (in the package's __pycache__ or NUMBA_CACHE_DIR), unpickled only
    # once their signature by this user's key holds: as numba loads the cache, and to say
    # whether a command is about to compile. The key: a file of this user's, mode 0600.
    ("base/compiled.py", "_read_key", "os.open"),
    ("base/compiled.py", "load_signed_index", "open"),
    ("base/compiled.py", "load_signed_index", "pickle.load"),
    ("base/compiled.py", "load_signed_index", "pickle.loads"),
    ("base/compiled.py", "_recovering._RecoveringCacheFile._payload", "open"),
    ("base/compiled.py", "_recovering._RecoveringCacheFile._load_index", "pickle.load"),
    ("base/compiled.py", "_recovering._RecoveringCacheFile._load_index", "pickle.loads"),
    ("base/compiled.py", "_recovering._RecoveringCacheFile._load_data", "pickle.loads"),
    # The folder lock: a file this tool creates in its output folder (check_replaceable first),
    # of which it reads the holder's 300 characters.
    ("execution/store.py", "lock_folder", "open"),
    # A worker sends back the state file the tool itself wrote when a run diverged.
    ("execution/runners.py", "JobFailure.from_exception", "Path(...).read_bytes"),
    # A round trip of an exception through pickle, in memory: will it cross to the parent?
    ("execution/runners.py", "JobFailure.from_exception", "pickle.loads"),
    # /dev/null, to silence a stream.
    ("cli/main.py", "_silence_stdout", "os.open"),
    # The servo bus (a serial port), not a file: DynamixelBus.open.
    ("live/session.py", "_run", "bus.open"),
    ("live/session.py", "_teleop", "DynamixelBus.from_config(...).open"),
    ("live/follow.py", "_follow", "DynamixelBus.from_config(...).open"),
    ("station/bus/driver.py", "DynamixelBus.__enter__", "self.open"),
    # A QA record's files, created empty and exclusively before they are written (nothing read),
    # and the PNG verify has just written, measured for the record's page.
    ("verification/qa_record.py", "_exclusive", "os.open"),
}


def _name(node: ast.AST) -> str:
    """The dotted name of a called expression: ``np.load``, ``Path(...).read_text``."""
    if isinstance(node, ast.Name):
        return node.id
    if isinstance(node, ast.Attribute):
        return f"{_name(node.value)}.{node.attr}"
    if isinstance(node, ast.Call):
        return f"{_name(node.func)}(...)"
    return "<expr>"


def _reads(call: ast.Call) -> bool:
    name = _name(call.func)
    last = name.rsplit(".", 1)[-1]
    if name in STRING_PARSERS:
        return False
    if last in ("load", "loads"):  # a bare load() was imported from one of them
        return name in ("load", "loads") or name.split(".", 1)[0] in LOADER_MODULES
    if last in ("yaml_load", "yaml_load_typed", "yaml_load_file"):
        # Drake's YAML loaders read a file with filename=, a string with data=.
        return last == "yaml_load_file" or any(k.arg == "filename" for k in call.keywords)
    return last in READERS_BY_ATTRIBUTE


class _Finder(ast.NodeVisitor):
    def __init__(self):
        self.scope: list[str] = []
        self.found: list[tuple[str, str, int]] = []

    def _enter(self, node):
        self.scope.append(node.name)
        self.generic_visit(node)
        self.scope.pop()

    visit_FunctionDef = visit_AsyncFunctionDef = visit_ClassDef = _enter

    def visit_Call(self, node: ast.Call):
        if _reads(node):
            self.found.append((".".join(self.scope), _name(node.func), node.lineno))
        self.generic_visit(node)


#: The checked reader, the only modules that open and load the files a user names: fileio
#: (read_checked, read_json) and npz (CheckedNpz, an archive's bytes through read_checked).
CHECKED_READER = {"base/fileio.py", "base/npz.py"}


def file_reads() -> list[tuple[str, str, str, int]]:
    """(path under the package, enclosing function, called name, line) of every call that
    opens or loads a file, outside the checked reader (:data:`CHECKED_READER`)."""
    found = []
    for path in sorted(PACKAGE.rglob("*.py")):
        rel = path.relative_to(PACKAGE).as_posix()
        if rel in CHECKED_READER:
            continue
        finder = _Finder()
        finder.visit(ast.parse(path.read_text(encoding="utf-8"), filename=str(path)))
        found += [(rel, scope, name, line) for scope, name, line in finder.found]
    return found


def _allowed(rel: str, scope: str, name: str) -> bool:
    return (rel, scope, name) in ALLOWED


def test_the_scan_sees_the_loaders_it_is_meant_to_catch(tmp_path):
    """The scan itself: each way of reading a file, written in a module, is found."""
    source = (
        "import json, pickle, numpy as np, yaml\n"
        "from pathlib import Path\n"
        "from pydrake.common.yaml import yaml_load_typed\n"
        "def f(p):\n"
        "    np.load(p); open(p); Path(p).read_text(); Path(p).read_bytes()\n"
        "    json.load(p); pickle.load(p); yaml.safe_load(p); np.loadtxt(p)\n"
        "    yaml_load_typed(schema=int, filename=p)\n"
        "    json.loads('{}'); yaml_load_typed(schema=int, data='1')\n"
    )
    finder = _Finder()
    finder.visit(ast.parse(source))
    assert [name for _, name, _ in finder.found] == [
        "np.load",
        "open",
        "Path(...).read_text",
        "Path(...).read_bytes",
        "json.load",
        "pickle.load",
        "yaml.safe_load",
        "np.loadtxt",
        "yaml_load_typed",
    ]


def test_every_file_the_package_reads_goes_through_fileio():
    outside = [
        f"stewart_drake/{rel}:{line} {name} (in {scope or 'the module'})"
        for rel, scope, name, line in file_reads()
        if not _allowed(rel, scope, name)
    ]
    assert not outside, (
        "read these through stewart_drake.base.fileio (read_checked, read_json) or base.npz "
        "(CheckedNpz), or "
        "add them to ALLOWED saying why they do not read a file a user names:\n"
        + "\n".join(outside)
    )


def test_every_allowed_call_is_still_there():
    """A stale entry would let a new call of the same name through unseen."""
    present = {(rel, scope, name) for rel, scope, name, _ in file_reads()}
    assert ALLOWED <= present, ALLOWED - present


# -- what the checked reader refuses --------------------------------------------------------


def _npz_with_header(path: Path, name: str, shape, dtype="<f8", payload: bytes = b"") -> Path:
    """An .npz whose entry ``name`` has an .npy header claiming ``shape`` of ``dtype`` but holds
    only ``payload`` after it."""
    header = np.lib.format.header_data_from_array_1_0(np.zeros(0))
    header.update(shape=tuple(shape), descr=dtype)
    import io

    buffer = io.BytesIO()
    np.lib.format.write_array_header_1_0(buffer, header)
    with zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED) as archive:
        archive.writestr(f"{name}.npy", buffer.getvalue() + payload)
    return path


def test_a_small_file_whose_header_claims_terabytes_is_refused_before_numpy_allocates(tmp_path):
    path = _npz_with_header(tmp_path / "huge.npz", "theta", (10**12, 6))
    assert path.stat().st_size < 1024
    claimed = math.prod((10**12, 6)) * 8  # 43.7 TiB
    assert claimed > 40 * 2**40
    with pytest.raises(CorruptFileError) as err:  # not a MemoryError
        CheckedNpz(path, "learned feed-forward model")
    message = str(err.value)
    assert "'theta' claims shape (1000000000000, 6)" in message and "huge.npz" in message
    assert "\n" not in message


def test_a_highly_compressible_file_is_refused_by_the_bound(tmp_path):
    path = tmp_path / "zeros.npz"
    np.savez_compressed(path, theta=np.zeros((2**24 // 6, 6)))  # 128 MiB of zeros
    assert path.stat().st_size < 0.2e6  # under the learned model's bound of 1 MB on disk
    with pytest.raises(CorruptFileError, match=r"after decompression .* over the bound"):
        load_learned(path)
    # The 12 MB of deflated zeros (12 GiB inflated) is over the bound on disk already.
    big = tmp_path / "big.npz"
    with open(big, "wb") as f:
        f.truncate(12 * 2**20)
    with pytest.raises(CorruptFileError, match=r"it holds 12.6 MB, over the bound of 1 MB"):
        load_learned(big)


@pytest.mark.parametrize(
    ("dtype", "expected"),
    [("|O", "holds object values"), ("<c16", "holds complex128 values"), ("|V8", "holds |V8")],
)
def test_entries_of_objects_complex_or_raw_bytes_are_refused_from_their_header(
    tmp_path, dtype, expected
):
    path = _npz_with_header(tmp_path / "odd.npz", "a", (1,), dtype, b"\0" * 16)
    with pytest.raises(CorruptFileError, match=expected):
        CheckedNpz(path, "run result file")


def _learned(path: Path, **entries) -> Path:
    arrays = {
        "format": np.int64(LEARNED_FORMAT),
        "theta": 0.01 * np.arange(basis_size() * 6).reshape(basis_size(), 6),
        "lags_s": np.asarray(LAGS_S),
        "geometry": np.asarray("paper"),
    }
    np.savez(path, **(arrays | entries))
    return path


def test_a_learned_model_round_trips_through_the_checked_reader(tmp_path):
    theta = np.random.default_rng(3).normal(size=(basis_size(), 6))
    path = save_learned(tmp_path / "model.npz", theta)
    np.testing.assert_array_equal(load_learned(path), theta)


@pytest.mark.parametrize(
    ("entries", "expected"),
    [
        ({"theta": np.full((basis_size(), 6), "1.0")}, "'theta' holds <U3 values, not numbers"),
        ({"format": np.array([1, 1, 1])}, "'format' must be one number, has shape"),
        ({"theta": np.ones((basis_size(), 6)) * (1 + 2j)}, "'theta' holds complex128 values"),
        ({"theta": np.ones((basis_size(), 6), dtype=object)}, "holds object values"),
    ],
    ids=["string weights", "format as an array", "complex weights", "object weights"],
)
def test_load_learned_refuses_what_is_not_a_model_naming_the_file(tmp_path, entries, expected):
    path = tmp_path / "bad.npz"
    if any(np.asarray(v).dtype == object for v in entries.values()):
        np.savez(path, **entries)  # allow_pickle: what a hostile file may hold
    else:
        _learned(path, **entries)
    with pytest.raises(CorruptFileError, match=expected) as err:
        load_learned(path)
    assert str(path) in str(err.value) and "\n" not in str(err.value)


def test_a_fifo_as_learned_returns_at_once_with_one_line(tmp_path, capsys):
    from stewart_drake.cli.main import main

    fifo = tmp_path / "model.npz"
    os.mkfifo(fifo)
    result = {}
    worker = threading.Thread(
        target=lambda: result.setdefault(
            "code", main(["reproduce", "breathing", "--learned", str(fifo)])
        ),
        daemon=True,
    )
    worker.start()
    worker.join(timeout=HANG_S)  # a hang guarded, not a speed asserted
    if worker.is_alive():  # unblock the reader so that the test process can end
        with open(fifo, "wb"):
            pass
        pytest.fail("--learned on a FIFO blocked")
    lines = capsys.readouterr().err.strip().splitlines()
    lines = [line for line in lines if "compiling the LQI" not in line]  # once per machine
    assert result["code"] == 2
    assert len(lines) == 1
    assert "a FIFO (named pipe), not a regular file" in lines[0] and str(fifo) in lines[0]


def test_design_task_samples_are_read_through_the_checked_reader(tmp_path):
    from stewart_drake.design.task_samples import TaskSamples

    rng = np.random.default_rng(0)
    task = TaskSamples(
        ("breath", "heart"),
        rng.normal(size=(4, 6)),
        rng.normal(size=(4, 6)),
        rng.normal(size=(4, 6)),
        np.array([0, 0, 1, 1]),
        np.zeros((0, 6)),
        1.5,
        0.8,
        0.9,
        (1e-4, np.inf),
    )
    task.save(tmp_path / "task.npz")
    back = TaskSamples.load(tmp_path / "task.npz")
    assert back.digest() == task.digest() and back.motion.dtype.kind == "i"
    _npz_with_header(tmp_path / "bad.npz", "x", (10**12, 6))
    with pytest.raises(CorruptFileError, match="design task samples"):
        TaskSamples.load(tmp_path / "bad.npz")


# -- every reader estimates its parse's memory before it parses ------------------------------------

#: The checked reader's own calls, which are not readers of a kind of file.
READER_PRIMITIVES = {"read_checked", "read_json", "CheckedNpz"}
#: Readers whose bytes are not parsed into anything larger, each with why.
NOT_PARSED = {
    # The settings file's bytes are hashed, nothing is built from them.
    ("execution/store.py", "file_digest"),
    # An example's bytes, and those of a file of its name where it is copied to, are hashed and
    # copied as they are, nothing built from them.
    ("organ_motion/examples.py", "_theirs"),
    ("organ_motion/examples.py", "copy_examples"),
}


def _calls(node) -> set:
    names = set()
    for call in ast.walk(node):
        if isinstance(call, ast.Call):
            f = call.func
            names.add(f.id if isinstance(f, ast.Name) else getattr(f, "attr", ""))
    return names


def readers_and_estimates() -> tuple[list, set]:
    """([(module, function, calls)] of every package function that calls the checked reader,
    the names that estimate a parse's memory: ``check_parse_memory``, ``check_memory``, and the
    readers that call one themselves before they parse (``read_json``; ``CheckedNpz``, whose
    entries' decompressed sizes are checked); not ``read_checked``, which bounds a file's
    bytes, not what is built from them)."""
    functions = []
    for path in sorted(PACKAGE.rglob("*.py")):
        rel = str(path.relative_to(PACKAGE))
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                functions.append((rel, node.name, _calls(node)))
    own = {name: calls for rel, name, calls in functions if rel in CHECKED_READER}
    estimates = {"check_parse_memory", "check_memory"}
    assert "check_parse_memory" in own["read_json"]
    assert "check_memory" in own["_check_entries"] and "_check_entries" in own["__init__"]
    estimates |= {"read_json", "CheckedNpz", "_check_entries"}
    readers = [f for f in functions if f[2] & READER_PRIMITIVES and f[1] not in READER_PRIMITIVES]
    return readers, estimates


def test_every_reader_estimates_its_parse_s_memory_before_it_parses():
    """A file within its byte bound can still cost tens of times its size to parse (a 200 MB
    CSV took 7.5 GB as lists of strings): each function that reads a file through the checked
    reader also estimates what its parse needs (base.fileio.check_parse_memory, or check_memory
    on a size it computed), so a file too large for the machine is one line, not a
    MemoryError."""
    readers, estimates = readers_and_estimates()
    assert len(readers) >= 8, readers  # the scan sees the package's readers
    names = {(rel, name) for rel, name, _ in readers}
    assert ("base/columns.py", "read_csv_columns") in names
    assert ("references/trace_files.py", "read_trace_table") in names
    missing = [
        f"stewart_drake/{rel}: {name}"
        for rel, name, calls in readers
        if not calls & estimates and (rel, name) not in NOT_PARSED
    ]
    assert not missing, (
        "these read a file and parse it without estimating the parse's memory first "
        "(call base.fileio.check_parse_memory with what the parse costs):\n" + "\n".join(missing)
    )
