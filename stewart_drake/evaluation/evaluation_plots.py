"""The evaluation's pictures: tracking against effort, frequency responses, step responses.

Drawing only, from the grid's rows (:func:`~.evaluation.run_case`): :func:`plot_results` writes
the three PNGs of docs/results.md, one function each. Fixed LQIs are one line or point per weight
ratio omega_Q / omega_R (the nine pairs are five controllers), coloured soft (yellow) to stiff
(purple); the frequency responses carry each fixed LQI's linear model beside its sweep
(:mod:`~stewart_drake.analysis.loop_analysis`).
"""

from __future__ import annotations

import functools
from pathlib import Path

import numpy as np

from ..base.fileio import atomic_write
from ..run.scenario_io import load_scenario
from .evaluation_grid import FIXED_LQI, FIXED_WEIGHTS, TORQUE_LIMIT_NM, index_rows

#: How the controllers that are not a fixed LQI are drawn in the plots: label, marker, colour.
_OTHERS = {
    "pd": ("crank-space PD", "s", "C3"),
    "ann_best_cost": ("ANN tuner, best-cost labels", "*", "C1"),
    "ann_paper": ("ANN tuner, paper labels", "D", "C6"),
}


def _ratio(controller: str) -> float | None:
    """omega_Q / omega_R of a fixed LQI of the grid, None for the others."""
    if controller not in FIXED_WEIGHTS:
        return None
    q, r = FIXED_WEIGHTS[controller]
    return q / r


def sweep_range(by: dict) -> tuple[float, float]:
    """The frequencies the sweeps' responses actually span, Hz (the first segment, the start
    transient, is dropped: :func:`~.metrics.frequency_response`); (1, 50) when none ran."""
    fs = [
        f
        for (_, ref, _), r in by.items()
        if ref.startswith("sweep_") and "error" not in r
        for f in r["response"]["f"]
    ]
    return (min(fs), max(fs)) if fs else (1.0, 50.0)


def _ratio_colors(ratios) -> dict:
    """One colour per omega_Q / omega_R, soft (yellow) to stiff (purple): viridis, which the
    red, orange and pink of the other controllers do not resemble."""
    import matplotlib

    ratios = sorted(set(ratios))
    shades = matplotlib.colormaps["viridis"](np.linspace(0.9, 0.05, max(len(ratios), 2)))
    return {r: shades[k] for k, r in enumerate(ratios)}


def _by_ratio(by: dict, reference: str, condition: str) -> dict:
    """{ratio: row} of the fixed LQIs that ran (reference, condition); pairs of one ratio are one
    controller (only the ratio sets the gain), the first one stands for them."""
    out: dict = {}
    for c in FIXED_LQI:
        r = by.get((c, reference, condition))
        if r is not None and "error" not in r:
            out.setdefault(_ratio(c), r)
    return dict(sorted(out.items()))


def _others(by: dict, reference: str, condition: str = "nominal"):
    """(label, marker, colour, row) of the controllers that are not a fixed LQI and ran."""
    for c, (label, marker, color) in _OTHERS.items():
        r = by.get((c, reference, condition))
        if r is not None and "error" not in r:
            yield label, marker, color, r


def plot_results(rows, out_dir: str | Path) -> list[Path]:
    """Three PNGs in out_dir: tracking vs feedback effort (paper manoeuvre, nominal and with
    noise), frequency responses (Z and phi sweeps), step responses (Z step). Fixed LQIs are one
    line or point per weight ratio omega_Q / omega_R (the nine pairs are five controllers).
    Returns their paths."""
    by = index_rows(rows)
    colors = _ratio_colors(_ratio(c) for c in FIXED_LQI)
    paths = []
    for name, draw in (
        ("results_tradeoff.png", _plot_tradeoff),
        ("results_bandwidth.png", _plot_bandwidth),
        ("results_steps.png", _plot_steps),
    ):
        fig = draw(by, colors)
        path = Path(out_dir) / name
        atomic_write(path, functools.partial(fig.savefig, dpi=100, format="png"))
        paths.append(path)
    return paths


