"""Recordings read as published: a marker export whose time column switches, for a run of lines,
to another unit (frame / 30 s among ms: 12700 then 25.6) while its frame counter climbs, is
repaired from the counter and says so line by line (read_measured, load_trace, verify, check);
a counter that does not climb, or times mostly off it, are refused naming why; without a
counter the refusal names the line as before; a closing line of zeros is still left out."""

import numpy as np
import pytest

from stewart_drake.base.errors import InvalidConfigError
from stewart_drake.cli.main import main
from stewart_drake.references.organ.library import make_motion
from stewart_drake.references.traces import load_trace
from stewart_drake.verification.measured_motion import read_measured

RATE_HZ = 30.0
#: The lines (0-based data rows) whose time the export wrote as frame / 30 s instead of ms.
GLITCH = range(200, 212)


def export(path, glitch=True, counter=True, zeros=True, frames=None, seconds=40.0):
    """A marker export of the library's breathing at 30 Hz, ms on its clock from frame 300:
    'frame,t [ms],X [mm],Y [mm],Z [mm]', the GLITCH rows' times in s, a closing line of zeros.
    Returns (path, the true times in s)."""
    n = int(seconds * RATE_HZ)
    f = np.arange(300, 300 + n) if frames is None else np.asarray(frames)
    t = f / RATE_HZ  # s
    x = make_motion("breathing").evaluate(t - t[0])[0][:, 3:] * 1e3
    written = t * 1e3
    if glitch:
        written = written.copy()
        written[list(GLITCH)] = t[list(GLITCH)]  # the export's other unit for a run of lines
    head = ("frame," if counter else "") + "t [ms],X [mm],Y [mm],Z [mm]"
    rows = [head] + [
        (f"{fr}," if counter else "") + f"{w:.6g},{a:.4f},{b:.4f},{c:.4f}"
        for fr, w, (a, b, c) in zip(f, written, x)
    ]
    if zeros:
        rows.append(",".join(["0"] * (5 if counter else 4)))
    path.write_text("\n".join(rows) + "\n")
    return path, t


def test_a_glitched_time_column_is_repaired_from_the_counter_line_by_line(tmp_path):
    path, t = export(tmp_path / "m.csv")
    m = read_measured(path)
    np.testing.assert_allclose(m.t, t, rtol=0, atol=5e-5)  # 6 digits of ms written: 0.05 ms
    assert len(m.repaired) == len(GLITCH)
    first = m.repaired[0]
    # Line 2 is the first data row: row 200 is line 202.
    assert first.startswith(f"line 202: the time {t[200]:.6g} ms repaired to ")
    repaired_ms = float(first.split("repaired to ")[1].split(" ms")[0])
    assert repaired_ms == pytest.approx(t[200] * 1e3, abs=1e-3)
    assert "30 frames a second" in first
    assert "left out: line" in m.words() and "12 times repaired from the frame counter" in m.words()


def test_a_trace_read_as_a_reference_is_repaired_alike_and_says_so(tmp_path):
    path, t = export(tmp_path / "trace.csv")
    trace = load_trace(path)
    assert len(trace.info.repaired) == len(GLITCH)
    assert "12 times repaired from the frame counter" in trace.info.summary()
    assert trace.info.duration_s == pytest.approx(t[-1] - t[0], abs=1e-3)


def test_a_clean_export_with_a_counter_is_read_as_written(tmp_path):
    path, t = export(tmp_path / "m.csv", glitch=False)
    m = read_measured(path)
    assert m.repaired == ()
    np.testing.assert_allclose(m.t, t, rtol=0, atol=5e-5)


def test_without_a_counter_the_refusal_names_the_line(tmp_path):
    path, _ = export(tmp_path / "m.csv", counter=False)
    with pytest.raises(InvalidConfigError, match=r"line 202: the time .* is not after"):
        read_measured(path)


def test_a_counter_that_does_not_climb_is_refused_naming_its_line(tmp_path):
    f = np.arange(300, 300 + 1200)
    f[500] = f[499]
    path, _ = export(tmp_path / "m.csv", frames=f)
    with pytest.raises(InvalidConfigError, match=r"line 502: the frame counter 799 is not after"):
        read_measured(path)


def test_times_mostly_off_the_counter_are_refused(tmp_path):
    path, t = export(tmp_path / "m.csv", glitch=False)
    lines = path.read_text().splitlines()
    # Every other line's time in s: half and more of the lines off the counter's line.
    for i in range(1, len(lines) - 1, 2):
        cells = lines[i].split(",")
        cells[1] = f"{float(cells[1]) / 1e3:.6g}"
        lines[i] = ",".join(cells)
    path.write_text("\n".join(lines) + "\n")
    with pytest.raises(InvalidConfigError, match="the counter, not the times, is in doubt"):
        read_measured(path)


def test_a_counters_rate_given_in_its_unit_is_used(tmp_path):
    path, t = export(tmp_path / "m.csv")
    text = path.read_text().replace("frame,", "frame [30 Hz],", 1)
    path.write_text(text)
    m = read_measured(path)
    assert len(m.repaired) == len(GLITCH)
    np.testing.assert_allclose(m.t, t, rtol=0, atol=5e-5)
    path.write_text(text.replace("frame [30 Hz]", "frame [mm]", 1))
    with pytest.raises(InvalidConfigError, match=r"the frame counter's unit is its rate"):
        read_measured(path)


def test_verify_and_check_read_the_glitched_export(tmp_path, capsys):
    path, _ = export(tmp_path / "m.csv")
    out = tmp_path / "out"
    code = main(["verify", "breathing", "--measured", str(path), "--out", str(out)])
    printed = capsys.readouterr()
    assert code == 0, printed.out + printed.err  # the breathing as asked: judged, and PASSes
    page = next(out.glob("verify_*.md")).read_text()
    assert "12 times repaired from the frame counter: line 202:" in page
    assert main(["check", str(path)]) == 0
    assert "12 times repaired from the frame counter" in capsys.readouterr().out
