"""``vehest-can daemon``: the ECU prototype daemon on a bus (lockstep or real time)."""
from __future__ import annotations

import json
import math
import sys
from contextlib import contextmanager
from dataclasses import asdict, replace
from pathlib import Path
from typing import TYPE_CHECKING

from ..bus import bus as busmod
from ..errors import ConfigError
from ._common import (
    add_car_argument,
    add_log_arguments,
    add_secoc_arguments,
    car_from_args,
    check_log_arguments,
    check_range,
    check_seconds,
    open_session_log,
    secoc_from_args,
)
from ._target import add_target_argument, make_ecu, on_qemu, refuse_on_qemu

if TYPE_CHECKING:  # annotations only: the verb's parser loads none of it
    from ..systems.ecu import Ecu


#: the verb's one line in `vehest-can --help` (read without building its parser)
HELP = "run the ECU on a CAN bus"


def add_subparser(subparsers) -> None:
    from ..service import sdnotify
    from ..xcp.args import add_arguments as add_xcp_arguments

    p = subparsers.add_parser("daemon", help=HELP,
                              description="Run the ECU firmware on a python-can bus until SIGINT/SIGTERM.")
    p.add_argument("--mode", choices=("lockstep", "realtime"), default="realtime",
                   help="lockstep: step on the simulator's SIM_Sync frames; realtime: own 2 kHz clock (default)")
    add_log_arguments(p)
    p.add_argument("--duration", type=float, metavar="S", help="stop after S seconds (of wall time)")
    p.add_argument("--exit-on-end", action="store_true", help="lockstep: stop when the simulator sends END")
    p.add_argument("--camber-cal", metavar="FILE",
                   help="camber inspection calibration file (written by `vehest-can camber calibrate`)")
    p.add_argument("--rx-burst-limit", type=int, default=2, metavar="N",
                   help="more frames of one message in a 500 us tick than N are a burst of stale samples, "
                        "not used until the message is regular again (default 2; 0 = off, for transports "
                        "that deliver in batches)")
    p.add_argument("--stats", metavar="FILE", help="write the run's statistics as JSON on exit")
    p.add_argument("--report", metavar="FILE",
                   help="realtime: append a JSON line every --report-every seconds (totals so far, the window's "
                        "latency and lateness percentiles)")
    p.add_argument("--report-every", type=float, default=60.0, metavar="S", help="seconds between reports (default 60)")
    p.add_argument("--idle-timeout", type=float, metavar="S", help="lockstep: stop after S seconds without a frame")
    p.add_argument("--hil", metavar="CONFIG",
                   help="open every bus the ECU (VEHEST) is on in this HIL configuration (docs/hil.md), one adapter "
                        "each, each frame sent on its DBC's bus; instead of the python-can bus flags")
    add_car_argument(p, "the car the ECU is calibrated for (a car file, docs/car.md, or a shipped car's name: "
                        "paper, commonroad_vehicle1 .. 3); default: the paper's")
    add_target_argument(p)
    sdnotify.add_log_level(p)
    add_xcp_arguments(p)  # the XCP slave in the ECU (its own flags, docs/xcp.md)
    add_secoc_arguments(p)
    busmod.add_arguments(p)
    p.set_defaults(func=run)


def run(args) -> int:
    from ..service import sdnotify
    from ..systems.camber.api import load_calibrations, load_into_ecu
    from ..systems.ecu import EcuConfig
    from ..xcp import ecu as xcp_ecu

    for flag, value in (("--duration", args.duration), ("--idle-timeout", args.idle_timeout),
                        ("--report-every", args.report_every)):
        check_seconds(value, flag, maximum=math.inf)
    check_range(args.rx_burst_limit, "--rx-burst-limit", 0, 255, "frames per message and tick")  # a uint8 in C
    if args.mode == "realtime":
        given = [flag for flag, on in (("--idle-timeout", args.idle_timeout is not None),
                                        ("--exit-on-end", args.exit_on_end)) if on]
        if given:
            verb = "applies" if len(given) == 1 else "apply"
            raise ConfigError(f"{' and '.join(given)} only {verb} to --mode lockstep (a real-time daemon has no "
                              f"simulator's END and ticks through silence): use --duration")
    elif args.report:
        raise ConfigError("--report applies to --mode realtime (a lockstep daemon's time is the simulator's)")
    check_log_arguments(args)
    if on_qemu(args) and args.mode != "lockstep":
        raise ConfigError(f"--target {args.target} needs --mode lockstep: an emulator's time is not the target's, it cannot "
                          "keep a 2 kHz wall clock")
    refuse_on_qemu(args, **{"--xcp": "the emulated board has no AES backend for the slave's seed & key",
                            "--secoc-keys": "the emulated board has no AES backend"})
    sdnotify.apply_log_level(args.log_level)
    ecu = make_ecu(args, replace(EcuConfig.default(), rx_burst_frames=args.rx_burst_limit,
                                 car=car_from_args(args, plant=False)))
    if args.camber_cal:
        cals = load_calibrations(args.camber_cal)
        if hasattr(ecu, "apply"):  # the emulated ECU: set on the host's copy of its state, written back
            ecu.apply(lambda e: load_into_ecu(e, cals))
        else:
            load_into_ecu(ecu, cals)
    xcp = xcp_ecu.from_args(args, ecu)
    xcp_config = xcp_ecu.bus_config(args, xcp)  # checked before any bus opens
    secoc = secoc_from_args(args, "VEHEST")
    if secoc is not None:
        ecu.enable_secoc(*secoc)
        if secoc[1] is not None:
            print(f"vehest-can daemon: SecOC freshness state {secoc[1].path}", file=sys.stderr, flush=True)
    try:
        return _serve(args, ecu, xcp, xcp_config)
    finally:
        if ecu.secoc is not None:
            ecu.secoc.close()  # the exact state of a clean end (a kill -9 leaves the last second's)
        if hasattr(ecu, "close"):
            ecu.close()  # the emulator


