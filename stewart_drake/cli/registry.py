"""The ``stewart-drake`` command's registry: the modules that add its subcommands, in the order
``stewart-drake --help`` lists them, and the parser built from them.

Each module's ``register(subparsers)`` adds its commands' parsers, with the function that runs
each (``set_defaults(func=...)``) and, when the command writes a file or sub-folders, what
:func:`~stewart_drake.cli.main.main` checks of ``--out`` first (``out_is_file``, ``out_sub``).
A command module imports what its command needs when the command runs, so building the parser
(and ``--help``) loads no torch, no Simulator. The options they share are
:mod:`stewart_drake.execution.options`, below the features.
"""

from __future__ import annotations

import argparse
import sys

from ..actuator import command as actuator_command
from ..analysis import command as analysis_command
from ..design import command as design_command
from ..evaluation import command as evaluation_command
from ..live import calibrate_command
from ..live import command as live_command
from ..organ_motion import command as organ_motion_command
from ..paper import command as paper_command
from ..tuner import command as tuner_command
from ..verification import pair_command
from ..viz import command as viz_command
from . import core

#: The command modules, in the order of the help: the paper's run first, the core's files last.
COMMANDS = (
    paper_command,  # run
    analysis_command,  # check, workspace, analyze
    organ_motion_command,  # reproduce, examples
    tuner_command,  # collect, train
    evaluation_command,  # evaluate
    design_command,  # design
    live_command,  # teleop, robot
    pair_command,  # verify, alone or with its surrogate
    calibrate_command,  # calibrate
    actuator_command,  # servo identify, servo replay
    viz_command,  # diagrams
    core,  # scenario, sdf, mjcf
)


class _HelpFormatter(argparse.HelpFormatter):
    """Every option's help ends with its default, ``(default: ...)``, unless it says its default
    itself (an option whose default is None says what applies then, e.g. "the scenario's")."""

    def _get_help_string(self, action):
        text = action.help or ""
        if (
            "default" in text
            or any(action.default is v for v in (None, False, argparse.SUPPRESS))
            or not action.option_strings
        ):
            return text
        return text + " (default: %(default)s)"


class _Parser(argparse.ArgumentParser):
    """argparse with a one-line error (argparse prints the usage block first) and the defaults
    in the help (:class:`_HelpFormatter`)."""

    def __init__(self, *args, **kwargs):
        kwargs.setdefault("formatter_class", _HelpFormatter)
        super().__init__(*args, **kwargs)

    def error(self, message: str):
        self.exit(2, f"{self.prog}: error: {message} (see {self.prog} --help)\n")

    def parse_args(self, args=None, namespace=None):
        """argparse's, with an option the command does not take refused by that command's
        parser ("stewart-drake check: error: unrecognized arguments: --x (see stewart-drake
        check --help)") instead of the top one's, whose help does not list it."""
        parsed, extras = self.parse_known_args(args, namespace)
        if extras:
            commands = [a for a in self._actions if isinstance(a, argparse._SubParsersAction)]
            command = getattr(parsed, "command", None)
            owner = commands[0].choices.get(command, self) if commands and command else self
            owner.error(f"unrecognized arguments: {' '.join(extras)}")
        return parsed


def version_text() -> str:
    """``stewart-drake --version``: this package's, Drake's and Python's versions."""
    from importlib.metadata import PackageNotFoundError, version

    from .. import __version__

    try:
        drake = version("drake")
    except PackageNotFoundError:  # a Drake built from source
        drake = "not from pip"
    return (
        f"stewart-drake {__version__} (drake {drake}, Python "
        f"{'.'.join(map(str, sys.version_info[:3]))})"
    )


def build_parser() -> argparse.ArgumentParser:
    """The ``stewart-drake`` parser: one sub-parser per command, added by the ``register`` of
    each module of :data:`COMMANDS`."""
    from .. import __doc__ as summary

    parser = _Parser(
        prog="stewart-drake",
        description=summary.splitlines()[0] + " Run `stewart-drake COMMAND --help` for a "
        "command's options.",
    )
    parser.add_argument("--version", action="version", version=version_text())
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for module in COMMANDS:
        module.register(sub)
    return parser
