"""The docs match the code: every module path, import, command, option and file named in
README.md, docs/*.md and the notebooks exists, and every Sphinx cross-reference in a docstring
(:func:, :mod:, :class:, :meth:, :data:, :attr:, :exc:) resolves.

Each check collects every broken name with its file and line and fails once with the whole list,
so whoever adds a page or renames a module sees everything to fix in one run.
"""

from __future__ import annotations

import argparse
import ast
import functools
import importlib
import inspect
import pkgutil
import re
import types
from pathlib import Path

import nbformat
import pytest

import stewart_drake
from stewart_drake.cli.registry import build_parser

REPO = Path(__file__).resolve().parent.parent
PACKAGE = REPO / "stewart_drake"
#: Folders whose files the docs may name (committed, so a name must exist).
COMMITTED = (
    "stewart_drake",
    "tests",
    "docs",
    "notebooks",
    "scenarios",
    "benchmarks",
    "tools",
    "sdf",
    "diagrams",
    ".ci",
)
#: Packages whose dotted names are checked by importing them.
PACKAGES = ("stewart_drake", "pydrake")

_DOTTED = re.compile(r"\b(?:stewart_drake|pydrake)(?:\.[A-Za-z_]\w*)+")
_PATH = re.compile(
    r"(?<![\w./-])((?:\.{1,2}/|/)?(?:[\w.-]+/)+[\w.-]+\.(?:py|md|yaml|ipynb|sdf|"
    r"png|svg|dot|npz|json|toml|txt|csv|lcm))\b"
)
_LINK = re.compile(r"\]\(([^)\s]+)\)")
_CODE_SPAN = re.compile(r"`([^`\n]+)`")
_COMMAND = re.compile(r"stewart-drake((?:[ \t]+[^\s`'\"|;&)#]+)*)")
_SCRIPT = re.compile(r"python\s+((?:benchmarks|tools)/[\w.-]+\.py)((?:[ \t]+[^\s`|;&)#]+)*)")
_OPTION = re.compile(r"(?<![\w-])(--[a-z][a-z0-9-]*)")


# -- the documents, line by line -----------------------------------------------------------------


def documents() -> list[Path]:
    return (
        [REPO / "README.md"]
        + sorted((REPO / "docs").glob("*.md"))
        + sorted((REPO / "notebooks").glob("*.ipynb"))
    )


def lines_of(path: Path):
    """(where, text, kind) per line: kind "prose", "code" (a fenced block or a notebook code
    cell) or "python" (python code: its imports are checked too); where is "file:line" or
    "file cell k line j"."""
    rel = path.relative_to(REPO)
    if path.suffix == ".ipynb":
        nb = nbformat.read(path, as_version=4)
        for k, cell in enumerate(nb.cells):
            kind = "python" if cell.cell_type == "code" else "prose"
            for j, text in enumerate(cell.source.splitlines(), start=1):
                yield f"{rel} cell {k} line {j}", text, kind
        return
    fence = None
    for n, text in enumerate(path.read_text().splitlines(), start=1):
        if text.lstrip().startswith("```"):
            fence = None if fence is not None else (text.strip()[3:].strip() or "text")
            continue
        kind = "prose" if fence is None else "python" if fence == "python" else "code"
        yield f"{rel}:{n}", text, kind


def code_fragments(text: str, kind: str) -> list[str]:
    """What is code on a line: the whole line in a code block, the `spans` in prose."""
    return [text] if kind != "prose" else _CODE_SPAN.findall(text)


# -- resolvers ------------------------------------------------------------------------------------


def resolve_dotted(name: str):
    """The object a dotted name denotes (the longest importable module, then attributes).

    Raises:
        LookupError: naming the part that does not exist.
    """
    if not name:
        raise LookupError("an empty name")
    parts = name.split(".")
    module, k = None, len(parts)
    while k > 0:
        try:
            module = importlib.import_module(".".join(parts[:k]))
            break
        except ModuleNotFoundError as err:
            if err.name is not None and not ".".join(parts[:k]).startswith(err.name):
                raise LookupError(f"importing {'.'.join(parts[:k])} fails: {err}") from None
            k -= 1
    if module is None:
        raise LookupError(f"no module {parts[0]}")
    obj = module
    for part in parts[k:]:
        try:
            obj = getattr(obj, part)
        except AttributeError:
            raise LookupError(f"{'.'.join(parts[: parts.index(part)])} has no {part!r}") from None
    return obj


