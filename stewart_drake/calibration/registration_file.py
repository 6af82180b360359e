"""REG.yaml, the registration's file: the fiducials a tracker measured (:func:`read_fiducials`,
then :func:`~.registration.register`), or the tracker's frames fitted once to a registration
motion (:func:`read_registration` reads either, :func:`motion_frames_yaml` writes the latter),
each value checked and a bad one refused in one line naming its field. What the frames are and
how they are fitted: :mod:`~.registration`.

**REG.yaml** (:func:`read_registration`)::

    point_sigma_m: 2.0e-6   # optional: a fiducial's measurement noise, m per axis (default 2 um)
    base_points:            # >= 3, not on one line
      - {base_m: [x, y, z], tracker_m: [x, y, z]}
    platform_points:        # optional
      marker_in_tracker: {rpy_rad: [phi, theta, psi], xyz_m: [x, y, z]}
      points:               # >= 3, not on one line
        - {platform_m: [x, y, z], tracker_m: [x, y, z]}

A REG.yaml may instead hold the frames fitted once to a registration motion (``stewart-drake
calibrate --register``, :mod:`~stewart_drake.verification.registration_motion`), which
:func:`motion_frames_yaml` writes and :func:`read_registration` reads::

    motion_frames:
      tracker_base: {rpy_rad: [...], xyz_m: [...], rotation_sigma_rad: s, translation_sigma_m: s}
      platform_marker: {rpy_rad: [...], xyz_m: [...], rotation_sigma_rad: s, ...}
      rms_m: 5.0e-05          # the marker's distance from the motion once fitted
      source: "registration measured in reg.csv, ..."

Such a registration takes the robot's kinematics as true (the motion it was fitted to is the
nominal robot's), so ``calibrate``, which identifies them, refuses it (:func:`read_fiducials`).

``marker_in_tracker`` takes ``rotation_sigma_rad`` and ``translation_sigma_m`` too (its
measurement's noise, one standard deviation per axis; default 20 urad and 5 um, one sample of
the tracker of docs/calibration.md's figures: the mean of many samples is better, say so). The
file is read through :func:`~stewart_drake.base.fileio.read_checked` and composed as YAML nodes
only (nothing is constructed from tags, nothing executed); every value is checked, and a bad one
refused in one line naming its field.
"""

from __future__ import annotations

import numpy as np

from ..base.errors import InvalidConfigError
from .registration import (
    DEFAULT_MARKER_SIGMA,
    DEFAULT_POINT_SIGMA_M,
    MAX_FIT_RMS_M,
    MIN_POINTS,
    Fiducials,
    Registration,
    _pose_vector,
    _transform,
    register,
)

#: The largest ``point_sigma_m``, m: fiducials measured worse cannot register a robot built to
#: tenths of a millimetre.
MAX_POINT_SIGMA_M = 1e-3
#: The smallest ``point_sigma_m``, m: no tracker measures a point to better than a nanometre (and
#: the fit's weights, sigma^-2, must stay finite).
MIN_POINT_SIGMA_M = 1e-9
#: The largest marker noise, (rad, m), as the calibration's largest tracker noise.
MAX_MARKER_SIGMA = (1e-2, 1e-3)
#: Largest coordinate of a fiducial or of the marker, m (a laser tracker reaches 80 m).
MAX_COORDINATE_M = 100.0
#: Largest roll, pitch or yaw of ``marker_in_tracker``, rad (degrees given as radians exceed it).
MAX_ANGLE_RAD = 2 * np.pi
#: Largest REG.yaml read, bytes (some thousands of fiducials).
MAX_REGISTRATION_BYTES = 256 * 1024
#: What a bad REG.yaml is told to become.
REGISTRATION_REMEDY = (
    "write base_points: (>= 3 of {base_m: [x, y, z], tracker_m: [x, y, z]}, m) and optionally "
    "platform_points: {marker_in_tracker: {rpy_rad: [...], xyz_m: [...]}, points: [...]} "
    "(docs/calibration.md, Registration)"
)
#: What to write when a field of the frames fitted to a registration motion is missing.
MOTION_FRAMES_REMEDY = (
    "write motion_frames: {tracker_base: {rpy_rad: [...], xyz_m: [...]}, platform_marker: "
    "{rpy_rad: [...], xyz_m: [...]}, rms_m: ...} as calibrate --register writes it "
    "(docs/calibration.md, Registration)"
)


