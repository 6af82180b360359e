"""Scenario files: loading, the shipped names, ``--set`` overrides, and the guards on what is read.

:func:`load_scenario` reads a YAML file or a shipped scenario's name (:func:`shipped_scenarios`,
``scenarios/*.yaml``) into a validated :class:`~.scenario.Scenario`, refusing before anything is
built what could hurt: a file over :data:`MAX_SCENARIO_BYTES`, text that is not UTF-8, a key given
twice in one mapping, a field the schema does not have. Loading never executes: Drake's
``yaml_load_typed`` builds only the schema's dataclasses. :func:`apply_override` sets one
``key.sub=value`` typed by the schema; :func:`apply_run_options` applies the shorthand options of
``stewart-drake run`` (``--duration``, ``--controller``, ``--tuner`` ...) the same way.
"""

import dataclasses
import importlib.resources
import typing
from pathlib import Path

from pydrake.common.yaml import yaml_load_typed

from ..base.errors import (
    CorruptFileError,
    InvalidConfigError,
    InvalidGeometryError,
    MissingFileError,
    StewartError,
)
from ..control.tuning import AnnTunerDriver, RatioTunerDriver
from .scenario import Scenario, use_paper_tuner

#: The scenario `run`, `collect`, `evaluate`, `workspace` and the diagram pictures use unless told:
#: the robot as built.
DEFAULT_SCENARIO = "paper_hardware"
#: The scenario ``robot`` uses unless told: the paper's experiment on the servo bus.
ROBOT_SCENARIO = "paper_bus"


#: Where the shipped scenarios are (``scenarios/`` of the repository, installed as package data).
def shipped_scenarios() -> dict:
    """{name: path} of the scenarios shipped with the package (``scenarios/*.yaml``; not the
    design requirements files beside them, ``*_requirements.yaml``)."""
    folder = importlib.resources.files("stewart_drake.scenarios")
    return {
        Path(p.name).stem: Path(str(p))
        for p in folder.iterdir()
        if p.name.endswith(".yaml") and not p.name.endswith("_requirements.yaml")
    }


def load_scenario(source="paper_ideal", overrides: typing.Sequence[str] = ()) -> Scenario:
    """Load a scenario from a YAML file or a shipped name, apply ``key=value`` overrides, validate.

    Args:
        source: a path to a ``.yaml`` file, or the name of a shipped scenario
            (:func:`shipped_scenarios`, e.g. "paper_ideal").
        overrides: ``"key.sub=value"`` strings (YAML values: ``controller.omega_Q=10``,
            ``controller=!PdDriver {}``, ``guard.max_closure_error_m=null``), applied in order.
    Returns:
        the validated :class:`Scenario`.
    Raises:
        MissingFileError: no such file or name.
        CorruptFileError (an InvalidConfigError): the file is empty, not UTF-8, not YAML, or
            YAML that does not fit the schema (unknown or mistyped field, named).
        InvalidConfigError, InvalidGeometryError, MissingFileError: a bad override, or a value
            out of range (named by file and field path).
    """
    from ..base.fileio import (
        YAML_BYTES_PER_BYTE,
        check_parse_memory,
        decode_text,
        note_input,
        read_checked,
    )

    shipped = shipped_scenarios()
    if not isinstance(source, (str, Path)):
        raise MissingFileError(
            f"a scenario is a .yaml path or a shipped name ({', '.join(sorted(shipped))}), "
            f"got {source!r}"
        )
    path = Path(source)
    if not path.exists():
        if str(source) in shipped:
            path = shipped[str(source)]
        else:
            raise MissingFileError(
                f"no scenario file {source} and no shipped scenario of that "
                f"name (shipped: {', '.join(sorted(shipped))})"
            )
    remedy = "fix it, or start from `stewart-drake scenario paper_hardware --out FILE.yaml`"
    raw = read_checked(
        path,
        "scenario file",
        MAX_SCENARIO_BYTES,
        remedy + "; long data (a reference) belongs in a CSV file",
    )
    check_parse_memory(path, "scenario file", raw, bytes_per_byte=YAML_BYTES_PER_BYTE)
    if not raw.strip():
        raise CorruptFileError(path, "scenario file", "it is empty", remedy)
    text = decode_text(raw, path, "scenario file", remedy)
    try:
        _refuse_duplicate_keys(text)
        text = _untag_sections(text)
        scenario = yaml_load_typed(schema=Scenario, data=text, allow_schema_with_no_yaml=True)
    except StewartError as err:
        raise _in_file(err, path) from None
    except Exception as err:  # noqa: BLE001 - yaml and Drake's loader raise several types
        problem = _one_line(err)
        if "['_tag']" in problem:
            problem = (
                "a tag (!Name) that is not its section's own class: a tag picks a choice "
                "(controller, reference, tuner); a section (hardware, learning, ...) takes none, "
                "or its class's name (learning: !IlcDriver {...})"
            )
        elif not problem.startswith("not YAML"):
            problem = f"it does not fit the Scenario schema: {problem}"
        raise CorruptFileError(path, "scenario file", problem, remedy) from None
    for override in overrides:
        apply_override(scenario, override)
    try:
        scenario = scenario.validate()
    except StewartError as err:
        raise _in_file(
            err, f"{path} with --set {', '.join(overrides)}" if overrides else path
        ) from None
    for field, named in scenario_files(scenario):  # a command never writes over them
        note_input(f"the scenario's {field} {named}", named)
    return scenario


