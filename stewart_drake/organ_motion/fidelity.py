"""How faithfully the robot reproduces a motion: the metrics of a run against its reference, from
the true platform pose.

:func:`fidelity` measures a run against its reference over a window: RMS and peak error per axis
(um and urad, and as a fraction of each axis's peak-to-peak motion), the time lag (sub-sample, by
the package's one lag search), the amplitude and phase error at each harmonic of the breathing
and cardiac frequencies, and the error of every cycle; :func:`verdict` holds it against a tolerance
(:func:`parse_tolerance`). The run that is measured is :mod:`~.reproduction`'s
(``stewart-drake reproduce``), its report :mod:`~.fidelity_report`'s. The poses are the plant's
(the true platform), never the controller's estimate.
"""

from __future__ import annotations

import math

import numpy as np

from ..base.errors import InvalidConfigError
from ..base.measures import peak_per_axis, rms_per_axis, rms_translation_rotation
from ..base.units import length_and_angle
from ..base.verdicts import axes_within

AXES = ("phi", "theta", "psi", "X", "Y", "Z")
#: An axis moves when its reference's peak to peak exceeds this: 10 um or 50 urad.
MOVING_P2P = (5e-5, 5e-5, 5e-5, 1e-5, 1e-5, 1e-5)
#: A harmonic is reported when its reference amplitude exceeds this share of the axis's
#: peak to peak.
HARMONIC_SHARE = 0.01
#: Largest lag searched, s.
MAX_LAG_S = 0.1

#: The phantom anchor: a built 6-DOF Stewart motion phantom replaying recorded tumour motion
#: (Belcher et al., Med. Phys. 41, 121704, 2014): (axis, RMSE, range), mm and deg.
PHANTOM_ANCHOR = (
    ("X", 0.14, 20.0),
    ("Y", 0.22, 20.0),
    ("Z", 0.08, 10.0),
    ("phi", 0.16, 10.0),
    ("theta", 0.06, 10.0),
    ("psi", 0.08, 10.0),
)


#: The gamma criteria a report gives (distance m, time s): the commissioning figure of motion
#: phantoms (HexaMotion: > 98 % at 0.5 mm / 100 ms) and one a hundred times stricter in
#: distance and ten in time, which separates controllers that all pass the first.
GAMMA_CRITERIA = ((0.5e-3, 0.1), (5e-6, 0.01))


def gamma_pass_rate(t, p, p_d, distance_m: float, time_s: float) -> float:
    """Share of the samples whose gamma index (:func:`gamma_index`) is at most 1."""
    return float(np.mean(gamma_index(t, p, p_d, distance_m, time_s) <= 1.0))


def gamma_index(t, p, p_d, distance_m: float, time_s: float) -> np.ndarray:
    """The gamma index of each sample: gamma_i = min over the reference's
    samples j within ``time_s`` of t_i of sqrt((|p_i - p_d,j| / distance_m)^2 + ((t_i -
    t_j) / time_s)^2), the distance-to-agreement test of dosimetry applied to a motion trace in
    time and space (as motion-phantom commissioning reports it; e.g. 0.5 mm / 100 ms).

    Args:
        t: (n,) s, evenly spaced. p: (n, k) the positions reached, m (k = 3: the platform's
            X, Y, Z). p_d: (n, k) the reference at the same times.
        distance_m, time_s: the criteria, > 0.
    Returns:
        (n,) gamma_i >= 0 (a sample passes at most 1).
    Raises:
        InvalidConfigError: non-positive criteria, shapes that differ, fewer than 2 samples.
    """
    # p and p_d as given (float32 logs stay float32: the difference of two close floats is
    # exact), t in float64.
    t, p, p_d = np.asarray(t, dtype=float), np.asarray(p), np.asarray(p_d)
    if not (distance_m > 0 and time_s > 0):
        raise InvalidConfigError(f"gamma criteria must be > 0, got {distance_m} m, {time_s} s")
    if p.shape != p_d.shape or p.shape[0] != t.size or t.size < 2:
        raise InvalidConfigError(f"t {t.shape}, p {p.shape} and p_d {p_d.shape} must match")
    dt = float(np.median(np.diff(t)))
    # A shift of n samples or more leaves no sample to compare (and its slices would wrap).
    reach = min(int(np.floor(time_s / dt)), t.size - 1)
    best = np.full(t.size, np.inf)  # gamma^2
    for k in range(-reach, reach + 1):  # each time shift of the reference within time_s
        lo, hi = max(0, -k), min(t.size, t.size - k)
        d2 = np.sum((p[lo:hi] - p_d[lo + k : hi + k]) ** 2, axis=1) / distance_m**2
        np.minimum(best[lo:hi], d2 + (k * dt / time_s) ** 2, out=best[lo:hi])
    return np.sqrt(best)


