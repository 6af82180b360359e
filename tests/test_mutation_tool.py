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
