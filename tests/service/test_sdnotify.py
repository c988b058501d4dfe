"""sd_notify: a real AF_UNIX datagram socket as NOTIFY_SOCKET hears a real ``vehest-can daemon`` say
READY=1, WATCHDOG=1 with STATUS=, then STOPPING=1, in that order; the abstract namespace too; no socket,
no messages and no harm. Plus the journal's level prefixes on a real stderr file."""
from __future__ import annotations

import json
import logging
import os
import random
import shlex
import shutil
import socket
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

import can
import pytest

from vehest_can.bus import bus as busmod
from vehest_can.bus.frames import unused_frame_id
from vehest_can.cli import build_parser
from vehest_can.service import sdnotify
from vehest_can.service.sdnotify import Notifier, Watchdog, socket_address, watchdog_interval


def group() -> str:
    return f"239.74.{random.randint(1, 254)}.{random.randint(1, 254)}"


@pytest.fixture
def notify_socket():
    """A bound AF_UNIX SOCK_DGRAM socket at a short path (sun_path holds 108 bytes)."""
    d = tempfile.mkdtemp(prefix="vh-", dir="/tmp")
    sock = socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM)
    sock.bind(f"{d}/notify")
    yield sock, f"{d}/notify"
    sock.close()
    shutil.rmtree(d, ignore_errors=True)


