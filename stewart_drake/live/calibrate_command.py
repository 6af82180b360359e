"""``stewart-drake calibrate``: the robot's per-leg parameters identified from a tracker's
measurements (``calibrate MEASUREMENTS.csv --out ROBOT.yaml``), the poses to measure chosen
(``--plan N --out POSES.csv``), a session's encoder log and tracker file joined into
measurements (``--join``), or the whole rehearsed on an emulated robot (``--rehearse``; over
the bus emulator with ``--bus``). With ``--registration REG.yaml`` the tracker's poses are its
marker's in its own frame, converted to the base frame by the frames REG.yaml's fiducials give
(:mod:`~stewart_drake.calibration.registration`).

The command lives with the robot live, not in :mod:`stewart_drake.calibration`: its rehearsal
over the bus (``--rehearse --bus``) drives the robot's session
(:mod:`~.calibration_rehearsal`), a floor above the calibration it calls."""

from __future__ import annotations

import math
import sys
from pathlib import Path

from ..calibration.calibrate_options import (
    add_identification_arguments,
    add_mode_arguments,
    add_rehearsal_arguments,
)
from ..execution.options import add_param_argument, add_scenario_arguments
from ..verification.command import add_measured_file_arguments


def register(sub) -> None:
    """Add the ``calibrate`` command to ``sub``, the ``stewart-drake`` subparsers."""
    from ..run.scenario_io import ROBOT_SCENARIO

    cal = sub.add_parser(
        "calibrate",
        help="identify the robot's per-leg geometry and encoder zeros from a tracker's "
        "measurements (docs/calibration.md); --plan chooses the poses, --rehearse tries it all "
        "on an emulated robot",
    )
    cal.add_argument(
        "measurements",
        nargs="?",
        default=None,
        metavar="MEASUREMENTS.csv",
        help="encoder readings and the tracker's poses, a header naming columns and units: "
        "q0 [rad] .. q5 [rad], phi [rad], theta [rad], psi [rad], X [m], Y [m], Z [m]; the "
        "platform frame's poses in the base frame, or with --registration the marker's in the "
        "tracker's frame",
    )
    cal.add_argument(
        "--registration",
        default=None,
        metavar="REG.yaml",
        help="the tracker's frames: fiducials it measured on the base (base_points: >= 3 of "
        "{base_m: [x, y, z], tracker_m: [x, y, z]}) and, optionally, on the platform with its "
        "marker (platform_points); the poses measured are then the marker's in the tracker's "
        "frame, converted to the base frame before the identification, the frames' "
        "uncertainty carried into the parameters' (docs/calibration.md, Registration). For "
        "identifying, --join and --rehearse (default: none, the poses are the platform "
        "frame's in the base frame)",
    )
    add_mode_arguments(cal, ROBOT_SCENARIO)
    cal.add_argument(
        "--out",
        default=None,
        help="the robot section to write (ROBOT.yaml), with --plan the path (POSES.csv), with "
        "--join the measurements (MEASUREMENTS.csv) (default: none, which only --rehearse "
        "accepts)",
    )
    add_scenario_arguments(cal, "the nominal robot and its encoders")
    add_identification_arguments(cal)
    add_rehearsal_arguments(cal)
    add_measured_file_arguments(cal)
    add_param_argument(
        cal,
        "with --register: a parameter of the registration motion with its unit "
        "(repeatable), as the robot ran it (default: the motion's own)",
    )
    cal.add_argument("--no-progress", action="store_true", help="hide the progress bar")
    # --scenario given or not: without it, the bus rehearsal takes the robot's bus scenario.
    cal.set_defaults(
        func=_cmd_calibrate, out_is_file=True, scenario=None, derived_inputs=_derived_inputs
    )


def _derived_inputs(args) -> list:
    """The file ``calibrate`` reads beside one its options name: ``--plan-file``'s windows
    file (with ``--join``)."""
    if args.plan_file is None:
        return []
    from ..calibration.files import windows_path

    return [(f"--plan-file {args.plan_file}'s windows file", windows_path(args.plan_file))]


