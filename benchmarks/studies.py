"""Scaling of the studies over runners: speedup, overhead per task, a 64-core
projection, and the memory of one worker over many runs.

    python benchmarks/studies.py                      # everything, about 10 min on 2 cores
    python benchmarks/studies.py --parts memory --memory-runs 50
    python benchmarks/studies.py --controllers pd     # a 14-case grid instead of 168
    python benchmarks/studies.py --parts scaling --controllers lqi_1_1,pd --repeat 3

Parts (one line per figure):
    scaling     ``evaluate --quick`` on 1 and 2 workers, local processes and Ray: wall time,
                speedup 2 over 1, overhead per task = (workers x wall - sum of case times) / cases.
    noop        round trip of an empty job through each backend (the protocol's floor).
    projection  from the measured per-case times of the 1-worker run (build time + duration /
                real-time factor per case), the wall time of the full evaluation (10 s runs) on
                a 64-core Ray cluster (longest-first schedule + the measured overhead per task),
                and on 2 processes to check the model against docs/results.md.
    memory      RSS of one worker after each of N consecutive runs, with and without recycling.
Measure on a quiet machine: the load average is printed before and after.
"""

from __future__ import annotations

import argparse
import contextlib
import heapq
import os
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from stewart_drake.evaluation.evaluation import evaluate  # noqa
from stewart_drake.evaluation.evaluation_grid import CONTROLLERS, SCENARIO_DURATION_S  # noqa
from stewart_drake.execution.clusters import RayRunner  # noqa
from stewart_drake.execution.runners import DEFAULT_RECYCLE, ProcessRunner  # noqa


def _noop(job):
    return job


def _rss_after_run(duration_s: float) -> tuple[int, float]:
    """(pid, RSS in MB) of this worker after one closed-loop run of ``duration_s``."""
    import psutil

    from stewart_drake.run.scenario_io import load_scenario
    from stewart_drake.run.simulate import run_experiment

    run_experiment(load_scenario("paper_hardware", [f"duration_s={duration_s}"]))
    return os.getpid(), psutil.Process().memory_info().rss / 2**20


def _busy_cores() -> float:
    """CPU seconds the whole machine has spent busy so far (all processes, all cores)."""
    import psutil

    t = psutil.cpu_times()
    return sum(t) - t.idle - getattr(t, "iowait", 0.0)


def _wait_quiet(max_wait_s: float, below: float = 0.3) -> None:
    """Wait (at most ``max_wait_s``) until the 1-minute load average is below ``below``: other
    users of a shared machine would take the cores the workers are meant to have."""
    deadline = time.monotonic() + max_wait_s
    while os.getloadavg()[0] >= below and time.monotonic() < deadline:
        time.sleep(5)


def _runner(kind: str, workers: int):
    return ProcessRunner(workers) if kind == "processes" else RayRunner(workers)


class _RayCluster:
    """A local Ray cluster of ``workers`` CPUs, up before the clock starts (as a cluster that
    is already running would be); prints its start-up time."""

    def __init__(self, workers: int):
        self.workers = workers

    def __enter__(self):
        import ray

        t0 = time.perf_counter()
        ray.init(num_cpus=self.workers, include_dashboard=False, log_to_driver=False)
        print(
            f"ray_init_{self.workers}_cpus_s {time.perf_counter() - t0:.1f} (not counted below)",
            flush=True,
        )

    def __exit__(self, *exc):
        import ray

        ray.shutdown()


def scaling(
    controllers, kinds=("processes", "ray"), quiet_wait_s: float = 0.0, repeat: int = 1
) -> dict:
    """Wall time of evaluate --quick per backend and worker count; the rows of each. Each line
    says how busy the machine was meanwhile (all processes: ours count ``workers`` cores). With
    ``repeat`` > 1 the configurations are interleaved and the fastest of each is kept (on a
    shared host, other machines' load only ever slows a run down)."""
    measured = {}
    for rep in range(repeat):
        for kind in kinds:
            for workers in (1, 2):
                _wait_quiet(quiet_wait_s)
                cluster = _RayCluster(workers) if kind == "ray" else contextlib.nullcontext()
                with tempfile.TemporaryDirectory() as tmp, cluster:
                    load0, busy0, t0 = os.getloadavg()[0], _busy_cores(), time.perf_counter()
                    report = evaluate(
                        Path(tmp) / "docs",
                        Path(tmp) / "out",
                        runner=_runner(kind, workers),
                        progress=False,
                        quick=True,
                        controllers=controllers,
                    )
                    wall = time.perf_counter() - t0
                    busy = (_busy_cores() - busy0) / wall
                rows = report["rows"]
                case_s = sum(r["wall_s"] for r in rows if "wall_s" in r)
                print(
                    f"{kind}_{workers}_workers_wall_s {wall:.1f} ({len(rows)} cases, sum of "
                    f"case times {case_s:.1f} s, {sum('error' in r for r in rows)} failed; "
                    f"machine busy {busy:.2f} cores on average, load {load0:.2f} at start; "
                    f"run {rep + 1} of {repeat})",
                    flush=True,
                )
                best = measured.get((kind, workers))
                if best is None or wall < best["wall"]:
                    measured[kind, workers] = {"wall": wall, "rows": rows, "case_s": case_s}
    for kind in kinds:
        one, two = measured[kind, 1], measured[kind, 2]
        n = len(two["rows"])
        print(
            f"{kind}_speedup_2_over_1 {one['wall'] / two['wall']:.2f} (fastest of {repeat}: "
            f"{one['wall']:.1f} s / {two['wall']:.1f} s)"
        )
        for w in (1, 2):
            m = measured[kind, w]
            print(
                f"{kind}_{w}_workers_overhead_per_task_ms "
                f"{1e3 * (w * m['wall'] - m['case_s']) / n:.0f}"
            )
    return measured


