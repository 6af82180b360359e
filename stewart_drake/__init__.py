"""stewart-drake: a 6-DOF rotary Stewart platform on a Drake closed-chain MultibodyPlant.

A small core by Drake role, imports flowing one way (a test walks them): base -> robot -> plant
-> control -> references -> station -> run -> execution; then the features, each a package with
its own command: viz, paper, analysis, organ_motion, tuner, evaluation, design, live; the
``stewart-drake`` command (cli) on top. docs/development.md has the tree.
"""

# The command's Ctrl-C is held from this package's first statement: ``_signal`` is the
# interpreter's own C module (importing it runs no Python code), and a SIGINT that arrives while
# the lines below decide whether this process is the command is noted, then handled as the
# command's (one line, 130) or passed to Python's handler as it would have been (a
# KeyboardInterrupt in the importing program's code).
import _signal  # type: ignore[import-not-found]  # no stub; the C module behind signal

_NOTED: list = []


def _note_ctrl_c(signum, frame):
    _NOTED.append(signum)


_HELD = _signal.getsignal(_signal.SIGINT) is _signal.default_int_handler
if _HELD:
    try:
        _signal.signal(_signal.SIGINT, _note_ctrl_c)
    except ValueError:  # imported outside the main thread: no handler can be set there
        _HELD = False

import os as _os  # noqa: E402
import sys as _sys  # noqa: E402


def _interrupted_while_starting(signum, frame):
    """SIGINT while the ``stewart-drake`` command imports this package and its own module,
    before its ``main`` can handle Ctrl-C: one line and 130, as any interrupted command, not
    a KeyboardInterrupt traceback. The process ends here (``os._exit``): an exception raised
    while an extension module initializes (numpy's imports the ``datetime`` module from C) is
    turned into that module's ImportError, with its traceback, and nothing has been written
    yet that an orderly exit would finish."""
    line = "stewart-drake: interrupted by SIGINT; partial outputs were not written"
    print(line, file=_sys.stderr)
    _sys.stderr.flush()
    _os._exit(128 + signum)


#: The command's names, and the modules ``python -m`` runs it as.
_COMMAND_NAMES = ("stewart-drake", "stewart-drake.exe")
_COMMAND_MODULES = ("stewart_drake", "stewart_drake.cli.main")
#: The interpreter's options that take the next argument as their value.
_OPTIONS_WITH_VALUES = ("-X", "-W", "--check-hash-based-pycs")


def _started_as_the_command() -> bool:
    """Whether this process is the ``stewart-drake`` command: its console script called by its
    name, by a relative or absolute path, or through a link to it (``sys.argv[0]``, resolved),
    or ``python -m stewart_drake`` (or ``-m stewart_drake.cli.main``). A program that only
    imports the package (a library user, a notebook, pytest) is not, and its handler of SIGINT
    is never touched."""
    argv = list(getattr(_sys, "orig_argv", None) or ())
    k = 1
    while k < len(argv):  # the interpreter's options, up to the program they run
        arg = argv[k]
        if arg == "-m" or (arg.startswith("-m") and not arg.startswith("--")):
            module = argv[k + 1] if arg == "-m" and k + 1 < len(argv) else arg[2:]
            return module in _COMMAND_MODULES
        if arg in ("-c", "-", "--") or not arg.startswith("-"):
            break
        k += 2 if arg in _OPTIONS_WITH_VALUES else 1
    script = _sys.argv[0] if _sys.argv else ""
    if not script or script.startswith("-"):
        return False
    if _os.path.basename(script) in _COMMAND_NAMES:
        return True
    try:
        return _os.path.basename(_os.path.realpath(script)) in _COMMAND_NAMES
    except (OSError, ValueError):
        return False


# Only over Python's own handler: a command started with SIGINT ignored (in a script's
# background) keeps it ignored. The CLI's main() puts Python's handler back. Before the restart
# below, so that a Ctrl-C in its window is one line too.
_COMMAND = _started_as_the_command()
if _HELD:
    if _COMMAND:
        _signal.signal(_signal.SIGINT, _interrupted_while_starting)
        if _NOTED:
            _interrupted_while_starting(_NOTED[0], None)
    else:
        _signal.signal(_signal.SIGINT, _signal.default_int_handler)
        if _NOTED:
            _signal.default_int_handler(_NOTED[0], None)  # raises KeyboardInterrupt, as it would

# The command starts itself again with glibc's thread cache sized for the plant's step (its
# CPU, not its results), before anything else: base.allocator imports only the standard library.
# A Ctrl-C that arrived while the restart held it reaches the handler above here.
if _COMMAND:
    from .base.allocator import release_held_ctrl_c, restart_with_tuned_allocator

    release_held_ctrl_c()
    restart_with_tuned_allocator()

# After the handler above: its window is these imports.
from .base.errors import (  # noqa: E402
    ForwardKinematicsError,
    InvalidConfigError,
    InvalidGeometryError,
    RiccatiSolveError,
    SimulationDivergedError,
    StewartError,
    UnreachablePoseError,
)
from .robot.geometry import X_HOME, StewartGeometry, reference_geometry  # noqa: E402

__all__ = [
    "ForwardKinematicsError",
    "InvalidConfigError",
    "InvalidGeometryError",
    "RiccatiSolveError",
    "SimulationDivergedError",
    "StewartError",
    "UnreachablePoseError",
    "StewartGeometry",
    "X_HOME",
    "reference_geometry",
]
__version__ = "0.1.0"
