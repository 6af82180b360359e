"""Reference and feed-forward torques, precomputed at the controller's sample instants.

The reference x_d(t) is known before the run, and so is the feed-forward torque that holds (or
drives) the platform along it. Evaluating both in Python at every 1 ms control step cost about a
third of the wall time of a run (IK, Jacobian and gravity gradient per step), so
:func:`add_reference_sources` evaluates them once, vectorized over the whole run, and puts them in
the Diagram as Drake ``TrajectorySource`` systems holding a zero-order-hold ``PiecewisePolynomial``.
The controller samples mid-interval (at k h + offset, 0 < offset < h), so each sample reads
exactly the value stored for step k, never its neighbour's, whatever the rounding of t.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from pydrake.systems.primitives import TrajectorySource
from pydrake.trajectories import PiecewisePolynomial

from ..model import kinematics
from ..model.statics import FEEDFORWARD_MODES, feedforward_torques
from ..errors import InvalidConfigError
from ..model.geometry import StewartGeometry



@dataclass
class ReferenceSources:
    """The two sources :func:`add_reference_sources` added, and the tables behind them.

    Attributes:
        x_d: TrajectorySource, output (18,) [pose, rate, acceleration] of the reference.
        T_ff: TrajectorySource, output (6,) feed-forward motor torques, N m.
        t_sample: (N,) controller sample instants, s.  t_eval: (N,) the times the reference was
        evaluated at (t_sample + lead).  x_d_table: (N, 18).  T_ff_table: (N, 6).
    """

    x_d: TrajectorySource
    T_ff: TrajectorySource
    t_sample: np.ndarray
    t_eval: np.ndarray
    x_d_table: np.ndarray
    T_ff_table: np.ndarray


def sample_reference(trajectory, geometry: StewartGeometry, duration_s: float, period_s: float,
                     offset_s: float, lead_s: float, feedforward: str = "gravity",
                     feedforward_lead_s: float = 0.0):
    """Reference and feed-forward at the sample instants t_k = k h + offset, k = 0..N.

    Args:
        feedforward_lead_s: the feed-forward is that of the reference this much later than
            x_d (s): with a computation delay the torque computed now acts one delay later, so
            it should hold (or drive) the platform where the reference will be then.
    Returns:
        (t_sample (N,), t_eval (N,), x_d (N, 18), T_ff (N, 6)) with t_eval = t_sample + lead_s,
        covering [0, duration_s] plus one period.
    Raises:
        InvalidConfigError: non-positive period or duration; UnreachablePoseError (naming the time
        and leg) if the reference leaves the workspace.
    """
    if not (np.isfinite(period_s) and period_s > 0 and np.isfinite(duration_s) and duration_s > 0):
        raise InvalidConfigError(f"period ({period_s}) and duration ({duration_s}) must be > 0 s")
    n = int(np.ceil(duration_s / period_s)) + 2
    t_sample = np.arange(n) * period_s + offset_s
    t_eval = t_sample + lead_s
    x, xd, xdd = trajectory.evaluate(t_eval)
    theta = kinematics.ik(geometry, x, t=t_eval)  # names the first unreachable time and leg
    if feedforward_lead_s:
        t_ff = t_eval + feedforward_lead_s
        x_ff, _, xdd_ff = trajectory.evaluate(t_ff)
        T_ff = feedforward_torques(geometry, x_ff, xdd_ff, feedforward,
                                   theta=kinematics.ik(geometry, x_ff, t=t_ff))
    else:
        T_ff = feedforward_torques(geometry, x, xdd, feedforward, theta=theta)
    return t_sample, t_eval, np.concatenate([x, xd, xdd], axis=1), T_ff


def add_reference_sources(builder, trajectory, geometry: StewartGeometry, duration_s: float,
                          period_s: float, offset_s: float = 0.0, lead_s: float = 0.0,
                          feedforward: str = "gravity",
                          feedforward_lead_s: float = 0.0) -> ReferenceSources:
    """Add the reference x_d and the feed-forward T_ff as zero-order-hold TrajectorySources.

    A consumer that samples at t_k = k h + offset_s reads x_d(t_k + lead_s) and the feed-forward
    at that reference. Each value is stored on [k h, (k + 1) h), so ``offset_s`` must lie strictly
    inside (0, h) for the sample to be unambiguous; offset 0 is allowed for consumers that sample
    exactly at k h (the value then also holds on the whole interval).

    Args:
        builder: the DiagramBuilder. trajectory: object with ``evaluate(t)``.
        geometry: the robot the controller believes in. duration_s: run length, s.
        period_s: controller period h, s. offset_s: sample offset in [0, h), s.
        lead_s: evaluate the reference this far ahead of the sample, s (see diagram.py).
        feedforward: see :func:`feedforward_torques`.
    Returns:
        :class:`ReferenceSources` (systems named "reference" and "feedforward").
    """
    if not 0.0 <= offset_s < period_s:
        raise InvalidConfigError(f"offset_s must be in [0, period_s), got {offset_s}")
    t_sample, t_eval, x_d, T_ff = sample_reference(trajectory, geometry, duration_s, period_s,
                                                   offset_s, lead_s, feedforward,
                                                   feedforward_lead_s)
    breaks = t_sample - offset_s                 # k h: the sample lies inside its interval
    # A zero-order hold keeps the value of break k on [t_k, t_k+1); the last break only closes
    # the last interval, so the tables already extend one period past the run.
    ref = builder.AddNamedSystem("reference", TrajectorySource(
        PiecewisePolynomial.ZeroOrderHold(breaks, x_d.T)))
    ff = builder.AddNamedSystem("feedforward", TrajectorySource(
        PiecewisePolynomial.ZeroOrderHold(breaks, T_ff.T)))
    return ReferenceSources(x_d=ref, T_ff=ff, t_sample=t_sample, t_eval=t_eval, x_d_table=x_d,
                            T_ff_table=T_ff)
