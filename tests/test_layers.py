"""The package's imports flow one way: a small core by Drake role, then the features, then the
command. Core: base (errors, checks, the checked reader; the generated LCM types) -> robot
(geometry, kinematics, statics, limits) -> plant (the MultibodyPlant, clearance, MuJoCo) ->
control -> references -> station -> run -> execution. Features above it: viz (replays and
pictures) below paper, analysis, organ_motion and tuner, which are below evaluation, design,
verification (verify, alone or with its surrogate's pair, and its record) and studies; live
(the robot live, and calibrate, which registers a tracker by verification's fit) above them;
cli on top. The command's
shared options (execution.options: argument types, output checks, the scenario, trace and
runner options), which every feature's command module imports, sit in execution, below the
features. A package imports its own package or a lower rank, never
a higher one nor another package of its own rank. Every import is counted (module level, inside
functions, under TYPE_CHECKING)."""

import ast
import pathlib

import pytest

PACKAGE = pathlib.Path(__file__).resolve().parent.parent / "stewart_drake"
#: Rank of each package; a module may import its own package or one of a lower rank.
LAYERS = {
    "base": 0,
    "lcmtypes": 0,
    "robot": 1,
    "plant": 2,
    "control": 3,
    "references": 4,
    "station": 5,
    "run": 6,
    "execution": 7,
    "viz": 8,
    "paper": 9,
    "analysis": 9,
    "organ_motion": 9,
    "tuner": 9,
    "calibration": 9,
    "actuator": 9,
    "evaluation": 10,
    "design": 10,
    "verification": 10,
    "studies": 10,
    "live": 11,
    "cli": 12,
}
#: Modules ranked apart from their package (a key of LAYERS): ``python -m stewart_drake`` is the
#: command, beside cli; a module imported from below its package's rank moves down to a package
#: of that rank.
MODULE_LAYERS: dict[str, str] = {"stewart_drake.__main__": "cli"}


def _module_name(path: pathlib.Path) -> str:
    parts = path.relative_to(PACKAGE.parent).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def _layer(module: str) -> str:
    if module in MODULE_LAYERS:
        return MODULE_LAYERS[module]
    parts = module.split(".")
    return parts[1] if len(parts) > 2 or (len(parts) == 2 and parts[1] in LAYERS) else "base"


def import_graph() -> dict:
    """{module: {imported stewart_drake modules}} from the source files' ASTs."""
    modules = {_module_name(p): p for p in PACKAGE.rglob("*.py")}
    graph = {}
    for name, path in modules.items():
        package = name if path.name == "__init__.py" else name.rsplit(".", 1)[0]
        targets = set()
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.ImportFrom):
                if node.level:
                    base = package.split(".")[: len(package.split(".")) - node.level + 1]
                    root = ".".join(base + ([node.module] if node.module else []))
                else:
                    root = node.module or ""
                candidates = [f"{root}.{a.name}" for a in node.names] + [root]
            elif isinstance(node, ast.Import):
                candidates = [a.name for a in node.names]
            else:
                continue
            targets |= {c for c in candidates if c in modules and c != name}
        graph[name] = targets
    return graph


def test_no_import_goes_up_a_layer():
    upward = []
    for module, targets in import_graph().items():
        if module == "stewart_drake":  # the package facade re-exports base and robot
            assert all(LAYERS[_layer(t)] <= LAYERS["robot"] for t in targets), targets
            continue
        for target in targets:
            here, there = _layer(module), _layer(target)
            if LAYERS[there] > LAYERS[here] or (there != here and LAYERS[there] == LAYERS[here]):
                upward.append(f"{module} ({here}) imports {target} ({there})")
    assert not upward, "imports against the layers:\n" + "\n".join(sorted(upward))


def test_no_import_circle():
    graph = import_graph()
    state, circles = {}, []

    def visit(node, path):
        state[node] = "open"
        for nxt in sorted(graph[node]):
            if state.get(nxt) == "open":
                circles.append(path[path.index(nxt) :] + [nxt])
            elif nxt not in state:
                visit(nxt, path + [nxt])
        state[node] = "done"

    for node in sorted(graph):
        if node not in state:
            visit(node, [node])
    assert not circles, "import circles: " + "; ".join(" -> ".join(c) for c in circles)


