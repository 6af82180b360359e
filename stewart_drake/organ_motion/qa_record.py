"""A QA record of a verification (``stewart-drake verify --record``): one PDF a physicist signs
and files, and the same results as named values that a QATrack+ test list takes.

The record holds what a QA record of a motion phantom needs to stand on its own (after AAPM
TG-142's tolerance and action levels and pylinac's ``results()``, ``results_data()`` and
``publish_pdf()``, which leave the database to QATrack+): the verdict against the tolerance and,
when given, an action level; per measured axis the RMS and peak error beside the tolerance
they are judged against; the causes of a FAIL or why the check cannot judge; the plots of the
verification's report (measured against reference per axis, the error over time, gamma); the
assumptions (the frames and the registration with its uncertainty, the clocks, the window);
every input's name, size and SHA-256; the phantom (scenario, serial); the software's versions;
the date, the operator and the notes; and lines to sign.

The levels, per axis: an RMS error beyond the tolerance FAILs (the verdict of
:func:`~.measured_verdict.judge`, unchanged); one within it but beyond the action level is
ACTION (within tolerance, to be looked at before it fails: TG-142's action level, pylinac's
``action_tolerance``); the verdict is the worst of the axes, and CANNOT JUDGE when the judgement
cannot (:func:`~.verdict_sensitivity.motion_unseen`).

Records are never overwritten: each is named by its verdict's time, and a name already taken
gets ``-2``, ``-3``... (the file is created exclusively).

The PDF is written with reportlab (the ``qa`` extra), which pylinac uses for its own.
"""

from __future__ import annotations

import hashlib
import json
import math
import os
import platform
from dataclasses import dataclass
from datetime import datetime
from pathlib import Path

import numpy as np

from ..base.errors import CorruptFileError, InvalidConfigError, MissingExtraError
from .fidelity import AXES, format_angle, format_length

#: The record's JSON layout; a reader checks it before reading the values.
RECORD_SCHEMA = "stewart-drake/verify-record/1"
#: The verdicts of a record, worst last.
LEVELS = ("PASS", "ACTION", "CANNOT JUDGE", "FAIL")
#: The longest operator, serial or notes a record takes, characters.
MAX_TEXT = 2000
#: The largest input whose SHA-256 a record gives, bytes (the trace reader's own bound).
MAX_INPUT_BYTES = 256e6
#: The largest record's JSON read back, bytes.
MAX_RECORD_BYTES = 10_000_000
#: How many records of one name and second a folder may hold before the writer gives up.
MAX_SAME_NAME = 1000


@dataclass(frozen=True)
class RecordContext:
    """What the physicist adds to a record.

    Attributes:
        operator: who ran the QA. phantom_serial: the phantom's serial number. notes: free text.
        scenario: the phantom's scenario (its name or file). action_level: (m, rad) per-axis
            RMS errors beyond which a result within tolerance is ACTION, or None (no action
            level). inputs: the files the verdict read (the measured file, the reference's
            trace, the registration). identities: each input's :func:`file_identity` taken
            before it was read, or none: the record's must be the same, or the file changed
            while it was judged and no record is written.
    """

    operator: str = ""
    phantom_serial: str = ""
    notes: str = ""
    scenario: str = ""
    action_level: tuple | None = None
    inputs: tuple = ()
    identities: tuple = ()

    def check(self, tolerance: tuple[float, float]) -> None:
        """Refuse, before any work, texts longer than :data:`MAX_TEXT` and an action level
        that is not within (0, tolerance] on both kinds of axis.

        Raises:
            InvalidConfigError: naming the option.
        """
        for option, text in (
            ("--operator", self.operator),
            ("--phantom-serial", self.phantom_serial),
            ("--notes", self.notes),
        ):
            if len(text) > MAX_TEXT:
                raise InvalidConfigError(
                    f"{option}: {len(text)} characters, at most {MAX_TEXT} in a record"
                )
        if self.action_level is not None:
            from .fidelity import format_angle, format_length

            for value, limit, what, shown in zip(
                self.action_level, tolerance, ("length", "angle"), (format_length, format_angle)
            ):
                if not 0.0 < value <= limit:
                    raise InvalidConfigError(
                        f"--action-level: its {what} must be above 0 and at most the "
                        f"--tolerance's {shown(limit)}, got {shown(value)}"
                    )


