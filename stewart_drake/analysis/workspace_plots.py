"""The workspace's pictures: holding-torque maps, the reachable tilt, the bottleneck motor.

Drawing only, from a :func:`~.workspace.workspace_summary`: :func:`plot_workspace` writes
workspace.png and bottleneck_and_orientation.png (atomically, as every file of
``stewart-drake workspace``).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..base.fileio import atomic_write
from ..robot.geometry import X_HOME


def _save_figure(fig, path: Path) -> None:
    atomic_write(path, lambda f: fig.savefig(f, format="png", dpi=100))


def _torque_slice(ax, h_axis, v_axis, result, index, labels, title, motors=(None, None)):
    """Map of max |T_i| on one slice where the pose is clear, with the boundaries of the joint
    limits (solid), of interference (dotted) and of cond(J) (dashed), and the contours of the
    motors' peak torque (red, solid) and of the share a reference may use (red, dashed);
    ``motors`` is (peak torque in N m or None, margin)."""
    sl = [slice(None)] * 3
    sl[index[0]] = index[1]
    sl = tuple(sl)
    tmax = np.where(result["clear"][sl], result["max_torque"][sl], np.nan).T
    mesh = ax.pcolormesh(h_axis, v_axis, np.ma.masked_invalid(tmax), shading="auto", cmap="viridis")
    for key, style in (("reachable", "-"), ("clear", ":"), ("usable", "--")):
        m = result[key][sl].T.astype(float)
        if 0 < m.sum() < m.size:
            ax.contour(
                h_axis, v_axis, m, levels=[0.5], colors="k", linestyles=style, linewidths=1.2
            )
    peak, margin = motors
    if peak is not None:
        for level, style in ((peak, "-"), (margin * peak, "--")):
            if np.nanmin(tmax) < level < np.nanmax(tmax):
                ax.contour(
                    h_axis,
                    v_axis,
                    np.ma.masked_invalid(tmax),
                    levels=[level],
                    colors="r",
                    linestyles=style,
                    linewidths=1.8,
                )
    ax.set_xlabel(labels[0])
    ax.set_ylabel(labels[1])
    ax.set_title(title, fontsize=9)
    ax.set_aspect("equal")
    return mesh


def plot_workspace(out: Path, s: dict) -> None:
    """workspace.png and bottleneck_and_orientation.png in the folder ``out``, of a
    :func:`~.workspace.workspace_summary` ``s``."""
    _plot_workspace(out, s)
    _plot_bottleneck(out, s)


def _plot_workspace(out: Path, s: dict) -> None:
    """workspace.png: the holding torques over two slices of the translation box, and the
    reachable tilt against the height."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 3, figsize=(14, 4.6))
    _translation_maps(fig, axes[0], axes[1], s)
    _tilt_curves(axes[2], s)
    fig.legend(
        handles=_boundary_handles(s),
        loc="lower center",
        ncol=5,
        fontsize=9,
        frameon=False,
    )
    share = s["interfering_share"]
    fig.suptitle(
        f"Workspace of states and holding torques (maps: clear poses only). Interference "
        f"removes {100 * share['translation']:.2g} % of the reachable translation box, "
        f"{100 * share['orientation']:.2g} % of the orientation box, "
        f"{100 * share['tilt']:.2g} % of the tilts",
        fontsize=10,
    )
    fig.tight_layout(rect=(0, 0.07, 1, 1))
    _save_figure(fig, out / "workspace.png")
    plt.close(fig)


def _translation_maps(fig, horizontal, vertical, s: dict) -> None:
    """The holding torques over the translation box: the horizontal slice at home height
    (``horizontal``) and the vertical slice through Y = 0 (``vertical``), each with its
    colour bar."""
    taxes, trans = s["translation_axes"], s["translation"]
    motors = (s["peak_torque_Nm"], s["effort_margin"])
    iz = int(np.argmin(np.abs(taxes[2] - X_HOME[5])))
    iy = int(np.argmin(np.abs(taxes[1])))
    m = _torque_slice(
        horizontal,
        taxes[0],
        taxes[1],
        trans,
        (2, iz),
        ("X [m]", "Y [m]"),
        f"max |T_i| [N m], Z = {taxes[2][iz]:.3f} m, home orientation",
        motors,
    )
    fig.colorbar(m, ax=horizontal, shrink=0.8)
    m = _torque_slice(
        vertical,
        taxes[0],
        taxes[2],
        trans,
        (1, iy),
        ("X [m]", "Z [m]"),
        f"max |T_i| [N m], Y = {taxes[1][iy]:.3f} m",
        motors,
    )
    fig.colorbar(m, ax=vertical, shrink=0.8)


