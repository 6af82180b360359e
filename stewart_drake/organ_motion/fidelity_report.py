"""The report of a reproduction (``stewart-drake reproduce``): a Markdown page with a verdict
against a tolerance (:func:`report_markdown`), one PNG of the poses, the errors, the cycles and
the harmonics (:func:`~.fidelity_figure.plot_report`), and the figures as JSON
(:func:`write_report`).

A measured motion (``stewart-drake verify``,
:class:`~stewart_drake.verification.verify.Verification`) is written by the same functions: its
page is :mod:`~stewart_drake.verification.report`'s, made of the same figure lines
(:func:`fidelity_lines`, :func:`startup_lines`, :func:`anchor_lines`); the figure and the JSON
are these, the axes it did not measure said so.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np

from ..base.fileio import atomic_write
from ..base.tables import markdown_lines
from .fidelity import (
    AXES,
    PHANTOM_ANCHOR,
    format_window,
    verdict,
)
from .fidelity_figure import (
    NOT_MEASURED,
    Verification,
    compared,
    compared_words,
    learning_of,
    plot_report,
    verdict_of,
)
from .reproduction import Reproduction


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


def report_markdown(rep: Reproduction, tolerance: tuple[float, float], context=()) -> str:
    """The Markdown report of a reproduction: verdict (naming what it compares, :func:`compared`),
    the ``context`` paragraphs (str: what else the verdict's reader must know, e.g. a figure
    beside it that is not the verdict), per-axis table, lag, harmonics, cycles, the learner, the
    phantom anchor."""
    fid = rep.fidelity
    ok, line = verdict(fid, tolerance, compared(rep))
    lines = [f"# Fidelity of {rep.name}", "", f"**{line}**", ""]
    for paragraph in context:
        lines += [paragraph, ""]
    lines += _run_lines(rep, fid)
    lines += fidelity_lines(fid)
    lines += _learner_lines(rep)
    lines += anchor_lines(fid)
    lines += ["", "Feasibility (the reference validator):", "", "```", rep.check, "```", ""]
    return "\n".join(lines)


def _run_lines(rep: Reproduction, fid: dict) -> list:
    """The report's lines on the run: its length, controller, learning and window; the model it
    started from, its scale, the trace it read."""
    lines: list = []
    lines.append(
        f"Run: {rep.result.t[-1]:.4g} s on the robot as built "
        f"({rep.result.config_summary.get('controller', '')}, "
        + learning_of(rep)
        + f"); measured over t = {fid['window_s'][0]:.4g}-"
        f"{fid['window_s'][1]:.4g} s from the true platform pose; wall time "
        f"{rep.wall_s:.0f} s."
    )
    lines += startup_lines(rep, fid)
    note = rep.result.config_summary.get("temperature_note")
    if note is not None:
        lines += ["", f"{note[0].upper()}{note[1:]}."]
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
    return lines


def startup_lines(rep, fid: dict) -> list:
    """The report's lines on what the measured window leaves out (the start-up, its RMS and
    peak; a rotation not measured said so) and on the encoders' resolution in the pose beside
    the measured figures (none when ``rep.resolution()`` is zero)."""
    lines: list = []
    start = getattr(rep, "startup", None) or {}
    if start and start["window_s"][1] > start["window_s"][0]:
        (a, b), rot = start["window_s"], start["rms_rotation_rad"]
        lines += [
            "",
            f"Start-up, not in the figures above or below (t = {format_window(a, b)} s): "
            f"RMS {start['rms_translation_m'] * 1e6:.3g} um / "
            + ("rotation not measured" if not np.isfinite(rot) else f"{rot * 1e6:.3g} urad")
            + f", peak {start['peak_translation_m'] * 1e6:.3g} um"
            + ("" if not np.isfinite(rot) else f" / {start['peak_rotation_rad'] * 1e6:.3g} urad")
            + ".",
        ]
    resolution = rep.resolution() if hasattr(rep, "resolution") else (0.0, 0.0)
    if resolution[0] > 0 and resolution[1] > 0:
        lines += [
            "",
            f"Encoders' resolution at these poses: {resolution[0] * 1e6:.3g} um / "
            f"{resolution[1] * 1e6:.3g} urad RMS in the pose the controller measures (their "
            f"rounding alone; measured here: {fid['rms_translation_m'] * 1e6:.3g} um / "
            f"{fid['rms_rotation_rad'] * 1e6:.3g} urad of the true pose, which the loop "
            f"filters).",
        ]
    return lines


def fidelity_lines(fid: dict) -> list:
    """The report's lines on the figures of :func:`~.fidelity.fidelity`: the error per axis, the
    3-D error and the lag, the gamma pass rates, the harmonics, the error per cycle."""
    return _axis_lines(fid) + _gamma_lines(fid) + _harmonic_lines(fid) + _cycle_lines(fid)


def _figure(value: float, unit: str) -> str:
    """``12.3 um`` of a value already in ``unit``, or :data:`NOT_MEASURED` for NaN."""
    return f"{value:.3g} {unit}" if np.isfinite(value) else NOT_MEASURED


def _axis_lines(fid: dict) -> list:
    """The report's table of the error per axis and its line on the 3-D error and the lag (the
    axes a measurement did not see: :data:`NOT_MEASURED`)."""
    lines: list = []
    units = ["urad"] * 3 + ["um"] * 3
    rows = []
    for k, axis in enumerate(AXES):
        scale, unit = (1e3, "mm") if k >= 3 else (180 / math.pi, "deg")
        lag = fid["lag_s"].get(axis)
        frac = fid["rms_fraction"][k]
        rows.append(
            [axis, f"{fid['p2p'][k] * scale:.4g} {unit}", _figure(fid["rms"][k] * 1e6, units[k])]
            + [_figure(fid["peak"][k] * 1e6, units[k])]
            + ["-" if not np.isfinite(frac) else f"{100 * frac:.3g} %"]
            + ["-" if lag is None else f"{1e3 * lag:.3g}"]
        )
    header = ["axis", "p2p motion", "RMS error", "peak error", "RMS / p2p", "lag [ms]"]
    lines += ["", *markdown_lines(header, rows)]
    lines += [
        "",
        f"3-D RMS error: translation {fid['rms_translation_m'] * 1e6:.3g} um, rotation "
        f"{_figure(fid['rms_rotation_rad'] * 1e6, 'urad')} (peaks "
        f"{fid['peak_translation_m'] * 1e6:.3g} um, "
        f"{_figure(fid['peak_rotation_rad'] * 1e6, 'urad')}); lag of the whole motion "
        f"{1e3 * fid['lag_all_s']:.3g} ms (least RMS difference, > 0: late).",
    ]
    return lines


def _gamma_lines(fid: dict) -> list:
    """The report's line on the gamma pass rates (none without)."""
    lines: list = []
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
    return lines


