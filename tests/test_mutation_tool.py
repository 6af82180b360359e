"""tools/mutation.py's module table: every module and test file it names exists, so the table
cannot rot when a module or a test file is renamed (the tool itself is not run by CI)."""

import importlib.util
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parent.parent


def _tool():
    spec = importlib.util.spec_from_file_location("mutation_tool", REPO / "tools" / "mutation.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


mutation = _tool()


@pytest.mark.parametrize("module", sorted(mutation.MODULES))
def test_the_table_names_existing_modules_and_test_files(module):
    assert (REPO / module).is_file(), module
    tests = mutation.MODULES[module]
    assert tests, f"{module} has no tests"
    for test in tests:
        assert (REPO / test).is_file(), test
        assert Path(test).name.startswith("test_"), test


def test_a_module_mutated_with_the_jit_on_has_no_compiled_kernel_of_its_own():
    """With the JIT on a kernel of the module would run compiled, its mutants unseen: only a
    module without one may be mutated so."""
    assert mutation.JIT_ON and mutation.JIT_ON <= set(mutation.MODULES)
    for module in mutation.JIT_ON:
        assert "_njit" not in (REPO / module).read_text(), module
    assert "_njit" in (REPO / "stewart_drake/control/lqi/step.py").read_text()  # the check sees one


def test_the_module_names_are_unique_as_the_command_line_gives_them():
    stems = [Path(m).stem for m in mutation.MODULES]
    assert len(stems) == len(set(stems))


def test_the_accounts_name_modules_of_the_table():
    modules = {m.removesuffix(".py").replace("/", ".") for m in mutation.MODULES}
    for name in mutation.load_accounts():
        assert any(name.startswith(m + ".") for m in modules), name


def test_the_mutmut_section_selects_the_module_and_its_tests_only():
    import tomllib

    section = tomllib.loads(
        mutation.mutmut_section("stewart_drake/robot/statics.py", ("tests/test_statics.py",))
    )["tool"]["mutmut"]
    assert section["only_mutate"] == ["stewart_drake/robot/statics.py"]
    assert section["pytest_add_cli_args_test_selection"] == ["tests/test_statics.py"]
    assert section["tests_dir"] == []


def _diff(old: str, new: str) -> str:
    return f"@@ -1 +1 @@\n-    {old}\n+    {new}"


@pytest.mark.parametrize(
    "old, new",
    [
        # an f-string message made None
        (
            'raise InvalidConfigError(f"theta {theta.shape} must match the poses x {x.shape}")',
            "raise InvalidConfigError(None)",
        ),
        # the second of a line's reshapes
        (
            "leg, ratio.reshape(-1, 6)[k, leg], t=t_k, pose=x.reshape(-1, 6)[k]",
            "leg, ratio.reshape(-1, 6)[k, leg], t=t_k, pose=x.reshape(-2, 6)[k]",
        ),
        # the rpy of a pose past its third value, for a function that reads three
        ("E = angular_velocity_map(x[..., :3])", "E = angular_velocity_map(x[..., :4])"),
        ("r_W = rotation_rpy(x[:3]) @ p", "r_W = rotation_rpy(x[:4]) @ p"),
        ("R, p = rotation_rpy(x[:, :3]), x[:, 3:]", "R, p = rotation_rpy(x[:, :4]), x[:, 3:]"),
        # the name an argument check gives
        ('q = as_number("quantum_rad", quantum_rad, 0.0)', "q = as_number(None, quantum_rad, 0.0)"),
        ('x = as_poses("x", x)', 'x = as_poses("X", x)'),
        (
            'seed = check_int("seed", seed, 0, 2**32 - 1)',
            "seed = check_int(None, seed, 0, 2**32 - 1)",
        ),
    ],
)
def test_a_rule_accounts_for_each_kind_it_names(old, new):
    assert mutation.rule_account(_diff(old, new)) is not None


@pytest.mark.parametrize(
    "old, new",
    [
        ('raise InvalidConfigError(f"max_iter {m}")', 'raise InvalidConfigError(f"max_iter {n}")'),
        ("pose=x.reshape(-1, 6)[k]", "pose=x.reshape(+1, 6)[k]"),
        ("E = angular_velocity_map(x[..., 1:3])", "E = angular_velocity_map(x[..., 1:4])"),
        ("p = other(x[:3])", "p = other(x[:4])"),
        ("p = other(x[:, :3])", "p = other(x[:, :4])"),
        ("R = rotation_rpy(x[:, 1:3])", "R = rotation_rpy(x[:, 1:4])"),
        ('q = as_number("q", q, 0.0)', 'q = as_number("q", q, None)'),
        ('s = check_int("seed", s, 0, 2**32 - 1)', 's = check_int("seed", s, 0, 2**32 + 1)'),
    ],
)
def test_a_change_of_a_number_is_left_to_its_tests(old, new):
    assert mutation.rule_account(_diff(old, new)) is None


@pytest.mark.parametrize(
    "old,new,kind",
    [
        ('raise E(f"x must be >= 0, got {x!r}")', "raise E(None)", "a message"),
        ('raise E(f"x={x}")', "raise E(None)", None),  # no words: a value, not a message
        ('A = as_array("A", A)', "A = as_array(None, A)", "the name of the argument"),
        ('A = as_array("A", A)', 'A = as_array("XXAXX", A)', "the name of the argument"),
        (
            'B, C = as_array("B", B), as_array("C", C)',
            'B, C = as_array("B", B), as_array("c", C)',
            "the name of the argument",
        ),
        ('h = as_number("h", h, 0.0)', 'h = as_number("h", h, None)', None),
        (
            "Q * d.reshape(-1, 1) * d.reshape(1, -1),",
            "Q * d.reshape(-1, 1) * d.reshape(-1),",
            "row",
        ),
        ("return d.reshape(1, -1)", "return d.reshape(-1)", None),  # not a factor: a shape
    ],
)
def test_the_rules_account_for_their_kind_only(old, new, kind):
    account = mutation.rule_account(_diff(old, new))
    assert (account is None) if kind is None else (kind in account), account


def test_a_message_over_several_lines_made_none_is_words():
    diff = '@@ -1,2 +1 @@\n-    f"needs A (n, n); got "\n-    f"{np.shape(A)}"\n+    None'
    assert "f-string" in mutation.rule_account(diff)
    diff = "@@ -1,2 +1 @@\n-    a = 1\n-    b = 2\n+    None"
    assert mutation.rule_account(diff) is None


def test_a_mutant_s_diff_shows_its_line_the_def_line_too():
    """mutmut's file holds each variant under its own name; the diff names the function as the
    module does, and a default argument mutated on the def line shows (it was left out)."""
    import ast

    source = "\n".join(
        [
            'def x_sweep__mutmut_orig(axis="Z"):',
            "    return 1 if axis else 0",
            'def x_sweep__mutmut_1(axis="XXZXX"):',
            "    return 1 if axis else 0",
            'def x_sweep__mutmut_2(axis="Z"):',
            "    return 2 if axis else 0",
        ]
    )
    functions = mutation._functions(ast.parse(source))
    name = "stewart_drake.references.trajectories.x_sweep__mutmut_"
    assert mutation.mutant_diff(source, functions, name + "1").splitlines() == [
        "@@ -1 +1 @@",
        '-def sweep(axis="Z"):',
        '+def sweep(axis="XXZXX"):',
    ]
    assert mutation.mutant_diff(source, functions, name + "2").splitlines() == [
        "@@ -2 +2 @@",
        "-    return 1 if axis else 0",
        "+    return 2 if axis else 0",
    ]


@pytest.mark.parametrize(
    "old, new, explained",
    [
        (
            "a, r = a.reshape(n, -1), r.reshape(n, -1)",
            "a, r = a.reshape(n, -1), r.reshape(n, -2)",
            True,
        ),
        (
            "a, r = a.reshape(n, -1), r.reshape(n, -1)",
            "a, r = a.reshape(n, -2), r.reshape(n, -1)",
            True,
        ),
        ("a = a.reshape(n, -1) + b", "a = a.reshape(n, -1) + c", False),
        ("p2p = np.ptp(rw, axis=0).astype(float)", "p2p = np.ptp(rw, axis=0).astype(None)", True),
        ("p2p = np.ptp(rw, axis=0).astype(float)", "p2p = np.ptp(rw, axis=1).astype(float)", False),
    ],
)
def test_the_rules_read_every_occurrence_of_their_kind(old, new, explained):
    diff = f"@@ -3 +3 @@\n-    {old}\n+    {new}"
    assert (mutation.rule_account(diff) is not None) == explained


def test_the_scores_go_to_the_docs_and_the_survivors_beside_the_tool():
    """The summary holds each module's counts and score (3 of 4 killed: 75.0 %) and points to
    the survivors' report; the survivors' report, not the summary, holds each survivor's diff
    and its account (an unaccounted one said so)."""
    result = mutation.ModuleResult(
        "stewart_drake/robot/statics.py",
        ("tests/test_statics.py",),
        [
            mutation.Mutant("stewart_drake.robot.statics.x_f__mutmut_1", "killed"),
            mutation.Mutant("stewart_drake.robot.statics.x_f__mutmut_2", "killed"),
            mutation.Mutant("stewart_drake.robot.statics.x_f__mutmut_3", "timeout"),
            mutation.Mutant("stewart_drake.robot.statics.x_f__mutmut_4", "survived", "-a\n+b"),
        ],
        seconds=90.0,
    )
    summary, survivors = mutation.report([result], {}, None)
    row = "| `stewart_drake/robot/statics.py` | test_statics.py | 4 | 2 | 1 | 1 | 0 | 75.0 % | 90 |"
    assert row in summary.splitlines()
    assert "1.5 min" in summary and "tools/mutation_survivors.md" in summary
    assert "x_f__mutmut_4" not in summary and "+b" not in summary
    assert "## Survivors in `stewart_drake/robot/statics.py`" in survivors
    assert "- `x_f__mutmut_4` (survived): **unaccounted**" in survivors
    assert "  +b" in survivors.splitlines() and "1 of 1 without an account." in survivors


def test_without_mutmut_the_tool_says_how_to_install_it_before_any_work(monkeypatch, capsys):
    real = importlib.util.find_spec
    monkeypatch.setattr(
        importlib.util,
        "find_spec",
        lambda name, *a: None if name == "mutmut" else real(name, *a),
    )
    monkeypatch.setattr(mutation, "run_module", lambda *a: pytest.fail("ran without mutmut"))
    with pytest.raises(SystemExit) as stop:
        mutation.main(["--module", "signals"])
    assert stop.value.code == 2
    assert 'pip install -e ".[test,mutation]"' in capsys.readouterr().err


def test_a_kernel_s_decorator_becomes_a_call_after_its_last_line():
    """mutmut mutates no decorated function: the scratch copy calls ``_njit`` after the function
    instead, and the module then holds the same marked functions as decorated."""
    source = (
        "def _njit(f):\n"
        "    f.kernel = True\n"
        "    return f\n"
        "\n"
        "@_njit\n"
        "def a(x):\n"
        "    return x + 1\n"
        "\n"
        "\n"
        "def b(x):\n"
        "    return a(x) * 2\n"
        "\n"
        "@_njit  \n"
        "def c(x):\n"
        "    y = x\n"
        "    return y\n"
        "reference = sorted(n for n, v in dict(globals()).items() if getattr(v, 'kernel', 0))\n"
    )
    text = mutation.undecorated(source)
    assert "@_njit" not in text
    assert text.count("= _njit(") == 2
    namespace: dict = {}
    exec(compile(text, "<undecorated>", "exec"), namespace)
    assert namespace["reference"] == ["a", "c"]
    assert namespace["b"](1) == 4
    assert not getattr(namespace["b"], "kernel", False)


def test_a_run_of_some_modules_replaces_their_rows_and_keeps_the_rest():
    """``--module``: the module's row replaces its old row where it stood, a module new to the
    table follows the last row, and the prose under the table stays."""
    old = "\n".join(
        [
            "# title",
            "",
            "| module | score |",
            "|---|---:|",
            "| `stewart_drake/a.py` | 90.0 % |",
            "| `stewart_drake/b.py` | 80.0 % |",
            "",
            "Prose written by hand under the table.",
        ]
    )
    new = "\n".join(
        [
            "# title",
            "",
            "| module | score |",
            "|---|---:|",
            "| `stewart_drake/b.py` | 86.5 % |",
            "| `stewart_drake/c.py` | 91.0 % |",
            "",
            "The whole run took 2.0 min on this machine.",
        ]
    )
    merged = mutation.merged_summary(old, new).splitlines()
    assert merged[4:8] == [
        "| `stewart_drake/a.py` | 90.0 % |",
        "| `stewart_drake/b.py` | 86.5 % |",
        "| `stewart_drake/c.py` | 91.0 % |",
        "",
    ]
    assert merged[-1] == "Prose written by hand under the table."
    assert "The whole run took 2.0 min on this machine." not in merged


def test_a_run_of_some_modules_replaces_their_survivor_sections_and_keeps_the_rest():
    old = (
        "# Surviving mutants\n\nintro\n\n"
        "## Survivors in `stewart_drake/a.py`\n\n- `x_f__mutmut_1` (survived): old a\n\n"
        "## Survivors in `stewart_drake/b.py`\n\n- `x_g__mutmut_2` (survived): old b\n"
    )
    new = (
        "# Surviving mutants\n\nanother intro\n\n"
        "## Survivors in `stewart_drake/a.py`\n\nNone.\n\n"
        "## Survivors in `stewart_drake/c.py`\n\n- `x_h__mutmut_3` (survived): new c\n"
    )
    merged = mutation.merged_survivors(old, new)
    assert merged == (
        "# Surviving mutants\n\nintro\n\n"
        "## Survivors in `stewart_drake/a.py`\n\nNone.\n\n"
        "## Survivors in `stewart_drake/b.py`\n\n- `x_g__mutmut_2` (survived): old b\n\n"
        "## Survivors in `stewart_drake/c.py`\n\n- `x_h__mutmut_3` (survived): new c\n"
    )


def test_a_standing_report_is_read_by_the_checked_reader_before_the_runs(tmp_path):
    from stewart_drake.base.errors import CorruptFileError

    assert mutation._standing_report(tmp_path / "none.md", "--out") is None
    report = tmp_path / "mutation.md"
    report.write_text("| `stewart_drake/a.py` | 90.0 % |\n")
    assert mutation._standing_report(report, "--out") == "| `stewart_drake/a.py` | 90.0 % |\n"
    with pytest.raises(CorruptFileError, match="--survivors report"):
        mutation._standing_report(tmp_path, "--survivors")  # a folder
