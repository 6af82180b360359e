"""Checks of user input, shared by every public entry point: typed errors, never NaN out.

The rule: a public function given a NaN, an inf, a wrong shape or a non-number raises a
:class:`~stewart_drake.base.errors.StewartError` that names the argument and says what to change; it
never returns NaN and never lets numpy's own ``ValueError``/``TypeError`` escape. The checks are
one ``np.isfinite(...).all()`` per array, so vectorized paths stay fast.

This module sits below every layer (it imports only :mod:`~stewart_drake.base.errors`); the
validation of a whole scenario lives beside the scenario's classes.
"""

from __future__ import annotations

import os

import numpy as np

from .errors import InvalidConfigError

#: Largest |position| accepted in a pose, m: a kilometre is far outside any Stewart platform and
#: keeps squared lengths (|l|^2 in the closed-form IK) far from overflow.
MAX_POSITION_M = 1e3
#: Largest seed of a random draw, Drake's RandomSource's included (a 32-bit unsigned integer).
MAX_SEED = 2**32 - 1


def as_array(
    name: str, value, shape: tuple | None = None, last: int | None = None, error=InvalidConfigError
) -> np.ndarray:
    """``value`` as a finite float64 array, or a typed error naming ``name``.

    Args:
        name: what the caller calls the argument (used in the message).
        value: anything ``np.asarray(value, dtype=float)`` accepts.
        shape: exact shape required, or None.
        last: size of the last axis required (batches ``(..., last)``), or None.
        error: the :class:`~stewart_drake.base.errors.StewartError` subclass to raise.
    Returns:
        the array (a view when ``value`` already is a float64 array).
    Raises:
        error: not numbers, a wrong shape, or a NaN/inf (first bad index named).
    """
    try:
        a = np.asarray(value, dtype=float)
    except (TypeError, ValueError) as err:
        raise error(f"{name} must be numbers, got {value!r:.80} ({err})") from None
    if shape is not None and a.shape != tuple(shape):
        raise error(f"{name} must have shape {tuple(shape)}, got {a.shape}")
    if last is not None and (a.ndim < 1 or a.shape[-1] != last):
        raise error(f"{name} must have shape (..., {last}), got {a.shape}")
    if not np.isfinite(a).all():
        bad = tuple(int(i) for i in np.argwhere(~np.isfinite(a))[0])
        raise error(
            f"{name} has a non-finite value {a[bad] if bad else a} at index {bad}; "
            f"give finite numbers"
        )
    return a


def as_poses(name: str, x) -> np.ndarray:
    """Poses (6,) or (..., 6) [phi, theta, psi, X, Y, Z] in rad and m, finite, |X|,|Y|,|Z| <= 1 km.

    Raises:
        InvalidConfigError: not (..., 6), non-finite, or a position beyond MAX_POSITION_M.
    """
    a = as_array(name, x, last=6)
    if a.size and np.abs(a[..., 3:]).max() > MAX_POSITION_M:
        raise InvalidConfigError(
            f"{name} has a position beyond {MAX_POSITION_M:g} m "
            f"(max |X|, |Y|, |Z| = {np.abs(a[..., 3:]).max():.3g} m); "
            f"poses are in m, not mm"
        )
    return a


def as_number(
    name: str,
    value,
    lo: float | None = None,
    hi: float | None = None,
    lo_open: bool = False,
    error=InvalidConfigError,
) -> float:
    """``value`` as a finite float in [lo, hi] ((lo, hi] with ``lo_open``), or a typed error.

    Raises:
        error: not a real number (bool is refused too), not finite, or out of range.
    """
    if isinstance(value, (bool, np.bool_)) or not np.isscalar(value) and np.ndim(value) != 0:
        raise error(f"{name} must be one number, got {value!r:.80}")
    if isinstance(value, (str, bytes)):
        raise error(f"{name} must be a number, got {value!r:.80} (a string)")
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise error(f"{name} must be a number, got {value!r:.80}") from None
    below = lo is not None and (v <= lo if lo_open else v < lo)
    if not np.isfinite(v) or below or (hi is not None and v > hi):
        lo_text = "-inf" if lo is None else f"{lo:g}"
        hi_text = "inf" if hi is None else f"{hi:g}"
        raise error(
            f"{name} must be a finite number in {'(' if lo_open else '['}{lo_text}, "
            f"{hi_text}], got {value!r:.80}"
        )
    return v


def check_int(name: str, value, lo: int, hi: int | None = None, why: str = "") -> int:
    """``value`` as an int in [lo, hi], or a typed error naming ``name``: the one check of an
    integer setting (a count, a seed, a number of periods).

    Args:
        name: what the caller calls the argument, e.g. the field path ``reference.seed``.
        value: a Python or numpy integer (a bool or a float is refused, even 3.0).
        lo, hi: the bounds, inclusive; ``hi`` None: no upper bound.
        why: said in brackets after the bound, e.g. "a grid through the home pose".
    Returns:
        ``int(value)``.
    Raises:
        InvalidConfigError: not an integer, or outside [lo, hi] (both named in the message:
            "must be an integer in [lo, hi]", or ">= lo" without ``hi``).
    """
    if (
        isinstance(value, bool)
        or not isinstance(value, (int, np.integer))
        or value < lo
        or (hi is not None and value > hi)
    ):
        bound = f">= {lo}" if hi is None else f"in [{lo}, {hi}]"
        raise InvalidConfigError(
            f"{name} must be an integer {bound}{f' ({why})' if why else ''}, got {value!r}"
        )
    return int(value)