def _harmonic_lines(fid: dict) -> list:
    """The report's table of the harmonics (none without)."""
    lines: list = []
    if fid["harmonics"]:
        rows = []
        for h in fid["harmonics"]:
            k = AXES.index(h["axis"])
            amp = h["reference"] * (1e3 if k >= 3 else 180 / math.pi)
            rows.append(
                [f"{h['source']} {h['k']}", f"{h['f_hz']:.4g}", h["axis"]]
                + [f"{amp:.4g} {'mm' if k >= 3 else 'deg'}"]
                + [f"{100 * h['amplitude_error']:+.3g} %"]
                + [f"{math.degrees(h['phase_error_rad']):+.3g}"]
            )
        header = ["harmonic", "f [Hz]", "axis", "reference amplitude", "amplitude error"]
        lines += ["", *markdown_lines(header + ["phase error [deg]"], rows)]
    return lines


def _cycle_lines(fid: dict) -> list:
    """The report's line on the error per cycle (none without cycles)."""
    lines: list = []
    cyc = fid["cycles"]
    if cyc["starts"]:
        lines += [
            "",
            "Error per cycle (RMS, translation um | rotation urad): "
            + ", ".join(
                f"{j}: {a * 1e6:.3g} | {_figure(b * 1e6, '').strip()}"
                for j, (a, b) in enumerate(zip(cyc["rms_translation_m"], cyc["rms_rotation_rad"]))
            ),
        ]
    return lines


