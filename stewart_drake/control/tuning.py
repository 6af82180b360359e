"""The tuner choices of a scenario: what drives the LQI's weights omega_Q, omega_R, as YAML.

Each choice checks its own fields (``validate``) and wires its systems into the Diagram
(``add_to``), the one place it does: :class:`AnnTunerDriver` (the paper's network,
:class:`~.tuner.ann.AnnTuner`, on the density features of :class:`~.features.DensityFeatures`),
:class:`RatioTunerDriver` (ours, :class:`~.tuner.ratio.RatioTuner`) and :class:`WeightSchedule`
(weights known in advance). A new tuner is one class here, added to :data:`TunerChoice`.

Drake's YAML loader (``yaml_load_typed``) reads the fields' annotations, so this module must not
use ``from __future__ import annotations``.
"""

from dataclasses import dataclass, field
from pathlib import Path
from typing import ClassVar

import numpy as np
from pydrake.systems.framework import OutputPort, System
from pydrake.systems.primitives import TrajectorySource
from pydrake.trajectories import PiecewisePolynomial

from ..base.checks import as_array, check_int, check_multiple
from ..base.errors import InvalidConfigError, MissingFileError
from .features import N_FEATURES, DensityFeatures
from .lqi.gain import LQI_OMEGA_MAX, LQI_OMEGA_MIN
from .tuner.ann import DEFAULT_TUNER_PATH, AnnTuner, TunerModel
from .tuner.network import load_tuner
from .tuner.ratio import DEFAULT_RATIO_TUNER_PATH, RatioTuner, RatioTunerModel


@dataclass(frozen=True)
class TunerPorts:
    """What a tuner is wired to in the Diagram (:meth:`TunerConfig.add_to`): the controller
    system with its port names, the reference's ``x_d`` (18) and the applied torques (6), and the
    control period and sample offset (s)."""

    controller: System
    inputs: frozenset
    outputs: frozenset
    x_d: OutputPort
    T_applied: OutputPort
    period_s: float
    offset_s: float
    duration_s: float


@dataclass(frozen=True)
class TunerSystems:
    """The systems a tuner added: ``features`` (or None), ``tuner`` (what drives ``omega``), and
    ``rho_period_s``, the period to log the features at (None: nothing to log)."""

    tuner: System
    features: System | None = None
    rho_period_s: float | None = None


class TunerConfig:
    """Base of a scenario's tuner choices (:class:`AnnTunerDriver`, :class:`RatioTunerDriver`,
    :class:`WeightSchedule`): each checks its fields (:meth:`validate`) and wires what drives the
    controller's ``omega`` input into the Diagram (:meth:`add_to`), the one place it does."""

    #: How a run's result files mark the tuner (``run_<reference><suffix>``).
    run_suffix: ClassVar[str] = "_tuned"

    def validate(self, controller, control_period_s: float) -> None:
        """Check the fields against the run's controller choice (``controller``, whose
        ``takes_omega`` says whether it has the ``omega`` input) and its control period, s.

        Raises:
            InvalidConfigError, MissingFileError: names the field (``tuner.<name>``).
        """
        if controller.takes_omega is False:
            raise InvalidConfigError(
                "a tuner drives the LQI's weights (its omega input): use an "
                "LqiDriver controller with a tuner"
            )

    def density_window(self) -> int | None:
        """The samples of the density features' window a controller may buffer for the tuner
        (None: the tuner reads no features)."""
        return None

    def weights_path(self) -> Path | None:
        """The network's weights file the run uses (None: no network)."""
        return None

    def add_to(self, builder, ports: TunerPorts) -> TunerSystems:
        """Add the systems that drive ``ports.controller``'s ``omega`` input, connected.

        Raises:
            InvalidConfigError: the controller lacks a port the tuner needs (named).
        """
        raise NotImplementedError


