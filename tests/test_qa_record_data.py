"""The QA record's values (verification/qa_record.py: ``results_data``, the axes' levels, the
measuring device, the inputs' identities, the record's files) from a verification made here by
hand, each field held to its unit with figures written in the test: the tolerance 0.1 deg (not
0.001745), rotations in degrees (not radians), the latency 12 ms (not 0.012), the gamma pass
rate 98 % (not 0.98), an error exactly at the tolerance PASS, X against the length tolerance and
theta against the angle's, a CANNOT JUDGE never saved as PASS. Without Drake or a PDF: fast
enough for the record's mutation testing (tools/mutation.py)."""

import hashlib
import json
import math
import re
from datetime import UTC, datetime
from types import SimpleNamespace

import numpy as np
import pytest

from stewart_drake.base.errors import CorruptFileError, InvalidConfigError, MissingExtraError
from stewart_drake.verification import qa_record
from stewart_drake.verification.measured_motion import MeasuredMotion
from stewart_drake.verification.qa_record import (
    LEVELS,
    MAX_TEXT,
    RECORD_SCHEMA,
    RecordContext,
    axis_levels,
    device_words,
    emulated,
    file_identity,
    read_results,
    results_data,
)

TOL = (1e-4, math.radians(0.1))  # 0.1 mm | 0.1 deg
WHEN = datetime(2026, 11, 28, 9, 30, 5, tzinfo=UTC)
ALL = [True] * 6
TRANSLATIONS = [False] * 3 + [True] * 3


def motion(kind="tracker", bus="", measured=ALL):
    """A measured motion of ``kind`` (two samples: results_data reads its kind, axes and bus)."""
    poses = np.zeros((2, 6))
    return MeasuredMotion(
        "/data/run/markers.csv", kind, np.array([0.0, 1.0]), poses, np.asarray(measured, bool),
        "a marker", bus=bus,
    )  # fmt: skip


def verification(
    rms,
    peak=None,
    measured=ALL,
    verdict="PASS",
    action=None,
    cannot=False,
    kind="tracker",
    bus="",
    latency_s=0.012,
    pass_rate=0.98,
    starts=(4.0, 8.0, 12.0),
):
    """A verification's fields as results_data reads them; ``rms`` and ``peak`` (6,) rad and m."""
    rms = np.asarray(rms, dtype=float)
    measured = np.asarray(measured, dtype=bool)
    return SimpleNamespace(
        fidelity={
            "rms": rms,
            "peak": 3 * rms if peak is None else np.asarray(peak, dtype=float),
            "gamma": [{"pass_rate": pass_rate, "distance_m": 5e-4, "time_s": 0.1}],
            "rms_translation_m": float(np.linalg.norm(rms[3:])) if measured[3:].any() else np.nan,
            "window_s": (4.0, 39.99),
        },
        judgement=SimpleNamespace(
            verdict=verdict,
            passed=verdict in ("PASS", "ACTION"),
            action_level=action,
            cannot_judge=cannot,
            latency_judged=True,
            line=f"{verdict}: the line",
            causes=("a cause",) if verdict == "FAIL" else (),
            tolerance=TOL,
        ),
        measured=motion(kind, bus, measured),
        latency_s=latency_s,
        max_latency_s=0.5,
        cycle_starts=list(starts),
        name="breathing",
        frame=SimpleNamespace(words=lambda offsets, measured: "each axis's offset removed"),
        offsets=np.zeros(6),
        clock="searched",
        clock_offset_s=-121.456,
    )


def rms_of(**axes):
    """(6,) rad and m from deg and mm by axis name: rms_of(theta=0.05, X=0.0705)."""
    out = np.zeros(6)
    for k, name in enumerate(("phi", "theta", "psi", "X", "Y", "Z")):
        v = axes.get(name, 0.0)
        out[k] = math.radians(v) if k < 3 else v * 1e-3
    return out


def data(ver, context=None, tolerance=TOL):
    ver.judgement.tolerance = tolerance  # the record reads the verdict's own
    return results_data(ver, context or RecordContext(), WHEN)


