"""The ``stewart-drake`` command: run the paper's experiment, sweep the workspace, and more.

Each subcommand parses its arguments here and calls the functions of the modules that own the idea
(imported when the subcommand runs, so `stewart-drake sdf` does not pay for torch or the Simulator);
bad arguments and our typed errors end in a one-line message and a non-zero exit, no traceback:
exit 2 for bad arguments and StewartError (refused input, a diverged run, a results folder of
other settings or in use by another study, lost jobs), 1 for a file that cannot be read or
written, 130 for Ctrl-C, 143 for SIGTERM and 129 for SIGHUP (128 + the signal: every command
handles the three alike, within a second or two). Every output (folder, file, the sub-folders a
command writes into) is checked before any work starts, so a long run never ends in a failed
save and a device node, FIFO or socket is never replaced; the hidden temporaries a killed write
left there (the tool's own, whose writer is gone) are removed.
"""

from __future__ import annotations

import argparse
import math
import os
import signal
import sys
import tempfile
import threading
from pathlib import Path

from ..base.errors import StewartError

#: Subcommands whose finished jobs are on disk as they arrive (run again: only the rest runs),
#: with the folder under ``--out`` that keeps them.
RESUMABLE = {"collect": "", "evaluate": "", "design": "search"}


class _HelpFormatter(argparse.HelpFormatter):
    """Every option's help ends with its default, ``(default: ...)``, unless it says its default
    itself (an option whose default is None says what applies then, e.g. "the scenario's")."""

    def _get_help_string(self, action):
        text = action.help or ""
        if (
            "default" in text
            or any(action.default is v for v in (None, False, argparse.SUPPRESS))
            or not action.option_strings
        ):
            return text
        return text + " (default: %(default)s)"


class _Parser(argparse.ArgumentParser):
    """argparse with a one-line error (argparse prints the usage block first) and the defaults
    in the help (:class:`_HelpFormatter`)."""

    def __init__(self, *args, **kwargs):
        kwargs.setdefault("formatter_class", _HelpFormatter)
        super().__init__(*args, **kwargs)

    def error(self, message: str):
        self.exit(2, f"{self.prog}: error: {message} (see {self.prog} --help)\n")


def version_text() -> str:
    """``stewart-drake --version``: this package's, Drake's and Python's versions."""
    from importlib.metadata import PackageNotFoundError, version

    from .. import __version__

    try:
        drake = version("drake")
    except PackageNotFoundError:  # a Drake built from source
        drake = "not from pip"
    return (
        f"stewart-drake {__version__} (drake {drake}, Python "
        f"{'.'.join(map(str, sys.version_info[:3]))})"
    )


def _int_at_least(lowest: int):
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


def _tcp_port(text: str) -> int:
    """A TCP port, 1..65535 (Meshcat would otherwise pick another port without a word)."""
    port = _int_at_least(1)(text)
    if port > 65535:
        raise argparse.ArgumentTypeError(f"a TCP port is at most 65535, got {text}")
    return port


def _realtime_rate(text: str) -> float:
    """A target real-time rate: 0 (as fast as it goes) or at least the slowest pacing the
    scenario accepts (``simulator.target_realtime_rate``: the Simulator sleeps in C++, where a
    slower rate would ignore Ctrl-C)."""
    from ..run.scenario import MIN_REALTIME_RATE

    try:
        rate = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None
    if not (rate == 0.0 or MIN_REALTIME_RATE <= rate < float("inf")):
        raise argparse.ArgumentTypeError(
            f"must be 0 (as fast as it goes) or a finite rate of at least {MIN_REALTIME_RATE:g}, "
            f"got {text}"
        )
    return rate


def check_writable(folder: Path, option: str = "--out") -> None:
    """Make sure ``folder`` can be created (if missing) and written, without creating it.

    Walks up to the nearest existing ancestor and writes a temporary file there.
    Raises:
        InvalidConfigError: a file stands in the path, or the nearest folder is not writable.
    """
    from ..base.errors import InvalidConfigError
    from ..base.fileio import describe_mode

    existing = folder.absolute()
    while not existing.exists() and existing.parent != existing:
        existing = existing.parent
    try:
        if not existing.is_dir():
            kind = describe_mode(existing.stat().st_mode)
            raise NotADirectoryError(
                20, f"{existing} is {'a file' if kind == 'a regular file' else kind}"
            )
        with tempfile.TemporaryFile(dir=existing):
            pass
    except OSError as err:
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


