"""Every ``stewart-drake`` command in the code blocks of README.md and docs/*.md runs as written in
a folder holding the example inputs (``stewart-drake examples``).

A command is a line of a fenced block (``\\`` continuations joined) whose shell words, split as
the shell splits them (quotes, ``&&``, ``;``, ``|``), hold the word ``stewart-drake``; a word in
front of it (``taskset -c 0``) is the shell's, not run here. A line of output that starts with
the command's name (``stewart-drake calibrate: warning: ...``) is not a command, nor is anything
in a block that shows a transcript (lines after a ``$`` prompt) but the prompted lines. A command
in an indented block is refused: write it in a fenced one, where this test finds it.

The trailing shell comment of a command's (last) line may hold, in clauses separated by ``;``:

- ``short: OPTIONS``: the tests run it with these options (each replacing the same option of the
  command, or added), as a user who wants a quicker try would;
- ``exit N``: the exit status it promises (0 when not said), e.g. ``FAIL, exit 2``;
- ``needs ...``: what it needs that the tests do not have (the robot, a cluster, a live source):
  it is only parsed, and the files it names come from what it needs;
- ``not run by the tests: WHY``: only parsed, for the reason given (many minutes, files of the
  repository rewritten).

The default tier checks that every command parses (with and without its short options) and
names only files that exist: an example, a file of the repository (a path under one of its
folders, from the repository's root) or a file an earlier command of the same block writes. The
slow tier runs each block's runnable commands in order, in process (``main(argv)``), in a fresh
folder holding the examples, and checks each exit status.
"""

from __future__ import annotations

import argparse
import contextlib
import functools
import io
import re
import shlex
import shutil
import time
from dataclasses import dataclass
from pathlib import Path

import pytest

from stewart_drake.cli.main import main
from stewart_drake.cli.registry import build_parser
from stewart_drake.organ_motion.examples import EXAMPLES

REPO = Path(__file__).resolve().parent.parent
#: The repository's folders a command may name a file under (run from the repository's root).
REPOSITORY_FOLDERS = ("scenarios", "stewart_drake")
#: The options whose value a command writes, not reads (their ``dest``).
#: The destinations that name what a command writes (``out_files``: the files it writes under
#: ``--out``, which a command declares before its work).
OUTPUTS = {
    "out",
    "out_files",
    "save_learned",
    "html",
    "docs",
    "bus",
    "save_measurements",
}
_FILE = re.compile(r"\.(csv|txt|yaml|yml|npz|json|lcm|html)$")
_SEPARATORS = {"&&", "||", ";", "|", "&"}


def documents() -> list[Path]:
    return [REPO / "README.md"] + sorted((REPO / "docs").glob("*.md"))


@dataclass(frozen=True)
class DocCommand:
    """A documented command: where it is, its block, its words after ``stewart-drake`` and its
    trailing comment."""

    where: str
    block: str
    argv: tuple
    comment: str
    prefix: tuple = ()
    transcript: bool = False
    #: A shell command that writes a file the block's later commands read (``cp A B``): its
    #: words in ``prefix``, nothing of ours run.
    shell: bool = False

    @property
    def copies_to(self) -> str | None:
        return self.prefix[-1] if self.shell and len(self.prefix) >= 3 else None

    def clause(self, pattern: str) -> re.Match | None:
        for part in self.comment.split(";"):
            match = re.match(pattern, part.strip())
            if match:
                return match
        return None

    @property
    def short(self) -> tuple:
        """The options of ``short:``, as words."""
        match = self.clause(r"short:\s*(.+)$")
        return tuple(shlex.split(match.group(1))) if match else ()

    @property
    def expected_exit(self) -> int:
        match = re.search(r"\bexit (\d+)\b", self.comment)
        return int(match.group(1)) if match else 0

    @property
    def needs(self) -> str | None:
        match = self.clause(r"(.*\bneeds\b.*)$")
        return match.group(1) if match else None

    @property
    def not_run(self) -> str | None:
        """Why it is only parsed (its ``needs`` or ``not run by the tests``), or None."""
        match = self.clause(r"not run by the tests:\s*(.+)$")
        if match:
            return match.group(1)
        if self.transcript:
            return "a transcript of a run, shown with its output"
        return self.needs

    @property
    def text(self) -> str:
        return shlex.join(self.prefix if self.shell else ("stewart-drake", *self.argv))