def time_lag(
    t: np.ndarray,
    achieved: np.ndarray,
    reference: np.ndarray,
    max_lag_s: float = MAX_LAG_S,
    weights=None,
) -> float:
    """The delay of ``achieved`` behind ``reference`` (s, > 0: late), sub-sample: the package's
    one lag search (:func:`~stewart_drake.base.lag.signal_lag`: the shift of least RMS
    difference, each column less its mean difference, over the samples more than ``max_lag_s``
    from either end, every shift on the samples' grid by FFT, then to a microsecond). The
    columns are weighed by ``weights`` first, so that each counts by its weight and not by its
    size. Returns NaN for a reference that does not move, for fewer samples than three times
    ``max_lag_s`` holds (in steps, at least one: the search no wider than the samples it
    compares) or for fewer than two samples inside the search's margins.

    Args:
        t: (n,) increasing times, s. achieved, reference: (n,) or (n, c) signals (one lag for
            every column). weights: (c,) factors of the columns (default 1).
    Raises:
        InvalidConfigError: signals of another length than ``t`` or of different shapes.
    """
    from ..base.lag import inner_mask, signal_lag

    a, r = np.asarray(achieved, dtype=float), np.asarray(reference, dtype=float)
    if a.shape != r.shape or len(a) != len(t):
        raise InvalidConfigError(
            f"time_lag needs two signals of the same shape, one row per time: t has {len(t)}, "
            f"achieved {a.shape}, reference {r.shape}"
        )
    t = np.asarray(t, dtype=float)
    if len(t) < 3:  # no sample inside the margins of any search
        return math.nan
    steps = max(1, round(max_lag_s / float(np.median(np.diff(t)))))
    if len(t) < 3 * steps or np.count_nonzero(inner_mask(t, max_lag_s)) < 2:
        return math.nan
    w = np.ones(a.reshape(len(t), -1).shape[1]) if weights is None else np.asarray(weights, float)
    a, r = a.reshape(len(t), -1) * w, r.reshape(len(t), -1) * w
    return signal_lag(t, a, r, max_lag_s, offsets=True, min_samples=2)[0]


def harmonic_phasors(t: np.ndarray, signals: np.ndarray, frequencies_hz) -> np.ndarray:
    """Complex amplitudes of ``signals`` (n, c) at ``frequencies_hz`` (m,): the least-squares
    fit of a constant and a cosine and sine at each frequency, all at once, as amplitude
    e^(i phase) of cos(2 pi f t + phase); (m, c).

    Over a window of whole periods of every frequency this is the DFT at those bins (numpy's
    FFT gives the same numbers); the joint fit keeps them apart in any other window too.

    Raises:
        InvalidConfigError: a frequency or a time that is not finite.
    """
    t = np.asarray(t, dtype=float)
    f = np.asarray(frequencies_hz, dtype=float).reshape(-1)
    if not (np.isfinite(f).all() and np.isfinite(t).all()):
        raise InvalidConfigError(
            f"harmonic_phasors needs finite times and frequencies, got frequencies {f}"
        )
    arg = 2 * np.pi * (t - t[0])[:, None] * f
    design = np.hstack([np.ones((len(t), 1)), np.cos(arg), np.sin(arg)])
    y = np.asarray(signals, dtype=float).reshape(len(t), -1)
    coef = np.linalg.lstsq(design, y, rcond=None)[0]
    m = len(f)
    phasor = coef[1 : m + 1] - 1j * coef[m + 1 :]
    # The fit's phases are of t - t[0]: cos(2 pi f (t - t0) + p) = cos(2 pi f t + p - 2 pi f t0).
    return phasor * np.exp(-2j * np.pi * f[:, None] * t[0])


