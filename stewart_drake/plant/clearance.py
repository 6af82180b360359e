"""Clearance between the robot's parts at any platform pose, from Drake's ``SceneGraph``.

:class:`ClearanceModel` builds the robot's plant with its collision geometry
(:func:`~.parts.robot_parts`), assembles it at a pose (:func:`~.closed_chain.assemble`: cranks from
the IK, rods from crank tip to platform joint) and asks the ``SceneGraph`` for the signed distance
of every pair of parts that may collide
(``QueryObject.ComputeSignedDistancePairwiseClosestPoints``): positive = apart, negative =
interpenetrating. Pairs that touch by design are filtered by Drake itself: a body and the bodies it
is jointed to (base-crank, crank-rod), and the shapes of one body. A rod end's sphere and its socket
on the platform are not both collision geometry (the socket's stud is drawn only), so a rod's tube
crossing the platform's plate is measured like any other pair.
The rod ends' spheres at the platform are centred on the platform joints: their distances to the
platform's parts and to each other are the same at every pose (``ClearanceModel.fixed``,
5 mm on the reference robot). They are measured once, at home, and filtered from the per-pose
queries, so that a path's clearance is that of the parts its motion brings together.

Every check of the project that asks whether parts collide calls this module: the reference
validator (:func:`~.limits.validate_trajectory`), the workspace maps, the guard of a run without
contact, ``stewart-drake check``.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from pydrake.geometry import CollisionFilterDeclaration, GeometrySet, Role
from pydrake.systems.framework import DiagramBuilder

from ..base.checks import as_number, as_poses
from ..robot.geometry import StewartGeometry
from ..robot.kinematics import angular_velocity_map, ik, ik_unchecked

#: Distances beyond this are not computed exactly (Drake's broad phase skips the pair), m.
QUERY_DISTANCE_M = 0.1


@dataclass(frozen=True)
class Contact:
    """The closest pair of parts at one pose.

    Attributes:
        distance: signed distance, m (negative: the parts overlap by that much).
        part_a, part_b: "link/shape" names, e.g. "rod_2/tube", "base/plate".
        p_WA, p_WB: (3,) closest points on each part, world frame, m.
    """

    distance: float
    part_a: str
    part_b: str
    p_WA: np.ndarray
    p_WB: np.ndarray

    def __str__(self) -> str:
        return f"{self.part_a} and {self.part_b} {_describe(self.distance)}"


def _describe(distance: float) -> str:
    return (
        f"{distance * 1e3:.3g} mm apart"
        if distance >= 0
        else f"overlap by {-distance * 1e3:.3g} mm"
    )


def family(part: str) -> str:
    """ "rod_2/tube" -> "rod tube": a part's kind without its leg number."""
    link, _, shape = part.partition("/")
    strip = lambda name: name.rstrip("0123456789").rstrip("_")  # noqa: E731
    return f"{strip(link)} {strip(shape)}".strip()


