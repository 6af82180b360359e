"""The PDF of a QA record (:mod:`.qa_record`), drawn with reportlab (the ``qa`` extra) from the
record's values (:func:`~.qa_record.results_data`) and its plots
(:func:`~.qa_record_figure.record_figure`).

The pages: the first the verdict, the per-axis tables (translations in mm, rotations in deg:
one unit per column, :func:`axis_tables`), the causes, the measurement (the reference with its
parameters, the device and its independence, the cycles judged), the phantom, the software and
the lines to sign; the second the verdict's line as the terminal said it, the assumptions and
the inputs with their SHA-256; the last the plots. No table is split across pages, and each
page's foot names the record, its verdict and "page X of Y".
"""

from __future__ import annotations

import functools
import io
import unicodedata
from pathlib import Path

from ..organ_motion.fidelity import AXES

#: The record's typeface: matplotlib's own DejaVu Sans (Latin, Greek, Cyrillic and more; always
#: installed with matplotlib), embedded, so that a name in those scripts is drawn where the
#: PDF's standard Helvetica would lose it to missing glyphs.
FONT = "DejaVuSans"
#: Its faces: regular, bold, oblique, bold oblique (reportlab's names, as registered).
_FACES = {"": FONT, "-Bold": f"{FONT}-Bold", "-Oblique": f"{FONT}-Oblique"}
_FACES["-BoldOblique"] = f"{FONT}-BoldOblique"


def _font_file(face: str = "") -> Path:
    """The TrueType file of a face of :data:`FONT` in matplotlib's data."""
    import matplotlib

    return Path(matplotlib.get_data_path()) / "fonts" / "ttf" / f"{FONT}{face}.ttf"


@functools.lru_cache(maxsize=1)
def _drawable_codepoints() -> frozenset:
    """The code points :data:`FONT` has a glyph for (its cmap, read with fontTools, a
    dependency of matplotlib)."""
    from fontTools.ttLib import TTFont

    with TTFont(str(_font_file()), lazy=True) as font:
        return frozenset(font.getBestCmap())


def undrawable(text: str) -> str:
    """Why the record's PDF cannot draw ``text``, in words naming its first such character, or
    "": a character of no glyph in :data:`FONT` (Japanese, Devanagari...), a right-to-left one
    (Hebrew, Arabic: reportlab draws them left to right, unshaped), or a byte that is not
    UTF-8 (read from the command line as a lone surrogate)."""
    from ..base.checks import undecoded_byte

    glyphs = _drawable_codepoints()
    for i, c in enumerate(text):
        code = ord(c)
        if 0xD800 <= code <= 0xDFFF:
            return f"a byte that is not UTF-8 ({undecoded_byte(c)}) at character {i + 1}"
        if unicodedata.bidirectional(c) in ("R", "AL"):
            what = "a right-to-left character"
        elif code not in glyphs and unicodedata.category(c)[0] != "C":
            what = f"a character of no glyph in {FONT}"
        else:
            continue
        return f"{what} ({c!r}, {unicodedata.name(c, f'U+{code:04X}')}) at character {i + 1}"
    return ""


def drawable(text) -> str:
    """``text`` with every character the PDF cannot draw (:func:`undrawable`) written as its
    escape (``\\u65e5``, ``\\udce9``): a file's name is shown whole, never with a glyph
    lost."""
    out = []
    for c in str(text):
        if undrawable(c):
            out.append(c.encode("unicode_escape").decode("ascii"))
        else:
            out.append(c)
    return "".join(out)


def _register_fonts() -> None:
    """Register :data:`FONT`'s faces with reportlab (once) as one family."""
    from reportlab.pdfbase import pdfmetrics
    from reportlab.pdfbase.ttfonts import TTFont

    if FONT in pdfmetrics.getRegisteredFontNames():
        return
    for face, name in _FACES.items():
        pdfmetrics.registerFont(TTFont(name, str(_font_file(face))))
    pdfmetrics.registerFontFamily(
        FONT,
        normal=FONT,
        bold=_FACES["-Bold"],
        italic=_FACES["-Oblique"],
        boldItalic=_FACES["-BoldOblique"],
    )


#: The colour of each verdict on the record's first page.
_VERDICT_COLOURS = {
    "PASS": "#1a7f37",
    "ACTION": "#b35900",
    "CANNOT JUDGE": "#5a5a5a",
    "FAIL": "#c62828",
}


