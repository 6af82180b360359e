"""CPU time of shaping a followed reference to the robot's limits, per control period, as the
live reference (``live.follow.FollowReference``, ``robot --follow-lcm``) steps it.

    python benchmarks/stream_shaping.py                # breathing, 60 s at 5 Hz, 0.1 mm noise
    python benchmarks/stream_shaping.py --seconds 30 --noise 0 --repeats 3

The library's breathing sampled ``--rate`` Hz with ``--noise`` m of Gaussian noise on X, Y, Z,
0.2 s late, followed with the default predictor (offline, ``references.stream.follow``: only
the shaping is timed), then ``run.shaping.Shaper.step`` called at every control period of the
phantom's scenario, as the live reference calls it: printed, the CPU time per period
(``time.process_time``, the best of ``--repeats``), over all periods and split into those given
the followed reference as it is and those shaped (each timed on its own).
"""

from __future__ import annotations

import argparse
import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))  # measure this checkout

from stewart_drake.references.organ.library import make_motion  # noqa: E402
from stewart_drake.references.prediction import DEFAULT_PREDICTOR  # noqa: E402
from stewart_drake.references.stream import Stream, follow  # noqa: E402
from stewart_drake.run.plan import make_plan  # noqa: E402
from stewart_drake.run.scenario_io import load_scenario  # noqa: E402
from stewart_drake.run.shaping import Shaper, shaping_limits  # noqa: E402


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=60.0, help="the stream's length (60)")
    parser.add_argument("--rate", type=float, default=5.0, help="its rate, Hz (5)")
    parser.add_argument("--noise", type=float, default=100e-6, help="its noise, m (1e-4)")
    parser.add_argument("--repeats", type=int, default=3, help="runs, best kept (3)")
    args = parser.parse_args()
    rng = np.random.default_rng(1)
    t = np.arange(0.0, args.seconds + 1e-9, 1.0 / args.rate)
    poses = np.asarray(make_motion("breathing", {}).evaluate(t)[0]).copy()
    poses[:, 3:] += rng.normal(0.0, args.noise, (t.size, 3))
    followed = follow(Stream(t, poses, 0.2, "noisy breathing"), DEFAULT_PREDICTOR)
    scenario = replace(load_scenario("phantom_hardware"), duration_s=args.seconds)
    limits = shaping_limits(make_plan(scenario, with_reference=False))
    times = np.arange(0.0, args.seconds, limits.period_s)
    x, v, a = (np.asarray(q) for q in followed.evaluate(times))
    best = None
    for _ in range(args.repeats):
        shaper = Shaper(limits)
        state = shaper.initial_state(x[0])
        cpu = np.empty(times.size)
        flags = np.empty(times.size, dtype=int)
        for k in range(times.size):
            c0 = time.process_time()
            _, flags[k] = shaper.step(state, times[k], (x[k], v[k], a[k]))
            cpu[k] = time.process_time() - c0
        if best is None or cpu.sum() < best[0].sum():
            best = (cpu, flags, shaper.record)
    cpu, flags, record = best
    print(f"{times.size} control periods of {limits.period_s * 1e3:g} ms; {record.words()}")
    for what, sel in (("all", slice(None)), ("as followed", flags == 0), ("shaped", flags != 0)):
        n = cpu[sel].size
        if n:
            print(f"  {what:12s} {n:7d} periods: {cpu[sel].mean() * 1e6:7.0f} us CPU a period")


if __name__ == "__main__":
    main()
