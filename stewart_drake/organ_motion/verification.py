"""A motion measured on a real phantom judged against the reference it was asked to follow
(``stewart-drake verify``): the same figures as a reproduction's (:func:`~.fidelity.fidelity`,
the report of :mod:`~.fidelity_report`) from a tracker's export or the robot's encoder log.

What is measured (:class:`MeasuredMotion`) is a tracker's file read by the readers of recorded
traces (:func:`read_measured`: a header naming columns and units, semicolons or commas, decimal
commas, ms, a frame column skipped with ``-``), the poses of its marker M in the tracker's frame
T on the tracker's clock, or the robot's encoder log turned into platform poses by forward
kinematics (:func:`encoder_motion`), on the reference's own clock. :func:`verify` then

1. **aligns the clocks**: the shift d (measured time + d = the reference's time whose pose it
   shows) is found coarsely by cross-correlation over every shift allowed, the measured positions
   against the reference's with the best rigid frame at each shift (the sum of the singular
   values of their cross-covariance, all shifts at once by FFT), then finely with the frames
   (step 2) by least squares, to a fraction of a sample;
2. **puts the frames together**: the poses are already the platform's in the base frame (the
   encoder log; ``frame="base"``; or mapped by a registration, ``base_poses``), or a rigid
   transform of the tracker's frame and the marker's offset on the platform are fitted
   (``frame="fit"``): the fit also removes any true constant error of the phantom (an offset or a
   tilt of its whole motion), and the report says so with what it removed;
3. **separates the latency from the clock offset**: only their difference is in the data
   (d = clock offset - latency). With the clocks' relation known (``clock_offset_s``: measured
   time + offset = the reference's time; the encoder log's ``t_path`` is the reference's clock
   itself) the latency is the offset less the shift; without it the whole shift is reported as
   the latency, ``clock_offset_s`` 0, and the report says that the two were not separated;
4. **measures** the aligned motion over the reference's whole cycles inside the recording
   (after the motion's first cycle when the recording holds its start: the start-up, reported
   apart) with :func:`~.fidelity.fidelity`: RMS, peak, gamma, harmonics, the error per cycle.
   The figures are those of the motion with its latency removed; the latency is given on its own.

A marker that gives positions only (a reflector, a 3-DoF target) is measured in translation; the
rotation figures are then NaN and named as not measured.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import ClassVar

import numpy as np
from scipy.spatial.transform import Rotation

from ..base.errors import InvalidConfigError
from ..references.motion import Reference
from ..robot.kinematics import rotation_rpy
from .fidelity import AXES, fidelity, startup_figures, time_lag

#: A rotation's weight against a translation in the fits, m per rad (a point 0.15 m from the
#: axis).
ROTATION_WEIGHT_M = 0.15
#: Largest latency searched when the clocks' relation is known, s (at most 0.45 of a periodic
#: reference's period, so that a cycle earlier or later is never taken).
MAX_LATENCY_S = 0.5
#: Longest stretch of a reference without cycles the shift is searched over when the clocks'
#: relation is not known, s (an hour: the longest run reproduce makes).
MAX_SEARCH_S = 3600.0
#: Shortest measured motion without cycles that is judged, s (a breath).
MIN_SPAN_S = 4.0
#: Step of the coarse clock search, s (finer when the measured samples are).
COARSE_STEP_S = 0.02
#: Jitter of a file's time steps beyond which its samples are resampled to an even grid (as a
#: share of the median step).
MAX_JITTER = 0.01
#: Weight of the prior that keeps a fitted frame where the data do not determine it: per sample,
#: m per rad for the rotations and dimensionless for the marker's offset (a bias of a few parts in
#: a million on what the motion determines).
FIT_PRIOR = (1e-5, 1e-3)

_W_ROT = np.array([ROTATION_WEIGHT_M] * 3)


@dataclass(frozen=True)
class MeasuredMotion:
    """A motion measured on a phantom, as read.

    Attributes:
        path: the file. kind: "tracker" (a tracker's file) or "encoders" (the robot's encoder
            log, by forward kinematics).
        t: (n,) s, increasing: the file's own clock ("tracker"), or the reference's clock
            ("encoders": the log's ``t_path``).
        poses: (n, 6) [phi, theta, psi, X, Y, Z] rad and m: the marker M in the tracker's frame
            T ("tracker"), the platform E in the base frame B ("encoders"); NaN on the axes
            not measured.
        measured: (6,) bool, the axes the file measures (the three translations always).
        layout: how the file was read, in words. dropped: what was left out as an export's
            artefact, or "".
    """

    path: str
    kind: str
    t: np.ndarray
    poses: np.ndarray
    measured: np.ndarray
    layout: str = ""
    dropped: str = ""

    @property
    def rotations_measured(self) -> bool:
        """Whether the file measures the rotations (a 6-DoF marker, the encoder log)."""
        return bool(np.all(self.measured[:3]))

    def words(self) -> str:
        """What was read, in words: the file, its samples, rate and span, its axes."""
        dt = float(np.median(np.diff(self.t)))
        axes = ", ".join(a for a, m in zip(AXES, self.measured) if m)
        what = "the robot's encoder log, by forward kinematics" if self.kind == "encoders" else ""
        return (
            f"{Path(self.path).name} ({what or self.layout}): {len(self.t)} samples at "
            f"{1 / dt:.4g} Hz over {self.t[-1] - self.t[0]:.4g} s; measured {axes}"
            + ("" if self.rotations_measured else " (positions only: rotation not measured)")
            + (f"; left out: {self.dropped}" if self.dropped else "")
        )


MEASURED_REMEDY = (
    "give a file whose first line names the time and the marker's X, Y, Z (and phi, theta, psi, "
    "or none) with their units, e.g. t [ms];X [mm];Y [mm];Z [mm], or name its columns with "
    "--measured-columns ('-,t [ms],X [mm],Y [mm],Z [mm]' skips a frame counter)"
)


def read_measured(path, columns: str = "", axis_map: dict | None = None) -> MeasuredMotion:
    """A tracker's file as a :class:`MeasuredMotion`: read by the readers of recorded traces
    (:func:`~stewart_drake.references.trace_files.read_trace_table`, any separator and decimal
    mark, a header or ``columns``, a column named ``-`` skipped, a closing line of zeros left
    out), on the file's own clock (its times as written, in s).

    Args:
        path: the file. columns: its columns' names and units when it has no header (or to
            replace it). axis_map: {column: axis with an optional sign}.
    Returns:
        :class:`MeasuredMotion` of kind "tracker".
    Raises:
        MissingFileError, CorruptFileError: no such file, not a regular file, too large, not
            UTF-8 text.
        InvalidConfigError: what the trace readers refuse (no time column, a unit missing or of
            the wrong kind, times not increasing, a row that is not numbers: the line named);
            not the three translations, or some rotations but not three; a missing or NaN
            value (its line and column named).
    """
    from ..references.trace_files import TIME_UNITS, read_trace_table, trace_samples

    path = Path(path)
    header, rows, layout = read_trace_table(path, "auto", columns)
    table = trace_samples(path, header, rows, layout, axis_map)
    axes = sorted(table.targets)
    if axes[-3:] != [3, 4, 5] or len(axes) not in (3, 6):
        found = ", ".join(f"{n} -> {AXES[k]}" for n, k in zip(table.names[1:], table.targets))
        raise InvalidConfigError(
            f"{path}: a measured motion needs the marker's X, Y and Z (and its three rotations "
            f"or none), got {found}; {MEASURED_REMEDY}"
        )
    n = len(table.t)
    values = table.data[:, 1:]
    bad = np.argwhere(~np.isfinite(values))
    if bad.size:
        i, j = (int(v) for v in bad[0])
        raise InvalidConfigError(
            f"{path}, line {rows[i][0]}: {table.names[j + 1]} is missing or NaN (the tracker "
            f"lost the marker?); verify compares measured samples only: cut the file to a stretch "
            f"without gaps"
        )
    poses = np.full((n, 6), np.nan)
    for j, (k, factor) in enumerate(zip(table.targets, table.factors)):
        poses[:, k] = values[:, j] * factor
    start = float(table.data[0, 0]) * TIME_UNITS[table.units[0].lower()]
    measured = np.zeros(6, dtype=bool)
    measured[table.targets] = True
    return MeasuredMotion(
        str(path), "tracker", table.t + start, poses, measured, table.layout, table.dropped
    )


def encoder_motion(path, t_path, readings, geometry) -> MeasuredMotion:
    """The robot's encoder log as a :class:`MeasuredMotion`: the platform's poses in the base
    frame by forward kinematics of ``geometry`` (the encoders' zero errors taken off first), on
    the reference's clock (the log's ``t_path``; its lines without one, the lead-in, left out).

    Args:
        path: the log, for messages. t_path: (n,) s, NaN on the lead-in's lines.
        readings: (n, 6) the encoders' raw readings, rad. geometry: the robot.
    Raises:
        InvalidConfigError: no line on the reference's clock, its times not increasing.
        ForwardKinematicsError: a reading forward kinematics cannot solve (named).
    """
    from ..robot.forward_kinematics import fk

    t_path, readings = np.asarray(t_path, float), np.asarray(readings, float).reshape(-1, 6)
    on = np.isfinite(t_path)
    if np.count_nonzero(on) < 4 or np.any(np.diff(t_path[on]) <= 0):
        raise InvalidConfigError(
            f"{path}: the encoder log needs at least 4 lines on the reference's clock (t_path), "
            f"increasing; give the <stem>_encoders.csv a robot run wrote"
        )
    theta = readings[on] - np.asarray(geometry.encoder_offsets)
    x = np.empty((len(theta), 6))
    x0 = None
    for a in range(0, len(theta), 2000):  # each block from the last pose of the one before
        x[a : a + 2000], _ = fk(geometry, theta[a : a + 2000], x0=x0)
        x0 = x[min(a + 1999, len(theta) - 1)]
    return MeasuredMotion(
        str(path), "encoders", t_path[on], x, np.ones(6, dtype=bool), "encoder log"
    )


# -- poses and frames ------------------------------------------------------------------------------


def _rotations(poses) -> Rotation:
    """The rotations R = Rz(psi) Ry(theta) Rx(phi) of poses (n, 6)."""
    return Rotation.from_euler("ZYX", np.asarray(poses)[:, 2::-1])


def _rpy(rotations: Rotation) -> np.ndarray:
    """(n, 3) roll, pitch, yaw of ``rotations`` (the inverse of :func:`_rotations`)."""
    return rotations.as_euler("ZYX")[:, ::-1]


def reference_poses(reference: Reference, t) -> np.ndarray:
    """(n, 6) the reference's poses at the times t (s), held at its first pose before t = 0
    and at its last after its ``end_time`` (a phantom at rest before and after its motion)."""
    end = getattr(reference, "end_time", None)
    held = np.clip(np.asarray(t, float), 0.0, math.inf if end is None else float(end))
    return np.asarray(reference.evaluate(held)[0], dtype=float)


@dataclass(frozen=True)
class FrameFit:
    """The frames that put the measured poses on the reference's.

    Attributes:
        how: "base" (the poses were the platform's in the base frame), "registration" (mapped by
            a registration file, ``note`` its words) or "fit" (a rigid transform fitted).
        R_BT, p_BT: (3, 3), (3,) m: the tracker's frame in the base frame (fitted; identity
            otherwise).
        R_ME, p_EM: (3, 3): the platform's frame in the marker's (6-DoF marker, fitted);
            (3,) m: the marker's origin on the platform, platform frame (fitted).
        free, fitted: of the ``fitted`` parameters of the frames, those the motion does not
            determine (a turn about the one line a motion runs along), held by the fit's prior
            (:data:`FIT_PRIOR`) where the coarse fit put them.
    """

    how: str
    R_BT: np.ndarray = field(default_factory=lambda: np.eye(3))
    p_BT: np.ndarray = field(default_factory=lambda: np.zeros(3))
    R_ME: np.ndarray = field(default_factory=lambda: np.eye(3))
    p_EM: np.ndarray = field(default_factory=lambda: np.zeros(3))
    free: int = 0
    fitted: int = 0
    note: str = ""

    def words(self) -> str:
        """What the frames did, in words."""
        if self.how == "base":
            return "none: the poses are the platform's in the base frame"
        if self.how == "registration":
            return f"from the registration file, nothing fitted: {self.note}"
        angle = math.degrees(Rotation.from_matrix(self.R_BT).magnitude())
        text = (
            f"fitted (a stated best fit): the tracker's frame at "
            f"{np.linalg.norm(self.p_BT) * 1e3:.4g} mm and {angle:.4g} deg from the base frame, "
            f"the marker {np.linalg.norm(self.p_EM) * 1e3:.3g} mm from the platform's origin"
        )
        if not np.allclose(self.R_ME, np.eye(3)):
            text += (
                f", its axes turned {math.degrees(Rotation.from_matrix(self.R_ME).magnitude()):.3g}"
                " deg from the platform's"
            )
        if self.free:
            text += (
                f"; {self.free} of its {self.fitted} parameters are not determined by this motion "
                "(a turn about the line it runs along, a part of the marker's offset that its "
                "turns do not show): they are held where the coarse fit put them, and no figure "
                "depends on them"
            )
        return (
            text + ". A best fit also removes any true constant error of the phantom (an offset "
            "or a tilt of its whole motion): give --registration REG.yaml to keep it"
        )

    def as_dict(self) -> dict:
        """The fit as JSON values: how, the transforms (rotation vectors, rad; positions, m)."""
        return {
            "how": self.how,
            "rotvec_BT_rad": Rotation.from_matrix(self.R_BT).as_rotvec().tolist(),
            "p_BT_m": np.asarray(self.p_BT).tolist(),
            "rotvec_ME_rad": Rotation.from_matrix(self.R_ME).as_rotvec().tolist(),
            "p_EM_m": np.asarray(self.p_EM).tolist(),
            "free": self.free,
            "fitted": self.fitted,
        }


def _in_base(fit: FrameFit, poses_TM: np.ndarray, reference_x: np.ndarray) -> np.ndarray:
    """(n, 6) the platform's poses in the base frame of the marker's poses_TM (n, 6) through the
    fitted frames: X_BE = X_BT X_TM X_ME; a marker without rotations (NaN) keeps NaN rotations
    and its offset p_EM is taken off along the reference's rotation (reference_x (n, 6))."""
    p_BE, R_BE = _platform(fit, poses_TM, _matrices(poses_TM), rotation_rpy(reference_x[:, :3]))
    out = np.full_like(poses_TM, np.nan)
    out[:, 3:] = p_BE
    if R_BE is not None:
        out[:, :3] = _rpy(Rotation.from_matrix(R_BE))
    return out


