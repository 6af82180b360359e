"""Nothing runs that the user did not ask for, nothing of theirs is lost, nothing hangs.

One test (or a parametrized family) per case of the issue, in the library; the same cases as a
user meets them at the command line are in tests/test_cli_faults.py.
"""

import functools
import io
import json
import os
import pickle
import re
import socket
import stat
import subprocess
import sys
import threading
import time
import tracemalloc
import zipfile
from pathlib import Path

import numpy as np
import pytest
from conftest import HANG_S, install_plugin, run_within

from stewart_drake.base.errors import CorruptFileError, FolderInUseError, InvalidConfigError
from stewart_drake.base.fileio import (
    atomic_write,
    check_replaceable,
    inputs_kept,
    read_checked,
    remove_stale_temporaries,
)
from stewart_drake.cli import main as cli
from stewart_drake.control import contract
from stewart_drake.control.tuner.ann import TunerModel
from stewart_drake.control.tuner.network import load_tuner
from stewart_drake.control.tuner.ratio import RatioTunerModel
from stewart_drake.references.samples import load_csv_trajectory
from stewart_drake.run.scenario import Scenario, UserController
from stewart_drake.run.scenario_io import MAX_SCENARIO_BYTES, apply_override, load_scenario

REPO = Path(__file__).resolve().parent.parent
#: A hostile input is refused before it is computed with: numpy's warnings of an overflow, an
#: invalid value or a division by zero on the way to a correct refusal fail these tests.
pytestmark = pytest.mark.filterwarnings("error::RuntimeWarning")
HEADER = "t,phi,theta,psi,X,Y,Z\n"


def _cli(capsys, argv):
    """(exit code, stdout, the stderr lines) of the CLI run in this process."""
    rc = cli.main(argv)
    captured = capsys.readouterr()
    return rc, captured.out, captured.err.strip().splitlines()


# -- case 1: loading never executes ---------------------------------------------------------------


def test_a_scenario_resolves_only_registered_names_and_imports_nothing(tmp_path, monkeypatch):
    (tmp_path / "marking.py").write_text(
        "from pathlib import Path\nPath(__file__).with_name('IMPORTED').touch()\n"
        "def factory(*a, **k):\n    Path(__file__).with_name('CALLED').touch()\n"
    )
    monkeypatch.syspath_prepend(str(tmp_path))
    path = tmp_path / "shared.yaml"
    path.write_text('controller: !UserController {factory: "marking:factory"}\nduration_s: 0.1\n')
    scenario = load_scenario(path)  # loading names, it does not resolve
    assert scenario.controller == UserController("marking:factory")
    with pytest.raises(
        InvalidConfigError,
        match=r"'marking:factory' is an import path, and a "
        r"scenario never imports code",
    ):
        contract.resolve_controller(scenario.controller.factory)
    from stewart_drake.run.diagram import make_stewart_diagram

    with pytest.raises(InvalidConfigError, match=r"registered: none"):
        make_stewart_diagram(scenario)
    assert not (tmp_path / "IMPORTED").exists() and not (tmp_path / "CALLED").exists()
    assert "marking" not in sys.modules

    def mine(context, gain=1.0):
        return ("built", gain)

    contract.register_controller("mine", mine)
    try:
        assert contract.resolve_controller("mine") is mine
        with pytest.raises(
            InvalidConfigError,
            match=r"'nope' is not a registered controller "
            r"\(registered: mine\)",
        ):
            contract.resolve_controller("nope")
    finally:
        contract.CONTROLLER_REGISTRY.pop("mine")


def test_an_entry_point_is_loaded_only_when_named(tmp_path, monkeypatch):
    site = install_plugin(
        tmp_path / "site",
        "sd_ep_demo",
        {"demo": "sd_ep_demo:make", "broken": "sd_ep_demo:nothing"},
        "from pathlib import Path\nPath(__file__).with_name('IMPORTED').touch()\n"
        "def make(context, **p):\n    return 'made'\n",
    )
    monkeypatch.syspath_prepend(str(site))
    monkeypatch.setattr(contract, "CONTROLLER_REGISTRY", {})
    with pytest.raises(
        InvalidConfigError,
        match=r"--plugin other: no installed entry point of "
        r"that name .* \(installed: broken, demo\)",
    ):
        contract.use_entry_point_controllers(["other"])
    assert not (site / "IMPORTED").exists()  # listing entry points imports nothing
    assert contract.use_entry_point_controllers(["demo"]) == ["demo"]
    assert (site / "IMPORTED").exists() and contract.resolve_controller("demo")(None) == "made"
    with pytest.raises(
        InvalidConfigError,
        match=r"--plugin broken: the entry point "
        r"sd_ep_demo:nothing cannot be loaded",
    ):
        contract.use_entry_point_controllers(["broken"])


