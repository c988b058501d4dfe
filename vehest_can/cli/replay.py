"""``vehest-can replay LOG``: run a recorded log through the ECU offline."""
from __future__ import annotations

import can

from ..bus.log import read_log
from ..service.replay import replay


def add_subparser(subparsers) -> None:
    p = subparsers.add_parser("replay", help="run a recorded CAN log through the ECU offline",
                              description="Replay a log (candump -L, .asc, .blf, .csv, .trc ...) through the ECU. "
                                          "Lockstep logs (with SIM_Sync) are replayed tick for tick and the ECU's "
                                          "output is compared with the one recorded.")
    p.add_argument("log", metavar="LOG")
    p.add_argument("-o", "--output", metavar="FILE", help="write the ECU frames of the replay to this log")
    p.set_defaults(func=run)


def run(args) -> int:
    result = replay(read_log(args.log))
    if args.output:
        with can.Logger(args.output) as writer:
            for m in result.produced:
                m.channel = "vcan0"
                writer.on_message_received(m)
    print(f"replayed {result.frames_in} frames in {result.ticks} ticks (paced by {result.paced_by})")
    print(f"ECU frames: {len(result.produced)} produced, {len(result.logged)} in the log")
    faults = ", ".join(f"{k}={v}" for k, v in result.counters.items() if v) or "none"
    print(f"RX faults: {faults}")
    if result.identical is None:
        print("no ECU frames in the log to compare with")
        return 0
    if result.identical:
        print(f"identical: all {len(result.logged)} ECU frames match the log bit for bit")
        return 0
    print(f"DIFFERENT: first difference at ECU frame {result.first_difference()}")
    return 3
