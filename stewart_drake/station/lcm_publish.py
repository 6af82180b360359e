"""The robot's status and motor commands on LCM channels, published from a running Diagram.

A sender (a ``LeafSystem``) packs vector ports into a message of
:mod:`stewart_drake.lcmtypes`; Drake's own ``LcmPublisherSystem`` publishes it at a fixed period
on a ``DrakeLcm`` (``DrakeLcm("memq://")`` in one process, the default UDP multicast URL between
processes and tools such as lcm-spy; docs/lcm.md). The senders' input ports are named and sized
as the station's outputs and the controller contract's ports, so they connect to the same
outputs the controller reads (:func:`add_status_publisher`, :func:`add_command_publisher`).
:class:`LcmConfig`, the scenario's ``lcm`` section, is read by Drake's ``yaml_load_typed``,
which needs its field types as classes: this module has no ``from __future__ import
annotations``.
"""

import os
import sys
import tempfile
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np
from pydrake.common.containers import namedview
from pydrake.common.value import AbstractValue
from pydrake.lcm import DrakeLcmInterface
from pydrake.systems.framework import DiagramBuilder, LeafSystem, OutputPort
from pydrake.systems.lcm import LcmPublisherSystem

from ..base.checks import as_number, check_multiple
from ..base.errors import InvalidConfigError
from ..lcmtypes import lcmt_stewart_command, lcmt_stewart_status
from .station import weak_callback

#: The channel of :class:`~stewart_drake.lcmtypes.lcmt_stewart_status`.
STATUS_CHANNEL = "STEWART_STATUS"
#: The channel of :class:`~stewart_drake.lcmtypes.lcmt_stewart_command`.
COMMAND_CHANNEL = "STEWART_COMMAND"

_INT32 = (-(2**31), 2**31 - 1)
#: The channel of the one empty message :func:`make_lcm` sends to check that what is published
#: on a URL arrives there.
CHECK_CHANNEL = "STEWART_LCM_CHECK"
#: How long :func:`make_lcm` waits for that message, ms (it arrives in well under 1 ms).
CHECK_TIMEOUT_MS = 1000

#: The numbers of a control loop in the status (the :class:`StatusSender`'s ``loop`` input, in
#: this order): mode (``lcmt_stewart_status.MODE_*``), deadline misses since the start, achieved
#: period of the last control period (us), age of the measurement when its torque was applied (us).
LoopStatus = namedview("LoopStatus", ["mode", "deadline_misses", "period_us", "measurement_age_us"])


def utime(t_s: float) -> int:
    """The Diagram time ``t_s`` (s) as an LCM ``utime``: whole microseconds, rounded."""
    return int(round(t_s * 1e6))


def _int32(value: float) -> int:
    """``value`` rounded into an int32 field (a count that overflows saturates)."""
    return int(np.clip(round(value), *_INT32))


