"""`-i socketcan` on a kernel without CAN: an error that names the cause and the way out (the host-only
default bus, user-mode Linux), not a bare `[Errno 97]`."""
import errno
import socket
import subprocess
import sys

import can
import pytest

from vehest_can.bus import bus as busmod
from vehest_can.errors import BusError


def test_the_error_names_the_cause_and_the_fix(monkeypatch):
    def no_af_can(**_kw):
        raise OSError(errno.EAFNOSUPPORT, "Address family not supported by protocol")

    monkeypatch.setattr(can, "Bus", no_af_can)
    with pytest.raises(BusError) as err:
        busmod.open_bus({"interface": "socketcan", "channel": "vcan0"})
    text = str(err.value)
    assert "[Errno 97]" in text and "no SocketCAN" in text
    assert "docs/bus.md" in text and "docs/uml.md" in text and "leave out -i/--interface" in text


def _kernel_has_can() -> bool:
    try:
        socket.socket(socket.AF_CAN, socket.SOCK_RAW, socket.CAN_RAW).close()
        return True
    except OSError:
        return False


@pytest.mark.skipif(_kernel_has_can(), reason="this kernel has SocketCAN: nothing to explain")
def test_on_this_kernel_every_verb_says_so():
    for verb in (["monitor", "--once", "--duration", "0.1"], ["daemon", "--duration", "0.1"]):
        out = subprocess.run([sys.executable, "-m", "vehest_can.cli", *verb, "-i", "socketcan", "-c", "vcan0"],
                             capture_output=True, text=True, timeout=60)
        assert out.returncode == 1 and "Traceback" not in out.stderr, out.stderr
        assert "no SocketCAN" in out.stderr and "docs/uml.md" in out.stderr, out.stderr