def split_comment(line: str) -> tuple[str, str]:
    """(code, comment) of a shell line: the comment starts at a ``#`` outside quotes that starts
    a word."""
    quote = None
    for k, c in enumerate(line):
        if quote:
            if c == quote:
                quote = None
        elif c in "'\"":
            quote = c
        elif c == "#" and (k == 0 or line[k - 1].isspace()):
            return line[:k], line[k + 1 :].strip()
    return line, ""


def shell_words(code: str) -> list[str]:
    lexer = shlex.shlex(code, posix=True, punctuation_chars=True)
    lexer.whitespace_split = True
    return list(lexer)


def fenced_blocks(path: Path):
    """(first line's number, [(line number, text)]) of each fenced block of ``path``."""
    block, start = None, 0
    for n, text in enumerate(path.read_text().splitlines(), start=1):
        if text.lstrip().startswith("```"):
            if block is None:
                block, start = [], n
            else:
                yield start, block
                block = None
        elif block is not None:
            block.append((n, text))


def block_commands(rel: str, start: int, lines) -> list[DocCommand]:
    """The commands of one fenced block of the page ``rel``."""
    joined, k = [], 0
    while k < len(lines):
        n, text = lines[k]
        while text.rstrip().endswith("\\") and k + 1 < len(lines):
            k += 1
            text = text.rstrip()[:-1] + " " + lines[k][1].strip()
        joined.append((n, text))
        k += 1
    transcript = any(t.lstrip().startswith("$ ") for _, t in joined)
    found = []
    for n, text in joined:
        if transcript:
            if not text.lstrip().startswith("$ "):
                continue
            text = text.lstrip()[2:]
        code, comment = split_comment(text)
        if "stewart-drake" not in code and not code.lstrip().startswith("cp "):
            continue
        segment: list[str] = []
        for word in shell_words(code) + [";"]:
            if word not in _SEPARATORS:
                segment.append(word)
                continue
            if segment[:1] == ["cp"]:
                found.append(
                    DocCommand(
                        f"{rel}:{n}", f"{rel}:{start}", (), comment, tuple(segment), shell=True
                    )
                )
            elif "stewart-drake" in segment:
                at = segment.index("stewart-drake")
                argv = tuple(segment[at + 1 :])
                if not (argv and argv[0].endswith(":")):  # a line of output
                    found.append(
                        DocCommand(
                            f"{rel}:{n}",
                            f"{rel}:{start}",
                            argv,
                            comment,
                            tuple(segment[:at]),
                            transcript,
                        )
                    )
            segment = []
    return found


def documented_commands(paths=None, shell: bool = False) -> list[DocCommand]:
    """The ``stewart-drake`` commands of the pages, in order; with ``shell`` the shell commands
    that write a file for them too (``cp``)."""
    found = []
    for path in paths or documents():
        rel = str(path.relative_to(REPO))
        for start, lines in fenced_blocks(path):
            found += [c for c in block_commands(rel, start, lines) if shell or not c.shell]
    return found


def indented_commands(paths=None) -> list[str]:
    """Where a command sits in an indented code block (outside a fence), unseen by this test."""
    found = []
    for path in paths or documents():
        fenced = False
        for n, text in enumerate(path.read_text().splitlines(), start=1):
            if text.lstrip().startswith("```"):
                fenced = not fenced
            elif not fenced and re.match(r"( {4,}|\t)(\$ )?stewart-drake\s", text):
                found.append(f"{path.relative_to(REPO)}:{n}")
    return found


def blocks() -> dict[str, list[DocCommand]]:
    grouped: dict[str, list[DocCommand]] = {}
    for command in documented_commands(shell=True):
        grouped.setdefault(command.block, []).append(command)
    return grouped


# -- parsing, and the files a command names ------------------------------------------------------


@functools.cache
def _parser() -> argparse.ArgumentParser:
    return build_parser()


def parse(argv) -> argparse.Namespace | str:
    """The namespace of ``stewart-drake ARGV``, or argparse's refusal (its message)."""
    err = io.StringIO()
    try:
        with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
            return _parser().parse_args(list(argv))
    except SystemExit as exit_:
        if exit_.code == 0 and "--version" in argv:
            return argparse.Namespace(command="--version")
        return err.getvalue().strip() or f"exit {exit_.code}"


