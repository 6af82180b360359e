"""How faithfully the robot reproduces a motion: metrics from the true platform pose, the
``stewart-drake reproduce`` run and its report.

:func:`fidelity` measures a run against its reference over a window: RMS and peak error per axis
(um and urad, and as a fraction of each axis's peak-to-peak motion), the time lag (sub-sample, by
cross-correlation), the amplitude and phase error at each harmonic of the breathing and cardiac
frequencies, and the error of every cycle. :func:`reproduce` checks a motion against the robot
(the one validator, :func:`~stewart_drake.run.plan.check_reference`), shrinks it on
request, runs the robot as built with or without learning, and measures it;
:func:`write_report` writes the Markdown report and its one PNG with a verdict against a
tolerance. The poses are the plant's (the true platform), never the controller's estimate.
"""

from __future__ import annotations

import json
import math
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from ..base.errors import InvalidConfigError
from ..base.fileio import atomic_write
from ..references.motion import Reference

if TYPE_CHECKING:  # for the annotation only: the functions import experiments when they run
    from ..run.result import RunResult

AXES = ("phi", "theta", "psi", "X", "Y", "Z")
#: An axis moves when its reference's peak to peak exceeds this: 10 um or 50 urad.
MOVING_P2P = (5e-5, 5e-5, 5e-5, 1e-5, 1e-5, 1e-5)
#: A harmonic is reported when its reference amplitude exceeds this share of the axis's
#: peak to peak.
HARMONIC_SHARE = 0.01
#: Largest lag searched by the cross-correlation, s.
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


def rms_translation_rotation(e: np.ndarray) -> tuple[float, float]:
    """(sqrt(mean |e_XYZ|^2) m, sqrt(mean |e_rpy|^2) rad) of pose errors (n, 6)."""
    e = np.asarray(e)  # float32 or float64 as given; the sums in float64
    return (
        float(np.sqrt(np.mean(np.sum(np.square(e[:, 3:]), axis=1, dtype=float)))),
        float(np.sqrt(np.mean(np.sum(np.square(e[:, :3]), axis=1, dtype=float)))),
    )


#: The gamma criteria a report gives (distance m, time s): the commissioning figure of motion
#: phantoms (HexaMotion: > 98 % at 0.5 mm / 100 ms) and one a hundred times stricter in
#: distance and ten in time, which separates controllers that all pass the first.
GAMMA_CRITERIA = ((0.5e-3, 0.1), (5e-6, 0.01))