# -- case 2: only regular files are replaced; only the tool's temporaries removed ----------------


@pytest.fixture
def specials(tmp_path):
    """{kind: path} of a FIFO, a socket, a folder and (when allowed) a character device."""
    paths = {"FIFO": tmp_path / "fifo", "socket": tmp_path / "sock", "folder": tmp_path / "dir"}
    os.mkfifo(paths["FIFO"])
    sock = socket.socket(socket.AF_UNIX)
    sock.bind(str(paths["socket"]))
    paths["folder"].mkdir()
    try:
        os.mknod(tmp_path / "null", stat.S_IFCHR | 0o666, os.makedev(1, 3))
        paths["character device"] = tmp_path / "null"
    except OSError:
        pass
    yield paths
    sock.close()


def test_atomic_write_refuses_every_output_that_is_not_a_regular_file(specials, tmp_path):
    for kind, path in specials.items():
        mode = path.lstat().st_mode
        with pytest.raises(InvalidConfigError, match=rf"{path} is a {kind}"):
            atomic_write(path, lambda f: f.write(b"x"))
        assert path.lstat().st_mode == mode
    link = tmp_path / "link"
    link.symlink_to(specials["FIFO"])  # a symlink is judged by what it points at
    with pytest.raises(InvalidConfigError, match="FIFO"):
        check_replaceable(link)
    assert sorted(p.name for p in tmp_path.iterdir() if p.name.endswith(".tmp")) == []
    atomic_write(tmp_path / "fine.txt", lambda f: f.write(b"ok"))  # a regular file: replaced
    atomic_write(tmp_path / "fine.txt", lambda f: f.write(b"ok2"))
    assert (tmp_path / "fine.txt").read_bytes() == b"ok2"


def test_no_write_replaces_a_file_the_command_reads(tmp_path):
    """Inside :func:`inputs_kept` every write through the checked writer refuses the inputs it
    keeps, by any name (a link, a hard link, a path through a linked folder), and the files a
    scenario it loads names; outside one (a library user) nothing is kept."""
    source = tmp_path / "trace.csv"
    source.write_text("t [s],SI [mm]\n")
    (tmp_path / "link.csv").symlink_to(source)
    os.link(source, tmp_path / "hard.csv")
    (tmp_path / "folder").symlink_to(tmp_path)
    scenario = tmp_path / "mine.yaml"
    scenario.write_text("reference: !CsvReference {path: %s}\n" % (tmp_path / "ref.csv"))
    (tmp_path / "ref.csv").write_text(HEADER + "0,0,0,0,0,0,0.3\n1,0,0,0,0,0,0.3\n")
    with inputs_kept([("the motion trace.csv", source), ("--nothing", None)]):
        for name in ("trace.csv", "link.csv", "hard.csv", "folder/trace.csv"):
            with pytest.raises(InvalidConfigError, match=r"the same file as the motion trace.csv"):
                atomic_write(tmp_path / name, lambda f: f.write(b"lost"))
        load_scenario(scenario)
        with pytest.raises(InvalidConfigError, match=r"the scenario's reference.path .*ref.csv"):
            atomic_write(tmp_path / "ref.csv", lambda f: f.write(b"lost"))
        atomic_write(tmp_path / "other.csv", lambda f: f.write(b"written"))
    assert source.read_text() == "t [s],SI [mm]\n" and (tmp_path / "other.csv").exists()
    load_scenario(scenario)  # outside: nothing is kept, nothing refused
    atomic_write(tmp_path / "hard.csv", lambda f: f.write(b"replaced"))
    assert source.read_text() == "t [s],SI [mm]\n"  # the hard link's name replaced, not the file


def test_the_cleanup_removes_only_the_tool_s_temporaries_whose_writer_is_gone(tmp_path):
    host = re.sub(r"[^A-Za-z0-9_]", "_", socket.gethostname())
    dead = int(
        subprocess.run(
            [sys.executable, "-c", "import os; print(os.getpid())"], capture_output=True, text=True
        ).stdout
    )
    sub = tmp_path / "rows"
    sub.mkdir()
    stale = [
        tmp_path / f".r.json.{host}-{dead}.a1b2c3d4.tmp",
        sub / f".x.npz.{host}-{dead}.zz_9yy8x.tmp",
    ]
    kept = [
        tmp_path / f".r.json.{host}-{os.getpid()}.a1b2c3d4.tmp",  # a live writer
        tmp_path / f".r.json.otherhost-{dead}.a1b2c3d4.tmp",  # a shared disk
        tmp_path / ".notes.tmp",
        tmp_path / ".a.npz.k2j3h4_a.tmp",  # the user's
        tmp_path / f".r.json.{host}-{dead}.tooLONGname.tmp",  # not mkstemp's
        tmp_path / f".r.json.{host}-{dead}.UPPERCAS.tmp",
    ]
    for path in stale + kept:
        path.write_bytes(b"x")
        os.utime(path, (time.time() - 3 * 3600,) * 2)
    fifo = tmp_path / f".f.json.{host}-{dead}.q1w2e3r4.tmp"  # the pattern, not a file
    os.mkfifo(fifo)
    assert sorted(remove_stale_temporaries(tmp_path)) == sorted(stale)
    assert all(p.exists() for p in kept) and stat.S_ISFIFO(fifo.lstat().st_mode)


