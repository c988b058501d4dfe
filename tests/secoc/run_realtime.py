"""A long real-time run with SecOC on (issue 15: "genuine traffic, 0 rejections over a 10-minute
real-time run"): the real-time ECU daemon (its own process, ``--secoc-keys``) and the roll car (plant,
chassis and roll nodes, its roll node secured) at 2 kHz on a private ``udp_multicast`` bus, the ECU's
commands closing the loop into the car's actuators. The car joins the running ECU: its roll node
waits for the ECU's next 1 Hz sync frame before the clock starts (frames before it cannot be
verified). Development keys are made for the run in a private temporary folder and deleted after
it. A lean loop: nothing is recorded, so memory is bounded. --duration is wall time.

    .venv/bin/python tests/secoc/run_realtime.py --duration 600

Prints the ECU's and the roll node's SecOC counters; exits 1 if anything was rejected.
"""
from __future__ import annotations

import argparse
import json
import os
import queue
import signal
import socket
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import can

from vehest_can.bus import bus as busmod
from vehest_can.bus.frames import TICK_S, frame_id, is_own, sent_by, to_message
from vehest_can.bus.rt import Ticker
from vehest_can.bus.secoc import write_dev_keys
from vehest_can.cli.secoc import sending_nodes
from vehest_can.native import lib
from vehest_can.systems.roll.scenario import RollCar, load_roll_scenario


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--duration", type=float, default=60.0, help="seconds of wall time (default 60)")
    ap.add_argument("--out", help="also write the counters here (JSON)")
    ap.add_argument("--scenario", default="roll_paper_72kph_active")
    args = ap.parse_args(argv)
    cfg = busmod.private_multicast()
    with tempfile.TemporaryDirectory(prefix="vehest-secoc-") as tmp:
        keyfile = Path(tmp) / "dev_keys.toml"
        keys = write_dev_keys(keyfile, sending_nodes())
        stats = Path(tmp) / "stats.json"
        notify = socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM)
        notify.bind(str(Path(tmp) / "notify.sock"))
        notify.settimeout(60)
        proc = subprocess.Popen(
            [sys.executable, "-m", "vehest_can.cli", "daemon", "--mode", "realtime", "--secoc-keys", str(keyfile),
             "--secoc-state", "none",  # keys made for this run: nothing to persist
             "--stats", str(stats), *busmod.cli_args(cfg)],
            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True,
            env={**os.environ, "NOTIFY_SOCKET": str(Path(tmp) / "notify.sock")})
        while b"READY=1" not in notify.recv(4096):
            pass
        car = RollCar(load_roll_scenario(args.scenario))
        car.enable_secoc(keys)
        own = sent_by({"CHS", "ROLL"})
        inbox: queue.SimpleQueue = queue.SimpleQueue()

        class Inbox(can.Listener):
            def on_message_received(self, msg):
                if not is_own(msg, own):
                    inbox.put(msg)

        bus = busmod.open_bus(cfg)
        notifier = can.Notifier(bus, [Inbox()], timeout=0.005)
        # The ECU started first: its sync frame of start-up went by unheard. The roll node joins at the
        # ECU's next one (1 Hz); until then it could verify nothing (each would count as unsynced).
        sync_id = frame_id("VEHEST_SecOCSyncCh", "ch")
        t_wait = time.monotonic()
        while not car.secoc["ROLL"].c.rx[lib.vh_secoc_bus_node(b"VEHEST")].synced:
            msg = inbox.get(timeout=5.0)
            if msg.arbitration_id == sync_id:
                car.rx(msg)
        print(f"roll node synchronised to the ECU after {time.monotonic() - t_wait:.2f} s")
        ticker = Ticker(TICK_S)
        sent = heard = k = 0
        t0 = time.monotonic()
        next_report = t0 + 60.0
        try:
            ticker.start()
            while time.monotonic() - t0 < args.duration:  # wall time: a loaded machine runs late, not long
                ticker.wait()
                for f in car.tick(k % car.n):  # the scenario's drive looped, the plant running on
                    bus.send(to_message(f))
                    sent += 1
                while not inbox.empty():
                    car.rx(inbox.get_nowait())
                    heard += 1
                k += 1
                if time.monotonic() >= next_report:
                    next_report += 60.0
                    c = car.secoc["ROLL"].counters()
                    print(f"{time.monotonic() - t0:.0f} s: {k} ticks, roll node accepted {c['accepted']} "
                          f"rejected {c['rejected']}", flush=True)
        finally:
            n_ticks = k
            wall = time.monotonic() - t0
            notifier.stop()
            bus.shutdown()
            proc.send_signal(signal.SIGTERM)
            _, err = proc.communicate(timeout=60)
        ecu = json.loads(stats.read_text()).get("secoc", {})
    node = car.secoc["ROLL"].counters()
    print(f"real time {wall:.0f} s ({n_ticks} ticks, {ticker.misses} car deadline misses): car sent {sent} frames, "
          f"heard {heard} of the ECU's")
    print("ECU (VEHEST) SecOC: " + ", ".join(f"{k} {v}" for k, v in ecu.items()))
    print("roll node (ROLL) SecOC: " + ", ".join(f"{k} {v}" for k, v in node.items())
          + f"; commands rejected {car.node.cnt_rejected}, command timeouts {car.node.cnt_timeout}")
    bad = ecu.get("rejected", 1) + node["rejected"] + car.node.cnt_rejected
    if args.out:
        Path(args.out).write_text(json.dumps({"wall_s": wall, "ticks": n_ticks, "car_deadline_misses": ticker.misses,
                                              "ecu": ecu, "roll_node": node,
                                              "commands_rejected": car.node.cnt_rejected}, indent=2) + "\n")
    print(("0 rejections" if bad == 0 else f"{bad} REJECTIONS") + f"; daemon: {err.strip().splitlines()[-1:]}")
    return 0 if bad == 0 else 1


if __name__ == "__main__":
    sys.exit(main())