def _positive_float(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None
    if not value > 0:
        raise argparse.ArgumentTypeError(f"must be > 0, got {text}")
    return value


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


def _refuse_system_folder(folder, option: str) -> None:
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


def _say_if_compiling(command: str, module: str = "stewart_drake.control.lqi_kernels") -> None:
    """Import the compiled LQI step (``module``) now, saying so first on stderr when numba's
    cache holds no valid entry for it (:func:`~stewart_drake.control.kernel_cache.will_compile`):
    the first import on a machine compiles it for about 40 s, before anything else would show;
    with the cache warm it loads in about a second, however busy the machine, and says nothing.
    Called by a command once its arguments are checked, just before it needs the step."""
    import importlib

    if module in sys.modules:
        return
    if _will_compile():
        print(
            f"stewart-drake {command}: compiling the LQI's control step for this machine and "
            f"Python (once, about 40 s; later runs start in seconds)",
            file=sys.stderr,
            flush=True,
        )
    importlib.import_module(module)


def _will_compile() -> bool:
    """Whether importing the LQI's compiled step compiles it (numba's cache, not a timer)."""
    from ..control.kernel_cache import will_compile

    return will_compile()


def _say_stage(command: str):
    """A function that says on stderr what ``command`` does next, a stage of some seconds that
    shows nothing else (writing plots, building a Diagram)."""

    def say(what: str) -> None:
        print(f"stewart-drake {command}: {what}", file=sys.stderr, flush=True)

    return say


def _why_failed(failed: list, base: str) -> str:
    """What the failed rows of an evaluation share, when it is known: the runs under a
    disturbance whose holding torque is beyond the motors' limit are lost by the sizing, not by
    the controllers ("" when there is nothing to say)."""
    from ..evaluation.evaluation_report import disturbance_holding_torques

    if not failed:
        return ""
    needs, limit = disturbance_holding_torques(base)
    beyond = {n for n, need in needs.items() if limit is not None and need > limit}
    lost = [r for r in failed if r["case"].get("condition") in beyond]
    if not lost:
        return ""
    names = ", ".join(sorted({r["case"]["condition"] for r in lost}))
    other = len(failed) - len(lost)
    return (
        f": {len(lost)} under {names}, which needs more holding torque than the motors' "
        f"{limit:.3f} N m: lost by the sizing, as results.md says"
        + (f"; {other} for other reasons" if other else "")
    )


def _default_scenario() -> str:
    """The scenario the commands use unless told (imported when the parser is built, so that
    importing this module loads no Drake: a Ctrl-C in the first second is then handled)."""
    from ..run.scenario_io import DEFAULT_SCENARIO

    return DEFAULT_SCENARIO


def has_torch() -> bool:
    """Whether torch (the [train] extra) can be imported, without importing it."""
    import importlib.util

    return importlib.util.find_spec("torch") is not None


def _cmd_sdf(args) -> int:
    from ..base.fileio import atomic_write
    from ..plant.plant import write_sdf

    text = write_sdf().encode()
    atomic_write(Path(args.out), lambda f: f.write(text))
    print(f"wrote {args.out}")
    return 0


def _cmd_mjcf(args) -> int:
    """``stewart-drake mjcf``: a scenario's robot as a MuJoCo MJCF (no MuJoCo needed to write):
    as built (rotor armature, servo friction, torque limit, encoder sensors) unless the scenario
    is the ideal robot."""
    from ..base.fileio import atomic_write
    from ..plant.mjcf import DEFAULT_INTEGRATOR, write_mjcf
    from ..run.plan import make_plan
    from ..run.scenario_io import load_scenario

    plan = make_plan(load_scenario(args.scenario, args.set or ()), with_reference=False)
    text = write_mjcf(
        plan.geometry,
        time_step=plan.plant_time_step_s,
        servo=plan.servo,
        torque_limit_Nm=plan.torque_limit_Nm,
    ).encode()
    atomic_write(Path(args.out), lambda f: f.write(text))
    built = (
        "the robot as built: rotor armature, friction, torque limit, encoders"
        if plan.servo is not None
        else "the ideal robot"
    )
    print(
        f"wrote {args.out} (MuJoCo MJCF of {args.scenario}, {built}; integrator "
        f"{DEFAULT_INTEGRATOR}, time step {1e3 * plan.plant_time_step_s:g} ms)"
    )
    return 0


def run_scenario(args):
    """The :class:`~stewart_drake.run.scenario.Scenario` of ``run``'s arguments: the
    ``--scenario`` file or name, then ``--set`` overrides, then the shorthand flags (each only
    when given), validated.

    Raises:
        InvalidConfigError: a bad override or value; ``--tuner-weights`` without ``--tuner ann``.
        MissingFileError: no such scenario, weights or CSV file.
    """
    from ..control.contract import use_entry_point_controllers
    from ..run.scenario_io import apply_run_options, load_scenario
    from ..run.simulate import DEFAULT_TUNER_OUT

    use_entry_point_controllers(args.plugin or ())
    scenario = load_scenario(args.scenario, args.set or ())
    return apply_run_options(
        scenario,
        duration_s=args.duration,
        trajectory=args.trajectory,
        trajectory_file=args.trajectory_file,
        controller=args.controller,
        omega_Q=args.omega_q,
        omega_R=args.omega_r,
        tuner=args.tuner,
        tuner_weights=args.tuner_weights,
        default_ann_weights=DEFAULT_TUNER_OUT,
        divergence_dir=Path(args.out) / "diverged",
    )


def run_stem(scenario, source: str | None = None, overrides=()) -> str:
    """``run_[<scenario>_]<reference>[_ann|_ratio|_tuned][_pd][_set<hash>]``: the name of a
    run's result files, from the scenario's reference, tuner and controller (``label``,
    ``run_suffix``), the scenario file or name ``source`` when it is not the default one, and a
    short hash of the ``--set`` overrides when there are any: two different runs never write
    the same files (the default run keeps ``run_paper``)."""
    import hashlib

    tuner = "" if scenario.tuner is None else scenario.tuner.run_suffix
    name = Path(str(source)).stem if source is not None else _default_scenario()
    prefix = "" if name == _default_scenario() else f"{name}_"
    digest = hashlib.sha256("\n".join(overrides).encode()).hexdigest()[:6]
    changed = f"_set{digest}" if overrides else ""
    return f"run_{prefix}{scenario.reference.label}{tuner}{scenario.controller.run_suffix}{changed}"


def _cmd_run(args) -> int:
    """``stewart-drake run``: simulate, print the figures, write .npz and .png into args.out."""
    from ..base.fileio import check_replaceable
    from ..paper.run_report import plot_fig7
    from ..run.metrics import format_metrics
    from ..run.result import export_result, save_result
    from ..run.simulate import run_experiment

    scenario = run_scenario(args)
    out = Path(args.out)
    if args.html is not None:
        check_output(args.html, "--html", is_file=True)
    stem = run_stem(scenario, args.scenario, args.set or ())
    for suffix in (".npz", ".png", ".csv", ".mat"):
        check_replaceable(out / f"{stem}{suffix}")
    if scenario.tuner is not None and scenario.tuner.weights_path() is not None:
        print(f"{scenario.tuner.kind} weights: {scenario.tuner.weights_path()}")
    say = None if args.no_progress else _say_stage("run")

    def on_checked() -> None:  # the run is refused, if it is, before this
        _say_if_compiling("run")
        if say is not None:
            say("building the Drake station and its controller, starting the simulator ...")

    if args.html:  # the same run, replayed into a standalone HTML
        from ..viz.visualize import record_html

        _say_if_compiling("run")
        result, html = record_html(scenario, args.html, progress=not args.no_progress)
        print(f"wrote {html} (Meshcat replay, opens in any browser)")
    else:
        result = run_experiment(scenario, progress=not args.no_progress, on_checked=on_checked)
    print(format_metrics(result.metrics), flush=True)  # before the files: a full disk keeps them
    if say is not None:
        say(f"writing {stem}.npz, drawing Fig. 7 ({stem}.png), the logs as CSV and MAT ...")
    npz = save_result(result, out / f"{stem}.npz")
    png = plot_fig7(result, out / f"{stem}.png")
    csv, mat = export_result(result, out / stem)
    print(f"wrote {npz} and {png}; the logs as a table: {csv} and {mat}")
    return 0


def _cmd_check(args) -> int:
    """``stewart-drake check``: every check of a reference, over time, without simulating."""
    from ..analysis.feasibility import check, plot_margins
    from ..base.errors import InvalidConfigError
    from ..references.trajectories import TRAJECTORIES, NamedReference
    from ..run.scenario_io import load_scenario

    source = args.reference
    trace = None  # a reference file, read once: its length and the reference checked
    if _is_trace_file(source) and Path(source).suffix.lower() not in (".yaml", ".yml"):
        scenario = load_scenario(args.scenario, args.set or ())
        scenario.reference = reading = _trace_reference(args, source)
        reading.validate()  # the options, before the file is read
        trace = reading.load()  # read as reproduce reads it
        if args.duration is None:  # as long as the file, as `run` and `reproduce` take it
            scenario.duration_s = trace.end_time - getattr(trace, "start_time", 0.0)
        scenario.validate()
        info = getattr(trace, "info", None)
        if info is not None:
            print(f"Trace: {info.summary()}")
    elif _trace_options_given(args):
        raise InvalidConfigError(
            f"{_TRACE_ONLY} are for a trace file; {source!r} is a named trajectory or a scenario"
        )
    elif source in TRAJECTORIES:
        scenario = load_scenario(args.scenario, args.set or ())
        scenario.reference = NamedReference(source)
    else:  # a scenario file or a shipped scenario's name
        scenario = load_scenario(source, args.set or ())
    if args.duration is not None:
        scenario.duration_s = args.duration
    report = check(scenario, reference=trace)
    print(report.summary())
    name = Path(source).stem
    png = plot_margins(
        report,
        Path(args.out) / f"check_{name}.png",
        f"{name} on {Path(str(args.scenario)).stem}, {scenario.duration_s:g} s",
    )
    print(f"wrote {png}")
    return 0 if report.ok else 2


def _key_values(items, option: str) -> dict:
    """{key: value} of repeated ``KEY=VALUE`` options (values kept as text)."""
    from ..base.errors import InvalidConfigError

    out = {}
    for item in items or ():
        key, sep, value = item.partition("=")
        if not sep or not key.strip() or not value.strip():
            raise InvalidConfigError(f"{option} takes KEY=VALUE, got {item!r}")
        out[key.strip()] = value.strip()
    return out


#: The options of :func:`_add_trace_arguments` a motion that is not a trace file refuses.
_TRACE_ONLY = "--format, --columns, --map, --lowpass-hz, --centre, --centre-on, --max-gap"


def _trace_options_given(args) -> bool:
    """Whether any option of :func:`_add_trace_arguments` differs from its default."""
    return bool(
        args.format != "auto"
        or args.columns
        or args.map
        or args.lowpass_hz
        or args.centre is not None
        or args.centre_on != "mean"
        or args.max_gap != 1.0
    )


def _trace_reference(args, source: str, add: dict | None = None):
    """The :class:`~stewart_drake.references.traces.TraceReference` of the trace file
    ``source`` read as the options of :func:`_add_trace_arguments` say, with library motions
    ``add`` laid on it."""
    from ..base.errors import InvalidConfigError
    from ..references.traces import TraceReference

    centre = [0.0, 0.0, 0.0, 0.0, 0.0, 0.30]
    if args.centre is not None:
        try:
            centre = [float(v) for v in args.centre.split(",")]
        except ValueError:
            raise InvalidConfigError(
                f"--centre takes six numbers phi,theta,psi,X,Y,Z (rad, m), got {args.centre!r}"
            ) from None
    return TraceReference(
        path=source,
        axis_map=_key_values(args.map, "--map"),
        centre=centre,
        centre_on=args.centre_on,
        lowpass_hz=args.lowpass_hz or 0.0,
        max_gap_s=args.max_gap,
        format=args.format,
        columns=args.columns or "",
        add=dict(add or {}),
    )


def _is_trace_file(source: str) -> bool:
    """Whether ``reproduce``'s motion names a file (a name with a suffix or a folder, or an
    existing file) rather than a motion of the library (plain names)."""
    path = Path(source)
    return bool(path.suffix) or len(path.parts) > 1 or path.is_file()


def _cmd_reproduce(args) -> int:
    """``stewart-drake reproduce``: a motion of the organ-motion library or a recorded trace on
    the robot, checked, run (learning on request) and measured: a report with a verdict."""
    from ..base.errors import InvalidConfigError
    from ..base.fileio import check_replaceable
    from ..organ_motion.fidelity import parse_tolerance, reproduce, verdict, write_report
    from ..references.organ_motion import OrganMotionReference, split_parameters
    from ..run.scenario_io import load_scenario

    tolerance = parse_tolerance(args.tolerance)
    scenario = load_scenario(args.scenario, args.set or ())
    source = args.motion
    params = _key_values(args.param, "--param")
    layers = list(args.add or ())
    if len(set(layers)) != len(layers):
        raise InvalidConfigError(f"--add takes each motion once, got {', '.join(layers)}")
    if _is_trace_file(source):
        if params and not layers:
            raise InvalidConfigError(
                "--param sets a library motion's parameters (of one added with --add on a "
                f"trace); a trace takes {_TRACE_ONLY}"
            )
        scenario.reference = _trace_reference(
            args, source, dict(zip(layers, split_parameters(layers, params)))
        )
        name = "+".join([Path(source).stem, *layers])
        size = Path(source).stat().st_size if Path(source).is_file() else 0
        if size > 1e6 and not args.no_progress:  # a few seconds to read and resample
            from ..base.checks import format_bytes

            print(f"reading {source} ({format_bytes(size)})", file=sys.stderr, flush=True)
    else:
        if _trace_options_given(args):
            raise InvalidConfigError(
                f"{_TRACE_ONLY} are for a trace file; a library motion takes --param"
            )
        shares = split_parameters([source, *layers], params)
        scenario.reference = OrganMotionReference(
            motion=source, parameters=shares[0], add=dict(zip(layers, shares[1:]))
        )
        name = "+".join([source, *layers])
    scenario.guard.divergence_dir = str(Path(args.out) / "diverged")
    scenario.validate()
    out = Path(args.out)
    for suffix in (".md", ".png", ".json"):
        check_replaceable(out / f"reproduce_{name}{suffix}")
    feedforward = _feedforward_choice(args, scenario)
    if args.html is not None:
        check_output(args.html, "--html", is_file=True)
    rep = reproduce(
        scenario,
        learn_cycles=args.learn_cycles,
        eval_cycles=args.cycles,
        scale_to_fit=args.scale_to_fit,
        duration_s=args.duration,
        progress=not args.no_progress,
        feedforward=feedforward,
        on_checked=lambda: _say_if_compiling("reproduce"),
    )
    if args.save_learned and rep.learned is not None:
        from ..control.feedforward_tuning import save_learned

        print(f"wrote {save_learned(args.save_learned, rep.learned)} (the learned feed-forward)")
    if rep.scale != 1.0:
        print(
            f"{name} did not fit the robot: scaled by {rep.scale:.3f} about its centre "
            f"(every check passes at that size)"
        )
    fid = rep.fidelity
    print(
        f"RMS error over t = {fid['window_s'][0]:.4g}-{fid['window_s'][1]:.4g} s: translation "
        f"{fid['rms_translation_m'] * 1e6:.3g} um, rotation {fid['rms_rotation_rad'] * 1e6:.3g} "
        f"urad; lag {fid['lag_all_s'] * 1e3:.3g} ms",
        flush=True,
    )
    md, png, js = write_report(rep, out, tolerance)
    ok, line = verdict(fid, tolerance)
    print(line)
    print(f"wrote {md}, {png} and {js}")
    if args.html:  # the run's plant-state log, replayed with the reference's ghost
        from ..organ_motion.fidelity_replay import reproduction_html
        from ..run.plan import make_plan

        geometry = make_plan(scenario, with_reference=False).plant_geometry
        html = reproduction_html(rep, geometry, args.html, tolerance)
        print(f"wrote {html} (Meshcat replay with the reference's ghost and the error)")
    return 0 if ok else 2


def _feedforward_choice(args, scenario):
    """The feed-forward learner ``reproduce``'s flags ask for (None: none), checked before the
    run: ``--feedforward``, ``--learned FILE`` (read now: numbers only), ``--hold``,
    ``--save-learned FILE``; the scenario's own ``learning`` when it is one, applied as ``run``
    applies it when it names a model (``learned_from``)."""
    from ..base.errors import InvalidConfigError
    from ..control.feedforward_tuning import FeedforwardTuning, load_learned

    ff = scenario.learning if isinstance(scenario.learning, FeedforwardTuning) else None
    flags = args.feedforward or args.learned or args.hold or args.save_learned
    if not flags and not (ff is not None and ff.learned_from):
        return None
    if args.learn_cycles:
        raise InvalidConfigError(
            "--learn-cycles learns per cycle; --feedforward, --learned, --hold and "
            "--save-learned (or the scenario's learning.learned_from) learn as a function of "
            "the reference: choose one"
        )
    if args.hold and not (args.learned or (ff is not None and ff.learned_from)):
        raise InvalidConfigError("--hold applies a model learned before: give --learned FILE")
    ff = ff or FeedforwardTuning()
    if args.learned:
        ff.learned_from = str(args.learned)
    if ff.learned_from:
        load_learned(ff.learned_from)  # refused now, not after the run
    if args.hold:
        ff.learn = False
    elif args.feedforward or args.learned:
        ff.learn = True
    if args.save_learned:
        check_output(args.save_learned, "--save-learned", is_file=True)
    ff.validate(scenario.control_period_s)
    return ff


def _cmd_scenario(args) -> int:
    """``stewart-drake scenario``: list the shipped scenarios, or print one (with overrides) as
    YAML, to start a file of one's own."""
    from ..run.scenario import dump_scenario
    from ..run.scenario_io import load_scenario, shipped_scenarios

    if args.list:
        for name, path in sorted(shipped_scenarios().items()):
            print(f"{name:24s} {path}")
        return 0
    scenario = load_scenario(args.source, args.set or ())
    if args.out:
        dump_scenario(scenario, args.out)
        print(f"wrote {args.out}")
    else:
        print(dump_scenario(scenario), end="")
    return 0


def _runner(args):
    """The runner of ``--runner``, ``--jobs``, ``--address``, ``--scheduler``, ``--retries``,
    ``--recycle``."""
    from ..execution.runners import AUTO_RECYCLE, make_runner

    return make_runner(
        args.runner,
        args.jobs,
        address=args.address,
        scheduler=args.scheduler,
        retries=args.retries,
        recycle=AUTO_RECYCLE if args.recycle is None else args.recycle,
        connect_timeout_s=args.connect_timeout,
    )


def _cmd_collect(args) -> int:
    """``stewart-drake collect``: the 9 closed-loop runs of the tuner's data set."""
    from ..run.scenario_io import load_scenario
    from ..tuner.collection import collect

    base = load_scenario(args.scenario, args.set or ())
    runner = _runner(args)
    _say_if_compiling("collect")
    manifest = collect(
        args.out,
        seed=args.seed,
        duration_s=args.duration,
        runner=runner,
        progress=not args.no_progress,
        base=base,
    )
    print(
        f"{len(manifest['runs'])} runs, {manifest['n_samples']} samples in {args.out} "
        f"({manifest['ran']} run now, {manifest['reused']} found on disk)"
    )
    for run in manifest["runs"]:
        rms = run["rms_error"]
        head = f"  omega_Q={run['omega_Q']:<4g} omega_R={run['omega_R']:<4g} "
        if run.get("lost"):
            print(head + f"lost the platform ({run['lost']}); no data")
            continue
        print(
            head + f"RMS phi {1e3 * rms[0]:.3f} mrad, Z {1e3 * rms[5]:.3f} mm, "
            f"sum T^2 dt {run['sum_T2_dt']:.3g}"
        )
    if manifest["ran"]:
        print(
            f"speedup over one process: {manifest['speedup']:.2f} "
            f"({manifest['sum_job_s']:.1f} s of runs in {manifest['wall_s']:.1f} s wall, "
            f"{manifest['workers']} workers)"
        )
    return 0


def _cmd_train(args) -> int:
    """``stewart-drake train``: fit the tuner in both label modes, save one. The data are
    checked first, then that torch is there."""
    from ..base.errors import InvalidConfigError, MissingExtraError
    from ..tuner import collection

    records = collection.load_records(args.data)
    if len(records) < 2:
        raise InvalidConfigError(
            f"{len(records)} of the runs in {args.data} kept the platform (the others lost the "
            f"platform): too few to train on; collect with a scenario the motors can follow"
        )
    try:
        import torch  # noqa: F401 - only to say which extra is missing
    except ImportError:
        raise MissingExtraError(
            "`stewart-drake train` needs torch: install PyTorch's CPU build, then pip install "
            "'stewart-drake[train]' (README: Install)"
        ) from None
    from ..control.tuner import save_tuner
    from ..control.tuning import AnnTunerDriver
    from ..run.scenario import Scenario
    from ..tuner.training import build_dataset, train

    reports = {}
    for mode in ("paper", "best_cost"):
        dataset = build_dataset(records, mode=mode)
        model, report = train(
            dataset,
            seed=args.seed,
            metadata={
                "label_mode": mode,
                "data": str(args.data),
                "feature_window": AnnTunerDriver().feature_window,
                "feature_period_s": Scenario().control_period_s,
            },
        )
        reports[mode] = (model, report)
        r2 = report["val_r2"]
        r2_text = ", ".join(f"{k} {v:.3f}" for k, v in r2.items()) if isinstance(r2, dict) else r2
        print(
            f"{mode:>9} labels: {dataset.info['n_samples']} samples, val loss "
            f"{report['val_loss']:.4f} (from {report['val_loss_initial']:.4f}), "
            f"validation R^2: {r2_text}"
        )
    model, _ = reports[args.mode]
    out = Path(args.out)
    save_tuner(model, out)
    print(f"wrote {out} (label mode {args.mode})")
    return 0


def _cmd_evaluate(args) -> int:
    """``stewart-drake evaluate``: the grid in parallel, results.md and plots (in --out unless
    --docs names another folder)."""
    from ..evaluation.evaluation import evaluate
    from ..evaluation.evaluation_grid import CONTROLLERS, QUICK_CONTROLLERS, check_controllers
    from ..tuner.tuner_study import GOAL, StudyArm

    if args.controllers:
        controllers = tuple(args.controllers.split(","))
    else:
        controllers = QUICK_CONTROLLERS if args.quick else CONTROLLERS
    check_controllers(controllers)  # an unknown name, before the rest
    docs = args.out if args.docs is None else args.docs  # never the repository's docs/
    _refuse_system_folder(docs, "--docs")
    check_output(docs, "--docs")
    tuner_study = not (args.no_tuner_study or args.quick)
    if tuner_study and not has_torch():
        print(
            "stewart-drake evaluate: the tuner study is left out: it trains our tuner with "
            "torch (pip install 'stewart-drake[train]'); --no-tuner-study hides this note",
            file=sys.stderr,
        )
        tuner_study = False
    _say_if_compiling("evaluate")
    report = evaluate(
        docs,
        args.out,
        runner=_runner(args),
        progress=not args.no_progress,
        quick=args.quick,
        controllers=controllers,
        base=args.scenario,
        tuner_study=tuner_study,
    )
    failed = [r for r in report["rows"] if "error" in r]
    info = report["info"]
    print(
        f"{len(report['rows'])} runs ({info['ran']} run now in {report['wall_s']:.0f} s wall, "
        f"{info['reused']} found on disk; {len(failed)} failed{_why_failed(failed, args.scenario)})"
    )
    if report.get("tuner"):
        print("tuner study (held-out tasks, paired against the best fixed ratio per task):")
        for lam, v in report["tuner"]["verdicts"].items():
            ours = v["controllers"][StudyArm("ours", lam=float(lam)).label]
            head = v["controllers"][StudyArm("hindsight", lam=float(lam)).label]
            print(
                f"  lambda {lam}: ours {100 * ours['mean']:+.0f} % +- {100 * ours['std']:.0f} %"
                f" ({'meets' if ours['beats'] else 'does not meet'} the {100 * GOAL:.0f} % "
                f"goal); hindsight headroom {100 * head['mean']:+.0f} % +- "
                f"{100 * head['std']:.0f} %"
            )
    for ann, v in report["verdict"].items():
        b = v["best_fixed"]
        print(
            f"{ann}: nRMS {v['ann']['normalized_rms']:.3g}, "
            + (
                f"best fixed LQI at no more effort {b['case']['controller']} "
                f"{b['normalized_rms']:.3g} -> {'beats' if v['beats'] else 'does not beat'} it"
                if b
                else "no fixed LQI at that effort"
            )
        )
    print("wrote " + ", ".join(str(p) for p in report["paths"]))
    return 0


def _cmd_analyze(args) -> int:
    """``stewart-drake analyze``: the linear loop of the scenario's robot and LQI at a pose:
    margins, Ms, Mt, bandwidth and the phase lag at 0.25 and 1.2 Hz per axis; Bode and
    sensitivity plots and the table as Markdown in --out."""
    import functools
    import json

    from ..analysis.loop_analysis import (
        axis_figures,
        figures_table,
        loop_map,
        loop_models,
        plot_loop,
        plot_map,
        tilt_grid,
        weakest_pose,
        weight_sweep,
    )
    from ..base.errors import InvalidConfigError
    from ..base.fileio import atomic_write
    from ..run.scenario_io import load_scenario

    scenario = load_scenario(args.scenario, args.set or ())
    x0 = None
    if args.pose is not None:
        try:
            x0 = [float(v) for v in args.pose.split(",")]
        except ValueError:
            x0 = []
        if len(x0) != 6:
            raise InvalidConfigError(
                f"--pose takes six numbers phi,theta,psi,X,Y,Z (rad, m), got {args.pose!r}"
            )
    out = check_output(args.out)
    say = _say_stage("analyze")
    say("linearizing the loop and computing the margins of the 6 axes ...")
    models = loop_models(scenario, x0, integrator=args.integrator)
    figures = axis_figures(models)
    name = Path(str(args.scenario)).stem
    pose = ", ".join(f"{v:.4g}" for v in models.x0)
    table = figures_table(figures)
    rho = models.spectral_radius
    print(
        f"{name} at pose [{pose}] (rad, m), control period {1e3 * models.h:g} ms: the closed "
        f"loop is {'stable' if rho < 1 else 'UNSTABLE'} (spectral radius {rho:.4f})"
        + ("" if rho < 1 else ": the margins below describe an unstable loop")
    )
    print("\n".join(table))
    out.mkdir(parents=True, exist_ok=True)
    title = f"{name} at [{pose}]: linear loop (stewart-drake analyze)"
    say("drawing the Bode and sensitivity plots of the 6 loops ...")
    bode, sens = plot_loop(models, title)
    paths = [out / "bode.png", out / "sensitivity.png", out / "loop.md", out / "loop.json"]
    for fig, path in zip((bode, sens), paths):
        atomic_write(path, functools.partial(fig.savefig, dpi=100, format="png"))
    text = "\n".join([f"# {title}", "", *table, ""]).encode()
    atomic_write(paths[2], lambda fh: fh.write(text))
    record = {
        "scenario": name,
        "pose": models.x0.tolist(),
        "spectral_radius": rho,
        "axes": [a.record() for a in figures],
    }
    if args.weights:
        say("the margins for omega_Q / omega_R = 0.01, 0.1, 1, 10, 100 ...")
        record["weights"] = weight_sweep(scenario, x0=models.x0)
        print(
            "omega_Q / omega_R: closed loop, smallest phase margin (axis), largest Ms (axis), "
            "Z bandwidth Hz"
        )
        for row in record["weights"]:
            pm = min(row["axes"], key=lambda a: a["phase_margin_deg"])
            ms = max(row["axes"], key=lambda a: a["Ms"])
            bw = row["axes"][5]["bandwidth_hz"]
            print(
                f"  {row['ratio']:g}: {'stable' if row['stable'] else 'UNSTABLE'} (spectral "
                f"radius {row['spectral_radius']:.4f}), {pm['phase_margin_deg']:.1f} deg "
                f"({pm['axis']}), {ms['Ms']:.2f} ({ms['axis']}), "
                + (f"{bw:.3g}" if bw is not None else row["axes"][5]["bandwidth_where"])
            )
    if args.map:
        say("the margins over 9 x 9 roll and pitch tilts, then map.png ...")
        rows = loop_map(scenario, tilt_grid(height_m=float(models.x0[5])))
        record["map"] = rows
        weak = weakest_pose(rows)
        where = ", ".join(f"{v:.3g}" for v in weak["pose"])
        print(
            f"weakest of {len(rows)} admissible tilts: pose [{where}]: Ms {weak['Ms']:.2f} "
            f"({weak['Ms_axis']}), phase margin {weak['phase_margin_deg']:.1f} deg "
            f"({weak['phase_margin_axis']}), gain margin {weak['gain_margin_db']:.1f} dB "
            f"({weak['gain_margin_axis']}), spectral radius {weak['spectral_radius']:.4f}"
        )
        fig = plot_map(rows, f"{name}: the loop over roll and pitch at Z = {models.x0[5]:g} m")
        paths.append(out / "map.png")
        atomic_write(paths[-1], functools.partial(fig.savefig, dpi=100, format="png"))
    data = json.dumps(record, indent=1, default=float).encode()
    atomic_write(paths[3], lambda fh: fh.write(data))
    print("wrote " + ", ".join(str(p) for p in paths))
    return 0


#: The coarsest workspace grid whose extents are worth reporting (a step of 1/20 of the box).
MIN_REPORTED_RESOLUTION = 21


def _cmd_workspace(args) -> int:
    """``stewart-drake workspace``: sweep the scenario's robot, write PNG, npz and CSV."""
    from ..analysis.workspace import write_workspace
    from ..run.plan import make_plan
    from ..run.scenario_io import load_scenario

    scenario = load_scenario(args.scenario, args.set or ())
    plan = make_plan(scenario, with_reference=False)
    geometry = plan.geometry
    if args.resolution < MIN_REPORTED_RESOLUTION:
        print(
            f"stewart-drake workspace: --resolution {args.resolution} is coarse: each extent "
            f"is known only to within a step of 1/{args.resolution - 1} of the box; use "
            f"{MIN_REPORTED_RESOLUTION} or more for figures to report",
            file=sys.stderr,
        )
    rows = write_workspace(
        args.out,
        args.resolution,
        args.jobs,
        progress=not args.no_progress,
        geometry=geometry,
        runner=_runner(args),
        motor_limits=plan.motor_limits,
        say=None if args.no_progress else _say_stage("workspace"),
    )
    for name, value, unit in rows[:11]:
        print(f"{name} {value} {unit}")
    print(
        f"wrote {args.out}/workspace.png, bottleneck_and_orientation.png, workspace.npz, "
        f"summary.csv, tilt_vs_height.csv"
    )
    return 0


def _cmd_design(args) -> int:
    """``stewart-drake design``: search the design for a requirements file, write the report and
    the chosen designs' scenarios; exit 1 when no design within the bounds meets the task."""
    from ..design.design_study import run_design

    outcome = run_design(
        args.requirements,
        args.out,
        motor=args.motor,
        objective=args.objective,
        cheapest=not args.no_cheapest,
        confirm=not args.no_confirm,
        seed=args.seed,
        runner=_runner(args),
        popsize=args.popsize,
        maxiter=args.generations,
        base_scenario=args.scenario,
        progress=not args.no_progress,
    )
    for search in outcome.searches:
        name, margin = search.best.binding
        verdict = (
            f"best {search.objective} {search.best.objective(search.objective):.4g}"
            if search.feasible
            else f"no design meets the task (binding: {name} {margin:+.3g})"
        )
        print(f"{search.motor}: {verdict}; {search.evaluations} evaluations, {search.wall_s:.0f} s")
    print(f"wrote {args.out}/design.md and " + ", ".join(p.name for p in outcome.files[:-1]))
    if outcome.binding:
        print(
            f"stewart-drake design: no design within the bounds meets {args.requirements}: "
            f"binding constraint {outcome.binding}",
            file=sys.stderr,
        )
        return 1
    return 0


def _cmd_teleop(args) -> int:
    """``stewart-drake teleop``: the robot as built at real time in Meshcat, driven by sliders."""
    from pydrake.geometry import Meshcat, MeshcatParams

    from ..live.teleop import build_teleop, run_teleop
    from ..run.scenario_io import load_scenario

    scenario = load_scenario(args.scenario, args.set or ())
    scenario.guard.divergence_dir = str(Path(args.out) / "diverged")
    params = MeshcatParams()
    if args.port is not None:
        params.port = args.port
    try:
        meshcat = Meshcat(params)
    except RuntimeError as err:  # the port is taken
        from ..base.errors import InvalidConfigError

        raise InvalidConfigError(
            f"Meshcat cannot listen on port {args.port}: {err} Choose "
            f"another --port, or leave it out for the first free one"
        ) from None
    _say_if_compiling("teleop")
    run = build_teleop(scenario, meshcat, realtime_rate=args.realtime_rate)
    how = f"for {args.duration:g} s" if args.duration else "until Ctrl-C"
    print(
        f"open {meshcat.web_url()} ; the sliders roll [rad] .. z [m] set the pose (keys Q/E W/S "
        f"A/D J/L I/K U/O), the gauges show the tracking error and the margins, the button "
        f"'pause / resume' (key P) stops the time; running {how}"
    )
    stats = run_teleop(run, args.duration)
    if "interrupted_by" in stats:  # the statistics are printed; say what ended it
        signum = stats["interrupted_by"]
        print(
            f"stewart-drake teleop: interrupted by {signal.Signals(signum).name} after "
            f"{stats['sim_s']:.1f} s simulated; nothing else to keep",
            file=sys.stderr,
        )
        return 128 + signum
    return 0


def _robot_reference(args, scenario):
    """``robot``'s REFERENCE onto ``scenario``: a name of
    :data:`~stewart_drake.references.trajectories.TRAJECTORIES` ("home" holds the home pose),
    a recorded trace or a CSV file; None keeps the scenario's."""
    from ..references.trajectories import TRAJECTORIES, NamedReference

    source = args.reference
    if source is None:
        return
    if source in TRAJECTORIES:
        scenario.reference = NamedReference(source)
    elif _is_trace_file(source):
        from ..references.traces import TraceReference

        scenario.reference = TraceReference(path=source)
    else:
        from ..base.errors import InvalidConfigError

        raise InvalidConfigError(
            f"robot takes a reference name ({', '.join(TRAJECTORIES)}), a trace or a CSV "
            f"file, got {source!r}"
        )


def _start_emulator(scenario, x0):
    """Start the bus emulator with the scenario's robot (its Drake plant at a 2 ms step, half
    the CPU of 1 ms) behind it in a process of its own, resting at pose ``x0``, and point
    ``scenario.bus`` at its pseudo-terminal; returns the
    :class:`~stewart_drake.live.emulator_process.EmulatorProcess` (close it)."""
    import copy
    import dataclasses

    from ..live.emulator_process import EmulatorProcess

    bus = scenario.bus
    plant = copy.copy(scenario.plant)
    plant.time_step = 0.002
    robot = dataclasses.replace(
        scenario,
        bus=None,
        plant=plant,
        control_period_s=0.002,
        log_period_s=0.002,
    )
    emulator = EmulatorProcess(
        x0=x0,
        ids=bus.ids,
        model=bus.model,
        scenario=robot,
        zero_counts=bus.zero_counts,
        start_timeout_s=300.0,
    ).start()
    bus.port = emulator.port
    return emulator


def _cmd_robot(args) -> int:
    """``stewart-drake robot``: the closed loop on the servos of the scenario's ``bus`` (or on
    the bus emulator with ``--emulate``): a dry run, or homing then the reference, with torque
    off and one line at every end."""
    from ..base.fileio import check_replaceable
    from ..live.session import SessionSignals
    from ..run.scenario_io import load_scenario

    if args.teleop and (args.reference is not None or args.dry_run):
        from ..base.errors import InvalidConfigError

        raise InvalidConfigError("--teleop takes no reference (the sliders are one) nor --dry-run")
    scenario = load_scenario(args.scenario, args.set or ())
    _robot_reference(args, scenario)
    if args.duration is not None:
        scenario.duration_s = args.duration
    if args.port is not None:
        if scenario.bus is None:
            from ..station.bus.servos import DynamixelBusConfig

            scenario.bus = DynamixelBusConfig(port=args.port)
        else:
            scenario.bus.port = args.port
    scenario.guard.divergence_dir = str(Path(args.out) / "diverged")
    scenario.validate()
    out = Path(args.out)
    stem = f"robot_{scenario.reference.label}" if args.reference else "robot"
    if not args.dry_run and args.calibrate is None:
        check_replaceable(out / f"{stem}.npz")
    from ..station.bus.driver import dynamixel_sdk

    dynamixel_sdk()  # the extra, before anything starts: MissingExtraError names it
    if args.calibrate is not None:
        _check_calibration_angle(scenario, args.calibrate)
    if args.emulate is not None:
        if scenario.bus is None:
            from ..station.bus.servos import DynamixelBusConfig

            scenario.bus = DynamixelBusConfig()
        _check_emulated_pose(scenario, args.emulate)
    if not args.dry_run and args.calibrate is None:
        # Loaded (or compiled) before anything is powered: a first load inside the first
        # control period would trip our watchdog.
        _say_if_compiling("robot")
    with SessionSignals() as signals:  # held from the torque-off through the end line
        return _robot_session(args, scenario, out, stem, signals)


def _check_calibration_angle(scenario, angle_deg: float) -> None:
    """Refuse ``--calibrate DEG`` outside the cranks' travel (the scenario's
    ``robot.motor_angle_min_deg`` .. ``motor_angle_max_deg``), or not finite.

    Raises:
        InvalidConfigError: names the range.
    """
    from ..base.errors import InvalidConfigError

    lo, hi = scenario.robot.motor_angle_min_deg, scenario.robot.motor_angle_max_deg
    if not (math.isfinite(angle_deg) and lo <= angle_deg <= hi):
        raise InvalidConfigError(
            f"--calibrate {angle_deg:g}: the angle the cranks are held at must be a finite "
            f"number of degrees in the cranks' travel [{lo:g}, {hi:g}]"
        )


def _check_emulated_pose(scenario, x0) -> None:
    """Refuse ``--emulate POSE`` where the scenario's robot cannot be assembled (before a
    process is spawned for it).

    Raises:
        InvalidConfigError: not six finite numbers, or a pose out of the rods' reach (named).
    """
    import numpy as np

    from ..base.errors import InvalidConfigError, StewartError
    from ..robot.kinematics import ik
    from ..run.plan import make_plan

    try:
        ik(make_plan(scenario, with_reference=False).geometry, np.asarray(x0, dtype=float))
    except StewartError as err:
        raise InvalidConfigError(
            f"--emulate {','.join(f'{v:g}' for v in x0)}: the robot cannot rest there ({err})"
        ) from None


def _robot_session(args, scenario, out, stem, signals) -> int:
    """``robot``'s work once the scenario is checked: start the emulator (``--emulate``),
    calibrate, dry run, or a session, ending in the end line; closes the emulator."""
    from ..live.session import end_line, measure_pose, run_on_robot
    from ..run.metrics import format_metrics

    emulator = None
    try:
        if args.emulate is not None:
            emulator = _start_emulator(scenario, args.emulate)
            print(f"bus emulator on {scenario.bus.port} (the robot's Drake plant at real time)")
        if args.calibrate is not None:
            from ..live.session import bus_config, zero_counts_at

            with bus_config(scenario).make_bus() as bus:
                zeros = zero_counts_at(bus, math.radians(args.calibrate))
            print(
                f"with every crank held at {args.calibrate:g} deg, put in the scenario's bus:\n"
                f"  zero_counts: [{', '.join(str(int(c)) for c in zeros)}]"
            )
            return 0
        if args.dry_run:
            measured = measure_pose(scenario)
            print(measured.summary())
            return 0 if measured.problem is None else 1
        meshcat = None
        if args.meshcat or args.teleop:
            from pydrake.geometry import Meshcat

            meshcat = Meshcat()
            print(f"open {meshcat.web_url()} to watch the robot at its measured pose")
        if args.teleop:
            from ..live.session import teleop_on_robot

            run = teleop_on_robot(
                scenario,
                meshcat,
                duration_s=args.duration,
                loop_timeout_s=args.loop_timeout,
                signals=signals,
            )
        else:
            run = run_on_robot(
                scenario,
                home_s=args.home_s,
                hold_s=args.hold,
                loop_timeout_s=args.loop_timeout,
                out=out,
                stem=stem,
                meshcat=meshcat,
                progress=not args.no_progress,
                signals=signals,
            )
    finally:
        if emulator is not None:
            emulator.close()
    if run.metrics is not None:
        print(format_metrics(run.metrics))
    if run.timing_lines:
        print("control loop timing:\n  " + "\n  ".join(run.timing_lines))
    signals.settle(run)
    print(f"stewart-drake robot: {end_line(run)}", file=sys.stderr if not run.ok else sys.stdout)
    return run.exit_code


def _cmd_diagrams(args) -> int:
    """``stewart-drake diagrams``: rewrite diagrams/*.dot and render diagrams/*.svg."""
    from ..viz.visualize import write_diagrams

    for path in write_diagrams(args.out, render=not args.dot_only):
        print(f"wrote {path}")
    return 0


def _add_runner_arguments(parser) -> None:
    """The options of a study's runner (jobs/runners.py)."""
    from ..execution.runners import (
        DEFAULT_CONNECT_TIMEOUT_S,
        DEFAULT_RECYCLE,
        DEFAULT_RETRIES,
        RUNNERS,
    )

    parser.add_argument(
        "--runner",
        choices=RUNNERS,
        default="processes",
        help="where jobs run: local processes, this process, Ray or Dask",
    )
    parser.add_argument(
        "--jobs",
        type=_int_at_least(0),
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
        type=_positive_float,
        default=DEFAULT_CONNECT_TIMEOUT_S,
        metavar="S",
        help="seconds for --address or --scheduler to accept a connection",
    )
    parser.add_argument(
        "--retries",
        type=_int_at_least(0),
        default=DEFAULT_RETRIES,
        help="attempts after the first for a job whose worker died",
    )
    parser.add_argument(
        "--recycle",
        type=_int_at_least(0),
        default=None,
        help="jobs a worker runs before it is replaced, to bound leaked memory (processes and "
        "ray; 0: never; default: never for local processes where Drake frees a run's Diagram, "
        f"as drake 1.58 does, else {DEFAULT_RECYCLE})",
    )


def _add_scenario_arguments(parser, what: str, default: str | None = None) -> None:
    """``--scenario`` (default ``default``, or the commands' default scenario) and ``--set``,
    the same for every command that starts from a scenario."""
    parser.add_argument(
        "--scenario",
        default=default or _default_scenario(),
        metavar="FILE|NAME",
        help=f"{what}: a .yaml file or a shipped name ({_default_scenario()}: the robot as "
        f"built; paper_ideal: the paper's ideal robot; `stewart-drake scenario --list`) "
        f"(default: {default or _default_scenario()})",
    )
    parser.add_argument(
        "--set",
        action="append",
        metavar="KEY=VALUE",
        help="override a scenario field with a YAML value (repeatable): "
        "--set controller.omega_Q=10 --set 'controller=!PdDriver {}' "
        "(default: none)",
    )


def build_parser() -> argparse.ArgumentParser:
    """The ``stewart-drake`` parser: one sub-parser per command, each built by its own
    ``_add_<command>_command``."""
    from .. import __doc__ as summary

    parser = _Parser(
        prog="stewart-drake",
        description=summary.splitlines()[0] + " Run `stewart-drake COMMAND --help` for a "
        "command's options.",
    )
    parser.add_argument("--version", action="version", version=version_text())
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    _add_run_command(sub)
    _add_check_command(sub)
    _add_reproduce_command(sub)
    _add_scenario_command(sub)
    _add_collect_command(sub)
    _add_train_command(sub)
    _add_evaluate_command(sub)
    _add_workspace_command(sub)
    _add_design_command(sub)
    _add_analyze_command(sub)
    _add_teleop_command(sub)
    _add_robot_command(sub)
    _add_diagrams_command(sub)
    _add_sdf_command(sub)
    _add_mjcf_command(sub)
    return parser


def _add_run_command(sub) -> None:
    """The ``run`` command's options."""
    from ..references.trajectories import TRAJECTORIES
    from ..run.scenario import named_controllers

    run = sub.add_parser(
        "run",
        help="simulate a scenario (default: the paper's experiment on "
        "the robot as built) and plot Fig. 7",
    )
    _add_scenario_arguments(run, "the run")
    run.add_argument(
        "--duration",
        type=_positive_float,
        default=None,
        metavar="SECONDS",
        help="simulated time, s (default: the scenario's duration_s, 10 s in the "
        "shipped ones; with --trajectory-file, the file's length)",
    )
    run.add_argument(
        "--trajectory",
        default=None,
        choices=sorted(TRAJECTORIES),
        metavar="NAME",
        help=f"reference, one of: {', '.join(sorted(TRAJECTORIES))} (default: the "
        f"scenario's, paper)",
    )
    run.add_argument(
        "--trajectory-file",
        default=None,
        metavar="FILE.csv",
        help="reference from a CSV file with header t,phi,theta,psi,X,Y,Z (s, rad, "
        "m); the run lasts as long as the file unless --duration says "
        "otherwise (default: none)",
    )
    run.add_argument(
        "--controller",
        choices=sorted(named_controllers()),
        default=None,
        help="the LQI of the paper or the crank-space PD baseline (default: the scenario's, lqi)",
    )
    run.add_argument(
        "--omega-q",
        type=_positive_float,
        default=None,
        help="LQI omega_Q (default: the scenario's, 1)",
    )
    run.add_argument(
        "--omega-r",
        type=_positive_float,
        default=None,
        help="LQI omega_R (default: the scenario's, 1)",
    )
    run.add_argument(
        "--tuner",
        choices=["none", "ann", "ratio"],
        default=None,
        help="online tuner of the LQI's weights: ann, the paper's network; ratio, "
        "ours from the tuner study (default: the scenario's, none)",
    )
    run.add_argument(
        "--tuner-weights",
        default=None,
        metavar="FILE.npz",
        help="the tuner's weights (default: for ann, results/tuner/ann_tuner.npz "
        "if `train` wrote it, else the shipped ones; for ratio, the shipped "
        "lambda = 0.1 ones)",
    )
    run.add_argument("--out", default="results", help="output folder")
    run.add_argument("--no-progress", action="store_true", help="hide the progress bar")
    run.add_argument(
        "--html",
        default=None,
        metavar="FILE.html",
        help="also write a standalone Meshcat replay of the run to this file (default: none); "
        "Drake's Meshcat opens a web port on localhost while it records, unused",
    )
    run.add_argument(
        "--plugin",
        action="append",
        metavar="NAME",
        help="make the installed controller entry point NAME (group "
        "stewart_drake.controllers) available to the scenario's "
        "UserController (repeatable; default: none); a scenario never imports "
        "code itself",
    )
    run.set_defaults(func=_cmd_run, out_sub=("diverged",))


def _add_trace_arguments(parser) -> None:
    """The options that say how a trace file is read, one definition for every command that
    reads one (``check``, ``reproduce``): :func:`_trace_reference` turns them into a
    :class:`~stewart_drake.references.traces.TraceReference`."""
    # Written out, not imported from simulation.traces: building the parser reads no numpy
    # (tests/test_trace_formats.py holds them equal to TRACE_FORMATS, CENTRE_MODES, SKIP_COLUMN).
    parser.add_argument(
        "--format",
        choices=["auto", "csv", "phantom", "surrogate"],
        default="auto",
        help="a trace's layout: auto reads a header line, else 7 columns as the phantom "
        "format and 2 as a surrogate",
    )
    parser.add_argument(
        "--columns",
        default=None,
        metavar="'t [s],SI [mm],...'",
        help="a trace's columns and units when it has no header line (or to replace it); "
        "a column named - is not read (a frame counter: "
        "'-,t [ms],X [mm],Y [mm],Z [mm]') (default: the file's header, or the "
        "phantom format's by its width)",
    )
    parser.add_argument(
        "--map",
        action="append",
        metavar="COLUMN=AXIS",
        help="put a trace's column on a platform axis, with a sign (repeatable): "
        "SI=-Z; patient axes SI, LR, AP go to X, Y, Z by default",
    )
    parser.add_argument(
        "--lowpass-hz",
        type=_positive_float,
        default=None,
        help="zero-phase low-pass of a trace, Hz (default: none)",
    )
    parser.add_argument(
        "--centre",
        default=None,
        metavar="PHI,THETA,PSI,X,Y,Z",
        help="the pose a trace is centred on, rad and m (default: home, 0,0,0,0,0,0.3)",
    )
    parser.add_argument(
        "--centre-on",
        choices=["mean", "first", "none"],
        default="mean",
        help="which pose of a trace goes to --centre (the report says what was removed)",
    )
    parser.add_argument(
        "--max-gap",
        type=_positive_float,
        default=1.0,
        metavar="S",
        help="longest interval without data a trace may have, s",
    )


def _add_check_command(sub) -> None:
    """The ``check`` command's options."""
    chk = sub.add_parser(
        "check",
        help="check a reference against every limit without "
        "simulating: reach, joints, singularity, clearance, "
        "torque, speed (exit 2 if refused)",
    )
    chk.add_argument(
        "reference",
        help="a reference file (t,phi,theta,psi,X,Y,Z, or a recorded trace as reproduce "
        "reads it), a named trajectory (paper, helix, step_<axis>, ...) or a scenario "
        "(a .yaml file or a shipped name)",
    )
    _add_trace_arguments(chk)
    _add_scenario_arguments(chk, "the robot to check on, for a file or named reference")
    chk.add_argument(
        "--duration",
        type=_positive_float,
        default=None,
        help="checked s (default: the scenario's duration_s)",
    )
    chk.add_argument("--out", default="results", help="folder of the margins plot")
    chk.set_defaults(func=_cmd_check)


def _add_reproduce_command(sub) -> None:
    """The ``reproduce`` command's options."""
    rp = sub.add_parser(
        "reproduce",
        help="reproduce organ motion (a library motion or a "
        "recorded trace) on the robot and report its fidelity "
        "(exit 2 if beyond --tolerance)",
    )
    rp.add_argument(
        "motion",
        help="breathing, heartbeat, breathing_heartbeat, "
        "irregular_breathing, hysteresis, sawtooth, sharkfin, baseline_drift, "
        "transient_excursion, persistent_excursion, breath_hold, or a trace file: text with "
        "a header naming columns and units (commas, semicolons, tabs or spaces; decimal "
        "points or commas), "
        "a motion phantom's 7-column (t LR SI AP [mm] rLR rSI rAP [deg]) or 2-column "
        "surrogate file, or t,phi,theta,psi,X,Y,Z",
    )
    rp.add_argument(
        "--param",
        action="append",
        metavar="KEY=VALUE",
        help="a library motion's parameter with its unit (repeatable): "
        "amplitude=15mm, period=4s, shape=3, direction=SI, tilt=2deg, "
        "heart_rate=72bpm, heart_amplitude=2mm, seed=1 (default: the "
        "motion's own); a key goes to the motion (or --add layer) that has it, "
        "or to the one written in front: heartbeat.amplitude=2mm",
    )
    rp.add_argument(
        "--add",
        action="append",
        metavar="MOTION",
        help="lay a library motion on the motion or trace (repeatable): "
        "baseline_drift, transient_excursion, persistent_excursion, heartbeat...; "
        "its parameters by --param (drift=3mm) (default: none)",
    )
    _add_trace_arguments(rp)
    _add_scenario_arguments(
        rp, "the robot and its controller; e.g. --set learning.gain=0.5 with --learn-cycles"
    )
    rp.add_argument(
        "--learn-cycles",
        type=_int_at_least(0),
        default=0,
        metavar="N",
        help="learn a correction from the first N cycles, then hold it (0: no learning)",
    )
    rp.add_argument(
        "--feedforward",
        action="store_true",
        help="learn a correction as a function of the reference over the run (any motion: a "
        "trace, irregular breathing, a heartbeat not locked to the breath); settings: --set "
        "learning.stretch_s=5 with a scenario's learning: !FeedforwardTuning {}",
    )
    rp.add_argument(
        "--learned",
        default=None,
        metavar="FILE.npz",
        help="start the feed-forward from a model an earlier run saved (--save-learned) "
        "(default: none, from zero)",
    )
    rp.add_argument(
        "--hold",
        action="store_true",
        help="apply the --learned model without learning further",
    )
    rp.add_argument(
        "--save-learned",
        default=None,
        metavar="FILE.npz",
        help="write the learned feed-forward at the end of the run (for --learned) (default: none)",
    )
    rp.add_argument(
        "--cycles",
        type=_int_at_least(1),
        default=2,
        metavar="N",
        help="cycles measured after the learned ones (or after one cycle to settle)",
    )
    rp.add_argument(
        "--tolerance",
        default="0.1mm,0.1deg",
        help="RMS error allowed per axis, a length and an angle",
    )
    rp.add_argument(
        "--scale-to-fit",
        action="store_true",
        help="shrink a motion the robot cannot follow about its centre until every "
        "check passes (instead of refusing it), saying by how much",
    )
    rp.add_argument(
        "--duration",
        type=_positive_float,
        default=None,
        help="s to run a trace that has no cycles (default: its length)",
    )
    rp.add_argument("--out", default="results/reproduce", help="report folder")
    rp.add_argument(
        "--html",
        default=None,
        metavar="FILE.html",
        help="also write a standalone Meshcat replay of the run to this file: the reference "
        "as a ghost, a marker coloured by the tracking error (default: none)",
    )
    rp.add_argument("--no-progress", action="store_true", help="hide the progress bar")
    rp.set_defaults(func=_cmd_reproduce, out_sub=("diverged",))


def _add_scenario_command(sub) -> None:
    """The ``scenario`` command's options."""
    scn = sub.add_parser("scenario", help="list the shipped scenarios or print one as YAML")
    scn.add_argument(
        "source",
        nargs="?",
        default=_default_scenario(),
        help=f"scenario file or shipped name (default: {_default_scenario()})",
    )
    scn.add_argument(
        "--set",
        action="append",
        metavar="KEY=VALUE",
        help="override a field, as for run (default: none)",
    )
    scn.add_argument("--list", action="store_true", help="list the shipped scenarios")
    scn.add_argument(
        "--out",
        default=None,
        metavar="FILE.yaml",
        help="write the YAML to this file (default: print it)",
    )
    scn.set_defaults(func=_cmd_scenario, out_is_file=True)


def _add_collect_command(sub) -> None:
    """The ``collect`` command's options."""
    col = sub.add_parser("collect", help="the 9 closed-loop runs that train the ANN tuner")
    _add_scenario_arguments(col, "the scenario the runs share")
    col.add_argument("--out", default="results/collect", help="output folder")
    col.add_argument(
        "--duration",
        type=_positive_float,
        default=10.0,
        metavar="SECONDS",
        help="simulated s per run",
    )
    col.add_argument("--seed", type=_int_at_least(0), default=0, help="trajectory seed")
    _add_runner_arguments(col)
    col.add_argument("--no-progress", action="store_true", help="hide the progress bar")
    col.set_defaults(func=_cmd_collect, out_sub=("diverged",))


def _add_train_command(sub) -> None:
    """The ``train`` command's options."""
    tr = sub.add_parser("train", help="train the ANN tuner on collected runs (needs torch)")
    tr.add_argument("--data", default="results/collect", help="folder written by collect")
    tr.add_argument(
        "--mode",
        choices=["paper", "best_cost"],
        default="best_cost",
        help="label mode of the saved tuner",
    )
    tr.add_argument(
        "--seed", type=_int_at_least(0), default=0, help="split and initialization seed"
    )
    tr.add_argument("--out", default="results/tuner/ann_tuner.npz", help="weights file")
    tr.set_defaults(func=_cmd_train, out_is_file=True)


def _add_evaluate_command(sub) -> None:
    """The ``evaluate`` command's options."""
    ev = sub.add_parser(
        "evaluate",
        help="every controller on every scenario, and the tuner study: results.md and its plots",
    )
    ev.add_argument(
        "--scenario",
        default=_default_scenario(),
        metavar="FILE|NAME",
        help="scenario every case starts from (a .yaml file or a shipped name)",
    )
    ev.add_argument(
        "--out",
        default="results/evaluation",
        help="folder of the runs (kept as they finish: run again to resume), "
        "rows.json and, unless --docs, results.md and its plots",
    )
    ev.add_argument(
        "--docs",
        default=None,
        metavar="FOLDER",
        help="write results.md and its plots here instead (default: --out; the "
        "repository's report is regenerated with --docs docs)",
    )
    _add_runner_arguments(ev)
    ev.add_argument(
        "--no-tuner-study",
        action="store_true",
        help="leave out the tuner study that leads the report",
    )
    ev.add_argument(
        "--controllers",
        default=None,
        metavar="NAME,NAME",
        help="comma-separated subset, e.g. lqi_1_1,pd,ann_best_cost (default: all "
        "12; with --quick, lqi_1_1,pd,ann_best_cost)",
    )
    ev.add_argument(
        "--quick",
        action="store_true",
        help="a smoke test of about a minute on 2 cores: 1-2 s runs of three "
        "controllers, no tuner study; not figures to quote",
    )
    ev.add_argument("--no-progress", action="store_true", help="hide the progress bar")
    ev.set_defaults(func=_cmd_evaluate, out_sub=("diverged", "rows"))


def _add_analyze_command(sub) -> None:
    """The ``analyze`` command's options."""
    an = sub.add_parser(
        "analyze",
        help="the loop as a control engineer sees it: margins, Ms, Mt, bandwidth, Bode plots",
    )
    _add_scenario_arguments(an, "the robot and LQI to analyse")
    an.add_argument(
        "--pose",
        default=None,
        metavar="PHI,THETA,PSI,X,Y,Z",
        help="the pose linearized at, rad and m (default: home, 0,0,0,0,0,0.3)",
    )
    an.add_argument(
        "--integrator",
        choices=["sap", "zoh"],
        default="sap",
        help="the plant as Drake's SAP steps it (sap) or the continuous robot sampled (zoh)",
    )
    an.add_argument(
        "--map",
        action="store_true",
        help="also the margins over roll and pitch (+-0.55 rad, 9 x 9) at the pose's height: "
        "map.png and the weakest pose",
    )
    an.add_argument(
        "--weights",
        action="store_true",
        help="also the margins for omega_Q / omega_R = 0.01, 0.1, 1, 10, 100 at the pose",
    )
    an.add_argument("--out", default="results/analyze", help="output folder")
    an.set_defaults(func=_cmd_analyze)


def _add_workspace_command(sub) -> None:
    """The ``workspace`` command's options."""
    ws = sub.add_parser(
        "workspace",
        help="reachable poses, singularities and holding torques of the scenario's robot",
    )
    _add_scenario_arguments(ws, "the robot to sweep (its robot: fields)")
    ws.add_argument("--out", default="results/workspace", help="output folder")
    ws.add_argument("--resolution", type=_int_at_least(3), default=41, help="grid points per axis")
    _add_runner_arguments(ws)
    ws.add_argument("--no-progress", action="store_true", help="hide the progress bar")
    ws.set_defaults(func=_cmd_workspace)


def _add_design_command(sub) -> None:
    """The ``design`` command's options."""
    from ..design.design_search import DEFAULT_MAXITER, DEFAULT_POPSIZE, OBJECTIVES
    from ..robot.motor_catalogue import MOTOR_CATALOGUE, REFERENCE_MOTOR

    dsg = sub.add_parser(
        "design",
        help="the robot's geometry and motor chosen for a task: a report and a scenario file",
    )
    dsg.add_argument(
        "requirements",
        metavar="REQUIREMENTS.yaml",
        help="what the robot must do (start from scenarios/design_requirements.yaml)",
    )
    dsg.add_argument(
        "--motor",
        choices=list(MOTOR_CATALOGUE),
        default=REFERENCE_MOTOR,
        help="the motor of the main search (docs/motor_catalogue.md; default: the reference's)",
    )
    dsg.add_argument(
        "--objective",
        choices=list(OBJECTIVES),
        default="peak_torque",
        help="what the main search minimizes: "
        + "; ".join(f"{k}: {v[1]}" for k, v in OBJECTIVES.items()),
    )
    dsg.add_argument(
        "--no-cheapest",
        action="store_true",
        help="skip the search for the cheapest catalogue motor that meets the task",
    )
    dsg.add_argument(
        "--no-confirm",
        action="store_true",
        help="skip the closed-loop runs of the chosen designs and the reference robot",
    )
    dsg.add_argument("--seed", type=_int_at_least(0), default=0, help="the optimizer's seed")
    dsg.add_argument(
        "--generations",
        type=_int_at_least(1),
        default=DEFAULT_MAXITER,
        help=f"generations of each search (default {DEFAULT_MAXITER})",
    )
    dsg.add_argument(
        "--popsize",
        type=_int_at_least(2),
        default=DEFAULT_POPSIZE,
        help=f"candidates per generation per design variable (default {DEFAULT_POPSIZE})",
    )
    dsg.add_argument(
        "--scenario",
        default="paper_hardware",
        metavar="FILE|NAME",
        help="the scenario the designs' scenario files and closed-loop runs start from "
        "(default: paper_hardware, the robot as built)",
    )
    dsg.add_argument("--out", default="results/design", help="output folder")
    _add_runner_arguments(dsg)
    dsg.add_argument("--no-progress", action="store_true", help="hide the progress bars")
    dsg.set_defaults(func=_cmd_design)


def _add_teleop_command(sub) -> None:
    """The ``teleop`` command's options."""
    tel = sub.add_parser("teleop", help="drive the robot live at real time from Meshcat sliders")
    _add_scenario_arguments(tel, "the robot driven")
    tel.add_argument(
        "--duration", type=_positive_float, default=None, help="simulated s (default: until Ctrl-C)"
    )
    tel.add_argument(
        "--realtime-rate",
        type=_realtime_rate,
        default=1.0,
        help="target real-time rate (0: as fast as it goes)",
    )
    tel.add_argument(
        "--port",
        type=_tcp_port,
        default=None,
        help="Meshcat's port (default: the first free from 7000)",
    )
    tel.add_argument("--out", default="results/teleop", help="folder of a divergence dump")
    tel.set_defaults(func=_cmd_teleop, out_sub=("diverged",))


def _pose6(text: str) -> list[float]:
    """Six comma-separated finite numbers phi,theta,psi,X,Y,Z (rad, m)."""
    try:
        values = [float(v) for v in text.split(",")]
    except ValueError:
        values = []
    if len(values) != 6 or not all(math.isfinite(v) for v in values):
        raise argparse.ArgumentTypeError(
            f"give six finite numbers phi,theta,psi,X,Y,Z in rad and m, got {text!r}"
        )
    return values


def _add_robot_command(sub) -> None:
    """The ``robot`` command's options."""
    rob = sub.add_parser(
        "robot",
        help="run the controller on the servos (docs/robot.md): dry run, home, a reference",
    )
    rob.add_argument(
        "reference",
        nargs="?",
        default=None,
        help="a reference name (paper, home, helix, step_<axis>, sweep_<axis>), a trace or "
        "a CSV file (default: the scenario's)",
    )
    from ..run.scenario_io import ROBOT_SCENARIO

    _add_scenario_arguments(rob, "the robot with its bus (a 'bus:' section)", ROBOT_SCENARIO)
    rob.add_argument(
        "--port", default=None, help="the servos' serial port (default: the scenario's bus.port)"
    )
    rob.add_argument(
        "--dry-run",
        action="store_true",
        help="read the bus with the torque off, print the pose and its verdict, stop",
    )
    rob.add_argument(
        "--calibrate",
        type=float,
        default=None,
        metavar="DEG",
        help="read the zero_counts with every crank held at DEG degrees (0: horizontal), "
        "torque off; print them and stop (default: no calibration)",
    )
    rob.add_argument(
        "--home-s",
        type=_positive_float,
        default=3.0,
        help="seconds of the homing lead-in from the measured pose to the reference's start",
    )
    rob.add_argument(
        "--hold",
        type=float,
        default=0.0,
        help="seconds the reference's last pose is held before the torque goes off",
    )
    rob.add_argument(
        "--duration",
        type=_positive_float,
        default=None,
        help="s of the reference (default: the scenario's)",
    )
    rob.add_argument(
        "--loop-timeout",
        type=_positive_float,
        default=0.1,
        help="our watchdog: the torque goes off when no control period completes for this long, s",
    )
    rob.add_argument(
        "--emulate",
        type=_pose6,
        nargs="?",
        const=[0.0, 0.0, 0.0, 0.0, 0.0, 0.28],
        default=None,
        metavar="POSE",
        help="rehearse on the bus emulator (a pseudo-terminal, the robot's Drake plant at real "
        "time behind it) resting at POSE phi,theta,psi,X,Y,Z (default 0,0,0,0,0,0.28)",
    )
    rob.add_argument("--meshcat", action="store_true", help="show the measured robot in Meshcat")
    rob.add_argument(
        "--teleop",
        action="store_true",
        help="drive the robot from Meshcat's sliders, from where it rests (until Ctrl-C, or "
        "--duration s)",
    )
    rob.add_argument("--no-progress", action="store_true", help="no progress bar")
    rob.add_argument("--out", default="results", help="folder of the logs")
    rob.set_defaults(func=_cmd_robot, out_sub=("diverged",))


def _add_diagrams_command(sub) -> None:
    """The ``diagrams`` command's options."""
    dg = sub.add_parser("diagrams", help="rewrite diagrams/*.dot and render *.svg (Graphviz)")
    dg.add_argument("--out", default="diagrams", help="folder (in the current folder)")
    dg.add_argument("--dot-only", action="store_true", help="write the .dot sources only")
    dg.set_defaults(func=_cmd_diagrams)


def _add_sdf_command(sub) -> None:
    """The ``sdf`` command's options."""
    sdf = sub.add_parser("sdf", help="write the reference robot's SDF")
    sdf.add_argument("--out", default="sdf/rotary_stewart.sdf", help="file (in the current folder)")
    sdf.set_defaults(func=_cmd_sdf, out_is_file=True)


def _add_mjcf_command(sub) -> None:
    """The ``mjcf`` command's options."""
    mj = sub.add_parser("mjcf", help="write a scenario's robot as a MuJoCo MJCF")
    _add_scenario_arguments(mj, "the robot to write")
    mj.add_argument(
        "--out", default="rotary_stewart.xml", help="file to write (in the current folder)"
    )
    mj.set_defaults(func=_cmd_mjcf, out_is_file=True)


def _interruptible():
    """Make SIGTERM and SIGHUP raise :class:`~stewart_drake.execution.runners.Interrupted` (a
    KeyboardInterrupt, as Ctrl-C) in the main thread while a command runs; returns the handlers
    to restore. A signal the process was started ignoring (``nohup``) stays ignored."""
    from ..execution.runners import raise_interrupted

    if threading.current_thread() is not threading.main_thread():
        return {}
    return {
        s: signal.signal(s, raise_interrupted)
        for s in (signal.SIGTERM, signal.SIGHUP)
        if signal.getsignal(s) is not signal.SIG_IGN
    }


def main(argv: list[str] | None = None) -> int:
    from .. import _interrupted_while_starting

    # From here a Ctrl-C is a KeyboardInterrupt that each stage below turns into one line.
    if signal.getsignal(signal.SIGINT) is _interrupted_while_starting:
        signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        restore = _interruptible()
    except KeyboardInterrupt as err:
        return _interrupted(err, "", None)
    try:
        return _main(argv)
    finally:
        for signum, handler in restore.items():
            signal.signal(signum, handler)


def _import_drake_whole() -> None:
    """Import pydrake with SIGINT, SIGTERM and SIGHUP held, then pass a held one to its handler
    (a KeyboardInterrupt, handled as any): a signal that lands inside pydrake's own
    initialization makes it print a C++ log with a stack dump before our one line. Held by
    Python handlers that only note the signal (blocking it would not do: numpy's threads, already
    started, would take it)."""
    if "pydrake" in sys.modules or threading.current_thread() is not threading.main_thread():
        return
    noted: list[int] = []
    handlers = {s: signal.getsignal(s) for s in (signal.SIGINT, signal.SIGTERM, signal.SIGHUP)}
    held = {s: h for s, h in handlers.items() if callable(h)}  # not SIG_IGN, SIG_DFL, None
    for signum in held:
        signal.signal(signum, lambda signum, frame: noted.append(signum))
    try:
        import pydrake  # noqa: F401 - initializes Drake's shared libraries (a third of a second)
    finally:
        for signum, handler in held.items():
            signal.signal(signum, handler)
    if noted:
        held[signal.Signals(noted[0])](noted[0], None)


def _main(argv: list[str] | None) -> int:
    try:
        _import_drake_whole()
        parser = build_parser()  # imports Drake (about a second)
        args = parser.parse_args(argv)
    except KeyboardInterrupt as err:
        return _interrupted(err, "", None)
    except ImportError as err:
        if not _interrupted_import(err):
            raise
        return _interrupted(KeyboardInterrupt(), "", None)
    try:
        if getattr(args, "out", None) is not None:
            check_output(
                args.out, "--out", getattr(args, "out_is_file", False), getattr(args, "out_sub", ())
            )
        return int(args.func(args) or 0)
    except StewartError as err:
        print(f"stewart-drake {args.command}: {err}", file=sys.stderr)
        return 2
    except BrokenPipeError:  # the reader went away (`... | head`): stop without a word
        _silence_stdout()
        return 128 + signal.SIGPIPE
    except OSError as err:  # disk full, file vanished, permissions
        print(f"stewart-drake {args.command}: {err}", file=sys.stderr)
        return 1
    except KeyboardInterrupt as err:  # Ctrl-C, SIGTERM, SIGHUP
        return _interrupted(err, args.command, getattr(args, "out", None))
    except ImportError as err:  # a Ctrl-C while a command's own imports initialize pydrake
        if not _interrupted_import(err):
            raise
        return _interrupted(KeyboardInterrupt(), args.command, getattr(args, "out", None))
    except SystemExit as err:  # code the command ran (a plug-in's controller) asked to exit
        plugins = ", ".join(getattr(args, "plugin", None) or ())
        print(
            f"stewart-drake {args.command}: stopped by SystemExit({err.code!r}) raised in code "
            f"it ran ({f'the plug-in {plugins}' if plugins else 'a controller or plug-in'}), "
            f"before the command finished; partial outputs were not written: fix that code",
            file=sys.stderr,
        )
        return 2
    except SystemError as err:  # a signal inside compiled code (numba's dispatcher wraps it)
        from ..execution.runners import interrupt_in

        interrupt = interrupt_in(err)
        if interrupt is None:
            raise
        return _interrupted(interrupt, args.command, getattr(args, "out", None))


def _interrupted_import(err: ImportError) -> bool:
    """Whether ``err`` is a Ctrl-C that landed while an extension module initialized: pydrake's
    and matplotlib's modules turn it into an ImportError ("initialization failed", or "Encountered
    an error while initializing the extension" around it), the KeyboardInterrupt kept as a cause
    or context somewhere down the chain, which is searched (at most 20 links)."""
    link: BaseException | None = err
    for _ in range(20):
        if link is None:
            return False
        if isinstance(link, KeyboardInterrupt) or "initialization failed" in str(link):
            return True
        link = link.__cause__ or link.__context__
    return False


def _silence_stdout() -> None:
    """Point standard output at the null device, so that the interpreter's last flush does not
    fail again on the closed pipe (Python's documentation on SIGPIPE)."""
    try:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
    except (OSError, ValueError, AttributeError):  # not a file descriptor (a test's capture)
        pass


def _interrupted(err: KeyboardInterrupt, command: str, out) -> int:
    """Say which signal ended ``command`` (one line) and return 128 + its number."""
    signum = getattr(err, "signum", signal.SIGINT)
    kept = (
        f"finished {'generations' if command == 'design' else 'results'} are kept in "
        f"{Path(out, RESUMABLE[command]) if RESUMABLE[command] else out}: run the same command "
        f"again to run only the rest"
        if command in RESUMABLE and out is not None
        else "partial outputs were not written"
    )
    name = f"stewart-drake {command}".rstrip()
    print(f"{name}: interrupted by {signal.Signals(signum).name}; {kept}", file=sys.stderr)
    return 128 + signum


if __name__ == "__main__":
    sys.exit(main())
