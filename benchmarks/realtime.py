"""Real-time factors of the plant alone and of the full Diagram, their ratio, and where time goes.

Measured in ONE process and interleaved (so a busy machine slows both alike), ``--repeats``
times each, medians printed:

* ``plant_alone``: the station of the scenario (the MultibodyPlant with its hardware: servos,
  friction, encoders, delay, current loop) under constant holding torques;
* ``full``: the whole closed-loop Diagram of the scenario with the ANN tuner (LQI with its
  estimator, density features, tuner, loggers, guard).

Target: ratio full / plant_alone >= 0.5 on the hardware scenario. One line per figure,
e.g. ``ratio_full_over_plant 0.52 (medians of 5 interleaved pairs)``.

``--breakdown`` adds where the full Diagram's time goes, per control step: the time inside each
Python callback measured in the running simulation (where each plant step leaves them with cold
CPU caches, so they cost about twice a microbenchmark's figure), and the ceiling of the ratio
with this Diagram: the same Diagram holding home with every Python update a no-op (what Drake's
framework, the station's hardware systems, the loggers and the Python dispatch cost alone).

Usage: python benchmarks/realtime.py [--scenario paper_hardware] [--duration 5] [--repeats 5]
       [--no-tuner] [--profile 25] [--riccati] [--breakdown] [--contact]
"""

import argparse
import collections
import dataclasses
import contextlib
import cProfile
import io
import pstats
import time

import numpy as np

from stewart_drake.control.estimator import PoseEstimator
from stewart_drake.control.features import DensityFeatures
from stewart_drake.control.lqi import (LqiController, error_model, input_matrix, lqi_gain,
                                       lqi_gain_warm)
from stewart_drake.control.tuner import AnnTuner
from stewart_drake.simulation.guard import DivergenceGuard
from stewart_drake.model.kinematics import X_HOME
from stewart_drake.simulation.scenario import AnnTunerDriver, NamedReference, load_scenario
from stewart_drake.simulation.station import held_station
from stewart_drake.simulation.trajectories import paper_manoeuvre
from stewart_drake.studies.experiments import build_simulator


def plant_alone(scenario, duration_s: float) -> float:
    """Wall seconds to simulate the scenario's station under constant holding torques."""
    _, simulator, _ = held_station(scenario, X_HOME)
    simulator.Initialize()
    t0 = time.perf_counter()
    simulator.AdvanceTo(duration_s)
    return time.perf_counter() - t0


def full(scenario, duration_s: float, profiler=None):
    """(wall seconds, StewartDiagram) of the closed-loop run, guarded as `run` is."""
    sd, simulator = build_simulator(scenario)
    if profiler:
        profiler.enable()
    t0 = time.perf_counter()
    simulator.AdvanceTo(duration_s)
    wall = time.perf_counter() - t0
    if profiler:
        profiler.disable()
    return wall, sd


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
    K, iterations, worst, warm = cold[0], 0, 0.0, []
    t0 = time.perf_counter()
    for A, B in models[1:]:
        K, it = lqi_gain_warm(A, B, Q, R, K)
        warm.append(K)
        iterations += it
    t_warm = (time.perf_counter() - t0) / (n - 1)
    for K_w, K_c in zip(warm, cold[1:]):
        worst = max(worst, np.abs(K_w - K_c).max() / np.abs(K_c).max())
    return {"cold_ms": 1e3 * t_cold, "warm_ms": 1e3 * t_warm, "iterations": iterations / (n - 1),
            "worst_rel": worst}


#: The Python callbacks of the full Diagram: (label, class, method).
CALLBACKS = (("LQI update (all)", LqiController, "_Update"),
             ("  of which FK estimator", PoseEstimator, "track_floats"),
             ("  of which gain solves", LqiController, "_gain"),
             ("density features", DensityFeatures, "_Update"),
             ("ANN tuner (and rho)", AnnTuner, "_Update"),
             ("guard checks", DivergenceGuard, "check"))


@contextlib.contextmanager
def _patched(changes):
    """Temporarily replace class attributes: changes = [(cls, name, value)]."""
    saved = [(cls, name, cls.__dict__[name]) for cls, name, _ in changes]
    try:
        for cls, name, value in changes:
            setattr(cls, name, value)
        yield
    finally:
        for cls, name, value in saved:
            setattr(cls, name, value)


def breakdown(scenario, duration_s: float) -> dict:
    """Seconds inside each Python callback during one full run (label -> s), and its wall s."""
    spent = collections.defaultdict(float)

    def timed(label, method):
        def wrapper(*args, **kwargs):
            t0 = time.perf_counter()
            try:
                return method(*args, **kwargs)
            finally:
                spent[label] += time.perf_counter() - t0
        return wrapper

    with _patched([(cls, name, timed(label, cls.__dict__[name]))
                   for label, cls, name in CALLBACKS]):
        wall, _ = full(scenario, duration_s)
    return {"wall": wall, **spent}