def _option_takes_value(command: str, option: str) -> bool:
    """Whether ``option`` of ``command`` (or of one of its own subcommands, ``servo
    identify``'s) takes a value."""
    sub = next(a for a in _parser()._actions if isinstance(a, argparse._SubParsersAction))
    parsers = [sub.choices[command]]
    while parsers:
        parser = parsers.pop()
        if option in parser._option_string_actions:
            return parser._option_string_actions[option].nargs != 0
        parsers += [
            verb
            for a in parser._actions
            if isinstance(a, argparse._SubParsersAction)
            for verb in a.choices.values()
        ]
    raise KeyError(option)


def with_short(command: DocCommand) -> list[str]:
    """The command's words with its short options: each replaces the same option, or is
    added."""
    argv, short = list(command.argv), list(command.short)
    k = 0
    while k < len(short):
        option = short[k].split("=")[0]
        takes = "=" not in short[k] and _option_takes_value(argv[0], option)
        given = short[k : k + 1 + takes]
        kept, j = [], 0
        while j < len(argv):
            word = argv[j]
            if word == option:
                j += 1 + takes
            elif word.startswith(option + "="):
                j += 1
            else:
                kept.append(word)
                j += 1
        argv = kept + given
        k += len(given)
    return argv


def _strings(value) -> list[str]:
    if isinstance(value, str):
        return [value]
    if isinstance(value, (list, tuple)):
        return [v for item in value for v in _strings(item)]
    return []


def named_files(namespace) -> tuple[list[str], list[str]]:
    """(files read, files and folders written) by a parsed command: the values that look like
    files, and those of its outputs (``--out results/cal``: what it writes under it counts)."""
    read, written = [], []
    for dest, value in vars(namespace).items():
        for text in _strings(value):
            if dest in OUTPUTS:
                written.append(text)
            elif _FILE.search(text):
                read.append(text)
    return read, written


def is_repository_file(name: str) -> bool:
    return name.split("/")[0] in REPOSITORY_FOLDERS and (REPO / name).is_file()


# -- the default tier ------------------------------------------------------------------------------


def test_the_documents_hold_commands_and_none_in_an_indented_block():
    commands = documented_commands()
    assert len(commands) > 50 and {c.argv[0] for c in commands if c.argv} >= {
        "run",
        "verify",
        "reproduce",
        "calibrate",
        "examples",
    }
    assert not indented_commands(), "write these in a fenced block: " + ", ".join(
        indented_commands()
    )


def test_every_documented_command_parses():
    refused = []
    for command in documented_commands():
        for argv in {tuple(command.argv), tuple(with_short(command))}:
            parsed = parse(argv)
            if isinstance(parsed, str):
                refused.append(f"{command.where}: {shlex.join(argv)}: {parsed}")
    assert not refused, f"{len(refused)} documented commands do not parse:\n" + "\n".join(refused)


def test_every_file_a_documented_command_names_exists():
    missing = []
    for commands in blocks().values():
        written: set[str] = set()
        for command in commands:
            if command.shell:
                written.add(command.copies_to)
                continue
            parsed = parse(command.argv)
            if isinstance(parsed, str):
                continue  # the test above names it
            read, out = named_files(parsed)
            if command.needs is None:
                missing += [
                    f"{command.where}: {name}"
                    for name in read
                    if name not in EXAMPLES
                    and not is_repository_file(name)
                    and not any(name == w or name.startswith(w.rstrip("/") + "/") for w in written)
                ]
            written |= set(out)
    assert not missing, (
        f"{len(missing)} files named by documented commands are neither an example "
        "(stewart-drake examples), a file of the repository, nor written by an earlier command "
        "of the block:\n" + "\n".join(missing)
    )


def test_every_registration_shown_is_one_the_reader_takes(tmp_path):
    """A REG.yaml shown in a block (one naming ``base_points:``) is whole: the reader that
    ``calibrate --registration`` and ``verify --registration`` use takes it as written."""
    from stewart_drake.calibration.registration_file import read_fiducials

    samples = [
        (f"{path.relative_to(REPO)}:{start}", "\n".join(text for _, text in lines) + "\n")
        for path in documents()
        for start, lines in fenced_blocks(path)
        if any(text.startswith("base_points:") for _, text in lines)
    ]
    assert samples
    for where, text in samples:
        path = tmp_path / "REG.yaml"
        path.write_text(text)
        fiducials = read_fiducials(path)
        assert len(fiducials.base_B) >= 3, where


