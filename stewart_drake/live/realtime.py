"""What the control loop asks of the operating system: a real-time priority, a core, locked memory.

:class:`RealtimeLoop` is entered in the thread that runs the control loop. It asks, each on its
own and each refusal said once:

1. the SCHED_FIFO policy at :data:`PRIORITY` (``os.sched_setscheduler``): no process of the
   normal policy (a tracker's software, a viewer, a browser, a compiler) preempts the loop, and
   the loop always sleeps to its next period, so it holds its core only for its own work
   (Linux keeps 5 % of each second for the rest: ``/proc/sys/kernel/sched_rt_runtime_us``);
2. one core to itself (``os.sched_setaffinity``): :func:`loop_core`, the last core the process
   may use, so that the loop is not moved between cores (cold caches) and leaves the others to
   the rest;
3. its memory locked (``mlockall(MCL_CURRENT | MCL_FUTURE | MCL_ONFAULT)``): no page of the
   loop is paged out and faulted back in mid-period; asked only where the lock is unlimited
   (root, or ``ulimit -l unlimited``): under a finite limit a growing process would have its
   allocations refused mid-run;
4. Python's cyclic garbage collector out of the periods: what exists is collected once and
   frozen (``gc.freeze``: never scanned again), automatic collection is off, and
   :meth:`RealtimeLoop.collect` (the driver calls it before it sleeps to a period) collects
   the young generations when they are as full as Python's own thresholds would allow;
5. the cores' idle states held shallow (a PM QoS request of :data:`IDLE_LATENCY_US` written to
   :data:`PM_QOS_DEVICE`, kept while the file is open, as ``cyclictest`` asks): a core the loop
   slept on is not put into a deep idle state (on a virtual machine, its virtual core handed
   back to the host) from which it wakes slowly and with its caches cold. On this project's
   2-core virtual machine it cut the loop's CPU time a period by a quarter (1.0-1.1 to
   0.7-0.9 ms on ``benchmarks/robot_loop.py``, the same half hour). The machine draws more
   power while the loop runs; the request ends when the loop does.

Everything is given back on exit (the policy, the cores, the memory lock, the collector), so a
process that runs several sessions (a test suite) is left as it was. Where the OS refuses (no
privilege, not Linux), ``RealtimeLoop.refusals`` says what was not granted and how to grant
it, and :meth:`RealtimeLoop.line` is the one line the session prints; the run goes on.
docs/hardware_bus.md, "Timing"; docs/robot.md, "What to ask of a robot's computer".
"""

from __future__ import annotations

import ctypes
import ctypes.util
import functools
import gc
import os
import resource
import struct
import sys

#: The loop's SCHED_FIFO priority (1..99): ``chrt -f 50``'s, the middle of the range, below the
#: kernel's own per-core threads (migration, watchdog: 99). Our watchdog's thread runs one above
#: it, so that a loop that stopped sleeping cannot keep it from removing the torque.
PRIORITY = 50

_MCL_CURRENT, _MCL_FUTURE, _MCL_ONFAULT = 1, 2, 4

#: Linux's PM QoS device for the CPUs' wake-up latency (Documentation/power/pm_qos_interface):
#: a process that writes a 32-bit latency to it (us) keeps every core out of idle states slower
#: to wake than that, for as long as it holds the file open; read, it gives the latency in force.
PM_QOS_DEVICE = "/dev/cpu_dma_latency"

#: The wake-up latency the loop asks for, us: 0, the shallowest idle state (polling).
IDLE_LATENCY_US = 0

#: How to grant each thing the loop asks for, said with its refusal.
HOW_TO_GRANT = {
    "priority": "run as root, or give the user a real-time limit (`ulimit -r {priority}`; "
    "/etc/security/limits.conf: `USER - rtprio {priority}`; a container: --cap-add SYS_NICE)",
    "memory": "run as root, or `ulimit -l unlimited` (/etc/security/limits.conf: "
    "`USER - memlock unlimited`)",
    "idle": f"run as root, or let the user write {PM_QOS_DEVICE} (a udev rule giving it to "
    "the user's group)",
}


