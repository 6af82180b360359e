"""``stewart-drake verify``: a motion measured on a real phantom (a tracker's export, or the
robot's encoder log) judged against the reference it was asked to follow, with the report of
``reproduce`` (:mod:`stewart_drake.verification.verify`).

It sits in the verification package, above the two features it joins: the organ-motion
library and its report (:mod:`~stewart_drake.organ_motion`), and the calibration's readers of a
robot session (the encoder log of :mod:`~stewart_drake.calibration.join`, the
registration of :mod:`~stewart_drake.calibration.registration`).
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path

from ..base import verdicts
from ..execution.options import add_motion_arguments, add_scenario_arguments, positive_float
from ..execution.trace_options import add_trace_arguments

#: The end of an encoder log's name (``<stem>_encoders.csv``, as ``robot`` writes it): such a
#: measured file is read as the robot's encoder log.
ENCODER_LOG_SUFFIX = "_encoders.csv"
#: What ``verify --save-registration`` says: a tracker is registered by ``calibrate``.
SAVE_REGISTRATION_MOVED = (
    "--save-registration moved to calibrate, beside the tracker's other registration: "
    "stewart-drake calibrate --register MEASURED.csv --out REG.yaml (with its "
    "--measured-columns, --measured-map, --clock-offset and the registration motion's --param)"
)


def add_verify_command(sub):
    """Add the ``verify`` command to ``sub``, the ``stewart-drake`` subparsers; returns its
    parser (its surrogate's options are added to it by
    :func:`stewart_drake.verification.pair_command.register`)."""
    from ..organ_motion import SCENARIO

    vp = sub.add_parser(
        "verify",
        help="judge a motion measured on a real phantom (a tracker's export, or the robot's "
        "encoder log) against the reference it was asked to follow: reproduce's report, with "
        "the latency (exit 2 if beyond --tolerance, 3 if the motion is too small to tell "
        "from none at it)",
    )
    add_motion_arguments(vp)
    add_trace_arguments(vp)
    _add_measured_arguments(vp)
    _add_frame_arguments(vp)
    _add_record_arguments(vp)
    add_scenario_arguments(
        vp, "the robot whose encoder log is read (forward kinematics)", default=SCENARIO
    )
    vp.add_argument("--out", default="results/verify", help="report folder")
    vp.set_defaults(func=cmd_verify)
    return vp


def _add_measured_arguments(vp) -> None:
    """``verify``'s options of the measured file: which, its columns and axes, its clock."""
    vp.add_argument(
        "--measured",
        action="append",
        required=True,
        metavar="FILE",
        help="the motion measured (repeatable: one report each, side by side): a tracker's "
        "export read as a trace is (a header naming the time and the marker's X, Y, Z with "
        "units, and its phi, theta, psi, a quaternion qw, qx, qy, qz, or none; semicolons, "
        "decimal commas, ms), or a robot "
        f"run's encoder log (a name ending in {ENCODER_LOG_SUFFIX}), turned into poses by "
        "forward kinematics of --scenario's robot (required: no default)",
    )
    add_measured_file_arguments(vp)
    vp.add_argument(
        "--exclude-outliers",
        action="store_true",
        help="judge without the frames far off the rest (beyond 6 robust SD and 5x the "
        "tolerance from the median error on some axis: a marker mis-detected); the verdict says "
        "how many (without it, the verdict names them and what the rest would give)",
    )
    vp.add_argument(
        "--measured-pauses",
        action="store_true",
        help="a step longer than --measured-max-gap is a planned pause (between imaging arcs): "
        "the stretches either side are judged as segments of one run, each sample at its own "
        "time, nothing bridged; the verdict names the pauses",
    )


