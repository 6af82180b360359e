"""A run, whatever asks for it (a study, the replay, the robot): the scenario's schema and
files, the plan derived once from it, the closed-loop Diagram, the learner's wiring, the
simulation with its guard, the logs, the result file and the figures of a run (:mod:`.metrics`).
The top of the core."""