def _tilt_curves(ax, s: dict) -> None:
    """The largest tilt reachable in every and in some direction against the height, by the
    joint limits and with clearance too."""
    heights = s["heights"]
    for key, style, label in (
        ("clear_tilt_every_rad", "-", "every direction, + clearance"),
        ("tilt_every_rad", "o:", "every direction, joint limits"),
        ("clear_tilt_some_rad", "-", "some direction, + clearance"),
        ("tilt_some_rad", "s:", "some direction, joint limits"),
    ):
        # The clearance curves are drawn wide and pale under the joint limits' ones, so a
        # curve that coincides with its partner stays visible; the legend says when it does.
        plain = key.removeprefix("clear_")
        wide = key != plain
        if wide and np.array_equal(s[key], s[plain], equal_nan=True):
            label += " (= joint limits)"
        ax.plot(
            heights,
            np.rad2deg(s[key]),
            style,
            ms=3,
            lw=5 if wide else 1.2,
            alpha=0.35 if wide else 1.0,
            label=label,
            color="C0" if "every" in key else "C1",
        )
    ax.set_xlabel("Z [m]")
    ax.set_ylabel("max tilt [deg]")
    ax.set_title("reachable tilt at (0, 0, Z)", fontsize=9)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)


def _boundary_handles(s: dict) -> list:
    """The legend of the maps' boundaries: joint limits, interference, cond(J), and the motors'
    peak and the reference's share of it when the motors are known."""
    from matplotlib.lines import Line2D

    motors = (s["peak_torque_Nm"], s["effort_margin"])
    return [
        Line2D([], [], color="k", ls="-", label="joint limits"),
        Line2D([], [], color="k", ls=":", label=f"parts {s['min_clearance_m'] * 1e3:g} mm apart"),
        Line2D([], [], color="k", ls="--", label=f"cond(J) <= {s['cond_threshold']:g}"),
        *(
            []
            if motors[0] is None
            else [
                Line2D([], [], color="r", ls="-", label=f"motors' peak {motors[0]:.3g} N m"),
                Line2D(
                    [],
                    [],
                    color="r",
                    ls="--",
                    label=f"reference's share {motors[1] * motors[0]:.3g} N m",
                ),
            ]
        ),
    ]


def _plot_bottleneck(out: Path, s: dict) -> None:
    """bottleneck_and_orientation.png: which motor holds the most torque over the translation
    box at home height, and the holding torques over the orientation box."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    taxes, trans, oaxes, orient = (
        s["translation_axes"],
        s["translation"],
        s["orientation_axes"],
        s["orientation"],
    )
    iz = int(np.argmin(np.abs(taxes[2] - X_HOME[5])))
    fig, axes = plt.subplots(1, 2, figsize=(10, 4.2))
    b = np.where(trans["clear"], trans["bottleneck"], -1)[:, :, iz].astype(float).T
    b[b < 0] = np.nan
    m = axes[0].pcolormesh(
        taxes[0],
        taxes[1],
        np.ma.masked_invalid(b),
        shading="auto",
        cmap=plt.get_cmap("tab10", 6),
        vmin=-0.5,
        vmax=5.5,
    )
    fig.colorbar(m, ax=axes[0], ticks=range(6), label="motor with max |T_i|")
    axes[0].set_title(f"bottleneck motor, Z = {taxes[2][iz]:.3f} m", fontsize=9)
    axes[0].set_xlabel("X [m]")
    axes[0].set_ylabel("Y [m]")
    axes[0].set_aspect("equal")
    ipsi = int(np.argmin(np.abs(oaxes[2])))
    m = _torque_slice(
        axes[1],
        np.rad2deg(oaxes[0]),
        np.rad2deg(oaxes[1]),
        orient,
        (2, ipsi),
        ("roll phi [deg]", "pitch theta [deg]"),
        f"max |T_i| [N m] at home position, yaw = {np.rad2deg(oaxes[2][ipsi]):.1f} deg",
        (s["peak_torque_Nm"], s["effort_margin"]),
    )
    fig.colorbar(m, ax=axes[1], shrink=0.8)
    fig.tight_layout()
    _save_figure(fig, out / "bottleneck_and_orientation.png")
    plt.close(fig)
