"""Mutation testing of the core numeric modules: for each module of :data:`MODULES`, mutmut
changes it one small edit at a time (an operator, a number, an argument) and runs only that
module's fast unit tests against each change; a mutant no test fails on is a wrong number the
tests would let through. Writes the score per module and every survivor with its account.

    pip install -e ".[test,mutation]"
    python tools/mutation.py                          # all modules: docs/mutation.md and
                                                      # tools/mutation_survivors.md
    python tools/mutation.py --module statics         # one module (a key's last part): its
                                                      # row and survivors replace theirs
    python tools/mutation.py --out /tmp/mutation.md --survivors /tmp/survivors.md  # elsewhere
    python tools/mutation.py --work /tmp/mut          # keep the scratch copies there

Not run by CI (a full run takes minutes per module). Each module is mutated in a scratch copy of
the working tree (the tracked folders below, with a ``[tool.mutmut]`` section added to its
pyproject.toml), never in the tree itself, with ``NUMBA_DISABLE_JIT=1`` (but the modules of
:data:`JIT_ON`): the compiled kernels run
as the Python they are written in, so a mutant costs no compilation and the tests see it. mutmut
does not mutate decorated functions, so in the scratch copy each ``@_njit`` line of a module
becomes a call after its function (with the JIT off, ``_njit`` returns the function itself,
marked as a kernel: the same code runs, and the module's interpreted ``reference`` holds it). mutmut
forks one process per mutant and runs only the tests that called the mutated function; a mutant
whose tests take longer than 2 times their clean time plus 3 s counts as a timeout (killed).

The LQI's step (control/lqi/step.py) is guarded by tests/test_lqi_stages.py, which holds each
stage to numbers computed from the equations, and not by test_lqi_step.py, which holds the
compiled step equal to its uncompiled reference (numba's ``py_func``): with the JIT off both of
its sides run the same mutated Python, so it cannot kill a mutant (nor its closed-loop runs, one
with each), only cost their time. A run where mutmut checked no mutant is reported as failed,
with mutmut's output.

A module's test files in :data:`MODULES` hold its fast unit tests only: no closed loop, no
pre-run check of a whole path, no command. With the JIT off those run the LQI's step and the
validator's kernels as Python, 10 to 80 s a test where compiled they take about 1 s, and mutmut
runs them in its first (stats) pass, again in its clean pass, and again for every mutant of any
function they call: the trajectories' run stalled on the two checks in stretches of
tests/test_plan.py (then in test_trajectories.py, 125 s), the fidelity measures' on the ten
``reproduce`` runs of tests/test_reproduce.py (then in test_fidelity.py, 160 s), for minutes
before the first mutant and hours after. Such tests live in their feature's suite; the two files
now run in 3 s with the JIT off.

The score is (killed + timeouts) / mutants, a mutant no selected test calls ("no tests") counted
as a survivor. Each survivor is listed with its diff and its account from :data:`ACCOUNTS_FILE`
(a TOML table, mutant name -> why it survives: equivalent, or not worth a test); a survivor
without one is listed as unaccounted. tests/test_mutation_tool.py checks that the table names
existing modules and test files.
"""

import argparse
import ast
import difflib
import functools
import json
import os
import re
import shutil
import subprocess
import sys
import tempfile
import time
import tomllib
from dataclasses import dataclass, field
from pathlib import Path

from tqdm import tqdm

from stewart_drake.base.fileio import read_checked
from stewart_drake.base.tables import markdown_lines

#: The largest file the tool reads (an earlier run's --json, the accounts), bytes.
MAX_INPUT_BYTES = 50e6

REPO = Path(__file__).resolve().parent.parent

