"""The robot: geometry, kinematics (IK, FK, Jacobian, wrench map), statics, joint limits, plant.

The lowest layer of stewart-drake: nothing here imports control, simulation, studies or
interfaces. Order inside: kinematics -> limits -> statics -> geometry -> plant.
"""