def file_identity(path) -> dict:
    """{"name", "path", "bytes", "sha256"} of an input file, read by the checked reader (at
    most :data:`MAX_INPUT_BYTES`: the inputs a verdict reads were read whole already).

    Raises:
        CorruptFileError: not a regular file, or larger than :data:`MAX_INPUT_BYTES`.
    """
    from ..base.fileio import check_parse_memory, read_checked

    p = Path(path)
    raw = read_checked(p, "input of the verdict", MAX_INPUT_BYTES)
    check_parse_memory(p, "input of the verdict", raw)  # hashed as read: nothing beyond it
    return {
        "name": p.name,
        "path": str(p.resolve()),
        "bytes": len(raw),
        "sha256": hashlib.sha256(raw).hexdigest(),
    }


def software_versions() -> dict:
    """{package: version} of the software a verdict depends on, and the Python and platform."""
    from importlib.metadata import PackageNotFoundError, version

    out = {}
    for package in ("stewart-drake", "drake", "numpy", "scipy", "matplotlib"):
        try:
            out[package] = version(package)
        except PackageNotFoundError:
            out[package] = "not installed"
    out["python"] = platform.python_version()
    out["platform"] = platform.platform()
    return out


def axis_levels(ver, tolerance, action_level) -> dict:
    """{axis: level} per measured axis: FAIL beyond the tolerance, ACTION beyond the action
    level (when given), else PASS (module docstring)."""
    rms = ver.fidelity["rms"]
    out = {}
    for k in np.flatnonzero(ver.measured.measured):
        limit = tolerance[0] if k >= 3 else tolerance[1]
        action = None if action_level is None else action_level[0 if k >= 3 else 1]
        value = rms[k]
        if not value <= limit:
            out[AXES[k]] = "FAIL"
        elif action is not None and value > action:
            out[AXES[k]] = "ACTION"
        else:
            out[AXES[k]] = "PASS"
    return out


def record_verdict(ver, tolerance, action_level) -> str:
    """The record's verdict (module docstring): the judgement's FAIL or CANNOT JUDGE as it is;
    a PASS is ACTION when an axis is beyond the action level."""
    verdict = ver.judgement.verdict
    if verdict != "PASS":
        return verdict
    return "ACTION" if "ACTION" in axis_levels(ver, tolerance, action_level).values() else "PASS"


