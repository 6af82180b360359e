"""``verify --surrogate``: the options of an internal motion judged with its surrogate on one
clock, the files it reads (a tracker's two files, or the robot's encoder log for both) and the
command that judges them (:mod:`.pair_judgement`) and writes the page (:mod:`.pair_report`)."""

from __future__ import annotations

from functools import partial
from pathlib import Path

from ..base.errors import InvalidConfigError
from ..organ_motion.fidelity import AXES
from .command import ENCODER_LOG_SUFFIX, SAVE_REGISTRATION_MOVED, exit_status, record_options
from .measured_verdict import (
    seconds,
)
from .pair_judgement import MAX_RELATIVE_LATENCY_S, verify_pair
from .pair_report import write_pair

#: ``--surrogate``'s word for the motion's external signal made by a correlation model
#: (:func:`~.external_reference.model_reference`) instead of a recorded file.
MODEL = "model"


def register(sub) -> None:
    """Add the ``verify`` command to ``sub``, the ``stewart-drake`` subparsers: the motion
    judged alone (:func:`stewart_drake.verification.command.add_verify_command`) or, with these
    options (:func:`add_pair_arguments`), with its surrogate on one clock."""
    from .command import add_verify_command

    add_pair_arguments(add_verify_command(sub))


def add_pair_arguments(vp) -> None:
    """Add to ``verify``'s parser ``vp`` the options of an internal motion judged with its
    surrogate (``--surrogate``, ``--measured-surrogate``, their columns and maps,
    ``--max-relative-latency``); ``verify`` runs :func:`cmd_verify_pair` when they are given, and
    as before otherwise."""
    from ..execution.options import positive_float

    vp.add_argument(
        "--surrogate",
        default=None,
        metavar="EXTERNAL",
        help="judge the motion with its external surrogate on one clock: the surrogate's "
        "recorded trace (a 2-column file, time and displacement, on SI; or a header naming its "
        "column and unit), on the motion's clock, or 'model' for the motion through a "
        "correlation model (--surrogate-param), as reproduce --surrogate model makes it, on SI; "
        "with --measured-surrogate; reports both fidelities and their relative latency "
        "(default: none, the motion alone)",
    )
    vp.add_argument(
        "--surrogate-param",
        nargs="*",
        default=None,
        metavar="KEY=VALUE",
        help="with --surrogate model: ratio=0.8 lead=0.3s drift=2mm/min change_at=20s "
        "lead_after=-0.2s ratio_after=1.2 blend=1s, as reproduce takes them (default: none, "
        "the motion itself: ratio 1, no lead, no drift, no change)",
    )
    vp.add_argument(
        "--surrogate-map",
        action="append",
        metavar="COLUMN=AXIS",
        help="put the surrogate trace's column on an axis, with a sign (repeatable) (default: a "
        "2-column file's displacement on SI)",
    )
    vp.add_argument(
        "--measured-surrogate",
        default=None,
        metavar="FILE",
        help="the surrogate's motion measured on the same clock as --measured (one camera seeing "
        "both platforms): a file read as --measured is, e.g. t [s],depth [mm]; or the robot "
        f"run's encoder log (a name ending in {ENCODER_LOG_SUFFIX}, the one given to --measured): "
        "its carriage's s [m] as the surrogate servo's encoder read it (default: none)",
    )
    vp.add_argument(
        "--measured-surrogate-columns",
        default=None,
        metavar="'t [s],X [mm]'",
        help="the measured surrogate file's columns and units when it has no header line (or to "
        "replace it) (default: its header)",
    )
    vp.add_argument(
        "--measured-surrogate-map",
        action="append",
        metavar="COLUMN=AXIS",
        help="put a measured surrogate column on an axis, with a sign (repeatable): the "
        "surrogate trace's axis, SI by default (default: by name)",
    )
    vp.add_argument(
        "--max-relative-latency",
        type=positive_float,
        default=MAX_RELATIVE_LATENCY_S,
        metavar="S",
        help="the largest |relative latency| of the motion against its surrogate that passes, "
        "s (> 0: the internal target late): IntERAct's claimed sync and AAPM TG-142's gating "
        "accuracy",
    )
    vp.set_defaults(func=partial(_verify_or_pair, vp.get_default("func")))