#: The tags a plain number resolves to (PyYAML reads 1e-6, without a point, as text); any
#: other (!!python/..., !Name, !!bool) is refused as not a number.
_NUMBER_TAGS = frozenset(f"tag:yaml.org,2002:{t}" for t in ("int", "float", "str"))


class _Nodes:
    """Typed reads of a composed YAML document's nodes, each refusal one line naming the file
    and the field; a missing key's refusal ends with ``remedy``, how to write the format the
    caller reads."""

    def __init__(self, path, remedy: str = REGISTRATION_REMEDY):
        self.path = path
        self.remedy = remedy

    def refuse(self, field: str, problem: str) -> InvalidConfigError:
        return InvalidConfigError(f"{self.path}: {field}: {problem}")

    def mapping(self, node, field: str, required: tuple, optional: tuple = ()) -> dict:
        """{key: node} of a mapping with exactly the keys ``required`` and some of
        ``optional``."""
        import yaml

        if not isinstance(node, yaml.MappingNode):
            raise self.refuse(field, f"expected a mapping of {', '.join(required + optional)}")
        out = {}
        for key, value in node.value:
            name = key.value if isinstance(key, yaml.ScalarNode) else None
            if name not in required + optional:
                shown = repr(name)[:40] if name is not None else "a key that is not text"
                raise self.refuse(
                    field,
                    f"unknown key {shown} (known: {', '.join(required + optional)})",
                )
            out[name] = value
        missing = [k for k in required if k not in out]
        if missing:
            raise self.refuse(field, f"missing {', '.join(missing)}; {self.remedy}")
        return out

    def sequence(self, node, field: str) -> list:
        import yaml

        if not isinstance(node, yaml.SequenceNode):
            raise self.refuse(field, "expected a list")
        return list(node.value)

    def number(self, node, field: str, lo: float, hi: float, unit: str) -> float:
        """A plain scalar that is a finite number in [lo, hi]."""
        import yaml

        text = node.value if isinstance(node, yaml.ScalarNode) else None
        value = float("nan")
        if text is not None and node.style is None and node.tag in _NUMBER_TAGS:
            try:
                value = float(text)
            except ValueError:
                pass
        if not (np.isfinite(value) and lo <= value <= hi):
            got = repr(text)[:40] if text is not None else "a list or mapping"
            raise self.refuse(
                field, f"expected a finite number in [{lo:g}, {hi:g}] {unit}, got {got}"
            )
        return value

    def text(self, node, field: str) -> str:
        """A plain scalar's text, at most :data:`MAX_SOURCE_CHARS` characters."""
        import yaml

        if not isinstance(node, yaml.ScalarNode) or len(node.value) > MAX_SOURCE_CHARS:
            raise self.refuse(field, f"expected a text of at most {MAX_SOURCE_CHARS} characters")
        return str(node.value)

    def vector(self, node, field: str, bound: float, unit: str) -> np.ndarray:
        """Three numbers, each within +-``bound``."""
        items = self.sequence(node, field)
        if len(items) != 3:
            raise self.refuse(field, f"expected 3 numbers [x, y, z] in {unit}, got {len(items)}")
        return np.array(
            [self.number(v, f"{field}[{k}]", -bound, bound, unit) for k, v in enumerate(items)]
        )

    def points(self, node, field: str, robot_key: str) -> tuple[np.ndarray, np.ndarray]:
        """((n, 3) robot-frame points, (n, 3) tracker points) of a list of {robot_key,
        tracker_m}."""
        items = self.sequence(node, field)
        if len(items) < MIN_POINTS:
            raise self.refuse(
                field,
                f"{len(items)} point{'s' if len(items) != 1 else ''}: a frame needs at least "
                f"{MIN_POINTS}, not on one line",
            )
        robot, tracker = [], []
        for k, item in enumerate(items):
            entry = self.mapping(item, f"{field}[{k}]", (robot_key, "tracker_m"))
            robot.append(
                self.vector(entry[robot_key], f"{field}[{k}].{robot_key}", MAX_COORDINATE_M, "m")
            )
            tracker.append(
                self.vector(entry["tracker_m"], f"{field}[{k}].tracker_m", MAX_COORDINATE_M, "m")
            )
        return np.array(robot), np.array(tracker)


