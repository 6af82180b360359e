"""``stewart-drake design``: a robot designed for a task, with its report and scenario file.

:func:`run_design` reads a requirements file (:mod:`~stewart_drake.design.requirements`),
judges the reference robot against it, searches the design with the user's motor and objective
(:func:`~.design_search.search`) and, unless told not to, the cheapest catalogue motor with which
a design meets the task (:func:`~.design_search.cheapest_motor`), then runs the chosen designs
and the reference robot on the requirement motions in closed loop (:mod:`~.design_confirm`), and
writes the report (``design.md`` and its plots) and each chosen design as a scenario file every
other command takes. A task no design meets ends with the binding constraint named, in the
report and as the return value's ``binding``.
"""

from __future__ import annotations

import json
import time
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from ..base.fileio import atomic_write
from ..base.tables import markdown_lines
from ..robot.kinematics import X_HOME, ik
from ..robot.motor_catalogue import REFERENCE_MOTOR
from .design_search import (
    DEFAULT_MAXITER,
    DEFAULT_POPSIZE,
    SearchResult,
    cheapest_motor,
    search,
)
from .margins import MARGINS, OBJECTIVES, Evaluation, design_geometry, evaluate
from .requirements import load_requirements
from .task_samples import task_samples
from .variables import DESIGN_BOUNDS, Design, reference_design


@dataclass
class DesignOutcome:
    """What :func:`run_design` found and wrote.

    Attributes:
        reference: the reference robot's :class:`~.margins.Evaluation`.
        searches: every search run (the user's motor first, then the cheapest-motor ladder).
        chosen: {role: Evaluation} of the feasible designs written ("objective", "cheapest").
        binding: when no search found a design that meets the task, the binding constraint
            ("name: margin" of the best candidate), else "".
        confirmation: {role: rows of :func:`~.design_confirm.confirm`} (empty: not run).
        robustness: {role: :func:`~.design_confirm.design_robustness`} of the reference robot
            and each chosen design: what its loop survives; a chosen design whose loop does not
            hold the requirement is not recommended (:meth:`unfit`).
        files: what was written.
    """

    reference: Evaluation
    searches: list
    chosen: dict
    binding: str
    confirmation: dict = field(default_factory=dict)
    robustness: dict = field(default_factory=dict)
    files: list = field(default_factory=list)

    def unfit(self) -> dict:
        """{role: verdict line} of the chosen designs whose loop does not hold what a shipped
        loop must survive (or has no model to say it does)."""
        return {
            role: self.robustness[role]["verdict"]
            for role in self.chosen
            if role in self.robustness and self.robustness[role]["holds"] is not True
        }


def _length_words(each_s: float, popsize: int, maxiter: int, cheapest: bool, motor, runner):
    """The line announcing how long the searches may take: the candidates of one motor's
    search (scipy's differential evolution: ``popsize`` x the variables, each of ``maxiter`` + 1
    generations), how many motors at most (the chosen, then the catalogue from the cheapest up
    while none meets the task), at ``each_s`` a candidate (the reference's full evaluation, an
    upper bound: a candidate stops at its first missed margin) over the runner's workers."""
    from ..robot.motor_catalogue import MOTOR_CATALOGUE
    from .design_search import SEARCH_VARIABLES, torque_refusal

    candidates = popsize * len(SEARCH_VARIABLES) * (maxiter + 1)
    motors = 1 + (sum(1 for m in MOTOR_CATALOGUE if not torque_refusal(m)) if cheapest else 0)
    workers = max(1, int(getattr(runner, "n_workers", 1) or 1))
    one = candidates * each_s / workers
    return (
        f"the search: {candidates} candidates a motor ({motor} first"
        + (f", then up to {motors - 1} more from the cheapest up" if cheapest else "")
        + f"), {each_s:.2g} s a candidate at most on {workers} worker(s): up to "
        f"{_duration(one)} a motor, {_duration(motors * one)} in all (a bar per motor)"
    )


def _duration(seconds: float) -> str:
    """A duration in words: whole minutes from a minute up, else seconds ("40 s", "12 min")."""
    return f"{seconds / 60:.0f} min" if seconds >= 59.5 else f"{max(seconds, 1):.0f} s"