def noop(n: int = 200) -> dict:
    """Seconds per empty job through each backend, pool start-up excluded."""
    out = {}
    for kind in ("processes", "ray"):
        cluster = _RayCluster(2) if kind == "ray" else contextlib.nullcontext()
        with cluster:
            it = _runner(kind, 2).map(_noop, {"warm": 0, **{str(k): k for k in range(n)}})
            next(it)  # the pool is up after the first result
            t0 = time.perf_counter()
            for _ in it:
                pass
            out[kind] = (time.perf_counter() - t0) / n
        print(f"noop_round_trip_ms_{kind} {1e3 * out[kind]:.2f} ({n} empty jobs, 2 workers)")
    return out


def _makespan(times, workers: int, overhead_s: float) -> float:
    """Longest-first list schedule of ``times`` (s) on ``workers``, + overhead per task."""
    finish = [0.0] * workers
    for t in sorted(times, reverse=True):
        heapq.heappush(finish, heapq.heappop(finish) + t + overhead_s)
    return max(finish)


def projection(rows, overhead_s: float) -> None:
    """The full evaluation's wall time, from the quick rows' per-case build and sim times."""
    full = []
    for r in rows:
        if "error" in r:
            continue
        quick_s = r["case"]["duration_s"]
        sim_wall = quick_s / r["realtime_factor"]
        build = max(r["wall_s"] - sim_wall, 0.0)
        full.append(build + SCENARIO_DURATION_S[r["case"]["scenario"]] / r["realtime_factor"])
    print(
        f"full_evaluation_sum_of_case_times_s {sum(full):.0f} ({len(full)} cases, longest "
        f"{max(full):.1f} s)"
    )
    print(
        f"projected_full_evaluation_64_core_ray_s {_makespan(full, 64, overhead_s):.1f} "
        f"(overhead {1e3 * overhead_s:.0f} ms per task; cluster already up)"
    )
    print(
        f"projected_full_evaluation_2_processes_s {_makespan(full, 2, overhead_s):.0f} "
        f"(docs/results.md measured 238 s for 168 runs on 2 processes)"
    )


def memory(runs: int, duration_s: float) -> None:
    """RSS of one worker after each of ``runs`` consecutive runs, with and without recycling."""
    for recycle in (None, DEFAULT_RECYCLE):
        jobs = {str(k): duration_s for k in range(runs)}
        got = dict(ProcessRunner(1, recycle=recycle).map(_rss_after_run, jobs))
        rss = [got[str(k)][1] for k in range(runs)]
        pids = {got[str(k)][0] for k in range(runs)}
        label = "no_recycling" if recycle is None else f"recycle_{recycle}"
        print(
            f"memory_{runs}_runs_{label}_MB first {rss[0]:.0f} max {max(rss):.0f} last "
            f"{rss[-1]:.0f} growth {max(rss) - rss[0]:.0f} ({len(pids)} worker processes, "
            f"{duration_s:g} s runs, {(rss[-1] - rss[0]) / max(runs - 1, 1):.2f} MB per run "
            f"between first and last)",
            flush=True,
        )


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--parts", default="scaling,noop,projection,memory")
    parser.add_argument("--controllers", default=None, help="comma-separated subset (all)")
    parser.add_argument("--memory-runs", type=int, default=50)
    parser.add_argument("--memory-duration", type=float, default=2.0, help="s per run (2)")
    parser.add_argument("--runners", default="processes,ray", help="backends of the scaling part")
    parser.add_argument(
        "--repeat",
        type=int,
        default=1,
        help="interleaved repetitions of the scaling runs; the fastest counts",
    )
    parser.add_argument(
        "--wait-quiet",
        type=float,
        default=0.0,
        help="before each scaling run, wait up to this many s for the load "
        "average to drop below 0.3 (a shared machine)",
    )
    args = parser.parse_args()
    parts = set(args.parts.split(","))
    controllers = tuple(args.controllers.split(",")) if args.controllers else CONTROLLERS
    print(f"cpus {os.cpu_count()} load_average_start {os.getloadavg()[0]:.2f}", flush=True)
    measured = None
    if "scaling" in parts or "projection" in parts:
        measured = scaling(
            controllers,
            tuple(args.runners.split(",")),
            quiet_wait_s=args.wait_quiet,
            repeat=args.repeat,
        )
    if "noop" in parts:
        noop()
    if "projection" in parts:
        m = measured["ray", 2]
        ray_overhead = max((2 * m["wall"] - m["case_s"]) / len(m["rows"]), 0.0)
        projection(measured["processes", 1]["rows"], ray_overhead)
    if "memory" in parts:
        memory(args.memory_runs, args.memory_duration)
    print(f"load_average_end {os.getloadavg()[0]:.2f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