def add_measured_file_arguments(parser) -> None:
    """The options of how a tracker's measured file is read and put on its reference's clock
    (its columns and axes, the clocks' offset, the latency searched, the longest gap):
    ``verify``'s, and ``calibrate --register``'s for the registration motion's file."""
    parser.add_argument(
        "--measured-columns",
        default=None,
        metavar="'-,t [ms],X [mm],...'",
        help="the measured file's columns and units when it has no header line (or to replace "
        "it); a column named - is not read (a frame counter) (default: its header)",
    )
    parser.add_argument(
        "--measured-map",
        action="append",
        metavar="COLUMN=AXIS",
        help="put a measured column on an axis, with a sign (repeatable) (default: by name)",
    )
    parser.add_argument(
        "--clock-offset",
        type=float,
        default=None,
        metavar="S",
        help="the measured file's time + S is the reference's (a tracker that started the "
        "motion at its time 12.5 s: -12.5): separates the phantom's latency from the clocks' "
        "offset (default: not known: the whole shift found is reported as the latency, with "
        "clock offset 0; the encoder log is on the reference's clock)",
    )
    parser.add_argument(
        "--max-latency",
        type=positive_float,
        default=0.5,
        metavar="S",
        help="the largest latency that passes with --clock-offset, s (latencies up to three "
        "times it are searched, so that one beyond it is found and fails)",
    )
    parser.add_argument(
        "--measured-max-gap",
        type=positive_float,
        default=0.5,
        metavar="S",
        help="the longest step between two measured samples judged across, s: the samples are "
        "judged at their own times, nothing interpolated; a longer gap (the tracker lost the "
        "marker) is refused where it is, unless --measured-pauses",
    )


def _add_frame_arguments(vp) -> None:
    """``verify``'s options of the frame the measured poses are judged in, and the tolerance."""
    vp.add_argument(
        "--registration",
        default=None,
        metavar="REG.yaml",
        help="the tracker registered to the robot: fiducials (as calibrate takes them) or the "
        "frames calibrate --register wrote; the measured poses are judged in the base frame, "
        "nothing fitted and no offset removed (default: none, see --frame)",
    )
    vp.add_argument(
        "--frame",
        default="axes",
        metavar="{axes,base}",
        help="without --registration: take each measured axis as the base frame's axis its "
        "column names and remove its constant offset, nothing else (axes), or take the measured "
        "poses as the platform's in the base frame, nothing removed (base)",
    )
    # Moved to ``calibrate --register``: kept only to say so in one line.
    vp.add_argument("--save-registration", default=None, help=argparse.SUPPRESS)
    vp.add_argument(
        "--tolerance",
        default="0.1mm,0.1deg",
        help="RMS error allowed per measured axis, a length and an angle",
    )


def _add_record_arguments(vp) -> None:
    """``verify``'s options of the QA record (``--record`` and what it writes in it)."""
    vp.add_argument(
        "--record",
        action="store_true",
        help="also write a QA record a physicist signs and files, never over an earlier one: "
        "OUT/records/<report>_<time>.pdf (the verdict, the tolerance and action level, the "
        "plots, the assumptions, the inputs' SHA-256, the phantom, the software, lines to "
        "sign) and .json (the same as named values for a QATrack+ upload test); needs the qa "
        "extra (reportlab)",
    )
    vp.add_argument(
        "--action-level",
        default=None,
        metavar="LENGTH,ANGLE",
        help="RMS errors per axis beyond which a result within --tolerance is ACTION (TG-142's "
        "action level: within tolerance, to be looked at before it fails; exit status 4), "
        "e.g. 0.07mm,0.07deg (default: none)",
    )
    vp.add_argument("--operator", default="", help="with --record: who ran the QA")
    vp.add_argument("--phantom-serial", default="", help="with --record: the phantom's serial")
    vp.add_argument("--notes", default="", help="with --record: notes for the record")


