"""The suite's own rules, read from the tests' source: no test asserts a speed (a wait that
guards a hang fails by timing out, conftest.wait_for and conftest.run_within; speed belongs to
benchmarks/), no wait is bounded by a literal time a busy machine can exceed (a hang's guard is
conftest.HANG_S), both also read as text in every file under tests/, and a test that needs an
extra skips naming the command that installs it."""

import ast
import re
from pathlib import Path

import pytest
from conftest import EXTRAS, HANG_S, extra_missing, needs_extra

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


#: A duration the test did not read from a clock itself but is named for one: the wall time or
#: the elapsed time that the code under test measured (``run.elapsed_s``, ``wall_time``,
#: ``row["wall_s"]``). Ordering it (``<``, ``>=``) asserts a speed; ``==`` with the record it
#: came from does not.
DURATION_NAME = re.compile(r"(wall|elapsed)", re.IGNORECASE)
ORDERING = (ast.Lt, ast.LtE, ast.Gt, ast.GtE)


def _named_duration(node: ast.AST) -> bool:
    """Whether ``node`` is a name, attribute or string-keyed item named as a duration
    (:data:`DURATION_NAME` at its start), or arithmetic on one."""
    if isinstance(node, ast.Name | ast.Attribute):
        return bool(DURATION_NAME.match(node.id if isinstance(node, ast.Name) else node.attr))
    if isinstance(node, ast.Subscript):
        key = node.slice
        named = isinstance(key, ast.Constant) and isinstance(key.value, str)
        return (named and bool(DURATION_NAME.match(key.value))) or _named_duration(node.value)
    if isinstance(node, ast.BinOp):
        return _named_duration(node.left) or _named_duration(node.right)
    if isinstance(node, ast.UnaryOp):
        return _named_duration(node.operand)
    if isinstance(node, ast.Call) and isinstance(node.func, ast.Name):
        return node.func.id in PASS_THROUGH and any(_named_duration(a) for a in node.args)
    return False


def _orders_a_duration(compare: ast.Compare) -> bool:
    operands = [compare.left, *compare.comparators]
    return any(
        isinstance(op, ORDERING) and (_named_duration(a) or _named_duration(b))
        for op, a, b in zip(compare.ops, operands, operands[1:])
    )


def wall_time_assertions(source: str) -> list[tuple[int, str]]:
    """(line, text) of every ``assert`` in ``source`` whose comparison reads a clock or a name
    computed from one, or orders a duration named as one (:data:`DURATION_NAME`)."""
    tree = ast.parse(source)
    out = []
    scopes = [n for n in ast.walk(tree) if isinstance(n, ast.FunctionDef | ast.AsyncFunctionDef)]
    for scope in [tree, *scopes]:
        names = _clock_names(scope) if scope is not tree else set()
        for node in ast.walk(scope):
            if not isinstance(node, ast.Assert):
                continue
            compares = [n for n in ast.walk(node.test) if isinstance(n, ast.Compare)]
            if any(_clocked(x, names) for c in compares for x in [c.left, *c.comparators]) or any(
                _orders_a_duration(c) for c in compares
            ):
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
        # Joined from two strings where a line of this file would read as what the text rule
        # (below) finds: the string is the offender, this line is not.
        (
            "def t():\n    t0 = time.monotonic()\n    f()\n    assert time.monotonic() - t0 "
            + "< 9\n",
            1,
        ),
        ("def t():\n    t0 = time.monotonic()\n    f()\n    assert 9 > time.monotonic() - t0\n", 1),
        ("def t():\n    w = time.perf_counter() - a\n    b = w * 2\n    assert b < 9\n", 1),
        ("def t():\n    s = []\n    s.append(time.time())\n    assert s[1] - s[0] < 1\n", 1),
        ("def t():\n    assert perf_counter() >= 0.2\n", 1),
        ("def t():\n    wait_for(done, 60, 'done')\n    assert done()\n", 0),
        ("def t():\n    t0 = time.monotonic()\n    assert f(t0)\n", 0),  # no comparison
        ("def t():\n    x = 3.0\n    assert x < 9\n", 0),
        ("def t():\n    s = []\n    s.append(time.time())\n    assert len(s) == 1\n", 0),
        # Durations the code under test measured, named as such.
        ("def t():\n    run = f()\n    assert 10 > run.elapsed_s\n", 1),
        ("def t():\n    assert row['wall_s'] <= 0.5 * budget\n", 1),
        ("def t():\n    assert 2 * wall_time >= 1\n", 1),
        ("def t():\n    assert summary['elapsed']['median'] > 0\n", 1),
        ("def t():\n    assert row['wall_s'] == records[0]\n", 0),  # the record, no speed
        ("def t():\n    assert len(walls) > 100\n", 0),  # a count of readings
    ],
)
def test_the_rule_finds_a_wall_time_assertion_and_nothing_else(source, caught):
    assert len(wall_time_assertions(source)) == caught