class _NetworkTuner(TunerConfig):
    """A network on the density features of the controller's error and torques (eqs. 35-36)
    that sets omega every ``period_s``: a subclass has the fields ``weights``, ``period_s`` and
    ``feature_window``, and makes the network's system (:meth:`make_tuner`)."""

    #: What the messages call it.
    kind: ClassVar[str] = "tuner"
    #: The name of its system in the Diagram.
    system_name: ClassVar[str] = "tuner"
    # The fields every subclass declares (as dataclass fields).
    weights: str
    period_s: float
    feature_window: int

    def validate(self, controller, control_period_s: float) -> None:
        super().validate(controller, control_period_s)
        check_multiple("tuner.period_s", self.period_s, "control_period_s", control_period_s)
        check_int("tuner.feature_window", self.feature_window, 1, 100_000)
        if self.weights and not Path(self.weights).exists():
            raise MissingFileError(
                f"no {self.kind} weights at {self.weights} (tuner.weights): "
                f"check the path, or leave it empty for the shipped weights"
            )

    def density_window(self) -> int | None:
        return self.feature_window

    def make_tuner(self):
        """The tuner system: input ``rho`` (12) (and ``x_d`` for ours), output ``omega`` (2)."""
        raise NotImplementedError

    def add_to(self, builder, ports: TunerPorts) -> TunerSystems:
        missing = [
            p
            for p, have in (
                ("omega input", "omega" in ports.inputs),
                ("e_bar output", "e_bar" in ports.outputs),
            )
            if not have
        ]
        name = ports.controller.get_name()
        if missing:
            raise InvalidConfigError(
                f"the {self.kind} needs a controller with an "
                f"{' and an '.join(missing)} (the LQI has both); {name} "
                f"has not"
            )
        window = self.feature_window
        # A controller that buffers the samples spares the features a callback per period.
        buffered = "feature_window" in ports.outputs
        size = N_FEATURES * window + 2
        if buffered and ports.controller.GetOutputPort("feature_window").size() != size:
            raise InvalidConfigError(
                f"{name}: output port 'feature_window' has size "
                f"{ports.controller.GetOutputPort('feature_window').size()}; the tuner's window "
                f"of {window} samples needs {size} (contract, control/contract.py)"
            )
        features = builder.AddNamedSystem(
            "features",
            DensityFeatures(
                window=window, period_s=ports.period_s, offset_s=ports.offset_s, buffered=buffered
            ),
        )
        tuner = self._add_tuner(builder, ports)
        if buffered:
            builder.Connect(
                ports.controller.GetOutputPort("feature_window"),
                features.GetInputPort("feature_window"),
            )
        else:
            builder.Connect(ports.controller.GetOutputPort("e_bar"), features.GetInputPort("e_bar"))
            builder.Connect(ports.T_applied, features.GetInputPort("T"))
        builder.Connect(features.GetOutputPort("rho"), tuner.GetInputPort("rho"))
        builder.Connect(tuner.GetOutputPort("omega"), ports.controller.GetInputPort("omega"))
        # rho is computed when read: log it where the tuner reads it, not every millisecond.
        return TunerSystems(tuner=tuner, features=features, rho_period_s=self.period_s)

    def _add_tuner(self, builder, ports: TunerPorts):
        return builder.AddNamedSystem(self.system_name, self.make_tuner())


@dataclass
class AnnTunerDriver(_NetworkTuner):
    """The ANN tuner of omega_Q, omega_R (paper section III.D) on density features
    (:class:`~stewart_drake.control.tuner.ann.AnnTuner`).

    It moves the weights every period, as fast as the gains can follow: run it with the paper's
    gain switching, ``controller.gain_transfer: none``, as
    :func:`~stewart_drake.run.scenario.use_paper_tuner` does (``run --tuner ann``,
    ``evaluate``, the tuner study). Our ``integral`` transfer re-maps the
    integral states at every switch, and switched that fast the re-maps pile up and the loop
    chatters at the torque limit (docs/paper_notes.md).

    Attributes:
        weights: the tuner's ``.npz`` (``stewart-drake train``); empty for the shipped weights.
        period_s: tuner period, s (a whole multiple of the control period).
        feature_window: samples m + 1 of the density features (eqs. 35-36).
    """

    weights: str = ""
    period_s: float = 0.02
    feature_window: int = 50

    run_suffix: ClassVar[str] = "_ann"
    kind: ClassVar[str] = "ANN tuner"
    system_name: ClassVar[str] = "ann_tuner"

    def weights_path(self) -> Path:
        return Path(self.weights) if self.weights else DEFAULT_TUNER_PATH

    def make_tuner(self):
        return AnnTuner(load_tuner(TunerModel, self.weights or None), period_s=self.period_s)


