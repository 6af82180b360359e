"""stewart-drake: a 6-DOF rotary Stewart platform on a Drake closed-chain MultibodyPlant.

A small core by Drake role, imports flowing one way (a test walks them): base -> robot -> plant
-> control -> references -> station -> run -> execution; then the features, each a package with
its own command: viz, paper, analysis, organ_motion, tuner, evaluation, design, live; the
``stewart-drake`` command (cli) on top. docs/development.md has the tree.
"""

import os as _os
import signal as _signal
import sys as _sys


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


def _started_as_the_command() -> bool:
    """Whether this process is the ``stewart-drake`` console script, called by its name or
    through a link to it (or the CLI module run with ``python -m``): a library user's handler
    of SIGINT is never touched."""
    script = _sys.argv[0] if _sys.argv else ""
    names = {_os.path.basename(script), _os.path.basename(_os.path.realpath(script))}
    return bool(names & {"stewart-drake", "stewart-drake.exe"}) or (
        "stewart_drake.cli.main" in getattr(_sys, "orig_argv", ())[:4]
    )


# Only over Python's own handler: a command started with SIGINT ignored (in a script's
# background) keeps it ignored. The CLI's main() puts Python's handler back. Before the restart
# below, so that a Ctrl-C in its window is one line too.
if _started_as_the_command() and _signal.getsignal(_signal.SIGINT) is _signal.default_int_handler:
    _signal.signal(_signal.SIGINT, _interrupted_while_starting)

# The command starts itself again with glibc's thread cache sized for the plant's step (its
# CPU, not its results), before anything else: base.allocator imports only the standard library.
# A Ctrl-C that arrived while the restart held it reaches the handler above here.
if _started_as_the_command():
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
