"""Varian RPM exports (.vxp) read as the RPM system writes them: the header's Data_layout,
Scale_factor and Samples_per_second, invalid samples dropped and counted. Every expected value
below is worked from the file's own numbers here, never from the reader."""

import numpy as np
import pytest

from stewart_drake.base.errors import InvalidConfigError
from stewart_drake.references.trace_files import read_trace_table, trace_samples
from stewart_drake.references.traces import load_trace
from stewart_drake.verification.measured_motion import read_measured

LAYOUT_16 = "amplitude,phase,timestamp,validflag,ttlin,mark,ttlout"


def _vxp(path, amplitude_raw, stamps_ms, flags, scale="10", rate="30", layout=LAYOUT_16):
    """A VXP 1.6 file as the RPM system writes one (the mark column's P and Z included)."""
    lines = ["[Header]", "CRC=1234", "Version=1.6", f"Data_layout={layout}"]
    lines += ["Patient_ID=Anonymous", "Date=11-28-2026", "Total_study_time=60"]
    lines += [f"Samples_per_second={rate}"] if rate is not None else []
    lines += [f"Scale_factor={scale}"] if scale is not None else []
    lines.append("[Data]")
    for k, (a, t, v) in enumerate(zip(amplitude_raw, stamps_ms, flags)):
        mark = "P" if k % 120 == 0 else ("Z" if k % 120 == 60 else "")
        lines.append(f"{a:.4f},{(k % 60) / 60 * 6.2832:.4f},{int(t)},{v},0,{mark},0")
    path.write_text("\n".join(lines) + "\n")
    return path


def _breath(n=1200, rate=30.0):
    """A 4 s breath of 0.5 (raw units) sampled at ``rate`` from 111424 ms, as RPM's clock."""
    t_ms = 111424 + np.round(np.arange(n) * 1000.0 / rate)
    raw = 0.5 * np.sin(2 * np.pi * (t_ms - t_ms[0]) / 4000.0)
    return raw, t_ms


def test_amplitude_and_time_are_read_in_the_units_the_header_gives(tmp_path):
    raw, t_ms = _breath()
    for scale in ("10", "1"):  # 10: cm as written; 1: a tenth of that
        path = _vxp(tmp_path / f"s{scale}.vxp", raw, t_ms, np.zeros(raw.size, int), scale=scale)
        header, rows, layout = read_trace_table(path, "auto", "")
        table = trace_samples(path, header, rows, layout, None)
        assert header == ["t [ms]", "amplitude [mm]"]
        # amplitude x Scale_factor / 10 cm = amplitude x Scale_factor mm, on the AP axis (Z).
        np.testing.assert_allclose(table.data[:, 1], raw.round(4) * float(scale), atol=1e-12)
        assert table.targets == [5] and table.factors == [pytest.approx(1e-3)]
        np.testing.assert_allclose(table.t, (t_ms - t_ms[0]) * 1e-3, atol=1e-12)
        assert table.start_s == pytest.approx(111.424)
        assert (
            layout.startswith("Varian RPM export (version 1.6") and "30 samples a second" in layout
        )


def test_invalid_samples_are_dropped_and_counted_by_their_flag(tmp_path):
    raw, t_ms = _breath()
    flags = np.zeros(raw.size, int)
    flags[100:130] = -1  # a second of lost track
    flags[500:505] = -2  # a cough
    raw = raw.copy()
    raw[100:130] = 9.0  # what a lost track reads: never the block's position
    path = _vxp(tmp_path / "dropout.vxp", raw, t_ms, flags)
    header, rows, layout = read_trace_table(path, "vxp", "")
    table = trace_samples(path, header, rows, layout, None)
    assert len(table.t) == raw.size - 35
    assert np.max(np.abs(table.data[:, 1])) == pytest.approx(5.0, abs=1e-3)  # 0.5 cm, in mm
    assert (
        "35 invalid samples dropped (validflag -1, the track lost or a bad video signal: 30; "
        "validflag -2, non-periodic breathing: 5)" in layout
    )


def test_the_reference_follows_the_breath_across_a_dropout_at_the_start(tmp_path):
    # The track lost for the first half second: the reference starts where the samples do.
    raw, t_ms = _breath(1800)
    flags = np.zeros(raw.size, int)
    flags[1:15] = -1
    path = _vxp(tmp_path / "start.vxp", raw, t_ms, flags)
    ref = load_trace(path, centre_on="none")
    x, _, _ = ref.evaluate(np.linspace(0.0, ref.end_time, 4000))
    assert np.ptp(x[:, 5]) == pytest.approx(0.010, rel=0.02)  # 2 x 5 mm, nothing more
    assert np.ptp(x[:, :5], axis=0) == pytest.approx(np.zeros(5), abs=1e-12)
    assert ref.info.gaps and ref.info.gaps[0][1] == pytest.approx(0.5, abs=0.02)