def _harmonics(t, x, x_d, frequencies: dict, moving, p2p, k_max: int):
    rows: list = []
    freqs = [
        (name, k, k * f0)
        for name, f0 in frequencies.items()
        for k in range(1, k_max + 1)
        if k * f0 < 0.25 / float(np.median(np.diff(t)))
    ]
    if not freqs:
        return rows
    F = [f for _, _, f in freqs]
    R = harmonic_phasors(t, x_d[:, moving], F)
    A = harmonic_phasors(t, x[:, moving], F)
    for (name, k, f), r_row, a_row in zip(freqs, R, A):
        for j, axis in enumerate(moving):
            if abs(r_row[j]) < HARMONIC_SHARE * p2p[axis]:
                continue
            rows.append(
                {
                    "source": name,
                    "k": k,
                    "f_hz": f,
                    "axis": AXES[axis],
                    "reference": float(abs(r_row[j])),
                    "amplitude_error": float(abs(a_row[j]) / abs(r_row[j]) - 1),
                    "phase_error_rad": float(np.angle(a_row[j] / r_row[j])),
                }
            )
    return rows


def _window_views(t, x, x_d, window) -> tuple:
    """(t, x, x_d, (tw, xw, rw)): the run's times and its poses and the reference's (the first
    6 columns), checked, and their views over ``window`` (see :func:`fidelity`).

    Raises:
        InvalidConfigError: shapes that differ, fewer than 10 samples in all or in the window.
    """
    # Views, not float64 copies: a long run's logs are float32 (RunResult) and the window a
    # slice; fidelity makes the error alone, in float32 (errors of microns to 7 digits; its sums
    # in float64).
    t, x, x_d = np.asarray(t, dtype=float), np.asarray(x), np.asarray(x_d)
    if x.ndim == 2 and x_d.ndim == 2:  # poses first: x and x_d may carry rates after them
        x, x_d = x[:, :6], x_d[:, :6]
    if x.ndim != 2 or x.shape != x_d.shape or x.shape[0] != t.size or t.ndim != 1:
        raise InvalidConfigError(f"t {t.shape}, x {x.shape} and x_d {x_d.shape} must match")
    if t.size < 10:  # the window's own test below reads t[0]
        raise InvalidConfigError(f"fewer than 10 samples ({t.size}): nothing to measure")
    t0, t1 = (t[0], t[-1]) if window is None else window
    i0 = int(np.searchsorted(t, t0 - 1e-9, side="left"))
    i1 = int(np.searchsorted(t, t1 + 1e-9, side="right"))
    if i1 - i0 < 10:
        raise InvalidConfigError(f"fewer than 10 samples in the window [{t0:g}, {t1:g}] s")
    tw, xw, rw = t[i0:i1], x[i0:i1], x_d[i0:i1]
    return t, x, x_d, (tw, xw, rw)


