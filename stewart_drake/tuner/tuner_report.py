"""The tuner study's report: its section of docs/results.md and its picture, from the summary
:func:`~.tuner_study.run_tuner_study` wrote. Rendering only: every figure is the summary's, and
each controller is known by its arm's fields (kind, ratio, lambda), never by parsing a label."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from ..base.tables import markdown_lines
from .study_runs import GOAL, R_HOLD, R_MOVE, RATIOS, SHIFTS, UNSEEN_FAMILY, StudyArm


def pct(v: float) -> str:
    """A relative difference v (0.1: 10 % more) as "+10 %", "lost" when it is not finite."""
    return "lost" if not np.isfinite(v) else f"{100 * v:+.0f} %"


def _controller(v: dict, kind: str, lam: float | None = None) -> Any:
    """The verdict's entry of the arm ``kind`` at ``lam`` (a dict; None: not run)."""
    return v["controllers"].get(StudyArm(kind, lam=lam).label)


def render_tuner_markdown(summary: dict, picture: str = "results_tuner.png") -> str:
    """The tuner study's section of docs/results.md, from the summary of
    :func:`~.tuner_study.run_tuner_study`."""
    st = summary["settings"]
    L = ["## Does online tuning beat the best fixed weights?", ""]
    if st["quick"]:
        L += ["**QUICK mode: 1 s tasks, one seed per family. A smoke test, not a verdict.**", ""]
    L += _setup_lines(st)
    L += ["**Verdict** (computed from the runs below):", ""]
    L += [
        _verdict_line(summary["verdicts"][f"{lam:g}"], lam)
        for lam in st["lambdas"]
        if _controller(summary["verdicts"][f"{lam:g}"], "ours", lam) is not None
    ] + [""]
    L += _why_lines(summary) + [""]
    for lam in st["lambdas"]:
        L += _lambda_table(summary, lam)
    L += _controllers_lines()
    if summary["lost"]:
        L += [
            "Runs that lost the platform (their J counts as infinite): "
            + "; ".join(summary["lost"])
            + ".",
            "",
        ]
    trained = summary.get("trained", {})
    if trained:
        L += [
            "Our tuners' training: "
            + "; ".join(
                f"lambda {k}: {m['samples']} samples, final loss {m['final_loss']:.3g}"
                for k, m in trained.items()
            )
            + ".",
            "",
        ]
    L += [
        f"![tracking vs feedback effort per controller]({picture})",
        "",
        f"{summary['n_runs']} runs whose own times add up to {summary.get('run_s', 0.0):.0f} s; "
        f"this call {summary['wall_s']:.0f} s wall (runs are stored as they finish in "
        "`results/evaluation/tuner_study/` and read back by a later call).",
        "",
    ]
    return "\n".join(L)


def _setup_lines(st: dict) -> list:
    """What every run is: the base, the cost, the tasks, the baseline and the goal."""
    return [
        f"Every run is the LQI on `{st['base']}`. The cost, declared before any run: J = mean "
        "over the run of sum_i (e_i / 1 mrad|mm)^2 + lambda sum_j (u_j / 0.3 N m)^2, e the "
        "true pose error, u the feedback torque (applied minus the static holding torque of "
        "the reference). Tasks of "
        f"{st['duration_s']:g} s (`simulation/tasks.py`): training on seeds "
        f"{sorted({t[1] for t in st['train']})} of {sorted({t[0] for t in st['train']})}; "
        f"held out: seeds {sorted({t[1] for t in st['test'] if t[0] != 'paper'})} of those "
        f"families, the `{UNSEEN_FAMILY}` family never seen in training, and the paper "
        f"manoeuvre ({len(st['test'])} tasks). The baseline of each task is the **best of "
        f"the 13 fixed ratios omega_Q / omega_R from 1e-3 to 1e3, chosen in hindsight for "
        f"that task** (the paper's nine pairs are five of these ratios). Each entry is the "
        f"paired relative difference (J - J_best fixed) / J_best fixed, mean +- standard "
        f"deviation over the tasks; negative is better. The goal we set: our tuner at least "
        f"{100 * GOAL:.0f} % below, beyond the spread, at every lambda.",
        "",
    ]


