"""Real-time factor of the `run` Diagram, the warm/cold Riccati cost and the profile's top entries.

Prints one line per figure, e.g. ``realtime_factor 2.47 (10.0 s sim / 4.05 s wall, tuner=ann)``.
Target (issue 6): real-time factor >= 2 on one core for the full Diagram (plant 1 ms + LQI 1 kHz +
density features + ANN tuner), i.e. ``--tuner ann``.

Usage: python benchmarks/realtime.py [--duration 10] [--tuner ann] [--riccati warm|cold]
       [--profile 15] [--guard-overhead]
"""

import argparse
import cProfile
import io
import pstats
import time

import numpy as np

from stewart_drake.control.lqi import error_model, input_matrix, lqi_gain, lqi_gain_warm
from stewart_drake.simulation.diagram import StewartConfig
from stewart_drake.studies.experiments import build_simulator
from stewart_drake.simulation.trajectories import paper_manoeuvre


def riccati_costs(controller, n: int = 200) -> dict:
    """Mean cold and warm solve times (ms) along the paper manoeuvre, re-scheduled every 10 ms,
    and the worst relative gain difference between them."""
    g, h = controller.geometry, controller.h
    Q, R = controller.scales.Q_unit(), controller.scales.R_unit()
    poses = paper_manoeuvre().evaluate(np.arange(n) * 0.01)[0]
    models = [error_model(input_matrix(g, x), h) for x in poses]
    t0 = time.perf_counter()
    cold = [lqi_gain(A, B, Q, R) for A, B in models]
    t_cold = (time.perf_counter() - t0) / n
    K, iterations, worst = cold[0], 0, 0.0
    t0 = time.perf_counter()
    warm = []
    for A, B in models[1:]:
        K, it = lqi_gain_warm(A, B, Q, R, K)
        warm.append(K)
        iterations += it
    t_warm = (time.perf_counter() - t0) / (n - 1)
    for K_w, K_c in zip(warm, cold[1:]):
        worst = max(worst, np.abs(K_w - K_c).max() / np.abs(K_c).max())
    t0 = time.perf_counter()
    for x in poses:
        input_matrix(g, x)
    t_b = (time.perf_counter() - t0) / n
    return {"cold_ms": 1e3 * t_cold, "warm_ms": 1e3 * t_warm, "B_ms": 1e3 * t_b,
            "iterations": iterations / (n - 1), "worst_rel": worst}


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--duration", type=float, default=10.0)
    parser.add_argument("--tuner", choices=["none", "ann"], default="ann")
    parser.add_argument("--riccati", choices=["warm", "cold"], default="warm")
    parser.add_argument("--profile", type=int, default=0, help="print the top N profile entries")
    parser.add_argument("--repeats", type=int, default=3,
                        help="timed runs; the median and the best are printed (3)")
    parser.add_argument("--guard-overhead", action="store_true",
                        help="also time runs with and without the divergence guard, interleaved")
    args = parser.parse_args()
    config = StewartConfig(duration_s=args.duration, riccati=args.riccati,
                           tuner=None if args.tuner == "none" else args.tuner)
    walls = []
    profiler = cProfile.Profile() if args.profile else None
    for k in range(max(1, args.repeats)):
        t0 = time.perf_counter()
        sd, simulator = build_simulator(config)
        build = time.perf_counter() - t0
        if profiler and k == 0:
            profiler.enable()
        t0 = time.perf_counter()
        simulator.AdvanceTo(config.duration_s)
        walls.append(time.perf_counter() - t0)
        if profiler and k == 0:
            profiler.disable()
    rtf = sorted(config.duration_s / w for w in (walls[1:] if profiler and len(walls) > 1
                                                  else walls))
    print(f"realtime_factor {float(np.median(rtf)):.2f} median, {rtf[-1]:.2f} best of {len(rtf)} "
          f"({config.duration_s:.1f} s sim, tuner={args.tuner}, riccati={args.riccati}, one "
          f"process; the VM's speed varies, so compare medians)")
    print(f"build_s {build:.2f} (reference + feed-forward tables, Diagram, assembly)")
    stats = sd.controller.solve_stats
    print(f"gain_solves warm {stats['warm']} (mean {stats['warm_iterations'] / max(stats['warm'], 1):.2f}"
          f" Newton iterations) cold {stats['cold']}")
    c = riccati_costs(sd.controller)
    print(f"riccati_cold_ms {c['cold_ms']:.3f}  riccati_warm_ms {c['warm_ms']:.3f}  "
          f"warm/cold {c['warm_ms'] / c['cold_ms']:.2f}  (B(x) {c['B_ms']:.3f} ms not included; "
          f"{c['iterations']:.2f} iterations; max |K_warm - K_cold| / |K_cold| {c['worst_rel']:.1e})")
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