def _cycle_errors(t, x, x_d, cycle_starts) -> dict:
    """{"starts", "rms_translation_m", "rms_rotation_rad", "peak_translation_m", "rms"}: the
    error of each cycle between ``cycle_starts`` that lies inside the data (see
    :func:`fidelity`; ``rms`` a (6,) list per cycle, rad and m)."""
    cycles: dict[str, list] = {
        "starts": [],
        "rms": [],
        "rms_translation_m": [],
        "rms_rotation_rad": [],
        "peak_translation_m": [],
    }
    if cycle_starts is not None:
        starts = np.asarray(cycle_starts, dtype=float)
        for a, b in zip(starts[:-1], starts[1:]):
            c = (t >= a - 1e-9) & (t < b - 1e-9)
            if a < t[0] - 1e-9 or b > t[-1] + 2 * np.median(np.diff(t)) or np.count_nonzero(c) < 10:
                continue
            ec = np.subtract(x[c], x_d[c], dtype=float)
            ct, cr = rms_translation_rotation(ec)
            cycles["starts"].append(float(a))
            cycles["rms"].append(rms_per_axis(ec[:, :6]).tolist())
            cycles["rms_translation_m"].append(ct)
            cycles["rms_rotation_rad"].append(cr)
            cycles["peak_translation_m"].append(float(np.linalg.norm(ec[:, 3:], axis=1).max()))
    return cycles


def fidelity(
    t, x, x_d, window=None, frequencies: dict | None = None, cycle_starts=None, harmonics: int = 5
) -> dict:
    """Fidelity of a run over ``window``, from the true pose.

    Args:
        t: (n,) s, evenly spaced. x: (n, >= 6) the true pose [rad, m]. x_d: (n, >= 6) the
            reference at the same times.
        window: (t0, t1) s (default the whole run).
        frequencies: {"breathing": Hz, "cardiac": Hz} whose harmonics 1..``harmonics`` are
            analysed (None or {}: none; give them only for a window of whole periods of a motion
            that repeats: the fit assumes steady frequencies).
        cycle_starts: (K + 1,) cycle boundaries, s, for the per-cycle errors (cycles inside the
            data only).
    Returns:
        dict (JSON values): ``window_s``; ``moving`` (axis names whose reference moves more
        than :data:`MOVING_P2P`); per axis (6 lists, rad and m) ``rms``, ``peak``, ``p2p``,
        ``rms_fraction`` and ``peak_fraction`` (of the axis's peak to peak; NaN for an axis that
        does not move); ``rms_translation_m``, ``rms_rotation_rad`` (3-D: sqrt of the mean
        squared norm), ``peak_translation_m``, ``peak_rotation_rad``; ``lag_s`` {axis: s} per
        moving axis and ``lag_all_s`` (all moving axes together, weighted by their motion);
        ``gamma`` (rows: distance_m, time_s, pass_rate of the translation, per
        :data:`GAMMA_CRITERIA`, :func:`gamma_pass_rate`);
        ``harmonics`` (rows: source, k, f_hz, axis, reference amplitude, amplitude_error as a
        fraction, phase_error_rad, negative = late); ``cycles`` {"starts", "rms_translation_m",
        "rms_rotation_rad", "peak_translation_m", "rms" (per cycle, per axis)}.
    Raises:
        InvalidConfigError: fewer than 10 samples (in all, or in the window), or shapes that
            differ.
    """
    t, x, x_d, (tw, xw, rw) = _window_views(t, x, x_d, window)
    e = np.subtract(xw, rw, dtype=np.float32)
    p2p = np.ptp(rw, axis=0).astype(float)
    moving = [k for k in range(6) if p2p[k] > MOVING_P2P[k]]
    rms = rms_per_axis(e)
    peak = peak_per_axis(e)
    with np.errstate(divide="ignore", invalid="ignore"):
        frac = np.where(p2p > np.asarray(MOVING_P2P), rms / p2p, np.nan)
        peak_frac = np.where(p2p > np.asarray(MOVING_P2P), peak / p2p, np.nan)
    tr, rot = rms_translation_rotation(e)
    out = {
        "window_s": [float(tw[0]), float(tw[-1])],
        "moving": [AXES[k] for k in moving],
        "rms": rms.tolist(),
        "peak": peak.tolist(),
        "p2p": p2p.tolist(),
        "rms_fraction": frac.tolist(),
        "peak_fraction": peak_frac.tolist(),
        "rms_translation_m": tr,
        "rms_rotation_rad": rot,
        "peak_translation_m": float(np.linalg.norm(e[:, 3:], axis=1).max()),
        "peak_rotation_rad": float(np.linalg.norm(e[:, :3], axis=1).max()),
        "lag_s": {AXES[k]: time_lag(tw, xw[:, k], rw[:, k]) for k in moving},
        "gamma": [
            {
                "distance_m": d,
                "time_s": dt,
                "pass_rate": gamma_pass_rate(tw, xw[:, 3:], rw[:, 3:], d, dt),
            }
            for d, dt in GAMMA_CRITERIA
        ],
    }
    weights = np.array([1.0 / p2p[k] for k in moving])
    out["lag_all_s"] = (
        time_lag(tw, xw[:, moving], rw[:, moving], weights=weights) if moving else math.nan
    )
    out["harmonics"] = (
        _harmonics(tw, xw, rw, frequencies, moving, p2p, harmonics)
        if frequencies and moving
        else []
    )
    out["cycles"] = _cycle_errors(t, x, x_d, cycle_starts)
    return out


