"""Pictures of the Diagram: Graphviz sources of the closed loop and its systems, and their SVGs.

:func:`diagram_dots` returns the Graphviz source of the full Diagram (fixed weights and ANN
tuner) and of the controller systems, with Drake's process-dependent system ids renumbered so the
text is the same in every process (:func:`normalize_dot`); :func:`wiring_dot` draws a Diagram's
wiring from the connections that run. :func:`write_diagrams` stores ``<name>.dot`` and renders
``<name>.svg`` with Graphviz ``dot``, stamping the SVG with the SHA-256 of its .dot
(:func:`svg_dot_hash`) so a stale picture is detected without Graphviz.
"""

from __future__ import annotations

import hashlib
import re
import shutil
import subprocess
from pathlib import Path

from ..base.errors import RenderToolMissingError
from ..base.fileio import atomic_write

#: Where ``stewart-drake diagrams`` writes by default: ``diagrams/`` in the current folder (from
#: the repository's root, the committed pictures).
DIAGRAMS_DIR = Path("diagrams")
_HASH_COMMENT = "<!-- dot-sha256: {} -->"


def normalize_dot(dot: str) -> str:
    """The same Graphviz text for the same Diagram, whatever ran before in the process.

    Drake numbers systems with a process-wide counter (``s123``, ``_123``, ``cluster123...``)
    and lists edges in the order of its connection map, keyed by memory address. Systems are
    renumbered by first appearance (the node list comes first, in the order they were added),
    then each run of consecutive edge lines is sorted.
    """
    ids: dict[str, str] = {}

    def renumber(match: re.Match) -> str:
        return match.group(1) + ids.setdefault(match.group(2), str(len(ids)))

    lines = re.sub(r"(digraph _|clusters?|\bs)(\d+)", renumber, dot).split("\n")
    out, edges = [], []
    for line in lines + [""]:
        if " -> " in line:
            edges.append(line)
            continue
        out += sorted(edges)
        edges = []
        out.append(line)
    return "\n".join(out[:-1])


def _html_node(name: str, kind: str, inputs, outputs, color: str = "") -> str:
    """A Graphviz node: a title cell, then the input ports left and the output ports right."""
    ins, outs = sorted(inputs), sorted(outputs)
    cells = "".join(
        "<TR>"
        + (
            f'<TD PORT="in_{ins[k]}" BORDER="1">{ins[k]}</TD>'
            if k < len(ins)
            else '<TD BORDER="0"></TD>'
        )
        + (
            f'<TD PORT="out_{outs[k]}" BORDER="1">{outs[k]}</TD>'
            if k < len(outs)
            else '<TD BORDER="0"></TD>'
        )
        + "</TR>"
        for k in range(max(len(ins), len(outs), 1))
    )
    color = f' BGCOLOR="{color}"' if color else ""
    return (
        f'  "{name}" [label=<<TABLE BORDER="0" CELLSPACING="0"><TR><TD BORDER="1" '
        f'COLSPAN="2"{color}><B>{name}</B><BR/>{kind}</TD></TR>{cells}</TABLE>>];'
    )


def wiring_dot(diagram, title: str = "", highlight: tuple = ("station",)) -> str:
    """A picture of a Diagram's wiring: one box per subsystem (loggers left out) with only the
    ports in use, each edge labelled with the signal's name and size, and the Diagram's own
    exported ports as the boxes ``inputs`` and ``outputs``. Built from ``connection_map()`` and
    the exported ports' locators, so it is always the wiring that runs, and it leaves out the
    ports nobody connects (a Drake release that adds ports to the plant draws the same picture).

    Args:
        diagram: a built Drake ``Diagram``.
        title: a caption drawn above the picture ("" for none).
        highlight: names of subsystems drawn shaded (the station in a closed loop).
    Returns:
        DOT text (left to right).
    """
    used, edges = _wiring(diagram)
    lines = [
        f"digraph {_dot_id(diagram.get_name())} {{",
        "  rankdir=LR;",
        "  node [shape=none, fontsize=10];",
    ]
    if title:
        lines.append(f'  labelloc=t; fontsize=12; label="{title}";')
    for name in sorted(used):
        kind, inputs, outputs = used[name]
        lines.append(
            _html_node(
                name,
                kind,
                inputs,
                outputs,
                "#dbe9f6"
                if name in highlight
                else "#eeeeee"
                if name in ("inputs", "outputs")
                else "",
            )
        )
    return "\n".join(lines + sorted(edges) + ["}", ""])


