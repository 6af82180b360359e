"""What a design must do, as a file: motions, a required workspace, a payload and margins.

A :class:`DesignRequirements` is read from YAML by :func:`load_requirements` with Drake's
``yaml_load_typed``, like a scenario (:mod:`~.scenario_io`): the motions are the scenario's
reference choices (``!NamedReference {name: paper}``, the paper manoeuvre;
``!OrganMotionReference {motion: breathing_heartbeat, parameters: {...}}``, the organ-motion
library with its parameters; ``!TraceReference {path: ...}``, a recorded trace), so each is
checked and built as a scenario's reference is. Loading never executes code, and a bad file or
value is one typed line naming the file and the field. ``scenarios/design_requirements.yaml``
is the issue's acceptance set. This module must not use ``from __future__ import annotations``
(``yaml_load_typed`` reads its dataclasses' field types).
"""

import dataclasses
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from pydrake.common.yaml import yaml_load_typed

from ..base.checks import as_number
from ..base.errors import CorruptFileError, InvalidConfigError, StewartError
from ..references.trajectories import NamedReference
from ..robot.kinematics import X_HOME
from ..robot.limits import DEFAULT_EFFORT_MARGIN
from ..run.scenario import ReferenceChoice
from ..run.scenario_io import _in_file, _one_line, read_yaml_text

#: Largest requirements file read, bytes (a few hundred bytes is typical).
MAX_REQUIREMENTS_BYTES = 64 * 1024
#: The finest resolution or accuracy a requirement may ask, m and rad: a tenth of a micrometre
#: and of a microradian, finer than any encoder the catalogue holds (the DYNAMIXEL-P's 526,374
#: counts a turn are 12 urad); a smaller number is a typo (5e-324 ended in a ZeroDivisionError).
FINEST_TRANSLATION_M = 1e-7
FINEST_ROTATION_RAD = 1e-7
#: Largest side of the required box, m, and largest payload, kg: past a tabletop platform.
MAX_BOX_SIDE_M, MAX_PAYLOAD_KG = 0.5, 20.0


@dataclass
class RequiredWorkspace:
    """Poses every design must reach and hold: a box of positions, each with a tilt cone.

    Attributes:
        box_m: (3,) the box's full extents along X, Y, Z, m, centred on (0, 0, height_m).
        tilt_deg: the platform may tilt by up to this angle about any horizontal axis at every
            position of the box, deg (a cone of the platform's normal), in [0, 45].
        height_m: the box's centre height in the base frame, m; None: the home height
            (``X_HOME``, 0.30 m).
    """

    box_m: list[float] = field(default_factory=lambda: [0.03, 0.03, 0.02])
    tilt_deg: float = 15.0
    height_m: float | None = None

    @property
    def centre_m(self) -> np.ndarray:
        """(3,) the box's centre, m."""
        z = float(X_HOME[5]) if self.height_m is None else self.height_m
        return np.array([0.0, 0.0, z])

    def validate(self) -> None:
        """Raises InvalidConfigError naming the field (``workspace.<name>``)."""
        if not isinstance(self.box_m, list) or len(self.box_m) != 3:
            raise InvalidConfigError(
                f"workspace.box_m must be 3 extents [X, Y, Z] in m, got {self.box_m!r}"
            )
        for axis, side in zip("XYZ", self.box_m, strict=True):
            as_number(f"workspace.box_m ({axis}, m)", side, 0.0, MAX_BOX_SIDE_M)
        as_number("workspace.tilt_deg", self.tilt_deg, 0.0, 45.0)
        if self.height_m is not None:
            as_number("workspace.height_m", self.height_m, 0.05, 1.0)


@dataclass
class Margins:
    """What a design keeps in reserve for the feedback, as fractions of the motor's figures.

    Attributes:
        torque: the share of the motors' peak torque the motions may not use, in [0, 0.9]
            (default 0.1: the motions may need 90 %, as ``GuardConfig.effort_margin``).
        speed: the share of the motors' no-load speed the motions may not use, in [0, 0.9].
    """

    torque: float = round(1.0 - DEFAULT_EFFORT_MARGIN, 12)
    speed: float = round(1.0 - DEFAULT_EFFORT_MARGIN, 12)

    def validate(self) -> None:
        """Raises InvalidConfigError naming the field (``margins.<name>``)."""
        as_number("margins.torque", self.torque, 0.0, 0.9)
        as_number("margins.speed", self.speed, 0.0, 0.9)


@dataclass
class Resolution:
    """How finely the robot must be able to place the platform: the largest pose error the
    encoders leave when every crank is read half a count off (the worst combination of signs),
    over every pose of the task. A feedback on those encoders cannot hold the platform closer
    than that (it dithers over a count or two), so this is the floor of its tracking error.

    Attributes:
        translation_m: largest position error, m, in [:data:`FINEST_TRANSLATION_M`, 0.01].
        rotation_rad: largest orientation error (the roll-pitch-yaw error's norm), rad, in
            [:data:`FINEST_ROTATION_RAD`, 0.1].
    """

    translation_m: float = 5.0e-5
    rotation_rad: float = 5.0e-4

    def validate(self) -> None:
        """Raises InvalidConfigError naming the field (``resolution.<name>``)."""
        as_number("resolution.translation_m", self.translation_m, FINEST_TRANSLATION_M, 0.01)
        as_number("resolution.rotation_rad", self.rotation_rad, FINEST_ROTATION_RAD, 0.1)