def is_encoder_log(path) -> bool:
    """Whether ``path`` names a robot run's encoder log (its name ends in
    :data:`~stewart_drake.verification.command.ENCODER_LOG_SUFFIX`, as ``robot`` writes it): given
    to ``--measured`` it is read as ``verify`` alone reads it (the platform by forward
    kinematics), given to ``--measured-surrogate`` for its surrogate's carriage ``s``."""
    return str(path).endswith(ENCODER_LOG_SUFFIX)


def carriage_axis(reference) -> tuple[int, float]:
    """(axis 3..5, sign +-1) along which the surrogate's ``reference`` moves: the one
    translation of a trace (its import record's ``info.axes``, e.g. "+X", "-Z"; the carriage's
    ``s`` is the trace's own displacement, the map's sign undone, as the robot drives it), or
    a reference's own ``carriage_axis``.

    Raises:
        InvalidConfigError: a reference of more than one axis, or of a rotation.
    """
    own = getattr(reference, "carriage_axis", None)
    if own is not None:
        return own
    axes = tuple(getattr(getattr(reference, "info", None), "axes", ()))
    if len(axes) != 1 or axes[0][1:] not in AXES[3:]:
        raise InvalidConfigError(
            f"the surrogate's carriage moves along one line, its reference along "
            f"{', '.join(axes) or 'no axis named'}: give --surrogate one displacement (a "
            "2-column file, or one column mapped with --surrogate-map)"
        )
    return AXES.index(axes[0][1:]), (-1.0 if axes[0][0] == "-" else 1.0)


def read_encoder_pair(path, surrogate_path, geometry, surrogate_reference) -> tuple:
    """(the platform's, the carriage's) :class:`~stewart_drake.verification.measured_motion.
    MeasuredMotion` from robot runs' encoder logs (one log may be given for both): the platform
    by forward kinematics of ``geometry``, the carriage's ``s`` (as its servo's encoder read
    it, never its command ``s_cmd``) on the axis of ``surrogate_reference``
    (:func:`carriage_axis`), each on its log's ``t_path``, the lead-in left out. Each log is
    read by the one checked reader of encoder logs
    (:func:`~stewart_drake.calibration.join.read_encoder_log`), its columns by name.

    Raises:
        MissingFileError, CorruptFileError, InvalidConfigError: as that reader's (a log without
            the ``s`` column named with its file); as :func:`carriage_axis`.
        ForwardKinematicsError: a reading forward kinematics cannot solve.
    """
    from ..calibration.join import read_encoder_log
    from .measured_motion import carriage_motion, encoder_motion

    axis, sign = carriage_axis(surrogate_reference)
    same = Path(path).resolve() == Path(surrogate_path).resolve()
    log = read_encoder_log(surrogate_path, carriage=True)
    carriage = carriage_motion(surrogate_path, log["t_path"], log["s"], axis, sign)
    if not same:
        log = read_encoder_log(path)
    return encoder_motion(path, log["t_path"], log["q"], geometry), carriage


def _verify_or_pair(alone, args) -> int:
    """``verify``: the pair (:func:`cmd_verify_pair`) when a surrogate or its measurement is
    given, else ``alone``, verify's own command."""
    if args.surrogate is None and args.measured_surrogate is None and not args.surrogate_param:
        return alone(args)
    return cmd_verify_pair(args)


