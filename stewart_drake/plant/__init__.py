"""The robot in a physics engine: the SDF (:mod:`.sdf`), the discrete SAP ``MultibodyPlant`` with
its ball-constraint loops (:mod:`.plant`), the closed chain's assembly, loop closure and inverse
dynamics (:mod:`.closed_chain`), clearance between parts from ``SceneGraph`` and the admissible
set of poses that uses it, the rods' ball joints, and the same robot in MuJoCo (:mod:`.mjcf`).
Imports base and robot."""