def check_multiple(name: str, period_s: float, base_name: str, base_s: float) -> int:
    """How many ``base_s`` steps make ``period_s``; a typed error if it is not a finite number
    > 0 or not a whole multiple: the one check of a period run on another's grid.

    Returns:
        the integer ratio, >= 1.
    Raises:
        InvalidConfigError: the period is not a finite number > 0 (:func:`as_number`), or not a
            whole multiple of the base (1e-6 relative slack), with the nearest valid value in the
            message.
    """
    period_s = as_number(name, period_s, 0.0, lo_open=True)
    ratio = period_s / base_s
    n = int(round(ratio)) if 0 < ratio < 1e12 else 0  # 1e12 steps: far past any run
    if n < 1 or abs(ratio - n) > 1e-6 * max(1.0, ratio):
        nearest = max(n, 1) * base_s
        raise InvalidConfigError(
            f"{name} ({period_s:g} s) must be a whole multiple of {base_name} "
            f"({base_s:g} s); the nearest valid value is {nearest:g} s"
        )
    return n


def _address_space_room() -> float | None:
    """Bytes this process may still map under its address-space limit (``ulimit -v``,
    ``RLIMIT_AS``): the limit less what it maps now; None without a limit."""
    try:
        import resource

        soft = resource.getrlimit(resource.RLIMIT_AS)[0]
        if soft == resource.RLIM_INFINITY:
            return None
        with open("/proc/self/statm") as f:
            mapped = float(f.read().split()[0]) * os.sysconf("SC_PAGE_SIZE")
    except (ImportError, OSError, ValueError, IndexError, AttributeError):
        return None
    return max(float(soft) - mapped, 0.0)


def available_memory_bytes() -> float | None:
    """Memory this process may still take, bytes: the kernel's MemAvailable, capped by a cgroup
    limit (containers, CI) and by the process's address-space limit (``ulimit -v``); None where
    none can be read (the check is then skipped)."""
    available = _address_space_room()
    free = None
    try:
        with open("/proc/meminfo") as f:
            for line in f:
                if line.startswith("MemAvailable:"):
                    free = float(line.split()[1]) * 1024
                    break
    except (OSError, ValueError, IndexError):
        pass
    if free is None:
        try:
            free = float(os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE"))
        except (AttributeError, ValueError, OSError):
            pass
    if free is not None:
        available = free if available is None else min(available, free)
    for limit_file, used_file in (
        ("/sys/fs/cgroup/memory.max", "/sys/fs/cgroup/memory.current"),
        (
            "/sys/fs/cgroup/memory/memory.limit_in_bytes",
            "/sys/fs/cgroup/memory/memory.usage_in_bytes",
        ),
    ):
        try:
            with open(limit_file) as f, open(used_file) as g:
                room = float(f.read().strip()) - float(g.read().strip())
        except (OSError, ValueError):
            continue
        available = room if available is None else min(available, room)
        break
    return available


def undecoded_byte(character: str) -> str:
    """The byte a lone surrogate stands for, as text ("0xE9"): Python reads each byte of a file
    name or an argument that is not UTF-8 as U+DC80-U+DCFF; any other surrogate as its code
    point ("U+D800")."""
    code = ord(character)
    return f"0x{code - 0xDC00:02X}" if 0xDC80 <= code <= 0xDCFF else f"U+{code:04X}"


def format_bytes(n_bytes: float) -> str:
    """``n_bytes`` for messages: "4.2 GB", "12 kB", "1e+20 bytes"."""
    if n_bytes >= 1e18:
        return f"{n_bytes:.3g} bytes"
    for unit, scale in (("PB", 1e15), ("TB", 1e12), ("GB", 1e9), ("MB", 1e6)):
        if n_bytes >= scale:
            return f"{n_bytes / scale:.3g} {unit}"
    return f"{n_bytes / 1e3:.3g} kB"


def check_memory(what: str, need_bytes: float, change: str) -> None:
    """Refuse a request whose estimated memory exceeds what the machine has available.

    Args:
        what: the request, e.g. "a run of 1e+05 s logged every 0.001 s".
        need_bytes: its estimate, bytes (inf and huge values allowed).
        change: what to change, e.g. "shorten --duration".
    Raises:
        InvalidConfigError: one line with the estimate, what is available and ``change``.
    """
    available = available_memory_bytes()
    if available is not None and not need_bytes <= available:
        need = (
            f"about {format_bytes(need_bytes)} of memory needed, more than"
            if np.isfinite(need_bytes)
            else "more memory needed than any machine has, and than"
        )
        raise InvalidConfigError(
            f"{what}: {need} the {format_bytes(available)} available on this machine; {change}"
        )