@dataclass
class Accuracy:
    """How accurately the robot must make its motions on its servo bus: the RMS error per axis a
    phantom must hold. A design meets it when the encoders' floor (every crank within half a
    count, uniform, through J^-1: RMS per axis, the largest over the task's poses) is at most
    :data:`ACCURACY_FLOOR_SHARE` of it: the crank servo on the bus leaves its robot's true
    error near its floor and the pose its encoders read about 1.4 times it (docs/robot.md,
    "The error budget"), and the rest of the accuracy is for what the floor does not hold
    (friction, the period, the model).

    Attributes:
        translation_m: RMS position error per axis, m, in [:data:`FINEST_TRANSLATION_M`,
            0.01].
        rotation_rad: RMS orientation error per axis, rad, in [:data:`FINEST_ROTATION_RAD`,
            0.1].
    """

    translation_m: float = 1.0e-4
    rotation_rad: float = 5.0e-4

    def validate(self) -> None:
        """Raises InvalidConfigError naming the field (``accuracy.<name>``)."""
        as_number("accuracy.translation_m", self.translation_m, FINEST_TRANSLATION_M, 0.01)
        as_number("accuracy.rotation_rad", self.rotation_rad, FINEST_ROTATION_RAD, 0.1)


#: The share of the required accuracy the encoders' floor may take (:class:`Accuracy`).
ACCURACY_FLOOR_SHARE = 0.5


@dataclass
class DesignRequirements:
    """A design task.

    Attributes:
        motions: the motions the robot must make, each a scenario reference choice (module
            docstring); at least one, or a workspace.
        workspace: the poses it must reach and hold (:class:`RequiredWorkspace`), or None.
        payload_kg: mass on the platform, kg, in [0, 20] (at the platform frame's origin).
        margins: what the motions leave to the feedback (:class:`Margins`).
        resolution: how finely the encoders must resolve the platform's pose
            (:class:`Resolution`), or None (not judged).
        accuracy: the RMS error per axis the robot must hold on its bus (:class:`Accuracy`),
            or None (not judged).
    """

    motions: list[ReferenceChoice] = field(default_factory=lambda: [NamedReference()])
    workspace: RequiredWorkspace | None = None
    payload_kg: float = 0.0
    margins: Margins = field(default_factory=Margins)
    resolution: Resolution | None = None
    accuracy: Accuracy | None = None

    def validate(self) -> "DesignRequirements":
        """Check every field; returns self.

        Raises:
            InvalidConfigError, MissingFileError: names the field (``motions[i]``: the motion's
                own message, e.g. an unknown library name or a missing trace file).
        """
        if not isinstance(self.motions, list):
            raise InvalidConfigError(f"motions must be a list, got {self.motions!r}")
        if not self.motions and self.workspace is None:
            raise InvalidConfigError("give at least one motion or a workspace: nothing is asked")
        for i, motion in enumerate(self.motions):
            try:
                motion.validate()
            except StewartError as err:
                raise _in_file(err, f"motions[{i}]") from None
        if self.workspace is not None:
            self.workspace.validate()
        as_number("payload_kg", self.payload_kg, 0.0, MAX_PAYLOAD_KG)
        self.margins.validate()
        if self.resolution is not None:
            self.resolution.validate()
        if self.accuracy is not None:
            self.accuracy.validate()
        return self


def _unknown_fields(message: str, problem: str) -> str:
    """Drake's "The fields [...] were unknown to the schema" (its whole ``message``; ``problem``
    is the one-line text to keep otherwise), naming only the keys that are field names (a typo
    to fix): a file that is not requirements at all (a password file, a log) has keys that are
    its lines, which are not quoted."""
    import ast
    import re

    if not message.startswith("The fields ["):
        return problem
    found = re.match(r"The fields (\[.*\]) were unknown to the schema", message, re.S)
    try:
        keys = [str(k) for k in ast.literal_eval(found.group(1))] if found else []
    except (ValueError, SyntaxError):
        keys = []
    names = [k for k in keys if re.fullmatch(r"[A-Za-z_][A-Za-z0-9_]{0,39}", k)]
    known = ", ".join(f.name for f in dataclasses.fields(DesignRequirements))
    if keys and len(names) == len(keys):
        return f"unknown field{'s' if len(keys) > 1 else ''} {', '.join(names)} (known: {known})"
    return f"it has no field of a requirements file (known: {known})"


def load_requirements(path) -> DesignRequirements:
    """Read a design's requirements from a YAML file (``scenarios/design_requirements.yaml``).

    Args:
        path: the ``.yaml`` file.
    Returns:
        the validated :class:`DesignRequirements`.
    Raises:
        MissingFileError: no such file (or a motion's trace file missing).
        CorruptFileError (an InvalidConfigError): empty, too large, not UTF-8, not YAML, a key
            twice, or YAML that does not fit the schema (the field named).
        InvalidConfigError: a value out of range, named by file and field.
    """
    kind = "design requirements file"
    remedy = "fix it, or start from scenarios/design_requirements.yaml"
    text = read_yaml_text(path, kind, MAX_REQUIREMENTS_BYTES, remedy)
    path = Path(path)
    try:
        requirements = yaml_load_typed(
            schema=DesignRequirements, data=text, allow_schema_with_no_yaml=True
        )
    except StewartError as err:
        raise _in_file(err, path) from None
    except Exception as err:  # noqa: BLE001 - yaml and Drake's loader raise several types
        problem = _one_line(err)
        if not problem.startswith("not YAML"):
            problem = _unknown_fields(str(err), problem)
            problem = f"it does not fit the DesignRequirements schema: {problem}"
        raise CorruptFileError(path, kind, problem, remedy) from None
    try:
        return requirements.validate()
    except StewartError as err:
        raise _in_file(err, path) from None
