"""The organ-motion library by name: :data:`LIBRARY`, :func:`make_motion` from a name and
parameters carrying units ("amplitude=15mm", "rate=72bpm", "direction=SI"), as the CLI and
scenarios give them, :func:`split_parameters` and :func:`make_layers` for the motions laid on
another, and :class:`OrganMotionReference`, a scenario's choice of one.

Drake's YAML loader reads :class:`OrganMotionReference`'s field types: this module must not use
``from __future__ import annotations``.
"""

import math
import re
from dataclasses import dataclass, field, fields

from ...base.checks import as_number
from ...base.errors import InvalidConfigError
from ...base.units import UNITS  # a parameter value's units, by its field's suffix
from ...robot.geometry import X_HOME, StewartGeometry
from ..motion import Reference, ReferenceConfig
from .breathing import BreathHold, Breathing, HysteresisBreathing, IrregularBreathing
from .combinators import MotionSum, layered, scaled
from .excursions import BaselineDrift, PersistentExcursion, TransientExcursion
from .heartbeat import Heartbeat
from .registration import RegistrationMotion
from .waveforms import Sawtooth, Sharkfin


def _breathing_heartbeat(**kw):
    heart = {k[len("heart_") :]: v for k, v in kw.items() if k.startswith("heart_")}
    breath = {k: v for k, v in kw.items() if not k.startswith("heart_") and k != "centre"}
    centre = kw.get("centre", tuple(X_HOME))
    return MotionSum(
        parts=(Breathing(**breath), Heartbeat(**heart)), centre=centre, name="breathing_heartbeat"
    )


#: name -> (factory, the class whose fields are its parameters).
LIBRARY = {
    "breathing": (Breathing, Breathing),
    "heartbeat": (Heartbeat, Heartbeat),
    "breathing_heartbeat": (_breathing_heartbeat, None),
    "irregular_breathing": (IrregularBreathing, IrregularBreathing),
    "hysteresis": (HysteresisBreathing, HysteresisBreathing),
    "sawtooth": (Sawtooth, Sawtooth),
    "sharkfin": (Sharkfin, Sharkfin),
    "baseline_drift": (BaselineDrift, BaselineDrift),
    "transient_excursion": (TransientExcursion, TransientExcursion),
    "persistent_excursion": (PersistentExcursion, PersistentExcursion),
    "breath_hold": (BreathHold, BreathHold),
    "registration": (RegistrationMotion, RegistrationMotion),
}


def parameter_names(motion: str) -> list[str]:
    """The parameters :func:`make_motion` takes for ``motion`` (field names; a field with a
    unit suffix, ``amplitude_m``, is also given without it, ``amplitude=15mm``)."""
    factory, cls = _library(motion)
    if cls is None:
        names = [f.name for f in fields(Breathing) if f.name not in ("name", "centre")]
        names += [f"heart_{f.name}" for f in fields(Heartbeat) if f.name not in ("name", "centre")]
        return names + ["centre"]
    return [f.name for f in fields(cls) if f.name != "name"]


def _library(motion: str):
    if motion not in LIBRARY:
        raise InvalidConfigError(
            f"unknown motion {motion!r}; the library has "
            f"{', '.join(LIBRARY)} (or give a trace file, .csv)"
        )
    return LIBRARY[motion]


def _parse_value(key: str, field_name: str, value):
    """A parameter value in the unit of ``field_name``'s suffix (SI), from a number or a string
    with a unit ("15mm", "72 bpm", "2deg"); vectors and axis names pass through."""
    field_name = field_name.removeprefix("heart_")
    suffix = field_name.rsplit("_", 1)[-1] if "_" in field_name else ""
    if not isinstance(value, str):
        return value
    text = value.strip()
    if suffix in UNITS:
        m = re.fullmatch(r"([-+]?(?:\d+(?:\.\d*)?|\.\d+)(?:[eE][-+]?\d+)?)\s*([a-zA-Z/]*)", text)
        if m is None or not math.isfinite(float(m.group(1))):
            raise InvalidConfigError(
                f"parameter {key}: {value!r} is not a finite number with a unit "
                f"(e.g. 15mm); units: {', '.join(UNITS[suffix])}"
            )
        number, unit = float(m.group(1)), m.group(2).lower()
        units = {u.lower(): f for u, f in UNITS[suffix].items()}
        if unit and unit not in units:
            raise InvalidConfigError(
                f"parameter {key}: unknown unit {m.group(2)!r}; use one of "
                f"{', '.join(UNITS[suffix])}"
            )
        return number * (units[unit] if unit else 1.0)
    if "direction" in field_name or "axis" in field_name:
        return text
    try:
        if field_name in ("harmonics", "harmonic_phases_rad", "centre"):
            return tuple(float(c) for c in text.split(",") if c.strip())
        return float(text)
    except ValueError:
        raise InvalidConfigError(
            f"parameter {key}: {value!r} is not a number"
            + (" list (1,0.5,0.25)" if "," in text else "")
        ) from None