def _serve(args, ecu: Ecu, xcp, xcp_config) -> int:
    from ..service import sdnotify
    from ..service.daemon import EcuDaemon
    from ..xcp import ecu as xcp_ecu

    buses, routes, channel = _open_buses(args)
    rx_by_bus = {}
    if xcp_config is not None:  # a bus of its own for XCP: its frames go there, the rest stay; it listens there only
        buses, routes = _add_xcp_bus(buses, routes, channel, xcp_config, xcp)
        rx_by_bus = {"xcp": lambda msg: xcp_ecu.rx_own(ecu, msg)}
    writer = open_session_log(args, {"VEHEST"})  # the log sets each frame's channel (its bus)
    daemon = EcuDaemon(buses if len(buses) > 1 else next(iter(buses.values())), ecu, log_writer=writer,
                       log_channel=channel, notifier=sdnotify.Notifier.from_env(), routes=routes,
                       rx_by_bus=rx_by_bus)
    first, *others = buses.values()
    with busmod.serving(first, writer, daemon.stop_event.set), _closing(others):
        if args.mode == "lockstep":
            stats = daemon.serve_lockstep(exit_on_end=args.exit_on_end, idle_timeout=args.idle_timeout,
                                          duration=args.duration)
        elif args.report:
            with open(args.report, "a") as fh:
                def report(snapshot: dict) -> None:
                    fh.write(json.dumps(snapshot) + "\n")
                    fh.flush()
                stats = daemon.serve_realtime(duration=args.duration, report=report, report_every=args.report_every)
        else:
            stats = daemon.serve_realtime(duration=args.duration)
    print("\n".join(stats.lines()), file=sys.stderr)
    if xcp is not None:
        print(xcp_ecu.summary(ecu), file=sys.stderr)
    if ecu.secoc is not None:
        print("SecOC: " + ", ".join(f"{k} {v}" for k, v in ecu.secoc.counters().items()), file=sys.stderr)
    if args.stats:
        doc = asdict(stats) | ({"secoc": ecu.secoc.counters()} if ecu.secoc is not None else {}) | \
            ({"xcp": xcp_ecu.state(ecu)} if xcp is not None else {})
        Path(args.stats).write_text(json.dumps(doc, indent=2) + "\n")
    return 0


def _open_buses(args) -> tuple[dict, dict, str | None]:
    """({name: bus}, frame ID -> bus name, log channel): the python-can flags' one bus, or each bus the
    ECU is on in a HIL configuration."""
    from ..service.hil import load_hil_config

    if not args.hil:
        config = busmod.bus_config(args)
        bus = busmod.open_bus(config)
        print(f"vehest-can daemon: bus {busmod.describe_bus(bus, config)}", file=sys.stderr, flush=True)
        return {"": bus}, {}, config.get("channel") if config["interface"] == "socketcan" else "vcan0"
    flags = [f for f in ("interface", "channel", "bitrate", "data_bitrate", "bus_config", "bus_kwargs")
             if getattr(args, f, None)]
    if flags:
        raise ConfigError(f"--hil takes the buses from {args.hil}: leave out the bus flags "
                          f"({', '.join('--' + f.replace('_', '-') for f in flags)})")
    hil = load_hil_config(args.hil)
    if not hil.ecu_buses:
        raise ConfigError(f"{args.hil}: the ECU (VEHEST) is not simulated there: nothing for the daemon to serve "
                          f"(declare VEHEST in nodes.simulated)")
    buses: dict = {}
    try:
        for name in hil.ecu_buses:
            buses[name] = busmod.open_bus(hil.bus_kwargs(name))
            print(f"vehest-can daemon: bus {name}: {busmod.describe_bus(buses[name], hil.bus_kwargs(name))}",
                  file=sys.stderr, flush=True)
    except BaseException:
        for b in buses.values():
            b.shutdown()
        raise
    return buses, hil.ecu_routes(), None


def _add_xcp_bus(buses: dict, routes: dict, channel: str | None, config: dict, desc) -> tuple[dict, dict]:
    """The XCP bus beside the ECU's, as "xcp": the slave's RES/ERR/DTO are routed there, and its CRO
    is taken there only (a CRO on another bus is counted, cro_foreign, and not answered)."""
    if "xcp" in buses:
        raise ConfigError("the HIL configuration has a bus named 'xcp' already: leave out --xcp-interface/--xcp-channel")
    try:
        bus = busmod.open_bus(config)
    except BaseException:
        for b in buses.values():
            b.shutdown()
        raise
    print(f"vehest-can daemon: XCP bus {busmod.describe_bus(bus, config)}", file=sys.stderr, flush=True)
    if list(buses) == [""]:  # one bus: named by its log channel now that there are two
        buses = {channel or "bus": buses[""]}
    return {**buses, "xcp": bus}, {**routes, desc.dto_id & 0x1FFFFFFF: "xcp"}


@contextmanager
def _closing(buses):
    try:
        yield
    finally:
        for b in buses:
            b.shutdown()