def _plot_tradeoff(by: dict, colors: dict):
    """Tracking against the feedback effort, the figure of the ANN verdict."""
    import matplotlib.ticker
    from matplotlib.figure import Figure  # no pyplot: no global backend switch

    fig = Figure(figsize=(12, 5.2))
    axes = fig.subplots(1, 2)
    for ax, condition, title in (
        (axes[0], "nominal", "nominal"),
        (axes[1], "noise", "with sensor noise"),
    ):
        fixed = _by_ratio(by, "paper", condition)
        if fixed:
            x = [r["sum_dT2_dt"] for r in fixed.values()]
            y = [r["normalized_rms"] for r in fixed.values()]
            ax.plot(x, y, "-", color="0.75", lw=1, zorder=1)
            ax.scatter(
                x,
                y,
                s=60,
                c=[colors[k] for k in fixed],
                edgecolors="k",
                lw=0.5,
                zorder=2,
                label=r"fixed LQI, labelled by $\omega_Q/\omega_R$",
            )
            for ratio, xi, yi in zip(fixed, x, y):
                ax.annotate(
                    f"{ratio:g}",
                    (xi, yi),
                    xytext=(6, -3),
                    textcoords="offset points",
                    fontsize=8,
                    color="0.25",
                )
        for label, marker, color, r in _others(by, "paper", condition):
            # hollow, drawn on top: a point under it stays visible
            ax.plot(
                r["sum_dT2_dt"],
                r["normalized_rms"],
                marker,
                mfc="none",
                mec=color,
                mew=1.8,
                ms=15 if marker == "*" else 10,
                ls="none",
                zorder=3,
                label=label,
            )
        ax.set_xscale("log")
        ax.set_yscale("log")
        for axis in (ax.xaxis, ax.yaxis):  # 0.02, not 2 x 10^-2
            axis.set_major_formatter(matplotlib.ticker.FuncFormatter(lambda v, _: f"{v:g}"))
            axis.set_minor_formatter(
                matplotlib.ticker.FuncFormatter(
                    lambda v, _: f"{v:g}" if f"{v:.0e}"[0] in "25" else ""
                )
            )
        ax.set_xlabel(r"feedback effort $\sum (T - T_{ff})^2 \Delta t$ [N$^2$ m$^2$ s]")
        ax.set_title(f"paper manoeuvre, {title}", fontsize=10)
        ax.grid(alpha=0.3, which="both")
        ax.legend(fontsize=8, loc="upper left")
    axes[0].set_ylabel("normalized RMS tracking error (1 = 1 mrad | 1 mm)")
    fig.suptitle("Tracking against feedback effort: lower left is better", fontsize=11)
    fig.tight_layout()
    return fig


def _model_tracking(row: dict, ratio: float, f) -> np.ndarray | None:
    """(K, 6) complex x_i / x_d,i of the linear model (:mod:`~.loop_analysis`) of the LQI of
    weight ratio ``ratio`` on the row's base scenario at home, at f (K,) Hz; None when the row
    names no base, the model cannot be built (a base whose loop is not an LQI's) or its closed
    loop is unstable."""
    from ..analysis.loop_analysis import loop_models, tracking_response
    from ..base.errors import StewartError

    base = row.get("case", {}).get("base")
    if not base:
        return None
    try:
        scenario = load_scenario(base)
        driver = scenario.lqi(omega_Q=float(ratio), omega_R=1.0)
        models = loop_models(scenario, driver=driver)
        # an unstable linear loop has no frequency response to draw (the sweep ran on friction)
        return tracking_response(models, f) if models.spectral_radius < 1 else None
    except (StewartError, OSError):
        return None


def _plot_bandwidth(by: dict, colors: dict):
    """The frequency responses of the Z and phi sweeps: gain (top) and phase (bottom), over
    the frequencies actually measured, with the linear model's response of each fixed LQI
    (dotted; :mod:`~.loop_analysis`, friction-free: where the sweep falls below it at small
    amplitude, the cranks' dry friction is why, docs/analysis.md)."""
    from matplotlib.figure import Figure

    fig = Figure(figsize=(12, 7.5))
    axes = fig.subplots(2, 2, sharex=True, sharey="row", height_ratios=[3, 2])
    f_lo, f_hi = sweep_range(by)
    for col, reference in enumerate(("sweep_Z", "sweep_phi")):
        ax, ax_phase = axes[0, col], axes[1, col]
        ratios = _by_ratio(by, reference, "nominal")
        curves = [
            (rf"LQI $\omega_Q/\omega_R$ = {ratio:g}", colors[ratio], "-", r)
            for ratio, r in ratios.items()
        ] + [(label, color, "--", r) for label, _, color, r in _others(by, reference)]
        k = 5 if reference == "sweep_Z" else 0
        _plot_models(ax, ax_phase, ratios, colors, np.geomspace(f_lo, f_hi, 200), k)
        for label, color, ls, r in curves:
            f = r["response"]["f"]
            if not f:
                continue
            ax.semilogx(
                f, 20 * np.log10(r["response"]["gain"]), color=color, lw=1.2, ls=ls, label=label
            )
            if "phase" in r["response"]:
                ax_phase.semilogx(f, np.degrees(r["response"]["phase"]), color=color, lw=1.2, ls=ls)
        _style_sweep_axes(ax, ax_phase, reference.replace("sweep_", ""), f_lo, f_hi)
    axes[0, 0].set_ylabel("gain [dB]")
    axes[1, 0].set_ylabel("phase [deg]")
    axes[0, 1].legend(fontsize=8, loc="lower left")
    fig.tight_layout()
    return fig


