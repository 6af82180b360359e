"""Write the error budget of a calibrated robot (stewart_drake.calibration.budget) into
docs/calibration.md, "The error budget": the platform's static error after calibration with each
of a real laboratory's imperfections, beside the ideal calibration's.

    python tools/calibration_budget.py [--docs docs/calibration.md] [--seeds 10]

Robots drawn with the default tolerances about the robot of ``paper_hardware`` (its motors'
torque bounds the poses), seeds 0 .. N-1; the rows are
:data:`~stewart_drake.calibration.budget.BUDGET`. About 12 s on one core for ten robots.
"""

import argparse
import time
from pathlib import Path

from stewart_drake.base.fileio import write_between_markers
from stewart_drake.calibration.budget import BUDGET, BUDGET_MARKERS, budget_rows, budget_table
from stewart_drake.calibration.rehearsal import workspace
from stewart_drake.run.plan import make_plan
from stewart_drake.run.scenario_io import load_scenario


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--docs", default="docs/calibration.md")
    parser.add_argument("--seeds", type=int, default=10)
    args = parser.parse_args()
    t0 = time.perf_counter()
    plan = make_plan(load_scenario("paper_hardware"), with_reference=False)
    space = workspace(plan.geometry, motor_limits=plan.motor_limits)
    total, done = len(BUDGET) * args.seeds, [0]

    def progress():
        done[0] += 1
        print(f"\r{done[0]}/{total} calibrations", end="", flush=True)

    rows = budget_rows(plan.geometry, space, range(args.seeds), progress=progress)
    table = budget_table(rows)
    print(f"\n{table}\n{time.perf_counter() - t0:.0f} s")
    block = f"{BUDGET_MARKERS[0]}\n\n{table}\n{BUDGET_MARKERS[1]}"
    print(f"wrote {write_between_markers(Path(args.docs), BUDGET_MARKERS, block)}")


if __name__ == "__main__":
    main()
