"""stewart-drake: a 6-DOF rotary Stewart platform on a Drake closed-chain MultibodyPlant.

Layers, imports flowing one way (a test walks them): base (errors, checks, fileio) -> model
(geometry, kinematics, statics, limits, plant) -> control (LQI, PD, features, tuner) ->
simulation (trajectories, reference, guard, scenario, station, diagram) -> studies (experiments,
collection, training, evaluation, workspace, runners, store) -> interfaces (cli, visualize).
"""

from .errors import (
    ForwardKinematicsError,
    InvalidConfigError,
    InvalidGeometryError,
    RiccatiSolveError,
    SimulationDivergedError,
    StewartError,
    UnreachablePoseError,
)
from .model.geometry import X_HOME, StewartGeometry, reference_geometry

__all__ = [
    "ForwardKinematicsError",
    "InvalidConfigError",
    "InvalidGeometryError",
    "RiccatiSolveError",
    "SimulationDivergedError",
    "StewartError",
    "UnreachablePoseError",
    "StewartGeometry",
    "X_HOME",
    "reference_geometry",
]
__version__ = "0.1.0"
