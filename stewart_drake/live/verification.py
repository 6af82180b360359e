"""``stewart-drake verify``: a motion measured on a real phantom (a tracker's export, or the
robot's encoder log) judged against the reference it was asked to follow, with the report of
``reproduce`` (:mod:`stewart_drake.organ_motion.verification`).

It lives with the robot live because it joins two features of one rank: the organ-motion
library, its readers and its report (:mod:`~stewart_drake.organ_motion`), and the calibration's
readers of a robot session (the encoder log of :mod:`~stewart_drake.calibration.join`, the
registration of :mod:`~stewart_drake.calibration.registration`).
"""

from __future__ import annotations

import math
from pathlib import Path

from ..execution.options import (
    add_motion_arguments,
    add_scenario_arguments,
    add_trace_arguments,
    positive_float,
)

#: The end of an encoder log's name (``<stem>_encoders.csv``, as ``robot`` writes it): such a
#: measured file is read as the robot's encoder log.
ENCODER_LOG_SUFFIX = "_encoders.csv"


def add_verify_command(sub) -> None:
    """Add the ``verify`` command to ``sub``, the ``stewart-drake`` subparsers."""
    from ..organ_motion import SCENARIO

    vp = sub.add_parser(
        "verify",
        help="judge a motion measured on a real phantom (a tracker's export, or the robot's "
        "encoder log) against the reference it was asked to follow: reproduce's report, with "
        "the latency (exit 2 if beyond --tolerance)",
    )
    add_motion_arguments(vp)
    add_trace_arguments(vp)
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
    vp.add_argument(
        "--measured-columns",
        default=None,
        metavar="'-,t [ms],X [mm],...'",
        help="the measured file's columns and units when it has no header line (or to replace "
        "it); a column named - is not read (a frame counter) (default: its header)",
    )
    vp.add_argument(
        "--measured-map",
        action="append",
        metavar="COLUMN=AXIS",
        help="put a measured column on an axis, with a sign (repeatable) (default: by name)",
    )
    vp.add_argument(
        "--clock-offset",
        type=float,
        default=None,
        metavar="S",
        help="the measured file's time + S is the reference's (a tracker that started the "
        "motion at its time 12.5 s: -12.5): separates the phantom's latency from the clocks' "
        "offset (default: not known: the whole shift found is reported as the latency, with "
        "clock offset 0; the encoder log is on the reference's clock)",
    )
    vp.add_argument(
        "--max-latency",
        type=positive_float,
        default=0.5,
        metavar="S",
        help="largest latency searched with --clock-offset, s",
    )
    vp.add_argument(
        "--registration",
        default=None,
        metavar="REG.yaml",
        help="the tracker's frames registered from fiducials (as calibrate takes them) "
        "(default: a stated best fit of the tracker's frame and the marker's offset, which also "
        "removes a true constant error of the phantom; or --frame base)",
    )
    vp.add_argument(
        "--frame",
        choices=["fit", "base"],
        default="fit",
        help="without --registration: fit the tracker's frame (fit), or take the measured "
        "poses as the platform's in the base frame (base)",
    )
    vp.add_argument(
        "--tolerance",
        default="0.1mm,0.1deg",
        help="RMS error allowed per axis, a length and an angle",
    )
    add_scenario_arguments(
        vp, "the robot whose encoder log is read (forward kinematics)", default=SCENARIO
    )
    vp.add_argument("--out", default="results/verify", help="report folder")
    vp.set_defaults(func=cmd_verify)


def cmd_verify(args) -> int:
    """``stewart-drake verify``: read the reference and each measured file, judge each, write
    its report and print a line per figure (a table side by side for several); 0 when every
    verdict passes, 2 otherwise.

    Raises:
        InvalidConfigError, MissingFileError, CorruptFileError: a bad option or file (one line:
            the measured file's columns, a NaN, too short, no overlap), before any report.
    """
    from ..base.errors import InvalidConfigError
    from ..base.fileio import check_replaceable
    from ..execution.options import key_values
    from ..organ_motion.command import motion_scenario
    from ..organ_motion.fidelity import parse_tolerance, verdict
    from ..organ_motion.verification import verify
    from ..organ_motion.verification_report import write_verification
    from ..run.plan import robot_geometry

    tolerance = parse_tolerance(args.tolerance)
    if args.registration and args.frame != "fit":
        raise InvalidConfigError("--registration gives the frames: leave --frame out")
    scenario, name = motion_scenario(args)
    reference = scenario.reference.make(robot_geometry(scenario), scenario.duration_s, None)
    registration = _registration(args.registration)
    axis_map = key_values(args.measured_map, "--measured-map")
    stems = [f"verify_{name}_{Path(m).stem}" for m in args.measured]
    if len(set(stems)) != len(stems):
        raise InvalidConfigError("--measured names two files of one name: give each once")
    out = Path(args.out)
    for stem in stems:
        for suffix in (".md", ".png", ".json"):
            check_replaceable(out / f"{stem}{suffix}")
    measured = [_measured(path, args, scenario, axis_map) for path in args.measured]
    results, passed = [], True
    for m, stem in zip(measured, stems):
        ver = verify(
            reference,
            m,
            clock_offset_s=args.clock_offset,
            frame=args.frame,
            registration=registration,
            max_latency_s=args.max_latency,
        )
        ok, line = verdict(ver.fidelity, tolerance)
        passed = passed and ok
        md, png, js = write_verification(ver, out, tolerance, stem)
        print(_summary(ver))
        print(line)
        print(f"wrote {md}, {png} and {js}")
        results.append(ver)
    if len(results) > 1:
        print("\n".join(_side_by_side(results)))
    return 0 if passed else 2