def run_design(
    requirements_path,
    out_dir="results/design",
    motor: str = REFERENCE_MOTOR,
    objective: str = "peak_torque",
    cheapest: bool = True,
    confirm: bool = True,
    seed: int = 0,
    runner=None,
    popsize: int = DEFAULT_POPSIZE,
    maxiter: int = DEFAULT_MAXITER,
    base_scenario: str = "paper_hardware",
    progress: bool = True,
    say=None,
) -> DesignOutcome:
    """Design the robot for the requirements in ``requirements_path`` (module docstring).

    Args:
        requirements_path: a requirements YAML file (``scenarios/design_requirements.yaml``).
        out_dir: the study's folder: ``search/`` (the optimizer's store: a rerun continues),
            ``diverged/`` (the logs of a confirmation run the guard stopped), ``design.md``,
            ``front.png``, ``designs.png``, ``margins.png``, ``designs.json`` and
            ``design_<role>.yaml`` per chosen design.
        motor, objective: the main search's (:data:`~.margins.OBJECTIVES`).
        cheapest: also search the catalogue's motors from the cheapest up.
        confirm: run the chosen designs and the reference robot in closed loop.
        seed, runner, popsize, maxiter: the optimizer's (:func:`~.design_search.search`).
        base_scenario: the scenario the designs' scenario files start from.
        progress: progress bars.
        say: None, or ``say(line)`` told of each stage that shows no bar (the best design's
            every margin, the report and its plots), before it starts.
    Raises:
        MissingFileError, CorruptFileError, InvalidConfigError: the requirements file (one
            line naming the field), the base scenario (one without hardware or an LQI) or an
            option; all before any search.
        ResultsMismatchError, FolderInUseError: ``out_dir/search`` holds another task's search.
    """
    from .design_confirm import check_base, design_robustness, load_base

    say = say or (lambda line: None)
    requirements = load_requirements(requirements_path)
    task = task_samples(requirements)
    # The base scenario is read and checked now, not after the search that it does not affect.
    base = load_base(base_scenario)
    check_base(base)
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    say("evaluating the reference robot on the task")
    started = time.perf_counter()
    reference = evaluate(reference_design(), task, lazy=False)
    say(_length_words(time.perf_counter() - started, popsize, maxiter, cheapest, motor, runner))
    folder = out / "search"
    searches: list[SearchResult] = [
        search(task, motor, objective, folder, seed, runner, popsize, maxiter, progress, say)
    ]
    if cheapest:
        searches += cheapest_motor(task, folder, seed, runner, popsize, maxiter, progress, say)
    chosen, binding = _chosen(searches)
    outcome = DesignOutcome(reference, searches, chosen, binding)
    designs = {role: e.design for role, e in _columns(outcome)}
    designs["reference"] = reference_design()
    say("what each design's loop survives (plant gain 0.5 to 2, the extra delay)")
    for role in ("reference", *chosen):
        design = reference_design() if role == "reference" else chosen[role].design
        outcome.robustness[role] = design_robustness(design, requirements, base)
    if confirm and chosen:
        from .design_confirm import confirm as run_confirm

        # A confirmation run the guard stops leaves its logs in the study's folder, wherever
        # the base scenario's guard.divergence_dir points (the scenario files keep the base's).
        diverged = str(out / "diverged")
        confirming = replace(base, guard=replace(base.guard, divergence_dir=diverged))
        for role, design in designs.items():
            say(f"confirming the {role} design in closed loop")
            outcome.confirmation[role] = run_confirm(
                design, requirements, base=confirming, runner=runner, progress=progress
            )
    say(f"writing the report, its plots and the designs' scenarios in {out}")
    outcome.files = _write(out, outcome, requirements, objective, base)
    return outcome


def _chosen(searches: list[SearchResult]) -> tuple[dict, str]:
    """The designs chosen ({"objective": the main search's best, "cheapest": the first feasible
    motor of the ladder's}, each where feasible) and, when no search found a feasible design,
    the margin that binds the least short of them in words ("" otherwise)."""
    chosen = {}
    if searches[0].feasible:
        chosen["objective"] = searches[0].best
    ladder = [s for s in searches[1:] if s.feasible]
    if ladder:
        chosen["cheapest"] = ladder[0].best
    binding = ""
    if not any(s.feasible for s in searches):
        best = min((s.best for s in searches), key=lambda e: e.shortfall)
        name, margin = best.binding
        binding = f"{name}: margin {margin:+.3g} ({MARGINS[name]})"
    return chosen, binding