#: Module (from the repository's top) -> the fast unit test files that guard it.
MODULES = {
    "stewart_drake/robot/kinematics.py": ("tests/test_kinematics.py",),
    "stewart_drake/robot/forward_kinematics.py": ("tests/test_fk.py",),
    "stewart_drake/robot/statics.py": ("tests/test_statics.py",),
    "stewart_drake/references/trajectories.py": ("tests/test_trajectories.py",),
    "stewart_drake/control/lqi/gain.py": ("tests/test_lqi.py",),
    # Not test_lqi_step.py: see the docstring.
    "stewart_drake/control/lqi/step.py": ("tests/test_lqi_stages.py",),
    # verify's modules against their unit tests, not tests/test_verify*.py, which run the
    # command and write its reports in process: 35 s with the JIT off, for every mutant of verify.
    # test_registration_motion.py too: the Kabsch search over shifts (rigid_shift) it fits with.
    "stewart_drake/verification/alignment.py": (
        "tests/test_alignment.py",
        "tests/test_registration_motion.py",
    ),
    # The one lag search: its own tests and verify's clock's, which drive its score and search;
    # the registration's, which drive its rotation-aware search (rigid_shift).
    "stewart_drake/base/lag.py": (
        "tests/test_lag.py",
        "tests/test_alignment.py",
        "tests/test_registration_motion.py",
    ),
    # The signal toolkit: its own tests, the verdict's periods and the Kalman model's.
    "stewart_drake/base/signals.py": (
        "tests/test_signals.py",
        "tests/test_measured_verdict.py",
        "tests/test_predictors.py",
    ),
    "stewart_drake/verification/measured_verdict.py": ("tests/test_measured_verdict.py",),
    "stewart_drake/verification/causes.py": ("tests/test_measured_verdict.py",),
    "stewart_drake/verification/verdict_notes.py": (
        "tests/test_verdict_notes.py",
        "tests/test_verification.py",
    ),
    "stewart_drake/verification/verdict_levels.py": ("tests/test_measured_verdict.py",),
    # Every PASS rule, held to bounds, NaNs and unjudged axes written in the test.
    "stewart_drake/base/verdicts.py": ("tests/test_verdicts.py",),
    # The record's values from a verification made by hand (tests/test_qa_record_data.py), not
    # tests/test_qa_record.py, which runs the command and draws the PDF: 10 s a mutant.
    "stewart_drake/verification/qa_record.py": ("tests/test_qa_record_data.py",),
    "stewart_drake/verification/verdict_sensitivity.py": (
        "tests/test_measured_verdict.py",
        "tests/test_verify_discrimination.py",
    ),
    "stewart_drake/verification/verify.py": ("tests/test_verification.py",),
    "stewart_drake/verification/measured_span.py": ("tests/test_verification.py",),
    "stewart_drake/verification/registration_motion.py": ("tests/test_registration_motion.py",),
    "stewart_drake/organ_motion/fidelity.py": ("tests/test_fidelity.py",),
    # test_predictors.py too: the settings' refusals, the bound, the envelope and the shrinkage's
    # gain, held to values it computes apart (4 s with the JIT off).
    "stewart_drake/references/prediction.py": (
        "tests/test_stream_prediction.py",
        "tests/test_stream_guards.py",
        "tests/test_predictors.py",
    ),
    # The selection's choice and verdicts from rows written in the test, the forms' draws.
    "stewart_drake/studies/stream_selection.py": ("tests/test_stream_selection.py",),
    "stewart_drake/studies/stream_sources.py": ("tests/test_stream_selection.py",),
    # Not test_live_follow.py: it holds the live follower to this module's curves, which both
    # sides run mutated alike (its own weights' moves, the one thing it recomputes, are checked
    # against hand-written moves in test_stream_prediction.py); 8 s more for every survivor.
    "stewart_drake/references/stream.py": ("tests/test_stream_prediction.py",),
    "stewart_drake/references/live_stream.py": ("tests/test_live_follow.py",),
    # Not test_calibration_registered.py (the identification and the command): see the docstring.
    "stewart_drake/calibration/registration.py": ("tests/test_calibration_registration.py",),
    "stewart_drake/calibration/registration_file.py": ("tests/test_calibration_registration.py",),
    "stewart_drake/calibration/budget.py": ("tests/test_calibration_budget.py",),
    # The reference's shaping into what the robot can follow, and its printed summary.
    "stewart_drake/run/shaping.py": ("tests/test_shaping.py",),
    "stewart_drake/run/shaping_record.py": ("tests/test_shaping_record.py",),
    # The surrogate: its lag matching and the goal it is matched to, its stage, and verify's
    # judgement of a pair of runs (not test_robot_surrogate.py, which drives the whole bus).
    "stewart_drake/station/surrogate/lag_matching.py": ("tests/test_lag_matching.py",),
    "stewart_drake/station/surrogate/lag_matched_goal.py": ("tests/test_lag_matching.py",),
    "stewart_drake/station/surrogate/linear_stage.py": ("tests/test_surrogate_servo.py",),
    "stewart_drake/verification/pair_judgement.py": (
        "tests/test_relative_latency.py",
        "tests/test_pair_judgement.py",
    ),
    # The causes a pair's FAIL names, each at its edge on motions the test writes out.
    "stewart_drake/verification/pair_causes.py": ("tests/test_pair_causes.py",),
    # The crank servo of the bus robots: its law and estimator (compiled, run as Python), its
    # LeafSystem, its design and its driver, against the law written out in the test; its
    # margins against the loop's characteristic roots; the servos' own loop's goal stream.
    "stewart_drake/control/servo/kernels.py": ("tests/test_crank_servo.py",),
    "stewart_drake/control/servo/controller.py": ("tests/test_crank_servo.py",),
    "stewart_drake/control/servo/design.py": (
        "tests/test_crank_servo.py",
        "tests/test_servo_margins.py",
    ),
    "stewart_drake/control/servo/driver.py": (
        "tests/test_crank_servo.py",
        "tests/test_servo_goal_stream.py",
    ),
    "stewart_drake/control/servo/margins.py": ("tests/test_servo_margins.py",),
    "stewart_drake/control/servo/goal_stream.py": ("tests/test_servo_goal_stream.py",),
    # The emulated bus: its replies' bytes and delays, its servos' tables and the plant behind.
    "stewart_drake/station/bus/emulator.py": (
        "tests/test_servo_emulation.py",
        "tests/test_emulator_clock.py",
        "tests/test_bus_emulator_answers.py",
    ),
    # The error budget: its floor, its table's units, each "without" run and the shares, the
    # closed loops stood in for (tests/test_error_budget.py runs them: a minute a mutant).
    "stewart_drake/analysis/error_budget.py": ("tests/test_error_budget_table.py",),
}
#: Modules with no compiled kernel of their own whose tests drive the package's compiled ones
#: (shaping: the IK and the path checks of every shaped period; the error budget: the forward
#: kinematics of its floor's check): mutated with the JIT on, since with it off their clean runs
#: take 289 s instead of 4.5 s (a mutant of theirs is compiled code never).
JIT_ON = frozenset({"stewart_drake/run/shaping.py", "stewart_drake/analysis/error_budget.py"})
#: What the scratch copy holds: the package, the tests and what they read.
COPIED = ("stewart_drake", "tests", "tools", "sdf", "scenarios", "docs", "README.md")
#: The survivors' accounts: ``"<mutant name>" = "why it survives"``.
ACCOUNTS_FILE = REPO / "tools" / "mutation_accounts.toml"
#: A mutant's tests may take this many times their clean run, plus TIMEOUT_CONSTANT_S.
TIMEOUT_MULTIPLIER = 2.0
TIMEOUT_CONSTANT_S = 3.0
#: The longest a module's run may take, s.
MODULE_TIMEOUT_S = 1500
#: A decorator line the scratch copy drops (the house's numba wrapper).
_NJIT_LINE = re.compile(r"^\s*@_njit\s*$")
#: mutmut's progress line: "⠋ 838/859  🎉 481 🫥 163  ⏰ 0  🤔 0  🙁 194 ...".
_PROGRESS = re.compile(r"(\d+)/(\d+)\s")


