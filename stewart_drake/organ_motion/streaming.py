"""A motion followed as it arrives, measured against the true motion, two ways: (a) the
literature's, at the samples: the prediction the horizon ahead against the newest sample held
(:func:`horizon_error`: the relative RMSE and the nRMSE); (b) end to end: the followed
reference (or the robot that ran it) with and without prediction at every instant
(:func:`stream_figures`: RMS, peak, nRMSE, the share of time within a tolerance).

:func:`follow_motion` streams a motion (:func:`~stewart_drake.references.stream.stream_of`),
follows it with a predictor and with none (:func:`~stewart_drake.references.stream.follow`)
and measures both ways; ``reproduce --stream`` runs the followed reference on the robot and
measures the robot's pose as (b) (:func:`reproduce_stream`), to be judged: the robot's true pose
against the true motion, never against the reference it was given, which is a prediction
(:mod:`~.stream_report`, which says and writes it). The true motion is checked first, as any
reference is (refused, or scaled with ``--scale-to-fit``); what the follower adds beyond the
robot's limits is shaped away, period by period (:mod:`~stewart_drake.run.shaping`, as ``robot
--follow-lcm`` shapes it), and said. The figure's band is what the realised errors say
(:func:`error_band`), not the predictor's own record.
"""

from __future__ import annotations

import numpy as np

from ..base.measures import rms_per_axis
from ..references.prediction import PredictorSettings
from ..references.stream import DEFAULT_STREAM_RATE_HZ, LOOP_LAG_S, SWITCH_S, follow, stream_of

#: The step of the grid the errors are measured on, s.
MEASURE_STEP_S = 0.01
#: The share of the realised errors the figure's band holds (:func:`error_band`) ...
BAND_QUANTILE = 0.95
#: ... among those of the samples of this last stretch, s (the predictor's record's time
#: constant, ``PredictorSettings.record_s``) ...
BAND_WINDOW_S = 10.0
#: ... once this many are known.
BAND_MIN_SAMPLES = 20


def stream_figures(x_true, x, tolerance=(1e-3, 0.01)) -> dict:
    """Errors of poses ``x`` against the true motion ``x_true``, sampled alike on a uniform
    grid (every figure is a mean over the samples, so a share of the samples is one of time).

    Args:
        x_true, x: (n, 6) [phi, theta, psi, X, Y, Z], rad and m.
        tolerance: (m, rad): the error allowed in translation (3-D) and rotation (3-D).
    Returns:
        {"rms_translation_m", "rms_rotation_rad" (3-D RMS), "peak_translation_m",
        "nrmse_translation" (RMS error over the RMS of the true translation about its mean),
        "within_tolerance" (share of the samples within both tolerances, 0-1)}.
    """
    e = np.asarray(x, dtype=float) - np.asarray(x_true, dtype=float)
    et = np.linalg.norm(e[:, 3:], axis=1)
    er = np.linalg.norm(e[:, :3], axis=1)
    spread = np.asarray(x_true)[:, 3:] - np.mean(x_true, axis=0)[3:]
    motion = float(np.sqrt(np.mean(np.sum(spread**2, axis=1))))
    rms_t = float(np.sqrt(np.mean(et**2)))
    return {
        "rms_translation_m": rms_t,
        "rms_rotation_rad": float(np.sqrt(np.mean(er**2))),
        "peak_translation_m": float(np.max(et, initial=0.0)),
        "nrmse_translation": rms_t / motion if motion > 0 else float("nan"),
        "within_tolerance": float(np.mean((et <= tolerance[0]) & (er <= tolerance[1]))),
    }


