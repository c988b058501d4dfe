"""The ECU daemon on vcan0 against can-utils: played-back sensors, hostile frames, a link outage.

    python tests/vcan_guest/realtime_faults.py OUT [PHASE...]

Phases (default: all, in this order), each with its own daemon process:

* ``canplayer``: writes ``OUT/sensors.log``, the DLS_Sensors frames of ``launch_2nd`` from 1 s to
  4 s in candump -L format, 0.5 ms apart; ``canplayer -I`` plays it, with its timing, into a
  real-time daemon; ``candump -L vcan0`` records everything (``OUT/canplayer.candump.log``).
* ``hostile``: ``cansend`` injects a repeated frame (frozen counter), a bad CRC, a counter
  jump, wrong lengths (FD 12 bytes, classic 8, an extended 0x100), unknown IDs and a remote
  frame into a real-time daemon; then marker ``7AA``, a ``cangen`` flood at full speed (20000
  mixed frames of random IDs, plus 5000 CAN FD frames on the DLS_Sensors ID with random
  payloads), marker ``7AB``. ``candump`` records the standard IDs 0x300 (VEHEST_Status) and
  0x7AA/0x7AB (``OUT/hostile.candump.log``; the flood may hit those IDs too).
* ``link_rt``: ``ip link set vcan0 down``, 1 s, ``up`` under a running real-time daemon, then
  one bad-CRC DLS frame and one unknown ID to show it receives again; ``candump -D`` records
  VEHEST_Status (``OUT/link_rt.candump.log``).
* ``link_lockstep``: the same outage under an idle lockstep daemon, then a 0.5 s lockstep
  session of ``launch_2nd`` from the simulator (``OUT/link_lockstep.session.npz``).

Every daemon is stopped with SIGTERM; its exit status, stderr (the summary) and ``--stats``
JSON go into the one JSON document printed on stdout, with what was injected.
"""
from __future__ import annotations

import subprocess
import sys
import time
from pathlib import Path

import can
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import guestlib  # noqa: E402
from guestlib import STATUS_ID, cansend, cansend_frame  # noqa: E402

from vehest_can.bus.frames import frame_id, message, to_message  # noqa: E402
from vehest_can.sim.powertrain import powertrain_car
from vehest_can.sim.session import SimMaster, run_inprocess  # noqa: E402
from vehest_can.systems.driveline.scenario import load_driveline_scenario  # noqa: E402
from vehest_can.systems.ecu import Ecu

DLS_ID = frame_id("DLS_Sensors")
DLS_LEN = message("DLS_Sensors").length  # with its SecOC tail
SCENARIO = "launch_2nd"
PLAY_FROM_S, PLAY_S = 1.0, 3.0
# Markers around the flood: payloads the flood's random frames will not repeat.
MARK_BEFORE, MARK_AFTER = "7AA#0102030405060708", "7AB#0807060504030201"


def dls_messages(seconds: float) -> list[can.Message]:
    """The DLS_Sensors frames of the scenario's first seconds, from the in-process run."""
    s = run_inprocess(powertrain_car(load_driveline_scenario(SCENARIO), seconds), Ecu())
    return [to_message(f) for f in s.frames if f["id"] == DLS_ID]


def write_sensor_log(path: Path, start_s: float = PLAY_FROM_S, seconds: float = PLAY_S) -> int:
    """DLS_Sensors of [start_s, start_s + seconds) as a candump -L log, 0.5 ms apart."""
    msgs = dls_messages(start_s + seconds)[int(round(start_s / 0.0005)):]
    t0 = 1_700_000_000.0
    with open(path, "w") as f:
        for k, m in enumerate(msgs):
            f.write(f"({t0 + k * 0.0005:.6f}) {guestlib.CHANNEL} {cansend_frame(m)}\n")
    return len(msgs)


def corrupt(m: can.Message, byte: int = 5) -> can.Message:
    data = bytearray(m.data)
    data[byte] ^= 0x01
    return can.Message(arbitration_id=m.arbitration_id, is_extended_id=m.is_extended_id, is_fd=m.is_fd,
                       bitrate_switch=m.bitrate_switch, data=bytes(data))


def realtime_daemon(out: Path, name: str, bus: can.BusABC, *extra: str) -> subprocess.Popen:
    """A real-time daemon; returns once its first VEHEST_Status is on the bus."""
    daemon = guestlib.start_daemon(out, name, "--mode", "realtime", *extra)
    guestlib.wait_for_frame(bus, STATUS_ID)
    return daemon


def phase_canplayer(out: Path) -> dict:
    n = write_sensor_log(out / "sensors.log")
    bus = guestlib.open_bus()
    try:
        # UML's 100 Hz timer wakes canplayer every 10 ms: it sends 20 frames at once, which the
        # burst check would rightly refuse as stale; the transport, not the sender, batches here
        daemon = realtime_daemon(out, "canplayer", bus, "--rx-burst-limit", "0")
    finally:
        bus.shutdown()
    # -T: candump ends 1 s after the daemon, once it has read every queued frame
    dump = guestlib.start_candump(out / "canplayer.candump.log", "-T", "1000")
    t = time.monotonic()
    play = subprocess.run(["canplayer", "-I", str(out / "sensors.log")], capture_output=True, text=True)
    played_s = time.monotonic() - t
    time.sleep(0.5)
    result = guestlib.daemon_result(out, "canplayer", daemon)
    result.update(frames_in_log=n, canplayer_rc=play.returncode, canplayer_stderr=play.stderr,
                  played_s=played_s, candump_rc=guestlib.finish_candump(dump))
    return result


