"""Organ motion reproduced: a breathing, heartbeat or recorded trace run on the robot as
built, with or without learning, and its fidelity (RMS, peak, gamma pass rate) with a verdict
(:mod:`.fidelity`, ``stewart-drake reproduce``); the library's and the traces' studies."""
