"""Workspace of states and torques: which poses the robot reaches, how well, and at what torque.

Every pose of a grid is classified at once (numpy, no Python loop per pose): loop closure, motor
travel and ball-joint cones (``limits.limit_margins``), nearness to singularity (cond(J)) and
the static motor torques that hold it against gravity (``statics.holding_torques``, virtual
work over the platform, cranks and rods); then, pose by pose, the clearance between the robot's
parts (Drake's ``SceneGraph``, :mod:`~stewart_drake.plant.clearance`), a limit of its own. Large
grids are split in chunks over processes.

Grids (all poses [phi, theta, psi, X, Y, Z] in rad and m, base frame of reference_geometry.md):
    translation box at fixed orientation -> reachable volume (m^3), extent per axis, slices;
    orientation box (roll, pitch, yaw) at a fixed position -> extent per angle;
    tilt about every horizontal axis vs height -> the largest tilt reachable in every direction.
The ``stewart-drake workspace`` command (:func:`write_workspace`) writes them as PNG, npz and CSV.
"""

from __future__ import annotations

import csv
import io
import os
from pathlib import Path

import numpy as np

from ..base.checks import check_int, check_memory
from ..base.errors import IncompleteResultsError, InvalidConfigError
from ..base.fileio import atomic_write
from ..base.measures import rms_per_axis
from ..execution.runners import JobFailure, ProcessRunner, SerialRunner
from ..plant.admissible import classify
from ..robot import kinematics, limits, statics
from ..robot.geometry import X_HOME, StewartGeometry
from ..robot.kinematics import AXIS_NAMES
from .workspace_plots import plot_workspace

#: Default boxes; each reaches past the reference robot's workspace on every side (a test checks
#: that no reachable pose lies on the boundary, so volumes and extents are not clipped).
TRANSLATION_BOX = ((-0.25, 0.25), (-0.25, 0.25), (0.10, 0.50))  # X, Y, Z in m
ORIENTATION_BOX = ((-1.0, 1.0), (-1.0, 1.0), (-1.3, 1.3))  # phi, theta, psi in rad
#: Keys of :func:`classify` results, each (...,) or (..., 6).
#: Memory a sweep holds per pose of its grids, bytes: the pose (48), the classification (82)
#: and its concatenation; measured 136 B per pose between resolution 21 and 61.
BYTES_PER_POSE = 200.0
FIELDS = (
    "reachable",
    "clear",
    "usable",
    "within_peak",
    "admissible",
    "clearance",
    "cond",
    "sigma_min_inv",
    "torques",
    "max_torque",
    "bottleneck",
)


def _classify_chunk(task):
    geometry, x, cond_threshold, min_clearance_m, motor_limits = task
    return classify(geometry, x, cond_threshold, min_clearance_m, motor_limits)


