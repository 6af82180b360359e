"""What a reference is: the motion x_d(t) of the platform pose that a run tracks, and how a
scenario chooses one.

A reference is any object with ``evaluate(t)`` and a ``name`` (:class:`Reference`): the
trajectories of :mod:`~.trajectories` and the tuner study's tasks (:mod:`~.tasks`), the motions
of the organ-motion library (:mod:`~.organ`), recorded traces (:mod:`~.traces`), and
their sums and scalings (:class:`~.combinators.MotionSum`,
:class:`~.combinators.ScaledReference`). Some references say more, and what asks for it uses it
when it is there (the optional members of :class:`Reference`): ``end_time``, ``centre``,
``cycles(t_end)``, ``repeat_period_s``, ``frequencies_hz()``. :func:`reference_cycles` is how
the learner and the fidelity report ask any reference for its cycles, :func:`learning_cycles`
the cycles a learner aligns on over a whole run.

A scenario chooses its reference by a :class:`ReferenceConfig` (in YAML,
``reference: !NamedReference {name: paper}``): one class per kind of reference, defined beside
what it builds, which checks its own fields and makes the reference.
"""

from typing import Protocol

import numpy as np

from ..base.errors import InvalidConfigError
from ..robot.geometry import StewartGeometry


class Reference(Protocol):
    """A reference x_d(t) of the platform pose [phi, theta, psi, X, Y, Z] (roll, pitch, yaw in
    rad; position in m).

    Attributes:
        name: the reference's label in result files and messages.

    Optional members, not part of the protocol (read them with ``getattr``; a reference without
    them has none):

    - ``end_time``: its last time, s (a run may not last longer; a CSV or a trace has one);
    - ``centre``: (6,) the pose it moves about, rad and m (the fixed point of
      :class:`~.combinators.ScaledReference`; else its pose at t = 0 is);
    - ``cycles(t_end)`` -> (starts (K + 1,), scale (K,)): the cycles that begin in [0, t_end),
      their starts in s (the last entry ends the last cycle) and each cycle's amplitude over the
      mean's (:func:`reference_cycles` finds them where a reference has none);
    - ``repeat_period_s``: the time after which it repeats exactly, s, or None (it never does);
    - ``frequencies_hz()`` -> {"breathing": Hz, "cardiac": Hz}: the fundamentals present, whose
      harmonics the fidelity report analyses (``{}``: none known).
    """

    @property
    def name(self) -> str:
        """The reference's label."""
        ...

    def evaluate(self, t) -> tuple:
        """Pose, rate and acceleration at times ``t``.

        Args:
            t: times, s: a number or an array of any shape.
        Returns:
            (pose, rate, acceleration), three float arrays of shape ``np.shape(t) + (6,)``
            ((6,) for one time): [rad, rad, rad, m, m, m], per s, per s^2.
        """
        ...


class ReferenceConfig:
    """Base of a scenario's reference choices: :class:`~.trajectories.NamedReference`,
    :class:`~.samples.CsvReference`, :class:`~.trajectories.SineReference`,
    :class:`~.data_collection.DataCollectionReference` (beside the trajectories they build),
    :class:`~.library.OrganMotionReference` and :class:`~.traces.TraceReference`;
    :data:`~.scenario.ReferenceChoice` is their union.

    Each is a plain mutable dataclass with concrete field types (Drake's ``yaml_load_typed``
    builds it with its defaults, then sets the fields; its module does not use
    ``from __future__ import annotations``), checks its own fields (:meth:`validate`) and makes
    the reference (:meth:`make`), the one place it does.
    """

    def validate(self) -> None:
        """Check the fields before anything is built.

        Raises:
            InvalidConfigError, MissingFileError: names the field (``reference.<name>``).
        """
        raise NotImplementedError

    def make(
        self, geometry: StewartGeometry, duration_s: float, torque_limit_Nm: float | None
    ) -> Reference:
        """The reference x_d(t) (:class:`Reference`).

        Args:
            geometry: the robot. duration_s: the run's length, s. torque_limit_Nm: the motors'
                torque limit in force, N m, or None (unlimited). Only
                :class:`~.data_collection.DataCollectionReference` uses them (its excitation
                lasts the run and fits the robot and its motors); the others ignore them.
        Raises:
            InvalidConfigError, MissingFileError, CorruptFileError: as :meth:`validate`, and
                what reading a file finds (a CSV or a trace that does not parse).
        """
        raise NotImplementedError

    @property
    def label(self) -> str:
        """The reference's name for display and for a run's file names (the ``name`` field of the
        choices that have one; the others define ``label``)."""
        return self.name  # type: ignore[attr-defined]  # every choice without a name overrides

    def memory_bytes(self) -> float:
        """Memory the reference itself holds, bytes, beyond a run's logs (0: negligible)."""
        return 0.0

    def memory_note(self) -> tuple:
        """(what, change): phrases for a refused run's memory message (``""`` when none)."""
        return "", ""


