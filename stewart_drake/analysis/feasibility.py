"""Whether a reference can be run on the robot, without simulating it: every check, over time.

:func:`check` runs the one reference validator
(:func:`~stewart_drake.run.plan.check_reference`: reach, joint limits, singularity,
clearance between the parts, the torque and speed each motor must give) without stopping at the
first refusal, and :func:`plot_margins` draws each margin over
time against its limit: the ``stewart-drake check`` command.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..base.fileio import atomic_write
from ..base.tables import markdown_lines
from ..robot.trajectory_report import TrajectoryReport
from ..run.plan import check_reference

#: Peak memory of :func:`check` per control-period sample, bytes: 0.86 kB measured (the peak of
#: `stewart-drake check paper` over 200 s against 10 s: the report's sample-by-sample series and
#: the plot; the check itself runs in stretches of fixed size), with slack.
CHECK_BYTES_PER_SAMPLE = 2.0e3


def check(scenario, reference=None) -> TrajectoryReport:
    """The validator's whole report of ``reference`` (default the scenario's) on the scenario's
    robot, every refusal reported instead of raised.

    Raises:
        InvalidConfigError: a bad scenario, a reference that is not finite or too short, or a
            check that needs more memory than the machine has (estimated before anything is
            sampled: :data:`CHECK_BYTES_PER_SAMPLE` per control period).
    """
    from ..base.checks import check_memory
    from ..references.trajectories import as_trajectory

    scenario = scenario.validate()
    duration, period = scenario.duration_s, scenario.control_period_s
    what = f"checking {duration:g} s of the reference every {period:g} s"
    on_reference, coarser = scenario.reference.memory_note()
    check_memory(
        what + on_reference,
        (duration / period + 1) * CHECK_BYTES_PER_SAMPLE + scenario.reference.memory_bytes(),
        "shorten --duration" + coarser,
    )
    trajectory = None if reference is None else as_trajectory(reference)
    return check_reference(scenario, trajectory, raise_refused=False)


def plot_margins(report: TrajectoryReport, path, title: str = "") -> Path:
    """One panel per check of ``report`` over time, each against its limit (red dashes; the
    time outside it shaded red): reach, joint angles, cond(J), 1/sigma_max(J), clearance,
    torque (with the motors' peak) and speed.

    Returns:
        the PNG written (atomically).
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    s = report.series
    panels = ["reach", "joints", "cond", "sigma"]
    panels += [
        p
        for p, key in (("clearance", "clearance"), ("torque", "torque"), ("speed", "speed"))
        if key in s
    ]
    fig, axes = plt.subplots(len(panels), 1, figsize=(9, 2.0 * len(panels) + 0.6), sharex=True)
    draw = {
        "reach": _draw_reach,
        "joints": _draw_joints,
        "cond": _draw_cond,
        "sigma": _draw_sigma,
        "clearance": _draw_clearance,
        "torque": _draw_effort,
        "speed": _draw_effort,
    }
    for ax, panel in zip(axes, panels):
        draw[panel](ax, report, panel)
        ax.grid(alpha=0.3)
    axes[-1].set_xlabel("t [s]")
    verdict = "OK" if report.ok else "REFUSED"
    fig.suptitle(f"{verdict}: {title} (red dashes: limits; shaded: outside)", fontsize=10)
    fig.tight_layout()
    path = Path(path)
    atomic_write(path, lambda f: fig.savefig(f, format="png", dpi=100))
    plt.close(fig)
    return path


def _limit(ax, value, below_is_bad: bool, times, series) -> None:
    """A limit as red dashes, and the times ``series`` is outside it shaded red."""
    ax.axhline(value, color="tab:red", ls="--", lw=1)
    bad = series < value if below_is_bad else series > value
    if np.any(bad):
        ax.fill_between(
            times,
            0,
            1,
            where=bad,
            color="tab:red",
            alpha=0.15,
            transform=ax.get_xaxis_transform(),
            step="mid",
        )


def _draw_reach(ax, report: TrajectoryReport, panel: str) -> None:
    s = report.series
    m = np.nanmin(s["margins"]["closure"], axis=1)
    ax.plot(s["t"], m, color="k")
    _limit(ax, 0.0, True, s["t"], m)
    ax.set_ylabel("reach margin\n1 - |L|/sqrt(M²+N²)")


def _draw_joints(ax, report: TrajectoryReport, panel: str) -> None:
    s, t = report.series, report.series["t"]
    for name, label in (
        ("motor_angle", "motor travel"),
        ("crank_joint", "crank rod end"),
        ("platform_joint", "platform socket"),
    ):
        ax.plot(t, np.rad2deg(np.nanmin(s["margins"][name], axis=1)), label=label)
    worst = np.rad2deg(
        np.nanmin(
            [
                np.nanmin(s["margins"][n], axis=1)
                for n in ("motor_angle", "crank_joint", "platform_joint")
            ],
            axis=0,
        )
    )
    _limit(ax, 0.0, True, t, worst)
    ax.set_ylabel("joint margin\n[deg]")
    ax.legend(fontsize=7, loc="upper right", ncol=3)


def _draw_cond(ax, report: TrajectoryReport, panel: str) -> None:
    """cond(J) against its threshold (near a singularity it grows without bound)."""
    s, t = report.series, report.series["t"]
    ax.plot(t, s["cond"], color="k")
    _limit(ax, report.cond_threshold, False, t, s["cond"])
    ax.set_ylabel("cond(J)")


def _draw_sigma(ax, report: TrajectoryReport, panel: str) -> None:
    """1/sigma_max(J) against its threshold (the platform's smallest motion per crank radian
    falls to zero at a dead point), on a panel and scale of its own."""
    s, t = report.series, report.series["t"]
    ax.plot(t, s["sigma_min_inv"], color="k")
    _limit(ax, report.sigma_min_inv_threshold, True, t, s["sigma_min_inv"])
    ax.set_ylabel("1/sigma_max(J)\n[(rad or m)/rad]")


def _draw_clearance(ax, report: TrajectoryReport, panel: str) -> None:
    tc, c = report.series["clearance_t"], 1e3 * report.series["clearance"]
    ax.plot(tc, c, color="k", drawstyle="steps-mid")
    _limit(ax, 1e3 * report.clearance_threshold, True, tc, c)
    ax.set_ylabel("closest parts\n[mm]")
    ax.set_ylim(bottom=min(0.0, np.nanmin(c) - 1))


def _draw_effort(ax, report: TrajectoryReport, panel: str) -> None:
    """The torque or the crank speed each motor needs, against the motors' limit."""
    t, values = report.series["t"], np.abs(report.series[panel])
    unit = "N m" if panel == "torque" else "rad/s"
    for i in range(6):
        ax.plot(t, values[:, i], lw=0.8, label=f"motor {i} (T{i + 1})")
    bound = report.torque_limit if panel == "torque" else report.speed_limit
    if np.isfinite(bound):
        _limit(ax, bound, False, t, np.nanmax(values, axis=1))
        motors = bound / report.effort_margin
        ax.axhline(motors, color="tab:red", lw=1)
        what = "peak" if panel == "torque" else "no-load speed"
        ax.annotate(
            f"motors' {what} {motors:.3g} {unit}; a reference may use "
            f"{100 * report.effort_margin:.3g} %: {bound:.3g} {unit} (dashes)",
            (0.01, motors),
            xycoords=("axes fraction", "data"),
            xytext=(0, 2),
            textcoords="offset points",
            fontsize=7,
            color="tab:red",
            va="bottom",
        )
    ax.set_ylabel(f"|{panel}| needed\n[{unit}]")
    top = max(bound / report.effort_margin if np.isfinite(bound) else 0.0, np.nanmax(values))
    if panel == "torque":
        ax.legend(fontsize=7, loc="lower center", ncol=6, bbox_to_anchor=(0.5, 1.0), frameon=False)
        ax.set_ylim(0.0, 1.2 * top)  # room for the motors' line and its words
    else:  # the no-load speed is far above a surgical motion's
        ax.set_yscale("log")
        ax.set_ylim(1e-2, 12 * max(top, 1.0))


#: Where :func:`clearance_table` goes in docs/reference_geometry.md (a test keeps it current).
CLEARANCE_TABLE_MARKERS = (
    "<!-- clearance table: generated by stewart_drake.analysis.feasibility.clearance_table -->",
    "<!-- end of clearance table -->",
)


def clearance_table(geometry=None, duration_s: float = 10.0, resolution_m: float = 1e-3) -> str:
    """Markdown table of the smallest clearance per pair of part families along the paper
    manoeuvre (eqs. 37-38), with when and between which parts, then the pairs fixed by design.

    Returns:
        the table's lines, between :data:`CLEARANCE_TABLE_MARKERS`.
    """
    from ..plant.clearance import clearance_model, family, sample_indices
    from ..references.trajectories import paper_manoeuvre
    from ..robot.geometry import StewartGeometry

    geometry = geometry or StewartGeometry()
    model = clearance_model(geometry)
    t = np.arange(0.0, duration_s + 5e-4, 1e-3)
    x = paper_manoeuvre().evaluate(t)[0]
    keep = sample_indices(geometry, x, resolution_m)
    _, _, families = model.sweep(x[keep], by_family=True, max_distance=0.3)
    lines = [
        CLEARANCE_TABLE_MARKERS[0],
        "",
    ]
    rows = [
        [f"{a} / {b}", f"{1e3 * distance:.1f}", f"{t[keep][k]:.2f}", f"{c.part_a} / {c.part_b}"]
        for (a, b), (distance, k, c) in sorted(families.items(), key=lambda kv: kv[1][0])
    ]
    seen = set()
    for c in model.fixed:
        key = tuple(sorted((family(c.part_a), family(c.part_b))))
        if key not in seen:
            seen.add(key)
            rows.append(
                [f"{key[0]} / {key[1]}", f"{1e3 * c.distance:.1f}"]
                + ["every pose (fixed by design)", f"{c.part_a} / {c.part_b}"]
            )
    header = ["parts", "smallest clearance [mm]", "at t [s]", "closest pair"]
    lines += markdown_lines(header, rows)
    return "\n".join(lines + ["", CLEARANCE_TABLE_MARKERS[1]])
