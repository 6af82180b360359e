"""Run the fidelity study (stewart_drake.studies.fidelity_study) and write its tables into
docs/organ_motion.md; the raw figures go to results/fidelity_study/results.json.

    python tools/organ_motion_tables.py [--docs docs/organ_motion.md] [--jobs 2]
    python tools/organ_motion_tables.py --from-json results/fidelity_study/results.json

About 25 minutes on two cores (the 20 s pattern of breathing plus heartbeat, learned over 11
cycles, is the longest run).
"""

import argparse
import json
import time
from pathlib import Path

from stewart_drake.execution.runners import ProcessRunner
from stewart_drake.fileio import atomic_write
from stewart_drake.studies.fidelity_study import run_study, write_tables


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--docs", default="docs/organ_motion.md")
    parser.add_argument("--out", default="results/fidelity_study/results.json")
    parser.add_argument("--jobs", type=int, default=2)
    parser.add_argument(
        "--from-json", default=None, help="write the tables from a results file instead of running"
    )
    args = parser.parse_args()
    if args.from_json:
        results = json.loads(Path(args.from_json).read_text())
    else:
        t0 = time.perf_counter()
        results = run_study(runner=ProcessRunner(n_workers=args.jobs, recycle=1))
        print(f"study: {time.perf_counter() - t0:.0f} s wall")
        out = Path(args.out)
        out.parent.mkdir(parents=True, exist_ok=True)
        atomic_write(out, lambda f: f.write(json.dumps(results, default=float).encode()))
    print(f"wrote {write_tables(Path(args.docs), results)}")


if __name__ == "__main__":
    main()