def _verdict_line(v: dict, lam: float) -> str:
    """One lambda's verdict: our tuner, its closed-loop choice, the headroom, the chosen fixed
    ratio, each against the best fixed ratio of each task."""
    ours, ours_cl = _controller(v, "ours", lam), _controller(v, "ours closed-loop", lam)
    head, chosen = _controller(v, "hindsight", lam), _controller(v, "fixed chosen", lam)

    def meets(c):
        return "meets" if c["beats"] else "does not meet"

    return (
        f"- lambda = {lam:g}: our tuner {pct(ours['mean'])} +- {100 * ours['std']:.0f} % "
        f"against the best fixed ratio: **{meets(ours)}** the goal"
        + (
            f"; its closed-loop choice {pct(ours_cl['mean'])} +- "
            f"{100 * ours_cl['std']:.0f} % (**{meets(ours_cl)}**)"
            if ours_cl
            else ""
        )
        + (
            f"; the hindsight schedule (the headroom) {pct(head['mean'])} +- "
            f"{100 * head['std']:.0f} %"
            if head
            else ""
        )
        + (
            f"; the single fixed ratio chosen on the training tasks "
            f"{pct(chosen['mean'])} +- {100 * chosen['std']:.0f} %"
            if chosen
            else ""
        )
        + "."
    )


def _lambda_table(summary: dict, lam: float) -> list:
    """One lambda's table: every controller against the best fixed ratio, by family."""
    st, v = summary["settings"], summary["verdicts"][f"{lam:g}"]
    test_families = sorted({t[0] for t in st["test"]})
    ratios = [r for r, _ in v["best_fixed"].values()]
    counts = {f"{r:.3g}": ratios.count(r) for r in sorted(set(ratios))}
    L = [
        f"### lambda = {lam:g}",
        "",
        "Best fixed ratio per held-out task (ratio: tasks): "
        + ", ".join(f"{k}: {n}" for k, n in counts.items())
        + ".",
        "",
    ]
    rows = []
    chosen = summary.get("chosen", {}).get(f"{lam:g}")
    for c in v["controllers"].values():
        arm = StudyArm(**c["arm"])
        cells = []
        for fam in test_families:
            m = c["by_family"].get(fam)
            cells.append(
                "-"
                if m is None
                else f"{pct(m[0])}" + (f" +- {100 * m[1]:.0f} %" if m[2] > 1 else "")
            )
        name = arm.name
        if arm.kind == "fixed chosen" and chosen:
            name += f" ({chosen['fixed_ratio']:.3g})"
        elif arm.kind == "ours closed-loop" and chosen:
            name += f" (shift {chosen['shift']:+g})"
        rows.append(
            [name, f"{pct(c['mean'])} +- {100 * c['std']:.0f} %", *cells]
            + ["yes" if c["beats"] else "no"]
        )
    header = ["controller", "all tasks", *test_families, "goal met"]
    return L + markdown_lines(header, rows) + [""]


def _controllers_lines() -> list:
    """What each controller of the tables is."""
    return [
        "Controllers: **hindsight**, per 0.2 s window the fixed ratio that had the lowest J "
        "over that window in its own run, replayed in closed loop as a schedule (what any "
        "tuner could at best learn from these runs); **ours**, `RatioTuner` (density "
        "features and the reference's speed and acceleration -> omega_Q / omega_R in [1e-3, "
        "1e3]), trained per lambda on the training tasks' fixed-ratio runs with the window's "
        "J at the predicted ratio as the loss; **ours closed-loop**, the same network with "
        "its output (log10 ratio) offset by the one of "
        f"{list(SHIFTS)} that gave the lowest mean J / J_best fixed when run in closed loop "
        "on the training tasks (training on the closed-loop cost, one weight: the output "
        "bias); **fixed chosen**, the one fixed ratio with the lowest mean J / J_best fixed "
        "over the training tasks (what a user without a tuner would deploy); **paper "
        "tuner**, the paper's 12-10-2 network on density features trained on the nine "
        "collection runs on the hardware with the paper's labels; "
        f"**speed schedule**, hand-made: ratio {R_HOLD:g} at rest to {R_MOVE:g} at speed; "
        "**fixed gain 1**, ratio 1 with the gain of the start pose (no re-scheduling on "
        "B(x), as the paper's LQI).",
        "",
    ]


