"""Each compiled module's ``reference`` (its kernels as the Python they are compiled from) holds
the same functions with the JIT off (``NUMBA_DISABLE_JIT=1``, as the mutation tool runs the unit
tests) as with it on: a test comparing the two forms then runs, where an empty namespace made
it fail before its first number."""

import importlib
import json
import os
import subprocess
import sys

import pytest
from conftest import HANG_S

MODULES = (
    "stewart_drake.robot.path_kernels",
    "stewart_drake.station.bus.servo_physics",
    "stewart_drake.station.bus.kernels",
    "stewart_drake.control.servo.kernels",
    "stewart_drake.control.lqi.step",
)


@pytest.mark.system
def test_the_interpreted_kernels_are_the_same_functions_with_the_jit_off():
    """Every kernel the JIT on compiles is there with it off; the only others are its aliases
    (``ik_compiled = _njit(ik_scalar)`` leaves ``ik_scalar`` the same function then)."""
    script = (
        "import importlib, json, sys\n"
        "out = {}\n"
        "for m in sys.argv[1:]:\n"
        "    mod = importlib.import_module(m)\n"
        "    names = sorted(vars(mod.reference))\n"
        "    g = vars(mod)\n"
        "    out[m] = {n: [k for k in names if k != n and g[k] is g[n]] for n in names}\n"
        "print(json.dumps(out))\n"
    )
    done = subprocess.run(
        [sys.executable, "-c", script, *MODULES],
        env=dict(os.environ, NUMBA_DISABLE_JIT="1"),
        capture_output=True,
        text=True,
        timeout=HANG_S,
    )
    assert done.returncode == 0, done.stderr[-2000:]
    off = json.loads(done.stdout.strip().splitlines()[-1])
    for name in MODULES:
        on = set(vars(importlib.import_module(name).reference))
        assert on, name  # the JIT on finds the compiled functions
        assert on <= set(off[name]), (name, on - set(off[name]))
        for extra in set(off[name]) - on:
            assert set(off[name][extra]) & on, (name, extra)  # an alias of a kernel
