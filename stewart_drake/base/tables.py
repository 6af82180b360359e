"""Markdown pipe tables, the one writer of the tables of the generated documents (docs/*.md,
the studies' reports): :func:`markdown_table` a whole table, :func:`markdown_lines` its lines,
:func:`markdown_row` one line."""

from collections.abc import Iterable, Sequence

#: The alignment row's cell of each alignment: None (the renderer's default, left), "left",
#: "right", "center".
ALIGNMENTS = {None: "---", "left": ":---", "right": "---:", "center": ":---:"}


def markdown_row(cells: Iterable) -> str:
    """One line of a pipe table: ``| a | b |``, each cell written as an f-string writes it.

    A cell that is None is a blank cell, written ``| |`` (the corner above a column of row
    labels, the columns a failed run's row leaves empty); an empty string is a cell like any
    other, written ``|  |``. Cells are written as given: a ``|`` inside one must be escaped
    (``\\|``) by the caller, or it splits the cell.
    """
    return "|" + "|".join(" " if c is None else f" {c} " for c in cells) + "|"


def markdown_lines(
    header: Sequence, rows: Iterable[Iterable], align: Sequence | None = None
) -> list[str]:
    """A pipe table's lines: the header line, the alignment line, a line per row.

    Args:
        header: the columns' names (cells as :func:`markdown_row` writes them).
        rows: the rows' cells. A row with fewer cells than the header is written as it is
            (Markdown shows the missing cells empty): a failed run's row that says so once.
        align: per column, a key of :data:`ALIGNMENTS`; None: ``---`` in every column.
    Returns:
        2 + len(rows) lines, without newlines.
    Raises:
        ValueError: ``align`` of another length than ``header``, or an unknown alignment.
    """
    if align is None:
        align = [None] * len(header)
    if len(align) != len(header):
        raise ValueError(f"{len(align)} alignments for {len(header)} columns")
    unknown = [a for a in align if a not in ALIGNMENTS]
    if unknown:
        raise ValueError(f"unknown alignment {unknown[0]!r}: one of {list(ALIGNMENTS)}")
    rule = "|" + "|".join(ALIGNMENTS[a] for a in align) + "|"
    return [markdown_row(header), rule] + [markdown_row(r) for r in rows]


def markdown_table(
    header: Sequence, rows: Iterable[Iterable], align: Sequence | None = None
) -> str:
    """A pipe table (:func:`markdown_lines`) as one text, its lines joined by ``\\n``, no
    trailing newline.

    Raises:
        ValueError: as :func:`markdown_lines`.
    """
    return "\n".join(markdown_lines(header, rows, align))
