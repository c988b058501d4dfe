"""Opening buses the python-can way: its CLI flags, env (CAN_INTERFACE/CAN_CHANNEL/CAN_CONFIG),
config files (``~/.canrc``, ``can.ini``), plus one embedded default.

The default, when nothing else names an interface, is ``udp_multicast`` on this host only: it needs
no kernel CAN support and no root, and carries CAN FD between processes. python-can's own
``UdpMulticastBus`` joins its group on ``INADDR_ANY`` (the interface of the default route) and sends
with TTL 1, which puts every frame on the local network segment and lets any host there inject
frames; every ``udp_multicast`` bus this package opens is instead joined on loopback and sends with
TTL 0 (:class:`HostMulticastBus`), unless the user names another interface and a TTL >= 1.
"""
from __future__ import annotations

import argparse
import difflib
import errno
import importlib
import inspect
import ipaddress
import logging
import math
import os
import random
import re
import signal
import socket
import struct
import sys
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import can
from can.cli import add_bus_arguments
from can.interfaces.udp_multicast.bus import GeneralPurposeUdpMulticastBus, UdpMulticastBus

from ..errors import BusError

log = logging.getLogger(__name__)

DEFAULT_INTERFACE = "udp_multicast"
DEFAULT_CHANNEL = "239.74.163.2"  # python-can's UdpMulticastBus.DEFAULT_GROUP_IPv4


def parse_bitrate(text: str | None, option: str = "bitrate") -> int | None:
    """'500000', '500k', '4M', '2.5M' -> bit/s; BusError for anything else or a rate <= 0. The one
    bitrate parser of every verb (python-can's -b/--data-bitrate take it too)."""
    if text is None:
        return None
    body = str(text).strip()
    scale = {"k": 1e3, "m": 1e6}.get(body[-1:].lower(), 1.0)
    if scale != 1.0:
        body = body[:-1]
    try:
        value = float(body) * scale
    except ValueError:
        value = math.nan
    if not math.isfinite(value) or value <= 0 or value != round(value) or value > 1e9:
        raise BusError(f"{option} {text!r}: expected a positive number of bit/s such as 500000, 500k or 4M")
    return int(round(value))


def _bitrate_type(text: str) -> int:
    try:
        return int(parse_bitrate(text) or 0)
    except BusError:
        raise argparse.ArgumentTypeError(f"{text!r}: expected a positive number of bit/s such as 500000, 500k "
                                         "or 4M") from None


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """python-can's own bus flags (-i/-c/-b/--fd/--data-bitrate/--bus-kwargs ...) plus a config file;
    -b and --data-bitrate take 500k / 2M as well as plain bit/s."""
    add_bus_arguments(parser)
    for action in parser._actions:
        if action.dest in ("bitrate", "data_bitrate"):
            action.type = _bitrate_type
            action.metavar = "BITRATE" if action.dest == "bitrate" else "DATA_BITRATE"
            action.help = (action.help or "") + " (bit/s: 500000, 500k, 2M)"
    group = parser.add_argument_group("bus configuration file")
    group.add_argument(
        "--bus-config", metavar="FILE",
        help="python-can configuration file (INI, as ~/.canrc); flags given on the command line win",
    )
    group.add_argument("--bus-context", metavar="SECTION", help="section of the configuration file")


def bus_config(args: argparse.Namespace, **overrides) -> dict:
    """Resolve the bus configuration: flags > env/config files > embedded default."""
    given = {}
    for key in ("interface", "channel", "bitrate", "fd", "data_bitrate", "timing"):
        if key in args and getattr(args, key) is not None:
            given[key] = getattr(args, key)
    extra = getattr(args, "bus_kwargs", None) or {}
    given.update(extra)
    path = getattr(args, "bus_config", None)
    try:
        config = dict(can.util.load_config(path=path, config=given, context=getattr(args, "bus_context", None)))
    except can.CanInterfaceNotImplementedError as exc:
        context = getattr(args, "bus_context", None)
        named = ("interface" in given or path or os.environ.get("CAN_INTERFACE")
                 or can.util.load_file_config(path, context or "default").get("interface"))
        if named:  # the user named one (flag, CAN_INTERFACE, a config file), and it is wrong
            raise BusError(f"bus configuration: {exc} (from {_named_where(given, path)})") from exc
        config = {"interface": DEFAULT_INTERFACE, "channel": DEFAULT_CHANNEL, **given}
    except (can.CanError, ValueError, KeyError) as exc:
        raise BusError(f"bus configuration: {exc}") from exc
    problems, _ = check_bus_kwargs(config["interface"], extra)
    if problems:
        key, problem = problems[0]
        raise BusError(f"bus keyword argument {key}={extra[key]}: {problem}")
    if config["interface"] in ("udp_multicast", "virtual", "socketcan") and "fd" not in config:
        config["fd"] = True  # the PT bus is CAN FD; these interfaces carry it as is
    config.update(overrides)
    return config


