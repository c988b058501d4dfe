"""Opening buses the python-can way: its CLI flags, env (CAN_INTERFACE/CAN_CHANNEL/CAN_CONFIG),
config files (``~/.canrc``, ``can.ini``), plus one embedded default.

The default, when nothing else names an interface, is ``udp_multicast`` on loopback: it needs no
kernel CAN support and no root, and carries CAN FD between processes.
"""
from __future__ import annotations

import argparse
import logging
import random
import signal
import socket
import sys
from contextlib import contextmanager

import can
from can.cli import add_bus_arguments

from .errors import BusError

log = logging.getLogger(__name__)

DEFAULT_INTERFACE = "udp_multicast"
DEFAULT_CHANNEL = "239.74.163.2"  # python-can's UdpMulticastBus.DEFAULT_GROUP_IPv4


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """python-can's own bus flags (-i/-c/-b/--fd/--data-bitrate/--bus-kwargs ...) plus a config file."""
    add_bus_arguments(parser)
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
    given.update(getattr(args, "bus_kwargs", None) or {})
    path = getattr(args, "bus_config", None)
    try:
        config = dict(can.util.load_config(path=path, config=given, context=getattr(args, "bus_context", None)))
    except can.CanInterfaceNotImplementedError as exc:
        if "interface" in given or path:  # the user named one, and it is wrong
            raise BusError(f"bus configuration: {exc}") from exc
        config = {"interface": DEFAULT_INTERFACE, "channel": DEFAULT_CHANNEL, **given}
    except (can.CanError, ValueError, KeyError) as exc:
        raise BusError(f"bus configuration: {exc}") from exc
    if config["interface"] in ("udp_multicast", "virtual", "socketcan") and "fd" not in config:
        config["fd"] = True  # the PT bus is CAN FD; these interfaces carry it as is
    config.update(overrides)
    return config


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


RCVBUF_BYTES = 4 << 20  # ~2 s of this project's traffic; the kernel caps it at net.core.rmem_max


def _tune_multicast(bus: can.BusABC) -> None:
    """Two fixes for python-can's udp_multicast socket, where we can reach it:

    * Linux hands a socket bound to INADDR_ANY:port the datagrams of *every* group joined on the
      machine (IP_MULTICAST_ALL defaults to 1), so two sessions on different groups but one port
      hear each other: switch that off.
    * The default receive buffer (~200 kB) holds ~0.1 s of a 2 kHz exchange; a process descheduled
      longer loses frames. A larger buffer turns such a stall into latency instead of loss."""
    sock = getattr(getattr(bus, "_multicast", None), "_socket", None)
    if sock is None or not sys.platform.startswith("linux"):
        return
    try:
        if sock.family == socket.AF_INET:
            sock.setsockopt(socket.IPPROTO_IP, IP_MULTICAST_ALL, 0)
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, RCVBUF_BYTES)
    except OSError as exc:  # pragma: no cover - a kernel without the option
        log.debug("udp_multicast socket options not set: %s", exc)


def open_bus(config: dict) -> can.BusABC:
    try:
        bus = can.Bus(**config)
    except (can.CanError, OSError, ValueError, ImportError, TypeError) as exc:
        raise BusError(f"cannot open bus {_describe(config)}: {exc}") from exc
    if config.get("interface") == "udp_multicast":
        _tune_multicast(bus)
    log.info("bus open: %s", _describe(config))
    return bus


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


def _describe(config: dict) -> str:
    return f"{config.get('interface')}:{config.get('channel')}"