@dataclass
class Mutant:
    """One mutant: its mutmut name, status and diff against the original function."""

    name: str
    status: str
    diff: str = ""


@dataclass
class ModuleResult:
    """A module's run: its mutants and how long mutmut took (s)."""

    module: str
    tests: tuple
    mutants: list[Mutant] = field(default_factory=list)
    seconds: float = 0.0
    error: str = ""

    def count(self, *statuses: str) -> int:
        return sum(m.status in statuses for m in self.mutants)

    @property
    def killed(self) -> int:
        return self.count("killed")

    @property
    def timeouts(self) -> int:
        return self.count("timeout")

    @property
    def survivors(self) -> list[Mutant]:
        return [m for m in self.mutants if m.status not in ("killed", "timeout", "skipped")]

    @property
    def score(self) -> float:
        counted = len(self.mutants) - self.count("skipped")
        return (self.killed + self.timeouts) / counted if counted else float("nan")


def mutmut_section(module: str, tests: tuple) -> str:
    """The ``[tool.mutmut]`` section that mutates ``module`` only, against ``tests`` only."""
    return "\n".join(
        [
            "",
            "[tool.mutmut]",
            'source_paths = ["stewart_drake/"]',
            f"only_mutate = {json.dumps([module])}",
            "tests_dir = []",
            f"pytest_add_cli_args_test_selection = {json.dumps(list(tests))}",
            # One process, no xdist, no cache folder; the fast tier only.
            'pytest_add_cli_args = ["-p", "no:cacheprovider", "-p", "no:xdist", "-o", '
            '"addopts=", "-m", "not slow"]',
            f"also_copy = {json.dumps([f'{p}/' if (REPO / p).is_dir() else p for p in COPIED])}",
            "use_git_change_detection = false",
            f"timeout_multiplier = {TIMEOUT_MULTIPLIER}",
            f"timeout_constant = {TIMEOUT_CONSTANT_S}",
            "",
        ]
    )


def scratch_copy(module: str, tests: tuple, folder: Path) -> None:
    """Copy the working tree's :data:`COPIED` into ``folder``, with the mutmut section added to
    pyproject.toml and the ``@_njit`` lines of ``module`` turned into calls after each function
    (mutmut does not mutate a decorated function)."""
    if folder.exists():
        shutil.rmtree(folder)
    folder.mkdir(parents=True)
    ignore = shutil.ignore_patterns("__pycache__", "*.pyc", "mutants", ".pytest_cache")
    for name in COPIED:
        source = REPO / name
        if source.is_dir():
            shutil.copytree(source, folder / name, ignore=ignore)
        else:
            shutil.copy2(source, folder / name)
    pyproject = (REPO / "pyproject.toml").read_text()
    (folder / "pyproject.toml").write_text(pyproject + mutmut_section(module, tests))
    target = folder / module
    target.write_text(undecorated(target.read_text()))