_PARAM = re.compile(r":param\s+(?:[\w\[\], .|]+\s+)?(\w+)\s*:")
_SIMPLE_TYPES: dict[str, type] = {"bool": bool, "int": int, "float": float, "str": str}
_TYPE_WORDS = {"typing", "Optional", "typing.Optional", "Union", "typing.Union", "None", "NoneType"}


def import_quietly(module: str):
    """python-can's interface modules log warnings at import about missing vendor libraries: not ours to show."""
    quiet = logging.getLogger("can")
    level = quiet.level
    quiet.setLevel(logging.ERROR)
    try:
        return importlib.import_module(module)
    finally:
        quiet.setLevel(level)


def _value_types(param: inspect.Parameter) -> tuple[type, ...] | None:
    """The simple types (bool, int, float, str) an argument's value may have, from its annotation (else
    its default's type); None when it takes anything else too (a sequence, a BitTiming: not checked)."""
    ann = param.annotation
    if ann is param.empty:
        return (type(param.default),) if type(param.default) in _SIMPLE_TYPES.values() else None
    text = ann if isinstance(ann, str) else ann.__name__ if isinstance(ann, type) else str(ann)
    words = set(re.findall(r"[A-Za-z_][\w.]*", text)) - _TYPE_WORDS
    if not words or not words <= set(_SIMPLE_TYPES):
        return None
    return tuple(_SIMPLE_TYPES[w] for w in sorted(words))


def interface_arguments(interface: str) -> tuple[dict[str, tuple[type, ...] | None] | None, str]:
    """The keyword arguments python-can's `interface` bus takes (its class's ``__init__`` signature and
    documented parameters, and ``can.BusABC``'s), each with the types its value may have (None: any),
    or (None, why) when the interface's module does not import here (a vendor library missing)."""
    cls: Any
    if interface == "udp_multicast":
        cls = HostMulticastBus
    else:
        try:
            module, name = can.interfaces.BACKENDS[interface]
            cls = getattr(import_quietly(module), name)
        except Exception as exc:  # noqa: BLE001 - any import failure of a vendor module means the same
            return None, f"its module does not import here: {exc}"
    args: dict[str, tuple[type, ...] | None] = {"can_filters": None}  # can.BusABC's own
    for klass in (cls, can.BusABC):
        for doc in (inspect.getdoc(klass.__init__), inspect.getdoc(klass)):
            for p in _PARAM.findall(doc or ""):
                args.setdefault(p, None)
        for p, v in inspect.signature(klass.__init__).parameters.items():
            if v.kind not in (v.VAR_KEYWORD, v.VAR_POSITIONAL) and p != "self":
                args[p] = _value_types(v) if klass is cls or p not in args else args[p]
    args.pop("kwargs", None)  # BusABC documents its **kwargs
    return args, ""


def _fits(value, types: tuple[type, ...]) -> bool:
    if isinstance(value, bool):
        return bool in types
    if isinstance(value, int):
        return bool(int in types or float in types or str in types or (bool in types and value in (0, 1)))
    if isinstance(value, float):
        return float in types or str in types
    return isinstance(value, str) and str in types


def check_bus_kwargs(interface: str, kwargs: dict) -> tuple[list[tuple[str, str]], str]:
    """What python-can's `interface` would refuse or silently ignore of the extra `kwargs`: an argument
    it does not take, a value of the wrong type (fd=maybe). Returns (key, problem) pairs and why the
    arguments could not be checked ("" when they were)."""
    known, why = interface_arguments(interface)
    if known is None:
        return [], (f"not checked against python-can's {interface} interface ({why})" if kwargs else "")
    problems = []
    for k, v in kwargs.items():
        if k not in known:
            near = difflib.get_close_matches(k, sorted(known), n=1)
            problems.append((k, f"python-can's {interface} interface takes no argument {k!r} "
                                f"({f'did you mean {near[0]!r}? ' if near else ''}it takes: {', '.join(sorted(known))})"))
            continue
        types = known[k]
        if types is not None and not isinstance(v, list) and not _fits(v, types):
            hint = " (true or false)" if types == (bool,) else ""
            problems.append((k, f"python-can's {interface} interface takes {k} as "
                                f"{' or '.join(t.__name__ for t in types)}{hint}, not {v!r}"))
    return problems, ""


