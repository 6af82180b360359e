"""The analyses at the command line: ``stewart-drake check`` (every limit of a reference
without simulating), ``workspace`` (the robot's reachable poses and torques) and ``analyze`` (the
linear loop's margins)."""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Any

from ..execution.options import (
    add_param_argument,
    add_runner_arguments,
    add_scenario_arguments,
    check_output,
    int_at_least,
    is_trace_file,
    positive_float,
    runner_from_args,
    say_stage,
)
from ..execution.trace_options import (
    TRACE_ONLY,
    add_trace_arguments,
    trace_options_given,
    trace_reference,
)


def register(sub) -> None:
    """Add the ``check``, ``workspace`` and ``analyze`` commands to ``sub``, the
    ``stewart-drake`` subparsers."""
    _add_check_command(sub)
    _add_workspace_command(sub)
    _add_analyze_command(sub)


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
    add_trace_arguments(chk)
    add_scenario_arguments(chk, "the robot to check on, for a file or named reference")
    chk.add_argument(
        "--duration",
        type=positive_float,
        default=None,
        help="checked s (default: the scenario's duration_s)",
    )
    chk.add_argument("--out", default="results", help="folder of the margins plot")
    chk.set_defaults(func=_cmd_check)


def _cmd_check(args) -> int:
    """``stewart-drake check``: every check of a reference, over time, without simulating."""
    from ..base.errors import InvalidConfigError
    from ..references.trajectories import TRAJECTORIES, NamedReference
    from ..run.scenario_io import load_scenario
    from .feasibility import check, plot_margins

    source = args.reference
    trace = None  # a reference file, read once: its length and the reference checked
    if is_trace_file(source) and Path(source).suffix.lower() not in (".yaml", ".yml"):
        scenario = load_scenario(args.scenario, args.set or ())
        scenario.reference = reading = trace_reference(args, source)
        reading.validate()  # the options, before the file is read
        trace = reading.load()  # read as reproduce reads it
        if args.duration is None:  # as long as the file, as `run` and `reproduce` take it
            scenario.duration_s = trace.end_time - getattr(trace, "start_time", 0.0)
        scenario.validate()
        info = getattr(trace, "info", None)
        if info is not None:
            print(f"Trace: {info.summary()}")
    elif trace_options_given(args):
        raise InvalidConfigError(
            f"{TRACE_ONLY} are for a trace file; {source!r} is a named trajectory or a scenario"
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


def _add_workspace_command(sub) -> None:
    """The ``workspace`` command's options."""
    ws = sub.add_parser(
        "workspace",
        help="reachable poses, singularities and holding torques of the scenario's robot",
    )
    add_scenario_arguments(ws, "the robot to sweep (its robot: fields)")
    ws.add_argument("--out", default="results/workspace", help="output folder")
    ws.add_argument("--resolution", type=int_at_least(3), default=41, help="grid points per axis")
    add_runner_arguments(ws)
    ws.add_argument("--no-progress", action="store_true", help="hide the progress bar")
    ws.set_defaults(func=_cmd_workspace)


#: The coarsest workspace grid whose extents are worth reporting (a step of 1/20 of the box).
MIN_REPORTED_RESOLUTION = 21


def _cmd_workspace(args) -> int:
    """``stewart-drake workspace``: sweep the scenario's robot, write PNG, npz and CSV."""
    from ..run.plan import robot_geometry, robot_motor_limits
    from ..run.scenario_io import load_scenario
    from .workspace import write_workspace

    scenario = load_scenario(args.scenario, args.set or ())
    geometry = robot_geometry(scenario)
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
        runner=runner_from_args(args),
        motor_limits=robot_motor_limits(scenario),
        say=None if args.no_progress else say_stage("workspace"),
    )
    for name, value, unit in rows[:11]:
        print(f"{name} {value} {unit}")
    print(
        f"wrote {args.out}/workspace.png, bottleneck_and_orientation.png, workspace.npz, "
        f"summary.csv, tilt_vs_height.csv"
    )
    return 0


def _add_analyze_command(sub) -> None:
    """The ``analyze`` command's options."""
    an = sub.add_parser(
        "analyze",
        help="the loop as a control engineer sees it: margins, Ms, Mt, bandwidth, Bode plots",
    )
    add_scenario_arguments(an, "the robot and LQI to analyse")
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
    an.add_argument(
        "--budget",
        nargs="?",
        const="breathing",
        default=None,
        metavar="MOTION",
        help="also the error budget of a library motion centred at the pose on the robot as "
        "built (the encoders' floor, then the motion simulated at the scenario's period with "
        "and without each source: encoders, period and delay, current loop, friction, "
        "backlash, model; about 6 simulations; default breathing; the only figures of a "
        "controller other than the LQI)",
    )
    add_param_argument(
        an,
        "a parameter of the budget's motion with its unit (repeatable), as reproduce "
        "takes them (default: the motion's own)",
    )
    an.add_argument("--out", default="results/analyze", help="output folder")
    an.set_defaults(func=_cmd_analyze)


