"""Run the fidelity study (stewart_drake.studies.fidelity_study) and the trace study
(stewart_drake.studies.trace_study) and write their tables into docs/organ_motion.md; the raw
figures go to results/fidelity_study/results.json and results/trace_study/results.json.

    python tools/organ_motion_tables.py [--docs docs/organ_motion.md] [--jobs 2]
    python tools/organ_motion_tables.py --only traces --traces PATH/TO/IntERAct
    python tools/organ_motion_tables.py --from-json results/fidelity_study/results.json
    python tools/organ_motion_tables.py --only traces --from-json results/trace_study/results.json

The fidelity study takes about 25 minutes on two cores (the 20 s pattern of breathing plus
heartbeat, learned over 11 cycles, is the longest run); the trace study about 3 minutes per
motion (four runs of 120 s: twice without learning, learning from zero and from the library's
model, or the transfer's). ``--traces`` names a folder holding the 6-D traces of the
Image-X Institute's robotic motion phantom (github.com/Image-X-Institute/IntERAct,
"Documentation/Robotic Motion QA traces"); without it the trace study runs the library's
motions only.
"""

import argparse
import json
import time
from pathlib import Path

from stewart_drake.base.fileio import atomic_write, read_checked
from stewart_drake.execution.runners import ProcessRunner
from stewart_drake.studies import trace_study
from stewart_drake.studies.fidelity_study import run_study, write_tables


def _read_results(path) -> dict:
    """A study's results.json, read through the package's checked reader."""
    return json.loads(read_checked(path, "study results", 200e6, "give a results.json"))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--docs", default="docs/organ_motion.md")
    parser.add_argument("--out", default="results/fidelity_study/results.json")
    parser.add_argument("--jobs", type=int, default=2)
    parser.add_argument(
        "--from-json", default=None, help="write the tables from a results file instead of running"
    )
    parser.add_argument(
        "--only", choices=["cycles", "traces"], default=None, help="run one study (default: both)"
    )
    parser.add_argument("--traces", default=None, help="a folder holding IntERAct's traces")
    parser.add_argument(
        "--as-built-only",
        action="store_true",
        help="the trace study on the robot as built only (not on every robot of ROBOTS)",
    )
    args = parser.parse_args()
    if args.only == "traces" and args.from_json:
        traces = _read_results(args.from_json)
        print(f"wrote {trace_study.write_tables(Path(args.docs), traces)}")
        return
    if args.only != "cycles" and not args.from_json:
        t0 = time.perf_counter()
        robots = trace_study.ROBOTS[:1] if args.as_built_only else trace_study.ROBOTS
        cases = trace_study.trace_cases(args.traces, robots=robots)
        traces = trace_study.run_study(cases, ProcessRunner(n_workers=args.jobs, recycle=1))
        print(f"trace study: {time.perf_counter() - t0:.0f} s wall")
        out = Path("results/trace_study/results.json")
        out.parent.mkdir(parents=True, exist_ok=True)
        atomic_write(out, lambda f: f.write(json.dumps(traces, default=float).encode()))
        print(f"wrote {trace_study.write_tables(Path(args.docs), traces)}")
    if args.only == "traces":
        return
    if args.from_json:
        results = _read_results(args.from_json)
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
