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
        help="the largest latency that passes with --clock-offset, s (latencies up to three "
        "times it are searched, so that one beyond it is found and fails)",
    )
    vp.add_argument(
        "--measured-max-gap",
        type=positive_float,
        default=0.5,
        metavar="S",
        help="the longest step between two measured samples judged across, s: the samples are "
        "judged at their own times, nothing interpolated; a longer gap (the tracker lost the "
        "marker) is refused where it is",
    )
    vp.add_argument(
        "--registration",
        default=None,
        metavar="REG.yaml",
        help="the tracker registered to the robot: fiducials (as calibrate takes them) or the "
        "frames --save-registration wrote; the measured poses are judged in the base frame, "
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
    vp.add_argument(
        "--save-registration",
        default=None,
        metavar="REG.yaml",
        help="register the tracker instead of judging: fit its frame and the marker's offset to "
        "this measured run of a known motion (the library's registration), write them as "
        "REG.yaml for later runs' --registration, and give no verdict (default: judge)",
    )
    vp.add_argument(
        "--tolerance",
        default="0.1mm,0.1deg",
        help="RMS error allowed per measured axis, a length and an angle",
    )
    add_scenario_arguments(
        vp, "the robot whose encoder log is read (forward kinematics)", default=SCENARIO
    )
    vp.add_argument("--out", default="results/verify", help="report folder")
    vp.set_defaults(func=cmd_verify)


def _check_frame(text: str) -> None:
    """``--frame``'s value: "axes" or "base"; "fit" refused saying why.

    Raises:
        InvalidConfigError: any other value (one line).
    """
    from ..base.errors import InvalidConfigError

    if text == "fit":
        raise InvalidConfigError(
            "--frame fit is gone: a frame fitted to the motion judged absorbs the errors it "
            "should find; register the tracker once (--save-registration on the registration "
            "motion, or fiducials) and give --registration REG.yaml, or use --frame axes"
        )
    if text not in ("axes", "base"):
        raise InvalidConfigError(f"--frame is axes or base, got {text!r}")


def cmd_verify(args) -> int:
    """``stewart-drake verify``: read the reference and each measured file, judge each, write
    its report and print its verdict and figures (a table side by side for several); 0 when
    every verdict passes, 2 otherwise. With ``--save-registration``: fit the tracker's frames to
    the one measured run of a known motion and write them, 0, no verdict.

    Raises:
        InvalidConfigError, MissingFileError, CorruptFileError: a bad option or file (one line:
            the measured file's columns, a NaN, too short, no overlap), before any report.
    """
    import sys

    from ..base.errors import InvalidConfigError
    from ..base.fileio import check_replaceable
    from ..execution.options import key_values
    from ..organ_motion.command import motion_scenario
    from ..organ_motion.fidelity import parse_tolerance
    from ..organ_motion.verification import verify
    from ..organ_motion.verification_report import write_verification
    from ..run.plan import robot_geometry

    tolerance = parse_tolerance(args.tolerance)
    _check_frame(args.frame)
    if args.registration and args.frame != "axes":
        raise InvalidConfigError("--registration gives the frames: leave --frame out")
    if args.save_registration and (args.registration or args.frame != "axes"):
        raise InvalidConfigError(
            "--save-registration fits the frames itself: leave --registration and --frame out"
        )
    if args.save_registration and len(args.measured) != 1:
        raise InvalidConfigError("--save-registration fits one measured run: give one --measured")
    scenario, name = motion_scenario(args)
    reference = scenario.reference.make(robot_geometry(scenario), scenario.duration_s, None)
    registration = _registration(args.registration)
    axis_map = key_values(args.measured_map, "--measured-map")
    out = Path(args.out)
    if args.save_registration:
        check_replaceable(Path(args.save_registration))
        path = args.measured[0]
        print(f"verify: reading {path}", file=sys.stderr, flush=True)
        return _save_registration(reference, _measured(path, args, scenario, axis_map), args)
    stems = [f"verify_{name}_{Path(m).stem}" for m in args.measured]
    if len(set(stems)) != len(stems):
        raise InvalidConfigError("--measured names two files of one name: give each once")
    for stem in stems:
        for suffix in (".md", ".png", ".json"):
            check_replaceable(out / f"{stem}{suffix}")
    measured = []
    for path in args.measured:
        print(f"verify: reading {path}", file=sys.stderr, flush=True)
        measured.append(_measured(path, args, scenario, axis_map))
    results, passed = [], True
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
        )
        passed = passed and ver.judgement.passed
        md, png, js = write_verification(ver, out, tolerance, stem)
        print(ver.judgement.line)
        print(_summary(ver))
        print(f"wrote {md}, {png} and {js}")
        results.append(ver)
    if len(results) > 1:
        print("\n".join(_side_by_side(results)))
    return 0 if passed else 2