def sweep(
    geometry: StewartGeometry,
    x,
    cond_threshold: float = limits.DEFAULT_COND_THRESHOLD,
    jobs: int = 1,
    chunk: int = 5000,
    progress=None,
    runner=None,
    min_clearance_m: float = limits.DEFAULT_MIN_CLEARANCE_M,
    motor_limits: limits.MotorLimits | None = None,
) -> dict:
    """:func:`classify` a large batch in chunks, over a runner.

    Args:
        x: (..., 6) poses [rad, m].
        jobs: processes when no ``runner`` is given; 1 runs here, 0 one per core. Workers are
            spawned (not forked), so the caller may hold Drake objects and threads.
        chunk: poses per task.
        progress: optional object with ``update(n)`` (a tqdm bar), called per finished chunk.
        runner: any runner of :mod:`.runners` (``--runner``); overrides ``jobs``.
        min_clearance_m, motor_limits: see :func:`classify`.
    Returns:
        dict like :func:`classify`'s, arrays shaped like x's batch.
    Raises:
        InvalidConfigError: jobs < 0 or chunk < 1.
        IncompleteResultsError: a chunk was lost with its worker (a chunk's own error is
            raised as itself).
    """
    if jobs < 0 or chunk < 1:
        raise InvalidConfigError(f"sweep needs jobs >= 0 and chunk >= 1, got {jobs}, {chunk}")
    x = np.asarray(x, dtype=float)
    batch = x.shape[:-1]
    flat = x.reshape(-1, 6)
    if motor_limits is not None:  # only the figures classify reads travel to the workers
        motor_limits = limits.MotorLimits(motor_limits.peak_torque_Nm, None, motor_limits.margin)
    tasks = {
        str(k): (geometry, flat[i : i + chunk], cond_threshold, min_clearance_m, motor_limits)
        for k, i in enumerate(range(0, len(flat), chunk))
    }
    if runner is None:
        jobs = jobs or os.cpu_count() or 1
        runner = (
            SerialRunner()
            if jobs == 1 or len(tasks) == 1
            else ProcessRunner(min(jobs, len(tasks)), recycle=None)
        )
    parts = {}
    for key, outcome in runner.map(_classify_chunk, tasks):
        if isinstance(outcome, JobFailure):
            raise outcome.error or IncompleteResultsError(f"workspace chunk {key}: {outcome}")
        parts[int(key)] = outcome
        if progress is not None:
            progress.update(len(tasks[key][1]))
    out = {}
    for key in FIELDS:
        joined = np.concatenate([parts[k][key] for k in sorted(parts)], axis=0)
        out[key] = joined.reshape(batch + joined.shape[1:])
    return out


def grid_axes(box, resolution: int) -> tuple:
    """Evenly spaced axes, one (resolution,) array per (low, high) of ``box``."""
    if resolution < 2:
        raise InvalidConfigError(f"resolution must be >= 2 points per axis, got {resolution}")
    return tuple(np.linspace(lo, hi, resolution) for lo, hi in box)


def translation_grid(axes, orientation=(0.0, 0.0, 0.0)) -> np.ndarray:
    """Poses (nx, ny, nz, 6) on the X, Y, Z axes (m) at a fixed orientation (rad)."""
    P = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1)
    x = np.empty(P.shape[:-1] + (6,))
    x[..., :3] = orientation
    x[..., 3:] = P
    return x


def orientation_grid(axes, position=tuple(X_HOME[3:])) -> np.ndarray:
    """Poses (n_phi, n_theta, n_psi, 6) on roll, pitch, yaw axes (rad) at a fixed position (m)."""
    A = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1)
    x = np.empty(A.shape[:-1] + (6,))
    x[..., :3] = A
    x[..., 3:] = position
    return x


def tilt_grid(heights, tilts, n_azimuth: int = 24) -> np.ndarray:
    """Poses (n_heights, n_tilts, n_azimuth, 6) at (0, 0, Z), tilted about horizontal axes.

    Tilt alpha (rad) about the axis (cos a, sin a, 0), a = 2 pi k / n_azimuth: the platform normal
    leans by alpha, with no twist; converted to roll-pitch-yaw (R = Rz Ry Rx).
    """
    Z, al, az = np.meshgrid(
        np.asarray(heights, float),
        np.asarray(tilts, float),
        2 * np.pi * np.arange(n_azimuth) / n_azimuth,
        indexing="ij",
    )
    u = np.stack([np.cos(az), np.sin(az), np.zeros_like(az)], axis=-1)
    K = kinematics.skew(u)
    s, c = np.sin(al)[..., None, None], np.cos(al)[..., None, None]
    R = np.eye(3) + s * K + (1 - c) * (K @ K)
    x = np.zeros(Z.shape + (6,))
    x[..., 0] = np.arctan2(R[..., 2, 1], R[..., 2, 2])
    x[..., 1] = -np.arcsin(np.clip(R[..., 2, 0], -1.0, 1.0))
    x[..., 2] = np.arctan2(R[..., 1, 0], R[..., 0, 0])
    x[..., 5] = Z
    return x


def reachable_volume(axes, mask) -> float:
    """Volume of the set ``mask`` (nx, ny, nz) on a grid with ``axes``: count x cell volume.

    Units: the product of the axes' units (m^3 for a translation grid, rad^3 for orientation).
    The error is of the order of the boundary's area times half a cell.
    """
    cell = np.prod([a[1] - a[0] for a in axes])
    return float(np.count_nonzero(mask) * cell)


