"""``vehest-can busload DBC...``: worst-case and nominal bus load per bus (one DBC file = one bus)."""
from __future__ import annotations

import json
import math
import sys
from dataclasses import asdict
from typing import TYPE_CHECKING

from ..bus import bus as busmod
from ..errors import BusError, ConfigError

if TYPE_CHECKING:  # annotations only: the verb's parser loads none of it
    from ..bus.busload import BusLoad, FrameLoad


#: the verb's one line in `vehest-can --help` (read without building its parser)
HELP = "worst-case and nominal bus load from DBC files"


def add_subparser(subparsers) -> None:
    parser = subparsers.add_parser(
        "busload",
        help=HELP,
        description="Bus load per bus (one DBC file = one bus) from each frame's length and cycle time: "
                    "worst case with bit stuffing, nominal without dynamic stuff bits. Classic CAN after "
                    "Davis et al. 2007; CAN FD per ISO 11898-1:2015, arbitration and data phase at their "
                    "own rates. Exit status 0: every bus within --limit; 2: a bus exceeds it; 1: error.",
    )
    parser.add_argument("dbc", nargs="+", metavar="DBC", help="DBC file(s), each one bus")
    parser.add_argument("-b", "--bitrate", metavar="B",
                        help="nominal (arbitration) bit rate in bit/s, e.g. 500000 or 500k "
                             "(default: the DBC's Baudrate attribute)")
    parser.add_argument("--data-bitrate", metavar="D",
                        help="CAN FD data-phase bit rate in bit/s, e.g. 4M; FD frames then use bit rate "
                             "switching (default: the DBC's BaudrateCANFD attribute, else no switching)")
    parser.add_argument("--limit", metavar="PERCENT", default="60",
                        help="worst-case load a bus may have, in %% (default: 60)")
    parser.add_argument("--frames", action="store_true", help="also list every frame")
    parser.add_argument("--json", action="store_true", help="print JSON instead of tables")
    parser.set_defaults(func=run)


def parse_bitrate(text: str | None, option: str) -> int | None:
    """The one bitrate parser (bus.parse_bitrate), its error a ConfigError naming the option."""
    try:
        return busmod.parse_bitrate(text, option)
    except BusError as exc:
        raise ConfigError(str(exc)) from None


def _percent(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        value = math.nan
    if not (math.isfinite(value) and 0 < value <= 100):
        raise ConfigError(f"--limit {text!r}: expected a percentage in (0, 100]")
    return value


def _rate_text(bps: int | None) -> str:
    if bps is None:
        return "-"
    for unit, scale in (("M", 1_000_000), ("k", 1_000)):
        if bps % scale == 0:
            return f"{bps // scale}{unit}"
    return str(bps)


def _cycle_text(frame: FrameLoad) -> str:

    if frame.cycle_us is None:
        return "event"
    us = frame.cycle_us
    return f"{us / 1000:g} ms" if us >= 1000 and us % 1000 == 0 else f"{us:g} us"


def _format(frame: FrameLoad) -> str:

    if not frame.fd:
        return "classic"
    return "FD+BRS" if frame.brs else "FD"


def _bus_table(buses: list[BusLoad], limit: float) -> list[str]:

    head = ("bus", "bitrate", "worst %", "nominal %", "cyclic", "event", f"limit {limit:g}%")
    rows = [(b.bus, f"{_rate_text(b.bitrate)}/{_rate_text(b.data_bitrate)}", f"{b.worst_pct:.1f}",
             f"{b.nominal_pct:.1f}", str(b.cyclic_frames), str(b.event_frames),
             "ok" if b.worst_pct <= limit else "EXCEEDED") for b in buses]
    return _table(head, rows, right=(2, 3, 4, 5))


def _frame_table(bus: BusLoad) -> list[str]:

    head = ("frame", "id", "DLC", "format", "cycle", "bits nom+data", "worst us", "worst %", "nominal %")
    rows = []
    for f in bus.frames:
        ident = f"0x{f.frame_id:08X}" if f.extended else f"0x{f.frame_id:03X}"  # candump style
        rows.append((f.name, ident, str(f.wire_length), _format(f), _cycle_text(f),
                     f"{f.bits_worst[0]}+{f.bits_worst[1]}", f"{f.wire_us_worst:.2f}",
                     "-" if f.event else f"{f.worst_pct:.2f}", "-" if f.event else f"{f.nominal_pct:.2f}"))
    return _table(head, rows, right=(2, 5, 6, 7, 8))


def _table(head, rows, right=()) -> list[str]:
    widths = [max(len(r[i]) for r in (head, *rows)) for i in range(len(head))]
    def line(row):
        return "  ".join(c.rjust(w) if i in right else c.ljust(w)
                         for i, (c, w) in enumerate(zip(row, widths))).rstrip()
    return [line(head), *(line(r) for r in rows)]


def run(args) -> int:
    from ..bus.busload import bus_load

    bitrate = parse_bitrate(args.bitrate, "--bitrate")
    data_bitrate = parse_bitrate(args.data_bitrate, "--data-bitrate")
    if bitrate is not None and data_bitrate is not None and data_bitrate < bitrate:
        raise ConfigError(f"--data-bitrate {data_bitrate} is lower than --bitrate {bitrate}")
    limit = _percent(args.limit)
    buses = [bus_load(path, bitrate, data_bitrate) for path in args.dbc]

    if args.json:
        doc = {"limit_pct": limit, "buses": [
            {**asdict(b), "cyclic_frames": b.cyclic_frames, "event_frames": b.event_frames,
             "within_limit": b.worst_pct <= limit} for b in buses]}
        print(json.dumps(doc, indent=2))
    else:
        print("\n".join(_bus_table(buses, limit)))
        for bus in buses:
            if args.frames:
                print(f"\n{bus.bus} ({bus.source}): bits = nominal-rate + data-rate bits, worst case")
                print("\n".join(_frame_table(bus)))
            # Event frames are already marked in the tables; the other notes say what was assumed.
            notes = [*bus.notes, *(f"{f.name}: {n}" for f in bus.frames for n in f.notes if not f.event
                                   or not n.startswith("event frame"))]
            for note in notes:
                print(f"note: {bus.bus}: {note}", file=sys.stderr)

    over = [b for b in buses if b.worst_pct > limit]
    for b in over:
        print(f"busload: bus {b.bus} worst case {b.worst_pct:.1f}% exceeds the {limit:g}% limit", file=sys.stderr)
    return 2 if over else 0
