"""Our tuner of the LQI weights: density features and the reference's motion -> the one ratio
omega_Q / omega_R that sets the gain (the tuner study, :mod:`stewart_drake.tuner.tuner_study`).

Its network is :class:`RatioTunerModel` (its file: :mod:`.network`), its Drake system
:class:`RatioTuner`; three trained networks ship, one per lambda of the study's cost
(:func:`ratio_tuner_path`).
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
from .network import DATA_FOLDER, Z_CLIP, TunerNetwork, check_network, check_schedule

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
#: The lambdas of the tuner study's cost (J = tracking + lambda effort) whose tuners ship.
RATIO_TUNER_LAMBDAS = (0.01, 0.1, 1.0)


def ratio_tuner_path(lam: float) -> Path:
    """The shipped weights of our tuner trained for the cost at ``lam``:
    ``stewart_drake/data/ratio_tuner_lambda<lam>.npz`` (its metadata name the data it came
    from)."""
    return DATA_FOLDER / f"ratio_tuner_lambda{lam:g}.npz"


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
class RatioTunerModel(TunerNetwork):
    """Our tuner's network: 16 inputs (:data:`RATIO_INPUTS`) -> hidden (tanh) -> log10 of the
    ratio omega_Q / omega_R, clamped to [-3, 3] (the study's grid, wider than the paper's).

    Only the ratio decides the LQI's gain (docs/paper_notes.md), so one output; the paper's
    network outputs both weights. The reference's speed and acceleration are inputs the paper
    leaves out: whether the platform moves or holds is what the best ratio depends on most.

    Attributes:
        W1 (hidden, 16), b1 (hidden,), W2 (1, hidden), b2 (1,): weights.
        x_mean, x_std: (16,) input normalization (training statistics), x_std > 0.
        metadata: JSON-able (lambda, training tasks, loss...).
        activation: "tanh", the hidden layer's (what its file records).
    Raises:
        InvalidConfigError: inconsistent shapes, non-finite numbers, x_std <= 0 or another
            activation.
    """

    metadata: dict = field(default_factory=dict)
    activation: str = "tanh"

    label: ClassVar[str] = "ratio tuner"
    log10_range: ClassVar[tuple[float, float]] = (RATIO_LOG10_MIN, RATIO_LOG10_MAX)
    remedy: ClassVar[str] = "train it again (the tuner study of `stewart-drake evaluate`)"
    missing_default: ClassVar[str] = (
        "the tuner study of `stewart-drake evaluate` trains them (its out folder, "
        "tuner_study/weights/chosen/)"
    )
    missing_given: ClassVar[str] = missing_default

    @classmethod
    def default_path(cls) -> Path:
        """:data:`DEFAULT_RATIO_TUNER_PATH`, the shipped weights for lambda = 0.1."""
        return DEFAULT_RATIO_TUNER_PATH

    def __post_init__(self):
        check_network(self, "ratio tuner", N_RATIO_INPUTS, 1)
        if self.activation != "tanh":
            raise InvalidConfigError(
                f"a ratio tuner's hidden layer is tanh, got activation {self.activation!r}"
            )

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
        omega0 = check_schedule(period_s, offset_s, omega_initial)
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
