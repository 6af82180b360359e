"""``verify --record``: the QA record a physicist signs and files, for a PASS, an ACTION and a
FAIL, its PDF's pages opened and its text read back, its JSON read by the QATrack+ upload
test's calculation procedure shown in docs/organ_motion.md (executed as QATrack+ executes it:
``FILE`` an open file, the macro name set), the inputs' SHA-256 computed independently, and no
record ever written over another."""

import hashlib
import json
import re
from pathlib import Path

import numpy as np
import pytest
from test_verify import MARKER_COLUMNS, PARAMS, phantom_run, tracker_view, write_marker_export

from stewart_drake.calibration.join import read_encoder_log, write_encoder_log
from stewart_drake.cli.main import main
from stewart_drake.verification.measured_motion import EMULATED_BUS

reportlab = pytest.importorskip("reportlab", reason='needs the qa extra: pip install -e ".[qa]"')

DOCS = Path(__file__).resolve().parent.parent / "docs" / "organ_motion.md"


def upload_procedure() -> str:
    """The QATrack+ upload test's calculation procedure, as docs/organ_motion.md shows it."""
    text = DOCS.read_text()
    m = re.search(r"<!-- qatrack-upload -->\n```python\n(.*?)```", text, re.S)
    assert m, "docs/organ_motion.md shows the upload procedure after <!-- qatrack-upload -->"
    return m.group(1)


@pytest.fixture(scope="module")
def exports(tmp_path_factory):
    """(right, wrong) marker exports seen by a tracker aligned with the base: the phantom as
    asked, and one moving 1.5x as far."""
    folder = tmp_path_factory.mktemp("record")
    t, x = phantom_run(seconds=30.0)
    wrong = x.copy()
    centre = wrong[:, 3:].mean(axis=0)
    wrong[:, 3:] = centre + 1.5 * (wrong[:, 3:] - centre)
    return (
        write_marker_export(folder / "right.csv", t, tracker_view(x, aligned=True)[:, 3:]),
        write_marker_export(folder / "wrong.csv", t, tracker_view(wrong, aligned=True)[:, 3:]),
    )


def record(tmp_path, export, *options):
    """Run ``verify --record`` on ``export``: (exit code, the PDF, the JSON)."""
    out = tmp_path / "out"
    code = main(
        ["verify", "breathing", *PARAMS, "--measured", str(export), "--measured-columns"]
        + [MARKER_COLUMNS, "--tolerance", "0.2mm,0.1deg", "--out", str(out), "--record"]
        + ["--operator", "A. Physicist", "--phantom-serial", "SD-0042", *options]
    )
    pdfs = sorted((out / "records").glob("*.pdf"))
    jsons = sorted((out / "records").glob("*.json"))
    return code, pdfs, jsons


def page_texts(pdf: Path, raw: bool = False) -> list[str]:
    """Each page's text, read back from the PDF by a reader of its own (pypdfium2 when
    installed and not ``raw``, else the raw content streams' text operators, which read the
    same on every machine)."""
    try:
        import pypdfium2 as pdfium
    except ImportError:
        pdfium = None
    if raw:
        pdfium = None
    if pdfium is not None:
        doc = pdfium.PdfDocument(str(pdf))
        return [doc[i].get_textpage().get_text_range() for i in range(len(doc))]
    import base64
    import zlib

    raw = pdf.read_bytes()
    texts = []
    # reportlab writes each stream ASCII85 then Flate encoded, one content stream a page (an
    # image's stream holds no text operator); a text operator's string is in parentheses
    # before Tj.
    for m in re.finditer(rb"stream\r?\n(.*?)endstream", raw, re.S):
        body = m.group(1).strip()
        try:
            if body.endswith(b"~>"):
                body = base64.a85decode(body.removeprefix(b"<~").removesuffix(b"~>"))
            text = zlib.decompress(body).decode("latin-1")
        except (ValueError, zlib.error):
            continue
        words = re.findall(r"\((.*?)\) Tj", text)
        if words:
            texts.append(" ".join(words))
    return texts