def _plot_models(ax, ax_phase, ratios: dict, colors: dict, f_model, k: int) -> None:
    """Gain (``ax``) and phase (``ax_phase``) of the linear model of each fixed LQI of
    ``ratios`` ({ratio: row}) on axis k of the pose at f_model (Hz), dotted
    (:func:`_model_tracking`; a model that cannot be drawn is left out)."""
    for n, (ratio, r) in enumerate(ratios.items()):
        G = _model_tracking(r, ratio, f_model)
        if G is None:
            continue
        ax.semilogx(
            f_model,
            20 * np.log10(np.abs(G[:, k])),
            color=colors[ratio],
            lw=0.9,
            ls=":",
            label="linear model (same colour), no Coulomb friction" if n == 0 else None,
        )
        ax_phase.semilogx(
            f_model,
            np.degrees(np.unwrap(np.angle(G[:, k]))),
            color=colors[ratio],
            lw=0.9,
            ls=":",
        )


def _style_sweep_axes(ax, ax_phase, axis: str, f_lo: float, f_hi: float) -> None:
    """The -3 dB line, the frequency ticks, grids, labels and the title of one sweep's gain
    (``ax``) and phase (``ax_phase``) axes; ``axis`` is the pose's axis swept ("Z", "phi")."""
    import matplotlib.ticker

    ax.axhline(-3, color="k", ls=":", lw=1)
    ax.annotate(
        "-3 dB: the bandwidth is where a gain crosses it",
        (0.01, -3),
        xycoords=("axes fraction", "data"),
        xytext=(0, -10),
        textcoords="offset points",
        fontsize=8,
        ha="left",
    )
    for a in (ax, ax_phase):
        a.xaxis.set_major_locator(matplotlib.ticker.FixedLocator([1, 2, 5, 10, 20, 50]))
        a.xaxis.set_major_formatter(matplotlib.ticker.ScalarFormatter())
        a.xaxis.set_minor_formatter(matplotlib.ticker.NullFormatter())
        a.grid(alpha=0.3, which="both")
    ax_phase.set_xlabel("frequency [Hz]")
    ax.set_title(
        f"reference to pose, {axis}: sine sweep measured {f_lo:.2g} to {f_hi:.3g} Hz",
        fontsize=10,
    )


def _plot_steps(by: dict, colors: dict):
    """The Z step responses, and under the saturation condition for one of each kind."""
    from matplotlib.figure import Figure

    fig = Figure(figsize=(9, 4.8))
    ax = fig.subplots()
    for ratio, r in _by_ratio(by, "step_Z", "nominal").items():
        ax.plot(
            r["trace"]["t"],
            1e3 * np.asarray(r["trace"]["y"]),
            color=colors[ratio],
            lw=1,
            label=rf"LQI $\omega_Q/\omega_R$ = {ratio:g}",
        )
    for label, _, color, r in _others(by, "step_Z"):
        ax.plot(
            r["trace"]["t"], 1e3 * np.asarray(r["trace"]["y"]), color=color, lw=1.5, label=label
        )
    for c in ("lqi_1_1", "pd", "ann_best_cost"):
        rs = next(
            (
                v
                for k, v in by.items()
                if k[0] == c and k[1] == "step_Z" and k[2] != "nominal" and "error" not in v
            ),
            None,
        )
        if rs is not None:
            ax.plot(
                rs["trace"]["t"],
                1e3 * np.asarray(rs["trace"]["y"]),
                ls="--",
                lw=1,
                color=_OTHERS.get(c, (None, None, colors[1.0]))[2],
                label=f"{_OTHERS.get(c, ('LQI ratio 1',))[0]}, |T| <= {TORQUE_LIMIT_NM:g} N m",
            )
    ax.set_xlim(0.4, 1.2)
    ax.set_xlabel("t [s]")
    ax.set_ylabel("Z - Z_home [mm]")
    ax.set_title("5 mm step on Z at t = 0.5 s")
    ax.legend(fontsize=7, ncol=2, loc="lower right")
    ax.grid(alpha=0.3)
    fig.tight_layout()
    return fig