class StatusSender(LeafSystem):
    """Packs the robot's state and its loop's into an ``lcmt_stewart_status``.

    Input ports:
        ``motor_angle`` (6,) rad, ``motor_rate`` (6,) rad/s, ``motor_torque_applied`` (6,) N m:
            the station's outputs of those names (``theta``, ``theta_dot``, ``tau``).
        ``x`` (12,): pose [rad, m] and rate, as the controller contract's ``x`` (the estimate
            from the encoders on the robot as built); the pose is sent.
        ``x_d`` (18,): the reference's pose, rate and acceleration; the pose is sent.
        ``loop`` (4,), optional: a hardware driver's :data:`LoopStatus` (mode, deadline misses,
            achieved period in us, measurement age in us); unconnected, a simulated run:
            MODE_RUNNING, nothing missed or measured.
        ``reason`` (abstract ``str``), optional: why the run stopped; unconnected, "".
    Output port:
        ``lcmt_stewart_status`` (abstract): the message, ``utime`` the context's time in
        microseconds; for ``LcmPublisherSystem.Make(channel, lcmt_stewart_status, lcm, ...)``.
    """

    def __init__(self):
        super().__init__()
        self._motor_angle = self.DeclareVectorInputPort("motor_angle", 6)
        self._motor_rate = self.DeclareVectorInputPort("motor_rate", 6)
        self._tau = self.DeclareVectorInputPort("motor_torque_applied", 6)
        self._x = self.DeclareVectorInputPort("x", 12)
        self._x_d = self.DeclareVectorInputPort("x_d", 18)
        self._loop = self.DeclareVectorInputPort("loop", len(LoopStatus.get_fields()))
        self._reason = self.DeclareAbstractInputPort("reason", AbstractValue.Make(""))
        self.DeclareAbstractOutputPort(
            "lcmt_stewart_status",
            lambda: AbstractValue.Make(lcmt_stewart_status()),
            weak_callback(self._Calc),
        )

    def _Calc(self, context, output):
        message = lcmt_stewart_status()
        message.utime = utime(context.get_time())
        message.theta = self._motor_angle.Eval(context).tolist()
        message.theta_dot = self._motor_rate.Eval(context).tolist()
        message.tau = self._tau.Eval(context).tolist()
        message.x = self._x.Eval(context)[:6].tolist()
        message.x_d = self._x_d.Eval(context)[:6].tolist()
        if self._loop.HasValue(context):
            loop = LoopStatus(self._loop.Eval(context))
            message.mode = int(round(loop.mode))
            message.deadline_misses = _int32(loop.deadline_misses)
            message.period_us = _int32(loop.period_us)
            message.measurement_age_us = _int32(loop.measurement_age_us)
        else:
            message.mode = lcmt_stewart_status.MODE_RUNNING
        if self._reason.HasValue(context):
            message.reason = self._reason.Eval(context)
        output.set_value(message)


class CommandSender(LeafSystem):
    """Packs the controller's torque command into an ``lcmt_stewart_command``.

    Input port: ``T`` (6,): motor torque commands, N m (the controller contract's output, the
    station's ``motor_torque`` input).
    Output port: ``lcmt_stewart_command`` (abstract): the message, ``utime`` the context's time
    in microseconds.
    """

    def __init__(self):
        super().__init__()
        self._T = self.DeclareVectorInputPort("T", 6)
        self.DeclareAbstractOutputPort(
            "lcmt_stewart_command",
            lambda: AbstractValue.Make(lcmt_stewart_command()),
            weak_callback(self._Calc),
        )

    def _Calc(self, context, output):
        message = lcmt_stewart_command()
        message.utime = utime(context.get_time())
        message.tau = self._T.Eval(context).tolist()
        output.set_value(message)


def _add_publisher(
    builder: DiagramBuilder,
    sender: LeafSystem,
    lcm_type: type,
    ports: Mapping[str, OutputPort],
    lcm: DrakeLcmInterface,
    period_s: float,
    channel: str,
) -> None:
    """``sender`` and Drake's publisher of ``lcm_type`` on ``channel`` every ``period_s`` (first
    at t = 0), in ``builder``; ``ports`` connected to the sender's inputs of the same names (the
    arguments checked: :func:`_check_publisher`)."""
    builder.AddNamedSystem(f"{channel.lower()}_sender", sender)
    publisher = builder.AddNamedSystem(
        f"{channel.lower()}_publisher",
        LcmPublisherSystem.Make(channel, lcm_type, lcm, publish_period=period_s),
    )
    builder.Connect(sender.get_output_port(), publisher.get_input_port())
    for name, port in ports.items():
        builder.Connect(port, sender.GetInputPort(name))


def _check_publisher(sender: LeafSystem, ports: Mapping, period_s: float, channel: str) -> float:
    """The publish period of a publisher's arguments, checked: a positive period, a non-empty
    channel, ``ports`` that the sender has. Raises InvalidConfigError naming what is wrong."""
    period_s = as_number("the LCM publish period (s)", period_s, 0.0, lo_open=True)
    if not isinstance(channel, str) or not channel:
        raise InvalidConfigError(f"an LCM channel is a non-empty string, got {channel!r:.80}")
    names = [sender.get_input_port(i).get_name() for i in range(sender.num_input_ports())]
    unknown = sorted(set(ports) - set(names))
    if unknown:
        raise InvalidConfigError(
            f"{type(sender).__name__} has no input port {', '.join(unknown)} "
            f"(its inputs: {', '.join(names)})"
        )
    return period_s