def test_a_pass_is_recorded_with_everything_a_physicist_signs(tmp_path, exports):
    code, pdfs, jsons = record(tmp_path, exports[0], "--notes", "monthly QA")
    assert code == 0
    assert len(pdfs) == 1 and len(jsons) == 1
    assert pdfs[0].read_bytes()[:5] == b"%PDF-"
    data = json.loads(jsons[0].read_text())
    assert data["verdict"] == "PASS" and data["passed"] is True
    assert data["operator"] == "A. Physicist" and data["phantom_serial"] == "SD-0042"
    assert data["notes"] == "monthly QA"
    # The inputs' identity, computed here independently.
    (measured,) = data["inputs"]
    body = exports[0].read_bytes()
    assert measured["sha256"] == hashlib.sha256(body).hexdigest()
    assert measured["bytes"] == len(body)
    # Per-axis figures beside the per-axis tolerance, read from the report verify wrote.
    report = json.loads(next((tmp_path / "out").glob("verify_*.json")).read_text())
    assert data["rms_x_mm"] == pytest.approx(report["fidelity"]["rms"][3] * 1e3, rel=1e-12)
    assert data["peak_x_mm"] == pytest.approx(report["fidelity"]["peak"][3] * 1e3, rel=1e-12)
    assert data["tolerance_mm"] == pytest.approx(0.2)
    assert data["rms_phi_deg"] is None and data["level_phi"] is None  # not measured
    texts = page_texts(pdfs[0])
    assert len(texts) == 3, texts
    whole = "\n".join(texts)
    for words in ("Motion phantom QA record", "PASS", "SD-0042", "A. Physicist", "Signature"):
        assert words in texts[0], words
    assert measured["sha256"][:16] in texts[1].replace("\n", "").replace(" ", "")
    assert "The plots: PASS, each axis against its own tolerance" in texts[2]
    for n in (1, 2, 3):
        assert f"/ PASS / page {n} of 3" in texts[n - 1]
    # The reference with its parameter, the device and its independence, the cycles judged, and
    # no phantom the run did not name (the default scenario is not this tracker's phantom).
    assert data["reference_motion"] == "breathing --param tilt=2deg"
    assert "breathing --param tilt=2deg measured in right.csv" in texts[0]
    assert data["independent"] is True and "external tracker" in data["measuring_device"]
    assert data["scenario"] == "" and "not named by the run" in texts[0]
    assert "phantom_hardware" not in whole
    # 30 s of a 4 s breathing judged from t = 4 s: cycles 4-8 ... 28-32, the last cut at the
    # window's end (31.93 s: within 2 % of a cycle, it counts), counted from the report's window.
    w0, w1 = report["fidelity"]["window_s"]
    assert data["cycles_judged"] == int(np.floor((w1 - 4.0) / 4.0 + 0.02)) == 7
    # One unit per column: the translation table's cells are the JSON's mm values.
    assert "RMS error [mm]" in texts[0] and "um" not in texts[0].split("Latency")[0]
    for axis in "xyz":
        assert f"{data[f'rms_{axis}_mm']:.4f}" in texts[0]
        assert f"{data[f'peak_{axis}_mm']:.4f}" in texts[0]
    assert "Rotation" not in texts[0].split("Latency")[0]  # no rotation measured: no table


