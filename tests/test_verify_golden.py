"""What every documented ``verify`` command prints and writes, held to what it printed and wrote
when this test was written: a refactoring of the verdict must leave every verdict, report,
figure and record the same.

Each block of docs/*.md that holds a ``verify`` command is run as tests/test_docs_commands.py's
slow tier runs it (in order, with its short options, in a fresh folder holding the shipped
examples, ``stewart-drake examples``), and everything each command leaves is written into one
text per block, compared with ``tests/golden/verify/BLOCK.txt``:

- its exit status, and what it printed on stdout and stderr, byte for byte (the folder's path
  and the loading line, which says how long Drake took, aside);
- every text file it wrote (``.md``, ``.json``, ``.yaml``), byte for byte, but a record's date
  (its file name's stamp and its ``date`` field), which is the clock's;
- every figure it saved (in a PNG or in a record), in order, by what it draws, not its bytes
  (matplotlib's own PNG bytes move with its version and its fonts): each axes' title, labels,
  limits, legend and texts, and each line's and collection's label, point count and data
  (first, last, least, greatest, RMS; no mean, whose cancelling sum keeps only the machine's
  last bits) to six significant digits;
- every PDF record by its text (tests/test_qa_record.py's reader of the raw streams, the same
  whether pypdfium2 is installed or not), the date aside.

The golden files are compared byte for byte where they were written (their first line names the
Python, numpy, scipy and matplotlib they were written with, and the CPU's SIMD kernels numpy
dispatches to). Elsewhere numpy's and scipy's own
arithmetic moves the last bits of a float (an FFT summed in another order: 0.00703124999999999
against 0.007031249999999993) and, on a rounding edge, a printed digit (2.812 mm against 2.813):
there every word must still be the same, every integer the same, and every other number within
a ten-thousandth of itself, 1e-9, or one unit of its last printed digit
(:func:`same_but_last_digits`).

The golden files are what the code printed before the verdict moved into a package of its own,
not values computed here: this is a characterisation test. To rewrite them after a change that
is meant to change what ``verify`` prints, run ``STEWART_DRAKE_WRITE_GOLDEN=1 python -m pytest
tests/test_verify_golden.py`` and read the diff before committing it.
"""

from __future__ import annotations

import os
import re
from pathlib import Path

import numpy as np
import pytest
from test_docs_commands import blocks, exit_status, stage, with_short
from test_qa_record import page_texts

from stewart_drake.cli.main import main

REPO = Path(__file__).resolve().parent.parent
GOLDEN = Path(__file__).resolve().parent / "golden" / "verify"
WRITE = os.environ.get("STEWART_DRAKE_WRITE_GOLDEN") == "1"
#: A record's time stamp, in its file name (20261128T235344) and in its fields.
_STAMP = re.compile(r"\d{8}T\d{6}|\d{4}-\d{2}-\d{2}T\d{2}:\d{2}:\d{2}(\.\d+)?([+-]\d{2}:\d{2}|Z)?")
_TEXT_SUFFIXES = {".md", ".json", ".yaml", ".txt", ".csv"}