def extents(axes, mask) -> np.ndarray:
    """(3, 2) [min, max] per axis of the grid points in ``mask``; NaN if the set is empty."""
    out = np.full((len(axes), 2), np.nan)
    if not np.any(mask):
        return out
    idx = np.nonzero(mask)
    for d, a in enumerate(axes):
        out[d] = a[idx[d].min()], a[idx[d].max()]
    return out


def max_tilt_vs_height(tilts, mask) -> tuple[np.ndarray, np.ndarray]:
    """Largest tilt (rad) per height from a :func:`tilt_grid` classification ``mask``.

    Returns:
        every_direction: (n_heights,) largest alpha such that every tilt <= alpha, about every
            axis of the grid, is reachable (NaN if even alpha = 0 is not).
        some_direction: (n_heights,) largest alpha reachable about at least one axis (contiguous
            from 0 along that axis).
    """
    tilts = np.asarray(tilts, dtype=float)
    all_dirs = np.cumprod(np.all(mask, axis=2), axis=1).astype(bool)  # (h, n_tilt)
    per_dir = np.cumprod(mask, axis=1).astype(bool)  # (h, n_tilt, az)
    n_every = all_dirs.sum(axis=1)
    n_some = per_dir.sum(axis=1).max(axis=1)
    pick = lambda n: np.where(n > 0, tilts[np.maximum(n - 1, 0)], np.nan)  # noqa: E731
    return pick(n_every), pick(n_some)


def summarize_dynamic_torques(geometry: StewartGeometry, t, x, T) -> dict:
    """Peak and RMS motor torques of a logged run, against the static holding torques.

    Args:
        t: (n,) times in s; x: (n, 6) measured poses [rad, m]; T: (n, 6) applied torques in N m.
    Returns:
        dict: ``peak`` (6,) max |T_i| in N m, ``peak_t`` (6,) its time in s, ``rms`` (6,) N m,
        ``bottleneck`` the motor with the largest peak, ``static_peak`` (6,) max |holding torque|
        along the same poses (N m), ``dynamic_over_static`` (6,) peak / static_peak.
    Raises:
        InvalidConfigError: mismatched shapes. UnreachablePoseError: a logged pose unreachable.
    """
    t = np.asarray(t, dtype=float).reshape(-1)
    x, T = np.asarray(x, dtype=float), np.asarray(T, dtype=float)
    if x.shape != (t.size, 6) or T.shape != (t.size, 6) or t.size == 0:
        raise InvalidConfigError(
            f"need t (n,), x (n, 6), T (n, 6); got {t.shape}, {x.shape}, {T.shape}"
        )
    k = np.argmax(np.abs(T), axis=0)
    peak = np.abs(T)[k, np.arange(6)]
    static_peak = np.abs(statics.holding_torques(geometry, x)).max(axis=0)
    return {
        "peak": peak,
        "peak_t": t[k],
        "rms": rms_per_axis(T),
        "bottleneck": int(np.argmax(peak)),
        "static_peak": static_peak,
        "dynamic_over_static": peak / static_peak,
    }


# --- outputs -------------------------------------------------------------------------------------


def _write_csv(path: Path, header, rows) -> None:
    text = io.StringIO()
    w = csv.writer(text)
    w.writerow(header)
    w.writerows(rows)
    atomic_write(path, lambda f: f.write(text.getvalue().encode()))