def gamma_pass_rate(t, p, p_d, distance_m: float, time_s: float) -> float:
    """Share of the samples whose gamma index is at most 1: gamma_i = min over the reference's
    samples j within ``time_s`` of t_i of sqrt((|p_i - p_d,j| / distance_m)^2 + ((t_i -
    t_j) / time_s)^2), the distance-to-agreement test of dosimetry applied to a motion trace in
    time and space (as motion-phantom commissioning reports it; e.g. 0.5 mm / 100 ms).

    Args:
        t: (n,) s, evenly spaced. p: (n, k) the positions reached, m (k = 3: the platform's
            X, Y, Z). p_d: (n, k) the reference at the same times.
        distance_m, time_s: the criteria, > 0.
    Returns:
        the pass rate in [0, 1].
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
    reach = int(np.floor(time_s / dt))
    best = np.full(t.size, np.inf)  # gamma^2
    for k in range(-reach, reach + 1):  # each time shift of the reference within time_s
        lo, hi = max(0, -k), min(t.size, t.size - k)
        d2 = np.sum((p[lo:hi] - p_d[lo + k : hi + k]) ** 2, axis=1) / distance_m**2
        np.minimum(best[lo:hi], d2 + (k * dt / time_s) ** 2, out=best[lo:hi])
    return float(np.mean(best <= 1.0))


def time_lag(
    t: np.ndarray,
    achieved: np.ndarray,
    reference: np.ndarray,
    max_lag_s: float = MAX_LAG_S,
    weights=None,
) -> float:
    """The delay of ``achieved`` behind ``reference`` (s, > 0: late), sub-sample.

    The cross-correlation of the two (means removed; ``scipy.signal.correlate``) peaks at the
    delay. The inner part of ``achieved`` (all but ``max_lag_s`` at each end) is correlated
    with the whole reference, so every lag sums the same samples of it, and each lag's sum is
    divided by the norm of the reference's samples it met (Cauchy-Schwarz: the peak is then
    where the two match): an overlap or a norm that changed with the lag would tilt the broad
    peak of a slow motion by far more than a sample. A parabola
    through the peak and its two neighbours places it between samples. Returns NaN for a
    reference that does not move or a window shorter than three times ``max_lag_s``.

    Args:
        t: (n,) evenly spaced times, s. achieved, reference: (n,) or (n, c) signals (columns
            summed in the correlation: one lag for several axes). weights: (c,) factors of the
            columns (default 1).
    Raises:
        InvalidConfigError: signals of another length than ``t`` or of different shapes.
    """
    from scipy.signal import correlate

    a, r = np.asarray(achieved), np.asarray(reference)
    if a.shape != r.shape or len(a) != len(t):
        raise InvalidConfigError(
            f"time_lag needs two signals of the same shape, one row per time: t has {len(t)}, "
            f"achieved {a.shape}, reference {r.shape}"
        )
    a, r = a.reshape(len(t), -1), r.reshape(len(t), -1)
    w = np.ones(a.shape[1]) if weights is None else np.asarray(weights, dtype=float)
    dt = float(np.median(np.diff(t)))
    L = max(1, int(round(max_lag_s / dt)))
    # A column at a time, in float64 (a long run's intermediates are (n,) vectors), by direct
    # sums over the 2 L + 1 lags (no FFT buffers of twice the run's length, and faster).
    c, r2, moves = np.zeros(2 * L + 1), np.zeros(len(t)), False
    for k in range(a.shape[1]):
        rk = np.asarray(r[:, k], dtype=float) * w[k]
        rk -= rk.mean()
        ak = np.asarray(a[:, k], dtype=float) * w[k]
        ak -= ak.mean()
        moves = moves or bool(np.any(rk))
        if len(t) >= 3 * L:
            c += correlate(rk, ak[L : len(t) - L], mode="valid", method="direct")
            r2 += rk * rk  # c[j]: achieved late by L - j
    if not moves or len(t) < 3 * L:
        return math.nan
    energy = correlate(r2, np.ones(len(t) - 2 * L), mode="valid", method="direct")
    c = c / np.sqrt(np.maximum(energy, 1e-300))  # the reference's part that was summed
    k = int(np.argmax(c))
    delta = 0.0
    if 0 < k < len(c) - 1:
        den = c[k - 1] - 2 * c[k] + c[k + 1]
        if den < 0:
            delta = 0.5 * (c[k - 1] - c[k + 1]) / den
    return float((L - k - delta) * dt)


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
    return phasor * np.exp(2j * np.pi * f[:, None] * t[0])


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
        "rms_rotation_rad", "peak_translation_m"}.
    Raises:
        InvalidConfigError: fewer than 10 samples (in all, or in the window), or shapes that
            differ.
    """
    # Views, not float64 copies: a long run's logs are float32 (RunResult) and the window a
    # slice; the error alone is made, in float32 (errors of microns to 7 digits; the sums below
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
    e = np.subtract(xw, rw, dtype=np.float32)
    p2p = np.ptp(rw, axis=0).astype(float)
    moving = [k for k in range(6) if p2p[k] > MOVING_P2P[k]]
    rms = np.sqrt(np.mean(np.square(e), axis=0, dtype=float))
    peak = np.abs(e).max(axis=0).astype(float)
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
    cycles: dict[str, list] = {
        "starts": [],
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
            cycles["rms_translation_m"].append(ct)
            cycles["rms_rotation_rad"].append(cr)
            cycles["peak_translation_m"].append(float(np.linalg.norm(ec[:, 3:], axis=1).max()))
    out["cycles"] = cycles
    return out


# -- tolerance -----------------------------------------------------------------------------------


def parse_tolerance(text: str) -> tuple[float, float]:
    """(m, rad) of a tolerance "0.1mm,0.1deg" (lengths m, cm, mm, um; angles rad, mrad, urad,
    deg; either order).

    Raises:
        InvalidConfigError: not one length and one angle, each a positive number with its unit.
    """
    from ..references.organ_motion import UNITS

    found = {}
    for part in str(text).split(","):
        m = re.fullmatch(r"\s*((?:\d+(?:\.\d*)?|\.\d+)(?:[eE][-+]?\d+)?)\s*([a-zA-Z]+)\s*", part)
        unit = m.group(2).lower() if m else ""
        kind = next((k for k in ("m", "rad") if unit in UNITS[k]), None)
        value = float(m.group(1)) if m else math.nan
        if kind is None or kind in found or not 0 < value < math.inf:
            raise InvalidConfigError(
                f"a tolerance is one length and one angle, each a finite positive number with "
                f"its unit, e.g. 0.1mm,0.1deg; got {text!r}"
            )
        found[kind] = value * UNITS[kind][unit]
    if len(found) != 2:
        raise InvalidConfigError(
            f"a tolerance is one length and one angle, e.g. 0.1mm,0.1deg; got {text!r}"
        )
    return found["m"], found["rad"]


def verdict(fid: dict, tolerance: tuple[float, float]) -> tuple[bool, str]:
    """(passed, one line): every axis's RMS error over the window within the tolerance
    (translations in m, rotations in rad), naming the largest of each kind."""
    rms = np.asarray(fid["rms"])
    kt, kr = 3 + int(np.argmax(rms[3:])), int(np.argmax(rms[:3]))
    ok = rms[3:].max() <= tolerance[0] and rms[:3].max() <= tolerance[1]
    w0, w1 = fid["window_s"]
    return ok, (
        f"{'PASS' if ok else 'FAIL'}: RMS error per axis {'within' if ok else 'beyond'} "
        f"{_length(tolerance[0])} | {_angle(tolerance[1])} over t = {w0:.4g}-{w1:.4g} s "
        f"(largest: {AXES[kt]} {_length(rms[kt])}, {AXES[kr]} {_angle(rms[kr])})"
    )


def _length(v: float) -> str:
    return f"{v * 1e3:.3g} mm" if v >= 1e-4 else f"{v * 1e6:.3g} um"


def _angle(v: float) -> str:
    return f"{math.degrees(v):.3g} deg" if v >= 1e-3 else f"{v * 1e6:.3g} urad"


# -- a reproduction ----------------------------------------------------------------------------


@dataclass
class Reproduction:
    """A motion reproduced by the robot and measured (:func:`reproduce`).

    Attributes:
        name: the motion's name. reference: the reference run (scaled when it had to be).
        scale: the scale applied to fit the robot (1: as given).
        result: the :class:`~.result.RunResult` (true pose, reference, torques).
        cycle_starts: (K + 1,) the cycles of the run, s (empty for a reference without).
        learn_cycles: cycles learned from (0: no learning).
        fidelity: :func:`fidelity` over the evaluation window (the last ``eval_cycles``).
        learner: (n, k) the learner's status log, or None; its columns are
            ``learner_names`` (:data:`~stewart_drake.control.ilc.ILC_STATUS_NAMES` or
            :data:`~stewart_drake.control.feedforward_tuning.FF_STATUS_NAMES`).
        learned: (p, 6) the weights a feed-forward learner ended with (for
            :func:`~stewart_drake.control.feedforward_tuning.save_learned`), or None.
        check: the validator's summary of the reference. wall_s: wall time of the run, s.
        learning: how the run learned, in words (:func:`learning_words`).
        learned_from: the model file a feed-forward learner started from or held, or "".
    """

    name: str
    reference: Reference
    scale: float
    result: RunResult
    cycle_starts: np.ndarray
    learn_cycles: int
    fidelity: dict
    learner: np.ndarray | None = None
    learner_names: tuple = ()
    learned: np.ndarray | None = None
    check: str = ""
    wall_s: float = 0.0
    notes: list = field(default_factory=list)
    learning: str = ""
    learned_from: str = ""


def learning_words(learning, learn_cycles: int = 0) -> str:
    """How a run with the scenario's ``learning`` learns, in words for a report: "no learning",
    "learning from N cycles, then held" (per cycle), "feed-forward learned over the run",
    "feed-forward started from <file>, learning over the run" or "feed-forward <file> held,
    not learning"."""
    from ..control.feedforward_tuning import FeedforwardTuning

    if isinstance(learning, FeedforwardTuning):
        model = Path(learning.learned_from).name
        if not learning.learned_from:
            return "feed-forward learned over the run"
        if learning.learn:
            return f"feed-forward started from {model}, learning over the run"
        return f"feed-forward {model} held, not learning"
    if learn_cycles:
        return f"learning from {learn_cycles} cycles, then held"
    return "no learning"


def scale_to_fit(scenario, reference: Reference, tol: float = 0.005) -> tuple[Reference, float]:
    """The largest scale in (0, 1] at which ``reference``, shrunk about its centre
    (:class:`~stewart_drake.references.organ_motion.ScaledReference`), passes every check of
    :func:`~stewart_drake.run.plan.check_reference` on the
    scenario's robot (reach, joint limits, singularity, clearance, motor torque and speed), by
    bisection to within ``tol``.

    Returns:
        (reference, scale): the reference itself and 1.0 when it passes as it is.
    Raises:
        InvalidConfigError: not even a scale of ``tol`` passes (the centre itself is refused:
            move it).
    """
    from ..references.organ_motion import ScaledReference
    from ..run.plan import check_reference, make_plan

    plan = make_plan(scenario, with_reference=False)

    def fits(s: float) -> bool:
        candidate = reference if s == 1.0 else ScaledReference(reference, s)
        try:
            report = check_reference(plan, candidate, raise_refused=False)
        except Exception:  # noqa: BLE001 - unreachable poses raise even when reporting
            return False
        return report.ok

    if fits(1.0):
        return reference, 1.0
    lo, hi = 0.0, 1.0
    while hi - lo > tol:
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if fits(mid) else (lo, mid)
    if lo < tol:
        raise InvalidConfigError(
            f"{getattr(reference, 'name', 'the reference')} cannot be "
            f"scaled to fit: even at {tol:g} of its size a check refuses "
            f"it; move its centre"
        )
    return ScaledReference(reference, lo), lo


_fit = scale_to_fit  # reproduce's argument of that name is a flag


def run(
    scenario, reference: Reference, progress: bool = False, desc: str = "simulating", report=None
):
    """Simulate ``scenario`` on ``reference`` (checked first unless its check's ``report`` is
    given, guarded): (:class:`~.result.RunResult`, the learner's status log (n + 1, k) or
    None, wall s, the learned weights (p, 6) of a feed-forward learner at the end or None).

    The learner's log has a row at each of the result's ``t_state`` (every
    ``state_log_period_s``) and ends with its state at the end of the run (the loggers' last
    sample is one period earlier: the update of a cycle's last sample would otherwise be
    missing)."""
    from ..run.result import finish_result, release_reference
    from ..run.simulate import build_simulator, simulate

    # A reproduction reads the pose, the torques and the status, not the controller's integral
    # or error estimate: a 25-minute trace is 72 MB lighter without them.
    sd, simulator = build_simulator(
        scenario, reference=reference, progress=progress, report=report, controller_logs=False
    )
    logs, wall = simulate(sd, simulator, progress, desc)
    learner = learned = None
    if sd.learner is not None:
        context = simulator.get_context()
        learner_context = sd.learner.GetMyContextFromRoot(context)
        log = sd.loggers[sd.learner.status_port].FindLog(context).data().T
        final = sd.learner.GetOutputPort(sd.learner.status_port).Eval(learner_context)
        learner = np.vstack([log, final])
        if sd.learner.HasOutputPort("theta"):
            theta = sd.learner.GetOutputPort("theta").Eval(learner_context)
            learned = np.asarray(theta).reshape(-1, 6)
    release_reference(sd)
    result = finish_result(logs, wall)
    return result, learner, wall, learned


def run_cycles(reference: Reference, learn_cycles: int, eval_cycles: int) -> int:
    """Cycles a reproduction runs: the learned ones (or one to settle without learning) and
    then the evaluated ones."""
    return max(learn_cycles, 1) + eval_cycles


def _check_counts(learn_cycles, eval_cycles) -> None:
    """Refuse cycle counts that are not integers >= 0, and no cycle to measure."""
    for name, value in (("learn_cycles", learn_cycles), ("eval_cycles", eval_cycles)):
        if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 0:
            raise InvalidConfigError(f"{name} must be an integer >= 0, got {value!r}")
    if eval_cycles < 1:
        raise InvalidConfigError("eval_cycles must be at least 1")


#: The longest run of a library motion reproduce makes, s: its cycles are counted over this
#: time.
MAX_REPRODUCE_S = 3600.0


def _reference_starts(reference: Reference, learn_cycles: int) -> np.ndarray:
    """(K + 1,) the starts of the reference's cycles over its length (or
    :data:`MAX_REPRODUCE_S`), s; empty for a reference without cycles, which only a run without
    learning accepts."""
    from ..references.motion import reference_cycles

    end = getattr(reference, "end_time", None)
    try:
        starts, _ = reference_cycles(reference, end if end is not None else MAX_REPRODUCE_S)
    except InvalidConfigError:
        if learn_cycles:
            raise
        starts = np.zeros(0)
    return starts


def _set_duration(
    scenario, reference, starts, learn_cycles: int, eval_cycles: int, duration_s: float | None
) -> bool:
    """True when a recorded trace runs whole (without learning); sets the scenario's
    ``duration_s``, s: the trace's length (at most), :func:`run_cycles` cycles or
    ``duration_s``."""
    name = getattr(reference, "name", "reference")
    end = getattr(reference, "end_time", None)
    total = run_cycles(reference, learn_cycles, eval_cycles)
    whole = end is not None and not learn_cycles  # a recorded trace: all of it
    if not whole and starts.size > 0 and duration_s is not None:
        raise InvalidConfigError(
            f"{name} runs whole cycles ({total} asked for): set the number of cycles, not a "
            f"duration (a duration is for a trace run whole or a reference without cycles)"
        )
    if not whole and end is None and 0 < starts.size <= total:
        raise InvalidConfigError(
            f"{total} cycles of {name} asked for; it gives {starts.size - 1} whole cycles in "
            f"{MAX_REPRODUCE_S:g} s, the longest run reproduce makes: ask for fewer cycles"
        )
    if whole and end is not None:
        scenario.duration_s = float(min(duration_s or end, end))
    elif starts.size > total:
        scenario.duration_s = float(starts[total])
    else:
        scenario.duration_s = float(duration_s or end or scenario.duration_s)
        if learn_cycles and starts.size <= learn_cycles + 1:
            raise InvalidConfigError(
                f"{name} holds {max(starts.size - 1, 0)} cycles: too few to "
                f"learn from {learn_cycles} and measure one more"
            )
    return whole


def _set_learning(scenario, learn_cycles: int) -> None:
    """Make the scenario learn from ``learn_cycles`` cycles (its ``learning`` or the default
    :class:`~stewart_drake.run.scenario.IlcDriver`), or not at all (0)."""
    from ..control.ilc import IlcDriver

    if learn_cycles:
        driver = scenario.learning or IlcDriver()
        driver.learn_cycles = learn_cycles
        scenario.learning = driver
    else:
        scenario.learning = None


def _status_names(learning) -> tuple:
    """The columns of the status log of the learner ``learning`` chooses (() for none)."""
    from ..control.feedforward_tuning import FF_STATUS_NAMES, FeedforwardTuning
    from ..control.ilc import ILC_STATUS_NAMES

    if learning is None:
        return ()
    return FF_STATUS_NAMES if isinstance(learning, FeedforwardTuning) else ILC_STATUS_NAMES


def _feedforward_line(last: dict) -> str:
    """The report's line on a feed-forward learner, from its last status."""
    return (
        f"Learner (feed-forward as a function of the reference): {int(last['updates'])} "
        f"update(s) over {int(last['stretch'])} stretch(es), {int(last['rollbacks'])} "
        f"rollback(s){', stopped by its bound' if last['stopped'] else ''}; last stretch "
        f"{last['E_trans_m'] * 1e6:.3g} um / {last['E_rot_rad'] * 1e6:.3g} urad measured by the "
        f"encoders, {last['D_trans_m'] * 1e6:.3g} um / {last['D_rot_rad'] * 1e6:.3g} urad "
        f"estimated without the correction."
    )


def _measured_window(starts, duration: float, whole: bool, eval_cycles: int) -> tuple[float, float]:
    """(start, end) of the window measured, s: after a whole trace's first cycle (or tenth), or
    the last ``eval_cycles`` cycles (the last nine tenths of a run without them)."""
    if whole:  # after the first cycle (or tenth) to the end
        return (starts[1] if starts.size > 2 else 0.1 * duration, duration)
    if starts.size > eval_cycles:
        return (starts[-eval_cycles - 1], starts[-1])
    return (0.1 * duration, duration)


def _harmonic_frequencies(reference: Reference) -> dict:
    """{"breathing": Hz, "cardiac": Hz}: the fundamentals whose harmonics :func:`fidelity`
    analyses, those of a reference that repeats ({} for one that does not)."""
    repeats = getattr(reference, "repeat_period_s", None) is not None
    frequencies = getattr(reference, "frequencies_hz", None)
    return frequencies() if repeats and callable(frequencies) else {}


def reproduce(
    scenario,
    reference=None,
    learn_cycles: int = 0,
    eval_cycles: int = 2,
    scale_to_fit: bool = False,
    duration_s: float | None = None,
    progress: bool = False,
    feedforward=None,
    on_checked=None,
) -> Reproduction:
    """Check a motion against the robot, run it, measure it.

    The run lasts :func:`run_cycles` cycles of the reference and is measured over the last
    ``eval_cycles``; a recorded trace (a reference with an ``end_time``) runs whole (or
    ``duration_s``) without learning and is measured after its first cycle (its first tenth when
    it has no cycles). Before anything is simulated the one validator checks reach, joint limits,
    singularity, clearance and each motor's torque and speed over the whole run
    (:func:`~stewart_drake.run.plan.check_reference`); a reference it refuses raises
    that refusal (which names what is over and when), or, with ``scale_to_fit``, is shrunk
    about its centre until it passes (:func:`scale_to_fit`).
    With ``learn_cycles`` the scenario learns (its ``learning`` or the default
    :class:`~stewart_drake.run.scenario.IlcDriver`) from that many cycles, then holds
    the correction through the evaluated cycles. With ``feedforward`` it learns a correction as
    a function of the reference over the whole run instead
    (:class:`~stewart_drake.control.feedforward_tuning.FeedforwardTuning`: any motion, a trace
    without cycles included; a trace runs whole, a motion with cycles ``learn_cycles`` +
    ``eval_cycles`` of them).

    Args:
        scenario: the robot and its controller (changed in place: duration, learning,
            divergence folder as given).
        reference: the motion (default the scenario's).
        learn_cycles: cycles to learn from (0: none). eval_cycles: cycles measured after.
        scale_to_fit: shrink a refused motion instead of refusing it.
        duration_s: length of a run on a reference without cycles, s.
        feedforward: a :class:`~stewart_drake.control.feedforward_tuning.FeedforwardTuning`
            to learn with, or None.
        on_checked: called (no arguments) once every check passed, before the run is built.
    Returns:
        :class:`Reproduction`.
    Raises:
        UnreachablePoseError, JointLimitError, SingularPoseError, InterferenceError,
        MotorLimitError: the validator's refusal (without ``scale_to_fit``).
        InvalidConfigError: learning on a reference that does not repeat, a bad count, a run
            that needs more memory than the machine has (checked before the reference is).
        SimulationDivergedError: the guard stopped the run.
    """
    from ..references.trajectories import as_trajectory
    from ..run.plan import check_reference_shown, check_run_memory, make_plan

    _check_counts(learn_cycles, eval_cycles)
    reference = as_trajectory(reference) if reference is not None else make_plan(scenario).reference
    name = getattr(reference, "name", "reference")
    starts = _reference_starts(reference, learn_cycles if feedforward is None else 0)
    whole = _set_duration(scenario, reference, starts, learn_cycles, eval_cycles, duration_s)
    if feedforward is None:
        _set_learning(scenario, learn_cycles)
    else:
        scenario.learning = feedforward
    check_run_memory(scenario)  # before the reference is checked at every control period
    plan = make_plan(scenario, reference=reference)  # validated once, here
    scale = 1.0
    if scale_to_fit:
        reference, scale = _fit(plan, reference)
    report = check_reference_shown(plan, reference, progress, keep_series=False)
    if on_checked is not None:
        on_checked()
    result, learner, wall, learned = run(plan, reference, progress, f"reproducing {name}", report)
    starts = starts[starts <= scenario.duration_s + 1e-9]
    window = _measured_window(starts, scenario.duration_s, whole, eval_cycles)
    freq = _harmonic_frequencies(reference)
    fid = fidelity(result.t, result.x, result.x_d, window, freq, starts)
    return Reproduction(
        name=name,
        reference=reference,
        scale=scale,
        result=result,
        cycle_starts=starts,
        learn_cycles=learn_cycles,
        fidelity=fid,
        learner=learner,
        learner_names=_status_names(scenario.learning),
        learned=learned,
        check=report.summary(),
        wall_s=wall,
        learning=learning_words(scenario.learning, learn_cycles),
        learned_from=str(getattr(scenario.learning, "learned_from", "") or ""),
    )


# -- the report ----------------------------------------------------------------------------------


def _learning(rep) -> str:
    """How ``rep``'s run learned, in words (a record without ``learning``: from its
    ``learn_cycles``)."""
    return getattr(rep, "learning", "") or learning_words(None, rep.learn_cycles)


def report_markdown(rep: Reproduction, tolerance: tuple[float, float]) -> str:
    """The Markdown report of a reproduction: verdict, per-axis table, lag, harmonics, cycles,
    the learner, the phantom anchor."""
    fid = rep.fidelity
    ok, line = verdict(fid, tolerance)
    units = ["urad"] * 3 + ["um"] * 3
    lines = [f"# Fidelity of {rep.name}", "", f"**{line}**", ""]
    lines.append(
        f"Run: {rep.result.t[-1]:.4g} s on the robot as built "
        f"({rep.result.config_summary.get('controller', '')}, "
        + _learning(rep)
        + f"); measured over t = {fid['window_s'][0]:.4g}-"
        f"{fid['window_s'][1]:.4g} s from the true platform pose; wall time "
        f"{rep.wall_s:.0f} s."
    )
    if getattr(rep, "learned_from", ""):
        lines += ["", f"Feed-forward model: {rep.learned_from}."]
    if rep.scale != 1.0:
        lines.append(
            f"The motion was scaled by {rep.scale:.3f} about its centre to fit the "
            f"robot (--scale-to-fit)."
        )
    source = rep.reference
    info = getattr(source, "info", None) or getattr(
        getattr(source, "reference", None), "info", None
    )
    if info is not None:  # a recorded trace: what was read, and how
        lines += ["", f"Trace: {info.summary()}."]
    lines += [
        "",
        "| axis | p2p motion | RMS error | peak error | RMS / p2p | lag [ms] |",
        "|---|---|---|---|---|---|",
    ]
    for k, axis in enumerate(AXES):
        scale, unit = (1e3, "mm") if k >= 3 else (180 / math.pi, "deg")
        lag = fid["lag_s"].get(axis)
        frac = fid["rms_fraction"][k]
        lines.append(
            f"| {axis} | {fid['p2p'][k] * scale:.4g} {unit} | "
            f"{fid['rms'][k] * 1e6:.3g} {units[k]} | "
            f"{fid['peak'][k] * 1e6:.3g} {units[k]} | "
            f"{'-' if not np.isfinite(frac) else f'{100 * frac:.3g} %'} | "
            f"{'-' if lag is None else f'{1e3 * lag:.3g}'} |"
        )
    lines += [
        "",
        f"3-D RMS error: translation {fid['rms_translation_m'] * 1e6:.3g} um, rotation "
        f"{fid['rms_rotation_rad'] * 1e6:.3g} urad (peaks "
        f"{fid['peak_translation_m'] * 1e6:.3g} um, "
        f"{fid['peak_rotation_rad'] * 1e6:.3g} urad); lag of the whole motion "
        f"{1e3 * fid['lag_all_s']:.3g} ms (cross-correlation, > 0: late).",
    ]
    if fid.get("gamma"):
        lines += [
            "",
            "Gamma pass rate of the translation (distance to agreement in space and time, as "
            "motion phantoms are commissioned): "
            + ", ".join(
                f"{100 * g['pass_rate']:.4g} % at {g['distance_m'] * 1e3:g} mm / "
                f"{g['time_s'] * 1e3:g} ms"
                for g in fid["gamma"]
            )
            + ".",
        ]
    if fid["harmonics"]:
        lines += [
            "",
            "| harmonic | f [Hz] | axis | reference amplitude | amplitude error | "
            "phase error [deg] |",
            "|---|---|---|---|---|---|",
        ]
        for h in fid["harmonics"]:
            k = AXES.index(h["axis"])
            amp = h["reference"] * (1e3 if k >= 3 else 180 / math.pi)
            lines.append(
                f"| {h['source']} {h['k']} | {h['f_hz']:.4g} | {h['axis']} | "
                f"{amp:.4g} {'mm' if k >= 3 else 'deg'} | "
                f"{100 * h['amplitude_error']:+.3g} % | "
                f"{math.degrees(h['phase_error_rad']):+.3g} |"
            )
    cyc = fid["cycles"]
    if cyc["starts"]:
        lines += [
            "",
            "Error per cycle (RMS, translation um | rotation urad): "
            + ", ".join(
                f"{j}: {a * 1e6:.3g} | {b * 1e6:.3g}"
                for j, (a, b) in enumerate(zip(cyc["rms_translation_m"], cyc["rms_rotation_rad"]))
            ),
        ]
    if rep.learner is not None and "updates" in rep.learner_names:
        lines += ["", _feedforward_line(dict(zip(rep.learner_names, rep.learner[-1])))]
    elif rep.learner is not None:
        last = dict(zip(rep.learner_names, rep.learner[-1]))
        lines += [
            "",
            f"Learner: learned from {int(last['learned_cycles'])} cycles, "
            f"{int(last['rollbacks'])} rollback(s)"
            + (", stopped by its bound" if last["stopped"] else "")
            + ".",
        ]
    lines += [
        "",
        "Phantom anchor (Belcher et al., Med. Phys. 41, 121704, 2014, a built 6-DOF "
        "Stewart motion phantom replaying recorded tumour motion):",
        "",
        "| axis | phantom RMSE | phantom range | phantom RMSE / range | here RMS / p2p |",
        "|---|---|---|---|---|",
    ]
    for axis, rmse, rng in PHANTOM_ANCHOR:
        k = AXES.index(axis)
        unit = "mm" if k >= 3 else "deg"
        frac = fid["rms_fraction"][k]
        lines.append(
            f"| {axis} | {rmse:g} {unit} | {rng:g} {unit} | {100 * rmse / rng:.2g} % | "
            f"{'-' if not np.isfinite(frac) else f'{100 * frac:.2g} %'} |"
        )
    lines += ["", "Feasibility (the reference validator):", "", "```", rep.check, "```", ""]
    return "\n".join(lines)


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


def _plot_poses(axes, moving: list, r, window) -> None:
    """Draw the reference and the achieved pose of each moving axis (mm or deg), one axis per
    row, the measured window shaded."""
    t = r.t
    w0, w1 = window
    for ax, k in zip(axes, moving):
        scale, unit = (1e3, "mm") if k >= 3 else (180 / math.pi, "deg")
        ax.plot(*_thinned(t, r.x_d[:, k] * scale), "k--", lw=1, label="reference")
        ax.plot(*_thinned(t, r.x[:, k] * scale), "C0", lw=0.9, label="achieved")
        ax.set_ylabel(f"{AXES[k]} [{unit}]")
        ax.axvspan(w0, w1, color="0.9", zorder=0)
        ax.legend(loc="upper right", fontsize=7, ncol=2)
        ax.grid(alpha=0.3)


def _plot_error(axes, r, window, tolerance: tuple[float, float]) -> None:
    """Draw the norm of the translation error (um) and of the rotation error (urad) over time,
    each on its own axis against its own tolerance, the measured window shaded."""
    t = r.t
    e = r.x[:, :6] - r.x_d[:, :6]
    w0, w1 = window
    for ax, part, tol, color, what, unit, scale in (
        (axes[0], slice(3, 6), tolerance[0], "C3", "translation", "um", 1e6),
        (axes[1], slice(0, 3), tolerance[1], "C2", "rotation", "urad", 1e6),
    ):
        norm = np.linalg.norm(e[:, part], axis=1) * scale
        ax.plot(*_thinned(t, norm, peaks=True), color, lw=0.6, label=f"|{what} error|")
        ax.axhline(
            tol * scale,
            color=color,
            ls=":",
            lw=1.2,
            label=f"tolerance {_length(tol) if unit == 'um' else _angle(tol)}",
        )
        ax.set_yscale("log")
        ax.set_ylim(0.1, 3 * max(tol * scale, float(norm.max())))
        ax.axvspan(w0, w1, color="0.9", zorder=0)
        ax.set_ylabel(f"{what}\nerror [{unit}]")
        ax.legend(loc="upper right", fontsize=7, ncol=2)
        ax.grid(alpha=0.3, which="both")
    axes[1].set_xlabel("t [s] (shaded: measured window)")


def _plot_cycles(ax, cyc: dict, learn_cycles: int) -> None:
    """Draw the RMS error of each cycle (um and urad), the cycles learned from marked, or say
    that the reference has none."""
    if cyc["starts"]:
        j = np.arange(len(cyc["starts"]))
        ax.plot(j, np.array(cyc["rms_translation_m"]) * 1e6, "o-C3", label="translation [um]")
        ax.plot(j, np.array(cyc["rms_rotation_rad"]) * 1e6, "s-C2", label="rotation [urad]")
        ax.set_ylim(bottom=0)
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

        ax.xaxis.set_major_locator(MaxNLocator(nbins=20, integer=True))  # labels never overlap
        ax.legend(loc="upper right", fontsize=7, ncol=2)
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
    ax.set_ylabel("RMS error\nper cycle")
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


def _plot_zoom(axes, moving: list, r, fid: dict, tolerance: tuple[float, float]) -> None:
    """Draw :data:`ZOOM_S` at full rate around the largest translation error of the measured
    window: the axis that moves most there (reference and achieved), and the translation error
    against its tolerance."""
    t = r.t
    e = np.linalg.norm(r.x[:, 3:6] - r.x_d[:, 3:6], axis=1)
    w0, w1 = fid["window_s"]
    inside = np.flatnonzero((t >= w0) & (t <= w1))
    k = int(inside[np.argmax(e[inside])]) if inside.size else int(np.argmax(e))
    a = float(np.clip(t[k] - ZOOM_S / 2, t[0], max(t[0], t[-1] - ZOOM_S)))
    m = (t >= a) & (t <= a + ZOOM_S)
    axis = max(moving, key=lambda j: float(np.ptp(r.x_d[m, j])) / (1e-3 if j >= 3 else 1e-2))
    scale, unit = (1e3, "mm") if axis >= 3 else (180 / math.pi, "deg")
    axes[0].plot(t[m], r.x_d[m, axis] * scale, "k--", lw=1, label="reference")
    axes[0].plot(t[m], r.x[m, axis] * scale, "C0", lw=0.9, label="achieved")
    axes[0].set_ylabel(f"zoom: {AXES[axis]}\n[{unit}]")
    axes[0].set_title(
        f"zoom, t = {a:.4g}-{a + ZOOM_S:.4g} s: around the largest translation error of the "
        f"measured window ({e[k] * 1e6:.3g} um at t = {t[k]:.4g} s)",
        fontsize=8,
    )
    axes[1].plot(t[m], e[m] * 1e6, "C3", lw=0.7, label="|translation error|")
    axes[1].axhline(tolerance[0] * 1e6, color="C3", ls=":", lw=1.2, label="tolerance")
    axes[1].set_yscale("log")
    axes[1].set_ylabel("zoom: translation\nerror [um]")
    axes[1].set_xlabel("t [s]")
    for ax in axes:
        ax.legend(loc="upper right", fontsize=7, ncol=2)
        ax.grid(alpha=0.3, which="both")


#: The report figure's title: its font size, pt, and the characters a line holds (a 10 in wide
#: figure holds about 150 at 9 pt; a long file name is wrapped, not cut at both ends).
TITLE_POINTS, TITLE_CHARS = 9, 110


def report_title(rep: Reproduction, line: str) -> str:
    """The report figure's title: the motion, the verdict ``line`` and how the run learned
    (the model file named), wrapped at :data:`TITLE_CHARS` characters a line."""
    import textwrap

    text = f"{rep.name}: {line} ({_learning(rep)})"
    return "\n".join(textwrap.wrap(text, TITLE_CHARS, break_on_hyphens=False))


def plot_report(rep: Reproduction, path, tolerance: tuple[float, float]) -> Path:
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
    _plot_poses(axes, moving, r, fid["window_s"])
    _plot_error(axes[len(moving) : len(moving) + 2], r, fid["window_s"], tolerance)
    if zoom:
        _plot_zoom(axes[len(moving) + 2 : len(moving) + 4], moving, r, fid, tolerance)
    _plot_cycles(axes[len(moving) + 2 + 2 * zoom], fid["cycles"], rep.learn_cycles)
    if fid["harmonics"]:
        _plot_harmonics(axes[-1], fid["harmonics"])
    ok, line = verdict(fid, tolerance)
    title = report_title(rep, line)
    fig.suptitle(title, fontsize=TITLE_POINTS, color="k" if ok else "tab:red")
    top_in = 0.1 + 0.18 * (title.count("\n") + 1)  # each line of the title, in
    fig.tight_layout(rect=(0, 0, 1, 1 - top_in / fig.get_figheight()))
    path = Path(path)
    atomic_write(path, lambda f: fig.savefig(f, format="png", dpi=100))
    plt.close(fig)
    return path


def write_report(
    rep: Reproduction, out, tolerance: tuple[float, float], stem: str | None = None
) -> tuple[Path, Path, Path]:
    """Write ``<stem>.md``, ``<stem>.png`` and ``<stem>.json`` (the figures) into ``out``.

    Returns:
        the three paths.
    """
    out = Path(out)
    stem = stem or f"reproduce_{rep.name}"
    md = out / f"{stem}.md"
    png = plot_report(rep, out / f"{stem}.png", tolerance)
    text = report_markdown(rep, tolerance) + f"\n![reference, achieved, errors]({png.name})\n"
    atomic_write(md, lambda f: f.write(text.encode()))
    figures = {
        "name": rep.name,
        "scale": rep.scale,
        "learn_cycles": rep.learn_cycles,
        "learning": _learning(rep),
        "learned_from": getattr(rep, "learned_from", ""),
        "tolerance": list(tolerance),
        "passed": verdict(rep.fidelity, tolerance)[0],
        "fidelity": rep.fidelity,
        "wall_s": rep.wall_s,
    }
    js = out / f"{stem}.json"
    atomic_write(js, lambda f: f.write(json.dumps(figures, indent=1, default=float).encode()))
    return md, png, js