def test_an_action_level_and_a_fail_are_recorded_as_such(tmp_path, exports, capsys):
    code, pdfs, jsons = record(tmp_path, exports[0], "--action-level", "0.05mm,0.05deg")
    data = json.loads(jsons[0].read_text())
    out = capsys.readouterr().out
    # The tracker's noise, 69 um per axis, is within 0.2 mm but beyond 0.05 mm: ACTION
    # everywhere: the terminal's line, the exit status (4), the report's JSON, the record's
    # JSON, its verdict's word and every page's foot.
    assert code == 4 and data["verdict"] == "ACTION" and data["passed"] is True
    assert out.startswith("ACTION: right.csv") and "beyond the action level 50 um" in out
    report = json.loads(next((tmp_path / "out").glob("verify_*.json")).read_text())
    assert report["verdict"]["verdict"] == "ACTION" and report["verdict"]["line"] == data["line"]
    assert data["line"].startswith("ACTION: ")
    assert data["level_x"] == "ACTION" and data["action_mm"] == pytest.approx(0.05)
    texts = page_texts(pdfs[0])
    assert "\nACTION\n" in f"\n{texts[0]}\n".replace(" ", "\n")
    for n, text in enumerate(texts, 1):
        assert f"/ ACTION / page {n} of {len(texts)}" in text
    assert "PASS" not in texts[0].split("Translation")[0]
    code, _, jsons = record(tmp_path / "f", exports[1])
    data = json.loads(jsons[0].read_text())
    assert code == 2 and data["verdict"] == "FAIL" and data["causes"]
    assert data["level_x"] == "FAIL"


def test_a_record_that_cannot_judge_says_so_on_every_axis_and_page(tmp_path, exports):
    """At 10 mm the phantom at rest would pass too (the reference moves X 5.4 mm RMS): CANNOT
    JUDGE, exit 3, in the JSON, on every axis (none says PASS) and every page's foot, with why
    on the first page; the action level given does not make it ACTION."""
    code, pdfs, jsons = record(
        tmp_path, exports[0], "--tolerance", "10mm,1deg", "--action-level", "5mm,1deg"
    )
    data = json.loads(jsons[0].read_text())
    assert code == 3 and data["verdict"] == "CANNOT JUDGE" and data["passed"] is False
    assert [data[f"level_{a}"] for a in "xyz"] == ["CANNOT JUDGE"] * 3
    texts = page_texts(pdfs[0])
    assert "Why it cannot judge" in texts[0] and "PASS" not in texts[0]
    for n, text in enumerate(texts, 1):
        assert f"/ CANNOT JUDGE / page {n} of {len(texts)}" in text


def test_the_action_level_grades_the_verdict_at_its_edge_without_a_record(tmp_path, exports):
    """``--action-level`` is the verdict's, with or without ``--record``: an action level just
    above the largest axis's RMS error PASSes (exit 0), one just below is ACTION (exit 4) on
    that axis alone; the RMS errors read from a first report."""
    out = tmp_path / "first"
    base = ["verify", "breathing", *PARAMS, "--measured", str(exports[0])]
    base += ["--measured-columns", MARKER_COLUMNS, "--tolerance", "0.2mm,0.1deg"]
    assert main([*base, "--out", str(out)]) == 0
    rms = json.loads(next(out.glob("verify_*.json")).read_text())["fidelity"]["rms"][3:]
    k = int(np.argmax(rms))
    for factor, code, level in ((1.001, 0, "PASS"), (0.999, 4, "ACTION")):
        folder = tmp_path / f"at{factor}"
        action = f"{max(rms) * factor * 1e3:.6f}mm,0.1deg"
        assert main([*base, "--out", str(folder), "--action-level", action]) == code
        verdict = json.loads(next(folder.glob("verify_*.json")).read_text())["verdict"]
        assert verdict["verdict"] == level
        assert list(verdict["action"]) == ([] if level == "PASS" else ["XYZ"[k]])
        assert not (folder / "records").exists()


def test_records_are_never_overwritten(tmp_path, exports):
    for _ in range(3):
        code, pdfs, jsons = record(tmp_path, exports[0])
        assert code == 0
    assert len(pdfs) == 3 and len(jsons) == 3
    assert len({p.read_bytes() for p in jsons}) == 3 or len({p.name for p in jsons}) == 3


