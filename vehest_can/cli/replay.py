"""``vehest-can replay LOG``: run a recorded log through the ECU offline."""
from __future__ import annotations

import math
from pathlib import Path

from ..bus.log import SessionLog, check_log_path
from ..errors import ConfigError
from ..progress import Progress
from ..service.replay import MAX_GAP_S, replay_file


def add_subparser(subparsers) -> None:
    p = subparsers.add_parser("replay", help="run a recorded CAN log through the ECU offline",
                              description="Replay a log (candump -L, .asc, .blf, .mf4 ...) through the ECU. "
                                          "Lockstep logs (with SIM_Sync) are replayed tick for tick and the ECU's "
                                          "output is compared with the one recorded. Exit status 3 when it differs.")
    p.add_argument("log", metavar="LOG")
    p.add_argument("-o", "--output", metavar="FILE",
                   help="write the ECU frames of the replay to this log (format by extension, as --log)")
    p.add_argument("--max-gap", type=float, default=MAX_GAP_S, metavar="S",
                   help=f"a gap between frames longer than S seconds is not stepped through tick by tick: the ECU "
                        f"steps S seconds of idle ticks, then the clock jumps to the next frame (default {MAX_GAP_S:g})")
    p.set_defaults(func=run)


def run(args) -> int:
    if not (math.isfinite(args.max_gap) and args.max_gap > 0):
        raise ConfigError(f"--max-gap must be a positive number of seconds, not {args.max_gap}")
    writer = SessionLog(check_log_path(args.output), {"VEHEST"}) if args.output else None
    try:
        progress = Progress(f"replay {Path(args.log).name}", unit="B")
        result = replay_file(args.log, writer=writer, max_gap_s=args.max_gap, progress=progress)
        progress.done()
    finally:
        if writer is not None:
            writer.stop()
    print(f"replayed {result.frames_in} frames in {result.ticks} ticks (paced by {result.paced_by})")
    if result.gaps:
        print(f"gaps: {result.gaps} longer than {args.max_gap:g} s, {result.idle_ticks_skipped} idle ticks "
              f"not stepped ({result.idle_ticks_skipped * 0.0005:.1f} s)")
    if result.out_of_order:
        print(f"out of order: {result.out_of_order} frames older than one before them (handed in late)")
    print(f"ECU frames: {result.n_produced} produced, {result.n_logged} in the log")
    faults = ", ".join(f"{k}={v}" for k, v in result.counters.items() if v) or "none"
    print(f"RX faults: {faults}")
    if result.identical is None:
        print("no ECU frames in the log to compare with")
        return 0
    if result.identical:
        print(f"identical: all {result.n_logged} ECU frames match the log bit for bit")
        return 0
    print(f"DIFFERENT: first difference at ECU frame {result.first_difference()}")
    return 3
