"""The one reader of the external surrogate's file, for the Diagram's stage
(:func:`~stewart_drake.station.surrogate.pairs.load_external`, ``reproduce --surrogate``) and the
robot's (:func:`~stewart_drake.station.surrogate.carriage.load_surrogate`, ``robot
--surrogate``): the same displacement from either, against the file's own numbers, and the same
refusals, each naming its command's options."""

import math

import numpy as np
import pytest

from stewart_drake.base.errors import InvalidConfigError, MissingFileError
from stewart_drake.station.surrogate.carriage import load_surrogate
from stewart_drake.station.surrogate.pairs import load_external
from stewart_drake.station.surrogate.trace import load_surrogate_trace

PERIOD_S = 4.0


def _resp(path, offset_mm=12.0, amplitude_mm=8.0, seconds=40.0):
    """An IntERAct-like ``Resp/`` file: 2 columns, time s and displacement mm, 10 Hz, whole
    breaths about ``offset_mm`` (so its mean is the offset)."""
    t = np.arange(0.0, seconds, 0.1)
    mm = offset_mm + amplitude_mm * np.sin(2 * math.pi * t / PERIOD_S)
    path.write_text("\n".join(f"{a:.2f} {b:.5f}" for a, b in zip(t, mm)) + "\n")
    return path


def test_both_commands_read_the_files_own_displacement_about_its_mean(tmp_path):
    path = _resp(tmp_path / "NAME_resp.txt")
    q = np.arange(1.0, 39.0, 0.01)
    # by hand: the sine in m, its 12 mm mean taken off
    expected = 8e-3 * np.sin(2 * math.pi * q / PERIOD_S)
    robot = load_surrogate(path)
    diagram = load_external(path)
    s, v, a = robot.evaluate(q)
    assert s == pytest.approx(expected, abs=2e-5)
    w = 2 * math.pi / PERIOD_S
    assert v == pytest.approx(8e-3 * w * np.cos(w * q), abs=2e-4)
    assert a[200:-200] == pytest.approx(-8e-3 * w * w * np.sin(w * q[200:-200]), abs=2e-3)
    assert diagram(q) == pytest.approx(s, abs=1e-12)  # one reader: the same numbers
    assert robot.axis == 3 and robot.sign == 1.0  # SI is the platform's X
    assert robot.duration_s == pytest.approx(39.9, abs=1e-9)
    # the wrong file is not read as right: a file twice as large reads twice as large
    double = load_surrogate(_resp(tmp_path / "double.txt", amplitude_mm=16.0))
    assert double.evaluate(q)[0] == pytest.approx(2 * expected, abs=4e-5)


def test_a_headed_file_of_one_translation_is_read_and_the_others_skipped(tmp_path):
    t = np.arange(0.0, 20.0, 0.1)
    path = tmp_path / "pair.csv"
    rows = (f"{a:.2f},{5 * math.sin(a):.5f},{3 + 6 * math.cos(a):.5f}" for a in t)
    path.write_text("t [s],SI [mm],chest [mm]\n" + "\n".join(rows) + "\n")
    chest = load_surrogate_trace(path, columns="t [s], -, AP [mm]")
    q = np.arange(2.0, 18.0, 0.5)
    mean = 6 * np.mean(np.cos(t))  # the file's samples' mean, taken off
    assert chest.evaluate(q)[0] == pytest.approx(6e-3 * np.cos(q) - 1e-3 * mean, abs=3e-5)
    assert chest.axis == 5  # AP is the platform's Z


@pytest.mark.parametrize(
    "text, gives",
    [
        ("\n".join(f"{0.2 * i:.1f} 1 2 3 0 0 0" for i in range(40)), "+theta, +phi, +psi"),
        ("t [s],rot_SI [deg]\n" + "\n".join(f"{0.2 * i:.1f},{i % 3}" for i in range(40)), "phi"),
        ("t [s],SI [mm],LR [mm]\n" + "\n".join(f"{0.2 * i:.1f},1,{i}" for i in range(40)), "+Y"),
    ],
    ids=["seven columns", "a rotation", "two translations"],
)
def test_a_file_that_is_not_one_line_is_refused_naming_each_commands_option(tmp_path, text, gives):
    path = tmp_path / "wrong.txt"
    path.write_text(text + "\n")
    with pytest.raises(InvalidConfigError, match="the surrogate moves along one line") as robot:
        load_surrogate(path)
    said = str(robot.value)
    assert said.startswith(f"--surrogate {path}:") and gives in said, said
    assert "--surrogate-columns" not in said  # robot has no such option
    with pytest.raises(InvalidConfigError, match="the surrogate moves along one line") as diagram:
        load_external(path)
    said = str(diagram.value)
    assert said.startswith(f"--surrogate {path}:") and gives in said, said
    assert "name the other columns '-' (--surrogate-columns)" in said


def test_a_missing_file_is_refused_by_either(tmp_path):
    for read in (load_surrogate, load_external):
        with pytest.raises(MissingFileError, match="none.txt"):
            read(tmp_path / "none.txt")