def _why_lines(summary: dict) -> list:
    """The headroom, the lambdas and what was tried, each sentence computed from the summary."""
    st = summary["settings"]
    L = ["**The headroom, the lambdas, what was tried** (computed):", ""]
    for lam in st["lambdas"]:
        v = summary["verdicts"][f"{lam:g}"]
        head = _controller(v, "hindsight", lam)
        ratios = [r for r, _ in v["best_fixed"].values()]
        top = max(set(ratios), key=ratios.count)
        if head is None:
            continue
        inside = np.isfinite(head["mean"]) and abs(head["mean"]) <= head["std"]
        L.append(
            f"- lambda = {lam:g}: the best fixed ratio is {top:.3g} on {ratios.count(top)} "
            f"of {len(ratios)} held-out tasks; the hindsight schedule is "
            f"{pct(head['mean'])} +- {100 * head['std']:.0f} % against it, "
            + (
                "**within the seed-to-seed spread: there is no headroom for a tuner to gain**"
                if inside
                else "outside the spread"
            )
            + "."
        )
    L += [
        "",
        "lambda prices 0.3 N m of feedback torque against 1 mrad (or 1 mm) of error: 0.01 "
        "puts tracking first, 0.1 balances, 1 puts effort first; chosen once before the study "
        "so that the best fixed ratio moves across the grid with lambda (counts above). Why no "
        "tuner wins: the best ratio hardly depends on what the platform does (the counts), J "
        "is flat around it (the trade-off curves below) and a switch of weights costs a "
        "transient (the hindsight schedule, built from windows of runs that never switched, "
        "pays it).",
        "",
    ]
    chosen = summary.get("chosen", {})
    if chosen:
        L.append(
            "Tried, on the training tasks only: our tuner trained on the declared cost "
            "(the window's J at the predicted ratio as the loss, not an argmin label), then "
            "its output offset chosen in closed loop (mean J / J_best fixed per offset: "
            + "; ".join(
                f"lambda {k}: "
                + ", ".join(f"{float(sh):+g}: {m:.3g}" for sh, m in c["shift_means"].items())
                for k, c in chosen.items()
            )
            + "); and the one fixed ratio best over the training tasks ("
            + ", ".join(f"lambda {k}: {c['fixed_ratio']:.3g}" for k, c in chosen.items())
            + "). Not tried (open): separate weights for rotation and translation errors, "
            "and a closed-loop search over all the network's weights (CMA-ES). The headroom "
            "above bounds any schedule of the one ratio, not those: a tuner with two ratios "
            "could still find something."
        )
        L.append("")
    return L


#: Markers of the tuner study's controllers by kind (the lambda they were made for is the colour).
_KIND_MARKERS = {
    "hindsight": ("s", "hindsight schedule (the headroom)"),
    "ours": ("^", "our tuner"),
    "ours closed-loop": ("v", "our tuner, shift chosen in closed loop"),
    "fixed chosen": ("P", "one fixed ratio chosen on the training tasks"),
    "paper tuner": ("D", "the paper's ANN tuner"),
    "speed schedule": ("o", "speed schedule (hand-made)"),
    "fixed gain": ("X", "ratio 1 with the start pose's gain"),
}
#: The fixed ratios named on the trade-off curve.
_CURVE_NAMES = {1e-3: "1e-3", 1.0: "1", 1e3: "1e3"}


