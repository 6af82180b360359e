"""A user's first minutes with the command: the compile note from numba's cache, design over a
damaged or foreign file, a Ctrl-C while the command starts, a plug-in that exits, and a line
before each long silent stage."""

import json
import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from conftest import HANG_S, install_plugin

from stewart_drake.cli import main as cli
from stewart_drake.control import contract
from stewart_drake.execution import options

REPO = Path(__file__).resolve().parent.parent
KERNELS = "stewart_drake.control.lqi.kernels"
COMPILING = "compiling the LQI's control step"
_SCRIPT = Path(sys.executable).with_name("stewart-drake")


# The compile note: from numba's cache, never a timer, never before a refusal ------------------


def test_will_compile_reads_numbas_cache_index_and_its_stamp(tmp_path, monkeypatch):
    """After the kernels are imported their cache is valid; a copy of a kernels' module with a
    copy of that cache is too; the same copy changed by one line (a stale stamp), or a cache folder
    with nothing in it, is not."""
    import importlib

    import numba

    from stewart_drake.control import kernel_cache

    importlib.import_module(KERNELS)  # compiles or loads: the cache holds it from here
    assert kernel_cache.will_compile() is False
    kernels_file = kernel_cache.KERNEL_FILES[0]
    source = tmp_path / "src" / kernels_file.name
    source.parent.mkdir()
    shutil.copy2(kernels_file, source)
    cached = Path(kernel_cache.cache_folder())
    copy_to = Path(kernel_cache.cache_folder(source))
    copy_to.mkdir(parents=True, exist_ok=True)
    indexes = list(cached.glob(f"{kernels_file.stem}.*.nb[ic]"))
    assert indexes, cached
    for path in indexes:
        shutil.copy2(path, copy_to / path.name)
    assert kernel_cache.will_compile(source) is False
    source.write_text(source.read_text() + "\n# changed\n")  # numba compiles again: stale stamp
    assert kernel_cache.will_compile(source) is True
    monkeypatch.setattr(numba.config, "CACHE_DIR", str(tmp_path / "empty"))
    assert kernel_cache.will_compile() is True


def test_the_compile_note_comes_from_the_cache_not_from_a_slow_import(
    tmp_path, monkeypatch, capsys
):
    """A cold cache says so before importing, however quick; a warm one says nothing, however
    slow the import (a busy machine)."""
    (tmp_path / "sd_slow_kernels.py").write_text("import time\ntime.sleep(0.5)\n")
    (tmp_path / "sd_quick_kernels.py").write_text("")
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.setattr(options, "_will_compile", lambda: False)
    options.say_if_compiling("run", module="sd_slow_kernels")
    assert "sd_slow_kernels" in sys.modules
    assert capsys.readouterr().err == ""
    monkeypatch.setattr(options, "_will_compile", lambda: True)
    options.say_if_compiling("run", module="sd_quick_kernels")
    err = capsys.readouterr().err
    assert err.startswith(f"stewart-drake run: {COMPILING}") and "about 40 s" in err, err
    for name in ("sd_slow_kernels", "sd_quick_kernels"):
        sys.modules.pop(name, None)


