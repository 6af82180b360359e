"""Learning in the Diagram: where the learner's cycles, bound and ports come from.

:func:`add_learning` adds the learner a scenario's ``learning`` chooses, an
:class:`~stewart_drake.control.ilc.IterativeLearningController` (from every cycle, for an
:class:`~stewart_drake.control.ilc.IlcDriver`) or a
:class:`~stewart_drake.control.feedforward_tuning.FeedforwardTuningLearner` (as a function of the
reference, for a :class:`~stewart_drake.control.feedforward_tuning.FeedforwardTuning`), and wires
it by port name:
it reads the reference source's ``x_d`` and the station's ``motor_angle`` (what the robot
measures), and an ``Adder`` puts its ``x_d_correction`` on the reference, whose sum the Diagram
gives the controller as its ``x_d`` (:mod:`~stewart_drake.control.contract`).
"""

from __future__ import annotations

import numpy as np
from pydrake.systems.primitives import Adder

from ..base.errors import InvalidConfigError
from ..control.feedforward_tuning import FeedforwardTuning, FeedforwardTuningLearner
from ..control.ilc import IlcDriver, IterativeLearningController
from ..references.motion import Reference, reference_cycles


def learning_cycles(
    driver: IlcDriver, trajectory: Reference, duration: float
) -> tuple[np.ndarray, np.ndarray]:
    """(starts (K + 1,), scale (K,)) of the cycles the learner aligns on over a run of
    ``duration`` s: the reference's own (:func:`~.motion.reference_cycles`), or
    ``driver.period_s`` from t = 0 when given. The cycles cover the run to its end: a tail
    after the last cycle the reference gives (a trace whose last breath is cut) gets cycles of
    the median length and the mean amplitude, so that it is corrected too.

    Raises:
        InvalidConfigError: a reference without cycles and no ``learning.period_s``, or not one
            whole cycle in the run.
    """
    if driver.period_s > 0:
        k = max(1, int(np.floor(duration / driver.period_s + 1e-9)))
        starts, scale = np.arange(k + 1) * driver.period_s, np.ones(k)
    else:
        try:
            starts, scale = reference_cycles(trajectory, duration)
        except InvalidConfigError as err:
            raise InvalidConfigError(
                f"learning needs a reference that repeats: {err}; give "
                f"learning.period_s for one of your own"
            ) from None
    k = int(np.count_nonzero(starts[:-1] < duration - 1e-9))  # cycles begun within the run
    if k < 1 or starts[1] > duration + 1e-9:
        raise InvalidConfigError(
            f"learning: the run ({duration:g} s) holds no whole cycle of "
            f"the reference (the first ends at {starts[1]:g} s)"
        )
    starts, scale = starts[: k + 1], scale[:k]
    if starts[-1] < duration - 1e-9:  # a tail after the last cycle found (a trace's end)
        length = float(np.median(np.diff(starts)))
        more = int(np.ceil((duration - starts[-1]) / length - 1e-9))
        starts = np.append(starts, starts[-1] + length * np.arange(1, more + 1))
        scale = np.append(scale, np.ones(more))
    return starts, scale


def add_learning(
    builder,
    d: IlcDriver | FeedforwardTuning,
    trajectory,
    x_d,
    motor_angle,
    *,
    geometry,
    period_s: float,
    offset_s: float,
    duration_s: float,
    floor: tuple[float, float],
):
    """Add the learner and the Adder; returns (learner, the corrected x_d output port).

    Args:
        builder: the DiagramBuilder. d: the learner's settings, which the learner takes whole
            (and checks). trajectory: the reference.
        x_d: the reference source's output port (18). motor_angle: the station's (6).
        geometry: the robot the controller believes in. period_s: the control period, s.
        offset_s: the controllers' sample offset, s. duration_s: the run's length, s.
        floor: (m, rad) the additive floor of the monitored bound: one encoder count at the
            crank tip as a translation and as a platform rotation
            (``RunPlan.encoder_count_at_tip``).
    """
    system: FeedforwardTuningLearner | IterativeLearningController
    if isinstance(d, FeedforwardTuning):
        system = FeedforwardTuningLearner(
            geometry, d, trajectory, period_s, offset_s, duration_s, floor=floor
        )
    else:
        starts, scale = learning_cycles(d, trajectory, duration_s)
        system = IterativeLearningController(
            geometry, d, period_s, offset_s, starts, scale, floor=floor
        )
    return _wire(builder, system, x_d, motor_angle)


def _wire(builder, system, x_d, motor_angle):
    """Add the learner and the Adder that puts its correction on the reference; returns
    (learner, the corrected x_d output port)."""
    learner = builder.AddNamedSystem("learner", system)
    builder.Connect(x_d, learner.GetInputPort("x_d"))
    builder.Connect(motor_angle, learner.GetInputPort("motor_angle"))
    add = builder.AddNamedSystem("learned_x_d", Adder(2, 18))
    builder.Connect(x_d, add.get_input_port(0))
    builder.Connect(learner.GetOutputPort("x_d_correction"), add.get_input_port(1))
    return learner, add.get_output_port()
