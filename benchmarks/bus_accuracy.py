"""How accurately the robot on its servo bus makes a motion: ``stewart-drake robot MOTION
--emulate``'s own session against the bus emulator (the robot's Drake plant in a process of its
own, at wall-clock time), the true pose (the emulator's plant) and the pose the encoders read,
each against the reference, beside the same motion simulated at the bus's period and the
encoders' floor.

Per run, one line per figure, per axis (phi, theta, psi mrad; X, Y, Z mm), RMS and peak over
the measured window (after the first ``--skip`` s of the motion, past the homing lead-in):

* ``true``: the emulator's plant, at every one of its steps, against the reference at the
  Diagram time of its wall-clock time (what the phantom really does);
* ``encoders``: the pose the driver measured each period (forward kinematics of the encoders'
  counts) against the reference at that period: what the robot and its own ``verify`` see;
* ``simulated``: ``reproduce``'s true pose of the same scenario and motion, simulated at the
  scenario's control period (no bus): the prediction;
* ``floor``: the encoders' quantization at the motion's centre pose (one count uniform on every
  crank, through J^-1: :func:`~stewart_drake.analysis.error_budget.quantization_floor`);
* the loop's CPU time a period (median, p99), its deadline misses, with ``--breakdown`` where it
  goes.

The emulated servos are the scenario's ``emulator`` section's (``robot --emulate``'s: realistic,
drawn from its seed, by default): ``--set emulator.servos=ideal`` the controller's own model,
``--set emulator.friction_scale=K`` (or any of its departures) one of them;
``--set payload_scale=K`` a payload the controller does not know.

Usage: python benchmarks/bus_accuracy.py [--scenario paper_bus] [--motion breathing]
    [--param KEY=VALUE ...] [--duration 30] [--period 0.01 ...] [--load 0 ...] [--skip 8]
    [--no-sim] [--breakdown] [--set KEY=VALUE ...]
"""

import argparse
import sys
import tempfile
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from robot_loop import REST, _period_starts, session_on_emulator  # noqa: E402

from stewart_drake.analysis.error_budget import quantization_floor  # noqa: E402
from stewart_drake.live.emulator_process import start_emulator  # noqa: E402
from stewart_drake.run.scenario_io import load_scenario  # noqa: E402

AXES = ("phi", "theta", "psi", "X", "Y", "Z")


def reference_of(motion: str, params: list[str]):
    """The scenario reference a motion names (a library motion and its parameters, or a trace
    file), as ``robot`` makes it."""
    from stewart_drake.execution.options import add_motion_arguments
    from stewart_drake.execution.trace_options import add_trace_arguments
    from stewart_drake.organ_motion.command import motion_reference

    parser = argparse.ArgumentParser()
    add_motion_arguments(parser)
    add_trace_arguments(parser)
    argv = [motion] + [f"--param={p}" for p in params]
    return motion_reference(parser.parse_args(argv))


def figures(e: np.ndarray) -> str:
    """Per axis RMS / peak, mrad and mm."""
    rms, peak = np.sqrt(np.mean(e**2, axis=0)) * 1e3, np.max(np.abs(e), axis=0) * 1e3
    return "  ".join(f"{a} {r:.3f}/{p:.2f}" for a, r, p in zip(AXES, rms, peak))


def emulated(scenario, args, period: float, load: int, out: str):
    """One session on the emulator: (true errors (n, 6), encoder errors (m, 6), cpu ms (k,),
    misses, periods, breakdown lines); ``args.end_reason`` set to why a run that did not reach
    its end ended (None: it did), ``args.slipped_s`` to the model time its plant
    slipped behind the wall clock (NaN on the loop's clock)."""
    scenario.control_period_s = scenario.log_period_s = period
    emulator = start_emulator(scenario, REST, realtime=True)
    loop_clock = {} if emulator.period_s is None else {"loop_timeout_s": 2.0}  # as robot's
    run, sd, clock, timed = session_on_emulator(
        scenario, emulator, load, args.breakdown, out, lambda line: None, realtime=True,
        **loop_clock,
    )  # fmt: skip
    args.end_reason = None if run.ok else run.reason
    driver = sd.station.driver
    t_periods, _, _ = driver.readings()
    walls = _period_starts(driver)
    t_true, x_true = emulator.truth()
    args.slipped_s = emulator.slipped_s if emulator.period_s is None else float("nan")
    if emulator.period_s is not None:  # the loop's clock: its times are the run's
        inside = np.ones(len(t_true), dtype=bool)
        t_run = t_true + t_periods[0]
    else:
        inside = (t_true >= walls[0]) & (t_true <= walls[-1])
        t_run = np.interp(t_true[inside], walls, t_periods[: len(walls)])
    start = t_run[-1] - scenario.duration_s + args.skip  # the motion's start, after the lead-in
    e_true = x_true[inside, :6] - sd.trajectory.evaluate(t_run)[0]
    x_enc = driver.pose_readings()
    e_enc = x_enc - sd.trajectory.evaluate(t_periods)[0]
    cpu = clock.per_period_ms()
    lines = timed.lines(cpu.size) if timed is not None else []
    return (
        e_true[t_run >= start],
        e_enc[t_periods >= start],
        cpu,
        driver.misses,
        len(t_periods),
        lines,
    )


