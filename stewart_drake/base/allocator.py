"""glibc's per-thread cache of freed blocks, sized for a discrete MultibodyPlant's step.

Each step of the plant with SAP builds its problem anew: the SAP model, the constraints'
bundles, the Jacobians and Eigen's temporaries, a few hundred small blocks allocated and freed
every millisecond of simulated time. glibc keeps at most 7 freed blocks of each size in a
thread's cache (``tcache``) by default; the rest go back through the allocator's bins, and
``malloc``/``free`` then take about a third of the station's CPU time (measured with ``perf``
on ``paper_hardware``). With :data:`TCACHE_COUNT` blocks of each size cached they come back from
the thread's cache: the station alone costs 0.73 of the CPU, the closed loop about 0.8, for
about 2 MB more memory (docs/performance.md, "The allocator"). The arithmetic does not change:
every result is bit-identical.

The cache's size is a glibc tunable, read once when a process starts (``GLIBC_TUNABLES``), so
:func:`restart_with_tuned_allocator` starts the ``stewart-drake`` command again with it, before
the command has done anything. Processes the command starts (workers, other commands) inherit
it. A library user sets it before Python starts, e.g.
``GLIBC_TUNABLES=glibc.malloc.tcache_count=256 jupyter lab``. A ``tcache_count`` already in
``GLIBC_TUNABLES`` is the user's choice and stays (``glibc.malloc.tcache_count=7`` is glibc's
default). Elsewhere than glibc (macOS, Windows, musl) nothing is done.

Imports nothing of the package and nothing but the standard library: the command calls it
first.
"""

import os
import signal
import sys
from collections.abc import Mapping

#: Freed blocks of each size a thread keeps (glibc's default: 7). 64 already gives most of the
#: gain and 256 all of it (the closed loop 0.255 -> 0.230 -> 0.212 CPU s per simulated s);
#: 1000 gives nothing more and holds more memory.
TCACHE_COUNT = 256

#: The glibc tunable that sizes the cache.
TCACHE_TUNABLE = "glibc.malloc.tcache_count"


def is_glibc() -> bool:
    """Whether this process's C library is glibc (whose tunables :func:`tuned_environment`
    sets)."""
    try:
        return bool(os.confstr("CS_GNU_LIBC_VERSION"))
    except (ValueError, OSError, AttributeError):
        return False


def tuned_environment(environ: Mapping[str, str]) -> dict[str, str] | None:
    """``environ`` with glibc's thread cache sized to :data:`TCACHE_COUNT` blocks, or None when
    there is nothing to add: the C library is not glibc, or ``GLIBC_TUNABLES`` already sizes
    the cache (the user's value is kept). Other tunables in ``GLIBC_TUNABLES`` are kept.

    Args:
        environ: a process environment (``os.environ``).
    Returns:
        a new dict, or None.
    """
    if not is_glibc():
        return None
    tunables = environ.get("GLIBC_TUNABLES", "")
    if any(item.split("=", 1)[0] == TCACHE_TUNABLE for item in tunables.split(":")):
        return None
    ours = f"{TCACHE_TUNABLE}={TCACHE_COUNT}"
    return {**environ, "GLIBC_TUNABLES": f"{tunables}:{ours}" if tunables else ours}


def _unsafe_to_restart(argv) -> str | None:
    """Why starting ``argv`` (the interpreter's own command line) again would not run the same
    command with the same streams, or None when it would: a standard stream closed (Python
    has no object for it, and the new process would fail on it), or a program that is not a
    file run again from its start (``python -`` reads a script from standard input, which the
    first process consumed; ``-c`` code is not the command)."""
    for number, stream in ((0, sys.stdin), (1, sys.stdout), (2, sys.stderr)):
        try:
            os.fstat(number)
        except OSError:
            return f"its standard {('input', 'output', 'error')[number]} is closed"
        if stream is None:
            return f"its standard {('input', 'output', 'error')[number]} is closed"
    if "-m" in argv:
        module = argv[argv.index("-m") + 1 :][:1]
        return None if module in (["stewart_drake"], ["stewart_drake.cli.main"]) else "-m"
    script = sys.argv[0] if sys.argv else ""
    if script in ("", "-", "-c") or not os.path.isfile(script) or script not in argv:
        return "it was not started from its own script file"
    return None


def restart_with_tuned_allocator() -> None:
    """Replace this process by the same command line with :func:`tuned_environment` (same pid,
    same arguments, same interpreter options), or return when it needs nothing, when that
    would not run the same command (:func:`_unsafe_to_restart`: said in one line on stderr),
    or when the interpreter cannot be found again. Call only at the start of a program's own
    entry point, before it has read input or written anything: nothing of this process
    survives but its pid, its open files and its environment."""
    env = tuned_environment(os.environ)
    argv = list(getattr(sys, "orig_argv", None) or ())
    if env is None or not argv or not sys.executable:
        return
    unsafe = _unsafe_to_restart(argv)
    if unsafe is not None:
        if sys.stderr is not None:
            print(
                f"stewart-drake: runs with glibc's default memory cache ({unsafe}; "
                f"GLIBC_TUNABLES={TCACHE_TUNABLE}={TCACHE_COUNT} in the environment saves about "
                "a fifth of a closed loop's CPU)",
                file=sys.stderr,
                flush=True,
            )
        return
    sys.stdout.flush()
    sys.stderr.flush()
    held = _hold_ctrl_c()
    if held:
        env[_CTRL_C_HELD] = "1"
    try:
        os.execve(sys.executable, argv, env)
    except OSError:
        if held:
            signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGINT})
        return  # the command runs as it is, with glibc's default cache


#: Set in the environment of the process the restart starts when SIGINT is held across it.
_CTRL_C_HELD = "_STEWART_DRAKE_SIGINT_HELD"


def _hold_ctrl_c() -> bool:
    """Block SIGINT for the restart's exec, whether it was blocked before: a blocked signal's
    mask and its pending arrival survive ``execve``, whereas a handler is reset, so a Ctrl-C
    in the window between the exec and the new process's start-up handler would otherwise be
    Python's KeyboardInterrupt traceback (or a kill by the default action). Not where SIGINT
    is ignored, already blocked, or the platform has no signal mask."""
    if not hasattr(signal, "pthread_sigmask") or signal.getsignal(signal.SIGINT) is signal.SIG_IGN:
        return False
    return signal.SIGINT not in signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})


def release_held_ctrl_c() -> None:
    """In the process a restart started, unblock the SIGINT it held (:func:`_hold_ctrl_c`):
    one that arrived meanwhile is delivered now, to the handler installed by then. Does
    nothing in any other process, whose mask is its parent's choice."""
    if os.environ.pop(_CTRL_C_HELD, None) is not None and hasattr(signal, "pthread_sigmask"):
        signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGINT})
