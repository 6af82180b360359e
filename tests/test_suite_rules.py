"""The suite's own rules, read from the tests' source: no test asserts a speed (a wait that
guards a hang fails by timing out, conftest.wait_for and conftest.run_within; speed belongs to
benchmarks/), and a test that needs an extra skips naming the command that installs it."""

import ast
from pathlib import Path

import pytest
from conftest import EXTRAS, extra_missing, needs_extra

TESTS = Path(__file__).resolve().parent

#: The clock readings of the time module: wall-clock and CPU time alike measure the machine.
CLOCKS = {
    "monotonic",
    "monotonic_ns",
    "perf_counter",
    "perf_counter_ns",
    "time",
    "time_ns",
    "process_time",
    "thread_time",
}


def _is_clock_call(node: ast.AST) -> bool:
    """``time.monotonic()``, ``perf_counter()`` and the like (the module's name or the bare
    function as imported)."""
    if not isinstance(node, ast.Call):
        return False
    func = node.func
    if isinstance(func, ast.Attribute):
        return func.attr in CLOCKS and isinstance(func.value, ast.Name) and func.value.id == "time"
    return isinstance(func, ast.Name) and func.id in CLOCKS - {"time"}


#: Calls whose value is a clock reading when their argument is one.
PASS_THROUGH = {"float", "abs", "min", "max", "round", "int"}


def _clocked(node: ast.AST, names: set) -> bool:
    """Whether the value of ``node`` is a clock reading or arithmetic on one: a clock call, a
    name known to hold one, a sum, difference, product or item of those (a count of readings,
    ``len(times)``, is not)."""
    if _is_clock_call(node):
        return True
    if isinstance(node, ast.Name):
        return node.id in names
    if isinstance(node, ast.BinOp):
        return _clocked(node.left, names) or _clocked(node.right, names)
    if isinstance(node, ast.UnaryOp):
        return _clocked(node.operand, names)
    if isinstance(node, ast.Subscript):
        return _clocked(node.value, names)
    if isinstance(node, ast.Call) and isinstance(node.func, ast.Name):
        return node.func.id in PASS_THROUGH and any(_clocked(a, names) for a in node.args)
    return False


def _clock_names(function: ast.AST) -> set:
    """The names in ``function`` that hold a clock reading or arithmetic on one (assigned,
    augmented, or a list appended to), found to a fixed point."""
    names: set = set()
    while True:
        found = set(names)
        for node in ast.walk(function):
            if isinstance(node, ast.Assign | ast.AnnAssign | ast.AugAssign) and node.value:
                if _clocked(node.value, found):
                    targets = node.targets if isinstance(node, ast.Assign) else [node.target]
                    found.update(t.id for t in targets if isinstance(t, ast.Name))
            elif (
                isinstance(node, ast.Call)
                and isinstance(node.func, ast.Attribute)
                and node.func.attr == "append"
                and isinstance(node.func.value, ast.Name)
                and any(_clocked(a, found) for a in node.args)
            ):
                found.add(node.func.value.id)
        if found == names:
            return names
        names = found


def wall_time_assertions(source: str) -> list[tuple[int, str]]:
    """(line, text) of every ``assert`` in ``source`` whose comparison reads a clock or a name
    computed from one."""
    tree = ast.parse(source)
    out = []
    scopes = [n for n in ast.walk(tree) if isinstance(n, ast.FunctionDef | ast.AsyncFunctionDef)]
    for scope in [tree, *scopes]:
        names = _clock_names(scope) if scope is not tree else set()
        for node in ast.walk(scope):
            if not isinstance(node, ast.Assert):
                continue
            compares = [n for n in ast.walk(node.test) if isinstance(n, ast.Compare)]
            if any(_clocked(x, names) for c in compares for x in [c.left, *c.comparators]):
                out.append((node.lineno, ast.get_source_segment(source, node) or ""))
    return sorted(set(out))


def test_no_test_asserts_on_wall_time():
    found = [
        f"{path.name}:{line}: {text.splitlines()[0]}"
        for path in sorted(TESTS.glob("*.py"))
        for line, text in wall_time_assertions(path.read_text())
    ]
    assert not found, (
        "assertions on wall or CPU time (guard a hang with conftest.wait_for or run_within, "
        "and measure speed in benchmarks/):\n" + "\n".join(found)
    )


@pytest.mark.parametrize(
    "source, caught",
    [
        ("def t():\n    t0 = time.monotonic()\n    f()\n    assert time.monotonic() - t0 < 9\n", 1),
        ("def t():\n    w = time.perf_counter() - a\n    b = w * 2\n    assert b < 9\n", 1),
        ("def t():\n    s = []\n    s.append(time.time())\n    assert s[1] - s[0] < 1\n", 1),
        ("def t():\n    assert perf_counter() >= 0.2\n", 1),
        ("def t():\n    wait_for(done, 60, 'done')\n    assert done()\n", 0),
        ("def t():\n    t0 = time.monotonic()\n    assert f(t0)\n", 0),  # no comparison
        ("def t():\n    x = 3.0\n    assert x < 9\n", 0),
        ("def t():\n    s = []\n    s.append(time.time())\n    assert len(s) == 1\n", 0),
    ],
)
def test_the_rule_finds_a_wall_time_assertion_and_nothing_else(source, caught):
    assert len(wall_time_assertions(source)) == caught


def test_a_missing_extra_is_named_with_its_install_command(monkeypatch):
    import importlib.util

    real = importlib.util.find_spec
    monkeypatch.setattr(
        importlib.util, "find_spec", lambda name, *a: None if name == "ray" else real(name, *a)
    )
    assert extra_missing("ray") == 'needs the ray extra: pip install -e ".[ray]"'
    mark = needs_extra("ray")
    assert mark.args == (True,) and mark.kwargs["reason"] == extra_missing("ray")
    assert set(EXTRAS) <= {"train", "mujoco", "ray", "dask", "analysis", "robot", "docs"}
    project = (TESTS.parent / "pyproject.toml").read_text()
    assert all(f"\n{extra} = [" in project for extra in EXTRAS)  # each an extra of ours
