"""The figure of a reproduction's or a measured motion's report (:mod:`.fidelity_report`): one
PNG of the poses, the errors (with a zoom at full rate on a long run), the error per cycle and the
harmonics, titled with the verdict (:func:`plot_report`); and what the page and the figure say
about the verdict alike (what it compares, how the run learned)."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np

from ..base.fileio import atomic_write
from .fidelity import AXES, COMPARED, format_angle, format_length, format_window, verdict
from .reproduction import Reproduction, learning_words

#: A measured motion's result, written by the same functions as a reproduction's: verify's
#: :class:`~stewart_drake.verification.verify.Verification`, which sits in a package above this
#: one (it imports these functions) and is named here only in words.
Verification = Any

#: What the report writes for a figure of an axis the measurement did not see.
NOT_MEASURED = "not measured"


def learning_of(rep) -> str:
    """How ``rep``'s run learned, in words (a record without ``learning``: from its
    ``learn_cycles``)."""
    return getattr(rep, "learning", "") or learning_words(None, rep.learn_cycles)


def compared(rep: Reproduction | Verification) -> str | None:
    """What ``rep``'s fidelity compares, in words, for :func:`~.fidelity.verdict`: a
    reproduction's :meth:`~.reproduction.Reproduction.comparison`; None (the verdict's default)
    for a record that does not say."""
    comparison = getattr(rep, "comparison", None)
    return comparison() if callable(comparison) else None


def verdict_of(rep: Reproduction | Verification, tolerance: tuple[float, float]) -> tuple:
    """(passed, line): a measured motion's own judgement (``rep.judgement``: it names what it
    compares, judges the latency and says why it fails), else :func:`~.fidelity.verdict`."""
    judgement = getattr(rep, "judgement", None)
    if judgement is not None:
        return judgement.passed, judgement.line
    return verdict(rep.fidelity, tolerance, compared(rep))


def compared_words(rep: Reproduction | Verification) -> str:
    """What ``rep``'s verdict compares, in words: a measured motion's judgement's, else
    :func:`compared` (or the verdict's default)."""
    judgement = getattr(rep, "judgement", None)
    if judgement is not None:
        return judgement.compared
    return compared(rep) or COMPARED


#: Points a report's curve draws at most: a long run's logs are thinned to this (every n-th
#: sample of a pose, the largest of each n of an error, so that no peak is lost).
PLOT_POINTS = 20_000


def _thinned(t: np.ndarray, y: np.ndarray, peaks: bool = False) -> tuple:
    """(t, y) with at most about :data:`PLOT_POINTS` points: every n-th sample, or with
    ``peaks`` the largest of each n consecutive samples (y >= 0)."""
    n = max(1, int(math.ceil(t.size / PLOT_POINTS)))
    if n == 1:
        return t, y
    if not peaks:
        return t[::n], y[::n]
    m = (t.size // n) * n
    return t[:m:n], y[:m].reshape(-1, n).max(axis=1)


def _plot_poses(axes, moving: list, r, window, label: str = "achieved") -> None:
    """Draw the reference and the achieved (or measured: ``label``) pose of each moving axis
    (mm or deg), one axis per row, the measured window shaded; an axis not measured (NaN)
    says so."""
    t = r.t
    w0, w1 = window
    for ax, k in zip(axes, moving):
        scale, unit = (1e3, "mm") if k >= 3 else (180 / math.pi, "deg")
        ax.plot(*_thinned(t, r.x_d[:, k] * scale), "k--", lw=1, label="reference")
        if np.isfinite(r.x[:, k]).any():
            ax.plot(*_thinned(t, r.x[:, k] * scale), "C0", lw=0.9, label=label)
        else:
            ax.set_title(f"{AXES[k]}: {NOT_MEASURED}", fontsize=8, loc="left")
        ax.set_ylabel(f"{AXES[k]} [{unit}]")
        ax.axvspan(w0, w1, color="0.9", zorder=0)
        _legend(ax)
        ax.grid(alpha=0.3)


#: The colour of each axis's error in the report's error rows (phi, theta, psi, X, Y, Z).
AXIS_COLOURS = ("C0", "C1", "C2", "C0", "C1", "C2")


#: The window of the running RMS the report's error rows draw, s (a breath's part: short enough
#: to show where an error grows, long enough to be an RMS like the one the tolerance bounds).
RUNNING_RMS_S = 1.0


def running_rms(t: np.ndarray, e: np.ndarray, width_s: float = RUNNING_RMS_S) -> np.ndarray:
    """(n,) the RMS of ``e`` (n,) over the samples within ``width_s`` / 2 of each sample's time
    ``t`` (n,) s, increasing; NaN samples left out (NaN where all are)."""
    e = np.asarray(e, dtype=float)
    seen = np.isfinite(e)
    c2 = np.concatenate([[0.0], np.cumsum(np.where(seen, e * e, 0.0))])
    cn = np.concatenate([[0], np.cumsum(seen)])
    lo = np.searchsorted(t, t - width_s / 2, side="left")
    hi = np.searchsorted(t, t + width_s / 2, side="right")
    n = cn[hi] - cn[lo]
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(n > 0, np.sqrt(np.maximum(c2[hi] - c2[lo], 0.0) / n), np.nan)


def _plot_error(axes, r, fid: dict, tolerance: tuple[float, float]) -> None:
    """Draw each translation axis's error (um) and each rotation axis's (urad) over time as the
    verdict judges them, per axis: its running RMS over :data:`RUNNING_RMS_S` (solid; its RMS
    over the judged window in the legend) over its samples' size (faint), against the
    per-axis RMS tolerance (dotted); never a norm of three axes, which is larger than each axis
    and no tolerance applies to. The judged window shaded, legends right of the data."""
    t = r.t
    e = np.abs(r.x[:, :6] - r.x_d[:, :6])
    w0, w1 = fid["window_s"]
    rms = np.asarray(fid["rms"], dtype=float)
    for ax, part, tol, what, unit in (
        (axes[0], range(3, 6), tolerance[0], "translation", "um"),
        (axes[1], range(3), tolerance[1], "rotation", "urad"),
    ):
        seen = [k for k in part if np.isfinite(e[:, k]).any()]
        ax.axvspan(w0, w1, color="0.9", zorder=0)
        ax.set_ylabel(f"{what}\nerror [{unit}]")
        if not seen:  # a marker that gives positions only
            ax.text(0.5, 0.5, f"{what} {NOT_MEASURED}", ha="center", transform=ax.transAxes)
            ax.set_xlim(axes[0].get_xlim())  # the translation's, drawn first
            ax.set_yticks([])
            continue
        top = tol
        for k in seen:
            ax.plot(*_thinned(t, e[:, k] * 1e6, peaks=True), AXIS_COLOURS[k], lw=0.4,
                    alpha=0.25)  # fmt: skip
            whole = f", {_amount(k, rms[k])} over the window" if np.isfinite(rms[k]) else ""
            ax.plot(*_thinned(t, running_rms(t, e[:, k]) * 1e6), AXIS_COLOURS[k], lw=1.4,
                    label=f"{AXES[k]} RMS{whole}")  # fmt: skip
            top = max(top, float(np.nanmax(e[:, k])))
        ax.axhline(tol * 1e6, color="k", ls=":", lw=1.4,
                   label=f"tolerance {_amount(seen[0], tol)} RMS per axis")  # fmt: skip
        # Linear: an RMS at 70 % of the tolerance reads as 70 % of the way to its line.
        ax.set_ylim(0.0, 1.05 * top * 1e6)
        _legend(ax)
        ax.grid(alpha=0.3)
    axes[1].set_xlabel(
        f"t [s] (shaded: the judged window; solid: each axis's RMS over {RUNNING_RMS_S:g} s; "
        "faint: each sample's error)"
    )


def _legend(ax) -> None:
    """The row's legend right of its data, never over it (every row's, so the rows keep one
    width)."""
    ax.legend(loc="upper left", bbox_to_anchor=(1.005, 1.0), fontsize=7, borderaxespad=0)


def _amount(k: int, value: float) -> str:
    """An axis's amount in words: a length for X, Y, Z, an angle for the rotations (below a
    nanometre or a nanoradian 0, not float noise)."""
    value = value if value >= 1e-9 else 0.0
    return format_length(value) if k >= 3 else format_angle(value)


def _plot_cycles(ax, cyc: dict, learn_cycles: int, tolerance: tuple[float, float]) -> None:
    """Draw each axis's RMS error of each cycle as a share of that axis's tolerance (the
    verdict's measure, six axes on one scale, the tolerance at 100 %), the cycles learned from
    marked, or say that the reference has none."""
    if cyc["starts"]:
        j = np.arange(len(cyc["starts"]))
        per_axis = np.asarray(cyc["rms"], dtype=float).reshape(len(j), 6)
        tol = np.array([tolerance[1]] * 3 + [tolerance[0]] * 3)
        for k in range(6):
            if np.isfinite(per_axis[:, k]).any():  # else an axis the file does not measure
                ax.plot(j, 100 * per_axis[:, k] / tol[k], ("s-" if k < 3 else "o-"),
                        color=AXIS_COLOURS[k], ms=4, lw=1, label=AXES[k])  # fmt: skip
        ax.axhline(100, color="k", ls=":", lw=1.4, label="tolerance")
        ax.set_ylim(0, max(110.0, 1.1 * float(np.nanmax(100 * per_axis / tol))))
        if learn_cycles:
            ax.axvline(learn_cycles - 0.5, color="k", ls=":", lw=1)
            ax.text(
                learn_cycles - 0.45,
                0.05 * ax.get_ylim()[1],
                "correction held",
                fontsize=7,
                va="bottom",
            )
        from matplotlib.ticker import MaxNLocator

        # Whole cycles on the axis, one alone too (two ticks at least would put fractions of a
        # cycle there); labels never overlap.
        ax.xaxis.set_major_locator(MaxNLocator(nbins=20, integer=True, min_n_ticks=1))
        _legend(ax)
    else:
        ax.text(
            0.5,
            0.5,
            "the reference has no cycles",
            ha="center",
            va="center",
            transform=ax.transAxes,
        )
    ax.set_xlabel("cycle")
    ax.set_ylabel("RMS per cycle\n[% of tolerance]")
    ax.grid(alpha=0.3)


def _plot_harmonics(ax, harmonics: list) -> None:
    """Draw the harmonic table: each harmonic's frequency, axis, reference amplitude and its
    amplitude and phase errors."""
    ax.axis("off")
    cells = [
        [
            f"{h['source']} {h['k']}",
            f"{h['f_hz']:.3g}",
            h["axis"],
            f"{h['reference'] * (1e3 if AXES.index(h['axis']) >= 3 else 57.2958):.3g}",
            f"{100 * h['amplitude_error']:+.2g} %",
            f"{math.degrees(h['phase_error_rad']):+.2g}",
        ]
        for h in harmonics
    ]
    table = ax.table(
        cellText=cells,
        colLabels=[
            "harmonic",
            "f [Hz]",
            "axis",
            "amplitude [mm|deg]",
            "amplitude error",
            "phase error [deg]",
        ],
        loc="center",
        cellLoc="center",
    )
    table.auto_set_font_size(False)
    table.set_fontsize(7)


#: A run longer than this, s, gets a zoom under its overview; the zoom's length, s.
ZOOM_AFTER_S, ZOOM_S = 60.0, 10.0


def _plot_zoom(
    axes, moving: list, r, fid: dict, tolerance: tuple[float, float], label: str = "achieved"
) -> None:
    """Draw :data:`ZOOM_S` at full rate around the largest error of one translation axis in the
    measured window: the axis that moves most there (reference and achieved, or measured:
    ``label``), and each translation axis's error against the per-axis tolerance."""
    t = r.t
    per_axis = np.abs(r.x[:, 3:6] - r.x_d[:, 3:6])
    e = np.nanmax(np.nan_to_num(per_axis, nan=-np.inf), axis=1)
    w0, w1 = fid["window_s"]
    inside = np.flatnonzero((t >= w0) & (t <= w1))
    k = int(inside[np.argmax(e[inside])]) if inside.size else int(np.argmax(e))
    a = float(np.clip(t[k] - ZOOM_S / 2, t[0], max(t[0], t[-1] - ZOOM_S)))
    m = (t >= a) & (t <= a + ZOOM_S)
    shown = [j for j in moving if np.isfinite(r.x[m, j]).any()] or moving  # measured ones
    axis = max(shown, key=lambda j: float(np.ptp(r.x_d[m, j])) / (1e-3 if j >= 3 else 1e-2))
    scale, unit = (1e3, "mm") if axis >= 3 else (180 / math.pi, "deg")
    axes[0].plot(t[m], r.x_d[m, axis] * scale, "k--", lw=1, label="reference")
    axes[0].plot(t[m], r.x[m, axis] * scale, "C0", lw=0.9, label=label)
    axes[0].set_ylabel(f"zoom: {AXES[axis]}\n[{unit}]")
    axes[0].set_title(
        f"zoom, t = {format_window(a, a + ZOOM_S)} s: around the largest error of a translation "
        "axis in the measured window "
        + (
            f"({e[k] * 1e6:.3g} um at t = {t[k]:.4g} s)" if np.isfinite(e[k]) else "(none measured)"
        ),
        fontsize=8,
    )
    for j in range(3):
        if np.isfinite(per_axis[m, j]).any():
            axes[1].plot(t[m], per_axis[m, j] * 1e6, AXIS_COLOURS[3 + j], lw=0.7,
                         label=f"|{AXES[3 + j]} error|")  # fmt: skip
    axes[1].axhline(tolerance[0] * 1e6, color="k", ls=":", lw=1.2,
                    label="tolerance (RMS per axis)")  # fmt: skip
    axes[1].set_yscale("log")
    axes[1].set_ylabel("zoom: translation\nerror [um]")
    axes[1].set_xlabel("t [s]")
    for ax in axes:
        _legend(ax)
        ax.grid(alpha=0.3, which="both")


#: The report figure's title: its font size, pt, and the characters a line holds (a 10 in wide
#: figure holds about 150 at 9 pt; a long file name is wrapped, not cut at both ends).
TITLE_POINTS, TITLE_CHARS = 9, 110


def report_title(rep: Reproduction | Verification, line: str) -> str:
    """The report figure's title: the motion, the verdict ``line`` and how the run learned
    (the model file named), wrapped at :data:`TITLE_CHARS` characters a line."""
    import textwrap

    text = f"{rep.name}: {line} ({learning_of(rep)})"
    return "\n".join(textwrap.wrap(text, TITLE_CHARS, break_on_hyphens=False))


def plot_report(rep: Reproduction | Verification, path, tolerance: tuple[float, float]) -> Path:
    """One PNG: reference and achieved pose per moving axis, the translation and rotation errors
    over time, for a run longer than :data:`ZOOM_AFTER_S` a zoom at full rate around its largest
    error, the error per cycle and the harmonic table. Returns the path (written atomically)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fid, r = rep.fidelity, rep.result
    moving = [AXES.index(a) for a in fid["moving"]] or [5]
    zoom = int(r.t[-1] - r.t[0] > ZOOM_AFTER_S)
    n_rows = len(moving) + 3 + 2 * zoom + (1 if fid["harmonics"] else 0)
    heights = (
        [1.4] * len(moving)
        + [1.3, 1.3]
        + [1.3, 1.1] * zoom
        + [1.4]
        + ([0.25 * len(fid["harmonics"]) + 0.6] if fid["harmonics"] else [])
    )
    fig, axes = plt.subplots(
        n_rows, 1, figsize=(10, sum(heights) + 1.2), gridspec_kw={"height_ratios": heights}
    )
    _plot_poses(axes, moving, r, fid["window_s"], getattr(rep, "curve_label", "achieved"))
    _plot_error(axes[len(moving) : len(moving) + 2], r, fid, tolerance)
    if zoom:
        _plot_zoom(
            axes[len(moving) + 2 : len(moving) + 4],
            moving,
            r,
            fid,
            tolerance,
            getattr(rep, "curve_label", "achieved"),
        )
    _plot_cycles(axes[len(moving) + 2 + 2 * zoom], fid["cycles"], rep.learn_cycles, tolerance)
    if fid["harmonics"]:
        _plot_harmonics(axes[-1], fid["harmonics"])
    ok, line = verdict_of(rep, tolerance)
    title = report_title(rep, line)
    fig.suptitle(title, fontsize=TITLE_POINTS, color="k" if ok else "tab:red")
    fig.tight_layout()  # which leaves the suptitle its room
    path = Path(path)
    atomic_write(path, lambda f: fig.savefig(f, format="png", dpi=100))
    plt.close(fig)
    return path


__all__ = [
    "NOT_MEASURED",
    "learning_of",
    "compared",
    "verdict_of",
    "compared_words",
    "PLOT_POINTS",
    "ZOOM_AFTER_S",
    "ZOOM_S",
    "TITLE_POINTS",
    "TITLE_CHARS",
    "report_title",
    "RUNNING_RMS_S",
    "running_rms",
    "plot_report",
]