def undecorated(text: str) -> str:
    """A module's source with each ``@_njit`` line removed and the decorator called after its
    function's last line instead (``name = _njit(name)``): mutmut mutates the function, and with
    the JIT off ``_njit`` returns it marked as a kernel, so the module's ``interpreted``
    namespace still holds it."""
    ends = {
        node.end_lineno: node.name
        for node in ast.parse(text).body
        if isinstance(node, ast.FunctionDef)
        and any(isinstance(d, ast.Name) and d.id == "_njit" for d in node.decorator_list)
    }
    out = []
    for number, line in enumerate(text.splitlines(keepends=True), start=1):
        if not _NJIT_LINE.match(line):
            out.append(line)
        if number in ends:
            out.append(f"{ends[number]} = _njit({ends[number]})\n")
    return "".join(out)


def run_mutmut(
    folder: Path, label: str, jit: bool = False, limit_s: float = MODULE_TIMEOUT_S
) -> tuple[int, str]:
    """Run ``mutmut run`` in ``folder`` with the JIT off (on with ``jit``: :data:`JIT_ON`), at
    low priority, showing its progress as a tqdm bar, stopped after ``limit_s``; returns (exit
    code, its output)."""
    env = dict(os.environ, NUMBA_DISABLE_JIT="0" if jit else "1")
    mutmut = [sys.executable, "-m", "mutmut", "run"]
    process = subprocess.Popen(
        ["nice", "-n", "10", *mutmut],
        cwd=folder,
        env=env,
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
    )
    assert process.stdout is not None
    output = bytearray()
    bar = tqdm(total=0, desc=label, unit="mutant")
    start = time.monotonic()
    while True:
        chunk = process.stdout.read1(4096)
        if not chunk:
            break
        output += chunk
        found = _PROGRESS.findall(chunk.decode("utf-8", "replace"))
        if found:
            done, total = (int(v) for v in found[-1])
            bar.total = total
            bar.n = done
            bar.refresh()
        if time.monotonic() - start > limit_s:
            process.kill()
            break
    bar.close()
    return process.wait(), output.decode("utf-8", "replace")


def _functions(tree: ast.Module) -> dict[str, ast.FunctionDef]:
    """Every function of a mutated module by name, methods included (mutmut names a method's
    variants ``xǁClassǁmethod__mutmut_N``, at the class's level)."""
    out = {}
    for node in ast.walk(tree):
        if isinstance(node, ast.FunctionDef):
            out[node.name] = node
    return out


#: A line and its end, as ast numbers lines: \r\n, \r or \n ends one (not \f, as str.splitlines).
_LINE = re.compile(r"[^\r\n]*(?:\r\n|\r|\n)|[^\r\n]+$")


@functools.lru_cache(maxsize=2)
def _lines(source: str) -> tuple[bytes, ...]:
    """The lines of ``source`` in UTF-8 (ast's column offsets count bytes), split once."""
    return tuple(line.encode() for line in _LINE.findall(source))


def _segment(source: str, node: ast.AST) -> str:
    """``ast.get_source_segment(source, node)``, from lines split once per source: that splits
    the whole file at every call, and mutmut's file of a module's mutants is megabytes (the
    fidelity measures': 1.9 MB, 426 functions read, 170 s)."""
    lines = _lines(source)
    first, last = node.lineno - 1, node.end_lineno - 1
    if first == last:
        return lines[first][node.col_offset : node.end_col_offset].decode()
    parts = [lines[first][node.col_offset :], *lines[first + 1 : last]]
    return b"".join([*parts, lines[last][: node.end_col_offset]]).decode()


def mutant_diff(source: str, functions: dict, name: str) -> str:
    """The unified diff of mutant ``name`` against its original, from mutmut's mutated file."""
    short = name.rsplit(".", 1)[-1]
    base = short.rsplit("__mutmut_", 1)[0]
    original, mutant = functions.get(f"{base}__mutmut_orig"), functions.get(short)
    if original is None or mutant is None:
        return ""
    # The def line too, under the function's own name on both sides: a default argument on it
    # is mutated too (sweep(axis="Z") -> "XXZXX"), and its diff was empty without it.
    plain = base.rsplit("ǁ", 1)[-1] if "ǁ" in base else base.removeprefix("x_")
    a, b = (
        _segment(source, node).replace(f"def {node.name}(", f"def {plain}(", 1).splitlines()
        for node in (original, mutant)
    )
    return "\n".join(list(difflib.unified_diff(a, b, lineterm="", n=0))[2:])