def _check_pair_options(args) -> None:
    """Refuse, before any work, what the pair does not take (one line each).

    Raises:
        InvalidConfigError: --surrogate-param without ``--surrogate model``, or a model refused
            (:func:`~stewart_drake.execution.trace_options.correlation_model`); --surrogate-map
            with a model; a surrogate without its measurement or the reverse, several
            --measured, --save-registration, --measured-pauses, --exclude-outliers, a QA
            record's options (``--record`` and those it takes: a record is of one motion's
            verdict), an encoder log beside a tracker's file (not one clock) or with
            --measured-surrogate-columns or -map (its columns are its own), --frame other than
            axes or base.
    """
    if args.surrogate == MODEL:
        from ..execution.trace_options import correlation_model

        correlation_model(args.surrogate_param)  # refused before any work
        if args.surrogate_map:
            raise InvalidConfigError(
                "--surrogate model is put on SI: leave --surrogate-map out (map the measured "
                "surrogate's column with --measured-surrogate-map instead)"
            )
    elif args.surrogate_param:
        raise InvalidConfigError(
            "--surrogate-param sets a correlation model: give --surrogate model"
        )
    if args.surrogate is None or args.measured_surrogate is None:
        given, missing = (
            ("--surrogate", "--measured-surrogate")
            if args.measured_surrogate is None
            else ("--measured-surrogate", "--surrogate")
        )
        raise InvalidConfigError(
            f"{given} judges the motion with its surrogate: give {missing} too (the surrogate's "
            "trace and its measurement on the clock of --measured)"
        )
    if len(args.measured) != 1:
        raise InvalidConfigError(
            "with --surrogate, give one --measured (the internal motion's measurement)"
        )
    if args.save_registration:
        raise InvalidConfigError(SAVE_REGISTRATION_MOVED)
    if args.exclude_outliers:
        raise InvalidConfigError(
            "--exclude-outliers judges one motion without some of its frames: leave --surrogate "
            "out and verify each motion alone"
        )
    if args.measured_pauses:
        raise InvalidConfigError(
            "--measured-pauses judges one motion in segments, and a pair's relative latency "
            "needs both unbroken: leave --surrogate out and verify each motion alone"
        )
    if args.action_level is not None:
        raise InvalidConfigError(
            "--action-level grades one motion's verdict, and a pair has three: leave "
            "--surrogate out and verify each motion alone with --action-level"
        )
    record = record_options(args)
    if record:
        raise InvalidConfigError(
            f"{record[0]} records one motion's verdict, and a pair has three: leave --surrogate "
            "out and verify each motion alone with --record"
        )
    _check_pair_files(args)
    if args.frame not in ("axes", "base"):
        raise InvalidConfigError(f"--frame is axes or base, got {args.frame!r}")
    if args.registration and args.frame != "axes":
        raise InvalidConfigError("--registration gives the frames: leave --frame out")


def _check_pair_files(args) -> None:
    """Refuse an encoder log beside a tracker's file (not one clock), or an encoder log for the
    surrogate with columns or a map (its columns are its own).

    Raises:
        InvalidConfigError: naming the files and what to give.
    """
    logs = [is_encoder_log(p) for p in (args.measured[0], args.measured_surrogate)]
    if logs[0] != logs[1]:
        log, other = (
            (args.measured[0], args.measured_surrogate)
            if logs[0]
            else (args.measured_surrogate, args.measured[0])
        )
        raise InvalidConfigError(
            f"{log} is an encoder log, on the reference's clock (t_path), and {other} a "
            "tracker's or a camera's file, on its own: they are not on one clock; give the "
            "encoder log to both --measured and --measured-surrogate, or two files of one camera"
        )
    if logs[1] and (args.measured_surrogate_columns or args.measured_surrogate_map):
        raise InvalidConfigError(
            f"{args.measured_surrogate}: an encoder log's columns are its own (the carriage's "
            "s [m]): leave --measured-surrogate-columns and --measured-surrogate-map out"
        )