def _cmd_calibrate(args) -> int:
    """``stewart-drake calibrate``: one of its modes (identify, ``--plan``, ``--rehearse``,
    ``--join``, ``--register``), each checked before any work."""
    from ..base.errors import InvalidConfigError

    if args.register is not None:
        return _register(args)
    for dest in ("param", "measured_columns", "measured_map", "clock_offset"):
        if getattr(args, dest) is not None:
            raise InvalidConfigError(f"--{dest.replace('_', '-')} is for --register")
    given = args.measurements is not None
    other = "--plan" if args.plan is not None else "--rehearse" if args.rehearse else "--join"
    if args.plan is not None or args.rehearse or args.join is not None:
        if given:
            raise InvalidConfigError(
                f"{other} takes no measurements file (got {args.measurements}): calibrate "
                f"MEASUREMENTS.csv --out ROBOT.yaml identifies, --plan N --out POSES.csv plans, "
                f"--join ENCODERS.csv TRACKER.csv --plan-file POSES.csv --out MEASUREMENTS.csv "
                f"joins, --rehearse rehearses"
            )
    elif not given:
        raise InvalidConfigError(
            "give the measurements file (calibrate MEASUREMENTS.csv --out ROBOT.yaml), or "
            "--plan N --out POSES.csv, or --join ENCODERS.csv TRACKER.csv --plan-file POSES.csv "
            "--out MEASUREMENTS.csv, or --rehearse"
        )
    if (args.plan_file is not None) != (args.join is not None):
        raise InvalidConfigError("--join and --plan-file go together: the logs and their path")
    if args.tracker_clock_offset is not None and args.join is None:
        raise InvalidConfigError("--tracker-clock-offset is for --join")
    if args.registration is not None and (args.plan is not None or args.bus is not None):
        raise InvalidConfigError(
            "--registration is for identifying, --join and the numerical --rehearse: --plan "
            "chooses poses in the base frame, and --rehearse --bus tracks the platform frame "
            "in it"
        )
    if args.bus is not None:
        _check_bus_rehearsal(args)
    if args.scenario is None:
        from ..execution.options import default_scenario

        args.scenario = default_scenario()
    if args.out is None and not args.rehearse:
        what = {
            "--plan": "POSES.csv (the path to drive)",
            "--join": "MEASUREMENTS.csv",
        }.get(other, "ROBOT.yaml")
        raise InvalidConfigError(f"--out is required: the file to write, {what}")
    registration = _registration(args)
    if args.join is not None:
        return _join(args, registration)
    if args.save_measurements is not None:
        if not args.rehearse:
            raise InvalidConfigError("--save-measurements is for --rehearse")
        from ..calibration.files import registration_path
        from ..execution.options import check_output

        check_output(args.save_measurements, "--save-measurements", is_file=True)
        if registration is not None:
            check_output(
                registration_path(args.save_measurements),
                "--save-measurements's registration file",
                is_file=True,
            )
    if args.plan is not None:  # its second file, checked before any work as --out is
        from ..calibration.files import windows_path
        from ..execution.options import check_output

        check_output(windows_path(args.out), "--out's windows file", is_file=True)
    context = _context(args)
    if args.plan is not None:
        return _plan(args, context)
    if args.rehearse and args.bus is not None:
        return _rehearse_on_bus(args, context)
    if args.rehearse:
        return _rehearse(args, context, registration)
    return _identify(args, context, registration)


#: The options ``calibrate --register`` does not take (identification's, --join's and
#: --rehearse's), each named when given.
NOT_FOR_REGISTER = (
    ("measurements", "a measurements file"),
    ("registration", "--registration (it fits the frames itself)"),
    ("plan_file", "--plan-file"),
    ("tracker_clock_offset", "--tracker-clock-offset (its clock is --clock-offset)"),
    ("bus", "--bus"),
    ("save_measurements", "--save-measurements"),
)


def _register(args) -> int:
    """``calibrate --register MEASURED.csv --out REG.yaml``: the tracker's frames fitted to its
    run of the registration motion and written
    (:func:`~stewart_drake.verification.registration_command.save_registration`), 0; the run
    is not judged. The motion is the library's ``registration`` with ``--param``, on
    ``--scenario``'s robot (default: ``reproduce``'s and ``verify``'s scenario).

    Raises:
        InvalidConfigError: an option of another mode; no --out, or one that exists (a
            registration is never replaced: the runs judged with it name it); what the reader
            and the fit refuse.
    """
    from dataclasses import replace

    from ..base.errors import InvalidConfigError
    from ..base.fileio import check_replaceable
    from ..execution.trace_options import key_values
    from ..organ_motion import SCENARIO
    from ..references.organ.library import OrganMotionReference
    from ..run.plan import robot_geometry
    from ..run.scenario_io import load_scenario
    from ..verification.command import measured_file
    from ..verification.registration_command import save_registration

    for dest, what in NOT_FOR_REGISTER:
        if getattr(args, dest) is not None:
            raise InvalidConfigError(f"--register takes no {what}")
    if args.out is None:
        raise InvalidConfigError("--register needs --out REG.yaml: the registration to write")
    out = Path(args.out)
    check_replaceable(out, f"--out {out}")
    if out.exists():
        raise InvalidConfigError(
            f"--out {out} exists: a registration is never replaced (the runs judged with it "
            "name it); give a new name, or move the old one away first"
        )
    params = key_values(args.param, "--param")
    scenario = load_scenario(args.scenario or SCENARIO, args.set or ())
    motion = OrganMotionReference("registration", params)
    scenario = replace(scenario, reference=motion).validate()
    reference = scenario.reference.make(robot_geometry(scenario), scenario.duration_s, None)
    axis_map = key_values(args.measured_map, "--measured-map")
    print(f"calibrate: reading {args.register}", file=sys.stderr, flush=True)
    measured = measured_file(args.register, args, scenario, axis_map)
    print("calibrate: fitting the tracker's frames to the registration motion", file=sys.stderr)
    print(
        save_registration(
            reference,
            measured,
            out,
            args.clock_offset,
            args.max_latency,
            args.measured_max_gap,
        )
    )
    print(f"wrote {out}")
    return 0