def horizon_error(followed, truth, horizon_s: float, from_s: float = 0.0) -> dict:
    """The literature's measure of a predictor, at the sample instants: the prediction of the
    motion ``horizon_s`` (s) after each sample, made from the samples up to it, against the
    true motion ``truth`` (a Reference) then, beside no prediction (the newest sample held),
    over the samples taken from ``from_s`` s whose horizon is within the motion.

    Returns:
        {"rms_translation_m": the prediction as used (the newest sample on the axes where the
        record chose no prediction), "rms_rotation_rad" (3-D RMS), "model_translation_m": the
        model's own on every axis, "none_translation_m": the newest sample held, "ratio": the
        first over the fourth (the relative RMSE), "nrmse", "nrmse_none": each RMS error over
        the RMS of the true translation about its mean at those instants, "samples": how many}.
    """
    t = followed.stream.t
    keep = (t >= from_s) & (t + horizon_s <= followed.end_time + 1e-9)
    x_true = np.asarray(truth.evaluate(t[keep] + horizon_s)[0]).reshape(-1, 6)
    used = followed.at_horizon(horizon_s, used=True)[keep]
    model = followed.at_horizon(horizon_s)[keep]
    held = followed.stream.poses[keep]

    def rms(x, axes=slice(3, 6)) -> float:
        return float(np.sqrt(np.mean(np.sum((x - x_true)[:, axes] ** 2, axis=1))))

    spread = x_true[:, 3:] - np.mean(x_true[:, 3:], axis=0)
    motion = float(np.sqrt(np.mean(np.sum(spread**2, axis=1))))
    out = {
        "rms_translation_m": rms(used),
        "rms_rotation_rad": rms(used, slice(0, 3)),
        "model_translation_m": rms(model),
        "none_translation_m": rms(held),
        "samples": int(np.count_nonzero(keep)),
    }
    nan = float("nan")
    out["ratio"] = (
        out["rms_translation_m"] / out["none_translation_m"]
        if out["none_translation_m"] > 0
        else nan
    )
    out["nrmse"] = out["rms_translation_m"] / motion if motion > 0 else nan
    out["nrmse_none"] = out["none_translation_m"] / motion if motion > 0 else nan
    return out


def _following(say, rate: float, name: str):
    """The progress callback ``(i, n)`` of following a stream at ``rate`` Hz with the predictor
    ``name``, telling ``say`` (None: no progress)."""
    if say is None:
        return None
    return lambda i, n: say(
        f"following the stream of {n} samples at {rate:g} Hz with {name}: {i} done "
        f"({100 * i / n:.0f} %)"
    )


def follow_motion(
    reference,
    latency_s: float,
    predictor: str = "linear",
    rate_hz: float | None = None,
    duration_s: float | None = None,
    settings: PredictorSettings | None = None,
    tolerance=(1e-3, 0.01),
    from_s: float = 0.0,
    loop_lag_s: float = LOOP_LAG_S,
    say=None,
    form=None,
) -> dict:
    """A motion streamed ``latency_s`` late and followed with ``predictor`` and with none: (b)
    each followed reference measured against the motion itself over [``from_s``, end]
    (:func:`stream_figures`, every :data:`MEASURE_STEP_S`), and (a) the prediction at the
    horizon (the latency plus the loop's lag) against the newest sample held, at the samples
    (:func:`horizon_error`).

    Args:
        reference: the true motion (a Reference; a trace's length is its ``end_time``).
        rate_hz: the stream's rate (default a trace's own, else
            :data:`~stewart_drake.references.stream.DEFAULT_STREAM_RATE_HZ`).
        duration_s: how long (default the reference's ``end_time``; required without one).
        say: called with a line of progress every few seconds of a long follow, or None.
        form: what happens to the samples on their way, or None (exact): a
            :class:`~.stream_sources.StreamForm` (its rate, when it has one, is the stream's);
            the followed references are judged against the true motion all the same.
    Returns:
        {"with": figures, "without": figures, "ratio_translation", "ratio_rotation",
        "horizon": :func:`horizon_error`, "latency_s", "rate_hz", "predictor", "used" (share
        of the arrivals whose prediction was used, over the moving axes), "clipped",
        "fallbacks" (the times an axis went back to no prediction), "rejected" (samples' axes
        taken as outliers),
        "followed": the :class:`~stewart_drake.references.stream.FollowedStream`}.
    Raises:
        InvalidConfigError: as :func:`~stewart_drake.references.stream.follow`.
    """
    rate = rate_hz or getattr(form, "rate_hz", None) or trace_rate(reference)
    rate = rate or DEFAULT_STREAM_RATE_HZ
    end = duration_s if duration_s is not None else float(reference.end_time)
    stream = stream_of(reference, latency_s, rate, end)
    if form is not None:
        stream = form.apply(stream)
    followed = {
        name: follow(stream, name, settings, loop_lag_s, progress=_following(say, rate, name))
        for name in ("none", predictor)
    }
    t = np.arange(from_s, end, MEASURE_STEP_S)
    x_true = np.asarray(reference.evaluate(t)[0])
    figures = {
        name: stream_figures(x_true, f.evaluate(t)[0], tolerance) for name, f in followed.items()
    }
    chosen = followed[predictor]
    moving = np.ptp(stream.poses, axis=0) > 0
    ratio = [
        figures[predictor][k] / figures["none"][k] if figures["none"][k] > 0 else float("nan")
        for k in ("rms_translation_m", "rms_rotation_rad")
    ]
    return {
        "with": figures[predictor],
        "without": figures["none"],
        "ratio_translation": ratio[0],
        "ratio_rotation": ratio[1],
        "horizon": horizon_error(chosen, reference, latency_s + loop_lag_s, from_s),
        "latency_s": float(latency_s),
        "rate_hz": float(rate),
        "predictor": predictor,
        "used": float(chosen.using[:, moving].mean()) if moving.any() else 0.0,
        "clipped": chosen.clipped,
        "fallbacks": chosen.fallbacks,
        "rejected": chosen.rejected,
        "followed": chosen,
    }


