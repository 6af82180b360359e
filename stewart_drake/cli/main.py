"""The ``stewart-drake`` command: run the paper's experiment, sweep the workspace, and more.

Each subcommand parses its arguments in its feature's command module (``<feature>/command.py``,
listed by :mod:`~stewart_drake.cli.registry`) and calls the functions of the modules that own the
idea (imported when the subcommand runs, so `stewart-drake sdf` does not pay for torch or the
Simulator). Here: :func:`main`, which turns what goes wrong into a one-line message and a non-zero
exit, no traceback: exit 2 for bad arguments and StewartError (refused input, a diverged run, a
results folder of other settings or in use by another study, lost jobs), 1 for a file that cannot be
read or written, 130 for Ctrl-C, 143 for SIGTERM, 129 for SIGHUP and 131 for SIGQUIT (Ctrl-\\; 128 +
the signal: every command handles the four alike, within a second or two). Every output (folder,
file, the sub-folders a command writes into) is checked before any work starts
(:func:`~stewart_drake.execution.options.check_outputs`), so a long run never ends in a failed save,
a device node, FIFO or socket is never replaced, and no output is one of the command's own inputs
(:func:`~stewart_drake.base.fileio.inputs_kept`); the hidden temporaries a killed write left there
(the tool's own, whose writer is gone) are removed.
"""

from __future__ import annotations

import contextlib
import os
import signal
import sys
import threading
from pathlib import Path

from ..base.errors import StewartError
from ..execution.options import (
    check_input_names,
    check_outputs,
    command_inputs,
    compile_note,
    say_starting,
)

#: Subcommands whose finished jobs are on disk as they arrive (run again: only the rest runs),
#: with the folder under ``--out`` that keeps them.
RESUMABLE = {"collect": "", "evaluate": "", "design": "search"}


def _interruptible():
    """Make SIGTERM, SIGHUP and SIGQUIT raise
    :class:`~stewart_drake.execution.runners.Interrupted` (a
    KeyboardInterrupt, as Ctrl-C) in the main thread while a command runs, and Ctrl-C its
    KeyboardInterrupt, each noted (:func:`~stewart_drake.execution.runners.interrupt_raised`:
    one that code swallows still stops the command before a robot is powered); returns the
    handlers to restore. A signal the process was started ignoring (``nohup``) stays ignored,
    and a SIGINT handler other than Python's is kept."""
    from ..execution.runners import (
        CANCEL_SIGNALS,
        forget_interrupts,
        raise_interrupted,
        raise_keyboard_interrupt,
    )

    forget_interrupts()
    if threading.current_thread() is not threading.main_thread():
        return {}
    handlers = {
        s: signal.signal(s, raise_interrupted)
        for s in CANCEL_SIGNALS
        if s != signal.SIGINT and signal.getsignal(s) is not signal.SIG_IGN
    }
    if signal.getsignal(signal.SIGINT) is signal.default_int_handler:
        handlers[signal.SIGINT] = signal.signal(signal.SIGINT, raise_keyboard_interrupt)
    return handlers


def _command_named(argv: list[str] | None) -> str | None:
    """The subcommand ``argv`` names (its first word that is not an option), before it is
    parsed; None when there is none."""
    words = sys.argv[1:] if argv is None else argv
    return next((w for w in words if not w.startswith("-")), None)


def main(argv: list[str] | None = None) -> int:
    from .. import _interrupted_while_starting, _started_as_the_command

    starting = signal.getsignal(signal.SIGINT) is _interrupted_while_starting
    # The process of the command (the console script, `python -m`), not a library's call: its
    # first line says what it does first, before the seconds of Drake's imports.
    own = _started_as_the_command()
    try:
        if own:
            say_starting(_command_named(argv))
        # From here a Ctrl-C is a KeyboardInterrupt that each stage below turns into one line.
        if starting:
            signal.signal(signal.SIGINT, signal.default_int_handler)
        restore = _interruptible()
    except KeyboardInterrupt as err:
        return _interrupted(err, "", None)
    try:
        return _main(argv, own)
    finally:
        for signum, handler in restore.items():
            signal.signal(signum, handler)
        if starting:  # the console script's last lines and the interpreter's exit: one line too
            signal.signal(signal.SIGINT, _interrupted_while_starting)
        from ..execution.runners import forget_interrupts

        forget_interrupts()


