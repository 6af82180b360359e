"""The robot behind ports: the simulated station (:mod:`.station`) and the servo-bus
station (:mod:`.bus`), siblings with one port contract; the sensors, the guard of a run and the
LCM publishers; beside the robot, an external surrogate's stage with the signal it follows and the
pair's figures (:mod:`.surrogate`). Imports the core below it, never the run."""