def test_a_measured_rpm_file_is_a_measured_ap_motion(tmp_path):
    raw, t_ms = _breath()
    path = _vxp(tmp_path / "block.vxp", raw, t_ms, np.zeros(raw.size, int))
    measured = read_measured(path)
    assert list(measured.measured) == [False] * 5 + [True]
    np.testing.assert_allclose(measured.poses[:, 5], raw.round(4) * 1e-2, atol=1e-12)
    # A map moves it and reverses it.
    measured = read_measured(path, axis_map={"amplitude": "-SI"})
    assert measured.measured[3] and not measured.measured[5]


@pytest.mark.parametrize(
    "change, words",
    [
        (dict(scale=None), "has no Scale_factor: the amplitude's unit is not known"),
        (dict(scale="0"), "Scale_factor must be a number above 0, got '0'"),
        (dict(scale="ten"), "Scale_factor must be a number above 0, got 'ten'"),
        (dict(rate=None), "has no Samples_per_second"),
        (dict(rate="0.03"), "the timestamps are in another unit"),
        (dict(layout="phase,timestamp,validflag"), "names no amplitude"),
    ],
)
def test_a_header_that_does_not_say_how_to_read_it_is_refused(tmp_path, change, words):
    raw, t_ms = _breath(300)
    path = _vxp(tmp_path / "bad.vxp", raw, t_ms, np.zeros(raw.size, int), **change)
    with pytest.raises(InvalidConfigError, match="bad.vxp") as err:
        read_trace_table(path, "auto", "")
    assert words in str(err.value)


def test_the_header_rate_is_said_when_the_timestamps_disagree_and_agrees_at_its_edge(tmp_path):
    raw, t_ms = _breath(300)
    flags = np.zeros(raw.size, int)
    # 30 Hz timestamps: a header of 25 is 1.2x off (said); 27.5, 1.09x (within 10 %).
    _, _, said = read_trace_table(_vxp(tmp_path / "a.vxp", raw, t_ms, flags, rate="25"), "auto", "")
    assert "its header's 25 samples a second against the timestamps' 30" in said
    _, _, quiet = read_trace_table(
        _vxp(tmp_path / "b.vxp", raw, t_ms, flags, rate="27.5"), "auto", ""
    )
    assert "27.5 samples a second" in quiet and "against" not in quiet
    # A factor of 2 is the edge of a wrong unit: 15 passes, 14.9 is refused.
    read_trace_table(_vxp(tmp_path / "c.vxp", raw, t_ms, flags, rate="15"), "auto", "")
    with pytest.raises(InvalidConfigError, match="another unit"):
        read_trace_table(_vxp(tmp_path / "d.vxp", raw, t_ms, flags, rate="14.9"), "auto", "")


def test_files_that_are_not_whole_vxp_exports_are_refused_by_line(tmp_path):
    raw, t_ms = _breath(300)
    path = _vxp(tmp_path / "cut.vxp", raw, t_ms, np.zeros(raw.size, int))
    text = path.read_text()
    (tmp_path / "nodata.vxp").write_text(text.split("[Data]")[0])
    with pytest.raises(InvalidConfigError, match=r"without its \[Data\] line"):
        read_trace_table(tmp_path / "nodata.vxp", "auto", "")
    lines = text.splitlines()
    lines[20] = "0.1,0.2"
    (tmp_path / "short.vxp").write_text("\n".join(lines))
    with pytest.raises(InvalidConfigError, match="line 21: 2 fields, its Data_layout needs 4"):
        read_trace_table(tmp_path / "short.vxp", "auto", "")
    lines[20] = "0.1,0.2,abc,0,0,,0"
    (tmp_path / "word.vxp").write_text("\n".join(lines))
    with pytest.raises(InvalidConfigError, match="line 21: not numbers"):
        read_trace_table(tmp_path / "word.vxp", "auto", "")
    every = _vxp(tmp_path / "none.vxp", raw, t_ms, -np.ones(raw.size, int))
    with pytest.raises(InvalidConfigError, match="no valid sample"):
        read_trace_table(every, "auto", "")
    with pytest.raises(InvalidConfigError, match="leave --columns out"):
        read_trace_table(path, "auto", "t [s],SI [mm]")
    csv = tmp_path / "plain.csv"
    csv.write_text("t [s],SI [mm]\n0,1\n0.1,2\n")
    with pytest.raises(InvalidConfigError, match="not a Varian RPM export"):
        read_trace_table(csv, "vxp", "")