def noop_floor(scenario, duration_s: float) -> float:
    """Wall seconds of the full Diagram holding home with every Python update a no-op."""
    def nothing(self, context, discrete_state):
        return None

    held = dataclasses.replace(scenario, reference=NamedReference("home"))
    with _patched([(LqiController, "_Update", nothing), (DensityFeatures, "_Update", nothing),
                   (AnnTuner, "_Update", nothing)]):
        return full(held, duration_s)[0]


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenario", default="paper_hardware")
    parser.add_argument("--duration", type=float, default=5.0, help="simulated s per run (5)")
    parser.add_argument("--repeats", type=int, default=5, help="interleaved pairs (5)")
    parser.add_argument("--no-tuner", action="store_true", help="fixed weights, no ANN tuner")
    parser.add_argument("--profile", type=int, default=0, help="print the top N profile entries")
    parser.add_argument("--riccati", action="store_true", help="also time warm vs cold Riccati")
    parser.add_argument("--breakdown", action="store_true",
                        help="also time each Python callback and the Diagram's ceiling")
    parser.add_argument("--contact", action="store_true",
                        help="also measure both with contact between the parts simulated")
    args = parser.parse_args()
    scenario = load_scenario(args.scenario, [f"duration_s={args.duration}"])
    if not args.no_tuner:
        scenario.tuner = AnnTunerDriver()
    walls = {"plant": [], "full": []}
    for _ in range(max(1, args.repeats)):
        walls["plant"].append(plant_alone(scenario, args.duration))
        walls["full"].append(full(scenario, args.duration)[0])
    rtf = {k: args.duration / np.array(v) for k, v in walls.items()}
    ratios = rtf["full"] / rtf["plant"]
    tuner = "no tuner" if args.no_tuner else "ANN tuner"
    print(f"realtime_factor_plant_alone {np.median(rtf['plant']):.2f} median, "
          f"{rtf['plant'].max():.2f} best ({args.duration:g} s sim, {args.scenario} station "
          f"under constant torques)")
    print(f"realtime_factor_full {np.median(rtf['full']):.2f} median, {rtf['full'].max():.2f} "
          f"best ({args.scenario}, {tuner}, guard on, one process)")
    print(f"ratio_full_over_plant {np.median(ratios):.2f} (median of {len(ratios)} interleaved "
          f"pairs; range {ratios.min():.2f} .. {ratios.max():.2f}; target >= 0.5)")
    if args.contact:
        contact = load_scenario(args.scenario, [f"duration_s={args.duration}", "contact=true"])
        contact.tuner = scenario.tuner
        on = {"plant": [], "full": []}
        for _ in range(max(1, args.repeats)):
            on["plant"].append(plant_alone(contact, args.duration))
            on["full"].append(full(contact, args.duration)[0])
        rtf_on = {k: args.duration / np.array(v) for k, v in on.items()}
        for key, label in (("plant", "plant_alone"), ("full", "full")):
            print(f"realtime_factor_{label}_contact {np.median(rtf_on[key]):.2f} median "
                  f"(contact on; off: {np.median(rtf[key]):.2f}; on / off "
                  f"{np.median(rtf_on[key]) / np.median(rtf[key]):.2f})")
        print(f"ratio_full_over_plant_contact "
              f"{np.median(rtf_on['full'] / rtf_on['plant']):.2f} (contact on)")
    if args.breakdown:
        steps = args.duration / scenario.control_period_s
        spent = breakdown(scenario, args.duration)
        floor = min(noop_floor(scenario, args.duration) for _ in range(max(1, args.repeats)))
        plant = min(walls["plant"])
        print(f"per control step in the full Diagram ({spent['wall'] / steps * 1e6:.0f} us of "
              f"wall; the plant alone {plant / steps * 1e6:.0f} us):")
        for label, _, _ in CALLBACKS:
            print(f"  {label:26s} {spent.get(label, 0.0) / steps * 1e6:7.1f} us")
        print(f"ceiling_ratio {plant / floor:.2f} (the Diagram with no-op Python updates, holding "
              f"home: {floor / steps * 1e6:.0f} us per step; best of {max(1, args.repeats)})")
    if args.riccati:
        _, sd = full(scenario, 0.01)
        c = riccati_costs(sd.controller)
        print(f"riccati_cold_ms {c['cold_ms']:.3f}  riccati_warm_ms {c['warm_ms']:.3f}  "
              f"warm/cold {c['warm_ms'] / c['cold_ms']:.2f}  ({c['iterations']:.2f} "
              f"iterations; max |K_warm - K_cold| / |K_cold| {c['worst_rel']:.1e})")
    if args.profile:
        profiler = cProfile.Profile()
        full(scenario, args.duration, profiler)
        s = io.StringIO()
        pstats.Stats(profiler, stream=s).sort_stats("tottime").print_stats(args.profile)
        print(s.getvalue())


if __name__ == "__main__":
    main()