def results_data(ver, tolerance, context: RecordContext, when: datetime) -> dict:
    """The record's values as JSON, each under a name a QATrack+ test's macro can take
    (letters, digits and underscores): ``verdict``, ``passed``, ``tolerance_mm`` /
    ``tolerance_deg``, ``action_mm`` / ``action_deg`` (None without), ``rms_<axis>_mm`` or
    ``_deg`` and ``peak_<axis>_...`` per axis (None for an axis not measured), ``level_<axis>``,
    ``latency_ms``, ``latency_judged``, ``gamma_pass_rate_pct`` (None without translations),
    ``window_s``, the identity (``reference``, ``measured_file``, ``inputs`` with their SHA-256,
    ``scenario``, ``phantom_serial``, ``operator``, ``notes``, ``date``, ``software``), the
    judgement's ``line`` and ``causes``, and ``schema`` (:data:`RECORD_SCHEMA`)."""
    fid = ver.fidelity
    levels = axis_levels(ver, tolerance, context.action_level)
    action = context.action_level
    out: dict = {
        "schema": RECORD_SCHEMA,
        "verdict": record_verdict(ver, tolerance, action),
        "passed": bool(ver.judgement.passed),
        "tolerance_mm": tolerance[0] * 1e3,
        "tolerance_deg": math.degrees(tolerance[1]),
        "action_mm": None if action is None else action[0] * 1e3,
        "action_deg": None if action is None else math.degrees(action[1]),
    }
    for k, axis in enumerate(AXES):
        unit, scale = ("mm", 1e3) if k >= 3 else ("deg", math.degrees(1.0))
        seen = axis in levels
        name = axis.lower()
        out[f"rms_{name}_{unit}"] = float(fid["rms"][k]) * scale if seen else None
        out[f"peak_{name}_{unit}"] = float(fid["peak"][k]) * scale if seen else None
        out[f"level_{name}"] = levels.get(axis)
    gamma = fid["gamma"][0]
    translations = not math.isnan(fid["rms_translation_m"])
    out.update(
        {
            "latency_ms": ver.latency_s * 1e3,
            "latency_judged": bool(ver.judgement.latency_judged),
            "max_latency_ms": ver.max_latency_s * 1e3,
            "gamma_pass_rate_pct": 100 * gamma["pass_rate"] if translations else None,
            "gamma_criteria": f"{gamma['distance_m'] * 1e3:g} mm / {gamma['time_s'] * 1e3:g} ms",
            "window_s": [float(v) for v in fid["window_s"]],
            "reference": ver.name,
            "measured_file": Path(ver.measured.path).name,
            "inputs": _unchanged_inputs(context),
            "frames": ver.frame.words(ver.offsets, ver.measured.measured),
            "clock": ver.clock,
            "clock_offset_s": ver.clock_offset_s,
            "scenario": context.scenario,
            "phantom_serial": context.phantom_serial,
            "operator": context.operator,
            "notes": context.notes,
            "date": when.isoformat(timespec="seconds"),
            "software": software_versions(),
            "line": ver.judgement.line,
            "causes": list(ver.judgement.causes),
            "cannot_judge": ver.judgement.cannot_judge,
        }
    )
    return out


def _unchanged_inputs(context: RecordContext) -> list:
    """The inputs' :func:`file_identity`, each the one taken before the verdict read it.

    Raises:
        CorruptFileError: an input whose bytes changed since (the record would give the hash
            of a file the verdict did not judge).
    """
    now = [file_identity(p) for p in context.inputs]
    before = {i["path"]: i for i in context.identities}
    for i in now:
        then = before.get(i["path"])
        if then is not None and then["sha256"] != i["sha256"]:
            raise CorruptFileError(
                i["path"],
                "input of the verdict",
                f"it changed while it was judged (SHA-256 {then['sha256'][:12]}... before, "
                f"{i['sha256'][:12]}... now): no record written",
                "verify it again",
            )
    return now


def _exclusive(folder: Path, stem: str, suffixes: tuple) -> tuple:
    """Paths ``folder/stem[-n]<suffix>`` for each suffix, none of which exists, each created
    empty and exclusively (another process cannot take them meanwhile).

    Raises:
        InvalidConfigError: :data:`MAX_SAME_NAME` names taken.
    """
    folder.mkdir(parents=True, exist_ok=True)
    for n in range(1, MAX_SAME_NAME + 1):
        name = stem if n == 1 else f"{stem}-{n}"
        paths = tuple(folder / f"{name}{s}" for s in suffixes)
        made = []
        try:
            for p in paths:
                os.close(os.open(p, os.O_CREAT | os.O_EXCL | os.O_WRONLY, 0o644))
                made.append(p)
        except FileExistsError:
            for p in made:
                p.unlink()
            continue
        return paths
    raise InvalidConfigError(
        f"{folder}: {MAX_SAME_NAME} records named {stem}: choose another --out"
    )