def read_results(module: str, tests: tuple, folder: Path) -> ModuleResult:
    """The mutants of ``module`` with their status (mutmut's ``.meta`` file) and diffs."""
    from mutmut.stats import status_by_exit_code

    result = ModuleResult(module, tests)
    mutated = folder / "mutants" / module
    meta = json.loads(mutated.with_name(mutated.name + ".meta").read_text())
    codes = meta["exit_code_by_key"]
    if codes and all(code is None for code in codes.values()):
        # mutmut stopped before its first mutant (its stats run of the tests failed).
        raise ValueError(f"mutmut checked none of the {len(codes)} mutants")
    source = mutated.read_text()
    functions = _functions(ast.parse(source))
    for name, code in sorted(codes.items(), key=lambda kv: _natural(kv[0])):
        status = status_by_exit_code[code] if code is not None else "not checked"
        diff = mutant_diff(source, functions, name) if status not in ("killed",) else ""
        result.mutants.append(Mutant(name, status, diff))
    return result


def _natural(name: str) -> tuple:
    base, _, n = name.rpartition("__mutmut_")
    return (base, int(n) if n.isdigit() else 0)


def run_module(
    module: str, tests: tuple, work: Path, limit_s: float = MODULE_TIMEOUT_S
) -> ModuleResult:
    """Mutate ``module`` against ``tests`` in a scratch copy under ``work``."""
    folder = work / Path(module).stem
    scratch_copy(module, tests, folder)
    start = time.monotonic()
    code, output = run_mutmut(folder, Path(module).stem, module in JIT_ON, limit_s)
    seconds = time.monotonic() - start
    try:
        result = read_results(module, tests, folder)
    except (OSError, ValueError) as err:
        result = ModuleResult(module, tests, error=f"{err}; mutmut exit {code}: {output[-2000:]}")
    result.seconds = seconds
    return result


#: Accounts that hold for every mutant of a kind, read from its diff: (what the kind is, a test
#: of the removed and the added line, the account). Each was read on the survivors it matches.
_EINSUM = re.compile(r'"[.a-z,]*->[.a-z]*"')
_STRING = re.compile(r'"[^"]*"')


def _einsum_renamed(old: str, new: str) -> bool:
    return any(old.replace(s, s.upper()) == new for s in _EINSUM.findall(old))


def _dtype_float_dropped(old: str, new: str) -> bool:
    return "dtype=float" in old and new in (
        old.replace("dtype=float", "dtype=None"),
        old.replace(", dtype=float", ", "),
    )


def _words_changed(old: str, new: str) -> bool:
    """A string of words (a message, a label) made XX..XX, upper or lower case, or None (an
    f-string too: mutmut makes a whole f-string None)."""
    for s in _STRING.findall(old):
        words = s[1:-1]
        if " " not in words.strip() and not words.endswith(("'", ":")):
            continue
        variants = (f'"XX{words}XX"', f'"{words.upper()}"', f'"{words.lower()}"', "None")
        if any(old.replace(p + s, v, 1) == new for p in ("", "f") for v in variants):
            return True
    return False


def _first_argument_changed(old: str, new: str, functions: tuple) -> bool:
    """The quoted first argument of a call of one of ``functions`` made XX..XX, upper or lower
    case, or None."""
    for function in functions:
        for call in re.finditer(rf'\b{function}\(("[^"]*")', old):
            s, start = call.group(1), call.start(1)
            head, tail = old[:start], old[start + len(s) :]
            variants = (f'"XX{s[1:-1]}XX"', s.upper(), s.lower(), "None")
            if any(head + v + tail == new for v in variants):
                return True
    return False


def _fstring_message_dropped(old: str, new: str) -> bool:
    """A message written as an f-string (words and the values it names) made None."""
    return any(" " in s and old.replace(f"f{s}", "None", 1) == new for s in _STRING.findall(old))


def _row_reshape_dropped(old: str, new: str) -> bool:
    """A 1-D factor of a product with a matrix reshaped (1, -1), made reshape(-1)."""
    return bool(re.search(r"\* [\w.()]+\.reshape\(1, -1\)", old)) and any(
        old.replace(m, m.replace("reshape(1, -1)", "reshape(-1)"), 1) == new
        for m in re.findall(r"[\w.()]+\.reshape\(1, -1\)", old)
    )


def _singular_name_changed(old: str, new: str) -> bool:
    """The first argument of finite_or_singular (the quantity a SingularPoseError names)."""
    return _first_argument_changed(old, new, ("finite_or_singular",))


def _checked_name_changed(old: str, new: str) -> bool:
    """The first argument of an argument check of base.checks (the name its error gives)."""
    return _first_argument_changed(old, new, ("as_number", "as_array", "as_poses", "check_int"))


def _one_replaced(old: str, new: str, a: str, b: str) -> bool:
    """``new`` is ``old`` with one of its ``a`` (any one, not only the first) made ``b``."""
    return any(
        old[:i] + b + old[i + len(a) :] == new for i in range(len(old)) if old.startswith(a, i)
    )


def _reshape_minus_two(old: str, new: str) -> bool:
    """reshape's "the rest" size -1 made -2 (numpy reads any negative size as the rest), in
    any of a line's reshapes."""
    return "reshape(" in old and any(
        _one_replaced(old, new, a, b) for a, b in (("reshape(-1", "reshape(-2"), (", -1)", ", -2)"))
    )