def _check_frame(text: str) -> None:
    """``--frame``'s value: "axes" or "base"; "fit" refused saying why.

    Raises:
        InvalidConfigError: any other value (one line).
    """
    from ..base.errors import InvalidConfigError

    if text == "fit":
        raise InvalidConfigError(
            "--frame fit is gone: a frame fitted to the motion judged absorbs the errors it "
            "should find; register the tracker once (calibrate --register on the registration "
            "motion, or fiducials) and give --registration REG.yaml, or use --frame axes"
        )
    if text not in ("axes", "base"):
        raise InvalidConfigError(f"--frame is axes or base, got {text!r}")


def cmd_verify(args) -> int:
    """``stewart-drake verify``: read the reference and each measured file, judge each, write
    its report and print its verdict and figures (a table side by side for several); 0 when
    every verdict passes, 2 when any FAILs, else 3 when any cannot judge, else 4 when any is
    ACTION (:func:`exit_status`).
    ``--save-registration`` is refused naming ``calibrate --register``, where it moved.

    Raises:
        InvalidConfigError, MissingFileError, CorruptFileError: a bad option or file (one line:
            the measured file's columns, a NaN, too short, no overlap), before any report.
    """
    import sys

    from ..base.errors import InvalidConfigError
    from ..base.fileio import check_replaceable
    from ..execution.trace_options import key_values
    from ..organ_motion.command import motion_scenario
    from ..organ_motion.fidelity import parse_tolerance
    from ..run.plan import robot_geometry
    from .report import write_verification
    from .verify import verify

    if args.save_registration:
        raise InvalidConfigError(SAVE_REGISTRATION_MOVED)
    tolerance = parse_tolerance(args.tolerance)
    action_level = _action_level(args, tolerance)
    context = _record_context(args, tolerance)
    _check_frame(args.frame)
    if args.registration and args.frame != "axes":
        raise InvalidConfigError("--registration gives the frames: leave --frame out")
    scenario, name = motion_scenario(args)
    reference = scenario.reference.make(robot_geometry(scenario), scenario.duration_s, None)
    registration = _registration(args.registration)
    axis_map = key_values(args.measured_map, "--measured-map")
    out = Path(args.out)
    stems = [f"verify_{name}_{Path(m).stem}" for m in args.measured]
    if len(set(stems)) != len(stems):
        raise InvalidConfigError("--measured names two files of one name: give each once")
    for stem in stems:
        for suffix in (".md", ".png", ".json"):
            check_replaceable(out / f"{stem}{suffix}")
    held = _identities(args, context)
    measured = []
    for path in args.measured:
        print(f"verify: reading {path}", file=sys.stderr, flush=True)
        measured.append(measured_file(path, args, scenario, axis_map))
        if measured[-1].repaired:
            print(
                f"verify: {path}: {len(measured[-1].repaired)} times repaired from its frame "
                f"counter (each listed in the report), the first: {measured[-1].repaired[0]}",
                file=sys.stderr,
                flush=True,
            )
    results = []
    for m, stem in zip(measured, stems):
        print(
            f"verify: aligning and judging {Path(m.path).name} ({len(m.t)} samples)",
            file=sys.stderr,
            flush=True,
        )
        ver = verify(
            reference,
            m,
            clock_offset_s=args.clock_offset,
            frame=args.frame,
            registration=registration,
            max_latency_s=args.max_latency,
            tolerance=tolerance,
            max_gap_s=args.measured_max_gap,
            pauses=args.measured_pauses,
            exclude_outliers=args.exclude_outliers,
            action_level=action_level,
        )
        replaced = _earlier_verdict(out / f"{stem}.json")
        md, png, js = write_verification(ver, out, stem)
        print(ver.judgement.line)
        print(_summary(ver))
        print(f"wrote {md}, {png} and {js}" + (f" (replacing {replaced})" if replaced else ""))
        if context is not None:
            from dataclasses import replace

            from .qa_record import write_record
            from .record_options import phantom_words

            inputs = _record_inputs(args, m.path)
            identities = tuple(held[str(p)] for p in inputs if str(p) in held)
            pdf, record = write_record(
                ver,
                out,
                replace(
                    context,
                    inputs=tuple(inputs),
                    identities=identities,
                    scenario=phantom_words(args, m),
                ),
                stem,
            )
            print(f"wrote the QA record {pdf} and {record}")
        results.append(ver)
    if len(results) > 1:
        print("\n".join(_side_by_side(results)))
    return exit_status([ver.judgement.verdict for ver in results])


