"""The robot live at the command line: ``stewart-drake teleop`` (the robot as built at real
time, driven from Meshcat's sliders), ``robot`` (the controller on the servos, or on the bus
emulator). ``verify`` is :mod:`stewart_drake.verification.command`'s."""

from __future__ import annotations

import argparse
import math
import signal
import sys
from pathlib import Path
from typing import Any

from ..execution.options import (
    add_motion_arguments,
    add_scenario_arguments,
    int_at_least,
    is_trace_file,
    positive_float,
    say_if_compiling,
    say_stage,
)
from ..execution.trace_options import TRACE_ONLY, add_trace_arguments, trace_options_given
from .robot_options import add_drive_arguments, add_session_arguments


def register(sub) -> None:
    """Add the ``teleop`` and ``robot`` commands to ``sub``, the ``stewart-drake`` subparsers."""
    _add_teleop_command(sub)
    _add_robot_command(sub)


def _add_teleop_command(sub) -> None:
    """The ``teleop`` command's options."""
    tel = sub.add_parser("teleop", help="drive the robot live at real time from Meshcat sliders")
    add_scenario_arguments(tel, "the robot driven")
    tel.add_argument(
        "--duration", type=positive_float, default=None, help="simulated s (default: until Ctrl-C)"
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


def _tcp_port(text: str) -> int:
    """A TCP port, 1..65535 (Meshcat would otherwise pick another port without a word)."""
    port = int_at_least(1)(text)
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


def _cmd_teleop(args) -> int:
    """``stewart-drake teleop``: the robot as built at real time in Meshcat, driven by sliders."""
    from pydrake.geometry import Meshcat, MeshcatParams

    from ..run.scenario_io import load_scenario
    from .teleop import build_teleop, run_teleop

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
    say_if_compiling("teleop")
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


def _add_robot_command(sub) -> None:
    """The ``robot`` command's options."""
    rob = sub.add_parser(
        "robot",
        help="run the controller on the servos (docs/robot.md): dry run, home, a reference",
    )
    add_motion_arguments(
        rob, named="a reference name (paper, home, helix, step_<axis>, sweep_<axis>)"
    )
    add_trace_arguments(rob)
    from ..run.scenario_io import ROBOT_SCENARIO

    add_scenario_arguments(rob, "the robot with its bus (a 'bus:' section)", ROBOT_SCENARIO)
    add_session_arguments(rob)
    add_drive_arguments(rob)
    from .follow_command import add_follow_arguments

    add_follow_arguments(rob)
    rob.add_argument("--no-progress", action="store_true", help="no progress bar")
    rob.add_argument("--out", default="results", help="folder of the logs")
    rob.set_defaults(func=_cmd_robot, out_sub=("diverged",))


def _cmd_robot(args) -> int:
    """``stewart-drake robot``: the closed loop on the servos of the scenario's ``bus`` (or on
    the bus emulator with ``--emulate``): a dry run, or homing then the reference, with torque
    off and one line at every end."""
    from ..base.fileio import check_replaceable
    from ..run.scenario_io import load_scenario
    from .session_signals import SessionSignals
    from .watchdog import check_loop_timeout

    if args.teleop and (args.motion is not None or args.dry_run):
        from ..base.errors import InvalidConfigError

        raise InvalidConfigError("--teleop takes no reference (the sliders are one) nor --dry-run")
    from .follow_command import check_follow_arguments

    args.follow = check_follow_arguments(args)  # None without --follow-lcm
    surrogate = _robot_surrogate(args)
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
    check_loop_timeout(args.loop_timeout, scenario.control_period_s)
    out = Path(args.out)
    stem = f"robot_{scenario.reference.label}" if args.motion else "robot"
    if args.follow is not None:
        stem = "robot_follow"
    stem += _scenario_suffix(args.scenario)
    if not args.dry_run and args.calibrate is None:
        from ..calibration.join import encoder_log_path

        check_replaceable(out / f"{stem}.npz")
        check_replaceable(encoder_log_path(out / f"{stem}.npz"))
    from ..station.bus.vendor_port import dynamixel_sdk

    dynamixel_sdk()  # the extra, before anything starts: MissingExtraError names it
    if args.calibrate is not None:
        _check_calibration_angle(scenario, args.calibrate)
    if args.emulate is not None:
        if scenario.bus is None:
            from ..station.bus.servos import DynamixelBusConfig

            scenario.bus = DynamixelBusConfig()
        if surrogate is not None and scenario.bus.surrogate is None:
            from ..station.bus.servos import SurrogateServoConfig

            scenario.bus.surrogate = SurrogateServoConfig.beside(scenario.bus.model)
        if args.emulate.servos is not None:
            scenario.emulator.servos = args.emulate.servos
        _check_emulated_pose(scenario, args.emulate.pose)
    if surrogate is not None:
        scenario.validate()
        from .session_surrogate import check_surrogate_trace

        check_surrogate_trace(scenario, surrogate)
    if not args.dry_run and args.calibrate is None:
        # Loaded (or compiled) before anything is powered: a first load inside the first
        # control period would trip our watchdog.
        say_if_compiling("robot")
    if args.budget:
        return _robot_budget(args, scenario)
    with SessionSignals() as signals:  # held from the torque-off through the end line
        return _robot_session(args, scenario, out, stem, signals, surrogate)


def _robot_surrogate(args):
    """``robot --surrogate EXTERNAL``: the surrogate's trace read and checked
    (:func:`~stewart_drake.station.surrogate.carriage.load_surrogate`), or None without the option.

    Raises:
        InvalidConfigError: with --teleop, --follow-lcm, --dry-run or --calibrate (a surrogate
            follows a reference run); the file's refusals.
    """
    if args.surrogate is None:
        return None
    from ..base.errors import InvalidConfigError

    given = [
        name
        for name, on in (
            ("--teleop", args.teleop),
            ("--follow-lcm", args.follow is not None),
            ("--dry-run", args.dry_run),
            ("--calibrate", args.calibrate is not None),
        )
        if on
    ]
    if given:
        raise InvalidConfigError(
            f"--surrogate drives the surrogate beside a reference run, not with {given[0]}"
        )
    from ..station.surrogate.carriage import load_surrogate

    return load_surrogate(args.surrogate)


def _scenario_suffix(source) -> str:
    """``""`` for the robot command's own scenario, else ``_<its name>`` (a file's stem): a run
    of another robot never replaces the default robot's files (``robot breathing --scenario
    phantom_bus`` writes ``robot_breathing_phantom_bus_encoders.csv``)."""
    from ..run.scenario_io import ROBOT_SCENARIO

    if str(source) == ROBOT_SCENARIO:
        return ""
    name = Path(str(source)).stem if str(source).endswith((".yaml", ".yml")) else str(source)
    return "_" + "".join(c if c.isalnum() or c in "-_" else "_" for c in name)


def _robot_reference(args, scenario) -> None:
    """``robot``'s MOTION onto ``scenario``: a name of
    :data:`~stewart_drake.references.trajectories.TRAJECTORIES` ("home" holds the home pose), or
    what ``reproduce`` takes (a library motion with its ``--param`` and ``--add``, a trace or
    CSV file with the trace options: :func:`~stewart_drake.organ_motion.command.motion_reference`);
    None keeps the scenario's. A trace without ``--duration`` runs whole: ``args.duration`` is
    set to its length, s.

    Raises:
        InvalidConfigError: a name neither a trajectory nor a library motion, or options its
            motion does not take (named).
    """
    from ..base.errors import InvalidConfigError
    from ..organ_motion.command import motion_reference
    from ..references.organ.library import LIBRARY
    from ..references.traces import TraceReference
    from ..references.trajectories import TRAJECTORIES, NamedReference

    source = args.motion
    if source is None or source in TRAJECTORIES:
        given = [o for o, v in (("--param", args.param), ("--add", args.add)) if v]
        if trace_options_given(args):
            given.append(TRACE_ONLY)
        if given:
            what = f"the reference {source}" if source else "the scenario's reference"
            raise InvalidConfigError(
                f"{', '.join(given)}: for a library motion or a trace file, not {what}; name "
                "one (robot breathing --param amplitude=10mm)"
            )
        if source is not None:
            scenario.reference = NamedReference(source)
        return
    if not is_trace_file(source) and source not in LIBRARY:
        raise InvalidConfigError(
            f"robot takes a reference name ({', '.join(TRAJECTORIES)}), a library motion "
            f"({', '.join(LIBRARY)}), a trace or a CSV file, got {source!r}"
        )
    scenario.reference = motion_reference(args)
    if isinstance(scenario.reference, TraceReference) and args.duration is None:
        # The whole of it (a planned path, a recorded motion).
        scenario.reference.validate()  # a missing file named before it is read
        args.duration = float(scenario.reference.load().end_time)


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
    from ..run.plan import robot_geometry

    try:
        ik(robot_geometry(scenario), np.asarray(x0, dtype=float))
    except StewartError as err:
        raise InvalidConfigError(
            f"--emulate {','.join(f'{v:g}' for v in x0)}: the robot cannot rest there ({err})"
        ) from None


def _robot_budget(args, scenario) -> int:
    """``robot MOTION --emulate --budget``: the error budget of servos as they are
    (:func:`~.emulated_budget.emulated_budget`), printed and written in ``--out``."""
    from ..base.errors import InvalidConfigError
    from .emulated_budget import SOURCES, emulated_budget, write_budget

    if args.emulate is None or args.motion is None:
        raise InvalidConfigError("--budget runs on the bus emulator: give a motion and --emulate")
    runs = len(SOURCES) + 1 - (scenario.emulator.clock == "loop")
    say = say_stage("robot")
    say(
        f"the error budget of servos as they are: {runs} sessions of {scenario.duration_s:g} s "
        "on the emulator (minutes)"
    )
    budget = emulated_budget(scenario, args.emulate.pose, say=say)
    print("\n".join(budget.lines()))
    paths = write_budget(budget, Path(args.out))
    print("wrote " + " and ".join(str(path) for path in paths))
    return 0


def _robot_session(args, scenario, out, stem, signals, surrogate=None) -> int:
    """``robot``'s work once the scenario is checked: start the emulator (``--emulate``),
    calibrate, dry run, or a session, ending in the end line; closes the emulator."""
    from .emulator_process import EMULATED_LOOP_TIMEOUT_S, start_emulator
    from .session import end_line, run_on_robot

    emulator = None
    held: dict[str, Any] = {}  # the session's station diagram, kept just before the torque goes on
    try:
        if args.emulate is not None:
            print(
                "stewart-drake robot: starting the bus emulator, the robot's Drake plant in a "
                "process of its own (seconds; longer on a busy machine)",
                file=sys.stderr,
                flush=True,
            )
            emulator = start_emulator(scenario, args.emulate.pose, args.realtime)
            clock = "at real time"
            if emulator.period_s is not None:  # its step holds a read: no robot's stall
                args.loop_timeout = max(args.loop_timeout, EMULATED_LOOP_TIMEOUT_S)
                clock = (
                    "on the loop's clock, a period at each command: its step's time shows as "
                    "late bus replies, counted and not fatal, our watchdog at "
                    f"{args.loop_timeout:g} s"
                )
            print(
                f"bus emulator on {scenario.bus.port} (the robot's Drake plant {clock}): "
                f"{emulator.servos.summary()}"
            )

        if args.calibrate is not None or args.dry_run:
            return _read_only(args, scenario)
        meshcat = None
        if args.meshcat or args.teleop:
            from pydrake.geometry import Meshcat

            meshcat = Meshcat()
            print(f"open {meshcat.web_url()} to watch the robot at its measured pose")
        if args.follow is not None:
            from .follow_command import follow_from_arguments

            run = follow_from_arguments(args.follow, args, scenario, out, stem, signals)
        elif args.teleop:
            from .session import teleop_on_robot

            run = teleop_on_robot(
                scenario,
                meshcat,
                duration_s=args.duration,
                loop_timeout_s=args.loop_timeout,
                signals=signals,
                realtime=args.realtime,
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
                realtime=args.realtime,
                surrogate=surrogate,
                before_torque=lambda sd, simulator: held.update(sd=sd),
            )
    finally:
        if emulator is not None:
            emulator.close()
    _print_run(run, scenario, held.get("sd"), emulator)
    if emulator is None or emulator.servos.realistic:
        _note_commissioning(scenario)
    signals.settle(run)
    print(f"stewart-drake robot: {end_line(run)}", file=sys.stderr if not run.ok else sys.stdout)
    return run.exit_code


def _note_commissioning(scenario) -> None:
    """A line on stderr, after a session's figures, when the crank servo drove servos as they
    are (real, or the realistic emulator's) on the catalogue's figures alone: it meets its
    bounds only commissioned. Not before: a refusal stays one line."""
    from ..control.servo.driver import CrankServoDriver

    if isinstance(scenario.controller, CrankServoDriver) and not scenario.controller.commissioned:
        print(
            "note: the crank servo believes the catalogue's torque constant "
            "and friction (no commissioning in the scenario); on servos as they are some draws "
            "miss its bounds: `stewart-drake servo identify` gives each servo's values for the "
            'controller section (docs/robot.md, "A commissioned paper_bus")',
            file=sys.stderr,
            flush=True,
        )


def _read_only(args, scenario) -> int:
    """``robot --calibrate`` (the zero counts at a held angle) or ``--dry-run`` (the pose the
    servos' angles give, judged), the torque never on: the exit code."""
    if args.calibrate is not None:
        from ..station.bus.driver import DynamixelBus
        from .measure import bus_config, zero_counts_at

        with DynamixelBus.from_config(bus_config(scenario)) as bus:
            zeros = zero_counts_at(bus, math.radians(args.calibrate))
        print(
            f"with every crank held at {args.calibrate:g} deg, put in the scenario's bus:\n"
            f"  zero_counts: [{', '.join(str(int(c)) for c in zeros)}]"
        )
        return 0
    from .measure import measure_pose

    print(
        "stewart-drake robot: reading the servos' angles, the torque off, and judging "
        "the pose they give",
        file=sys.stderr,
        flush=True,
    )
    measured = measure_pose(scenario)
    print(measured.summary())
    return 0 if measured.problem is None else 1


def _print_run(run, scenario, sd, emulator) -> None:
    """A session's figures: its metrics (and, on the emulator, the true pose against the
    encoders' from the station diagram ``sd``), the loop's timing, the relative latency."""
    from ..run.metrics import format_metrics

    if run.metrics is not None:
        print(format_metrics(run.metrics, "the pose the encoders read"))
        if emulator is not None and sd is not None:
            print("\n".join(_truth_lines(scenario, sd, emulator, run.metrics)))
    if run.timing_lines:
        print("control loop timing:\n  " + "\n  ".join(run.timing_lines))
    if run.relative_latency_line is not None:
        print(run.relative_latency_line)


def _truth_lines(scenario, sd, emulator, metrics) -> list[str]:
    """A rehearsal's true pose (the emulator's plant) against what the encoders read, over the
    metrics' window (:func:`~.emulator_process.truth_lines`), with the encoders' floor at the
    reference's mean pose there."""
    import numpy as np

    from ..analysis.error_budget import quantization_floor
    from .emulator_process import truth_lines

    window = metrics["window_s"]
    t = np.linspace(window[0], window[1], 50)
    centre = sd.trajectory.evaluate(t)[0].mean(axis=0)
    floor = quantization_floor(scenario, centre)
    return truth_lines(sd, emulator.truth(), window, floor, emulator)
