"""stewart-drake: a 6-DOF rotary Stewart platform on a Drake closed-chain MultibodyPlant.

Modules, in the one direction data flows: geometry -> kinematics -> plant -> controller /
features / tuner -> trajectories -> diagram -> experiments -> cli.
"""

from .errors import (ForwardKinematicsError, InvalidConfigError, InvalidGeometryError,
                     RiccatiSolveError, SimulationDivergedError, StewartError,
                     UnreachablePoseError)
from .geometry import X_HOME, StewartGeometry, reference_geometry

__all__ = [
    "ForwardKinematicsError", "InvalidConfigError", "InvalidGeometryError", "RiccatiSolveError",
    "SimulationDivergedError", "StewartError", "UnreachablePoseError", "StewartGeometry",
    "X_HOME", "reference_geometry",
]
__version__ = "0.1.0"