def test_the_qatrack_upload_procedure_reads_the_record(tmp_path, exports):
    _, _, jsons = record(tmp_path, exports[1])
    data = json.loads(jsons[0].read_text())
    with open(jsons[0], "rb") as FILE:  # QATrack+ hands the procedure an open file
        namespace = {"FILE": FILE}
        exec(upload_procedure(), namespace)
    values = namespace["motion_qa"]
    assert values["verdict"] == "FAIL"
    for key in ("rms_x_mm", "rms_y_mm", "rms_z_mm", "peak_x_mm", "latency_ms"):
        assert values[key] == pytest.approx(data[key])
    assert np.isfinite(values["gamma_pass_rate_pct"])


@pytest.mark.parametrize(
    "options, words",
    [
        (["--operator", "X"], "--operator is for the QA record: add --record"),
        (
            ["--action-level", "0.3mm,0.1deg"],
            "--action-level: its length must be above 0 and at most the --tolerance's 0.2 mm, "
            "got 0.3 mm",
        ),
        (
            ["--record", "--action-level", "0.3mm,0.1deg"],
            "--action-level: its length must be above 0 and at most the --tolerance's 0.2 mm, "
            "got 0.3 mm",
        ),
        (
            ["--record", "--action-level", "0.1mm,0.2deg"],
            "--action-level: its angle must be above 0 and at most the --tolerance's 0.1 deg, "
            "got 0.2 deg",
        ),
        (["--record", "--action-level", "0.05Mm,0.1deg"], "--action-level: one length and one"),
    ],
)
def test_record_options_are_checked_before_any_work(tmp_path, exports, capsys, options, words):
    code = main(
        ["verify", "breathing", *PARAMS, "--measured", str(exports[0]), "--measured-columns"]
        + [MARKER_COLUMNS, "--tolerance", "0.2mm,0.1deg", "--out", str(tmp_path / "o"), *options]
    )
    assert code == 2
    assert words in capsys.readouterr().err
    assert not (tmp_path / "o").exists()


def test_a_file_changed_while_it_is_judged_gets_no_record(tmp_path, exports, capsys, monkeypatch):
    """The record's SHA-256 must be of the bytes judged: a measured file changed after it was
    read (here as its report is written) is refused by name, and no record is left. Was: the
    record hashed the changed file."""
    import shutil

    from stewart_drake.verification import report as verification_report

    export = Path(shutil.copy(exports[0], tmp_path / "export.csv"))
    write = verification_report.write_verification

    def write_then_change(*args, **kw):
        written = write(*args, **kw)
        with open(export, "a") as f:  # another program appends a line meanwhile
            f.write("\n")
        return written

    monkeypatch.setattr(verification_report, "write_verification", write_then_change)
    code, pdfs, jsons = record(tmp_path, export)
    err = capsys.readouterr().err
    assert code == 2 and pdfs == jsons == [], err
    assert "export.csv" in err and "changed while it was judged" in err
    assert "no record written" in err


def test_an_interrupted_record_leaves_neither_file(tmp_path, exports, monkeypatch, ctrl_c):
    """Ctrl-C while the PDF is drawn: neither the PDF nor the JSON of that record stays (a JSON
    saying PASS beside an empty PDF was left)."""
    from stewart_drake.verification import qa_record

    def drawn_then_interrupted(pdf, data, figure):
        Path(pdf).write_bytes(b"%PDF-1.4 cut")
        raise KeyboardInterrupt

    monkeypatch.setattr(qa_record, "record_pdf", drawn_then_interrupted)
    code, pdfs, jsons = record(tmp_path, exports[0])
    assert code == 130 and pdfs == jsons == []
    assert list((tmp_path / "out" / "records").iterdir()) == []