@dataclass
class RatioTunerDriver(_NetworkTuner):
    """Our tuner (:class:`~stewart_drake.control.tuner.ratio.RatioTuner`): the density features
    and the reference's speed and acceleration -> the ratio omega_Q / omega_R (the tuner study).

    Attributes:
        weights: its ``.npz`` (:func:`~stewart_drake.control.tuner.network.save_tuner`); empty
            for the shipped weights trained for the cost at lambda = 0.1
            (:data:`~stewart_drake.control.tuner.ratio.DEFAULT_RATIO_TUNER_PATH`; the ones for
            lambda = 0.01 and 1 ship beside them:
            :func:`~stewart_drake.control.tuner.ratio.ratio_tuner_path`).
        period_s: tuner period, s (a whole multiple of the control period).
        feature_window: samples m + 1 of the density features.
        smoothing_s: time constant of the low-pass on its log10 ratio, s (0: none).
    """

    weights: str = ""
    period_s: float = 0.02
    feature_window: int = 50
    smoothing_s: float = 0.0

    run_suffix: ClassVar[str] = "_ratio"
    kind: ClassVar[str] = "ratio tuner"
    system_name: ClassVar[str] = "ratio_tuner"

    def weights_path(self) -> Path:
        return Path(self.weights) if self.weights else DEFAULT_RATIO_TUNER_PATH

    def make_tuner(self):
        return RatioTuner(
            load_tuner(RatioTunerModel, self.weights or None),
            period_s=self.period_s,
            smoothing_s=self.smoothing_s,
        )

    def _add_tuner(self, builder, ports: TunerPorts):
        tuner = super()._add_tuner(builder, ports)
        builder.Connect(ports.x_d, tuner.GetInputPort("x_d"))
        return tuner


@dataclass
class WeightSchedule(TunerConfig):
    """omega_Q and omega_R known in advance, held from each time to the next: the hindsight
    schedule and the hand-made ones of the tuner study.

    Attributes:
        t: increasing times, s (the first is 0).  omega_Q, omega_R: the weights from each time
            on, in [1e-3, 1e3].
    """

    t: list[float] = field(default_factory=lambda: [0.0])
    omega_Q: list[float] = field(default_factory=lambda: [1.0])
    omega_R: list[float] = field(default_factory=lambda: [1.0])

    def validate(self, controller, control_period_s: float) -> None:
        super().validate(controller, control_period_s)
        times = as_array("tuner.t", self.t)
        if times.ndim != 1 or times.size < 1 or times[0] != 0.0 or np.any(np.diff(times) <= 0):
            raise InvalidConfigError(
                f"tuner.t must be increasing times starting at 0 s, got {self.t!r:.80}"
            )
        for name in ("omega_Q", "omega_R"):
            values = as_array(f"tuner.{name}", getattr(self, name))
            if values.shape != times.shape:
                raise InvalidConfigError(
                    f"tuner.{name} needs one value per time ({times.size}), got {values.size}"
                )
            if np.any(values < LQI_OMEGA_MIN) or np.any(values > LQI_OMEGA_MAX):
                raise InvalidConfigError(
                    f"tuner.{name} must be in [{LQI_OMEGA_MIN:g}, {LQI_OMEGA_MAX:g}]"
                )

    def add_to(self, builder, ports: TunerPorts) -> TunerSystems:
        if "omega" not in ports.inputs:
            raise InvalidConfigError(
                f"a weight schedule drives the omega input; {ports.controller.get_name()} has none"
            )
        t_s = np.append(np.asarray(self.t, dtype=float), ports.duration_s + 1.0)
        values = np.array([self.omega_Q, self.omega_R], dtype=float)
        tuner = builder.AddNamedSystem(
            "weight_schedule",
            TrajectorySource(
                PiecewisePolynomial.ZeroOrderHold(  # type: ignore[call-overload]  # stub shapes
                    t_s, np.hstack([values, values[:, -1:]])
                )
            ),
        )
        builder.Connect(tuner.get_output_port(), ports.controller.GetInputPort("omega"))
        return TunerSystems(tuner=tuner)


TunerChoice = AnnTunerDriver | RatioTunerDriver | WeightSchedule
