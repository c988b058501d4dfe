"""``vehest-can daemon``: the ECU prototype daemon on a bus (lockstep or real time)."""
from __future__ import annotations

import json
import sys
from dataclasses import asdict, replace
from pathlib import Path

from ..bus import bus as busmod
from ..errors import ConfigError
from ..service import sdnotify
from ..service.daemon import EcuDaemon
from ..systems.camber.api import load_calibrations
from ..systems.ecu import Ecu, EcuConfig
from ..xcp import ecu as xcp_ecu
from ._common import add_log_arguments, check_log_arguments, open_session_log


def add_subparser(subparsers) -> None:
    p = subparsers.add_parser("daemon", help="run the ECU on a CAN bus",
                              description="Run the ECU firmware on a python-can bus until SIGINT/SIGTERM.")
    p.add_argument("--mode", choices=("lockstep", "realtime"), default="realtime",
                   help="lockstep: step on the simulator's SIM_Sync frames; realtime: own 2 kHz clock (default)")
    add_log_arguments(p)
    p.add_argument("--duration", type=float, metavar="S", help="realtime: stop after S seconds")
    p.add_argument("--exit-on-end", action="store_true", help="lockstep: stop when the simulator sends END")
    p.add_argument("--camber-cal", metavar="FILE",
                   help="camber inspection calibration file (written by `vehest-can camber calibrate`)")
    p.add_argument("--rx-burst-limit", type=int, default=2, metavar="N",
                   help="more frames of one message in a 500 us tick than N are a burst of stale samples, "
                        "not used until the message is regular again (default 2; 0 = off, for transports "
                        "that deliver in batches)")
    p.add_argument("--stats", metavar="FILE", help="write the run's statistics as JSON on exit")
    p.add_argument("--idle-timeout", type=float, metavar="S", help="lockstep: stop after S seconds without a frame")
    sdnotify.add_log_level(p)
    xcp_ecu.add_arguments(p)  # the XCP slave in the ECU (its own flags, docs/xcp.md)
    busmod.add_arguments(p)
    p.set_defaults(func=run)


def run(args) -> int:
    if args.duration is not None and args.duration <= 0:
        raise ConfigError("--duration must be positive")
    check_log_arguments(args)
    sdnotify.apply_log_level(args.log_level)
    ecu = Ecu(replace(EcuConfig.default(), rx_burst_frames=args.rx_burst_limit))
    if args.camber_cal:
        ecu.set_camber_calibrations(load_calibrations(args.camber_cal))
    xcp = xcp_ecu.from_args(args, ecu)
    config = busmod.bus_config(args)
    bus = busmod.open_bus(config)
    print(f"vehest-can daemon: bus {busmod.describe_bus(bus, config)}", file=sys.stderr, flush=True)
    writer = open_session_log(args, {"VEHEST"})  # the log sets each frame's channel (its bus)
    daemon = EcuDaemon(bus, ecu, log_writer=writer, notifier=sdnotify.Notifier.from_env())
    with busmod.serving(bus, writer, daemon.stop_event.set):
        if args.mode == "lockstep":
            stats = daemon.serve_lockstep(exit_on_end=args.exit_on_end, idle_timeout=args.idle_timeout)
        else:
            stats = daemon.serve_realtime(duration=args.duration)
    print("\n".join(stats.lines()), file=sys.stderr)
    if xcp is not None:
        print(xcp_ecu.summary(ecu), file=sys.stderr)
    if args.stats:
        Path(args.stats).write_text(json.dumps(asdict(stats), indent=2) + "\n")
    return 0
