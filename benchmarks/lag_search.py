"""CPU time of the package's one lag search (``stewart_drake.base.lag.signal_lag``), and of the
same least found by a loop over the shifts, measured in the same run.

    python benchmarks/lag_search.py               # 30 s at 10 ms and 60 s at 1 ms, +-0.5 s
    python benchmarks/lag_search.py --repeats 50

The windows: the encoders' relative latency of a 30 s run at the bus's 10 ms (3,000 samples,
101 shifts on the samples' step), and a reproduced pair's 60 s at the plant's 1 ms (60,000
samples, 1,001 shifts). The signal: an irregular breath 12.3 ms late. Printed per window: the
search's CPU time of this thread (``time.thread_time``; the best of ``--repeats``), that of a
loop interpolating the command at every shift on the samples' step then refining (the
O(n K) way the pair's delays and the encoders' lags were searched before), and their ratio.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np
from scipy.optimize import minimize_scalar

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))  # measure this checkout

from stewart_drake.base.lag import signal_lag  # noqa: E402

MAX_LAG_S = 0.5
DELAY_S = 0.0123


def breath(t):
    """An irregular breath, m: a cos^4 shape, its period wandering 3.7-4.4 s."""
    phase = 2 * np.pi * (t / 4.0 + 0.08 * np.sin(2 * np.pi * t / 23.0))
    return 0.01 * np.cos(phase / 2) ** 4


def shift_loop(t, y, c, max_lag_s):
    """The least RMS(y(t_k) - c(t_k - L)) by a loop over every shift on the samples' step, then
    a bounded scalar minimisation within a step of it, s."""
    h = float(np.median(np.diff(t)))
    inner = (t >= t[0] + max_lag_s) & (t <= t[-1] - max_lag_s)
    t_in, y_in = t[inner], y[inner]

    def rms(lag):
        return float(np.sqrt(np.mean((y_in - np.interp(t_in - lag, t, c)) ** 2)))

    grid = np.arange(-max_lag_s, max_lag_s + 0.5 * h, h)
    k = int(np.argmin([rms(g) for g in grid]))
    bounds = (grid[k] - h, grid[k] + h)
    return float(minimize_scalar(rms, bounds=bounds, method="bounded").x)


def best_cpu_s(fn, repeats: int) -> float:
    """The least thread CPU time of ``repeats`` calls of ``fn``, s (after one not counted)."""
    fn()
    best = float("inf")
    for _ in range(repeats):
        start = time.thread_time()
        fn()
        best = min(best, time.thread_time() - start)
    return best


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=20, help="calls timed, the best kept")
    args = parser.parse_args(argv)
    for name, span_s, step_s in (("30s_10ms", 30.0, 0.01), ("60s_1ms", 60.0, 0.001)):
        t = np.arange(0.0, span_s, step_s)
        y, c = breath(t - DELAY_S), breath(t)
        lag = signal_lag(t, y, c, MAX_LAG_S)[0]
        ours = best_cpu_s(lambda t=t, y=y, c=c: signal_lag(t, y, c, MAX_LAG_S), args.repeats)
        loop_repeats = max(1, args.repeats // 10)
        loop = best_cpu_s(lambda t=t, y=y, c=c: shift_loop(t, y, c, MAX_LAG_S), loop_repeats)
        print(f"lag_search_{name}_ms {1e3 * ours:.3g} ({t.size} samples, +-{MAX_LAG_S} s)")
        print(f"lag_error_{name}_us {1e6 * (lag - DELAY_S):+.3g}")
        print(f"shift_loop_{name}_ms {1e3 * loop:.3g}")
        print(f"lag_search_over_shift_loop_{name} {ours / loop:.3g}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