def _columns(outcome: DesignOutcome) -> list:
    """[(label, evaluation)]: the reference robot, then each chosen design once (a design chosen
    for two roles is one column, "objective = cheapest")."""
    columns: list = [("reference", outcome.reference)]
    for role, e in outcome.chosen.items():
        same = [i for i, (_, c) in enumerate(columns) if i and c.design == e.design]
        if same:
            columns[same[0]] = (f"{columns[same[0]][0]} = {role}", columns[same[0]][1])
        else:
            columns.append((role, e))
    return columns


def _write(out: Path, outcome: DesignOutcome, requirements, objective: str, base) -> list:
    """The report, its plots, the evaluations as JSON and the chosen designs' scenarios."""
    files = []
    for role, evaluation in outcome.chosen.items():
        path = out / f"design_{role}.yaml"
        _write_scenario(path, evaluation.design, requirements, base)
        files.append(path)
    document = {
        "reference": outcome.reference.to_json(),
        "chosen": {k: e.to_json() for k, e in outcome.chosen.items()},
        "searches": [
            {
                "motor": s.motor,
                "objective": s.objective,
                "seed": s.seed,
                "feasible": s.feasible,
                "evaluations": s.evaluations,
                "reused": s.reused,
                "wall_s": s.wall_s,
                "compute_s": s.compute_s,
                "best": s.best.to_json(),
                "generations": s.generations,
            }
            for s in outcome.searches
        ],
        "binding": outcome.binding,
        "confirmation": outcome.confirmation,
        "robustness": outcome.robustness,
    }
    text = json.dumps(document, indent=1, default=float).encode()
    atomic_write(out / "designs.json", lambda f: f.write(text))
    files.append(out / "designs.json")
    files += _plots(out, outcome)
    report = render_markdown(outcome, objective).encode()
    atomic_write(out / "design.md", lambda f: f.write(report))
    files.append(out / "design.md")
    return files


def _write_scenario(path: Path, design: Design, requirements, base) -> None:
    """The design as a scenario file: the base scenario with the design's robot (the task's
    payload on its platform) and motor (:func:`~.design_confirm.design_scenario`)."""
    from ..run.scenario import dump_scenario
    from .design_confirm import design_scenario

    scenario = design_scenario(design, requirements, requirements.motions[0], base=base)
    text = (
        f"# A design of stewart-drake design: {design.summary()}\n" + dump_scenario(scenario)
    ).encode()
    atomic_write(path, lambda f: f.write(text))


def _save_png(fig, path: Path) -> None:
    """``fig`` as a PNG at ``path``, written atomically (a link there is replaced, never
    written through)."""
    atomic_write(path, lambda f: fig.savefig(f, format="png", dpi=120))


def _fmt(value, digits: int = 4) -> str:
    return "-" if value is None else f"{value:.{digits}g}"


