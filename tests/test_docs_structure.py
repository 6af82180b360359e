"""Docs a newcomer can walk: docs/index.md reaches every page and README.md points to it, the
layout table of docs/development.md is what tools/layout_table.py writes from the tree (so it
cannot go stale), and the API reference builds without a warning (tools/api_docs.py, where the
``docs`` extra is installed)."""

import importlib.util
import pkgutil
import re
import sys
from pathlib import Path

import pytest
from conftest import needs_extra

import stewart_drake

REPO = Path(__file__).resolve().parent.parent
DOCS = REPO / "docs"


def _tool(name: str):
    """A script of tools/ as a module."""
    spec = importlib.util.spec_from_file_location(name, REPO / "tools" / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


layout_table = _tool("layout_table")

# -- the layout table ---------------------------------------------------------------------------


def test_the_layout_table_is_what_the_tool_writes():
    """The committed table is the tree's: regenerate it with ``python tools/layout_table.py``
    after adding, moving or renaming a module or changing its docstring's first sentence."""
    text = (DOCS / "development.md").read_text(encoding="utf-8")
    assert all(marker in text for marker in layout_table.MARKERS)
    assert layout_table.block() in text, (
        "docs/development.md's layout table is stale: run python tools/layout_table.py"
    )
    assert layout_table.main(["--check"]) == 0


def test_the_layout_table_names_every_module_python_finds():
    """The tool's walk of the files agrees with Python's walk of the package (pkgutil)."""
    rows = layout_table.package_rows(REPO, layout_table.layer_ranks(REPO / "tests/test_layers.py"))
    # An installed package may map data folders into it (stewart_drake.scenarios): modules only.
    walk = [
        info
        for info in pkgutil.walk_packages(stewart_drake.__path__, "stewart_drake.")
        if (REPO / "stewart_drake")
        in Path(importlib.util.find_spec(info.name).origin or "/").parents
    ]
    assert {row.name for row in rows} == {"stewart_drake"} | {info.name for info in walk}
    packages = {"stewart_drake"} | {info.name for info in walk if info.ispkg}
    assert {row.name for row in rows if row.is_package} == packages


def test_the_layout_section_names_every_package():
    """The prose above the table names each top-level package, so a new package gets its
    sentence there too."""
    text = (DOCS / "development.md").read_text(encoding="utf-8")
    section = text[text.index("## Layout") : text.index(layout_table.MARKERS[0])]
    tops = sorted(p.parent.name for p in (REPO / "stewart_drake").glob("*/__init__.py"))
    missing = [top for top in tops if f"`{top}`" not in section]
    assert not missing, "docs/development.md's Layout section does not name " + ", ".join(missing)


@pytest.mark.parametrize(
    "docstring, shown",
    [
        ("One line.\n\nMore.", "One line."),
        ("Split over\n    two lines. Then more.", "Split over two lines."),
        ("IK eq. 6 and Fig. 7 of the paper. More.", "IK eq. 6 and Fig. 7 of the paper."),
        (
            "Text (:func:`~.metrics.format_metrics`, :mod:`.runners`, :class:`Scenario`).",
            "Text (`format_metrics`, `runners`, `Scenario`).",
        ),
        ("A ``|L|`` ratio. More.", "A `\\|L\\|` ratio."),
    ],
)
def test_a_summary_is_the_first_sentence_as_sphinx_shows_it(docstring, shown):
    assert layout_table.summary(docstring) == shown


def _tree(root: Path, files: dict) -> Path:
    for name, text in files.items():
        (root / name).parent.mkdir(parents=True, exist_ok=True)
        (root / name).write_text(text)
    return root


def test_the_layout_table_refuses_a_module_without_a_docstring_or_a_rank(tmp_path):
    repo = _tree(
        tmp_path,
        {
            "stewart_drake/__init__.py": '"""The package."""\n',
            "stewart_drake/base/__init__.py": '"""Base."""\n',
            "stewart_drake/base/quiet.py": "X = 1\n",
            "stewart_drake/extra/__init__.py": '"""A package without a rank."""\n',
            "tests/test_layers.py": 'LAYERS = {"base": 0}\n',
        },
    )
    ranks = layout_table.layer_ranks(repo / "tests" / "test_layers.py")
    with pytest.raises(layout_table.LayoutError, match="no rank in tests/test_layers.py for extra"):
        layout_table.package_rows(repo, ranks)
    with pytest.raises(layout_table.LayoutError, match="quiet.py: no docstring"):
        layout_table.package_rows(repo, {"base": 0, "extra": 1})


# -- the API reference ----------------------------------------------------------------------------


@pytest.fixture
def api_docs():
    return _tool("api_docs")


@needs_extra("docs")
def test_the_api_reference_builds_a_page_per_module(api_docs, tmp_path):
    """The whole package, as CI's lint step builds it: no module fails to import, nothing warns
    (torch-only code imports without torch), and the front page links every module."""
    out = tmp_path / "api"
    problems = api_docs.build(REPO / "stewart_drake", out)
    assert problems == []
    names = api_docs.module_names(REPO / "stewart_drake")
    assert "stewart_drake.run.plan" in names
    missing = [n for n in names if not (out / f"{n.replace('.', '/')}.html").is_file()]
    assert not missing
    front = (out / "stewart_drake.html").read_text(encoding="utf-8")
    assert all(f'href="{n.replace(".", "/")}.html"' in front for n in names if n != "stewart_drake")
    # A relative Sphinx reference is a link to the module Sphinx finds (run_report names
    # :func:`~.metrics.format_metrics`, a module of another package).
    page = (out / "stewart_drake/paper/run_report.html").read_text(encoding="utf-8")
    assert 'href="../run/metrics.html#format_metrics"' in page


@pytest.fixture
def probe(tmp_path, monkeypatch):
    """A package of three modules: one clean, one that cannot be imported, one that warns."""
    package = (
        _tree(
            tmp_path,
            {
                "apidocs_probe/__init__.py": '"""A probe."""\n',
                "apidocs_probe/clean.py": '"""Clean."""\n\n\ndef f():\n    """Returns 1."""\n',
                "apidocs_probe/broken.py": "import apidocs_probe_no_such_module\n",
                "apidocs_probe/noisy.py": 'import warnings\n\nwarnings.warn("noisy at import")\n',
            },
        )
        / "apidocs_probe"
    )
    monkeypatch.syspath_prepend(str(tmp_path))
    yield package
    for name in [n for n in sys.modules if n.startswith("apidocs_probe")]:
        del sys.modules[name]


@needs_extra("docs")
def test_the_api_reference_fails_on_an_import_error_and_on_a_warning(api_docs, probe, capsys):
    out = probe.parent / "out"
    assert api_docs.main(["--package", str(probe), "--out", str(out)]) == 1
    err = capsys.readouterr().err
    assert "apidocs_probe.broken: cannot be imported: ModuleNotFoundError" in err
    assert "warning: UserWarning: noisy at import" in err
    assert "2 problems" in err
    assert (out / "apidocs_probe" / "clean.html").is_file()  # the rest is built, for a look
    # A second build replaces its own folder; a folder it did not write is refused.
    assert api_docs.main(["--package", str(probe), "--out", str(out)]) == 1
    (probe.parent / "mine").mkdir()
    (probe.parent / "mine" / "notes.txt").write_text("keep")
    assert api_docs.main(["--package", str(probe), "--out", str(probe.parent / "mine")]) == 1
    assert "did not write" in capsys.readouterr().err
    assert (probe.parent / "mine" / "notes.txt").read_text() == "keep"
    assert api_docs.main(["--package", str(probe), "--out", str(probe.parent / "mine/notes.txt")])
    assert "is not a folder" in capsys.readouterr().err


# -- the index -----------------------------------------------------------------------------------

#: A Markdown link's target, without its #anchor.
_LINK = re.compile(r"\]\(([^)\s#]+)(?:#[^)\s]*)?\)")


def linked_pages(page: Path) -> set[Path]:
    """The Markdown pages of the repository that ``page`` links to."""
    targets = (
        (page.parent / t).resolve()
        for t in _LINK.findall(page.read_text(encoding="utf-8"))
        if not t.startswith(("http://", "https://", "mailto:"))
    )
    return {t for t in targets if t.suffix == ".md" and t.is_file()}


def test_the_index_reaches_every_page():
    """Every page of docs/ (its subfolders too) is reached from docs/index.md by following
    links."""
    seen, todo = set(), [(DOCS / "index.md").resolve()]
    while todo:
        page = todo.pop()
        if page not in seen:
            seen.add(page)
            todo += [p for p in linked_pages(page) if DOCS.resolve() in p.parents]
    missing = sorted(
        str(p.relative_to(REPO)) for p in DOCS.rglob("*.md") if p.resolve() not in seen
    )
    assert not missing, "pages docs/index.md does not reach: " + ", ".join(missing)


def test_the_index_links_every_top_level_page_itself():
    """A newcomer finds each page of docs/ on the index, not two clicks away."""
    linked = linked_pages(DOCS / "index.md")
    missing = [p.name for p in sorted(DOCS.glob("*.md")) if p.name != "index.md"]
    missing = [name for name in missing if (DOCS / name).resolve() not in linked]
    assert not missing, "docs/index.md does not link " + ", ".join(missing)


def test_the_readme_points_to_the_index():
    readme = (REPO / "README.md").read_text(encoding="utf-8")
    section = readme[readme.index("## Where to go next") :].split("\n## ")[0]
    assert "](docs/index.md)" in section
