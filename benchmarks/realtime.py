"""Real-time factor of the `run` Diagram and the cost of one gain re-schedule.

Prints one line per figure, e.g. ``realtime_factor 2.31 (10.0 s sim / 4.33 s wall)``.
Target (issue 6): real-time factor >= 2 on one core for the full Diagram.

Usage: python benchmarks/realtime.py [--duration 10] [--tuner ann] [--profile 15] [--guard-overhead]
"""

import argparse
import cProfile
import io
import pstats
import time

import numpy as np

from stewart_drake.diagram import StewartConfig
from stewart_drake.experiments import build_simulator
from stewart_drake.geometry import X_HOME


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--duration", type=float, default=10.0)
    parser.add_argument("--tuner", choices=["none", "ann"], default="none")
    parser.add_argument("--profile", type=int, default=0, help="print the top N profile entries")
    parser.add_argument("--guard-overhead", action="store_true",
                        help="also time runs with and without the divergence guard, interleaved")
    args = parser.parse_args()
    config = StewartConfig(duration_s=args.duration,
                           tuner=None if args.tuner == "none" else args.tuner)
    sd, simulator = build_simulator(config)
    profiler = cProfile.Profile() if args.profile else None
    t0 = time.perf_counter()
    if profiler:
        profiler.enable()
    simulator.AdvanceTo(config.duration_s)
    if profiler:
        profiler.disable()
    wall = time.perf_counter() - t0
    print(f"realtime_factor {config.duration_s / wall:.2f} "
          f"({config.duration_s:.1f} s sim / {wall:.2f} s wall, tuner={args.tuner})")

    controller = sd.controller
    n = 200
    t0 = time.perf_counter()
    for k in range(n):
        controller.gain(X_HOME + 1e-4 * np.sin(k) * np.ones(6), 1.0, 1.0)
    per = (time.perf_counter() - t0) / n
    print(f"gain_reschedule_ms {1e3 * per:.3f} (mean of {n}, DARE + B(x) on 18 states)")
    steps = config.duration_s / config.schedule_period_s
    print(f"reschedule_share_of_wall {steps * per / wall:.3f} "
          f"({steps:.0f} re-schedules x {1e3 * per:.3f} ms / {wall:.2f} s)")
    if args.guard_overhead:
        guard_overhead(config)
    if profiler:
        s = io.StringIO()
        pstats.Stats(profiler, stream=s).sort_stats("tottime").print_stats(args.profile)
        print(s.getvalue())


def guard_overhead(config, repeats: int = 5):
    """Wall time of the same run with the DivergenceGuard as monitor and without, interleaved so
    that a busy machine slows both alike; prints the ratio of the fastest runs (the least
    disturbed) and of the medians."""
    walls = {"guarded": [], "bare": []}
    for _ in range(repeats):
        for mode in walls:
            sd, simulator = build_simulator(config)
            if mode == "bare":
                simulator.clear_monitor()
            t0 = time.perf_counter()
            simulator.AdvanceTo(config.duration_s)
            walls[mode].append(time.perf_counter() - t0)
    guarded, bare = min(walls["guarded"]), min(walls["bare"])
    median = np.median(walls["guarded"]) / np.median(walls["bare"]) - 1
    print(f"guard_overhead {guarded / bare - 1:+.3f} (fastest of {repeats}: {guarded:.2f} s "
          f"guarded / {bare:.2f} s bare, {config.duration_s:.1f} s sim; medians {median:+.3f})")


if __name__ == "__main__":
    main()
