"""Tune the stream predictor on the library's motions, measure it on every motion and on
IntERAct's patients' traces at 0.1-0.5 s of latency (stewart_drake.organ_motion.stream_study),
and write the tables into docs/organ_motion.md.

    python tools/stream_prediction_table.py --traces PATH/TO/IntERAct [--docs docs/organ_motion.md]

``--traces`` names a folder holding the 6-D traces of the Image-X Institute's robotic motion
phantom (github.com/Image-X-Institute/IntERAct, "Documentation/Robotic Motion QA traces" and
"Traces/LARK & SABR TRACES"); without it only the library's motions are measured. About 7
minutes of tuning (18 settings) and 2 of measuring on a loaded 2-core machine. The settings it
chooses are the shipped defaults of ``PredictorSettings``: when they differ the tool says so
(change them there and run it again).
"""

import argparse
import time
from pathlib import Path

from tqdm import tqdm

from stewart_drake.organ_motion import stream_study
from stewart_drake.references.prediction import PredictorSettings


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--docs", default="docs/organ_motion.md")
    parser.add_argument("--traces", default=None, help="a folder holding IntERAct's traces")
    args = parser.parse_args()
    cases = stream_study.stream_cases(args.traces)
    tuning = [c for c in cases if c.tuned_on]
    t0 = time.perf_counter()
    grid = 1
    for values in stream_study.TUNING_GRID.values():
        grid *= len(values)
    with tqdm(total=grid, desc="tuning on the library's motions") as bar:
        best, scores = stream_study.tune(tuning, progress=bar.update)
    print(f"tuned in {time.perf_counter() - t0:.0f} s: {best}")
    if best != PredictorSettings():
        print(f"the shipped defaults are {PredictorSettings()}: make them {best}")
    t0 = time.perf_counter()
    with tqdm(total=len(cases), desc="measuring") as bar:
        rows = stream_study.study(cases, best, progress=bar.update)
    print(f"measured in {time.perf_counter() - t0:.0f} s")
    for line in stream_study.verdicts(rows):
        print(line)
    print(f"wrote {stream_study.write_tables(Path(args.docs), rows, best, scores)}")


if __name__ == "__main__":
    main()