def _cmd_analyze(args) -> int:
    """``stewart-drake analyze``: the linear loop of the scenario's robot and LQI at a pose:
    margins, Ms, Mt, bandwidth and the phase lag at 0.25 and 1.2 Hz per axis; Bode and
    sensitivity plots and the table as Markdown in --out."""
    import functools
    import json

    from ..base.fileio import atomic_write
    from ..control.lqi.driver import LqiDriver
    from ..run.scenario_io import load_scenario
    from .loop_analysis import axis_figures, figures_table, loop_models, plot_loop
    from .robustness import lqi_robust_range, robust_lines

    scenario = load_scenario(args.scenario, args.set or ())
    x0 = _pose_option(args.pose)
    out = check_output(args.out)
    say = say_stage("analyze")
    name = Path(str(args.scenario)).stem
    if not isinstance(scenario.controller, LqiDriver):
        return _not_an_lqi(args, scenario, x0, name, out, say)
    say("linearizing the loop and computing the margins of the 6 axes ...")
    models = loop_models(scenario, x0, integrator=args.integrator)
    figures = axis_figures(models)
    pose = ", ".join(f"{v:.4g}" for v in models.x0)
    table = figures_table(figures)
    rho = models.spectral_radius
    print(
        f"{name} at pose [{pose}] (rad, m), control period {1e3 * models.h:g} ms: the closed "
        f"loop is {'stable' if rho < 1 else 'UNSTABLE'} (spectral radius {rho:.4f})"
        + ("" if rho < 1 else ": the margins below describe an unstable loop")
    )
    print("\n".join(table))
    say("the plant gains and the delay the loop survives ...")
    survives = lqi_robust_range(scenario, x0)
    print("\n".join(robust_lines(survives)))
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
        "robustness": survives.record(),
    }
    if args.weights:
        record["weights"] = _weight_sweep(scenario, models, say)
    if args.map:
        record["map"] = _tilt_map(scenario, models, name, out / "map.png", say)
        paths.append(out / "map.png")
    data = json.dumps(record, indent=1, default=float).encode()
    atomic_write(paths[3], lambda fh: fh.write(data))
    print("wrote " + ", ".join(str(p) for p in paths))
    if args.budget is not None:
        return _budget(args, scenario, x0, name, out, say, {"scenario": name})
    return 0


def _not_an_lqi(args, scenario, x0, name: str, out, say) -> int:
    """``analyze`` of a scenario whose controller is not the LQI: the crank servo's margins or
    the servos' own loop's, then its error budget where the host's controller runs the loop.

    Raises:
        InvalidConfigError: ``--budget`` on servos that run their own position loop.
    """
    from ..base.errors import InvalidConfigError

    print(
        f"{name}: the loop's margins are the LQI's linear model "
        f"(controller: !LqiDriver); this scenario's controller is a "
        f"{type(scenario.controller).__name__}: "
        + (
            "its error budget instead"
            if scenario.bus is None or scenario.bus.position_loop is None
            else "the servos' own loop's margins instead"
        )
    )
    record: dict[str, Any] = {"scenario": name}
    robust = _crank_servo_margins(scenario)
    if robust is not None:
        print("\n".join(robust))
        record["crank_servo_margins"] = robust
    servos_loop = _position_loop_margins(scenario)
    if servos_loop is not None:
        print("\n".join(servos_loop))
        why = (
            f"{name}'s servos run their own position loop, which the error budget's "
            "simulation (the host's controller at the bus's period) does not hold: its "
            "figures are the bus emulator's (python benchmarks/servo_departures.py; "
            'docs/robot.md, "The servo\'s own loop")'
        )
        if args.budget is not None:
            raise InvalidConfigError(f"--budget: {why}")
        print(f"no error budget: {why}")
        return 0
    return _budget(args, scenario, x0, name, out, say, record)


def _crank_servo_margins(scenario) -> list[str] | None:
    """The crank servo's robust margins (:func:`~stewart_drake.control.servo.margins.
    margin_lines`), or None for another controller."""
    from ..control.servo.driver import CrankServoDriver
    from ..control.servo.margins import margin_lines
    from .robustness import crank_servo_loop

    if not isinstance(scenario.controller, CrankServoDriver):
        return None
    return margin_lines(crank_servo_loop(scenario))


def _position_loop_margins(scenario) -> list[str] | None:
    """The servos' own position loop's margins (:func:`~stewart_drake.station.bus.
    position_margins.position_margin_lines`, on the gains the bus writes), or None without
    ``bus.position_loop``."""
    if scenario.bus is None or scenario.bus.position_loop is None:
        return None
    from ..station.bus.position_margins import position_margin_lines
    from .robustness import position_loop_model

    return position_margin_lines(*position_loop_model(scenario))


