"""The robot's control loop on the bus emulator as ``stewart-drake robot paper --emulate`` runs it:
its CPU time a period, its deadlines, and the true pose's tracking, idle and under load.

Each run is the command's own session (:func:`~stewart_drake.live.session.run_on_robot` against
the bus emulator in its own process,
:func:`~stewart_drake.live.emulator_process.start_emulator`, the robot's Drake plant behind
it): the shipped ``paper_bus`` scenario (XM430-W350-T, omega_Q
0.01), homed from the emulator's rest pose, then the paper manoeuvre for ``--duration`` s, at
each ``--period``, with ``--load`` other processes (``python -c "while True: pass"``) keeping
cores busy for the length of the run.

Printed per run, one line per figure:

* ``cpu_per_period``: the loop thread's CPU time (``time.thread_time``) from one period of the
  driver to the next, median / p99 / worst, ms: everything the Diagram does in a period (the
  bus, the pose, the controller, the guard, the logs). Measured here by timing the driver's
  update from outside, so that the same figure can be taken of any version of the code;
* ``misses``: deadline misses (periods that started over a period late) over periods, and how
  the run ended;
* ``true_pose`` and ``measured_pose``: RMS tracking error over the second half of the run
  (rotation mrad, translation mm), of the emulator's plant (its true pose at every step, against
  the reference at the Diagram time of its wall-clock time) and of the pose the driver measured;
* the driver's own timing lines (the realtime grant, the period, jitter, cpu, late causes);
* with ``--breakdown``, the loop thread's CPU time a period inside each Python callback of the
  Diagram and in the parts they call (the bus's read and write, the guard's SceneGraph query,
  the LQI's gain re-schedule and Newton solve), ms a period (averaged over the periods) and us
  a call.

Usage: python benchmarks/robot_loop.py [--duration 20] [--period 0.01 0.005] [--load 0 2]
    [--no-realtime] [--breakdown] [--servos realistic|ideal]
"""

import argparse
import collections
import subprocess
import sys
import tempfile
import time

import numpy as np

from stewart_drake.live.emulator_process import start_emulator
from stewart_drake.live.session import run_on_robot
from stewart_drake.references.trajectories import NamedReference
from stewart_drake.run.result import load_result
from stewart_drake.run.scenario_io import ROBOT_SCENARIO, load_scenario
from stewart_drake.station.bus.station import DynamixelDriver

#: Where the emulated robot rests (``robot --emulate``'s default).
REST = [0.0, 0.0, 0.0, 0.0, 0.0, 0.28]


class UpdateClock:
    """The thread CPU time at every call of the driver's update (its class patched, so it works
    on any version of the driver)."""

    def __init__(self):
        self.cpu: list[float] = []
        self._update = DynamixelDriver._Update
        clock = self

        def update(driver, context, state):
            clock.cpu.append(time.thread_time())
            return clock._update(driver, context, state)

        DynamixelDriver._Update = update

    def per_period_ms(self) -> np.ndarray:
        return 1e3 * np.diff(np.array(self.cpu))


#: What ``--breakdown`` times: (module, class, method) of the Diagram's Python callbacks and of
#: the parts they call.
TIMED = (
    ("stewart_drake.station.bus.station", "DynamixelDriver", "_Update"),
    ("stewart_drake.station.bus.driver", "DynamixelBus", "read_state"),
    ("stewart_drake.station.bus.driver", "DynamixelBus", "write_torques"),
    ("stewart_drake.station.bus.station", "MeasuredPlantState", "_Calc"),
    ("stewart_drake.station.guard", "DivergenceGuard", "_Check"),
    ("stewart_drake.plant.clearance", "ClearanceModel", "overlaps"),
    ("stewart_drake.control.lqi.controller", "LqiController", "_Update"),
    ("stewart_drake.control.lqi.controller", "LqiController", "_reschedule"),
    ("stewart_drake.control.lqi.controller", "LqiController", "_estimate_by_newton"),
    ("stewart_drake.control.servo.controller", "CrankServoController", "_Update"),
    ("stewart_drake.control.servo.controller", "CrankServoController", "_inertia"),
)


class Breakdown:
    """Thread CPU time inside each method of :data:`TIMED` (their classes patched)."""

    def __init__(self):
        import importlib

        self.cpu: collections.Counter = collections.Counter()
        self.calls: collections.Counter = collections.Counter()
        self._saved = []
        for module, cls, name in TIMED:
            owner = getattr(importlib.import_module(module), cls)
            self._saved.append((owner, name, getattr(owner, name)))
            setattr(owner, name, self._timed(f"{cls}.{name}", getattr(owner, name)))

    def _timed(self, label, method):
        def timed(*args, **kwargs):
            t0 = time.thread_time()
            try:
                return method(*args, **kwargs)
            finally:
                self.cpu[label] += time.thread_time() - t0
                self.calls[label] += 1

        return timed

    def restore(self) -> None:
        for owner, name, method in self._saved:
            setattr(owner, name, method)

    def lines(self, periods: int) -> list[str]:
        return [
            f"{label:40s} {1e3 * cpu / periods:6.3f} ms a period, "
            f"{1e6 * cpu / self.calls[label]:6.0f} us a call ({self.calls[label]} calls)"
            for label, cpu in self.cpu.most_common()
        ]