def _registration(args):
    """(the registration, its fiducials) of ``--registration``, read and checked before any
    work, or None."""
    if args.registration is None:
        return None
    from ..calibration.registration import register
    from ..calibration.registration_file import read_fiducials

    fiducials = read_fiducials(args.registration)
    return register(fiducials, args.registration), fiducials


#: The files ``calibrate --rehearse --bus FOLDER`` writes in FOLDER.
BUS_REHEARSAL_FILES = (
    "poses.csv",
    "poses_windows.csv",
    "robot.npz",
    "robot_encoders.csv",
    "tracker.csv",
    "measurements.csv",
    "robot.yaml",
)


def _check_bus_rehearsal(args) -> None:
    """``--rehearse --bus FOLDER``'s options, before any work; the default scenario becomes
    the robot's (:data:`~stewart_drake.run.scenario_io.ROBOT_SCENARIO`, with a bus).

    Raises:
        InvalidConfigError: --bus without --rehearse, with --out or --save-measurements (its
            files are in FOLDER), or FOLDER not writable.
    """
    from ..base.errors import InvalidConfigError
    from ..execution.options import check_output

    if not args.rehearse:
        raise InvalidConfigError("--bus is for --rehearse (the rehearsal over the bus emulator)")
    if args.out is not None or args.save_measurements is not None:
        raise InvalidConfigError(
            f"--rehearse --bus keeps its files in {args.bus} (robot.yaml, measurements.csv): "
            f"leave out --out and --save-measurements"
        )
    # Every file it writes, checked before the drive (each was checked only when written).
    for name in BUS_REHEARSAL_FILES:
        check_output(Path(args.bus) / name, "--bus", is_file=True)
    check_output(Path(args.bus) / "diverged", "--bus")
    if args.scenario is None:
        from ..run.scenario_io import ROBOT_SCENARIO

        args.scenario = ROBOT_SCENARIO


def _join(args, registration) -> int:
    """``calibrate --join ENCODERS.csv TRACKER.csv --plan-file POSES.csv --out
    MEASUREMENTS.csv``: every file read and checked before the one written."""
    from ..calibration.files import windows_path, write_measurements
    from ..calibration.join import join

    encoders, tracker = args.join
    joined = join(
        encoders,
        tracker,
        windows_path(args.plan_file),
        clock_offset=_clock_offset(args.tracker_clock_offset),
        path_file=args.plan_file,
        registration=None if registration is None else registration[0],
    )
    path = write_measurements(args.out, joined.poses, joined.readings)
    if joined.clock is not None:
        print(
            f"the tracker's clock + {joined.clock_offset_s:.4f} s = the robot computer's "
            f"(estimated from the motion: the tracked poses {joined.clock.residual_m * 1e3:.3g} "
            f"mm RMS from the path over {joined.clock.samples} samples, rotations at 0.15 m)"
        )
    elif joined.clock_offset_s:
        print(f"the tracker's times + {joined.clock_offset_s:g} s, as given")
    print(
        f"joined {len(joined.poses)} poses: {int(joined.readings_used.min())} to "
        f"{int(joined.readings_used.max())} readings and {int(joined.tracker_used.min())} to "
        f"{int(joined.tracker_used.max())} tracker samples a window; the readings' largest "
        f"spread in a window {joined.reading_spread.max() * 1e6:.3g} urad"
    )
    if registration is None:
        print(f"wrote {path} (calibrate {path} --out ROBOT.yaml identifies the robot)")
    else:
        print(
            f"wrote {path}: the marker's poses in the tracker's frame, as the tracker file's "
            f"(calibrate {path} --registration {args.registration} --out ROBOT.yaml identifies "
            f"the robot)"
        )
    return 0


