"""CPU time of following a streamed motion: every predictor's update per sample (its mean and its
slowest), the linear predictor and a whole follower at each history the stream study tunes over,
and the live follower.

    python benchmarks/stream_prediction.py                # breathing, 120 s at 25 Hz, 0.2 s late
    python benchmarks/stream_prediction.py --seconds 60 --rate 5 --repeats 3

``references.prediction.LinearModel`` alone (the regression), ``OnlinePredictor`` (with its
record and envelope) and ``references.stream.follow`` (the reference a robot follows, with its
curves), on the library's breathing streamed ``--rate`` Hz and 0.2 s late; and the live
follower (``references.live_stream.LiveFollower``, what ``robot --follow-lcm`` runs): each
sample received, and the reference evaluated every 10 ms (the robot's control period). Printed
per history: the CPU time of the process (``time.process_time``: BLAS's threads included; the
best of ``--repeats``) and per sample, and the wall time of that call. Per predictor
(``references.prediction.PREDICTORS``, the shipped settings, the record, bound and shrinkage
included): the CPU per sample and the slowest single sample's wall time, against the robot's
10 ms control period (a live sample is read between two periods).
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))  # measure this checkout

from stewart_drake.references.live_stream import LiveFollower  # noqa: E402
from stewart_drake.references.organ.library import make_motion  # noqa: E402
from stewart_drake.references.prediction import (  # noqa: E402
    PREDICTORS,
    LinearModel,
    OnlinePredictor,
    PredictorSettings,
)
from stewart_drake.references.stream import (  # noqa: E402
    BLEND_S,
    LOOP_LAG_S,
    follow,
    follower_steps,
    stream_of,
)


def best_of(repeats: int, work) -> tuple:
    """(CPU s, wall s) of the call of ``work()`` that took the least CPU of ``repeats``."""
    times = []
    for _ in range(repeats):
        c0, w0 = time.process_time(), time.perf_counter()
        work()
        times.append((time.process_time() - c0, time.perf_counter() - w0))
    return min(times)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=120.0, help="the stream's length (120)")
    parser.add_argument("--rate", type=float, default=25.0, help="its rate, Hz (25)")
    parser.add_argument("--latency", type=float, default=0.2, help="its latency, s (0.2)")
    parser.add_argument("--repeats", type=int, default=3, help="calls per form, best kept (3)")
    args = parser.parse_args()
    stream = stream_of(make_motion("breathing", {}), args.latency, args.rate, args.seconds)
    dt, n = stream.dt, stream.t.size
    steps = follower_steps(args.latency, dt, LOOP_LAG_S, min(BLEND_S, dt))
    print(f"breathing, {args.seconds:g} s at {args.rate:g} Hz ({n} samples), {args.latency:g} s "
          f"late: {steps} steps ahead")  # fmt: skip
    for name in PREDICTORS:
        slowest, cpu = [], []
        for _ in range(args.repeats):
            m = OnlinePredictor(name, dt, steps, 6)
            c0, worst = time.process_time(), 0.0
            for y in stream.poses:
                w0 = time.perf_counter()
                m.raw_update(y)
                worst = max(worst, time.perf_counter() - w0)
            cpu.append(time.process_time() - c0)
            slowest.append(worst)
        print(f"predictor {name}: {min(cpu) / n * 1e6:.0f} us CPU a sample, the slowest "
              f"sample {min(slowest) * 1e3:.2f} ms wall (control period 10 ms)")  # fmt: skip
    for history in (0.5, 1.0, 2.0, 4.0):
        settings = PredictorSettings(history_s=history)
        p = settings.lags(dt)

        def model(settings=settings):
            m = LinearModel(dt, steps, 6, settings)
            for y in stream.poses:
                m.update(y)

        def predictor(settings=settings):
            m = OnlinePredictor("linear", dt, steps, 6, settings)
            for y in stream.poses:
                m.raw_update(y)

        cells = []
        for name, work in (
            ("model", model),
            ("predictor", predictor),
            ("follow", lambda settings=settings: follow(stream, "linear", settings)),
        ):
            cpu, wall = best_of(args.repeats, work)
            cells.append(
                f"{name} {cpu:.2f} s CPU ({cpu / n * 1e6:.0f} us/sample; {wall:.2f} s wall)"
            )
        stride = settings.lag_stride(dt)
        print(f"history {history:g} s ({p} lags, every {stride} sample(s)): " + ", ".join(cells))
    live = LiveFollower(args.latency, args.rate)
    c0, evaluations = time.process_time(), 0
    for i, (t, y) in enumerate(zip(stream.t, stream.poses)):
        live.receive(stream.arrival[i], i, int(round(t * 1e6)), y)
        for now in stream.arrival[i] + np.arange(0.0, stream.dt - 1e-9, 0.01):
            live.evaluate(now)
            evaluations += 1
    cpu = time.process_time() - c0
    print(f"live, the shipped settings: {cpu:.2f} s CPU for {n} samples received and "
          f"{evaluations} evaluations ({cpu / evaluations * 1e6:.0f} us an evaluation with "
          "its share of the receiving)")  # fmt: skip


if __name__ == "__main__":
    main()