#: The section of a REG.yaml that holds frames fitted to a registration motion.
MOTION_FRAMES = "motion_frames"
#: The longest ``source`` text of :data:`MOTION_FRAMES`, characters.
MAX_SOURCE_CHARS = 1000


def _composed(path) -> tuple[_Nodes, object]:
    """(the typed reader, the root node) of a REG.yaml, composed as YAML nodes only."""
    import yaml

    from ..run.scenario_io import read_yaml_text

    text = read_yaml_text(path, "registration file", MAX_REGISTRATION_BYTES, REGISTRATION_REMEDY)
    # Composed, not constructed: nodes and their text only, whatever tags they carry.
    return _Nodes(path), yaml.compose(text, Loader=yaml.SafeLoader)


def _has_key(node, key: str) -> bool:
    """Whether a composed node is a mapping with ``key``."""
    import yaml

    return isinstance(node, yaml.MappingNode) and any(
        isinstance(k, yaml.ScalarNode) and k.value == key for k, _ in node.value
    )


def read_fiducials(path) -> Fiducials:
    """The :class:`Fiducials` of a REG.yaml (module docstring), every value checked.

    Raises:
        MissingFileError: no such file.  CorruptFileError: not a regular file, over
            :data:`MAX_REGISTRATION_BYTES`, empty, not UTF-8, not YAML, a key twice, anchors
            expanding past the scenario's bound.  InvalidConfigError: one line naming the
            field: an unknown or missing key, not 3 numbers, a number not finite or out of its
            range, fewer than :data:`MIN_POINTS` points; frames fitted to a motion
            (:data:`MOTION_FRAMES`), which take the kinematics a calibration identifies as true.
    """
    nodes, root = _composed(path)
    if _has_key(root, MOTION_FRAMES):
        raise nodes.refuse(
            MOTION_FRAMES,
            "frames fitted to a registration motion take the robot's kinematics as true, which "
            "a calibration identifies: register the tracker with fiducials (base_points) for "
            "calibrate",
        )
    return _fiducials(nodes, root)


def _fiducials(nodes: _Nodes, root) -> Fiducials:
    """:func:`read_fiducials` of a composed REG.yaml."""
    top = nodes.mapping(root, "the file", ("base_points",), ("platform_points", "point_sigma_m"))
    sigma = DEFAULT_POINT_SIGMA_M
    if "point_sigma_m" in top:
        sigma = nodes.number(top["point_sigma_m"], "point_sigma_m", 0.0, MAX_POINT_SIGMA_M, "m")
        if sigma < MIN_POINT_SIGMA_M:
            raise nodes.refuse(
                "point_sigma_m",
                f"must be at least {MIN_POINT_SIGMA_M:g} m (a fiducial's noise per axis), got "
                f"{sigma:g}",
            )
    base_B, base_T = nodes.points(top["base_points"], "base_points", "base_m")
    if "platform_points" not in top:
        return Fiducials(base_B, base_T, point_sigma_m=sigma)
    platform = nodes.mapping(
        top["platform_points"], "platform_points", ("marker_in_tracker", "points")
    )
    marker = nodes.mapping(
        platform["marker_in_tracker"],
        "platform_points.marker_in_tracker",
        ("rpy_rad", "xyz_m"),
        ("rotation_sigma_rad", "translation_sigma_m"),
    )
    where = "platform_points.marker_in_tracker"
    rpy = nodes.vector(marker["rpy_rad"], f"{where}.rpy_rad", MAX_ANGLE_RAD, "rad")
    xyz = nodes.vector(marker["xyz_m"], f"{where}.xyz_m", MAX_COORDINATE_M, "m")
    marker_sigma = list(DEFAULT_MARKER_SIGMA)
    for k, name in enumerate(("rotation_sigma_rad", "translation_sigma_m")):
        if name in marker:
            marker_sigma[k] = nodes.number(
                marker[name], f"{where}.{name}", 0.0, MAX_MARKER_SIGMA[k], name.rsplit("_")[-1]
            )
    platform_P, platform_T = nodes.points(
        platform["points"], "platform_points.points", "platform_m"
    )
    return Fiducials(
        base_B,
        base_T,
        platform_P,
        platform_T,
        np.concatenate([rpy, xyz]),
        sigma,
        tuple(marker_sigma),
    )