def _astype_float_to_none(old: str, new: str) -> bool:
    """astype(float) made astype(None): numpy's dtype None is float64, as float is."""
    return _one_replaced(old, new, ".astype(float)", ".astype(None)")


def _errstate_changed(old: str, new: str) -> bool:
    """Which floating-point warnings numpy keeps quiet: never a number."""
    return old.startswith("with np.errstate(") and new.startswith("with np.errstate(")


def _theta_recomputed(old: str, new: str) -> bool:
    """The motor angles a caller passes dropped, so that the IK computes them again."""
    return (
        new in (old.replace(", theta)", ", None)", 1), old.replace(", theta)", ", )", 1))
        or new == old.replace("(theta is None)", "(theta is None) or True", 1)
        or new == old.replace("if theta is None", "if (theta is None) or True", 1)
    ) and new != old


#: The roll, pitch and yaw of a pose (or of each of a stack of poses, ``x[:, :3]``) passed to a
#: function that reads only those three.
_RPY_ARGUMENT = re.compile(r"(?:rotation_rpy|angular_velocity_map)\(\w+\[(?:\.\.\., |:, )?:3\]\)")


def _slice_past_the_pose(old: str, new: str) -> bool:
    """A slice of a pose's last axis (6 values) made to end past it: x[..., :3] -> :4 where
    only the first three are read (rotation_rpy, angular_velocity_map), 3:6 -> 3:7."""
    return any(old.replace(a, b, 1) == new for a, b in (("3:6]", "3:7]"), ("3:]", "3:7]"))) or any(
        old[: m.start()] + m.group().replace(":3]", ":4]") + old[m.end() :] == new
        for m in _RPY_ARGUMENT.finditer(old)
    )


_MESSAGE_DROPPED = (
    "not worth a test: the words of a message (an f-string, or string literals over several "
    "lines) made None; the error is raised either way"
)

RULES = (
    (
        _theta_recomputed,
        "equivalent for every caller: they pass theta = ik(x), and without it the IK gives the "
        "same angles again",
    ),
    (
        _slice_past_the_pose,
        "equivalent: the slice ends past the pose's six values, or the function reads only the "
        "first three of the four (roll, pitch, yaw)",
    ),
    (
        _reshape_minus_two,
        "equivalent: numpy reads any negative size in reshape as the rest, -2 as -1",
    ),
    (
        _astype_float_to_none,
        "equivalent: astype(None) is astype(float64), numpy's default dtype, as astype(float) is",
    ),
    (
        _errstate_changed,
        "equivalent: np.errstate only chooses which floating-point warnings numpy prints; "
        "the numbers are the same",
    ),
    (
        _einsum_renamed,
        "equivalent: the einsum subscripts renamed in upper case, the same contraction",
    ),
    (
        _dtype_float_dropped,
        "equivalent for the float arrays every caller passes: the dtype only changes integer "
        "input, which the arithmetic after it makes float anyway",
    ),
    (
        _singular_name_changed,
        "not worth a test: the name of the quantity a SingularPoseError gives in its message "
        "(the error itself is raised either way)",
    ),
    (
        _checked_name_changed,
        "not worth a test: the name of the argument that a check of base.checks gives in its "
        "error's message (the error is raised either way)",
    ),
    (
        _row_reshape_dropped,
        "equivalent: numpy broadcasts a 1-D factor against a matrix as a row, which is what "
        "reshape(1, -1) makes it",
    ),
    (
        _words_changed,
        "not worth a test: the words of a message or a label, not a number",
    ),
    (_fstring_message_dropped, _MESSAGE_DROPPED),
)

#: A message written over several lines of string literals, which mutmut makes one None.
_LITERAL_LINE = re.compile(r'^f?"[^"]*",?$')


def rule_account(diff: str) -> str | None:
    """The account of a one-line mutant that one of :data:`RULES` explains (or of a message
    over several lines made None), else None."""
    old = [line[1:].strip() for line in diff.splitlines() if line.startswith("-")]
    new = [line[1:].strip() for line in diff.splitlines() if line.startswith("+")]
    if (
        len(old) > 1
        and new in (["None"], ["None,"])
        and all(_LITERAL_LINE.match(line) for line in old)
        and " " in "".join(old)
    ):
        return _MESSAGE_DROPPED
    if len(old) != 1 or len(new) != 1:
        return None
    for test, account in RULES:
        if test(old[0], new[0]):
            return account
    return None


def load_accounts(path: Path = ACCOUNTS_FILE) -> dict[str, str]:
    """The survivors' accounts, mutant name -> account ({} when the file does not exist)."""
    if not path.exists():
        return {}
    raw = read_checked(path, "mutation accounts file", MAX_INPUT_BYTES, "a TOML table of names")
    return tomllib.loads(raw.decode("utf-8"))