@pytest.mark.parametrize("kind", ["file", "link to a file", "dangling link", "read-only"])
def test_a_records_folder_that_cannot_take_the_record_is_refused_before_any_work(
    tmp_path, exports, capsys, kind
):
    """OUT/records a file, a link to one, a link to nothing or a folder that cannot be written:
    refused in one line naming it before the verification runs (was: PASS printed, then a raw
    [Errno 17] or [Errno 13] and exit 1)."""
    import os

    records = tmp_path / "out" / "records"
    records.parent.mkdir()
    if kind == "file":
        records.write_text("not a folder\n")
    elif kind == "link to a file":
        (tmp_path / "elsewhere.txt").write_text("x\n")
        records.symlink_to(tmp_path / "elsewhere.txt")
    elif kind == "dangling link":
        records.symlink_to(tmp_path / "gone")
    else:
        if os.geteuid() == 0:
            pytest.skip("root writes in a read-only folder")
        records.mkdir()
        records.chmod(0o555)
    code, _, _ = record(tmp_path, exports[0])
    out, err = capsys.readouterr()
    assert code == 2, (out, err)
    assert err.strip().splitlines()[-1].startswith("stewart-drake verify: cannot write to "), err
    assert "records" in err and "choose another output with --out" in err
    assert "PASS" not in out and not list((tmp_path / "out").glob("verify_*"))


def test_an_encoder_logs_record_names_its_robot_and_says_it_is_not_independent(tmp_path):
    """The robot's own encoder log (the shipped example): its record names the robot whose log
    it is (the --scenario whose forward kinematics read it) and says, in the JSON and on the
    first page, that the measurement is not independent of the robot."""
    assert main(["examples", str(tmp_path / "ex")]) == 0
    out = tmp_path / "out"
    code = main(
        ["verify", "breathing", *PARAMS, "--measured", str(tmp_path / "ex" / "run_encoders.csv")]
        + ["--out", str(out), "--record"]
    )
    assert code == 0
    data = json.loads(next((out / "records").glob("*.json")).read_text())
    assert data["independent"] is False and "not independent" in data["measuring_device"]
    assert data["scenario"].startswith("phantom_hardware (the robot whose encoder log this is")
    first = page_texts(next((out / "records").glob("*.pdf")))[0]
    assert "Measured by the robot's own encoders: not independent of the robot" in first
    assert "Rotation" in first and "RMS error [deg]" in first  # six axes: both tables


@pytest.mark.parametrize(
    "bus, emulated",
    [
        (EMULATED_BUS + "realistic servos (seed 3): k 0.9-1.1 N m/A", True),
        ("the servos on /dev/ttyUSB0, not emulated by this run", False),
        ("", None),
    ],
    ids=["emulated", "not-emulated", "unsaid"],
)
def test_an_encoder_logs_record_says_whether_its_bus_was_emulated(tmp_path, bus, emulated):
    """The bus line a run writes under its encoder log's header is read back as written and
    carried into the record: ``emulated`` True, False, or None (null) for a log that does not
    say, and the first page's measuring device quotes it (or says it is not written)."""
    assert main(["examples", str(tmp_path / "ex")]) == 0
    log = read_encoder_log(tmp_path / "ex" / "run_encoders.csv")
    path = write_encoder_log(
        tmp_path / "run_encoders.csv", log["time"], log["t_run"], log["t_path"], log["q"], bus=bus
    )
    again = read_encoder_log(path)  # the comment line is read past: the same log
    assert again["bus"] == bus
    assert np.array_equal(again["q"], log["q"]) and len(again["time"]) == len(log["time"])
    out = tmp_path / "out"
    code = main(["verify", "breathing", *PARAMS, "--measured", str(path), "--out", str(out)]
                + ["--record"])  # fmt: skip
    assert code == 0
    data = json.loads(next((out / "records").glob("*.json")).read_text())
    assert data["emulated"] is emulated
    first = page_texts(next((out / "records").glob("*.pdf")))[0]
    first = " ".join(first.replace("\\(", "(").replace("\\)", ")").split())
    said = f"Its run wrote of its bus: {bus}." if bus else "Whether its bus was emulated is not"
    assert said in first and said in data["measuring_device"], first


