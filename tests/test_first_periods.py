"""A robot's first periods pay for no compilation: every compiled kernel a control period calls is
compiled, or loaded from numba's cache, before the torque goes on, with the argument types the
period passes (a read-only array is another type to numba); what was compiled or loaded while
the torque was on is named in the run's timing (``RobotRun.late_kernels``)."""

import sys
from pathlib import Path

import numpy as np
import pytest
from conftest import HANG_S, needs_extra, robot_bus_yaml, start_as_a_user

from stewart_drake.base.compiled import kernel_versions, versions_added
from stewart_drake.calibration.join import read_encoder_log
from stewart_drake.verification.measured_motion import EMULATED_BUS

LATE = "compiled or loaded with the torque on"


def test_the_versions_of_a_kernel_count_its_argument_types_a_read_only_array_apart():
    """A kernel met with a writable, then a read-only array holds two versions: the second
    reading names it, and only it; a third call of a type met before adds nothing."""
    import numba

    module = type(sys)("stewart_drake._versions_probe")
    sys.modules[module.__name__] = module
    try:

        def total(a):
            s = 0.0
            for v in a:
                s += v
            return s

        total.__module__ = module.__name__
        module.total = numba.njit(total)
        a = np.arange(3.0)
        assert module.total(a) == 3.0
        before = kernel_versions()
        assert before[f"{module.__name__}.total"] == 1
        b = np.arange(4.0)
        b.setflags(write=False)
        assert module.total(b) == 6.0
        assert versions_added(before) == [f"{module.__name__}.total"]
        after = kernel_versions()
        module.total(np.arange(2.0))
        assert versions_added(after) == []
    finally:
        del sys.modules[module.__name__]


def test_a_kernel_new_since_the_first_reading_is_named():
    assert versions_added({"a.f": 1}, {"a.f": 1, "a.g": 1}) == ["a.g"]
    assert versions_added({"a.f": 1, "a.g": 2}, {"a.f": 1, "a.g": 2}) == []
    assert versions_added({"a.f": 2}, {"a.f": 3, "b.h": 1}) == ["a.f", "b.h"]


def _first_run(tmp_path: Path, **env) -> tuple[int, str, str]:
    """``robot breathing --emulate`` as a user runs it, in a process of its own (whose kernels
    are only what its own import and warm-ups met), on a bus that waits out a loaded machine:
    (exit code, stdout, stderr)."""
    argv = [
        sys.executable, "-m", "stewart_drake.cli.main", "robot", "breathing",
        "--scenario", str(robot_bus_yaml(tmp_path)), "--emulate", "--no-realtime",
        "--home-s", "0.5", "--duration", "1.5", "--loop-timeout", "5", "--no-progress",
        "--out", str(tmp_path / "out"),
    ]  # fmt: skip
    process = start_as_a_user(argv, tmp_path, **env)
    out, err = process.communicate(timeout=HANG_S)
    return process.returncode, out, err


@pytest.mark.system
@needs_extra("robot")
def test_a_robot_run_compiles_and_loads_nothing_once_the_torque_is_on(tmp_path):
    """With numba's cache holding every version (the suite's runs wrote it), a new process
    still loads each version its periods need before the torque: the crank servo's step with
    its read-only gains and the inertia's re-schedule (0.1 s in) were once loaded in the loop,
    and the first period stalled past our watchdog's 100 ms."""
    code, out, err = _first_run(tmp_path)
    assert code == 0, (out, err)
    assert "torque on" in err and LATE not in out + err, (out, err)
    assert "the reference ran to its end" in out + err
    # The shipped scenario's crank servo carries no commissioning, and the emulator's servos
    # are drawn: the run says so.
    assert "crank servo believes the catalogue's" in err, err
    # Its encoder log says its servos were the emulator's, as the run printed them.
    bus = read_encoder_log(next((tmp_path / "out").glob("*_encoders.csv")))["bus"]
    assert bus.startswith(EMULATED_BUS) and bus[len(EMULATED_BUS) :] in out, (bus, out)


@pytest.mark.slow
@needs_extra("robot")
def test_a_first_run_with_an_empty_cache_compiles_everything_before_the_torque(tmp_path):
    """The first run on a new machine: numba's cache empty, every kernel compiled (a minute and
    more) before the torque goes on; the run ends as it should, naming none as late."""
    cache = tmp_path / "numba_cache"
    cache.mkdir()
    code, out, err = _first_run(tmp_path, NUMBA_CACHE_DIR=str(cache))
    assert code == 0, (out, err)
    before, after = err.split("torque on", 1)
    assert "compiling" in before and "compiling" not in after, err
    assert LATE not in out + err
    assert any(cache.iterdir())
