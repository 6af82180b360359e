"""The shape of the code: the longest functions, and the places that dispatch on a driver type.

Prints the N longest functions and methods of ``stewart_drake/`` (lines from ``def`` to the last
line of the body, docstring included, and the same without the docstring) and every
``isinstance`` test against a scenario choice (controller drivers, tuners, references), by file
and function: the figures a refactor of the package is measured by.

Usage: python tools/code_shape.py [--top 10] [--package stewart_drake]
"""

import argparse
import ast
from pathlib import Path


def choice_names() -> set:
    """The class names of the scenario's tagged choices (controllers, references, tuners, the
    learner), read from the scenario's unions: isinstance tests on them dispatch on a variant."""
    from stewart_drake.run.scenario import choice_classes

    return {kind.__name__ for kinds in choice_classes().values() for kind in kinds}


def functions(root: Path):
    """(lines, "file:qualified.name", code lines) of every function under ``root``: lines from
    ``def`` to the end of the body, and the same without the docstring."""
    out = []
    for path in sorted(root.rglob("*.py")):
        tree = ast.parse(path.read_text())
        where = path.relative_to(root.parent)

        def visit(node, prefix="", where=where):  # bound now: a def in a loop
            for child in ast.iter_child_nodes(node):
                if isinstance(child, (ast.FunctionDef, ast.AsyncFunctionDef)):
                    name = f"{prefix}{child.name}"
                    lines = child.end_lineno - child.lineno + 1
                    first = child.body[0]
                    doc = (
                        first.end_lineno - first.lineno + 1
                        if isinstance(first, ast.Expr)
                        and isinstance(first.value, ast.Constant)
                        and isinstance(first.value.value, str)
                        else 0
                    )
                    out.append((lines, f"{where}:{name}", lines - doc))
                    visit(child, name + ".")
                elif isinstance(child, ast.ClassDef):
                    visit(child, f"{prefix}{child.name}.")

        visit(tree)
    return sorted(out, reverse=True)


def dispatches(root: Path):
    """["file:function"] of every isinstance test whose class is one of the scenario's choices
    (:func:`choice_names`)."""
    choices = choice_names()
    out = []
    for path in sorted(root.rglob("*.py")):
        tree = ast.parse(path.read_text())
        for func in ast.walk(tree):
            if not isinstance(func, (ast.FunctionDef, ast.AsyncFunctionDef)):
                continue
            for node in ast.walk(func):
                if (
                    isinstance(node, ast.Call)
                    and getattr(node.func, "id", None) == "isinstance"
                    and len(node.args) == 2
                ):
                    names = {
                        n.id if isinstance(n, ast.Name) else getattr(n, "attr", "")
                        for n in ast.walk(node.args[1])
                    }
                    if names & choices:
                        out.append(
                            f"{path.relative_to(root.parent)}:{func.name} "
                            f"({', '.join(sorted(names & choices))})"
                        )
    return out


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--top", type=int, default=10)
    parser.add_argument(
        "--package", default=str(Path(__file__).resolve().parents[1] / "stewart_drake")
    )
    args = parser.parse_args()
    root = Path(args.package)
    print(f"longest {args.top} functions (lines; without the docstring):")
    for lines, name, code in functions(root)[: args.top]:
        print(f"  {lines:4d}  {code:4d}  {name}")
    found = dispatches(root)
    print(f"isinstance dispatches on a scenario choice: {len(found)}")
    for place in found:
        print(f"  {place}")


if __name__ == "__main__":
    main()
