"""What a run tracks: the Reference protocol (:mod:`.motion`), trajectories and CSV
references (:mod:`.trajectories`), the organ-motion library (:mod:`.organ_motion`) and recorded
traces (:mod:`.traces`). Imports base and robot."""
