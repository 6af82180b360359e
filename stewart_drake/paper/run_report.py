"""A run shown: its figures as text (:func:`~.metrics.format_metrics`) and the paper's Fig. 7
(:func:`plot_fig7`), from a :class:`~stewart_drake.run.result.RunResult`; nothing here
simulates or computes a figure (:mod:`.metrics` does)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..base.fileio import atomic_write
from ..robot.kinematics import AXIS_NAMES
from ..run.metrics import tracking_error

#: Window of the torque panel's means and of the feedback map, s.
TORQUE_WINDOW_S = 0.05


def _window_stats(t: np.ndarray, values: np.ndarray, window_s: float):
    """(t_w (W,), mean (W, k), rms (W, k)) of values (N, k) over consecutive windows of
    ``window_s``: the 1 kHz torque chatter of an encoder's quantum averaged out (mean) and
    measured (rms)."""
    index = ((t - t[0]) / window_s + 1e-9).astype(int)
    n = index[-1] + 1
    counts = np.maximum(np.bincount(index, minlength=n), 1)[:, None]
    mean = np.stack([np.bincount(index, weights=v, minlength=n) for v in values.T], 1) / counts
    square = np.stack([np.bincount(index, weights=v**2, minlength=n) for v in values.T], 1)
    t_w = t[0] + (np.arange(n) + 0.5) * window_s
    return t_w, mean, np.sqrt(square / counts)


def _zoom_window(t: np.ndarray, ref: np.ndarray, err: np.ndarray) -> slice:
    """Samples around the largest |err| over which the reference moves by about four times that
    error, so that reference and achieved value are told apart in a zoom (5 ms .. 1 s)."""
    k = int(np.argmax(np.abs(err)))
    peak = max(abs(err[k]), 1e-15)
    dt = float(np.median(np.diff(t))) if len(t) > 1 else 1.0
    half = max(int(round(0.005 / dt)), 2)
    while half * dt < 1.0:
        window = ref[max(k - half, 0) : k + half + 1]
        if np.ptp(window) > 4 * peak:
            break
        half = int(half * 1.5) + 1
    return slice(max(k - half, 0), min(k + half + 1, len(t)))


def _fig7_panels(result) -> list:
    """The panels of Fig. 7 this run has data for, top to bottom."""
    panels = ["phi", "Z", "angle_error", "position_error"]
    if result.integral is not None:
        panels.append("integral")
    if result.omega is not None and np.ptp(result.omega) > 0:
        panels.append("omega")
    panels.append("torque")
    if result.T_ff is not None:
        panels.append("feedback")
    return panels


def plot_fig7(result, path: str | Path) -> Path:
    """Paper Fig. 7 as a PNG, one quantity per panel, plain linear axes.

    Panels: phi and Z with their references, each with a zoom on the instant of its largest
    error where the two curves part (mrad, mm); the angle and position tracking errors (urad,
    um); the integral states z (eq. 23) when the controller has them; omega_Q and omega_R when
    tuned (log axis: they span decades); the motor torques as 50 ms means with the motors'
    limit; and, when the feed-forward is known, the feedback torque T - T_ff per motor as a map
    of its 50 ms RMS (the chatter of the encoders' quantum, which drawn raw hides the six
    motors in one band).
    Returns:
        the path written (atomically).
    """
    # A Figure without pyplot: no global backend switch (a notebook keeps its inline plots).
    from matplotlib.figure import Figure

    panels = _fig7_panels(result)
    heights = [1.2 if p in ("phi", "Z") else 0.8 if p == "feedback" else 1.0 for p in panels]
    fig = Figure(figsize=(10, 1.75 * sum(heights) + 0.8))
    # Left: the time series, one width, one time axis. Right: the zooms, legends, colour bar.
    grid = fig.add_gridspec(len(panels), 2, height_ratios=heights, width_ratios=(3.3, 1))
    axes: list = []
    sides: list = []
    for row in range(len(panels)):
        axes.append(fig.add_subplot(grid[row, 0], sharex=axes[0] if axes else None))
        sides.append(fig.add_subplot(grid[row, 1]))
    for ax in axes[:-1]:
        ax.tick_params(labelbottom=False)
    draw = {
        "phi": _draw_reference,
        "Z": _draw_reference,
        "angle_error": _draw_errors,
        "position_error": _draw_errors,
        "integral": _draw_integral,
        "omega": _draw_omega,
        "torque": _draw_torque,
        "feedback": _draw_feedback,
    }
    for ax, side, panel in zip(axes, sides, panels):
        draw[panel](fig, ax, side, panel, result)
        if panel != "feedback":
            ax.grid(alpha=0.3)
    t = result.t
    axes[-1].set_xlabel("t [s]")
    axes[-1].set_xlim(t[0], t[-1])
    summary = result.config_summary
    name = summary.get("trajectory", "")
    robot = "robot as built (encoders, servos, delay)" if summary.get("hardware") else "ideal robot"
    what = "Fig. 7: paper manoeuvre (eqs. 37-38)" if name == "paper" else f"{name} run"
    fig.suptitle(f"{what}, {robot}", fontsize=11)
    fig.tight_layout()
    path = Path(path)
    atomic_write(path, lambda f: fig.savefig(f, dpi=110, format="png"))
    return path


def _legend_beside(ax, side, loc="center left", **kwargs) -> None:
    side.set_axis_off()
    side.legend(*ax.get_legend_handles_labels(), loc=loc, fontsize=8, frameon=False, **kwargs)


def _draw_reference(fig, ax, side, panel, result) -> None:
    """phi or Z with its reference, and beside it a zoom on the largest error."""
    t, err = result.t, tracking_error(result)
    k, unit, scale, zoom_unit = (0, "rad", 1e3, "mrad") if panel == "phi" else (5, "m", 1e3, "mm")
    sym = r"\varphi" if panel == "phi" else "Z"
    color = "C0" if k == 0 else "C3"
    ax.plot(t, result.x_d[:, k], color="0.75", lw=3.5, label=f"${sym}_d$ reference")
    ax.plot(t, result.x[:, k], color, lw=1.0, label=f"${sym}$ achieved")
    ax.set_ylabel(f"${sym}$ [{unit}]")
    ax.legend(loc="upper left", fontsize=8, ncol=2)
    # The error is a thousandth of the motion: only a zoom shows both curves apart.
    w = _zoom_window(t, result.x_d[:, k], err[:, k])
    ax.axvspan(t[w][0], t[w][-1], color="k", alpha=0.3, lw=0)
    base = result.x_d[w, k][len(result.x_d[w, k]) // 2]
    side.plot(t[w], scale * (result.x_d[w, k] - base), color="0.75", lw=3.5)
    side.plot(t[w], scale * (result.x[w, k] - base), color, lw=1.0)
    side.set_title(
        f"zoom at the largest error (grey band),\naround ${sym}$ = {base:.4g} {unit}", fontsize=8
    )
    side.set_ylabel(f"[{zoom_unit}]", fontsize=8)
    side.set_xlabel("t [s]", fontsize=8, labelpad=1)
    side.tick_params(labelsize=7)
    side.grid(alpha=0.3)


def _draw_errors(fig, ax, side, panel, result) -> None:
    """The three angle or the three position tracking errors."""
    t, err = result.t, tracking_error(result)
    angles = panel == "angle_error"
    for k in range(3) if angles else range(3, 6):
        ax.plot(t, 1e6 * err[:, k], lw=0.8, label=AXIS_NAMES[k])
    ax.set_ylabel(
        f"{'angle' if angles else 'position'} error\nx - x_d [{'urad' if angles else 'um'}]"
    )
    _legend_beside(ax, side, title="axis")


def _draw_integral(fig, ax, side, panel, result) -> None:
    """The controller's integral states z (eq. 23)."""
    for k in range(6):
        ax.plot(result.t, 1e6 * result.integral[:, k], lw=0.8, label=AXIS_NAMES[k])
    ax.set_ylabel("integral states z\n[urad s | um s]")
    _legend_beside(ax, side, ncol=2, title="axis")