class ClearanceModel:
    """Signed distances between the robot's parts at platform poses (module docstring).

    Args:
        geometry: the robot (its part sizes are fields of
            :class:`~stewart_drake.robot.geometry.StewartGeometry`).
    Attributes:
        geometry; pairs: the (part_a, part_b) names of every pair whose distance changes with
            the pose (the per-pose queries).
        fixed: the pairs whose distance is the same at every pose (rod ends on the platform
            joints against the platform and each other), :class:`Contact` at home, closest first.
        plant: its MultibodyPlant (with collision geometry): the positions ``q`` that
            :meth:`contacts` takes are this plant's (a station's plant has the same layout).
    """

    def __init__(self, geometry: StewartGeometry | None = None):
        from .plant import add_stewart_plant

        self.geometry = geometry or StewartGeometry()
        builder = DiagramBuilder()
        self._plant, self._scene_graph, self._handles = add_stewart_plant(
            builder, self.geometry, contact=True
        )
        self.plant = self._plant
        self._diagram = builder.Build()
        self._context = self._diagram.CreateDefaultContext()
        self._plant_context = self._plant.GetMyMutableContextFromRoot(self._context)
        self._sg_context = self._scene_graph.GetMyContextFromRoot(self._context)
        inspector = self._scene_graph.model_inspector()
        self._names = {}
        for gid in inspector.GetGeometryIds(
            GeometrySet(inspector.GetAllGeometryIds()), Role.kProximity
        ):
            body = self._plant.GetBodyFromFrameId(inspector.GetFrameId(gid))
            self._names[gid] = f"{body.name()}/{inspector.GetName(gid).split('::')[-1]}"
        # Pose-independent pairs: measured at home, then filtered from the queries.
        tops = [gid for gid, name in self._names.items() if name.endswith("/end_top")]
        platform = [gid for gid, name in self._names.items() if name.startswith("platform/")]
        query = self._scene_graph.get_query_output_port().Eval(self._sg_context)
        fixed = [
            query.ComputeSignedDistancePairClosestPoints(a, b)
            for k, a in enumerate(tops)
            for b in tops[k + 1 :] + platform
        ]
        self.fixed = sorted((self._contact(query, r) for r in fixed), key=lambda c: c.distance)
        self._scene_graph.collision_filter_manager(
            self._scene_graph.GetMyMutableContextFromRoot(self._context)
        ).Apply(
            CollisionFilterDeclaration()
            .ExcludeWithin(GeometrySet(tops))
            .ExcludeBetween(GeometrySet(tops), GeometrySet(platform))
        )
        inspector = self._scene_graph.get_query_output_port().Eval(self._sg_context).inspector()
        self.pairs = tuple(
            sorted(
                tuple(sorted((self._names[a], self._names[b])))
                for a, b in inspector.GetCollisionCandidates()
            )
        )

    def contacts(self, x, max_distance: float = QUERY_DISTANCE_M, q=None) -> list[Contact]:
        """Every pair of parts closer than ``max_distance`` at pose x, closest first.

        Args:
            x: (6,) reachable pose [rad, m].
            max_distance: m; farther pairs are left out.
            q: the plant positions of x when already computed
                (:func:`~.closed_chain.assembled_positions`).
        Raises:
            UnreachablePoseError: x cannot be assembled. InvalidConfigError: x not (6,) finite.
        """
        from .closed_chain import assembled_positions

        if q is None:
            x = as_poses("pose x", x).reshape(6)
            ik(self.geometry, x)  # names an unreachable leg
            q = assembled_positions(self._plant, self._handles, x)
        query, found = self._query(q, max_distance)
        return sorted((self._contact(query, r) for r in found), key=lambda c: c.distance)

    def positions(self, x) -> np.ndarray:
        """The positions q of this model's plant (rods as bodies) assembled at poses x (..., 6):
        how a plant whose rods are distance constraints (no rod bodies) is checked; NaN rows
        where x is unreachable."""
        from .closed_chain import assembled_positions

        return assembled_positions(self._plant, self._handles, x)

    def overlaps(self, q) -> list[Contact]:
        """The pairs of parts that overlap at the plant positions ``q`` (a station's plant has
        the same layout), deepest first; empty, and cheap (Drake's ``HasCollisions``), when none
        does. For a check at every step of a run."""
        self._plant.SetPositions(self._plant_context, q)
        query = self._scene_graph.get_query_output_port().Eval(self._sg_context)
        if not query.HasCollisions():
            return []
        found = query.ComputeSignedDistancePairwiseClosestPoints(0.0)
        return sorted(
            (self._contact(query, r) for r in found if r.distance < 0), key=lambda c: c.distance
        )

    def _query(self, q, max_distance: float):
        """(query object, Drake's signed-distance pairs) with the plant at positions q."""
        self._plant.SetPositions(self._plant_context, q)
        query = self._scene_graph.get_query_output_port().Eval(self._sg_context)
        return query, query.ComputeSignedDistancePairwiseClosestPoints(max_distance)

    def _contact(self, query, r) -> Contact:
        (a, p_A), (b, p_B) = sorted(
            [
                (self._names[r.id_A], query.GetPoseInWorld(r.id_A) @ r.p_ACa),
                (self._names[r.id_B], query.GetPoseInWorld(r.id_B) @ r.p_BCb),
            ]
        )
        return Contact(float(r.distance), a, b, np.asarray(p_A), np.asarray(p_B))

    def closest(self, x) -> Contact:
        """The closest pair of parts at pose x (a :class:`Contact` with distance
        :data:`QUERY_DISTANCE_M` and no names when every pair is farther)."""
        found = self.contacts(x)
        if found:
            return found[0]
        return Contact(QUERY_DISTANCE_M, "", "", np.full(3, np.nan), np.full(3, np.nan))

    def sweep(self, x, by_family: bool = False, max_distance: float = QUERY_DISTANCE_M):
        """The clearance along poses x (n, 6): the closest pair at each pose.

        Args:
            x: (n, 6) poses; unreachable ones get NaN.
            by_family: also return, per pair of part families (sorted names, e.g. ("base plate",
                "rod tube")), the smallest distance over the poses and the index of that pose.
            max_distance: m; a pose whose parts are all farther apart reports this distance.
        Returns:
            (distance (n,) m, closest (list of n :class:`Contact` or None)) and, with
            ``by_family``, a dict (family_a, family_b) -> (distance m, pose index, Contact).
        """
        from .closed_chain import assembled_positions

        x = as_poses("poses x", x).reshape(-1, 6)
        q = assembled_positions(self._plant, self._handles, x)
        reachable = np.all(np.isfinite(q), axis=1)
        distance = np.full(x.shape[0], np.nan)
        closest: list = [None] * x.shape[0]
        families: dict = {}
        for k in np.flatnonzero(reachable):
            query, found = self._query(q[k], max_distance)
            if not found:
                distance[k] = max_distance
                continue
            nearest = min(found, key=lambda r: r.distance)
            distance[k], closest[k] = nearest.distance, self._contact(query, nearest)
            if by_family:
                for c in (self._contact(query, r) for r in found):
                    key = tuple(sorted((family(c.part_a), family(c.part_b))))
                    if key not in families or c.distance < families[key][0]:
                        families[key] = (c.distance, int(k), c)
        return (distance, closest, families) if by_family else (distance, closest)

    def sample_indices(self, x, resolution_m: float, theta=None) -> np.ndarray:
        """:func:`sample_indices` of this model's geometry."""
        return sample_indices(self.geometry, x, resolution_m, theta)


