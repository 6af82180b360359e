"""What a kelvin costs: the platform's error when the robot is warmer or colder than its lengths
were measured at and the controller does not know it.

A robot's lengths hold at its ``lengths_at_c``
(:class:`~stewart_drake.robot.geometry.StewartGeometry`); at another temperature its rods and the
rest of its loop expand (:meth:`~stewart_drake.robot.geometry.StewartGeometry.at_temperature`).
A controller that keeps the lengths as measured puts the motors at the angles its inverse
kinematics gives for a pose; the warm robot at those angles is elsewhere, by its own forward
kinematics (:func:`temperature_error`). :func:`temperature_table` gives those figures per kelvin
at typical poses, rods, frame and the whole robot apart (docs/calibration.md, "Temperature").
"""

from __future__ import annotations

import numpy as np

from ..base.checks import as_number, as_poses
from ..base.tables import markdown_table
from .forward_kinematics import fk
from .geometry import StewartGeometry
from .kinematics import ik, rotation_rpy

#: Typical poses of the budget, (name, pose [phi, theta, psi, X, Y, Z] in rad and m): home, the
#: translations and rotations an organ-motion trace or the paper's manoeuvre reaches.
TYPICAL_POSES = (
    ("home", (0.0, 0.0, 0.0, 0.0, 0.0, 0.30)),
    ("X +30 mm", (0.0, 0.0, 0.0, 0.03, 0.0, 0.30)),
    ("Z -30 mm", (0.0, 0.0, 0.0, 0.0, 0.0, 0.27)),
    ("Z +30 mm", (0.0, 0.0, 0.0, 0.0, 0.0, 0.33)),
    ("roll 0.1 rad", (0.1, 0.0, 0.0, 0.0, 0.0, 0.30)),
    ("yaw 0.1 rad", (0.0, 0.0, 0.1, 0.0, 0.0, 0.30)),
)


def temperature_error(geometry: StewartGeometry, x, delta_k: float = 1.0):
    """How far the platform is from the poses ``x`` when the robot is ``delta_k`` warmer than
    ``geometry``'s ``lengths_at_c`` and its motors hold the angles ``geometry``'s inverse
    kinematics gives for ``x`` (a controller on the lengths as measured).

    Args:
        geometry: the robot as its lengths were measured.  x: (6,) or (N, 6) poses, rad and m.
        delta_k: K, the warm robot's temperature minus ``geometry.lengths_at_c`` (negative:
            colder).
    Returns:
        (moved, turned): (N,) each, the translation's norm, m, and the rotation's angle, rad,
        of the warm robot's pose (:func:`~.forward_kinematics.fk` from ``x``) against ``x``.
    Raises:
        UnreachablePoseError: a pose ``geometry`` cannot reach. ForwardKinematicsError: the warm
            robot has no pose near ``x`` at those angles. InvalidGeometryError: a temperature
            out of :data:`~.geometry.TEMPERATURE_RANGE_C`. InvalidConfigError: x not (..., 6).
    """
    x = as_poses("pose x", x).reshape(-1, 6)
    delta_k = as_number("delta_k", delta_k)
    warm = geometry.at_temperature(geometry.lengths_at_c + delta_k)
    x_warm, _ = fk(warm, ik(geometry, x), x0=x)
    moved = np.linalg.norm(x_warm[:, 3:] - x[:, 3:], axis=-1)
    R = np.einsum("nij,nkj->nik", rotation_rpy(x_warm[:, :3]), rotation_rpy(x[:, :3]))
    cos = np.clip(0.5 * (np.trace(R, axis1=-2, axis2=-1) - 1.0), -1.0, 1.0)
    return moved, np.arccos(cos)


def temperature_table(
    geometry: StewartGeometry | None = None, poses=TYPICAL_POSES, workspace=None
) -> str:
    """The budget of a kelvin as a Markdown table: per pose of ``poses`` ((name, (6,)) pairs),
    the platform's error per K (:func:`temperature_error` at 1 K) with the rods alone
    expanding, the rest of the loop alone (cranks, base, platform), and the whole robot, each
    at ``geometry``'s coefficients; with ``workspace``, a last row of its median (largest).

    Args:
        geometry: the robot (default the reference robot, aluminium throughout).
        poses: (name, pose) pairs.  workspace: None, or (N, 6) admissible poses, rad and m.
    Returns:
        the table's text, um/K and urad/K, a line per pose.
    Raises:
        as :func:`temperature_error`.
    """
    geometry = geometry if geometry is not None else StewartGeometry()
    a_rod, a_frame = geometry.rod_expansion_per_k, geometry.frame_expansion_per_k
    cases = (
        geometry.replace(frame_expansion_per_k=0.0),
        geometry.replace(rod_expansion_per_k=0.0),
        geometry,
    )
    x = np.array([pose for _, pose in poses], dtype=float)
    figures = [temperature_error(g, x, 1.0) for g in cases]
    header = (
        "pose",
        f"rods alone ({a_rod * 1e6:g}e-6/K)",
        f"cranks, base and platform alone ({a_frame * 1e6:g}e-6/K)",
        "the whole robot",
    )
    rows = [
        [name] + [f"{m[k] * 1e6:.2f} um, {r[k] * 1e6:.2f} urad" for m, r in figures]
        for k, (name, _) in enumerate(poses)
    ]
    if workspace is not None:
        x = as_poses("workspace", workspace).reshape(-1, 6)
        row = [f"{len(x)} admissible poses: median (largest)"]
        for g in cases:
            m, r = temperature_error(g, x, 1.0)
            row.append(
                f"{np.median(m) * 1e6:.2f} ({m.max() * 1e6:.2f}) um, "
                f"{np.median(r) * 1e6:.2f} ({r.max() * 1e6:.2f}) urad"
            )
        rows.append(row)
    return markdown_table(header, rows) + "\n"