@pytest.mark.parametrize(
    "argv, expected",
    [
        (["run", "--set", "duration_s=abc"], "duration_s"),
        (["run", "--set", "controler.omega_Q=2"], "controler"),
        (["run", "--duration", "1e9"], "a run of 1e+09 s logged"),
        (["collect", "--set", "duration_s=abc"], "duration_s"),
        (["reproduce", "breathing", "--param", "amplitude=15"], "amplitude"),
    ],
)
def test_a_refusal_with_a_cold_cache_is_one_line_without_the_compile_note(
    tmp_path, monkeypatch, capsys, argv, expected
):
    monkeypatch.setattr(options, "_will_compile", lambda: True)
    monkeypatch.delitem(sys.modules, KERNELS, raising=False)
    assert cli.main([*argv, "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and expected in err[0], err


def test_a_valid_run_with_a_cold_cache_says_it_compiles_then_what_it_builds_and_writes(
    tmp_path, monkeypatch, capsys
):
    """The note once, after the checks and before the Diagram is built; the silent stages
    around the bar say what they do."""
    monkeypatch.setattr(options, "_will_compile", lambda: True)
    monkeypatch.delitem(sys.modules, KERNELS, raising=False)  # restored after the test
    assert cli.main(["run", "--duration", "0.05", "--out", str(tmp_path)]) == 0
    captured = capsys.readouterr()
    lines = [x.strip() for x in captured.err.replace("\r", "\n").splitlines() if x.strip()]
    notes = [x for x in lines if x.startswith("stewart-drake run:")]
    assert notes == [
        f"stewart-drake run: {COMPILING} for this machine and Python (once, about 40 s; later "
        f"runs start in seconds)",
        "stewart-drake run: building the Drake station and its controller, starting the "
        "simulator ...",
        "stewart-drake run: writing run_paper.npz, drawing Fig. 7 (run_paper.png), the logs "
        "as CSV and MAT ...",
    ], notes
    assert lines.index(notes[0]) < lines.index(notes[1])
    assert "wrote" in captured.out and (tmp_path / "run_paper.npz").exists(), captured.out


# design: damaged generations, files that are not what they should be ---------------------------


DESIGN = (
    "--generations 1 --popsize 2 --no-cheapest --no-confirm --runner serial --no-progress".split()
)


#: A task one generation of two candidates meets: breathing (the paper's manoeuvre takes the
#: reference robot's motors to 94 % of their continuous torque, beyond the 80 % design allows).
TASK = "motions:\n  - !OrganMotionReference {motion: breathing}\n"


def _requirements(tmp_path, text=TASK) -> Path:
    path = tmp_path / "requirements.yaml"
    path.write_text(text)
    return path


def _one_line(capsys, argv, code=2) -> str:
    rc = cli.main(argv)
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == code and len(err) == 1, (rc, err)
    assert "Traceback" not in err[0]
    return err[0]


@pytest.fixture(scope="module")
def designed(tmp_path_factory):
    """(requirements, out): one finished design search, searched once for the module; a test
    damages its own copy of ``out``."""
    root = tmp_path_factory.mktemp("designed")
    requirements, out = _requirements(root), root / "out"
    assert cli.main(["design", str(requirements), "--out", str(out), *DESIGN]) == 0
    return requirements, out


@pytest.mark.parametrize(
    "damage, problem",
    [
        (b"{ not json", "not JSON"),
        (b'[{"design": {}}]', "not the generation's evaluations"),
        (b"[]", "0 evaluations for"),
    ],
)
def test_design_resumed_over_a_damaged_generation_names_the_file(
    tmp_path, capsys, designed, damage, problem
):
    """Not scipy's RuntimeError around it: the typed line naming the file and what to do."""
    requirements, finished = designed
    out = tmp_path / "out"
    shutil.copytree(finished, out)
    argv = ["design", str(requirements), "--out", str(out), *DESIGN]
    generations = sorted((out / "search").glob("*_gen_*.json"))
    assert len(generations) == 2  # x0's generation and one more
    generations[0].write_bytes(damage)
    assert cli.main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    # The stages said before the search (how long it may take), then the one error line.
    assert err[0] == "stewart-drake design: evaluating the reference robot on the task", err
    assert all(e.startswith("stewart-drake design: ") for e in err), err
    assert not any("Traceback" in e for e in err)
    line = err[-1]
    assert str(generations[0]) in line and "is not a valid design" in line, line
    assert problem in line and "delete it and run the same command again" in line, line
    assert "RuntimeError" not in line and "map-like" not in line


def test_design_quotes_no_line_of_a_file_that_is_not_what_it_should_be(tmp_path, capsys):
    """A private file named where a trace, a CSV or the requirements are due: refused, and
    nothing of its content in the message."""
    secret = tmp_path / "private"
    # as /etc/shadow is: each line a YAML key, so the file even parses as YAML
    secret.write_text("alice:$6$s3cr3t-hash:19000:0:99999:7:::\nbob:*:19000:0:99999:7:::\n")
    for text in (
        f"motions:\n  - !TraceReference {{path: {secret}}}\n",
        f"motions:\n  - !CsvReference {{path: {secret}}}\n",
    ):
        path = _requirements(tmp_path, text)
        line = _one_line(capsys, ["design", str(path), "--out", str(tmp_path / "o"), *DESIGN])
        assert str(secret) in line and "s3cr3t" not in line and "alice" not in line, line
    line = _one_line(capsys, ["design", str(secret), "--out", str(tmp_path / "o"), *DESIGN])
    assert "is not a valid design requirements file" in line, line
    assert "s3cr3t" not in line and "alice" not in line and "bob" not in line, line
    assert "known: motions, workspace" in line
    # a typo in a real requirements file is still named
    path = _requirements(tmp_path, "motion: []\n")
    line = _one_line(capsys, ["design", str(path), "--out", str(tmp_path / "o"), *DESIGN])
    assert "unknown field motion (known: motions" in line, line


def test_design_names_a_folder_as_a_folder(tmp_path, capsys):
    line = _one_line(capsys, ["design", str(tmp_path), "--out", str(tmp_path / "o"), *DESIGN])
    assert "it is a folder, not a regular file" in line and "no design" not in line, line


@pytest.mark.parametrize(
    "scenario, expected",
    [("missing.yaml", "missing.yaml"), ("paper_ideal", "needs hardware")],
)
def test_design_reads_its_base_scenario_before_the_search(tmp_path, capsys, scenario, expected):
    out = tmp_path / "out"
    argv = ["design", str(_requirements(tmp_path)), "--out", str(out), *DESIGN]
    line = _one_line(capsys, [*argv, "--scenario", scenario])
    assert expected in line, line
    assert not (out / "search").exists()  # no generation was evaluated


def test_an_interrupted_design_says_its_finished_generations_are_kept():
    import io
    from contextlib import redirect_stderr

    err = io.StringIO()
    with redirect_stderr(err):
        assert cli._interrupted(KeyboardInterrupt(), "design", "results/design") == 130
    assert err.getvalue().strip() == (
        "stewart-drake design: interrupted by SIGINT; finished generations are kept in "
        "results/design/search: run the same command again to run only the rest"
    )
    with redirect_stderr(err := io.StringIO()):
        cli._interrupted(KeyboardInterrupt(), "sdf", "x.sdf")
    assert err.getvalue().strip().endswith("partial outputs were not written")


# Ctrl-C while the command imports ------------------------------------------------------------


def _numpy_loaded(pid: int) -> bool:
    """Whether process ``pid`` has numpy's core extension mapped: it is importing the package
    (``stewart_drake/__init__`` imports numpy after installing its handler)."""
    try:
        return "_multiarray_umath" in Path(f"/proc/{pid}/maps").read_text()
    except OSError:
        return False


@pytest.mark.system
@pytest.mark.skipif(not Path("/proc/self/maps").exists(), reason="needs Linux's /proc")
@pytest.mark.parametrize("delay_s", [0.0, 0.05, 0.15, 0.3])
def test_ctrl_c_while_the_command_imports_is_one_line(tmp_path, delay_s):
    """From the moment the package imports numpy (its first import, after its handler) to the
    command's end: one line, 130, no traceback, and no C++ log of pydrake's."""
    command = (
        [str(_SCRIPT)] if _SCRIPT.exists() else [sys.executable, "-m", "stewart_drake.cli.main"]
    )
    proc = subprocess.Popen(
        [*command, "run", "--set", "duration_s=abc", "--out", str(tmp_path)],
        cwd=tmp_path,
        env=dict(os.environ, PYTHONPATH=str(REPO)),
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL),
    )
    deadline = time.monotonic() + HANG_S  # a guard against a hang, not a measure
    while not _numpy_loaded(proc.pid) and proc.poll() is None and time.monotonic() < deadline:
        time.sleep(0.002)
    time.sleep(delay_s)
    proc.send_signal(signal.SIGINT)
    _, err = proc.communicate(timeout=HANG_S)
    lines = err.strip().splitlines()
    if lines and lines[0] == f"stewart-drake run: {options.STARTING}":  # said before the signal
        lines = lines[1:]
    if proc.returncode == 2:  # the command ended (refusing the typo) before the signal came
        assert lines == [lines[0]] and "duration_s" in lines[0], err
        return
    assert proc.returncode == 130, err
    assert len(lines) == 1 and "interrupted by SIGINT" in lines[0], err
    assert "Traceback" not in err and "pydrake" not in err


# A plug-in that asks the process to exit -----------------------------------------------------


@pytest.mark.parametrize("where", ["import", "factory"])
def test_a_plugin_that_raises_system_exit_is_one_line_and_exit_2(
    tmp_path, monkeypatch, capsys, where
):
    site = install_plugin(
        tmp_path / "site",
        f"sd_quitting_{where}",
        {"quitter": f"sd_quitting_{where}:make"},
        ("raise SystemExit(0)\n" if where == "import" else "")
        + "def make(context):\n    raise SystemExit(0)\n",
    )
    monkeypatch.syspath_prepend(str(site))
    monkeypatch.setattr(contract, "CONTROLLER_REGISTRY", {})
    scenario = tmp_path / "mine.yaml"
    scenario.write_text("controller: !UserController {factory: quitter}\n")
    argv = ["run", "--scenario", str(scenario), "--duration", "0.05", "--no-progress"]
    line = _one_line(capsys, [*argv, "--plugin", "quitter", "--out", str(tmp_path / "out")])
    assert "SystemExit" in line, line
    assert not list((tmp_path / "out").glob("run_*"))


def test_system_exit_anywhere_in_a_command_is_one_line_and_exit_2(tmp_path, monkeypatch, capsys):
    """A controller's own callback may exit the same way, inside the simulation."""
    from stewart_drake.run import simulate as experiments

    def exits(*args, **kwargs):
        raise SystemExit(0)

    monkeypatch.setattr(experiments, "run_experiment", exits)
    line = _one_line(capsys, ["run", "--duration", "0.05", "--out", str(tmp_path)])
    assert line.startswith("stewart-drake run: stopped by SystemExit(0)"), line


# Silent stages say what they do --------------------------------------------------------------


@pytest.mark.system
def test_the_command_s_first_line_says_what_it_does_before_drake_loads(tmp_path):
    """The installed command's first line on stderr names its first step, before Python imports
    pydrake (its -X importtime lines say when), once (the command starts itself again with its
    allocator's settings first); the rest of its output follows. Awaited as an event: a hang
    fails the test, a busy machine does not."""
    command = (
        [str(_SCRIPT)] if _SCRIPT.exists() else [sys.executable, "-m", "stewart_drake.cli.main"]
    )
    done = subprocess.run(
        [*command, "scenario", "--list"],
        cwd=tmp_path,
        env=dict(os.environ, PYTHONPATH=str(REPO), PYTHONPROFILEIMPORTTIME="1"),
        capture_output=True,
        text=True,
        timeout=HANG_S,
    )
    lines = done.stderr.splitlines()
    said = [k for k, line in enumerate(lines) if not line.startswith("import time:")]
    drake = next(k for k, line in enumerate(lines) if line.endswith(" pydrake"))
    assert done.returncode == 0 and "paper_hardware" in done.stdout, done.stderr[-2000:]
    assert [lines[k] for k in said] == [f"stewart-drake scenario: {options.STARTING}"]
    assert said[0] < drake, lines[said[0] - 2 : said[0] + 3]


def test_a_command_says_which_kernels_it_compiles_as_they_start_once_each(monkeypatch, capsys):
    """In the command's process, numba's first compilation of a module's kernels is said in
    one line just before it (numba's compile event: a kernel loaded from the cache says
    nothing), naming what they are; a second kernel of the module says nothing more, and a
    library's call of the command (not its process) says neither line."""
    import stewart_drake
    from stewart_drake.base import compiled
    from stewart_drake.run import scenario_io

    def kernel(x):
        return x + 1

    def other(x):
        return 2 * x

    for f in (kernel, other):  # as if written in the servo bus's kernels
        f.__module__ = "stewart_drake.station.bus.kernels"
    order = []

    def listing():  # scenario --list's first step, here compiling
        for f in (kernel, other):
            order.append(("compiled", compiled.njit_cached(f, cache=False)(1)))
        order.append(("said before", capsys.readouterr().err))
        return {}

    monkeypatch.setattr(scenario_io, "shipped_scenarios", listing)
    # The inputs' check before the work asks for the shipped scenarios too: not this test's.
    monkeypatch.setattr(cli, "command_inputs", lambda args: [])
    monkeypatch.setattr(compiled, "_announced", set())
    monkeypatch.setattr(stewart_drake, "_started_as_the_command", lambda: True)
    assert cli.main(["scenario", "--list"]) == 0
    err = order[-1][1].splitlines()
    assert err == [
        f"stewart-drake scenario: {options.STARTING}",
        "stewart-drake scenario: compiling the servo bus's per-period arithmetic (about 10 s) "
        "for this machine and Python (once: later runs load it from numba's disk cache)",
    ]
    assert order[:2] == [("compiled", 2), ("compiled", 2)]
    monkeypatch.setattr(compiled, "_announced", set())
    monkeypatch.setattr(stewart_drake, "_started_as_the_command", lambda: False)
    assert cli.main(["scenario", "--list"]) == 0
    assert order[-1][1] == ""
    import importlib.util

    # Every module the notes name exists (a renamed one would be said by its bare name).
    assert all(importlib.util.find_spec(m) for m in options.COMPILED_KERNELS)


def test_analyze_says_what_it_computes_and_draws(tmp_path, capsys):
    assert cli.main(["analyze", "--out", str(tmp_path)]) == 0
    captured = capsys.readouterr()
    assert captured.err.splitlines() == [
        "stewart-drake analyze: linearizing the loop and computing the margins of the 6 axes ...",
        "stewart-drake analyze: the plant gains and the delay the loop survives ...",
        "stewart-drake analyze: drawing the Bode and sensitivity plots of the 6 loops ...",
    ]
    assert "wrote" in captured.out
    record = json.loads((tmp_path / "loop.json").read_text())
    assert record["spectral_radius"] < 1
    # what the loop survives, said and written: holds or does NOT hold, never silent
    verdict = "holds" if record["robustness"]["holds"] else "does NOT hold"
    assert f"  {verdict} gain 0.5 to 2 with 6 ms more delay" in captured.out


def test_workspace_says_what_it_writes_after_the_sweep(tmp_path, capsys):
    argv = ["workspace", "--resolution", "5", "--runner", "serial", "--out", str(tmp_path)]
    assert cli.main(argv) == 0
    err = capsys.readouterr().err
    assert "stewart-drake workspace: writing workspace.npz and the CSV files" in err, err
    assert (tmp_path / "workspace.png").stat().st_size > 10_000
    assert cli.main([*argv, "--no-progress"]) == 0
    assert "writing workspace.npz" not in capsys.readouterr().err


def test_design_s_confirmation_runs_leave_their_divergence_logs_under_out(
    tmp_path, capsys, designed, monkeypatch
):
    """A base scenario whose guard.divergence_dir names a folder elsewhere: the confirmation
    runs' scenarios carry ``--out``'s ``diverged`` instead, as every other command's runs do;
    the written scenario files keep the base's own setting."""
    from stewart_drake.design import design_confirm

    requirements, finished = designed
    out = tmp_path / "out"
    shutil.copytree(finished, out)
    outside = tmp_path / "elsewhere"
    base = tmp_path / "base.yaml"
    setting = f"guard.divergence_dir={outside}"
    assert cli.main(["scenario", "paper_hardware", "--set", setting, "--out", str(base)]) == 0
    seen = []

    def run_motion(job):
        seen.append(job.scenario.guard.divergence_dir)
        return design_confirm._failed_row(job, "not run in this test")

    monkeypatch.setattr(design_confirm, "run_motion", run_motion)
    argv = ["design", str(requirements), "--out", str(out), "--scenario", str(base)]
    argv += [a for a in DESIGN if a != "--no-confirm"]
    assert cli.main(argv) == 0, capsys.readouterr().err
    assert seen and set(seen) == {str(out / "diverged")}, seen
    assert not outside.exists()
    written = (out / "design_objective.yaml").read_text()
    assert f"divergence_dir: {outside}" in written  # the user's scenario, as the user wrote it
