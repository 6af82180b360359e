"""Files within their byte bound that cost more memory to parse than the process has: the
command, run as a user runs it in a child whose address space is capped (``ulimit -v``) a little
above what it maps once its modules are loaded, refuses them in one line naming the size that
fits, before parsing; the calibration's CSVs are parsed row by row into arrays, so a file that
took ten times its size as lists of strings now fits where it did not."""

import os
import subprocess
import sys

import numpy as np
import pytest
from conftest import HANG_S

from stewart_drake.calibration.files import POSE_COLUMNS, READING_COLUMNS
from stewart_drake.calibration.join import ENCODER_LOG_COLUMNS

pytestmark = [
    pytest.mark.system,
    pytest.mark.skipif(not os.path.exists("/proc/self/statm"), reason="needs Linux's /proc"),
]

#: The child: the command's modules loaded, then its address space capped at what it maps plus
#: ``margin`` bytes, then the command's main with the arguments given.
_CHILD = """
import os, resource, sys
from stewart_drake.cli.registry import build_parser
import stewart_drake.live.calibrate_command, stewart_drake.calibration.identify  # noqa: F401
import stewart_drake.references.traces, stewart_drake.run.plan  # noqa: F401
import scipy.optimize, scipy.linalg  # noqa: F401
from stewart_drake.cli.main import main
build_parser()
with open("/proc/self/statm") as f:
    mapped = int(f.read().split()[0]) * os.sysconf("SC_PAGE_SIZE")
cap = int(mapped + float(sys.argv[1]))
resource.setrlimit(resource.RLIMIT_AS, (cap, resource.RLIM_INFINITY))
sys.exit(main(sys.argv[2:]))
"""


def _capped(margin_bytes: float, argv: list, cwd) -> tuple[int, list]:
    """(exit code, stderr's lines) of ``stewart-drake ARGV`` under the cap; a hang fails."""
    done = subprocess.run(
        [sys.executable, "-c", _CHILD, str(margin_bytes), *argv],
        cwd=cwd,
        capture_output=True,
        text=True,
        timeout=HANG_S,
    )
    return done.returncode, done.stderr.strip().splitlines()


def _table(path, header: list, values: np.ndarray) -> None:
    with open(path, "w") as f:
        f.write(",".join(header) + "\n")
        np.savetxt(f, values, delimiter=",", fmt="%.17g")


@pytest.fixture(scope="module")
def measurements(tmp_path_factory):
    """27 MB of measurements (1e5 poses) whose poses the robot cannot reach: a read that fits
    ends at the first pose, one line naming it."""
    path = tmp_path_factory.mktemp("m") / "measurements.csv"
    header = [f"{n} [rad]" for n in READING_COLUMNS]
    header += [f"{n} [{'rad' if k < 3 else 'm'}]" for k, n in enumerate(POSE_COLUMNS)]
    values = np.random.default_rng(0).normal(size=(100_000, 12)) * 0.01
    _table(path, header, values)
    return path


def test_a_measurements_file_too_long_for_the_memory_is_refused_before_it_is_parsed(
    measurements, tmp_path
):
    code, err = _capped(30e6, ["calibrate", str(measurements), "--out", "o"], tmp_path)
    assert code == 2 and len(err) == 1, err
    assert err[0].startswith(
        f"stewart-drake calibrate: {measurements}: reading this measurements file of 26.6 MB"
    ), err[0]
    assert "(100,001 lines) needs about" in err[0] and "one of up to about" in err[0], err[0]
    assert "lines) fits here: split it into shorter files, or free some memory" in err[0]


def test_a_measurements_file_parsed_row_by_row_fits_where_lists_of_strings_did_not(
    measurements, tmp_path
):
    """150 MB above the loaded command: the whole file parsed (its first pose named by its
    line), where the parse as lists of strings took about 280 MB and ended in a MemoryError."""
    code, err = _capped(150e6, ["calibrate", str(measurements), "--out", "o"], tmp_path)
    assert code == 2 and len(err) == 1, err
    assert "line 2: the nominal robot cannot reach the pose" in err[0], err[0]


def test_an_encoder_log_too_long_for_the_memory_is_refused_in_one_line(tmp_path):
    header = [
        f"{n} [{'s' if kind == 'time' else 'rad'}]" for n, kind in ENCODER_LOG_COLUMNS.items()
    ]
    t = np.arange(600_000) * 0.01  # 100 minutes at 100 Hz, 36 MB
    log = np.column_stack([t + 1.7e9, t, t, *np.zeros((6, t.size))])
    _table(tmp_path / "log_encoders.csv", header, log)
    (tmp_path / "tracker.csv").write_text(
        "time [s],phi [rad],theta [rad],psi [rad],X [m],Y [m],Z [m]\n0,0,0,0,0,0,0.3\n"
    )
    (tmp_path / "poses.csv").write_text(
        "t [s],phi [rad],theta [rad],psi [rad],X [m],Y [m],Z [m]\n0,0,0,0,0,0,0.3\n"
    )
    argv = ["calibrate", "--join", "log_encoders.csv", "tracker.csv", "--plan-file", "poses.csv"]
    code, err = _capped(100e6, [*argv, "--out", "m.csv"], tmp_path)
    assert code == 2 and len(err) == 1, err
    assert "log_encoders.csv: reading this encoder log of" in err[0], err[0]
    assert "(600,001 lines) needs about" in err[0], err[0]


def test_a_trace_too_long_for_the_memory_is_refused_in_one_line_by_check(tmp_path):
    t = np.arange(100_000) * 0.04
    _table(tmp_path / "trace.csv", ["t [s]", "SI [mm]"], np.column_stack([t, np.sin(t)]))
    code, err = _capped(100e6, ["check", "trace.csv", "--out", "o"], tmp_path)
    assert code == 2 and len(err) == 1, err
    assert "trace.csv: reading this trace file of" in err[0], err[0]
    assert "(100,001 lines) needs about 280 MB of memory" in err[0], err[0]