def _named_where(given: dict, path) -> str:
    if "interface" in given:
        return "-i/--interface"
    if path:
        return f"--bus-config {path}"
    if os.environ.get("CAN_INTERFACE"):
        return "the CAN_INTERFACE environment variable"
    return "a python-can configuration file (~/.canrc, /etc/can.conf)"


def private_multicast() -> dict:
    """A udp_multicast bus that no other session on this machine hears. Linux hands a multicast
    datagram to every socket bound to its port whatever group it joined (IP_MULTICAST_ALL), so a
    group of one's own is not enough: the session needs a port of its own."""
    return {"interface": "udp_multicast", "channel": DEFAULT_CHANNEL, "port": random.randint(49152, 64999), "fd": True}


def cli_args(config: dict) -> list[str]:
    """python-can CLI flags that reopen the bus of a resolved config (for a child process)."""
    out = ["-i", str(config["interface"])]
    if config.get("channel") is not None:
        out += ["-c", str(config["channel"])]
    for key, flag in (("bitrate", "-b"), ("data_bitrate", "--data-bitrate")):
        if config.get(key) is not None:
            out += [flag, str(config[key])]
    if config.get("fd"):
        out.append("--fd")
    extra = {k: v for k, v in config.items()
             if k not in ("interface", "channel", "bitrate", "data_bitrate", "fd") and isinstance(v, (int, float, str, bool))}
    if extra:
        out += ["--bus-kwargs", *(f"{k}={v}" for k, v in extra.items())]
    return out


IP_MULTICAST_ALL = getattr(socket, "IP_MULTICAST_ALL", 49)  # Linux <linux/in.h>
SO_TIMESTAMPNS = getattr(socket, "SO_TIMESTAMPNS", 35)      # Linux <asm/socket.h>
IFF_LOOPBACK = 0x8                                          # Linux <linux/if.h>
RCVBUF_BYTES = 4 << 20  # ~2 s of this project's traffic; the kernel caps it at net.core.rmem_max
LOOPBACK_V4 = "127.0.0.1"


def _is_loopback(interface: str) -> bool:
    """An interface address (IPv4/IPv6) or a Linux interface name that is the loopback device."""
    try:
        return ipaddress.ip_address(interface).is_loopback
    except ValueError:
        pass
    try:
        return bool(int(Path(f"/sys/class/net/{interface}/flags").read_text(), 16) & IFF_LOOPBACK)
    except (OSError, ValueError):
        return interface in ("lo", "lo0")