def startup_figures(t, x, x_d, end: float) -> dict:
    """The figures of a motion before ``end`` (s): {"window_s": (t[0], end),
    "rms_translation_m", "rms_rotation_rad", "peak_translation_m", "peak_rotation_rad"} of
    the errors x - x_d ((n, 6) poses at the times t (n,)); zeros when no sample is before it,
    NaN for a rotation not measured."""
    before = np.asarray(t) < end
    e = np.asarray(x[before, :6], dtype=float) - x_d[before, :6]
    rms = rms_translation_rotation(e) if len(e) else (0.0, 0.0)
    return {
        "window_s": (float(t[0]) if len(t) else 0.0, float(end)),
        "rms_translation_m": rms[0],
        "rms_rotation_rad": rms[1],
        "peak_translation_m": float(np.max(np.linalg.norm(e[:, 3:], axis=1), initial=0.0)),
        "peak_rotation_rad": float(np.max(np.linalg.norm(e[:, :3], axis=1), initial=0.0)),
    }


# -- tolerance -----------------------------------------------------------------------------------


#: The largest tolerance a verdict takes: (m, rad). A phantom's motion is centimetres and
#: degrees; a tolerance past a metre or half a turn judges nothing.
MAX_TOLERANCE = (1.0, math.pi)


def parse_tolerance(text: str, option: str = "--tolerance") -> tuple[float, float]:
    """(m, rad) of a tolerance "0.1mm,0.1deg" (lengths m, cm, mm, um; angles rad, mrad, urad,
    deg; either order; a unit as written there or all in capitals), by the one reader of a
    length with an angle (:func:`~stewart_drake.base.units.length_and_angle`).

    Raises:
        InvalidConfigError: naming ``option``: not one length and one angle, each a positive
            number with its unit, at most :data:`MAX_TOLERANCE`.
    """
    return length_and_angle(
        text,
        option,
        MAX_TOLERANCE,
        "at most 1 m and 180 deg (a tolerance past them judges nothing)",
    )


#: What a verdict compares when its caller does not say: a pose against its reference.
COMPARED = "the pose against its reference"


