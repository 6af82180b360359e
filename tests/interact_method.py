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

The relative latency of their 6-DoF and 1-DoF platforms, as their ``RMSEAlignMethod.m`` gives it:
``latency = shift6D - shift1D``, each shift ``findOptimalShift`` of the camera's depth of one
platform against its commanded trace (the 6-D trace's ``SI_index`` column, the respiratory
trace's second column less its least value, ``read1Dfile``), on the camera's one clock
(:func:`relative_latency`; tests/test_verify_interact.py, tools/interact_relative_latency_table.py).
"""

from pathlib import Path

import numpy as np

#: The longest camera gap ``verify`` judges across on these runs, s: two of them hold one gap
#: of 1.34 s.
MAX_GAP_S = 1.5
#: The largest of their files read, bytes (a 300 s trace at 100 Hz is about 150 kB).
MAX_FILE_BYTES = 50e6


def read_columns(path) -> np.ndarray:
    """One of their whitespace-separated numeric files (a trace, a time or a depth file) as
    ``np.loadtxt`` reads it, its bytes read by stewart-drake's checked reader: a folder, a
    device or a file over :data:`MAX_FILE_BYTES` is refused unread."""
    import io

    from stewart_drake.base.fileio import read_checked

    raw = read_checked(path, "IntERAct data file", MAX_FILE_BYTES, "point --data at their files")
    return np.loadtxt(io.BytesIO(raw))


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


def laboratory_pairs(root):
    """[(label, the commanded 6-D trace, the commanded respiratory trace, the camera's time file,
    its 6-D depth file, its 1-D depth file)] of the 21 laboratory runs under ``root``
    (:func:`laboratory_runs`), each with the 2-column respiratory trace of its motion's folder
    and the camera's depth of the 1-DoF platform of its test."""
    from pathlib import Path

    pairs = []
    for label, trace, time_file, depth_6d in laboratory_runs(root):
        (resp,) = [p for p in Path(trace).parent.glob("*.txt") if "resp" in p.name]
        (depth_1d,) = sorted(Path(time_file).parent.glob("dist_array1D*.txt"))
        pairs.append((label, trace, resp, time_file, depth_6d, depth_1d))
    return pairs


def relative_latency(trace, resp, time_file, depth_6d, depth_1d, step=0.05):
    """(latency, shift6D, shift1D) s: ``RMSEAlignMethod.m``'s relative latency of the 6-DoF
    platform against the 1-DoF one (module docstring), each shift searched over 0-40 s by
    ``step`` (``IntERAct_data_analysis.m``'s 0.05 s; ``RMSEAlignMethod.m`` steps 0.01 s)."""
    data, r = read_columns(trace), read_columns(resp)
    t = read_columns(time_file)
    s6, _, _ = optimal_shift(
        data[:, 0], data[:, TRACE_COLUMN], t, read_columns(depth_6d), step=step
    )
    s1, _, _ = optimal_shift(r[:, 0], r[:, 1] - r[:, 1].min(), t, read_columns(depth_1d), step=step)
    return s6 - s1, s6, s1


def camera_file(path, time_file, depth_file):
    """``path``: the camera's time file and one depth file joined into ``t [s],depth [mm]``, as
    ``stewart-drake verify`` reads a single-axis sensor's file."""
    t, depth = read_columns(time_file), read_columns(depth_file)
    rows = ["t [s],depth [mm]"] + [f"{float(a)!r},{float(b)!r}" for a, b in zip(t, depth)]
    path.write_text("\n".join(rows) + "\n")
    return path


def write_table(docs, markers, header, rows, summary: str) -> None:
    """Print ``summary`` and write the table (``header``, ``rows``) and it between ``markers``
    in the page ``docs``."""
    from stewart_drake.base.fileio import write_between_markers
    from stewart_drake.base.tables import markdown_lines

    print(summary)
    block = "\n".join([markers[0], "", *markdown_lines(header, rows), "", summary, "", markers[1]])
    print(f"wrote {write_between_markers(Path(docs), markers, block)}")