def dataclass_field_names(obj) -> set:
    return set(getattr(obj, "__dataclass_fields__", {}))


def _field_types(cls, name: str) -> list:
    """The classes a dataclass field may hold (every member of a Union or Optional)."""
    import typing

    hint = typing.get_type_hints(cls).get(name)
    union = typing.get_origin(hint) in (typing.Union, types.UnionType)
    members = typing.get_args(hint) if union else (hint,)
    return [m for m in members if isinstance(m, type)]


def resolve_field_path(cls, parts) -> bool:
    """Whether ``a.b.c`` is a field path of the dataclass ``cls`` (a member of a tagged union
    counts), or ends in an attribute of the class it reaches."""
    if not parts:
        return True
    if parts[0] in dataclass_field_names(cls):
        kinds = _field_types(cls, parts[0])
        # Drake's config structs (MultibodyPlantConfig, SimulatorConfig) are not dataclasses:
        # their fields are attributes.
        return len(parts) == 1 or any(
            resolve_field_path(k, parts[1:])
            if dataclass_field_names(k)
            else len(parts) == 2 and hasattr(k, parts[1])
            for k in kinds
        )
    return len(parts) == 1 and hasattr(cls, parts[0])


def short_names():
    """{first part: how to resolve the rest}: our modules by their last name (``limits``,
    ``kinematics``) and the objects the docs name by a variable (``scenario.``, ``context.``)."""
    from stewart_drake.control.contract import ControllerContext
    from stewart_drake.run.result import RunResult
    from stewart_drake.run.scenario import Scenario

    names = {m.__name__.rsplit(".", 1)[-1]: m for m in our_modules()}
    names.update(
        stewart_drake=stewart_drake, scenario=Scenario, context=ControllerContext, result=RunResult
    )
    return names


_FILE_SUFFIX = re.compile(
    r"\.(py|md|yaml|ipynb|sdf|png|svg|dot|npz|json|toml|txt|csv|html|xml|lcm)$"
)
#: A code span that is a dotted name (``limits.validate_trajectory``, ``controller.omega_Q``).
_SHORT = re.compile(r"^([a-z_]\w*)((?:\.[A-Za-z_]\w*)+)$")


def resolve_short(span: str, names: dict) -> str | None:
    """None when a dotted code span names something that exists: a field path of a Scenario
    (``controller.omega_Q``, ``hardware.encoders``), or an attribute of one of our modules
    (``kinematics.ik``) or of a documented variable (``context.period_s``); else the reason."""
    from stewart_drake.run.scenario import Scenario

    first, rest = span.split(".", 1)
    parts = rest.split(".")
    if resolve_field_path(Scenario, [first] + parts):
        return None
    target = names.get(first)
    if target is None:
        return None if first not in EVERY_MODULE_WORD else f"no module or field {first!r}"
    if isinstance(target, type) and dataclass_field_names(target):
        return None if resolve_field_path(target, parts) else f"{target.__name__} has no {rest!r}"
    try:
        resolve_dotted(f"{getattr(target, '__name__', first)}.{rest}")
    except LookupError as err:
        return str(err)
    return None


def _package_words() -> set:
    """The names of our modules and packages (``stewart_drake/**/*.py``), read from the tree."""
    root = Path(stewart_drake.__file__).resolve().parent
    return {p.stem for p in root.rglob("*.py") if p.stem != "__init__"} | {
        p.parent.name for p in root.rglob("__init__.py")
    }


#: First words of dotted spans that must be ours: our modules' names (read from the package), the
#: names the code had before (a stale page uses them), Scenario's sections.
EVERY_MODULE_WORD = _package_words() | {
    "baselines",
    "controller",
    "hardware",
    "context",
    "result",
    "runners",
    "store",
}


def script_options() -> set:
    """The options of benchmarks/*.py and tools/*.py (their ``"--name"`` strings)."""
    found = set()
    for script in list((REPO / "benchmarks").glob("*.py")) + list((REPO / "tools").glob("*.py")):
        found |= set(re.findall(r'"(--[a-z][a-z0-9-]*)"', script.read_text()))
    return found


def _options_of(parser) -> set:
    """Every option of ``parser`` and of its own subcommands (``servo identify``'s are
    ``servo``'s)."""
    found = {o for a in parser._actions for o in a.option_strings}
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for verb in action.choices.values():
                found |= _options_of(verb)
    return found


