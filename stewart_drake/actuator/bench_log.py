"""A servo's bench log: one servo swinging a pendulum in its own position mode, as a bench
records it, read and checked (:func:`read_bench_log`).

The format is the raw log of the BAM bench (Duclusaud et al., ICRA 2025; Rhoban/bam), which our
own bench run writes too (:func:`write_bench_log`): a JSON object with the pendulum's ``mass``
(kg, at the end of its arm) and ``length`` (m), an optional ``arm_mass`` (kg, a uniform arm;
0 by default), the firmware's position P gain ``kp`` (the control table's value), the supply
``vin`` (V), the ``motor`` and ``trajectory`` names, and ``entries``: one object a sample with
``timestamp`` (s), ``goal_position`` and ``position`` (rad, the servo's encoder), ``torque_enable``
(bool) and, when recorded, ``input_volts`` (V), ``speed``, ``load``, ``temp``. A log of the
servo in Current Control Mode (our commissioning excitation, :mod:`.commissioning`) says
``"mode": "current"`` and gives each entry's ``goal_current`` (A) instead of its goal position.
Nothing in a log is run or imported: it is numbers and names.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..base.errors import CorruptFileError
from ..base.fileio import atomic_write, read_json

#: The largest bench log read, bytes (a minute at 1 kHz is about 12 MB).
MAX_LOG_BYTES = 64e6
#: The fewest samples a log must hold.
MIN_SAMPLES = 20
KIND = "servo bench log"
REMEDY = (
    "give a bench log as `stewart-drake servo` documents it (docs/servo_bench.md): a JSON "
    "object with mass, length, kp, vin and entries of timestamp, goal_position, position and "
    "torque_enable"
)


@dataclass(frozen=True)
class BenchLog:
    """A checked bench log.

    Attributes:
        path: where it was read from ("" for one made in memory).
        mass_kg, length_m, arm_mass_kg: the pendulum (a point mass at the end of a uniform arm).
        kp: the firmware's position P gain (raw, the control table's).
        supply_V: the servo's supply: the mean of ``input_volts`` where recorded, else ``vin``.
        motor, trajectory: the log's names.
        t: (n,) s, strictly increasing.  goal: (n,) the goal position, rad (``mode``
            "position"), or current, A ("current").  q: (n,) rad.  enabled: (n,) bool.
        mode: "position" (the servo's own position loop: BAM's logs) or "current" (Current
            Control Mode: a commissioning excitation over the bus).
    """

    path: str
    mass_kg: float
    length_m: float
    arm_mass_kg: float
    kp: float
    supply_V: float
    motor: str
    trajectory: str
    t: np.ndarray
    goal: np.ndarray
    q: np.ndarray
    enabled: np.ndarray
    mode: str = "position"

    @property
    def name(self) -> str:
        """The file's name, or the trajectory's for a log made in memory."""
        return Path(self.path).name if self.path else self.trajectory

    @property
    def inertia_kg_m2(self) -> float:
        """The pendulum's inertia about the shaft: m l^2 + m_arm l^2 / 3, kg m^2."""
        return (self.mass_kg + self.arm_mass_kg / 3.0) * self.length_m**2

    @property
    def gravity_Nm(self) -> float:
        """The pendulum's largest gravity torque (m + m_arm / 2) g l, N m (horizontal)."""
        return (self.mass_kg + self.arm_mass_kg / 2.0) * 9.80665 * self.length_m


def _number(path, where: str, value, lo: float = -math.inf, lo_open: bool = False) -> float:
    """``value`` as a finite float above ``lo``, or the file refused naming ``where``."""
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise CorruptFileError(path, KIND, f"{where} is {value!r:.40}, not a number", REMEDY)
    v = float(value)
    if not math.isfinite(v) or v < lo or (lo_open and v == lo):
        bound = f"{'above' if lo_open else 'at least'} {lo:g}"
        raise CorruptFileError(path, KIND, f"{where} is {v!r}, not a finite number {bound}", REMEDY)
    return v