def _registration(path):
    """The registration REG.yaml gives
    (:func:`~stewart_drake.calibration.registration.read_registration`), or None."""
    if not path:
        return None
    from ..calibration.registration import read_registration

    return read_registration(path)


def _measured(path: str, args, scenario, axis_map: dict):
    """The :class:`~stewart_drake.organ_motion.measured_motion.MeasuredMotion` of a measured file:
    an encoder log (its name ends in :data:`ENCODER_LOG_SUFFIX`; read by the join's reader and
    turned into poses by forward kinematics of the scenario's robot) or a tracker's file (the
    trace readers, ``--measured-columns``, ``--measured-map``)."""
    from ..organ_motion.measured_motion import encoder_motion, read_measured

    if not str(path).endswith(ENCODER_LOG_SUFFIX):
        return read_measured(path, args.measured_columns or "", axis_map)
    import numpy as np

    from ..calibration.files import READING_COLUMNS
    from ..calibration.join import ENCODER_LOG_COLUMNS, ENCODER_LOG_REMEDY, read_table
    from ..run.plan import robot_geometry

    log = read_table(
        path, "encoder log", ENCODER_LOG_COLUMNS, ENCODER_LOG_REMEDY, nan_ok=("t_path",)
    )
    readings = np.column_stack([log[n] for n in READING_COLUMNS])
    return encoder_motion(path, log["t_path"], readings, robot_geometry(scenario))


def _summary(ver) -> str:
    """The printed line of a verification: latency, RMS, peak, gamma."""
    from ..organ_motion.verification import seconds

    fid = ver.fidelity
    rot = fid["rms_rotation_rad"]
    gamma = fid["gamma"][0]
    return (
        f"{Path(ver.measured.path).name}: latency {seconds(ver.latency_s)} (clock offset "
        f"{ver.clock_offset_s:+.6g} s, {ver.clock}); RMS error over t = "
        f"{fid['window_s'][0]:.4g}-{fid['window_s'][1]:.4g} s: translation "
        f"{fid['rms_translation_m'] * 1e6:.3g} um, rotation "
        + ("not measured" if math.isnan(rot) else f"{rot * 1e6:.3g} urad")
        + f"; peak {fid['peak_translation_m'] * 1e6:.3g} um; gamma "
        f"{100 * gamma['pass_rate']:.4g} % at {gamma['distance_m'] * 1e3:g} mm / "
        f"{gamma['time_s'] * 1e3:g} ms"
    )


def _side_by_side(results: list) -> list:
    """The lines of a table of several measured views of one motion (the tracker's and the
    encoders'), one row each."""
    from ..base.tables import markdown_lines
    from ..organ_motion.verification import seconds

    rows = []
    for ver in results:
        fid = ver.fidelity
        rot = fid["rms_rotation_rad"]
        rows.append(
            [
                Path(ver.measured.path).name,
                ver.measured.kind,
                seconds(ver.latency_s),
                f"{fid['rms_translation_m'] * 1e6:.3g} um",
                "not measured" if math.isnan(rot) else f"{rot * 1e6:.3g} urad",
                f"{fid['peak_translation_m'] * 1e6:.3g} um",
                f"{100 * fid['gamma'][0]['pass_rate']:.4g} %",
            ]
        )
    header = ["measured", "by", "latency", "RMS translation", "RMS rotation", "peak", "gamma"]
    return ["", "side by side:", *markdown_lines(header, rows)]


__all__ = ["ENCODER_LOG_SUFFIX", "add_verify_command", "cmd_verify"]