def test_every_figure_is_in_the_unit_its_name_says():
    ver = verification(rms_of(phi=0.01, theta=0.02, psi=0.03, X=0.0705, Y=0.0678, Z=0.0693))
    d = data(ver, RecordContext(reference="breathing --param tilt=2deg"))
    assert d["schema"] == RECORD_SCHEMA == "stewart-drake/verify-record/1"
    assert d["tolerance_mm"] == pytest.approx(0.1, rel=1e-12)
    assert d["tolerance_deg"] == pytest.approx(0.1, rel=1e-12)
    assert d["rms_x_mm"] == pytest.approx(0.0705, rel=1e-12)
    assert d["rms_z_mm"] == pytest.approx(0.0693, rel=1e-12)
    assert d["rms_theta_deg"] == pytest.approx(0.02, rel=1e-12)
    assert d["peak_psi_deg"] == pytest.approx(0.09, rel=1e-12)
    assert d["peak_y_mm"] == pytest.approx(3 * 0.0678, rel=1e-12)
    assert d["latency_ms"] == pytest.approx(12.0, rel=1e-12)
    assert d["max_latency_ms"] == pytest.approx(500.0, rel=1e-12)
    assert d["gamma_pass_rate_pct"] == pytest.approx(98.0, rel=1e-12)
    assert d["gamma_criteria"] == "0.5 mm / 100 ms"
    assert d["window_s"] == [4.0, 39.99] and d["cycles_judged"] == 2
    assert d["action_mm"] is None and d["action_deg"] is None
    assert d["verdict"] == "PASS" and d["passed"] is True and d["cannot_judge"] is False
    assert d["latency_judged"] is True
    assert d["reference"] == "breathing"
    assert d["reference_motion"] == "breathing --param tilt=2deg"
    assert d["measured_file"] == "markers.csv"
    assert d["frames"] == "each axis's offset removed"
    assert d["clock"] == "searched" and d["clock_offset_s"] == -121.456
    assert d["date"] == "2026-11-28T09:30:05+00:00"
    assert d["line"] == "PASS: the line" and d["causes"] == []
    assert set(d["software"]) >= {"stewart-drake", "numpy", "python", "platform"}
    json.dumps(d)  # every value is JSON's


def test_the_reference_motion_is_the_verifications_name_when_the_run_names_none():
    assert data(verification(np.zeros(6)))["reference_motion"] == "breathing"


@pytest.mark.parametrize("starts, cycles", [((), 0), ((4.0,), 0), ((4.0, 8.0), 1)])
def test_the_cycles_judged_are_the_whole_cycles_between_starts(starts, cycles):
    assert data(verification(np.zeros(6), starts=starts))["cycles_judged"] == cycles


def test_an_axis_not_measured_has_no_figure_and_no_level():
    ver = verification(rms_of(X=0.05, Y=0.05, Z=0.05), measured=TRANSLATIONS)
    d = data(ver)
    for name in ("phi", "theta", "psi"):
        assert d[f"rms_{name}_deg"] is None and d[f"peak_{name}_deg"] is None
        assert d[f"level_{name}"] is None
    assert d["level_x"] == "PASS" and d["rms_y_mm"] == pytest.approx(0.05)


def test_without_translations_there_is_no_gamma():
    rotations = [True] * 3 + [False] * 3
    assert data(verification(rms_of(theta=0.01), measured=rotations))["gamma_pass_rate_pct"] is None


@pytest.mark.parametrize(
    "x_mm, level",
    [(0.1, "PASS"), (0.1 * (1 + 1e-9), "FAIL"), (0.0999, "PASS"), (0.5, "FAIL")],
)
def test_an_error_exactly_at_the_tolerance_passes(x_mm, level):
    ver = verification(rms_of(X=x_mm))
    assert axis_levels(ver, TOL)["X"] == level
    assert data(ver)["level_x"] == level


def test_each_axis_is_held_to_its_own_kind_of_tolerance():
    """X at 0.5 mm FAILs the 0.1 mm tolerance (it would pass 1.745e-3 as an angle); theta at
    0.05 deg (873 urad) PASSes the 0.1 deg (it would fail 1e-4 as a length)."""
    levels = axis_levels(verification(rms_of(X=0.5, theta=0.05)), TOL)
    assert levels["X"] == "FAIL" and levels["theta"] == "PASS" and levels["Y"] == "PASS"