def simulated(scenario, args) -> np.ndarray:
    """The same motion simulated at the scenario's period (no bus): true-pose errors over the
    same window."""
    import dataclasses

    from stewart_drake.run.simulate import run_experiment

    sim = dataclasses.replace(
        scenario, bus=None, hardware=scenario.bus.hardware(scenario.control_period_s)
    )
    result = run_experiment(sim)
    keep = result.t >= args.skip
    return result.x[keep, :6] - result.x_d[keep, :6]


def scenario_of(args, period: float):
    """The run's scenario: ``--scenario`` with ``--set``, the period, the motion, its length."""
    scenario = load_scenario(args.scenario, [*args.set, f"control_period_s={period}"])
    scenario.reference = reference_of(args.motion, args.param)
    scenario.duration_s = args.duration
    return scenario


def main() -> None:
    parser = argparse.ArgumentParser(
        description="How accurately the robot on its servo bus makes a motion, against the bus "
        "emulator at wall-clock time: the true pose and the encoders' against the reference, "
        "the same simulated, the encoders' floor, the loop's CPU (see the module's docstring)."
    )
    parser.add_argument("--scenario", default="paper_bus", help="a bus scenario (its name or file)")
    parser.add_argument(
        "--motion", default="breathing", help="a library motion or a trace file (as robot's)"
    )
    parser.add_argument(
        "--param", action="append", default=[], help="KEY=VALUE: a parameter of the motion"
    )
    parser.add_argument(
        "--set", action="append", default=[], help="KEY=VALUE: a scenario field (as run's --set)"
    )
    parser.add_argument("--duration", type=float, default=30.0, help="s of the motion")
    parser.add_argument("--skip", type=float, default=8.0, help="s of the motion not measured")
    parser.add_argument(
        "--period", type=float, nargs="+", default=[0.01], help="control periods, s (one run each)"
    )
    parser.add_argument(
        "--load", type=int, nargs="+", default=[0], help="busy processes beside each run"
    )
    parser.add_argument("--no-sim", action="store_true", help="no simulated prediction")
    parser.add_argument("--breakdown", action="store_true", help="where the loop's CPU goes")
    args = parser.parse_args()
    for period in args.period:
        scenario = scenario_of(args, period)
        floor = quantization_floor(scenario)
        print(f"{args.scenario} {args.motion} {' '.join(args.param)}, period {period * 1e3:g} ms")
        print(f"  floor      {'  '.join(f'{a} {1e3 * f:.3f}' for a, f in zip(AXES, floor))}")
        if not args.no_sim:
            print(f"  simulated  {figures(simulated(scenario, args))}")
        for load in args.load:
            with tempfile.TemporaryDirectory() as out:
                scenario = scenario_of(args, period)
                scenario.guard.divergence_dir = f"{out}/diverged"
                e_true, e_enc, cpu, misses, n, lines = emulated(scenario, args, period, load, out)
            print(f"  load {load}:")
            print(f"    true       {figures(e_true)}")
            print(f"    encoders   {figures(e_enc)}")
            print(
                f"    cpu median {np.median(cpu):.3f} p99 {np.percentile(cpu, 99):.3f} ms, "
                f"misses {misses} of {n}"
            )
            for line in lines:
                print(f"      {line}")


if __name__ == "__main__":
    main()