def write_record(ver, out, tolerance, context: RecordContext, figure: Path, stem: str) -> tuple:
    """Write the QA record of a verification into ``out/records``: ``<stem>_<time>.pdf``
    (:func:`record_pdf`) and ``<stem>_<time>.json`` (:func:`results_data`), never over an
    earlier one (module docstring).

    Args:
        ver: the :class:`~.verification.Verification`. out: the output folder. tolerance:
            (m, rad). context: :class:`RecordContext`. figure: the verification's PNG (its
            report's plots). stem: the report's stem.
    Returns:
        (pdf path, json path).
    Raises:
        MissingExtraError: reportlab is not installed (the ``qa`` extra), before any file.
        InvalidConfigError: :func:`_exclusive`'s.
    """
    _reportlab()
    when = datetime.now().astimezone()
    data = results_data(ver, tolerance, context, when)
    pdf, js = _exclusive(Path(out) / "records", f"{stem}_{when:%Y%m%dT%H%M%S}", (".pdf", ".json"))
    try:  # the PDF first: a JSON saying PASS never stands beside an empty or cut PDF
        record_pdf(pdf, data, figure)
        js.write_text(json.dumps(data, indent=2) + "\n")
    except BaseException:  # an error, Ctrl-C: neither of the two files this call made stays
        for p in (pdf, js):
            p.unlink(missing_ok=True)
        raise
    return pdf, js


def _reportlab():
    """reportlab, or the error that names the extra: asked before any file is written, so a
    missing extra leaves nothing behind (:func:`record_pdf` imports what it draws with)."""
    try:
        import reportlab
    except ImportError:
        raise MissingExtraError(
            'a QA record is a PDF written by reportlab: pip install -e ".[qa]" (or leave '
            "--record out: verify's .md, .png and .json are written without it)"
        ) from None
    return reportlab


#: The colour of each verdict on the record's first page.
_VERDICT_COLOURS = dict(zip(LEVELS, ("#1a7f37", "#b35900", "#5a5a5a", "#c62828")))


class _Flowables:
    """The record's reportlab styles, and its paragraphs and tables made with them."""

    def __init__(self):
        from reportlab.lib import colors
        from reportlab.lib.styles import ParagraphStyle, getSampleStyleSheet

        self.colors = colors
        self.styles = getSampleStyleSheet()
        self.body = ParagraphStyle("body", parent=self.styles["BodyText"], fontSize=9, leading=11.5)
        self.small = ParagraphStyle("small", parent=self.body, fontSize=7.5, leading=9.5)
        self.head = self.styles["Heading3"]

    def p(self, text, style=None):
        """A paragraph of ``text``, escaped (a file's name is text, not markup)."""
        from xml.sax.saxutils import escape

        from reportlab.platypus import Paragraph

        return Paragraph(escape(str(text)), style or self.body)

    def table(self, rows, widths, header=True):
        """A gridded table, its first row shaded when it is a ``header``."""
        from reportlab.platypus import Table, TableStyle

        t = Table(rows, colWidths=widths, hAlign="LEFT")
        style = [
            ("FONTSIZE", (0, 0), (-1, -1), 8.5),
            ("VALIGN", (0, 0), (-1, -1), "TOP"),
            ("GRID", (0, 0), (-1, -1), 0.4, self.colors.grey),
        ]
        if header:
            style.append(("BACKGROUND", (0, 0), (-1, 0), self.colors.HexColor("#e8e8e8")))
        t.setStyle(TableStyle(style))
        return t


def _axis_rows(data: dict) -> list:
    """The per-axis table of the record: a header, then each axis judged (RMS and peak error,
    tolerance, action level, its level)."""
    rows = [["axis", "RMS error", "peak error", "tolerance", "action level", "level"]]
    for k, axis in enumerate(AXES):
        name = axis.lower()
        unit = "mm" if k >= 3 else "deg"
        if data[f"level_{name}"] is None:
            continue
        rms, peak = data[f"rms_{name}_{unit}"], data[f"peak_{name}_{unit}"]
        show = format_length if k >= 3 else format_angle
        scale = 1e-3 if k >= 3 else math.radians(1.0)
        limit = data["tolerance_mm"] if k >= 3 else data["tolerance_deg"]
        act = data["action_mm"] if k >= 3 else data["action_deg"]
        rows.append(
            [
                axis,
                show(rms * scale),
                show(peak * scale),
                show(limit * scale),
                "-" if act is None else show(act * scale),
                data[f"level_{name}"],
            ]
        )
    return rows


