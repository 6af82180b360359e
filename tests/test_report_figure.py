"""The report figure's error rows (organ_motion/fidelity_figure.py) draw what the verdict
judges: each axis's error against the per-axis RMS tolerance, never a norm of three axes (a
PASS at 70 um on each axis is 121 um as a norm, and looked failed against a 0.1 mm line), and
each cycle's per-axis RMS as a share of that axis's tolerance. Values read back from the
artists drawn, against computations written here."""

from types import SimpleNamespace

import matplotlib
import numpy as np
import pytest

from stewart_drake.organ_motion.fidelity_figure import (
    _plot_cycles,
    _plot_error,
    running_rms,
)

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

TOL = (1e-4, np.radians(0.1))


def test_the_running_rms_is_each_windows_rms():
    t = np.arange(0.0, 10.0, 0.01)
    e = np.where(t < 5.0, 3e-5, 7e-5)
    e[100] = np.nan  # a sample not measured is left out, not taken as 0
    r = running_rms(t, e, 1.0)
    # Far from the step, the RMS of a constant is the constant.
    assert r[200] == pytest.approx(3e-5, rel=1e-12) and r[800] == pytest.approx(7e-5, rel=1e-12)
    # At the step, t = 5 s: the 101 samples within 0.5 s, 50 at 3e-5 and 51 at 7e-5.
    k = 500
    inside = (t >= t[k] - 0.5 - 1e-12) & (t <= t[k] + 0.5 + 1e-12)
    assert inside.sum() in (100, 101, 102)
    assert r[k] == pytest.approx(np.sqrt(np.mean(e[inside] ** 2)), rel=1e-9)
    assert np.isnan(running_rms(t, np.full_like(t, np.nan)))[0]


def _run(error_per_axis_m):
    """A run of 40 s whose X, Y, Z are each ``error_per_axis_m`` off the reference with
    alternating sign (each axis's RMS is that error), rotations not measured."""
    t = np.arange(0.0, 40.0, 0.01)
    x_d = np.zeros((len(t), 6))
    x_d[:, 3] = 5e-3 * np.sin(2 * np.pi * t / 4)
    x = x_d.copy()
    x[:, 3:] += error_per_axis_m * np.where(np.arange(len(t)) % 2, 1.0, -1.0)[:, None]
    x[:, :3] = np.nan
    rms = [np.nan] * 3 + [error_per_axis_m] * 3
    fid = {"window_s": (4.0, 39.99), "rms": rms}
    return SimpleNamespace(t=t, x=x, x_d=x_d), fid


def test_the_error_rows_draw_each_axis_against_the_per_axis_tolerance():
    r, fid = _run(7e-5)
    fig, axes = plt.subplots(2, 1)
    try:
        _plot_error(axes, r, fid, TOL)
        labels = [line.get_label() for line in axes[0].get_lines()]
        assert "X RMS, 70 um over the window" in labels and "Z RMS, 70 um over the window" in labels
        assert "tolerance 0.1 mm RMS per axis" in labels
        drawn = {line.get_label(): line.get_ydata() for line in axes[0].get_lines()}
        # Each axis's running RMS: 70 um throughout, not the three axes' norm (121 um).
        for axis in "XYZ":
            y = np.asarray(drawn[f"{axis} RMS, 70 um over the window"], dtype=float)
            assert np.allclose(y, 70.0, rtol=1e-9), (axis, y.min(), y.max())
        assert np.allclose(drawn["tolerance 0.1 mm RMS per axis"], 100.0)
        assert max(float(np.max(np.asarray(y, float))) for y in drawn.values()) < 100.01
        # Rotations not measured: said, nothing drawn.
        assert not axes[1].get_lines()
        assert any("rotation not measured" in t.get_text() for t in axes[1].texts)
    finally:
        plt.close(fig)


def test_each_cycles_rms_is_drawn_as_a_share_of_its_axis_tolerance():
    rms = [[np.nan, np.nan, np.nan, 7e-5, 1.2e-4, 5e-5], [np.nan, np.nan, np.nan, 8e-5, 9e-5, 1e-5]]
    cyc = {"starts": [4.0, 8.0], "rms": rms}
    fig, ax = plt.subplots()
    try:
        _plot_cycles(ax, cyc, 0, TOL)
        drawn = {line.get_label(): np.asarray(line.get_ydata(), float) for line in ax.get_lines()}
        assert set(drawn) == {"X", "Y", "Z", "tolerance"}  # no rotation: not measured
        assert np.allclose(drawn["X"], [70, 80]) and np.allclose(drawn["Y"], [120, 90])
        assert np.allclose(drawn["Z"], [50, 10]) and np.allclose(drawn["tolerance"], 100)
        assert ax.get_ylim()[1] >= 120 * 1.1 - 1e-9  # the worst cycle inside the axes
    finally:
        plt.close(fig)


def test_a_rotation_is_drawn_against_the_angle_tolerance():
    """theta's 0.05 deg per cycle is 50 % of 0.1 deg, not 0.05 / 0.1 mm."""
    cyc = {"starts": [0.0], "rms": [[0.0, np.radians(0.05), 0.0, 1e-5, 0.0, 0.0]]}
    fig, ax = plt.subplots()
    try:
        _plot_cycles(ax, cyc, 0, TOL)
        drawn = {line.get_label(): np.asarray(line.get_ydata(), float) for line in ax.get_lines()}
        assert np.allclose(drawn["theta"], [50.0]) and np.allclose(drawn["X"], [10.0])
    finally:
        plt.close(fig)


@pytest.mark.parametrize("cycles", [1, 3, 40])
def test_the_cycles_axis_is_labelled_by_whole_cycles_only(cycles):
    """One cycle alone is labelled 0, not fractions of a cycle about it; more are labelled by
    whole cycles too."""
    fig, ax = plt.subplots()
    cyc = {"starts": list(range(cycles)), "rms": [[1e-4] * 6] * cycles}
    _plot_cycles(ax, cyc, 0, (3e-4, 0.005))
    fig.canvas.draw()
    lo, hi = ax.get_xlim()
    ticks = [t for t in ax.get_xticks() if lo <= t <= hi]
    plt.close(fig)
    assert ticks and all(float(t).is_integer() for t in ticks), ticks
    assert 0 <= min(ticks) and max(ticks) <= cycles - 1
