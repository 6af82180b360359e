"""The robot on paper, numpy: geometry and inertia (:mod:`.geometry`), closed-form kinematics
(IK eq. 6, FK, Jacobian, wrench map), statics and feed-forward, joint limits and the one
reference validator (its per-pose arithmetic also compiled by numba, :mod:`.path_kernels`), the
robot as built leg by leg and the tolerances that draw it (:mod:`.legs`, :mod:`.tolerances`),
the solid parts, the servo and the motor catalogue. Imports only base."""
