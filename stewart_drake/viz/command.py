"""``stewart-drake diagrams``: the Diagram's pictures rewritten (diagrams/*.dot, rendered as
SVG by Graphviz)."""

from __future__ import annotations


def register(sub) -> None:
    """Add the ``diagrams`` command to ``sub``, the ``stewart-drake`` subparsers."""
    _add_diagrams_command(sub)


def _add_diagrams_command(sub) -> None:
    """The ``diagrams`` command's options."""
    dg = sub.add_parser("diagrams", help="rewrite diagrams/*.dot and render *.svg (Graphviz)")
    dg.add_argument("--out", default="diagrams", help="folder (in the current folder)")
    dg.add_argument("--dot-only", action="store_true", help="write the .dot sources only")
    dg.set_defaults(func=_cmd_diagrams)


def _cmd_diagrams(args) -> int:
    """``stewart-drake diagrams``: rewrite diagrams/*.dot and render diagrams/*.svg."""
    from .diagrams import write_diagrams

    for path in write_diagrams(args.out, render=not args.dot_only):
        print(f"wrote {path}")
    return 0
