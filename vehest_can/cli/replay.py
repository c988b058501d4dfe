"""``vehest-can replay LOG``: run a recorded log through the ECU offline, or play it onto a bus."""
from __future__ import annotations

from pathlib import Path

from ..bus import bus as busmod
from ..bus.formats import MAX_GAP_S, TABLE_FORMATS
from ..errors import ConfigError
from ._common import add_car_argument, car_from_args, check_range
from ._target import add_target_argument, make_ecu

_BUS_FLAGS = ("interface", "channel", "bitrate", "fd", "data_bitrate", "timing", "bus_kwargs", "bus_config", "bus_context")


#: the verb's one line in `vehest-can --help` (read without building its parser)
HELP = "run a recorded CAN log through the ECU offline, or play it onto a bus"


def add_subparser(subparsers) -> None:
    p = subparsers.add_parser("replay", help=HELP,
                              description="Replay a log (candump -L, .asc, .blf, .mf4 ...) through the ECU. "
                                          "Lockstep logs (with SIM_Sync) are replayed tick for tick and the ECU's "
                                          "output is compared with the one recorded. Exit status 3 when it differs. "
                                          "With --play, the log's frames are sent onto a bus at their recorded pace "
                                          "instead (like canplayer), for an ECU on that bus.")
    p.add_argument("log", metavar="LOG")
    p.add_argument("-o", "--output", metavar="FILE",
                   help="write the ECU frames of the replay to this log (format by extension, as --log)")
    p.add_argument("--table", metavar="FILE",
                   help="write the ECU's estimates decoded, one row per ECU frame with the log's time, to a table: "
                        + ", ".join(f"{k} ({v})" for k, v in TABLE_FORMATS.items()))
    p.add_argument("--max-gap", type=float, default=MAX_GAP_S, metavar="S",
                   help=f"a gap between frames longer than S seconds is not stepped through tick by tick: the ECU "
                        f"steps S seconds of idle ticks, then the clock jumps to the next frame; with --play, the "
                        f"gap is shortened to S (default {MAX_GAP_S:g}; one tick..3600)")
    p.add_argument("--play", action="store_true",
                   help="send the log's frames (not the ECU's own) onto the bus of -i/-c at their recorded pace "
                        "(default: udp_multicast on this host only)")
    add_car_argument(p, "the car the ECU is calibrated for (a car file, docs/car.md, or a shipped car's name: "
                        "paper, commonroad_vehicle1 .. 3); default: the paper's. A log recorded with an ECU "
                        "calibrated for another car replays DIFFERENT")
    add_target_argument(p)
    busmod.add_arguments(p)
    p.set_defaults(func=run)


def run(args) -> int:
    # a gap shorter than a tick is no gap; an hour of idle ticks is 7.2 M steps of the ECU
    from ..bus.frames import TICK_S
    from ..bus.log import check_log_file
    from ..systems.ecu import EcuConfig

    check_range(args.max_gap, "--max-gap", TICK_S, 3600.0, "seconds")
    if args.play:
        if args.car or args.target != "host":
            raise ConfigError("--car and --target choose the offline replay's ECU; --play only sends the log onto a bus")
        return _play(args)
    given = [f for f in _BUS_FLAGS if getattr(args, f, None) not in (None, False, [], {})]  # python-can's: absent if not given
    if given:
        raise ConfigError(f"bus options ({', '.join('--' + f.replace('_', '-') for f in given)}) apply to --play only: "
                          "the offline replay uses no bus")
    check_log_file(args.log)
    ecu = make_ecu(args, EcuConfig(car=car_from_args(args, plant=False)))
    try:
        return _replay(args, ecu)
    finally:
        if hasattr(ecu, "close"):
            ecu.close()  # the emulator


def _replay(args, ecu) -> int:
    from ..bus.log import SessionLog, check_log_path
    from ..progress import Progress
    from ..service.estimates import EstimateTable, check_table_path
    from ..service.replay import ECU_TX, replay_file

    table_path = check_table_path(args.table) if args.table else None
    writer = SessionLog(check_log_path(args.output), {"VEHEST"}) if args.output else None
    table = None
    try:
        table = EstimateTable(table_path, ECU_TX) if table_path else None
        progress = Progress(f"replay {Path(args.log).name}", unit="B")
        result = replay_file(args.log, ecu, writer=writer, table=table, max_gap_s=args.max_gap, progress=progress)
        progress.done()
    finally:
        if writer is not None:
            writer.stop()
        if table is not None:
            table.close()
    print(f"replayed {result.frames_in} frames in {result.ticks} ticks (paced by {result.paced_by})")
    if result.gaps:
        print(f"gaps: {result.gaps} longer than {args.max_gap:g} s, {result.idle_ticks_skipped} idle ticks "
              f"not stepped ({result.idle_ticks_skipped * 0.0005:.1f} s)")
    if result.backwards:
        print(_backwards(result, args.max_gap))
    if result.out_of_order:
        print(f"out of order: {result.out_of_order} frames older than one before them (handed in late)")
    print(f"ECU frames: {result.n_produced} produced, {result.n_logged} in the log")
    if table is not None:
        print(f"estimates: {table.rows} rows written to {table.path}")
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


def _play(args) -> int:
    from ..bus.log import check_log_frames
    from ..service.replay import play

    offline = [flag for flag, v in (("-o/--output", args.output), ("--table", args.table)) if v]
    if offline:
        raise ConfigError(f"{' and '.join(offline)} write the offline replay's results; --play only sends the log "
                          "onto a bus (log the ECU there with `vehest-can daemon --log`)")
    check_log_frames(args.log)
    config = busmod.bus_config(args)
    bus = busmod.open_bus(config)
    try:
        print(f"playing {args.log} onto {busmod.describe_bus(bus, config)}", flush=True)
        r = play(args.log, bus, max_gap_s=args.max_gap)
    finally:
        bus.shutdown()
    print(f"sent {r.sent} frames in {r.seconds:.2f} s ({r.not_sent} ECU frames of the log not sent"
          + (f", {r.send_failures} refused by the bus" if r.send_failures else "")
          + (f", {r.gaps} gaps shortened to {args.max_gap:g} s" if r.gaps else "") + ")")
    if r.backwards:
        print(_backwards(r, args.max_gap))
    print(f"latest frame: {1e3 * r.late_max_s:.1f} ms behind its recorded time")
    return 1 if r.send_failures else 0


def _backwards(r, max_gap: float) -> str:
    """The summary line of a log whose time goes backwards (a ReplayResult or a PlayResult)."""
    text = (f"backwards in time: {r.backwards} frames earlier than the frame before them (largest step back "
            f"{r.backward_max_s:.6g} s)")
    if r.jumps_back:
        text += f"; {r.jumps_back} more than {max_gap:g} s back: the log's clock went on from the frame before"
    return text