@contextlib.contextmanager
def _signals_held():
    """Hold the terminal's signals (SIGINT, SIGTERM, SIGHUP, SIGQUIT) while the block runs, then
    pass a held one to its handler (a KeyboardInterrupt, handled as any). For the imports that
    initialize Drake's extension modules: a signal that lands inside pydrake's own initialization
    makes it print a C++ log with a stack dump before our one line, and one inside a nanobind
    module's import (Drake's ``systems.framework`` creating an enum) aborts the process (SIGABRT).
    Held by Python handlers that only note the signal (blocking it would not do: numpy's threads,
    already started, would take it). Outside the main thread it holds nothing."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    noted: list[int] = []
    from ..execution.runners import CANCEL_SIGNALS

    handlers = {s: signal.getsignal(s) for s in CANCEL_SIGNALS}
    held = {s: h for s, h in handlers.items() if callable(h)}  # not SIG_IGN, SIG_DFL, None
    for signum in held:
        signal.signal(signum, lambda signum, frame: noted.append(signum))
    try:
        yield
    finally:
        for signum, handler in held.items():
            signal.signal(signum, handler)
    if noted:
        held[signal.Signals(noted[0])](noted[0], None)


def _build_parser():
    """The command line's parser (:func:`~.registry.build_parser`), built with the signals held
    (:func:`_signals_held`): building it imports pydrake and the commands' modules, Drake's
    extension modules among them (about a second)."""
    with _signals_held():
        import pydrake.systems.framework  # noqa: F401 - the nanobind module every command uses

        from .registry import build_parser

        return build_parser()


def _main(argv: list[str] | None, own: bool = False) -> int:
    """Parse ``argv`` and run its command (:func:`main`); ``own``: in the command's process,
    whose compilations are said as they start
    (:func:`~stewart_drake.base.compiled.announce_compiles`)."""
    try:
        parser = _build_parser()
        args = parser.parse_args(argv)
    except KeyboardInterrupt as err:
        return _interrupted(err, "", None)
    except (ImportError, MemoryError) as err:
        if _out_of_memory(err):
            return _no_memory("")
        if not _interrupted_import(err):
            raise
        return _interrupted(KeyboardInterrupt(), "", None)
    try:
        from ..base.fileio import inputs_kept

        # What the command reads is kept from what it writes, from its first check to its end.
        inputs = command_inputs(args)
        check_input_names(inputs)
        with inputs_kept(inputs):
            check_outputs(args)
            if not own:
                return int(args.func(args) or 0)
            from ..base.compiled import announce_compiles

            with announce_compiles(compile_note(args.command)):
                return int(args.func(args) or 0)
    except StewartError as err:
        print(f"stewart-drake {args.command}: {err}", file=sys.stderr)
        return 2
    except BrokenPipeError:  # the reader went away (`... | head`): stop without a word
        _silence_stdout()
        return 128 + signal.SIGPIPE
    except OSError as err:  # disk full, file vanished, permissions
        print(f"stewart-drake {args.command}: {err}", file=sys.stderr)
        return 1
    except KeyboardInterrupt as err:  # Ctrl-C, SIGTERM, SIGHUP, SIGQUIT
        return _interrupted(err, args.command, getattr(args, "out", None))
    except (ImportError, MemoryError) as err:  # a Ctrl-C while imports initialize pydrake
        if _out_of_memory(err):
            return _no_memory(args.command)
        if not _interrupted_import(err):
            raise
        return _interrupted(KeyboardInterrupt(), args.command, getattr(args, "out", None))
    except SystemExit as err:  # code the command ran (a plug-in's controller) asked to exit
        plugins = ", ".join(getattr(args, "plugin", None) or ())
        print(
            f"stewart-drake {args.command}: stopped by SystemExit({err.code!r}) raised in code "
            f"it ran ({f'the plug-in {plugins}' if plugins else 'a controller or plug-in'}), "
            f"before the command finished; partial outputs were not written: fix that code",
            file=sys.stderr,
        )
        return 2
    except SystemError as err:  # a signal inside compiled code (numba's dispatcher wraps it)
        from ..execution.runners import interrupt_in

        interrupt = interrupt_in(err)
        if interrupt is None:
            raise
        return _interrupted(interrupt, args.command, getattr(args, "out", None))


def _out_of_memory(err: BaseException) -> bool:
    """Whether ``err`` is, or was caused by, a MemoryError (an extension module that could not
    allocate while it initialized reports "initialization failed" around it) or a shared
    library the loader could not map, searched as :func:`_interrupted_import` searches."""
    link: BaseException | None = err
    for _ in range(20):
        if link is None or isinstance(link, KeyboardInterrupt):
            return False
        if isinstance(link, MemoryError) or (
            isinstance(link, ImportError) and any(m in str(link) for m in _NO_MAP)
        ):
            return True
        link = link.__cause__ or link.__context__
    return False


#: What the dynamic loader says of a library it could not map for want of memory.
_NO_MAP = ("failed to map segment", "cannot allocate memory", "Cannot allocate memory")


def _no_memory(command: str) -> int:
    """One line for a command that ran out of memory where no estimate refused it first; 1."""
    name = f"stewart-drake {command}" if command else "stewart-drake"
    print(
        f"{name}: out of memory (the machine's, a container's or `ulimit -v`); partial outputs "
        "were not written: free some memory, raise the limit, or give a smaller input",
        file=sys.stderr,
    )
    return 1


def _interrupted_import(err: BaseException) -> bool:
    """Whether ``err`` is a Ctrl-C that landed while an extension module initialized: pydrake's
    and matplotlib's modules turn it into an ImportError ("initialization failed", or "Encountered
    an error while initializing the extension" around it), the KeyboardInterrupt kept as a cause
    or context somewhere down the chain, which is searched (at most 20 links)."""
    link: BaseException | None = err
    for _ in range(20):
        if link is None:
            return False
        if isinstance(link, KeyboardInterrupt) or "initialization failed" in str(link):
            return True
        link = link.__cause__ or link.__context__
    return False


def _silence_stdout() -> None:
    """Point standard output at the null device, so that the interpreter's last flush does not
    fail again on the closed pipe (Python's documentation on SIGPIPE)."""
    try:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
    except (OSError, ValueError, AttributeError):  # not a file descriptor (a test's capture)
        pass


def _interrupted(err: KeyboardInterrupt, command: str, out) -> int:
    """Say which signal ended ``command`` (one line) and return 128 + its number."""
    signum = getattr(err, "signum", signal.SIGINT)
    kept = (
        f"finished {'generations' if command == 'design' else 'results'} are kept in "
        f"{Path(out, RESUMABLE[command]) if RESUMABLE[command] else out}: run the same command "
        f"again to run only the rest"
        if command in RESUMABLE and out is not None
        else "partial outputs were not written"
    )
    name = f"stewart-drake {command}".rstrip()
    print(f"{name}: interrupted by {signal.Signals(signum).name}; {kept}", file=sys.stderr)
    return 128 + signum


if __name__ == "__main__":
    sys.exit(main())
