"""The external surrogate beside the platform, all of it: a 1-DoF linear stage (`linear_stage`)
in the run's Diagram and on its clock (`stage`, with `axis` the scenario's section) and as a
seventh servo on the robot's bus (`bus_servo`), its command on the robot (`carriage`), lag
matched to the platform (`lag_matching`, `lag_matched_goal`); the external signal it follows, from
a recorded trace (`trace`, `pairs`) or from a library motion through a correlation model
(`correlation`); and the figures that judge the pair (`sync_figures`: relative latency, lead,
hysteresis, correlation, drift; `report`; on the robot, `encoder_relative_latency`). A measured
pair is judged by ``verify --surrogate`` (:mod:`stewart_drake.verification.pair_judgement`)."""