def cmd_verify_pair(args) -> int:
    """``stewart-drake verify INTERNAL --surrogate EXTERNAL --measured INTERNAL_MEAS
    --measured-surrogate EXTERNAL_MEAS``: read the two references and the two measurements,
    judge them (:func:`verify_pair`), write each motion's report as ``verify`` does and the
    pair's (``verify_<motion>_pair.md|.json``), print the three verdicts; 0 when all three pass,
    2 otherwise.

    Raises:
        InvalidConfigError, MissingFileError, CorruptFileError: a bad option or file (one line),
            before any report.
    """
    import sys

    from ..calibration.registration_file import read_registration
    from ..execution.trace_options import key_values
    from ..organ_motion.command import motion_scenario
    from ..organ_motion.fidelity import parse_tolerance
    from ..references.traces import load_trace
    from ..run.plan import robot_geometry
    from .external_reference import model_reference

    _check_pair_options(args)
    tolerance = parse_tolerance(args.tolerance)
    scenario, name = motion_scenario(args)
    registration = read_registration(args.registration) if args.registration else None
    out = Path(args.out)
    paths = (args.measured[0], args.measured_surrogate)
    stems = _pair_stems(out, name, args.surrogate, paths)
    reference = scenario.reference.make(robot_geometry(scenario), scenario.duration_s, None)
    if args.surrogate == MODEL:
        surrogate = model_reference(reference, args.surrogate_param, scenario.duration_s)
    else:
        print(f"verify: reading {args.surrogate}", file=sys.stderr, flush=True)
        surrogate = load_trace(args.surrogate, key_values(args.surrogate_map, "--surrogate-map"))
        surrogate = _on_the_motions_clock(surrogate, reference, args.surrogate)
    internal_measured, surrogate_measured = _read_measured_pair(args, paths, scenario, surrogate)
    print("verify: aligning and judging the motion and its surrogate", file=sys.stderr, flush=True)
    pair = verify_pair(
        reference,
        surrogate,
        internal_measured,
        surrogate_measured,
        clock_offset_s=args.clock_offset,
        frame=args.frame,
        registration=registration,
        max_latency_s=args.max_latency,
        max_relative_latency_s=args.max_relative_latency,
        tolerance=tolerance,
        max_gap_s=args.measured_max_gap,
    )
    written = write_pair(pair, out, stems)
    print(pair.internal.judgement.line)
    print(pair.surrogate.judgement.line)
    print(pair.judgement.line)
    for note in pair.notes:
        print(note)
    print(f"wrote {', '.join(str(p) for p in written)}")
    return exit_status(pair.verdicts)


def _pair_stems(out: Path, name: str, surrogate: str, paths) -> list[str]:
    """The three reports' names (the motion's, the surrogate's, the pair's), each file of
    them replaceable in ``out``.

    Raises:
        InvalidConfigError: two reports of one name; a file in the way that is not the tool's.
    """
    from ..base.fileio import check_replaceable

    stems = [
        f"verify_{name}_{Path(paths[0]).stem}",
        f"verify_{Path(surrogate).stem}_{Path(paths[1]).stem}",
        f"verify_{name}_pair",
    ]
    if len(set(stems)) != 3:
        raise InvalidConfigError(
            "the motion's and the surrogate's reports would have one name: give files of "
            "different names"
        )
    for stem in stems:
        for suffix in (".md", ".png", ".json") if stem != stems[2] else (".md", ".json"):
            check_replaceable(out / f"{stem}{suffix}")
    return stems


def _read_measured_pair(args, paths, scenario, surrogate):
    """(the internal's measured motion, the surrogate's): both from one encoder log and its
    carriage, or each file through the one reader of measured files with its options.

    Raises:
        MissingFileError, CorruptFileError, InvalidConfigError: as the readers'.
    """
    import sys

    from ..execution.trace_options import key_values
    from ..run.plan import robot_geometry
    from .measured_motion import read_measured

    print(f"verify: reading {paths[0]}", file=sys.stderr, flush=True)
    if is_encoder_log(paths[0]):
        return read_encoder_pair(paths[0], paths[1], robot_geometry(scenario), surrogate)
    internal_measured = read_measured(
        paths[0], args.measured_columns or "", key_values(args.measured_map, "--measured-map")
    )
    print(f"verify: reading {paths[1]}", file=sys.stderr, flush=True)
    surrogate_measured = read_measured(
        paths[1],
        args.measured_surrogate_columns or "",
        key_values(args.measured_surrogate_map, "--measured-surrogate-map"),
        "--measured-surrogate-columns",
    )
    return internal_measured, surrogate_measured


def _on_the_motions_clock(surrogate, reference, path):
    """The surrogate's trace on the motion's clock, their files' times taken as written
    (:func:`~stewart_drake.references.clock.on_clock_of`), said on stderr when they do not
    start together."""
    import sys

    from ..references.clock import OnClockOf, on_clock_of

    shifted = on_clock_of(surrogate, reference)
    if isinstance(shifted, OnClockOf):
        lag = shifted.lag_s
        print(
            f"verify: {path} starts {seconds(abs(lag))} {'after' if lag > 0 else 'before'} the "
            "motion's file on their clock: its times taken as written, not re-zeroed",
            file=sys.stderr,
            flush=True,
        )
    return shifted


__all__ = [
    "MODEL",
    "is_encoder_log",
    "carriage_axis",
    "read_encoder_pair",
    "add_pair_arguments",
    "cmd_verify_pair",
]
