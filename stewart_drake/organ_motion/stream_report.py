"""What ``reproduce --stream`` says and writes of a motion followed as it arrives
(:func:`~.streaming.reproduce_stream`): the verdict, the robot's true pose against the true
motion, never against the reference it was given, which is a prediction (:func:`stream_verdict`),
with what is beside it (the robot against the reference given, the start-up left out, the
predictor's warm-up); the summary lines (:func:`stream_summary`); and the report, .md, .png and
.json (:func:`write_stream_report`).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..references.stream import LOOP_LAG_S, SWITCH_S
from .fidelity import format_length, format_window, tolerance_line, verdict
from .streaming import MEASURE_STEP_S, band_figures


def stream_verdict(figures: dict, tolerance: tuple[float, float]) -> tuple[bool, list]:
    """The verdict of ``reproduce --stream``: the robot's true pose against the true motion
    (``figures["judged"]``, :func:`~.streaming.reproduce_stream`), every axis's RMS error within
    ``tolerance`` (m, rad) over the reproduction's measured window.

    Returns:
        (passed, lines): the verdict's line (:func:`~.fidelity.verdict`, naming the true
        motion); the robot against the reference it was given, over the same window, labelled
        as not the verdict; what the window leaves out (the start-up) and where the predictor's
        warm-up lies; when the warm-up is inside the window, the figures after it
        (:func:`~.streaming.after_warm_up`), labelled as not the verdict.
    """
    judged, rep = figures["judged"], figures["reproduction"]
    ok, line = verdict(judged.fidelity, tolerance, judged.comparison())
    _, given = tolerance_line(rep.fidelity, tolerance)
    (w0, w1), start = judged.fidelity["window_s"], judged.startup
    given_is = (
        "the late samples joined"
        if figures["predictor"] == "none"
        else "the motion as predicted from its late samples"
    )
    lines = [
        line,
        f"beside it, not the verdict: the robot's true pose against the reference it was "
        f"given ({rep.name}: {given_is}, not the motion), {given}",
        f"the figures are over t = {format_window(w0, w1)} s; the start-up before it (the first "
        f"sample arrives at t = {figures['latency_s']:g} s) is left out: against the true "
        f"motion RMS {format_length(start['rms_translation_m'])}, peak "
        f"{format_length(start['peak_translation_m'])}; " + _warm_up_words(figures, w0),
    ]
    later = figures.get("after_warm_up")
    if later is not None:
        lines.append(
            "after the warm-up, not the verdict: the robot's true pose against the true motion, "
            + tolerance_line(later, tolerance)[1]
        )
    scale = figures.get("scale", 1.0)
    if scale != 1.0:
        lines.append(
            f"the true motion was scaled by {scale:.3f} about its centre to fit the robot, then "
            f"streamed: the verdict counts the shrink as error (the true motion is as it happened)"
        )
    return ok, lines


def _warm_up_words(figures: dict, window_start_s: float) -> str:
    """Where the predictor's warm-up lies against the measured window, in words."""
    first = figures["prediction_from_s"]
    if figures["predictor"] == "none":
        return "no predictor: the samples are followed without prediction throughout"
    if first is None:
        return (
            "the prediction was never chosen: the samples were followed without prediction "
            "throughout, and the figures are theirs"
        )
    where = (
        "inside the window: its error counts in the figures"
        if first + SWITCH_S > window_start_s
        else "before the window"
    )
    return (
        f"the predictor's warm-up, the samples followed without prediction until it was first "
        f"chosen at t = {first:.3g} s (and moved onto over {SWITCH_S:g} s), is {where}"
    )