def _clock_offset(text):
    """--tracker-clock-offset: a finite number of seconds, "estimate", or None (0)."""
    from ..base.errors import InvalidConfigError

    if text is None:
        return 0.0
    if text.strip() == "estimate":
        return "estimate"
    try:
        value = float(text)
    except ValueError:
        value = math.nan
    if not math.isfinite(value):
        raise InvalidConfigError(
            f"--tracker-clock-offset takes a number of seconds or estimate, got {text!r}"
        )
    return value


def _context(args):
    """(the command's scenario, the nominal geometry at the temperature of the measurements
    (:func:`~.files.nominal_at_temperature`), the measurement noise)."""
    from ..calibration.files import nominal_at_temperature
    from ..calibration.tracker import COUNTS_PER_REV, MeasurementNoise
    from ..run.plan import as_built
    from ..run.scenario_io import load_scenario

    scenario = load_scenario(args.scenario, args.set or ())
    hardware = as_built(scenario).hardware  # on a bus, the robot built with its servos
    counts = hardware.encoders.counts_per_rev if hardware is not None else COUNTS_PER_REV
    noise = MeasurementNoise(args.noise[0], args.noise[1], counts)
    return scenario, nominal_at_temperature(scenario), noise


def _identify(args, context, registration) -> int:
    """``calibrate MEASUREMENTS.csv --out ROBOT.yaml [--registration REG.yaml]``."""
    from dataclasses import replace

    from ..calibration.files import read_measurements, robot_section
    from ..calibration.registration import register_poses
    from ..calibration.report import (
        check_reachable,
        frames_text,
        identification_checks,
        identification_text,
        write_identified,
    )

    scenario, geometry, noise = context
    data = read_measurements(args.measurements, noise.counts_per_rev)
    registered = None
    if registration is not None:
        registered = register_poses(
            registration[0], data.poses, noise.rotation_rad, noise.translation_m
        )
        data = replace(data, poses=registered.poses)
    check_reachable(geometry, data, registered is not None)
    print(
        f"read {len(data.poses)} measured poses from {args.measurements}"
        + (
            f" (converted: {', '.join(f'{n} [{u}]' for n, u in data.converted)})"
            if data.converted
            else ""
        )
        + (f"; columns not read: {', '.join(data.ignored)}" if data.ignored else "")
    )
    ident = _identification(args, geometry, data.poses, data.readings, noise, registered)
    if registration is not None:
        print(frames_text(geometry, ident, registration[0], data.poses, args.registration))
    print(identification_text(ident, noise, data.lines))
    checked, warnings = identification_checks(
        scenario, geometry, ident, data.poses, data.readings, noise, registered
    )
    print("\n".join(checked))
    for line in warnings:
        print(f"stewart-drake calibrate: warning: {line}", file=sys.stderr)
    frames = None if registration is None else (registration[0], args.registration)
    robot = robot_section(scenario.robot, geometry)
    path = write_identified(args.out, robot, ident, args.measurements, frames)
    if path is None:
        return 1
    print(f"wrote {path} (a scenario's robot: section{_held_at(scenario, geometry)})")
    return 0


def _held_at(scenario, geometry) -> str:
    """Words on the temperature a written robot's lengths hold at, when one was given."""
    if scenario.temperature_c is None:
        return ""
    return f"; its lengths hold at {geometry.lengths_at_c:g} C, the measurements' temperature"


def _identification(args, geometry, poses, q, noise, registered=None):
    """:func:`~.identify.identify` with the command's options (and a registration's
    :class:`~.registration.RegisteredPoses`' errors)."""
    from ..calibration.identify import identify

    return identify(
        geometry,
        poses,
        q,
        noise,
        min_singular=args.min_singular,
        outlier_threshold=args.outlier_threshold,
        robust=args.robust,
        drop_outliers=args.drop_outliers,
        pose_covariances=None if registered is None else registered.pose_covariances,
        frames=None if registered is None else registered.frames,
    )


def _plan(args, context) -> int:
    """``calibrate --plan N --out POSES.csv``."""
    from ..calibration.report import plan_poses

    scenario, _, noise = context
    return plan_poses(
        scenario,
        args.plan,
        args.out,
        noise,
        args.seed,
        args.dwell,
        n_candidates=args.candidates,
        progress=not args.no_progress,
    )