def phase_hostile(out: Path) -> dict:
    dls = dls_messages(0.01)
    m0, m1, m4, m5 = dls[0], dls[1], dls[4], dls[5]
    ext = can.Message(arbitration_id=DLS_ID, is_extended_id=True, is_fd=True, bitrate_switch=True,
                      data=m5.data)
    injected = {  # what each frame must do to the ECU's counters
        "good, first": (cansend_frame(m0), {}),
        "same frame again (frozen counter)": (cansend_frame(m0), {"counter_repeat": 1}),
        "bad CRC": (cansend_frame(corrupt(m1)), {"crc_error": 1}),
        "good, next counter": (cansend_frame(m1), {}),
        "counter jumps by 3": (cansend_frame(m4), {"counter_skip": 1}),
        f"FD, 12 bytes instead of {DLS_LEN}": (f"100##1{bytes(m5.data[:12]).hex().upper()}", {"dlc_error": 1}),
        "classic, 8 bytes": (f"100#{bytes(m5.data[:8]).hex().upper()}", {"dlc_error": 1}),
        "extended ID 0x100": (cansend_frame(ext), {"dlc_error": 1}),
        "unknown standard ID": ("6AB#00", {"unknown_id": 1}),
        "unknown extended ID": ("1ABCDEF0#11223344", {"unknown_id": 1}),
        "remote frame on 0x100 (ignored)": ("100#R", {}),
    }
    bus = guestlib.open_bus()
    try:
        daemon = realtime_daemon(out, "hostile", bus)
    finally:
        bus.shutdown()
    # -T 5000, not 1000: it passes only VEHEST_Status and the markers, and a guest starved by the flood
    # can leave the daemon silent for over a second (then candump ended before the second marker)
    dump = guestlib.start_candump(out / "hostile.candump.log", "-T", "5000", filters=",300:C00007FF,7AA:C00007FE")
    for frame, _ in injected.values():
        cansend(frame)
    time.sleep(0.5)  # VEHEST_Status frames with the counters go out
    cansend(MARK_BEFORE)
    floods = [["cangen", guestlib.CHANNEL, "-g", "0", "-n", "20000", "-m", "-i"],
              ["cangen", guestlib.CHANNEL, "-g", "0", "-n", "5000", "-f", "-b", "-I", "100", "-L", str(DLS_LEN), "-i"]]
    t = time.monotonic()
    flood_rc = [subprocess.run(cmd, capture_output=True, text=True).returncode for cmd in floods]
    flood_s = time.monotonic() - t
    time.sleep(1.0)
    cansend(MARK_AFTER)
    time.sleep(0.5)
    result = guestlib.daemon_result(out, "hostile", daemon)
    result.update(injected={k: {"frame": f, "expect": e} for k, (f, e) in injected.items()},
                  markers=[MARK_BEFORE, MARK_AFTER],
                  floods=[" ".join(c) for c in floods], flood_rc=flood_rc, flood_frames=25000,
                  flood_s=flood_s, candump_rc=guestlib.finish_candump(dump))
    return result


def outage(seconds: float) -> float:
    t = time.monotonic()
    guestlib.ip_link("down")
    time.sleep(seconds)
    guestlib.ip_link("up")
    return time.monotonic() - t


def phase_link_rt(out: Path) -> dict:
    dls = dls_messages(0.01)
    bus = guestlib.open_bus()
    try:
        daemon = realtime_daemon(out, "link_rt", bus)
        # -D: candump survives the outage; -T 3000: ends 3 s after the daemon (1 s outage)
        dump = guestlib.start_candump(out / "link_rt.candump.log", "-D", "-T", "3000", filters=",300:C00007FF")
        down_s = outage(1.0)
        # the observer's socket reports the outage once, like the daemon's
        observer_error = guestlib.recv_or_error(bus, 0.5)
        time.sleep(0.5)
        cansend(cansend_frame(corrupt(dls[1])), "6AB#00")
        guestlib.wait_for_frame(bus, STATUS_ID)
        time.sleep(0.3)
    finally:
        bus.shutdown()
    result = guestlib.daemon_result(out, "link_rt", daemon)
    result.update(down_s=down_s, observer_error=repr(observer_error), candump_rc=guestlib.finish_candump(dump))
    return result


def phase_link_lockstep(out: Path) -> dict:
    daemon = guestlib.start_daemon(out, "link_lockstep", "--mode", "lockstep")
    bus = guestlib.open_bus()
    try:
        resets = guestlib.wait_for_lockstep_daemon(bus)
    finally:
        bus.shutdown()
    down_s = outage(0.5)
    time.sleep(0.2)
    bus = guestlib.open_bus()  # a socket bound after the outage: no pending ENETDOWN
    try:
        drive = powertrain_car(load_driveline_scenario(SCENARIO), 0.5)
        session = SimMaster(bus, drive, ack_timeout=30.0).run_lockstep(end=False)
    finally:
        bus.shutdown()
    np.savez(out / "link_lockstep.session.npz", frames=session.frames, frame_tick=session.frame_tick,
             truth=session.truth)
    result = guestlib.daemon_result(out, "link_lockstep", daemon)
    result.update(down_s=down_s, handshake_resets=resets, session_ticks=drive.n, session_frames=len(session.frames))
    return result


PHASES = {"canplayer": phase_canplayer, "hostile": phase_hostile, "link_rt": phase_link_rt,
          "link_lockstep": phase_link_lockstep}


def main() -> None:
    out = guestlib.out_dir(sys.argv[1])
    names = sys.argv[2:] or list(PHASES)
    result = {}
    for name in names:
        t = time.monotonic()
        result[name] = PHASES[name](out)
        result[name]["phase_s"] = time.monotonic() - t
    guestlib.emit(result)


if __name__ == "__main__":
    main()
