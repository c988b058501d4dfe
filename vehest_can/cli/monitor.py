"""``vehest-can monitor``: every frame on a bus decoded (the bundled DBCs and one's own), with keys."""
from __future__ import annotations

import sys
import time

from ..bus import bus as busmod
from ._common import check_seconds

#: the verb's one line in `vehest-can --help` (read without building its parser)
HELP = "live view of a bus: every frame decoded, pause, filter, raw view"


def add_subparser(subparsers) -> None:
    p = subparsers.add_parser("monitor", help=HELP,
                              description="Listen on a python-can bus and show every message on it decoded through "
                                          "the DBCs (the bundled ones and --dbc), each with its rate and age; the "
                                          "ECU's messages are listed before they are heard, frames of an ID in no "
                                          "DBC are shown raw. On a terminal, keys as in cantools monitor: q quit, "
                                          "p or space pause, f or / filter (a regex on message, ID, bus or signal; "
                                          "Enter keeps, Esc cancels), x raw/decoded view, r reset, arrows, "
                                          "PgUp/PgDn, Home/End scroll. Otherwise (stdout not a terminal, or "
                                          "--once) one snapshot is printed when it stops (--duration, Ctrl-C).")
    p.add_argument("--dbc", action="append", default=[], metavar="FILE",
                   help="a database of one's own (DBC, or any format cantools reads), over the bundled ones: an ID "
                        "in both is decoded by FILE; repeatable")
    p.add_argument("--filter", metavar="REGEX", default="",
                   help="start with this filter (case-insensitive regex on message names, IDs, buses, signal names)")
    p.add_argument("--raw", action="store_true", help="start in the raw view (each ID's latest payload in hex)")
    p.add_argument("--duration", type=float, metavar="S", help="stop after S seconds (default: until q or Ctrl-C)")
    p.add_argument("--refresh", type=float, default=0.25, metavar="S", help="redraw every S seconds (0.25)")
    p.add_argument("--once", action="store_true", help="no screen: print one snapshot when it stops")
    busmod.add_arguments(p)
    p.set_defaults(func=run)


def run(args) -> int:
    from ..service.monitor import Monitor, compile_filter

    check_seconds(args.duration, "--duration", maximum=365 * 86400.0)
    check_seconds(args.refresh, "--refresh", maximum=60.0)
    mon = Monitor(args.dbc)  # a bad --dbc is an error before the bus opens
    live = sys.stdout.isatty() and sys.stdin.isatty() and not args.once
    bus = busmod.open_bus(busmod.bus_config(args))
    stop: list[int] = []
    try:
        with busmod.stop_on_signals(lambda: stop.append(1)):
            if live:
                from ..service import monitor_screen

                monitor_screen.run(bus, mon, duration=args.duration, refresh=args.refresh, stopped=lambda: bool(stop),
                                   filter_text=args.filter, raw=args.raw)
            else:
                t0 = time.monotonic()
                while not stop and (args.duration is None or time.monotonic() - t0 < args.duration):
                    msg = bus.recv(timeout=0.05)
                    if msg is not None:
                        mon.feed(msg)
    finally:
        bus.shutdown()
    if not live:
        print("\n".join(mon.render(100, pattern=compile_filter(args.filter), raw=args.raw)))
    return 0
