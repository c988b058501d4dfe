"""Helpers shared by the guest scripts in this folder: processes on a real SocketCAN vcan0.

These scripts run inside user-mode Linux (``vehest_can.tools.uml``), as root, with the host's venv.
They orchestrate can-utils and the ``vehest-can daemon`` as separate processes and write what
they saw to files and one JSON document on stdout; the host-side tests (tests/service/test_vcan.py)
judge it. Nothing here asserts on time: the guest's clock is not a real-time one.
"""
from __future__ import annotations

import glob
import json
import re
import signal
import subprocess
import sys
import time
from pathlib import Path

import can

from vehest_can.bus import bus as busmod
from vehest_can.bus import lockstep
from vehest_can.bus.frames import frame_id

CHANNEL = "vcan0"
STATUS_ID = frame_id("VEHEST_Status")
_RAW_SOCKET = re.compile(rf"^\s+{CHANNEL}\s.*\sraw$")


def raw_sockets() -> int:
    """CAN_RAW filter entries on vcan0 in the kernel's receive lists (all, sff, eff, fil, ...)."""
    n = 0
    for path in glob.glob("/proc/net/can/rcvlist_*"):
        with open(path) as f:
            n += sum(bool(_RAW_SOCKET.match(line)) for line in f)
    return n


def wait_until(pred, timeout: float, what: str, poll: float = 0.01) -> None:
    end = time.monotonic() + timeout
    while not pred():
        if time.monotonic() > end:
            raise SystemExit(f"guest: timed out waiting for {what}")
        time.sleep(poll)


def start_candump(path: Path, *options: str, filters: str = "") -> subprocess.Popen:
    """``candump -L`` of vcan0 into path (a 16 MB socket buffer); returns once it listens."""
    before = raw_sockets()
    out = open(path, "w")
    proc = subprocess.Popen(["candump", "-L", "-r", str(16 << 20), *options, CHANNEL + filters],
                            stdout=out, stderr=subprocess.PIPE, text=True)
    out.close()
    wait_until(lambda: raw_sockets() > before or proc.poll() is not None, 30, "candump to listen")
    if proc.poll() is not None:
        raise SystemExit(f"guest: candump exited {proc.returncode}: {proc.stderr.read()}")
    return proc


def finish_candump(proc: subprocess.Popen, timeout: float = 60.0) -> int:
    """Wait for a ``candump -T`` to end by itself (it has then read every queued frame)."""
    try:
        return proc.wait(timeout=timeout)
    except subprocess.TimeoutExpired:  # the bus never went quiet: stop it
        return stop(proc)


def stop(proc: subprocess.Popen, timeout: float = 60.0) -> int:
    """SIGTERM (if still running) and wait; the exit status."""
    if proc.poll() is None:
        proc.send_signal(signal.SIGTERM)
    try:
        proc.wait(timeout=timeout)
    except subprocess.TimeoutExpired:
        proc.kill()
        proc.wait()
        return -9
    return proc.returncode


def start_daemon(out: Path, name: str, *args: str, interface: str = "socketcan",
                 channel: str = CHANNEL) -> subprocess.Popen:
    """``vehest-can daemon -i socketcan -c vcan0 ARGS --stats out/name.json``, stderr to out/name.err."""
    err = open(out / f"{name}.err", "w")
    proc = subprocess.Popen(
        [sys.executable, "-m", "vehest_can.cli", "daemon", "-i", interface, "-c", channel, *args,
         "--stats", str(out / f"{name}.json")],
        stdout=subprocess.DEVNULL, stderr=err, text=True)
    err.close()
    return proc


def daemon_result(out: Path, name: str, proc: subprocess.Popen) -> dict:
    """SIGTERM the daemon; its exit status, stderr (the summary) and --stats JSON."""
    rc = stop(proc)
    stats = out / f"{name}.json"
    return {"rc": rc, "stderr": (out / f"{name}.err").read_text(),
            "stats": json.loads(stats.read_text()) if stats.exists() else None}


def open_bus(interface: str = "socketcan", channel: str = CHANNEL) -> can.BusABC:
    """The bus as vehest-can opens it (udp_multicast: host only, as the daemon's)."""
    return busmod.open_bus({"interface": interface, "channel": channel, "fd": True})


def recv_or_error(bus: can.BusABC, timeout: float):
    """bus.recv that returns a received error (the link went down) instead of raising it."""
    try:
        return bus.recv(timeout=timeout)
    except can.CanOperationError as exc:
        return exc


def wait_for_frame(bus: can.BusABC, arbitration_id: int, timeout: float = 60.0) -> can.Message:
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        msg = recv_or_error(bus, 0.1)
        if isinstance(msg, can.Message) and msg.arbitration_id == arbitration_id and not msg.is_extended_id:
            return msg
    raise SystemExit(f"guest: no frame 0x{arbitration_id:X} on {CHANNEL} within {timeout} s")


def drain(bus: can.BusABC, quiet: float = 0.3) -> int:
    n = 0
    while recv_or_error(bus, quiet) is not None:
        n += 1
    return n


def wait_for_lockstep_daemon(bus: can.BusABC, timeout: float = 60.0) -> int:
    """RESET handshakes until the lockstep daemon answers, then drain the late answers.

    ``SimMaster.connect`` waits only 0.2 s per RESET; a daemon still starting up could answer
    an earlier RESET late and be mistaken for the answer to a later one. Returns the number of
    RESETs sent.
    """
    end = time.monotonic() + timeout
    sent = 0
    while time.monotonic() < end:
        bus.send(lockstep.sync_message(0, lockstep.RESET))
        sent += 1
        answer_by = time.monotonic() + 1.0
        while time.monotonic() < answer_by:
            msg = recv_or_error(bus, 0.1)
            if isinstance(msg, can.Message) and lockstep.is_ack(msg):
                drain(bus)
                return sent
    raise SystemExit(f"guest: the lockstep daemon did not answer RESET within {timeout} s")


def cansend(*frames: str) -> None:
    for frame in frames:
        subprocess.run(["cansend", CHANNEL, frame], check=True)


def cansend_frame(msg: can.Message) -> str:
    """A can.Message in cansend's syntax (123#..., 12345678#..., 123##<flags>...)."""
    ident = f"{msg.arbitration_id:08X}" if msg.is_extended_id else f"{msg.arbitration_id:03X}"
    if msg.is_fd:
        return f"{ident}##{int(msg.bitrate_switch)}{bytes(msg.data).hex().upper()}"
    return f"{ident}#{bytes(msg.data).hex().upper()}"


def ip_link(state: str) -> None:
    subprocess.run(["ip", "link", "set", CHANNEL, state], check=True)


def emit(result: dict) -> None:
    json.dump(result, sys.stdout, indent=1)
    sys.stdout.write("\n")
    sys.stdout.flush()


def out_dir(arg: str) -> Path:
    out = Path(arg).resolve()
    out.mkdir(parents=True, exist_ok=True)
    return out