# -- cycles of any reference ---------------------------------------------------------------------


def reference_cycles(
    reference: Reference, t_end: float, dt: float = 0.01
) -> tuple[np.ndarray, np.ndarray]:
    """(starts (K + 1,), scale (K,)) of a reference's cycles over [0, t_end] s.

    A reference that knows its cycles says them (``cycles``: the motions of the library). Any
    other (a trace, a CSV) is cut where its main motion peaks (:func:`peak_cycles`).

    Raises:
        InvalidConfigError: fewer than two cycles found (a motion that does not repeat).
    """
    cycles = getattr(reference, "cycles", None)
    if callable(cycles):
        starts, scale = cycles(t_end)
        return np.asarray(starts, dtype=float), np.asarray(scale, dtype=float)
    return peak_cycles(reference, t_end, dt)


def peak_cycles(
    reference: Reference, t_end: float, dt: float = 0.01
) -> tuple[np.ndarray, np.ndarray]:
    """(starts (K + 1,), scale (K,)) of a reference's cycles over [0, t_end] s, found where its
    main motion peaks: the principal component of the pose, sampled every ``dt`` s, the side
    whose peaks come most regularly; starts in s, ``scale`` each cycle's peak to peak over the
    median.

    Raises:
        InvalidConfigError: fewer than two cycles found (a motion that does not repeat).
    """
    from scipy.signal import find_peaks

    t = np.arange(0.0, t_end + 0.5 * dt, dt)
    x = reference.evaluate(t)[0]
    x = (x - x.mean(axis=0)) / np.maximum(x.std(axis=0), 1e-12) * (x.std(axis=0) > 1e-9)
    _, _, vt = np.linalg.svd(x, full_matrices=False)
    pc = x @ vt[0]
    spread = np.percentile(pc, 95) - np.percentile(pc, 5)
    best = None
    for signal in (pc, -pc):
        peaks, _ = find_peaks(signal, prominence=0.3 * spread, distance=max(1, int(0.5 / dt)))
        if len(peaks) >= 3:
            gaps = np.diff(t[peaks])
            cv = gaps.std() / gaps.mean()
            if best is None or cv < best[0]:
                best = (cv, peaks)
    if best is None:
        raise InvalidConfigError(
            f"the reference {getattr(reference, 'name', '')} does not "
            f"repeat: fewer than two cycles in {t_end:g} s"
        )
    peaks = best[1]
    p2p = np.array([np.ptp(pc[a : b + 1]) for a, b in zip(peaks[:-1], peaks[1:])])
    return t[peaks], p2p / np.median(p2p)


__all__ = ["Reference", "ReferenceConfig", "reference_cycles", "peak_cycles"]


def learning_cycles(
    period_s: float, trajectory: Reference, duration: float
) -> tuple[np.ndarray, np.ndarray]:
    """(starts (K + 1,), scale (K,)) of the cycles a learner aligns on over a run of
    ``duration`` s: the reference's own (:func:`reference_cycles`), or ``period_s``'s (the
    learning choice's ``period_s``, s) from t = 0 when it is > 0. The cycles cover the run to
    its end: a tail after the last cycle the reference gives (a trace whose last breath is
    cut) gets cycles of the median length and the mean amplitude, so that it is corrected too.

    Raises:
        InvalidConfigError: a reference without cycles and no ``learning.period_s``, or not one
            whole cycle in the run.
    """
    if period_s > 0:
        k = max(1, int(np.floor(duration / period_s + 1e-9)))
        starts, scale = np.arange(k + 1) * period_s, np.ones(k)
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