def stream_summary(figures: dict) -> list:
    """The lines ``reproduce --stream`` prints and its report leads with."""
    w, n, r, h = figures["with"], figures["without"], figures.get("robot"), figures["horizon"]
    lines = [
        f"streamed {figures['latency_s']:g} s late at {figures['rate_hz']:.3g} Hz, predictor "
        f"{figures['predictor']} (latency assumed {figures['latency_s']:g} s + the loop's "
        f"{LOOP_LAG_S * 1e3:.2g} ms): prediction used on {figures['used'] * 100:.0f} % of the "
        f"arrivals, {figures['fallbacks']} fallback{'' if figures['fallbacks'] == 1 else 's'} "
        f"to no prediction where it stopped paying, {figures['rejected']} sample axes taken as "
        f"outliers, {figures['clipped']} predicted positions clipped to the motion's recent "
        "range",
        f"(a) the prediction {figures['latency_s'] + LOOP_LAG_S:.3g} s ahead, at the samples "
        f"(the literature's measure): {h['rms_translation_m'] * 1e3:.3g} mm RMS against "
        f"{h['none_translation_m'] * 1e3:.3g} mm with the newest sample held (relative RMSE "
        f"{h['ratio']:.2f}); nRMSE {h['nrmse_none']:.3f} -> {h['nrmse']:.3f}",
        f"(b) the followed reference against the true motion over the whole run, t = 0-"
        f"{figures['followed'].end_time:.4g} s (the warm-up included), translation RMS: without "
        f"prediction (the samples joined one sample step behind the newest) "
        f"{n['rms_translation_m'] * 1e3:.3g} mm, with {w['rms_translation_m'] * 1e3:.3g} mm "
        f"(ratio {figures['ratio_translation']:.2f}); peak {n['peak_translation_m'] * 1e3:.3g} "
        f"-> {w['peak_translation_m'] * 1e3:.3g} mm; nRMSE {n['nrmse_translation']:.3f} -> "
        f"{w['nrmse_translation']:.3f}; within tolerance {n['within_tolerance'] * 100:.1f} -> "
        f"{w['within_tolerance'] * 100:.1f} % of the time",
    ]
    shaping = figures.get("shaping")
    if shaping is not None:
        shaped, band = figures["shaped"], figures["band"]
        lines.append(
            f"the reference given to the robot: {_shaping_words(shaping)}; against the "
            f"{_streamed(figures)} over the whole run, translation RMS "
            f"{shaped['rms_translation_m'] * 1e3:.3g} mm shaped, "
            f"{w['rms_translation_m'] * 1e3:.3g} mm as followed; peak "
            f"{shaped['peak_translation_m'] * 1e3:.3g} mm, {w['peak_translation_m'] * 1e3:.3g} mm"
        )
        lines.append(
            f"the figure's band, {band['quantile'] * 100:.0f} % of the realised errors at the "
            f"samples of the last {band['window_s']:g} s (causal; median "
            f"{band['median_m'] * 1e3:.3g} mm), held {band['coverage'] * 100:.1f} % of the errors "
            f"of the reference given, every {MEASURE_STEP_S * 1e3:g} ms"
        )
    if r is not None:
        tracking = figures["robot_tracking"]
        lines.append(
            f"the robot, as built, against the true motion over the whole run: "
            f"{r['rms_translation_m'] * 1e3:.3g} mm "
            f"RMS, peak {r['peak_translation_m'] * 1e3:.3g} mm, within tolerance "
            f"{r['within_tolerance'] * 100:.1f} % (its own tracking of the followed reference: "
            f"{tracking['rms_translation_m'] * 1e6:.3g} um)"
        )
    return lines


def _shaping_words(record: dict) -> str:
    """:meth:`~stewart_drake.run.shaping_record.ShapingRecord.words` of a record's plain numbers."""
    from ..run.shaping_record import ShapingRecord

    return ShapingRecord(**record).words()


def _streamed(figures: dict) -> str:
    """The motion streamed, in words: the true motion, or the true motion scaled to fit."""
    scale = figures.get("scale", 1.0)
    return "true motion" if scale == 1.0 else f"true motion scaled by {scale:.3f}"