class _GroupSocket(GeneralPurposeUdpMulticastBus):
    """python-can's multicast socket handler, with the group joined on one named interface (not
    INADDR_ANY), outgoing multicast through that interface, and bound to the group address, so
    neither a unicast datagram to this host's port nor another group's traffic is heard."""

    def __init__(self, group: str, port: int, hop_limit: int, interface: str) -> None:
        self.interface = interface
        super().__init__(group, port, hop_limit)

    def _create_socket(self, address_family: socket.AddressFamily) -> socket.socket:
        sock = socket.socket(address_family, socket.SOCK_DGRAM)
        try:
            group = socket.inet_pton(address_family, self.group)
            if address_family == socket.AF_INET:
                try:
                    addr = socket.inet_aton(str(ipaddress.IPv4Address(self.interface)))
                    join, out_if = group + addr, addr                           # struct ip_mreq
                except ValueError:  # an interface name: struct ip_mreqn (Linux)
                    out_if = struct.pack("@4s4si", b"\0" * 4, b"\0" * 4, socket.if_nametoindex(self.interface))
                    join = struct.pack("@4s4si", group, b"\0" * 4, socket.if_nametoindex(self.interface))
                sock.setsockopt(socket.IPPROTO_IP, socket.IP_MULTICAST_TTL, self.hop_limit)
                sock.setsockopt(socket.IPPROTO_IP, socket.IP_MULTICAST_IF, out_if)
                if sys.platform.startswith("linux"):  # hear only the groups this socket joined
                    sock.setsockopt(socket.IPPROTO_IP, IP_MULTICAST_ALL, 0)
                membership = (socket.IPPROTO_IP, socket.IP_ADD_MEMBERSHIP, join)
            else:
                index = socket.if_nametoindex(self.interface)
                sock.setsockopt(socket.IPPROTO_IPV6, socket.IPV6_MULTICAST_HOPS, self.hop_limit)
                sock.setsockopt(socket.IPPROTO_IPV6, socket.IPV6_MULTICAST_IF, index)
                membership = (socket.IPPROTO_IPV6, socket.IPV6_JOIN_GROUP, group + struct.pack("@I", index))
            sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
            if hasattr(socket, "SO_REUSEPORT"):
                sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEPORT, 1)
            try:
                sock.setsockopt(socket.SOL_SOCKET, SO_TIMESTAMPNS, 1)
                self.timestamp_nanosecond = True  # python-can's recv() then reads the kernel's stamp
            except OSError:
                self.timestamp_nanosecond = False
            # A larger receive buffer turns a descheduled process's stall into latency, not loss.
            sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, RCVBUF_BYTES)
            sock.bind((self.group, self.port) if sys.platform.startswith("linux") else ("", self.port))
            sock.setsockopt(*membership)
            return sock
        except OSError as exc:
            sock.close()
            raise can.CanInitializationError(
                f"udp_multicast group {self.group} on interface {self.interface}: {exc}") from exc


class HostMulticastBus(UdpMulticastBus):
    """python-can's ``udp_multicast`` bus (same wire format, same group and port), kept on this host
    unless asked otherwise: joined on loopback, sent through loopback with TTL/hop limit 0, so even
    a misrouted datagram is never transmitted (RFC 1112: TTL 0 stays on the host).

    A bus across machines (two laptops on a bench network) is asked for explicitly:
    ``--bus-kwargs multicast_interface=192.168.1.10 hop_limit=1`` (an interface's IPv4 address or
    its name, e.g. ``eth0``; IPv6 groups need a name)."""

    def __init__(self, channel: str = UdpMulticastBus.DEFAULT_GROUP_IPv4, port: int = 43113,
                 hop_limit: int = 0, multicast_interface: str | None = None,
                 receive_own_messages: bool = False, fd: bool = True, **kwargs) -> None:
        channel, port, hop_limit, interface = multicast_settings(channel, port, hop_limit, multicast_interface)
        self.host_only = _is_loopback(interface) or hop_limit == 0
        if receive_own_messages:
            raise can.CanInterfaceNotImplementedError("receiving own messages is not yet implemented")
        can.BusABC.__init__(self, channel, **kwargs)
        self._multicast = _GroupSocket(channel, port, hop_limit, interface)
        self._can_protocol = can.CanProtocol.CAN_FD if fd else can.CanProtocol.CAN_20
        self.channel_info = (f"udp_multicast {channel} port {int(port)} on {interface}, "
                             f"TTL {hop_limit}: " + ("this host only" if self.host_only else "reaches other machines"))


def multicast_settings(channel, port=43113, hop_limit=0, multicast_interface=None) -> tuple[str, int, int, str]:
    """A udp_multicast bus's (group, port, hop limit, interface), checked before any socket is opened
    (:class:`HostMulticastBus` and ``hil --check``): ``can.CanInitializationError`` saying what is wrong."""
    channel = str(channel)
    try:
        group = ipaddress.ip_address(channel)
    except ValueError:
        raise can.CanInitializationError(f"udp_multicast channel {channel!r} is not an IP multicast group") from None
    if not group.is_multicast:
        raise can.CanInitializationError(f"udp_multicast channel {channel} is not a multicast group "
                                         f"(IPv4 224.0.0.0/4, e.g. {UdpMulticastBus.DEFAULT_GROUP_IPv4}; IPv6 ff00::/8)")
    ipv6 = group.version == 6
    values = {}
    for key, value, hi in (("port", port, 65535), ("hop_limit", hop_limit, 255)):
        if isinstance(value, str) and value.strip().isdigit():  # from a config file
            value = int(value)
        if isinstance(value, bool) or not isinstance(value, int) or not (0 if key == "hop_limit" else 1) <= value <= hi:
            lo = 0 if key == "hop_limit" else 1
            raise can.CanInitializationError(f"udp_multicast {key} must be an integer {lo}..{hi}, not {value!r}")
        values[key] = value
    hop_limit = values["hop_limit"]
    interface = str(multicast_interface) if multicast_interface is not None else ("lo" if ipv6 else LOOPBACK_V4)
    if not _is_loopback(interface) and hop_limit == 0:
        raise can.CanInitializationError(
            f"udp_multicast on {interface} with hop_limit=0 would hear other machines but send them "
            "nothing: give hop_limit=1 (or more) for a bus across machines, or leave "
            "multicast_interface out for this host only")
    if ipv6 and _is_loopback(interface) and sys.platform.startswith("linux"):
        raise can.CanInitializationError(
            f"udp_multicast IPv6 group {channel} cannot stay on this host: Linux's loopback carries no "
            f"IPv6 multicast. Use an IPv4 group (the default {UdpMulticastBus.DEFAULT_GROUP_IPv4}), or "
            "name an interface and a hop limit for a bus across machines (multicast_interface=eth0 hop_limit=1)")
    return channel, values["port"], hop_limit, interface