def test_no_package_imports_a_package_that_imports_it_back():
    """Packages as wholes (a module's imports counted for its package): no circle. The command
    options lived in cli, which imports every feature, and every feature imported them."""
    graph = import_graph()
    packages: dict[str, set] = {}
    for module, targets in graph.items():
        if module == "stewart_drake":  # the facade re-exports base and robot
            continue
        here = _layer(module)
        packages.setdefault(here, set()).update(_layer(t) for t in targets if _layer(t) != here)
    both_ways = sorted(
        f"{a} <-> {b}"
        for a, targets in packages.items()
        for b in targets
        if a < b and a in packages.get(b, set())
    )
    assert not both_ways, both_ways


def test_the_walker_sees_local_and_relative_imports():
    """The test would pass vacuously if the walker missed imports: check known edges."""
    graph = import_graph()
    assert "stewart_drake.robot.kinematics" in graph["stewart_drake.robot.geometry"]
    assert "stewart_drake.base.errors" in graph["stewart_drake.robot.kinematics"]
    assert "stewart_drake.run.simulate" in graph["stewart_drake.paper.command"]  # local
    assert "stewart_drake.execution.options" in graph["stewart_drake.paper.command"]  # relative
    assert _layer("stewart_drake.base.checks") == "base"
    assert _layer("stewart_drake.execution.options") == "execution"
    assert _layer("stewart_drake.cli.main") == "cli"
    assert _layer("stewart_drake.control.lqi") == "control"
    with pytest.raises(KeyError):
        LAYERS[_layer("stewart_drake.nowhere.x")]


LIVE, SESSION = "stewart_drake.live.", "stewart_drake.live.session"


def _not_driving_the_robot(graph: dict) -> list:
    """The modules of ``live`` that do not take part in driving the robot: a module takes part
    when it imports the servo bus (``station.bus``) or the session, or a module of ``live`` that
    takes part, or when the session imports it (its watchdog, its real-time loop, its
    teleoperation)."""
    live = [m for m in graph if m.startswith(LIVE)]
    driving = {SESSION} | {
        m for m in live if any(t.startswith("stewart_drake.station.bus") for t in graph[m])
    }
    driving |= {m for m in graph[SESSION] if m.startswith(LIVE)}
    grew = True
    while grew:
        more = {m for m in live if m not in driving and graph[m] & driving}
        driving |= more
        grew = bool(more)
    return sorted(set(live) - driving)


def test_live_holds_only_what_drives_the_robot():
    """``live`` is the robot live (the session, what it runs, the commands that open a bus);
    what judges or reports without touching the robot belongs to verification or the studies."""
    graph = import_graph()
    assert _not_driving_the_robot(graph) == []
    # the check sees a module of live that neither drives the bus nor is the session's
    graph[LIVE + "verdict_of_a_file"] = {"stewart_drake.base.measures"}
    assert _not_driving_the_robot(graph) == [LIVE + "verdict_of_a_file"]


#: Lines a module of the package may hold, and a function from ``def`` to its end, docstring in.
MAX_MODULE_LINES, MAX_FUNCTION_LINES = 600, 80
#: The functions longer than that when the limit was set (docs/development.md, "Layout"): none
#: may be added, and one that falls within the limit leaves the list.
LONG_FUNCTIONS = {
    "stewart_drake.verification.verify.verify",
    "stewart_drake.control.servo.controller.CrankServoController.__init__",
    "stewart_drake.analysis.error_budget.error_budget",
    "stewart_drake.station.bus.emulator_config.EmulatorConfig.draw",
    "stewart_drake.verification.command.cmd_verify",
    "stewart_drake.verification.measured_verdict.judge",
    "stewart_drake.run.scenario.Scenario.validate",
}