def _stderr_line(text: str) -> None:
    """A line of progress on stderr, at once."""
    import sys

    print(text, file=sys.stderr, flush=True)


def trace_rate(reference) -> float | None:
    """A recorded trace's own sample rate, Hz (its import record's median), or None."""
    info = getattr(reference, "info", None)
    rate = getattr(info, "sample_rate_hz", None)
    return float(rate) if rate else None


#: A library motion's run when streamed without ``--duration``, s.
STREAM_DEFAULT_S = 60.0


def reproduce_stream(
    scenario,
    latency_s: float,
    predictor: str = "linear",
    rate_hz: float | None = None,
    duration_s: float | None = None,
    tolerance=(1e-3, 0.01),
    scale_to_fit: bool = False,
    progress: bool = False,
    on_checked=None,
) -> dict:
    """``reproduce --stream``: the scenario's motion streamed ``latency_s`` late, followed with
    ``predictor``, shaped to the robot's limits and run on the robot; the robot's true pose
    measured against the true motion, beside the reference without prediction's.

    The true motion is checked first as any reference is (reach, joint limits, singularity,
    clearance, the motors' torque and speed): refused, or shrunk about its centre with
    ``scale_to_fit`` (:func:`~.reproduction.scale_to_fit`) and that motion streamed. What the
    follower adds (a prediction's revisions ask for accelerations the motion never has) is
    then shaped away period by period (:func:`~stewart_drake.run.shaping.shape_followed`, the
    validator's limits), so the reference the robot is given passes the validator, which checks
    it again before the run.

    Returns:
        :func:`follow_motion`'s dict (the followed reference against the motion streamed, with and
        without prediction, over the whole run) with "given": the shaped reference the robot ran
        (:class:`~stewart_drake.run.shaping.ShapedReference`), "shaped": :func:`stream_figures` of
        it against the motion streamed, "shaping": its record
        (:meth:`~stewart_drake.run.shaping_record.ShapingRecord.as_dict`), "band":
        :func:`band_figures` of it, "scale": the true motion's scale (1.0: as it is), "robot":
        :func:`stream_figures` of the robot's true pose against the true motion over the whole run,
        "reproduction": the :class:`~.reproduction.Reproduction` of the shaped reference,
        "robot_tracking": its own fidelity (the robot against what it was given), "judged": the same
        run measured against the true motion over the same window
        (:func:`~.reproduction.measured_against`: what :func:`~.stream_report.stream_verdict`
        judges), "truth": the true motion, "prediction_from_s": :func:`prediction_start`.
    Raises:
        InvalidConfigError: a bad latency, an unknown predictor, a stream too short; and as
            :func:`~.reproduction.reproduce`.
        UnreachablePoseError, JointLimitError, SingularPoseError, InterferenceError,
            MotorLimitError: the true motion refused (without ``scale_to_fit``), its message
            led by "the true motion".
    """
    from dataclasses import replace

    from ..run.plan import make_plan, run_reference
    from ..run.shaping import shape_followed, shaping_limits
    from .reproduction import reproduce

    truth = run_reference(scenario)
    end = getattr(truth, "end_time", None)
    duration = float(min(duration_s or end or STREAM_DEFAULT_S, end or np.inf))
    say = _stderr_line if progress else None
    tell = say or (lambda line: None)
    tell(f"reproduce: following the motion streamed {latency_s * 1e3:g} ms late ...")
    figures = follow_motion(
        truth, latency_s, predictor, rate_hz, duration, tolerance=tolerance, say=say
    )
    plan = make_plan(replace(scenario, duration_s=duration), with_reference=False)
    streamed, scale = fitted_motion(plan, truth, scale_to_fit)
    if scale != 1.0:  # the motion that fits, at the true motion's rate
        rate = figures["rate_hz"]
        figures = follow_motion(
            streamed, latency_s, predictor, rate, duration, tolerance=tolerance, say=say
        )
    tell("reproduce: shaping the followed reference to the robot's limits ...")
    given = shape_followed(figures["followed"], shaping_limits(plan), duration)
    figures.update(_given_figures(given, streamed, figures["followed"], duration, tolerance))
    figures["scale"] = scale
    rep = reproduce(
        scenario,
        reference=given,
        duration_s=duration,
        progress=progress,
        on_checked=on_checked,
    )
    figures.update(_robot_figures(rep, truth, tolerance))
    figures["prediction_from_s"] = prediction_start(figures["followed"])
    figures["after_warm_up"] = after_warm_up(figures["judged"], figures["prediction_from_s"])
    return figures