def run_daemon(env_extra: dict, sock: socket.socket, *args, timeout=60.0):
    """Run ``vehest-can daemon ARGS`` and collect (receive time, message) until STOPPING=1 and exit."""
    env = {k: v for k, v in os.environ.items() if k not in ("NOTIFY_SOCKET", "WATCHDOG_USEC", "WATCHDOG_PID")}
    proc = subprocess.Popen([sys.executable, "-m", "vehest_can.cli", "daemon", *args], env={**env, **env_extra},
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    got = []
    sock.settimeout(0.2)
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        try:
            data = sock.recv(4096)
        except TimeoutError:
            if proc.poll() is not None:
                break
            continue
        got.append((time.monotonic(), data.decode()))
        if "STOPPING=1" in data.decode():
            break
    out, err = proc.communicate(timeout=30)
    assert proc.returncode == 0, err
    return got, err


def fields(message: str) -> dict:
    return dict(line.split("=", 1) for line in message.split("\n"))


@pytest.mark.multicast
def test_realtime_daemon_notifies_ready_watchdog_status_stopping_in_order(notify_socket, tmp_path):
    sock, path = notify_socket
    stats = tmp_path / "stats.json"
    channel = group()
    stop = threading.Event()

    def junk():  # frames of an ID the ECU does not receive: a fault counter that rises
        bus = busmod.open_bus({"interface": "udp_multicast", "channel": channel, "fd": True})
        try:
            while not stop.wait(0.01):
                bus.send(can.Message(arbitration_id=unused_frame_id(), is_extended_id=False, data=bytes(8)))
        finally:
            bus.shutdown()

    sender = threading.Thread(target=junk, daemon=True)
    sender.start()
    try:
        got, err = run_daemon({"NOTIFY_SOCKET": path, "WATCHDOG_USEC": "400000"}, sock,
                              "--mode", "realtime", "--duration", "2", "-i", "udp_multicast", "-c", channel,
                              "--stats", str(stats), "--log-level", "info")
    finally:
        stop.set()
        sender.join()
    msgs = [fields(m) for _, m in got]
    assert msgs[0]["READY"] == "1" and msgs[0]["STATUS"].startswith("realtime: serving on")
    assert msgs[-1]["STOPPING"] == "1"
    beats = [(t, m) for (t, _), m in zip(got, msgs) if m.get("WATCHDOG") == "1"]
    assert len(beats) == len(msgs) - 2 and len(beats) >= 5  # everything between is a watchdog beat
    # half of WATCHDOG_USEC=400 ms: a beat every 0.2 s, never more often
    gaps = [b[0] - a[0] for a, b in zip(beats[1:], beats[2:])]
    assert min(gaps) > 0.15 and sorted(gaps)[len(gaps) // 2] < 0.4, gaps
    ticks = [int(m["STATUS"].split(": ")[1].split()[0]) for _, m in beats]
    assert ticks == sorted(ticks) and ticks[-1] > 0
    # the last status is the daemon's own count (its --stats file is the independent record)
    s = json.loads(stats.read_text())
    final = msgs[-1]["STATUS"]
    assert final.startswith(f"realtime stopping: {s['ticks']} ticks; faults: ")
    assert "unknown_id=" in final and "input_invalid" not in final  # no car: not heard, not a fault
    # log lines on stderr, with levels
    assert "INFO vehest_can.service.daemon: ECU daemon serving in realtime mode" in err
    assert "WARNING vehest_can.service.daemon: realtime: faults rising: unknown_id" in err
    assert "INFO vehest_can.service.daemon: ECU daemon stopped" in err


@pytest.mark.multicast
def test_lockstep_daemon_beats_while_idle_on_an_abstract_socket():
    name = f"vehest-test-{os.getpid()}-{random.randint(0, 1 << 30)}"
    sock = socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM)
    sock.bind(b"\0" + name.encode())
    try:
        # no simulator on this bus: the daemon idles 1.5 s, beating, then stops on its idle timeout
        got, err = run_daemon({"NOTIFY_SOCKET": f"@{name}", "WATCHDOG_USEC": "200000"}, sock,
                              "--mode", "lockstep", "--idle-timeout", "1.5", "-i", "udp_multicast", "-c", group())
    finally:
        sock.close()
    msgs = [fields(m) for _, m in got]
    assert "READY" in msgs[0] and "STOPPING" in msgs[-1]
    idle = [m for m in msgs if m.get("WATCHDOG") == "1"]
    assert len(idle) >= 8  # 1.5 s at one beat per 0.1 s
    assert all(m["STATUS"] == "lockstep: 0 ticks; faults: none" for m in idle)
    assert "no frame for 1.5 s" in err


@pytest.mark.multicast
def test_without_notify_socket_the_daemon_runs_and_sends_nothing(notify_socket):
    sock, path = notify_socket
    # the socket exists, but NOTIFY_SOCKET does not name it: nothing must arrive
    got, err = run_daemon({}, sock, "--mode", "realtime", "--duration", "0.5", "-i", "udp_multicast", "-c", group(),
                          timeout=30)
    assert got == []
    assert "mode realtime:" in err


def test_unset_socket_is_a_noop():
    n = Notifier.from_env({})
    assert not n.enabled
    assert n.ready() is False and n.watchdog("x") is False and n.status("x") is False and n.stopping() is False
    w = Watchdog(n, "test", lambda: 7, lambda: {"crc_error": 0}, interval=0.2)
    # it still keeps its own schedule (and logs faults) without systemd
    assert w.tick(0.0) is True and w.tick(0.1) is False and w.tick(0.2) is True


def test_addresses_and_watchdog_interval():
    assert socket_address("/run/systemd/notify") == "/run/systemd/notify"
    assert socket_address("@abstract/name") == b"\0abstract/name"
    assert socket_address("") is None and socket_address(None) is None
    assert socket_address("vsock:2:1234") is None
    assert watchdog_interval({"WATCHDOG_USEC": "30000000"}) == 15.0
    assert watchdog_interval({"WATCHDOG_USEC": "400000", "WATCHDOG_PID": str(os.getpid())}) == 0.2
    assert watchdog_interval({"WATCHDOG_USEC": "400000", "WATCHDOG_PID": "1"}, pid=2) is None  # not for us
    assert watchdog_interval({}) is None
    assert watchdog_interval({"WATCHDOG_USEC": "soon"}) is None
    assert watchdog_interval({"WATCHDOG_USEC": "0"}) is None


def test_watchdog_rate_and_fault_logging(notify_socket, caplog):
    sock, path = notify_socket
    sock.settimeout(1.0)
    counters = {"crc_error": 0, "timeout": 0}
    ticks = [0]
    w = Watchdog(Notifier(path), "realtime", lambda: ticks[0], lambda: counters, interval=0.25)
    assert w.interval == 0.25
    with caplog.at_level(logging.INFO, logger="vehest_can.service.sdnotify"):
        beat_at = []
        for i in range(0, 65):  # 1 s of loop iterations every 1/64 s (binary-exact times) on a given clock
            now = i / 64
            ticks[0] = i
            if i == 20:
                counters["crc_error"] = 3
            if w.tick(now):
                beat_at.append(now)
        assert beat_at == [0.0, 0.25, 0.5, 0.75, 1.0]
        got = [sock.recv(4096).decode() for _ in beat_at]
        assert got[0] == "WATCHDOG=1\nSTATUS=realtime: 0 ticks; faults: none"
        assert got[2] == "WATCHDOG=1\nSTATUS=realtime: 32 ticks; faults: crc_error=3"
        warnings = [r.getMessage() for r in caplog.records if r.levelno == logging.WARNING]
        assert warnings == ["realtime: faults rising: crc_error +3 (total 3)"]  # once, not every beat
        # settled after QUIET_S without a new fault: one INFO line
        w.tick(1.0 + sdnotify.QUIET_S)
        infos = [r.getMessage() for r in caplog.records if r.levelno == logging.INFO]
        assert infos == [f"realtime: no new faults for {sdnotify.QUIET_S:g} s: crc_error=3"]
    # the longest gap between STATUS lines is 1 s, whatever the systemd watchdog says
    assert Watchdog(Notifier(None), "x", int, dict, interval=15.0).interval == 1.0


def test_a_full_or_vanished_receiver_never_blocks_or_raises(notify_socket):
    sock, path = notify_socket
    n = Notifier(path)
    t0 = time.perf_counter()
    sent = sum(n.watchdog("x") for _ in range(200))  # nobody reads: the queue fills up
    assert time.perf_counter() - t0 < 1.0
    assert 0 < sent < 200 and n.dropped == 200 - sent and n.enabled
    gone = Notifier(path + ".absent")
    assert gone.ready() is False and not gone.enabled  # warned once, then quiet


def test_journal_level_prefixes_on_a_real_stderr_file(tmp_path):
    err_path = tmp_path / "stderr"
    code = ("import logging, sys\n"
            "from vehest_can.service import sdnotify\n"
            "logging.basicConfig(level=logging.INFO, stream=sys.stderr)\n"
            "print(sdnotify.use_journal_levels(), file=sys.stderr)\n"
            "logging.getLogger('vehest_can.service.daemon').info('serving')\n"
            "logging.getLogger('vehest_can.service.daemon').warning('faults rising')\n")
    with open(err_path, "w") as fh:
        st = os.fstat(fh.fileno())
        env = {**os.environ, "JOURNAL_STREAM": f"{st.st_dev}:{st.st_ino}"}
        subprocess.run([sys.executable, "-c", code], stderr=fh, env=env, check=True, timeout=60)
    assert err_path.read_text().splitlines() == [
        "True", "<6>vehest_can.service.daemon: serving", "<4>vehest_can.service.daemon: faults rising"]
    # another stream than the one JOURNAL_STREAM names: no prefixes
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, timeout=60)
    assert r.stderr.splitlines()[0] == "False" and "INFO:vehest_can.service.daemon:serving" in r.stderr