def _matrices(poses) -> np.ndarray | None:
    """(n, 3, 3) the rotation matrices of poses (n, 6), None when their rotations are NaN."""
    return rotation_rpy(poses[:, :3]) if np.all(np.isfinite(poses[:, :3])) else None


def _platform(fit: FrameFit, poses_TM, R_TM, R_ref) -> tuple:
    """(p_BE (n, 3), R_BE (n, 3, 3) or None) of the marker's poses_TM (n, 6) with their
    rotations R_TM (n, 3, 3) (None: not measured; the marker's offset then taken off along the
    reference's rotations R_ref (n, 3, 3))."""
    p_BM = poses_TM[:, 3:] @ fit.R_BT.T + fit.p_BT
    R_BE = None if R_TM is None else fit.R_BT @ R_TM @ fit.R_ME
    return p_BM - (R_ref if R_BE is None else R_BE) @ fit.p_EM, R_BE


def _rotation_error(R_ref, R) -> np.ndarray:
    """(n, 3) the rotation from R_ref (n, 3, 3) to R (n, 3, 3), in its own axes: the vector of
    the skew part of R_ref^T R (sin of the angle times the axis; the angle for small ones)."""
    E = np.swapaxes(R_ref, 1, 2) @ R
    return 0.5 * np.stack(
        [E[:, 2, 1] - E[:, 1, 2], E[:, 0, 2] - E[:, 2, 0], E[:, 1, 0] - E[:, 0, 1]], axis=1
    )


