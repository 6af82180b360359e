"""The column helpers of base: interpolation column by column and the unit-bearing CSV reader."""

import numpy as np
import pytest

from stewart_drake.base.columns import (
    CSV_BYTES_PER_LINE,
    header_cell,
    interp_columns,
    read_csv_columns,
    uniform_columns,
)
from stewart_drake.base.errors import CorruptFileError, InvalidConfigError, MissingFileError


def test_interp_columns_is_np_interp_per_column_and_the_hand_value():
    t = np.array([0.0, 1.0, 3.0])
    Y = np.array([[0.0, 10.0], [2.0, 20.0], [6.0, -20.0]])
    t_new = np.array([-1.0, 0.5, 2.0, 4.0])
    got = interp_columns(t_new, t, Y)
    # By hand: held at the ends, halfway between the samples inside.
    assert got.tolist() == [[0.0, 10.0], [1.0, 15.0], [4.0, 0.0], [6.0, -20.0]]
    rng = np.random.default_rng(3)
    t = np.sort(rng.uniform(0, 1, 50))
    Y = rng.normal(size=(50, 4))
    t_new = rng.uniform(-0.1, 1.1, 200)
    expected = np.column_stack([np.interp(t_new, t, Y[:, c]) for c in range(4)])
    assert np.array_equal(interp_columns(t_new, t, Y), expected)


def test_interp_columns_wraps_with_a_period_and_fills_out():
    phase = np.array([0.0, 0.25, 0.5, 0.75])
    Y = np.array([[0.0], [1.0], [0.0], [-1.0]])
    got = interp_columns(np.array([0.875, 1.0]), phase, Y, period=1.0)
    assert got.tolist() == [[-0.5], [0.0]]  # between 0.75 (-1) and 1.0 = 0 (0): wrapped
    out = np.zeros((2, 1), dtype=np.float32)
    assert interp_columns(np.array([0.125, 0.375]), phase, Y, out=out) is out
    assert out.tolist() == [[0.5], [0.5]]


@pytest.mark.parametrize(
    "Y, out, message",
    [
        (np.zeros(3), None, r"Y of shape \(3,\): expected \(3, k\)"),
        (np.zeros((2, 2)), None, r"Y of shape \(2, 2\): expected \(3, k\)"),
        (np.zeros((3, 2)), np.zeros((4, 2)), r"out of shape \(4, 2\): expected \(5, 2\)"),
    ],
)
def test_interp_columns_refuses_shapes_it_cannot_fill(Y, out, message):
    with pytest.raises(ValueError, match=message):
        interp_columns(np.linspace(0, 1, 5), np.array([0.0, 0.5, 1.0]), Y, out=out)


def _length_columns(path):
    """columns_of for a file with the columns t [s|ms] and X [m|mm]."""
    units = {"t": {"s": 1.0, "ms": 1e-3}, "X": {"m": 1.0, "mm": 1e-3}}

    def columns_of(cells):
        found = {}
        for index, cell in enumerate(cells):
            name, unit = header_cell(cell)
            if name in units:
                if unit not in units[name]:
                    raise InvalidConfigError(f"{path}: column {name!r} has the unit [{unit}]")
                found[name] = (index, units[name][unit])
        return found

    return columns_of


def _read(path, text, **kw):
    path.write_text(text)
    return read_csv_columns(path, "log", 1e6, "write it again", _length_columns(path), **kw)


def test_uniform_columns_resamples_on_the_steps_from_the_first_time_to_the_last():
    # Times 0, 0.3, 1.0, 1.25 s; a line and a parabola: on a 0.1 s grid from 0 to 1.2 s, the
    # line exactly and the parabola by its chords (each written out by hand).
    t = np.array([0.0, 0.3, 1.0, 1.25])
    Y = np.column_stack([2.0 * t + 1.0, t**2])
    grid, Yg = uniform_columns(t, Y, 0.1)
    assert grid == pytest.approx(np.arange(13) * 0.1, abs=1e-12)
    assert Yg[:, 0] == pytest.approx(2.0 * grid + 1.0, abs=1e-12)
    assert Yg[2, 1] == pytest.approx(0.09 * 2 / 3, abs=1e-12)  # on 0 -> 0.09 over 0.3 s
    assert Yg[5, 1] == pytest.approx(0.09 + (1.0 - 0.09) * 0.2 / 0.7, abs=1e-12)
    assert Yg[12, 1] == pytest.approx(1.0 + (1.5625 - 1.0) * 0.2 / 0.25, abs=1e-12)


