"""The tuners' networks as numpy arrays, their checks, and the one file format they share.

Both tuners are one-hidden-layer networks on normalized inputs, z = (x - x_mean) / x_std with
the statistics of their training split: the paper's (:class:`~.ann.TunerModel`, 12 density
features -> log10 [omega_Q, omega_R]) and ours (:class:`~.ratio.RatioTunerModel`, 16 inputs ->
log10 omega_Q / omega_R). Training uses torch (:mod:`stewart_drake.tuner.training`, the tuner
study); inference does not: the models hold numpy arrays, so ``run --tuner ann`` never imports
torch.

File format (``.npz``, loadable with ``np.load(path, allow_pickle=False)``), one for both, written
by :func:`save_tuner` and read by :func:`load_tuner`:
    W1 (hidden, n_in), b1 (hidden,),   float64, torch ``nn.Linear`` layout (the paper's: 10 x 12,
    W2 (n_out, hidden), b2 (n_out,)    2 x 10; ours: 1 output)
    x_mean (n_in,), x_std (n_in,)      float64, input normalization
    log10_min, log10_max               float64 scalars, the clamp of the output's log10: (-1, 1)
                                       for the paper's, (-3, 3) for ours
    activation                         str scalar, "tanh" or "sigmoid" (ours: "tanh")
    format_version                     int scalar, 1
    metadata_json                      str scalar, JSON (label mode, seed, R^2, the data the
                                       weights came from ...)
The kind of network a file holds is told by its sizes and its clamp: a reader asks for one kind
and refuses the other, naming what it found.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any, ClassVar, TypeVar

import numpy as np

from ...base.errors import InvalidConfigError, MissingFileError
from ...base.fileio import atomic_write
from ...base.npz import CheckedNpz

FORMAT_VERSION = 1
#: |normalized input| cap, in training standard deviations.
Z_CLIP = 1e3
#: Largest tuner weights file, after decompression, bytes (the networks hold a few kB).
MAX_WEIGHTS_BYTES = 16e6
#: Where the shipped weights live: ``stewart_drake/data``.
DATA_FOLDER = Path(__file__).resolve().parents[2] / "data"
ACTIVATIONS = ("tanh", "sigmoid")
#: The network's arrays, in the order the file holds them.
WEIGHT_NAMES = ("W1", "b1", "W2", "b2", "x_mean", "x_std")


def check_network(
    model, kind: str, n_in: int, n_out: int, non_finite: str = "", shape: str = "", x_std: str = ""
) -> None:
    """Make a frozen one-hidden-layer model's weights read-only float64 arrays and check them:
    finite, W1 (hidden, n_in), b1 (hidden,), W2 (n_out, hidden), b2 (n_out,), x_mean and x_std
    (n_in,), x_std > 0. ``kind`` names the model in the errors, the other strings end them.

    Raises:
        InvalidConfigError: the first fault found.
    """
    for name in WEIGHT_NAMES:
        value = np.array(getattr(model, name), dtype=np.float64)
        value.setflags(write=False)
        object.__setattr__(model, name, value)
        if not np.all(np.isfinite(value)):
            raise InvalidConfigError(f"{kind} weight {name} has non-finite entries{non_finite}")
    hidden = model.W1.shape[0] if model.W1.ndim == 2 else -1
    expected = {
        "W1": (hidden, n_in),
        "b1": (hidden,),
        "W2": (n_out, hidden),
        "b2": (n_out,),
        "x_mean": (n_in,),
        "x_std": (n_in,),
    }
    for name, want in expected.items():
        if hidden < 1 or getattr(model, name).shape != want:
            raise InvalidConfigError(
                f"{kind} weight {name} has shape "
                f"{getattr(model, name).shape}, expected {want}{shape}"
            )
    if not np.all(model.x_std > 0):
        raise InvalidConfigError(f"{kind} x_std must be > 0{x_std}")


def check_schedule(period_s: float, offset_s: float, omega_initial) -> np.ndarray:
    """A tuner system's update period (> 0 s) and first update (>= 0 s) checked, and the
    weights [omega_Q, omega_R] it holds before that update, (2,), returned.

    Raises:
        InvalidConfigError: period_s <= 0, offset_s < 0, a non-finite one, or omega_initial not
            2 finite numbers.
    """
    if not (np.isfinite(period_s) and period_s > 0):
        raise InvalidConfigError(f"period_s must be > 0 s, got {period_s}")
    if not (np.isfinite(offset_s) and offset_s >= 0):
        raise InvalidConfigError(f"offset_s must be >= 0 s, got {offset_s}")
    omega0 = np.asarray(omega_initial, dtype=float)
    if omega0.shape != (2,) or not np.all(np.isfinite(omega0)):
        raise InvalidConfigError(f"omega_initial must be 2 finite numbers, got {omega_initial}")
    return omega0


@dataclass(frozen=True)
class TunerNetwork:
    """A tuner's one-hidden-layer network: its weights (the fields of :data:`WEIGHT_NAMES`),
    and what its class tells its file's writer and reader. A subclass adds ``activation`` and
    ``metadata`` and checks them all (:func:`check_network`).

    Attributes:
        W1 (hidden, n_in), b1 (hidden,), W2 (n_out, hidden), b2 (n_out,): the layers.
        x_mean, x_std: (n_in,) the inputs' normalization (training statistics).
    """

    W1: np.ndarray
    b1: np.ndarray
    W2: np.ndarray
    b2: np.ndarray
    x_mean: np.ndarray
    x_std: np.ndarray

    #: How messages name it ("ANN tuner": "no ANN tuner weights at ...").
    label: ClassVar[str]
    #: The clamp of its output's log10, as its files record it.
    log10_range: ClassVar[tuple[float, float]]
    #: What to do about a damaged file, ending the message.
    remedy: ClassVar[str]
    #: How to get the shipped weights when they are missing, and another file.
    missing_default: ClassVar[str]
    missing_given: ClassVar[str]

    @classmethod
    def default_path(cls) -> Path:
        """The shipped weights a reader loads when it is given no path."""
        raise NotImplementedError

    @classmethod
    def file_kind(cls) -> str:
        """What the file is called in messages: "ANN tuner weights file"."""
        return f"{cls.label} weights file"


Network = TypeVar("Network", bound=TunerNetwork)


def save_tuner(model, path) -> Path:
    """Write a tuner's network (either kind: a :class:`TunerNetwork` with its ``activation`` and
    ``metadata``) to a ``.npz`` (the module docstring's format); returns the path.

    Written atomically (a temporary file, then a rename): an interrupted save leaves the old file.

    Raises:
        TypeError: metadata that JSON cannot encode.
    """
    path = Path(path)
    lo, hi = model.log10_range
    arrays: dict[str, Any] = {name: getattr(model, name) for name in WEIGHT_NAMES}
    arrays.update(
        log10_min=np.float64(lo),
        log10_max=np.float64(hi),
        activation=np.str_(model.activation),
        format_version=np.int64(FORMAT_VERSION),
        metadata_json=np.str_(json.dumps(model.metadata, sort_keys=True)),
    )
    atomic_write(path, lambda f: np.savez(f, **arrays))  # a file object: no ".npz" appended
    return path


def load_tuner(kind: type[Network], path=None) -> Network:
    """Load a network of class ``kind`` (:class:`~.ann.TunerModel` or
    :class:`~.ratio.RatioTunerModel`) that :func:`save_tuner` wrote; no torch needed.

    Args:
        kind: the network's class. path: the ``.npz``; None loads the shipped weights
            (``kind.default_path()``).
    Returns:
        the network.
    Raises:
        MissingFileError (a FileNotFoundError): no such file; for the shipped weights it names
            the command that makes them.
        CorruptFileError: the file is not a valid weights file of that kind: truncated, random
            bytes, empty, an entry missing or of the wrong type (an object array), another
            format version, the other kind's clamp, metadata that is not JSON, a failed CRC, or
            weights of the wrong shape or not finite; the message names the file and the fault.
    """
    default = path is None
    path = kind.default_path() if default else Path(path)
    if not path.exists():
        how = kind.missing_default if default else kind.missing_given
        raise MissingFileError(f"no {kind.label} weights at {path}: {how}")
    data = CheckedNpz(path, kind.file_kind(), kind.remedy, max_bytes=MAX_WEIGHTS_BYTES)
    version = data.integer("format_version")
    if version != FORMAT_VERSION:
        raise data.corrupt(f"tuner format {version}, this stewart-drake reads {FORMAT_VERSION}")
    clamp = (data.number("log10_min"), data.number("log10_max"))
    if clamp != kind.log10_range:
        raise data.corrupt(
            f"it clamps log10 of its output to {clamp}, expected {kind.log10_range} (the other "
            f"tuner's weights? the paper's go in an AnnTunerDriver, ours in a RatioTunerDriver)"
        )
    weights = {name: data.array(name) for name in WEIGHT_NAMES}
    activation, metadata = data.text("activation"), data.json("metadata_json")
    make: Any = kind  # the subclasses add activation and metadata (TunerNetwork's docstring)
    try:
        return make(**weights, activation=activation, metadata=metadata)
    except InvalidConfigError as err:
        raise data.corrupt(str(err)) from None