def bench_log_from(data, path="") -> BenchLog:
    """The :class:`BenchLog` of a parsed log ``data`` (a dict), ``path`` naming it in errors.

    Raises:
        CorruptFileError: not an object, a field missing or not a number where one is needed, a
            pendulum of no mass or length, fewer than :data:`MIN_SAMPLES` samples, timestamps
            not strictly increasing; each named.
    """
    if not isinstance(data, dict):
        raise CorruptFileError(path, KIND, f"it holds a {type(data).__name__}, not an object")
    for key in ("mass", "length", "kp", "vin", "entries"):
        if key not in data:
            raise CorruptFileError(path, KIND, f"it has no {key!r}", REMEDY)
    mass = _number(path, "mass", data["mass"], 0.0, lo_open=True)
    length = _number(path, "length", data["length"], 0.0, lo_open=True)
    arm = _number(path, "arm_mass", data.get("arm_mass", 0.0), 0.0)
    kp = _number(path, "kp", data["kp"], 0.0)
    vin = _number(path, "vin", data["vin"], 0.0, lo_open=True)
    entries = data["entries"]
    if not isinstance(entries, list) or len(entries) < MIN_SAMPLES:
        n = len(entries) if isinstance(entries, list) else type(entries).__name__
        raise CorruptFileError(
            path, KIND, f"entries holds {n} samples, fewer than the {MIN_SAMPLES} a log needs"
        )
    mode = data.get("mode", "position")
    if mode not in ("position", "current"):
        raise CorruptFileError(path, KIND, f"its mode is {mode!r:.40}, not position or current")
    goal_key = "goal_current" if mode == "current" else "goal_position"
    columns = {k: np.empty(len(entries)) for k in ("timestamp", goal_key, "position")}
    enabled = np.empty(len(entries), dtype=bool)
    volts = []
    for i, entry in enumerate(entries):
        if not isinstance(entry, dict):
            raise CorruptFileError(path, KIND, f"entry {i} is not an object", REMEDY)
        for key, column in columns.items():
            if key not in entry:
                raise CorruptFileError(path, KIND, f"entry {i} has no {key!r}", REMEDY)
            column[i] = _number(path, f"entry {i}'s {key}", entry[key])
        on = entry.get("torque_enable", True)
        if not isinstance(on, (bool, int)) or isinstance(on, int) and on not in (0, 1):
            raise CorruptFileError(path, KIND, f"entry {i}'s torque_enable is {on!r:.40}")
        enabled[i] = bool(on)
        if "input_volts" in entry:
            volts.append(_number(path, f"entry {i}'s input_volts", entry["input_volts"], 0.0))
    t = columns["timestamp"]
    steps = np.diff(t)
    if not np.all(steps > 0):
        k = int(np.argmax(~(steps > 0)))
        raise CorruptFileError(
            path, KIND, f"its timestamps do not increase at entry {k + 1} ({t[k]!r} then "
            f"{t[k + 1]!r})", REMEDY
        )  # fmt: skip
    supply = float(np.mean(volts)) if volts and min(volts) > 0 else vin
    return BenchLog(
        str(path),
        mass,
        length,
        arm,
        kp,
        supply,
        str(data.get("motor", "")),
        str(data.get("trajectory", "")),
        t - t[0],
        columns[goal_key],
        columns["position"],
        enabled,
        mode,
    )


def read_bench_log(path) -> BenchLog:
    """The bench log in ``path``, read through the checked reader and checked.

    Raises:
        CorruptFileError: not a regular file, over :data:`MAX_LOG_BYTES`, not JSON, or as
            :func:`bench_log_from`.
        OSError: the file cannot be read.
    """
    return bench_log_from(read_json(path, KIND, REMEDY, max_bytes=MAX_LOG_BYTES), path)


def write_bench_log(path, log: BenchLog) -> Path:
    """``log`` as a bench log file (the format :func:`read_bench_log` reads), written whole or
    not at all; returns the path."""
    goal_key = "goal_current" if log.mode == "current" else "goal_position"
    entries = [
        {
            "timestamp": float(t),
            goal_key: float(g),
            "position": float(q),
            "torque_enable": bool(on),
            "input_volts": log.supply_V,
        }
        for t, g, q, on in zip(log.t, log.goal, log.q, log.enabled)
    ]
    data = {
        "mass": log.mass_kg,
        "length": log.length_m,
        "arm_mass": log.arm_mass_kg,
        "kp": log.kp,
        "vin": log.supply_V,
        "motor": log.motor,
        "trajectory": log.trajectory,
        "mode": log.mode,
        "entries": entries,
    }
    path = Path(path)
    atomic_write(path, lambda f: f.write(json.dumps(data).encode()))
    return path