def busy(n: int) -> list:
    """``n`` processes that keep a core busy each."""
    return [subprocess.Popen([sys.executable, "-c", "while True: pass"]) for _ in range(n)]


def session_on_emulator(scenario, emulator, load: int, breakdown: bool, out: str, say, **kwargs):
    """``run_on_robot(scenario)`` on ``emulator`` (closed after) beside ``load`` busy processes,
    the driver's update timed: (what ``run_on_robot`` returned, the run's station Diagram, its
    :class:`UpdateClock`, its :class:`Breakdown` or None); every patch undone and every
    process ended, however the run ends."""
    held = {}
    clock = UpdateClock()
    timed = Breakdown() if breakdown else None
    loads = busy(load)
    try:
        time.sleep(1.0 if load else 0.0)  # the load settles on the cores
        run = run_on_robot(
            scenario,
            out=out,
            progress=False,
            say=say,
            before_torque=lambda sd, simulator: held.update(sd=sd),
            **kwargs,
        )
    finally:
        for p in loads:
            p.kill()
            p.wait()
        emulator.close()
        DynamixelDriver._Update = clock._update
        if timed is not None:
            timed.restore()
    return run, held["sd"], clock, timed


def rms(e) -> str:
    rot, pos = e[:, :3], e[:, 3:6]
    return f"{1e3 * np.sqrt((rot**2).mean()):.2f} mrad {1e3 * np.sqrt((pos**2).mean()):.3f} mm RMS"


def one_run(
    period: float,
    duration: float,
    load: int,
    realtime: bool,
    out: str,
    breakdown: bool,
    servos: str = "realistic",
) -> None:
    scenario = load_scenario(ROBOT_SCENARIO, (f"emulator.servos={servos}",))
    scenario.reference = NamedReference("paper")
    scenario.duration_s = duration
    scenario.control_period_s = scenario.log_period_s = period
    scenario.guard.divergence_dir = f"{out}/diverged"
    lines: list[str] = []
    kwargs = {"realtime": True} if realtime else {}
    emulator = start_emulator(scenario, REST, **kwargs)
    run, sd, clock, timed = session_on_emulator(
        scenario, emulator, load, breakdown, out, lines.append, **kwargs
    )
    driver = sd.station.driver
    cpu = clock.per_period_ms()
    label = f"period {1e3 * period:g} ms, load {load}, {'realtime' if realtime else 'normal'}"
    print(f"{label}:")
    for line in lines:
        if line.startswith("realtime"):
            print(f"  {line}")
    print(
        f"  cpu_per_period median {np.median(cpu):.3f} p99 {np.percentile(cpu, 99):.3f} "
        f"worst {cpu.max():.3f} ms (n = {cpu.size})"
    )
    periods = len(driver.readings()[0])
    print(
        f"  misses {driver.misses} of {periods} periods ({100 * driver.misses / periods:.2f} %); "
        f"{run.reason}"
    )
    if run.logs is not None:
        result = load_result(run.logs)
        half = result.t >= result.t[-1] / 2
        print(f"  measured_pose {rms(result.x[half, :6] - result.x_d[half, :6])}")
    t_periods, _, _ = driver.readings()
    walls = _period_starts(driver)
    t_true, x_true = emulator.truth()
    inside = (t_true >= walls[0]) & (t_true <= walls[-1])
    t_run = np.interp(t_true[inside], walls, t_periods[: len(walls)])
    x_d = sd.trajectory.evaluate(t_run)[0]
    e = x_true[inside, :6] - x_d
    half = t_run >= t_run[-1] / 2
    print(f"  true_pose {rms(e[half])}")
    for line in run.timing_lines:
        print(f"    {line}")
    if timed is not None:
        for line in timed.lines(cpu.size):
            print(f"    {line}")


def _period_starts(driver) -> np.ndarray:
    """The wall-clock start of every period (perf_counter s)."""
    timing = getattr(driver, "timing", None)
    if timing is not None:
        return timing.rows()[:, 0]
    return np.array(driver._records)[:, 0]  # the driver before LoopTiming


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--duration", type=float, default=20.0, help="s of the manoeuvre")
    parser.add_argument("--period", type=float, nargs="+", default=[0.01, 0.005])
    parser.add_argument("--load", type=int, nargs="+", default=[0, 2], help="busy processes")
    parser.add_argument("--no-realtime", action="store_true", help="the loop as before")
    parser.add_argument("--breakdown", action="store_true", help="CPU time a callback")
    parser.add_argument(
        "--servos", choices=("realistic", "ideal"), default="realistic", help="the emulator's"
    )
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as out:
        for period in args.period:
            for load in args.load:
                one_run(
                    period,
                    args.duration,
                    load,
                    not args.no_realtime,
                    out,
                    args.breakdown,
                    args.servos,
                )


if __name__ == "__main__":
    main()