def add_run_publishers(
    builder: DiagramBuilder,
    config: "LcmConfig",
    station,
    T: OutputPort,
    x: OutputPort,
    x_d: OutputPort,
    lcm: DrakeLcmInterface | None = None,
) -> DrakeLcmInterface:
    """A run's status and torque commands on the channels of the scenario's ``lcm``
    (:class:`LcmConfig`, validated with the scenario) every ``config.period_s``: the status of
    the station's measurements, the pose ``x`` the controller reads and the reference ``x_d``
    (on the servo bus also the driver's loop numbers, its ``loop`` output), the commands of the
    controller's ``T``.

    Args:
        builder: the Diagram's builder. station: the station (its ports). lcm: the ``DrakeLcm``
            of ``config.url`` when the caller has made it (:func:`make_lcm`); made here
            otherwise.
    Returns:
        the ``DrakeLcm`` the run publishes on.
    Raises:
        InvalidConfigError: (:func:`make_lcm`) nothing published on ``config.url`` arrives.
    """
    lcm = make_lcm(config.url) if lcm is None else lcm  # refuses a URL that delivers nothing
    ports = {
        name: station.GetOutputPort(name)
        for name in ("motor_angle", "motor_rate", "motor_torque_applied")
    }
    if station.HasOutputPort("loop"):
        ports["loop"] = station.GetOutputPort("loop")
    ports |= {"x": x, "x_d": x_d}
    period, status, command = config.period_s, config.status_channel, config.command_channel
    _add_publisher(builder, StatusSender(), lcmt_stewart_status, ports, lcm, period, status)
    _add_publisher(builder, CommandSender(), lcmt_stewart_command, {"T": T}, lcm, period, command)
    return lcm


def add_status_publisher(
    builder: DiagramBuilder,
    lcm: DrakeLcmInterface,
    ports: Mapping[str, OutputPort],
    period_s: float,
    channel: str = STATUS_CHANNEL,
) -> StatusSender:
    """A :class:`StatusSender` and Drake's ``LcmPublisherSystem`` publishing its
    ``lcmt_stewart_status`` on ``channel`` every ``period_s`` (s, first at t = 0).

    Args:
        builder: the Diagram's builder. lcm: where to publish (a ``DrakeLcm``).
        ports: {the sender's input port name: the output port feeding it}; the required ones
            (``motor_angle``, ``motor_rate``, ``motor_torque_applied``, ``x``, ``x_d``) not given
            here must be connected by the caller before the Diagram is built.
        period_s: publish period, s (> 0). channel: the LCM channel.
    Returns:
        the sender (its ``loop`` and ``reason`` inputs for a hardware driver to connect).
    Raises:
        InvalidConfigError: a period that is not a positive number, an empty channel, or a
            port name the sender does not have; before anything is added to ``builder``.
    """
    sender = StatusSender()
    period_s = _check_publisher(sender, ports, period_s, channel)
    _add_publisher(builder, sender, lcmt_stewart_status, ports, lcm, period_s, channel)
    return sender


def add_command_publisher(
    builder: DiagramBuilder,
    lcm: DrakeLcmInterface,
    T: OutputPort,
    period_s: float,
    channel: str = COMMAND_CHANNEL,
) -> CommandSender:
    """A :class:`CommandSender` fed by ``T`` (the controller's torque command, (6,) N m) and
    Drake's ``LcmPublisherSystem`` publishing its ``lcmt_stewart_command`` on ``channel`` every
    ``period_s`` (s, first at t = 0).

    Raises:
        InvalidConfigError: as :func:`add_status_publisher`.
    """
    sender = CommandSender()
    period_s = _check_publisher(sender, {"T": T}, period_s, channel)
    _add_publisher(builder, sender, lcmt_stewart_command, {"T": T}, lcm, period_s, channel)
    return sender


