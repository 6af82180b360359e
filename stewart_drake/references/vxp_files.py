"""Varian RPM exports (``.vxp``): the Real-time Position Management system's recording of a
marker block on the patient's chest or abdomen, read as the system writes it.

A VXP file is text: a ``[Header]`` section of ``key=value`` lines, then ``[Data]`` and one sample
a line, its fields in the order the header's ``Data_layout`` names (VXP 1.6:
``amplitude,phase,timestamp,validflag,ttlin,mark,ttlout``; VXP 1.5 has no ``ttlout``). Read as
G. C. Sharp's ``readrpm.m`` (Massachusetts General Hospital, version 1.3, 2008) reads it:

- ``timestamp`` in ms from the application's start;
- ``amplitude`` the block's displacement in cm times ``Scale_factor`` / 10 (``Scale_factor=10``:
  cm as written), so ``amplitude x Scale_factor`` mm. A header without ``Scale_factor`` is
  refused: the amplitude's unit would be a guess;
- ``validflag`` >= 0 a valid, periodic sample; -1 the track lost (or a bad video signal); -2
  non-periodic breathing (a cough). Samples below 0 are dropped and counted by flag in the
  layout's words: an invalid sample is not the block's position;
- ``Samples_per_second`` is checked against the timestamps' median step: off by more than
  :data:`MAX_RATE_RATIO` (the timestamps in another unit) is refused, off by more than
  :data:`RATE_SLACK` is said (a recording with pauses has fewer samples a second than its
  rate).

The amplitude goes to the patient's AP axis unless the axis map says otherwise
(:data:`VXP_AXIS`): the camera sees the block rise and fall with the chest wall. The sign is the
file's; a map ``amplitude=-AP`` reverses it.
"""

import math
from pathlib import Path

from ..base.errors import InvalidConfigError

#: The header line that opens a VXP file.
VXP_OPENING = "[Header]"
#: The line that ends the header.
VXP_DATA = "[Data]"
#: The fields a VXP file's ``Data_layout`` must name: the sample's time and the block's
#: position (``validflag`` is read when named).
VXP_FIELDS = ("amplitude", "timestamp")
#: The platform axis of the amplitude unless an axis map says otherwise.
VXP_AXIS = {"amplitude": "AP"}
#: The words of each invalid ``validflag`` (readrpm.m's).
INVALID_FLAGS = {-1: "the track lost or a bad video signal", -2: "non-periodic breathing"}
#: A header's sample rate and the timestamps' further apart than this ratio: refused.
MAX_RATE_RATIO = 2.0
#: A header's sample rate and the timestamps' further apart than this share: said.
RATE_SLACK = 0.1
#: The words a VXP table's layout starts with (:func:`~.trace_files.trace_samples` maps its
#: amplitude by :data:`VXP_AXIS` on them).
VXP_LAYOUT = "Varian RPM export"


def is_vxp(text: str) -> bool:
    """Whether a trace's text opens as a VXP file does (:data:`VXP_OPENING`)."""
    first = next((ln.strip() for ln in text.splitlines() if ln.strip()), "")
    return first == VXP_OPENING


def _header(path: Path, lines: list) -> tuple[dict, int]:
    """({key: value} of the header, the index of the first data line).

    Raises:
        InvalidConfigError: no ``[Data]`` line; a header line that is not key=value.
    """
    fields: dict = {}
    for i, line in enumerate(lines):
        text = line.strip()
        if not text or text == VXP_OPENING:
            continue
        if text == VXP_DATA:
            return fields, i + 1
        key, eq, value = text.partition("=")
        if not eq:
            raise InvalidConfigError(
                f"{path}, line {i + 1}: a VXP header line is key=value, got {text[:80]!r}"
            )
        fields[key.strip().lower()] = value.strip()
    raise InvalidConfigError(
        f"{path}: a VXP header without its {VXP_DATA} line: the file is cut short, or not a "
        "Varian RPM export"
    )


def _number(path: Path, fields: dict, key: str, written: str) -> float:
    """The header's ``key`` as a finite number > 0.

    Raises:
        InvalidConfigError: missing, not a number, or not above 0 (named as ``written``).
    """
    try:
        value = float(fields[key])
    except KeyError:
        raise InvalidConfigError(
            f"{path}: the VXP header has no {written}: the amplitude's unit is not known "
            f"without it (amplitude x {written} / 10 is cm); add the line the RPM system wrote"
            if key == "scale_factor"
            else f"{path}: the VXP header has no {written}"
        ) from None
    except ValueError:
        value = math.nan
    if not (math.isfinite(value) and value > 0):
        raise InvalidConfigError(
            f"{path}: the VXP header's {written} must be a number above 0, got {fields[key]!r}"
        )
    return value