def _plot_stream(figures: dict, name: str, tolerance: tuple[float, float], png: Path) -> tuple:
    """Draw :func:`write_stream_report`'s figure into ``png`` (written atomically): the true
    motion, the followed references and the robot on the axis that moves most over the last
    20 s, with the errors and the band; titled with the verdict. Returns
    :func:`stream_verdict`'s (passed, lines)."""
    import textwrap

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from ..base.fileio import atomic_write

    followed, truth = figures["followed"], figures["truth"]
    rep = figures.get("reproduction")
    end = followed.end_time
    t = np.arange(0.0, end, MEASURE_STEP_S)
    x_true = np.asarray(truth.evaluate(t)[0])
    axis = int(np.argmax(np.ptp(x_true, axis=0) * np.array([0.1, 0.1, 0.1, 1, 1, 1])))
    scale, unit = (1e3, "mm") if axis >= 3 else (np.degrees(1.0), "deg")
    from ..references.stream import follow

    none = follow(followed.stream, "none", followed.settings, followed.loop_lag_s)
    x_with, x_none = followed.evaluate(t)[0], none.evaluate(t)[0]
    given = figures.get("given", followed)
    x_given = given.evaluate(t)[0]
    fig, (a0, a1) = plt.subplots(2, 1, figsize=(13, 7), sharex=True, layout="constrained")
    zoom = t >= max(0.0, end - 20.0)
    a0.plot(t[zoom], x_true[zoom, axis] * scale, "k", lw=2, label="true motion")
    a0.plot(t[zoom], x_none[zoom, axis] * scale, color="tab:red", label="followed, no prediction")
    a0.plot(t[zoom], x_with[zoom, axis] * scale, color="tab:blue", label="followed, predicted")
    a0.plot(t[zoom], x_given[zoom, axis] * scale, "--", color="tab:purple",
            label="given to the robot (shaped)")  # fmt: skip
    if rep is not None:
        rt = np.asarray(rep.result.t)
        rz = rt >= t[zoom][0]
        a0.plot(rt[rz], rep.result.x[rz, axis] * scale, ":", color="tab:green", label="robot")
    names = ("phi", "theta", "psi", "X", "Y", "Z")
    a0.set_ylabel(f"{names[axis]} [{unit}]")
    a0.set_title(
        f"{name} streamed {figures['latency_s']:g} s late ({figures['rate_hz']:.3g} Hz): "
        f"the last {min(20.0, end):.0f} s"
    )
    ok, lines = stream_verdict(figures, tolerance)
    fig.suptitle(
        "\n".join(textwrap.wrap(lines[0], 130)), fontsize=9, color="k" if ok else "tab:red"
    )
    # Beside the plots, not over the curves (which fill each plot's width).
    a0.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=8)
    e_none = np.linalg.norm(x_none[zoom, 3:] - x_true[zoom, 3:], axis=1) * 1e3
    e_with = np.linalg.norm(x_with[zoom, 3:] - x_true[zoom, 3:], axis=1) * 1e3
    e_given = np.linalg.norm(x_given[zoom, 3:] - x_true[zoom, 3:], axis=1) * 1e3
    a1.plot(t[zoom], e_none, color="tab:red", label="no prediction")
    a1.plot(t[zoom], e_with, color="tab:blue", label="predicted")
    a1.plot(t[zoom], e_given, "--", color="tab:purple", label="given to the robot (shaped)")
    band = figures.get("band") or band_figures(given, truth, followed.stream)
    arrive = followed.stream.arrival
    sel = arrive >= t[zoom][0]
    a1.step(arrive[sel], 1e3 * band["band"][sel], where="post", color="tab:gray", lw=1,
            label=f"{band['quantile'] * 100:.0f} % of the realised errors of the last "
            f"{band['window_s']:g} s (held {band['coverage'] * 100:.0f} %)")  # fmt: skip
    a1.set_ylabel("translation error [mm]")
    a1.set_xlabel("t [s]")
    a1.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=8)
    atomic_write(png, lambda f: fig.savefig(f, format="png", dpi=110))
    plt.close(fig)
    return ok, lines