#: ``verify``'s exit status of each verdict, the package's one
#: (:data:`stewart_drake.base.verdicts.EXIT_STATUS`); of several, the worst's
#: (:func:`~stewart_drake.base.verdicts.exit_status`).
EXIT_STATUS = verdicts.EXIT_STATUS
exit_status = verdicts.exit_status


def record_options(args) -> list[str]:
    """The options of a QA record given on the command line (``--record`` first when given,
    then those it takes), in that order: one list for the checks that refuse them."""
    return [
        option
        for option, value in (
            ("--record", args.record),
            ("--operator", args.operator),
            ("--phantom-serial", args.phantom_serial),
            ("--notes", args.notes),
        )
        if value
    ]


def _action_level(args, tolerance):
    """``--action-level`` as (m, rad), checked within the tolerance before any work, or None.

    Raises:
        InvalidConfigError: not LENGTH,ANGLE; beyond the tolerance or not above 0.
    """
    from ..organ_motion.fidelity import parse_tolerance
    from .verdict_levels import check_action_level

    if args.action_level is None:
        return None
    action = parse_tolerance(args.action_level, "--action-level")
    check_action_level(action, tolerance)
    return action


def _record_context(args, tolerance):
    """The :class:`~stewart_drake.verification.qa_record.RecordContext` of ``--record`` and its
    options, checked before any work (reportlab importable), or None without ``--record``.

    Raises:
        InvalidConfigError: a record's option without ``--record``; a text too long
            (:meth:`~stewart_drake.verification.qa_record.RecordContext.check`).
        MissingExtraError: reportlab is not installed.
    """
    from ..base.errors import InvalidConfigError
    from .qa_record import RecordContext, _reportlab
    from .record_options import reference_words

    given = record_options(args)
    if not args.record:
        if given:  # --record itself is not among them
            raise InvalidConfigError(f"{given[0]} is for the QA record: add --record")
        return None
    from ..execution.options import check_writable

    check_writable(Path(args.out) / "records", "--out")  # where the record goes, before any work
    context = RecordContext(
        operator=args.operator,
        phantom_serial=args.phantom_serial,
        notes=args.notes,
        scenario=str(args.scenario),
        reference=reference_words(args),
    )
    context.check()
    _reportlab()
    return context


def _identities(args, context) -> dict:
    """{path: :func:`~stewart_drake.verification.qa_record.file_identity`} of every file a
    record would name, taken before any is read ({} without ``--record``): the record holds
    the hash of the bytes judged, or refuses to be written."""
    if context is None:
        return {}
    from .qa_record import file_identity

    paths = [p for measured in args.measured for p in _record_inputs(args, measured)]
    return {str(p): file_identity(p) for p in paths}


def _record_inputs(args, measured) -> list:
    """The files a record of the measured file ``measured`` names: it, the motion's trace file
    (a named motion has none) and the registration, in that order."""
    from ..execution.options import is_trace_file

    trace = [args.motion] if is_trace_file(args.motion) else []
    return [measured, *trace, *([args.registration] if args.registration else [])]


def _earlier_verdict(path) -> str:
    """The words of an earlier report this run's replaces (its name and verdict), or ""."""
    from ..base.fileio import read_json

    try:
        data = read_json(path, "verify report")
        verdict = data["verdict"].get("verdict") or (
            "PASS" if data["verdict"]["passed"] else "FAIL"
        )
    except FileNotFoundError:
        return ""
    except Exception:  # a report of another version, or damaged: replaced all the same
        return f"the earlier report {Path(path).name}"
    return f"an earlier report of this name, its verdict {verdict}"