def test_the_reference_is_recorded_as_the_command_line_chose_it():
    """The motion with every --param and --add given, and the trace options that differ from
    their defaults, in the order given; nothing else."""
    from stewart_drake.cli.registry import build_parser
    from stewart_drake.verification.record_options import reference_words

    parser = build_parser()
    args = parser.parse_args(
        ["verify", "breathing", "--param", "tilt=2deg", "--add", "heartbeat", "--measured", "m"]
    )
    assert reference_words(args) == "breathing --param tilt=2deg --add heartbeat"
    args = parser.parse_args(["verify", "trace.txt", "--lowpass-hz", "2", "--measured", "m"])
    assert reference_words(args) == "trace.txt --lowpass-hz 2.0"
    assert reference_words(parser.parse_args(["verify", "trace.txt", "--measured", "m"])) == (
        "trace.txt"
    )


def test_a_cyrillic_or_greek_operator_is_drawn_in_an_embedded_typeface(tmp_path, exports):
    """Helvetica, the PDF's standard face, has no Cyrillic or Greek glyph: the record embeds
    DejaVu Sans (matplotlib's), so the signed page keeps the operator's name; the JSON holds it
    as given."""
    code, pdfs, jsons = record(tmp_path, exports[0], "--operator", "Ж. Физик", "--notes", "Ωμέγα")
    assert code == 0
    data = json.loads(jsons[0].read_text())
    assert data["operator"] == "Ж. Физик" and data["notes"] == "Ωμέγα"
    raw = pdfs[0].read_bytes()
    assert re.search(rb"/BaseFont /[A-Z]{6}\+DejaVuSans\b", raw)


@pytest.mark.parametrize(
    "option, value, words",
    [
        ("--operator", "山田 太郎", "a character of no glyph in DejaVuSans ('山', CJK UNIFIED"),
        ("--operator", "देव", "a character of no glyph in DejaVuSans ('द', DEVANAGARI"),
        ("--notes", "דוד", "a right-to-left character ('ד', HEBREW LETTER DALET) at character 1"),
        ("--phantom-serial", "SD-محمد", "a right-to-left character ('م', ARABIC LETTER MEEM)"),
        ("--operator", "Jos\udce9", "a byte that is not UTF-8 (0xE9) at character 4"),
    ],
)
def test_text_the_pdf_cannot_draw_is_refused_before_any_work(
    tmp_path, exports, capsys, option, value, words
):
    """A name the signed page would lose (no glyph, or a right-to-left script reportlab would
    draw reversed and unshaped, or a Latin-1 byte) is refused in one line naming the option,
    before any work."""
    code = main(
        ["verify", "breathing", *PARAMS, "--measured", str(exports[0]), "--measured-columns"]
        + [MARKER_COLUMNS, "--out", str(tmp_path / "o"), "--record", option, value]
    )
    err = capsys.readouterr().err
    assert code == 2
    assert f"{option}: {words}" in err and "the signed page would lose it" in err
    assert not (tmp_path / "o").exists()


def test_a_measured_file_whose_name_is_not_utf8_is_refused_before_any_work(
    tmp_path, exports, capsys
):
    """A Latin-1 byte in the measured file's name (was: a 44-line traceback from the figure's
    title): refused in one line naming the option and the byte, nothing written."""
    import os
    import shutil

    name = os.fsdecode(b"mark\xe9rs.csv")
    shutil.copy(exports[0], tmp_path / name)
    code = main(
        ["verify", "breathing", *PARAMS, "--measured", str(tmp_path / name), "--measured-columns"]
        + [MARKER_COLUMNS, "--out", str(tmp_path / "o")]
    )
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1, err
    assert "its name is not UTF-8 text (byte 0xE9 at character" in err[0]
    assert err[0].startswith("stewart-drake verify: --measured ")
    assert not (tmp_path / "o").exists()
