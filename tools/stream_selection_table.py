"""Choose the stream predictor across sources, leaving each out in turn, show its fallback on
motions where prediction cannot pay, and write the tables into docs/organ_motion.md
(stewart_drake.studies.stream_selection).

    python tools/stream_selection_table.py [--traces PATH/TO/IntERAct] [--docs docs/organ_motion.md]

``--traces`` names a folder holding IntERAct's traces (github.com/Image-X-Institute/IntERAct:
"Documentation/Robotic Motion QA traces" and "Traces/LARK & SABR TRACES"); without it that
source is left out. About 20 minutes on a 2-core machine (every candidate on about 60 motions at
two latencies). The candidate it chooses on every source should be the shipped default
(``PredictorSettings`` and ``DEFAULT_PREDICTOR``): when it is not, the tool says so.
"""

import argparse
import time
from dataclasses import asdict
from pathlib import Path

from tqdm import tqdm

from stewart_drake.references.prediction import DEFAULT_PREDICTOR, PredictorSettings
from stewart_drake.studies import stream_selection, stream_sources


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--docs", default="docs/organ_motion.md")
    parser.add_argument("--traces", default=None, help="a folder holding IntERAct's traces")
    args = parser.parse_args()
    sources = stream_sources.sources(args.traces)
    hurting = stream_sources.hurting()
    latencies = len(stream_selection.LATENCIES)
    t0 = time.perf_counter()
    with tqdm(total=sum(len(s.cases) for s in sources) * latencies, desc="measuring") as bar:
        rows = stream_selection.measure(sources, progress=bar.update)
    chosen = stream_selection.choose(rows)
    candidate = next(c for c in stream_selection.CANDIDATES if c.label == chosen)
    with tqdm(total=sum(len(s.cases) for s in hurting) * latencies, desc="fallback") as bar:
        fallback = stream_selection.measure(hurting, (candidate,), progress=bar.update)
    print(f"measured in {time.perf_counter() - t0:.0f} s; chosen on every source: {chosen}")
    for line in stream_selection.verdicts(rows, fallback):
        print(line)
    shipped = (DEFAULT_PREDICTOR, PredictorSettings())
    if (candidate.predictor, candidate.settings) != shipped:
        changed = {
            k: v for k, v in asdict(candidate.settings).items() if getattr(shipped[1], k) != v
        }
        print(
            f"the shipped default is {DEFAULT_PREDICTOR} with other settings: make it "
            f"{candidate.predictor} with {changed} (references/prediction.py)"
        )
    path = stream_selection.write_tables(Path(args.docs), rows, sources, fallback)
    print(f"wrote {path}")


if __name__ == "__main__":
    main()
