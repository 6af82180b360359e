"""``stewart-drake design``: the robot's geometry and motor searched for a task, with a report
and the chosen designs' scenario files."""

from __future__ import annotations

import sys

from ..execution.options import add_runner_arguments, int_at_least, runner_from_args, say_stage


def register(sub) -> None:
    """Add the ``design`` command to ``sub``, the ``stewart-drake`` subparsers."""
    _add_design_command(sub)


def _add_design_command(sub) -> None:
    """The ``design`` command's options."""
    from ..robot.motor_catalogue import MOTOR_CATALOGUE, REFERENCE_MOTOR
    from .design_search import DEFAULT_MAXITER, DEFAULT_POPSIZE
    from .margins import OBJECTIVES

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
    dsg.add_argument("--seed", type=int_at_least(0), default=0, help="the optimizer's seed")
    dsg.add_argument(
        "--generations",
        type=int_at_least(1),
        default=DEFAULT_MAXITER,
        help=f"generations of each search (default {DEFAULT_MAXITER})",
    )
    dsg.add_argument(
        "--popsize",
        type=int_at_least(2),
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
    add_runner_arguments(dsg)
    dsg.add_argument(
        "--no-progress",
        action="store_true",
        help="hide the progress bars (the stages' lines, and how long the searches may take, "
        "are still said)",
    )
    dsg.set_defaults(func=_cmd_design, out_sub=("search", "diverged"), out_files=DESIGN_FILES)


#: The files ``design`` writes in its ``--out`` folder (checked before the search).
DESIGN_FILES = (
    "design_objective.yaml",
    "design_cheapest.yaml",
    "designs.json",
    "design.md",
    "front.png",
    "designs.png",
    "margins.png",
)


def _cmd_design(args) -> int:
    """``stewart-drake design``: search the design for a requirements file, write the report and
    the chosen designs' scenarios; exit 1 when no design within the bounds meets the task."""
    from .design_study import run_design

    outcome = run_design(
        args.requirements,
        args.out,
        motor=args.motor,
        objective=args.objective,
        cheapest=not args.no_cheapest,
        confirm=not args.no_confirm,
        seed=args.seed,
        runner=runner_from_args(args),
        popsize=args.popsize,
        maxiter=args.generations,
        base_scenario=args.scenario,
        progress=not args.no_progress,
        # The stages' lines (how long the searches may take, each stage without a bar) are
        # said with or without the bars: a search of minutes is never silent.
        say=say_stage("design"),
    )
    for search in outcome.searches:
        name, margin = search.best.binding
        verdict = (
            f"best {search.objective} {search.best.objective(search.objective):.4g}"
            if search.feasible
            else f"no design meets the task (binding: {name} {margin:+.3g})"
        )
        print(f"{search.motor}: {verdict}; {search.evaluations} evaluations, {search.wall_s:.0f} s")
    for role, record in outcome.robustness.items():
        print(f"{role} design's loop: {record['verdict']}")
    for role in outcome.unfit():
        print(f"the {role} design is not recommended as it is: its loop does not hold (design.md)")
    print(f"wrote {args.out}/design.md and " + ", ".join(p.name for p in outcome.files[:-1]))
    if outcome.binding:
        print(
            f"stewart-drake design: no design within the bounds meets {args.requirements}: "
            f"binding constraint {outcome.binding}",
            file=sys.stderr,
        )
        return 1
    return 0
