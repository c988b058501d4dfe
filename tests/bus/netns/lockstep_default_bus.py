"""Run inside a network namespace that has only loopback (see tests/bus/test_host_only.py).

The ECU daemon (its own process) and the simulator, in lockstep over the *default* bus: no
``-i``/``-c`` given, no CAN_* environment. Writes the ECU's frames and the daemon's stderr to OUT.
"""
import argparse
import os
import socket
import subprocess
import sys
from pathlib import Path

import numpy as np

from vehest_can.bus import bus as busmod
from vehest_can.sim.powertrain import powertrain_car
from vehest_can.sim.session import SimMaster
from vehest_can.systems.driveline.scenario import load_driveline_scenario

out = Path(sys.argv[1])
seconds = float(sys.argv[2])
env = {k: v for k, v in os.environ.items() if not k.startswith("CAN_")}
notify = socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM)
notify.bind(str(out / "notify.sock"))
notify.settimeout(0.5)
env["NOTIFY_SOCKET"] = str(out / "notify.sock")
daemon = subprocess.Popen([sys.executable, "-m", "vehest_can.cli", "daemon", "--mode", "lockstep",
                           "--exit-on-end", "--idle-timeout", "60"],
                          stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env)
try:
    while True:  # READY=1: the daemon's bus is open; a daemon that died instead ends the run
        try:
            if b"READY=1" in notify.recv(4096):
                break
        except TimeoutError:
            if daemon.poll() is not None:
                sys.exit(f"the daemon exited {daemon.returncode}: {daemon.communicate()[1]}")
    config = busmod.bus_config(argparse.Namespace())
    bus = busmod.open_bus(config)
    try:
        session = SimMaster(bus, powertrain_car(load_driveline_scenario("launch_2nd"), seconds)).run_lockstep()
    finally:
        bus.shutdown()
    _, err = daemon.communicate(timeout=60)
finally:
    if daemon.poll() is None:
        daemon.kill()
        _, err = daemon.communicate()
(out / "daemon.err").write_text(err)
np.savez(out / "session.npz", frames=session.frames, frame_tick=session.frame_tick,
         config=repr(config), rc=daemon.returncode)