def _draw_omega(fig, ax, side, panel, result) -> None:
    """The tuner's omega_Q and omega_R, log axis."""
    ax.plot(result.t, result.omega[:, 0], label=r"$\omega_Q$")
    ax.plot(result.t, result.omega[:, 1], label=r"$\omega_R$")
    ax.set_yscale("log")
    ax.set_ylabel("tuner output")
    _legend_beside(ax, side)


def _draw_torque(fig, ax, side, panel, result) -> None:
    """The motor torques as window means, with the peak and the motors' limit beside."""
    t_w, mean, _ = _window_stats(result.t, result.T, TORQUE_WINDOW_S)
    for i in range(6):
        ax.plot(t_w, mean[:, i], lw=1.2, label=f"{i} ($T_{i + 1}$)")
    limit = result.config_summary.get("motor_limit_Nm")
    ax.set_ylabel(f"motor torque\n{1e3 * TORQUE_WINDOW_S:g} ms means [N m]")
    _legend_beside(ax, side, loc="upper left", ncol=2, title="motor (paper's)")
    side.text(
        0.0,
        0.0,
        f"peak |T| {np.abs(result.T).max():.3g} N m in 1 ms samples"
        + (f"\nmotors' peak {limit:.3g} N m: commands clip there" if limit else ""),
        fontsize=7,
        transform=side.transAxes,
        va="bottom",
    )


def _draw_feedback(fig, ax, side, panel, result) -> None:
    """The feedback torque T - T_ff per motor as a map of its window RMS."""
    t_w, _, rms = _window_stats(result.t, result.T - result.T_ff, TORQUE_WINDOW_S)
    image = ax.imshow(
        rms.T,
        aspect="auto",
        origin="lower",
        cmap="viridis",
        extent=(t_w[0] - TORQUE_WINDOW_S / 2, t_w[-1] + TORQUE_WINDOW_S / 2, 0.5, 6.5),
        interpolation="nearest",
    )
    ax.set_yticks(range(1, 7), [str(i) for i in range(6)])
    ax.set_ylabel("feedback T - T_ff\nper motor")
    side.set_axis_off()
    bar = fig.colorbar(image, cax=side.inset_axes([0.0, 0.05, 0.06, 0.9]))
    bar.set_label(f"{1e3 * TORQUE_WINDOW_S:g} ms RMS [N m]", fontsize=8)
    bar.ax.tick_params(labelsize=7)