def commands() -> dict[str, set]:
    """{subcommand: its options, its own subcommands' included} of the `stewart-drake` parser,
    with the global options."""
    parser = build_parser()
    (sub,) = [a for a in parser._actions if isinstance(a, argparse._SubParsersAction)]
    top = {o for a in parser._actions for o in a.option_strings}
    return {name: top | _options_of(p) for name, p in sub.choices.items()} | {"": top}


# -- the checks ---------------------------------------------------------------------------------

#: Not a module: the entry-point group of installed controllers (a name users write).
from stewart_drake.control.contract import ENTRY_POINT_GROUP  # noqa: E402


def broken_names_in_documents() -> list[str]:
    cmds = commands()
    every_option = set().union(*cmds.values()) | script_options() | {"--help"}
    names = short_names()
    broken = []
    for path in documents():
        for where, text, kind in lines_of(path):
            fragments = code_fragments(text, kind)
            # dotted names of our package and of Drake, in code or prose
            for name in set(_DOTTED.findall(text)) - {ENTRY_POINT_GROUP}:
                try:
                    resolve_dotted(name.rstrip("."))
                except LookupError as err:
                    broken.append(f"{where}: {name}: {err}")
            # files in the repository
            for target in set(_PATH.findall(text)) | {
                t.split("#")[0]
                for t in _LINK.findall(text)
                if not t.startswith(("http://", "https://", "mailto:", "#"))
            }:
                if (
                    not target
                    or any(c in target for c in "<>*{}")
                    or target.startswith(("results/", "/tmp/"))
                ):
                    continue  # an output or a pattern, not a file
                base = (
                    path.parent
                    if target.startswith(".")
                    or "/" not in target
                    or not target.split("/")[0] in COMMITTED
                    else REPO
                )
                candidates = [base / target, path.parent / target, REPO / target, PACKAGE / target]
                if not any(c.exists() for c in candidates):
                    broken.append(f"{where}: no file {target}")
            # dotted names in code spans: a module's attribute or a scenario field path
            if kind == "prose":
                for span in fragments:
                    span = span.strip().removesuffix("()")
                    if re.fullmatch(r"[\w-]+\.py", span):
                        if not any(p.name == span for p in REPO.rglob(span)):
                            broken.append(f"{where}: no file {span} in the repository")
                    elif (
                        _SHORT.match(span)
                        and not span.startswith(PACKAGES)
                        and not _FILE_SUFFIX.search(span)
                    ):
                        reason = resolve_short(span, names)
                        if reason:
                            broken.append(f"{where}: {span}: {reason}")
            # stewart-drake commands and their options
            for fragment in fragments:
                for match in _COMMAND.finditer(fragment):
                    words = match.group(1).split()
                    sub = words[0].rstrip(":,.") if words and not words[0].startswith("-") else ""
                    if sub not in cmds:
                        broken.append(f"{where}: no command `stewart-drake {sub}`")
                        continue
                    for option in (w.split("=")[0] for w in words if w.startswith("--")):
                        if option not in cmds[sub]:
                            broken.append(f"{where}: `stewart-drake {sub}` has no option {option}")
                for match in _SCRIPT.finditer(fragment):
                    script = REPO / match.group(1)
                    if not script.is_file():
                        broken.append(f"{where}: no script {match.group(1)}")
                        continue
                    source = script.read_text()
                    for option in _OPTION.findall(match.group(2)):
                        if f'"{option}"' not in source:
                            broken.append(f"{where}: {match.group(1)} has no option {option}")
                # an option named alone must belong to some command (pytest's are not ours)
                if "stewart-drake" not in fragment and "python" not in fragment:
                    for option in _OPTION.findall(fragment):
                        if option not in every_option and not fragment.lstrip().startswith(
                            ("pip", "pytest", "jupyter", "git")
                        ):
                            broken.append(f"{where}: no command has the option {option}")
    broken += broken_imports_in_documents()
    return sorted(set(broken))