def _latency_and_gamma(data: dict) -> str:
    """The record's line on the latency (judged or not) and the gamma pass rate."""
    from .verification import seconds

    gamma = (
        "not computed (no translation measured)"
        if data["gamma_pass_rate_pct"] is None
        else f"{data['gamma_pass_rate_pct']:.4g} % at {data['gamma_criteria']}"
    )
    latency = seconds(data["latency_ms"] * 1e-3) + (
        f", judged against {seconds(data['max_latency_ms'] * 1e-3)}"
        if data["latency_judged"]
        else ", not judged (the clocks' relation not given)"
    )
    return f"Latency {latency}. Gamma pass rate {gamma}."


def _signature_table(f: _Flowables):
    """The lines to sign: performed by, reviewed by, each with its signature and date."""
    from reportlab.lib.units import mm
    from reportlab.platypus import Table, TableStyle

    grey = f.colors.HexColor("#e8e8e8")
    return Table(
        [
            ["Performed by", "Signature", "Date"],
            ["", "", ""],
            ["Reviewed by", "Signature", "Date"],
            ["", "", ""],
        ],
        colWidths=[60 * mm, 60 * mm, 50 * mm],
        rowHeights=[6 * mm, 14 * mm, 6 * mm, 14 * mm],
        hAlign="LEFT",
        style=TableStyle(
            [
                ("FONTSIZE", (0, 0), (-1, -1), 8.5),
                ("GRID", (0, 0), (-1, -1), 0.4, f.colors.grey),
                ("BACKGROUND", (0, 0), (-1, 0), grey),
                ("BACKGROUND", (0, 2), (-1, 2), grey),
            ]
        ),
    )


def _assumptions_and_inputs(data: dict, f: _Flowables) -> list:
    """The record's verdict line, its assumptions (frames, clock, window), its inputs with their
    SHA-256 and the phantom, operator and software."""
    from reportlab.lib.units import mm

    p, small, head = f.p, f.small, f.head
    software = ", ".join(f"{k} {v}" for k, v in data["software"].items())
    return [
        p("Verdict", head),
        p(data["line"], small),
        p("Assumptions", head),
        p(f"Frames: {data['frames']}"),
        p(
            f"Clock: {data['clock']} (offset {data['clock_offset_s']:+.6g} s); window t = "
            f"{data['window_s'][0]:.4g} to {data['window_s'][1]:.4g} s of the reference."
        ),
        p("Inputs", head),
        f.table(
            [["file", "bytes", "SHA-256"]]
            + [
                [p(i["name"], small), str(i["bytes"]), p(i["sha256"], small)]
                for i in data["inputs"]
            ],
            [50 * mm, 20 * mm, 100 * mm],
        ),
        p("Phantom, operator, software", head),
        f.table(
            [
                ["phantom (scenario)", p(data["scenario"] or "-", small)],
                ["serial", p(data["phantom_serial"] or "-", small)],
                ["operator", p(data["operator"] or "-", small)],
                ["date", data["date"]],
                ["notes", p(data["notes"] or "-", small)],
                ["software", p(software, small)],
            ],
            [40 * mm, 130 * mm],
            header=False,
        ),
    ]


