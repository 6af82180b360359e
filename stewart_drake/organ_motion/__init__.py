"""Organ motion reproduced: a breathing, heartbeat or recorded trace run on the robot as
built, with or without learning (:mod:`.reproduction`, ``stewart-drake reproduce``), its fidelity
(RMS, peak, lag, gamma pass rate, harmonics: :mod:`.fidelity`) with a verdict, and its report
(:mod:`.fidelity_report`, :mod:`.fidelity_replay`); the library's and the traces' studies."""
