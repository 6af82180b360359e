"""The core's own files at the command line: ``stewart-drake scenario`` (the shipped scenarios,
one printed as YAML), ``sdf`` (the reference robot's SDF) and ``mjcf`` (a scenario's robot for
MuJoCo)."""

from __future__ import annotations

from pathlib import Path

from ..execution.options import add_scenario_arguments, default_scenario


def register(sub) -> None:
    """Add the ``scenario``, ``sdf`` and ``mjcf`` commands to ``sub``, the
    ``stewart-drake`` subparsers."""
    _add_scenario_command(sub)
    _add_sdf_command(sub)
    _add_mjcf_command(sub)


def _add_scenario_command(sub) -> None:
    """The ``scenario`` command's options."""
    scn = sub.add_parser("scenario", help="list the shipped scenarios or print one as YAML")
    scn.add_argument(
        "source",
        nargs="?",
        default=default_scenario(),
        help=f"scenario file or shipped name (default: {default_scenario()})",
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


def _add_sdf_command(sub) -> None:
    """The ``sdf`` command's options."""
    sdf = sub.add_parser("sdf", help="write the reference robot's SDF")
    sdf.add_argument("--out", default="sdf/rotary_stewart.sdf", help="file (in the current folder)")
    sdf.set_defaults(func=_cmd_sdf, out_is_file=True)


def _cmd_sdf(args) -> int:
    from ..base.fileio import atomic_write
    from ..plant.sdf import write_sdf

    text = write_sdf().encode()
    atomic_write(Path(args.out), lambda f: f.write(text))
    print(f"wrote {args.out}")
    return 0


def _add_mjcf_command(sub) -> None:
    """The ``mjcf`` command's options."""
    mj = sub.add_parser("mjcf", help="write a scenario's robot as a MuJoCo MJCF")
    add_scenario_arguments(mj, "the robot to write")
    mj.add_argument(
        "--out", default="rotary_stewart.xml", help="file to write (in the current folder)"
    )
    mj.set_defaults(func=_cmd_mjcf, out_is_file=True)


def _cmd_mjcf(args) -> int:
    """``stewart-drake mjcf``: a scenario's robot as a MuJoCo MJCF (no MuJoCo needed to write):
    as built (rotor armature, servo friction, torque limit, encoder sensors) unless the scenario
    is the ideal robot."""
    from ..base.fileio import atomic_write
    from ..plant.mjcf import DEFAULT_INTEGRATOR, write_mjcf
    from ..run.plan import robot_geometry, robot_motor_limits
    from ..run.scenario_io import load_scenario

    scenario = load_scenario(args.scenario, args.set or ())
    motors, time_step = robot_motor_limits(scenario), scenario.plant.time_step
    text = write_mjcf(
        robot_geometry(scenario),
        time_step=time_step,
        servo=motors.servo,
        torque_limit_Nm=motors.peak_torque_Nm,
    ).encode()
    atomic_write(Path(args.out), lambda f: f.write(text))
    built = (
        "the robot as built: rotor armature, friction, torque limit, encoders"
        if motors.servo is not None
        else "the ideal robot"
    )
    print(
        f"wrote {args.out} (MuJoCo MJCF of {args.scenario}, {built}; integrator "
        f"{DEFAULT_INTEGRATOR}, time step {1e3 * time_step:g} ms)"
    )
    return 0