def _given_figures(given, streamed, followed, duration: float, tolerance) -> dict:
    """:func:`reproduce_stream`'s figures of the shaped reference the robot is given: "given",
    "shaped" (against the motion streamed), "shaping" (its record), "band"."""
    t = np.arange(0.0, duration, MEASURE_STEP_S)
    x_streamed = np.asarray(streamed.evaluate(t)[0])
    return {
        "given": given,
        "shaped": stream_figures(x_streamed, given.evaluate(t)[0], tolerance),
        "shaping": given.record.as_dict(),
        "band": band_figures(given, streamed, followed.stream),
    }


def _robot_figures(rep, truth, tolerance) -> dict:
    """:func:`reproduce_stream`'s figures of the robot's run ``rep`` against the true motion:
    "robot", "reproduction", "robot_tracking", "truth", "judged"."""
    from .reproduction import measured_against

    t = np.asarray(rep.result.t, dtype=float)
    x = np.asarray(rep.result.x[:, :6], dtype=float)
    name = getattr(truth, "name", "the motion")
    compared = f"the robot's true pose against the true motion ({name})"
    return {
        "robot": stream_figures(np.asarray(truth.evaluate(t)[0]), x, tolerance),
        "reproduction": rep,
        "robot_tracking": rep.fidelity,
        "truth": truth,
        "judged": measured_against(rep, truth, compared),
    }


def fitted_motion(plan, truth, scale_to_fit: bool = False) -> tuple:
    """(the motion to stream, its scale): ``truth`` as it is (1.0) when every check of
    :func:`~stewart_drake.run.plan.check_reference` passes on the robot of ``plan`` over its
    duration; else, with ``scale_to_fit``, shrunk about its centre until they do
    (:func:`~.reproduction.scale_to_fit`).

    Raises:
        UnreachablePoseError, JointLimitError, SingularPoseError, InterferenceError,
            MotorLimitError: without ``scale_to_fit``, the validator's refusal of the true
            motion, its message led by "the true motion (<name>), before it is followed: ".
        InvalidConfigError: as :func:`~.reproduction.scale_to_fit`.
    """
    from ..base.errors import StewartError
    from ..run.plan import check_reference
    from .reproduction import scale_to_fit as fit

    if scale_to_fit:
        return fit(plan.scenario, truth)
    try:
        check_reference(plan, truth, keep_series=False)
    except StewartError as err:
        name = getattr(truth, "name", "")
        # The validator's own error, its type kept, said of the true motion: not the
        # follower's, which is shaped away instead.
        err.args = (f"the true motion ({name}), before it is followed: {err}", *err.args[1:])
        raise
    return truth, 1.0