#: The fields of a scenario's sections that name a file it reads: a reference's CSV or trace,
#: a tuner's weights, a learned feed-forward model.
FILE_FIELDS = ("path", "weights", "learned_from")


def scenario_files(scenario) -> list[tuple[str, str]]:
    """(field path, file) of every file ``scenario`` names (:data:`FILE_FIELDS` of any of its
    sections, e.g. ``("reference.path", "trace.csv")``), empty names left out."""
    found: list[tuple[str, str]] = []

    def walk(value, prefix: str) -> None:
        if not dataclasses.is_dataclass(value) or isinstance(value, type):
            return
        for field in dataclasses.fields(value):
            item = getattr(value, field.name, None)
            if field.name in FILE_FIELDS and isinstance(item, str) and item:
                found.append((prefix + field.name, item))
            else:
                walk(item, f"{prefix}{field.name}.")

    walk(scenario, "")
    return found


def read_yaml_text(path, kind: str, max_bytes: float, remedy: str) -> str:
    """The text of a YAML file a user names (a design's requirements, a registration), checked
    as a scenario's is before anything parses it: a regular file of at most ``max_bytes``
    (:func:`~stewart_drake.base.fileio.read_checked`), memory for its parse, not empty, UTF-8,
    YAML without a key twice in one mapping or anchors expanding past
    :data:`MAX_SCENARIO_NODES` (:func:`_refuse_duplicate_keys`).

    Args:
        path: the file.  kind: what it is, for messages ("registration file").
        max_bytes: the largest such file, bytes.  remedy: what to do about a bad one.
    Raises:
        MissingFileError: no such file.  CorruptFileError: not a regular file, too large,
            empty, not UTF-8, not YAML.  InvalidConfigError: a key twice, anchors too many,
            more memory than available; each naming the file.
    """
    from ..base.fileio import YAML_BYTES_PER_BYTE, check_parse_memory, decode_text, read_checked

    if not isinstance(path, (str, Path)) or not Path(path).exists():
        raise MissingFileError(f"no {kind} {path!r}: check the path")
    raw = read_checked(path, kind, max_bytes, remedy)
    check_parse_memory(path, kind, raw, bytes_per_byte=YAML_BYTES_PER_BYTE)
    if not raw.strip():
        raise CorruptFileError(path, kind, "it is empty", remedy)
    text = decode_text(raw, path, kind, remedy)
    try:
        _refuse_duplicate_keys(text)
    except StewartError as err:
        raise _in_file(err, path) from None
    except Exception as err:  # noqa: BLE001 - PyYAML raises several types
        raise CorruptFileError(path, kind, _one_line(err), remedy) from None
    return text