# -- case 3: every wait bounded --------------------------------------------------------------------


@pytest.mark.parametrize(
    "override, message",
    [
        (
            "simulator.target_realtime_rate=1e-9",
            r"simulator.target_realtime_rate must be 0 \(as fast "
            r"as possible\) or at least 0.01",
        ),
        ("simulator.target_realtime_rate=-1", r"target_realtime_rate must be a finite number"),
        ("simulator.integration_scheme=bogus", r"simulator.integration_scheme must be one of "),
        (
            "simulator.start_time=100",
            r"simulator.start_time must be 0 \(the reference and "
            r"duration_s count from t = 0\), got 100",
        ),
        ("simulator.max_step_size=0", r"simulator.max_step_size must be a finite number in \(0"),
        ("simulator.accuracy=nan", r"simulator.accuracy must be a finite number"),
        ("plant.contact_model=bogus", r"plant: Unknown contact_model: 'bogus'"),
        (
            "plant.contact_surface_representation=x",
            r"plant: Unknown hydroelastic contact "
            r"representation: 'x'",
        ),
        ("plant.stiction_tolerance=-1", r"plant.stiction_tolerance must be a finite number in \(0"),
        ("plant.penetration_allowance=0", r"plant.penetration_allowance must be a finite number"),
        ("plant.sap_near_rigid_threshold=-1", r"plant.sap_near_rigid_threshold must be a finite"),
    ],
)
def test_drake_config_values_are_checked_naming_the_field(override, message):
    """Cases 3 and 6: values Drake would hang on, abort on, or answer with a traceback."""
    with pytest.raises(InvalidConfigError, match=message):
        load_scenario("paper_ideal", [override])


def test_the_real_time_rates_that_are_kept_still_run(monkeypatch):
    for rate in (0.0, 0.01, 1.0, 1e6):
        load_scenario("paper_ideal", [f"simulator.target_realtime_rate={rate}"])
    from stewart_drake.run.simulate import build_simulator, run_experiment

    slow = load_scenario("paper_ideal", ["simulator.target_realtime_rate=0.5", "duration_s=0.1"])
    _, simulator = build_simulator(slow)
    assert simulator.get_target_realtime_rate() == 0.5  # Drake paces the run: 0.1 s / 0.5
    assert run_experiment(slow).metrics["finite"]


def test_a_cluster_address_where_nothing_listens_is_refused_within_the_timeout():
    from stewart_drake.execution.clusters import make_runner

    for kind, option in (("ray", "address"), ("dask", "scheduler")):
        with pytest.raises(
            InvalidConfigError,
            match=rf"--{option} 127.0.0.1:1: nothing accepts "
            rf"a connection there within 0.5 s",
        ):
            # The wait is bounded by the timeout, not by the peer: a hang fails the test.
            run_within(HANG_S, make_runner, kind, **{option: "127.0.0.1:1"}, connect_timeout_s=0.5)


def test_a_ray_join_that_hangs_is_bounded_and_interruptible(monkeypatch):
    """An address that answers but is no Ray cluster: Ray's handshake retries in C++ for
    minutes; the join waits at most RAY_JOIN_TIMEOUT_S, in a thread the main thread can leave."""
    from stewart_drake.execution import clusters

    server = socket.socket()
    server.bind(("127.0.0.1", 0))
    server.listen()
    release = threading.Event()

    class HangingRay:
        def init(self, **kwargs):
            release.wait()  # as Ray's handshake: until given up on (released at the end)

    monkeypatch.setattr(clusters, "RAY_JOIN_TIMEOUT_S", 1.0)
    runner = clusters.RayRunner(address=f"127.0.0.1:{server.getsockname()[1]}")
    try:
        with pytest.raises(
            InvalidConfigError,
            match=r"it answers, but no Ray cluster joined "
            r"within 1 s",
        ):
            # 1.0 s on a quiet machine; the hang is forever, and HANG_S fails the test
            run_within(HANG_S, runner._join, HangingRay())
    finally:
        release.set()
        server.close()


def _sleep(job):
    time.sleep(2 * HANG_S)  # outlasts the guard: only the pool's own end may stop it


