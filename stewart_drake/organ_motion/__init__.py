"""Organ motion reproduced: a breathing, heartbeat or recorded trace run on the robot as
built, with or without learning (:mod:`.reproduction`, ``stewart-drake reproduce``), its fidelity
(RMS, peak, lag, gamma pass rate, harmonics: :mod:`.fidelity`) with a verdict, and its report
(:mod:`.fidelity_report`, :mod:`.fidelity_replay`); example inputs to try them on
(:mod:`.examples`, ``stewart-drake examples``). A motion measured on a real phantom is judged
with the same figures and report by ``stewart-drake verify`` (:mod:`stewart_drake.verification`);
the studies of the library's motions and the traces are :mod:`stewart_drake.studies`'s."""

#: The scenario organ motion is reproduced on unless told (``reproduce``, the trace study): the
#: robot as built with its LQI set for organ motion, the reference's inverse dynamics and 0.7 x
#: the motors' Coulomb friction fed forward (``scenarios/phantom_hardware.yaml``;
#: docs/organ_motion.md, "The friction feed-forward as built").
SCENARIO = "phantom_hardware"
