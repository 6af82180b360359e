"""What the validator of a reference path reports: the earliest :class:`LimitViolation`, the
:class:`TrajectoryReport` with its :meth:`~TrajectoryReport.summary`, and one report of a path
checked in consecutive stretches (:func:`merge_reports`).

The report is made by :func:`~.limits.validate_trajectory` (every sample's limits, singularity
measures, clearance and motors' effort); its margins are keyed by the names of
:data:`~.limits.LIMITS`, in that order.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from ..base.errors import MotorLimitError


@dataclass(frozen=True)
class LimitViolation:
    """One leg outside one limit.

    Attributes:
        leg: 0..5, reference_geometry.md order.
        limit: a name of :data:`~.limits.LIMITS`.
        margin: < 0, in the limit's unit (rad; dimensionless for ``closure``).
        t: time along a trajectory in s, or None.
    """

    leg: int
    limit: str
    margin: float
    t: float | None = None

    def __str__(self) -> str:
        where = "" if self.t is None else f" at t = {self.t:.4g} s"
        amount = (
            f"{-self.margin:.4g} (ratio {1 - self.margin:.4g} > 1)"
            if self.limit == "closure"
            else f"{np.rad2deg(-self.margin):.3g} deg"
        )
        return f"leg {self.leg} exceeds its {self.limit} limit by {amount}{where}"


@dataclass(frozen=True)
class TrajectoryReport:
    """Result of :func:`~.limits.validate_trajectory`.

    Attributes:
        ok: every sample inside every limit and below the condition-number threshold.
        min_margin: limit name -> smallest margin over samples and legs (rad; 1 for closure).
        min_margin_leg, min_margin_t: limit name -> leg and time (s) of that smallest margin.
        first_violation: the earliest :class:`LimitViolation` (worst leg at that time) or None.
        max_cond, max_cond_t: largest cond(J) along the path and its time (s).
        first_singular_t: first time (s) with cond(J) > cond_threshold, or None.
        min_sigma_min_inv: smallest 1/sigma_max(J) along the path ((rad or m) per rad).
        cond_threshold: the threshold used.
        min_sigma_min_inv_t: time (s) of ``min_sigma_min_inv``.
        first_weak_t: first time (s) with 1/sigma_max(J) < sigma_min_inv_threshold, or None.
        sigma_min_inv_threshold: the threshold used ((rad or m) per rad).
        min_clearance: smallest distance between two parts along the path, m (NaN when not
            checked), at ``min_clearance_t`` between ``min_clearance_parts`` ("a and b").
        clearance_threshold: the smallest clearance allowed, m.
        first_interference: (t, part_a, part_b, clearance) of the first measured pose below it,
            or None.
        design_clearance, design_clearance_parts: the closest of the pairs whose distance is the
            same at every pose (the clearance model's ``fixed`` pairs), m, and its parts.
        peak_torque, peak_torque_motor, peak_torque_t: the largest |torque| the motion needs
            (N m), which motor, when (NaN / -1 when not checked).  torque_limit: what it may use.
        peak_speed, peak_speed_motor, peak_speed_t, speed_limit: the same for the crank speed,
            rad/s.
        effort_margin: the share of the motors' peak torque and no-load speed a reference may
            use (``torque_limit`` is that share of the peak; NaN when not checked).
        first_effort_violation: :class:`~.errors.MotorLimitError` of the first time
            a motor is over its limit, or None.
        clearance_profile: (t (m,) s, clearance (m,) m, resolution m) at the measured poses,
            kept even without ``series`` (a few bytes a pose): between two of them the parts
            are at least the smaller value less the resolution apart (the guard reads it,
            :class:`~stewart_drake.station.guard.DivergenceGuard`); () when not checked.
        series: the checks sample by sample, for plots: ``t`` (n,) s; ``margins`` dict name ->
            (n, 6) as :func:`~.limits.limit_margins`; ``cond``, ``sigma_min_inv`` (n,); with
            clearance, ``clearance_t`` (m,) s and ``clearance`` (m,) m at the measured poses;
            with motor limits, ``torque`` and ``speed`` (n, 6) in N m and rad/s (NaN where
            unreachable).
    """

    ok: bool
    min_margin: dict
    min_margin_leg: dict
    min_margin_t: dict
    first_violation: LimitViolation | None
    max_cond: float
    max_cond_t: float
    first_singular_t: float | None
    min_sigma_min_inv: float
    cond_threshold: float
    min_sigma_min_inv_t: float = float("nan")
    first_weak_t: float | None = None
    sigma_min_inv_threshold: float = 0.0
    min_clearance: float = float("nan")
    min_clearance_t: float = float("nan")
    min_clearance_parts: str = ""
    clearance_threshold: float = float("nan")
    first_interference: tuple | None = None
    design_clearance: float = float("nan")
    design_clearance_parts: str = ""
    peak_torque: float = float("nan")
    peak_torque_motor: int = -1
    peak_torque_t: float = float("nan")
    torque_limit: float = float("nan")
    peak_speed: float = float("nan")
    peak_speed_motor: int = -1
    peak_speed_t: float = float("nan")
    speed_limit: float = float("nan")
    first_effort_violation: MotorLimitError | None = None
    effort_margin: float = float("nan")
    series: dict = field(default_factory=dict, repr=False, compare=False)
    clearance_profile: tuple = field(default=(), repr=False, compare=False)

    @property
    def feasible(self) -> bool:
        """No motor over its torque or speed limit (True when they were not checked)."""
        return self.first_effort_violation is None

    def summary(self) -> str:
        """Human-readable lines: verdict, each limit's smallest margin, singularity."""
        lines = [("OK" if self.ok else "REFUSED") + ": trajectory validated"]
        lines += self._margin_lines() + self._clearance_lines() + self._effort_lines()
        return "\n".join(lines + self._first_lines())

    def _margin_lines(self) -> list:
        """The summary's lines of the limits' margins and the singularity measures."""
        lines = []
        for name in self.min_margin:  # the limits, in the order of limits.LIMITS
            m = self.min_margin[name]
            unit = f"{m:.4g}" if name == "closure" else f"{np.rad2deg(m):.4g} deg"
            lines.append(
                f"  {name:15s} min margin {unit} (leg {self.min_margin_leg[name]}, "
                f"t = {self.min_margin_t[name]:.4g} s)"
            )
        lines.append(
            f"  cond(J) max {self.max_cond:.4g} at t = {self.max_cond_t:.4g} s "
            f"(threshold {self.cond_threshold:g})"
        )
        lines.append(
            f"  1/sigma_max(J) min {self.min_sigma_min_inv:.4g} at "
            f"t = {self.min_sigma_min_inv_t:.4g} s "
            f"(threshold {self.sigma_min_inv_threshold:g})"
        )
        if self.first_singular_t is not None:
            lines.append(
                f"  closer to singularity than the threshold first at "
                f"t = {self.first_singular_t:.4g} s"
            )
        if self.first_weak_t is not None:
            lines.append(
                f"  1/sigma_max(J) below its threshold first at t = {self.first_weak_t:.4g} s"
            )
        return lines

    def _clearance_lines(self) -> list:
        """The summary's lines of the clearance between the parts (none when not checked)."""
        lines = []
        if np.isfinite(self.min_clearance):
            lines.append(
                f"  clearance       min {self.min_clearance * 1e3:.3g} mm "
                f"({self.min_clearance_parts}, t = {self.min_clearance_t:.4g} s; "
                f"threshold {self.clearance_threshold * 1e3:.3g} mm)"
            )
        if np.isfinite(self.design_clearance):
            lines.append(
                f"                  {self.design_clearance * 1e3:.3g} mm at every pose "
                f"({self.design_clearance_parts}: fixed by the design)"
            )
        return lines

    def _effort_lines(self) -> list:
        """The summary's lines of the motors' torque and speed (none when not checked)."""
        lines = []
        for name, unit, peak, motor, when, limit in (
            (
                "torque",
                "N m",
                self.peak_torque,
                self.peak_torque_motor,
                self.peak_torque_t,
                self.torque_limit,
            ),
            (
                "speed",
                "rad/s",
                self.peak_speed,
                self.peak_speed_motor,
                self.peak_speed_t,
                self.speed_limit,
            ),
        ):
            if np.isfinite(peak):
                bound = "no limit"
                if np.isfinite(limit):
                    motors = "peak" if name == "torque" else "no-load speed"
                    bound = (
                        f"limit {limit:.3g} {unit}, {100 * self.effort_margin:.3g} % of the "
                        f"motors' {limit / self.effort_margin:.3g} {unit} {motors}"
                    )
                lines.append(
                    f"  {name:15s} peak {peak:.3g} {unit} (motor {motor}, "
                    f"t = {when:.4g} s; {bound})"
                )
        return lines

    def _first_lines(self) -> list:
        """The summary's lines of the first refusal of each kind."""
        lines = []
        if self.first_violation is not None:
            lines.append(f"  first violation: {self.first_violation}")
        if self.first_interference is not None:
            t, a, b, d = self.first_interference
            lines.append(f"  first interference: {a} and {b} at {d * 1e3:.3g} mm, t = {t:.4g} s")
        if self.first_effort_violation is not None:
            e = self.first_effort_violation
            lines.append(
                f"  first motor over its limit: motor {e.motor} needs "
                f"{e.required:.3g} {'N m' if e.quantity == 'torque' else 'rad/s'} of "
                f"{e.quantity} (limit {e.limit:.3g}) at t = {e.t:.4g} s"
            )
        return lines


def merge_reports(reports) -> TrajectoryReport:
    """One :class:`TrajectoryReport` of a path checked in consecutive stretches of time: the
    report :func:`~.limits.validate_trajectory` gives for the whole path (each extreme with its
    time, leg or motor, each "first" the earliest), its ``series`` concatenated.

    Args:
        reports: the stretches' reports in time order, each from the same thresholds.
    Returns:
        :class:`TrajectoryReport`.
    """
    reports = list(reports)
    head = reports[0]
    if len(reports) == 1:
        return head

    def first(name):
        return next((v for r in reports if (v := getattr(r, name)) is not None), None)

    def extreme(value, fields, pick=min):
        ranked = [r for r in reports if not np.isnan(getattr(r, value))]
        if not ranked:
            return {}
        best = pick(ranked, key=lambda r: getattr(r, value))
        return {name: getattr(best, name) for name in (value, *fields)}

    min_margin, min_leg, min_t = {}, {}, {}
    for name in head.min_margin:  # the limits, in the order of limits.LIMITS
        best = min(reports, key=lambda r: r.min_margin[name])
        min_margin[name] = best.min_margin[name]
        min_leg[name], min_t[name] = best.min_margin_leg[name], best.min_margin_t[name]
    merged = replace(
        head,
        ok=all(r.ok for r in reports),
        min_margin=min_margin,
        min_margin_leg=min_leg,
        min_margin_t=min_t,
        first_violation=first("first_violation"),
        first_singular_t=first("first_singular_t"),
        first_weak_t=first("first_weak_t"),
        first_interference=first("first_interference"),
        first_effort_violation=first("first_effort_violation"),
        **extreme("max_cond", ("max_cond_t",), max),
        **extreme("min_sigma_min_inv", ("min_sigma_min_inv_t",)),
        **extreme("min_clearance", ("min_clearance_t", "min_clearance_parts")),
        **extreme("peak_torque", ("peak_torque_motor", "peak_torque_t"), max),
        **extreme("peak_speed", ("peak_speed_motor", "peak_speed_t"), max),
        series=_concatenated([r.series for r in reports]),
        clearance_profile=_joined_profiles([r.clearance_profile for r in reports]),
    )
    return merged


def _joined_profiles(profiles: list) -> tuple:
    """The clearance profiles of consecutive stretches as one (each stretch's first and last
    pose are measured, so the bound holds across their joins), or () when one is missing."""
    if not profiles or any(len(p) != 3 for p in profiles):
        return ()
    return (
        np.concatenate([p[0] for p in profiles]),
        np.concatenate([p[1] for p in profiles]),
        max(p[2] for p in profiles),
    )


def _concatenated(parts: list):
    """Dicts (nested) of arrays joined along their first axis; other values from the first."""
    if isinstance(parts[0], dict):
        keys = [k for k in parts[0] if all(k in p for p in parts)]
        return {k: _concatenated([p[k] for p in parts]) for k in keys}
    if isinstance(parts[0], np.ndarray):
        return np.concatenate(parts)
    return parts[0]
