"""Memory per closed-loop run in one long-lived process, and whether each run's Diagram is freed.

    python benchmarks/memory_per_run.py                        # 20 runs of 0.5 s, paper_hardware
    python benchmarks/memory_per_run.py --runs 30 --duration 1 --scenario paper_ideal
    python benchmarks/memory_per_run.py --runs 0 --study 80     # a study's wall time only

Each run takes the path a study worker takes (``build_simulator``, ``simulate``,
``release_reference``, ``finish_result``); then every reference to the run is dropped, the
garbage collector runs, and the process's RSS is read (``/proc/self/statm``). Weak references
to the run's Diagram and to its station (a Python ``Diagram`` of ours) say whether they were
freed. Printed: a row per run (RSS, growth since the previous run, freed or not), the growth
per run over the second half of the runs (the first ones warm caches: numba, Drake's
scalar-type conversions), and a hash of the first run's logs (it must not change when only
the freeing of memory changes).

With ``--study N``: N such runs as a study runs them, over two local worker processes
(``ProcessRunner``), recycled every ``DEFAULT_RECYCLE`` jobs and as the runner decides for this
Drake (``AUTO_RECYCLE``: never where it frees a run's Diagram), interleaved ``--repeat`` times:
wall time, worker processes used and the largest worker RSS.
"""

from __future__ import annotations

import argparse
import gc
import hashlib
import os
import sys
import time
import weakref
from importlib.metadata import version
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

import numpy as np  # noqa: E402

from stewart_drake.run.result import finish_result, release_reference
from stewart_drake.run.scenario_io import load_scenario  # noqa: E402
from stewart_drake.run.simulate import build_simulator, simulate  # noqa: E402


def rss_mb() -> float:
    """Resident set size of this process, MB (Linux ``/proc/self/statm``)."""
    with open("/proc/self/statm") as f:
        return int(f.read().split()[1]) * os.sysconf("SC_PAGE_SIZE") / 2**20


def logs_digest(result) -> str:
    """SHA-256 (first 16 hex digits) of a run's logged arrays (times, pose, torques, state)."""
    h = hashlib.sha256()
    for a in (result.t, result.x, result.T, result.x_d, result.state, result.closure):
        h.update(np.ascontiguousarray(a).tobytes())
    return h.hexdigest()[:16]


def one_run(scenario) -> tuple[object, weakref.ref, weakref.ref, float]:
    """(result, weakref to the Diagram, weakref to the station, wall s) of one run; nothing of
    the run but its result is left referenced when this returns."""
    wall0 = time.perf_counter()
    sd, simulator = build_simulator(scenario)
    logs, wall = simulate(sd, simulator)
    release_reference(sd)
    result = finish_result(logs, wall)
    diagram, station = weakref.ref(sd.diagram), weakref.ref(sd.station)
    del sd, simulator, logs
    return result, diagram, station, time.perf_counter() - wall0


def study_job(job: tuple) -> tuple[int, float]:
    """(pid, RSS in MB) of a worker after one run of (scenario name, duration in s)."""
    name, duration_s = job
    one_run(load_scenario(name, [f"duration_s={duration_s}"]))
    return os.getpid(), rss_mb()


def study(n_jobs: int, name: str, duration_s: float, repeat: int) -> None:
    """Print the wall time of ``n_jobs`` runs over 2 local workers, recycled and not."""
    from stewart_drake.execution.runners import AUTO_RECYCLE, DEFAULT_RECYCLE, ProcessRunner

    jobs = {str(k): (name, duration_s) for k in range(n_jobs)}
    for r in range(repeat):
        for recycle in (DEFAULT_RECYCLE, AUTO_RECYCLE):
            runner = ProcessRunner(2, recycle=recycle)
            wall0 = time.perf_counter()
            got = dict(runner.map(study_job, jobs))
            wall = time.perf_counter() - wall0
            print(
                f"study repeat {r + 1}: {n_jobs} runs on 2 workers, recycle {recycle} "
                f"({runner.recycle}): wall {wall:.1f} s, {len({p for p, _ in got.values()})} "
                f"worker processes, largest worker RSS {max(m for _, m in got.values()):.0f} MB",
                flush=True,
            )


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=20, help="runs in the process (20)")
    parser.add_argument("--duration", type=float, default=0.5, help="s per run (0.5)")
    parser.add_argument("--scenario", default="paper_hardware", help="scenario (paper_hardware)")
    parser.add_argument("--study", type=int, default=0, help="runs of a 2-worker study (0)")
    parser.add_argument("--repeat", type=int, default=2, help="interleaved study repeats (2)")
    args = parser.parse_args()
    if args.study:
        study(args.study, args.scenario, args.duration, args.repeat)
    if args.runs == 0:
        return 0
    scenario = load_scenario(args.scenario, [f"duration_s={args.duration}"])

    print(
        f"drake {version('drake')}, Python {sys.version.split()[0]}, {args.runs} runs of "
        f"{args.duration:g} s of {args.scenario}"
    )
    print(f"{'run':>4} {'rss_MB':>8} {'delta_MB':>9} {'diagram_freed':>14} {'station_freed':>14}")
    rss, freed, walls, digest = [rss_mb()], [], [], None
    for k in range(args.runs):
        result, diagram, station, wall = one_run(scenario)
        if digest is None:
            digest = logs_digest(result)
        del result
        gc.collect()
        rss.append(rss_mb())
        freed.append(diagram() is None)
        walls.append(wall)
        print(
            f"{k + 1:>4} {rss[-1]:>8.1f} {rss[-1] - rss[-2]:>9.2f} "
            f"{'yes' if freed[-1] else 'no':>14} {'yes' if station() is None else 'no':>14}",
            flush=True,
        )
    half = args.runs // 2
    slope = (rss[-1] - rss[half]) / max(args.runs - half, 1)
    print(
        f"growth per run over runs {half + 1}..{args.runs}: {slope:.2f} MB; Diagrams freed "
        f"{sum(freed)}/{args.runs}; median wall per run {np.median(walls):.2f} s; "
        f"first run's logs {digest}"
    )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
