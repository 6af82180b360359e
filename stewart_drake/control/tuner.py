"""ANN tuner of the LQI weights: density features rho (12,) -> [omega_Q, omega_R] (paper III.D).

The network is the paper's: one hidden layer of 10 neurons (tanh), 12 inputs, 2 outputs. The
outputs are y = log10 omega, so the weights stay positive, and y is clamped to [-1, 1], i.e.
omega_Q, omega_R in [0.1, 10] (the range of the 9 training runs, {0.1, 1, 10}^2). Inputs are
normalized, z = (rho - x_mean) / x_std, with the statistics of the training split, stored with
the weights.

Training uses torch (:mod:`stewart_drake.tuner.training`); inference does not: :class:`TunerModel`
holds numpy arrays and :class:`AnnTuner` evaluates them, so ``run --tuner ann`` never imports
torch. torch is imported lazily, only by :func:`build_mlp`, :meth:`TunerModel.from_torch` and
:meth:`TunerModel.to_torch`.

File format (``.npz``, loadable with ``np.load(path, allow_pickle=False)``):
    W1 (10, 12), b1 (10,), W2 (2, 10), b2 (2,)   float64, torch ``nn.Linear`` layout
    x_mean (12,), x_std (12,)                    float64, input normalization
    log10_min, log10_max                         float64 scalars, output clamp (-1, 1)
    activation                                   str scalar, "tanh" or "sigmoid"
    format_version                               int scalar, 1
    metadata_json                                str scalar, JSON (label mode, seed, R^2, ...)
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from pydrake.systems.framework import LeafSystem

from ..base.checks import as_array
from ..base.errors import InvalidConfigError, MissingFileError
from ..base.fileio import CheckedNpz, atomic_write
from .features import N_FEATURES

FORMAT_VERSION = 1
#: The paper's ANN outputs log10 omega_Q and log10 omega_R clipped to this range (the paper's
#: nine training pairs span it), so its weights stay within [ANN_OMEGA_MIN, ANN_OMEGA_MAX].
ANN_LOG10_MIN, ANN_LOG10_MAX = -1.0, 1.0
ANN_OMEGA_MIN, ANN_OMEGA_MAX = 10.0**ANN_LOG10_MIN, 10.0**ANN_LOG10_MAX
Z_CLIP = 1e3  # |normalized input| cap, in training stds
DEFAULT_TUNER_PATH = Path(__file__).resolve().parents[1] / "data" / "ann_tuner.npz"
#: Largest tuner weights file, after decompression, bytes (the networks hold a few kB).
MAX_WEIGHTS_BYTES = 16e6
#: The same network trained on the paper's labels (each sample labelled with its run's weights),
#: shipped for the evaluation's comparison of the two label modes.
PAPER_LABEL_TUNER_PATH = DEFAULT_TUNER_PATH.with_name("ann_tuner_paper.npz")
ACTIVATIONS = ("tanh", "sigmoid")


def _freeze_and_check_mlp(
    model, kind: str, n_in: int, n_out: int, non_finite: str = "", shape: str = "", x_std: str = ""
) -> None:
    """Make a frozen one-hidden-layer model's weights read-only float64 arrays and check them:
    finite, W1 (hidden, n_in), b1 (hidden,), W2 (n_out, hidden), b2 (n_out,), x_mean and x_std
    (n_in,), x_std > 0. ``kind`` names the model in the errors, the other strings end them.

    Raises:
        InvalidConfigError: the first fault found.
    """
    for name in ("W1", "b1", "W2", "b2", "x_mean", "x_std"):
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


def _activation(name: str, h: np.ndarray) -> np.ndarray:
    if name == "tanh":
        return np.tanh(h)
    return 0.5 * (1.0 + np.tanh(0.5 * h))  # sigmoid without overflow in exp


@dataclass(frozen=True)
class TunerModel:
    """Trained tuner network as numpy arrays: rho (12,) -> [omega_Q, omega_R].

    Attributes:
        W1: (hidden, 12), b1: (hidden,), W2: (2, hidden), b2: (2,): layer weights (float64).
        x_mean, x_std: (12,) normalization of rho (training split statistics), x_std > 0.
        activation: "tanh" or "sigmoid" (hidden layer).
        metadata: JSON-serializable dict (label mode, seed, validation R^2, feature settings).
    Raises:
        InvalidConfigError: inconsistent shapes, non-finite numbers, x_std <= 0 or an unknown
            activation.
    Source: paper section III.D (one hidden layer of 10); log10 outputs and the clamp are ours.
    """

    W1: np.ndarray
    b1: np.ndarray
    W2: np.ndarray
    b2: np.ndarray
    x_mean: np.ndarray
    x_std: np.ndarray
    activation: str = "tanh"
    metadata: dict = field(default_factory=dict)

    def __post_init__(self):
        _freeze_and_check_mlp(
            self,
            "tuner",
            N_FEATURES,
            2,
            non_finite="; retrain",
            shape=" (12 features -> hidden -> [omega_Q, omega_R])",
            x_std=" (normalization of rho)",
        )
        if self.activation not in ACTIVATIONS:
            raise InvalidConfigError(
                f"activation must be one of {ACTIVATIONS}, got {self.activation!r}"
            )

    @property
    def hidden(self) -> int:
        """Neurons in the hidden layer (10 in the paper)."""
        return self.W1.shape[0]

    def predict_log10(self, rho) -> np.ndarray:
        """log10 [omega_Q, omega_R] for features rho, clamped to [-1, 1].

        Args:
            rho: (..., 12) finite density features [rho_e, rho_T], dimensionless.
        Returns:
            (..., 2) log10 of [omega_Q, omega_R] in [-1, 1]; finite for every finite rho
            (normalized inputs are capped at +-1000 training standard deviations).
        Raises:
            InvalidConfigError (a ValueError): rho not (..., 12) or not finite, or weights so
                large that the network's sums overflow (inf - inf).
        """
        rho = as_array("rho (the tuner needs finite features)", rho, last=N_FEATURES)
        with np.errstate(over="ignore", invalid="ignore"):
            z = np.clip((rho - self.x_mean) / self.x_std, -Z_CLIP, Z_CLIP)
            h = _activation(self.activation, z @ self.W1.T + self.b1)
            y = np.clip(h @ self.W2.T + self.b2, ANN_LOG10_MIN, ANN_LOG10_MAX)
        if not np.isfinite(y).all():
            raise InvalidConfigError(
                "the tuner's output is NaN: its weights overflow float64 "
                "sums; retrain with `stewart-drake train`"
            )
        return y

    def predict(self, rho) -> np.ndarray:
        """[omega_Q, omega_R] for features rho.

        Args:
            rho: (..., 12) finite density features, dimensionless.
        Returns:
            (..., 2) [omega_Q, omega_R], dimensionless LQI weights in [0.1, 10] (eq. 27).
        Raises:
            InvalidConfigError: see :meth:`predict_log10`.
        """
        return np.clip(10.0 ** self.predict_log10(rho), ANN_OMEGA_MIN, ANN_OMEGA_MAX)

    # -- torch ---------------------------------------------------------------------------------
    @classmethod
    def from_torch(cls, mlp, x_mean, x_std, metadata: dict | None = None) -> TunerModel:
        """Numpy copy of a :func:`build_mlp` network and its input normalization."""
        import torch

        linears = [m for m in mlp if isinstance(m, torch.nn.Linear)]
        act = "tanh" if any(isinstance(m, torch.nn.Tanh) for m in mlp) else "sigmoid"
        with torch.no_grad():
            W1, b1, W2, b2 = (
                p.detach().cpu().double().numpy().copy()
                for lin in linears
                for p in (lin.weight, lin.bias)
            )
        return cls(W1, b1, W2, b2, x_mean, x_std, act, dict(metadata or {}))

    def to_torch(self):
        """A :func:`build_mlp` network (float64) with these weights; input must be normalized."""
        import torch

        mlp = build_mlp(self.hidden, self.activation)
        with torch.no_grad():
            mlp[0].weight.copy_(torch.tensor(self.W1))
            mlp[0].bias.copy_(torch.tensor(self.b1))
            mlp[2].weight.copy_(torch.tensor(self.W2))
            mlp[2].bias.copy_(torch.tensor(self.b2))
        return mlp


def build_mlp(hidden: int = 10, activation: str = "tanh"):
    """The paper's network as ``torch.nn.Sequential(Linear(12, hidden), act, Linear(hidden, 2))``.

    Args:
        hidden: neurons in the hidden layer (10 in the paper).
        activation: "tanh" or "sigmoid".
    Returns:
        float64 torch module mapping normalized rho (B, 12) to unclamped log10 omega (B, 2).
    Raises:
        InvalidConfigError: hidden < 1 or an unknown activation.
    Source: paper section III.D.
    """
    import torch

    if activation not in ACTIVATIONS:
        raise InvalidConfigError(f"activation must be one of {ACTIVATIONS}, got {activation!r}")
    if not (isinstance(hidden, int) and hidden >= 1):
        raise InvalidConfigError(f"hidden must be an integer >= 1, got {hidden!r}")
    act = torch.nn.Tanh() if activation == "tanh" else torch.nn.Sigmoid()
    return torch.nn.Sequential(
        torch.nn.Linear(N_FEATURES, hidden), act, torch.nn.Linear(hidden, 2)
    ).double()


def save_tuner(model: TunerModel, path) -> Path:
    """Write ``model`` to a ``.npz`` (format in the module docstring); returns the path.

    Written atomically (a temporary file, then a rename): an interrupted save leaves the old file.

    Raises:
        TypeError: metadata that JSON cannot encode.
    """
    path = Path(path)
    arrays: dict[str, Any] = dict(
        W1=model.W1,
        b1=model.b1,
        W2=model.W2,
        b2=model.b2,
        x_mean=model.x_mean,
        x_std=model.x_std,
        log10_min=np.float64(ANN_LOG10_MIN),
        log10_max=np.float64(ANN_LOG10_MAX),
        activation=np.str_(model.activation),
        format_version=np.int64(FORMAT_VERSION),
        metadata_json=np.str_(json.dumps(model.metadata, sort_keys=True)),
    )
    atomic_write(path, lambda f: np.savez(f, **arrays))  # a file object: no ".npz" appended
    return path


def load_tuner(path=None) -> TunerModel:
    """Load a tuner written by :func:`save_tuner`; no torch needed.

    Args:
        path: the ``.npz``; None loads the shipped weights ``stewart_drake/data/ann_tuner.npz``.
    Returns:
        the :class:`TunerModel`.
    Raises:
        MissingFileError (a FileNotFoundError): no such file; for the shipped weights it names
            the command that makes them (``stewart-drake collect && stewart-drake train``).
        CorruptFileError: the file is not a valid tuner file: truncated, random bytes, empty, an
            entry missing or of the wrong type (an object array), another format version or
            clamp range, metadata that is not JSON, a failed CRC, or weights of the wrong shape
            or not finite; the message names the file and the fault.
    """
    default = path is None
    path = DEFAULT_TUNER_PATH if default else Path(path)
    if not path.exists():
        how = (
            "run `stewart-drake collect && stewart-drake train` to collect the 9 closed-loop "
            "runs and train it"
            if default
            else "check the path, or pass none for the shipped weights"
        )
        raise MissingFileError(f"no ANN tuner weights at {path}: {how}")
    data = CheckedNpz(
        path,
        "ANN tuner weights file",
        "retrain with `stewart-drake train` or use the shipped weights",
        max_bytes=MAX_WEIGHTS_BYTES,
    )
    version = data.integer("format_version")
    if version != FORMAT_VERSION:
        raise data.corrupt(f"tuner format {version}, this stewart-drake reads {FORMAT_VERSION}")
    clamp = (data.number("log10_min"), data.number("log10_max"))
    if clamp != (ANN_LOG10_MIN, ANN_LOG10_MAX):
        raise data.corrupt(
            f"it clamps log10 omega to {clamp}, expected {(ANN_LOG10_MIN, ANN_LOG10_MAX)}"
        )
    W1, b1, W2, b2, x_mean, x_std = (
        data.array(name) for name in ("W1", "b1", "W2", "b2", "x_mean", "x_std")
    )
    activation, metadata = data.text("activation"), data.json("metadata_json")
    try:
        return TunerModel(W1, b1, W2, b2, x_mean, x_std, activation, metadata)
    except InvalidConfigError as err:
        raise data.corrupt(str(err)) from None


class AnnTuner(LeafSystem):
    """Online tuner of the LQI weights: density features -> [omega_Q, omega_R] (paper Fig. 5).

    Input port:
        ``rho`` (12,): density features [rho_e, rho_T] (:class:`~.features.DensityFeatures`).
    Output ports:
        ``omega`` (2,): [omega_Q, omega_R] in [0.1, 10], held between updates (connect it to the
            LQI's ``omega`` input).
        ``nonfinite_count`` (1,): updates skipped because rho was not finite.
    Discrete state (numbers only): omega (2,), nonfinite_count (1,).

    Every period_s (first at offset_s) the network is evaluated in numpy on the sampled rho. A
    non-finite rho keeps the last omega and increments ``nonfinite_count``; the output is never
    NaN and never leaves [0.1, 10].

    Args:
        model: the network (:func:`load_tuner`); None loads the shipped weights.
        period_s: update period, s (20 ms).
        offset_s: time of the first update, s (0).
        omega_initial: [omega_Q, omega_R] before the first update (clamped to [0.1, 10]).
    Raises:
        InvalidConfigError: period_s <= 0, offset_s < 0 or a non-finite omega_initial.
        FileNotFoundError: model is None and the shipped weights are missing.
    Source: paper section III.D; the clamp and the non-finite guard are ours.
    """

    def __init__(
        self,
        model: TunerModel | None = None,
        period_s: float = 0.02,
        offset_s: float = 0.0,
        omega_initial=(1.0, 1.0),
    ):
        super().__init__()
        if not (np.isfinite(period_s) and period_s > 0):
            raise InvalidConfigError(f"period_s must be > 0 s, got {period_s}")
        if not (np.isfinite(offset_s) and offset_s >= 0):
            raise InvalidConfigError(f"offset_s must be >= 0 s, got {offset_s}")
        omega0 = np.asarray(omega_initial, dtype=float)
        if omega0.shape != (2,) or not np.all(np.isfinite(omega0)):
            raise InvalidConfigError(f"omega_initial must be 2 finite numbers, got {omega_initial}")
        self.model = load_tuner() if model is None else model
        self.period_s = float(period_s)
        self._rho = self.DeclareVectorInputPort("rho", N_FEATURES)
        self._omega_index = self.DeclareDiscreteState(np.clip(omega0, ANN_OMEGA_MIN, ANN_OMEGA_MAX))
        self._count_index = self.DeclareDiscreteState(1)
        self._omega = self.DeclareStateOutputPort("omega", self._omega_index)
        self._count = self.DeclareStateOutputPort("nonfinite_count", self._count_index)
        self.DeclarePeriodicDiscreteUpdateEvent(
            period_sec=self.period_s, offset_sec=offset_s, update=self._Update
        )

    def get_rho_input_port(self):
        return self._rho

    def get_omega_output_port(self):
        return self._omega

    def get_nonfinite_count_output_port(self):
        return self._count

    def _Update(self, context, discrete_state):
        rho = self._rho.Eval(context)
        try:
            discrete_state.set_value(self._omega_index, self.model.predict(rho))
        except InvalidConfigError:  # rho (or the output) not finite
            count = context.get_discrete_state(self._count_index).get_value()[0]
            discrete_state.set_value(self._count_index, [count + 1.0])


# -- ours: one ratio from density features and the reference's motion ------------------------------

#: Inputs of :class:`RatioTunerModel`, in order: the 12 density features, then the reference's
#: speed and acceleration, rotation and translation apart, each over its scale.
RATIO_INPUTS = tuple(f"rho_{k}" for k in range(N_FEATURES)) + (
    "|rpy_dot_d| / 1 rad/s",
    "|p_dot_d| / 0.1 m/s",
    "|rpy_ddot_d| / 10 rad/s^2",
    "|p_ddot_d| / 1 m/s^2",
)
N_RATIO_INPUTS = len(RATIO_INPUTS)
RATIO_LOG10_MIN, RATIO_LOG10_MAX = -3.0, 3.0  # omega_Q / omega_R in [1e-3, 1e3]
RATIO_FORMAT = "ratio_tuner_v1"
#: The lambdas of the tuner study's cost (J = tracking + lambda effort) whose tuners ship.
RATIO_TUNER_LAMBDAS = (0.01, 0.1, 1.0)


def ratio_tuner_path(lam: float) -> Path:
    """The shipped weights of our tuner trained for the cost at ``lam``:
    ``stewart_drake/data/ratio_tuner_lambda<lam>.npz`` (its metadata name the data it came
    from)."""
    return DEFAULT_TUNER_PATH.with_name(f"ratio_tuner_lambda{lam:g}.npz")


#: What ``run --tuner ratio`` and an empty ``RatioTunerDriver.weights`` load: the balanced cost.
DEFAULT_RATIO_TUNER_PATH = ratio_tuner_path(0.1)
_MOTION_SCALES = np.array([1.0, 0.1, 10.0, 1.0])


def ratio_tuner_inputs(rho, x_d) -> np.ndarray:
    """The inputs of :class:`RatioTunerModel`: rho (..., 12) and the reference's motion.

    Args:
        rho: (..., 12) density features.  x_d: (..., 18) reference [pose, rate, acceleration].
    Returns:
        (..., 16) [rho, |rpy_dot_d|, |p_dot_d|, |rpy_ddot_d|, |p_ddot_d|] over 1 rad/s, 0.1 m/s,
        10 rad/s^2, 1 m/s^2.
    """
    rho, x_d = np.asarray(rho, dtype=float), np.asarray(x_d, dtype=float)
    motion = (
        np.stack(
            [
                np.linalg.norm(x_d[..., 6:9], axis=-1),
                np.linalg.norm(x_d[..., 9:12], axis=-1),
                np.linalg.norm(x_d[..., 12:15], axis=-1),
                np.linalg.norm(x_d[..., 15:18], axis=-1),
            ],
            axis=-1,
        )
        / _MOTION_SCALES
    )
    return np.concatenate([rho, motion], axis=-1)


@dataclass(frozen=True)
class RatioTunerModel:
    """Our tuner's network: 16 inputs (:data:`RATIO_INPUTS`) -> hidden (tanh) -> log10 of the
    ratio omega_Q / omega_R, clamped to [-3, 3] (the study's grid, wider than the paper's).

    Only the ratio decides the LQI's gain (docs/paper_notes.md), so one output; the paper's
    network outputs both weights. The reference's speed and acceleration are inputs the paper
    leaves out: whether the platform moves or holds is what the best ratio depends on most.

    Attributes:
        W1 (hidden, 16), b1 (hidden,), W2 (1, hidden), b2 (1,): weights.
        x_mean, x_std: (16,) input normalization (training statistics), x_std > 0.
        metadata: JSON-able (lambda, training tasks, loss...).
    Raises:
        InvalidConfigError: inconsistent shapes, non-finite numbers or x_std <= 0.
    """

    W1: np.ndarray
    b1: np.ndarray
    W2: np.ndarray
    b2: np.ndarray
    x_mean: np.ndarray
    x_std: np.ndarray
    metadata: dict = field(default_factory=dict)

    def __post_init__(self):
        _freeze_and_check_mlp(self, "ratio tuner", N_RATIO_INPUTS, 1)

    def predict_log10(self, inputs) -> np.ndarray:
        """(...,) log10 omega_Q / omega_R in [-3, 3] for inputs (..., 16) (finite).

        Raises:
            InvalidConfigError: inputs not (..., 16) or not finite.
        """
        inputs = as_array("ratio tuner inputs (must be finite)", inputs, last=N_RATIO_INPUTS)
        z = np.clip((inputs - self.x_mean) / self.x_std, -Z_CLIP, Z_CLIP)
        y = np.tanh(z @ self.W1.T + self.b1) @ self.W2.T + self.b2
        return np.clip(y[..., 0], RATIO_LOG10_MIN, RATIO_LOG10_MAX)

    def predict(self, inputs) -> np.ndarray:
        """(..., 2) [omega_Q, omega_R] = [ratio, 1] for inputs (..., 16)."""
        ratio = 10.0 ** self.predict_log10(inputs)
        return np.stack([ratio, np.ones_like(ratio)], axis=-1)


def save_ratio_tuner(model: RatioTunerModel, path) -> Path:
    """Write ``model`` to a ``.npz`` (atomically); returns the path."""
    path = Path(path)
    arrays: dict[str, Any] = dict(
        W1=model.W1,
        b1=model.b1,
        W2=model.W2,
        b2=model.b2,
        x_mean=model.x_mean,
        x_std=model.x_std,
        format=np.str_(RATIO_FORMAT),
        inputs=np.array(RATIO_INPUTS),
        metadata_json=np.str_(json.dumps(model.metadata, sort_keys=True)),
    )
    atomic_write(path, lambda f: np.savez(f, **arrays))
    return path


def load_ratio_tuner(path=None) -> RatioTunerModel:
    """Load a :func:`save_ratio_tuner` file; no torch needed.

    Args:
        path: the ``.npz``; None loads the shipped weights for lambda = 0.1
            (:data:`DEFAULT_RATIO_TUNER_PATH`).
    Raises:
        MissingFileError: no such file.
        CorruptFileError: not a valid ratio tuner file (another format, an entry missing or of
            the wrong type, bad weights, a damaged archive); names the file and the fault.
    """
    path = DEFAULT_RATIO_TUNER_PATH if path is None else Path(path)
    if not path.exists():
        raise MissingFileError(
            f"no ratio tuner weights at {path}: the tuner study of "
            f"`stewart-drake evaluate` trains them (its out folder, "
            f"tuner_study/weights/chosen/)"
        )
    data = CheckedNpz(
        path,
        "ratio tuner weights file",
        "train it again (the tuner study of `stewart-drake evaluate`)",
        max_bytes=MAX_WEIGHTS_BYTES,
    )
    if "format" not in data or data.text("format") != RATIO_FORMAT:
        raise data.corrupt(
            f"its format is not {RATIO_FORMAT!r} (the paper's network's weights "
            f"go in an AnnTunerDriver)"
        )
    W1, b1, W2, b2, x_mean, x_std = (
        data.array(name) for name in ("W1", "b1", "W2", "b2", "x_mean", "x_std")
    )
    metadata = data.json("metadata_json")
    try:
        return RatioTunerModel(W1, b1, W2, b2, x_mean, x_std, metadata)
    except InvalidConfigError as err:
        raise data.corrupt(str(err)) from None


class RatioTuner(LeafSystem):
    """Our online tuner: density features and the reference's motion -> [omega_Q / omega_R, 1].

    Input ports:
        ``rho`` (12,): density features (:class:`~.features.DensityFeatures`).
        ``x_d`` (18,): the reference [pose, rate, acceleration].
    Output port:
        ``omega`` (2,): [ratio, 1], ratio in [1e-3, 1e3], held between updates.
    Every period_s (first at offset_s) :class:`RatioTunerModel` is evaluated on the sampled
    inputs and its log10 ratio low-passed with time constant ``smoothing_s`` (0: none); a
    non-finite input keeps the last omega (counted in ``nonfinite_count``).

    Args:
        model: the network.  period_s: s (20 ms).  offset_s: s.
        omega_initial: [omega_Q, omega_R] before the first update.
        smoothing_s: time constant of the low-pass on the predicted log10 ratio, s (0: none):
            a gain that jumps every 20 ms between distant ratios excites the loop.
    Raises:
        InvalidConfigError: period_s <= 0, offset_s < 0, a non-finite omega_initial.
    """

    def __init__(
        self,
        model: RatioTunerModel,
        period_s: float = 0.02,
        offset_s: float = 0.0,
        omega_initial=(1.0, 1.0),
        smoothing_s: float = 0.0,
    ):
        super().__init__()
        if not (np.isfinite(period_s) and period_s > 0):
            raise InvalidConfigError(f"period_s must be > 0 s, got {period_s}")
        if not (np.isfinite(offset_s) and offset_s >= 0):
            raise InvalidConfigError(f"offset_s must be >= 0 s, got {offset_s}")
        omega0 = np.asarray(omega_initial, dtype=float)
        if omega0.shape != (2,) or not np.all(np.isfinite(omega0)):
            raise InvalidConfigError(f"omega_initial must be 2 finite numbers, got {omega_initial}")
        if not (np.isfinite(smoothing_s) and smoothing_s >= 0):
            raise InvalidConfigError(f"smoothing_s must be >= 0 s, got {smoothing_s}")
        self.model = model
        self.period_s = float(period_s)
        #: weight of a new prediction in the low-pass on log10 ratio (1: none)
        self.alpha = 1.0 if smoothing_s == 0 else 1.0 - np.exp(-self.period_s / smoothing_s)
        self._rho = self.DeclareVectorInputPort("rho", N_FEATURES)
        self._x_d = self.DeclareVectorInputPort("x_d", 18)
        self._omega_index = self.DeclareDiscreteState(omega0)
        self._count_index = self.DeclareDiscreteState(1)
        self.DeclareStateOutputPort("omega", self._omega_index)
        self.DeclareStateOutputPort("nonfinite_count", self._count_index)
        self.DeclarePeriodicDiscreteUpdateEvent(
            period_sec=self.period_s, offset_sec=offset_s, update=self._Update
        )

    def _Update(self, context, discrete_state):
        inputs = ratio_tuner_inputs(self._rho.Eval(context), self._x_d.Eval(context))
        try:
            y = float(self.model.predict_log10(inputs))
            last = np.log10(context.get_discrete_state(self._omega_index).get_value()[0])
            y = last + self.alpha * (y - last)
            discrete_state.set_value(self._omega_index, [10.0**y, 1.0])
        except InvalidConfigError:  # a non-finite input
            count = context.get_discrete_state(self._count_index).get_value()[0]
            discrete_state.set_value(self._count_index, [count + 1.0])