def test_workers_ended_mid_result_leave_no_thread_that_holds_the_exit():
    """A worker killed while it sends a result leaves half a message in the result pipe; the
    executor's thread then waited for the rest forever, and the interpreter for it at exit (a
    SIGTERMed collect printed its message and never ended)."""
    import struct

    from stewart_drake.execution.runners import _LocalPool

    pool = _LocalPool(1, None, "spawn")
    future = pool.submit(_sleep, "a", 1)
    manager = pool.executor._executor_manager_thread
    writer = pool.executor._result_queue._writer
    os.write(writer.fileno(), struct.pack("!i", 1000) + b"half")  # what the killed one sent
    time.sleep(0.5)
    assert manager.is_alive()  # reading the rest
    pool.close([future])
    manager.join(HANG_S)  # at once on a quiet machine; the hang it proves gone is forever
    assert not manager.is_alive()


def test_sigterm_and_sighup_interrupt_any_command_in_process(capsys, monkeypatch):
    """The CLI turns SIGTERM and SIGHUP into the same interruption as Ctrl-C, then restores the
    handlers it found (a library caller's own handlers survive a call of main)."""
    import signal

    from stewart_drake.execution.runners import Interrupted
    from stewart_drake.run import simulate as experiments

    def mine(signum, frame):
        pass

    old = {s: signal.signal(s, mine) for s in (signal.SIGTERM, signal.SIGHUP)}
    try:
        for signum in (signal.SIGTERM, signal.SIGHUP):

            def kill_me(*args, signum=signum, **kwargs):
                os.kill(os.getpid(), signum)
                time.sleep(5)
                pytest.fail("the signal did not interrupt")

            monkeypatch.setattr(experiments, "run_experiment", kill_me)
            rc, _, err = _cli(
                capsys, ["run", "--duration", "0.1", "--no-progress", "--out", "/tmp/never-written"]
            )
            assert rc == 128 + signum and err == [
                f"stewart-drake run: interrupted by {signal.Signals(signum).name}; partial "
                f"outputs were not written"
            ]
            assert signal.getsignal(signum) is mine
        assert pickle.loads(pickle.dumps(Interrupted(signal.SIGTERM))).signum == signal.SIGTERM
    finally:
        for s, handler in old.items():
            signal.signal(s, handler)


# -- case 4 and the BOM: reference CSV files -------------------------------------------------------


@pytest.mark.parametrize(
    "data, error, message",
    [
        (
            HEADER + "0,0,0,0,0,0,0.3\n1e300,0,0,0,0,0,0.3\n2e300,0,0,0,0,0,0.3\n",
            InvalidConfigError,
            r"the last time is 2e\+300 s; a reference ends by 1e\+07 s",
        ),
        (
            HEADER + "0,0,0,0,0,0,0.3\n1e-100,0,0,0,0,0,0.3\n2e-100,0,0,0,0,0,0.3\n",
            InvalidConfigError,
            r"samples must be at least 1e-06 s apart; those at t = 0 s and 1e-100 s are "
            r"1e-100 s apart",
        ),
        (bytes(range(256)) * 8, CorruptFileError, r"not UTF-8 text"),
        (
            (HEADER + "0,0,0,0,0,0,0.3 # caf\xe9\n").encode("latin-1"),
            CorruptFileError,
            r"not UTF-8 text \(invalid continuation byte at byte 43\)",
        ),
        (
            HEADER + "x" * 200_000 + "\n",
            CorruptFileError,
            r"not CSV \(field larger than field limit \(131072\)\)",
        ),
        (HEADER + '0,0,0,0,0,0,0.3\n"a\x00b\n', InvalidConfigError, r"line 3: expected 7 finite"),
        (
            HEADER + "0,0,0,0,0,0,3e3\n1,0,0,0,0,0,0.3\n2,0,0,0,0,0,0.3\n",
            InvalidConfigError,
            r"has a position beyond 1000 m",
        ),
    ],
    ids=[
        "times-1e300",
        "times-1e-100",
        "random-bytes",
        "latin-1",
        "field-over-limit",
        "nul",
        "km-position",
    ],
)
def test_a_damaged_reference_csv_is_one_typed_error(tmp_path, data, error, message):
    path = tmp_path / "ref.csv"
    path.write_bytes(data if isinstance(data, bytes) else data.encode())
    with pytest.raises(error, match=message) as info:
        load_csv_trajectory(path)
    assert str(path) in str(info.value)


def test_a_utf8_byte_order_mark_before_the_header_is_read_as_text(tmp_path):
    path = tmp_path / "excel.csv"
    path.write_bytes(
        b"\xef\xbb\xbf"
        + (HEADER + "0,0,0,0,0,0,0.3\n0.5,0,0,0,0,0,0.3\n1,0,0,0,0,0,0.31\n").encode()
    )
    reference = load_csv_trajectory(path)
    assert reference.end_time == 1.0
    np.testing.assert_allclose(reference.evaluate(np.array([1.0]))[0][0, 5], 0.31)


