"""Trace files as instruments export them: an optical tracker's marker export read by the options
alone (a frame column skipped, its closing line of zeros left out and said, the mean it sat at
named), times in ms declared as s named before any memory is asked for, a space-separated header
with units, and ``check`` taking every reading option ``reproduce`` takes."""

import warnings

import numpy as np
import pytest
from conftest import write_trace

import stewart_drake.base.checks
from stewart_drake.base.errors import InvalidConfigError
from stewart_drake.cli.main import main
from stewart_drake.cli.registry import build_parser
from stewart_drake.references.trace_cleaning import SEAM_BLEND_S
from stewart_drake.references.trace_files import MAX_SAMPLE_STEP_S, SKIP_COLUMN, TRACE_FORMATS
from stewart_drake.references.traces import CENTRE_MODES, SMOOTHING_MODES, load_trace

#: The columns a user gives a marker export: its frame counter skipped, time in ms.
MARKER_COLUMNS = "-,t [ms],X [mm],Y [mm],Z [mm]"


def write_marker_export(path, seconds=222.0, rate_hz=10.0, mean_mm=(-12.5, 31.0, -490.0)):
    """Write an optical tracker's marker export: a quoted header ``"Frame";"Timestamp";"x";"y";
    "z"``, ``;``-separated, decimal commas, CRLF line ends, time in ms from the tracker's clock
    (not from 0), absolute marker coordinates in mm breathing about ``mean_mm`` (6 mm on z at
    0.25 Hz), and a last line ``0;0;0;0;0``. Returns (path, the zero line's number, (n, 4) the
    numbers written: t ms, x, y, z mm)."""
    n = int(round(seconds * rate_hz))
    t_ms = 123456.0 + np.arange(n) * 1000.0 / rate_hz
    breath = 6.0 * np.sin(np.pi * 0.25 * (t_ms - t_ms[0]) / 1000.0) ** 2
    xyz = np.column_stack([0.3 * breath, 0.5 * breath, breath]) + np.asarray(mean_mm)

    def comma(v):
        return f"{v:.3f}".replace(".", ",")

    lines = ['"Frame";"Timestamp";"x";"y";"z"']
    lines += [";".join([str(k + 1), comma(t_ms[k])] + [comma(v) for v in xyz[k]]) for k in range(n)]
    lines.append("0;0;0;0;0")
    path.write_bytes(("\r\n".join(lines) + "\r\n").encode())
    written = np.column_stack([t_ms, np.round(xyz, 3)])
    return path, len(lines), written


def test_a_marker_export_reads_with_the_frame_column_skipped_and_says_what_it_removed(tmp_path):
    path, zero_line, written = write_marker_export(tmp_path / "markers.csv")
    assert zero_line == 2222  # the file: 2220 samples, a header and the zero line
    raw = path.read_bytes()
    assert raw.count(b"\r\n") == zero_line and b"490,000" in raw  # as the tracker writes it

    ref = load_trace(path, columns=MARKER_COLUMNS)
    info = ref.info
    assert info.samples == 2220 and info.sample_rate_hz == pytest.approx(10.0)
    assert ref.end_time == pytest.approx(221.9)  # ms from the first sample, not the clock
    assert info.axes == ("+X", "+Y", "+Z") and info.columns[1:] == ("X", "Y", "Z")
    assert "semicolons, decimal commas" in info.layout
    assert info.dropped == "line 2222 (all zeros after the last sample)"
    # The mean removed is the marker's own (about -490 mm on z), said in the summary.
    removed_mm = np.asarray(info.removed)[3:] * 1e3
    assert removed_mm == pytest.approx(written[:, 1:].mean(axis=0), abs=0.05)
    assert removed_mm[2] == pytest.approx(-490.0 + 3.0, abs=0.05)  # 6 mm breath, mean +3
    summary = info.summary()
    assert f"its mean removed (X {removed_mm[0]:.4g} mm, Y {removed_mm[1]:.4g} mm, Z " in summary
    assert "Z -487 mm" in summary and "left out: line 2222" in summary
    # What is left is the breath about the centre: 6 mm peak to peak, no -490 mm offset.
    x = ref.evaluate(np.arange(0.0, 220.0, 0.05))[0]
    assert np.ptp(x[:, 5]) * 1e3 == pytest.approx(6.0, abs=0.01)
    assert np.mean(x[:, 5]) == pytest.approx(0.30, abs=1e-4)
    assert np.ptp(x[:, 3]) * 1e3 == pytest.approx(1.8, abs=0.01)


