"""The tuners of the LQI's weights omega_Q, omega_R as Drake systems: the paper's ANN
(:mod:`.ann`) and our ratio tuner (:mod:`.ratio`), whose networks share one file format
(:mod:`.network`). The scenario's tuner choices that wire them into the Diagram:
:mod:`~stewart_drake.control.tuning`."""