def test_a_fifo_or_a_sparse_giant_is_never_read(tmp_path):
    os.mkfifo(tmp_path / "ref.csv")
    # Refused from what it is and from its size, never read: opening the FIFO would block for
    # ever, reading the giant for minutes (the guard against a hang fails the test then).
    with pytest.raises(CorruptFileError, match=r"it is a FIFO \(named pipe\), not a regular file"):
        run_within(HANG_S, load_csv_trajectory, tmp_path / "ref.csv")
    with open(tmp_path / "big.npz", "wb") as f:
        f.truncate(100 * 10**9)
    with pytest.raises(
        CorruptFileError,
        match=r"ANN tuner weights file: it holds 100 GB, over "
        r"the bound of 16 MB for this kind of file",
    ):
        run_within(HANG_S, load_tuner, TunerModel, tmp_path / "big.npz")


# -- case 5: the reference is in the memory estimate ---------------------------------------------


def test_a_reference_csv_too_large_for_the_memory_is_refused_before_it_is_parsed(
    tmp_path, capsys, monkeypatch
):
    from stewart_drake.base import checks
    from stewart_drake.references import samples
    from stewart_drake.run.memory import run_memory_bytes

    path = tmp_path / "long.csv"
    with open(path, "w") as f:
        f.write(HEADER)
        f.write("0,0,0,0,0,0,0.3\n" * 2_000_000)  # 32 MB, 2e6 rows
    from stewart_drake.run.scenario import CsvReference

    base = run_memory_bytes(Scenario(duration_s=0.1))
    scenario = Scenario(duration_s=0.1, reference=CsvReference(str(path)))
    assert run_memory_bytes(scenario) == pytest.approx(base + 2_000_002 * 1.5e3)
    monkeypatch.setattr(checks, "available_memory_bytes", lambda: 2e9)
    monkeypatch.setattr(samples.csv, "reader", lambda *a, **k: pytest.fail("parsed"))
    rc, _, err = _cli(
        capsys,
        [
            "run",
            "--trajectory-file",
            str(path),
            "--duration",
            "0.1",
            "--no-progress",
            "--out",
            str(tmp_path / "out"),
        ],
    )
    assert rc == 2 and len(err) == 1  # refused unparsed: csv.reader fails the test if called
    assert re.search(
        rf"a run of 0.1 s logged every 0.001 s on the reference {path}: about 3.4 GB "
        rf"of memory needed, more than the 2 GB available on this machine; .*sample "
        rf"the reference CSV more coarsely",
        err[0],
    ), err[0]
    with pytest.raises(InvalidConfigError, match=r"a reference of 2000002 rows"):
        load_csv_trajectory(path)  # the loader checks by itself too


# -- case 6: extreme physics, one typed line -------------------------------------------------------


def test_a_robot_the_motors_cannot_move_is_one_typed_line(capsys, tmp_path):
    rc, _, err = _cli(
        capsys,
        [
            "run",
            "--scenario",
            "paper_ideal",
            "--set",
            "robot.platform_mass=1e9",
            "--duration",
            "0.01",
            "--no-progress",
            "--out",
            str(tmp_path),
        ],
    )
    assert rc == 2 and len(err) == 1
    # A mass beyond any robot is refused as the field it is, before any model is built (the
    # LQI's Hautus test refused it once a model was made).
    assert re.match(
        r"stewart-drake run: .*paper_ideal.yaml with --set robot.platform_mass=1e9: robot: "
        r"platform_mass must be a finite number in \(0, 100000\]",
        err[0],
    )


# -- cases 7 and 9: study files through the checked loaders, each holding its own id --------------


def _store(tmp_path, study="evaluate"):
    from stewart_drake.execution.store import ResultStore

    return ResultStore(tmp_path / "out", study, {"quick": True}, pattern="rows/*.json")


def test_a_damaged_evaluation_row_is_a_corrupt_file(tmp_path):
    from stewart_drake.evaluation.evaluation import load_row
    from stewart_drake.evaluation.evaluation_grid import case_id, make_case

    store = _store(tmp_path)
    case = make_case("pd", "step_Z", duration_s=2.5)
    for value, problem in (
        ({}, "the entry 'case' is missing"),
        ([], "a JSON list, not an object"),
        (
            {"case": {**make_case("pd", "step_Z").record(), "duration_s": 2.5}},
            "the entry 'rms_error' is missing or not 6 numbers",
        ),
        ({"case": case.record(), "error": 3}, "the entry 'error' must be a string"),
    ):
        store.put_json(case_id(case), f"rows/{case_id(case)}.json", value)
        with pytest.raises(CorruptFileError, match=re.escape(problem)) as info:
            load_row(store, case_id(case), case)
        assert info.value.path == str(tmp_path / "out" / "rows" / f"{case_id(case)}.json")
    (tmp_path / "out" / "rows" / f"{case_id(case)}.json").write_bytes(b'{"case": {"contr')
    with pytest.raises(CorruptFileError, match="not JSON"):
        load_row(store, case_id(case), case)
    store.close()


