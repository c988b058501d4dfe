"""``python -m vehest_can.xcp``: the slave on a bus with a simulated ECU memory image, for a bench.

Until the slave is in the ECU daemon, this gives a master (pyxcp, CANape, ...) something live to
measure and calibrate: the demo description's measurements move every tick (``ecu_tick`` counts,
the floats are slow sines of it), characteristics are served from the calibration pages. Buses
the python-can way (``-i/-c``, ``--fd``); the default is python-can's in-process ``virtual``
interface, so traffic stays on this host unless a bus is asked for.
"""
from __future__ import annotations

import argparse
import math
import os
import sys
import time

import can

from ..errors import ConfigError
from . import DEMO, Slave, XcpBridge, load
from .keys import DEV_KEY, load_key


def simulate(slave: Slave):
    desc = slave.desc

    def step(tick: int) -> None:
        for i, m in enumerate(desc.measurements):
            if m.name == "ecu_tick":
                v: float = tick & 0xFFFFFFFF
            elif m.ctype in ("float", "double"):
                v = 100.0 * math.sin(2 * math.pi * tick / (2000.0 + 100 * i))
            else:
                lo, hi = m.raw_limits()
                v = int(lo) + (tick // 20 + i) % (int(hi) - int(lo) + 1)
            slave.write_measurement(m.name, v)
    return step


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m vehest_can.xcp", description=__doc__.splitlines()[0])
    ap.add_argument("description", nargs="?", default=str(DEMO), help="TOML description (default: the demo)")
    ap.add_argument("-i", "--interface", default="virtual", help="python-can interface (default: virtual)")
    ap.add_argument("-c", "--channel", default="xcp", help="python-can channel")
    ap.add_argument("--fd", action="store_true", help="CAN FD frames (with max_cto/max_dto up to 64)")
    ap.add_argument("--seconds", type=float, default=None, help="stop after this long (default: until Ctrl-C)")
    k = ap.add_mutually_exclusive_group(required=True)
    k.add_argument("--key", metavar="FILE", help="seed & key key file (`vehest-can xcp keygen FILE`)")
    k.add_argument("--dev", action="store_true", help="the fixed, public development key (a bench only)")
    args = ap.parse_args(argv)
    desc = load(args.description)
    try:
        key = DEV_KEY if args.dev else load_key(args.key)
    except ConfigError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    if args.dev:
        print("XCP development mode: seed & key with the fixed, public development key", file=sys.stderr)
    slave = Slave(desc, key=key, salt=os.urandom(8))
    with can.Bus(interface=args.interface, channel=args.channel, fd=args.fd or desc.fd) as bus:
        bridge = XcpBridge(bus, slave, on_tick=simulate(slave)).start()
        bridge.start_clock()
        print(f"XCP slave {desc.name} on {args.interface}:{args.channel}: CRO 0x{desc.cro_id:X}, "
              f"DTO 0x{desc.dto_id:X}, MAX_CTO {desc.max_cto}, MAX_DTO {desc.max_dto}", flush=True)
        try:
            t_end = None if args.seconds is None else time.monotonic() + args.seconds
            while t_end is None or time.monotonic() < t_end:
                time.sleep(0.05 if t_end is None else max(0.0, min(0.05, t_end - time.monotonic())))
        except KeyboardInterrupt:
            pass
        finally:
            bridge.stop()
    c = slave.counters()
    print(f"ticks {bridge.tick}, frames sent {bridge.sent}, " + ", ".join(f"{k} {v}" for k, v in c.items() if v))
    return 0


if __name__ == "__main__":
    sys.exit(main())
