"""Lockstep sessions over a bus, the ECU daemon in its own process; optionally captured by candump.

    python tests/vcan_guest/lockstep_sessions.py OUT [-i socketcan] [-c vcan0] [--duration S]
        [--capture] [--daemon-log] SCENARIO...

Starts ``vehest-can daemon --mode lockstep --stats OUT/daemon.json`` (``--daemon-log``: also
``--log OUT/daemon.log``), waits until it answers a RESET, then per scenario (shipped name or
file; ``--duration`` overrides the scenario's own length) runs the simulator (``SimMaster``) in
lockstep, with ``--capture`` under ``candump -L vcan0 > OUT/<name>.candump.log``, and saves the
simulator's session (every frame with its tick, the plant's truth) to ``OUT/<name>.session.npz``.
Finally SIGTERMs the daemon. Prints one JSON document: per scenario ticks, frames and wall
seconds, candump's exit status, the daemon's exit status, summary and statistics.

Runs on any python-can bus (``-i udp_multicast -c 239.74.x.y`` on the host); ``--capture`` needs
a SocketCAN channel. Inside user-mode Linux:

    vehest-can uml -- .venv/bin/python tests/vcan_guest/lockstep_sessions.py \\
        out/vcan --capture --daemon-log launch_2nd tip_in_tip_out
"""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import guestlib  # noqa: E402

from vehest_can.sim.session import SimMaster  # noqa: E402
from vehest_can.systems import load_any_scenario  # noqa: E402


def main() -> None:
    p = argparse.ArgumentParser()
    p.add_argument("out")
    p.add_argument("scenarios", nargs="+")
    p.add_argument("-i", "--interface", default="socketcan")
    p.add_argument("-c", "--channel", default=guestlib.CHANNEL)
    p.add_argument("--duration", type=float)
    p.add_argument("--capture", action="store_true")
    p.add_argument("--daemon-log", action="store_true")
    args = p.parse_args()
    out = guestlib.out_dir(args.out)
    result = {"interface": args.interface, "channel": args.channel, "sessions": {}}

    extra = ["--log", str(out / "daemon.log")] if args.daemon_log else []
    t0 = time.monotonic()
    daemon = guestlib.start_daemon(out, "daemon", "--mode", "lockstep", *extra,
                                   interface=args.interface, channel=args.channel)
    bus = guestlib.open_bus(args.interface, args.channel)
    try:
        result["handshake_resets"] = guestlib.wait_for_lockstep_daemon(bus)
        result["daemon_start_s"] = time.monotonic() - t0
        for name in args.scenarios:
            system, sc = load_any_scenario(name)   # any registered system's scenario
            drive = system.car(sc, args.duration)
            entry = result["sessions"][sc.name] = {"ticks": drive.n}
            dump = None
            if args.capture:
                # -T: candump ends itself after 2 s without a frame, once it has read everything
                dump = guestlib.start_candump(out / f"{sc.name}.candump.log", "-T", "2000")
            t1 = time.monotonic()
            session = SimMaster(bus, drive, ack_timeout=30.0).run_lockstep(end=False)
            entry["wall_s"] = time.monotonic() - t1
            entry["frames"] = len(session.frames)
            np.savez(out / f"{sc.name}.session.npz", frames=session.frames,
                     frame_tick=session.frame_tick, truth=session.truth)
            if dump is not None:
                entry["candump_rc"] = guestlib.finish_candump(dump)
                entry["candump_stderr"] = dump.stderr.read()
    finally:
        bus.shutdown()
        result["daemon"] = guestlib.daemon_result(out, "daemon", daemon)
    result["total_s"] = time.monotonic() - t0
    guestlib.emit(result)


if __name__ == "__main__":
    main()
