"""CPU per simulated second with glibc's default thread cache and with the one the command sets.

glibc reads its tunables once, when a process starts, so the two cannot share one process: each
measurement is a child process (the same interpreter), the settings alternated ``--repeats``
times so that a busy machine slows both alike, each child timed by its own thread's CPU time.
Each child measures, ``--duration`` simulated s each:

* ``station``: the scenario's station alone under constant holding torques;
* ``<scenario>``: the closed loop of each scenario as it is (fixed weights), built and run as
  ``stewart-drake run`` builds it (``build_simulator``);

and reports its peak resident memory. ``--before DIR`` adds a third contender: the package in
DIR (a checkout of an earlier commit) with glibc's default, for the figure "now against before".

Prints one line per figure, e.g.
``paper_hardware default 0.262  tuned 0.214  tuned/default 0.82 (median of 3; ...)``.

Usage: python benchmarks/allocator.py [--scenarios paper_hardware paper_ideal] [--duration 5]
       [--repeats 3] [--before DIR]
"""

import argparse
import json
import os
import subprocess
import sys

import numpy as np

from stewart_drake.base.allocator import TCACHE_COUNT, TCACHE_TUNABLE, is_glibc

#: What a child runs: argv[1] the JSON list of scenarios, argv[2] the duration; prints JSON.
CHILD = """
import dataclasses, json, resource, sys, time
from stewart_drake.robot.kinematics import X_HOME
from stewart_drake.run.diagram import held_station
from stewart_drake.run.scenario_io import load_scenario
from stewart_drake.run.simulate import build_simulator
names, D = json.loads(sys.argv[1]), float(sys.argv[2])
out = {}
_, simulator, _ = held_station(load_scenario(names[0]), X_HOME)
simulator.Initialize()
t0 = time.thread_time()
simulator.AdvanceTo(D)
out["station"] = (time.thread_time() - t0) / D
for name in names:
    scenario = dataclasses.replace(load_scenario(name), duration_s=D)
    build_simulator(dataclasses.replace(scenario, duration_s=0.01))[1].AdvanceTo(0.01)
    _, simulator = build_simulator(scenario)
    t0 = time.thread_time()
    simulator.AdvanceTo(D)
    out[name] = (time.thread_time() - t0) / D
out["peak_mb"] = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
print(json.dumps(out))
"""


def measure(scenarios, duration_s: float, tcache: int | None, tree: str | None = None) -> dict:
    """One child's figures: CPU s per simulated s of the station and of each scenario's closed
    loop, and its peak memory (MB), with glibc's cache of ``tcache`` blocks a size (None: the
    command's setting) and the package of ``tree`` (None: this one)."""
    env = dict(os.environ)
    env["GLIBC_TUNABLES"] = f"{TCACHE_TUNABLE}={TCACHE_COUNT if tcache is None else tcache}"
    if tree is not None:
        env["PYTHONPATH"] = os.path.abspath(tree)
    done = subprocess.run(
        [sys.executable, "-c", CHILD, json.dumps(list(scenarios)), str(duration_s)],
        env=env,
        capture_output=True,
        text=True,
        check=True,
        cwd=tree or None,
        timeout=3600,
    )
    return json.loads(done.stdout.strip().splitlines()[-1])


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenarios", nargs="+", default=["paper_hardware", "paper_ideal"])
    parser.add_argument("--duration", type=float, default=5.0, help="simulated s per run (5)")
    parser.add_argument("--repeats", type=int, default=3, help="alternations (3)")
    parser.add_argument(
        "--before", default=None, metavar="DIR", help="also the package in DIR, glibc's default"
    )
    args = parser.parse_args()
    if not is_glibc():
        parser.exit(2, "allocator.py: this C library is not glibc; there is nothing to compare\n")
    contenders = {"default": (7, None), "tuned": (None, None)}
    if args.before:
        contenders = {"before": (7, args.before), **contenders}
    runs = {name: [] for name in contenders}
    load = os.getloadavg()[0]
    for _ in range(max(1, args.repeats)):
        for name, (tcache, tree) in contenders.items():
            runs[name].append(measure(args.scenarios, args.duration, tcache, tree))
    print(
        f"glibc thread cache: default 7 blocks a size, tuned {TCACHE_COUNT}; CPU s per "
        f"simulated s ({args.duration:g} s runs), medians of {args.repeats} alternated "
        f"children; load {load:.1f} at start, {os.getloadavg()[0]:.1f} at the end"
    )
    for key in ["station", *args.scenarios, "peak_mb"]:
        figures = {n: np.array([r[key] for r in rs]) for n, rs in runs.items()}
        cells = "  ".join(f"{n} {np.median(v):.3f}" for n, v in figures.items())
        ratios = [
            f"{a}/{b} {np.median(figures[a] / figures[b]):.2f} "
            f"({np.min(figures[a] / figures[b]):.2f} .. {np.max(figures[a] / figures[b]):.2f})"
            for a, b in (("tuned", "default"), ("tuned", "before"))
            if b in figures
        ]
        print(f"{key:16s} {cells}  {'  '.join(ratios)}")


if __name__ == "__main__":
    main()