def broken_imports_in_documents() -> list[str]:
    """`import x` and `from x import a, b` of our package in python blocks and notebook cells."""
    broken = []
    for path in documents():
        blocks, current = [], []
        for where, text, kind in lines_of(path):
            if kind == "python":
                current.append((where, text))
            elif current:
                blocks.append(current)
                current = []
        blocks.append(current)
        for block in blocks:
            for where, text in block:
                stripped = text.strip()
                if not stripped.startswith(("import ", "from ")):
                    continue
                try:
                    tree = ast.parse(stripped.rstrip("\\").rstrip("("))
                except SyntaxError:
                    tree = _parse_continued(block, where)
                    if tree is None:
                        broken.append(f"{where}: cannot parse {stripped!r}")
                        continue
                for node in ast.walk(tree):
                    if (
                        isinstance(node, ast.ImportFrom)
                        and node.module
                        and node.module.split(".")[0] in PACKAGES
                    ):
                        for alias in node.names:
                            try:
                                resolve_dotted(f"{node.module}.{alias.name}")
                            except LookupError as err:
                                broken.append(
                                    f"{where}: from {node.module} import {alias.name}: {err}"
                                )
                    elif isinstance(node, ast.Import):
                        for alias in node.names:
                            if alias.name.split(".")[0] in PACKAGES:
                                try:
                                    importlib.import_module(alias.name)
                                except ImportError as err:
                                    broken.append(f"{where}: import {alias.name}: {err}")
    return broken


def _parse_continued(block, where):
    """An import statement continued over several lines (parentheses), parsed whole."""
    start = [w for w, _ in block].index(where)
    text = ""
    for _, line in block[start:]:
        text += line + "\n"
        try:
            return ast.parse(text)
        except SyntaxError:
            continue
    return None


@functools.cache
def our_modules() -> tuple:
    """stewart_drake and every module of it (the scenarios folder holds data)."""
    return (stewart_drake,) + tuple(
        importlib.import_module(info.name)
        for info in pkgutil.walk_packages(stewart_drake.__path__, "stewart_drake.")
        if not info.name.startswith("stewart_drake.scenarios")
    )


_XREF = re.compile(r":(func|mod|class|meth|data|attr|exc):`~?([^`<]+?)(?:\s*<[^>]*>)?`")


def resolve_xref(target: str, module, owner: str | None):
    """Resolve a Sphinx cross-reference as Sphinx's Python domain does: the name absolute, in
    the current module, in the owning class, and a leading "." relative to the module's package
    and its parents.

    Raises:
        LookupError: no candidate resolves.
    """
    name = target.strip().removesuffix("()")
    relative = name.startswith(".")
    name = name.lstrip(".")
    package = (
        module.__name__.rsplit(".", 1)[0] if module.__name__ != "stewart_drake" else "stewart_drake"
    )
    candidates = [name, f"{module.__name__}.{name}"]
    if owner:
        candidates.append(f"{module.__name__}.{owner}.{name}")
    parts = package.split(".")
    candidates += [".".join(parts[:k] + [name]) for k in range(len(parts), 0, -1)]
    if relative:  # Sphinx: then any object whose dotted name ends so
        candidates.insert(0, f"{package}.{name}")
        first = name.split(".")[0]
        candidates += [
            f"{m.__name__}.{name.split('.', 1)[1]}" if "." in name else m.__name__
            for m in our_modules()
            if m.__name__.endswith("." + first)
        ]
        candidates += [f"{m.__name__}.{name}" for m in our_modules()]
    if owner:  # an instance attribute its class documents (Attributes:)
        doc = getattr(getattr(module, owner, None), "__doc__", "") or ""
        if re.search(rf"(^|\s){re.escape(name)}:", doc):
            return f"{module.__name__}.{owner}.{name}"
    for candidate in candidates:
        try:
            resolve_dotted(candidate)
            return candidate
        except LookupError:
            pass
        head, _, attribute = candidate.rpartition(".")
        try:  # a dataclass field: a class attribute only when defaulted
            if head and attribute in dataclass_field_names(resolve_dotted(head)):
                return candidate
        except LookupError:
            pass
    raise LookupError(f"none of {candidates[:3]}... exists")


def docstrings(module):
    """(line, docstring text, owning class or None) of the module, its classes and functions,
    read from the source so that lines are the file's."""
    source = inspect.getsource(module)
    tree = ast.parse(source)
    owner = _owners(tree)
    for node in ast.walk(tree):
        if isinstance(node, (ast.Module, ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef)):
            body = node.body
            if (
                body
                and isinstance(body[0], ast.Expr)
                and isinstance(getattr(body[0], "value", None), ast.Constant)
                and isinstance(body[0].value.value, str)
            ):
                yield body[0].lineno, body[0].value.value, owner.get(node)
        if isinstance(node, ast.Call):  # docstrings given to a factory
            for arg in node.args:
                if (
                    isinstance(arg, ast.Constant)
                    and isinstance(arg.value, str)
                    and ":`" in arg.value
                ):
                    yield arg.lineno, arg.value, None