class _Flowables:
    """The record's reportlab styles, and its paragraphs and tables made with them."""

    def __init__(self):
        from reportlab.lib import colors
        from reportlab.lib.styles import ParagraphStyle, getSampleStyleSheet

        _register_fonts()
        self.colors = colors
        self.styles = getSampleStyleSheet()
        for style in self.styles.byName.values():  # every text style in DejaVu Sans's faces
            if not hasattr(style, "fontName"):
                continue
            bold = "Bold" in style.fontName
            oblique = "Oblique" in style.fontName or "Italic" in style.fontName
            face = ("Bold" if bold else "") + ("Oblique" if oblique else "")
            style.fontName = _FACES[f"-{face}" if face else ""]
        self.body = ParagraphStyle("body", parent=self.styles["BodyText"], fontSize=9, leading=11.5)
        self.small = ParagraphStyle("small", parent=self.body, fontSize=7.5, leading=9.5)
        self.head = self.styles["Heading3"]

    def p(self, text, style=None):
        """A paragraph of ``text``, escaped (a file's name is text, not markup) and drawable
        (:func:`drawable`)."""
        from xml.sax.saxutils import escape

        from reportlab.platypus import Paragraph

        return Paragraph(escape(drawable(text)), style or self.body)

    def table(self, rows, widths, header=True):
        """A gridded table, its first row shaded when it is a ``header``."""
        from reportlab.platypus import Table, TableStyle

        rows = [[drawable(c) if isinstance(c, str) else c for c in row] for row in rows]
        t = Table(rows, colWidths=widths, hAlign="LEFT")
        style = [
            ("FONTNAME", (0, 0), (-1, -1), FONT),
            ("FONTSIZE", (0, 0), (-1, -1), 8.5),
            ("VALIGN", (0, 0), (-1, -1), "TOP"),
            ("GRID", (0, 0), (-1, -1), 0.4, self.colors.grey),
            ("TOPPADDING", (0, 0), (-1, -1), 1.5),
            ("BOTTOMPADDING", (0, 0), (-1, -1), 1.5),
        ]
        if header:
            style.append(("BACKGROUND", (0, 0), (-1, 0), self.colors.HexColor("#e8e8e8")))
        t.setStyle(TableStyle(style))
        return t


def axis_tables(data: dict) -> list:
    """The record's per-axis tables, one per kind of axis measured, each in one unit: [(title,
    rows)], rows a header naming the unit then each axis judged (RMS and peak error, tolerance,
    action level, level). Translations in mm, rotations in deg (the JSON's units)."""
    tables = []
    for title, unit, names in (
        ("Translation", "mm", AXES[3:]),
        ("Rotation", "deg", AXES[:3]),
    ):
        rows = [
            [
                "axis",
                f"RMS error [{unit}]",
                f"peak error [{unit}]",
                f"tolerance [{unit}]",
                f"action level [{unit}]",
                "level",
            ]
        ]
        limit, act = data[f"tolerance_{unit}"], data[f"action_{unit}"]
        for axis in names:
            name = axis.lower()
            if data[f"level_{name}"] is None:
                continue
            rows.append(
                [
                    axis,
                    f"{data[f'rms_{name}_{unit}']:.4f}",
                    f"{data[f'peak_{name}_{unit}']:.4f}",
                    f"{limit:.4f}",
                    "-" if act is None else f"{act:.4f}",
                    data[f"level_{name}"],
                ]
            )
        if len(rows) > 1:
            tables.append((title, rows))
    return tables


def _latency_and_gamma(data: dict) -> str:
    """The record's line on the latency (judged or not), the gamma pass rate and the cycles
    judged."""
    from .verify import seconds

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
    w0, w1 = data["window_s"]
    return (
        f"Latency {latency}. Gamma pass rate {gamma}. Judged over t = {w0:.4g} to {w1:.4g} s "
        f"of the reference: {data['cycles_judged']} of its cycles."
    )


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
                ("FONTNAME", (0, 0), (-1, -1), FONT),
                ("FONTSIZE", (0, 0), (-1, -1), 8.5),
                ("GRID", (0, 0), (-1, -1), 0.4, f.colors.grey),
                ("BACKGROUND", (0, 0), (-1, 0), grey),
                ("BACKGROUND", (0, 2), (-1, 2), grey),
            ]
        ),
    )


def _measurement_and_phantom(data: dict, f: _Flowables) -> list:
    """The measurement (the reference with its parameters, the device and its independence,
    the cycles judged) and the phantom, operator and software: each table kept on one page."""
    from reportlab.lib.units import mm
    from reportlab.platypus import KeepTogether

    p, small, head = f.p, f.small, f.head
    software = ", ".join(f"{k} {v}" for k, v in data["software"].items())
    return [
        KeepTogether(
            [
                p("Measurement", head),
                f.table(
                    [
                        ["reference", p(data["reference_motion"], small)],
                        ["measured", p(data["measured_file"], small)],
                        ["measuring device", p(data["measuring_device"], small)],
                        ["independent of the robot", "yes" if data["independent"] else "NO"],
                        ["cycles judged", str(data["cycles_judged"])],
                    ],
                    [44 * mm, 126 * mm],
                    header=False,
                ),
            ]
        ),
        KeepTogether(
            [
                p("Phantom, operator, software", head),
                f.table(
                    [
                        ["phantom", p(data["scenario"] or "not named by the run", small)],
                        ["serial", p(data["phantom_serial"] or "-", small)],
                        ["operator", p(data["operator"] or "-", small)],
                        ["date", data["date"]],
                        ["notes", p(data["notes"] or "-", small)],
                        ["software", p(software, small)],
                    ],
                    [44 * mm, 126 * mm],
                    header=False,
                ),
            ]
        ),
    ]