def workspace_summary(
    geometry: StewartGeometry,
    resolution: int = 41,
    jobs: int = 1,
    cond_threshold: float = limits.DEFAULT_COND_THRESHOLD,
    progress=None,
    n_azimuth: int = 24,
    runner=None,
    min_clearance_m: float = limits.DEFAULT_MIN_CLEARANCE_M,
    motor_limits: limits.MotorLimits | None = None,
) -> dict:
    """Run the three standard sweeps and reduce them to figures.

    Args:
        resolution: grid points per axis of each box (translation: resolution^3 poses).
        jobs, progress, runner: see :func:`sweep`.
        cond_threshold, min_clearance_m, motor_limits: see :func:`classify`.
    Returns:
        dict with the grids (``translation_axes``, ``orientation_axes``, ``heights``, ``tilts``),
        the classifications (``translation``, ``orientation``, ``tilt``: dicts of :func:`classify`)
        and the figures, by the joint limits alone and (``clear_*``) with interference as a
        limit too: ``volume_m3``, ``clear_volume_m3`` and ``usable_volume_m3`` (clear and
        cond(J) within its threshold, the motors ignored) at home orientation,
        ``usable_within_peak_volume_m3`` and ``admissible_volume_m3`` (usable and the holding
        torques within the motors' peak, and within the share of it a reference may use),
        ``orientation_usable_share`` / ``orientation_within_peak_share`` /
        ``orientation_admissible_share`` (fractions of the orientation box),
        ``extent_xyz_m`` (3, 2),
        ``extent_rpy_rad`` (3, 2) at the home position, ``tilt_every_rad`` / ``tilt_some_rad``
        (n_heights,), ``max_holding_torque_Nm`` over the clear translation box and
        ``bottleneck_share`` (6,) fraction of those poses where each motor carries the largest
        |T_i|; ``interfering_share``: per grid, the fraction of the reachable poses where two
        parts come closer than ``min_clearance_m``.
    Raises:
        InvalidConfigError: resolution < 3, or grids that need more memory than the machine
            has (:data:`BYTES_PER_POSE`), before any grid is allocated.
    """
    _check_resolution(resolution, n_azimuth)
    taxes = grid_axes(TRANSLATION_BOX, resolution)
    oaxes = grid_axes(ORIENTATION_BOX, resolution)
    heights = np.linspace(TRANSLATION_BOX[2][0], TRANSLATION_BOX[2][1], resolution)
    tilts = np.linspace(0.0, np.deg2rad(60.0), resolution)
    run = lambda x: sweep(
        geometry,
        x,
        cond_threshold,
        jobs=jobs,
        progress=progress,  # noqa: E731
        runner=runner,
        min_clearance_m=min_clearance_m,
        motor_limits=motor_limits,
    )
    trans = run(translation_grid(taxes))
    orient = run(orientation_grid(oaxes))
    tilt = run(tilt_grid(heights, tilts, n_azimuth))
    return {
        "translation_axes": taxes,
        "orientation_axes": oaxes,
        "heights": heights,
        "tilts": tilts,
        "translation": trans,
        "orientation": orient,
        "tilt": tilt,
        **_figures(
            (taxes, oaxes, tilts),
            (trans, orient, tilt),
            cond_threshold,
            min_clearance_m,
            motor_limits,
        ),
    }


def _check_resolution(resolution, n_azimuth: int) -> None:
    """Refuse a resolution :func:`workspace_summary` cannot use, or grids that need more memory
    than the machine has (InvalidConfigError), before any grid is allocated."""
    # 2: the box's corners only, none reachable.
    check_int("resolution", resolution, 3, why="a grid through the home pose")
    n_poses = 2 * float(resolution) ** 3 + n_azimuth * float(resolution) ** 2
    check_memory(
        f"a workspace sweep at resolution {resolution} ({n_poses:.3g} poses)",
        n_poses * BYTES_PER_POSE,
        "lower --resolution (default 41)",
    )


