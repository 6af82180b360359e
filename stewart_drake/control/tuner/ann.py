"""ANN tuner of the LQI weights: density features rho (12,) -> [omega_Q, omega_R] (paper III.D).

The network is the paper's: one hidden layer of 10 neurons (tanh), 12 inputs, 2 outputs. The
outputs are y = log10 omega, so the weights stay positive, and y is clamped to [-1, 1], i.e.
omega_Q, omega_R in [0.1, 10] (the range of the 9 training runs, {0.1, 1, 10}^2). Inputs are
normalized, z = (rho - x_mean) / x_std, with the statistics of the training split, stored with
the weights (the file: :mod:`.network`).

Training uses torch (:mod:`stewart_drake.tuner.training`); inference does not: :class:`TunerModel`
holds numpy arrays and :class:`AnnTuner` evaluates them, so ``run --tuner ann`` never imports
torch. torch is imported lazily, only by :func:`build_mlp`, :meth:`TunerModel.from_torch` and
:meth:`TunerModel.to_torch`.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import ClassVar

import numpy as np
from pydrake.systems.framework import LeafSystem

from ...base.checks import as_array
from ...base.errors import InvalidConfigError
from ..features import N_FEATURES
from .network import (
    ACTIVATIONS,
    DATA_FOLDER,
    Z_CLIP,
    TunerNetwork,
    check_network,
    check_schedule,
    load_tuner,
)

#: The paper's ANN outputs log10 omega_Q and log10 omega_R clipped to this range (the paper's
#: nine training pairs span it), so its weights stay within [ANN_OMEGA_MIN, ANN_OMEGA_MAX].
ANN_LOG10_MIN, ANN_LOG10_MAX = -1.0, 1.0
ANN_OMEGA_MIN, ANN_OMEGA_MAX = 10.0**ANN_LOG10_MIN, 10.0**ANN_LOG10_MAX
DEFAULT_TUNER_PATH = DATA_FOLDER / "ann_tuner.npz"
#: The same network trained on the paper's labels (each sample labelled with its run's weights),
#: shipped for the evaluation's comparison of the two label modes.
PAPER_LABEL_TUNER_PATH = DEFAULT_TUNER_PATH.with_name("ann_tuner_paper.npz")


def _activation(name: str, h: np.ndarray) -> np.ndarray:
    if name == "tanh":
        return np.tanh(h)
    return 0.5 * (1.0 + np.tanh(0.5 * h))  # sigmoid without overflow in exp


@dataclass(frozen=True)
class TunerModel(TunerNetwork):
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

    activation: str = "tanh"
    metadata: dict = field(default_factory=dict)

    label: ClassVar[str] = "ANN tuner"
    log10_range: ClassVar[tuple[float, float]] = (ANN_LOG10_MIN, ANN_LOG10_MAX)
    remedy: ClassVar[str] = "retrain with `stewart-drake train` or use the shipped weights"
    missing_default: ClassVar[str] = (
        "run `stewart-drake collect && stewart-drake train` to collect the 9 closed-loop "
        "runs and train it"
    )
    missing_given: ClassVar[str] = "check the path, or pass none for the shipped weights"

    @classmethod
    def default_path(cls) -> Path:
        """:data:`DEFAULT_TUNER_PATH`, the shipped weights (best-cost labels)."""
        return DEFAULT_TUNER_PATH

    def __post_init__(self):
        check_network(
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
        model: the network (:func:`~.network.load_tuner`); None loads the shipped weights.
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
        omega0 = check_schedule(period_s, offset_s, omega_initial)
        self.model = load_tuner(TunerModel) if model is None else model
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