def render_markdown(outcome: DesignOutcome, objective: str) -> str:
    """The report as Markdown: verdict, designs side by side, margins, searches, confirmation."""
    lines = ["# Design for the task", ""]
    if outcome.binding:
        lines += [
            f"**No design within the bounds meets the task.** Binding constraint: "
            f"{outcome.binding}.",
            "",
        ]
    columns = _columns(outcome)
    lines += _verdicts(outcome, objective)
    rows = [
        [f"{name} ({unit})", *(_fmt(getattr(e.design, name)) for _, e in columns)]
        for name, (_, _, unit, _) in DESIGN_BOUNDS.items()
    ]
    rows.append(["motor", *(e.design.motor for _, e in columns)])
    figures = (
        ("peak_torque_Nm", "peak motor torque (N m)"),
        ("holding_torque_Nm", "peak holding torque, workspace (N m)"),
        ("motion_torque_Nm", "peak torque, motions (N m)"),
        ("rms_torque_Nm", "largest RMS torque of a motion (N m)"),
        ("motor_peak_Nm", "motor's peak torque (N m)"),
        ("motor_continuous_Nm", "motor's continuous torque (N m)"),
        ("peak_speed_rad_s", "peak crank speed (rad/s)"),
        ("motor_no_load_rad_s", "motor's no-load speed (rad/s)"),
        ("max_cond", "largest cond(J)"),
        ("min_clearance_m", "smallest clearance (m)"),
        ("price_usd", "six motors (USD)"),
    )
    rows += [[label, *(_fmt(e.figures.get(key)) for _, e in columns)] for key, label in figures]
    lines += ["## The designs", "", *markdown_lines([None, *(r for r, _ in columns)], rows)]
    rows = [
        [name, *(_fmt(e.margins.get(name), 3) for _, e in columns), meaning]
        for name, meaning in MARGINS.items()
    ]
    header = ["margin", *(r for r, _ in columns), "meaning"]
    lines += ["", "## Margins (>= 0: met)", "", *markdown_lines(header, rows)]
    lines += ["", "![margins](margins.png)", "", "![designs](designs.png)", ""]
    header = ["motor", "objective", "met", "best", "binding"]
    header += ["evaluations (read back)", "evaluating (s)"]
    rows = []
    for s in outcome.searches:
        name, margin = s.best.binding
        rows.append(
            [s.motor, s.objective, "yes" if s.feasible else "no"]
            + [_fmt(s.best.objective(s.objective)), f"{name} ({margin:+.3g})"]
            + [f"{s.evaluations} ({s.reused})"]
            + [f"{s.compute_s:.0f}" if s.compute_s > 0 else "not recorded"]
        )
    lines += ["## Searches", "", *markdown_lines(header, rows)]
    lines += ["", "![front](front.png)", ""]
    if outcome.robustness:
        from .design_confirm import robustness_lines

        lines += robustness_lines(outcome.robustness)
    if outcome.confirmation:
        lines += _confirmation_table(outcome.confirmation)
    lines += [
        "Method: stewart_drake/design/design_search.py (the task sampled once, every candidate "
        "judged by one vectorized pass; scipy's differential evolution with Deb's feasibility "
        "rule). What the kinematic evaluation does not judge (feedback, encoders, the current "
        "loop) is what the closed-loop confirmation shows.",
        "",
    ]
    return "\n".join(lines)


def _verdicts(outcome: DesignOutcome, objective: str) -> list:
    ref = outcome.reference
    lines = []
    unit = OBJECTIVES[objective][0]
    if "objective" in outcome.chosen:
        best = outcome.chosen["objective"]
        if objective == "peak_torque":
            change = best.objective(objective) / ref.objective(objective) - 1.0
            lines.append(
                f"- Least {objective}: {_fmt(best.objective(objective))} {unit} with "
                f"{best.design.motor}, {change:+.1%} against the reference robot's "
                f"{_fmt(ref.objective(objective))} {unit} (binding: {best.binding[0]})."
            )
        else:
            lines.append(
                f"- Best {objective}: {_fmt(best.objective(objective))}"
                f"{'' if unit == '1' else ' ' + unit} with "
                f"{best.design.motor} (reference robot: {_fmt(ref.objective(objective))})."
            )
    if "cheapest" in outcome.chosen:
        c = outcome.chosen["cheapest"]
        lines.append(
            f"- Cheapest motor with which a design meets the task: {c.design.motor} "
            f"({_fmt(c.figures['price_usd'])} USD for six; the design needs "
            f"{c.objective('torque_share'):.0%} of the torque it may use)."
        )
    for role, verdict in outcome.unfit().items():
        lines.append(
            f"- **The {role} design is not recommended as it is: its loop {verdict}** (a slower "
            "loop, or the servos' own, with the same motor: `stewart-drake analyze` on its "
            "scenario)."
        )
    if ref.feasible:
        lines.append("- The reference robot meets the task.")
    else:
        name, margin = ref.binding
        lines.append(f"- The reference robot does not meet the task: {name} {margin:+.3g}.")
    return lines + [""]


