"""The report of a measured motion (``stewart-drake verify``): the page of a
:class:`~.verify.Verification` (:func:`verification_markdown`: what was measured, what the
alignment removed, then the figures of a reproduction's report), written with the reproduction's
figure and JSON (:func:`write_verification`: reproduce's keys, then ``latency_s``,
``clock_offset_s`` and what was removed).
"""

from __future__ import annotations

from pathlib import Path

from ..organ_motion.fidelity import AXES, format_angle, format_length
from ..organ_motion.fidelity_report import anchor_lines, fidelity_lines, startup_lines, write_report
from .verdict_sensitivity import sensitivity_words
from .verify import Verification, seconds


def verification_markdown(ver: Verification) -> str:
    """The Markdown page of a measured motion: the verdict (what it compares) and its causes,
    what was measured and against what, what the check can see, the latency, what the alignment
    removed, then the figures (per axis, gamma, harmonics, cycles, the start-up, the phantom
    anchor) as a reproduction's report gives them."""
    fid = ver.fidelity
    judgement, tolerance = ver.judgement, ver.tolerance
    source = ver.reference
    info = getattr(source, "info", None) or getattr(
        getattr(source, "reference", None), "info", None
    )
    not_measured = [a for a, m in zip(AXES, ver.measured.measured) if not m]
    lines = [
        f"# Fidelity of {ver.name}, measured ({Path(ver.measured.path).name})",
        "",
        f"**{judgement.line}**",
        "",
    ]
    if judgement.causes:
        lines += ["Why it fails:", "", *(f"- {c}" for c in judgement.causes), ""]
    lines += [
        f"Compared: {judgement.compared}.",
        "",
        f"Measured: {ver.measured.words()}."
        + (f" Not measured, so not judged: {', '.join(not_measured)}." if not_measured else ""),
        "",
        f"Reference: {ver.name}" + (f" ({info.summary()})" if info is not None else "") + ".",
        "",
        f"What this check can see, at {format_length(tolerance[0])} | "
        f"{format_angle(tolerance[1])}: {sensitivity_words(judgement.sensitivity)}.",
        "",
        f"Latency: {seconds(ver.latency_s)} (> 0: the phantom late); clock offset "
        f"{ver.clock_offset_s:+.6g} s ({ver.clock}); "
        + (
            f"judged against --max-latency {seconds(ver.max_latency_s)}."
            if judgement.latency_judged
            else "not judged: the clocks' relation was not given."
        ),
        "",
        "What was removed before the figures (they are those of the motion with its latency "
        "removed; the latency is given on its own):",
        "",
        *(f"- {what}" for what in ver.removed),
    ]
    lines += startup_lines(ver, fid)
    lines += fidelity_lines(fid)
    lines += anchor_lines(fid)
    return "\n".join(lines) + "\n"


def verification_figures(ver: Verification) -> dict:
    """What a measured motion's JSON adds to a reproduction's keys (whose ``passed`` is the
    judgement's): ``verdict`` (:meth:`~.measured_verdict.Judgement.as_dict`: the line, what
    it compares, the causes, per-axis figures, the sensitivity), ``latency_s`` and
    ``clock_offset_s`` (s), ``max_latency_s`` and ``shift_s`` (measured time + shift = the
    reference's), ``clock`` (how the offset was known), ``measured`` (the file, its kind, the
    axes it measured and those it did not), ``frame`` (:meth:`~.alignment.Frames.as_dict`),
    ``offsets_removed`` (6,) (rad and m, zeros unless the ``"axes"`` frames) and ``removed``
    (the report's lines)."""
    m = ver.measured
    return {
        "verdict": ver.judgement.as_dict(),
        "latency_s": ver.latency_s,
        "max_latency_s": ver.max_latency_s,
        "clock_offset_s": ver.clock_offset_s,
        "shift_s": ver.shift_s,
        "clock": ver.clock,
        "measured": {
            "path": m.path,
            "kind": m.kind,
            "axes": ver.fidelity["measured"],
            "not_measured": [a for a, k in zip(AXES, m.measured) if not k],
            "samples": len(m.t),
            "layout": m.layout,
        },
        "frame": ver.frame.as_dict(),
        "offsets_removed": [float(v) for v in ver.offsets],
        "removed": list(ver.removed),
    }


def write_verification(ver: Verification, out, stem: str) -> tuple[Path, Path, Path]:
    """Write ``<stem>.md``, ``<stem>.png`` and ``<stem>.json`` into ``out``: the page of
    :func:`verification_markdown`, the reproduction's figure
    (:func:`~.fidelity_figure.plot_report`) and its JSON with :func:`verification_figures`
    added (:func:`~.fidelity_report.write_report`).

    Returns:
        the three paths.
    """
    return write_report(
        ver,
        out,
        ver.tolerance,
        stem,
        text=verification_markdown(ver),
        extra=verification_figures(ver),
    )


__all__ = ["verification_markdown", "verification_figures", "write_verification"]