def _kabsch(H: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(R (..., 3, 3), score (...,)): the rotations maximising tr(R^T H) of cross-covariances H
    (..., 3, 3) (a sum of r y^T: R maps y onto r) and that maximum (Kabsch)."""
    U, S, Vt = np.linalg.svd(H)
    sign = np.sign(np.linalg.det(U @ Vt))
    sign = np.where(sign == 0, 1.0, sign)
    D = np.ones(S.shape)
    D[..., 2] = sign
    return (U * D[..., None, :]) @ Vt, np.sum(S * D, axis=-1)


# -- the clock -------------------------------------------------------------------------------------


def coarse_shift(
    t, y, reference: Reference, shifts: tuple[float, float], step_s: float, fit_frame: bool
) -> tuple[float, np.ndarray]:
    """The shift d in [shifts] (measured time + d = the reference's time) at which the measured
    positions y best match the reference's, to ``step_s``: their mean squared distance, after
    the best rigid transform at each shift when ``fit_frame`` (Kabsch: the cross-covariances of
    every shift at once by FFT), else as they are; the reference held before its start and
    after its end (:func:`reference_poses`).

    Args:
        t: (n,) s, increasing. y: (n, 3) positions, m. shifts: (lo, hi) s. step_s: s.
    Returns:
        (d s, (3, 3) the rotation R_BT at d; the identity without ``fit_frame``).
    """
    from scipy.signal import correlate

    grid = t[0] + step_s * np.arange(int((t[-1] - t[0]) / step_s) + 1)
    ym = np.column_stack([np.interp(grid, t, y[:, c]) for c in range(3)])
    m = len(grid)
    k_shifts = int(np.floor((shifts[1] - shifts[0]) / step_s)) + 1
    r = reference_poses(reference, grid[0] + shifts[0] + step_s * np.arange(m + k_shifts - 1))
    r = r[:, 3:]
    ones = np.ones(m)
    S_r = np.column_stack([correlate(r[:, b], ones, "valid") for b in range(3)])  # (K, 3)
    S_rr = correlate(np.sum(r * r, axis=1), ones, "valid")
    C = np.empty((k_shifts, 3, 3))  # C[k, b, a] = sum_i r[i + k, b] y[i, a]
    for b in range(3):
        for a in range(3):
            C[:, b, a] = correlate(r[:, b], ym[:, a], "valid")
    if fit_frame:
        y0 = ym - ym.mean(axis=0)
        H = C - S_r[:, :, None] * ym.mean(axis=0)[None, None, :]
        R, score = _kabsch(H)
        ms = (np.sum(y0 * y0) + S_rr - np.sum(S_r * S_r, axis=1) / m - 2 * score) / m
    else:
        R = np.broadcast_to(np.eye(3), (k_shifts, 3, 3))
        ms = (np.sum(ym * ym) + S_rr - 2 * np.trace(C, axis1=1, axis2=2)) / m
    k = int(np.argmin(ms))
    return float(shifts[0] + k * step_s), np.array(R[k])


#: Most samples the fine fit uses (evenly picked): its 13 parameters need far fewer.
FIT_SAMPLES = 3000


def _fine_fit(
    t, y, measured: MeasuredMotion, reference: Reference, d0: float, fit: FrameFit, fitting: bool
) -> tuple[float, FrameFit]:
    """(d s, the frames) minimising the distance between the measured poses at t + d and the
    reference's (least squares, from the coarse shift d0 and frames ``fit``, on at most
    :data:`FIT_SAMPLES` samples): the shift alone, or with ``fitting`` the tracker's frame
    (turned about the measured positions' centroid, so that a tracker a metre away does not tie
    its rotation to its translation), the marker's offset and, for a 6-DoF marker, its axes."""
    from scipy.optimize import least_squares

    pick = slice(None, None, max(1, len(t) // FIT_SAMPLES))
    t, y = t[pick], y[pick]
    rot = measured.rotations_measured
    R_TM = _matrices(y) if rot else None
    n = len(t)
    prior_rot, prior_off = FIT_PRIOR[0] * math.sqrt(n), FIT_PRIOR[1] * math.sqrt(n)
    c_T = y[:, 3:].mean(axis=0)
    c_B0 = c_T @ fit.R_BT.T + fit.p_BT

    def unpack(p) -> FrameFit:
        if not fitting:
            return fit
        R_BT = Rotation.from_rotvec(p[1:4]).as_matrix() @ fit.R_BT
        R_ME = Rotation.from_rotvec(p[7:10]).as_matrix() @ fit.R_ME if rot else fit.R_ME
        p_BT = c_B0 + p[4:7] - R_BT @ c_T
        return FrameFit("fit", R_BT, p_BT, R_ME, p[-3:])

    def residuals(p) -> np.ndarray:
        x_d = reference_poses(reference, t + d0 + p[0])
        R_ref = rotation_rpy(x_d[:, :3])
        p_BE, R_BE = _platform(unpack(p), y, R_TM, R_ref)
        e = [(p_BE - x_d[:, 3:]).ravel()]
        if R_BE is not None:
            e.append((_rotation_error(R_ref, R_BE) * _W_ROT).ravel())
        if fitting:
            e += [prior_rot * p[1:4], prior_off * p[-3:]]
            if rot:
                e.append(prior_rot * p[7:10])
        return np.concatenate(e)

    p0 = np.zeros(1 + (0 if not fitting else (12 if rot else 9)))
    if fitting:
        p0[-3:] = fit.p_EM
    sol = least_squares(residuals, p0, method="trf", x_scale="jac")
    if not fitting:
        return d0 + float(sol.x[0]), fit
    # The translation has no prior (it is always determined): a weight of 1 m per m.
    weights = np.array([prior_rot] * 3 + [1.0] * 3 + [prior_rot] * (3 * rot) + [prior_off] * 3)
    out = replace(unpack(sol.x), free=_free(sol.jac, weights), fitted=len(p0) - 1)
    return d0 + float(sol.x[0]), out


def _free(jac: np.ndarray, weights: np.ndarray) -> int:
    """How many of the frames' parameters the data leave free: the directions of the Jacobian
    (m, 1 + k) whose columns 1.. are scaled by their prior's ``weights`` (k,) in which the
    residuals change by less than three times the prior's own change."""
    J = np.asarray(jac.todense() if hasattr(jac, "todense") else jac)[:, 1:] / weights
    s = np.linalg.svd(J, compute_uv=False)
    return int(np.count_nonzero(s < 3.0))


# -- the verification ------------------------------------------------------------------------------


@dataclass(frozen=True)
class MeasuredRun:
    """The aligned motion, as a run's log: t (n,) the reference's times, s; x (n, 6) the
    measured platform poses in the base frame (NaN on the axes not measured); x_d (n, 6) the
    reference's."""

    t: np.ndarray
    x: np.ndarray
    x_d: np.ndarray


@dataclass
class Verification:
    """A measured motion judged against its reference (:func:`verify`); what
    :mod:`~.fidelity_report` writes up, as it does a :class:`~.reproduction.Reproduction`.

    Attributes:
        name: the reference's name. reference: the reference. measured: the
            :class:`MeasuredMotion` as read.
        result: the aligned motion (:class:`MeasuredRun`), over the recording's overlap with
            the reference.
        cycle_starts: (K + 1,) the reference's cycles in the overlap, s (empty without).
        fidelity: :func:`~.fidelity.fidelity` over the measured window, the axes not measured
            NaN and ``measured`` naming those that are.
        startup: the recording before the window when it holds the motion's start: {"window_s",
            "rms_translation_m", "rms_rotation_rad", "peak_translation_m",
            "peak_rotation_rad"}; an empty window otherwise.
        shift_s: d, the measured time + d is the reference's time its pose shows, s.
        clock_offset_s: the measured clock's offset (measured time + offset = the reference's
            time), s: given, the encoder log's (0), or 0 when not known.
        clock: how the offset was known, in words. latency_s: the phantom's lag behind the
            reference, s (> 0: late): offset - shift.
        frame: the frames (:class:`FrameFit`).
        removed: what was removed before the figures, in words (the clock, the frames, any
            resampling, what the recording holds outside the reference).
    """

    name: str
    reference: Reference
    measured: MeasuredMotion
    result: MeasuredRun
    cycle_starts: np.ndarray
    fidelity: dict
    startup: dict
    shift_s: float
    clock_offset_s: float
    clock: str
    latency_s: float
    frame: FrameFit
    removed: list
    learn_cycles: int = 0
    scale: float = 1.0
    learned_from: str = ""
    wall_s: float = 0.0
    #: The figure's name of the curve beside the reference's.
    curve_label: ClassVar[str] = "measured"

    @property
    def learning(self) -> str:
        """The report title's words on the run: what measured it."""
        return (
            f"measured by the encoders, {Path(self.measured.path).name}"
            if self.measured.kind == "encoders"
            else f"measured by the tracker, {Path(self.measured.path).name}"
        )

    def resolution(self) -> tuple[float, float]:
        """(0, 0): the measured pose's resolution is the instrument's, not known here."""
        return (0.0, 0.0)


def _even(t: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray, str]:
    """(t, y, what was done in words or ""): the samples as they are when their steps are even
    to :data:`MAX_JITTER`, else resampled linearly to an even grid at their median step."""
    steps = np.diff(t)
    dt = float(np.median(steps))
    if np.max(np.abs(steps - dt)) <= MAX_JITTER * dt:
        return t, y, ""
    grid = t[0] + dt * np.arange(int(np.floor((t[-1] - t[0]) / dt + 1e-9)) + 1)
    out = np.column_stack([np.interp(grid, t, y[:, c]) for c in range(y.shape[1])])
    words = (
        f"resampling: {len(t)} samples whose steps range {steps.min() * 1e3:.4g}-"
        f"{steps.max() * 1e3:.4g} ms resampled linearly to {len(grid)} at {dt * 1e3:.4g} ms"
    )
    return grid, out, words


def _search(reference: Reference, t: np.ndarray, clock_offset_s, max_latency_s: float):
    """(lo, hi) s: the shifts searched. Known clocks: the offset less the latencies up to
    ``max_latency_s`` (at most 0.45 of a periodic reference's period); unknown: every shift that
    puts the recording's start from half its length before the motion's start to the end of the
    reference (one period of a periodic one, :data:`MAX_SEARCH_S` of one without an end)."""
    period = getattr(reference, "repeat_period_s", None)
    if clock_offset_s is not None:
        lat = max_latency_s if not period else min(max_latency_s, 0.45 * period)
        return clock_offset_s - lat, clock_offset_s + lat
    span = float(t[-1] - t[0])
    end = getattr(reference, "end_time", None)
    top = float(end) - 0.5 * span if end is not None else float(period or MAX_SEARCH_S)
    return -t[0] - 0.5 * span, -t[0] + max(top, 0.0)


def _window(reference: Reference, a: float, b: float) -> tuple[tuple, np.ndarray, bool]:
    """((w0, w1) the window measured, (K + 1,) the cycle starts in [a, b], whether the recording
    [a, b] (reference time, s) holds the motion's first cycle): the whole cycles after the first
    one of the motion; all of [a, b] for a reference without cycles.

    Raises:
        InvalidConfigError: not one whole cycle (or :data:`MIN_SPAN_S` without cycles).
    """
    from ..references.motion import reference_cycles

    name = getattr(reference, "name", "the reference")
    try:
        starts, _ = reference_cycles(reference, b)
    except InvalidConfigError:
        starts = np.zeros(0)
    if starts.size < 2:
        if b - a < MIN_SPAN_S:
            raise InvalidConfigError(
                f"the measured motion covers {b - a:.3g} s of {name} once aligned, shorter than "
                f"a breath ({MIN_SPAN_S:g} s): record a longer stretch"
            )
        return (a, b), np.zeros(0), False
    holds_start = a < starts[1]
    inside = starts[(starts >= max(a, starts[1]) - 1e-9) & (starts <= b + 1e-9)]
    if inside.size < 2:
        cycle = float(np.median(np.diff(starts)))
        raise InvalidConfigError(
            f"the measured motion covers t = {a:.4g}-{b:.4g} s of {name} once aligned: not one "
            f"whole cycle ({cycle:.3g} s) after the motion's first; record at least two cycles"
        )
    return (float(inside[0]), float(inside[-1])), inside, holds_start


def _not_measured(fid: dict, measured: np.ndarray, t, x, x_d) -> dict:
    """``fid`` with the figures of the axes not measured NaN (their harmonics and lags left out;
    the lag of the whole motion from the measured axes), and ``measured`` naming the others."""
    off = [k for k in range(6) if not measured[k]]
    if not off:
        return {**fid, "measured": list(AXES)}
    fid = dict(fid)
    for key in ("rms", "peak", "rms_fraction", "peak_fraction"):
        fid[key] = [math.nan if k in off else v for k, v in enumerate(fid[key])]
    fid["rms_rotation_rad"] = fid["peak_rotation_rad"] = math.nan
    fid["lag_s"] = {a: v for a, v in fid["lag_s"].items() if measured[AXES.index(a)]}
    fid["harmonics"] = [h for h in fid["harmonics"] if measured[AXES.index(h["axis"])]]
    fid["cycles"] = {
        **fid["cycles"],
        "rms_rotation_rad": [math.nan] * len(fid["cycles"]["rms_rotation_rad"]),
    }
    moving = [AXES.index(a) for a in fid["moving"] if measured[AXES.index(a)]]
    if moving:
        w0, w1 = fid["window_s"]
        m = (t >= w0 - 1e-9) & (t <= w1 + 1e-9)
        p2p = np.asarray(fid["p2p"])[moving]
        fid["lag_all_s"] = time_lag(t[m], x[m][:, moving], x_d[m][:, moving], weights=1 / p2p)
    fid["measured"] = [a for a, m in zip(AXES, measured) if m]
    return fid


def verify(
    reference: Reference,
    measured: MeasuredMotion,
    clock_offset_s: float | None = None,
    frame: str = "fit",
    registration=None,
    max_latency_s: float = MAX_LATENCY_S,
) -> Verification:
    """Judge a measured motion against the reference it was asked to follow (module docstring).

    Args:
        reference: the motion asked for (:class:`~stewart_drake.references.motion.Reference`).
        measured: the motion measured (:func:`read_measured`, :func:`encoder_motion`).
        clock_offset_s: s, the measured time + this is the reference's (None: not known; the
            encoder log is on the reference's clock, 0).
        frame: "fit" (fit the tracker's frame and the marker's offset) or "base" (the poses are
            the platform's in the base frame already); ignored for the encoder log.
        registration: the tracker's frames registered from fiducials
            (:class:`~stewart_drake.calibration.registration.Registration`: ``X_TB``,
            ``X_PM``, ``base_poses``, ``words``), or None; replaces ``frame``.
        max_latency_s: the largest latency searched when the clocks' relation is known, s.
    Returns:
        :class:`Verification`.
    Raises:
        InvalidConfigError: a frame that is neither "fit" nor "base"; a recording not one whole
            cycle of the reference long (or a breath, without cycles), before or after the
            alignment; no overlap with the reference once aligned; a non-finite offset.
    """
    if frame not in ("fit", "base"):
        raise InvalidConfigError(f"frame must be 'fit' or 'base', got {frame!r}")
    if clock_offset_s is not None and not math.isfinite(clock_offset_s):
        raise InvalidConfigError(f"the clock offset must be a finite number, got {clock_offset_s}")
    t, y = measured.t, measured.poses
    if measured.kind == "encoders":
        clock_offset_s, clock = 0.0, "the encoder log's t_path is the reference's own clock"
        fit = FrameFit("base")
    else:
        clock = "given (--clock-offset)" if clock_offset_s is not None else "not known"
        fit = FrameFit(frame) if registration is None else _registered(registration, measured)
    if fit.how == "registration" and measured.rotations_measured:
        y = np.asarray(registration.base_poses(y), dtype=float)
    t, y, resampled = _even(t, y)
    _check_length(reference, t)
    fitting = fit.how == "fit"
    step = max(COARSE_STEP_S, float(np.median(np.diff(t))))
    lo, hi = _search(reference, t, clock_offset_s, max_latency_s)
    y_coarse = y[:, 3:] @ fit.R_BT.T + fit.p_BT
    d0, R0 = coarse_shift(t, y_coarse, reference, (lo, hi), step, fitting)
    if fitting:
        fit = _first_fit(reference, t + d0, y, R0)
    use = _overlap(reference, t + d0, step)
    d, fit = _fine_fit(t[use], y[use], measured, reference, d0, fit, fitting)
    keep = _overlap(reference, t + d, 0.0)
    t_ref = t[keep] + d
    x_d = reference_poses(reference, t_ref)
    x = _in_base(fit, y[keep], x_d)
    (w0, w1), starts, holds_start = _window(reference, float(t_ref[0]), float(t_ref[-1]))
    x_fid = np.where(np.isfinite(x), x, x_d)  # the axes not measured compare to themselves
    fid = fidelity(t_ref, x_fid, x_d, (w0, w1), _frequencies(reference), starts)
    offset = 0.0 if clock_offset_s is None else float(clock_offset_s)
    return Verification(
        name=getattr(reference, "name", "reference"),
        reference=reference,
        measured=measured,
        result=MeasuredRun(t_ref, x, x_d),
        cycle_starts=starts,
        fidelity=_not_measured(fid, measured.measured, t_ref, x_fid, x_d),
        startup=startup_figures(t_ref, x, x_d, w0 if holds_start else float(t_ref[0])),
        shift_s=d,
        clock_offset_s=offset,
        clock=clock,
        latency_s=offset - d,
        frame=fit,
        removed=_removed_words(d, offset, offset - d, clock, fit, resampled)
        + _outside_words(t + d, t_ref, (w0, w1), holds_start),
    )


def _registered(registration, measured: MeasuredMotion) -> FrameFit:
    """The frames of a registration (its ``X_TB``, ``X_PM``): identities for a 6-DoF marker,
    whose poses its ``base_poses`` converts; for a marker without rotations the tracker's frame
    in the base frame and the marker's offset on the platform (taken off along the reference's
    rotation)."""
    note = registration.words()
    if measured.rotations_measured:
        return FrameFit("registration", note=note)
    X_BT = registration.X_TB.inverse()
    return FrameFit(
        "registration",
        X_BT.rotation().matrix(),
        X_BT.translation(),
        p_EM=registration.X_PM.translation(),
        note=note,
    )


def _first_fit(reference: Reference, t_ref, y, R_BT) -> FrameFit:
    """The frames the fine fit starts from: the coarse rotation ``R_BT`` (3, 3), the
    translation that puts the measured positions' centroid on the reference's, for a 6-DoF
    marker its axes' mean turn from the platform's; the marker at the platform's origin."""
    x_d = reference_poses(reference, t_ref)
    p_BT = x_d[:, 3:].mean(axis=0) - y[:, 3:].mean(axis=0) @ R_BT.T
    R_ME = np.eye(3)
    if np.all(np.isfinite(y[:, :3])):
        R_ME = (Rotation.from_matrix(R_BT) * _rotations(y)).inv() * _rotations(x_d)
        R_ME = R_ME.mean().as_matrix()
    return FrameFit("fit", R_BT, p_BT, R_ME, np.zeros(3))


def _check_length(reference: Reference, t: np.ndarray) -> None:
    """Refuse a recording shorter than one cycle of the reference (or a breath, without)."""
    from ..references.motion import reference_cycles

    span = float(t[-1] - t[0])
    period = getattr(reference, "repeat_period_s", None)
    end = getattr(reference, "end_time", None)
    if period is None:
        try:
            starts, _ = reference_cycles(
                reference, max(4 * span, 60.0) if end is None else float(end)
            )
            period = float(np.median(np.diff(starts)))
        except InvalidConfigError:
            period = MIN_SPAN_S
    if span < period:
        raise InvalidConfigError(
            f"the measured motion lasts {span:.3g} s, shorter than one cycle of "
            f"{getattr(reference, 'name', 'the reference')} ({period:.3g} s): record at least "
            f"two cycles"
        )


def _overlap(reference: Reference, t_ref: np.ndarray, margin: float) -> np.ndarray:
    """(n,) bool: the times t_ref (s, the reference's) inside its span, ``margin`` s in.

    Raises:
        InvalidConfigError: fewer than 10 such times (no overlap).
    """
    end = getattr(reference, "end_time", None)
    top = math.inf if end is None else float(end) - margin
    on = (t_ref >= margin) & (t_ref <= top)
    if np.count_nonzero(on) < 10:
        raise InvalidConfigError(
            f"once aligned, the measured motion spans t = {t_ref[0]:.4g}-{t_ref[-1]:.4g} s of "
            f"the reference's clock, which runs over 0-{'' if end is None else f'{end:.4g}'} s: "
            f"no overlap; check --clock-offset and that the file recorded this motion"
        )
    return on


def _frequencies(reference: Reference) -> dict:
    """The fundamentals of a reference that repeats ({} for one that does not)."""
    repeats = getattr(reference, "repeat_period_s", None) is not None
    frequencies = getattr(reference, "frequencies_hz", None)
    return frequencies() if repeats and callable(frequencies) else {}


def seconds(value: float) -> str:
    """A time in s as text: ``60.1 ms`` below a second, else ``1232 s`` (4 digits)."""
    return f"{value * 1e3:.4g} ms" if abs(value) < 1.0 else f"{value:.4g} s"


def _removed_words(d, offset, latency, clock, fit: FrameFit, resampled) -> list:
    """The report's lines on what the alignment removed: the clock, the frames, any
    resampling."""
    if clock == "not known":
        clock_line = (
            f"the clock: the measured motion shifted by {d:+.6g} s onto the reference's clock "
            f"(cross-correlation, then least squares). The clocks' relation was not given, so the "
            f"whole shift is reported as the latency ({seconds(latency)}) with clock offset "
            f"0: it holds any offset of the tracker's clock; give --clock-offset S (the measured "
            f"time + S = the reference's) to separate the phantom's own lag"
        )
    else:
        clock_line = (
            f"the clock: the measured motion shifted by {d:+.6g} s onto the reference's clock "
            f"(cross-correlation, then least squares): the clock offset {offset:+.6g} s ({clock}) "
            f"less the latency, {seconds(latency)} (> 0: the phantom late)"
        )
    lines = [clock_line, f"the frames: {fit.words()}"]
    if resampled:
        lines.append(resampled)
    return lines


def _outside_words(t_all, t_ref, window, holds_start: bool) -> list:
    """The report's line on the parts of the recording outside the figures (none if none)."""
    before = float(t_ref[0] - t_all[0])
    after = float(t_all[-1] - t_ref[-1])
    parts = []
    if before > 0 or after > 0:
        parts.append(
            f"{before:.3g} s of the recording before the reference's start and {after:.3g} s "
            f"after its end are not compared"
        )
    head = window[0] - t_ref[0]
    tail = t_ref[-1] - window[1]
    if head > 0 or tail > 0:
        what = "the motion's first cycle, the start-up" if holds_start else "part of a cycle"
        parts.append(
            f"the figures are over whole cycles, t = {window[0]:.4g}-{window[1]:.4g} s: "
            f"{head:.3g} s before ({what}) and {tail:.3g} s after are outside them"
        )
    return ["what the figures leave out: " + "; ".join(parts)] if parts else []


__all__ = [
    "ROTATION_WEIGHT_M",
    "MAX_LATENCY_S",
    "MAX_SEARCH_S",
    "MIN_SPAN_S",
    "COARSE_STEP_S",
    "MAX_JITTER",
    "FIT_PRIOR",
    "FIT_SAMPLES",
    "MeasuredMotion",
    "MEASURED_REMEDY",
    "read_measured",
    "encoder_motion",
    "reference_poses",
    "FrameFit",
    "coarse_shift",
    "MeasuredRun",
    "Verification",
    "seconds",
    "verify",
]