def _confirmation_table(confirmation: dict) -> list:
    from .design_confirm import confirmation_table

    lines = [
        "## Closed loop on the Drake plant",
        "",
        "Each requirement motion run on the design as built (the base scenario's hardware: its "
        "motor, its encoders, the payload the controller knows), the LQI's torque scale the same "
        "share of the motor's peak as the reference robot's "
        "(stewart_drake/design/design_confirm.py).",
        "",
    ]
    for role, rows in confirmation.items():
        lines += [f"**{role}** ({rows[0]['motor'] if rows else ''})", "", confirmation_table(rows)]
    return lines


def _plots(out: Path, outcome: DesignOutcome) -> list:
    """front.png (the main search's candidates and convergence), designs.png (the robots at
    home, top and side), margins.png (each margin of each design)."""
    import matplotlib

    matplotlib.use("Agg")
    columns = _columns(outcome)
    palette = ["0.4", "tab:blue", "tab:orange"]
    colours = {role: palette[i % 3] for i, (role, _) in enumerate(columns)}
    return [
        _plot_margins(out, columns, colours),
        _plot_designs(out, columns, colours),
        _plot_front(out, outcome),
    ]


def _plot_margins(out: Path, columns: list, colours: dict) -> Path:
    """margins.png: each margin of each design of ``columns`` (:func:`_columns`), as bars."""
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(8, 4), constrained_layout=True)
    names = list(MARGINS)
    width = 0.8 / len(columns)
    for j, (role, e) in enumerate(columns):
        values = [e.margins.get(n, np.nan) for n in names]
        ax.bar(
            np.arange(len(names)) + j * width,
            np.clip(values, -1.0, 3.0),
            width,
            label=f"{role} ({e.design.motor})",
            color=colours.get(role),
        )
    ax.axhline(0.0, color="k", lw=1)
    ax.set_xticks(np.arange(len(names)) + width * (len(columns) - 1) / 2, names, rotation=20)
    ax.set_ylabel("margin (>= 0: met; clipped to [-1, 3])")
    ax.set_title("What each design keeps in reserve")
    ax.legend(fontsize=8)
    _save_png(fig, out / "margins.png")
    plt.close(fig)
    return out / "margins.png"


def _plot_designs(out: Path, columns: list, colours: dict) -> Path:
    """designs.png: the robots of ``columns`` at home, seen from the top and the side."""
    import matplotlib.pyplot as plt

    fig, (top, side) = plt.subplots(1, 2, figsize=(10, 4.6), constrained_layout=True)
    for role, e in columns:
        g = design_geometry(e.design)
        theta = ik(g, X_HOME)
        tips = g.crank_tips(theta)
        p = X_HOME[3:] + g.p_E
        c = colours.get(role)
        for view, (i, k) in ((top, (0, 1)), (side, (0, 2))):
            closed = np.vstack([g.P_B, g.P_B[:1]])
            view.plot(closed[:, i], closed[:, k], "o-", color=c, ms=3, lw=0.8)
            ring = np.vstack([p, p[:1]])
            view.plot(ring[:, i], ring[:, k], "s-", color=c, ms=3, lw=1.2)
            for leg in range(6):
                view.plot(
                    [g.P_B[leg, i], tips[leg, i]], [g.P_B[leg, k], tips[leg, k]], color=c, lw=2.5
                )
                view.plot(
                    [tips[leg, i], p[leg, i]], [tips[leg, k], p[leg, k]], color=c, lw=0.8, ls="--"
                )
        top.plot([], [], color=c, label=f"{role} ({e.design.motor})")
    top.set(
        title="top view at home (cranks solid, rods dashed)",
        xlabel="X (m)",
        ylabel="Y (m)",
        aspect="equal",
    )
    side.set(title="side view at home", xlabel="X (m)", ylabel="Z (m)", aspect="equal")
    top.legend(fontsize=8, loc="upper right")
    _save_png(fig, out / "designs.png")
    plt.close(fig)
    return out / "designs.png"


def _plot_front(out: Path, outcome: DesignOutcome) -> Path:
    """front.png: the main search's convergence (left), and each search's best design's price
    against the torque it needs (right)."""
    import matplotlib.pyplot as plt

    fig, (conv, ax) = plt.subplots(1, 2, figsize=(11, 4.2), constrained_layout=True)
    _plot_convergence(conv, outcome.searches[0])
    _plot_cost_against_torque(ax, outcome)
    _save_png(fig, out / "front.png")
    plt.close(fig)
    return out / "front.png"


