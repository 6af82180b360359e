"""Measure the shipped stream predictor on every motion of the library and on IntERAct's
patients' traces at 0.1-0.5 s of latency (stewart_drake.studies.stream_study), and write
the tables into docs/organ_motion.md.

    python tools/stream_prediction_table.py --traces PATH/TO/IntERAct [--docs docs/organ_motion.md]

``--traces`` names a folder holding the 6-D traces of the Image-X Institute's robotic motion
phantom (github.com/Image-X-Institute/IntERAct, "Documentation/Robotic Motion QA traces" and
"Traces/LARK & SABR TRACES"); without it only the library's motions are measured. About 3
minutes on a 2-core machine. The predictor and its settings are the shipped ones
(``PredictorSettings``), chosen across sources by tools/stream_selection_table.py.
"""

import argparse
import time
from pathlib import Path

from tqdm import tqdm

from stewart_drake.references.prediction import PredictorSettings
from stewart_drake.studies import stream_study


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--docs", default="docs/organ_motion.md")
    parser.add_argument("--traces", default=None, help="a folder holding IntERAct's traces")
    args = parser.parse_args()
    cases = stream_study.stream_cases(args.traces)
    settings = PredictorSettings()
    t0 = time.perf_counter()
    with tqdm(total=len(cases), desc="measuring") as bar:
        rows = stream_study.study(cases, settings, progress=bar.update)
    print(f"measured in {time.perf_counter() - t0:.0f} s")
    for line in stream_study.verdicts(rows):
        print(line)
    print(f"wrote {stream_study.write_tables(Path(args.docs), rows, settings)}")


if __name__ == "__main__":
    main()