def vxp_table(path: Path, text: str) -> tuple[list, list, str]:
    """(header cells ``t [ms]``, ``amplitude [mm]``; data rows, each its line number then its
    two cells; the layout in words) of a VXP file's text, its invalid samples dropped and
    counted (module docstring): what :func:`~.trace_files.read_trace_table` gives of any trace.

    Raises:
        InvalidConfigError: no ``[Data]`` line, a header line that is not key=value; a
            ``Data_layout`` without amplitude and timestamp; no or a bad ``Scale_factor`` or
            ``Samples_per_second``; a sample with fewer fields than the layout needs or that
            is not numbers (its line named); no valid sample; a sample rate the timestamps
            contradict (:data:`MAX_RATE_RATIO`).
    """
    lines = text.splitlines()
    fields, first = _header(path, lines)
    layout = [c.strip().lower() for c in fields.get("data_layout", "").split(",")]
    missing = [f for f in VXP_FIELDS if f not in layout]
    if missing:
        raise InvalidConfigError(
            f"{path}: the VXP header's Data_layout ({fields.get('data_layout', 'none')!r}) "
            f"names no {' or '.join(missing)}: a VXP 1.5 or 1.6 export names "
            "amplitude,phase,timestamp,validflag,..."
        )
    scale = _number(path, fields, "scale_factor", "Scale_factor")
    rate = _number(path, fields, "samples_per_second", "Samples_per_second")
    a, t = layout.index("amplitude"), layout.index("timestamp")
    v = layout.index("validflag") if "validflag" in layout else None
    need = max(a, t, -1 if v is None else v) + 1
    rows: list = []
    stamps: list = []  # ms, as read: the rate's check takes them so
    dropped: dict[int, int] = {}
    for number, line in enumerate(lines[first:], start=first + 1):
        if not line.strip():
            continue
        cells = line.split(",")
        if len(cells) < need:
            raise InvalidConfigError(
                f"{path}, line {number}: {len(cells)} fields, its Data_layout needs {need}"
            )
        try:
            flag = 0 if v is None else int(float(cells[v]))
            amplitude, stamp = float(cells[a]), float(cells[t])
        except ValueError:
            raise InvalidConfigError(
                f"{path}, line {number}: not numbers where its Data_layout puts amplitude, "
                f"timestamp and validflag: {line.strip()[:120]!r}"
            ) from None
        if flag < 0:
            dropped[flag] = dropped.get(flag, 0) + 1
            continue
        rows.append([number, repr(stamp), repr(amplitude * scale)])
        stamps.append(stamp)
    if not rows:
        raise InvalidConfigError(f"{path}: no valid sample (every validflag below 0)")
    words = [
        f"{VXP_LAYOUT} (version {fields.get('version', 'not given')}; Data_layout "
        f"{','.join(layout)}; Scale_factor {scale:g}: amplitude x {scale:g} mm)"
    ]
    words += _rate_words(path, stamps, rate)
    if dropped:
        words.append(
            f"{sum(dropped.values())} invalid samples dropped ("
            + "; ".join(
                f"validflag {flag}, {INVALID_FLAGS.get(flag, 'invalid')}: {count}"
                for flag, count in sorted(dropped.items(), reverse=True)
            )
            + ")"
        )
    return ["t [ms]", "amplitude [mm]"], rows, ", ".join(words)


def _rate_words(path: Path, stamps: list, rate: float) -> list:
    """The layout's words on the header's sample rate against the timestamps' (``stamps``, ms;
    the rate's words alone when they agree to :data:`RATE_SLACK`).

    Raises:
        InvalidConfigError: further apart than :data:`MAX_RATE_RATIO`.
    """
    stamps = sorted(stamps)
    steps = sorted(b - a for a, b in zip(stamps, stamps[1:]) if b > a)
    if not steps:
        return []
    # The mean of the steps near the median: whole ms make a 30 Hz clock step 33 and 34 ms, and a
    # pause is not a step of the rate.
    typical = [d for d in steps if d <= 1.5 * steps[len(steps) // 2]]
    measured = 1e3 * len(typical) / sum(typical)
    ratio = max(measured / rate, rate / measured)
    if ratio > MAX_RATE_RATIO:
        raise InvalidConfigError(
            f"{path}: its header says {rate:g} samples a second and its timestamps, read in "
            f"ms as the VXP format writes them, step {measured:.4g} a second: the timestamps "
            "are in another unit, or the header is another file's"
        )
    if ratio > 1 + RATE_SLACK:
        return [f"its header's {rate:g} samples a second against the timestamps' {measured:.4g}"]
    return [f"{rate:g} samples a second"]


__all__ = [
    "VXP_OPENING",
    "VXP_DATA",
    "VXP_FIELDS",
    "VXP_AXIS",
    "VXP_LAYOUT",
    "INVALID_FLAGS",
    "MAX_RATE_RATIO",
    "RATE_SLACK",
    "is_vxp",
    "vxp_table",
]
