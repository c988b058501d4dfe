"""The ECU daemon as its own process (`python -m vehest_can.cli daemon`), for tests in any folder
(tests/ is on sys.path: its conftest.py lives there)."""
import os
import signal
import socket
import subprocess
import sys

from vehest_can.bus.bus import cli_args


def start_daemon(config, *extra, tmp_path=None):
    """The daemon as its own process; with tmp_path, wait for its sd_notify READY=1 (bus open,
    loop starting) instead of guessing how long start-up takes on a loaded machine."""
    env = dict(os.environ)
    sock = None
    if tmp_path is not None:
        sock = socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM)
        sock.bind(str(tmp_path / "notify.sock"))
        sock.settimeout(60)
        env["NOTIFY_SOCKET"] = str(tmp_path / "notify.sock")
    proc = subprocess.Popen(
        [sys.executable, "-m", "vehest_can.cli", "daemon", *cli_args(config), *extra],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env,
    )
    if sock is not None:
        try:
            while b"READY=1" not in sock.recv(4096):
                pass
        finally:
            sock.close()
    return proc


def stop_daemon(proc, sig=signal.SIGTERM):
    if proc.poll() is None:
        proc.send_signal(sig)
    out, err = proc.communicate(timeout=20)
    return proc.returncode, err
