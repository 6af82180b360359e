"""Typed errors of stewart-drake; every message says what to change.

All inherit from :class:`StewartError` so callers can catch the family at once.
"""

from __future__ import annotations


class StewartError(Exception):
    """Base class of every error raised on purpose by stewart-drake."""


class InvalidGeometryError(StewartError, ValueError):
    """A geometry (lengths, anchors, inertias) that cannot describe a real robot."""


class InvalidConfigError(StewartError, ValueError):
    """A simulation or controller setting out of its valid range."""


class UnreachablePoseError(StewartError, ValueError):
    """A pose that one leg cannot reach: |L| / sqrt(M^2 + N^2) > 1 (paper eq. 6).

    Attributes:
        leg: index 0..5 of the first leg that cannot close (reference_geometry.md order).
        ratio: |L| / sqrt(M^2 + N^2) of that leg; > 1 means unreachable.
        t: time in s along a trajectory, or None for a single pose.
        pose: the (6,) pose [phi, theta, psi, X, Y, Z] that failed, if known.
    """

    def __init__(self, leg: int, ratio: float, t: float | None = None, pose=None):
        self.leg = int(leg)
        self.ratio = float(ratio)
        self.t = None if t is None else float(t)
        self.pose = None if pose is None else [float(v) for v in pose]
        where = "" if self.t is None else f" at t = {self.t:.4g} s"
        at = "" if self.pose is None else (
            " (pose [phi, theta, psi, X, Y, Z] = ["
            + ", ".join(f"{v:.4g}" for v in self.pose) + "])")
        super().__init__(
            f"leg {self.leg} cannot reach the pose{where}{at}: "
            f"|L|/sqrt(M^2+N^2) = {self.ratio:.4g} > 1. Bring the pose closer to home "
            f"[0, 0, 0, 0, 0, 0.30] or reduce the trajectory's amplitude.")


class RiccatiSolveError(StewartError, RuntimeError):
    """The discrete algebraic Riccati equation (paper eqs. 31-32) had no stabilizing solution."""


class SimulationDivergedError(StewartError, RuntimeError):
    """A simulation left its safe envelope; the data up to then is saved at ``path``."""

    def __init__(self, message: str, t: float, path: str | None = None):
        self.t = float(t)
        self.path = path
        saved = f"; data up to then saved in {path}" if path else ""
        super().__init__(f"simulation diverged at t = {self.t:.4g} s: {message}{saved}")


class ForwardKinematicsError(StewartError, RuntimeError):
    """Newton iteration of the forward kinematics did not converge."""


class RenderToolMissingError(StewartError, RuntimeError):
    """An external renderer (Graphviz ``dot``, a browser) needed for a picture is not installed."""