def _plot_convergence(conv, main: SearchResult) -> None:
    """The best penalized objective of each generation of the search ``main``, the best so
    far, and the share of candidates that meet the task (right axis); a search no candidate of
    which met the task says so, with the margin its best design misses."""
    gens = np.array(main.generations)
    feasible_best = np.where(gens[:, 0] < 1e5, gens[:, 0], np.nan)
    conv.set(xlabel="generation", title=f"search with {main.motor}")
    if not np.isfinite(feasible_best).any():  # nothing to draw: said, never an empty axis
        name, margin = main.best.binding
        conv.text(
            0.5,
            0.5,
            f"no candidate of its {len(gens)} generations met the task\n(its best by the "
            f"search's rule misses on {name}:\nmargin {margin:+.3g})",
            ha="center",
            va="center",
            transform=conv.transAxes,
        )
        conv.set_xlim(0, max(len(gens) - 1, 1))
        conv.set_yticks([])
        return
    conv.plot(
        np.arange(len(gens)),
        np.fmin.accumulate(np.nan_to_num(feasible_best, nan=np.inf)),
        "k-",
        label="best so far",
    )
    conv.plot(
        np.arange(len(gens)), feasible_best, "o", ms=3, color="tab:blue", label="generation's best"
    )
    conv.set(ylabel=f"{main.objective} ({OBJECTIVES[main.objective][0]})")
    ax2 = conv.twinx()
    ax2.plot(np.arange(len(gens)), 100 * gens[:, 1], color="tab:green", lw=0.8)
    ax2.set_ylabel("candidates meeting the task (%)", color="tab:green")
    conv.legend(fontsize=8, loc="upper right")


def _plot_cost_against_torque(ax, outcome: DesignOutcome) -> None:
    """Each search's best design: the six motors' price against the peak torque the task needs
    (a cross: it misses the task), with the torque its motor may give, and the reference
    robot."""
    import matplotlib.ticker

    rows = []
    for s in outcome.searches:
        rows.append((s.motor, s.best))
    named: set = set()
    for n, (motor, e) in enumerate(rows):
        if "peak_torque_Nm" in e.figures:
            ax.scatter(
                e.figures["price_usd"],
                e.figures["peak_torque_Nm"],
                marker="o" if e.feasible else "x",
                s=50,
                color="tab:blue" if e.feasible else "tab:red",
            )
            if motor not in named:  # a motor searched twice is named once
                named.add(motor)
                ax.annotate(
                    motor.split("-")[0],
                    (e.figures["price_usd"], e.figures["peak_torque_Nm"]),
                    fontsize=7,
                    xytext=(5, 5 if n % 2 else -11),
                    textcoords="offset points",
                )
            ax.scatter(
                e.figures["price_usd"],
                e.figures["motor_peak_Nm"] * e.figures["torque_share"],
                marker="_",
                s=200,
                color="k",
            )
    r = outcome.reference
    if "peak_torque_Nm" in r.figures:
        ax.scatter(
            r.figures["price_usd"],
            r.figures["peak_torque_Nm"],
            marker="*",
            s=120,
            color="0.4",
            label="reference robot",
        )
    if not any("peak_torque_Nm" in e.figures for _, e in rows):
        ax.text(
            0.5,
            0.5,
            "no candidate reached every pose of the task:\nno torque to compare",
            ha="center",
            va="center",
            transform=ax.transAxes,
        )
    else:
        ax.scatter([], [], marker="_", color="k", label="torque the motor may give")
        ax.scatter([], [], marker="o", color="tab:blue", label="best design, meets the task")
        ax.scatter([], [], marker="x", color="tab:red", label="best design, misses")
        ax.set(xscale="log", yscale="log")
        prices = sorted({e.figures["price_usd"] for _, e in rows} | {r.figures["price_usd"]})
        ax.set_xticks(prices, [f"{p:.0f}" for p in prices], minor=False)
        ax.xaxis.set_minor_locator(matplotlib.ticker.NullLocator())
        ax.tick_params(axis="x", labelrotation=45)
        ax.legend(fontsize=7)
    ax.set(
        xlabel="six motors (USD)",
        ylabel="peak motor torque the task needs (N m)",
        title="cost against torque: each motor's best design",
    )
