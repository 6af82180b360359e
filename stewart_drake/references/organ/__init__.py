"""Organ motion as references of the platform pose: breathing, heartbeat and their variants.

A motion of the library is a frozen dataclass with ``evaluate(t)`` -> (pose, rate,
acceleration), each ``t.shape + (6,)`` in [rad, rad, rad, m, m, m] (and /s, /s^2), a
:class:`~.motion.Reference` like every reference of :mod:`~.trajectories`, plus what fidelity
and learning need: ``frequencies_hz()`` (the fundamentals whose harmonics the report analyses),
``repeat_period_s`` (the time after which the motion repeats exactly, or None) and
``cycles(t_end)`` (the start of each cycle and its amplitude relative to the mean, for per-cycle
errors and the learning controller's alignment). What every motion shares is in :mod:`.core`
(:class:`~.core.LibraryMotion`, the axes and directions).

Motions (every parameter in SI units, its default and source in the class docstring), by kind:

=========================  =====================================================================
``breathing``              :class:`~.breathing.Breathing`, Lujan et al., Med. Phys. 26, 715
                           (1999): z(t) = z0 - b cos^(2n)(pi t / tau - phi), with a direction
                           and a tilt
``heartbeat``              :class:`~.heartbeat.Heartbeat`: a fundamental at the heart rate and
                           harmonics
``breathing_heartbeat``    :class:`~.combinators.MotionSum` of the two
``irregular_breathing``    :class:`~.breathing.IrregularBreathing`: amplitude and period drawn
                           per cycle, seeded
``hysteresis``             :class:`~.breathing.HysteresisBreathing`: different inhale and exhale
                           paths
``sawtooth``               :class:`~.waveforms.Sawtooth`: straight ramps in and out, corners
                           rounded
``sharkfin``               :class:`~.waveforms.Sharkfin`: a fast inhale, an exponential exhale,
                           rounded
``baseline_drift``         :class:`~.excursions.BaselineDrift`: a linear or sinusoidal drift of
                           the mean
``transient_excursion``    :class:`~.excursions.TransientExcursion`: away for a while, then back
``persistent_excursion``   :class:`~.excursions.PersistentExcursion`: a smooth step to a new
                           baseline
``breath_hold``            :class:`~.breathing.BreathHold`: breathing that stops at a phase,
                           then resumes
=========================  =====================================================================

The last six are the library of the commercial motion phantoms (CIRS Motion Control), each C2:
where the phantom's waveform has a corner, a smoothstep blend over a stated time replaces it
(:func:`~.smoothstep.smoothstep`). A drift or an excursion is a displacement alone;
:func:`~.combinators.layered` lays it on another motion or on a recorded trace (``reproduce
breathing --add baseline_drift``, a scenario's ``add``).

Directions are vectors in the platform frame or axis names: the platform's ``X``, ``Y``, ``Z``
or the patient's ``SI``, ``LR``, ``AP`` (:data:`~.core.PATIENT_AXES`: the patient lies supine
along the platform's X axis, head towards +X, left towards +Y, anterior up), with an optional
sign. :func:`~.library.make_motion` builds a motion from a name and ``key=value`` parameters
carrying units ("amplitude=15mm", "rate=72bpm", "direction=SI"), as the CLI and scenarios give
them; :class:`~.library.OrganMotionReference` is a scenario's choice of one.

References add up (:class:`~.combinators.MotionSum`) and shrink about their centre
(:class:`~.combinators.ScaledReference`:
:func:`~stewart_drake.organ_motion.reproduction.scale_to_fit` finds the scale the one reference
validator accepts). Recorded traces of organ motion are read by :mod:`~.traces`.

Modules: :mod:`.core` (axes, directions, the base class), :mod:`.breathing`, :mod:`.heartbeat`,
:mod:`.waveforms` and :mod:`.excursions` (the motions by kind), :mod:`.combinators` (sum,
layers, scale) and :mod:`.library` (by name, with units; the scenario's choice). None uses
``from __future__ import annotations``: Drake's YAML loader reads
:class:`~.library.OrganMotionReference`'s field types.
"""