def _budget(args, scenario, x0, name: str, out: Path, say, record: dict) -> int:
    """``analyze --budget``: the error budget of the motion centred at the pose
    (:func:`~.error_budget.error_budget`), printed as a table and written as budget.md and
    budget.json in ``out``."""
    import json

    from ..base.fileio import atomic_write
    from ..execution.trace_options import key_values
    from ..references.organ.library import OrganMotionReference, split_parameters
    from ..robot.kinematics import X_HOME
    from .error_budget import error_budget

    motion = args.budget or "breathing"
    params = key_values(args.param, "--param")
    centre = X_HOME if x0 is None else x0
    params.setdefault("centre", ",".join(f"{v:.17g}" for v in centre))
    shares = split_parameters([motion], params)
    reference = OrganMotionReference(motion=motion, parameters=shares[0])
    reference.validate()
    say(f"the error budget of {motion}: one simulation, then one without each source ...")
    budget = error_budget(scenario, reference, say=say)
    where = ", ".join(f"{v:.4g}" for v in centre)
    title = (
        f"{name}: error budget of {motion} at [{where}] (rad, m), RMS over t = "
        f"{budget.window_s[0]:g}-{budget.window_s[1]:g} s, per axis"
    )
    lines = [title, "", *budget.lines()]
    print("\n".join(lines))
    out.mkdir(parents=True, exist_ok=True)
    text = "\n".join(["# " + title, "", *budget.lines(), ""]).encode()
    atomic_write(out / "budget.md", lambda fh: fh.write(text))
    data = json.dumps({**record, "motion": motion, **budget.record()}, indent=1).encode()
    atomic_write(out / "budget.json", lambda fh: fh.write(data))
    print(f"wrote {out / 'budget.md'} and {out / 'budget.json'}")
    return 0


def _pose_option(text: str | None):
    """``analyze``'s ``--pose``: six numbers phi,theta,psi,X,Y,Z (rad, m); None: home.

    Raises:
        InvalidConfigError: not six numbers.
    """
    from ..base.errors import InvalidConfigError

    if text is None:
        return None
    try:
        x0 = [float(v) for v in text.split(",")]
    except ValueError:
        x0 = []
    if len(x0) != 6:
        raise InvalidConfigError(
            f"--pose takes six numbers phi,theta,psi,X,Y,Z (rad, m), got {text!r}"
        )
    return x0


def _weight_sweep(scenario, models, say) -> list:
    """``analyze --weights``: the loop's margins at the pose for each ratio omega_Q / omega_R,
    printed one line a ratio; returns the rows of the record."""
    from .loop_analysis import weight_sweep

    say("the margins for omega_Q / omega_R = 0.01, 0.1, 1, 10, 100 ...")
    rows = weight_sweep(scenario, x0=models.x0)
    print(
        "omega_Q / omega_R: closed loop, smallest phase margin (axis), largest Ms (axis), "
        "Z bandwidth Hz"
    )
    for row in rows:
        pm = min(row["axes"], key=lambda a: a["phase_margin_deg"])
        ms = max(row["axes"], key=lambda a: a["Ms"])
        bw = row["axes"][5]["bandwidth_hz"]
        print(
            f"  {row['ratio']:g}: {'stable' if row['stable'] else 'UNSTABLE'} (spectral "
            f"radius {row['spectral_radius']:.4f}), {pm['phase_margin_deg']:.1f} deg "
            f"({pm['axis']}), {ms['Ms']:.2f} ({ms['axis']}), "
            + (f"{bw:.3g}" if bw is not None else row["axes"][5]["bandwidth_where"])
        )
    return rows


def _tilt_map(scenario, models, name: str, png: Path, say) -> list:
    """``analyze --map``: the loop's margins over roll and pitch at the pose's height, the
    weakest pose printed and the map drawn into ``png``; returns the rows of the record."""
    import functools

    from ..base.fileio import atomic_write
    from .loop_analysis import loop_map, plot_map, tilt_grid, weakest_pose

    say("the margins over 9 x 9 roll and pitch tilts, then map.png ...")
    rows = loop_map(scenario, tilt_grid(height_m=float(models.x0[5])))
    weak = weakest_pose(rows)
    where = ", ".join(f"{v:.3g}" for v in weak["pose"])
    print(
        f"weakest of {len(rows)} admissible tilts: pose [{where}]: Ms {weak['Ms']:.2f} "
        f"({weak['Ms_axis']}), phase margin {weak['phase_margin_deg']:.1f} deg "
        f"({weak['phase_margin_axis']}), gain margin {weak['gain_margin_db']:.1f} dB "
        f"({weak['gain_margin_axis']}), spectral radius {weak['spectral_radius']:.4f}"
    )
    fig = plot_map(rows, f"{name}: the loop over roll and pitch at Z = {models.x0[5]:g} m")
    atomic_write(png, functools.partial(fig.savefig, dpi=100, format="png"))
    return rows
