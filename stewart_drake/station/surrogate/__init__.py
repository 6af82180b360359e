"""The external surrogate beside the platform, all of it: a 1-DoF linear stage (`linear_stage`)
in the run's Diagram and on its clock (`stage`, with `axis` the scenario's section) and as a
seventh servo on the robot's bus (`bus_servo`), its command on the robot (`carriage`), lag
matched to the platform (`lag_matching`, `lag_matched_goal`); the external signal it follows, from
a recorded trace (`trace`, `pairs`) or from a library motion through a correlation model
(`correlation`). The station holds the surrogate's hardware and its command only: the figures of
a pair are measured by :mod:`stewart_drake.base.pair_figures`, the one definition of each; a pair
reproduced in the Diagram is reported by :mod:`stewart_drake.organ_motion.surrogate_pair`, one on
the robot judged from its encoders by :mod:`stewart_drake.live.session_surrogate`, and a measured
pair by ``verify --surrogate`` (:mod:`stewart_drake.verification.pair_judgement`)."""
