"""What learning from every cycle costs per control period, measured in one process.

The same breathing-plus-heartbeat motion on the robot as built (paper_hardware), run with and
without the learner (stewart_drake.control.ilc), for a 5 s cycle and for the 20 s pattern of a
4 s breath and a 72 bpm heartbeat; prints one line per figure:

    learner_overhead_5s 1.05 (12.3 s wall with / 11.7 s without, 10 s simulated)

Usage: python benchmarks/learning.py [--duration 10] [--repeat 2] (runs at least one cycle)
"""

import argparse
import time

from stewart_drake.control.ilc import IlcDriver
from stewart_drake.organ_motion.reproduction import run
from stewart_drake.run.plan import make_plan
from stewart_drake.run.scenario import OrganMotionReference
from stewart_drake.run.scenario_io import load_scenario


def wall(parameters: dict, learning: bool, duration: float) -> float:
    scenario = load_scenario("paper_hardware")
    scenario.reference = OrganMotionReference("breathing_heartbeat", parameters)
    scenario.duration_s = duration
    scenario.learning = IlcDriver() if learning else None
    return run(scenario.validate(), make_plan(scenario).reference)[2]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--duration", type=float, default=10.0)
    parser.add_argument("--repeat", type=int, default=2)
    args = parser.parse_args()
    for name, parameters, cycle in (("5s", {"period": "5s"}, 5.0), ("20s", {}, 20.0)):
        t0 = time.perf_counter()
        duration = max(args.duration, cycle)  # at least one cycle of the learner
        with_, without = (
            min(wall(parameters, learn, duration) for _ in range(args.repeat))
            for learn in (True, False)
        )
        per_period_us = 1e6 * (with_ - without) / (duration / 1e-3)
        print(
            f"learner_overhead_{name} {with_ / without:.3f} ({with_:.2f} s wall with / "
            f"{without:.2f} s without, {duration:g} s simulated; "
            f"{per_period_us:.0f} us per control period; {time.perf_counter() - t0:.0f} s)"
        )


if __name__ == "__main__":
    main()
