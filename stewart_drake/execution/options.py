"""What several commands share: argument types, the checks of an output before any work, the
``--scenario``/``--set``, runner and motion options with what they build (a trace's options:
:mod:`.trace_options`), and the notes a command prints on stderr before a silent stage (the
compiled LQI step, a stage of some seconds).

Every feature's command module (``<feature>/command.py``) imports it, and the command
(:mod:`stewart_drake.cli`) builds on them: it sits below the features, with the runners its
options build. It imports nothing of the features, and nothing heavy when imported: building the
parser reads no Drake beyond the names the options list, and a command's own imports run when it
runs.
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
from pathlib import Path


def int_at_least(lowest: int):
    """An argparse type: an integer of at least ``lowest``."""

    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected an integer, got {text!r}") from None
        if value < lowest:
            raise argparse.ArgumentTypeError(f"must be >= {lowest}, got {text}")
        return value

    parse.__name__ = f"integer >= {lowest}"
    return parse


def positive_float(text: str) -> float:
    """An argparse type: a number greater than 0 (the unit is the option's)."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None
    if not value > 0:
        raise argparse.ArgumentTypeError(f"must be > 0, got {text}")
    return value


def check_writable(folder: Path, option: str = "--out") -> None:
    """Make sure ``folder`` can be created (if missing) and written, without creating it.

    Walks up to the nearest existing ancestor and writes a temporary file there.
    Raises:
        InvalidConfigError: a file (or a link to one, or to nothing) stands in the path, or the
            nearest folder is not writable.
    """
    from ..base.errors import InvalidConfigError
    from ..base.fileio import describe_mode

    existing = folder.absolute()
    while not existing.exists() and not existing.is_symlink() and existing.parent != existing:
        existing = existing.parent
    try:
        if existing.is_symlink() and not existing.exists():
            raise NotADirectoryError(
                20, f"{existing} is a link to {os.readlink(existing)}, which does not exist"
            )
        if not existing.is_dir():
            kind = describe_mode(existing.stat().st_mode)
            raise NotADirectoryError(
                20, f"{existing} is {'a file' if kind == 'a regular file' else kind}"
            )
        with tempfile.TemporaryFile(dir=existing):
            pass
    except OSError as err:
        if not isinstance(err, NotADirectoryError):  # the folder, or where it would be made
            where = "there" if existing == folder.absolute() else f"in {existing}"
            raise InvalidConfigError(
                f"cannot write to {folder}: no file can be made {where} "
                f"({err.strerror or err}); choose another output with {option}"
            ) from None
        raise InvalidConfigError(
            f"cannot write to {folder}: {err.strerror or err}; choose another output with {option}"
        ) from None


def check_output(path, option: str = "--out", is_file: bool = False, sub=()) -> Path:
    """Refuse an output before any work: empty, a folder where a file is due, a device node, a
    FIFO or a socket (only regular files are replaced), or a place that cannot be written
    (:func:`check_writable`); ``sub`` names sub-folders the command writes into (``diverged``,
    ``rows``), checked too. Then remove the temporaries an earlier run killed mid-write left
    there (:func:`~stewart_drake.base.fileio.remove_stale_temporaries`). Returns the path.

    Raises:
        InvalidConfigError: names the option and what to change.
    """
    from ..base.errors import InvalidConfigError
    from ..base.fileio import check_replaceable, remove_stale_temporaries

    if path is None or not str(path).strip():
        raise InvalidConfigError(
            f"{option} is empty: give a {'file' if is_file else 'folder'} to write"
        )
    path = Path(path)
    if is_file and path.is_dir():
        raise InvalidConfigError(f"{option} {path} is a folder: give a file name to write")
    if is_file:
        check_replaceable(path, f"{option} {path}")
    check_writable(path.parent if is_file else path, option)
    for name in sub:
        check_writable(path / name, option)
    remove_stale_temporaries(path.parent if is_file else path, depth=0 if is_file else 1)
    return path


#: The options of the commands (argparse destinations) that name a file the command reads, or a
#: folder whose files it reads (``train --data``), with how a message names each: nothing a
#: command writes may be one of them (:func:`command_inputs`, :func:`check_outputs`).
INPUT_OPTIONS = {
    "scenario": "--scenario",
    "source": "the scenario",
    "trajectory_file": "--trajectory-file",
    "tuner_weights": "--tuner-weights",
    "reference": "the reference",
    "motion": "the motion",
    "learned": "--learned",
    "data": "--data",
    "requirements": "the requirements",
    "measured": "--measured",
    "surrogate": "--surrogate",
    "measured_surrogate": "--measured-surrogate",
    "registration": "--registration",
    "register": "--register",
    "measurements": "the measurements",
    "join": "--join",
    "plan_file": "--plan-file",
    "bench_logs": "the log",
}
#: The options that name a file a command writes, beside ``--out`` (each command checks them
#: as it checks its other outputs; :func:`check_outputs` holds them apart from the inputs first).
OUTPUT_FILE_OPTIONS = {
    "html": "--html",
    "save_learned": "--save-learned",
    "save_measurements": "--save-measurements",
    "plot": "--plot",
}


def _input_path(dest: str, value) -> Path | None:
    """The file an input option's ``value`` names, or None when it names none: a shipped
    scenario's name is its file, ``--learned library`` the shipped model, and a motion or a
    reference that is a name of the library (no suffix, no folder) no file, nor ``--surrogate
    model``."""
    if value is None or not str(value).strip():
        return None
    path = Path(str(value))
    if dest in ("scenario", "source") and not path.exists():
        from ..run.scenario_io import shipped_scenarios

        return shipped_scenarios().get(str(value))
    if dest in ("motion", "reference") and not is_trace_file(str(value)):
        return None
    if dest == "surrogate" and str(value) == "model":  # a correlation model, no file
        return None
    if dest == "learned" and str(value) == "library":
        from ..control.feedforward_basis import LIBRARY_MODEL

        return LIBRARY_MODEL
    return path


def command_inputs(args) -> list[tuple[str, Path]]:
    """(how a message names it, path) of every file or folder the command of ``args`` reads by
    its options (:data:`INPUT_OPTIONS`), and those its ``derived_inputs(args)`` adds (a file
    found beside one, e.g. ``--plan-file``'s windows file)."""
    found = []
    for dest, option in INPUT_OPTIONS.items():
        values = getattr(args, dest, None)
        for value in values if isinstance(values, (list, tuple)) else [values]:
            path = _input_path(dest, value)
            if path is not None:
                found.append((f"{option} {value}", path))
    derived = getattr(args, "derived_inputs", None)
    return found + (list(derived(args)) if derived is not None else [])


def check_input_names(inputs) -> None:
    """Refuse, before any work, an input whose name is not UTF-8 text (a byte such as 0xE9 of a
    Latin-1 name, read from the command line as a lone surrogate): every report, figure and
    record names the file, and none could write it.

    Args:
        inputs: :func:`command_inputs`'s (how a message names it, path).
    Raises:
        InvalidConfigError: naming the option, the byte and its place.
    """
    from ..base.checks import undecoded_byte
    from ..base.errors import InvalidConfigError

    for words, path in inputs:
        name = str(path)
        try:
            name.encode("utf-8")
        except UnicodeEncodeError as err:
            byte = undecoded_byte(name[err.start])
            shown = name.encode("utf-8", "backslashreplace").decode("ascii", "backslashreplace")
            raise InvalidConfigError(
                f"{words.split(' ', 1)[0]} {shown}: its name is not UTF-8 text (byte {byte} at "
                f"character {err.start + 1}: a Latin-1 name?); the reports name the file: "
                "rename it in UTF-8"
            ) from None


def check_outputs(args) -> None:
    """Every output the command of ``args`` names, checked before any work: ``--out``
    (:func:`check_output`, a file or a folder with its ``out_sub`` folders and the files
    ``out_files`` it writes there), and the other files it writes (:data:`OUTPUT_FILE_OPTIONS`)
    apart from its inputs. Call inside
    :func:`~stewart_drake.base.fileio.inputs_kept` (:func:`command_inputs`): an output that is
    one of the inputs (the same path, a link to it, a hard link) is refused naming both.

    Raises:
        InvalidConfigError: names the option, the output and what to change.
    """
    from ..base.fileio import check_not_an_input, check_replaceable

    for dest, option in OUTPUT_FILE_OPTIONS.items():
        value = getattr(args, dest, None)
        if value is not None and str(value).strip():
            check_not_an_input(value, f"{option} {value}")
    out = getattr(args, "out", None)
    if out is None:
        return
    check_output(out, "--out", getattr(args, "out_is_file", False), getattr(args, "out_sub", ()))
    for name in getattr(args, "out_files", ()):
        check_replaceable(Path(out) / name)


#: Folders of the operating system a report is never written into (nor anywhere below them),
#: even by a user allowed to: a report there is a mistake, and it would mix with system files.
SYSTEM_FOLDERS = (
    "/bin",
    "/boot",
    "/dev",
    "/etc",
    "/lib",
    "/lib32",
    "/lib64",
    "/proc",
    "/sbin",
    "/sys",
    "/usr",
    "/var/cache",
    "/var/lib",
    "/var/log",
    "/var/spool",
)


def refuse_system_folder(folder, option: str) -> None:
    """Refuse ``folder`` when it is the file system's root or in :data:`SYSTEM_FOLDERS`.

    Raises:
        InvalidConfigError: names the option, the folder and what to give instead.
    """
    from ..base.errors import InvalidConfigError

    resolved = Path(folder).expanduser().resolve()
    system = [s for s in SYSTEM_FOLDERS if resolved.is_relative_to(s)]
    if resolved == Path(resolved.anchor) or system:
        raise InvalidConfigError(
            f"{option} {folder}: {resolved} is a folder of the operating system; give a folder "
            "of your own (e.g. docs in a clone of the repository, or results/evaluation)"
        )


def say_if_compiling(command: str, module: str = "stewart_drake.control.lqi.kernels") -> None:
    """Import the compiled LQI step (``module``) now, saying so first on stderr when numba's
    cache holds no valid entry for it (:func:`~stewart_drake.control.kernel_cache.will_compile`):
    the first import on a machine compiles it for about 40 s, before anything else would show;
    with the cache warm it loads in about a second, however busy the machine, and says nothing.
    Called by a command once its arguments are checked, just before it needs the step."""
    import importlib

    from ..base.compiled import announced

    if module in sys.modules:
        return
    if _will_compile():
        print(
            f"stewart-drake {command}: compiling the LQI's control step for this machine and "
            f"Python (once, about 40 s; later runs start in seconds)",
            file=sys.stderr,
            flush=True,
        )
        announced("stewart_drake.control.lqi")  # said: not again as its modules compile
    importlib.import_module(module)


def _will_compile() -> bool:
    """Whether importing the LQI's compiled step compiles it (numba's cache, not a timer)."""
    from ..control.kernel_cache import will_compile

    return will_compile()


#: What compiling each module (or package) of the package's kernels is, for the line a command
#: says before it (:func:`compile_note`); the LQI's step says so itself (:func:`say_if_compiling`).
COMPILED_KERNELS = {
    "stewart_drake.station.bus.kernels": "the servo bus's per-period arithmetic (about 10 s)",
    "stewart_drake.robot.path_kernels": "the reference validator's per-pose arithmetic (about 7 s)",
    "stewart_drake.control.lqi": "the LQI's control step (about 40 s)",
    "stewart_drake.control.servo": "the crank servo's control step (about 5 s)",
}


def compile_note(command: str):
    """A function ``note(module)`` that says on stderr, in one line, that ``command`` compiles
    the kernels of ``module`` (a module's ``__name__``) for this machine and Python, what they
    are (:data:`COMPILED_KERNELS`) and that it is once: for
    :func:`~stewart_drake.base.compiled.announce_compiles`."""

    def note(module: str) -> None:
        what = next(
            (w for m, w in COMPILED_KERNELS.items() if module == m or module.startswith(m + ".")),
            f"the compiled code of {module}",
        )
        print(
            f"stewart-drake {command}: compiling {what} for this machine and Python (once: "
            "later runs load it from numba's disk cache)",
            file=sys.stderr,
            flush=True,
        )

    return note


#: What a command's process does first, said in its first line (:func:`say_starting`).
STARTING = "loading Drake and the command (seconds; longer on a busy machine)"


def say_starting(command: str | None) -> None:
    """The first line of a command's process, on stderr, before it loads Drake and its own
    modules (about 2 s of CPU, and on a loaded machine tens of seconds that showed nothing):
    what it does first (:data:`STARTING`). ``command``: the subcommand's name (None: none)."""
    name = f"stewart-drake {command}" if command else "stewart-drake"
    print(f"{name}: {STARTING}", file=sys.stderr, flush=True)


def say_stage(command: str):
    """A function that says on stderr what ``command`` does next, a stage of some seconds that
    shows nothing else (writing plots, building a Diagram)."""

    def say(what: str) -> None:
        print(f"stewart-drake {command}: {what}", file=sys.stderr, flush=True)

    return say


def default_scenario() -> str:
    """The scenario the commands use unless told (imported when the parser is built, so that
    importing this module loads no Drake: a Ctrl-C in the first second is then handled)."""
    from ..run.scenario_io import DEFAULT_SCENARIO

    return DEFAULT_SCENARIO


def add_scenario_arguments(parser, what: str, default: str | None = None) -> None:
    """``--scenario`` (default ``default``, or the commands' default scenario), ``--set`` and
    ``--temperature`` (an override of ``temperature_c`` among the ``--set`` ones, in the order
    given), the same for every command that starts from a scenario."""
    parser.add_argument(
        "--scenario",
        default=default or default_scenario(),
        metavar="FILE|NAME",
        help=f"{what}: a .yaml file or a shipped name ({default_scenario()}: the robot as "
        f"built; paper_ideal: the paper's ideal robot; `stewart-drake scenario --list`) "
        f"(default: {default or default_scenario()})",
    )
    parser.add_argument(
        "--set",
        action="append",
        metavar="KEY=VALUE",
        help="override a scenario field with a YAML value (repeatable): "
        "--set controller.omega_Q=10 --set 'controller=!PdDriver {}' "
        "(default: none)",
    )
    parser.add_argument(
        "--temperature",
        type=finite_float,
        action=_SetTemperature,
        dest="set",
        metavar="C",
        help="the robot's temperature, degrees C, during the run (its lengths, measured at "
        "robot.lengths_at_c, scaled to it; the controller told unless compensate_temperature "
        "is false) or, for calibrate, during the measurements (the robot written holds its "
        "lengths at it): --set temperature_c=C (default: none, the lengths as measured; "
        "docs/robot.md, Temperature)",
    )


def finite_float(text: str) -> float:
    """An argparse type: a finite number (the unit is the option's)."""
    try:
        value = float(text)
    except ValueError:
        value = float("nan")
    if value != value or value in (float("inf"), float("-inf")):
        raise argparse.ArgumentTypeError(f"expected a finite number, got {text!r}")
    return value


class _SetTemperature(argparse.Action):
    """``--temperature C``: appends ``temperature_c=C`` to the ``--set`` overrides."""

    def __call__(self, parser, namespace, values, option_string=None):
        overrides = list(getattr(namespace, self.dest, None) or [])
        setattr(namespace, self.dest, overrides + [f"temperature_c={values!r}"])


def add_runner_arguments(parser) -> None:
    """The options of a study's runner (:mod:`~stewart_drake.execution.runners`)."""
    from .clusters import DEFAULT_CONNECT_TIMEOUT_S
    from .runners import DEFAULT_RECYCLE, DEFAULT_RETRIES, RUNNERS

    parser.add_argument(
        "--runner",
        choices=RUNNERS,
        default="processes",
        help="where jobs run: local processes, this process, Ray or Dask",
    )
    parser.add_argument(
        "--jobs",
        type=int_at_least(0),
        default=0,
        help="workers: processes, or the CPUs of a local Ray or Dask cluster "
        "(default: 0, one per core)",
    )
    parser.add_argument(
        "--address",
        default=None,
        help="Ray cluster to join (--runner ray; default: start a local one)",
    )
    parser.add_argument(
        "--scheduler",
        default=None,
        help="Dask scheduler to join, tcp://host:8786 (--runner dask; default: "
        "start a local cluster)",
    )
    parser.add_argument(
        "--connect-timeout",
        type=positive_float,
        default=DEFAULT_CONNECT_TIMEOUT_S,
        metavar="S",
        help="seconds for --address or --scheduler to accept a connection",
    )
    parser.add_argument(
        "--retries",
        type=int_at_least(0),
        default=DEFAULT_RETRIES,
        help="attempts after the first for a job whose worker died",
    )
    parser.add_argument(
        "--recycle",
        type=int_at_least(0),
        default=None,
        help="jobs a worker runs before it is replaced, to bound leaked memory (processes and "
        "ray; 0: never; default: never for local processes where Drake frees a run's Diagram, "
        f"as drake 1.58 does, else {DEFAULT_RECYCLE})",
    )


def runner_from_args(args):
    """The runner of ``--runner``, ``--jobs``, ``--address``, ``--scheduler``, ``--retries``,
    ``--recycle``."""
    from .clusters import make_runner
    from .runners import AUTO_RECYCLE

    return make_runner(
        args.runner,
        args.jobs,
        address=args.address,
        scheduler=args.scheduler,
        retries=args.retries,
        recycle=AUTO_RECYCLE if args.recycle is None else args.recycle,
        connect_timeout_s=args.connect_timeout,
    )


#: The organ-motion library's motions as the parser's help lists them, written out: building the
#: parser reads no numpy (tests/test_organ_motion.py holds them equal to the library's).
LIBRARY_MOTIONS = (
    "breathing",
    "heartbeat",
    "breathing_heartbeat",
    "irregular_breathing",
    "hysteresis",
    "sawtooth",
    "sharkfin",
    "baseline_drift",
    "transient_excursion",
    "persistent_excursion",
    "breath_hold",
    "registration",
)


def add_param_argument(parser, help: str) -> None:
    """``--param KEY=VALUE`` (repeatable): a library motion's parameters with their units, as
    :func:`~stewart_drake.execution.trace_options.key_values` reads them; ``help`` says whose."""
    parser.add_argument("--param", action="append", metavar="KEY=VALUE", help=help)


def add_motion_arguments(parser, named: str | None = None) -> None:
    """The motion a command drives or judges, one definition for ``reproduce``, ``verify`` and
    ``robot``: the positional ``motion`` (a motion of the organ-motion library or a trace file),
    ``--param`` (its parameters, with units) and ``--add`` (library motions laid on it);
    :func:`~stewart_drake.organ_motion.command.motion_reference` turns them into a scenario's
    reference. With ``named`` (text listing reference names the command also takes, e.g.
    ``robot``'s trajectories) the motion may also be one of those, and may be left out: the
    scenario's reference then stands."""
    motion = (
        f"{', '.join(LIBRARY_MOTIONS)}, or a trace file: text with a header naming columns and "
        "units (commas, semicolons, tabs or spaces; decimal points or commas), a motion "
        "phantom's 7-column (t LR SI AP [mm] rLR rSI rAP [deg]) or 2-column surrogate file, or "
        "t,phi,theta,psi,X,Y,Z"
    )
    if named is None:
        parser.add_argument("motion", help=motion)
    else:
        parser.add_argument(
            "motion",
            nargs="?",
            default=None,
            help=f"{named}; a library motion: {motion} (default: the scenario's reference)",
        )
    add_param_argument(
        parser,
        "a library motion's parameter with its unit (repeatable): "
        "amplitude=15mm, period=4s, shape=3, direction=SI, tilt=2deg, "
        "heart_rate=72bpm, heart_amplitude=2mm, seed=1 (default: the "
        "motion's own); a key goes to the motion (or --add layer) that has it, "
        "or to the one written in front: heartbeat.amplitude=2mm",
    )
    parser.add_argument(
        "--add",
        action="append",
        metavar="MOTION",
        help="lay a library motion on the motion or trace (repeatable): "
        "baseline_drift, transient_excursion, persistent_excursion, heartbeat...; "
        "its parameters by --param (drift=3mm) (default: none)",
    )


def is_trace_file(source: str) -> bool:
    """Whether ``reproduce``'s motion names a file (a name with a suffix or a folder, or an
    existing file) rather than a motion of the library (plain names)."""
    path = Path(source)
    return bool(path.suffix) or len(path.parts) > 1 or path.is_file()