def is_log(system, connections: dict) -> bool:
    """Whether ``system`` only logs: a ``VectorLogSink``, or a ``Multiplexer`` gathering a
    log's signals into one (``connections``: a Diagram's ``connection_map()``)."""
    kind = type(system).__name__
    if kind == "VectorLogSink":
        return True
    return kind == "Multiplexer" and any(
        src is system and type(dst).__name__ == "VectorLogSink"
        for (dst, _), (src, _) in connections.items()
    )


def _wiring(diagram) -> tuple[dict, list]:
    """The wiring :func:`wiring_dot` draws: ({subsystem name: (its type's name, input ports in
    use, output ports in use)}, [DOT edge lines]), loggers left out, the Diagram's exported
    ports as the subsystems ``inputs`` and ``outputs``."""
    from pydrake.systems.framework import InputPortIndex, OutputPortIndex

    def vector_size(port) -> str:
        return f" ({port.size()})" if port.get_data_type().name == "kVectorValued" else ""

    edges: list = []
    used: dict = {}

    def edge(src, out_name, dst, in_name, label):
        used.setdefault(src[0], (src[1], set(), set()))[2].add(out_name)
        used.setdefault(dst[0], (dst[1], set(), set()))[1].add(in_name)
        edges.append(
            f'  "{src[0]}":"out_{out_name}" -> "{dst[0]}":"in_{in_name}" '
            f'[label="{label}", fontsize=9];'
        )

    connections = diagram.connection_map()
    for (dst, i), (src, j) in connections.items():
        if is_log(dst, connections):
            continue
        out, inp = src.get_output_port(j), dst.get_input_port(i)
        edge(
            (src.get_name(), type(src).__name__),
            out.get_name(),
            (dst.get_name(), type(dst).__name__),
            inp.get_name(),
            out.get_name() + vector_size(out),
        )
    for i in range(diagram.num_input_ports()):
        port = diagram.get_input_port(i)
        for dst, j in diagram.GetInputPortLocators(InputPortIndex(i)):
            edge(
                ("inputs", "exported"),
                port.get_name(),
                (dst.get_name(), type(dst).__name__),
                dst.get_input_port(j).get_name(),
                port.get_name() + vector_size(port),
            )
    for i in range(diagram.num_output_ports()):
        port = diagram.get_output_port(i)
        src, j = diagram.get_output_port_locator(OutputPortIndex(i))
        edge(
            (src.get_name(), type(src).__name__),
            src.get_output_port(j).get_name(),
            ("outputs", "exported"),
            port.get_name(),
            port.get_name() + vector_size(port),
        )
    return used, edges


def _dot_id(name: str) -> str:
    return re.sub(r"\W", "_", name) or "diagram"


def control_loop_dot(diagram, title: str = "") -> str:
    """The control loop: :func:`wiring_dot` of the whole closed-loop Diagram, the station drawn
    with the ports in use only.

    Returns:
        DOT text (left to right).
    """
    return wiring_dot(diagram, title)


def titled(dot: str, title: str) -> str:
    """A Drake ``GetGraphvizString`` picture with ``title`` as its caption."""
    head, sep, rest = dot.partition("\n")
    return f'{head}{sep}labelloc=t\nfontsize=12\nlabel="{title}"\n{rest}'


#: The captions of the pictures of the two shipped robots (DOT "\\n" breaks the line).
HARDWARE_CAPTION = (
    "the robot as built (paper_hardware, the default of stewart-drake run)\\n"
    "station: encoders, computation delay, servos with current loop, friction "
    "and torque limit; the LQI estimates the pose from the encoders (FK)"
)


IDEAL_CAPTION = (
    "the ideal robot (paper_ideal)\\nthe controller reads the exact pose; ideal "
    "torque sources, no friction, no delay"
)