#: Largest scenario file read, bytes: a scenario is a few kB; parsing is about 5 s per MB.
MAX_SCENARIO_BYTES = 256 * 1024


#: Most YAML nodes a scenario may expand to, every use of an anchor (``*a``, ``<<: *a``)
#: counted: a full scenario has about 200. Drake's loader expands aliases and merge keys, so a
#: few hundred bytes of nested merges would otherwise expand to billions of nodes.
MAX_SCENARIO_NODES = 100_000


def _refuse_duplicate_keys(text: str) -> None:
    """Refuse a mapping that names a key twice (YAML loaders keep the last silently), and a
    document that expands to more than :data:`MAX_SCENARIO_NODES` nodes.

    The document is composed, not constructed (PyYAML's node graph: tags are not resolved,
    nothing is built), and each node is visited once, so aliases cannot multiply the work; the
    expanded size is counted on that graph (:func:`_expanded_nodes`) before Drake's loader,
    which expands it, sees the text.
    Raises:
        InvalidConfigError: names the key and its two lines; or the expanded size.
    """
    import yaml

    root = yaml.compose(text, Loader=yaml.SafeLoader)
    seen, stack = set(), [root] if root is not None else []
    while stack:
        node = stack.pop()
        if id(node) in seen:
            continue
        seen.add(id(node))
        if isinstance(node, yaml.MappingNode):
            first: dict[str, int] = {}
            for key, value in node.value:
                if isinstance(key, yaml.ScalarNode) and key.value != "<<":
                    if key.value in first:
                        raise InvalidConfigError(
                            f"the key {key.value!r} appears twice in one mapping (lines "
                            f"{first[key.value] + 1} and {key.start_mark.line + 1}); keep one"
                        )
                    first[key.value] = key.start_mark.line
                stack += [key, value]
        elif isinstance(node, yaml.SequenceNode):
            stack += node.value
    if root is not None and (size := _expanded_nodes(root)) > MAX_SCENARIO_NODES:
        raise InvalidConfigError(
            f"its anchors and merge keys expand to {size:.3g} YAML nodes, over the bound of "
            f"{MAX_SCENARIO_NODES:,} (a scenario has a few hundred): write the values out"
        )


def _section_class(hint):
    """The one dataclass a field holds (``X`` or ``X | None``), or None for a choice (a union of
    several classes, written with a tag) or a plain value."""
    import typing

    kinds = [k for k in typing.get_args(hint) or (hint,) if k is not type(None)]
    if len(kinds) == 1 and dataclasses.is_dataclass(kinds[0]):
        return kinds[0]
    return None


def _untag_sections(text: str) -> str:
    """``text`` with the tag of each section written as its own class's name removed
    (``learning: !IlcDriver {...}``, ``hardware: !Hardware ...``): a section is not a choice,
    and Drake's loader reads a tag there as an unknown field ``_tag``. Only such tags are
    removed, at the positions the composed document gives; anything else is left to the
    loader to refuse."""
    import typing

    import yaml

    root = yaml.compose(text, Loader=yaml.SafeLoader)
    cuts: list[tuple[int, int]] = []
    stack = [(root, Scenario)] if isinstance(root, yaml.MappingNode) else []
    while stack:
        node, cls = stack.pop()
        hints = typing.get_type_hints(cls)
        for key, value in node.value:
            section = (
                _section_class(hints.get(key.value)) if isinstance(key, yaml.ScalarNode) else None
            )
            if section is None or not isinstance(value, yaml.MappingNode):
                continue
            tag, at = f"!{section.__name__}", value.start_mark.index
            if value.tag == tag and text[at : at + len(tag)] == tag:
                cuts.append((at, at + len(tag)))
            stack.append((value, section))
    for start, end in sorted(cuts, reverse=True):
        text = text[:start] + text[end:]
    return text