def _save_registration(reference, measured, args) -> int:
    """Fit the tracker's frames to ``measured``, a run of the known ``reference``
    (:func:`~stewart_drake.organ_motion.registration_motion.fit_registration`), and write them
    to ``--save-registration``
    (:func:`~stewart_drake.calibration.registration_file.motion_frames_yaml`); 0.

    Raises:
        InvalidConfigError: what the fit refuses; frames too uncertain to be written.
    """
    import sys

    import numpy as np
    from pydrake.math import RigidTransform, RotationMatrix

    from ..base.errors import InvalidConfigError
    from ..base.fileio import atomic_write
    from ..calibration.registration_file import MAX_MARKER_SIGMA, motion_frames_yaml
    from ..organ_motion.registration_motion import fit_registration

    print("verify: fitting the tracker's frames to the registration motion", file=sys.stderr)
    fit = fit_registration(
        reference, measured, args.clock_offset, args.max_latency, args.measured_max_gap
    )
    for what, sigma in (("the tracker's frame", fit.sigma_B), ("the marker's", fit.sigma_M)):
        if sigma[0] > MAX_MARKER_SIGMA[0] or sigma[1] > MAX_MARKER_SIGMA[1]:
            raise InvalidConfigError(
                f"{measured.path}: {what} is known to +- {sigma[0] * 1e3:.3g} mrad, "
                f"{sigma[1] * 1e3:.3g} mm only: measure a longer run of the registration motion"
            )
    X_BT = RigidTransform(RotationMatrix(fit.R_BT), fit.p_BT)
    X_PM = RigidTransform(RotationMatrix(fit.R_PM), fit.p_PM)
    text = motion_frames_yaml(
        X_BT.inverse(), X_PM, fit.sigma_B, fit.sigma_M, fit.rms_m, fit.words()
    )
    path = Path(args.save_registration)
    atomic_write(path, lambda f: f.write(text.encode()))
    print(
        f"registered the tracker: {fit.words()}; the tracker's frame known to +- "
        f"{fit.sigma_B[0] * 1e6:.3g} urad, {fit.sigma_B[1] * 1e6:.3g} um, the marker "
        f"{np.linalg.norm(fit.p_PM) * 1e3:.4g} mm from the platform's origin (+- "
        f"{fit.sigma_M[1] * 1e6:.3g} um). This run is not judged: a frame fitted to a motion "
        f"absorbs its errors. Judge later runs with --registration {path}"
    )
    print(f"wrote {path}")
    return 0


def _registration(path):
    """The registration REG.yaml gives
    (:func:`~stewart_drake.calibration.registration_file.read_registration`), or None."""
    if not path:
        return None
    from ..calibration.registration_file import read_registration

    return read_registration(path)


def _measured(path: str, args, scenario, axis_map: dict):
    """The :class:`~stewart_drake.organ_motion.measured_motion.MeasuredMotion` of a measured file:
    an encoder log (its name ends in :data:`ENCODER_LOG_SUFFIX`; read by the join's reader and
    turned into poses by forward kinematics of the scenario's robot) or a tracker's file (the
    trace readers, ``--measured-columns``, ``--measured-map``)."""
    from ..organ_motion.measured_motion import encoder_motion, read_measured

    if not str(path).endswith(ENCODER_LOG_SUFFIX):
        return read_measured(path, args.measured_columns or "", axis_map)
    from ..calibration.join import read_encoder_log
    from ..run.plan import robot_geometry

    log = read_encoder_log(path)
    return encoder_motion(path, log["t_path"], log["q"], robot_geometry(scenario))


def _summary(ver) -> str:
    """The printed line of a verification's figures: latency, RMS, peak, gamma."""
    from ..organ_motion.fidelity import format_window
    from ..organ_motion.verification import seconds

    fid = ver.fidelity
    rot, tr = fid["rms_rotation_rad"], fid["rms_translation_m"]
    gamma = fid["gamma"][0]
    return (
        f"{Path(ver.measured.path).name}: latency {seconds(ver.latency_s)} (clock offset "
        f"{ver.clock_offset_s:+.6g} s, {ver.clock}); RMS error over t = "
        f"{format_window(*fid['window_s'])} s: translation "
        + ("not measured" if math.isnan(tr) else f"{tr * 1e6:.3g} um")
        + ", rotation "
        + ("not measured" if math.isnan(rot) else f"{rot * 1e6:.3g} urad")
        + (
            ""
            if math.isnan(tr)
            else f"; peak {fid['peak_translation_m'] * 1e6:.3g} um; gamma "
            f"{100 * gamma['pass_rate']:.4g} % at {gamma['distance_m'] * 1e3:g} mm / "
            f"{gamma['time_s'] * 1e3:g} ms"
        )
    )


def _side_by_side(results: list) -> list:
    """The lines of a table of several measured views of one motion (the tracker's and the
    encoders'), one row each."""
    from ..base.tables import markdown_lines
    from ..organ_motion.verification import seconds

    def number(v: float, scale: float, unit: str) -> str:
        return "not measured" if math.isnan(v) else f"{v * scale:.3g} {unit}"

    rows = []
    for ver in results:
        fid = ver.fidelity
        rows.append(
            [
                Path(ver.measured.path).name,
                ver.measured.kind,
                "PASS" if ver.judgement.passed else "FAIL",
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