def _rehearse(args, context, registration) -> int:
    """``calibrate --rehearse [--registration REG.yaml]``: with a registration, the emulated
    tracker stands at its frames, its fiducials where REG.yaml's drawing puts them."""
    from ..calibration.files import robot_section
    from ..calibration.rehearsal import pick, rehearse, setup_of_registration, workspace
    from ..calibration.report import rehearsal_text, write_identified
    from ..robot.tolerances import Tolerances
    from ..run.plan import robot_motor_limits

    scenario, geometry, noise = context
    tolerances = Tolerances()
    select = args.select or "random"
    setup, sigma = setup_of_registration(registration)
    print(
        f"rehearsal: a robot drawn with seed {args.seed} (+-0.5 mm joints, +-0.2 mm cranks, "
        f"+-0.3 mm rods, +-1 mrad shaft tilts and crank azimuths, +-5 mrad encoder zeros), "
        f"{args.poses} {select} poses, tracker {noise.words()}"
        + (
            ""
            if scenario.temperature_c is None
            else f", at {geometry.lengths_at_c:g} C (the nominal lengths scaled from "
            f"robot.lengths_at_c = {scenario.robot.lengths_at_c:g} C)"
        )
        + (
            ""
            if setup is None
            else f"; the tracker and its marker at {args.registration}'s frames, its "
            f"fiducials measured again at {sigma * 1e6:.3g} um"
        ),
        flush=True,
    )
    from tqdm import tqdm

    with tqdm(total=3, desc="rehearsing", disable=args.no_progress, leave=False) as bar:
        space = workspace(geometry, args.candidates, motor_limits=robot_motor_limits(scenario))
        bar.update(1)
        idx = pick(geometry, space, args.poses, select, noise, tolerances, args.seed)
        bar.update(1)
        r = rehearse(geometry, space, idx, noise, args.seed, tolerances, select, setup, sigma)
        bar.update(1)
    print(rehearsal_text(r, noise))
    if args.save_measurements is not None:
        _save_rehearsal(args, geometry, r, space.candidates[idx], noise, setup, sigma)
    if args.out is not None:
        frames = None if r.registration is None else (r.registration, "the emulated fiducials")
        robot = robot_section(scenario.robot, geometry)
        path = write_identified(args.out, robot, r.identification, "a rehearsal", frames)
        if path is None:
            return 1
        print(f"wrote {Path(path)} (a scenario's robot: section{_held_at(scenario, geometry)})")
    return 0


def _save_rehearsal(args, geometry, r, x, noise, setup, sigma) -> None:
    """``--save-measurements``: the rehearsal's measurements (the marker's in the tracker's
    frame with a setup, and the fiducials measured, a REG.yaml beside them)."""
    from ..calibration.files import registration_path, write_measurements, write_registration
    from ..calibration.tracker import measure

    data = measure(geometry, r.truth, x, noise, args.seed, setup=setup)
    path = write_measurements(args.save_measurements, data.poses, data.readings)
    if setup is None:
        print(f"wrote {path} (the emulated measurements: calibrate reads them)")
        return
    fiducials = setup.fiducials(noise, args.seed + 30_000, sigma)
    reg = write_registration(registration_path(path), fiducials)
    print(
        f"wrote {path} (the emulated measurements, the marker's in the tracker's frame) and "
        f"{reg} (its fiducials: calibrate {path.name} --registration {reg.name} reads them)"
    )


def _rehearse_on_bus(args, context) -> int:
    """``calibrate --rehearse --bus FOLDER``: the calibration rehearsed over the bus emulator
    (:func:`~.calibration_rehearsal.rehearse_on_bus`), its figures printed; ``context`` is the
    calibrate command's (the scenario, the nominal geometry, the tracker's noise)."""
    from ..base.errors import InvalidConfigError
    from .calibration_rehearsal import rehearse_on_bus

    scenario, _, noise = context
    if scenario.bus is None:
        raise InvalidConfigError(
            f"--rehearse --bus drives the robot on its bus: --scenario {args.scenario} has no "
            f"bus section (paper_bus has one)"
        )
    from ..station.bus.vendor_port import dynamixel_sdk

    dynamixel_sdk()  # the extra, before anything starts: MissingExtraError names it
    from ..execution.options import say_if_compiling

    say_if_compiling("robot")
    rehearsal = rehearse_on_bus(
        scenario,
        args.poses,
        args.bus,
        seed=args.seed,
        noise=noise,
        select=args.select or "chosen",
        dwell_s=args.dwell,
        n_candidates=args.candidates,
        progress=not args.no_progress,
        say=lambda line: print(line, flush=True),
    )
    print(rehearsal.text())
    print(f"wrote in {args.bus}: " + ", ".join(Path(p).name for p in rehearsal.files.values()))
    return 0
