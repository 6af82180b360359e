"""The alignment of Image-X Institute's IntERAct analysis, reimplemented independently of
stewart-drake from its published MATLAB (github.com/Image-X-Institute/IntERAct, ``Post
processing/IntERAct_data_analysis.m``, ``findOptimalShift``), to hold ``stewart-drake verify``'s
delay and RMS error against it (tests/test_verify_interact.py, tools/interact_verify_table.py).

Their method, as written there: for each time shift s in ``lo:0.05:hi`` s, the measured samples
whose times less s fall inside the commanded trace's span are compared with the trace linearly
interpolated at those times (``interp1``, duplicates of time dropped by ``unique``); for each
such s, every amplitude shift a in ``min(d):0.01:max(d)`` mm of the differences d is tried and
the RMSE of d - a kept at its least; the s of least RMSE is the delay, and that RMSE the error.
Here the amplitude grid is searched in closed form: the RMSE^2 is var(d) + (mean(d) - a)^2, least
at the grid point nearest mean(d), which is what their loop finds.
"""

import numpy as np


def optimal_shift(t_in, y_in, t_out, y_out, lo=0.0, hi=40.0, step=0.05, amplitude_step=0.01):
    """(delay s, amplitude shift mm, RMSE mm): IntERAct's ``findOptimalShift`` (module
    docstring) of the measured (t_out, y_out) against the commanded (t_in, y_in), mm."""
    t_in, y_in = np.asarray(t_in, float), np.asarray(y_in, float)
    t_out, y_out = np.asarray(t_out, float), np.asarray(y_out, float)
    u, first = np.unique(t_in, return_index=True)
    yu = y_in[first]
    best = (np.inf, np.nan, np.nan)
    for s in np.arange(lo, hi + 1e-9, step):
        shifted = t_out - s
        valid = (shifted >= t_in.min()) & (shifted <= t_in.max())
        if not valid.any():
            continue
        d = y_out[valid] - np.interp(shifted[valid], u, yu)
        points = int(np.floor((d.max() - d.min()) / amplitude_step + 1e-9)) + 1
        k = min(max(int(np.round((d.mean() - d.min()) / amplitude_step)), 0), points - 1)
        a = d.min() + amplitude_step * k
        rmse = float(np.sqrt(np.mean((d - a) ** 2)))
        if rmse < best[0]:
            best = (rmse, float(s), float(a))
    return best[1], best[2], best[0]


def laboratory_runs(root):
    """[(label, the commanded 6-D trace file, the camera's time file, its 6-D depth file)] of
    the 21 laboratory runs under ``root`` (IntERAct's ``Post processing/Figure 5 - Table 2``, or
    a folder holding it), each motion's three tests."""
    from pathlib import Path

    root = Path(root)
    found = list(root.rglob("Figure 5 - Table 2"))
    base = found[0] if found else root
    runs = []
    for folder in sorted(p for p in base.iterdir() if p.is_dir()):
        inputs = [p for p in folder.glob("*.txt") if "resp" not in p.name]
        if len(inputs) != 1:
            continue
        for test in sorted(folder.glob("Test *")):
            times = sorted(test.glob("time_array*.txt"))
            depths = sorted(test.glob("dist_array6D*.txt"))
            if times and depths:
                runs.append((f"{folder.name}, {test.name}", inputs[0], times[0], depths[0]))
    return runs


#: IntERAct's ``SI_index`` of the laboratory runs: the column of the 7-column trace their analysis
#: compares with the camera's depth (MATLAB's 1-based column 4: the third axis, which the phantom
#: format names AP, our Z).
TRACE_COLUMN = 3