#: The shortest literal bound a test may give a wait, s. A wait that guards a hang waits
#: conftest.HANG_S; a shorter literal bound fails on a machine busy enough (at a load of 20 on
#: 2 cores, "did not happen within 120 s" of a command that was only slow), unless it bounds
#: something that must NOT happen within it, and its line says so: ``# wait-kept: why``.
LITERAL_WAIT_LIMIT_S = 1000.0
KEPT = "# wait-kept:"

#: Calls whose positional argument at this index, or keyword ``timeout_s``, is a wait's bound,
#: s (by the called name: conftest's ``wait_for`` and ``run_within``, a browser's
#: ``wait_for``, ``Event.wait``, ``Popen.wait``, ``Thread.join``, the Meshcat clicks).
BOUND_ARGUMENT = {
    "wait_for": 1,
    "run_within": 0,
    "wait": 0,
    "join": 0,
    "click": 2,
    "send_click": 3,
}
#: The keyword that bounds a wait, s, in any call (``subprocess.run``, ``communicate``,
#: ``psutil.wait_procs``, ``Thread.join``, nbclient); a setting of the code under test
#: (``reply_timeout_s``, a watchdog's ``timeout_s``) is not a wait of the test's.
BOUND_KEYWORD = "timeout"


def _literal_s(node: ast.AST) -> float | None:
    """The number ``node`` writes out (a constant, or arithmetic on constants), else None."""
    if isinstance(node, ast.Constant) and type(node.value) in (int, float):
        return float(node.value)
    if isinstance(node, ast.UnaryOp) and isinstance(node.op, ast.USub):
        value = _literal_s(node.operand)
        return None if value is None else -value
    if isinstance(node, ast.BinOp) and isinstance(node.op, ast.Add | ast.Sub | ast.Mult):
        left, right = _literal_s(node.left), _literal_s(node.right)
        if left is None or right is None:
            return None
        ops = {ast.Add: left + right, ast.Sub: left - right, ast.Mult: left * right}
        return ops[type(node.op)]
    return None


def _short(node: ast.AST | None) -> bool:
    value = None if node is None else _literal_s(node)
    return value is not None and value < LITERAL_WAIT_LIMIT_S


def _called_name(call: ast.Call) -> str | None:
    func = call.func
    return func.attr if isinstance(func, ast.Attribute) else getattr(func, "id", None)