def _owners(tree) -> dict:
    """{node: name of its class} for each class and each statement directly in a class's
    body (its methods), in one walk of the tree."""
    owner = {}
    for parent in ast.walk(tree):
        if isinstance(parent, ast.ClassDef):
            owner.setdefault(parent, parent.name)
            for child in parent.body:
                owner.setdefault(child, parent.name)
    return owner


def broken_cross_references() -> list[str]:
    broken = []
    for module in our_modules():
        rel = Path(module.__file__).relative_to(REPO)
        for line, text, owner in docstrings(module):
            for k, doc_line in enumerate(text.splitlines()):
                for role, target in _XREF.findall(doc_line):
                    try:
                        resolve_xref(target, module, owner)
                    except LookupError:
                        broken.append(f"{rel}:{line + k}: :{role}:`{target}` does not resolve")
    return sorted(set(broken))


def test_every_name_in_the_docs_exists():
    broken = broken_names_in_documents()
    assert not broken, (
        f"{len(broken)} names in README.md, docs/ and the notebooks do not "
        f"exist:\n" + "\n".join(broken)
    )


def test_every_cross_reference_in_a_docstring_resolves():
    broken = broken_cross_references()
    assert not broken, f"{len(broken)} docstring cross-references do not resolve:\n" + "\n".join(
        broken
    )


def test_the_checks_catch_a_renamed_module(tmp_path, monkeypatch):
    """The checks can fail: a page naming a module, a function, a file, a command and an option
    that do not exist gets one line each."""
    page = tmp_path / "docs"
    page.mkdir()
    (page / "bad.md").write_text(
        "See `stewart_drake.visualize.record_html` and [the notes](missing.md).\n"
        "```python\nfrom stewart_drake.run.simulate import run_experiments\n```\n"
        "Run `stewart-drake run --fast` or `stewart-drake simulate`.\n"
    )
    (tmp_path / "README.md").write_text("ok: `stewart_drake.viz.visualize.record_html`\n")
    (tmp_path / "notebooks").mkdir()
    monkeypatch.setattr(__import__(__name__), "REPO", tmp_path)
    broken = broken_names_in_documents()
    assert broken == [
        "docs/bad.md:1: no file missing.md",
        "docs/bad.md:1: stewart_drake.visualize.record_html: stewart_drake has no 'visualize'",
        "docs/bad.md:3: from stewart_drake.run.simulate import run_experiments: "
        "stewart_drake.run.simulate has no 'run_experiments'",
        "docs/bad.md:5: `stewart-drake run` has no option --fast",
        "docs/bad.md:5: no command `stewart-drake simulate`",
    ]


@pytest.mark.parametrize(
    "target, ok",
    [
        (".runners", True),
        ("~stewart_drake.control.contract", True),
        ("LqiTuning", False),
        ("stewart_drake.evaluation.evaluation.evaluate", True),
        ("gone", False),
    ],
)
def test_cross_references_resolve_as_sphinx_does(target, ok):
    from stewart_drake.evaluation import evaluation

    if ok:
        resolve_xref(target.lstrip("~"), evaluation, None)
    else:
        with pytest.raises(LookupError):
            resolve_xref(target, evaluation, None)


def test_ci_runs_the_readme_test_command_at_both_ends():
    """.ci/run runs the test command the README shows, on the oldest and the newest supported
    Python and once with README's install command as written (no other extra), and the pins
    in pyproject.toml are those two ends."""
    ci = (REPO / ".ci" / "run").read_text()
    (command,) = re.findall(r"^TEST_COMMAND='(.+)'$", ci, re.M)
    readme = (REPO / "README.md").read_text()
    assert f"&& {command}\n" in readme, f"README.md does not show CI's test command {command!r}"
    assert "python3.13" in ci and "python3.11" in ci and "torch==2.13.0" in ci
    # One run installs exactly what README's command installs, nothing before it and no other
    # extra: a test that needs an extra and does not skip naming it fails there.
    install = r'pip install -e "\.\[(\w+)\]" && '
    (extras,) = re.findall(install + re.escape(command) + "$", readme, re.M)
    runs = re.findall(r'^suite (\w+) "\$\w+" "([\w,]+)"(.*?) \|\|', ci, re.M)
    assert (extras, "") in [(installed, before.strip()) for _, installed, before in runs], (
        f"no CI run installs README's [{extras}] alone: {runs}"
    )
    project = (REPO / "pyproject.toml").read_text()
    assert 'requires-python = ">=3.11,<3.14"' in project and '"drake>=1.51,<1.59"' in project