#: Elsewhere, a number may move by this share of itself (single-precision sums: 7e-6 seen)...
RELATIVE = 1e-4
#: ... or by this much (a sum that cancels to 1e-16 in one order and 1.00001e-16 in another).
ABSOLUTE = 1e-9
_NUMBER = re.compile(r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?")


def environment() -> str:
    """The first line of a golden file: where it is compared byte for byte. The CPU counts:
    the same numpy and scipy sum and transform in another order where numpy dispatches to
    other SIMD instructions (an AVX-512 machine printed 0.0028124999999999995 where the
    golden's, written on another, held 0.0028125000000000003)."""
    import platform

    import matplotlib
    import scipy

    try:  # numpy's own record of what it dispatches to (np.show_runtime reads the same)
        from numpy._core._multiarray_umath import __cpu_dispatch__, __cpu_features__

        simd = next((f for f in reversed(__cpu_dispatch__) if __cpu_features__.get(f)), "none")
    except ImportError:
        simd = "unknown"
    return (
        f"# written with Python {platform.python_version()}, numpy {np.__version__}, "
        f"scipy {scipy.__version__}, matplotlib {matplotlib.__version__}, on "
        f"{platform.machine()} with numpy's {simd} kernels"
    )


def _unit(token: str) -> float:
    """One unit of the last printed digit of a number's text (0 for an integer)."""
    mantissa, _, exponent = token.lower().partition("e")
    if "." not in mantissa and not exponent:
        return 0.0
    decimals = len(mantissa.partition(".")[2])
    return 10.0 ** (int(exponent or 0) - decimals)


def same_but_last_digits(expected: str, now: str) -> list[str]:
    """The lines of ``now`` that differ from ``expected`` by more than the last bits of a
    float (module docstring), as ``golden | now`` pairs; [] when none."""
    a, b = expected.splitlines(), now.splitlines()
    if len(a) != len(b):
        return [f"{len(a)} lines | {len(b)} lines"]
    wrong = []
    for x, y in zip(a, b):
        if x == y:
            continue
        if _NUMBER.sub("#", x) != _NUMBER.sub("#", y):
            wrong.append(f"{x} | {y}")
            continue
        for p, q in zip(_NUMBER.findall(x), _NUMBER.findall(y)):
            u, v = float(p), float(q)
            bound = max(
                RELATIVE * max(abs(u), abs(v)), ABSOLUTE, 1.000001 * max(_unit(p), _unit(q))
            )
            if (bound == 0.0 and p != q) or abs(u - v) > bound:
                wrong.append(f"{x} | {y}")
                break
    return wrong


def verify_blocks() -> list[str]:
    """The documented blocks holding a runnable ``verify`` command."""
    return [
        name
        for name, commands in blocks().items()
        if any(c.argv[:1] == ("verify",) and not c.not_run for c in commands)
    ]


def _golden_name(block: str) -> str:
    return block.replace("/", "_").replace(".md:", "_") + ".txt"


def _g(value) -> str:
    return f"{float(value):.6g}"


def _series(values) -> str:
    a = np.asarray(values, dtype=float).ravel()
    a = a[np.isfinite(a)]
    if not a.size:
        return "n 0"
    return (
        f"n {a.size} first {_g(a[0])} last {_g(a[-1])} min {_g(a.min())} max {_g(a.max())} "
        f"rms {_g(np.sqrt(np.mean(a**2)))}"
    )


def figure_lines(figure) -> list[str]:
    """What a matplotlib figure draws, as lines of text (module docstring)."""
    lines = [f"figure {figure.get_size_inches()[0]:.3g} x {figure.get_size_inches()[1]:.3g} in"]
    if figure._suptitle is not None:
        lines.append(f"  suptitle {figure._suptitle.get_text()!r}")
    for k, ax in enumerate(figure.axes):
        lines.append(
            f"  axes {k}: title {ax.get_title()!r} x {ax.get_xlabel()!r} y {ax.get_ylabel()!r} "
            f"xlim {_g(ax.get_xlim()[0])} {_g(ax.get_xlim()[1])} "
            f"ylim {_g(ax.get_ylim()[0])} {_g(ax.get_ylim()[1])}"
        )
        legend = ax.get_legend()
        if legend is not None:
            lines.append(f"    legend {[t.get_text() for t in legend.get_texts()]!r}")
        for text in ax.texts:
            lines.append(f"    text {text.get_text()!r}")
        for line in ax.get_lines():
            x, y = line.get_data()
            lines.append(f"    line {line.get_label()!r} x {_series(x)} | y {_series(y)}")
        for collection in ax.collections:
            offsets = collection.get_offsets()
            lines.append(f"    collection {collection.get_label()!r} {_series(offsets)}")
        for patch in ax.patches:  # in its own coordinates (data, axes): not the screen's
            corners = patch.get_patch_transform().transform(patch.get_path().vertices)
            lines.append(f"    patch {type(patch).__name__} {_series(corners)}")
    return lines


class FigureLog:
    """The figures saved while it is installed, in order, by what they draw (``savefig``
    wrapped: the commands save through a temporary file or into a PDF's buffer, so a figure is
    known by its order, not its file's name)."""

    def __init__(self, monkeypatch):
        from matplotlib.figure import Figure

        self.saved: list[list[str]] = []
        savefig = Figure.savefig

        def logged(figure, fname, *args, **kwargs):
            self.saved.append(figure_lines(figure))
            return savefig(figure, fname, *args, **kwargs)

        monkeypatch.setattr(Figure, "savefig", logged)


def _where_it_ran() -> dict[str, str]:
    """What a record says of the machine it ran on (its JSON's strings, its PDF's "drake 1.51.1"
    and the golden file's own first line), and the placeholder for each."""
    import platform
    from importlib.metadata import version

    import matplotlib
    import scipy

    versions = {
        "python": platform.python_version(),
        "drake": version("drake"),
        "numpy": np.__version__,
        "scipy": scipy.__version__,
        "matplotlib": matplotlib.__version__,
    }
    found = {platform.platform(): "PLATFORM"}
    for name, number in versions.items():
        found[f'"{number}"'] = f'"{name.upper()}"'
        for spelled in (name, name.capitalize()):
            found[f"{spelled} {number}"] = f"{spelled} {name.upper()}"
    return found


def _anonymous(text: str, folder: Path) -> str:
    """``text`` with the folder, a record's time stamp and the machine's versions replaced."""
    text = _STAMP.sub("STAMP", text.replace(str(folder), "FOLDER"))
    for name, placeholder in _where_it_ran().items():
        text = text.replace(name, placeholder)
    return text


def _printed(text: str, folder: Path) -> str:
    kept = [
        line
        for line in _anonymous(text, folder).splitlines()
        if not line.startswith("stewart-drake verify: loading Drake")
    ]
    return "\n".join(kept)


def _written(path: Path, folder: Path) -> list[str]:
    name = _STAMP.sub("STAMP", str(path.relative_to(folder)))
    if path.suffix in _TEXT_SUFFIXES:
        body = _anonymous(path.read_text(), folder)
        return [f"--- file {name}", body.rstrip("\n")]
    if path.suffix == ".pdf":
        pages = page_texts(path, raw=True)
        return [f"--- pdf {name}: {len(pages)} pages"] + [
            f"page {k + 1}: {_anonymous(text, folder).strip()}" for k, text in enumerate(pages)
        ]
    if path.suffix == ".png":
        return [f"--- png {name}"]  # what it draws is in the figures' lines
    return [f"--- other {name}: {path.stat().st_size} bytes"]


def run_block(block: str, folder: Path, figures: FigureLog, capsys) -> str:
    """Everything the block's commands print and write, as one text."""
    assert main(["examples", str(folder)]) == 0
    capsys.readouterr()
    examples = {p for p in folder.rglob("*") if p.is_file()}
    parts: list[str] = []
    for command in blocks()[block]:
        if command.not_run or stage(command, folder):
            continue
        argv = with_short(command)
        before = {p: p.stat().st_mtime_ns for p in folder.rglob("*") if p.is_file()}
        code = exit_status(argv)
        out, err = capsys.readouterr()
        parts += [
            f"=== {command.where}: stewart-drake {' '.join(argv)}",
            f"exit {code}",
            "--- stdout",
            _printed(out, folder),
            "--- stderr",
            _printed(err, folder),
        ]
        written = sorted(
            p
            for p in folder.rglob("*")
            if p.is_file() and p not in examples and before.get(p) != p.stat().st_mtime_ns
        )
        for path in written:
            parts += _written(path, folder)
        for k, drawn in enumerate(figures.saved):
            parts += [f"--- figure {k + 1} of {len(figures.saved)} saved"] + drawn
        figures.saved.clear()
    return "\n".join(parts) + "\n"


@pytest.mark.parametrize("block", verify_blocks())
def test_a_documented_verify_block_prints_and_writes_what_it_did(
    block, tmp_path, monkeypatch, capsys
):
    monkeypatch.chdir(tmp_path)
    figures = FigureLog(monkeypatch)
    text = run_block(block, tmp_path, figures, capsys)
    golden = GOLDEN / _golden_name(block)
    if WRITE:
        GOLDEN.mkdir(parents=True, exist_ok=True)
        golden.write_text(environment() + "\n" + text)
    assert golden.is_file(), f"{golden} is missing: STEWART_DRAKE_WRITE_GOLDEN=1 writes it"
    written_with, _, expected = golden.read_text().partition("\n")
    if text == expected:
        return
    if written_with == environment():
        import difflib

        diff = difflib.unified_diff(
            expected.splitlines(), text.splitlines(), "golden", "now", lineterm=""
        )
        pytest.fail(f"{block}: verify's output changed:\n" + "\n".join(list(diff)[:80]))
    wrong = same_but_last_digits(expected, text)
    assert not wrong, f"{block}: verify's output changed (golden | now):\n" + "\n".join(wrong[:40])


def test_every_documented_verify_block_has_its_golden_text():
    names = {_golden_name(b) for b in verify_blocks()}
    assert len(names) >= 5
    assert names == {p.name for p in GOLDEN.glob("*.txt")}, "a golden text without its block"


def test_a_changed_number_or_word_is_seen(monkeypatch, tmp_path):
    """The comparison can see a wrong figure: a line moved by a part in a million, a changed
    title, a changed printed digit."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    def drawn(scale: float, title: str) -> list[str]:
        figure, ax = plt.subplots()
        ax.plot(np.linspace(0, 1, 50), scale * np.sin(np.linspace(0, 3, 50)), label="X")
        ax.set_title(title)
        ax.legend()
        lines = figure_lines(figure)
        plt.close(figure)
        return lines

    assert drawn(1.0, "X") == drawn(1.0, "X")
    assert drawn(1.0, "X") != drawn(1.000002, "X")
    assert drawn(1.0, "X") != drawn(1.0, "Y")
    assert _printed("PASS 0.123 mm", tmp_path) != _printed("PASS 0.124 mm", tmp_path)
    assert _printed(f"wrote {tmp_path}/a.md", tmp_path) == "wrote FOLDER/a.md"
    assert _STAMP.sub("S", "r_20261128T235344.pdf 2026-11-28T23:53:44+00:00") == "r_S.pdf S"


def test_another_machine_is_allowed_its_last_bits_and_nothing_more():
    golden = '"reference": 0.00703124999999999,\n| 2 | 2.812 mm | +0.0762 % |\nn 4000 PASS'
    assert not same_but_last_digits(
        golden, '"reference": 0.007031249999999993,\n| 2 | 2.813 mm | +0.0762 % |\nn 4000 PASS'
    )
    for wrong in (
        '"reference": 0.0070320,\n| 2 | 2.812 mm | +0.0762 % |\nn 4000 PASS',  # 1.1e-4
        '"reference": 0.00703124999999999,\n| 2 | 2.814 mm | +0.0762 % |\nn 4000 PASS',
        '"reference": 0.00703124999999999,\n| 2 | 2.812 um | +0.0762 % |\nn 4000 PASS',
        '"reference": 0.00703124999999999,\n| 2 | 2.812 mm | +0.0762 % |\nn 4001 PASS',
        '"reference": 0.00703124999999999,\n| 2 | 2.812 mm | +0.0762 % |\nn 4000 FAIL',
        '"reference": 0.00703124999999999,\n| 2 | 2.812 mm | +0.0762 % |',
    ):
        assert same_but_last_digits(golden, wrong), wrong