def _record_story(data: dict, figure, f: _Flowables) -> list:
    """The record's flowables: page 1 the verdict, the per-axis table, the causes, the
    assumptions, the inputs, the phantom, the software and the lines to sign; page 2 the
    verification's plots (when ``figure`` exists)."""
    from reportlab.lib.styles import ParagraphStyle
    from reportlab.lib.units import mm
    from reportlab.platypus import Image, PageBreak, Spacer

    p, head, styles = f.p, f.head, f.styles
    verdict = data["verdict"]
    big = ParagraphStyle(
        "verdict",
        parent=styles["Title"],
        textColor=f.colors.HexColor(_VERDICT_COLOURS[verdict]),
        fontSize=26,
        leading=30,
    )
    tol = f"{data['tolerance_mm']:g} mm | {data['tolerance_deg']:g} deg RMS per axis"
    action = (
        "none given"
        if data["action_mm"] is None
        else f"{data['action_mm']:g} mm | {data['action_deg']:g} deg RMS per axis"
    )
    story = [
        p("Motion phantom QA record", styles["Title"]),
        p(f"{data['reference']} measured in {data['measured_file']}", styles["Heading2"]),
        p(verdict, big),
        p(f"Tolerance {tol}; action level {action}."),
        Spacer(1, 3 * mm),
        f.table(_axis_rows(data), [18 * mm, 28 * mm, 28 * mm, 28 * mm, 28 * mm, 28 * mm]),
        Spacer(1, 3 * mm),
        p(_latency_and_gamma(data)),
    ]
    if data["causes"]:
        story += [p("Why it fails", head), *(p(f"- {c}") for c in data["causes"])]
    if data["cannot_judge"]:
        story += [p("Why it cannot judge", head), p(data["cannot_judge"])]
    story += [*_assumptions_and_inputs(data, f), Spacer(1, 10 * mm), _signature_table(f)]
    if figure is not None and Path(figure).exists():
        from PIL import Image as PILImage

        with PILImage.open(figure) as im:
            w, h = im.size
        width = 180 * mm
        story += [
            PageBreak(),
            p("The verification's plots", styles["Heading2"]),
            Image(str(figure), width=width, height=width * h / w),
        ]
    return story


def record_pdf(path: Path, data: dict, figure: Path) -> None:
    """The record's PDF (A4): page 1 the verdict, the per-axis table, the causes, the
    assumptions, the inputs, the phantom, the software and the lines to sign; page 2 the
    verification's plots."""
    from reportlab.lib.pagesizes import A4
    from reportlab.lib.units import mm
    from reportlab.platypus import SimpleDocTemplate

    story = _record_story(data, figure, _Flowables())

    def footer(canvas, doc):
        canvas.saveState()
        canvas.setFont("Helvetica", 7)
        canvas.drawString(
            15 * mm,
            8 * mm,
            f"{data['reference']} / {data['measured_file']} / {data['date']} / "
            f"{data['verdict']} / page {doc.page}",
        )
        canvas.restoreState()

    doc = SimpleDocTemplate(
        str(path),
        pagesize=A4,
        leftMargin=15 * mm,
        rightMargin=15 * mm,
        topMargin=12 * mm,
        bottomMargin=15 * mm,
        title=f"QA record: {data['reference']}, {data['measured_file']}",
        author=data["operator"] or "stewart-drake verify",
    )
    doc.build(story, onFirstPage=footer, onLaterPages=footer)


def read_results(path) -> dict:
    """A record's JSON, checked: a file written by :func:`write_record` (its ``schema``).

    Raises:
        CorruptFileError: larger than :data:`MAX_RECORD_BYTES`, not JSON, or not a record of
            :data:`RECORD_SCHEMA`.
    """
    from ..base.errors import CorruptFileError
    from ..base.fileio import read_json

    data = read_json(path, "QA record", "give a record verify --record wrote", MAX_RECORD_BYTES)
    if not isinstance(data, dict) or data.get("schema") != RECORD_SCHEMA:
        raise CorruptFileError(path, "QA record", f"not a record of {RECORD_SCHEMA}")
    return data


__all__ = [
    "RECORD_SCHEMA",
    "LEVELS",
    "RecordContext",
    "file_identity",
    "software_versions",
    "axis_levels",
    "record_verdict",
    "results_data",
    "write_record",
    "record_pdf",
    "read_results",
]