def _expanded_nodes(root) -> int:
    """How many nodes the composed document ``root`` has once every alias is expanded: each
    node's count is 1 + its children's, computed once per node (aliases share their node)."""
    import yaml

    def children(node):
        if isinstance(node, yaml.MappingNode):
            return [n for pair in node.value for n in pair]
        return node.value if isinstance(node, yaml.SequenceNode) else []

    size: dict[int, int] = {}
    stack = [(root, False)]
    while stack:
        node, ready = stack.pop()
        if id(node) in size:
            continue
        if ready:
            size[id(node)] = 1 + sum(size[id(c)] for c in children(node))
        else:
            stack.append((node, True))
            stack += [(c, False) for c in children(node) if id(c) not in size]
    return size[id(root)]


def _in_file(err: StewartError, where) -> StewartError:
    """``err`` with "<where>: " in front of its message, when its class takes just a message
    (InvalidConfigError, InvalidGeometryError, MissingFileError); other errors as they are."""
    if type(err) not in (InvalidConfigError, InvalidGeometryError, MissingFileError):
        return err
    return type(err)(f"{where}: {err}")


def apply_override(scenario: Scenario, override: str) -> None:
    """Set one ``key.sub=value`` (value in YAML) on ``scenario`` in place, typed by the schema.

    Raises:
        InvalidConfigError: no ``=``, a key that is not a field (names it), or a value the field's
            type does not accept.
    """
    if len(override.encode(errors="replace")) > MAX_SCENARIO_BYTES:
        raise InvalidConfigError(
            f"--set {override[:40]}...: {len(override):,} characters, over the bound of a "
            f"scenario file ({MAX_SCENARIO_BYTES:,} bytes); long data belongs in a file"
        )
    key, sep, value = override.partition("=")
    key = key.strip()
    if not sep or not key:
        raise InvalidConfigError(
            f"an override must be key=value (e.g. controller.omega_Q=10), got {override!r}"
        )
    *parents, leaf = key.split(".")
    target = scenario
    for name in parents:
        if name not in _field_names(target):
            raise InvalidConfigError(
                f"--set {key}: {name!r} is not a field of {type(target).__name__}"
            )
        target = getattr(target, name)
    fields = _field_names(target)
    if leaf not in fields:
        raise InvalidConfigError(
            f"--set {key}: {leaf!r} is not a field of "
            f"{type(target).__name__} (fields: {', '.join(sorted(fields))})"
        )
    try:
        _refuse_duplicate_keys(f"{leaf}: {value}\n")
    except StewartError as err:
        raise InvalidConfigError(f"--set {key}: {err}") from None
    except Exception as err:  # noqa: BLE001 - yaml raises several types
        raise InvalidConfigError(f"--set {key}={value}: {_one_line(err)}") from None
    try:
        updated = yaml_load_typed(
            schema=type(target),
            data=f"{leaf}: {value}\n",
            defaults=target,
            allow_schema_with_no_yaml=True,
        )
    except Exception as err:  # noqa: BLE001 - yaml and Drake's loader raise several types
        raise InvalidConfigError(f"--set {key}={value}: {_one_line(err)}") from None
    setattr(target, leaf, getattr(updated, leaf))


def _field_names(value) -> list[str]:
    """The fields of a scenario dataclass or of a Drake config struct (``__fields__``, what
    ``yaml_load_typed`` reads: ``plant.time_step``, ``simulator.target_realtime_rate``)."""
    if dataclasses.is_dataclass(value):
        return [f.name for f in dataclasses.fields(value)]
    return [f.name for f in getattr(type(value), "__fields__", ())]