def test_a_line_of_zeros_inside_a_trace_is_refused_by_its_line(tmp_path):
    path, _, _ = write_marker_export(tmp_path / "markers.csv", seconds=30.0)
    lines = path.read_bytes().split(b"\r\n")
    lines.insert(101, b"0;0;0;0;0")  # line 102: after the sample of line 101
    path.write_bytes(b"\r\n".join(lines))
    with pytest.raises(InvalidConfigError, match=r"line 102: the time 0 is not after") as err:
        load_trace(path, columns=MARKER_COLUMNS)
    assert "line 101" in str(err.value)
    # without the skip, the frame counter is the first column and the message says how
    with pytest.raises(InvalidConfigError, match=f"naming it {SKIP_COLUMN}: --columns"):
        load_trace(path)


def test_ms_declared_as_s_is_refused_with_the_likely_unit_before_any_memory_check(
    tmp_path, monkeypatch
):
    path, _, _ = write_marker_export(tmp_path / "markers.csv")

    def no_memory_check(*args, **kwargs):
        raise AssertionError("the memory check ran before the unit was checked")

    monkeypatch.setattr(stewart_drake.base.checks, "check_memory", no_memory_check)
    with pytest.raises(InvalidConfigError) as err:
        load_trace(path, columns="-,t [s],X [mm],Y [mm],Z [mm]")
    text = str(err.value)
    assert "likely in ms: as 't [ms]' they are 10 Hz over 221.9 s" in text
    assert "100 s apart (0.01 Hz) over 2.219e+05 s" in text
    assert text.index("likely in ms") < text.index("declared in s")  # the unit first


def test_a_space_separated_header_keeps_each_unit_with_its_name(tmp_path):
    t = np.arange(0.0, 12.0, 0.1)
    si = 5.0 * np.sin(2 * np.pi * 0.25 * t)
    path = tmp_path / "spaced.txt"
    path.write_text("t [s]  SI [mm]\n" + "".join(f"{a:.2f}  {b:.4f}\n" for a, b in zip(t, si)))
    ref = load_trace(path, centre_on="none", smoothing="none")
    assert ref.info.columns == ("t", "SI") and ref.info.units == ("s", "mm")
    assert ref.evaluate(t)[0][:, 3] * 1e3 == pytest.approx(si, abs=1e-4)
    path.write_text("t  SI [mm]\n" + "".join(f"{a:.2f}  {b:.4f}\n" for a, b in zip(t, si)))
    with pytest.raises(InvalidConfigError, match=r"needs its unit .*got 't'$"):
        load_trace(path)


def _trace_options(command: str) -> dict:
    parser = build_parser()
    sub = [a for a in parser._actions if isinstance(getattr(a, "choices", None), dict)][0]
    options = {}
    for action in sub.choices[command]._actions:
        for flag in action.option_strings:
            options[flag] = (action.default, action.choices, action.help)
    return options


def test_check_and_reproduce_read_a_trace_with_the_same_options():
    check, reproduce = _trace_options("check"), _trace_options("reproduce")
    reading = ["--format", "--columns", "--map", "--lowpass-hz", "--centre", "--centre-on"]
    for flag in reading + ["--max-gap", "--smoothing", "--seam-blend"]:
        assert flag in check and check[flag] == reproduce[flag], flag
    assert list(check["--smoothing"][1]) == list(SMOOTHING_MODES)
    assert check["--seam-blend"][0] == SEAM_BLEND_S
    assert list(check["--format"][1]) == list(TRACE_FORMATS)
    assert list(check["--centre-on"][1]) == list(CENTRE_MODES)
    assert f"'{SKIP_COLUMN},t [ms]" in check["--columns"][2]