def _short_bounds(scope: ast.AST, names: set) -> list[ast.AST]:
    """The nodes in ``scope`` that bound a wait by a short literal: a bound argument of the
    calls of :data:`BOUND_ARGUMENT`, the keyword :data:`BOUND_KEYWORD`, a default of a
    parameter named for a timeout, a deadline ``clock + literal`` or a time left
    ``literal - clock`` (``names``: the names holding a clock reading)."""
    found: list[ast.AST] = []
    for node in ast.walk(scope):
        if isinstance(node, ast.Call):
            index = BOUND_ARGUMENT.get(_called_name(node) or "")
            keywords = {BOUND_KEYWORD} | ({"timeout_s"} if index is not None else set())
            if index is not None and len(node.args) > index and _short(node.args[index]):
                found.append(node)
            if any(k.arg in keywords and _short(k.value) for k in node.keywords):
                found.append(node)
        elif isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef):
            params = node.args.posonlyargs + node.args.args
            pairs = list(zip(params[len(params) - len(node.args.defaults) :], node.args.defaults))
            pairs += [(a, d) for a, d in zip(node.args.kwonlyargs, node.args.kw_defaults) if d]
            found += [d for a, d in pairs if "timeout" in a.arg and _short(d)]
        elif isinstance(node, ast.BinOp) and isinstance(node.op, ast.Add):
            sides = (node.left, node.right)
            if any(_clocked(a, names) for a in sides) and any(_short(b) for b in sides):
                found.append(node)
        elif isinstance(node, ast.BinOp) and isinstance(node.op, ast.Sub):
            if _short(node.left) and _clocked(node.right, names):
                found.append(node)
    return found


def short_wait_bounds(source: str) -> list[tuple[int, str]]:
    """(line, text) of every wait in ``source`` bounded by a literal under
    :data:`LITERAL_WAIT_LIMIT_S` whose lines do not say, with :data:`KEPT` and a reason, why
    it is kept."""
    tree = ast.parse(source)
    lines = source.splitlines()
    out = set()
    scopes = [n for n in ast.walk(tree) if isinstance(n, ast.FunctionDef | ast.AsyncFunctionDef)]
    for scope in [tree, *scopes]:
        names = _clock_names(scope) if scope is not tree else set()
        for node in _short_bounds(scope, names):
            first, last = node.lineno, node.end_lineno or node.lineno
            said = [ln.split(KEPT, 1)[1].strip() for ln in lines[first - 1 : last] if KEPT in ln]
            if not any(said):
                out.add((first, lines[first - 1].strip()))
    return sorted(out)


def test_every_wait_with_a_short_literal_bound_says_why_it_is_kept():
    found = [
        f"{path.name}:{line}: {text}"
        for path in sorted(TESTS.glob("*.py"))
        for line, text in short_wait_bounds(path.read_text())
    ]
    assert not found, (
        f"waits bounded by a literal under {LITERAL_WAIT_LIMIT_S:g} s: a guard against a hang "
        f"waits conftest.HANG_S ({HANG_S:g} s); a bound on something that must not happen "
        f"within it says why on its line ({KEPT} ...):\n" + "\n".join(found)
    )


@pytest.mark.parametrize(
    "source, caught",
    [
        ("def t():\n    wait_for(done, 120, 'the manifest')\n", 1),
        ("def t():\n    assert shown.wait(" + "60)\n", 1),  # two strings: see above
        ("def t():\n    proc.communicate(timeout=30)\n", 1),
        ("def t():\n    run_within(2 * 60, f)\n", 1),
        ("def t():\n    worker.join(timeout=120)\n", 1),
        ("def t():\n    reader.join(5)\n", 1),
        ("def t():\n    psutil.wait_procs(p, timeout=max(0.0, 30 - (time.monotonic() - t0)))\n", 1),
        ("def t():\n    deadline = time.monotonic() + 60.0\n", 1),
        ("def t():\n    t0 = time.perf_counter()\n    end = t0 + 0.1 + 1.0\n", 1),
        ("def run(argv, timeout_s=300.0):\n    pass\n", 1),
        ("def t():\n    wait_for(done, HANG_S, 'the manifest')\n", 0),
        ("def t():\n    proc.wait(timeout=HANG_S)\n", 0),
        ("def t():\n    wait_for(done, 1800, 'x')\n", 0),
        ("def t():\n    ', '.join(names)\n", 0),
        ("def t():\n    bus = Bus(port, reply_timeout_s=1.0)\n", 0),  # a setting, not a wait
        ("def t():\n    dog = LoopWatchdog(off, timeout_s=0.2)\n", 0),  # the code's limit
        ("def t():\n    wait_for(done, timeout_s=60, what='x')\n", 1),
        ("def t():\n    x = time.time() - 3 * 3600\n", 0),
        (
            "def t():\n    assert not fired.wait(" + "0.5)  # wait-kept: not before its time\n",
            0,
        ),
        ("def t():\n    assert not fired.wait(" + "0.5)  # wait-kept:\n", 1),  # no reason given
    ],
)
def test_the_rule_finds_a_short_wait_bound_and_nothing_else(source, caught):
    assert len(short_wait_bounds(source)) == caught