def test_a_manifest_entry_pointing_at_another_case_s_row_is_refused(tmp_path):
    """Case 9: the entry of A names B's row; with B's entry kept (two jobs, one file) the
    manifest is refused; with B's entry gone, the row says it is B's."""
    from stewart_drake.evaluation.evaluation import load_row
    from stewart_drake.evaluation.evaluation_grid import case_id, make_case
    from stewart_drake.execution.store import MANIFEST, read_manifest

    store = _store(tmp_path)
    a, b = make_case("pd", "helix", duration_s=4.0), make_case("lqi_1_1", "helix", duration_s=4.0)
    row = {
        "rms_error": [0.0] * 6,
        "peak_error": [0.0] * 6,
        "peak_torque": [0.1] * 6,
        "sum_T2_dt": 1.0,
        "normalized_rms": 0.1,
        "sum_dT2_dt": 0.1,
        "max_closure_m": 1e-7,
    }
    for case in (a, b):
        store.put_json(case_id(case), f"rows/{case_id(case)}.json", {"case": case.record(), **row})
    assert load_row(store, case_id(a), a)["case"]["controller"] == "pd"
    store.close()
    path = tmp_path / "out" / MANIFEST
    manifest = json.loads(path.read_text())
    manifest["jobs"][case_id(a)]["file"] = f"rows/{case_id(b)}.json"
    path.write_text(json.dumps(manifest))
    with pytest.raises(
        CorruptFileError,
        match=rf"jobs '{case_id(a)}' and '{case_id(b)}' both "
        rf"name the file 'rows/{case_id(b)}.json'",
    ):
        read_manifest(tmp_path / "out")
    del manifest["jobs"][case_id(b)]
    path.write_text(json.dumps(manifest))
    store = _store(tmp_path)
    with pytest.raises(
        CorruptFileError,
        match=r"it holds the row of another case \(lqi_1_1 \| "
        r"helix \| nominal\), not of pd \| helix \| "
        r"nominal",
    ):
        load_row(store, case_id(a), a)
    store.close()


def test_a_collection_whose_manifest_swaps_two_runs_is_refused(tmp_path):
    from stewart_drake.execution.runners import SerialRunner
    from stewart_drake.execution.store import MANIFEST
    from stewart_drake.tuner.collection import collect, load_records

    out = tmp_path / "collect"
    collect(out, duration_s=0.05, runner=SerialRunner(), progress=False)
    manifest = json.loads((out / MANIFEST).read_text())
    runs = manifest["runs"]
    runs[0]["file"] = runs[1]["file"]  # one run listed twice, one missed
    (out / MANIFEST).write_text(json.dumps(manifest))
    with pytest.raises(
        CorruptFileError,
        match=r"it holds the run at omega_Q = 0.1, omega_R = 1, "
        r"not the one its manifest entry names "
        r"\(omega_Q = 0.1, omega_R = 0.1\)",
    ):
        load_records(out)


def test_a_truncated_tuner_study_run_is_a_corrupt_file(tmp_path):
    from stewart_drake.tuner.tuner_study import load_run

    arrays = {
        "e2": np.float64(1.0),
        "u2": np.float64(2.0),
        "ratio_mean": np.float64(1.0),
        "wall_s": np.float64(0.1),
        "e2_w": np.ones(3),
        "u2_w": np.ones(3),
        "inputs": np.zeros((2, 16)),
        "input_window": np.zeros(2),
        "job_id": np.array("fixed__dash__s0__1"),
    }
    path = tmp_path / "runs" / "fixed__dash__s0__1.npz"
    path.parent.mkdir()
    buffer = io.BytesIO()
    np.savez(buffer, **arrays)
    path.write_bytes(buffer.getvalue())
    assert load_run(path, "fixed__dash__s0__1")["e2"] == 1.0
    with pytest.raises(
        CorruptFileError,
        match=r"it holds the run 'fixed__dash__s0__1', not "
        r"'fixed__dash__s1__1'",
    ):
        load_run(path, "fixed__dash__s1__1")
    path.write_bytes(buffer.getvalue()[:300])
    with pytest.raises(
        CorruptFileError,
        match=r"is not a valid tuner study run: not a readable "
        r"\.npz archive \(BadZipFile",
    ):
        load_run(path, "fixed__dash__s0__1")
    lost = path.with_suffix(".json")
    lost.write_text("{}")
    with pytest.raises(CorruptFileError, match=r"it must be \{\"lost\": why\}"):
        load_run(lost, "fixed__dash__s0__1")