UNIT = Path(__file__).resolve().parents[2] / "examples" / "systemd" / "vehest-ecu.service"


def test_systemd_unit_example_is_a_notify_service_with_a_valid_command(tmp_path):
    text = UNIT.read_text()
    service = {}
    for line in text.split("[Service]")[1].split("[Install]")[0].splitlines():
        if "=" in line and not line.startswith("#"):
            key, value = line.split("=", 1)
            service[key] = value
    assert service["Type"] == "notify" and service["NotifyAccess"] == "main"
    assert service["WatchdogSec"] == "5s" and service["Restart"] == "on-failure"
    assert service["KillSignal"] == "SIGTERM" and service["StandardError"] == "journal"
    # ExecStart is a command line our CLI accepts
    argv = shlex.split(service["ExecStart"])
    assert argv[0].endswith("/.venv/bin/vehest-can")
    args = build_parser().parse_args(argv[1:])
    assert args.verb == "daemon" and args.mode == "realtime" and args.log_level == "info"
    # systemd's own checker, with ExecStart pointing at this checkout's console script
    analyze = shutil.which("systemd-analyze")
    if analyze is None:
        pytest.skip("systemd-analyze not installed")
    script = Path(sys.executable).parent / "vehest-can"
    assert script.exists()
    unit = tmp_path / "vehest-ecu.service"
    unit.write_text(text.replace(argv[0], str(script)))
    r = subprocess.run([analyze, "verify", str(unit)], capture_output=True, text=True, timeout=60)
    assert r.returncode == 0, r.stderr
    # the interface dependency is the only thing it may mention (no can0 here)
    assert all("can0" in line for line in r.stderr.splitlines() if line.strip()), r.stderr