#: The two rules above read as text, line by line, in every file under tests/: what a reader
#: searching the tests finds, and what the rules above cannot parse (a script a test writes out
#: and runs is a string to them). An ``assert`` that orders a wall or elapsed time, or a clock
#: reading less another, against a bound; a ``.wait`` bounded by a literal of at most three
#: digits (under 1000 s). A wait kept short (:data:`KEPT`) names its bound here: a constant
#: whose comment says what must not happen within it.
TIMED_LINES = {
    "an assertion on wall time": re.compile(
        r"assert[^#]*(\b(wall|elapsed)[a-z_]*\s*<|(monotonic|perf_counter|time)\(\)\s*-\s*"
        r"[a-z_0-9]+\s*<)"
    ),
    "a fixed wait under 1000 s": re.compile(
        r"\.wait\(\s*(timeout\s*=\s*)?[0-9]{1,3}(\.[0-9]+)?\s*\)"
    ),
}


def timed_lines(text: str) -> list[tuple[int, str, str]]:
    """(line number, what, line) of every line of ``text`` that :data:`TIMED_LINES` finds."""
    return [
        (k, what, line.strip())
        for k, line in enumerate(text.splitlines(), 1)
        for what, pattern in TIMED_LINES.items()
        if pattern.search(line)
    ]


def test_no_line_of_the_tests_reads_as_a_timed_assertion_or_a_fixed_wait():
    files = [p for p in sorted(TESTS.rglob("*")) if p.is_file() and "__pycache__" not in p.parts]
    found = [
        f"{path.relative_to(TESTS)}:{k}: {what}: {line}"
        for path in files
        for k, what, line in timed_lines(path.read_text(errors="replace"))
    ]
    assert not found, (
        "lines that read as a speed asserted or a fixed wait (measure speed in benchmarks/; "
        f"guard a hang with conftest.HANG_S, {HANG_S:g} s):\n" + "\n".join(found)
    )


@pytest.mark.parametrize(
    "line, caught",
    [
        # Two strings each, so that this file's lines are not the lines the rule finds.
        ("    assert elapsed " + "< 5.0", 1),
        ("    assert wall_time_s " + "<= 0.5 * budget", 1),
        ("    assert time.monotonic() - t0 " + "< 9, 'too slow'", 1),
        ("    assert perf_counter() - start " + "< 1", 1),
        ("    assert done.wait(" + "60)", 1),
        ("    proc.wait(timeout=" + "30)", 1),
        ("    assert not fired.wait(" + "0.5)  # wait-kept: not before its time", 1),
        ("    proc.wait(timeout=HANG_S)", 0),
        ("    assert shown.wait(1800.0)", 0),  # four digits: a hang's bound
        ("    assert elapsed > 0  # measured at all", 0),
        ("    assert n_wall < 3", 0),  # not a name that starts as a duration's
        ("    print(f'{elapsed:.0f} s')  # said, not asserted", 0),
    ],
)
def test_the_text_rule_finds_a_timed_line_and_nothing_else(line, caught):
    assert len(timed_lines(line)) == caught


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