def test_an_edited_settings_hash_says_what_is_wrong(tmp_path):
    """The low case: a hash edited by hand was refused with "()" and advice to run with the
    same settings, which could not work."""
    from stewart_drake.execution.store import MANIFEST, read_manifest

    _store(tmp_path).close()
    path = tmp_path / "out" / MANIFEST
    manifest = json.loads(path.read_text())
    manifest["settings_hash"] = "0123456789abcdef"
    path.write_text(json.dumps(manifest))
    with pytest.raises(
        CorruptFileError,
        match=r"its settings_hash '0123456789abcdef' is not the "
        r"hash of its settings \('[0-9a-f]{16}'\): one was "
        r"edited; delete the folder",
    ):
        read_manifest(tmp_path / "out")


# -- case 8: one writer per study folder -----------------------------------------------------------


@pytest.mark.system
def test_a_study_folder_is_locked_against_a_second_writer(tmp_path):
    from stewart_drake.execution.store import LOCK, lock_folder, unlock_folder

    folder = tmp_path / "out"
    holder = subprocess.Popen(
        [
            sys.executable,
            "-c",
            "import sys, time\nfrom stewart_drake.execution.store import "
            f"lock_folder\nlock_folder({str(folder)!r}, 'collect')\nprint('locked', flush=True)\n"
            f"time.sleep({HANG_S})",
        ],
        stdout=subprocess.PIPE,
        text=True,
        env=dict(os.environ, PYTHONPATH=str(REPO)),
    )
    try:
        assert holder.stdout.readline() == "locked\n"
        with pytest.raises(
            FolderInUseError,
            match=rf"{folder} is being written by another study "
            rf"\(`collect` study, pid {holder.pid} on ",
        ):
            _store(tmp_path, "collect")
        assert not (folder / "manifest.json").exists()  # refused before writing
    finally:
        holder.kill()  # kill -9: the kernel releases
        holder.wait()
    store = _store(tmp_path, "collect")
    assert f"pid {os.getpid()}" in (folder / LOCK).read_text()
    lock_folder(folder, "collect")  # this process again: it holds it
    store.finish(True)  # released at the end
    unlock_folder(folder)
    assert not (folder / LOCK).exists()  # and no stale lock file left behind
    probe = subprocess.run(
        [
            sys.executable,
            "-c",
            "from stewart_drake.execution.store import lock_folder\n"
            f"lock_folder({str(folder)!r}, 'evaluate'); print('ok')",
        ],
        capture_output=True,
        text=True,
        env=dict(os.environ, PYTHONPATH=str(REPO)),
    )
    assert probe.stdout == "ok\n", probe.stderr


# -- case 10: npz entries bounded after decompression ----------------------------------------------


def test_a_weights_file_that_inflates_to_gigabytes_is_refused_before_decompression(tmp_path):
    path = tmp_path / "bomb.npz"
    header = io.BytesIO()
    np.lib.format.write_array_header_1_0(
        header, {"descr": "<f8", "fortran_order": False, "shape": (12_500_000,)}
    )
    chunk = bytes(1_000_000)
    with zipfile.ZipFile(path, "w", compression=zipfile.ZIP_DEFLATED, compresslevel=1) as archive:
        with archive.open("W1.npy", "w", force_zip64=True) as member:
            member.write(header.getvalue())
            for _ in range(100):  # 100 MB of zeros
                member.write(chunk)
    assert path.stat().st_size < 1e6
    tracemalloc.start()
    try:
        with pytest.raises(
            CorruptFileError,
            match=r"its entries hold 100 MB after decompression "
            r"\('W1.npy': 100 MB\), over the bound of 16 "
            r"MB for this kind of file",
        ):
            load_tuner(TunerModel, path)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak < 10e6  # nothing was inflated


def test_read_checked_bounds_every_file_it_reads(tmp_path):
    path = tmp_path / "f"
    path.write_bytes(b"x" * 1000)
    assert read_checked(path, "thing", 1000) == b"x" * 1000
    with pytest.raises(CorruptFileError, match=r"it holds 1 kB, over the bound of 0.999 kB"):
        read_checked(path, "thing", 999)
    with pytest.raises(CorruptFileError, match="it is a folder"):
        read_checked(tmp_path, "thing", 1e6)


def test_every_loader_refuses_what_is_not_a_regular_file_without_blocking(specials):
    from stewart_drake.execution.store import read_manifest
    from stewart_drake.run.result import load_result

    loaders = [
        ("reference CSV", load_csv_trajectory),
        ("scenario file", load_scenario),
        ("ANN tuner weights file", functools.partial(load_tuner, TunerModel)),
        ("ratio tuner weights file", functools.partial(load_tuner, RatioTunerModel)),
        ("run result file", load_result),
    ]
    # Refused from what they are, never opened for reading (a FIFO would block for ever):
    # milliseconds when quiet; the guard against a hang fails the test on one.
    for kind, path in specials.items():
        if kind == "folder":
            continue
        for what, load in loaders:
            with pytest.raises(
                CorruptFileError,
                match=rf"{path} is not a valid {what}: it is a "
                rf"{kind}",
            ):
                run_within(HANG_S, load, path)
    os.mkfifo(specials["folder"] / "manifest.json")
    with pytest.raises(CorruptFileError, match=r"it is a FIFO"):
        run_within(HANG_S, read_manifest, specials["folder"])


