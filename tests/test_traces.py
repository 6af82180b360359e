"""Recorded traces: units and headers read, gaps refused with their time, centring, mapping and
the low-pass, a C2 reference out."""

import numpy as np
import pytest
from conftest import write_trace

from stewart_drake.base.errors import InvalidConfigError
from stewart_drake.references.traces import TraceTrajectory, load_trace
from stewart_drake.robot.geometry import X_HOME


def test_a_30_hz_trace_in_mm_and_deg_with_a_gap_becomes_a_c2_reference(tmp_path):
    t = np.arange(0.0, 12.0, 1 / 30)
    si = 7.5 * np.cos(np.pi * t / 4) ** 2  # mm
    pitch = 0.5 * np.sin(np.pi * t / 4)  # deg
    path = write_trace(
        tmp_path / "patient.csv", t, {"SI [mm]": si, "rot_LR (deg)": pitch}, gap=(5.0, 5.5)
    )
    ref = load_trace(path, centre_on="none")
    assert isinstance(ref, TraceTrajectory) and ref.end_time == pytest.approx(t[-1])
    assert ref.info.axes == ("+X", "+theta") and ref.info.units[1:] == ("mm", "deg")
    assert len(ref.info.gaps) == 1 and 0.5 <= ref.info.gaps[0][1] < 0.6  # both axes
    assert ref.info.sample_rate_hz == pytest.approx(30.0, rel=1e-3)
    x, v, a = ref.evaluate(t)
    assert np.allclose(x[:, 3], X_HOME[3] + si * 1e-3, atol=2e-6)  # mm -> m, also in the gap
    assert np.allclose(x[:, 1], np.radians(pitch), atol=2e-6)  # deg -> rad
    assert np.allclose(x[:, [0, 2, 4]], 0.0) and np.allclose(x[:, 5], X_HOME[5])
    # C2: rate and acceleration continuous across the knots
    tk = np.arange(0.5, 11.5, 0.01)
    for part in (v, a):
        left, right = (
            np.asarray(ref.evaluate(tk + s)[1 if part is v else 2]) for s in (-1e-9, 1e-9)
        )
        assert np.abs(left - right).max() < 1e-5
    assert "gaps bridged" in ref.info.summary() and "SI [mm] -> +X" in ref.info.summary()


def test_trace_centring_mapping_and_lowpass(tmp_path):
    t = np.arange(0.0, 8.0, 0.01)
    slow, fast = 5 * np.sin(2 * np.pi * 0.25 * t), 0.5 * np.sin(2 * np.pi * 20 * t)
    path = write_trace(tmp_path / "trace.csv", t, {"depth [mm]": 2 + slow + fast})
    centre = [0, 0, 0, 0.001, 0, 0.31]
    ref = load_trace(path, axis_map={"depth": "-Z"}, centre=centre, lowpass_hz=2.0)
    z = ref.evaluate(t)[0][:, 5]
    inner = (t > 1) & (t < 7)
    # mean removed, sign flipped, 20 Hz gone, the slow motion kept without lag
    assert np.abs(z - (0.31 - (slow + 2 - (2 + slow + fast).mean()) * 1e-3))[inner].max() < 2e-5
    first = load_trace(path, axis_map={"depth": "Z"}, centre_on="first")
    assert first.evaluate(0.0)[0][5] == pytest.approx(X_HOME[5])


@pytest.mark.parametrize(
    "header,row,match",
    [
        ("time [s],SI", "0,1", "needs a unit of length"),
        ("time [s],SI [deg]", "0,1", "a angle on a translation axis|an angle|angle on a"),
        ("time [s],SI [mm],X [mm]", "0,1,2", "two columns go to the platform's X"),
        ("depth [mm],t [s]", "0,1", "first column must be the time"),
        ("t [furlong],Z [mm]", "0,1", "time column needs its unit"),
        ("t [s],heart [mm]", "0,1", "unknown axis 'heart'"),
    ],
)
def test_a_bad_trace_header_is_refused_naming_the_column(tmp_path, header, row, match):
    path = tmp_path / "bad.csv"
    path.write_text(header + "\n" + "\n".join([row] * 5) + "\n")
    with pytest.raises(InvalidConfigError, match=match):
        load_trace(path)


def test_a_gap_longer_than_allowed_is_refused_with_its_time(tmp_path):
    t = np.arange(0.0, 10.0, 0.1)
    path = write_trace(tmp_path / "gap.csv", t, {"Z [mm]": np.sin(t)}, gap=(3.0, 5.0))
    with pytest.raises(InvalidConfigError, match=r"no data for 2 s from t = 3 s"):
        load_trace(path, max_gap_s=1.0)
    assert load_trace(path, max_gap_s=3.0).info.gaps


def test_a_trace_shorter_than_two_resampling_steps_is_refused(tmp_path):
    from stewart_drake.base.errors import InvalidConfigError as Refused
    from stewart_drake.references.traces import load_trace as load

    path = tmp_path / "tiny.csv"
    path.write_text("t [s],SI [mm]\n0,0\n0.001,1\n0.002,0\n0.003,1\n")
    with pytest.raises(Refused, match=r"lasts 0.003 s, shorter than two resampling steps"):
        load(path)


