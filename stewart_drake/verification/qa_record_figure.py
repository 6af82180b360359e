"""The plots of a QA record (:mod:`.qa_record`), drawn for print from the verification itself.

Each measured axis is drawn against its own tolerance, in that axis's unit, because the
tolerance is an RMS error per axis: a 3-D error norm drawn against it makes a PASS look failed
(three axes at 70 um each are a norm of 120 um). Per measured axis, one row:

- the motion: the measured motion over the reference, over the window judged;
- the RMS error of each cycle of the reference within the window, with the RMS over the whole
  window (the figure judged), the tolerance and, when given, the action level as lines.

Then the gamma index of each sample of the translation (:func:`~.fidelity.gamma_index`, at the
record's first criteria) with its pass line at 1. Legends stand outside the plotting area, so
that no legend hides data. The figure is rendered at :data:`DPI` into memory: nothing is
written beside the record.
"""

from __future__ import annotations

import io
import math

import numpy as np

from ..organ_motion.fidelity import AXES, GAMMA_CRITERIA, gamma_index

#: The record's plots' resolution, dots per inch (print: 300 would double the PDF for no
#: visible gain at the 180 mm width it is drawn).
DPI = 200
#: The figure's width, inches (the record's 180 mm text width).
WIDTH_IN = 7.1


def _unit(k: int) -> tuple[str, float]:
    """(unit, scale from SI) of axis k on the record: mm for a translation, deg for a rotation
    (the units of the record's tables)."""
    return ("mm", 1e3) if k >= 3 else ("deg", math.degrees(1.0))


def cycle_rms(ver) -> tuple[np.ndarray, np.ndarray]:
    """(starts (K,) s, rms (K, 6) rad and m) of the reference's cycles the verification judged
    (:func:`~.measured_span.cycle_window`'s: a cycle the recording misses by at most
    :data:`~.measured_span.CYCLE_SLACK` of a cycle counts, cut to it; NaN on an axis not
    measured); (0,) and (0, 6) without cycles."""
    cyc = ver.fidelity.get("cycles", {})
    starts = np.asarray(cyc.get("starts", []), dtype=float)
    return starts, np.asarray(cyc.get("rms", []), dtype=float).reshape(-1, 6)


def _legend_outside(ax) -> None:
    """The axes' legend to the right of its plotting area, never over its data."""
    ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=7, frameon=False)


def _plot_motion(ax, t, x, x_d, k: int) -> None:
    unit, scale = _unit(k)
    ax.plot(t, x_d[:, k] * scale, color="k", ls="--", lw=0.9, label="reference")
    ax.plot(t, x[:, k] * scale, color="#1f77b4", lw=0.8, label="measured")
    ax.set_ylabel(f"{AXES[k]} [{unit}]", fontsize=8)
    ax.set_title(f"{AXES[k]}: the motion", fontsize=8, loc="left")
    _legend_outside(ax)


def _plot_cycle_rms(ax, starts, rms, k: int, whole: float, tolerance, action_level) -> None:
    unit, scale = _unit(k)
    limit = (tolerance[0] if k >= 3 else tolerance[1]) * scale
    top = [limit, whole * scale]
    if starts.size:
        values = rms[:, k] * scale
        ax.plot(np.arange(1, starts.size + 1), values, "o-", ms=3, lw=1, label="RMS per cycle")
        top.append(float(np.nanmax(values)))
    else:
        ax.text(
            0.5,
            0.5,
            "the reference has no cycles in the window",
            ha="center",
            va="center",
            transform=ax.transAxes,
            fontsize=7,
        )
    ax.axhline(whole * scale, color="k", lw=1, label="RMS over the window (judged)")
    ax.axhline(limit, color="#c62828", ls="--", lw=1.2, label="tolerance")
    if action_level is not None:
        act = (action_level[0] if k >= 3 else action_level[1]) * scale
        ax.axhline(act, color="#b35900", ls=":", lw=1.2, label="action level")
    ax.set_ylim(0, 1.15 * max(top))
    ax.set_ylabel(f"RMS error [{unit}]", fontsize=8)
    ax.set_xlabel("cycle", fontsize=8)
    ax.set_title(f"{AXES[k]}: RMS error per cycle against its tolerance", fontsize=8, loc="left")
    from matplotlib.ticker import MaxNLocator

    ax.xaxis.set_major_locator(MaxNLocator(integer=True))
    _legend_outside(ax)


def _plot_gamma(ax, t, x, x_d, measured) -> float | None:
    """The gamma index of the translation's samples; its pass rate in %, or None (no
    translation measured: the panel says so)."""
    distance, time = GAMMA_CRITERIA[0]
    if not np.any(measured[3:]):
        ax.text(
            0.5,
            0.5,
            "gamma not computed: no translation measured",
            ha="center",
            va="center",
            transform=ax.transAxes,
            fontsize=8,
        )
        ax.set_axis_off()
        return None
    g = gamma_index(t, x[:, 3:], x_d[:, 3:], distance, time)
    rate = 100.0 * float(np.mean(g <= 1.0))
    ax.plot(t, g, lw=0.6, color="#1f77b4", label="gamma of each sample")
    ax.axhline(1.0, color="#c62828", ls="--", lw=1.2, label="pass (at most 1)")
    ax.set_ylim(0, max(1.5, 1.1 * float(np.max(g))))
    ax.set_xlabel("t of the reference [s]", fontsize=8)
    ax.set_ylabel("gamma", fontsize=8)
    ax.set_title(
        f"gamma index of the translation at {distance * 1e3:g} mm / {time * 1e3:g} ms: "
        f"{rate:.4g} % of samples pass",
        fontsize=8,
        loc="left",
    )
    _legend_outside(ax)
    return rate


def record_figure(ver) -> bytes:
    """The record's plots as PNG bytes at :data:`DPI` (module docstring).

    Args:
        ver: the :class:`~.verify.Verification`: its judgement's tolerance and action level
            (m, rad; the action level may be None) are drawn beside each axis.
    Returns:
        the PNG's bytes.
    """
    import matplotlib

    from .verify import judged_window

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    tolerance, action_level = ver.judgement.tolerance, ver.judgement.action_level
    measured = np.asarray(ver.measured.measured, dtype=bool)
    axes_k = [int(k) for k in np.flatnonzero(measured)]
    t, x, x_d = judged_window(ver)
    starts, rms = cycle_rms(ver)
    rows = 2 * len(axes_k) + 1
    fig, axs = plt.subplots(rows, 1, figsize=(WIDTH_IN, 1.3 * rows + 0.2), squeeze=False)
    try:
        for i, k in enumerate(axes_k):
            _plot_motion(axs[2 * i, 0], t, x, x_d, k)
            _plot_cycle_rms(
                axs[2 * i + 1, 0], starts, rms, k, ver.fidelity["rms"][k], tolerance, action_level
            )
        _plot_gamma(axs[-1, 0], t, x, x_d, measured)
        for a in fig.axes:
            a.tick_params(labelsize=7)
            a.grid(alpha=0.3)
        fig.tight_layout(h_pad=0.6)
        fig.subplots_adjust(right=0.72)  # the legends' column, right of every plot
        out = io.BytesIO()
        fig.savefig(out, format="png", dpi=DPI)
    finally:
        plt.close(fig)
    return out.getvalue()


__all__ = ["DPI", "cycle_rms", "record_figure"]