def _one_line(err: BaseException) -> str:
    """An exception's text on one line, at most 300 characters; for a YAML syntax error its
    problem and where (PyYAML's message spans several lines with the text it quotes)."""
    import yaml

    if isinstance(err, yaml.MarkedYAMLError) and err.problem:
        mark = err.problem_mark
        where = f" at line {mark.line + 1}, column {mark.column + 1}" if mark else ""
        text = f"not YAML ({' '.join(filter(None, (err.context, err.problem)))}{where})"
    else:
        text = " ".join(str(err).split()) or type(err).__name__
    return text if len(text) <= 300 else text[:297] + "..."


def apply_run_options(
    scenario: Scenario,
    *,
    duration_s=None,
    trajectory=None,
    trajectory_file=None,
    controller=None,
    omega_Q=None,
    omega_R=None,
    tuner=None,
    tuner_weights=None,
    default_ann_weights=None,
    divergence_dir=None,
) -> Scenario:
    """Apply the shorthand options of ``stewart-drake run`` to ``scenario`` (each only when not
    None), in place, after the file and its ``--set`` overrides; returns it validated.

    Args:
        duration_s: ``--duration``, s. trajectory: ``--trajectory``, a named reference.
        trajectory_file: ``--trajectory-file``, a CSV reference (the run then lasts as long as
            the file unless ``duration_s`` is given).
        controller: ``--controller``: "lqi" (the scenario's LQI options, if it has any) or
            "pd"; None keeps the scenario's. omega_Q, omega_R: ``--omega-q``, ``--omega-r``.
        tuner: ``--tuner``: "ann" (with the paper's gain switching), "ratio" or "none".
        tuner_weights: ``--tuner-weights``, a tuner's ``.npz``. default_ann_weights: the ANN
            weights used when ``tuner`` is "ann" without ``tuner_weights`` and the file exists
            (what ``stewart-drake train`` last wrote); else the shipped ones.
        divergence_dir: ``guard.divergence_dir``, where a diverged run's logs go.
    Raises:
        InvalidConfigError: ``tuner_weights`` without an "ann" or "ratio" tuner, both
            ``trajectory`` and ``trajectory_file``, a controller name never registered, a value
            out of range. MissingFileError: no such weights or CSV file.
    """
    from ..control.pd import PdDriver
    from ..references.samples import CsvReference, load_csv_trajectory
    from ..references.trajectories import NamedReference

    if tuner_weights is not None and tuner not in ("ann", "ratio"):
        raise InvalidConfigError(
            "--tuner-weights needs --tuner ann or --tuner ratio (the weights are a tuner's)"
        )
    if duration_s is not None:
        scenario.duration_s = duration_s
    if trajectory is not None and trajectory_file is not None:
        raise InvalidConfigError("give --trajectory or --trajectory-file, not both")
    if trajectory is not None:
        scenario.reference = NamedReference(trajectory)
    if trajectory_file is not None:
        scenario.reference = CsvReference(trajectory_file)
        if duration_s is None:  # the run lasts as long as the file
            csv = load_csv_trajectory(trajectory_file)
            scenario.duration_s = csv.end_time - csv.start_time
    if controller == "pd":
        scenario.controller = PdDriver()
    elif controller == "lqi":
        scenario.controller = scenario.lqi()  # the scenario's LQI options, if it has any
    weights = {k: v for k, v in (("omega_Q", omega_Q), ("omega_R", omega_R)) if v is not None}
    if weights:
        scenario.controller = scenario.controller.with_weights(**weights)
    if tuner == "ann":
        weights_file = tuner_weights
        if (
            weights_file is None
            and default_ann_weights is not None
            and Path(default_ann_weights).exists()
        ):
            weights_file = str(default_ann_weights)
        use_paper_tuner(scenario, AnnTunerDriver(weights=weights_file or ""))
    elif tuner == "ratio":
        scenario.tuner = RatioTunerDriver(weights=tuner_weights or "")
    elif tuner == "none":
        scenario.tuner = None
    if divergence_dir is not None:
        scenario.guard.divergence_dir = str(divergence_dir)
    scenario.controller.resolve()  # a name never registered: refused
    return scenario.validate()
