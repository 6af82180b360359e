"""The report of a measured motion (``stewart-drake verify``): the page of a
:class:`~.verification.Verification` (:func:`verification_markdown`: what was measured, what the
alignment removed, then the figures of a reproduction's report), written with the reproduction's
figure and JSON (:func:`write_verification`: reproduce's keys, then ``latency_s``,
``clock_offset_s`` and what was removed).
"""

from __future__ import annotations

from pathlib import Path

from .fidelity import verdict
from .fidelity_report import anchor_lines, fidelity_lines, startup_lines, write_report
from .verification import Verification, seconds


def verification_markdown(ver: Verification, tolerance: tuple[float, float]) -> str:
    """The Markdown page of a measured motion: the verdict, what was measured and against
    what, the latency, what the alignment removed, then the figures (per axis, gamma,
    harmonics, cycles, the start-up, the phantom anchor) as a reproduction's report gives them.
    """
    fid = ver.fidelity
    _, line = verdict(fid, tolerance)
    source = ver.reference
    info = getattr(source, "info", None) or getattr(
        getattr(source, "reference", None), "info", None
    )
    lines = [
        f"# Fidelity of {ver.name}, measured ({Path(ver.measured.path).name})",
        "",
        f"**{line}**",
        "",
        f"Measured: {ver.measured.words()}.",
        "",
        f"Reference: {ver.name}" + (f" ({info.summary()})" if info is not None else "") + ".",
        "",
        f"Latency: {seconds(ver.latency_s)} (> 0: the phantom late); clock offset "
        f"{ver.clock_offset_s:+.6g} s ({ver.clock}).",
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
    """What a measured motion's JSON adds to a reproduction's keys: ``latency_s`` and
    ``clock_offset_s`` (s), ``shift_s`` (measured time + shift = the reference's), ``clock``
    (how the offset was known), ``measured`` (the file, its kind, the axes it measured),
    ``frame`` (:meth:`~.alignment.FrameFit.as_dict`) and ``removed`` (the report's lines)."""
    m = ver.measured
    return {
        "latency_s": ver.latency_s,
        "clock_offset_s": ver.clock_offset_s,
        "shift_s": ver.shift_s,
        "clock": ver.clock,
        "measured": {
            "path": m.path,
            "kind": m.kind,
            "axes": ver.fidelity["measured"],
            "samples": len(m.t),
            "layout": m.layout,
        },
        "frame": ver.frame.as_dict(),
        "removed": list(ver.removed),
    }


def write_verification(
    ver: Verification, out, tolerance: tuple[float, float], stem: str
) -> tuple[Path, Path, Path]:
    """Write ``<stem>.md``, ``<stem>.png`` and ``<stem>.json`` into ``out``: the page of
    :func:`verification_markdown`, the reproduction's figure
    (:func:`~.fidelity_report.plot_report`) and its JSON with :func:`verification_figures`
    added (:func:`~.fidelity_report.write_report`).

    Returns:
        the three paths.
    """
    return write_report(
        ver,
        out,
        tolerance,
        stem,
        text=verification_markdown(ver, tolerance),
        extra=verification_figures(ver),
    )


__all__ = ["verification_markdown", "verification_figures", "write_verification"]