def plot_tuner_tradeoff(summary: dict, path) -> Path:
    """Tracking (mean e2) against feedback effort (mean u2), one panel per held-out family: the
    13 fixed ratios as a curve, every other controller as a point (means over the family's
    tasks); the marker says what a controller is, the colour the lambda it was made for, and
    the legends sit in a panel of their own. Returns the path."""
    from matplotlib.figure import Figure  # no pyplot: no global backend switch

    from ..base.fileio import atomic_write

    points, tasks = summary["points"], summary["tasks"]
    lambdas = [f"{lam:g}" for lam in summary["settings"]["lambdas"]]
    colors = dict(zip(lambdas, ("C0", "C1", "C2", "C4", "C5")))
    families = sorted({task["family"] for task in tasks.values()})
    ncols = min(3, len(families) + 1)
    nrows = -(-(len(families) + 1) // ncols)
    fig = Figure(figsize=(5.0 * ncols, 4.2 * nrows))
    axes = fig.subplots(nrows, ncols, squeeze=False)
    for ax in axes.flat[len(families) :]:
        ax.set_axis_off()
    kinds_seen = set()
    for ax, fam in zip(axes.flat, families):
        runs = [points[k] for k, task in tasks.items() if task["family"] == fam and k in points]
        kinds_seen |= _draw_family(ax, runs, colors)
        ax.set_title(
            f"held-out family: {fam}" if fam != "paper" else "the paper manoeuvre", fontsize=10
        )
        ax.set_xlabel("feedback effort: mean sum (u / 0.3 N m)^2")
        ax.grid(True, which="both", alpha=0.3)
    for row in axes:
        row[0].set_ylabel("tracking: mean sum (e / 1 mrad|mm)^2")
    _legends(axes.flat[len(families)], kinds_seen, colors)
    fig.suptitle(
        "Held-out tasks: every controller against the fixed-ratio trade-off curve "
        "(lower left is better)"
    )
    fig.tight_layout()
    path = Path(path)
    atomic_write(path, lambda f: fig.savefig(f, dpi=110, format="png"))
    return path


def _draw_family(ax, runs: list, colors: dict) -> set:
    """One family's panel: the fixed ratios' curve and every other controller's point, means
    over the family's tasks (``runs``: {label: point} per task). Returns the kinds drawn."""
    arms: dict = {}
    for task in runs:
        for label, point in task.items():
            arms.setdefault(label, StudyArm(**point["arm"]))

    def mean(label, key):
        vals = [task[label][key] for task in runs if label in task]
        return float(np.mean(vals)) if vals else np.nan

    fixed = [
        StudyArm("fixed", ratio=r).label for r in RATIOS if StudyArm("fixed", ratio=r).label in arms
    ]
    xs, ys = [mean(lab, "u2") for lab in fixed], [mean(lab, "e2") for lab in fixed]
    ax.loglog(xs, ys, "o-", color="0.6", ms=3, zorder=1)
    for lab, x, y in zip(fixed, xs, ys):
        if arms[lab].ratio in _CURVE_NAMES:
            ax.annotate(
                _CURVE_NAMES[arms[lab].ratio],
                (x, y),
                fontsize=8,
                color="0.35",
                xytext=(4, 4),
                textcoords="offset points",
            )
    kinds = set()
    for lab in sorted(arms):
        arm = arms[lab]
        if arm.kind not in _KIND_MARKERS:
            continue
        kinds.add(arm.kind)
        color = colors.get(None if arm.lam is None else f"{arm.lam:g}", "0.2")
        ax.loglog(
            mean(lab, "u2"),
            mean(lab, "e2"),
            _KIND_MARKERS[arm.kind][0],
            mfc="none",
            mec=color,
            mew=1.5,
            ms=8,
            zorder=3,
            ls="none",
        )
    return kinds


def _legends(side, kinds_seen: set, colors: dict) -> None:
    """The legends' panel: what each marker is, and what each colour's lambda is."""
    from matplotlib.lines import Line2D

    kinds = [
        Line2D(
            [],
            [],
            color="0.6",
            marker="o",
            ms=3,
            label="fixed ratios 1e-3 .. 1e3 (the trade-off curve)",
        )
    ]
    kinds += [
        Line2D([], [], marker=m, mfc="none", mec="0.2", mew=1.5, ms=8, ls="none", label=text)
        for kind, (m, text) in _KIND_MARKERS.items()
        if kind in kinds_seen
    ]
    first = side.legend(
        handles=kinds,
        loc="upper left",
        fontsize=8,
        title="controller",
        title_fontsize=9,
        frameon=False,
    )
    side.add_artist(first)
    side.legend(
        handles=[
            Line2D([], [], marker="s", color=c, ls="none", label=f"lambda = {lam}")
            for lam, c in colors.items()
        ],
        loc="lower left",
        fontsize=8,
        frameon=False,
        title="colour: the lambda of the cost\nthe controller was made for",
        title_fontsize=9,
    )