def _drake_lcm(url: str):
    """``DrakeLcm(url)`` with what LCM's C library prints on stderr while it opens the URL
    (bind: Address already in use ...) captured, not shown: returned as (lcm or None, error)."""
    from pydrake.lcm import DrakeLcm

    sys.stderr.flush()
    saved = os.dup(2)
    with tempfile.TemporaryFile() as captured:
        os.dup2(captured.fileno(), 2)
        try:
            lcm, error = DrakeLcm(url), ""
        except RuntimeError as err:
            lcm, error = None, str(err)
        finally:
            os.dup2(saved, 2)
            os.close(saved)
        captured.seek(0)
        said = captured.read(4096).decode("utf-8", "replace").split()
    return lcm, " ".join(said) or error


def make_lcm(url: str):
    """The ``DrakeLcm`` of a scenario's ``lcm.url``, checked to deliver what is published on it.

    ``url`` "" is Drake's default: ``LCM_DEFAULT_URL`` from the environment, else LCM's own
    :data:`~LCM_DEFAULT_URL`; it is checked as ``lcm.url`` is
    (:func:`~check_lcm_url`) before LCM opens it. Where LCM cannot open a URL it
    says so on stderr and Drake goes on with an in-process queue: nothing would leave the
    process. So, for a ``udpm://`` URL, a second instance on the same URL must receive one
    empty message sent on :data:`CHECK_CHANNEL` within :data:`CHECK_TIMEOUT_MS`.

    Raises:
        InvalidConfigError: the URL is not one a run may use, or nothing published on it
            arrives (LCM could not open it: a port taken, no multicast route), in one line.
    """
    resolved = url or os.environ.get("LCM_DEFAULT_URL") or LCM_DEFAULT_URL
    what = "lcm.url" if url or "LCM_DEFAULT_URL" not in os.environ else "LCM_DEFAULT_URL"
    check_lcm_url(resolved, what)

    def dead(problem: str) -> InvalidConfigError:
        return InvalidConfigError(
            f"{what} {resolved!r}: {problem}; choose another port or address, or see "
            f"'Watching with LCM's tools' in docs/lcm.md (multicast may need a route)"
        )

    lcm, error = _drake_lcm(url)
    if lcm is None:
        raise dead(f"LCM cannot open it ({error:.200})")
    if resolved == "memq://":
        return lcm  # in this process only, and it cannot fail
    probe, probe_error = _drake_lcm(url)
    if probe is None:
        raise dead(f"LCM cannot open it ({probe_error:.200})")
    received: list[bytes] = []
    probe.Subscribe(CHECK_CHANNEL, received.append)
    lcm.Publish(CHECK_CHANNEL, b"")
    for _ in range(CHECK_TIMEOUT_MS // 100):
        if probe.HandleSubscriptions(100) or received:
            break
    if not received:
        said = f": {error:.200}" if error else ""
        raise dead(f"nothing published on it arrives (LCM could not open it{said})")
    return lcm


#: LCM's default URL, which Drake uses for ``url: ""`` when ``LCM_DEFAULT_URL`` is not set.
LCM_DEFAULT_URL = "udpm://239.255.76.67:7667?ttl=0"


#: LCM's longest channel name, characters (``LCM_MAX_CHANNEL_NAME_LENGTH``): a longer one is
#: dropped at every publish with a message on stderr.
LCM_MAX_CHANNEL_CHARS = 63


#: The options a ``udpm://`` URL may carry, with their ranges.
_UDPM_OPTIONS = {"ttl": (0, 255), "recv_buf_size": (1, 2**31 - 1)}


_LCM_URL_FORMS = (
    '"memq://" (in one process), "udpm://ADDRESS:PORT[?ttl=N]" with a multicast IPv4 address '
    "(224.0.0.0/4; LCM's own is udpm://239.255.76.67:7667?ttl=0), or \"\" for Drake's default"
)


def check_lcm_url(url: str, what: str = "lcm.url") -> None:
    """Accept the LCM URLs a run may publish on, refuse every other (docs/lcm.md).

    Accepted: ``memq://`` (in one process) and ``udpm://A.B.C.D:PORT`` with a multicast IPv4
    address, a port in 1..65535 and the options ``ttl`` (0..255) and ``recv_buf_size``.
    Refused: ``file://`` (LCM would create, truncate or append to that file, outside the run's
    output: the run's ``.npz`` records what was published), ``tcpq://`` and ``mpudpm://`` (not
    supported here), anything else LCM does not know.

    Args:
        url: the URL. what: how messages name it ("lcm.url", "LCM_DEFAULT_URL").
    Raises:
        InvalidConfigError: naming ``what``, the URL and the forms accepted.
    """
    import ipaddress

    def refuse(problem: str) -> InvalidConfigError:
        return InvalidConfigError(f"{what} {url!r}: {problem}; use {_LCM_URL_FORMS}")

    scheme, sep, rest = url.partition("://")
    if not sep:
        raise refuse("not an LCM URL (provider://address)")
    if scheme == "file":
        raise refuse(
            "LCM would create, truncate or read that file, outside the run's output; the "
            "run's .npz (--out) records what was published, lcm-logger records a udpm:// bus"
        )
    if scheme == "memq":
        if rest:
            raise refuse("memq:// takes no address or options")
        return
    if scheme != "udpm":
        raise refuse(f"the provider {scheme!r} is not supported")
    address, _, query = rest.partition("?")
    host, colon, port = address.rpartition(":")
    try:
        multicast = ipaddress.IPv4Address(host).is_multicast
    except ValueError:
        raise refuse(f"{host or address!r} is not an IPv4 address") from None
    if not multicast:
        raise refuse(f"{host} is not a multicast address (224.0.0.0/4)")
    if not (colon and port.isdigit() and port.isascii() and 1 <= int(port) <= 65535):
        raise refuse("the port must be a number in 1..65535")
    seen = set()
    for option in query.split("&") if query else ():
        key, equals, value = option.partition("=")
        if key not in _UDPM_OPTIONS or not equals or key in seen:
            raise refuse(f"the option {option!r} is not one of {', '.join(_UDPM_OPTIONS)}, once")
        seen.add(key)
        lo, hi = _UDPM_OPTIONS[key]
        if not (value.isdigit() and value.isascii() and lo <= int(value) <= hi):
            raise refuse(f"{key} must be an integer in {lo}..{hi}")


@dataclass
class LcmConfig:
    """The run's status and commands on LCM channels (:mod:`~.lcm_publish`, docs/lcm.md), in
    simulation and on the servo bus alike.

    Attributes:
        url: the ``DrakeLcm`` URL: "memq://" in one process (tests), "udpm://ADDRESS:PORT?ttl=N"
            on a multicast group, "" for Drake's default (``LCM_DEFAULT_URL`` or LCM's own UDP
            multicast, for lcm-spy and other processes); nothing else (:func:`check_lcm_url`).
        status_channel: channel of ``lcmt_stewart_status``. command_channel: of
            ``lcmt_stewart_command`` (another channel: each has its own publisher).
        period_s: publish period, s (a whole multiple of the plant step).
    """

    url: str = "memq://"
    status_channel: str = "STEWART_STATUS"
    command_channel: str = "STEWART_COMMAND"
    period_s: float = 0.01

    def validate(self, plant_time_step_s: float) -> None:
        """Check every field (``lcm.<name>``). Raises InvalidConfigError naming it."""
        for name in ("url", "status_channel", "command_channel"):
            if not isinstance(getattr(self, name), str):
                raise InvalidConfigError(f"lcm.{name} must be a string")
        if self.url:
            check_lcm_url(self.url)
        for name in ("status_channel", "command_channel"):
            channel = getattr(self, name)
            if not channel:
                raise InvalidConfigError(f"lcm.{name} must not be empty")
            if len(channel) > LCM_MAX_CHANNEL_CHARS or not channel.isprintable():
                raise InvalidConfigError(
                    f"lcm.{name} {channel!r}: a channel is at most {LCM_MAX_CHANNEL_CHARS} "
                    f"printable characters (LCM drops longer ones)"
                )
        if self.status_channel == self.command_channel:
            raise InvalidConfigError(
                f"lcm.status_channel and lcm.command_channel are both "
                f"{self.status_channel!r}: give them different channels (each message type "
                f"has its own)"
            )
        check_multiple("lcm.period_s", self.period_s, "plant.time_step", plant_time_step_s)