def read_registration(path) -> Registration:
    """The :class:`Registration` a REG.yaml gives (module docstring): its fiducials'
    (:func:`read_fiducials`, then :func:`register`), or the frames fitted to a registration
    motion (:data:`MOTION_FRAMES`).

    Raises:
        MissingFileError, CorruptFileError, InvalidConfigError: as :func:`read_fiducials` and
            :func:`register` (points on one line, points that fit no rigid motion), each one
            line naming the file, the field and what to fix.
    """
    nodes, root = _composed(path)
    if not _has_key(root, MOTION_FRAMES):
        return register(_fiducials(nodes, root), str(path))
    nodes = _Nodes(path, MOTION_FRAMES_REMEDY)
    top = nodes.mapping(root, "the file", (MOTION_FRAMES,))
    section = nodes.mapping(
        top[MOTION_FRAMES],
        MOTION_FRAMES,
        ("tracker_base", "platform_marker", "rms_m"),
        ("source",),
    )
    frames, covariances = [], []
    for key in ("tracker_base", "platform_marker"):
        where = f"{MOTION_FRAMES}.{key}"
        entry = nodes.mapping(
            section[key],
            where,
            ("rpy_rad", "xyz_m"),
            ("rotation_sigma_rad", "translation_sigma_m"),
        )
        rpy = nodes.vector(entry["rpy_rad"], f"{where}.rpy_rad", MAX_ANGLE_RAD, "rad")
        xyz = nodes.vector(entry["xyz_m"], f"{where}.xyz_m", MAX_COORDINATE_M, "m")
        sig = [
            nodes.number(entry[name], f"{where}.{name}", 0.0, bound, name.rsplit("_")[-1])
            if name in entry
            else 0.0
            for name, bound in zip(("rotation_sigma_rad", "translation_sigma_m"), MAX_MARKER_SIGMA)
        ]
        frames.append(_transform(np.concatenate([rpy, xyz])))
        covariances.append(np.diag([sig[0] ** 2] * 3 + [sig[1] ** 2] * 3))
    rms = nodes.number(section["rms_m"], f"{MOTION_FRAMES}.rms_m", 0.0, MAX_FIT_RMS_M, "m")
    source = nodes.text(section["source"], f"{MOTION_FRAMES}.source") if "source" in section else ""
    return Registration(
        frames[0],
        frames[1],
        covariances[0],
        covariances[1],
        rms,
        0.0,
        source=f"fitted to a registration motion ({source or 'no source given'})",
    )


def motion_frames_yaml(X_TB, X_PM, sigma_B, sigma_M, rms_m: float, source: str) -> str:
    """The REG.yaml of frames fitted to a registration motion (:data:`MOTION_FRAMES`), which
    :func:`read_registration` reads back.

    Args:
        X_TB, X_PM: RigidTransform: the base in the tracker's frame, the marker in the
            platform's. sigma_B, sigma_M: (rad, m) one standard deviation per axis of each.
        rms_m: the fit's residual, m. source: what it was fitted to, in words.
    """
    import yaml

    def frame(X, sigma) -> dict:
        x = _pose_vector(X)
        return {
            # + 0.0: a zero is written 0.0, never -0.0 (an identity's angles came out -0.0).
            "rpy_rad": [float(v) + 0.0 for v in x[:3]],
            "xyz_m": [float(v) + 0.0 for v in x[3:]],
            "rotation_sigma_rad": float(sigma[0]),
            "translation_sigma_m": float(sigma[1]),
        }

    body = {
        MOTION_FRAMES: {
            "tracker_base": frame(X_TB, sigma_B),
            "platform_marker": frame(X_PM, sigma_M),
            "rms_m": float(rms_m),
            "source": str(source)[:MAX_SOURCE_CHARS],
        }
    }
    head = (
        "# The tracker's frames fitted to a registration motion (stewart-drake calibrate "
        "--register):\n# X_TB the base in the tracker's frame, X_PM the marker on "
        "the platform. Give this file to\n# verify --registration; calibrate's identification "
        "needs fiducials instead.\n"
    )
    return head + yaml.safe_dump(body, sort_keys=False, default_flow_style=None, width=100)