def test_the_action_level_grades_each_axis_and_is_recorded_in_its_units():
    action = (7e-5, math.radians(0.07))
    ver = verification(
        rms_of(X=0.0705, Y=0.0699, theta=0.071, psi=0.2), verdict="FAIL", action=action
    )
    d = data(ver)
    assert d["action_mm"] == pytest.approx(0.07, rel=1e-12)
    assert d["action_deg"] == pytest.approx(0.07, rel=1e-12)
    assert (d["level_x"], d["level_y"], d["level_z"]) == ("ACTION", "PASS", "PASS")
    assert (d["level_theta"], d["level_psi"], d["level_phi"]) == ("ACTION", "FAIL", "PASS")
    assert d["verdict"] == "FAIL" and d["passed"] is False and d["causes"] == ["a cause"]


def test_a_record_that_cannot_judge_never_says_pass():
    ver = verification(rms_of(X=0.05, Y=0.2), verdict="CANNOT JUDGE", cannot=True)
    d = data(ver)
    assert d["verdict"] == "CANNOT JUDGE" and d["cannot_judge"] is True
    assert d["level_x"] == "CANNOT JUDGE" and d["level_theta"] == "CANNOT JUDGE"
    assert d["level_y"] == "FAIL"  # beyond the tolerance whatever else holds
    assert "PASS" not in {v for k, v in d.items() if k.startswith("level_")}


def test_the_levels_are_ordered_worst_last():
    assert LEVELS == ("PASS", "ACTION", "CANNOT JUDGE", "FAIL")


def test_the_measuring_device_says_whether_it_is_independent_and_emulated():
    tracker = verification(np.zeros(6)).measured
    words, independent = device_words(tracker)
    assert independent is True and words == "an external tracker's file (a marker)"
    assert emulated(tracker) is None
    for kind in ("encoders", "carriage"):
        log = motion(kind, "emulated: ideal servos")
        words, independent = device_words(log)
        assert independent is False and "not independent of the robot" in words
        assert "Its run wrote of its bus: emulated: ideal servos." in words
        assert emulated(log) is True
    real = motion("encoders", "the servos on /dev/ttyUSB0, ...")
    assert emulated(real) is False
    unsaid = motion("encoders", "")
    assert emulated(unsaid) is None
    assert "Whether its bus was emulated is not written" in device_words(unsaid)[0]
    d = data(verification(np.zeros(6), kind="encoders", bus="emulated: x"))
    assert d["independent"] is False and d["emulated"] is True


def test_the_inputs_are_identified_by_their_bytes(tmp_path):
    path = tmp_path / "markers.csv"
    raw = b"t [s],X [mm]\n0,1\n"
    path.write_bytes(raw)
    d = data(verification(np.zeros(6)), RecordContext(inputs=(str(path),)))
    (ident,) = d["inputs"]
    assert ident == {
        "name": "markers.csv",
        "path": str(path.resolve()),
        "bytes": len(raw),
        "sha256": hashlib.sha256(raw).hexdigest(),
    }


def test_an_input_changed_since_it_was_read_gets_no_record(tmp_path):
    path = tmp_path / "markers.csv"
    path.write_bytes(b"t [s],X [mm]\n0,1\n")
    before = file_identity(path)
    same = RecordContext(inputs=(str(path),), identities=(before,))
    assert data(verification(np.zeros(6)), same)["inputs"] == [before]
    path.write_bytes(b"t [s],X [mm]\n0,2\n")
    with pytest.raises(CorruptFileError, match="changed while it was judged"):
        data(verification(np.zeros(6)), same)


def test_the_record_carries_what_the_physicist_adds():
    context = RecordContext("A. Physicist", "SD-0042", "after service", "phantom_bus", "breathing")
    d = data(verification(np.zeros(6)), context)
    assert (d["operator"], d["phantom_serial"], d["notes"]) == (
        "A. Physicist",
        "SD-0042",
        "after service",
    )
    assert d["scenario"] == "phantom_bus"