#: Where the survivors' report goes unless told: beside the tool, not in docs/ (it lists every
#: surviving mutant's diff, thousands of lines a reader of the docs does not need).
SURVIVORS_FILE = REPO / "tools" / "mutation_survivors.md"


def report(
    results: list[ModuleResult], accounts: dict[str, str], before: dict | None
) -> tuple[str, str]:
    """The two Markdown reports: (the scores, a table per module for docs/mutation.md; the
    survivors: an earlier run's scores, ``before``, the ``--json`` it wrote, when given, then
    each module's survivors with diffs and accounts)."""
    return summary_report(results), survivor_report(results, accounts, before)


def summary_report(results: list[ModuleResult]) -> str:
    """The scores: a row per module, and where the survivors are listed."""
    lines = [
        "# Mutation testing of the core numeric modules",
        "",
        "Written by `python tools/mutation.py` (mutmut, `NUMBA_DISABLE_JIT=1` but for "
        "`JIT_ON`; how and why in the tool's docstring and docs/development.md). Score = "
        "(killed + timeouts) / mutants; a mutant no selected test calls counts as a survivor.",
        "",
    ]
    header = ["module", "tests", "mutants", "killed", "timeouts", "survived", "no tests"]
    rows = [
        [
            f"`{r.module}`",
            ", ".join(Path(t).name for t in r.tests),
            len(r.mutants),
            r.killed,
            r.timeouts,
            r.count("survived"),
            r.count("no tests"),
            f"{100 * r.score:.1f} %",
            f"{r.seconds:.0f}",
        ]
        for r in results
    ]
    lines += markdown_lines(header + ["score", "run, s"], rows, [None, None] + ["right"] * 7)
    total = sum(r.seconds for r in results)
    lines += [
        "",
        f"The whole run took {total / 60:.1f} min on this machine.",
        "",
        "Every survivor, with its diff and its account from `tools/mutation_accounts.toml` "
        "(equivalent, or not worth a test, and why): the report written beside the tool, "
        "[tools/mutation_survivors.md](../tools/mutation_survivors.md).",
    ]
    return "\n".join(lines).rstrip() + "\n"


def survivor_report(
    results: list[ModuleResult], accounts: dict[str, str], before: dict | None
) -> str:
    """Every survivor with its diff and account, per module; first the scores before the tests
    written for them (``before``: an earlier run's ``--json``) when given."""
    lines = [
        "# Surviving mutants of the core numeric modules",
        "",
        "Written by `python tools/mutation.py` with docs/mutation.md, which gives the scores. "
        "Each survivor with its diff and its account from `tools/mutation_accounts.toml`.",
        "",
    ]
    if before:
        lines += [
            "Before the tests added for the survivors (the same run on the tests as they were):",
            "",
        ]
        after = {r.module: r for r in results}
        rows = []
        for module, b in before.items():
            statuses = list(b["mutants"].values())
            k = sum(s in ("killed", "timeout") for s in statuses)
            n = sum(s != "skipped" for s in statuses)
            r = after.get(module)
            score = f"{100 * r.score:.1f} %" if r else "not run again"
            rows.append([f"`{module}`", len(statuses), k, f"{100 * k / max(n, 1):.1f} %", score])
        header = ["module", "mutants", "killed + timeouts", "score before", "score after"]
        lines += markdown_lines(header, rows, [None] + ["right"] * 4)
        lines.append("")
    for r in results:
        lines += [f"## Survivors in `{r.module}`", ""]
        if r.error:
            lines += ["The run failed:", "", "```", r.error, "```", ""]
            continue
        survivors = r.survivors
        if not survivors:
            lines += ["None.", ""]
        unaccounted = [
            m for m in survivors if m.name not in accounts and rule_account(m.diff) is None
        ]
        if unaccounted:
            lines += [f"{len(unaccounted)} of {len(survivors)} without an account.", ""]
        for m in survivors:
            account = accounts.get(m.name) or rule_account(m.diff) or "**unaccounted**"
            short = m.name.rsplit(".", 1)[-1]  # the module is the section's
            lines += [f"- `{short}` ({m.status}): {account}", "", "  ```diff"]
            lines += [f"  {d}" for d in m.diff.splitlines()] + ["  ```", ""]
    return "\n".join(lines).rstrip() + "\n"


def merged_summary(old: str, new: str) -> str:
    """``old`` (docs/mutation.md as it stands) with the table rows of ``new`` (a run of some
    modules) put in: a module's row replaces its old row where it stood, a module without one is
    added after the table's last row; every other line of ``old``, the prose written under the
    table included, is kept as it was."""
    rows = {_row_module(line): line for line in new.splitlines() if _row_module(line)}
    lines = old.splitlines()
    for i, line in enumerate(lines):
        module = _row_module(line)
        if module in rows:
            lines[i] = rows.pop(module)
    last = max((i for i, line in enumerate(lines) if _row_module(line)), default=None)
    if last is None:
        return new
    lines[last + 1 : last + 1] = list(rows.values())
    return "\n".join(lines).rstrip() + "\n"