def tolerance_line(fid: dict, tolerance: tuple[float, float]) -> tuple[bool, str]:
    """(within, text): every axis's RMS error of ``fid`` (:func:`fidelity`) over its window
    within ``tolerance`` (translations in m, rotations in rad), and the text "RMS error per axis
    within|beyond <m> | <rad> over t = a-b s (largest: ...)" naming the largest of each kind;
    rotations that were not measured (NaN: a marker that gives positions only) are not judged,
    and the text says so. :func:`verdict` makes a verdict of it; a figure reported beside a
    verdict, which must not read as one, uses the text alone."""
    rms = np.asarray(fid["rms"], dtype=float)
    kt = 3 + int(np.argmax(rms[3:]))
    rotation = np.isfinite(rms[:3])
    bounds = [tolerance[1]] * 3 + [tolerance[0]] * 3
    ok = axes_within(rms, bounds, np.concatenate([rotation, [True] * 3]))
    largest = f"{AXES[kt]} {format_length(rms[kt])}, "
    if rotation.any():
        kr = int(np.argmax(np.where(rotation, rms[:3], -np.inf)))
        largest += f"{AXES[kr]} {format_angle(rms[kr])}"
    else:
        largest += "rotation not measured"
    w0, w1 = fid["window_s"]
    return bool(ok), (
        f"RMS error per axis {'within' if ok else 'beyond'} "
        f"{format_length(tolerance[0])} | {format_angle(tolerance[1])} "
        f"over t = {format_window(w0, w1)} s (largest: {largest})"
    )


def verdict(
    fid: dict, tolerance: tuple[float, float], compared: str | None = None
) -> tuple[bool, str]:
    """(passed, one line): "PASS|FAIL: <compared>, " then :func:`tolerance_line`'s text.

    Args:
        fid: :func:`fidelity`'s figures (``rms`` (6,) rad and m, ``window_s``).
        tolerance: (m, rad), the RMS error allowed per axis.
        compared: what ``fid`` compares, in words, e.g. "the robot's true pose against the true
            motion (breathing)": a verdict names what it judged, so that a PASS is never read
            as one on something else (default :data:`COMPARED`).
    Returns:
        (passed, line): passed from the figures of ``fid`` only."""
    ok, text = tolerance_line(fid, tolerance)
    return ok, f"{'PASS' if ok else 'FAIL'}: {compared or COMPARED}, {text}"


def format_length(v: float) -> str:
    """A length in m as text: "0.123 mm" from 0.1 mm up, else "12.3 um" (3 digits)."""
    return f"{v * 1e3:.3g} mm" if v >= 1e-4 else f"{v * 1e6:.3g} um"


def format_angle(v: float) -> str:
    """An angle in rad as text: "0.123 deg" from 1 mrad up, else "123 urad" (3 digits)."""
    return f"{math.degrees(v):.3g} deg" if v >= 1e-3 else f"{v * 1e6:.3g} urad"


def format_window(t0: float, t1: float) -> str:
    """A window of time as text, "t0-t1" (s; the unit is the caller's to write; "t0 to t1"
    when an end is negative): each end with the decimals that show the window's length to 4
    significant digits, trailing zeros left out ("4-19.98"); for times far from zero (a
    tracker's clock since it booted) every digit before the point too ("259200-259230.5"), not
    "2.592e+05-2.592e+05"."""
    span = abs(t1 - t0)
    decimals = max(0, 3 - math.floor(math.log10(span))) if span > 0 else 3

    def end(t: float) -> str:
        text = f"{t:.{decimals}f}"
        if "." in text:
            text = text.rstrip("0").rstrip(".")
        return "0" if text == "-0" else text

    a, b = end(t0), end(t1)
    return f"{a} to {b}" if a.startswith("-") or b.startswith("-") else f"{a}-{b}"


__all__ = [
    "AXES",
    "MOVING_P2P",
    "HARMONIC_SHARE",
    "MAX_LAG_S",
    "PHANTOM_ANCHOR",
    "GAMMA_CRITERIA",
    "rms_translation_rotation",
    "gamma_pass_rate",
    "gamma_index",
    "time_lag",
    "harmonic_phasors",
    "fidelity",
    "startup_figures",
    "parse_tolerance",
    "COMPARED",
    "tolerance_line",
    "verdict",
    "format_length",
    "format_angle",
]