@pytest.mark.parametrize("option", ["operator", "phantom_serial", "notes"])
def test_a_text_longer_than_a_record_takes_is_refused_naming_its_option(option):
    RecordContext(**{option: "a" * MAX_TEXT}).check()
    with pytest.raises(InvalidConfigError, match=f"--{option.replace('_', '-')}: {MAX_TEXT + 1}"):
        RecordContext(**{option: "a" * (MAX_TEXT + 1)}).check()


def test_records_of_one_name_are_made_exclusively(tmp_path):
    first = qa_record._exclusive(tmp_path / "records", "verify_x", (".pdf", ".json"))
    second = qa_record._exclusive(tmp_path / "records", "verify_x", (".pdf", ".json"))
    assert [p.name for p in first] == ["verify_x.pdf", "verify_x.json"]
    assert [p.name for p in second] == ["verify_x-2.pdf", "verify_x-2.json"]
    assert all(p.exists() and p.stat().st_size == 0 for p in first + second)
    # A name whose JSON alone is taken is skipped whole, its PDF not left behind.
    (tmp_path / "records" / "verify_y.json").write_text("{}")
    third = qa_record._exclusive(tmp_path / "records", "verify_y", (".pdf", ".json"))
    assert [p.name for p in third] == ["verify_y-2.pdf", "verify_y-2.json"]
    assert not (tmp_path / "records" / "verify_y.pdf").exists()


def test_a_record_is_read_back_only_with_its_schema(tmp_path):
    good = tmp_path / "good.json"
    good.write_text(json.dumps({"schema": RECORD_SCHEMA, "verdict": "PASS"}))
    assert read_results(good)["verdict"] == "PASS"
    for text in (json.dumps({"schema": "other/1"}), json.dumps([1, 2])):
        bad = tmp_path / "bad.json"
        bad.write_text(text)
        with pytest.raises(CorruptFileError, match=RECORD_SCHEMA):
            read_results(bad)


def test_the_measuring_device_and_the_frames_are_recorded_as_given():
    calls = []
    ver = verification(np.zeros(6), measured=TRANSLATIONS)
    ver.frame = SimpleNamespace(
        words=lambda offsets, measured: calls.append((offsets, measured)) or "f"
    )
    d = data(ver)
    assert d["measuring_device"] == "an external tracker's file (a marker)" and d["frames"] == "f"
    ((offsets, measured),) = calls
    assert offsets is ver.offsets and measured.tolist() == TRANSLATIONS
    bare = MeasuredMotion(
        "m.csv", "tracker", np.array([0.0, 1.0]), np.zeros((2, 6)), np.ones(6, bool)
    )
    assert device_words(bare) == ("an external tracker's file (as read)", True)


def test_the_software_versions_name_what_is_missing(monkeypatch):
    import importlib.metadata
    import platform

    real = importlib.metadata.version

    def version(name):
        if name == "scipy":
            raise importlib.metadata.PackageNotFoundError(name)
        return real(name)

    monkeypatch.setattr(importlib.metadata, "version", version)
    got = qa_record.software_versions()
    assert list(got) == [
        "stewart-drake",
        "drake",
        "numpy",
        "scipy",
        "matplotlib",
        "python",
        "platform",
    ]
    assert got["scipy"] == "not installed" and got["numpy"] == np.__version__
    assert got["python"] == platform.python_version() and got["platform"] == platform.platform()


def test_a_changed_input_is_named_with_both_hashes(tmp_path):
    path = tmp_path / "markers.csv"
    path.write_bytes(b"one")
    before = file_identity(path)
    path.write_bytes(b"two")
    with pytest.raises(CorruptFileError) as info:
        qa_record._unchanged_inputs(RecordContext(inputs=(str(path),), identities=(before,)))
    err = info.value
    old, new = hashlib.sha256(b"one").hexdigest(), hashlib.sha256(b"two").hexdigest()
    assert err.path == str(path.resolve()) and err.kind == "input of the verdict"
    assert f"(SHA-256 {old[:12]}... before, {new[:12]}... now): no record written" in err.problem
    assert err.remedy == "verify it again"


def test_a_folder_is_no_input(tmp_path):
    with pytest.raises(CorruptFileError, match="input of the verdict"):
        file_identity(tmp_path)


