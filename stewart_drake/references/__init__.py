"""What a run tracks: the Reference protocol (:mod:`.motion`), trajectories and CSV
references (:mod:`.trajectories`), the organ-motion library (:mod:`.organ`) and recorded
traces (:mod:`.traces`). Imports base and robot."""