@lru_cache(maxsize=8)
def clearance_model(geometry: StewartGeometry) -> ClearanceModel:
    """The :class:`ClearanceModel` of ``geometry``, built once per geometry and process."""
    return ClearanceModel(geometry)


def sample_indices(geometry: StewartGeometry, x, resolution_m: float, theta=None) -> np.ndarray:
    """Indices of the poses of a path x (n, 6) at which clearance must be measured so that no
    point of any part moves more than ``resolution_m`` between two measured poses; theta: their
    motor angles (n, 6) when already known (:func:`~.kinematics.ik_unchecked`'s, NaN where a leg
    cannot close).

    A point of the platform moves at most |dp| + |E d rpy| r_max between samples (r_max the
    farthest point of the platform's parts from E); a point of a rod or crank at most the larger
    of its ends' motion. Between measured poses the clearance is then at least the smaller
    measured value minus ``resolution_m``.

    Returns:
        (m,) increasing indices, the first and last pose always included.
    """
    resolution_m = as_number("clearance resolution", resolution_m, 0.0, lo_open=True)
    x = np.asarray(x, dtype=float)
    if theta is None:
        theta, _ = ik_unchecked(geometry, x)
    r_platform = np.hypot(max(geometry.platform_plate_radius, geometry.platform_radius), 0.08)
    turn = np.einsum("kij,kj->ki", angular_velocity_map(x[:-1, :3]), np.diff(x[:, :3], axis=0))
    step = (
        np.linalg.norm(np.diff(x[:, 3:], axis=0), axis=1)
        + np.linalg.norm(turn, axis=1) * r_platform
    )
    crank = np.max(geometry.crank_lengths) * np.max(np.abs(np.diff(theta, axis=0)), axis=1)
    step = np.maximum(np.nan_to_num(step, nan=np.inf), np.nan_to_num(crank, nan=np.inf))
    keep, moved = [0], 0.0
    for k, d in enumerate(step, start=1):
        if moved + d > resolution_m and keep[-1] != k - 1:
            keep.append(k - 1)  # the last pose within the resolution
            moved = 0.0
        moved += d
        if moved > resolution_m:  # one step longer than the resolution
            keep.append(k)
            moved = 0.0
    if keep[-1] != x.shape[0] - 1:
        keep.append(x.shape[0] - 1)
    return np.asarray(keep)