@pytest.mark.parametrize("step", [0.0, -0.1, float("nan"), float("inf")])
def test_uniform_columns_refuses_a_step_that_is_not_positive(step):
    with pytest.raises(InvalidConfigError, match="step > 0"):
        uniform_columns(np.array([0.0, 1.0]), np.zeros((2, 1)), step)


def test_read_csv_columns_converts_units_and_names_each_row_s_line(tmp_path):
    path = tmp_path / "log.csv"
    text = "# a tracker log\nframe, t [ms] ,X [mm]\n\n7,250,1.5\n# pause\n8,500,-2\n"
    columns, lines = _read(path, text)
    assert set(columns) == {"t", "X"}  # "frame" is read past
    assert columns["t"].tolist() == [0.25, 0.5]  # 250 ms, 500 ms
    assert columns["X"].tolist() == [1.5e-3, -2e-3]  # 1.5 mm, -2 mm: the same product
    assert lines.tolist() == [4, 6]  # the comments and the blank line keep their numbers
    assert header_cell(" X [ mm ] ") == ("X", "mm") and header_cell("frame ") == ("frame", "")


@pytest.mark.parametrize(
    "text, kw, message",
    [
        ("t [s],X [m]\n0,1\n1,abc\n", {}, r"log.csv, line 3, column X: 'abc' is not a finite"),
        ("t [s],X [m]\n0,nan\n", {}, r"line 2, column X: 'nan' is not a finite number; redo$"),
        ("t [s],X [m]\n0,1,2\n", {}, r"log.csv, line 2: 3 cells where the header names 2$"),
        ("# only a comment\n", {}, r"log.csv: the log is empty; write it again$"),
        ("t [h],X [m]\n", {}, r"log.csv: column 't' has the unit \[h\]$"),
    ],
)
def test_read_csv_columns_refuses_in_one_line(tmp_path, text, kw, message):
    with pytest.raises(InvalidConfigError, match=message) as err:
        _read(tmp_path / "log.csv", text, bad_cell="; redo", **kw)
    assert "\n" not in str(err.value)


def test_read_csv_columns_takes_nan_where_allowed_and_refuses_what_is_not_csv(tmp_path):
    columns, _ = _read(tmp_path / "log.csv", "t [s],X [m]\n0,nan\n", nan_ok=("X",))
    assert np.isnan(columns["X"][0])
    with pytest.raises(CorruptFileError, match=r"not CSV \(field larger than field limit"):
        _read(tmp_path / "log.csv", "t [s],X [m]\n0," + "1" * 200_000 + "\n")
    with pytest.raises(MissingFileError, match="no log at"):
        read_csv_columns(tmp_path / "none.csv", "log", 1e6, "", _length_columns(None))


def test_read_csv_columns_estimates_its_memory_before_it_parses(tmp_path, monkeypatch):
    """1000 lines of 6 bytes: 1000 * CSV_BYTES_PER_LINE + 6000 bytes of text, refused when
    the process has less."""
    import stewart_drake.base.fileio as fileio

    text = "t [s],X [m]\n" + "0,1.5\n" * 999
    need = 1000 * CSV_BYTES_PER_LINE + len(text)
    monkeypatch.setattr(fileio, "available_memory_bytes", lambda: need - 1)
    with pytest.raises(InvalidConfigError, match=r"\(1,000 lines\) needs about"):
        _read(tmp_path / "log.csv", text)
    monkeypatch.setattr(fileio, "available_memory_bytes", lambda: need)
    assert len(_read(tmp_path / "log.csv", text)[1]) == 999