# -- the layouts users have ----------------------------------------------------------------------


def _phantom_text(t, columns, sep=" ", decimal="."):
    """A trace written as motion phantoms write theirs: no header, one sample per line, no
    newline after the last."""
    lines = [sep.join(f"{v:.6g}" for v in row) for row in np.column_stack([t, *columns])]
    return "\n".join(lines).replace(".", decimal) if decimal != "." else "\n".join(lines)


def test_the_phantom_format_is_read_as_downloaded(tmp_path):
    """7 columns, spaces, no header (t LR SI AP [mm] rLR rSI rAP [deg], 5 Hz): each column on
    its patient axis, in SI units, and the layout said."""
    t = np.arange(0.0, 30.0, 0.2)
    lr, si, ap = 0.5 * np.sin(t), 6.0 * np.sin(2 * np.pi * t / 4), 1.5 * np.cos(t)
    r_lr, r_si, r_ap = 0.8 * np.sin(t / 2), 0.4 * np.cos(t / 3), 0.2 * np.sin(t / 5)
    path = tmp_path / "Liver_Trace 1.txt"
    path.write_text(_phantom_text(t, [lr, si, ap, r_lr, r_si, r_ap]))
    ref = load_trace(path, centre_on="none", smoothing="none")
    assert ref.info.layout == "phantom format, no header, separated by spaces"
    assert ref.info.columns == ("t", "LR", "SI", "AP", "rot_LR", "rot_SI", "rot_AP")
    assert ref.info.axes == ("+Y", "+X", "+Z", "+theta", "+phi", "+psi")
    x = ref.evaluate(t)[0]
    for k, values, scale in (
        (3, si, 1e-3),
        (4, lr, 1e-3),
        (5, ap, 1e-3),
        (0, r_si, np.pi / 180),
        (1, r_lr, np.pi / 180),
        (2, r_ap, np.pi / 180),
    ):
        assert np.allclose(x[:, k] - X_HOME[k], values * scale, atol=1e-9), k
    with pytest.raises(InvalidConfigError, match=r"the csv.*no header|no header line naming"):
        load_trace(path, format="csv")


def test_a_surrogate_file_goes_to_si_unless_mapped(tmp_path):
    t = np.arange(0.0, 20.0, 0.2)
    path = tmp_path / "resp.txt"
    path.write_text(_phantom_text(t, [3.0 * np.sin(t)]))
    ref = load_trace(path, centre_on="none", smoothing="none")
    assert ref.info.layout.startswith("surrogate format") and ref.info.axes == ("+X",)
    assert np.allclose(ref.evaluate(t)[0][:, 3], 3e-3 * np.sin(t), atol=1e-9)
    ref = load_trace(path, centre_on="none", axis_map={"surrogate": "-Z"}, smoothing="none")
    assert ref.info.axes == ("-Z",)
    assert np.allclose(ref.evaluate(t)[0][:, 5] - X_HOME[5], -3e-3 * np.sin(t), atol=1e-9)


@pytest.mark.parametrize(
    "sep, decimal, layout",
    [
        (";", ",", "header, separated by semicolons, decimal commas"),
        ("\t", ",", "header, separated by tabs, decimal commas"),
        ("\t", ".", "header, separated by tabs"),
        (" ", ",", "columns given, separated by spaces, decimal commas"),
    ],
    ids=["semicolon-comma", "tab-comma", "tab-point", "space-comma"],
)
def test_any_separator_and_decimal_mark_read_as_the_comma_file(tmp_path, sep, decimal, layout):
    """The same samples as a comma-separated file with a header, written as spreadsheets in
    many locales write them, give the same reference to the last bit."""
    t = np.arange(0.0, 12.0, 0.04)
    si, ap = 5.0 * np.sin(2 * np.pi * t / 4) ** 2, 1.2 * np.cos(2 * np.pi * t / 4)
    plain = tmp_path / "plain.csv"
    plain.write_text("t [s],SI [mm],AP [mm]\n" + _phantom_text(t, [si, ap], sep=",") + "\n")
    body = _phantom_text(t, [si, ap], sep=sep, decimal=decimal)
    other = tmp_path / "other.txt"
    columns = ""
    if layout.startswith("header"):
        other.write_text(sep.join(["t [s]", "SI [mm]", "AP [mm]"]) + "\n" + body + "\n")
    else:
        other.write_text(body + "\n")
        columns = "t [s], SI [mm], AP [mm]"
        with pytest.raises(InvalidConfigError, match=r"no header line and 3 columns"):
            load_trace(other)
    a, b = load_trace(plain), load_trace(other, columns=columns)
    assert b.info.layout == layout
    probe = np.linspace(0.0, t[-1], 777)
    assert np.array_equal(a.evaluate(probe)[0], b.evaluate(probe)[0])


def test_a_header_where_the_phantom_format_has_none_is_refused(tmp_path):
    path = write_trace(tmp_path / "h.csv", np.arange(0.0, 5.0, 0.1), {"SI [mm]": np.zeros(50)})
    with pytest.raises(InvalidConfigError, match=r"the phantom format has no header line"):
        load_trace(path, format="phantom")
    with pytest.raises(InvalidConfigError, match=r"trace format 'xml': use one of auto, csv"):
        load_trace(path, format="xml")
