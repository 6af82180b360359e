"""Run the calibration study (stewart_drake.calibration.rehearsal.study) and write its table
into docs/calibration.md, its rows into docs/calibration.json.

    python tools/calibration_tables.py [--docs docs/calibration.md] [--seeds 10]
    python tools/calibration_tables.py --from-json docs/calibration.json

Rehearsals on the default robot of ``paper_hardware`` (its motors' torque limits bound the
poses): pose counts 20, 40, 60, 80, 120, trackers of 5 um / 20 urad and 20 um / 50 urad, the poses
chosen (greedy D-optimal) and random, each on robots drawn with seeds 0 .. 9 (about five
minutes on one core).
"""

import argparse
import json
import time
from pathlib import Path

from stewart_drake.base.fileio import read_checked
from stewart_drake.calibration.rehearsal import study, write_table
from stewart_drake.run.plan import make_plan
from stewart_drake.run.scenario_io import load_scenario


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--docs", default="docs/calibration.md")
    parser.add_argument("--seeds", type=int, default=10)
    parser.add_argument("--from-json", default=None, help="write the table from a rows file")
    args = parser.parse_args()
    if args.from_json:
        rows = json.loads(read_checked(args.from_json, "study rows", 50e6, "give its .json"))
    else:
        t0 = time.perf_counter()
        plan = make_plan(load_scenario("paper_hardware"), with_reference=False)
        rows = study(
            plan.geometry,
            seeds=tuple(range(args.seeds)),
            motor_limits=plan.motor_limits,
            progress=True,
        )
        print(f"study: {time.perf_counter() - t0:.0f} s wall")
    print(f"wrote {write_table(Path(args.docs), rows)}")


if __name__ == "__main__":
    main()
