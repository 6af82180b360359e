"""The surrogate stage's goal with lag matching in a Diagram: the external signal taken as late
as the platform is measured to be on its own reference
(:mod:`~stewart_drake.station.surrogate.lag_matching`), as the robot's session does on the bus.

:class:`LagMatchedGoal` replaces the stage's goal table when the scenario's surrogate matches
the platform's lag: each control period (at the controller's sample instants) it takes the
platform's pose as the controller measures it and advances the lag estimate held in its
context; its output, the goal [p_d, v_d, a_d] the stage's controller samples, is the signal at
(t - delay), linear between the signal's samples, the position rounded to the stage's
resolution. With the delay 0 it gives the goal table's values at the sample instants exactly.
One Python system a control period (its update a few microseconds of arithmetic).
"""

import numpy as np
from pydrake.systems.framework import BasicVector, LeafSystem

from .lag_matching import PlatformLagMatch


class LagMatchedGoal(LeafSystem):
    """The stage's goal, the platform's lag matched (module docstring).

    Input port ``platform_state`` (12,): the platform's pose and rate as the controller
    measures them, rad and m (only the translation along the match's direction is read).
    Output port ``goal`` (3,): [p_d m, v_d m/s, a_d m/s^2].
    Discrete state (6,): the estimator's ``state`` (:class:`~.lag_matching.PlatformLagMatch`:
    the fit's sums, the delay in use).

    Args:
        match: the :class:`~.lag_matching.PlatformLagMatch` (its reference sampled at the
            controller's instants; only its settings and tables are used, its own state never).
        samples: (t (n,), p (n,), v (n,), a (n,)) the signal at the controller's instants
            [s, m, m/s, m/s^2], t uniformly spaced by ``period_s``.
        period_s: the control period, s. offset_s: the controller's sample offset, s.
        resolution_m: the stage's position resolution (one count of its servo), m (0: none).
    """

    def __init__(
        self,
        match: PlatformLagMatch,
        samples,
        period_s: float,
        offset_s: float,
        resolution_m: float = 0.0,
    ):
        super().__init__()
        self.match = match
        t, p, v, a = (np.asarray(s, dtype=float) for s in samples)
        self._t0, self._h, self._last = float(t[0]), float(period_s), len(t) - 1
        self._table = np.column_stack([p, v, a])
        self._q = float(resolution_m)
        self._input = self.DeclareVectorInputPort("platform_state", 12)
        self._state = self.DeclareDiscreteState(6)
        self.DeclarePeriodicDiscreteUpdateEvent(period_s, offset_s, self._Update)
        self.DeclareVectorOutputPort("goal", BasicVector(3), self._CalcGoal)

    def _Update(self, context, discrete_state):
        state = context.get_discrete_state(self._state).CopyToVector()
        y = self.match.coordinate(self._input.Eval(context))
        self.match.step(state, context.get_time(), y)
        discrete_state.get_mutable_vector(self._state).SetFromVector(state)

    def goal_at(self, t: float) -> np.ndarray:
        """(3,) [p_d rounded to the resolution, v_d, a_d] of the signal at time ``t`` (s;
        linear between samples, the ends held)."""
        x = (t - self._t0) / self._h
        k = min(max(int(np.floor(x)), 0), self._last)
        w = min(max(x - k, 0.0), 1.0) if k < self._last else 0.0
        row, nxt = self._table[k], self._table[min(k + 1, self._last)]
        goal = row + w * (nxt - row)
        if self._q > 0:
            goal[0] = np.round(goal[0] / self._q) * self._q
        return goal

    def _CalcGoal(self, context, output):
        delay = context.get_discrete_state(self._state).GetAtIndex(5)
        output.SetFromVector(self.goal_at(context.get_time() - delay))

    def delay_s(self, context) -> float:
        """The delay in use in ``context`` (this system's), s."""
        return float(context.get_discrete_state(self._state).GetAtIndex(5))
