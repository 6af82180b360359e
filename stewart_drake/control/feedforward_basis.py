"""The basis of the feed-forward learner (:mod:`~.feedforward_tuning`) and its learned model as
a file: the basis functions phi of the reference, and the weights a run learned on them, saved
with the basis they belong to so that a model of another basis is refused on reading.
"""

from pathlib import Path

import numpy as np

from ..base.errors import CorruptFileError
from ..robot import kinematics

#: Lags of the motors' rate signs in the basis, s (positive: the past; negative: the future,
#: which the feed-forward knows): the friction transient after a reversal lasts ~0.1 s.
LAGS_S = (-0.02, 0.0, 0.005, 0.01, 0.02, 0.04, 0.08, 0.16)
#: Version of the learned-model file (:func:`save_learned`).
LEARNED_FORMAT = 1
_KIND = "learned feed-forward model (.npz)"
#: The model learned on the shipped library (``python tools/feedforward_library_model.py``):
#: a run may start from it instead of from zero (``learned_from``).
LIBRARY_MODEL = Path(__file__).resolve().parents[1] / "data" / "feedforward_library.npz"
#: Largest learned-model file, bytes, on disk and after decompression: the weights are
#: p x 6 float64 (a few kB), so anything near this bound is not one.
MAX_LEARNED_BYTES = 1e6


def basis_size(lags=LAGS_S) -> int:
    """p: the number of basis functions (module docstring)."""
    return 19 + 6 * len(lags)


def reference_basis(
    geometry, pose, rate, acceleration, h: float, rate_scale: float, lags=LAGS_S
) -> np.ndarray:
    """The basis functions phi of the module docstring on an even grid of step ``h``, (n, p).

    Args:
        geometry: the robot (for the motors' rates J(x_d) x_d_dot).
        pose, rate, acceleration: (n, 6) the reference on the grid, rad, m and their rates.
        h: the grid's step, s. rate_scale: omega_0, rad/s (the width of the smooth sign).
        lags: the signs' lags, s (rounded to the grid).
    Returns:
        (n, p); the lagged signs hold their first (last) value beyond the grid's ends, so the
        grid should extend max(lags) before and -min(lags) after the times used.
    """
    pose = np.asarray(pose, dtype=float)
    rate = np.asarray(rate, dtype=float)
    acceleration = np.asarray(acceleration, dtype=float)
    n = len(pose)
    jerk = np.gradient(acceleration, h, axis=0) if n > 1 else np.zeros_like(acceleration)
    J = kinematics.jacobian_unchecked(geometry, pose)
    omega = np.nan_to_num(np.einsum("nij,nj->ni", J, rate), nan=0.0, posinf=0.0, neginf=0.0)
    sign = np.tanh(omega / rate_scale)
    parts = [np.ones((n, 1)), rate, acceleration, jerk]
    for lag in lags:
        m = int(round(lag / h))
        z = np.empty_like(sign)
        if m > 0:
            z[m:], z[:m] = sign[:-m], sign[0]
        elif m < 0:
            z[:m], z[m:] = sign[-m:], sign[-1]
        else:
            z[:] = sign
        parts.append(z)
    return np.concatenate(parts, axis=1)


# -- the learned model as a file ------------------------------------------------------------


def save_learned(path, theta, geometry_name: str = "") -> Path:
    """Write learned weights (p, 6) to an .npz (numbers only) that :func:`load_learned` reads,
    with the basis it belongs to (the lags, its size and the file format)."""
    from ..base.fileio import atomic_write

    theta = np.asarray(theta, dtype=float).reshape(basis_size(), 6)
    path = Path(path)

    def write(f):
        np.savez(
            f,
            format=np.int64(LEARNED_FORMAT),
            theta=theta,
            lags_s=np.asarray(LAGS_S),
            geometry=np.asarray(geometry_name),
        )

    atomic_write(path, write)
    return path


def load_learned(path) -> np.ndarray:
    """The (p, 6) weights of a file :func:`save_learned` wrote, read through
    :class:`~stewart_drake.base.npz.CheckedNpz` (a regular file of at most
    :data:`MAX_LEARNED_BYTES`, each entry's header checked before it is loaded, no pickles).

    Returns:
        (p, 6) float64 weights theta, p = :func:`basis_size`.
    Raises:
        CorruptFileError: naming the file: not a readable ``.npz`` (a FIFO, too large, an
            entry whose header claims more than it holds); ``format`` not one integer;
            ``theta`` or ``lags_s`` not real numbers (text, complex); a model of another basis;
            weights not all finite.
        OSError: the file cannot be read (missing, permissions).
    """
    from ..base.npz import CheckedNpz

    path = Path(path)
    data = CheckedNpz(path, _KIND, "write it with --save-learned", MAX_LEARNED_BYTES)
    fmt = data.integer("format")
    theta, lags = data.array("theta"), data.array("lags_s")
    same_basis = lags.shape == (len(LAGS_S),) and np.allclose(lags, LAGS_S)
    if fmt != LEARNED_FORMAT or not same_basis or theta.shape != (basis_size(), 6):
        raise CorruptFileError(
            path,
            _KIND,
            f"a model of another basis (format {fmt}, weights {theta.shape})",
            "learn it again with this version",
        )
    if not np.all(np.isfinite(theta)):
        raise CorruptFileError(path, _KIND, "the weights are not all finite")
    return theta