def _figures(axes: tuple, grids: tuple, cond_threshold, min_clearance_m, motor_limits) -> dict:
    """The figures of :func:`workspace_summary` (from ``volume_m3`` on) of the classifications
    ``grids`` = (translation, orientation, tilt) on ``axes`` = (translation axes, orientation
    axes, tilts)."""
    taxes, oaxes, tilts = axes
    trans, orient, tilt = grids
    every, some = max_tilt_vs_height(tilts, tilt["reachable"])
    every_clear, some_clear = max_tilt_vs_height(tilts, tilt["clear"])
    b = trans["bottleneck"][trans["clear"]]
    share = np.bincount(b[b >= 0], minlength=6) / max(b.size, 1)
    return {
        "volume_m3": reachable_volume(taxes, trans["reachable"]),
        "clear_volume_m3": reachable_volume(taxes, trans["clear"]),
        "usable_volume_m3": reachable_volume(taxes, trans["usable"]),
        "usable_within_peak_volume_m3": reachable_volume(taxes, trans["within_peak"]),
        "admissible_volume_m3": reachable_volume(taxes, trans["admissible"]),
        **{
            f"orientation_{key}_share": float(np.mean(orient[key]))
            for key in ("usable", "within_peak", "admissible")
        },
        "peak_torque_Nm": None if motor_limits is None else motor_limits.peak_torque_Nm,
        "effort_margin": None if motor_limits is None else motor_limits.margin,
        "extent_xyz_m": extents(taxes, trans["reachable"]),
        "extent_rpy_rad": extents(oaxes, orient["reachable"]),
        "clear_extent_xyz_m": extents(taxes, trans["clear"]),
        "clear_extent_rpy_rad": extents(oaxes, orient["clear"]),
        "tilt_every_rad": every,
        "tilt_some_rad": some,
        "clear_tilt_every_rad": every_clear,
        "clear_tilt_some_rad": some_clear,
        "max_holding_torque_Nm": float(
            np.nanmax(np.where(trans["clear"], trans["max_torque"], np.nan))
        ),
        "bottleneck_share": share,
        "cond_threshold": float(cond_threshold),
        "min_clearance_m": float(min_clearance_m),
        "interfering_share": {
            grid: float(np.sum(c["reachable"] & ~c["clear"]) / max(np.sum(c["reachable"]), 1))
            for grid, c in (("translation", trans), ("orientation", orient), ("tilt", tilt))
        },
    }


def write_workspace(
    out,
    resolution: int = 41,
    jobs: int = 0,
    progress: bool = True,
    geometry: StewartGeometry | None = None,
    runner=None,
    motor_limits: limits.MotorLimits | None = None,
    say=None,
) -> list:
    """Sweep the robot over the three grids and write PNG, npz and CSV to ``out``.

    Args:
        out: folder. resolution: grid points per axis (>= 3). jobs: processes (0: one per
            core). progress: show a tqdm bar. geometry: the robot (default: the reference one).
        runner: any runner of :mod:`.runners` (overrides ``jobs``).
        motor_limits: the motors (see :func:`classify`); None ignores them.
        say: called with a line (str) before the writing and plotting after the sweep, which
            take seconds with nothing else to show (None: nothing said).
    Writes (each atomically: a temporary file, then os.replace):
        workspace.npz (grids and classifications), summary.csv (figure, value, unit),
        tilt_vs_height.csv, workspace.png (torque maps + tilt vs height),
        bottleneck_and_orientation.png.
    Returns:
        rows (figure, value, unit) of summary.csv.
    Raises:
        InvalidConfigError: resolution < 3 or jobs < 0.
    """
    from tqdm import tqdm

    if resolution < 3 or jobs < 0:
        raise InvalidConfigError(
            f"--resolution must be >= 3 and --jobs >= 0 (got {resolution}, {jobs})"
        )
    geometry = geometry or StewartGeometry()
    out = Path(out)
    n = resolution
    total = 2 * n**3 + n * n * 24
    with tqdm(total=total, unit="pose", disable=not progress, desc="workspace") as bar:
        s = workspace_summary(
            geometry, n, jobs, progress=bar, runner=runner, motor_limits=motor_limits
        )
    arrays = _arrays(s)
    if say is not None:
        say(
            "writing workspace.npz and the CSV files, drawing workspace.png and "
            "bottleneck_and_orientation.png ..."
        )
    atomic_write(out / "workspace.npz", lambda f: np.savez_compressed(f, **arrays))
    rows = _summary_rows(s)
    _write_csv(out / "summary.csv", ("figure", "value", "unit"), rows)
    _write_tilt_csv(out / "tilt_vs_height.csv", s)
    plot_workspace(out, s)
    return rows


