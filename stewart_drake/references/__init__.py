"""What a run tracks: the Reference protocol (:mod:`.motion`), trajectories (:mod:`.trajectories`:
sines, steps, sweeps, adapters and the check of a reference before a run), references from
samples and the reference CSV (:mod:`.samples`), the tuner's data-collection excitation
(:mod:`.data_collection`), the organ-motion library (:mod:`.organ`), recorded traces
(:mod:`.traces`, their files read by :mod:`.trace_files`), the one quintic smoothstep
(:mod:`.smoothstep`) and the robot's run on it: a homing lead-in, then the reference started and
ended at rest (:mod:`.homing`). Imports base and robot."""
