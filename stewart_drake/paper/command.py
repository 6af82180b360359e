"""``stewart-drake run``: a scenario simulated (the paper's experiment unless told), its
figures printed, its logs written as .npz, CSV and MAT with Fig. 7 beside them."""

from __future__ import annotations

from pathlib import Path

from ..execution.options import (
    add_scenario_arguments,
    check_output,
    default_scenario,
    positive_float,
    say_if_compiling,
    say_stage,
)


def register(sub) -> None:
    """Add the ``run`` command to ``sub``, the ``stewart-drake`` subparsers."""
    _add_run_command(sub)


def _add_run_command(sub) -> None:
    """The ``run`` command's options."""
    run = sub.add_parser(
        "run",
        help="simulate a scenario (default: the paper's experiment on "
        "the robot as built) and plot Fig. 7",
    )
    add_scenario_arguments(run, "the run")
    _add_reference_arguments(run)
    _add_controller_arguments(run)
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


def _add_reference_arguments(run) -> None:
    """``run``'s shorthands for the scenario's reference and length."""
    from ..references.trajectories import TRAJECTORIES

    run.add_argument(
        "--duration",
        type=positive_float,
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


def _add_controller_arguments(run) -> None:
    """``run``'s shorthands for the scenario's controller, its weights and its tuner."""
    from ..run.scenario import named_controllers

    run.add_argument(
        "--controller",
        choices=sorted(named_controllers()),
        default=None,
        help="the LQI of the paper or the crank-space PD baseline (default: the scenario's, lqi)",
    )
    run.add_argument(
        "--omega-q",
        type=positive_float,
        default=None,
        help="LQI omega_Q (default: the scenario's, 1)",
    )
    run.add_argument(
        "--omega-r",
        type=positive_float,
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
    name = Path(str(source)).stem if source is not None else default_scenario()
    prefix = "" if name == default_scenario() else f"{name}_"
    digest = hashlib.sha256("\n".join(overrides).encode()).hexdigest()[:6]
    changed = f"_set{digest}" if overrides else ""
    return f"run_{prefix}{scenario.reference.label}{tuner}{scenario.controller.run_suffix}{changed}"


def _cmd_run(args) -> int:
    """``stewart-drake run``: simulate, print the figures, write .npz and .png into args.out."""
    from ..base.fileio import check_replaceable
    from ..run.metrics import format_metrics
    from ..run.result import export_result, save_result
    from ..run.simulate import run_experiment
    from .run_report import plot_fig7

    scenario = run_scenario(args)
    out = Path(args.out)
    if args.html is not None:
        check_output(args.html, "--html", is_file=True)
    stem = run_stem(scenario, args.scenario, args.set or ())
    for suffix in (".npz", ".png", ".csv", ".mat"):
        check_replaceable(out / f"{stem}{suffix}")
    if scenario.tuner is not None and scenario.tuner.weights_path() is not None:
        print(f"{scenario.tuner.kind} weights: {scenario.tuner.weights_path()}")
    say = None if args.no_progress else say_stage("run")

    def on_checked() -> None:  # the run is refused, if it is, before this
        say_if_compiling("run")
        if say is not None:
            say("building the Drake station and its controller, starting the simulator ...")

    if args.html:  # the same run, replayed into a standalone HTML
        from ..viz.visualize import record_html

        say_if_compiling("run")
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