def _arrays(s: dict) -> dict:
    """workspace.npz's arrays of a :func:`workspace_summary`: the grids' axes, the tilts, and
    every field of each grid's classification (``<grid>_<field>``)."""
    arrays = {
        "translation_X": s["translation_axes"][0],
        "translation_Y": s["translation_axes"][1],
        "translation_Z": s["translation_axes"][2],
        "orientation_phi": s["orientation_axes"][0],
        "orientation_theta": s["orientation_axes"][1],
        "orientation_psi": s["orientation_axes"][2],
        "heights": s["heights"],
        "tilts": s["tilts"],
        **{
            key: s[key]
            for key in (
                "tilt_every_rad",
                "tilt_some_rad",
                "clear_tilt_every_rad",
                "clear_tilt_some_rad",
            )
        },
    }
    for grid in ("translation", "orientation", "tilt"):
        for key in FIELDS:
            arrays[f"{grid}_{key}"] = s[grid][key]
    return arrays


def _summary_rows(s: dict) -> list:
    """summary.csv's rows (figure, value, unit) of a :func:`workspace_summary`, as text."""
    rows = [
        ("reachable_volume", f"{s['volume_m3']:.6g}", "m^3"),
        ("clear_volume", f"{s['clear_volume_m3']:.6g}", "m^3"),
        ("usable_volume_ignoring_torque", f"{s['usable_volume_m3']:.6g}", "m^3"),
        ("usable_volume_within_peak_torque", f"{s['usable_within_peak_volume_m3']:.6g}", "m^3"),
        ("usable_volume_within_reference_torque", f"{s['admissible_volume_m3']:.6g}", "m^3"),
        ("orientation_usable_share_ignoring_torque", f"{s['orientation_usable_share']:.6g}", "1"),
        (
            "orientation_usable_share_within_peak_torque",
            f"{s['orientation_within_peak_share']:.6g}",
            "1",
        ),
        (
            "orientation_usable_share_within_reference_torque",
            f"{s['orientation_admissible_share']:.6g}",
            "1",
        ),
        # inf: the motors unlimited (no torque limit given)
        ("peak_torque", f"{s['peak_torque_Nm'] or np.inf:g}", "N m"),
        ("effort_margin", f"{s['effort_margin'] or 1.0:g}", "1"),
        ("cond_threshold", f"{s['cond_threshold']:g}", "1"),
        ("min_clearance", f"{s['min_clearance_m']:g}", "m"),
    ]
    for prefix, ext, rpy in (
        ("", s["extent_xyz_m"], s["extent_rpy_rad"]),
        ("clear_", s["clear_extent_xyz_m"], s["clear_extent_rpy_rad"]),
    ):
        rows += [
            (f"{prefix}extent_{a}_{side}", f"{ext[d, j]:.6g}", "m")
            for d, a in enumerate("XYZ")
            for j, side in enumerate(("min", "max"))
        ]
        rows += [
            (f"{prefix}extent_{a}_{side}", f"{rpy[d, j]:.6g}", "rad")
            for d, a in enumerate(AXIS_NAMES[:3])
            for j, side in enumerate(("min", "max"))
        ]
    rows += [
        (f"interfering_share_{grid}", f"{share:.4g}", "1")
        for grid, share in s["interfering_share"].items()
    ]
    rows.append(("max_holding_torque", f"{s['max_holding_torque_Nm']:.6g}", "N m"))
    rows += [
        (f"bottleneck_share_motor_{i}", f"{v:.4g}", "1")
        for i, v in enumerate(s["bottleneck_share"])
    ]
    return rows


def _write_tilt_csv(path: Path, s: dict) -> None:
    """tilt_vs_height.csv: the largest tilt, deg, in every and in some direction, by the joint
    limits and with clearance, at each height of a :func:`workspace_summary`."""
    _write_csv(
        path,
        (
            "Z_m",
            "tilt_every_direction_deg",
            "tilt_some_direction_deg",
            "clear_tilt_every_direction_deg",
            "clear_tilt_some_direction_deg",
        ),
        [
            (f"{z:.6g}", *(f"{np.rad2deg(v):.6g}" for v in values))
            for z, *values in zip(
                s["heights"],
                s["tilt_every_rad"],
                s["tilt_some_rad"],
                s["clear_tilt_every_rad"],
                s["clear_tilt_some_rad"],
            )
        ],
    )