def _row_module(line: str) -> str | None:
    """The module a score table's row is of (its first cell's path), None for any other line."""
    if line.startswith("| `stewart_drake/"):
        return line.split("`", 2)[1]
    return None


def merged_survivors(old: str, new: str) -> str:
    """``old`` (tools/mutation_survivors.md as it stands) with the module sections of ``new`` (a
    run of some modules) put in: a module's section replaces its old one where it stood, a new
    module's section goes at the end; the other modules' sections and the lines before the first
    section are kept as they were."""
    old_head, old_sections = _sections(old)
    new_sections = _sections(new)[1]
    for module, text in new_sections.items():
        old_sections[module] = text  # a dict keeps an old key's place
    body = "".join(text.rstrip("\n") + "\n\n" for text in old_sections.values())
    return (old_head + body).rstrip() + "\n"


def _sections(text: str) -> tuple[str, dict[str, str]]:
    """The lines before the first ``## Survivors in `module``` heading, and each module's section
    (its heading to the next), in order."""
    head, sections, module = [], {}, None
    for line in text.splitlines(keepends=True):
        if line.startswith("## Survivors in `"):
            module = line.split("`", 2)[1]
            sections[module] = ""
        if module is None:
            head.append(line)
        else:
            sections[module] += line
    return "".join(head), sections


def _standing_report(path: Path, option: str) -> str | None:
    """The text of a report ``--module`` puts its rows into, read by the checked reader before
    the runs (None where there is none yet)."""
    if not path.exists():
        return None
    raw = read_checked(path, f"{option} report", MAX_INPUT_BYTES, "give a report this tool wrote")
    return raw.decode("utf-8")


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument(
        "--module",
        action="append",
        help="a module's file stem (repeatable); its row and survivors replace theirs in --out "
        "and --survivors, the other modules' are kept",
    )
    parser.add_argument("--out", type=Path, default=REPO / "docs" / "mutation.md")
    parser.add_argument("--survivors", type=Path, default=SURVIVORS_FILE)
    parser.add_argument("--work", type=Path, help="folder for the scratch copies (kept)")
    parser.add_argument(
        "--json", type=Path, help="also write the mutants' names and statuses as JSON here"
    )
    parser.add_argument(
        "--before", type=Path, help="an earlier run's --json, whose scores the report gives too"
    )
    parser.add_argument(
        "--limit",
        type=float,
        default=MODULE_TIMEOUT_S,
        metavar="S",
        help=f"the longest a module's run may take, s (default {MODULE_TIMEOUT_S}; a module "
        "stopped there scores the mutants it did not reach as not killed)",
    )
    args = parser.parse_args(argv)
    if not args.limit > 0:
        parser.error(f"--limit must be > 0 s, got {args.limit}")
    chosen = {m: t for m, t in MODULES.items() if not args.module or Path(m).stem in args.module}
    if not chosen:
        parser.error(f"no module {args.module}: one of {[Path(m).stem for m in MODULES]}")
    # The files it reads, read and checked before the runs, which take minutes.
    before = None
    if args.before:
        raw = read_checked(args.before, "--before", MAX_INPUT_BYTES, "give a --json it wrote")
        before = json.loads(raw.decode("utf-8"))
    accounts = load_accounts()
    # --module: the reports as they stand, which its rows and sections go into.
    standing = [
        _standing_report(path, option) if args.module else None
        for path, option in ((args.out, "--out"), (args.survivors, "--survivors"))
    ]
    import importlib.util

    if importlib.util.find_spec("mutmut") is None:
        parser.error('mutmut is not installed: pip install -e ".[test,mutation]"')
    work = args.work or Path(tempfile.mkdtemp(prefix="stewart-mutation-"))
    results = [run_module(m, t, work, args.limit) for m, t in chosen.items()]
    summary, survivors = report(results, accounts, before)
    if standing[0] is not None:
        summary = merged_summary(standing[0], summary)
    if standing[1] is not None:
        survivors = merged_survivors(standing[1], survivors)
    args.out.write_text(summary)
    args.survivors.write_text(survivors)
    if args.json:
        args.json.write_text(
            json.dumps(
                {
                    r.module: {
                        "seconds": r.seconds,
                        "mutants": {m.name: m.status for m in r.mutants},
                    }
                    for r in results
                },
                indent=1,
            )
        )
    for r in results:
        print(
            f"{r.module}: {len(r.mutants)} mutants, {r.killed} killed, {r.timeouts} timeouts, "
            f"{len(r.survivors)} survivors, score {100 * r.score:.1f} % ({r.seconds:.0f} s)"
        )
    if not args.work:
        shutil.rmtree(work, ignore_errors=True)
    return 0 if all(not r.error for r in results) else 1


if __name__ == "__main__":
    sys.exit(main())