def _long_functions(tree: ast.Module, module: str) -> set:
    """The qualified names of the functions of ``tree`` over :data:`MAX_FUNCTION_LINES`."""
    found = set()

    def visit(node, prefix):
        for child in ast.iter_child_nodes(node):
            if isinstance(child, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
                name = f"{prefix}.{child.name}"
                if not isinstance(child, ast.ClassDef):
                    if child.end_lineno - child.lineno + 1 > MAX_FUNCTION_LINES:
                        found.add(name)
                visit(child, name)

    visit(tree, module)
    return found


def test_modules_and_functions_stay_within_their_lengths():
    """No module over 600 lines (lcm-gen's generated types aside) and no function over 80 but
    the listed ones: a module pressed against the limit is split by what it holds, a long
    function into the steps it takes."""
    big, long = [], set()
    for path in PACKAGE.rglob("*.py"):
        if path.parent.name == "lcmtypes":
            continue
        text = path.read_text()
        lines = text.count("\n")
        if lines > MAX_MODULE_LINES:
            big.append(f"{path.relative_to(PACKAGE.parent)}: {lines} lines")
        long |= _long_functions(ast.parse(text), _module_name(path))
    assert not big, big
    new, shorter = sorted(long - LONG_FUNCTIONS), sorted(LONG_FUNCTIONS - long)
    assert not new and not shorter, f"over the limit: {new}; within it now: {shorter}"
    # the check sees a long function, nested ones by their class's name
    body = "\n".join(["class A:", "    def f(self):"] + ["        pass"] * MAX_FUNCTION_LINES)
    assert _long_functions(ast.parse(body), "m") == {"m.A.f"}


def test_pyproject_installs_every_package():
    """A package missing from pyproject's explicit list works from a checkout and is absent from
    a wheel: the list holds every folder of the package with an __init__.py."""
    import tomllib

    root = PACKAGE.parent
    listed = set(
        tomllib.loads((root / "pyproject.toml").read_text())["tool"]["setuptools"]["packages"]
    )
    tree = {".".join(p.parent.relative_to(root).parts) for p in PACKAGE.rglob("__init__.py")}
    assert tree <= listed, f"add to [tool.setuptools] packages: {sorted(tree - listed)}"


#: The command line: the modules that may hold an argparse namespace (cli/, a feature's
#: command.py or NAME_command.py, its options.py or NAME_options.py). What they pass below is
#: typed: numbers, paths, a scenario, a runner, a reference.
COMMAND_LINE_NAMES = ("command", "options")
#: Modules that parse their own ``python -m`` command and hand no namespace on.
OWN_ENTRY_POINTS = {"stewart_drake.station.bus.emulator"}


def _is_command_line(module: str) -> bool:
    last = module.rsplit(".", 1)[-1]
    return (
        _layer(module) == "cli"
        or module in OWN_ENTRY_POINTS
        or any(last == n or last.endswith(f"_{n}") for n in COMMAND_LINE_NAMES)
    )


def namespace_readers() -> dict[str, list[str]]:
    """{module: [what reads a namespace there]}: a parameter named ``args`` (the package's name
    for a namespace; not ``*args``), a call of ``parse_args``/``parse_known_args``, an import of
    argparse."""
    found: dict[str, list[str]] = {}
    for path in PACKAGE.rglob("*.py"):
        module = _module_name(path)
        for node in ast.walk(ast.parse(path.read_text())):
            what = None
            if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef):
                named = [
                    a.arg for a in node.args.posonlyargs + node.args.args + node.args.kwonlyargs
                ]
                if "args" in named:
                    what = f"{node.name}(args)"
            elif isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute):
                if node.func.attr in ("parse_args", "parse_known_args"):
                    what = node.func.attr
            elif isinstance(node, ast.Import | ast.ImportFrom):
                names = [a.name for a in node.names] + [getattr(node, "module", None) or ""]
                if "argparse" in names:
                    what = "import argparse"
            if what:
                found.setdefault(module, []).append(what)
    return found


def test_no_argparse_namespace_below_the_command_line():
    """Options are parsed at the command line and reach the domain typed: no module but the
    command line's (:func:`_is_command_line`) takes, parses or imports argparse's namespace."""
    below = {m: w for m, w in namespace_readers().items() if not _is_command_line(m)}
    assert not below, f"an argparse namespace below the command line: {below}"


def test_the_namespace_check_sees_a_reader():
    """The check would pass vacuously if it missed readers: known ones, each kind."""
    found = namespace_readers()
    assert "cmd_verify(args)" in found["stewart_drake.verification.command"]
    assert "import argparse" in found["stewart_drake.calibration.calibrate_options"]
    assert "parse_args" in found["stewart_drake.station.bus.emulator"]
    assert _is_command_line("stewart_drake.live.follow_command")
    assert _is_command_line("stewart_drake.execution.trace_options")
    assert not _is_command_line("stewart_drake.organ_motion.examples")
    assert not _is_command_line("stewart_drake.live.session")