def _learner_lines(rep: Reproduction) -> list:
    """The report's line on the learner (none without)."""
    lines: list = []
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
    return lines


def anchor_lines(fid: dict) -> list:
    """The report's table of the phantom anchor against this run."""
    lines: list = []
    lines += [
        "",
        "Phantom anchor (Belcher et al., Med. Phys. 41, 121704, 2014, a built 6-DOF "
        "Stewart motion phantom replaying recorded tumour motion):",
        "",
    ]
    rows = []
    for axis, rmse, rng in PHANTOM_ANCHOR:
        k = AXES.index(axis)
        unit = "mm" if k >= 3 else "deg"
        frac = fid["rms_fraction"][k]
        rows.append(
            [axis, f"{rmse:g} {unit}", f"{rng:g} {unit}", f"{100 * rmse / rng:.2g} %"]
            + ["-" if not np.isfinite(frac) else f"{100 * frac:.2g} %"]
        )
    header = ["axis", "phantom RMSE", "phantom range", "phantom RMSE / range"]
    return lines + markdown_lines(header + ["here RMS / p2p"], rows)


def write_report(
    rep: Reproduction | Verification,
    out,
    tolerance: tuple[float, float],
    stem: str | None = None,
    text: str | None = None,
    extra: dict | None = None,
) -> tuple[Path, Path, Path]:
    """Write ``<stem>.md``, ``<stem>.png`` and ``<stem>.json`` (the figures) into ``out``.

    Args:
        rep: a :class:`~.reproduction.Reproduction`, or a
            :class:`~stewart_drake.verification.verify.Verification` (a measured motion).
        out: the folder. tolerance: (m, rad) of the verdict. stem: the files' name (default
            ``reproduce_<name>``).
        text: the Markdown page (default :func:`report_markdown`'s); the figure's link is
            appended.
        extra: figures added to the JSON after the reproduction's keys.
    Returns:
        the three paths.
    """
    if text is None:
        if not isinstance(rep, Reproduction):
            raise TypeError("write_report: a measured motion's page is given (text)")
        text = report_markdown(rep, tolerance)
    out = Path(out)
    stem = stem or f"reproduce_{rep.name}"
    md = out / f"{stem}.md"
    png = plot_report(rep, out / f"{stem}.png", tolerance)
    page = text
    page += f"\n![reference, achieved, errors]({png.name})\n"
    atomic_write(md, lambda f: f.write(page.encode()))
    figures = {
        "name": rep.name,
        "scale": rep.scale,
        "learn_cycles": rep.learn_cycles,
        "learning": learning_of(rep),
        "learned_from": getattr(rep, "learned_from", ""),
        "tolerance": list(tolerance),
        "passed": verdict_of(rep, tolerance)[0],
        "compared": compared_words(rep),
        "fidelity": rep.fidelity,
        "startup": getattr(rep, "startup", {}),
        "encoder_resolution_m_rad": list(rep.resolution()),
        "wall_s": rep.wall_s,
    } | (extra or {})
    js = out / f"{stem}.json"
    atomic_write(js, lambda f: f.write(json.dumps(figures, indent=1, default=float).encode()))
    return md, png, js


__all__ = [
    "report_markdown",
    "startup_lines",
    "fidelity_lines",
    "anchor_lines",
    "write_report",
]