def _details(data: dict, f: _Flowables) -> list:
    """The record's verdict line in full, its assumptions (frames, clock, window) and its
    inputs with their SHA-256 (the table kept on one page)."""
    from reportlab.lib.units import mm
    from reportlab.platypus import KeepTogether

    p, small, head = f.p, f.small, f.head
    return [
        p("Verdict, as the terminal said it", head),
        p(data["line"], small),
        p("Assumptions", head),
        p(f"Frames: {data['frames']}"),
        p(
            f"Clock: {data['clock']} (offset {data['clock_offset_s']:+.6g} s); window t = "
            f"{data['window_s'][0]:.4g} to {data['window_s'][1]:.4g} s of the reference."
        ),
        KeepTogether(
            [
                p("Inputs", head),
                f.table(
                    [["file", "size [bytes]", "SHA-256"]]
                    + [
                        [p(i["name"], small), str(i["bytes"]), p(i["sha256"], small)]
                        for i in data["inputs"]
                    ],
                    [50 * mm, 20 * mm, 100 * mm],
                ),
            ]
        ),
    ]


def _record_story(data: dict, figure: bytes | None, f: _Flowables) -> list:
    """The record's flowables: the verdict, the per-axis tables, the causes, the measurement,
    the phantom, the software and the lines to sign; then the verdict's line, the assumptions
    and the inputs; then, on a page of their own, the plots (``figure``: PNG bytes, or
    None)."""

    from reportlab.lib.styles import ParagraphStyle
    from reportlab.lib.units import mm
    from reportlab.platypus import Image, KeepTogether, PageBreak, Spacer

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
        p(f"{data['reference_motion']} measured in {data['measured_file']}", styles["Heading2"]),
        p(verdict, big),
        p(f"Tolerance {tol}; action level {action}."),
    ]
    if not data["independent"]:
        story.append(
            p(
                "Measured by the robot's own encoders: not independent of the robot "
                "(Measurement, below)."
            )
        )
    for title, rows in axis_tables(data):
        story.append(
            KeepTogether(
                [
                    Spacer(1, 2 * mm),
                    p(title, head),
                    f.table(rows, [14 * mm, 29 * mm, 29 * mm, 29 * mm, 33 * mm, 22 * mm]),
                ]
            )
        )
    story += [Spacer(1, 3 * mm), p(_latency_and_gamma(data))]
    if data["causes"]:
        story += [p("Why it fails", head), *(p(f"- {c}") for c in data["causes"])]
    if data["cannot_judge"]:
        story += [p("Why it cannot judge", head), p(data["cannot_judge"])]
    story += [
        *_measurement_and_phantom(data, f),
        KeepTogether([Spacer(1, 8 * mm), _signature_table(f)]),
        PageBreak(),
        *_details(data, f),
    ]
    if figure is not None:
        from reportlab.lib.utils import ImageReader

        w, h = ImageReader(io.BytesIO(figure)).getSize()  # the plots this record drew
        width = 180 * mm
        height = min(width * h / w, 255 * mm)
        story += [
            PageBreak(),
            p(f"The plots: {verdict}, each axis against its own tolerance", styles["Heading2"]),
            Image(io.BytesIO(figure), width=height * w / h, height=height),
        ]
    return story


def record_pdf(path: Path, data: dict, figure: bytes | None) -> None:
    """The record's PDF (A4; module docstring), each page's foot naming the record, its
    verdict and "page X of Y": built once to count the pages, then written."""

    from reportlab.lib.pagesizes import A4
    from reportlab.lib.units import mm
    from reportlab.platypus import SimpleDocTemplate

    def build(target, total: int | None) -> int:
        def footer(canvas, doc):
            canvas.saveState()
            canvas.setFont(FONT, 7)
            canvas.drawString(
                15 * mm,
                8 * mm,
                drawable(
                    f"{data['reference']} / {data['measured_file']} / {data['date']} / "
                    f"{data['verdict']} / page {doc.page} of {total}"
                ),
            )
            canvas.restoreState()

        doc = SimpleDocTemplate(
            target,
            pagesize=A4,
            leftMargin=15 * mm,
            rightMargin=15 * mm,
            topMargin=12 * mm,
            bottomMargin=15 * mm,
            title=f"QA record: {data['reference']}, {data['measured_file']}",
            author=data["operator"] or "stewart-drake verify",
        )
        doc.build(
            _record_story(data, figure, _Flowables()), onFirstPage=footer, onLaterPages=footer
        )
        return doc.page

    pages = build(io.BytesIO(), None)
    build(str(path), pages)


__all__ = ["FONT", "axis_tables", "drawable", "record_pdf", "undrawable"]