def idle_latency_in_force() -> int | None:
    """The CPUs' wake-up latency the kernel holds now, us (:data:`PM_QOS_DEVICE` read; about
    2e9 when nobody asks); None where the device is missing or unreadable."""
    try:
        fd = os.open(PM_QOS_DEVICE, os.O_RDONLY)
    except OSError:
        return None
    try:
        raw = os.read(fd, 4)
    except OSError:
        return None
    finally:
        os.close(fd)
    return struct.unpack("i", raw)[0] if len(raw) == 4 else None


def loop_core() -> int | None:
    """The core the loop is pinned to: the last one this process may run on (None: the OS
    does not say, as on macOS)."""
    try:
        return max(os.sched_getaffinity(0))
    except (AttributeError, OSError, ValueError):
        return None


@functools.cache
def _libc():
    """The C library (for ``mlockall``), found once a process: ``find_library`` runs
    ``ldconfig``, milliseconds that the locking and the unlocking after a run need not pay twice."""
    name = ctypes.util.find_library("c")
    return ctypes.CDLL(name, use_errno=True) if name else None


def _memory_lock_refusal() -> str | None:
    """Why the memory will not be locked (None: it may be)."""
    if not sys.platform.startswith("linux"):
        return "not Linux"
    soft, _ = resource.getrlimit(resource.RLIMIT_MEMLOCK)
    if soft != resource.RLIM_INFINITY and os.geteuid() != 0:
        return f"the memory lock limit is {soft // 1024} kB (ulimit -l), not unlimited"
    return None