def error_band(
    reference, stream, quantile: float = BAND_QUANTILE, window_s: float = BAND_WINDOW_S
) -> np.ndarray:
    """The band the realised errors give, causally: at each arrival of ``stream``, the
    ``quantile`` of the translation errors (3-D) of ``reference`` (what the robot is given) at
    the samples of the last ``window_s`` s up to the newest, |reference(t_j) - y_j|, each known
    once sample j has arrived (the reference at t_j was made before it).

    Args:
        reference: the reference (``evaluate``). stream: the
            :class:`~stewart_drake.references.stream.Stream` it follows. quantile: in (0, 1).
        window_s: the past read, s (at least :data:`BAND_MIN_SAMPLES` samples).
    Returns:
        (N,) m at each arrival; NaN before :data:`BAND_MIN_SAMPLES` errors are known.
    Source: an empirical quantile of past residuals (the split-conformal idea, Vovk, Gammerman
        and Shafer, Algorithmic Learning in a Random World, 2005, ch. 2) read over a sliding
        window: the window and the quantile are our choice.
    """
    from numpy.lib.stride_tricks import sliding_window_view

    e = np.linalg.norm(
        np.asarray(reference.evaluate(stream.t)[0])[:, 3:] - stream.poses[:, 3:], axis=1
    )
    m = max(BAND_MIN_SAMPLES, int(round(window_s / stream.dt)))
    windows = sliding_window_view(np.concatenate([np.full(m - 1, np.nan), e]), m)
    band = np.full(e.size, np.nan)
    known = np.arange(e.size) >= BAND_MIN_SAMPLES - 1
    if np.any(known):
        band[known] = np.nanquantile(windows[known], quantile, axis=1)
    return band


def band_figures(reference, motion, stream) -> dict:
    """How well :func:`error_band` of ``reference`` (following ``stream`` of ``motion``) holds
    its errors: {"quantile", "window_s", "coverage": the share of the instants (every
    :data:`MEASURE_STEP_S` from the first band) whose translation error against ``motion`` is
    within the band of the newest arrival, "median_m": the band's median, m, "band": (N,) the
    band at each arrival, m}."""
    band = error_band(reference, stream)
    arrival = stream.arrival
    first = np.flatnonzero(np.isfinite(band))
    out = {"quantile": BAND_QUANTILE, "window_s": BAND_WINDOW_S, "band": band}
    if first.size == 0:
        return out | {"coverage": float("nan"), "median_m": float("nan")}
    t = np.arange(arrival[first[0]], float(stream.t[-1]), MEASURE_STEP_S)
    e = np.linalg.norm(
        np.asarray(reference.evaluate(t)[0])[:, 3:] - np.asarray(motion.evaluate(t)[0])[:, 3:],
        axis=1,
    )
    b = band[np.searchsorted(arrival, t, side="right") - 1]
    return out | {
        "coverage": float(np.mean(e <= b)) if t.size else float("nan"),
        "median_m": float(np.nanmedian(b)) if t.size else float("nan"),
    }


def after_warm_up(judged, prediction_from_s: float | None) -> dict | None:
    """The figures of ``judged`` (a :class:`~.reproduction.Reproduction` measured against the
    true motion) once the prediction is followed: {"window_s": [a, b], "rms": (6,) per axis,
    rad and m} from ``prediction_from_s`` + :data:`~stewart_drake.references.stream.SWITCH_S`
    (:func:`prediction_start`) to the end of its window; None when that is not inside the window
    (no warm-up in it) or holds fewer than 10 samples. Reported beside the verdict, never as it:
    the warm-up is part of the run."""
    if prediction_from_s is None:
        return None
    w0, w1 = judged.fidelity["window_s"]
    r = judged.result
    t = np.asarray(r.t, dtype=float)
    inside = (t >= prediction_from_s + SWITCH_S - 1e-9) & (t <= w1 + 1e-9)
    if prediction_from_s + SWITCH_S <= w0 or np.count_nonzero(inside) < 10:
        return None
    e = np.subtract(r.x[inside, :6], r.x_d[inside, :6], dtype=float)
    window = [float(t[inside][0]), float(t[inside][-1])]
    return {"window_s": window, "rms": rms_per_axis(e).tolist()}


def prediction_start(followed) -> float | None:
    """When the prediction was first chosen, s: the arrival at which the predictor's record
    first chose its positions on an axis that moves (the reference then moves onto them over
    :data:`~stewart_drake.references.stream.SWITCH_S`); None when it never was (``none``, a
    motion at rest, a record that never found the model better). Before it, the samples are
    followed without prediction: the predictor's warm-up."""
    moving = np.ptp(followed.stream.poses, axis=0) > 0
    used = np.asarray(followed.using)[:, moving].any(axis=1)
    if not used.any():  # also no axis that moves
        return None
    return float(followed.stream.arrival[int(np.argmax(used))])


__all__ = [
    "stream_figures",
    "horizon_error",
    "follow_motion",
    "trace_rate",
    "reproduce_stream",
    "prediction_start",
    "after_warm_up",
    "fitted_motion",
    "error_band",
    "band_figures",
    "MEASURE_STEP_S",
    "BAND_QUANTILE",
    "BAND_WINDOW_S",
    "BAND_MIN_SAMPLES",
]
