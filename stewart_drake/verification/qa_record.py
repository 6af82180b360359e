"""A QA record of a verification (``stewart-drake verify --record``): one PDF a physicist signs
and files, and the same results as named values that a QATrack+ test list takes.

The record holds what a QA record of a motion phantom needs to stand on its own (after AAPM
TG-142's tolerance and action levels and pylinac's ``results()``, ``results_data()`` and
``publish_pdf()``, which leave the database to QATrack+): the verdict against the tolerance and,
when given, an action level; per measured axis the RMS and peak error beside the tolerance
they are judged against; the causes of a FAIL or why the check cannot judge; the plots of the
verification's report (measured against reference per axis, the error over time, gamma); the
assumptions (the frames and the registration with its uncertainty, the clocks, the window);
the reference as the command line chose it (the motion and its parameters), the measuring
device and whether it is independent of the robot (the robot's own encoder log is not), the
cycles judged; every input's name, size and SHA-256; the phantom (the robot whose encoder log
was read, or the ``--scenario`` given: never a default the run did not name) and its serial;
the software's versions; the date, the operator and the notes; and lines to sign.

The verdict is the judgement's own (:attr:`~.measured_verdict.Judgement.verdict`), the word the
terminal, the report, the JSON and every page say: per axis an RMS error beyond the tolerance
FAILs; one within it but beyond the action level is ACTION (within tolerance, to be looked at
before it fails: TG-142's action level, pylinac's ``action_tolerance``;
:func:`~.verdict_levels.axis_levels`); CANNOT JUDGE when the judgement cannot
(:func:`~.verdict_sensitivity.motion_unseen`).

The PDF's pages (:mod:`.qa_record_pdf`): the verdict with its per-axis tables (one unit per
column), the causes, the measurement, the phantom and the lines to sign; the verdict's line, the
assumptions and the inputs; the plots (:mod:`.qa_record_figure`: each measured axis against its
own tolerance, the RMS error per cycle, the gamma index). No table is split across pages, and
each page says "page X of Y".

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
from ..base.verdicts import VERDICTS
from ..organ_motion.fidelity import AXES
from .qa_record_pdf import FONT, record_pdf, undrawable
from .verdict_levels import axis_levels as _axis_levels

#: The record's JSON layout; a reader checks it before reading the values.
RECORD_SCHEMA = "stewart-drake/verify-record/1"
#: The verdicts of a record, worst last: the package's one list
#: (:mod:`stewart_drake.base.verdicts`).
LEVELS = VERDICTS
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
        scenario: the phantom (the robot whose encoder log was read, or the scenario named;
            "": not named). reference: the reference as the command line chose it (the
            motion and its parameters). inputs: the files the verdict read (the measured file,
            the reference's
            trace, the registration). identities: each input's :func:`file_identity` taken
            before it was read, or none: the record's must be the same, or the file changed
            while it was judged and no record is written.
    """

    operator: str = ""
    phantom_serial: str = ""
    notes: str = ""
    scenario: str = ""
    reference: str = ""
    inputs: tuple = ()
    identities: tuple = ()

    def check(self) -> None:
        """Refuse, before any work, texts longer than :data:`MAX_TEXT` and texts the PDF
        cannot draw (:func:`~.qa_record_pdf.undrawable`: a character of no glyph in its
        typeface, a right-to-left script, a byte that is not UTF-8).

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
            why = undrawable(text)
            if why:
                raise InvalidConfigError(
                    f"{option}: {why}: the record's PDF ({FONT}) cannot draw it, and the "
                    "signed page would lose it; write it as UTF-8 text in Latin, Greek or "
                    "Cyrillic letters"
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


def axis_levels(ver, tolerance) -> dict:
    """{axis: "PASS", "ACTION" or "FAIL"} per measured axis of ``ver`` at ``tolerance`` and
    the judgement's action level (:func:`~.verdict_levels.axis_levels`); "CANNOT JUDGE" for
    every axis within the tolerance when the judgement cannot judge (an axis's PASS would say
    what the verdict refuses to)."""
    rms = np.asarray(ver.fidelity["rms"], dtype=float)
    levels = _axis_levels(rms, ver.measured.measured, tolerance, ver.judgement.action_level)
    if ver.judgement.cannot_judge:
        return {a: v if v == "FAIL" else "CANNOT JUDGE" for a, v in levels.items()}
    return levels


def device_words(measured) -> tuple[str, bool]:
    """(the measuring device in words, whether it is independent of the robot) of a
    :class:`~.measured_motion.MeasuredMotion`: a tracker's file is; the robot's own encoder log
    is not (its encoders see neither the gears' play, nor what bends, nor a geometry that is
    wrong: forward kinematics of the model turn them into poses)."""
    if measured.from_the_robot:
        bus = (
            f"Its run wrote of its bus: {measured.bus}"
            if measured.bus
            else "Whether its bus was emulated is not written in the log"
        )
        return (
            "the robot's own encoder log (forward kinematics of the robot's model): not "
            f"independent of the robot; it sees neither the gears' play nor what bends. {bus}. "
            "An acceptance needs an external tracker",
            False,
        )
    return f"an external tracker's file ({measured.layout or 'as read'})", True


def emulated(measured) -> bool | None:
    """Whether the motion judged ran on an emulated bus, as its encoder log says (its
    :attr:`~.measured_motion.MeasuredMotion.bus`): True, False, or None where the file does
    not say (a tracker's file, which measures whatever stood before it; a log without the
    line)."""
    if not measured.bus:
        return None
    from .measured_motion import EMULATED_BUS

    return measured.bus.startswith(EMULATED_BUS)


def results_data(ver, context: RecordContext, when: datetime) -> dict:
    """The record's values as JSON, each under a name a QATrack+ test's macro can take
    (letters, digits and underscores): ``verdict``, ``passed``, ``tolerance_mm`` /
    ``tolerance_deg``, ``action_mm`` / ``action_deg`` (None without), ``rms_<axis>_mm`` or
    ``_deg`` and ``peak_<axis>_...`` per axis (None for an axis not measured), ``level_<axis>``,
    ``latency_ms``, ``latency_judged``, ``gamma_pass_rate_pct`` (None without translations),
    ``window_s``, ``cycles_judged`` (the reference's cycles the window holds: one the
    recording misses by at most :data:`~.measured_span.CYCLE_SLACK` of a cycle counts), the
    identity (``reference``, ``reference_motion`` (the motion and its parameters),
    ``measured_file``, ``measuring_device`` and ``independent``, ``emulated`` (:func:`emulated`),
    ``inputs`` with their SHA-256,
    ``scenario`` (the phantom; "" when the run names none), ``phantom_serial``, ``operator``,
    ``notes``, ``date``, ``software``), the judgement's ``line`` and ``causes``, and ``schema``
    (:data:`RECORD_SCHEMA`)."""
    fid, tolerance = ver.fidelity, ver.judgement.tolerance
    levels = axis_levels(ver, tolerance)
    action = ver.judgement.action_level
    device, independent = device_words(ver.measured)
    out: dict = {
        "schema": RECORD_SCHEMA,
        "verdict": ver.judgement.verdict,
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
            "cycles_judged": max(len(ver.cycle_starts) - 1, 0),
            "reference": ver.name,
            "reference_motion": context.reference or ver.name,
            "measured_file": Path(ver.measured.path).name,
            "measuring_device": device,
            "independent": independent,
            "emulated": emulated(ver.measured),
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


def write_record(ver, out, context: RecordContext, stem: str) -> tuple:
    """Write the QA record of a verification into ``out/records``: ``<stem>_<time>.pdf``
    (:func:`record_pdf`, its plots drawn from ``ver`` by
    :func:`~.qa_record_figure.record_figure`) and ``<stem>_<time>.json``
    (:func:`results_data`), never over an earlier one (module docstring).

    Args:
        ver: the :class:`~.verify.Verification` (its judgement's tolerance and action level
            are the record's). out: the output folder. context: :class:`RecordContext`.
            stem: the report's stem.
    Returns:
        (pdf path, json path).
    Raises:
        MissingExtraError: reportlab is not installed (the ``qa`` extra), before any file.
        InvalidConfigError: :func:`_exclusive`'s.
    """
    from .qa_record_figure import record_figure

    _reportlab()
    when = datetime.now().astimezone()
    data = results_data(ver, context, when)
    figure = record_figure(ver)
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
    "device_words",
    "results_data",
    "write_record",
    "record_pdf",
    "read_results",
]