def test_check_reads_the_marker_export_with_the_options(tmp_path, capsys):
    path, _, _ = write_marker_export(tmp_path / "markers.csv", seconds=20.0)
    out = tmp_path / "out"
    argv = ["check", str(path), "--columns", MARKER_COLUMNS, "--out", str(out)]
    assert main(argv + ["--map", "Z=-Z", "--centre-on", "first"]) == 0
    printed = capsys.readouterr().out
    assert "Z [mm] -> -Z" in printed and "its first sample removed" in printed
    assert "left out: line 202 (all zeros" in printed
    assert "trajectory validated" in printed and (out / "check_markers.png").is_file()
    # the options reach the reading: ms declared as s is refused, exit 2, one line
    assert main(["check", str(path), "--columns", "-,t [s],X [mm],Y [mm],Z [mm]"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "likely in ms" in err
    # and a motion that is not a file refuses them
    assert main(["check", "paper", "--columns", MARKER_COLUMNS]) == 2
    assert "are for a trace file" in capsys.readouterr().err


def test_fidelity_of_empty_logs_is_refused_in_words():
    from stewart_drake.organ_motion.fidelity import fidelity

    with pytest.raises(InvalidConfigError, match=r"fewer than 10 samples \(0\)"):
        fidelity(np.zeros(0), np.zeros((0, 6)), np.zeros((0, 6)))
    with pytest.raises(InvalidConfigError, match=r"must match"):  # empty lists, no axes
        fidelity([], [], [])


def test_huge_relative_harmonics_are_refused_without_numpy_warnings(tmp_path, capsys):
    from stewart_drake.references.organ.heartbeat import Heartbeat

    with warnings.catch_warnings():
        warnings.simplefilter("error")  # an overflow warning would raise here
        with pytest.raises(InvalidConfigError, match="relative amplitudes"):
            Heartbeat(harmonics=(1e308, 1e308))
        with pytest.raises(InvalidConfigError, match="relative amplitudes"):
            Heartbeat(harmonics=(1e-320,))
        argv = ["reproduce", "heartbeat", "--param", "harmonics=1e308,1e308"]
        assert main(argv + ["--out", str(tmp_path), "--no-progress"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.splitlines() == [err] and "divide them by the largest" in err
    # ratios are what matter: scaled together they are the same motion
    a, b = Heartbeat(harmonics=(1.0, 0.5)), Heartbeat(harmonics=(1e5, 0.5e5))
    t = np.linspace(0.0, 2.0, 201)
    assert np.allclose(a.evaluate(t)[0], b.evaluate(t)[0], atol=1e-12)


def test_a_slow_trace_at_the_step_bound_still_reads_and_one_beyond_it_does_not(tmp_path):
    """1 Hz and 0.5 Hz (a slow drift recorder) are read; beyond MAX_SAMPLE_STEP_S, refused."""
    for step, ok in ((1.0, True), (MAX_SAMPLE_STEP_S, True), (2.5, False)):
        t = np.arange(0.0, 300.0, step)
        path = write_trace(tmp_path / "drift.csv", t, {"SI [mm]": 0.01 * t})
        if ok:
            assert load_trace(path).info.sample_rate_hz == pytest.approx(1.0 / step)
        else:
            with pytest.raises(InvalidConfigError, match="too slow to sample a breath"):
                load_trace(path)


@pytest.mark.parametrize("last_s, dropped", [(-40.0, True), (-0.1, False), (5.0, True)])
def test_a_closing_line_of_zeros_on_a_clock_below_zero(tmp_path, last_s, dropped):
    """A tracker's export on a clock that runs below zero (times -60 to -40 s) ends with its
    line of zeros: not a sample at t = 0 (40 s after the last; was read as one, and the right
    export refused); one a step after the last (t = -0.1, then 0) is a sample; after a later
    time (5 s) it never is."""
    t = np.arange(201) * 0.1 + (last_s - 20.0)
    rows = ["t [s],X [mm]"] + [f"{v:.3f},{1.0 + np.sin(v):.4f}" for v in t] + ["0,0"]
    path = tmp_path / "export.csv"
    path.write_text("\n".join(rows) + "\n")
    ref = load_trace(path)
    assert ref.info.samples == (201 if dropped else 202)
    assert (ref.info.dropped == f"line {len(rows)} (all zeros after the last sample)") == dropped
