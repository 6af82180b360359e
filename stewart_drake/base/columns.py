"""Columns of numbers: :func:`interp_columns` resamples the columns of a log at other times."""

import numpy as np


def interp_columns(t_new, t, Y, period: float | None = None, out=None) -> np.ndarray:
    """Each column of Y, known at the times t, linearly interpolated at t_new: numpy's
    ``np.interp`` column by column, so held at the ends (or wrapped, with ``period``).

    Args:
        t_new: (m,) where the values are wanted.  t: (n,) increasing, where Y is known (any
            order with ``period``).  Y: (n, k) the values, a column per signal.
        period: the period of t (e.g. 1.0 for a phase in [0, 1)); None: not periodic.
        out: (m, k) filled column by column and returned (cast to its dtype; one (m,) float64
            column at a time in memory); None: a new float64 array.
    Returns:
        (m, k) the values at t_new.
    Raises:
        ValueError: Y not 2-D with a row per time, or ``out`` not (m, k) (np.interp's own
            refusals otherwise).
    """
    Y = np.asarray(Y)
    if Y.ndim != 2 or Y.shape[0] != len(t):
        raise ValueError(f"Y of shape {Y.shape}: expected ({len(t)}, k), a row per time")
    shape = (len(t_new), Y.shape[1])
    if out is None:
        out = np.empty(shape)
    elif out.shape != shape:
        raise ValueError(f"out of shape {out.shape}: expected {shape}")
    for c in range(Y.shape[1]):
        out[:, c] = np.interp(t_new, t, Y[:, c], period=period)
    return out
