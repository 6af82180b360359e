"""Organ motion as references of the platform pose: breathing, heartbeat and their variants.

A motion of the library is a frozen dataclass (:class:`~.core.LibraryMotion`) with
``evaluate(t)`` -> (pose, rate, acceleration), each ``t.shape + (6,)`` in [rad, rad, rad, m, m,
m] (and /s, /s^2), a :class:`~.motion.Reference` like every reference of :mod:`~.trajectories`,
plus what fidelity and learning need: ``frequencies_hz()`` (the fundamentals whose harmonics the
report analyses), ``repeat_period_s`` (the time after which the motion repeats exactly, or None)
and ``cycles(t_end)`` (the start of each cycle and its amplitude relative to the mean). Every
parameter is in SI units, its default and source in the class docstring; every motion is C2
(corners rounded by :func:`~.smoothstep.smoothstep`).

Motions by kind: :class:`~.breathing.Breathing` (Lujan et al., Med. Phys. 26, 715, 1999),
:class:`~.breathing.IrregularBreathing`, :class:`~.breathing.HysteresisBreathing`,
:class:`~.breathing.BreathHold`, :class:`~.heartbeat.Heartbeat`; the commercial phantoms' (CIRS
Motion Control) :class:`~.waveforms.Sawtooth`, :class:`~.waveforms.Sharkfin`,
:class:`~.excursions.BaselineDrift`, :class:`~.excursions.TransientExcursion`,
:class:`~.excursions.PersistentExcursion`. They add up (:class:`~.combinators.MotionSum`), lie
on another motion or a trace (:func:`~.combinators.layered`) and shrink about their centre
(:class:`~.combinators.ScaledReference`, for
:func:`~stewart_drake.organ_motion.reproduction.scale_to_fit`). :func:`~.library.make_motion`
builds one from a name and ``key=value`` parameters with units; a scenario's choice is
:class:`~.library.OrganMotionReference`. Recorded traces are :mod:`~.traces`'. The names,
models, defaults and sources, directions and axes: docs/organ_motion.md, "The motion library".

Modules: :mod:`.core` (axes, directions, the base class), :mod:`.breathing`, :mod:`.heartbeat`,
:mod:`.waveforms`, :mod:`.excursions`, :mod:`.combinators` and :mod:`.library`. None uses
``from __future__ import annotations``: Drake's YAML loader reads
:class:`~.library.OrganMotionReference`'s field types.
"""