# -- the low cases ---------------------------------------------------------------------------------


def test_a_scenario_file_beyond_the_size_bound_is_refused_unparsed(tmp_path, monkeypatch):
    path = tmp_path / "big.yaml"
    path.write_text("tuner: !WeightSchedule\n  t: [" + ", ".join(["0.0"] * 200_000) + "]\n")
    import yaml

    monkeypatch.setattr(yaml, "compose", lambda *a, **k: pytest.fail("parsed"))
    with pytest.raises(
        CorruptFileError,
        match=rf"it holds 1 MB, over the bound of "
        rf"{MAX_SCENARIO_BYTES / 1e3:.3g} kB",
    ):
        load_scenario(path)


def test_a_long_computation_delay_is_refused_where_the_lqi_would_crawl():
    with pytest.raises(
        InvalidConfigError,
        match=r"hardware.computation_delay_periods = 100 with "
        r"the LQI's delay compensation gives a model of "
        r"6 x \(3 \+ 100\) = 618 states",
    ):
        load_scenario("paper_hardware", ["hardware.computation_delay_periods=100"])
    load_scenario("paper_hardware", ["hardware.computation_delay_periods=20"])
    load_scenario(
        "paper_hardware",
        ["hardware.computation_delay_periods=100", "controller.delay_compensation=false"],
    )


def test_drake_config_fields_can_be_set_and_are_listed():
    scenario = load_scenario(
        "paper_ideal", ["plant.time_step=0.0005", "simulator.target_realtime_rate=2.0"]
    )
    assert scenario.plant.time_step == 0.0005 and scenario.simulator.target_realtime_rate == 2.0
    with pytest.raises(
        InvalidConfigError,
        match=r"--set plant.time_stp: 'time_stp' is not a "
        r"field of MultibodyPlantConfig \(fields: "
        r".*contact_model.*time_step",
    ):
        apply_override(scenario, "plant.time_stp=1")


@pytest.mark.parametrize(
    "text, key, lines",
    [
        ("duration_s: 1.0\nduration_s: 2.0\n", "duration_s", (1, 2)),
        (
            "controller: !LqiDriver\n  omega_Q: 1.0\n  omega_R: 2.0\n  omega_Q: 3.0\n",
            "omega_Q",
            (2, 4),
        ),
    ],
)
def test_a_key_given_twice_is_refused_naming_it(tmp_path, text, key, lines):
    path = tmp_path / "twice.yaml"
    path.write_text(text)
    with pytest.raises(
        InvalidConfigError,
        match=rf"the key '{key}' appears twice in one mapping "
        rf"\(lines {lines[0]} and {lines[1]}\)",
    ):
        load_scenario(path)


def test_anchors_and_merge_keys_are_not_duplicates(tmp_path):
    path = tmp_path / "anchors.yaml"
    path.write_text(
        "guard: &g {check_period_s: 0.01}\nreference: !NamedReference {name: helix}\n"
        "duration_s: 1.0\n"
    )
    assert load_scenario(path).duration_s == 1.0


def test_the_smallest_workspace_sweep_has_finite_extents():
    from stewart_drake.analysis.workspace import workspace_summary
    from stewart_drake.robot.geometry import StewartGeometry

    s = workspace_summary(StewartGeometry(), 3, jobs=1)
    assert np.isfinite(s["extent_xyz_m"]).all() and np.isfinite(s["extent_rpy_rad"]).all()
    with pytest.raises(InvalidConfigError, match=r"resolution must be an integer >= 3"):
        workspace_summary(StewartGeometry(), 2, jobs=1)


def test_a_full_disk_during_run_names_the_file_and_keeps_the_figures(capsys, tmp_path, monkeypatch):
    from stewart_drake.base import fileio

    def full(f, **arrays):
        f.write(b"PK\x03\x04")
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(fileio.np, "savez_compressed", full)
    rc, out, err = _cli(
        capsys, ["run", "--duration", "0.1", "--no-progress", "--out", str(tmp_path)]
    )
    assert rc == 1 and err == [
        f"stewart-drake run: [Errno 28] No space left on device: '{tmp_path / 'run_paper.npz'}'"
    ]
    assert "RMS tracking error over" in out and "real-time factor" in out  # printed first
    assert sorted(p.name for p in tmp_path.iterdir()) == []  # no temporary left