def is_undecodable(exc: BaseException) -> bool:
    """A receive error about the bytes that arrived, not about the bus: python-can's udp_multicast
    raises CanOperationError("could not unpack received message") from its msgpack error."""
    cause = exc.__cause__
    return isinstance(exc, can.CanOperationError) and cause is not None and not isinstance(cause, OSError)


def open_bus(config: dict) -> can.BusABC:
    """A python-can bus; ``udp_multicast`` is :class:`HostMulticastBus` (this host only by default)."""
    bus: can.BusABC
    try:
        if config.get("interface") == "udp_multicast":
            bus = HostMulticastBus(**{k: v for k, v in config.items() if k != "interface"})
        else:
            bus = can.Bus(**config)
    except (can.CanError, OSError, ValueError, ImportError, TypeError) as exc:
        raise BusError(f"cannot open bus {_describe(config)}: {exc}{_why(config, exc)}") from exc
    log.info("bus open: %s", describe_bus(bus, config))
    return bus


def describe_bus(bus: can.BusABC, config: dict) -> str:
    """What a user needs to know of an open bus: interface, channel and, for udp_multicast, where
    its datagrams go (interface and TTL)."""
    if isinstance(bus, HostMulticastBus):
        return bus.channel_info
    return _describe(config)


@contextmanager
def stop_on_signals(stop):
    """SIGINT/SIGTERM call `stop()` (a clean shutdown, not an exception) while the block runs;
    the previous handlers come back afterwards."""
    old = {s: signal.signal(s, lambda *_: stop()) for s in (signal.SIGINT, signal.SIGTERM)}
    try:
        yield
    finally:
        for s, h in old.items():
            signal.signal(s, h)


@contextmanager
def serving(bus: can.BusABC, writer: can.Listener | None, stop):
    """A node's run: stop() on SIGINT/SIGTERM; then the log is flushed and the bus closed."""
    try:
        with stop_on_signals(stop):
            yield
    finally:
        if writer is not None:
            writer.stop()
        bus.shutdown()


def _why(config: dict, exc: BaseException) -> str:
    """What a bare errno means for this interface, and what to do about it."""
    errno_ = getattr(exc, "errno", None) or getattr(exc.__cause__ or exc.__context__, "errno", None)
    if config.get("interface") == "socketcan" and errno_ == errno.EAFNOSUPPORT:
        return ("\n  this kernel has no SocketCAN (no AF_CAN sockets; `modprobe can-raw vcan` needs a kernel with "
                "CAN, which containers and many VMs lack). Without it: leave out -i/--interface, and the ECU and "
                "the tools meet on the default udp_multicast bus that stays on this host (docs/bus.md); for a "
                "real vcan0, run inside user-mode Linux (docs/uml.md)")
    if config.get("interface") == "socketcan" and errno_ == errno.ENODEV:
        ch = config.get("channel")
        return (f"\n  no CAN interface {ch!r} here: create one (`ip link add dev {ch} type vcan && ip link set up "
                f"{ch}`, as root) or name an existing one (`ip link show type can`, `ip link show type vcan`)")
    return ""


def _describe(config: dict) -> str:
    return f"{config.get('interface')}:{config.get('channel')}"
