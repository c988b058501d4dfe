"""``vehest-can monitor``: a live view of the ECU's estimates, validity, health and fault counters."""
from __future__ import annotations

import shutil
import sys
import time

from ..bus import bus as busmod
from ._common import check_seconds

#: the verb's one line in `vehest-can --help` (read without building its parser)
HELP = "live view of the ECU's estimates, health and fault counters"


def add_subparser(subparsers) -> None:
    p = subparsers.add_parser("monitor", help=HELP,
                              description="Listen on a python-can bus and show the latest value of every signal "
                                          "the ECU publishes, decoded through the DBCs (cantools monitor style). "
                                          "On a terminal the screen is redrawn; otherwise (or with --once) "
                                          "one snapshot is printed at the end. Ctrl-C stops.")
    p.add_argument("--duration", type=float, metavar="S", help="stop after S seconds (default: until Ctrl-C)")
    p.add_argument("--refresh", type=float, default=0.25, metavar="S", help="redraw every S seconds (0.25)")
    p.add_argument("--once", action="store_true", help="no redrawing: print one snapshot when it stops")
    busmod.add_arguments(p)
    p.set_defaults(func=run)


def run(args) -> int:
    from ..service.monitor import Monitor

    check_seconds(args.duration, "--duration", maximum=365 * 86400.0)
    check_seconds(args.refresh, "--refresh", maximum=60.0)
    live = sys.stdout.isatty() and not args.once
    bus = busmod.open_bus(busmod.bus_config(args))
    mon = Monitor()
    t0 = time.monotonic()
    next_draw = t0
    stop = []
    try:
        with busmod.stop_on_signals(lambda: stop.append(1)):
            while not stop and (args.duration is None or time.monotonic() - t0 < args.duration):
                msg = bus.recv(timeout=0.05)
                if msg is not None:
                    mon.feed(msg)
                if live and time.monotonic() >= next_draw:
                    width = min(shutil.get_terminal_size().columns, 160)
                    sys.stdout.write("\x1b[H\x1b[J" + "\n".join(mon.render(width)) + "\n")
                    sys.stdout.flush()
                    next_draw = time.monotonic() + args.refresh
    finally:
        bus.shutdown()
    if not live:
        print("\n".join(mon.render(100)))
    return 0