def _stream_json(figures: dict, passed: bool, verdict: str, tolerance: tuple) -> dict:
    """The JSON :func:`write_stream_report` writes (its docstring)."""
    judged, rep = figures["judged"], figures["reproduction"]
    keep = {k: v for k, v in figures.items() if k in ("with", "without", "robot", "horizon")}
    keep.update(
        passed=passed,
        verdict=verdict,
        tolerance=list(tolerance),
        against_true_motion=_judged_figures(judged),
        against_given_reference=_judged_figures(rep) | {"not_the_verdict": True},
        prediction_from_s=figures["prediction_from_s"],
        after_warm_up=figures.get("after_warm_up"),
    )
    if "shaping" in figures:
        band = {k: v for k, v in figures["band"].items() if k != "band"}
        keep.update(
            shaped=figures["shaped"], shaping=figures["shaping"], band=band, scale=figures["scale"]
        )
    keep.update(
        {
            k: figures[k]
            for k in (
                "latency_s",
                "rate_hz",
                "predictor",
                "used",
                "clipped",
                "fallbacks",
                "rejected",
            )
        },
        ratio_translation=figures["ratio_translation"],
        ratio_rotation=figures["ratio_rotation"],
        loop_lag_s=LOOP_LAG_S,
    )
    return keep


def write_stream_report(figures: dict, out, name: str, tolerance: tuple[float, float]) -> tuple:
    """``reproduce_<name>_stream.md``, ``.png`` and ``.json`` in ``out``: the verdict of
    :func:`stream_verdict` at ``tolerance`` (m, rad; the robot's true pose against the true
    motion) with what is beside it, the summary, the figures, and the true motion, the followed
    reference with and without prediction, the reference given (shaped) and the robot on the
    axis that moves most, with the errors over time and the band of the realised errors
    (:func:`~.streaming.error_band`: :data:`~.streaming.BAND_QUANTILE` of those of the last
    :data:`~.streaming.BAND_WINDOW_S` s).

    The JSON's ``passed`` is that verdict; ``against_true_motion`` its figures (``rms`` per axis,
    rad and m, the 3-D RMS, ``window_s``, ``startup``); ``against_given_reference`` the robot
    against the reference it ran, over the same window, and ``after_warm_up``
    (:func:`~.streaming.after_warm_up`, or null), which are not the verdict; ``shaping`` what was
    shaped (:meth:`~stewart_drake.run.shaping_record.ShapingRecord.as_dict`), ``shaped`` the
    reference given against the motion streamed (:func:`~.streaming.stream_figures`), ``band``
    the band's coverage (:func:`~.streaming.band_figures`) and ``scale`` the true motion's.

    Returns:
        the three paths (.md, .png, .json), each written atomically.
    """
    import json

    from ..base.fileio import atomic_write

    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    stem = out / f"reproduce_{name}_stream"
    png = stem.parent / f"{stem.name}.png"  # a name may hold a dot: not with_suffix
    ok, lines = _plot_stream(figures, name, tolerance, png)
    md_text = "\n".join(
        [f"# {name} followed as it arrives", "", f"**{lines[0]}**", "",
         *[f"{line[0].upper()}{line[1:]}.\n" for line in lines[1:]],
         *[f"- {line}" for line in stream_summary(figures)], "",
         f"![the true motion and the followed reference]({png.name})", ""]
    )  # fmt: skip
    keep = _stream_json(figures, ok, lines[0], tolerance)
    md, js = (stem.parent / f"{stem.name}{suffix}" for suffix in (".md", ".json"))
    atomic_write(md, lambda f: f.write(md_text.encode()))
    atomic_write(js, lambda f: f.write(json.dumps(keep, indent=1, default=float).encode()))
    return md, png, js


def _judged_figures(rep) -> dict:
    """What the stream's JSON keeps of a reproduction's measure: what it compares, its window,
    its RMS per axis (rad and m), its 3-D RMS and peak translation, and the start-up before the
    window."""
    fid = rep.fidelity
    keys = ("window_s", "rms", "rms_translation_m", "rms_rotation_rad", "peak_translation_m")
    return {"compared": rep.comparison()} | {k: fid[k] for k in keys} | {"startup": rep.startup}


__all__ = ["stream_verdict", "stream_summary", "write_stream_report"]