class RealtimeLoop:
    """The calling thread on SCHED_FIFO at ``priority``, pinned to ``core``, its process's memory
    locked, the garbage collector out of the periods; all given back on exit.

    Args:
        priority: SCHED_FIFO priority, 1..99.
        core: the core to pin the thread to (default :func:`loop_core`).
    Attributes (after entering):
        policy: "SCHED_FIFO" when granted, else "SCHED_OTHER" (the normal policy).
        priority, core: what was granted (priority 0 and core None when refused).
        memory_locked: whether mlockall succeeded.
        idle_latency_us: the wake-up latency asked of the cores and written, us (None: refused).
        refusals: one phrase for each thing not granted, with how to grant it.
    """

    def __init__(self, priority: int = PRIORITY, core: int | None = None):
        self.asked_priority = int(priority)
        self.asked_core = loop_core() if core is None else int(core)
        self.policy, self.priority = "SCHED_OTHER", 0
        self.core: int | None = None
        self.memory_locked = False
        self.idle_latency_us: int | None = None
        self._qos_fd: int | None = None
        self.refusals: list[str] = []
        self._old_policy: tuple | None = None
        self._old_affinity: set[int] | None = None
        self._gc_was_enabled = False
        self._thresholds = gc.get_threshold()

    def __enter__(self) -> RealtimeLoop:
        self._ask_priority()
        self._ask_core()
        self._ask_memory_lock()
        self._ask_idle_latency()
        self._gc_was_enabled = gc.isenabled()
        gc.collect()
        gc.freeze()
        gc.disable()
        return self

    def __exit__(self, *exc) -> None:
        gc.unfreeze()
        if self._qos_fd is not None:
            os.close(self._qos_fd)  # the kernel drops the request with the file
            self._qos_fd, self.idle_latency_us = None, None
        if self._gc_was_enabled:
            gc.enable()
        if self.memory_locked:
            libc = _libc()
            if libc is not None:
                libc.munlockall()
            self.memory_locked = False
        if self._old_affinity is not None:
            try:
                os.sched_setaffinity(0, self._old_affinity)
            except OSError:
                pass
        if self._old_policy is not None:
            try:
                os.sched_setscheduler(0, *self._old_policy)
            except OSError:
                pass

    def _ask_priority(self) -> None:
        try:
            old = (os.sched_getscheduler(0), os.sched_getparam(0))
            os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(self.asked_priority))
        except AttributeError:
            self.refusals.append("SCHED_FIFO (not Linux)")
            return
        except OSError as err:
            how = HOW_TO_GRANT["priority"].format(priority=self.asked_priority)
            self.refusals.append(
                f"SCHED_FIFO priority {self.asked_priority} ({err.strerror or err}: {how})"
            )
            return
        self._old_policy = old
        self.policy, self.priority = "SCHED_FIFO", self.asked_priority

    def _ask_core(self) -> None:
        if self.asked_core is None:
            self.refusals.append("a core of its own (the OS does not pin threads)")
            return
        try:
            old = os.sched_getaffinity(0)
            os.sched_setaffinity(0, {self.asked_core})
        except (AttributeError, OSError, ValueError) as err:
            self.refusals.append(f"core {self.asked_core} ({getattr(err, 'strerror', err)})")
            return
        self._old_affinity, self.core = old, self.asked_core

    def _ask_memory_lock(self) -> None:
        why = _memory_lock_refusal()
        libc = _libc() if why is None else None
        if why is None and libc is None:
            why = "no C library found"
        if why is None and libc is not None:
            flags = _MCL_CURRENT | _MCL_FUTURE
            ok = libc.mlockall(flags | _MCL_ONFAULT) == 0 or libc.mlockall(flags) == 0
            if ok:
                self.memory_locked = True
                return
            why = os.strerror(ctypes.get_errno())
        self.refusals.append(f"locked memory ({why}: {HOW_TO_GRANT['memory']})")

    def _ask_idle_latency(self) -> None:
        if not sys.platform.startswith("linux"):
            self.refusals.append("shallow idle states (not Linux)")
            return
        try:
            fd = os.open(PM_QOS_DEVICE, os.O_WRONLY)
        except FileNotFoundError:
            self.refusals.append(
                f"shallow idle states (no {PM_QOS_DEVICE}: a kernel without PM QoS)"
            )
            return
        except OSError as err:
            self.refusals.append(
                f"shallow idle states ({err.strerror or err}: {HOW_TO_GRANT['idle']})"
            )
            return
        try:
            os.write(fd, struct.pack("i", IDLE_LATENCY_US))
        except OSError as err:
            os.close(fd)
            self.refusals.append(f"shallow idle states ({err.strerror or err})")
            return
        self._qos_fd, self.idle_latency_us = fd, IDLE_LATENCY_US

    def lift(self, native_id: int | None) -> None:
        """Put another thread of the process (by its native id; ``threading.Thread.native_id``)
        one priority above the loop and on every core the process had: a thread started from the
        loop's inherits its policy and its core. Nothing when the loop was not granted
        SCHED_FIFO or the OS refuses."""
        if native_id is None:
            return
        try:
            if self._old_affinity is not None:
                os.sched_setaffinity(native_id, self._old_affinity)
            if self.policy == "SCHED_FIFO":
                os.sched_setscheduler(
                    native_id, os.SCHED_FIFO, os.sched_param(min(self.priority + 1, 99))
                )
        except (AttributeError, OSError):
            pass

    def collect(self) -> None:
        """Collect the young generations of Python's garbage when they are as full as its
        own thresholds allow (gc.get_threshold()); called between periods, never inside one."""
        counts, limits = gc.get_count(), self._thresholds
        if counts[0] < limits[0]:
            return
        generation = 0
        if counts[1] >= limits[1]:
            generation = 2 if counts[2] >= limits[2] else 1
        gc.collect(generation)

    def granted(self) -> str:
        """What the loop was given, in words."""
        parts = [
            f"{self.policy} priority {self.priority}"
            if self.policy == "SCHED_FIFO"
            else "the normal policy (SCHED_OTHER)"
        ]
        parts.append(f"pinned to core {self.core}" if self.core is not None else "not pinned")
        parts.append("memory locked" if self.memory_locked else "memory not locked")
        parts.append("garbage collected between periods")
        if self.idle_latency_us is not None:
            parts.append(f"idle states held to {self.idle_latency_us} us wake-up")
        return ", ".join(parts)

    def line(self) -> str | None:
        """The one line for the session when something was refused (None: all granted)."""
        if not self.refusals:
            return None
        return (
            f"realtime: not granted: {'; '.join(self.refusals)}; the loop runs with "
            f"{self.granted()}"
        )