def test_the_markers_are_read_as_the_docstring_says(tmp_path):
    page = tmp_path / "page.md"
    page.write_text(
        "```bash\n"
        "stewart-drake run --duration 10   # the paper; short: --duration 2\n"
        "stewart-drake verify breathing --measured m.csv \\\n"
        "    --measured-columns '-,t [ms],X [mm]'   # FAIL, exit 2: turned\n"
        "taskset -c 0 stewart-drake run --no-progress && cp a b  # one core\n"
        "stewart-drake robot --emulate     # needs the robot's port\n"
        "stewart-drake calibrate: warning: the poses # output, not a command\n"
        "```\n"
        "```\n$ stewart-drake evaluate --quick\nwrote results/evaluation/results.md\n```\n"
        "    stewart-drake run\n"
    )
    global REPO
    saved, REPO = REPO, tmp_path
    try:
        run, verify, pinned, robot, evaluate = documented_commands([page])
        indented = indented_commands([page])
    finally:
        REPO = saved
    assert run.short == ("--duration", "2") and run.not_run is None
    assert with_short(run) == ["run", "--duration", "2"]
    assert verify.argv[-2:] == ("--measured-columns", "-,t [ms],X [mm]")
    assert verify.expected_exit == 2 and verify.where == "page.md:3"
    assert pinned.prefix == ("taskset", "-c", "0") and pinned.argv == ("run", "--no-progress")
    assert robot.not_run == "needs the robot's port" and robot.needs
    assert evaluate.transcript and evaluate.not_run and evaluate.block == "page.md:9"
    assert indented == ["page.md:13"]


# -- the slow tier: each block run --------------------------------------------------------------


def _runnable_blocks() -> list[str]:
    return [
        name
        for name, commands in blocks().items()
        if any(not c.not_run and not c.shell for c in commands)
    ]


@pytest.mark.slow
@pytest.mark.parametrize("block", _runnable_blocks())
def test_a_documented_block_runs_as_written(block, tmp_path, monkeypatch, capsys):
    """Each runnable command of the block, in order, in a folder holding the examples (and the
    repository's files it names), with its short options: its exit status the one promised."""
    assert main(["examples", str(tmp_path)]) == 0
    monkeypatch.chdir(tmp_path)
    results, wrong = [], []
    for command in blocks()[block]:
        if command.not_run:
            results.append(f"{command.where}: parsed only ({command.not_run}): {command.text}")
            continue
        if stage(command, tmp_path):
            results.append(f"{command.where}: {shlex.join(command.prefix)}")
            continue
        argv = with_short(command)
        capsys.readouterr()
        start = time.monotonic()
        code = exit_status(argv)
        seconds = time.monotonic() - start
        out, err = capsys.readouterr()
        line = f"{command.where}: exit {code} in {seconds:.0f} s: stewart-drake {shlex.join(argv)}"
        results.append(line)
        if code != command.expected_exit:
            tail = "\n".join((out + err).strip().splitlines()[-5:])
            wrong.append(f"{line} (expected {command.expected_exit}):\n{tail}")
    with capsys.disabled():
        print("\n" + "\n".join(results))
    assert not wrong, "\n".join(wrong)


def stage(command: DocCommand, folder: Path) -> bool:
    """Before a runnable command of a block runs in ``folder`` (the current one): a ``cp`` is
    carried out (True: nothing more to run), else the repository's files the command names are
    copied in (False)."""
    if command.shell:  # cp, from the repository's root
        source, target = command.prefix[-2:]
        shutil.copy(REPO / source if is_repository_file(source) else source, target)
        return True
    for name in named_files(parse(command.argv))[0]:
        if is_repository_file(name) and not (folder / name).exists():
            (folder / name).parent.mkdir(parents=True, exist_ok=True)
            shutil.copy(REPO / name, folder / name)
    return False


def exit_status(argv) -> int:
    try:
        return main(list(argv))
    except SystemExit as exit_:  # --version, --help
        return int(exit_.code or 0)
