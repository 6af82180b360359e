"""The page of an internal motion judged with its surrogate (:mod:`.pair_judgement`): the three
verdicts, the relative latency with its definition, each motion's shift and latency, written
beside each motion's own report."""

from __future__ import annotations

import math
from pathlib import Path

from ..base.tables import markdown_lines
from .measured_verdict import (
    seconds,
)
from .pair_judgement import DEFINITION, PairVerification


def pair_markdown(pair: PairVerification) -> str:
    """The pair's page: the three verdicts, the relative latency with its definition, each
    motion's shift and latency, and where each motion's own report is."""
    rows = []
    for what, ver in (("internal", pair.internal), ("surrogate", pair.surrogate)):
        rms = [v for v in ver.fidelity["rms"] if not math.isnan(v)]
        rows.append(
            [
                what,
                ver.name,
                Path(ver.measured.path).name,
                ", ".join(ver.fidelity["measured"]),
                f"{-ver.shift_s:+.4f}",
                f"{max(rms) * 1e3:.3g}",
                ver.judgement.verdict,
            ]
        )
    lines = [
        f"# {pair.internal.name} with its surrogate {pair.surrogate.name}, measured on one clock",
        "",
        f"**{'PASS' if pair.passed else 'FAIL'}**: the relative latency, and neither fidelity "
        "failing (one that cannot be judged at the tolerance is said so below).",
        "",
        f"- {pair.internal.judgement.line}",
        f"- {pair.surrogate.judgement.line}",
        f"- **{pair.judgement.line}**",
        "",
        f"Relative latency: {seconds(pair.relative_latency_s)} ({DEFINITION}). Searched "
        f"within {seconds(pair.searched_s[0])} to {seconds(pair.searched_s[1])}; the bound "
        f"+-{seconds(pair.judgement.max_relative_latency_s)}.",
        "",
        *markdown_lines(
            [
                "motion",
                "reference",
                "measured",
                "axes",
                "delay behind its reference [s]",
                "largest RMS error [mm or rad x 1e3]",
                "verdict",
            ],
            rows,
            [None, None, None, None, "right", "right", None],
        ),
        "",
        "Each delay is -d, on the measured clock: it holds the clocks' offset unless "
        "--clock-offset was given; their difference, the relative latency, does not.",
    ]
    lines += [""] + [f"- {n}" for n in pair.notes] if pair.notes else []
    return "\n".join(lines) + "\n"


def write_pair(pair: PairVerification, out, stems) -> list:
    """Write each motion's report (as ``verify`` does: ``<stem>.md|.png|.json``) and the
    pair's ``<stem>.md`` (:func:`pair_markdown`) and ``<stem>.json``
    (:meth:`PairVerification.as_dict`) into ``out``, the stems (internal, surrogate, pair).

    Returns:
        the paths written.
    """
    import json

    from ..base.fileio import atomic_write
    from .report import write_verification

    out = Path(out)
    written = [*write_verification(pair.internal, out, stems[0])]
    written += write_verification(pair.surrogate, out, stems[1])
    md, js = out / f"{stems[2]}.md", out / f"{stems[2]}.json"
    text = pair_markdown(pair)
    atomic_write(md, lambda f: f.write(text.encode()))
    data = json.dumps(pair.as_dict(), indent=1)
    atomic_write(js, lambda f: f.write(data.encode()))
    return written + [md, js]


__all__ = [
    "pair_markdown",
    "write_pair",
]
