"""A servo's identified model as a file: JSON, written whole or not at all
(:func:`write_model`), read through the checked reader and every value checked
(:func:`read_model`). It holds numbers and names only: reading it runs nothing.

    {"format": "stewart-drake servo model", "version": 1, "servo": "XL330-M288-T",
     "model_class": "m6", "k_Nm_per_A": 0.36, "resistance_ohm": 2.8, "armature_kg_m2": 0.0018,
     "q_offset_rad": 0.03, "friction": {"coulomb_Nm": 0.005, ...},
     "identified_on": ["a.json", ...], "mae_rad": 0.02, "seed": 0}
"""

from __future__ import annotations

import json
import math
from pathlib import Path

from ..base.errors import CorruptFileError, InvalidConfigError
from ..base.fileio import atomic_write, read_json
from .bench import BenchModel
from .identify import Identified

FORMAT = "stewart-drake servo model"
VERSION = 1
KIND = "servo model file"
REMEDY = "write one with `stewart-drake servo identify LOG... --servo NAME --out FILE`"
#: The largest model file read, bytes.
MAX_MODEL_BYTES = 1e6
#: The models the package ships, identified on real servos' bench logs: {servo: file}
#: (docs/servo_bench.md says on which logs and how well each replays the others).
SHIPPED = {
    "XL330-M288-T": Path(__file__).resolve().parents[1] / "data" / "servos" / "XL330-M288-T_m6.json"
}


def model_path(name) -> Path:
    """The model file ``name`` names: a file, or, where no file has that name, a shipped model's
    servo (:data:`SHIPPED`)."""
    path = Path(str(name))
    if not path.exists() and str(name) in SHIPPED:
        return SHIPPED[str(name)]
    return path


def write_model(path, identified: Identified, seed: int) -> Path:
    """``identified`` as a model file at ``path``; returns the path."""
    m = identified.model
    data = {
        "format": FORMAT,
        "version": VERSION,
        "servo": m.servo,
        "model_class": m.model_class,
        "k_Nm_per_A": m.k_Nm_per_A,
        "resistance_ohm": m.resistance_ohm,
        "armature_kg_m2": m.armature_kg_m2,
        "q_offset_rad": m.q_offset_rad,
        "current_time_constant_s": m.current_time_constant_s,
        "friction": dict(m.friction),
        "identified_on": list(identified.logs),
        "mae_rad": identified.mae_rad,
        "seed": int(seed),
        "search_settled": identified.settled,
        "search_generations": identified.generations,
    }
    path = Path(path)
    atomic_write(path, lambda f: f.write((json.dumps(data, indent=1) + "\n").encode()))
    return path


def read_model(path) -> tuple[BenchModel, tuple[str, ...]]:
    """The :class:`~.bench.BenchModel` in the model file ``path`` (or the shipped model of the
    servo it names, :func:`model_path`), and the names of the logs it was identified on (a
    replay says which logs it was not).

    Raises:
        CorruptFileError: not a regular file, too large, not JSON, not this format or version,
            a value missing, not a number, or out of its range (named).
        OSError: the file cannot be read.
    """
    path = model_path(path)
    data = read_json(path, KIND, REMEDY, max_bytes=MAX_MODEL_BYTES)
    if not isinstance(data, dict) or data.get("format") != FORMAT:
        raise CorruptFileError(path, KIND, f"its format is not {FORMAT!r}", REMEDY)
    if data.get("version") != VERSION:
        raise CorruptFileError(
            path, KIND, f"it is version {data.get('version')!r}, not {VERSION}", REMEDY
        )
    numbers = {}
    for key in ("k_Nm_per_A", "resistance_ohm", "armature_kg_m2", "q_offset_rad"):
        numbers[key] = _number(path, key, data.get(key))
    numbers["current_time_constant_s"] = _number(
        path, "current_time_constant_s", data.get("current_time_constant_s", 0.0)
    )
    friction = data.get("friction")
    if not isinstance(friction, dict):
        raise CorruptFileError(path, KIND, "its friction is not an object of terms", REMEDY)
    terms = {str(name): _number(path, f"friction {name}", v) for name, v in friction.items()}
    for key in ("servo", "model_class"):
        if not isinstance(data.get(key), str):
            raise CorruptFileError(path, KIND, f"its {key} is not a name", REMEDY)
    logs = data.get("identified_on", [])
    if not isinstance(logs, list) or not all(isinstance(name, str) for name in logs):
        raise CorruptFileError(path, KIND, "its identified_on is not a list of names", REMEDY)
    try:
        model = BenchModel(data["servo"], data["model_class"], friction=terms, **numbers)
    except InvalidConfigError as err:
        raise CorruptFileError(path, KIND, str(err), REMEDY) from None
    return model, tuple(logs)


def _number(path, key: str, value) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise CorruptFileError(path, KIND, f"its {key} is {value!r:.40}, not a finite number")
    return float(value)
