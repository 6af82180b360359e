"""The figure of ``servo replay --plot``: each log's goal, the real servo's angle and the model's,
one panel a log, its error in the title."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from ..base.fileio import atomic_write
from .bench import replay


def plot_replays(model, logs, rows, path) -> Path:
    """Draw ``logs`` replayed by ``model`` (``rows``: their errors, as ``servo replay`` prints
    them) into the PNG ``path``; returns it."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    n = len(logs)
    cols = min(3, n)
    nrows = math.ceil(n / cols)
    fig, axes = plt.subplots(nrows, cols, figsize=(5.2 * cols, 3.2 * nrows), squeeze=False)
    for ax, log, row in zip(axes.ravel(), logs, rows):
        ax.plot(log.t, log.goal, color="0.6", lw=1.0, ls="--", label="goal")
        ax.plot(log.t, log.q, color="tab:blue", lw=1.4, label="real servo (encoder)")
        ax.plot(log.t, replay(model, log), color="tab:orange", lw=1.2, label="model")
        off = np.flatnonzero(~log.enabled)
        if off.size:
            ax.axvspan(log.t[off[0]], log.t[-1], color="0.92", zorder=0, label="torque off")
        seen = " (identified on it)" if row["seen"] else " (held out)"
        ax.set_title(
            f"{log.name}, kp {log.kp:g}{seen}\nMAE {1e3 * row['mae_rad']:.1f} mrad, "
            f"RMS {1e3 * row['rms_rad']:.1f} mrad",
            fontsize=9,
        )
        ax.set_xlabel("t [s]")
        ax.set_ylabel("angle [rad]")
        ax.grid(alpha=0.3)
    for ax in axes.ravel()[n:]:
        ax.axis("off")
    legend: dict = {}
    for ax in axes.ravel()[:n]:
        for handle, label in zip(*ax.get_legend_handles_labels()):
            legend.setdefault(label, handle)
    fig.legend(legend.values(), legend.keys(), loc="lower center", ncol=4, frameon=False)
    fig.suptitle(f"{model.servo} ({model.model_class}) replayed on its bench logs")
    fig.tight_layout(rect=(0, 0.05, 1, 0.97))
    path = Path(path)
    atomic_write(path, lambda f: fig.savefig(f, format="png", dpi=90))
    plt.close(fig)
    return path
