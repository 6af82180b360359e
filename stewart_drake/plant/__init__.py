"""The robot in a physics engine: the SDF and the discrete SAP ``MultibodyPlant`` with its
ball-constraint loops, assembly and closed-chain inverse dynamics (:mod:`.plant`), clearance
between parts from ``SceneGraph`` and the admissible set of poses that uses it, the rods' ball
joints, and the same robot in MuJoCo (:mod:`.mjcf`). Imports base and robot."""