def make_motion(motion: str, parameters: dict | None = None):
    """A motion of the library by name with parameters carrying units.

    Args:
        motion: one of :data:`LIBRARY` (breathing, heartbeat, breathing_heartbeat,
            irregular_breathing, hysteresis, sawtooth, sharkfin, baseline_drift,
            transient_excursion, persistent_excursion, breath_hold; and registration, the
            known motion a tracker is registered with).
        parameters: {name: value}: a field of the motion's class (``amplitude_m``: a number in
            its SI unit) or the field without its unit suffix with a value carrying a unit
            (``amplitude``: "15mm"; ``rate``: "72bpm"; ``tilt``: "2deg"); directions as axis
            names ("SI", "-Z") or "x,y,z"; for breathing_heartbeat the heart's parameters
            start with ``heart_`` (``heart_amplitude``, ``heart_rate``).
    Returns:
        the motion (frozen dataclass with ``evaluate``).
    Raises:
        InvalidConfigError: an unknown motion or parameter (the known ones listed), a value
            without a number, an unknown unit, or a value out of range (named).
    """
    factory, cls = _library(motion)
    known = parameter_names(motion)
    kwargs = {}
    for key, value in (parameters or {}).items():
        key = str(key).strip()
        name = (
            key
            if key in known
            else next(
                (
                    n
                    for n in known
                    if "_" in n
                    and n.rsplit("_", 1)[0] == key
                    and n.rsplit("_", 1)[1] in (*UNITS, "n")
                ),
                None,
            )
        )
        if name is None:
            raise InvalidConfigError(
                f"{motion} has no parameter {key!r}; its parameters: "
                f"{', '.join(known)} (a unit suffix may be left out and "
                f"given with the value: amplitude=15mm)"
            )
        kwargs[name] = _parse_value(key, name, value)
    try:
        return factory(**kwargs)
    except TypeError as err:
        raise InvalidConfigError(f"{motion}: {err}") from None


def _has_parameter(known: list[str], key: str) -> bool:
    """Whether ``key`` names one of the ``known`` fields, with or without its unit suffix."""
    return key in known or any(
        "_" in n and n.rsplit("_", 1)[0] == key and n.rsplit("_", 1)[1] in (*UNITS, "n")
        for n in known
    )


def split_parameters(motions, parameters: dict | None) -> list[dict]:
    """Each motion's share of one set of ``KEY=VALUE`` parameters (as ``reproduce --param``
    gives them for a motion and the motions ``--add`` lays on it).

    A key goes to the one motion that has it (``drift=3mm`` to baseline_drift, whose field is
    ``drift_m``), or to the motion written in front of it (``heartbeat.amplitude=2mm``); every
    key goes to a motion alone.

    Args:
        motions: names of the library (:data:`LIBRARY`).  parameters: {key: value}.
    Returns:
        one dict per motion, in order.
    Raises:
        InvalidConfigError: an unknown motion, a key no motion has or several have (the
            message says to put the motion in front), a motion named that is not among them.
    """
    motions = list(motions)
    known = [parameter_names(m) for m in motions]
    out: list[dict] = [{} for _ in motions]
    for key, value in (parameters or {}).items():
        key = str(key).strip()
        motion, dot, bare = key.rpartition(".")
        if dot:
            if motion not in motions:
                raise InvalidConfigError(
                    f"parameter {key}: {motion!r} is not among the motions ({', '.join(motions)})"
                )
            out[motions.index(motion)][bare] = value
            continue
        owners = [i for i, names in enumerate(known) if _has_parameter(names, key)]
        if not owners and len(motions) == 1:
            owners = [0]  # make_motion names what is wrong
        if len(owners) != 1:
            raise InvalidConfigError(
                f"parameter {key}: "
                + (
                    f"{' and '.join(motions[i] for i in owners)} both have it; write the motion "
                    f"in front: {motions[owners[0]]}.{key}="
                    if owners
                    else f"none of {', '.join(motions)} has it; their parameters: "
                    + "; ".join(f"{m}: {', '.join(n)}" for m, n in zip(motions, known))
                )
            )
        out[owners[0]][key] = value
    return out


def make_layers(add: dict | None) -> tuple:
    """The motions of the library to lay on a reference (:func:`layered`), from {name:
    parameters} (:func:`make_motion` each).

    Raises:
        InvalidConfigError: as :func:`make_motion`.
    """
    return tuple(make_motion(str(name), dict(p or {})) for name, p in (add or {}).items())


# -- a scenario's choice of a motion ---------------------------------------------------------------


@dataclass
class OrganMotionReference(ReferenceConfig):
    """A motion of the organ-motion library (:mod:`~.organ`: breathing, heartbeat,
    breathing_heartbeat, irregular_breathing, hysteresis and the phantoms' sawtooth, sharkfin,
    baseline_drift, transient_excursion, persistent_excursion, breath_hold) with parameters
    carrying units, e.g.
    ``{amplitude: 15mm, period: 4s, direction: SI}`` (:func:`make_motion`).

    Attributes:
        motion: the library's name. parameters: name -> value (a number in the field's SI unit,
            or text with a unit). scale: the motion shrunk about its centre, in (0, 1]
            (``reproduce --scale-to-fit`` finds it). add: motions of the library laid on it,
            name -> parameters (``{baseline_drift: {drift: 3mm}}``, :func:`layered`).
    """

    motion: str = "breathing"
    parameters: dict[str, str] = field(default_factory=dict)
    scale: float = 1.0
    add: dict[str, dict[str, str]] = field(default_factory=dict)

    def validate(self) -> None:
        as_number("reference.scale", self.scale, 0.0, 1.0, lo_open=True)
        self._motion()  # names an unknown motion or parameter

    def make(
        self, geometry: StewartGeometry, duration_s: float, torque_limit_Nm: float | None
    ) -> Reference:
        return self._motion()

    def _motion(self) -> Reference:
        motion = layered(make_motion(self.motion, self.parameters), make_layers(self.add))
        return scaled(motion, self.scale)

    @property
    def label(self) -> str:
        return "+".join([self.motion, *self.add])


__all__ = [
    "LIBRARY",
    "UNITS",
    "make_motion",
    "parameter_names",
    "split_parameters",
    "make_layers",
    "OrganMotionReference",
]