def diagram_dots() -> dict[str, str]:
    """Graphviz sources of the Diagram pictures, normalized (:func:`normalize_dot`).

    Every picture is built from the default scenario of ``stewart-drake run``, the robot as
    built (``paper_hardware``), but the ones whose name ends in ``_ideal`` (``paper_ideal``).

    Returns:
        {name: DOT text}: ``control_loop`` and ``control_loop_ideal`` (:func:`control_loop_dot`
        of the fixed-weight LQI loop: the station with the ports in use), ``station`` and
        ``station_ideal`` (:func:`wiring_dot` of the robot's Diagram inside), ``diagram_fixed``
        and ``diagram_ann`` (Drake's picture of the whole closed loop, one level deep, with fixed
        weights and with the ANN tuner), ``lqi_controller``, ``density_features``,
        ``ann_tuner`` and ``crank_pd`` (the controller systems and their ports: each follows
        the controller contract, so either plugs into the same Diagram).
    """
    from ..control.tuning import AnnTunerDriver
    from ..run.diagram import make_stewart_diagram
    from ..run.scenario import PdDriver, use_paper_tuner
    from ..run.scenario_io import DEFAULT_SCENARIO, load_scenario

    def scenario(name=DEFAULT_SCENARIO):
        return load_scenario(name)

    fixed = make_stewart_diagram(scenario())
    ideal = make_stewart_diagram(scenario("paper_ideal"))
    ann = make_stewart_diagram(use_paper_tuner(scenario(), AnnTunerDriver()))
    pd = scenario()
    pd.controller = PdDriver()
    pd = make_stewart_diagram(pd)
    raw = {
        "control_loop": control_loop_dot(
            fixed.diagram, f"closed loop with the LQI: {HARDWARE_CAPTION}"
        ),
        "control_loop_ideal": control_loop_dot(
            ideal.diagram, f"closed loop with the LQI: {IDEAL_CAPTION}"
        ),
        "station": wiring_dot(
            fixed.station, f"inside the station: {HARDWARE_CAPTION}", highlight=()
        ),
        "station_ideal": wiring_dot(
            ideal.station, f"inside the station: {IDEAL_CAPTION}", highlight=()
        ),
        "diagram_fixed": titled(
            fixed.diagram.GetGraphvizString(max_depth=1), f"fixed weights: {HARDWARE_CAPTION}"
        ),
        "diagram_ann": titled(
            ann.diagram.GetGraphvizString(max_depth=1), f"the paper's ANN tuner: {HARDWARE_CAPTION}"
        ),
        "lqi_controller": fixed.controller.GetGraphvizString(),
        # With the paper's tuner the loop has both (StewartDiagram types them optional).
        "density_features": ann.features.GetGraphvizString(),  # type: ignore[union-attr]
        "ann_tuner": ann.tuner.GetGraphvizString(),  # type: ignore[union-attr]
        "crank_pd": pd.controller.GetGraphvizString(),
    }
    return {name: normalize_dot(dot) for name, dot in raw.items()}


def dot_hash(dot: str) -> str:
    """SHA-256 hex digest of a DOT text (UTF-8)."""
    return hashlib.sha256(dot.encode("utf-8")).hexdigest()


def svg_dot_hash(svg: str) -> str | None:
    """The DOT hash stamped into an SVG by :func:`write_diagrams`, or None if there is none."""
    match = re.search(r"<!-- dot-sha256: ([0-9a-f]{64}) -->", svg)
    return match.group(1) if match else None


def render_svg(dot: str, dot_executable: str | None = None) -> str:
    """SVG text of ``dot`` rendered by Graphviz, stamped with ``<!-- dot-sha256: ... -->``.

    Raises:
        RenderToolMissingError: Graphviz ``dot`` is not on PATH.
    """
    exe = dot_executable or shutil.which("dot")
    if exe is None:
        raise RenderToolMissingError(
            "Graphviz `dot` is not on PATH: install graphviz (e.g. `apt install graphviz`) to "
            "render the .svg pictures; the .dot sources were written"
        )
    svg = subprocess.run(
        [exe, "-Tsvg"], input=dot, capture_output=True, text=True, check=True
    ).stdout
    stamp = _HASH_COMMENT.format(dot_hash(dot))
    head, sep, rest = svg.partition("?>\n")  # after the XML declaration
    return head + sep + stamp + "\n" + rest if sep else stamp + "\n" + svg


def write_diagrams(out_dir: str | Path = DIAGRAMS_DIR, render: bool = True) -> list[Path]:
    """Write ``<name>.dot`` for each of :func:`diagram_dots` and, if ``render``, ``<name>.svg``.

    Returns:
        the paths written.
    Raises:
        RenderToolMissingError: ``render`` and no Graphviz ``dot`` (the .dot files are written).
    """
    out = Path(out_dir)
    dots = diagram_dots()
    written = []
    for name, dot in dots.items():
        path = out / f"{name}.dot"
        atomic_write(path, lambda f, d=dot: f.write(d.encode("utf-8")))
        written.append(path)
    if render:
        for name, dot in dots.items():
            svg = render_svg(dot)
            path = out / f"{name}.svg"
            atomic_write(path, lambda f, s=svg: f.write(s.encode("utf-8")))
            written.append(path)
    return written