def _registration(path):
    """The registration REG.yaml gives
    (:func:`~stewart_drake.calibration.registration_file.read_registration`), or None."""
    if not path:
        return None
    from ..calibration.registration_file import read_registration

    return read_registration(path)


def measured_file(path: str, args, scenario, axis_map: dict):
    """The :class:`~stewart_drake.verification.measured_motion.MeasuredMotion` of a measured file:
    an encoder log (its name ends in :data:`ENCODER_LOG_SUFFIX`; read by the join's reader and
    turned into poses by forward kinematics of the scenario's robot) or a tracker's file (the
    trace readers, ``--measured-columns``, ``--measured-map``)."""
    from .measured_motion import encoder_motion, read_measured

    if not str(path).endswith(ENCODER_LOG_SUFFIX):
        return read_measured(path, args.measured_columns or "", axis_map)
    from ..calibration.join import read_encoder_log
    from ..run.plan import robot_geometry

    log = read_encoder_log(path)
    return encoder_motion(path, log["t_path"], log["q"], robot_geometry(scenario), log["bus"])


def _summary(ver) -> str:
    """The printed line of a verification's figures: latency, then per measured axis the RMS
    and peak error (each beside the per-axis tolerance it is judged against), and gamma; in
    um below 0.1 mm, mm above (urad and deg for the rotations)."""
    import numpy as np

    from ..organ_motion.fidelity import AXES, format_angle, format_length, format_window
    from .verify import seconds

    fid = ver.fidelity
    measured = np.asarray(ver.measured.measured, dtype=bool)
    rms, peak = fid["rms"], fid["peak"]

    def amount(k: int, v: float) -> str:
        return format_length(abs(v)) if k >= 3 else format_angle(abs(v))

    axes = ", ".join(
        f"{AXES[k]} {amount(k, rms[k])} (peak {amount(k, peak[k])})"
        for k in map(int, np.flatnonzero(measured))
    )
    gamma = fid["gamma"][0]
    return (
        f"{Path(ver.measured.path).name}: latency {seconds(ver.latency_s)} (clock offset "
        f"{ver.clock_offset_s:+.6g} s, {ver.clock}); RMS error per axis over t = "
        f"{format_window(*fid['window_s'])} s: {axes}"
        + (
            ""
            if math.isnan(fid["rms_translation_m"])
            else f"; gamma {100 * gamma['pass_rate']:.4g} % at {gamma['distance_m'] * 1e3:g} mm "
            f"/ {gamma['time_s'] * 1e3:g} ms"
        )
    )


def _side_by_side(results: list) -> list:
    """The lines of a table of several measured views of one motion (the tracker's and the
    encoders'), one row each."""
    from ..base.tables import markdown_lines
    from .verify import seconds

    def number(v: float, scale: float, unit: str) -> str:
        return "not measured" if math.isnan(v) else f"{v * scale:.3g} {unit}"

    rows = []
    for ver in results:
        fid = ver.fidelity
        rows.append(
            [
                Path(ver.measured.path).name,
                ver.measured.kind,
                ver.judgement.verdict,
                seconds(ver.latency_s),
                number(fid["rms_translation_m"], 1e6, "um"),
                number(fid["rms_rotation_rad"], 1e6, "urad"),
                number(fid["peak_translation_m"], 1e6, "um"),
                f"{100 * fid['gamma'][0]['pass_rate']:.4g} %",
            ]
        )
    header = [
        "measured",
        "by",
        "verdict",
        "latency",
        "RMS translation",
        "RMS rotation",
        "peak",
        "gamma",
    ]
    return ["", "side by side:", *markdown_lines(header, rows)]


__all__ = ["ENCODER_LOG_SUFFIX", "add_verify_command", "cmd_verify"]