def test_records_are_made_in_a_new_folder_readable_and_give_up_after_their_bound(
    tmp_path, monkeypatch
):
    folder = tmp_path / "a" / "b" / "records"
    (pdf, js) = qa_record._exclusive(folder, "v", (".pdf", ".json"))
    import os

    mask = os.umask(0)
    os.umask(mask)
    assert pdf.stat().st_mode & 0o777 == 0o644 & ~mask
    monkeypatch.setattr(qa_record, "MAX_SAME_NAME", 3)
    for _ in range(2):
        qa_record._exclusive(folder, "v", (".pdf", ".json"))
    assert (folder / "v-3.pdf").exists()
    with pytest.raises(InvalidConfigError, match="3 records named v: choose another --out"):
        qa_record._exclusive(folder, "v", (".pdf", ".json"))


def test_a_record_read_back_names_its_file_and_is_bounded(tmp_path, monkeypatch):
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps({"schema": "other/1"}))
    with pytest.raises(CorruptFileError) as info:
        read_results(bad)
    assert info.value.path == str(bad) and info.value.kind == "QA record"
    big = tmp_path / "big.json"
    big.write_text(json.dumps({"schema": RECORD_SCHEMA, "notes": "x" * 200}))
    monkeypatch.setattr(qa_record, "MAX_RECORD_BYTES", 100)
    with pytest.raises(CorruptFileError, match="give a record verify --record wrote"):
        read_results(big)


def test_an_undrawable_operator_is_refused_naming_the_option_and_the_typeface():
    with pytest.raises(InvalidConfigError) as info:
        RecordContext(operator="Dov \u05d3").check()
    words = str(info.value)
    assert words.startswith("--operator: a right-to-left character")
    assert "the record's PDF (DejaVuSans) cannot draw it" in words


@pytest.fixture
def drawn(monkeypatch):
    """write_record with the PDF and its plots replaced by stand-ins that record what they were
    given (the PDF's own tests draw it)."""
    from stewart_drake.verification import qa_record_figure

    made = {}

    def pdf(path, data, figure):
        made.update(
            path=path, data=data, figure=figure, json_then=path.with_suffix(".json").read_bytes()
        )
        path.write_bytes(b"%PDF-stand-in")

    monkeypatch.setattr(qa_record, "record_pdf", pdf)
    monkeypatch.setattr(qa_record, "_reportlab", lambda: None)  # the stand-in needs none
    monkeypatch.setattr(qa_record_figure, "record_figure", lambda ver: b"png")
    return made


def test_a_record_is_its_pdf_then_its_json(tmp_path, drawn):
    ver = verification(rms_of(X=0.05))
    pdf, js = qa_record.write_record(ver, tmp_path / "out", RecordContext(), "verify_b")
    assert pdf.parent == js.parent == tmp_path / "out" / "records"
    assert re.fullmatch(r"verify_b_\d{8}T\d{6}\.pdf", pdf.name) and js.name == pdf.stem + ".json"
    assert drawn["path"] == pdf and drawn["figure"] == b"png" and drawn["json_then"] == b""
    saved = json.loads(js.read_text())
    assert saved == drawn["data"] and saved["rms_x_mm"] == pytest.approx(0.05)
    assert js.read_text().endswith("}\n") and pdf.read_bytes() == b"%PDF-stand-in"


@pytest.mark.parametrize("interrupt", [KeyboardInterrupt, OSError])
def test_an_interrupted_record_leaves_neither_file(tmp_path, monkeypatch, drawn, interrupt):
    def broken(path, data, figure):
        path.write_bytes(b"%PDF-half")
        raise interrupt()

    monkeypatch.setattr(qa_record, "record_pdf", broken)
    with pytest.raises(interrupt):
        qa_record.write_record(verification(np.zeros(6)), tmp_path, RecordContext(), "v")
    assert list((tmp_path / "records").iterdir()) == []


def test_a_record_without_reportlab_names_the_extra_and_writes_nothing(tmp_path, monkeypatch):
    import sys

    monkeypatch.setitem(sys.modules, "reportlab", None)  # import reportlab raises ImportError
    with pytest.raises(MissingExtraError, match=r'pip install -e "\.\[qa\]"'):
        qa_record.write_record(verification(np.zeros(6)), tmp_path, RecordContext(), "v")
    assert not (tmp_path / "records").exists()
