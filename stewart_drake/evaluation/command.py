"""``stewart-drake evaluate``: every controller on every scenario in parallel, and the tuner
study, with results.md and its plots."""

from __future__ import annotations

import sys

from ..execution.options import (
    add_runner_arguments,
    check_output,
    default_scenario,
    refuse_system_folder,
    runner_from_args,
    say_if_compiling,
)


def register(sub) -> None:
    """Add the ``evaluate`` command to ``sub``, the ``stewart-drake`` subparsers."""
    _add_evaluate_command(sub)


def _add_evaluate_command(sub) -> None:
    """The ``evaluate`` command's options."""
    ev = sub.add_parser(
        "evaluate",
        help="every controller on every scenario, and the tuner study: results.md and its plots",
    )
    ev.add_argument(
        "--scenario",
        default=default_scenario(),
        metavar="FILE|NAME",
        help="scenario every case starts from (a .yaml file or a shipped name)",
    )
    ev.add_argument(
        "--out",
        default="results/evaluation",
        help="folder of the runs (kept as they finish: run again to resume), "
        "rows.json and, unless --docs, results.md and its plots",
    )
    ev.add_argument(
        "--docs",
        default=None,
        metavar="FOLDER",
        help="write results.md and its plots here instead (default: --out; the "
        "repository's report is regenerated with --docs docs)",
    )
    add_runner_arguments(ev)
    ev.add_argument(
        "--no-tuner-study",
        action="store_true",
        help="leave out the tuner study that leads the report",
    )
    ev.add_argument(
        "--controllers",
        default=None,
        metavar="NAME,NAME",
        help="comma-separated subset, e.g. lqi_1_1,pd,ann_best_cost (default: all "
        "12; with --quick, lqi_1_1,pd,ann_best_cost)",
    )
    ev.add_argument(
        "--quick",
        action="store_true",
        help="a smoke test of about a minute on 2 cores: 1-2 s runs of three "
        "controllers, no tuner study; not figures to quote",
    )
    ev.add_argument("--no-progress", action="store_true", help="hide the progress bar")
    ev.set_defaults(func=_cmd_evaluate, out_sub=("diverged", "rows"))


def _cmd_evaluate(args) -> int:
    """``stewart-drake evaluate``: the grid in parallel, results.md and plots (in --out unless
    --docs names another folder)."""
    from ..tuner.study_runs import GOAL, StudyArm
    from .evaluation import evaluate
    from .evaluation_grid import CONTROLLERS, QUICK_CONTROLLERS, check_controllers

    if args.controllers:
        controllers = tuple(args.controllers.split(","))
    else:
        controllers = QUICK_CONTROLLERS if args.quick else CONTROLLERS
    check_controllers(controllers)  # an unknown name, before the rest
    docs = args.out if args.docs is None else args.docs  # never the repository's docs/
    refuse_system_folder(docs, "--docs")
    check_output(docs, "--docs")
    tuner_study = not (args.no_tuner_study or args.quick)
    if tuner_study and not has_torch():
        print(
            "stewart-drake evaluate: the tuner study is left out: it trains our tuner with "
            "torch (pip install 'stewart-drake[train]'); --no-tuner-study hides this note",
            file=sys.stderr,
        )
        tuner_study = False
    say_if_compiling("evaluate")
    report = evaluate(
        docs,
        args.out,
        runner=runner_from_args(args),
        progress=not args.no_progress,
        quick=args.quick,
        controllers=controllers,
        base=args.scenario,
        tuner_study=tuner_study,
    )
    failed = [r for r in report["rows"] if "error" in r]
    info = report["info"]
    print(
        f"{len(report['rows'])} runs ({info['ran']} run now in {report['wall_s']:.0f} s wall, "
        f"{info['reused']} found on disk; {len(failed)} failed{_why_failed(failed, args.scenario)})"
    )
    if report.get("tuner"):
        print("tuner study (held-out tasks, paired against the best fixed ratio per task):")
        for lam, v in report["tuner"]["verdicts"].items():
            ours = v["controllers"][StudyArm("ours", lam=float(lam)).label]
            head = v["controllers"][StudyArm("hindsight", lam=float(lam)).label]
            print(
                f"  lambda {lam}: ours {100 * ours['mean']:+.0f} % +- {100 * ours['std']:.0f} %"
                f" ({'meets' if ours['beats'] else 'does not meet'} the {100 * GOAL:.0f} % "
                f"goal); hindsight headroom {100 * head['mean']:+.0f} % +- "
                f"{100 * head['std']:.0f} %"
            )
    for ann, v in report["verdict"].items():
        b = v["best_fixed"]
        print(
            f"{ann}: nRMS {v['ann']['normalized_rms']:.3g}, "
            + (
                f"best fixed LQI at no more effort {b['case']['controller']} "
                f"{b['normalized_rms']:.3g} -> {'beats' if v['beats'] else 'does not beat'} it"
                if b
                else "no fixed LQI at that effort"
            )
        )
    print("wrote " + ", ".join(str(p) for p in report["paths"]))
    return 0


def _why_failed(failed: list, base: str) -> str:
    """What the failed rows of an evaluation share, when it is known: the runs under a
    disturbance whose holding torque is beyond the motors' limit are lost by the sizing, not by
    the controllers ("" when there is nothing to say)."""
    from .evaluation_report import disturbance_holding_torques

    if not failed:
        return ""
    needs, limit = disturbance_holding_torques(base)
    beyond = {n for n, need in needs.items() if limit is not None and need > limit}
    lost = [r for r in failed if r["case"].get("condition") in beyond]
    if not lost:
        return ""
    names = ", ".join(sorted({r["case"]["condition"] for r in lost}))
    other = len(failed) - len(lost)
    return (
        f": {len(lost)} under {names}, which needs more holding torque than the motors' "
        f"{limit:.3f} N m: lost by the sizing, as results.md says"
        + (f"; {other} for other reasons" if other else "")
    )


def has_torch() -> bool:
    """Whether torch (the [train] extra) can be imported, without importing it."""
    import importlib.util

    return importlib.util.find_spec("torch") is not None
