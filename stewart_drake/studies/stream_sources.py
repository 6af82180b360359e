"""The sources a stream predictor is chosen across and judged on: the motion library, IntERAct's
patients' traces, and the forms real inputs take (a slower tracker, 0.1 mm steps, noise,
outliers, dropouts, irregular and slowly drifting breathing).

A source is a set of motions (:class:`~.stream_study.StreamCase`) streamed in one
:class:`StreamForm`: the true motion is what the follower is judged against, and the form is
what happens to its samples on the way (the tracker's rate, its resolution, its noise, its
glitches). :func:`sources` lists them; :mod:`~.stream_selection` leaves each out in turn.

The forms' sizes are ours, chosen to match what the inputs show: an external-marker export at
10 Hz written in 0.1 mm steps; 0.3 mm of white noise (an optical tracker's, the order of
Krauss et al. 2011's); 1 % of samples off by a few mm (a reflection, a marker swap); 5 % of
samples lost and the last one repeated in their place (an occluded marker, as RPM-style
exports write it). They are drawn from a seeded generator: the same source is the same samples.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from ..base.checks import check_int
from ..base.errors import InvalidConfigError
from .stream_study import LIBRARY_S, StreamCase, stream_cases

#: The library's motions the forms are laid on (label, motion, parameters).
FORM_BASES = (
    ("breathing", "breathing", ()),
    ("irregular breathing", "irregular_breathing", (("seed", "3"),)),
    ("breathing 4.2 s + heartbeat", "breathing_heartbeat", (("period", "4.2s"),)),
    ("sharkfin", "sharkfin", ()),
    ("hysteresis", "hysteresis", ()),
)


@dataclass(frozen=True)
class StreamForm:
    """What happens to a motion's samples on their way to the follower (translations only: a
    marker's position).

    Attributes:
        rate_hz: the tracker's rate, Hz; None: the motion's own (a trace's) or 25 Hz.
        quantum_m: the resolution the positions are written in, m (0: exact).
        noise_m: the standard deviation of white noise on each translation, m.
        outlier_share: the share of samples off by a random 3-D offset ...
        outlier_m: ... of this standard deviation per axis, m.
        dropout_share: the share of samples lost, the one before repeated in their place.
        seed: of the draws.
    Raises:
        InvalidConfigError: a size < 0, a share outside [0, 0.5] or a seed that is not an
            integer >= 0.
    """

    rate_hz: float | None = None
    quantum_m: float = 0.0
    noise_m: float = 0.0
    outlier_share: float = 0.0
    outlier_m: float = 0.003
    dropout_share: float = 0.0
    seed: int = 0

    def __post_init__(self):
        for name in ("quantum_m", "noise_m", "outlier_m"):
            if not (np.isfinite(getattr(self, name)) and getattr(self, name) >= 0):
                raise InvalidConfigError(f"{name} must be >= 0 m, got {getattr(self, name)!r}")
        for name in ("outlier_share", "dropout_share"):
            if not 0 <= getattr(self, name) <= 0.5:
                raise InvalidConfigError(f"{name} must be in [0, 0.5], got {getattr(self, name)!r}")
        # None would draw other samples at every run: the same source, the same samples.
        check_int("seed", self.seed, 0)

    def apply(self, stream):
        """``stream`` (a :class:`~stewart_drake.references.stream.Stream` of the true motion)
        with its samples as this form writes them: noise, outliers, then dropouts (the sample
        before repeated), then the resolution."""
        rng = np.random.default_rng(self.seed)
        poses = np.array(stream.poses, dtype=float)
        n = poses.shape[0]
        if self.noise_m > 0:
            poses[:, 3:] += rng.normal(0.0, self.noise_m, (n, 3))
        if self.outlier_share > 0:
            hit = rng.random(n) < self.outlier_share
            poses[hit, 3:] += rng.normal(0.0, self.outlier_m, (int(hit.sum()), 3))
        if self.dropout_share > 0:
            for i in np.flatnonzero(rng.random(n) < self.dropout_share):
                if i > 0:
                    poses[i] = poses[i - 1]
        if self.quantum_m > 0:
            poses[:, 3:] = np.round(poses[:, 3:] / self.quantum_m) * self.quantum_m
        return replace(stream, poses=poses)

    def words(self) -> str:
        """The form in a few words ("10 Hz, 0.1 mm steps")."""
        parts = [f"{self.rate_hz:g} Hz"] if self.rate_hz else []
        if self.quantum_m:
            parts.append(f"{self.quantum_m * 1e3:g} mm steps")
        if self.noise_m:
            parts.append(f"{self.noise_m * 1e3:g} mm noise")
        if self.outlier_share:
            parts.append(f"{self.outlier_share * 100:g} % outliers of {self.outlier_m * 1e3:g} mm")
        if self.dropout_share:
            parts.append(f"{self.dropout_share * 100:g} % dropouts")
        return ", ".join(parts) or "as sampled"


@dataclass(frozen=True)
class Source:
    """One source: ``cases`` streamed in ``form``; ``name`` says which."""

    name: str
    cases: tuple
    form: StreamForm = StreamForm()


def _bases() -> tuple:
    return tuple(StreamCase(label, motion, parameters) for label, motion, parameters in FORM_BASES)


def sources(traces=None) -> list:
    """The sources: "library" (its 11 motions at 25 Hz), "IntERAct" (its 14 traces at their own
    rate, when ``traces`` names the folder holding them), then the forms laid on
    :data:`FORM_BASES`: "10 Hz", "10 Hz, 0.1 mm steps", "25 Hz, 0.3 mm noise", "1 % outliers",
    "5 % dropouts"; and two sources of their own motion: "irregular" (irregular breathing of
    other seeds and wider variation than the library's) and "drifting" (breathing on a drift of
    its baseline)."""
    cases = stream_cases(traces)
    library = tuple(c for c in cases if c.tuned_on)
    found = tuple(c for c in cases if not c.tuned_on)
    bases = _bases()
    out = [Source("library", library)]
    if found:
        out.append(Source("IntERAct", found))
    out += [
        Source("10 Hz", bases, StreamForm(rate_hz=10.0)),
        Source("10 Hz, 0.1 mm steps", bases, StreamForm(rate_hz=10.0, quantum_m=1e-4, seed=1)),
        Source("0.3 mm noise", bases, StreamForm(rate_hz=25.0, noise_m=3e-4, seed=2)),
        Source("1 % outliers", bases, StreamForm(rate_hz=25.0, outlier_share=0.01, seed=3)),
        Source("5 % dropouts", bases, StreamForm(rate_hz=25.0, dropout_share=0.05, seed=4)),
    ]
    irregular = tuple(
        StreamCase(
            f"irregular breathing, seed {seed}, cv {cv:g}",
            "irregular_breathing",
            (("seed", str(seed)), ("amplitude_cv", str(cv)), ("period_cv", str(cv))),
        )
        for seed, cv in ((11, 0.2), (12, 0.25), (13, 0.3), (14, 0.2))
    )
    drifting = tuple(
        StreamCase(label, "breathing+baseline_drift", parameters)
        for label, parameters in (
            ("breathing, 5 mm drift over 60 s", (("drift", "5mm"),)),
            ("breathing, 3 mm drift back and forth every 40 s",
             (("drift", "3mm"), ("drift_period", "40s"))),
            ("breathing 3.2 s, -4 mm drift over 90 s",
             (("period", "3.2s"), ("drift", "-4mm"), ("drift_duration", "90s"))),
        )
    )  # fmt: skip
    out += [Source("irregular", irregular), Source("drifting", drifting)]
    return out


#: The random walk's step every 10 ms, m per axis: about 10 mm over 120 s.
WALK_STEP_M = 1e-4


def random_walk(seed: int = 0, duration_s: float = LIBRARY_S):
    """A random walk of the translations about home (each axis a sum of independent normal
    steps of :data:`WALK_STEP_M` every 10 ms, seeded), joined by a C2 spline: the motion whose
    best prediction is its newest sample (its increments are independent), so a predictor can
    only lose on it."""
    from ..references.organ.library import X_HOME
    from ..references.samples import CubicSplineTrajectory

    t = np.arange(0.0, duration_s + 1e-9, 0.01)
    poses = np.tile(np.asarray(X_HOME, dtype=float), (t.size, 1))
    steps = np.random.default_rng(seed).normal(0.0, WALK_STEP_M, (t.size, 3))
    poses[:, 3:] += np.cumsum(steps, axis=0) - steps[0]
    return CubicSplineTrajectory(t, poses, name=f"random walk {seed}")


def hurting() -> list:
    """Motions on which prediction cannot pay, to show the fallback (never in the selection):
    random walks (:func:`random_walk`, whose best prediction is none), and breathing with 10 %
    of its samples 10 mm off."""
    from functools import partial

    breathing = (StreamCase("breathing", "breathing"),)
    walks = tuple(
        StreamCase(f"random walk, seed {seed}", made_by=partial(random_walk, seed))
        for seed in (1, 2, 3)
    )
    return [
        Source("random walk", walks, StreamForm(rate_hz=25.0)),
        Source(
            "10 % outliers of 10 mm",
            breathing,
            StreamForm(rate_hz=25.0, outlier_share=0.1, outlier_m=0.01, seed=7),
        ),
    ]


__all__ = [
    "FORM_BASES",
    "WALK_STEP_M",
    "StreamForm",
    "Source",
    "sources",
    "random_walk",
    "hurting",
    "LIBRARY_S",
]
